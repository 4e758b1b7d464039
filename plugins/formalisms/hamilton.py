"""Formalism ``hamilton``: Hamilton's canonical equations in (q, p) (book 5.8.3).

The coordinates q are the free joint coordinates of the spanning tree; the momenta
p = dL/dq' = M(q) q' (scleronomic: T = 1/2 q'^T M q') replace the velocities in the state,
which is [q, p]. With the Hamiltonian built by the Legendre transform

    q'(q, p) = M(q)^-1 p,     H(q, p) = p . q' - L(q, q'(q, p)),   L = T - V,

and differentiated by CasADi's automatic differentiation, the canonical equations are

    q' = dH/dp,     p' = -dH/dq + Q_nc,

Q_nc the non-conservative generalized forces (as in ``lagrange-ad``). In the workbench's
equations contract the momenta play the role of the velocities: the mechanical form is
I p' = Q with q' = H(q) p, H = M(q)^-1, and every observable (poses, twists, energies,
constraint residuals) is a function of (t, q, p) through q'(q, p), so runs, metrics and
recordings need nothing special. The joint-space map of initial states is p = M(q) q'.
M^-1 p is a symbolic solve up to :data:`workbench.equations.SYMBOLIC_SOLVE_LIMIT`
coordinates and a numeric LU inside an MX graph beyond.

Not supported: closed loops and nonholonomic constraints (their multipliers would act
along M^-1 W^T in p-space), driven joints (p = M q' + b(t, q) is affine in q'), spherical
and free joints (quaternions, q' != v). Use ``lagrange-ad`` or ``minimal-ode`` for them.

Written only against the public plugin API, as a worked example for plugin authors.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from workbench.equations import (
    SYMBOLIC_SOLVE_LIMIT,
    Equations,
    MechanicalSystem,
    build_equations,
)
from workbench.mechanics.kinematics import BodyState, TreeKinematics, quaternion_slices
from workbench.mechanics.lagrangian import joint_space_lagrangian, quaternion_joints
from workbench.model import Model
from workbench.plugin.formalism import Formalism
from workbench.plugin.registry import formalism


@formalism
class Hamilton(Formalism):
    """Hamilton's canonical equations in joint coordinates and momenta."""

    name = "hamilton"
    summary = "Hamilton's canonical equations in (q, p), H by Legendre transform and AD (5.8.3)"
    capabilities = frozenset({"planar", "spatial", "point-masses"})

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        return {"ode": 0, "dae": 0, "mechanical": 0}

    @classmethod
    def unsupported(cls, model: Model) -> set[str]:
        return super().unsupported(model) | quaternion_joints(model)

    def build(self, model: Model, options: Any = None) -> Equations:
        self.parse_options(options)
        model.validate()
        self.check(model)
        k = TreeKinematics(model)
        kinetic, potential, nonconservative = joint_space_lagrangian(model, k)
        mass = ca.hessian(kinetic, k.v)[0]  # M(q): T is quadratic in q' (scleronomic)
        # (t, q, v) -> everything the canonical equations and observables need
        flat = []
        for body in model.bodies:
            state = k.bodies[body]
            flat += [state.position, state.rotation, state.velocity, state.angular_velocity]
        joints = [k.joint_coordinates(j)[0] for j in model.tree_joints]
        parts = ca.Function(
            "parts", [k.t, k.q, k.v], [mass, kinetic - potential, nonconservative, *joints, *flat]
        )
        symbolic = k.nv <= SYMBOLIC_SOLVE_LIMIT
        kind = ca.SX if symbolic else ca.MX
        t, q, p = kind.sym("t"), kind.sym("q", k.nq), kind.sym("p", k.nv)
        mass_q = parts(t, q, ca.DM.zeros(k.nv))[0]
        rate = ca.solve(mass_q, p) if symbolic else ca.solve(mass_q, p, "ldl")
        _, lagrangian, q_nc, *rest = parts(t, q, rate)
        hamiltonian = ca.dot(p, rate) - lagrangian  # Legendre transform
        qdot = ca.gradient(hamiltonian, p)
        pdot = -ca.gradient(hamiltonian, q) + q_nc
        n_joints = len(joints)
        bodies = {
            body: BodyState(*rest[n_joints + 4 * i : n_joints + 4 * i + 4])
            for i, body in enumerate(model.bodies)
        }
        system = MechanicalSystem(
            t=t,
            q=q,
            v=p,
            qdot=qdot,
            mass=kind.eye(k.nv),
            forces=pdot,
            q_names=k.q_names,
            v_names=[name.replace(".v", ".p", 1) for name in k.v_names],
            acceleration=pdot,
        )
        momentum = ca.mtimes(mass, k.v)  # joint space -> (q, p)
        return build_equations(
            self.name,
            model,
            system,
            bodies,
            ([k.t, k.q, k.v], [k.q, momentum]),
            joint_coordinates={j.name: rest[i] for i, j in enumerate(model.tree_joints)},
            notes=["state [q, p]: the velocity slots hold the generalized momenta p = M q'"],
            quaternion_slices=quaternion_slices(k),
        )
