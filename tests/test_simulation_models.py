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
