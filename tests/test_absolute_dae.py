"""Formalism absolute-dae: physics as the oracle on small models built inline.

The models (also used by tests/test_cross_formalism.py) are built by the ``MODELS``
factories; ``consistent_state`` puts random joint-space states on the closure and
nonholonomic constraints.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from workbench.errors import ModelError
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import Drive, Frame, JointForce, KnifeEdge, Model, RollingDisk
from workbench.plugin.registry import get_formalism

# ---- models ---------------------------------------------------------------------------


def point_pendulum() -> Model:
    """Planar point mass (1 kg) on a massless rod of 1 m, pivot at the origin."""
    m = Model("point-pendulum", kind="planar")
    m.add_point_mass("bob", 1.0)
    m.add_joint("pivot", "revolute", "ground", "bob", child_frame=Frame.at(0.0, 1.0, 0.0))
    return m


def double_pendulum() -> Model:
    """Planar double pendulum of two uniform rods (1 kg, 1 m; 0.5 kg, 0.8 m)."""
    m = Model("double-pendulum", kind="planar")
    m.add_body("link1", 1.0, com=(0.5, 0.0, 0.0), inertia=1.0 / 12)
    m.add_body("link2", 0.5, com=(0.4, 0.0, 0.0), inertia=0.5 * 0.64 / 12)
    m.add_joint("j1", "revolute", "ground", "link1")
    m.add_joint("j2", "revolute", "link1", "link2", parent_frame=Frame.at(1.0, 0.0, 0.0))
    return m


def slider_crank() -> Model:
    """Planar slider-crank: crank 0.2 m, rod 0.6 m, slider on the x axis; cut joint rod-slider."""
    m = Model("slider-crank", kind="planar")
    m.add_body("crank", 1.0, com=(0.1, 0.0, 0.0), inertia=0.01)
    m.add_body("rod", 0.8, com=(0.3, 0.0, 0.0), inertia=0.03)
    m.add_body("slider", 0.5, com=(0.0, 0.0, 0.0), inertia=0.002)
    m.add_joint("crank_pivot", "revolute", "ground", "crank")
    m.add_joint("crank_rod", "revolute", "crank", "rod", parent_frame=Frame.at(0.2, 0.0, 0.0))
    m.add_joint("slide", "prismatic", "ground", "slider", axis=(1.0, 0.0, 0.0))
    m.add_joint(
        "rod_slider", "revolute", "rod", "slider", parent_frame=Frame.at(0.6, 0.0, 0.0), cut=True
    )
    return m


def driven_pendulum() -> Model:
    """Planar pendulum hanging from a cart driven along x: x = 0.1 sin(3 t) (rheonomic)."""
    m = Model("driven-pendulum", kind="planar")
    m.add_body("cart", 2.0, inertia=0.1)
    m.add_body("rod", 1.0, com=(0.0, -0.5, 0.0), inertia=1.0 / 12)
    drive = Drive(
        lambda t: 0.1 * ca.sin(3 * t), lambda t: 0.3 * ca.cos(3 * t), lambda t: -0.9 * ca.sin(3 * t)
    )
    m.add_joint("rail", "prismatic", "ground", "cart", axis=(1.0, 0.0, 0.0), drive=drive)
    m.add_joint("hinge", "revolute", "cart", "rod")
    return m


def heavy_top() -> Model:
    """Spatial heavy top on a spherical joint: 1 kg, com 0.1 m up its z axis."""
    m = Model("heavy-top", kind="spatial")
    m.add_body("top", 1.0, com=(0.0, 0.0, 0.1), inertia=(0.004, 0.004, 0.002))
    m.add_joint("tip", "spherical", "ground", "top")
    return m


def chain3() -> Model:
    """Spatial chain: revolute (x), universal (y then x), prismatic (z), with a spring."""
    from workbench.model import JointSpringDamper

    m = Model("chain3", kind="spatial")
    m.add_body("b1", 1.0, com=(0.0, 0.1, -0.25), inertia=(0.02, 0.03, 0.01))
    m.add_body("b2", 0.7, com=(0.05, 0.0, -0.2), inertia=(0.01, 0.012, 0.004))
    m.add_body("b3", 0.4, com=(0.0, 0.0, -0.1), inertia=(0.002, 0.002, 0.001))
    m.add_joint("r1", "revolute", "ground", "b1", axis=(1.0, 0.0, 0.0))
    m.add_joint(
        "u2",
        "universal",
        "b1",
        "b2",
        parent_frame=Frame.at(0.0, 0.0, -0.5),
        axis=(0.0, 1.0, 0.0),
        axis2=(1.0, 0.0, 0.0),
    )
    m.add_joint(
        "p3", "prismatic", "b2", "b3", parent_frame=Frame.at(0.0, 0.0, -0.4), axis=(0.0, 0.0, 1.0)
    )
    m.add_force(JointSpringDamper("p3_spring", "p3", stiffness=50.0, rest=-0.1))
    return m


def rolling_disk() -> Model:
    """Spatial thin disk (radius 0.3 m, 1 kg) rolling without slip on z = 0 (free joint)."""
    m = Model("rolling-disk", kind="spatial")
    m.add_body("disk", 1.0, inertia=(0.0225, 0.045, 0.0225))
    m.add_joint("float", "free", "ground", "disk")
    m.add_nonholonomic(RollingDisk("contact", "disk", radius=0.3, axis=(0.0, 1.0, 0.0)))
    return m


def knife_edge() -> Model:
    """Planar sleigh (Chaplygin): knife edge at the body origin, com 0.2 m ahead."""
    m = Model("knife-edge", kind="planar", gravity=np.zeros(3))
    m.add_body("sleigh", 1.0, com=(0.2, 0.0, 0.0), inertia=0.05)
    m.add_joint("plane", "planar", "ground", "sleigh")
    m.add_nonholonomic(
        KnifeEdge("blade", "sleigh", point=np.zeros(3), direction=np.array([0.0, 1.0, 0.0]))
    )
    return m


def parallel_four_bar() -> Model:
    """A planar four-bar built with spatial revolute joints, all axes along z (overconstrained)."""
    m = Model("parallel-four-bar", kind="spatial")
    inertia = (0.01, 0.01, 0.01)
    m.add_body("crank", 1.0, com=(0.1, 0.0, 0.0), inertia=inertia)
    m.add_body("coupler", 1.0, com=(0.3, 0.0, 0.0), inertia=inertia)
    m.add_body("rocker", 1.0, com=(0.2, 0.0, 0.0), inertia=inertia)
    m.add_joint("j1", "revolute", "ground", "crank")
    m.add_joint("j2", "revolute", "crank", "coupler", parent_frame=Frame.at(0.2, 0.0, 0.0))
    m.add_joint("j3", "revolute", "ground", "rocker", parent_frame=Frame.at(0.5, 0.0, 0.0))
    m.add_joint(
        "j4",
        "revolute",
        "coupler",
        "rocker",
        parent_frame=Frame.at(0.6, 0.0, 0.0),
        child_frame=Frame.at(0.4, 0.0, 0.0),
        cut=True,
    )
    return m


MODELS = {
    "point-pendulum": point_pendulum,
    "double-pendulum": double_pendulum,
    "slider-crank": slider_crank,
    "driven-pendulum": driven_pendulum,
    "heavy-top": heavy_top,
    "chain3": chain3,
    "rolling-disk": rolling_disk,
    "knife-edge": knife_edge,
    "parallel-four-bar": parallel_four_bar,
}
CONSERVATIVE = [
    "point-pendulum",
    "double-pendulum",
    "slider-crank",
    "heavy-top",
    "chain3",
    "rolling-disk",
    "knife-edge",
    "parallel-four-bar",
]
# joint coordinates kept fixed when a random state is pulled onto the closure constraints
FIXED_COORDINATE = {"slider-crank": "crank_pivot", "parallel-four-bar": "j1"}


# ---- consistent joint-space states ----------------------------------------------------


def consistent_state(model: Model, seed: int, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Random tree coordinates and velocities on the closure and velocity constraints.

    q: random, quaternions normalized; then Newton on g(t, q) = 0 (minimum-norm steps,
    the coordinate named in FIXED_COORDINATE held). v: random, then W v + w = 0 by the
    minimum-norm correction.
    """
    rng = np.random.default_rng(seed)
    tree = TreeKinematics(model)
    q = np.zeros(tree.nq)
    quaternion_slices = []
    for joint in tree.free_joints:
        q_slice, _ = tree.joint_slices[joint.name]
        n = q_slice.stop - q_slice.start
        if joint.type == "spherical":
            quaternion_slices.append(q_slice)
        elif joint.type == "free":
            quaternion_slices.append(slice(q_slice.start + 3, q_slice.stop))
        q[q_slice] = rng.uniform(-0.6, 0.6, n)
    for s in quaternion_slices:
        q[s] = np.array([1.0, 0.0, 0.0, 0.0]) + 0.4 * rng.standard_normal(4)
        q[s] /= np.linalg.norm(q[s])
    v = rng.uniform(-1.5, 1.5, tree.nv)
    h_matrix = ca.jacobian(tree.qdot, tree.v)
    evaluate = ca.Function(
        "state",
        [tree.t, tree.q],
        [
            ca.densify(x)
            for x in (
                tree.closure_constraints,
                tree.velocity_constraint_matrix,
                tree.velocity_constraint_bias,
                h_matrix,
            )
        ],
    )
    held = np.ones(tree.nv)
    if model.name in FIXED_COORDINATE:
        held[tree.joint_slices[FIXED_COORDINATE[model.name]][1]] = 0.0
    n_h = tree.n_holonomic
    for _ in range(100):
        g, w_matrix, _, h_value = (np.asarray(x, dtype=float) for x in evaluate(t, q))
        g = g.reshape(-1)
        if g.size == 0 or np.max(np.abs(g)) < 1e-14:
            break
        step, *_ = np.linalg.lstsq(w_matrix.reshape(-1, tree.nv)[:n_h] * held, -g, rcond=None)
        q = q + h_value.reshape(tree.nq, tree.nv) @ (held * step)
        for s in quaternion_slices:
            q[s] /= np.linalg.norm(q[s])
    g, w_matrix, bias, _ = (np.asarray(x, dtype=float) for x in evaluate(t, q))
    assert g.size == 0 or np.max(np.abs(g)) < 1e-12, f"{model.name}: closure not reached"
    w_matrix = w_matrix.reshape(-1, tree.nv)
    if w_matrix.size:
        v = v - np.linalg.pinv(w_matrix, rcond=1e-10) @ (w_matrix @ v + bias.reshape(-1))
    return q, v


