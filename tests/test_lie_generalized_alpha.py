"""Lie-group generalized-alpha (Bruls-Cardona-Arnold 2012) and the rotation blocks it reads.

Oracles: SciPy's rotation vectors (exponential map) and finite differences (tangent
operator); a tight DOP853 solution of the heavy top (order 2); the heavy top's invariants
(energy, angular momentum about the vertical, spin about the symmetry axis); |p| = 1 of a
product of unit quaternions.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from workbench.equations.initial import consistent_initial_state
from workbench.errors import PluginError
from workbench.numerics import rotations as rot
from workbench.plugin.registry import get_formalism, get_integrator, get_problem
from workbench.plugins.integrators import lie_generalized_alpha
from workbench.testing import check_integrator
from workbench.testing.integrator import ANALYTIC_PROBLEMS

LIE = "lie-generalized-alpha"


def _skew_part(matrix: np.ndarray) -> np.ndarray:
    return np.array([matrix[2, 1], matrix[0, 2], matrix[1, 0]])


@pytest.mark.parametrize(
    "theta", [[0.3, -1.2, 0.7], [1e-5, -2e-5, 3e-6], [0.0, 0.0, 0.0], [2.5, 1.0, -1.5]]
)
def test_exponential_map_and_tangent_operator_agree_with_scipy(theta: list[float]) -> None:
    theta = np.asarray(theta)
    p = rot.quaternion_exp(theta)
    expected = Rotation.from_rotvec(theta).as_quat(scalar_first=True)
    np.testing.assert_allclose(p, expected, atol=1e-15)
    # exp(theta + e d) = exp(theta) skew(T d) to first order in e
    direction, e = np.array([0.2, 0.5, -0.4]), 1e-6
    matrices = [Rotation.from_rotvec(theta + s * e * direction).as_matrix() for s in (1, -1)]
    derivative = Rotation.from_rotvec(theta).as_matrix().T @ (matrices[0] - matrices[1]) / (2 * e)
    np.testing.assert_allclose(
        rot.tangent_operator(theta) @ direction, _skew_part(derivative), atol=1e-9
    )


@pytest.mark.parametrize("formalism", ["recursive", "minimal-ode", "absolute-dae"])
def test_formalisms_state_their_rotation_blocks(formalism: str) -> None:
    """The heavy top's quaternion and body-frame angular velocity are one rotation block
    (build_equations checks p' = 1/2 p * (0, omega) on it)."""
    equations = get_formalism(formalism)().build(get_problem("heavy-top")().model())
    blocks = equations.forms["mechanical"].rotation_blocks
    assert [q for q, _ in blocks] == equations.quaternion_slices
    assert [(len(range(equations.nq)[q]), len(range(equations.nv)[v])) for q, v in blocks] == [
        (4, 3)
    ]


def test_a_wrong_rotation_block_is_refused() -> None:
    from workbench.equations import build_joint_space_equations
    from workbench.mechanics.kinematics import TreeKinematics
    from workbench.plugins.formalisms.minimal_ode import MinimalOde, minimal_mechanical_system

    model = get_problem("heavy-top")().model()
    kinematics = TreeKinematics(model)
    system = minimal_mechanical_system(model, kinematics)
    system.rotation_blocks = [(slice(0, 4), slice(0, 3))]
    build_joint_space_equations("minimal-ode", model, kinematics, system,
                                MinimalOde.parse_options(None), ode=True)  # fmt: skip
    system.rotation_blocks = [(slice(0, 4), slice(0, 2))]
    with pytest.raises(PluginError, match="rotation block"):
        build_joint_space_equations("minimal-ode", model, kinematics, system,
                                    MinimalOde.parse_options(None), ode=True)  # fmt: skip


def test_refuses_euler_parameters_without_rotation_block() -> None:
    model = get_problem("heavy-top")().model()
    equations = get_formalism("nonholonomic-projection")().build(model)
    assert equations.quaternion_slices and not equations.forms["mechanical"].rotation_blocks
    reason = get_integrator(LIE)().incompatibility(equations, None)
    assert reason and "rotation block" in reason


@pytest.mark.slow  # 12 s CPU
def test_conformance() -> None:
    """The kit's analytic problems, and two more with rotations: the asymmetric torque-free
    gyro (spherical joint) and the ball rolling on a turntable (free joint: rotation block
    and additive translation, nonholonomic and rheonomic rows)."""
    problems = [*ANALYTIC_PROBLEMS, "torque-free-gyro", "ball-on-rotating-plane"]
    check_integrator(LIE, problems).raise_if_failed()


def test_without_rotations_it_is_generalized_alpha() -> None:
    problem = get_problem("slider-crank")()
    equations = get_formalism("minimal-ode")().build(problem.model(), {"index": 3})
    assert equations.forms["mechanical"].rotation_blocks == []
    state = consistent_initial_state(equations, problem)
    lie, vector_space = (_solve(name, equations, state, [0.0, 0.1, 0.2], 1e-6)
                         for name in (LIE, "generalized-alpha"))  # fmt: skip
    np.testing.assert_array_equal(lie.y, vector_space.y)


def _heavy_top(formalism: str = "recursive", t_end: float = 2.0) -> tuple:
    problem = get_problem("heavy-top")()
    equations = get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    times = np.linspace(0.0, t_end, 41)
    return problem, equations, state, times


def _solve(name: str, equations, state, times, rtol: float, options=None):
    trajectory = get_integrator(name)().solve(
        equations, state.y0(equations, "mechanical"), None, times, rtol, rtol, options
    )
    assert trajectory.success, trajectory.message
    return trajectory


def test_order_two_on_the_heavy_top() -> None:
    _, equations, state, _ = _heavy_top()
    rhs = equations.forms["ode"].rhs
    y0 = np.r_[state.q, state.v]
    reference = solve_ivp(lambda t, y: rhs(t, y)[0], (0.0, 0.5), y0, method="DOP853",
                          rtol=1e-13, atol=1e-13).y[: equations.nq, -1]  # fmt: skip
    steps, errors = [4e-3, 2e-3, 1e-3], []
    for step in steps:
        trajectory = _solve(LIE, equations, state, [0.0, 0.5], 1e-6, {"step": step})
        errors.append(np.abs(trajectory.y[-1, : equations.nq] - reference).max())
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 2.0) < 0.3, (slope, errors)


