"""The Euler-Poinsot closed form of the torque-free asymmetric gyro (book 4.8.1) as an
oracle: body rates by Jacobi elliptic functions against Euler's equations and a workbench
run; the orientation (one quadrature) against the stored reference."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from workbench.equations.initial import consistent_initial_state
from workbench.execution.references import Pipeline, given_reference, solve_poses
from workbench.numerics.geometry import rotation_angle
from workbench.numerics.rotations import quaternion_to_matrix
from workbench.plugin.registry import get_formalism, get_problem
from workbench.problems.ch4_gyros import (
    ASYMMETRIC_INERTIA,
    ASYMMETRIC_OMEGA,
    torque_free_body_rates,
    torque_free_quaternions,
)

TIMES = np.linspace(0.0, 5.0, 51)


def euler_equations(inertia: np.ndarray):
    i1, i2, i3 = inertia
    return lambda t, w: [
        (i2 - i3) * w[1] * w[2] / i1,
        (i3 - i1) * w[2] * w[0] / i2,
        (i1 - i2) * w[0] * w[1] / i3,
    ]


@pytest.mark.parametrize(
    "omega0",
    [
        ASYMMETRIC_OMEGA,  # near the intermediate axis, M^2 > 2T I2
        (0.2, 6.0, -0.2),
        (-3.0, -0.5, 0.2),  # about the smallest axis, M^2 < 2T I2
        (0.3, -1.0, 4.0),  # about the largest axis
        (0.0, 0.0, 5.0),  # steady spin
    ],
)
def test_body_rates_solve_eulers_equations(omega0) -> None:
    inertia = np.array(ASYMMETRIC_INERTIA)
    solution = solve_ivp(
        euler_equations(inertia),
        (0.0, TIMES[-1]),
        omega0,
        method="DOP853",
        t_eval=TIMES,
        rtol=1e-12,
        atol=1e-12,
    )
    closed = torque_free_body_rates(TIMES, ASYMMETRIC_INERTIA, omega0)
    assert np.allclose(closed[0], omega0, atol=1e-12)
    assert np.abs(solution.y.T - closed).max() < 1e-9 * max(1.0, np.abs(omega0).max())


def test_body_rates_of_a_workbench_run() -> None:
    problem = get_problem("torque-free-gyro")()
    equations = get_formalism("minimal-ode")().build(problem.model(), {"index": 1})
    state = consistent_initial_state(equations, problem)
    ode = equations.forms["ode"]
    solution = solve_ivp(
        lambda t, y: ode.rhs(t, y)[0],
        (0.0, TIMES[-1]),
        state.y0(equations, "ode"),
        method="DOP853",
        t_eval=TIMES,
        rtol=1e-11,
        atol=1e-12,
    )
    nq = equations.nq
    rates = []
    for t, y in zip(TIMES, solution.y.T, strict=True):
        (twists,) = equations.observables.twists(t, y[:nq], y[nq:])
        omega = np.reshape(twists, (-1, 6)) if twists.ndim == 1 else twists.T
        rotation = quaternion_to_matrix(equations.observables.poses(t, y[:nq])[0, 3:])
        rates.append(rotation.T @ omega[0, 3:])  # inertial -> body frame
    closed = torque_free_body_rates(TIMES, ASYMMETRIC_INERTIA, ASYMMETRIC_OMEGA)
    assert np.abs(np.array(rates) - closed).max() < 1e-7  # of 6 rad/s


def test_orientation_agrees_with_the_stored_reference() -> None:
    problem = get_problem("torque-free-gyro")()
    reference = given_reference(problem)
    assert reference is not None and reference.kind == "stored"
    times = problem.sample_times()[::10]
    closed = torque_free_quaternions(times, ASYMMETRIC_INERTIA, ASYMMETRIC_OMEGA, [1, 0, 0, 0])
    stored = reference.poses(times)[:, 0, 3:]
    assert rotation_angle(closed, stored).max() < 1e-8


def test_orientation_from_a_tilted_start() -> None:
    """R(0) = R(q0) and the motion is that of a tight run started there."""
    problem = get_problem("torque-free-gyro")()
    q0 = np.array([np.cos(0.4), np.sin(0.4) * 0.6, 0.0, np.sin(0.4) * 0.8])
    problem.initial_joint_coordinates = lambda: {"pivot": q0}
    times = TIMES[:21]
    joint_pipeline = Pipeline("minimal-ode", {"index": 1}, "scipy-dop853")
    poses, _, _ = solve_poses(problem, joint_pipeline, times, 1e-11, 1e-12)
    closed = torque_free_quaternions(times, ASYMMETRIC_INERTIA, ASYMMETRIC_OMEGA, q0)
    assert rotation_angle(closed[:1], q0[None]).max() < 1e-12
    assert rotation_angle(closed, poses[:, 0, 3:]).max() < 1e-8


def test_moments_must_be_ascending() -> None:
    with pytest.raises(ValueError, match="ascending"):
        torque_free_body_rates(TIMES, (0.03, 0.02, 0.04), ASYMMETRIC_OMEGA)
