"""Formalism ``recursive`` (ABA, RNEA, CRBA) against ``minimal-ode`` on random trees."""

from __future__ import annotations

import time

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import (
    AppliedForce,
    Drive,
    Frame,
    JointForce,
    JointSpringDamper,
    Model,
    SpringDamper,
)
from workbench.plugin.registry import get_formalism
from workbench.plugins.formalisms import recursive as rec
from workbench.plugins.formalisms.minimal_ode import minimal_mechanical_system

JOINT_TYPES = ("revolute", "prismatic", "universal", "spherical", "cylindrical", "planar")


def random_frame(rng: np.random.Generator) -> Frame:
    return Frame(rng.uniform(-0.5, 0.5, 3), Rotation.random(random_state=rng).as_matrix())


def random_body(model: Model, name: str, rng: np.random.Generator, point_mass: bool) -> None:
    mass = rng.uniform(0.5, 2.0)
    if point_mass:
        model.add_point_mass(name, mass)
        return
    a, b, c = rng.uniform(0.1, 1.0, 3)  # a box's edges: the principal moments are physical
    moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    rotation = Rotation.random(random_state=rng).as_matrix()
    model.add_body(
        name, mass, com=rng.uniform(-0.3, 0.3, 3), inertia=rotation @ np.diag(moments) @ rotation.T
    )


def random_tree(n: int, seed: int, forces: bool = True, drive: bool = False) -> Model:
    """n bodies: a free joint at the root, random joint types, frames, inertias, parents.

    A point mass rides on a prismatic joint at the end (a point mass on a rotational
    joint would have a singular mass matrix). ``forces``: springs, joint forces and an
    applied force; ``drive``: a driven revolute joint carrying a free universal joint.
    """
    rng = np.random.default_rng(seed)
    model = Model(f"random-tree-{n}-{seed}", kind="spatial")
    random_body(model, "b0", rng, point_mass=False)
    model.add_joint("j0", "free", "ground", "b0", child_frame=random_frame(rng))
    for i in range(1, n):
        kind = JOINT_TYPES[rng.integers(len(JOINT_TYPES))]
        parent = f"b{rng.integers(i)}"
        axis = rng.standard_normal(3)
        axis2 = np.cross(axis, rng.standard_normal(3))
        random_body(model, f"b{i}", rng, point_mass=False)
        model.add_joint(
            f"j{i}",
            kind,
            parent,
            f"b{i}",
            parent_frame=random_frame(rng),
            child_frame=random_frame(rng),
            axis=axis,
            axis2=axis2,
        )
    if n >= 2:
        # a point mass on a prismatic joint: its one DOF has mass, no rotational inertia
        model.add_point_mass("tip", 0.3)
        model.add_joint(
            "j_tip",
            "prismatic",
            f"b{n - 1}",
            "tip",
            parent_frame=random_frame(rng),
            axis=rng.standard_normal(3),
        )
    if forces and n >= 2:
        model.add_force(
            SpringDamper(
                "spring",
                "b0",
                np.array([0.1, 0, 0]),
                f"b{n - 1}",
                np.zeros(3),
                stiffness=20.0,
                damping=0.5,
                rest_length=0.2,
            )
        )
        model.add_force(JointSpringDamper("joint-spring", "j_tip", 5.0, 0.3, rest=0.1))
        model.add_force(JointForce("motor", "j_tip", lambda t, q, v: ca.sin(t) - 0.2 * q))
        model.add_force(
            AppliedForce(
                "push",
                "b1",
                np.array([0.1, 0.2, 0.0]),
                lambda t, r, rot, vel, omega: (
                    ca.vertcat(1.0, -0.5, 0.3 * ca.cos(t)) - 0.1 * vel,
                    ca.vertcat(0.0, 0.2, 0.0) - 0.05 * omega,
                ),
            )
        )
    if drive:
        # drive the last rigid body's joint if it has one coordinate, else add one
        model.add_body("driven", 0.7, com=(0.1, 0.0, 0.0), inertia=(0.01, 0.02, 0.025))
        model.add_joint(
            "j_driven",
            "revolute",
            "b0",
            "driven",
            parent_frame=random_frame(rng),
            axis=rng.standard_normal(3),
            drive=Drive(
                lambda t: 0.5 * ca.sin(2 * t), lambda t: ca.cos(2 * t), lambda t: -2 * ca.sin(2 * t)
            ),
        )
        model.add_body("on-driven", 0.4, com=(0.0, 0.1, 0.0), inertia=(0.01, 0.01, 0.015))
        model.add_joint(
            "j_on_driven",
            "universal",
            "driven",
            "on-driven",
            parent_frame=random_frame(rng),
            axis=(1, 0, 0),
            axis2=(0, 1, 0),
        )
    return model.validate()


