"""The midpoint variational integrator on systems with a configuration-dependent M(q).

Oracles: order 2 against a tight DOP853 solution (double pendulum in joint angles,
unconstrained; slider-crank with its closure constraint); the constraints held at every
output state; and the property a variational integrator exists for: over 10^4 periods of
the double pendulum its energy error stays bounded, where the explicit midpoint rule
(same order, same step) drifts away.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.test_multibody_integrators import SliderCrankProblem
from workbench.equations.initial import consistent_initial_state
from workbench.plugin.registry import get_formalism, get_integrator
from workbench.plugins.formalisms.minimal_ode import MinimalOde
from workbench.problems.double_pendulum import DoublePendulum

warnings.filterwarnings("ignore", category=FutureWarning)

METHOD = "variational-midpoint"
FAST_PERIOD = 0.8472  # s: the double pendulum's fast normal mode (slow mode: 2.222 s)


class SmallDoublePendulum(DoublePendulum):
    """The catalog's double pendulum released from 0.5 rad: quasi-periodic, not chaotic."""

    name = "test-small-double-pendulum"

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"joint1": 0.5, "joint2": 0.0}


def setup(problem):
    eq3 = MinimalOde().build(problem.model(), {"index": 3})
    state = consistent_initial_state(eq3, problem)
    eq1 = MinimalOde().build(problem.model(), {"index": 1})
    return eq3, eq1, state


def energy(eq, times, y) -> np.ndarray:
    n = eq.nq
    pairs = zip(times, y, strict=True)
    return np.array([eq.observables.energy(t, r[:n], r[n : 2 * n])[0].sum() for t, r in pairs])


@pytest.mark.parametrize("problem", [SmallDoublePendulum, DoublePendulum, SliderCrankProblem])
def test_order_two_against_a_tight_solution(problem) -> None:
    eq3, eq1, state = setup(problem())
    rhs, t_end = eq1.forms["ode"].rhs, 0.5
    reference = solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, t_end),
        np.r_[state.q, state.v],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[: eq3.nq, -1]
    steps, errors = [4e-3, 2e-3, 1e-3], []
    for step in steps:
        result = get_integrator(METHOD)().solve(
            eq3, state.y0(eq3, "mechanical"), None, [0.0, t_end], 1e-6, 1e-6, {"step": step}
        )
        assert result.success, result.message
        errors.append(np.abs(result.y[-1, : eq3.nq] - reference).max())
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 2.0) < 0.2, (slope, errors)


def test_constraints_hold_at_every_output_state() -> None:
    eq3, _, state = setup(SliderCrankProblem())
    mech = eq3.forms["mechanical"]
    result = get_integrator(METHOD)().solve(
        eq3, state.y0(eq3, "mechanical"), None, np.linspace(0, 1, 21), 1e-6, 1e-6, {"step": 2e-3}
    )
    assert result.success, result.message
    for t, y in zip(result.times, result.y, strict=True):
        q, v = y[:3], y[3:6]
        assert np.abs(mech.position_constraints(t, q)[0]).max() < 1e-12
        assert np.abs(mech.velocity_constraints(t, q, v)[0]).max() < 1e-10


@pytest.mark.parametrize(
    "problem, formalism, fragment",
    [
        ("heavy-top", "absolute-dae", "needs q' = v"),
        ("knife-edge-cart", "minimal-ode", "nonholonomic constraints are not handled"),
    ],
)
def test_what_it_cannot_integrate_is_refused_with_the_reason(problem, formalism, fragment):
    from workbench.plugin.registry import get_problem

    model = get_problem(problem)({}).model()
    equations = get_formalism(formalism)().build(model, {"index": 3})
    reason = get_integrator(METHOD)().incompatibility(equations, None)
    assert reason is not None and fragment in reason