_CACHE: dict[tuple, object] = {}


def build(name: str, formalism: str = "absolute-dae", **options: object):
    """Equations of a test model (cached: building is the slow part)."""
    key = (name, formalism, tuple(sorted(options.items())))
    if key not in _CACHE:
        _CACHE[key] = get_formalism(formalism)().build(MODELS[name](), options)
    return _CACHE[key]


def absolute_state(name: str, seed: int, t: float = 0.0, **options: object):
    """(equations, q, v): a consistent random state mapped to absolute coordinates."""
    eq = build(name, **options)
    q_joint, v_joint = consistent_state(eq.model, seed, t)
    q, v = eq.joint_space_map(t, q_joint, v_joint)
    return eq, q, v


def accelerations(mech, t: float, q: np.ndarray, v: np.ndarray):
    """(v', lambda) from [M W^T; W 0] [v'; lambda] = [Q; gamma]."""
    nv, nc = v.size, mech.n_constraints
    mass = mech.mass(t, q)[0].reshape(nv, nv)  # one-velocity outputs come back flat
    (forces,) = mech.forces(t, q, v)
    if nc == 0:
        return np.linalg.solve(mass, forces), np.zeros(0)
    w_matrix = mech.velocity_matrix(t, q)[0].reshape(nc, nv)
    (gamma,) = mech.acceleration_rhs(t, q, v)
    kkt = np.block([[mass, w_matrix.T], [w_matrix, np.zeros((nc, nc))]])
    solution = np.linalg.solve(kkt, np.concatenate([forces, gamma]))
    return solution[:nv], solution[nv:]


