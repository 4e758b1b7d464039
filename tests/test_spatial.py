"""Spatial algebra (workbench/numerics/spatial.py): identities of the algebra, the block
forms against the dense 6 x 6 products, and the NumPy and CasADi paths against each other."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.numerics import spatial as sp


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    return Rotation.random(random_state=rng).as_matrix()


def random_symmetric(rng: np.random.Generator, n: int = 6) -> np.ndarray:
    half = rng.uniform(-1, 1, (n, n))
    return half @ half.T


def random_body_inertia(rng: np.random.Generator) -> tuple[float, np.ndarray, np.ndarray]:
    """mass, centre of mass and a physical inertia tensor (a box's) about it."""
    mass = rng.uniform(0.5, 2.0)
    a, b, c = rng.uniform(0.1, 1.0, 3)
    moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    rotation = random_rotation(rng)
    inertia = rotation @ np.diag(moments) @ rotation.T
    return mass, rng.uniform(-0.5, 0.5, 3), (inertia + inertia.T) / 2


def cross_matrix(v: np.ndarray) -> np.ndarray:
    """The 6 x 6 matrix of v x (written out densely, independently of the module)."""
    w_tilde = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    v_tilde = np.array([[0, -v[5], v[4]], [v[5], 0, -v[3]], [-v[4], v[3], 0]])
    return np.block([[w_tilde, np.zeros((3, 3))], [v_tilde, w_tilde]])


@pytest.mark.parametrize("seed", range(4))
def test_congruence_equals_the_dense_transform(seed: int) -> None:
    """congruence(E, r, I) = X^T I X with X = [E 0; -E r~ E]: random rotation, offset and
    symmetric I (the ABA's and CRBA's articulated-inertia step), also with a symbolic r
    (prismatic joints move the child's origin)."""
    rng = np.random.default_rng(seed)
    E = Rotation.random(random_state=rng).as_matrix()
    r = rng.uniform(-1, 1, 3)
    half = rng.uniform(-1, 1, (6, 6))
    inertia = half @ half.T
    r_sym = ca.SX.sym("r", 3)
    dense = ca.mtimes([sp.plucker(ca.DM(E), r_sym).T, ca.DM(inertia), sp.plucker(ca.DM(E), r_sym)])
    blocks = sp.congruence(ca.SX(ca.DM(E)), r_sym, ca.SX(ca.DM(inertia)))
    evaluate = ca.Function("both", [r_sym], [dense, blocks])
    expected, got = (np.asarray(x) for x in evaluate(r))
    assert np.allclose(got, got.T, rtol=0, atol=0)  # symmetric by construction
    assert np.abs(got - expected).max() <= 1e-13 * np.abs(expected).max()
    # and in NumPy
    numeric = sp.congruence(E, r, inertia)
    assert np.array_equal(numeric, numeric.T)
    assert np.abs(numeric - expected).max() <= 1e-13 * np.abs(expected).max()


@pytest.mark.parametrize("seed", range(4))
def test_rotate_z_inertia_equals_the_congruence_of_the_rotation(seed: int) -> None:
    """rotate_z_inertia(cos, sin, I) = X^T I X for X = plucker(R_z^T, 0) (a revolute
    joint's turn, applied before its constant placement in the articulated-body
    algorithm), for a symbolic angle; and an articulated inertia's zero rows and columns
    of the z axis stay structurally zero (no instructions for them)."""
    rng = np.random.default_rng(seed)
    inertia = random_symmetric(rng)
    angle = ca.SX.sym("q")
    c, s = ca.cos(angle), ca.sin(angle)
    R_z = ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    dense = sp.congruence(R_z.T, ca.SX.zeros(3), ca.SX(ca.DM(inertia)))
    turned = sp.rotate_z_inertia(c, s, ca.SX(ca.DM(inertia)))
    evaluate = ca.Function("both", [angle], [dense, turned])
    for q in rng.uniform(-4, 4, 5):
        expected, got = (np.asarray(x) for x in evaluate(q))
        assert np.array_equal(got, got.T)
        assert np.abs(got - expected).max() <= 1e-13 * np.abs(expected).max()
    articulated = ca.SX(ca.DM(inertia))
    articulated[2, :], articulated[:, 2] = 0, 0
    turned = ca.evalf(ca.substitute(sp.rotate_z_inertia(c, s, articulated), angle, 0.7))
    assert np.all(np.asarray(turned)[2, :] == 0) and np.all(np.asarray(turned)[:, 2] == 0)


@pytest.mark.parametrize("seed", range(4))
def test_motion_and_force_cross_products(seed: int) -> None:
    """v x m is the matrix of v x applied to m; v x* is its negative transpose dual:
    f . (v x m) = -(v x* f) . m, for every f and m (power is frame independent)."""
    rng = np.random.default_rng(seed)
    v, m, f = rng.uniform(-1, 1, (3, 6))
    assert np.allclose(sp.motion_cross(v, m), cross_matrix(v) @ m, rtol=0, atol=1e-15)
    assert np.allclose(sp.force_cross(v, f), -cross_matrix(v).T @ f, rtol=0, atol=1e-15)
    assert np.dot(f, sp.motion_cross(v, m)) == pytest.approx(
        -np.dot(sp.force_cross(v, f), m), abs=1e-14
    )
    # v x v = 0: a body does not accelerate itself by moving
    assert np.allclose(sp.motion_cross(v, v), 0, rtol=0, atol=1e-15)


@pytest.mark.parametrize("seed", range(4))
def test_plucker_transforms_compose_and_match_the_block_forms(seed: int) -> None:
    """X(E2, r2) X(E1, r1) = X(E2 E1, r1 + E1^T r2) (frames A -> B -> C); X m and X^T f
    equal the block forms; power is preserved: (X^T f) . m = f . (X m)."""
    rng = np.random.default_rng(seed)
    E1, E2 = random_rotation(rng), random_rotation(rng)
    r1, r2 = rng.uniform(-1, 1, (2, 3))
    X1, X2 = sp.plucker(E1, r1), sp.plucker(E2, r2)
    assert np.allclose(X2 @ X1, sp.plucker(E2 @ E1, r1 + E1.T @ r2), rtol=0, atol=1e-14)
    m, f = rng.uniform(-1, 1, (2, 6))
    assert np.allclose(sp.transform_motion(E1, r1, m), X1 @ m, rtol=0, atol=1e-14)
    assert np.allclose(sp.transform_force_back(E1, r1, f), X1.T @ f, rtol=0, atol=1e-14)
    forces = rng.uniform(-1, 1, (6, 3))  # several columns: the CRBA's I^C S
    assert np.allclose(sp.transform_force_back(E1, r1, forces), X1.T @ forces, atol=1e-14)
    assert np.dot(sp.transform_force_back(E1, r1, f), m) == pytest.approx(
        np.dot(f, sp.transform_motion(E1, r1, m)), abs=1e-14
    )
    # the cross product moves with the frame: X (v x m) = (X v) x (X m)
    v = rng.uniform(-1, 1, 6)
    assert np.allclose(
        X1 @ sp.motion_cross(v, m), sp.motion_cross(X1 @ v, X1 @ m), rtol=0, atol=1e-14
    )


@pytest.mark.parametrize("seed", range(4))
def test_transformed_spatial_inertia_stays_a_rigid_body_inertia(seed: int) -> None:
    """X^T I X of a body's spatial inertia is symmetric positive definite, has the same
    mass, and is the spatial inertia of the same body about the new frame (the centre of
    mass moved and the inertia tensor rotated)."""
    rng = np.random.default_rng(seed)
    mass, com, inertia_c = random_body_inertia(rng)
    inertia = sp.spatial_inertia(mass, com, inertia_c)
    assert np.allclose(inertia, inertia.T, rtol=0, atol=1e-15)
    E, r = random_rotation(rng), rng.uniform(-1, 1, 3)
    moved = sp.congruence(E, r, inertia)
    assert np.array_equal(moved, moved.T)
    assert np.linalg.eigvalsh(moved).min() > 0
    assert np.allclose(moved[3:, 3:], mass * np.eye(3), rtol=0, atol=1e-14)
    # the child's frame has origin r and axes E^T in parent coordinates
    expected = sp.spatial_inertia(mass, r + E.T @ com, E.T @ inertia_c @ E)
    assert np.allclose(moved, expected, rtol=0, atol=1e-13)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_articulated_update_equals_the_dense_formula(n: int) -> None:
    """I^a = I^A - U D^-1 U^T with U = I^A S, D = S^T U, symmetric, and S^T I^a S = 0:
    the joint's own directions carry no inertia any more."""
    rng = np.random.default_rng(n)
    I_A = random_symmetric(rng)
    S = rng.uniform(-1, 1, (6, n))
    U = I_A @ S
    D = S.T @ U
    I_a = sp.articulated_update(I_A, U, np.linalg.solve(D, U.T))
    assert np.allclose(I_a, I_A - U @ np.linalg.solve(D, U.T), rtol=0, atol=1e-12)
    assert np.array_equal(I_a, I_a.T)
    assert np.allclose(S.T @ I_a @ S, 0, atol=1e-11)


def test_symmetric_computes_the_upper_triangle_only() -> None:
    calls = []

    def entry(i: int, j: int) -> float:
        calls.append((i, j))
        return 10.0 * i + j

    matrix = sp.symmetric(entry, 4)
    assert sorted(calls) == [(i, j) for i in range(4) for j in range(i, 4)]
    assert matrix[3, 1] == matrix[1, 3] == 13.0


@pytest.mark.parametrize("seed", range(3))
def test_numpy_and_casadi_paths_agree(seed: int) -> None:
    """Every operation on NumPy arrays gives what its CasADi graph evaluates to."""
    rng = np.random.default_rng(seed)
    E, r = random_rotation(rng), rng.uniform(-1, 1, 3)
    v, m, f = rng.uniform(-1, 1, (3, 6))
    inertia = random_symmetric(rng)
    S = rng.uniform(-1, 1, (6, 2))
    U = inertia @ S
    D_inv_U = np.linalg.solve(S.T @ U, U.T)
    mass, com, inertia_c = random_body_inertia(rng)
    cases = {
        "motion_cross": (sp.motion_cross, (v, m)),
        "force_cross": (sp.force_cross, (v, f)),
        "transform_motion": (sp.transform_motion, (E, r, m)),
        "transform_force_back": (sp.transform_force_back, (E, r, f)),
        "transform_force_back columns": (sp.transform_force_back, (E, r, S)),
        "plucker": (sp.plucker, (E, r)),
        "congruence": (sp.congruence, (E, r, inertia)),
        "articulated_update": (sp.articulated_update, (inertia, U, D_inv_U)),
        "spatial_inertia": (sp.spatial_inertia, (mass, com, inertia_c)),
    }
    for name, (operation, args) in cases.items():
        numeric = np.asarray(operation(*args), dtype=float)
        assert isinstance(operation(*args), np.ndarray), name
        symbols = [ca.SX.sym(f"x{k}", *np.atleast_1d(a).shape) for k, a in enumerate(args)]
        expression = operation(*symbols)
        assert isinstance(expression, ca.SX), name
        (value,) = ca.Function("operation", symbols, [expression]).call([ca.DM(a) for a in args])
        value = np.asarray(value, dtype=float)
        assert np.allclose(value.reshape(numeric.shape), numeric, rtol=0, atol=1e-13), name


def arithmetic(function: ca.Function) -> int:
    """Operations of an SX Function: its instructions without inputs, outputs, constants."""
    skip = (ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_PARAMETER)
    return sum(function.instruction_id(k) not in skip for k in range(function.n_instructions()))


@pytest.mark.parametrize("seed", range(4))
def test_rigid_bias_force_equals_v_cross_star_i_v_in_fewer_operations(seed: int) -> None:
    """V x* I V of a rigid body through its centre of mass ([w x I_c w + c x f; f],
    f = m w x (v + w x c)) equals the dense form force_cross(V, I V) for NumPy and CasADi,
    in at most 60 operations for a general body against 72 through I V."""
    rng = np.random.default_rng(seed)
    mass, com, inertia_c = random_body_inertia(rng)
    inertia = sp.spatial_inertia(mass, com, inertia_c)
    V = rng.uniform(-2, 2, 6)
    dense = sp.force_cross(V, inertia @ V)
    assert np.allclose(sp.rigid_bias_force(mass, com, inertia_c, V), dense, rtol=0, atol=1e-13)
    V_sym = ca.SX.sym("V", 6)
    through_com = ca.Function("com", [V_sym], [sp.rigid_bias_force(mass, com, inertia_c, V_sym)])
    through_I = ca.Function(
        "dense", [V_sym], [sp.force_cross(V_sym, ca.mtimes(ca.SX(ca.DM(inertia)), V_sym))]
    )
    assert np.allclose(np.ravel(through_com(V)), dense, rtol=0, atol=1e-13)
    assert arithmetic(through_com) <= 60 < arithmetic(through_I)


def test_symmetric_sum_adds_one_triangle() -> None:
    """A + B of symmetric 6 x 6 matrices: 21 sums (the upper triangle mirrored), not 36,
    and the same matrix."""
    rng = np.random.default_rng(5)
    A, B = random_symmetric(rng), random_symmetric(rng)
    a = sp.symmetric(lambda i, j: ca.SX.sym(f"a{i}{j}"), 6)
    b = sp.symmetric(lambda i, j: ca.SX.sym(f"b{i}{j}"), 6)
    symbols = [ca.vertcat(*[x[i, j] for i in range(6) for j in range(i, 6)]) for x in (a, b)]
    total = ca.Function("sum", symbols, [sp.symmetric_sum(a, b)])
    assert arithmetic(total) == 21
    upper = [np.array([x[i, j] for i in range(6) for j in range(i, 6)]) for x in (A, B)]
    assert np.array_equal(np.asarray(total(*upper)), A + B)
