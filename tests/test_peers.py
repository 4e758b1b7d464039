"""The peers of benchmarks/peers.py model the same mechanism: our recursive formalism's
accelerations equal Pinocchio's ``aba`` and MuJoCo's ``mj_forward`` at random states.
(Pinocchio and MuJoCo are in the ``test`` and ``bench`` extras, so CI runs these tests.)"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from benchmarks.peer_models import mujoco_model, pinocchio_model
from benchmarks.peers import random_states
from workbench.plugin.registry import get_formalism, get_problem

CASES = [("spatial-chain", {"n_links": 5}), ("planar-chain", {"n_links": 4}), ("binary-tree", {})]


@functools.cache
def recursive_rhs(problem: str, options: tuple):
    model = get_problem(problem)(dict(options)).model()
    return model, get_formalism("recursive")().build(model).forms["ode"].rhs


def our_accelerations(problem: str, options: dict, states: int = 4):
    model, rhs = recursive_rhs(problem, tuple(options.items()))
    n = rhs.function.size1_in(1) // 2
    rng = np.random.default_rng(7)
    for _ in range(states):
        q, v = rng.uniform(-2, 2, n), rng.uniform(-3, 3, n)
        (f,) = rhs(0.0, np.concatenate([q, v]))
        yield model, q, v, f[n:]


@pytest.mark.parametrize(("problem", "options"), CASES)
def test_recursive_equals_pinocchio_aba(problem, options):
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    for model, q, v, accelerations in our_accelerations(problem, options):
        pin_model, order = pinocchio_model(model)
        expected = pin.aba(pin_model, pin_model.createData(), q[order], v[order], np.zeros(q.size))
        scale = np.abs(expected).max()
        assert scale > 1.0
        np.testing.assert_allclose(accelerations[order], expected, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize(("problem", "options"), CASES)
def test_recursive_equals_mujoco_forward(problem, options):
    mujoco = pytest.importorskip("mujoco", reason="MuJoCo is in the test extra")
    for model, q, v, accelerations in our_accelerations(problem, options):
        mj_model, order = mujoco_model(model)
        data = mujoco.MjData(mj_model)
        data.qpos[:], data.qvel[:] = q[order], v[order]
        mujoco.mj_forward(mj_model, data)
        scale = np.abs(data.qacc).max()
        np.testing.assert_allclose(accelerations[order], data.qacc, rtol=0, atol=1e-9 * scale)


def test_pinocchio_mass_matrix_equals_ours_on_a_tree():
    """pin.crba (upper triangle) equals our M on the binary tree, whose breadth-first and
    depth-first joint orders differ: Pinocchio's CRBA needs contiguous subtrees."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    from benchmarks.peer_models import depth_first
    from workbench.mechanics.kinematics import TreeKinematics

    model = get_problem("binary-tree")().model()
    kinematics = TreeKinematics(model)
    assert [j.name for j in depth_first(kinematics)] != [j.name for j in kinematics.order]
    mass = get_formalism("minimal-ode")().build(model).forms["mechanical"].mass
    pin_model, order = pinocchio_model(model)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = rng.uniform(-2, 2, kinematics.nq)
        (ours,) = mass(0.0, q)
        upper = pin.crba(pin_model, pin_model.createData(), q[order])
        theirs = np.triu(upper) + np.triu(upper, 1).T
        expected = np.asarray(ours)[np.ix_(order, order)]
        np.testing.assert_allclose(theirs, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_peer_models_refuse_what_they_cannot_represent():
    model = get_problem("slider-crank")().model()
    with pytest.raises(ValueError, match="trees of free revolute joints only"):
        pinocchio_model(model)


@pytest.mark.parametrize("n, seed", [(6, 1), (12, 2)])
def test_recursive_equals_pinocchio_on_random_trees(n: int, seed: int) -> None:
    """Revolute, prismatic and spherical joints on a free base, rotated joint frames,
    unaligned axes and full inertias: our ABA (in joint frames chosen at build time), RNEA
    and CRBA equal pin.aba and pin.crba, and FD(ID(a)) = a."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    from benchmarks.peer_models import random_tree
    from workbench.mechanics.kinematics import TreeKinematics
    from workbench.plugins.formalisms import recursive

    model = random_tree(n, seed)
    kinematics = TreeKinematics(model)
    assert {j.type for j in model.tree_joints} == {"free", "revolute", "prismatic", "spherical"}
    pin_model, peer = pinocchio_model(model, general=True)
    data = pin_model.createData()
    equations = get_formalism("recursive")().build(model)
    mass = equations.forms["mechanical"].mass
    rng = np.random.default_rng(seed + 1)  # the accelerations of the round trip
    for q, v in random_states(kinematics, 3, seed):
        (f,) = equations.forms["ode"].rhs(0.0, np.concatenate([q, v]))
        q_pin, v_pin = peer.state(q, v)
        a_pin = pin.aba(pin_model, data, q_pin, v_pin, np.zeros(kinematics.nv))
        expected = peer.accelerations(a_pin, q, v)
        scale = np.abs(expected).max()
        assert scale > 1.0
        np.testing.assert_allclose(f[kinematics.nq :], expected, rtol=0, atol=1e-9 * scale)
        # M: ours by CRBA in joint frames; Pinocchio's maps as M_pin = T M T^T
        (ours,) = mass(0.0, q)
        t_matrix = np.column_stack([peer.state(q, e)[1] for e in np.eye(kinematics.nv)])
        upper = pin.crba(pin_model, data, q_pin)
        theirs = np.triu(upper) + np.triu(upper, 1).T
        expected_mass = t_matrix @ np.asarray(ours) @ t_matrix.T
        np.testing.assert_allclose(theirs, expected_mass, atol=1e-10 * np.abs(theirs).max())
        # inverse then forward dynamics
        a = rng.uniform(-2, 2, kinematics.nv)
        tau = recursive.inverse_dynamics(model, q, v, a)
        np.testing.assert_allclose(recursive.forward_dynamics(model, q, v, tau), a, atol=1e-9)
