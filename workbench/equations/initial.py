"""Consistent initial states, computed once in joint space for every formalism.

The problem gives the free tree-joint coordinates and velocities. Here they are projected
onto the loop-closure (and contact-height) constraints by Newton's method, keeping the
independent coordinates fixed; the velocities onto W v + w = 0 likewise; then mapped into
the formalism's coordinates by ``Equations.joint_space_map``; the accelerations and
multipliers follow from [M W^T; W 0] [v'; lambda] = [Q; gamma].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from workbench.equations import Equations
from workbench.errors import IntegrationError
from workbench.mechanics.kinematics import (
    TreeKinematics,
    initial_joint_values,
    normalize_quaternions,
)
from workbench.mechanics.newton_euler import mass_and_bias
from workbench.numerics.linalg import gauss_newton, independent_columns, independent_rows


@dataclass
class InitialState:
    """A consistent state at t0 in the formalism's coordinates, and in joint space."""

    t0: float
    q: np.ndarray
    v: np.ndarray
    qdot: np.ndarray
    acceleration: np.ndarray
    multipliers: np.ndarray
    q_joint: np.ndarray
    v_joint: np.ndarray
    acceleration_solve: str = ""  # how v' was solved (:func:`solve_accelerations`)

    def y0(self, equations: Equations, form: str) -> np.ndarray:
        """Initial state vector of ``form`` ([q, v, (lambda), (mu)])."""
        base = np.concatenate([self.q, self.v])
        if form != "dae":
            return base
        n = equations.forms["dae"].n
        extra = np.zeros(n - base.size)
        extra[: min(self.multipliers.size, extra.size)] = self.multipliers[: extra.size]
        return np.concatenate([base, extra])

    def yp0(self, equations: Equations, form: str) -> np.ndarray:
        """Initial derivative of the state vector of ``form``."""
        base = np.concatenate([self.qdot, self.acceleration])
        if form != "dae":
            return base
        return np.concatenate([base, np.zeros(equations.forms["dae"].n - base.size)])


def _independent_columns(kinematics: TreeKinematics, problem: Any, velocities: bool) -> list[int]:
    chosen = getattr(problem, "independent_coordinates", None) or ()
    columns = []
    for joint_name, index in chosen:
        if joint_name not in kinematics.joint_slices:
            raise IntegrationError(
                f"problem {problem.name!r}: independent coordinate {joint_name!r} is not a free "
                "tree joint"
            )
        q_slice, v_slice = kinematics.joint_slices[joint_name]
        for where, part in (("coordinates", q_slice), ("velocities", v_slice)):
            size = part.stop - part.start
            if not 0 <= index < size:  # else it names the next joint's coordinate
                raise IntegrationError(
                    f"problem {problem.name!r}: independent coordinate ({joint_name!r}, "
                    f"{index}) is out of range: joint {joint_name!r} has {size} {where}; "
                    f"give an index from 0 to {size - 1}"
                )
        columns.append((v_slice if velocities else q_slice).start + index)
    return columns


def _held_too_much(kinematics: TreeKinematics, problem: Any, jacobian: np.ndarray,
                   fixed: list[int]) -> str:  # fmt: skip
    """Why the closure cannot be met with the independent coordinates held ("" when they
    are not the reason): without them the closure Jacobian loses rank."""
    free = [c for c in range(jacobian.shape[1]) if c not in fixed]
    rank, left = np.linalg.matrix_rank(jacobian), np.linalg.matrix_rank(jacobian[:, free])
    if not fixed or left >= rank:
        return ""
    chosen = ", ".join(f"{name}[{index}]" for name, index in problem.independent_coordinates)
    return (
        f"; the independent coordinates ({chosen}) are held fixed, and the others can meet "
        f"only {left} of the {rank} independent closure conditions: declare fewer, or ones "
        "the loop does not fix"
    )


def _dependent_columns(jacobian: np.ndarray, fixed: list[int]) -> np.ndarray:
    """Columns to solve for: the best-conditioned ones by pivoted QR, avoiding ``fixed``."""
    n = jacobian.shape[1]
    candidates = np.array([c for c in range(n) if c not in fixed], dtype=int)
    if jacobian.shape[0] == 0 or candidates.size == 0:
        return np.zeros(0, dtype=int)
    return candidates[independent_columns(jacobian[:, candidates], tolerance=1e-10)]


