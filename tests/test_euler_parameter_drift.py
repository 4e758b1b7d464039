"""Euler parameters that drift off the unit sphere must not change the motion.

An integrator that does not conserve p^T p (BDF does not) moves the Euler parameters of a
free or spherical joint off the unit sphere. The rotation matrix of such a p used to be
the unit-sphere formula evaluated off the sphere (not a rotation), so the drift fed back
into the dynamics: on the ball rolling on a turntable, IDA on the index-2 (GGL) equations
reached the analytic circle only to 1.6e-6 m at rtol 1e-8 and ran out of steps at 1e-10
(issue 17 item 8). With R(p / |p|) the drift is harmless.

Oracles: the analytic circle of the ball's centre (book 8.3); R(s p) = R(p) for s > 0.
"""

from __future__ import annotations

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.numerics import rotations as rot
from workbench.plugin.registry import get_formalism, get_integrator, get_problem


def test_rotation_of_scaled_euler_parameters_is_the_rotation():
    rng = np.random.default_rng(0)
    for _ in range(20):
        p = rng.normal(size=4)
        unit = p / np.linalg.norm(p)
        for scale in (1 - 1e-6, 1.0, 1.3):
            rotation = np.asarray(rot.quaternion_to_matrix(scale * unit), dtype=float)
            np.testing.assert_allclose(rotation, rot.quaternion_to_matrix(unit), atol=1e-15)
            np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-15)


@pytest.mark.parametrize("formalism", ["absolute-dae", "minimal-ode"])
@pytest.mark.parametrize(("rtol", "bound"), [(1e-8, 1e-7), (1e-10, 1e-8)])
def test_ida_index_2_follows_the_rolling_ball_to_its_tolerance(formalism, rtol, bound):
    problem = get_problem("ball-on-rotating-plane")()
    equations = get_formalism(formalism)().build(problem.model(), {"index": 2})
    assert equations.forms["dae"].index == 2
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()
    trajectory = get_integrator("sundials-ida")().solve(
        equations, state.y0(equations, "dae"), state.yp0(equations, "dae"), times,
        rtol, rtol * 1e-3, {"max_steps": 30_000}, "dae",
    )  # fmt: skip
    assert trajectory.success, trajectory.message
    poses = np.stack([equations.observables.poses(t, y[: equations.nq]) for t, y in
                      zip(times, trajectory.y, strict=True)])  # fmt: skip
    expected = problem.reference().poses(times)
    error = np.max(np.linalg.norm(poses[:, 0, :3] - expected[:, 0, :3], axis=-1))
    assert error < bound, f"{error:.3g} m"
