"""Rotation parameterizations (book ch. 3): checked against SciPy, finite differences and
the algebra of rotations, on the NumPy and the CasADi path."""

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from workbench.errors import WorkbenchError
from workbench.numerics import rotations as rot

settings.register_profile("rotations", deadline=None, max_examples=60)
settings.load_profile("rotations")

FRAMES = ["body", "inertial"]
PI = np.pi


# --- strategies and helpers ---------------------------------------------------------------


def floats(low: float, high: float) -> st.SearchStrategy[float]:
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


def vectors(low: float, high: float, n: int = 3) -> st.SearchStrategy[np.ndarray]:
    return st.lists(floats(low, high), min_size=n, max_size=n).map(np.array)


def _normalized(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


unit_quaternions = vectors(-1, 1, 4).filter(lambda v: np.linalg.norm(v) > 0.1).map(_normalized)
unit_axes = vectors(-1, 1).filter(lambda v: np.linalg.norm(v) > 0.1).map(_normalized)
omegas = vectors(-10, 10)

# Each minimal parameterization: its functions, a strategy over its principal range, and the
# quantity that vanishes at its singularity (|cos b|, |sin b|, p0 = cos(angle/2)).
MINIMAL = {
    "cardan_xyz": dict(
        to_matrix=rot.cardan_xyz_to_matrix,
        from_matrix=rot.matrix_to_cardan_xyz,
        rate=rot.cardan_xyz_rate_matrix,
        angular_velocity=rot.cardan_xyz_angular_velocity_matrix,
        values=st.tuples(floats(-PI, PI), floats(-PI / 2, PI / 2), floats(-PI, PI)).map(np.array),
        regularity=lambda x: abs(np.cos(x[1])),
        scipy=lambda x: Rotation.from_euler("XYZ", x),
        angles=True,
    ),
    "euler_zxz": dict(
        to_matrix=rot.euler_zxz_to_matrix,
        from_matrix=rot.matrix_to_euler_zxz,
        rate=rot.euler_zxz_rate_matrix,
        angular_velocity=rot.euler_zxz_angular_velocity_matrix,
        values=st.tuples(floats(-PI, PI), floats(0, PI), floats(-PI, PI)).map(np.array),
        regularity=lambda x: abs(np.sin(x[1])),
        scipy=lambda x: Rotation.from_euler("ZXZ", x),
        angles=True,
    ),
    "rodrigues": dict(
        to_matrix=rot.rodrigues_to_matrix,
        from_matrix=rot.matrix_to_rodrigues,
        rate=rot.rodrigues_rate_matrix,
        angular_velocity=rot.rodrigues_angular_velocity_matrix,
        values=vectors(-10, 10),
        regularity=lambda x: 1 / np.sqrt(1 + x @ x),
        scipy=lambda x: Rotation.from_rotvec(rodrigues_to_rotvec(x)),
        angles=False,
    ),
}


def rodrigues_to_rotvec(rho: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(rho)
    return rho if norm == 0 else 2 * np.arctan(norm) * rho / norm


def scipy_rotation(p: np.ndarray) -> Rotation:
    """SciPy is scalar-last."""
    return Rotation.from_quat([p[1], p[2], p[3], p[0]])


def scipy_quaternion(r: Rotation) -> np.ndarray:
    x, y, z, w = r.as_quat()
    return np.array([w, x, y, z])


def same_quaternion(p: np.ndarray, q: np.ndarray, atol: float = 1e-12) -> bool:
    """Equal up to the double cover p ~ -p."""
    return min(np.abs(p - q).max(), np.abs(p + q).max()) <= atol


def angle_difference(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return (np.asarray(x) - np.asarray(y) + PI) % (2 * PI) - PI


def assert_rotation_matrix(R: np.ndarray) -> None:
    assert R.shape == (3, 3)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


# --- rotation matrices --------------------------------------------------------------------


@given(x=vectors(-10, 10), p=unit_quaternions, axis=unit_axes, angle=floats(-10, 10))
def test_every_parameterization_gives_a_rotation_matrix(x, p, axis, angle):
    for R in [
        rot.cardan_xyz_to_matrix(x),
        rot.euler_zxz_to_matrix(x),
        rot.rodrigues_to_matrix(x),
        rot.quaternion_to_matrix(p),
        rot.axis_angle_to_matrix(axis, angle),
        rot.quaternion_to_matrix(rot.axis_angle_to_quaternion(axis, angle)),
        rot.elementary_rotation("y", angle),
    ]:
        assert_rotation_matrix(R)


@given(angle=floats(-10, 10))
def test_elementary_rotations_are_axis_angle_rotations_about_the_frame_axes(angle):
    for index, name in enumerate("xyz"):
        axis = np.eye(3)[index]
        expected = rot.axis_angle_to_matrix(axis, angle)
        np.testing.assert_allclose(rot.elementary_rotation(name, angle), expected, atol=1e-15)
        np.testing.assert_allclose(rot.elementary_rotation(index, angle), expected, atol=1e-15)


def test_elementary_rotation_rejects_an_unknown_axis():
    with pytest.raises(ValueError, match="axis"):
        rot.elementary_rotation("w", 0.1)


def test_compose_multiplies_left_to_right():
    A, B = rot.elementary_rotation("x", 0.3), rot.elementary_rotation("z", 1.1)
    np.testing.assert_allclose(rot.compose(A, B), A @ B, atol=1e-15)
    assert not np.allclose(A @ B, B @ A)
    np.testing.assert_allclose(rot.compose(), np.eye(3))
    np.testing.assert_allclose(rot.compose(A), A)


@given(x=vectors(-PI, PI))
def test_cardan_and_euler_angles_are_rotations_about_co_rotating_axes(x):
    a, b, c = x
    Rx, Ry, Rz = (lambda t, i=i: rot.elementary_rotation(i, t) for i in range(3))
    np.testing.assert_allclose(
        rot.cardan_xyz_to_matrix(x), rot.compose(Rx(a), Ry(b), Rz(c)), atol=1e-15
    )
    np.testing.assert_allclose(
        rot.euler_zxz_to_matrix(x), rot.compose(Rz(a), Rx(b), Rz(c)), atol=1e-15
    )


def test_rotation_maps_body_coordinates_to_inertial_ones():
    # A body turned by +90 degrees about z: its x axis points along the inertial y axis.
    R = rot.elementary_rotation("z", PI / 2)
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    p = rot.axis_angle_to_quaternion([0.0, 0.0, 1.0], PI / 2)
    np.testing.assert_allclose(p, [np.cos(PI / 4), 0.0, 0.0, np.sin(PI / 4)])


# --- agreement with SciPy -----------------------------------------------------------------


@pytest.mark.parametrize("name", list(MINIMAL))
@given(data=st.data())
def test_minimal_parameterizations_agree_with_scipy(name, data):
    par = MINIMAL[name]
    x = data.draw(par["values"])
    np.testing.assert_allclose(par["to_matrix"](x), par["scipy"](x).as_matrix(), atol=1e-12)


@given(p=unit_quaternions)
def test_matrix_to_cardan_and_euler_angles_agree_with_scipy(p):
    R = rot.quaternion_to_matrix(p)
    assume(np.hypot(R[0, 0], R[0, 1]) > 1e-3 and np.hypot(R[2, 0], R[2, 1]) > 1e-3)
    cardan = scipy_rotation(p).as_euler("XYZ")
    euler = scipy_rotation(p).as_euler("ZXZ")
    np.testing.assert_allclose(angle_difference(rot.matrix_to_cardan_xyz(R), cardan), 0, atol=1e-9)
    np.testing.assert_allclose(angle_difference(rot.matrix_to_euler_zxz(R), euler), 0, atol=1e-9)


@given(p=unit_quaternions)
def test_euler_parameters_agree_with_scipy(p):
    R = scipy_rotation(p).as_matrix()
    np.testing.assert_allclose(rot.quaternion_to_matrix(p), R, atol=1e-12)
    q = rot.matrix_to_quaternion(R)
    assert q[0] >= 0
    assert same_quaternion(q, scipy_quaternion(scipy_rotation(p)), atol=1e-12)
    assert same_quaternion(q, p, atol=1e-12)


@given(axis=unit_axes, angle=floats(-10, 10))
def test_axis_angle_agrees_with_scipy(axis, angle):
    r = Rotation.from_rotvec(angle * axis)
    np.testing.assert_allclose(rot.axis_angle_to_matrix(axis, angle), r.as_matrix(), atol=1e-12)
    p = rot.axis_angle_to_quaternion(axis, angle)
    assert same_quaternion(p, scipy_quaternion(r))


@given(p=unit_quaternions)
def test_matrix_to_axis_angle_agrees_with_scipy(p):
    rotvec = scipy_rotation(p).as_rotvec()
    assume(np.linalg.norm(rotvec) < PI - 1e-6)  # at pi the sign of the axis is arbitrary
    axis, angle = rot.matrix_to_axis_angle(rot.quaternion_to_matrix(p))
    assert 0 <= angle <= PI
    np.testing.assert_allclose(angle * axis, rotvec, atol=1e-12)


@given(p=unit_quaternions)
def test_matrix_to_rodrigues_agrees_with_scipy(p):
    rotvec = scipy_rotation(p).as_rotvec()
    angle = np.linalg.norm(rotvec)
    assume(angle < PI - 1e-3)
    rho = rot.matrix_to_rodrigues(rot.quaternion_to_matrix(p))
    expected = np.tan(angle / 2) * rotvec / angle if angle > 0 else rotvec
    np.testing.assert_allclose(rho, expected, rtol=1e-9, atol=1e-12)


@given(p=unit_quaternions, q=unit_quaternions)
def test_quaternion_multiply_agrees_with_scipy_composition(p, q):
    expected = scipy_quaternion(scipy_rotation(p) * scipy_rotation(q))
    assert same_quaternion(rot.quaternion_multiply(p, q), expected)


# --- round trips --------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(MINIMAL))
@given(data=st.data())
def test_parameters_to_matrix_and_back(name, data):
    par = MINIMAL[name]
    x = data.draw(par["values"])
    regularity = par["regularity"](x)
    assume(regularity > 1e-4)
    back = par["from_matrix"](par["to_matrix"](x))
    if par["angles"]:
        # errors in a and c grow like eps / regularity near the singularity
        np.testing.assert_allclose(angle_difference(back, x), 0, atol=1e-11 / regularity)
    else:
        np.testing.assert_allclose(back, x, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("name", list(MINIMAL))
@given(p=unit_quaternions)
def test_matrix_to_parameters_and_back(name, p):
    par = MINIMAL[name]
    R = rot.quaternion_to_matrix(p)
    try:
        x = par["from_matrix"](R, tol=1e-4)
    except rot.SingularityError:
        assume(False)
    np.testing.assert_allclose(par["to_matrix"](x), R, atol=1e-10)


@given(p=unit_quaternions)
def test_quaternion_to_matrix_and_back_up_to_sign(p):
    q = rot.matrix_to_quaternion(rot.quaternion_to_matrix(p))
    assert q[0] >= 0
    assert same_quaternion(q, p)  # at p0 = 0 either sign is valid


@given(axis=unit_axes, angle=floats(1e-6, PI))
def test_axis_angle_to_matrix_and_back(axis, angle):
    back_axis, back_angle = rot.matrix_to_axis_angle(rot.axis_angle_to_matrix(axis, angle))
    assert back_angle == pytest.approx(angle, abs=1e-10)
    if angle < PI - 1e-6:
        np.testing.assert_allclose(back_axis, axis, atol=1e-9)
    else:  # at pi, e and -e give the same rotation
        assert min(np.abs(back_axis - axis).max(), np.abs(back_axis + axis).max()) < 1e-6


@pytest.mark.parametrize("delta", [0.0, 1e-12, 1e-9, 1e-6])
@pytest.mark.parametrize("axis", [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0.6, -0.8, 0]])
def test_matrix_to_axis_angle_is_accurate_near_pi(axis, delta):
    axis = np.array(axis)
    back_axis, back_angle = rot.matrix_to_axis_angle(rot.axis_angle_to_matrix(axis, PI - delta))
    assert back_angle == pytest.approx(PI - delta, abs=1e-14)
    if delta == 0.0:
        back_axis = back_axis * np.sign(back_axis @ axis)
    np.testing.assert_allclose(back_axis, axis, atol=1e-14)


def test_matrix_to_axis_angle_at_zero_returns_the_z_axis():
    axis, angle = rot.matrix_to_axis_angle(np.eye(3))
    assert angle == 0.0
    np.testing.assert_array_equal(axis, [0.0, 0.0, 1.0])


@given(p=vectors(-3, 3, 4).filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_normalize_quaternion_keeps_the_rotation(p):
    unit = rot.normalize_quaternion(p)
    assert np.linalg.norm(unit) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(unit, p / np.linalg.norm(p), atol=1e-15)


def test_normalize_quaternion_rejects_zero():
    with pytest.raises(ValueError, match="norm"):
        rot.normalize_quaternion(np.zeros(4))


# --- quaternion algebra -------------------------------------------------------------------


@given(p=unit_quaternions, q=unit_quaternions)
def test_quaternion_multiply_is_the_matrix_product(p, q):
    np.testing.assert_allclose(
        rot.quaternion_to_matrix(rot.quaternion_multiply(p, q)),
        rot.quaternion_to_matrix(p) @ rot.quaternion_to_matrix(q),
        atol=1e-12,
    )


@given(p=unit_quaternions)
def test_quaternion_conjugate_is_the_inverse_rotation(p):
    conjugate = rot.quaternion_conjugate(p)
    np.testing.assert_allclose(rot.quaternion_multiply(p, conjugate), [1, 0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(
        rot.quaternion_to_matrix(conjugate), rot.quaternion_to_matrix(p).T, atol=1e-15
    )


@given(axis=unit_axes, first=floats(-5, 5), second=floats(-5, 5))
def test_rotations_about_one_axis_add_their_angles(axis, first, second):
    p = rot.quaternion_multiply(
        rot.axis_angle_to_quaternion(axis, first), rot.axis_angle_to_quaternion(axis, second)
    )
    np.testing.assert_allclose(p, rot.axis_angle_to_quaternion(axis, first + second), atol=1e-14)


# --- kinematic differential equations -----------------------------------------------------


def assert_kinematics(to_matrix, x, xdot, omega, frame):
    """(R(x + h x') - R(x - h x')) / 2h equals R skew(omega) (body) or skew(omega) R."""
    h = 1e-6 / max(1.0, np.linalg.norm(xdot))
    Rdot = (to_matrix(x + h * xdot) - to_matrix(x - h * xdot)) / (2 * h)
    R = to_matrix(x)
    expected = R @ rot.skew(omega) if frame == "body" else rot.skew(omega) @ R
    np.testing.assert_allclose(Rdot, expected, atol=1e-6 * (1 + np.linalg.norm(xdot)))


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("name", list(MINIMAL))
@given(data=st.data(), omega=omegas)
def test_rate_matrix_solves_the_kinematic_equation(name, frame, data, omega):
    par = MINIMAL[name]
    x = data.draw(par["values"])
    assume(par["regularity"](x) > 0.05)
    assert_kinematics(par["to_matrix"], x, par["rate"](x, frame) @ omega, omega, frame)


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("name", list(MINIMAL))
@given(data=st.data(), xdot=vectors(-5, 5))
def test_angular_velocity_matrix_gives_the_angular_velocity(name, frame, data, xdot):
    par = MINIMAL[name]
    x = data.draw(par["values"])
    omega = par["angular_velocity"](x, frame) @ xdot
    assert_kinematics(par["to_matrix"], x, xdot, omega, frame)


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("name", list(MINIMAL))
@given(data=st.data())
def test_rate_matrix_inverts_angular_velocity_matrix(name, frame, data):
    par = MINIMAL[name]
    x = data.draw(par["values"])
    regularity = par["regularity"](x)
    assume(regularity > 1e-3)
    K, G = par["rate"](x, frame), par["angular_velocity"](x, frame)
    np.testing.assert_allclose(K @ G, np.eye(3), atol=1e-12 / regularity**2)
    np.testing.assert_allclose(G @ K, np.eye(3), atol=1e-12 / regularity**2)


@pytest.mark.parametrize("frame", FRAMES)
@given(p=unit_quaternions, omega=omegas)
def test_quaternion_rates_solve_the_kinematic_equation(frame, p, omega):
    pdot = rot.quaternion_rates(p, omega, frame)
    assert pdot @ p == pytest.approx(0.0, abs=1e-12)  # keeps |p| = 1
    assert_kinematics(rot.quaternion_to_matrix, p, pdot, omega, frame)
    np.testing.assert_allclose(rot.quaternion_angular_velocity(p, pdot, frame), omega, atol=1e-12)


@pytest.mark.parametrize("frame", FRAMES)
@given(p=unit_quaternions, pdot=vectors(-5, 5, 4))
def test_quaternion_angular_velocity_ignores_changes_of_norm(frame, p, pdot):
    tangent = pdot - (pdot @ p) * p
    omega = rot.quaternion_angular_velocity(p, pdot, frame)
    np.testing.assert_allclose(
        omega, rot.quaternion_angular_velocity(p, tangent, frame), atol=1e-12
    )
    assert_kinematics(rot.quaternion_to_matrix, p, tangent, omega, frame)
    H, G2 = rot.quaternion_rate_matrix(p, frame), rot.quaternion_angular_velocity_matrix(p, frame)
    np.testing.assert_allclose(G2 @ H, np.eye(3), atol=1e-14)


@given(p=unit_quaternions, omega=omegas)
def test_body_and_inertial_angular_velocities_are_related_by_R(p, omega):
    R = rot.quaternion_to_matrix(p)
    np.testing.assert_allclose(
        rot.quaternion_rates(p, omega, "body"),
        rot.quaternion_rates(p, R @ omega, "inertial"),
        atol=1e-12,
    )


@pytest.mark.parametrize(
    "function",
    [
        rot.cardan_xyz_rate_matrix,
        rot.cardan_xyz_angular_velocity_matrix,
        rot.euler_zxz_rate_matrix,
        rot.euler_zxz_angular_velocity_matrix,
        rot.rodrigues_rate_matrix,
        rot.rodrigues_angular_velocity_matrix,
        lambda x, frame: rot.quaternion_rates(np.array([1.0, 0, 0, 0]), x, frame),
        lambda x, frame: rot.quaternion_angular_velocity(
            np.array([1.0, 0, 0, 0]), np.append(x, 0), frame
        ),
    ],
)
def test_an_unknown_frame_is_rejected(function):
    with pytest.raises(ValueError, match="frame"):
        function(np.array([0.1, 0.2, 0.3]), "world")


# --- singularities ------------------------------------------------------------------------

SINGULAR = [
    ("Cardan", rot.matrix_to_cardan_xyz, rot.cardan_xyz_to_matrix, [0.3, PI / 2, -0.2]),
    ("Cardan", rot.matrix_to_cardan_xyz, rot.cardan_xyz_to_matrix, [0.3, -PI / 2, -0.2]),
    ("Euler", rot.matrix_to_euler_zxz, rot.euler_zxz_to_matrix, [0.3, 0.0, -0.2]),
    ("Euler", rot.matrix_to_euler_zxz, rot.euler_zxz_to_matrix, [0.3, PI, -0.2]),
]


@pytest.mark.parametrize("what, from_matrix, to_matrix, angles", SINGULAR)
def test_angles_from_a_matrix_in_gimbal_lock_raise(what, from_matrix, to_matrix, angles):
    with pytest.raises(rot.SingularityError, match=what) as error:
        from_matrix(to_matrix(np.array(angles)))
    assert "Euler parameters" in str(error.value)
    assert isinstance(error.value, WorkbenchError) and isinstance(error.value, ValueError)


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize(
    "what, rate, angles",
    [
        ("Cardan", rot.cardan_xyz_rate_matrix, [0.3, PI / 2, -0.2]),
        ("Cardan", rot.cardan_xyz_rate_matrix, [0.3, -PI / 2, -0.2]),
        ("Euler", rot.euler_zxz_rate_matrix, [0.3, 0.0, -0.2]),
        ("Euler", rot.euler_zxz_rate_matrix, [0.3, PI, -0.2]),
    ],
)
def test_rate_matrix_at_the_singularity_raises(what, rate, angles, frame):
    with pytest.raises(rot.SingularityError, match="(?i)use Euler parameters"):
        rate(np.array(angles), frame)
    with pytest.raises(rot.SingularityError, match=what):
        rate(np.array(angles), frame)


@pytest.mark.parametrize("axis", [[1.0, 0, 0], [0, 0, 1.0], [0.6, 0, -0.8]])
def test_rodrigues_vector_of_a_half_turn_raises(axis):
    with pytest.raises(rot.SingularityError, match="Rodrigues.*Euler parameters"):
        rot.matrix_to_rodrigues(rot.axis_angle_to_matrix(np.array(axis), PI))


def test_singularity_tolerance_is_on_the_vanishing_quantity():
    near = np.array([0.3, PI / 2 - 1e-6, -0.2])  # |cos b| = 1e-6
    R = rot.cardan_xyz_to_matrix(near)
    np.testing.assert_allclose(rot.cardan_xyz_to_matrix(rot.matrix_to_cardan_xyz(R)), R, atol=1e-9)
    rot.cardan_xyz_rate_matrix(near)
    with pytest.raises(rot.SingularityError):
        rot.matrix_to_cardan_xyz(R, tol=1e-5)
    with pytest.raises(rot.SingularityError):
        rot.cardan_xyz_rate_matrix(near, tol=1e-5)
    half_turn = rot.axis_angle_to_matrix(np.array([0.0, 1.0, 0.0]), PI - 2e-6)  # p0 = 1e-6
    np.testing.assert_allclose(rot.matrix_to_rodrigues(half_turn), [0, 1e6, 0], rtol=1e-6)
    with pytest.raises(rot.SingularityError):
        rot.matrix_to_rodrigues(half_turn, tol=1e-5)


def test_symbolic_rate_matrix_returns_the_formula_at_the_singularity():
    angles = ca.SX.sym("angles", 3)
    rate = ca.Function("K", [angles], [rot.cardan_xyz_rate_matrix(angles)])
    K = np.array(rate([0.3, PI / 2, -0.2]))
    assert not np.all(np.isfinite(K)) or np.abs(K).max() > 1e12


# --- CasADi: the same numbers from symbols ------------------------------------------------

_rng = np.random.default_rng(3)
_R = Rotation.random(random_state=4).as_matrix()
_p = scipy_quaternion(Rotation.random(random_state=5))
_q = scipy_quaternion(Rotation.random(random_state=6))
_x = np.array([0.4, -0.7, 1.2])
_omega = np.array([0.3, -2.0, 1.1])
_pdot = _rng.normal(size=4)
_axis = _normalized(np.array([1.0, -2.0, 0.5]))

CASADI_CASES = [
    ("skew", rot.skew, [_x]),
    ("axis_angle_to_matrix", rot.axis_angle_to_matrix, [_axis, 0.7]),
    ("quaternion_to_matrix", rot.quaternion_to_matrix, [_p]),
    ("elementary_rotation_x", lambda t: rot.elementary_rotation("x", t), [0.7]),
    ("elementary_rotation_1", lambda t: rot.elementary_rotation(1, t), [0.7]),
    ("elementary_rotation_z", lambda t: rot.elementary_rotation("z", t), [0.7]),
    ("compose", rot.compose, [_R, _R.T @ _R @ _R, np.eye(3)]),
    ("matrix_to_axis_angle", rot.matrix_to_axis_angle, [_R]),
    ("axis_angle_to_quaternion", rot.axis_angle_to_quaternion, [_axis, 0.7]),
    ("quaternion_multiply", rot.quaternion_multiply, [_p, _q]),
    ("quaternion_conjugate", rot.quaternion_conjugate, [_p]),
    ("matrix_to_quaternion", rot.matrix_to_quaternion, [_R]),
    ("normalize_quaternion", rot.normalize_quaternion, [3 * _p]),
    ("cardan_xyz_to_matrix", rot.cardan_xyz_to_matrix, [_x]),
    ("matrix_to_cardan_xyz", rot.matrix_to_cardan_xyz, [_R]),
    ("euler_zxz_to_matrix", rot.euler_zxz_to_matrix, [_x]),
    ("matrix_to_euler_zxz", rot.matrix_to_euler_zxz, [_R]),
    ("rodrigues_to_matrix", rot.rodrigues_to_matrix, [_x]),
    ("matrix_to_rodrigues", rot.matrix_to_rodrigues, [_R]),
]
for _frame in FRAMES:
    CASADI_CASES += [
        (f"{f.__name__}_{_frame}", lambda *a, f=f, fr=_frame: f(*a, fr), args)
        for f, args in [
            (rot.quaternion_rate_matrix, [_p]),
            (rot.quaternion_angular_velocity_matrix, [_p]),
            (rot.quaternion_rates, [_p, _omega]),
            (rot.quaternion_angular_velocity, [_p, _pdot]),
            (rot.cardan_xyz_rate_matrix, [_x]),
            (rot.cardan_xyz_angular_velocity_matrix, [_x]),
            (rot.euler_zxz_rate_matrix, [_x]),
            (rot.euler_zxz_angular_velocity_matrix, [_x]),
            (rot.rodrigues_rate_matrix, [_x]),
            (rot.rodrigues_angular_velocity_matrix, [_x]),
        ]
    ]


def symbolic_function(function, numeric_args):
    """A casadi.Function of ``function`` built from SX symbols shaped like ``numeric_args``."""
    symbols = [
        ca.SX.sym(f"a{i}", *(np.shape(a) + (1,) * (2 - np.ndim(a))))
        for i, a in enumerate(numeric_args)
    ]
    outputs = function(*symbols)
    outputs = list(outputs) if isinstance(outputs, tuple) else [outputs]
    assert all(isinstance(out, ca.SX) for out in outputs)
    return ca.Function("f", symbols, outputs)


@pytest.mark.parametrize("name, function, args", CASADI_CASES, ids=[c[0] for c in CASADI_CASES])
def test_casadi_symbols_give_the_numpy_numbers(name, function, args):
    expected = function(*args)
    expected = list(expected) if isinstance(expected, tuple) else [expected]
    results = symbolic_function(function, args)(*args)
    results = list(results) if isinstance(results, tuple) else [results]
    for result, value in zip(results, expected, strict=True):
        value = np.asarray(value, dtype=float)
        np.testing.assert_allclose(np.array(result).reshape(value.shape), value, atol=1e-13)


@pytest.mark.parametrize(
    "axis, angle",
    [
        ([1.0, 0, 0], 0.0),
        ([1.0, 0, 0], PI),
        ([0, 1.0, 0], PI),
        ([0, 0, 1.0], PI),
        ([0.6, -0.8, 0], PI - 1e-9),
        ([0, 0.6, 0.8], 2.5),
    ],
)
def test_casadi_matrix_to_quaternion_selects_the_robust_branch(axis, angle):
    # each case makes a different entry of Shepperd's table the largest
    R = rot.axis_angle_to_matrix(np.array(axis), angle)
    to_quaternion = symbolic_function(rot.matrix_to_quaternion, [R])
    to_axis_angle = symbolic_function(rot.matrix_to_axis_angle, [R])
    np.testing.assert_allclose(
        np.array(to_quaternion(R)).ravel(), rot.matrix_to_quaternion(R), atol=1e-15
    )
    symbolic_axis, symbolic_angle = to_axis_angle(R)
    numeric_axis, numeric_angle = rot.matrix_to_axis_angle(R)
    np.testing.assert_allclose(np.array(symbolic_axis).ravel(), numeric_axis, atol=1e-15)
    assert float(symbolic_angle) == pytest.approx(numeric_angle, abs=1e-15)
