"""HHT-alpha and Newmark: the generalized-alpha family's named presets.

Oracles: the orders the theory gives (2 for HHT and the average-acceleration Newmark rule,
1 for Newmark with gamma > 1/2) against a tight DOP853 solution of the slider-crank, and
the spectral radius at infinity each parameter set is designed to have, measured as the
per-step decay of a stiff linear oscillator at omega h = 1e4 (a wrong parameter mapping
gives another decay rate).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.test_multibody_integrators import SliderCrankProblem
from workbench.equations.initial import consistent_initial_state
from workbench.errors import ConfigError
from workbench.model import Frame, JointSpringDamper, Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import get_integrator
from workbench.plugins.formalisms.minimal_ode import MinimalOde

warnings.filterwarnings("ignore", category=FutureWarning)


@pytest.fixture(scope="module")
def slider_crank():
    problem = SliderCrankProblem()
    eq3 = MinimalOde().build(problem.model(), {"index": 3})
    state = consistent_initial_state(eq3, problem)
    rhs = MinimalOde().build(problem.model(), {"index": 1}).forms["ode"].rhs
    reference = solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, 1.0),
        np.r_[state.q, state.v],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[:3, -1]
    return eq3, state, reference


def fitted_order(slider_crank, name: str, options: dict) -> float:
    eq3, state, reference = slider_crank
    steps, errors = [4e-3, 2e-3, 1e-3, 5e-4], []
    for step in steps:
        result = get_integrator(name)().solve(
            eq3,
            state.y0(eq3, "mechanical"),
            None,
            np.linspace(0.0, 1.0, 11),
            1e-6,
            1e-6,
            options | {"step": step},
        )
        assert result.success, result.message
        errors.append(np.abs(result.y[-1, :3] - reference).max())
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


@pytest.mark.parametrize(
    "name, options, order",
    [
        ("hht-alpha", {"alpha": -0.1}, 2.0),
        ("hht-alpha", {"alpha": -1.0 / 3.0}, 2.0),
        ("newmark", {"gamma": 0.55, "beta": 0.275625}, 1.0),
        ("newmark", {"gamma": 0.6, "beta": 0.3025}, 1.0),
    ],
)
def test_order_of_convergence(slider_crank, name, options, order) -> None:
    slope = fitted_order(slider_crank, name, options)
    assert abs(slope - order) < 0.35, (name, options, slope)


class StiffOscillator(Problem):
    """A unit mass on a spring of stiffness 1e8 N/m (omega = 1e4 rad/s), no gravity."""

    name = "test-stiff-oscillator"

    def model(self) -> Model:
        m = Model("oscillator", kind="planar", gravity=(0.0, 0.0, 0.0))
        m.add_body("mass", 1.0, inertia=1.0)
        m.add_joint("slide", "prismatic", "ground", "mass", axis=(1, 0, 0), parent_frame=Frame())
        m.add_force(JointSpringDamper("spring", "slide", 1e8))
        return m

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"slide": 1e-3}


def measured_spectral_radius(name: str, options: dict) -> float:
    """Per-step decay of (x, v / omega) over steps 100..300 at h = 1 s, omega h = 1e4."""
    problem = StiffOscillator()
    eq = MinimalOde().build(problem.model(), {"index": 3})
    state = consistent_initial_state(eq, problem)
    times = np.arange(301.0)
    result = get_integrator(name)().solve(
        eq, state.y0(eq, "mechanical"), None, times, 1e-6, 1e-6, options | {"step": 1.0}
    )
    assert result.success, result.message
    size = np.hypot(result.y[:, 0], result.y[:, 1] / 1e4)
    return float((size[300] / size[100]) ** (1 / 200))


@pytest.mark.parametrize(
    "name, options, rho",
    [
        ("hht-alpha", {"alpha": -1.0 / 3.0}, 0.5),
        ("hht-alpha", {"alpha": -0.1}, 0.9 / 1.1),
        ("hht-alpha", {"alpha": 0.0}, 1.0),
        ("newmark", {}, 1.0),
        # beta = (gamma + 1/2)^2 / 4: rho_inf = |1 - (gamma + 1/2) / (2 beta)| = 0.9 / 1.1
        ("newmark", {"gamma": 0.6, "beta": 0.3025}, 0.9 / 1.1),
        ("generalized-alpha", {"rho_inf": 0.6}, 0.6),
    ],
)
def test_spectral_radius_at_infinity(name, options, rho) -> None:
    assert measured_spectral_radius(name, options) == pytest.approx(rho, abs=0.02)


@pytest.mark.parametrize(
    "name, options, fragment",
    [
        ("hht-alpha", {"alpha": 0.1}, "alpha must lie in [-1/3, 0]"),
        ("hht-alpha", {"alpha": -0.5}, "alpha must lie in [-1/3, 0]"),
        ("newmark", {"gamma": 0.4}, "gamma must be >= 1/2"),
        ("newmark", {"beta": 0.0}, "beta must lie in (0, 1/2]"),
        ("newmark", {"step": -1.0}, "step must be a positive number"),
    ],
)
def test_bad_parameters_are_refused(name, options, fragment) -> None:
    with pytest.raises(ConfigError, match=fragment.replace("(", r"\(").replace("[", r"\[")):
        get_integrator(name).parse_options(options)


@pytest.mark.slow  # 6 s CPU each
@pytest.mark.parametrize("name", ["hht-alpha", "newmark"])
def test_passes_the_integrator_conformance_checks(name) -> None:
    from workbench.testing import check_integrator

    check_integrator(name).raise_if_failed()