# ---- tests ----------------------------------------------------------------------------

ALL = list(MODELS)


@pytest.mark.parametrize("name", ALL)
def test_mass_matrix_symmetric_positive_semidefinite(name: str) -> None:
    eq, q, _ = absolute_state(name, seed=1)
    (mass,) = eq.forms["mechanical"].mass(0.0, q)
    np.testing.assert_allclose(mass, mass.T, atol=1e-14)
    eigenvalues = np.linalg.eigvalsh(mass)
    assert eigenvalues.min() > -1e-12 * eigenvalues.max()


@pytest.mark.parametrize("name", ALL)
def test_augmented_matrix_nonsingular(name: str) -> None:
    eq, q, _ = absolute_state(name, seed=2)
    mech = eq.forms["mechanical"]
    (mass,), (w_matrix,) = mech.mass(0.0, q), mech.velocity_matrix(0.0, q)
    nc = w_matrix.shape[0]
    kkt = np.block([[mass, w_matrix.T], [w_matrix, np.zeros((nc, nc))]])
    assert np.linalg.cond(kkt) < 1e10


@pytest.mark.parametrize("name", ALL)
def test_constraints_vanish_at_mapped_states(name: str) -> None:
    t = 0.37
    eq, q, v = absolute_state(name, seed=3, t=t)
    mech = eq.forms["mechanical"]
    (g,) = mech.position_constraints(t, q)
    (c,) = mech.velocity_constraints(t, q, v)
    assert np.max(np.abs(g), initial=0.0) < 1e-11
    assert np.max(np.abs(c), initial=0.0) < 1e-10
    position, velocity, nonholonomic = eq.observables.residuals(t, q, v)
    for residual in (position, velocity, nonholonomic):
        assert np.max(np.abs(residual), initial=0.0) < 1e-10
    if eq.model.kind == "spatial":  # mapped Euler parameters are unit
        for i in range(len(eq.model.bodies)):
            assert abs(np.linalg.norm(q[7 * i + 3 : 7 * i + 7]) - 1.0) < 1e-14


