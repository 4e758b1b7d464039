"""The starter problems: registered, valid, right DOF, consistent initial states, invariants."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from workbench.execution.references import given_reference
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
from workbench.mechanics.topology import analyze
from workbench.plugin.registry import get_problem
from workbench.problems import heavy_top, simple_pendulum

STARTERS = {
    # name: (dof, loops)
    "simple-pendulum": (1, 0),
    "double-pendulum": (2, 0),
    "slider-crank": (1, 1),
    "heavy-top": (3, 0),
}


def initial_state(problem):
    """(kinematics, q0, v0) of a problem's initial joint values."""
    model = problem.model()
    kinematics = TreeKinematics(model)
    q0 = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    v0 = initial_joint_values(model, kinematics, problem.initial_joint_velocities(), True)
    return kinematics, q0, v0


def evaluate(kinematics, expressions, q0, v0, t=0.0):
    f = ca.Function("f", [kinematics.t, kinematics.q, kinematics.v], expressions)
    out = f(t, q0, v0)
    out = out if isinstance(out, list | tuple) else [out]
    return [np.asarray(ca.DM(x), dtype=float) for x in out]


@pytest.mark.parametrize("name", list(STARTERS))
def test_registered_valid_with_dof_and_loops(name: str) -> None:
    problem = get_problem(name)()
    assert problem.name == name and problem.summary and problem.source
    model = problem.model()
    assert model.validate() is model
    topology = analyze(model)
    dof, loops = STARTERS[name]
    assert topology.dof_gruebler == dof
    assert topology.dof == dof
    assert topology.n_loops == loops
    assert topology.redundant_constraints == []
    assert problem.t_end > problem.t_start


@pytest.mark.parametrize("name", list(STARTERS))
def test_initial_state_satisfies_the_constraints(name: str) -> None:
    kinematics, q0, v0 = initial_state(get_problem(name)())
    g, Wv = evaluate(
        kinematics, [kinematics.closure_constraints, kinematics.velocity_constraints], q0, v0
    )
    assert np.all(np.abs(g) < 1e-12) and np.all(np.abs(Wv) < 1e-12)


# ---- simple pendulum -------------------------------------------------------------


def test_simple_pendulum_geometry_and_options() -> None:
    problem = get_problem("simple-pendulum")({"initial_angle": 0.3})
    kinematics, q0, v0 = initial_state(problem)
    bob = kinematics.bodies["bob"]
    (position,) = evaluate(kinematics, [bob.position], q0, v0)
    l = simple_pendulum.LENGTH
    assert np.allclose(position.ravel(), [l * math.sin(0.3), -l * math.cos(0.3), 0.0])
    assert given_reference(problem) is None
    assert problem.t_end == 10.0
    assert get_problem("simple-pendulum")().options.initial_angle == 0.5


def test_simple_pendulum_rejects_bad_angle() -> None:
    from workbench.errors import ConfigError

    with pytest.raises(ConfigError, match="initial_angle"):
        get_problem("simple-pendulum")({"initial_angle": 4.0})


def test_pendulum_solutions() -> None:
    l, g = 1.0, 9.81
    t = np.linspace(0.0, 10.0, 1001)
    small = simple_pendulum.small_angle_solution(t, 1e-3, l, g)
    exact = simple_pendulum.exact_solution(t, 1e-3, l, g)
    assert np.max(np.abs(exact - small)) < 1e-8
    # the exact solution solves theta'' = -(g / l) sin(theta) and has the elliptic period
    theta0 = 2.0
    dt = 1e-4
    tt = np.linspace(0.1, 3.0, 30)
    th = simple_pendulum.exact_solution(np.stack([tt - dt, tt, tt + dt]), theta0, l, g)
    acceleration = (th[0] - 2 * th[1] + th[2]) / dt**2
    assert np.allclose(acceleration, -g / l * np.sin(th[1]), atol=1e-4)
    period = simple_pendulum.period(theta0, l, g)
    assert simple_pendulum.exact_solution(period, theta0, l, g) == pytest.approx(theta0)
    assert simple_pendulum.exact_solution(0.0, -0.5, l, g) == pytest.approx(-0.5)


# ---- slider-crank ----------------------------------------------------------------


def test_slider_crank_declares_the_crank_independent() -> None:
    problem = get_problem("slider-crank")()
    assert problem.independent_coordinates == (("crank", 0),)
    assert "crank" in problem.model().joints


