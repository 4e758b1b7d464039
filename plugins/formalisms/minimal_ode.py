"""Formalism ``minimal-ode``: joint coordinates, M(q) q'' = Q - h (book 5.6.2, 6.6.2, 7.6.2, 10.5).

The generalized coordinates are the free joint coordinates of the spanning tree. The
explicit constraints (forward kinematics, :class:`~workbench.kinematics.TreeKinematics`)
give each body's centre-of-mass velocity v_c = J_T v and angular velocity w = J_R v; then

    M = sum J_T^T m J_T + J_R^T I J_R,     h = sum J_T^T m a_c,bias + J_R^T (I a_R,bias + w x I w),

with the bias accelerations at v' = 0 — the non-recursive O(n^3) formalism. Closed loops
(option ``loops="dae"``, book 11.4.1): primary (tree) joint coordinates plus the closure
constraints of the cut joints with multipliers, at the index given by option ``index``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca

from workbench import forces as fm
from workbench.equations import Equations, MechanicalSystem, build_equations
from workbench.errors import ConfigError
from workbench.formalism import Formalism
from workbench.kinematics import TreeKinematics
from workbench.model import Model
from workbench.registry import formalism


@dataclass(frozen=True)
class MinimalOptions:
    loops: Literal["dae", "state-space"] = "dae"
    index: Literal[1, 2, 3] = 3
    baumgarte_alpha: float = 10.0
    baumgarte_beta: float = 10.0

    def __post_init__(self) -> None:
        if self.baumgarte_alpha < 0 or self.baumgarte_beta < 0:
            raise ConfigError("Baumgarte gains must be >= 0")


def minimal_mechanical_system(model: Model, kinematics: TreeKinematics) -> MechanicalSystem:
    """M, Q - h and the constraints in the tree's joint coordinates."""
    k = kinematics
    mass = ca.SX.zeros(k.nv, k.nv)
    bias = ca.SX.zeros(k.nv)
    for name, body in model.bodies.items():
        state = k.body(name)
        v_com = state.point_velocity(body.com)
        omega = state.angular_velocity
        j_t, j_r = ca.jacobian(v_com, k.v), ca.jacobian(omega, k.v)
        # accelerations at v' = 0: d/dt along q' = H v and explicit time (drives)
        a_com = ca.mtimes(ca.jacobian(v_com, k.q), k.qdot) + ca.jacobian(v_com, k.t)
        alpha = ca.mtimes(ca.jacobian(omega, k.q), k.qdot) + ca.jacobian(omega, k.t)
        inertia = ca.mtimes([state.rotation, ca.DM(body.inertia), state.rotation.T])
        mass += body.mass * ca.mtimes(j_t.T, j_t) + ca.mtimes([j_r.T, inertia, j_r])
        gyroscopic = ca.mtimes(inertia, alpha) + ca.cross(omega, ca.mtimes(inertia, omega))
        bias += body.mass * ca.mtimes(j_t.T, a_com) + ca.mtimes(j_r.T, gyroscopic)
    joint_coordinates = {j.name: k.joint_coordinates(j) for j in model.tree_joints}
    applied = fm.generalized_forces(model, k.t, k.v, k.bodies, joint_coordinates)
    return MechanicalSystem(
        t=k.t,
        q=k.q,
        v=k.v,
        qdot=k.qdot,
        mass=mass,
        forces=applied - bias,
        q_names=k.q_names,
        v_names=k.v_names,
        position_constraints=k.closure_constraints,
        velocity_constraints=k.velocity_constraints,
        constraint_names=k.velocity_constraint_names,
    )


@formalism
class MinimalOde(Formalism):
    name = "minimal-ode"
    summary = "Joint coordinates of the spanning tree, mass matrix M(q), O(n^3) (book 10.5)"
    Options = MinimalOptions
    capabilities = frozenset(
        {"planar", "spatial", "closed-loops", "rheonomic", "point-masses", "nonholonomic"}
    )

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        options = cls.parse_options(options)
        forms = {"dae": options.index, "mechanical": 0}
        if options.index == 1:
            forms["ode"] = 0
        return forms

    def build(self, model: Model, options: Any = None) -> Equations:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        if options.loops == "state-space":
            raise ConfigError(
                "minimal-ode: loops='state-space' is not available yet; use loops='dae'"
            )
        kinematics = TreeKinematics(model)
        system = minimal_mechanical_system(model, kinematics)
        joint_coordinates = {
            j.name: kinematics.joint_coordinates(j)[0]
            for j in model.tree_joints
        }
        return build_equations(
            self.name,
            model,
            system,
            kinematics.bodies,
            ([kinematics.t, kinematics.q, kinematics.v], [kinematics.q, kinematics.v]),
            dae_index=options.index,
            baumgarte=(options.baumgarte_alpha, options.baumgarte_beta),
            ode=system.n_constraints == 0 or options.index == 1,
            joint_coordinates=joint_coordinates,
        )