@pytest.mark.parametrize(
    "name",
    ["double-pendulum", "slider-crank", "heavy-top", "chain3", "rolling-disk", "driven-pendulum"],
)
def test_poses_match_tree_kinematics(name: str) -> None:
    """Body frames of the mapped absolute state equal the joint-space forward kinematics."""
    t = 0.2
    eq, q, v = absolute_state(name, seed=4, t=t)
    minimal = build(name, "minimal-ode")
    q_joint, v_joint = consistent_state(eq.model, 4, t)
    for a, b in zip(
        eq.observables.frames(t, q), minimal.observables.frames(t, q_joint), strict=True
    ):
        np.testing.assert_allclose(a, b, atol=1e-13)
    np.testing.assert_allclose(
        eq.observables.twists(t, q, v)[0],
        minimal.observables.twists(t, q_joint, v_joint)[0],
        atol=1e-12,
    )


def _central_difference(function, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    columns = []
    for i in range(x.size):
        step = np.zeros_like(x)
        step[i] = h
        columns.append((function(x + step) - function(x - step)) / (2 * h))
    return np.stack(columns, axis=1)


@pytest.mark.parametrize(
    "name",
    [
        "double-pendulum",
        "slider-crank",
        "heavy-top",
        "chain3",
        "knife-edge",
        "rolling-disk",
        "driven-pendulum",
    ],
)
def test_ode_jacobian_matches_finite_differences(name: str) -> None:
    eq, q, v = absolute_state(name, seed=5, index=1)
    ode = eq.forms["ode"]
    y = np.concatenate([q, v])
    t = 0.1
    (jacobian,) = ode.jacobian(t, y)
    numeric = _central_difference(lambda x: ode.rhs(t, x)[0], y)
    np.testing.assert_allclose(jacobian, numeric, atol=1e-5 * max(1.0, np.abs(numeric).max()))


@pytest.mark.parametrize("index", [1, 2, 3])
@pytest.mark.parametrize("name", ["slider-crank", "heavy-top", "chain3", "rolling-disk"])
def test_dae_jacobian_matches_finite_differences(name: str, index: int) -> None:
    eq, q, v = absolute_state(name, seed=6, index=index)
    dae = eq.forms["dae"]
    rng = np.random.default_rng(7)
    y = np.concatenate([q, v, rng.standard_normal(dae.n - q.size - v.size)])
    yp = rng.standard_normal(dae.n)
    t, coefficient = 0.05, 3.7
    (jacobian,) = dae.jacobian(t, y, yp, coefficient)
    d_y = _central_difference(lambda x: dae.residual(t, x, yp)[0], y)
    d_yp = _central_difference(lambda x: dae.residual(t, y, x)[0], yp)
    numeric = d_y + coefficient * d_yp
    np.testing.assert_allclose(jacobian, numeric, atol=1e-5 * max(1.0, np.abs(numeric).max()))


@pytest.mark.parametrize("index", [1, 2, 3])
@pytest.mark.parametrize("name", ALL)
def test_dae_residual_vanishes_at_consistent_state(name: str, index: int) -> None:
    t = 0.3
    eq, q, v = absolute_state(name, seed=8, t=t, index=index)
    mech, dae = eq.forms["mechanical"], eq.forms["dae"]
    acceleration, lam = accelerations(mech, t, q, v)
    (qdot,) = mech.qdot(t, q, v)
    extra = dae.n - q.size - v.size
    y = np.concatenate([q, v, lam, np.zeros(extra - lam.size)])
    yp = np.concatenate([qdot, acceleration, np.zeros(extra)])
    (residual,) = dae.residual(t, y, yp)
    scale = max(1.0, np.abs(yp).max())
    assert np.max(np.abs(residual)) < 1e-10 * scale
    assert dae.algebraic.sum() == extra


@pytest.mark.parametrize("name", CONSERVATIVE)
def test_energy_conserved_index1_radau(name: str) -> None:
    eq, q, v = absolute_state(name, seed=9, index=1)
    ode = eq.forms["ode"]
    y0 = np.concatenate([q, v])
    rtol = 1e-8
    solution = solve_ivp(
        lambda t, y: ode.rhs(t, y)[0],
        (0.0, 0.5),
        y0,
        method="Radau",
        rtol=rtol,
        atol=1e-10,
        jac=lambda t, y: ode.jacobian(t, y)[0],
    )
    assert solution.success, solution.message
    energies = np.array(
        [eq.observables.energy(0.0, y[: q.size], y[q.size :])[0].sum() for y in solution.y.T]
    )
    kinetic = eq.observables.energy(0.0, q, v)[0][0]
    drift = np.max(np.abs(energies - energies[0])) / max(abs(energies[0]), kinetic, 1e-3)
    assert drift < 100 * rtol, f"relative energy drift {drift:.2e}"
    position = eq.observables.residuals(0.5, solution.y[: q.size, -1], solution.y[q.size :, -1])
    assert np.max(np.abs(position[0]), initial=0.0) < 1e-6


def test_redundant_four_bar_rows_removed() -> None:
    eq = build("parallel-four-bar")
    assert any(n.startswith("removed redundant constraint rows: j4[") for n in eq.notes)
    removed = next(n for n in eq.notes if n.startswith("removed")).split(": ")[1].split(", ")
    assert len(removed) == 3  # 4 joints x 3 out-of-plane rows on 3 x 3 out-of-plane velocities
    assert not set(removed) & set(eq.constraint_names)
    assert eq.nv - eq.n_constraints == 1  # one degree of freedom


def test_redundant_error_names_rows() -> None:
    with pytest.raises(ModelError, match=r"redundant constraint rows j4\["):
        get_formalism("absolute-dae")().build(parallel_four_bar(), {"redundant": "error"})


def test_forms_and_notes() -> None:
    formalism = get_formalism("absolute-dae")
    assert formalism.forms({"index": 1}) == {"dae": 1, "mechanical": 0, "ode": 0}
    assert formalism.forms({}) == {"dae": 3, "mechanical": 0}
    eq = build("heavy-top")
    assert any("p^T p = 1" in note for note in eq.notes)
    assert eq.q_names[:7] == ["top.x", "top.y", "top.z", "top.p0", "top.p1", "top.p2", "top.p3"]
    assert "ode" not in eq.forms


# ---- joint forces on quaternion joints ---------------------------------------------------


def quaternion_joint_forces() -> Model:
    """Spatial: a body on a spherical joint, a second on a free joint from it, joint forces on
    both depending on the Euler parameters and velocities; frames rotated and offset."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(3)

    def frame() -> Frame:
        return Frame(rng.uniform(-0.3, 0.3, 3), Rotation.random(random_state=rng).as_matrix())

    m = Model("quaternion-joint-forces", kind="spatial", gravity=(0.0, 0.0, -9.81))
    m.add_body("arm", 1.2, com=(0.1, 0.2, -0.3), inertia=(0.05, 0.04, 0.02))
    m.add_body("float", 0.7, com=(0.0, 0.1, 0.05), inertia=(0.01, 0.02, 0.015))
    m.add_joint("ball", "spherical", "ground", "arm", parent_frame=frame(), child_frame=frame())
    m.add_joint("loose", "free", "arm", "float", parent_frame=frame(), child_frame=frame())
    m.add_force(
        JointForce(
            "ball-motor",
            "ball",
            lambda t, q, v: (
                ca.vertcat(2.0 * q[1] - 0.3 * v[0], -1.5 * q[2] * q[0], ca.sin(t)) - 0.2 * v
            ),
        )
    )
    m.add_force(
        JointForce(
            "loose-motor",
            "loose",
            lambda t, q, v: ca.vertcat(-3.0 * q[0:3] - 0.5 * v[0:3], 1.0 * q[4:7] - 0.1 * v[3:6]),
        )
    )
    return m


def test_joint_force_on_spherical_and_free_joints_agrees_with_minimal_ode() -> None:
    """The generalized force of a joint force on a quaternion joint goes through the joint's
    velocities (angular velocity in C, origin rate in P), not through the Euler-parameter
    rates: absolute-dae and minimal-ode give the same body accelerations."""
    from workbench.testing.states import body_accelerations, formalism_state

    model = quaternion_joint_forces()
    absolute = get_formalism("absolute-dae")().build(model, {"index": 1})
    minimal = get_formalism("minimal-ode")().build(model, {})
    kinematics = TreeKinematics(model)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.standard_normal(kinematics.nq)
        q[0:4] /= np.linalg.norm(q[0:4])  # ball: Euler parameters
        q[4:7] *= 0.3  # loose: position of C in P
        q[7:11] /= np.linalg.norm(q[7:11])  # loose: Euler parameters
        v = rng.standard_normal(kinematics.nv)
        t = float(rng.uniform(0.0, 2.0))
        ours = body_accelerations(absolute, formalism_state(absolute, t, q, v))
        theirs = body_accelerations(minimal, formalism_state(minimal, t, q, v))
        assert np.max(np.abs(ours - theirs)) <= 1e-9 * np.max(np.abs(theirs))


def universal_joint_forces() -> Model:
    """Spatial: a Cardan arm on a universal joint with axes 60 degrees apart (not
    perpendicular), a second body on a universal joint from it; a joint force depending on
    both angles and rates, a joint spring-damper on the second; frames rotated and offset."""
    from scipy.spatial.transform import Rotation

    from workbench.model import JointSpringDamper

    rng = np.random.default_rng(5)

    def frame() -> Frame:
        return Frame(rng.uniform(-0.3, 0.3, 3), Rotation.random(random_state=rng).as_matrix())

    m = Model("universal-joint-forces", kind="spatial", gravity=(0.0, 0.0, -9.81))
    m.add_body("arm", 1.2, com=(0.1, 0.2, -0.3), inertia=(0.05, 0.04, 0.02))
    m.add_body("tip", 0.7, com=(0.0, 0.1, 0.25), inertia=(0.01, 0.02, 0.015))
    axis2 = (0.5, np.sqrt(3) / 2, 0.0)  # 60 degrees from axis (1, 0, 0)
    m.add_joint("cardan", "universal", "ground", "arm", axis=(1, 0, 0), axis2=axis2,
                parent_frame=frame(), child_frame=frame())  # fmt: skip
    m.add_joint("wrist", "universal", "arm", "tip", axis=(0, 0, 1), axis2=(0, 1, 0),
                parent_frame=frame(), child_frame=frame())  # fmt: skip
    m.add_force(
        JointForce(
            "cardan-motor",
            "cardan",
            lambda t, q, v: (
                ca.vertcat(2.0 * ca.sin(q[1]) - 0.3 * v[0], -1.5 * q[0] + ca.cos(t)) - 0.2 * v
            ),
        )
    )
    m.add_force(JointSpringDamper("wrist-spring", "wrist", 3.0, 0.4, (0.2, -0.1)))
    return m


def test_joint_force_on_universal_joints_agrees_with_minimal_ode() -> None:
    """Joint forces and springs on universal joints (perpendicular axes or not) see the
    same two angles in absolute-dae, recovered from the body poses, as in joint
    coordinates: the body accelerations agree with minimal-ode's to round-off."""
    from workbench.testing.states import body_accelerations, formalism_state

    model = universal_joint_forces()
    absolute = get_formalism("absolute-dae")().build(model, {"index": 1})
    minimal = get_formalism("minimal-ode")().build(model, {})
    kinematics = TreeKinematics(model)
    rng = np.random.default_rng(11)
    for _ in range(8):
        q = rng.uniform(-3.0, 3.0, kinematics.nq)  # angles anywhere in (-pi, pi)
        v = rng.standard_normal(kinematics.nv)
        t = float(rng.uniform(0.0, 2.0))
        ours = body_accelerations(absolute, formalism_state(absolute, t, q, v))
        theirs = body_accelerations(minimal, formalism_state(minimal, t, q, v))
        assert np.max(np.abs(ours - theirs)) <= 1e-13 * np.max(np.abs(theirs))