def _invariant_errors(problem, equations, trajectory) -> dict[str, float]:
    nq, nv = equations.nq, equations.nv
    sampled = equations.observables.along(
        trajectory.times, trajectory.y[:, :nq], trajectory.y[:, nq : nq + nv]
    )
    energy = sampled.energy.sum(axis=1)
    errors = {"energy": np.max(np.abs(energy - energy[0])) / abs(energy[0])}
    for invariant in problem.invariants():
        values = invariant.along(equations.model, trajectory.times, sampled.poses, sampled.twists)
        errors[invariant.name] = np.max(np.abs(values - values[0])) / abs(values[0])
    return errors


def _norm_drift(equations, trajectory) -> float:
    part = equations.quaternion_slices[0]
    return float(np.max(np.abs(np.linalg.norm(trajectory.y[:, part], axis=1) - 1.0)))


def test_heavy_top_invariants_and_unit_quaternion_without_projection() -> None:
    """At the step rtol asks for (order 2: 1e-2 s at rtol 1e-4, 1e-3 s at 1e-6) the
    invariants hold to a few rtol and their errors fall as h^2; the spin about the
    symmetry axis (C w3' = 0) is kept to round-off. Measured at rtol 1e-6: energy 1.5e-6,
    vertical angular momentum 1.8e-5 (relative), spin 4e-16; |p| - 1 below 1e-14 where
    generalized-alpha on the same equations drifts 1e-4 (0.1 at rtol 1e-4)."""
    problem, equations, state, times = _heavy_top()
    errors = {}
    for rtol in (1e-4, 1e-6):
        lie = _solve(LIE, equations, state, times, rtol)
        errors[rtol] = _invariant_errors(problem, equations, lie)
        assert _norm_drift(equations, lie) < 1e-13
    assert set(errors[1e-6]) == {"energy", "vertical_angular_momentum", "spin"}
    assert errors[1e-6]["energy"] < 3e-6, errors
    assert errors[1e-6]["vertical_angular_momentum"] < 3e-5, errors
    assert errors[1e-6]["spin"] < 1e-12, errors
    for name in ("energy", "vertical_angular_momentum"):  # order 2: 10x smaller h, 100x
        assert errors[1e-6][name] < errors[1e-4][name] / 50, errors
    # the vector-space method on the same equations leaves the unit sphere
    vector_space = _solve("generalized-alpha", equations, state, times, 1e-6)
    assert _norm_drift(equations, vector_space) > 1e-6


def test_adaptive_steps_stay_on_the_unit_sphere() -> None:
    """The adaptive error estimate compares with a predictor on the group (an additive
    predictor would differ from the step by O(h^2) and shrink it needlessly)."""
    problem, equations, state, times = _heavy_top()
    trajectory = _solve(LIE, equations, state, times, 1e-6, {"adaptive": True})
    assert trajectory.stats.n_steps < 2000  # fewer than the fixed step from rtol 1e-6
    assert _norm_drift(equations, trajectory) < 1e-13
    assert max(_invariant_errors(problem, equations, trajectory).values()) < 1e-4


def test_additive_update_in_place_of_the_exponential_is_caught(monkeypatch) -> None:
    """p_n * (1, h omega / 2), the first-order (additive) update, leaves the sphere."""
    _, equations, state, times = _heavy_top(t_end=0.5)
    monkeypatch.setattr(lie_generalized_alpha, "quaternion_exp",
                        lambda theta: np.concatenate([[1.0], 0.5 * theta]))  # fmt: skip
    trajectory = _solve(LIE, equations, state, times[:11], 1e-6)
    assert _norm_drift(equations, trajectory) > 1e-8
