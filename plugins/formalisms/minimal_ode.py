"""Formalism ``minimal-ode``: joint coordinates, M(q) q'' = Q - h (book 5.6.2, 6.6.2, 7.6.2, 10.5).

The generalized coordinates are the free joint coordinates of the spanning tree. The
explicit constraints (forward kinematics, :class:`~workbench.mechanics.kinematics.TreeKinematics`)
give each body's centre-of-mass velocity v_c = J_T v and angular velocity w = J_R v; then

    M = sum J_T^T m J_T + J_R^T I J_R,     h = sum J_T^T m a_c,bias + J_R^T (I a_R,bias + w x I w),

with the bias accelerations at v' = 0 — the non-recursive O(n^3) formalism. Closed loops
(option ``loops="dae"``, book 11.4.1): primary (tree) joint coordinates plus the closure
constraints of the cut joints with multipliers, at the index given by option ``index``.
Option ``loops="state-space"`` (book 11.5, coordinate partitioning after Wehage and Haug,
1982): the velocities are the independent ones v_i (chosen by pivoted QR of the
constraint Jacobian where ``workbench describe`` decides the rank: the model's initial
configuration, the problem's, assembled; :func:`workbench.mechanics.topology.analyze`);
the dependent coordinates
stay in the state as the starting guess of a Newton solve of g(t, q_i, q_d) = 0 made at
every evaluation, so the equations are an ODE (F^T M F) v_i' = F^T (Q - M c) on the
constraint manifold, with v = F v_i + f. A singular partition makes the Newton solve fail,
which ends the integration with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np

from workbench.equations import (
    Equations,
    MechanicalSystem,
    build_equations,
    build_joint_space_equations,
    joint_space_system,
)
from workbench.equations.compiled import Compiler
from workbench.errors import ModelError
from workbench.mechanics.kinematics import TreeKinematics
from workbench.mechanics.newton_euler import newton_euler_forces
from workbench.model import Model
from workbench.numerics.linalg import independent_columns
from workbench.plugin.formalism import ConstraintOptions, Formalism, constrained_forms
from workbench.plugin.registry import formalism


@dataclass(frozen=True)
class MinimalOptions(ConstraintOptions):
    loops: Literal["dae", "state-space"] = "dae"


def minimal_mechanical_system(model: Model, kinematics: TreeKinematics) -> MechanicalSystem:
    """M, Q - h (Newton-Euler, projected) and the constraints in the tree's joint coordinates."""
    k = kinematics
    joint_coordinates = {j.name: k.joint_coordinates(j) for j in model.tree_joints}
    mass, forces = newton_euler_forces(model, k.bodies, joint_coordinates, k.t, k.q, k.v, k.qdot)
    return joint_space_system(k, mass, forces)


@formalism
class MinimalOde(Formalism):
    name = "minimal-ode"
    summary = "Joint coordinates of the spanning tree, mass matrix M(q), O(n^3) (book 10.5)"
    Options = MinimalOptions
    capabilities = frozenset(
        {"planar", "spatial", "closed-loops", "rheonomic", "point-masses", "nonholonomic"}
    ) | {"contacts"}  # the contact form comes from build_equations

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        options = cls.parse_options(options)
        if options.loops == "state-space":
            return {"ode": 0, "dae": 0, "mechanical": 0}
        return constrained_forms(options)

    def build(self, model: Model, options: Any = None) -> Equations:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        kinematics = TreeKinematics(model)
        system = minimal_mechanical_system(model, kinematics)
        if options.loops == "state-space" and system.n_constraints:
            return state_space_equations(self.name, model, kinematics, system, options)
        ode = system.n_constraints == 0 or options.index == 1
        return build_joint_space_equations(self.name, model, kinematics, system, options, ode)


def independent_partition(model: Model, kinematics: TreeKinematics) -> np.ndarray:
    """Indices of the dependent velocities, by pivoted QR of W where ``describe`` takes the
    rank (the model's initial configuration, assembled)."""
    from workbench.mechanics.topology import analyze

    topology = analyze(model)
    if model.nonholonomic:
        raise ModelError(
            f"minimal-ode loops='state-space' handles holonomic loops only (model {model.name!r} "
            "has nonholonomic constraints); use nonholonomic-projection"
        )
    w_function = kinematics.function("W", [kinematics.velocity_constraint_matrix])
    w_matrix = w_function(0.0, topology.configuration, np.zeros(kinematics.nv))
    w_matrix = np.atleast_2d(np.asarray(w_matrix))
    scalar = [i for i in range(kinematics.nv) if _is_scalar_velocity(kinematics, i)]
    columns = independent_columns(w_matrix[:, scalar])
    if columns.size < w_matrix.shape[0]:
        raise ModelError(
            f"minimal-ode loops='state-space': model {model.name!r} has redundant closure "
            "constraints or too few one-coordinate joints to solve for; use loops='dae'"
        )
    return np.sort(np.asarray(scalar)[columns])


def _is_scalar_velocity(kinematics: TreeKinematics, index: int) -> bool:
    """True if velocity ``index`` belongs to a joint with q' = v (Newton may move its q)."""
    for joint in kinematics.free_joints:
        q_slice, v_slice = kinematics.joint_slices[joint.name]
        if v_slice.start <= index < v_slice.stop:
            return joint.type not in ("spherical", "free")
    return False