def project_joint_state(
    kinematics: TreeKinematics,
    problem: Any,
    t0: float,
    q: np.ndarray,
    v: np.ndarray,
    tolerance: float = 1e-12,
    max_iterations: int = 50,
) -> tuple[np.ndarray, np.ndarray]:
    """Project (q (nq), v (nv)) onto g(t0, q) = 0 and W v + w = 0, independent ones fixed.

    Positions by :func:`~workbench.numerics.linalg.gauss_newton` in the dependent
    coordinates (chosen by pivoted QR at each iterate, avoiding the problem's
    ``independent_coordinates``) to max |g| <= ``tolerance``; velocities by one
    least-squares solve in the dependent velocities.
    """
    g_function = kinematics.function(
        "closure", [kinematics.closure_constraints, kinematics.closure_jacobian], with_v=False
    )
    w_function = kinematics.function(
        "velocity", [kinematics.velocity_constraint_matrix, kinematics.velocity_constraint_bias]
    )
    fixed = _independent_columns(kinematics, problem, velocities=False)
    if kinematics.closure_constraints.numel():
        columns = np.zeros(0, dtype=int)  # the dependent coordinates, chosen at each iterate

        def evaluate(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            nonlocal columns
            g, g_q = (np.asarray(x) for x in g_function(t0, q))
            columns = _dependent_columns(g_q, fixed)
            return g.ravel(), g_q[:, columns]

        def update(q: np.ndarray, step: np.ndarray) -> np.ndarray:
            q = q.copy()
            q[columns] += step
            normalize_quaternions(kinematics, q)
            return q

        solution = gauss_newton(evaluate, q, update, tolerance, max_iterations, accept=tolerance)
        if not solution.converged:
            g = solution.residual
            worst = int(np.argmax(np.abs(g)))
            held = _held_too_much(kinematics, problem, np.asarray(g_function(t0, solution.x)[1]),
                                  fixed)  # fmt: skip
            raise IntegrationError(
                f"initial state: the loop-closure constraints could not be satisfied; the largest "
                f"residual is {kinematics.closure_names[worst]} = {g[worst]:.3g}"
                + (held or "; give initial joint coordinates closer to an assembled "
                   "configuration")
            )
        q = solution.x
    v = v.copy()
    if kinematics.velocity_constraints.numel():
        w_matrix, w_bias = (np.asarray(x) for x in w_function(t0, q, v))
        w_matrix, w_bias = np.atleast_2d(w_matrix), w_bias.ravel()
        residual = w_matrix @ v + w_bias
        fixed_v = _independent_columns(kinematics, problem, velocities=True)
        columns = _dependent_columns(w_matrix, fixed_v)
        step, *_ = np.linalg.lstsq(w_matrix[:, columns], -residual, rcond=None)
        v[columns] += step
        left = np.abs(w_matrix @ v + w_bias)
        if left.max(initial=0.0) > 1e-8 * max(1.0, np.abs(v).max(initial=0.0)):
            worst = int(np.argmax(left))
            raise IntegrationError(
                f"initial state: the velocity constraint "
                f"{kinematics.velocity_constraint_names[worst]} cannot be satisfied with the "
                "independent velocities given"
            )
    return q, v


def consistent_initial_state(
    equations: Equations, problem: Any, kinematics: TreeKinematics | None = None
) -> InitialState:
    """The problem's initial condition as a consistent state of ``equations``."""
    model = equations.model
    kinematics = kinematics or TreeKinematics(model)
    t0 = float(problem.t_start)
    q_joint = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    v_joint = initial_joint_values(model, kinematics, problem.initial_joint_velocities(), True)
    normalize_quaternions(kinematics, q_joint)
    q_joint, v_joint = project_joint_state(kinematics, problem, t0, q_joint, v_joint)
    q, v = equations.joint_space_map(t0, q_joint, v_joint)
    q, v = np.ravel(q), np.ravel(v)
    acceleration, multipliers, qdot, method = accelerations_and_method(equations, t0, q, v)
    if method.startswith("least squares") or not np.all(np.isfinite(acceleration)):
        _refuse_undetermined_motion(equations, problem, t0, q)
    return InitialState(t0, q, v, qdot, acceleration, multipliers, q_joint, v_joint, method)


def _refuse_undetermined_motion(equations: Equations, problem: Any, t0: float,
                                q: np.ndarray) -> None:  # fmt: skip
    """Raise when M is singular on the velocities the constraints allow (a massless body
    free to move, two slides along one axis with nothing between them): the accelerations
    are then not determined, and every formalism failed later with a NaN right-hand side or
    a LAPACK message, or gave one of the infinitely many answers. Redundant constraint
    rows alone (a rank-deficient W) pass: those are the least-squares solve's purpose."""
    mech = equations.forms.get("mechanical")
    if mech is None:
        return
    mass = np.atleast_2d(np.asarray(mech.mass(t0, q)[0], dtype=float))
    nv, nc = mass.shape[0], mech.n_constraints
    w_matrix = np.zeros((0, nv))
    if nc:
        w_matrix = np.reshape(np.asarray(mech.velocity_matrix(t0, q)[0], dtype=float), (nc, nv))
    names = motion_without_inertia(mass, w_matrix, equations.v_names)
    if names:
        raise IntegrationError(
            f"problem {problem.name!r}: {singular_mass_finding(names, t0)}; give the bodies "
            "it moves mass (and rotational inertia), or remove the joint that adds no motion"
        )


def motion_without_inertia(mass: np.ndarray, w_matrix: np.ndarray, v_names: list[str]) -> list[str]:
    """The velocities (largest share first, at most six) of a motion that W v = 0 allows
    and M gives no inertia; [] when M is regular on every allowed motion.

    ``mass`` M (nv, nv), ``w_matrix`` W (n_rows, nv) (dependent rows are left out here),
    ``v_names`` (nv). Decided by the smallest singular value of [M W^T; W 0].
    """
    nv = mass.shape[0]
    rows = independent_rows(w_matrix) if w_matrix.shape[0] else []
    w_matrix = w_matrix[rows]
    kkt = np.block([[mass, w_matrix.T], [w_matrix, np.zeros((len(rows), len(rows)))]])
    if kkt.size == 0:  # every joint driven: no motion to determine
        return []
    singular = np.linalg.svd(kkt)
    tolerance = 1e-12 * max(singular.S[0], 1e-300) * kkt.shape[0]
    if singular.S[-1] > tolerance:
        return []
    free = singular.Vh[-1, :nv]  # a velocity the constraints allow and M gives no inertia
    names = [v_names[k] for k in np.argsort(-np.abs(free))
             if abs(free[k]) > 1e-6 * np.abs(free).max()]  # fmt: skip
    return names[:6]


def singular_mass_finding(names: list[str], t0: float) -> str:
    """What a run's error and ``describe`` say of a motion without inertia (``names``)."""
    return (
        f"the mass matrix is singular on the motions the constraints allow at t = {t0:g} s: "
        f"a motion of {', '.join(names)} has no inertia, so the accelerations are not "
        "determined"
    )


def model_motion_without_inertia(model: Any, t: float, q: np.ndarray) -> list[str]:
    """:func:`motion_without_inertia` of ``model`` in its tree's joint coordinates at time
    ``t`` (s) and tree configuration ``q`` (nq), for ``describe``. Only a body without mass
    or with a singular inertia can leave such a motion: other models are not built
    symbolically (that costs minutes on a 10,000-link chain)."""

    def inert(body: Any) -> bool:
        inertia = np.asarray(body.inertia, dtype=float)
        return bool(
            body.mass > 0
            and not body.point_mass
            and np.all(np.isfinite(inertia))
            and np.linalg.eigvalsh(inertia).min() > 0
        )

    if all(inert(body) for body in model.bodies.values()):
        return []
    k = TreeKinematics(model)
    if k.nv == 0:
        return []
    mass, _ = mass_and_bias(model, k.bodies, k.t, k.q, k.v, k.qdot)
    function = k.function("M_W", [mass, k.velocity_constraint_matrix], with_v=False)
    mass_value, w_value = (np.asarray(x, dtype=float) for x in function(t, q))
    return motion_without_inertia(
        np.atleast_2d(mass_value), w_value.reshape(-1, k.nv), list(k.v_names)
    )


def accelerations(
    equations: Equations, t: float, q: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(v', lambda, q') at a consistent state, from the mechanical form (or the ode form).

    Solved by :func:`solve_accelerations` (the structure's own factorization; how:
    :func:`accelerations_and_method`).
    """
    acceleration, multipliers, qdot, _ = accelerations_and_method(equations, t, q, v)
    return acceleration, multipliers, qdot


def accelerations_and_method(
    equations: Equations, t: float, q: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """:func:`accelerations` and how they were solved (:func:`solve_accelerations`)."""
    if "mechanical" in equations.forms:
        mech = equations.forms["mechanical"]
        (mass,) = mech.mass(t, q)
        (forces,) = mech.forces(t, q, v)
        (qdot,) = mech.qdot(t, q, v)
        nc = mech.n_constraints
        w_matrix = np.zeros((0, v.size))
        gamma = np.zeros(0)
        if nc:
            (w_matrix,) = mech.velocity_matrix(t, q)
            (gamma,) = mech.acceleration_rhs(t, q, v)
            w_matrix = np.reshape(np.asarray(w_matrix, dtype=float), (nc, -1))
        acceleration, multipliers, method = solve_accelerations(
            np.atleast_2d(np.asarray(mass, dtype=float)), np.ravel(forces), w_matrix,
            np.ravel(gamma))  # fmt: skip
        return acceleration, multipliers, np.ravel(qdot), method
    (f,) = equations.forms["ode"].rhs(t, np.concatenate([q, v]))
    f = np.ravel(f)
    return f[q.size :], np.zeros(0), f[: q.size], "ode right-hand side"


def solve_accelerations(
    mass: np.ndarray, forces: np.ndarray, w_matrix: np.ndarray, gamma: np.ndarray
) -> tuple[np.ndarray, np.ndarray, str]:
    """(v' (nv), lambda (nc), method) of [M W^T; W 0] [v'; lambda] = [Q; gamma].

    The factorization matches the structure: Cholesky of M (SPD) and of the Schur
    complement W M^-1 W^T when W has full row rank; LU of M, or of the whole KKT matrix,
    when M is not SPD but the system is regular; least squares (minimum norm) only when
    the system is rank-deficient (redundant constraint rows), which ``method`` then says.
    A least-squares solve of a regular system loses 1.5-2 digits and breaks the exact
    symmetry of a symmetric motion.
    """
    nc, nv = w_matrix.shape[0], mass.shape[0]
    try:
        factor = scipy.linalg.cho_factor(mass)
    except (np.linalg.LinAlgError, ValueError):
        factor = None
    full_rank = nc == 0 or len(independent_rows(w_matrix)) == nc
    if factor is not None and full_rank:
        if nc == 0:
            return scipy.linalg.cho_solve(factor, forces), np.zeros(0), "cholesky of M"
        m_inv_wt = scipy.linalg.cho_solve(factor, w_matrix.T)  # M^-1 W^T (nv, nc)
        m_inv_q = scipy.linalg.cho_solve(factor, forces)
        schur = w_matrix @ m_inv_wt
        schur = (schur + schur.T) / 2  # symmetric to the last bit
        try:
            multipliers = scipy.linalg.cho_solve(
                scipy.linalg.cho_factor(schur), w_matrix @ m_inv_q - gamma
            )
        except np.linalg.LinAlgError:
            pass  # W M^-1 W^T numerically singular: the KKT solve below
        else:
            return m_inv_q - m_inv_wt @ multipliers, multipliers, "cholesky of M and W M^-1 W^T"
    kkt = np.block([[mass, w_matrix.T], [w_matrix, np.zeros((nc, nc))]])
    rhs = np.concatenate([forces, gamma])
    if full_rank:
        lu, pivots = scipy.linalg.lu_factor(kkt, check_finite=True)
        if np.min(np.abs(np.diag(lu))) > 1e-13 * np.max(np.abs(np.diag(lu))):
            solution = scipy.linalg.lu_solve((lu, pivots), rhs)
            return solution[:nv], solution[nv:], "LU of the KKT matrix"
    solution, _, rank, _ = np.linalg.lstsq(kkt, rhs, rcond=None)
    return (
        solution[:nv],
        solution[nv:],
        f"least squares: the KKT matrix is rank-deficient (rank {rank} of {nv + nc}; "
        f"W has {len(independent_rows(w_matrix))} independent rows of {nc})",
    )


__all__ = [
    "InitialState",
    "accelerations",
    "accelerations_and_method",
    "consistent_initial_state",
    "project_joint_state",
    "solve_accelerations",
]