def random_state(kinematics: TreeKinematics, rng: np.random.Generator) -> np.ndarray:
    q = rng.uniform(-1.0, 1.0, kinematics.nq)
    for joint in kinematics.free_joints:
        if joint.type in ("spherical", "free"):
            q_slice, _ = kinematics.joint_slices[joint.name]
            p = q[q_slice][-4:]
            q[q_slice.stop - 4 : q_slice.stop] = p / np.linalg.norm(p)
    v = rng.uniform(-1.0, 1.0, kinematics.nv)
    return np.concatenate([q, v])


def minimal_rhs(model: Model) -> ca.Function:
    """minimal-ode's ode right-hand side, [q'; M^-1 (Q - h)] (M solved numerically here)."""
    k = TreeKinematics(model)
    system = minimal_mechanical_system(model, k)
    return ca.Function("minimal", [k.t, k.q, k.v], [system.qdot, system.mass, system.forces])


def minimal_accelerations(function: ca.Function, t: float, q: np.ndarray, v: np.ndarray):
    qdot, mass, forces = (np.asarray(x, dtype=float) for x in function(t, q, v))
    return np.concatenate([qdot.ravel(), np.linalg.solve(mass, forces.ravel())])


def assert_close(actual: np.ndarray, expected: np.ndarray, rtol: float = 1e-9) -> None:
    scale = max(1.0, float(np.max(np.abs(expected))))
    assert np.max(np.abs(actual - expected)) <= rtol * scale, (actual, expected)


@pytest.mark.parametrize("n, seed", [(1, 0), (2, 1), (3, 2), (5, 3), (8, 4), (13, 5)])
def test_recursive_matches_minimal_ode_on_random_trees(n: int, seed: int) -> None:
    model = random_tree(n, seed)
    equations = get_formalism("recursive")().build(model)
    k = TreeKinematics(model)
    minimal = minimal_rhs(model)
    rng = np.random.default_rng(100 + seed)
    for _ in range(3):
        t = float(rng.uniform(0, 2))
        y = random_state(k, rng)
        (rhs,) = equations.forms["ode"].rhs(t, y)
        assert_close(rhs, minimal_accelerations(minimal, t, y[: k.nq], y[k.nq :]))
        # the mechanical form (CRBA, RNEA) gives the same accelerations
        mech = equations.forms["mechanical"]
        (mass,) = mech.mass(t, y[: k.nq])
        (forces,) = mech.forces(t, y[: k.nq], y[k.nq :])
        assert_close(np.linalg.solve(mass, forces), rhs[k.nq :])
        assert np.allclose(mass, mass.T, atol=1e-12)


def test_thirty_body_tree_matches_minimal_ode() -> None:
    model = random_tree(30, 7)
    k = TreeKinematics(model)
    start = time.perf_counter()
    function = rec.ode_function(model)
    assert time.perf_counter() - start < 300  # only a hang: build cost is in benchmarks/scaling.py
    minimal = minimal_rhs(model)
    rng = np.random.default_rng(7)
    for _ in range(2):
        t = float(rng.uniform(0, 2))
        y = random_state(k, rng)
        rhs = np.asarray(function(t, y), dtype=float).ravel()
        assert_close(rhs, minimal_accelerations(minimal, t, y[: k.nq], y[k.nq :]))


def test_free_joints_below_the_root_match_minimal_ode() -> None:
    """The articulated-body algorithm takes a free joint in its local velocities
    [R^T p'; omega] (``LocalVelocities``): a free body hanging from a moving body (not
    the root: its articulated inertia is handed on) and one carrying a child, with joint
    forces on both, against minimal-ode."""
    rng = np.random.default_rng(41)
    model = Model("free-below-root", kind="spatial")
    for name in ("base", "arm", "floating", "tip"):
        random_body(model, name, rng, point_mass=False)
    model.add_joint("j0", "free", "ground", "base", child_frame=random_frame(rng))
    model.add_joint("j1", "revolute", "base", "arm", parent_frame=random_frame(rng),
                    child_frame=random_frame(rng), axis=rng.standard_normal(3))  # fmt: skip
    model.add_joint("j2", "free", "arm", "floating", parent_frame=random_frame(rng),
                    child_frame=random_frame(rng))  # fmt: skip
    model.add_joint("j3", "revolute", "floating", "tip", parent_frame=random_frame(rng),
                    axis=rng.standard_normal(3))  # fmt: skip
    model.add_force(JointForce("push-free", "j2", lambda t, q, v: ca.sin(t) - 0.3 * v))
    model.add_force(JointForce("push-base", "j0", lambda t, q, v: 0.5 - 0.2 * v))
    model.validate()
    equations = get_formalism("recursive")().build(model)
    k = TreeKinematics(model)
    minimal = minimal_rhs(model)
    for _ in range(3):
        t = float(rng.uniform(0, 2))
        y = random_state(k, rng)
        (rhs,) = equations.forms["ode"].rhs(t, y)
        assert_close(rhs, minimal_accelerations(minimal, t, y[: k.nq], y[k.nq :]))


