"""Contacts beside bilateral constraints (docs/nonsmooth.md): a pendulum whose bob strikes a
wall, in absolute coordinates (a revolute joint's two constraint rows) and in minimal ones
(none), against the impact law's analytic times and energies."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ellipk

from workbench.equations.initial import consistent_initial_state
from workbench.model import Frame, Model
from workbench.plugin import registry
from workbench.plugin.problem import Problem

LENGTH, GRAVITY, RESTITUTION, MASS = 1.0, 9.81, 0.7, 1.0


class PendulumWall(Problem):
    """A point mass (1 kg) on a 1 m massless rod, released from rest horizontal (x > 0),
    strikes a frictionless wall x = 0 (point contact, e = 0.7) at the bottom of each swing:
    impact k leaves it the energy m g L e^(2k) above the bottom, and it swings back up to
    the amplitude theta_k with 1 - cos theta_k = e^(2k), returning after half the period
    T(theta_k) = 4 sqrt(L/g) K(sin^2(theta_k/2))."""

    name = "pendulum-wall"
    t_end = 3.0
    n_samples = 301
    conservative = False

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_point_mass("bob", MASS)
        model.add_joint("pivot", "revolute", "ground", "bob", child_frame=Frame.at(-LENGTH))
        model.add_contact("wall", "bob", plane_normal=(1.0, 0.0, 0.0), restitution=RESTITUTION)
        return model

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        return {"pivot": [0.0]}


def _period(amplitude: float) -> float:
    return 4 * math.sqrt(LENGTH / GRAVITY) * float(ellipk(math.sin(amplitude / 2) ** 2))


def impact_times(t_end: float) -> np.ndarray:
    times = [_period(math.pi / 2) / 4]
    k = 1
    while True:
        amplitude = math.acos(1 - RESTITUTION ** (2 * k))
        times.append(times[-1] + _period(amplitude) / 2)
        if times[-1] > t_end:
            return np.array(times[:-1])
        k += 1


def _run(formalism: str, integrator: str, options: dict | None = None, tolerances=(1e-9, 1e-12)):
    problem = PendulumWall()
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()
    trajectory = registry.get_integrator(integrator)().solve(
        equations, state.y0(equations, "mechanical"), None, times, *tolerances, options
    )
    assert trajectory.success, trajectory.message
    nq = equations.nq
    sampled = equations.observables.along(
        trajectory.times, trajectory.y[:, :nq], trajectory.y[:, nq : nq + equations.nv]
    )
    energy = sampled.energy.sum(axis=1) + MASS * GRAVITY * LENGTH  # above the bottom
    drift = float(np.max(np.abs(sampled.residuals[0]), initial=0.0))  # joint positions
    return equations, trajectory, energy, drift


def _energy_law(times: np.ndarray, impacts: np.ndarray) -> np.ndarray:
    k = np.searchsorted(impacts, times, side="right")
    return MASS * GRAVITY * LENGTH * RESTITUTION ** (2 * k)


def _away_from(times: np.ndarray, impacts: np.ndarray, margin: float) -> np.ndarray:
    return np.min(np.abs(times[:, None] - impacts[None, :]), axis=1) > margin


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae", "recursive"])
def test_event_driven_pendulum_strikes_a_wall_by_newtons_law(formalism):
    """Both coordinates give the analytic impact times to 1e-7 s and the energy
    m g L e^(2k) after the k-th impact; the joint stays closed to 1e-8 m."""
    equations, trajectory, energy, drift = _run(formalism, "event-driven")
    impacts = impact_times(PendulumWall.t_end)
    assert impacts.size == 3
    np.testing.assert_allclose(trajectory.contact["event_times"], impacts, atol=1e-7)
    np.testing.assert_allclose(energy, _energy_law(trajectory.times, impacts), atol=1e-6)
    assert drift < 1e-8
    assert equations.n_constraints == (2 if formalism == "absolute-dae" else 0)


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae"])
def test_moreau_jean_pendulum_strikes_a_wall_by_newtons_law(formalism):
    """Moreau-Jean (h = 1e-4 s, first order): impact times to 1e-3 s, the energy between
    impacts to 1 % of the drop's, the joint closed to 1e-10 m by the projection."""
    _, trajectory, energy, drift = _run(formalism, "moreau-jean", {"step": 1e-4})
    impacts = impact_times(PendulumWall.t_end)
    np.testing.assert_allclose(trajectory.contact["event_times"], impacts, atol=1e-3)
    between = _away_from(trajectory.times, impacts, 0.02)
    law = _energy_law(trajectory.times, impacts)
    np.testing.assert_allclose(energy[between], law[between], atol=0.01 * MASS * GRAVITY)
    assert drift < 1e-10


def test_compliant_contact_pendulum_agrees_across_coordinates():
    """Penalty contact beside a joint: its constraint forces are solved with the contact
    force (drift below 1e-8 m), so absolute coordinates give what minimal ones give
    (impact times to 1e-5 s, energies to 1e-4 relative); the rebound is near e^2 (the
    damper's cut-off, no pull, returns a little more: 5 % of the energy here).
    At rtol 1e-8 (drift 5.7e-10 m, impact times 1.6e-9 s and energies 3.9e-8 apart): at
    1e-9, absolute coordinates took 35 s of CPU (Zen 3), minimal ones 2.3 s."""
    tight = (1e-8, 1e-11)
    _, minimal, minimal_energy, _ = _run("minimal-ode", "compliant-contact", None, tight)
    _, absolute, absolute_energy, drift = _run("absolute-dae", "compliant-contact", None, tight)
    assert drift < 1e-8
    np.testing.assert_allclose(absolute.contact["event_times"], minimal.contact["event_times"],
                               atol=1e-5)  # fmt: skip
    np.testing.assert_allclose(absolute_energy, minimal_energy, rtol=1e-4)
    impacts = impact_times(PendulumWall.t_end)
    assert abs(absolute.contact["event_times"][0] - impacts[0]) < 1e-3
    after_first = (absolute.times > impacts[0] + 0.05) & (absolute.times < impacts[1] - 0.05)
    law = MASS * GRAVITY * LENGTH * RESTITUTION**2
    np.testing.assert_allclose(absolute_energy[after_first], law, rtol=0.1)
