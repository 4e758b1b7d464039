"""Catalog contact problems with published laws (docs/nonsmooth.md): Housner's rocking
block and the woodpecker toy, through the contact integrators."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.plugin import registry
from workbench.problems.ch5_rocking import HOUSNER_R, SLENDERNESS, rocking_angle
from workbench.problems.woodpecker import cycle_lag


def _run(name: str, formalism: str, integrator: str, rtol: float, **options):
    problem = registry.get_problem(name)()
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()
    method = registry.get_integrator(integrator)()
    trajectory = method.solve(equations, state.y0(equations, "mechanical"), None, times, rtol,
                              rtol * 1e-3, options or None)  # fmt: skip
    assert trajectory.success, trajectory.message
    poses = np.stack([equations.observables.poses(t, y[: equations.nq])
                      for t, y in zip(trajectory.times, trajectory.y, strict=True)])  # fmt: skip
    return problem, equations, trajectory, poses


def test_housner_coefficient_and_reference():
    """r = 1 - 3/2 sin^2(alpha), and the reference's rate at each impact falls by r."""
    assert HOUSNER_R == pytest.approx(1 - 1.5 * 0.1)  # sin^2(atan(1/3)) = 1/10
    problem = registry.get_problem("rocking-block")()
    impacts = problem.contact_events()
    assert impacts.size == 9
    before = rocking_angle(impacts - 1e-9, problem.t_end)[1]
    after = rocking_angle(impacts + 1e-9, problem.t_end)[1]
    np.testing.assert_allclose(after / before, HOUSNER_R, rtol=1e-6)
    # the tilt between impacts stays below alpha (the block never tips over)
    angle, _ = rocking_angle(problem.sample_times(), problem.t_end)
    assert np.max(np.abs(angle)) < SLENDERNESS


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae", "recursive"])
def test_event_driven_block_rocks_as_housner_says(formalism):
    """Newton's law with e = 0 at both corners gives Housner's impact: the impulse at the
    striking corner only, the old one lifts off; impact times, poses and the energy each
    impact takes (1 - r^2 of the kinetic energy) follow the one-DOF rocking equation."""
    problem, _, trajectory, poses = _run("rocking-block", formalism, "event-driven", 1e-10)
    impacts = problem.contact_events()
    events = np.array(trajectory.contact["event_times"])
    assert events.size == impacts.size
    np.testing.assert_allclose(events, impacts, atol=1e-5)  # 8e-7 measured: errors grow
    reference = problem.reference().poses(trajectory.times)
    np.testing.assert_allclose(poses[..., :3], reference[..., :3], atol=1e-6)
    np.testing.assert_allclose(poses[..., 3:], reference[..., 3:], atol=1e-6)
    assert trajectory.contact["penetration_max"] < 1e-9


def test_moreau_jean_block_converges_to_housner():
    """Time-stepping (h = 1e-4 s) at first order: every Housner impact within 0.01 s,
    the poses within 1e-3 m, the energy after the impacts that of the reference."""
    problem, equations, trajectory, poses = _run("rocking-block", "minimal-ode", "moreau-jean",
                                                 1e-6, step=1e-4)  # fmt: skip
    impacts = problem.contact_events()
    events = np.array(trajectory.contact["event_times"])
    nearest = np.min(np.abs(impacts[:, None] - events[None, :]), axis=1)
    assert np.max(nearest) < 1e-2  # 4e-5 s at the first, 4.7e-3 s at the ninth (drift)
    reference = problem.reference().poses(trajectory.times)
    np.testing.assert_allclose(poses[..., :2], reference[..., :2], atol=1e-3)
    nq, energy_of = equations.nq, equations.observables.energy
    energy = np.array([float(np.sum(energy_of(t, y[:nq], y[nq:]))) for t, y in
                       zip(trajectory.times, trajectory.y, strict=True)])  # fmt: skip
    expected = problem.reference_energy(trajectory.times)
    lost, expected_lost = energy[0] - energy[-1], expected[0] - expected[-1]
    assert lost == pytest.approx(expected_lost, rel=0.05)