def chain(n: int, kind: str = "spatial") -> Model:
    model = Model(f"chain-{n}", kind=kind)
    parent = "ground"
    for i in range(n):
        model.add_body(f"link{i}", 1.0, com=(0.0, -0.5, 0.0), inertia=(0.09, 0.01, 0.09))
        axis = (0, 0, 1) if kind == "planar" or i % 2 == 0 else (1, 0, 0)
        model.add_joint(
            f"joint{i}",
            "revolute",
            parent,
            f"link{i}",
            parent_frame=Frame.at(0, -1.0 if i else 0.0, 0),
            axis=axis,
        )
        parent = f"link{i}"
    return model.validate()


def test_aba_graph_grows_linearly() -> None:
    """Every further body adds the same number of instructions (no O(n^2) terms)."""
    counts = {n: rec.ode_function(chain(n)).n_instructions() for n in (10, 20, 40)}
    per_body_10_20 = (counts[20] - counts[10]) / 10
    per_body_20_40 = (counts[40] - counts[20]) / 20
    assert per_body_20_40 == pytest.approx(per_body_10_20, rel=0.02), counts


@pytest.mark.parametrize("model", ["chain", "random"])
def test_a_revolute_turn_first_never_costs_instructions(model: str, monkeypatch) -> None:
    """The congruence of a revolute joint turned about z first and then moved by its
    constant placement (:class:`rec.Turn`) costs fewer instructions than the congruence
    through E = R_z^T F where F is sparse (the chain's aligned axes: Talos, Solo12), and
    is not used where F is a general rotation (a random tree's rotated frames, where it
    cost 3 % more: 3,872 -> 3,980 instructions at N = 7). Both give the same v'."""
    built = chain(8) if model == "chain" else random_tree(7, 7, forces=False)
    turned = rec.ode_function(built)
    monkeypatch.setattr(rec, "TURN_MAX_NONZEROS", -1)  # never turn first
    plain = rec.ode_function(built)
    if model == "chain":
        assert turned.n_instructions() < 0.95 * plain.n_instructions()  # 1,526 against 1,679
    else:
        assert turned.n_instructions() <= plain.n_instructions()
    rng = np.random.default_rng(3)
    for _ in range(3):
        y = rng.uniform(-1, 1, turned.nnz_in(1))
        a, b = (np.asarray(f(0.0, y)).ravel() for f in (turned, plain))
        assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(b).max())


def test_unit_column_joints_solve_only_what_is_not_known() -> None:
    """For S with unit columns e_k (a joint in its own frame) U's rows k are D, so
    D^-1 U^T has exact unit columns there (not D^-1 D computed), and a_i's rows k are
    D^-1 (u - U_o^T a'_o) over the other rows: a revolute joint's v' is then equal to the
    general formula D^-1 (u - U^T a') without forming it. With the bias force through the
    centre of mass, the 8-link chain went from 1,526 instructions to 1,441."""
    I_A = ca.SX(ca.DM(np.diag([2.0, 3.0, 4.0, 5.0, 6.0, 7.0]) + 0.1))
    S = rec._unit_columns([2])
    U, u = ca.mtimes(I_A, S), ca.SX.sym("u")
    D_inv_U, D_inv_u = rec._joint_solve(ca.mtimes(S.T, U), U, u, (2,))
    assert D_inv_U[0, 2].is_one() and all(not D_inv_U[0, k].is_one() for k in (0, 1, 3))
    a_prime = ca.SX.sym("a", 6)
    a_rows = D_inv_u - ca.mtimes(D_inv_U[:, [0, 1, 3, 4, 5]], a_prime[[0, 1, 3, 4, 5]])
    a, vdot = rec._unit_joint_accelerations(a_prime, a_rows, (2,))
    general = (u - ca.mtimes(U.T, a_prime)) / ca.mtimes(S.T, U)
    check = ca.Function("check", [u, a_prime], [vdot - general, a - a_prime - S * general])
    rng = np.random.default_rng(2)
    for residual in check(rng.uniform(-1, 1), rng.uniform(-1, 1, 6)):
        assert np.abs(np.asarray(residual)).max() <= 1e-15
    assert rec.ode_function(chain(8)).n_instructions() <= 1_460


