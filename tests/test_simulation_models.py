"""The peers of benchmarks/simulation.py model the same mechanisms: on the 7-link chain, the
random 30-body revolute tree (rotated frames, unaligned axes, full inertias) and the UR5
(Pinocchio built from the URDF, MuJoCo from our import), Pinocchio's ``aba`` and MuJoCo's
``mj_forward`` give our recursive formalism's accelerations at random states."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.simulation_models import CASES, TOLERANCE, Peers, case, check_equal
from workbench.plugins.formalisms.recursive import ode_function


@pytest.mark.parametrize("name", CASES)
def test_peers_give_our_accelerations(name: str) -> None:
    pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    pytest.importorskip("mujoco", reason="MuJoCo is in the test extra")
    if name == "ur5":
        pytest.importorskip("workbench.problems.robots", reason="example-robot-data missing")
    bench = case(name)
    function = ode_function(bench.model)
    n = function.size1_in(1) // 2

    def ours(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.asarray(function(0.0, np.concatenate([q, v]))).ravel()[n:]

    peers = Peers(bench)
    assert check_equal(ours, peers, n) <= TOLERANCE
    # the check can fail: a peer whose gravity is off by 1 % is caught
    peers.pin_model.gravity.linear = 1.01 * peers.pin_model.gravity.linear
    with pytest.raises(AssertionError, match="pin.aba differs"):
        check_equal(ours, peers, n)


def test_random_tree_is_general() -> None:
    """Rotated joint frames, unaligned axes and full inertia tensors (what makes it hard)."""
    model = case("tree").model
    joints = list(model.tree_joints)
    assert len(joints) == 30
    assert all(not np.allclose(j.parent_frame.rotation, np.eye(3)) for j in joints)
    assert all(np.count_nonzero(np.abs(j.axis) > 1e-3) == 3 for j in joints)
    assert all(abs(model.bodies[j.child].inertia[0, 1]) > 1e-6 for j in joints)


def test_rhs_clock_sees_every_evaluation_and_changes_nothing() -> None:
    """benchmarks.simulation's split of a DOP853 solve (SciPy's own time against the
    right-hand side's) counts exactly SciPy's evaluations and leaves the solution as it
    is."""
    from scipy.integrate import solve_ivp

    from benchmarks.simulation import RhsClock

    def decay(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([-y[0] + np.sin(t), -2.0 * y[1]])

    arguments = ((0.0, 3.0), np.array([1.0, 2.0]))
    options = {"method": "DOP853", "rtol": 1e-8, "atol": 1e-10}
    plain = solve_ivp(decay, *arguments, **options)
    clock = RhsClock()
    timed = clock.solve_ivp(decay, *arguments, **options)
    own, inside, calls = clock.split()
    assert calls == plain.nfev == timed.nfev
    np.testing.assert_array_equal(timed.y, plain.y)
    assert clock.total > 0 and inside > 0


def test_match_takes_the_loosest_setting_within_the_slack_and_its_counts() -> None:
    """benchmarks.simulation runs each pipeline at the first (loosest) setting of its
    ladder whose end error is within SLACK x the target, keeping that run's (steps, rhs
    calls); a setting that fails is skipped; none within: the last that ran, showing the miss."""
    from benchmarks.simulation import LADDER, SLACK, match

    assert LADDER[0] == 1e-6 and LADDER[-1] == 1e-12 and len(LADDER) == 13  # half decades
    assert all(1 / 3.2 < b / a < 1 / 3.1 for a, b in zip(LADDER, LADDER[1:], strict=False))

    def run(rtol: float) -> tuple:
        if rtol == 1e-6:
            raise RuntimeError("too loose to finish")
        return np.array([rtol * 1e3]), 0.0, (1 / rtol, 2 / rtol)  # end error 1000 rtol

    target = 1.01e-5 / SLACK  # 1e-4 at rtol 1e-7 and 3.16e-5 at 3.16e-8 are above it
    setting, error, counts = match(run, LADDER, lambda final: float(final[0]), target)
    assert setting == 1e-8 and error == pytest.approx(1e-5) and counts == (1e8, 2e8)
    setting, error, _ = match(run, LADDER[:3], lambda final: float(final[0]), target)
    assert setting == 1e-7 and error > SLACK * target