@pytest.mark.slow
def test_energy_error_stays_bounded_over_ten_thousand_periods() -> None:
    """10^4 periods of the fast mode (8,472 s) at h = 0.1 s: the variational integrator's
    energy error over the last tenth is no larger than over the first; the explicit
    midpoint rule at the same step leaves any bound (its energy grows without limit)."""
    eq3, eq1, state = setup(SmallDoublePendulum())
    t_end, step = 1e4 * FAST_PERIOD, 0.1
    times = np.linspace(0.0, t_end, 101)
    result = get_integrator(METHOD)().solve(
        eq3, state.y0(eq3, "mechanical"), None, times, 1e-6, 1e-6, {"step": step}
    )
    assert result.success, result.message
    e = energy(eq3, result.times, result.y)
    error = np.abs(e - e[0]) / np.abs(e[0])
    early, late = error[1:11].max(), error[-10:].max()
    assert late <= 1.5 * early and error.max() < 1e-3, (early, late, error.max())

    rhs = eq1.forms["ode"].rhs  # explicit midpoint, by hand: the comparison method
    y, t = np.r_[state.q, state.v], 0.0
    steps_per_sample = round(times[1] / step)
    explicit = [energy(eq3, [0.0], [y])[0]]
    for _ in range(100):
        for _ in range(steps_per_sample):
            k1 = np.ravel(rhs(t, y)[0])
            y = y + step * np.ravel(rhs(t + step / 2, y + step / 2 * k1)[0])
            t += step
        explicit.append(energy(eq3, [t], [y])[0] if np.all(np.isfinite(y)) else np.inf)
        if not np.isfinite(explicit[-1]):
            break
    explicit_error = np.abs(np.array(explicit) - e[0]) / np.abs(e[0])
    assert not explicit_error[-1] <= 100 * error.max(), explicit_error


def test_a_mass_matrix_singular_off_the_constraints_is_integrated_at_order_two() -> None:
    """Point masses in absolute coordinates: M has zero rotational inertia (singular), but
    [M G^T; G 0] is regular. The masses' positions converge at order 2 to those of a tight
    solution in joint angles (another formalism); this raised LinAlgError before."""
    from workbench.plugin.registry import get_problem

    problem = get_problem("double-point-pendulum")({})
    model, t_end = problem.model(), 0.5
    eq_abs = get_formalism("absolute-dae")().build(model, {"index": 3})
    mech = eq_abs.forms["mechanical"]
    (mass,) = mech.mass(0.0, consistent_initial_state(eq_abs, problem).q)
    assert np.linalg.matrix_rank(np.reshape(mass, (eq_abs.nq, eq_abs.nq))) < eq_abs.nq
    eq3, eq1, state = setup(problem)
    rhs = eq1.forms["ode"].rhs
    tight = solve_ivp(lambda t, y: rhs(t, y)[0], (0.0, t_end), np.r_[state.q, state.v],
                      method="DOP853", rtol=1e-13, atol=1e-13).y[: eq3.nq, -1]  # fmt: skip
    expected = eq3.observables.frames(t_end, tight)[0]
    start = consistent_initial_state(eq_abs, problem)
    steps, errors = [4e-3, 2e-3], []
    for step in steps:
        result = get_integrator(METHOD)().solve(
            eq_abs, start.y0(eq_abs, "mechanical"), None, [0.0, t_end], 1e-6, 1e-6, {"step": step}
        )
        assert result.success, result.message
        positions = eq_abs.observables.frames(t_end, result.y[-1, : eq_abs.nq])[0]
        errors.append(np.abs(np.asarray(positions) - np.asarray(expected)).max())
    assert errors[-1] < 1e-4 and 3.0 < errors[0] / errors[1] < 5.0, errors


@pytest.mark.slow  # 5 s CPU
def test_passes_the_integrator_conformance_checks() -> None:
    """The kit's analytic problems are a quaternion gyro and a nonholonomic cart, both
    refused with their reason (skipped); the IFToMM A01 pendulum, exact elliptic-function
    reference, is one it takes."""
    from workbench.testing import check_integrator
    from workbench.testing.integrator import ANALYTIC_PROBLEMS

    report = check_integrator(METHOD, [*ANALYTIC_PROBLEMS, "iftomm-a01"]).raise_if_failed()
    assert [r.status for r in report.results if r.check == "accuracy"] == ["skip", "skip", "pass"]
