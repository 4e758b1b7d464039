"""Formalism ``lagrange-ad``: Lagrange's equations of the second kind by automatic
differentiation of T and V in joint coordinates (book 5.8.2).

The generalized coordinates q are the free joint coordinates of the spanning tree, with
q' = v. From the kinetic energy T(t, q, q') and the potential energy V(t, q) of the
workbench's formalism-neutral kinematics and force elements, CasADi's automatic
differentiation gives

    d/dt (dT/dq') - dT/dq + dV/dq = Q_nc,
    M = d^2 T / dq'^2,   M q'' = dT/dq - dV/dq - (d^2 T / dq' dq) q' - d^2 T / dq' dt + Q_nc,

where Q_nc are the non-conservative generalized forces (damping, joint and applied
forces); T, V and Q_nc come from
:func:`workbench.mechanics.lagrangian.joint_space_lagrangian`. Driven joints enter through
the explicit time dependence of T. Closed loops and nonholonomic constraints are appended
as in Lagrange's equations of the first kind (multipliers, option ``index``). Spherical
and free joints are not supported: their quaternion coordinates have q' != v, where
Lagrange's equations in this form do not hold.

Written only against the public plugin API, as a worked example for plugin authors.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from workbench.equations import Equations, build_joint_space_equations, joint_space_system
from workbench.mechanics.kinematics import TreeKinematics
from workbench.mechanics.lagrangian import joint_space_lagrangian, quaternion_joints
from workbench.model import Model
from workbench.plugin.formalism import ConstraintOptions, Formalism, constrained_forms
from workbench.plugin.registry import formalism


@formalism
class LagrangeAD(Formalism):
    """Lagrange's equations of the second kind from T and V by automatic differentiation."""

    name = "lagrange-ad"
    summary = (
        "Lagrange's equations from T(q, q') and V(q) by CasADi automatic differentiation (5.8.2)"
    )
    Options = ConstraintOptions
    capabilities = frozenset(
        {"planar", "spatial", "point-masses", "rheonomic", "closed-loops", "nonholonomic"}
    )

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        return constrained_forms(cls.parse_options(options))

    @classmethod
    def unsupported(cls, model: Model) -> set[str]:
        return super().unsupported(model) | quaternion_joints(model)

    def build(self, model: Model, options: Any = None) -> Equations:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        k = TreeKinematics(model)
        kinetic, potential, nonconservative = joint_space_lagrangian(model, k)
        momentum = ca.gradient(kinetic, k.v)  # p = dT/dq'
        mass = ca.jacobian(momentum, k.v)  # M = d^2 T / dq'^2
        forces = (
            ca.gradient(kinetic, k.q)
            - ca.gradient(potential, k.q)
            - ca.mtimes(ca.jacobian(momentum, k.q), k.v)
            - ca.jacobian(momentum, k.t)
            + nonconservative
        )
        system = joint_space_system(k, mass, forces)
        ode = system.n_constraints == 0 or options.index == 1
        return build_joint_space_equations(self.name, model, k, system, options, ode)
