"""A penalty formalism for the conformance kit's tests (issue 34.3): loop closures enforced
approximately, by a stiff spring-damper on the closure residual, instead of multipliers.

Lagrange's equations in the spanning tree's joint coordinates (as the scaffold's worked
example), plus the penalty force Q_p = -W^T (stiffness g + damping g') on the cut joints'
position constraints g(q) = 0 (W = dg/dq, g' = W v). No constraint rows are kept: the
equations have nv degrees of freedom, not describe's nv - rank W. For a mechanism of mass
m under forces of size F the residual settles near F / stiffness, so ``Options.declared``
(the residual this formalism promises, m and rad) is what a test sets: right, or too tight.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca

from workbench.equations import MechanicalSystem, build_equations
from workbench.equations.compiled import Compiler
from workbench.mechanics.kinematics import TreeKinematics
from workbench.mechanics.lagrangian import joint_space_lagrangian
from workbench.plugin.formalism import ConstraintOptions, Formalism
from workbench.plugin.registry import formalism


@dataclass(frozen=True)
class PenaltyOptions(ConstraintOptions):
    """Penalty stiffness (1/s^2, per unit mass of the loop) and damping (1/s); the residual
    declared to the kit (m, rad)."""

    index: int = 1
    stiffness: float = 1e6
    damping: float = 2e3
    declared: float = 0.0  # 0: declares nothing (as if the constraints were exact)


@formalism
class PenaltyLoops(Formalism):
    """Tree coordinates, loop closures by a penalty spring-damper (test formalism)."""

    name = "test-penalty"
    summary = "Lagrange in tree coordinates, loops closed by penalty forces (test)"
    Options = PenaltyOptions
    capabilities = frozenset({"planar", "closed-loops"})

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        return {"ode": 0, "dae": 0, "mechanical": 0}  # no constraint rows: index 0

    @classmethod
    def constraint_tolerance(cls, options: Any) -> float | None:
        declared = cls.parse_options(options).declared
        return declared if declared != 0 else None

    def build(self, model: Any, options: Any = None) -> Any:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        k = TreeKinematics(model)
        kinetic, potential, nonconservative = joint_space_lagrangian(model, k)
        momentum = ca.gradient(kinetic, k.v)
        mass = ca.jacobian(momentum, k.v)
        forces = (
            ca.gradient(kinetic - potential, k.q)
            - ca.mtimes(ca.jacobian(momentum, k.q), k.v)
            - ca.jacobian(momentum, k.t)
            + nonconservative
        )
        g = k.closure_constraints
        if g.numel():
            w_matrix = ca.jacobian(g, k.q)  # q' = v: tree joints of a planar model
            g_dot = ca.mtimes(w_matrix, k.v)
            scale = ca.trace(mass) / k.nv  # a mass of the loop, so the gains are per unit mass
            penalty = scale * (options.stiffness * g + options.damping * g_dot)
            forces = forces - ca.mtimes(w_matrix.T, penalty)
        system = MechanicalSystem(
            t=k.t, q=k.q, v=k.v, qdot=k.qdot, mass=mass, forces=forces,
            q_names=k.q_names, v_names=k.v_names,
        )  # fmt: skip
        return build_equations(
            self.name, model, system, k.bodies, ([k.t, k.q, k.v], [k.q, k.v]),
            joint_coordinates={j.name: k.joint_coordinates(j)[0] for j in model.tree_joints},
            compiler=Compiler.from_options(options),
        )  # fmt: skip
