"""States and motions shared by the conformance checks, computed in joint space so that
every formalism is evaluated at the same physical state.

* :func:`random_joint_states`: consistent (t, q_joint, v_joint): the problem's initial
  condition perturbed at random, then projected onto the loop-closure and nonholonomic
  constraints (the projection the runner uses for initial states);
* :func:`formalism_state`: such a state in a formalism's coordinates, with v', lambda, q';
* :func:`body_accelerations`: the time derivative of every body's twist, exact through
  CasADi from the formalism's own kinematics and accelerations;
* :func:`tight_run`: a short tight-tolerance integration of the ode form.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations import Equations
from workbench.equations.initial import InitialState, accelerations, project_joint_state
from workbench.errors import WorkbenchError
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values

QUATERNION_JOINTS = ("spherical", "free")


def _normalize(kinematics: TreeKinematics, q: np.ndarray) -> np.ndarray:
    q = q.copy()
    for joint in kinematics.free_joints:
        if joint.type in QUATERNION_JOINTS:
            q_slice, _ = kinematics.joint_slices[joint.name]
            part = slice(q_slice.stop - 4, q_slice.stop)
            q[part] /= np.linalg.norm(q[part])
    return q


def random_joint_states(
    problem: Any, n: int, seed: int = 0, spread: float = 0.3
) -> Iterator[tuple[float, np.ndarray, np.ndarray]]:
    """``n`` consistent joint states (t, q_joint, v_joint); the first is the initial one.

    A perturbation that cannot be projected onto the constraints is retried smaller.
    """
    model = problem.model()
    kinematics = TreeKinematics(model)
    rng = np.random.default_rng(seed)
    t0 = float(problem.t_start)
    q0 = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    v0 = initial_joint_values(model, kinematics, problem.initial_joint_velocities(), True)
    for i in range(n):
        scale = spread if i else 0.0
        for _ in range(4):
            t = t0 + (0.1 * rng.uniform() if i else 0.0)
            q = _normalize(kinematics, q0 + scale * rng.standard_normal(q0.size))
            v = v0 + scale * (1.0 + np.abs(v0)) * rng.standard_normal(v0.size)
            try:
                q, v = project_joint_state(kinematics, problem, t, q, v)
                break
            except WorkbenchError:
                scale /= 4
        else:
            continue
        yield t, q, v


def formalism_state(
    equations: Equations, t: float, q_joint: np.ndarray, v_joint: np.ndarray
) -> InitialState:
    """The joint state (t, q_joint, v_joint) in the coordinates of ``equations``."""
    q, v = (np.ravel(x) for x in equations.joint_space_map(t, q_joint, v_joint))
    acceleration, multipliers, qdot = accelerations(equations, t, q, v)
    return InitialState(t, q, v, qdot, acceleration, multipliers, q_joint, v_joint)


def body_accelerations(equations: Equations, state: InitialState) -> np.ndarray:
    """d/dt of every body's twist (6 n_bodies,) at ``state``, exact through CasADi from the
    formalism's own kinematics (the twist observable) and accelerations."""
    function = getattr(equations, "_twist_rate", None)
    if function is None:  # built once per Equations
        twists = equations.observables.twists.function
        kind = ca.MX if twists.is_a("MXFunction") else ca.SX  # MX: numeric solves inside
        t, q, v = kind.sym("t"), kind.sym("q", equations.nq), kind.sym("v", equations.nv)
        twist = ca.vec(twists(t, q, v))
        qdot, a = kind.sym("qd", equations.nq), kind.sym("a", equations.nv)
        rate = ca.jacobian(twist, q) @ qdot + ca.jacobian(twist, v) @ a + ca.jacobian(twist, t)
        function = ca.Function("twist_rate", [t, q, v, qdot, a], [rate])
        equations._twist_rate = function
    value = function(state.t0, state.q, state.v, state.qdot, state.acceleration)
    return np.asarray(value).ravel()


def observed(equations: Equations, state: InitialState) -> dict[str, np.ndarray]:
    """Poses (n_bodies, 7), twists (n_bodies, 6) and energies [T, V] at ``state``."""
    obs = equations.observables
    t, q, v = state.t0, state.q, state.v
    return {
        "poses": obs.poses(t, q),
        "twists": np.reshape(obs.twists(t, q, v)[0], (6, -1)).T,
        "energy": np.ravel(obs.energy(t, q, v)[0]),
    }


def missing_ode_form(equations: Equations) -> str:
    """Why :func:`tight_run` cannot run ``equations`` (no ode form), or ""."""
    if "ode" in equations.forms:
        return ""
    return (
        f"formalism {equations.formalism!r} built no ode form here (give options that "
        "offer one, e.g. index=1)"
    )


def tight_run(
    equations: Equations,
    state: InitialState,
    t_end: float,
    n: int = 11,
    rtol: float = 1e-10,
    times: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(times, y) of the ode form from ``state`` to ``t_end`` with SciPy's DOP853, at
    ``n`` equally spaced times or at ``times`` (starting at the state's time).

    Raises WorkbenchError if the formalism offers no ode form or the run fails.
    """
    import scipy.integrate

    if missing_ode_form(equations):
        raise WorkbenchError(missing_ode_form(equations))
    rhs = equations.forms["ode"].rhs
    times = np.linspace(state.t0, t_end, n) if times is None else np.asarray(times, float)
    n = times.size
    solution = scipy.integrate.solve_ivp(
        lambda t, y: rhs.into(t, y)[0].copy(),
        (times[0], times[-1]),
        np.concatenate([state.q, state.v]),
        method="DOP853",
        t_eval=times,
        rtol=rtol,
        atol=rtol,
    )
    if not solution.success or solution.y.shape[1] != n:
        raise WorkbenchError(f"tight run failed: {solution.message}")
    return solution.t, solution.y.T


def central_difference(function: Any, x: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d function / dx (m, n) by central differences, relative step ``step``."""
    columns = []
    for i in range(x.size):
        h = step * max(1.0, abs(x[i]))
        plus, minus = x.copy(), x.copy()
        plus[i] += h
        minus[i] -= h
        columns.append((np.ravel(function(plus)) - np.ravel(function(minus))) / (2 * h))
    return np.stack(columns, axis=1) if columns else np.zeros((0, 0))


def energy_scale(energies: np.ndarray) -> float:
    """The energy present in the motion (as in :mod:`workbench.execution.metrics`): T0 + |V0|,
    max T."""
    return max(energies[0, 0] + abs(energies[0, 1]), float(np.max(energies[:, 0])), 1e-300)
