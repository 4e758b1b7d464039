"""The reference's body poses come from one mapped evaluation, not one call per sample
(issue 18.15: 24 s of a run's 25 s at 10^5 output times), and equal the per-sample poses."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.equations.observables import Observables
from workbench.execution import references
from workbench.plugin import registry

CASES = [  # (problem, formalism, options): planar and spatial, tree, loop, nonholonomic
    ("double-pendulum", "minimal-ode", {"index": 1}),
    ("four-bar", "minimal-ode", {"index": 1}),
    ("heavy-top", "absolute-dae", {"index": 1}),
    ("knife-edge-cart", "nonholonomic-projection", {}),
    ("binary-tree", "recursive", {}),
]


@pytest.mark.parametrize(("name", "formalism", "options"), CASES)
def test_mapped_poses_equal_per_sample_poses(name, formalism, options) -> None:
    problem = registry.get_problem(name)()
    equations = registry.get_formalism(formalism)().build(problem.model(), options)
    q0 = consistent_initial_state(equations, problem).q
    rng = np.random.default_rng(18_15)
    n = 200
    times = np.linspace(problem.t_start, problem.t_end, n)
    q = q0 + 0.05 * rng.standard_normal((n, q0.size))  # near q0, on or off g = 0
    mapped = equations.observables.poses_along(times, q)
    pairs = zip(times, q, strict=True)
    one_by_one = np.stack([equations.observables.poses(t, qk) for t, qk in pairs])
    assert mapped.shape == (n, len(equations.observables.body_names), 7)
    np.testing.assert_allclose(mapped, one_by_one, rtol=0, atol=1e-15)
    # unit quaternions, scalar first and non-negative, as the metrics compare them
    np.testing.assert_allclose(np.linalg.norm(mapped[..., 3:], axis=-1), 1.0, atol=1e-14)
    assert (mapped[..., 3] >= 0).all()


def test_computed_reference_makes_no_call_per_sample(monkeypatch) -> None:
    problem = registry.get_problem("double-pendulum")()
    problem.n_samples = 301
    times = problem.sample_times()
    pipeline = references.configured_pipeline("computed", problem.model())
    expected, bodies, _ = references.solve_poses(problem, pipeline, times, 1e-10, 1e-12)

    def per_sample(*args, **kwargs):
        raise AssertionError("Observables.poses called once per sample")

    monkeypatch.setattr(Observables, "poses", per_sample)
    poses, again, _ = references.solve_poses(problem, pipeline, times, 1e-10, 1e-12)
    assert again == bodies and poses.shape == (301, len(bodies), 7)
    np.testing.assert_array_equal(poses, expected)
    # the poses are the pendulum's: both links hang from the pivot at distances that the
    # motion cannot change (rigid links), so the mapped poses are those of this trajectory
    link_lengths = np.linalg.norm(poses[:, 1, :3] - poses[:, 0, :3], axis=-1)
    np.testing.assert_allclose(link_lengths, link_lengths[0], rtol=1e-12)