@pytest.mark.parametrize("angle", [0.0, 0.7, 2.5, -1.9])
def test_slider_crank_consistent_for_any_crank_angle(angle: float) -> None:
    problem = get_problem("slider-crank")(
        {"initial_crank_angle": angle, "initial_crank_rate": -3.0}
    )
    kinematics, q0, v0 = initial_state(problem)
    g, Wv = evaluate(
        kinematics, [kinematics.closure_constraints, kinematics.velocity_constraints], q0, v0
    )
    assert np.all(np.abs(g) < 1e-12) and np.all(np.abs(Wv) < 1e-12)
    assert analyze(problem.model(), q=q0).dof == 1


# ---- heavy top ---------------------------------------------------------------------


def top_state(quaternion, omega):
    poses = np.array([[0.0, 0.0, 0.0, *quaternion]])
    twists = np.array([[0.0, 0.0, 0.0, *omega]])
    return poses, twists


def test_heavy_top_upright_spin_invariants() -> None:
    problem = get_problem("heavy-top")()
    model = problem.model()
    invariants = {inv.name: inv.function for inv in problem.invariants()}
    assert set(invariants) == {"vertical_angular_momentum", "spin"}
    poses, twists = top_state((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 40.0))
    C = heavy_top.AXIAL_INERTIA
    assert invariants["vertical_angular_momentum"](model, 0.0, poses, twists) == pytest.approx(
        C * 40.0
    )
    assert invariants["spin"](model, 0.0, poses, twists) == pytest.approx(40.0)


def test_heavy_top_tilted_precession_invariants() -> None:
    """Tilted by theta about x, turning at Omega about the vertical only."""
    model = get_problem("heavy-top")().model()
    theta, rate = 0.4, 2.0
    poses, twists = top_state((math.cos(theta / 2), math.sin(theta / 2), 0, 0), (0, 0, rate))
    A, C = heavy_top.TRANSVERSE_INERTIA, heavy_top.AXIAL_INERTIA
    m, a = heavy_top.MASS, heavy_top.COM_DISTANCE
    expected = rate * ((A + m * a**2) * math.sin(theta) ** 2 + C * math.cos(theta) ** 2)
    assert heavy_top.vertical_angular_momentum(model, 0.0, poses, twists) == pytest.approx(expected)
    assert heavy_top.spin(model, 0.0, poses, twists) == pytest.approx(rate * math.cos(theta))


def test_heavy_top_initial_state() -> None:
    problem = get_problem("heavy-top")({"initial_tilt": 0.3, "spin": 50.0})
    kinematics, q0, v0 = initial_state(problem)
    top = kinematics.bodies["top"]
    rotation, omega = evaluate(kinematics, [top.rotation, top.angular_velocity], q0, v0)
    axis = rotation[:, 2]
    assert axis @ np.array([0.0, 0.0, 1.0]) == pytest.approx(math.cos(0.3))
    assert np.allclose(omega.ravel(), 50.0 * axis)


def test_heavy_top_invariants_conserved_along_euler_equations() -> None:
    """Integrate the top's Euler equations about the tip independently of any formalism."""
    from scipy.integrate import solve_ivp
    from scipy.spatial.transform import Rotation

    from workbench.numerics.rotations import quaternion_rate_matrix

    problem = get_problem("heavy-top")()
    model = problem.model()
    body = model.bodies["top"]
    inertia_tip = body.inertia + body.mass * (
        body.com @ body.com * np.eye(3) - np.outer(body.com, body.com)
    )

    def rhs(t, y):
        p, omega = y[:4], y[4:]
        rotation = Rotation.from_quat([*p[1:], p[0]]).as_matrix()
        torque = np.cross(body.com, body.mass * rotation.T @ model.gravity)
        alpha = np.linalg.solve(inertia_tip, torque - np.cross(omega, inertia_tip @ omega))
        return np.concatenate([quaternion_rate_matrix(p, "body") @ omega, alpha])

    y0 = np.concatenate(
        [problem.initial_joint_coordinates()["tip"], problem.initial_joint_velocities()["tip"]]
    )
    solution = solve_ivp(rhs, (0.0, 1.0), y0, rtol=1e-10, atol=1e-12, t_eval=[0.0, 0.4, 1.0])
    values = []
    for p, omega_body in zip(solution.y[:4].T, solution.y[4:].T, strict=True):
        p = p / np.linalg.norm(p)
        rotation = Rotation.from_quat([*p[1:], p[0]]).as_matrix()
        poses, twists = top_state(p, rotation @ omega_body)
        values.append([inv.function(model, 0.0, poses, twists) for inv in problem.invariants()])
    values = np.array(values)
    assert np.allclose(values, values[0], rtol=1e-7)
    assert values[0, 1] == pytest.approx(50.0)