def state_space_equations(
    name: str,
    model: Model,
    kinematics: TreeKinematics,
    system: MechanicalSystem,
    options: Any = None,
) -> Equations:
    """Minimal form by coordinate partitioning (see the module docstring)."""
    k = kinematics
    dependent = independent_partition(model, k)
    independent = np.setdiff1d(np.arange(k.nv), dependent)
    q_of_v = {}  # velocity index -> coordinate index, for scalar joints
    for joint in k.free_joints:
        q_slice, v_slice = k.joint_slices[joint.name]
        if joint.type not in ("spherical", "free"):
            for offset in range(v_slice.stop - v_slice.start):
                q_of_v[v_slice.start + offset] = q_slice.start + offset
    q_dependent = [q_of_v[i] for i in dependent]
    # Newton on the dependent coordinates, parameters (t, q)
    q_d_sym = ca.SX.sym("q_d", len(q_dependent))
    q_sub = ca.vertcat(
        *[q_d_sym[q_dependent.index(i)] if i in q_dependent else k.q[i] for i in range(k.nq)]
    )
    closure = ca.substitute(k.closure_constraints, k.q, q_sub)
    residual = ca.Function("closure", [q_d_sym, ca.vertcat(k.t, k.q)], [closure])
    solver = ca.rootfinder(  # named in its errors: what failed, in words
        "state_space_dependent_coordinates", "newton", residual,
        {"error_on_fail": True, "abstol": 1e-13, "max_iter": 50},
    )
    t, q, s = ca.MX.sym("t"), ca.MX.sym("q", k.nq), ca.MX.sym("s", len(independent))
    q_solved = solver(q[q_dependent], ca.vertcat(t, q))
    q_star = ca.vertcat(
        *[q_solved[q_dependent.index(i)] if i in q_dependent else q[i] for i in range(k.nq)]
    )
    w_matrix = ca.Function(
        "W", [k.t, k.q], [k.velocity_constraint_matrix, k.velocity_constraint_bias]
    )(t, q_star)
    w_all, w_bias = w_matrix
    w_i, w_d = w_all[:, list(independent)], w_all[:, list(dependent)]
    # v = F s + f with F = P [I; -W_d^-1 W_i], f = P [0; -W_d^-1 w]
    selection_i = ca.DM.zeros(k.nv, len(independent))
    selection_d = ca.DM.zeros(k.nv, len(dependent))
    for column, row in enumerate(independent):
        selection_i[int(row), column] = 1.0
    for column, row in enumerate(dependent):
        selection_d[int(row), column] = 1.0
    f_matrix = selection_i - ca.mtimes(selection_d, ca.solve(w_d, w_i))
    f_bias = -ca.mtimes(selection_d, ca.solve(w_d, w_bias))
    v_full = ca.mtimes(f_matrix, s) + f_bias
    mass = ca.Function("M", [k.t, k.q], [system.mass])(t, q_star)
    forces, qdot = ca.Function("Q", [k.t, k.q, k.v], [system.forces, k.qdot])(t, q_star, v_full)
    # c: the part of v' not proportional to s', from W v' = gamma
    gamma = ca.Function("gamma", [k.t, k.q, k.v], [_gamma(system)])(t, q_star, v_full)
    correction = ca.mtimes(selection_d, ca.solve(w_d, gamma))
    reduced = MechanicalSystem(
        t=t,
        q=q,
        v=s,
        qdot=qdot,
        mass=ca.mtimes([f_matrix.T, mass, f_matrix]),
        forces=ca.mtimes(f_matrix.T, forces - ca.mtimes(mass, correction)),
        q_names=k.q_names,
        v_names=[k.v_names[i] for i in independent],
    )
    body_function = ca.Function(
        "bodies",
        [k.t, k.q, k.v],
        [
            e
            for b in model.bodies
            for e in (
                k.bodies[b].position,
                k.bodies[b].rotation,
                k.bodies[b].velocity,
                k.bodies[b].angular_velocity,
            )
        ],
    )
    values = body_function(t, q_star, v_full)
    from workbench.mechanics.kinematics import BodyState

    bodies = {b: BodyState(*values[4 * i : 4 * i + 4]) for i, b in enumerate(model.bodies)}
    joint_coordinates = {
        j.name: ca.Function("qj", [k.t, k.q], [k.joint_coordinates(j)[0]])(t, q_star)
        for j in model.tree_joints
    }
    names = ", ".join(k.v_names[i] for i in independent)
    equations = build_equations(
        name,
        model,
        reduced,
        bodies,
        ([k.t, k.q, k.v], [k.q, k.v[list(independent)]]),
        joint_coordinates=joint_coordinates,
        notes=[f"state-space: independent velocities {names} (coordinate partitioning)"],
        compiler=Compiler.from_options(options),
    )
    # the closure on the state's own q, for the branch audit: the observables' residuals
    # are taken at the Newton-solved q and vanish whatever the state (the audit followed
    # them and saw every run leave its branch)
    g = k.closure_constraints
    equations.position_closure = ca.Function("g_and_g_q", [k.t, k.q], [g, ca.jacobian(g, k.q)])
    return equations


def _gamma(system: MechanicalSystem) -> Any:
    from workbench.equations import constraint_acceleration_rhs

    return constraint_acceleration_rhs(system)
