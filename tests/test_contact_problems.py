"""Catalog contact problems with published laws (docs/nonsmooth.md): Housner's rocking
block and the woodpecker toy, through the contact integrators."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.plugin import registry
from workbench.problems.ch5_rocking import HOUSNER_R, SLENDERNESS, rocking_angle


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


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae"])
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