def test_woodpecker_walks_down_the_pole_in_a_limit_cycle():
    """Moreau-Jean (h = 1e-4 s) on minimal-ode: the events repeat with one period (the
    published initial state lies on the limit cycle), the state at them repeats, the
    sleeve only descends, and over a cycle the energy lost is the potential energy the
    descent released (the motion repeats, so impacts and friction take exactly that)."""
    problem, equations, trajectory, _ = _run("woodpecker", "minimal-ode", "moreau-jean", 1e-6,
                                             step=1e-4)  # fmt: skip
    events = np.array(trajectory.contact["event_times"])
    events = events[events > 0.01]  # the start sits on the lower edge's closing
    per_cycle = 3  # three closings a cycle (measured: 0.0827, 0.1092, 0.1144 s, ...)
    cycles = events.size // per_cycle
    assert cycles >= 3
    grid = events[: cycles * per_cycle].reshape(cycles, per_cycle)
    period = np.diff(grid, axis=0)
    # 0.1292..0.1301 s: the exact-geometry start settles onto its cycle within 1 %
    np.testing.assert_allclose(period, period[0, 0], rtol=0.01)
    assert 0.1 < period[0, 0] < 0.16  # 0.1296 s measured
    # the limit cycle: the state one period later is the same (descent aside)
    times, y = trajectory.times, trajectory.y
    t_a = grid[0, 0] + 0.01
    i, j = np.argmin(np.abs(times - t_a)), np.argmin(np.abs(times - t_a - period[0, 0]))
    scale = np.max(np.abs(y[:, 1:]), axis=0)
    assert np.all(np.abs(y[j, 1:] - y[i, 1:]) <= 0.05 * scale), (y[i], y[j])
    # descends cycle after cycle (within a cycle it may rise by 0.1 mm after the peck)
    descent = y[:, 0]
    at_cycles = [descent[np.argmin(np.abs(times - t))] for t in grid[:, 0] + 0.01]
    assert np.all(np.diff(at_cycles) < -0.005)
    speed = -(descent[j] - descent[i]) / (times[j] - times[i])
    assert 0.05 < speed < 0.2  # 0.103 m/s measured
    # energy balance over one cycle: what is lost is m g (the descent)
    nq, energy_of = equations.nq, equations.observables.energy
    energy = [
        float(np.sum(energy_of(t, s[:nq], s[nq:]))) for t, s in ((times[i], y[i]), (times[j], y[j]))
    ]
    mass = 3.0e-4 + 4.5e-3
    released = mass * 9.81 * (descent[i] - descent[j])
    # measured: 6.396e-4 J lost, 6.403e-4 J released
    assert energy[0] - energy[1] == pytest.approx(released, rel=0.02)
    assert trajectory.contact["complementarity_max"] < 1e-6


@pytest.mark.parametrize(
    ("formalism", "integrator", "options"),
    [("minimal-ode", "event-driven", {}), ("absolute-dae", "event-driven", {}),
     ("recursive", "event-driven", {}), ("absolute-dae", "moreau-jean", {"step": 1e-4})],
)  # fmt: skip
def test_woodpecker_cycle_is_the_same_in_every_pairing(formalism, integrator, options):
    """The other pairings walk the same limit cycle as Moreau-Jean on minimal-ode above:
    the bodies' angles repeat after one period (found as the lag that best repeats them,
    0.1296 s measured), and over that period the energy lost is the potential energy the
    descent released. Event-driven once stopped here at t = 0.059 s, re-firing the sleeve's
    lift-off event (lambda_N = 0 left it closed) until max_events."""
    problem, equations, trajectory, poses = _run("woodpecker", formalism, integrator, 1e-7,
                                                 **options)  # fmt: skip
    times, y = trajectory.times, trajectory.y
    assert times[-1] == pytest.approx(problem.t_end)
    start, lag, mismatch = cycle_lag(times, poses)
    period = times[start + lag] - times[start]
    assert period == pytest.approx(0.1296, rel=0.02)
    assert mismatch < 0.05 * np.max(np.abs(poses[:, 1:, 3:]))  # the orientations repeat
    i, j = start, start + lag
    height = poses[:, 1, 1]  # the sleeve's height
    assert height[j] < height[i] - 0.005  # it walked down
    nq, energy_of = equations.nq, equations.observables.energy
    energy = [float(np.sum(energy_of(times[k], y[k, :nq], y[k, nq : nq + equations.nv])))
              for k in (i, j)]  # fmt: skip
    released = (3.0e-4 + 4.5e-3) * 9.81 * (height[i] - height[j])
    assert energy[0] - energy[1] == pytest.approx(released, rel=0.03)