def test_joint_frames_fold_the_geometry_into_numbers() -> None:
    """Joint frames chosen at build time keep rotated frames and unaligned axes out of the
    symbolic graph: the 30-body random tree had 53,978 instructions with body frames,
    25,909 in joint frames; a revolute joint's S is the constant e_z."""
    model = random_tree(30, 7, forces=False)
    assert rec.ode_function(model).n_instructions() < 30_000
    tree = rec.SpatialTree(model, TreeKinematics(model))
    revolute = [link for link in tree.links if link.joint.type == "revolute" and link.nv]
    assert revolute and all(rec._unit_rows(link.S) == (2,) for link in revolute)


@pytest.mark.parametrize("n, seed", [(4, 11), (12, 12)])
def test_inverse_then_forward_dynamics_round_trip(n: int, seed: int) -> None:
    model = random_tree(n, seed)
    k = TreeKinematics(model)
    rng = np.random.default_rng(seed)
    y = random_state(k, rng)
    q, v = y[: k.nq], y[k.nq :]
    a = rng.uniform(-2, 2, k.nv)
    tau = rec.inverse_dynamics(model, q, v, a, t=0.4)
    for algorithm in ("aba", "rnea-crba"):
        assert_close(rec.forward_dynamics(model, q, v, tau, t=0.4, algorithm=algorithm), a)
    # the model's own accelerations need no extra joint forces
    free = rec.forward_dynamics(model, q, v, t=0.4)
    assert_close(rec.inverse_dynamics(model, q, v, free, t=0.4), np.zeros(k.nv))


@pytest.mark.parametrize("n, seed", [(3, 21), (7, 22)])
def test_aba_and_rnea_crba_agree(n: int, seed: int) -> None:
    model = random_tree(n, seed, drive=True)
    aba = get_formalism("recursive")().build(model, {"algorithm": "aba"})
    crba = get_formalism("recursive")().build(model, {"algorithm": "rnea-crba"})
    k = TreeKinematics(model)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        t = float(rng.uniform(0, 2))
        y = random_state(k, rng)
        (a1,) = aba.forms["ode"].rhs(t, y)
        (a2,) = crba.forms["ode"].rhs(t, y)
        assert_close(a1, a2)


def test_driven_joint_matches_minimal_ode() -> None:
    model = random_tree(4, 31, drive=True)
    equations = get_formalism("recursive")().build(model)
    k = TreeKinematics(model)
    assert "j_driven" not in k.joint_slices
    minimal = minimal_rhs(model)
    rng = np.random.default_rng(31)
    for _ in range(3):
        t = float(rng.uniform(0, 3))
        y = random_state(k, rng)
        (rhs,) = equations.forms["ode"].rhs(t, y)
        assert_close(rhs, minimal_accelerations(minimal, t, y[: k.nq], y[k.nq :]))


def test_planar_chain_and_closed_loop_match_minimal_ode() -> None:
    from workbench.plugin.registry import get_problem

    for model in (chain(6, "planar"), get_problem("slider-crank")().model()):
        recursive = get_formalism("recursive")().build(model, {"index": 1})
        minimal = get_formalism("minimal-ode")().build(model, {"index": 1})
        k = TreeKinematics(model)
        rng = np.random.default_rng(5)
        y = random_state(k, rng)
        (a1,) = recursive.forms["ode"].rhs(0.2, y)
        (a2,) = minimal.forms["ode"].rhs(0.2, y)
        assert_close(a1, a2)
        assert recursive.forms["dae"].index == (1 if model.cut_joints else 0)


def test_options_and_capabilities() -> None:
    plugin = get_formalism("recursive")
    assert plugin.forms({"index": 2}) == {"ode": 0, "dae": 2, "mechanical": 0}
    assert "nonholonomic" not in plugin.capabilities
    from workbench.errors import ConfigError

    with pytest.raises(ConfigError):
        plugin.parse_options({"algorithm": "featherstone"})
