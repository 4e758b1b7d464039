"""Multibody integrators: rattle, generalized-alpha and projected.

Oracles independent of the methods under test: a point-mass pendulum written by hand in
absolute coordinates (x, y) with g = x^2 + y^2 - l^2 (constant M = m I, q' = v); the
slider-crank in joint coordinates (minimal-ode) with a tight DOP853 reference on its
index-1 ode form; the multipliers of [M W^T; W 0] at the states reached.
"""

from __future__ import annotations

import math
import warnings

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from workbench.equations import MechanicalSystem, build_equations
from workbench.equations.initial import accelerations, consistent_initial_state
from workbench.errors import PluginError
from workbench.mechanics.forces import generalized_forces, potential_energy
from workbench.mechanics.kinematics import BodyState
from workbench.model import AppliedForce, Frame, Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import get_formalism, get_integrator
from workbench.plugins.formalisms.minimal_ode import MinimalOde
from workbench.plugins.integrators.generalized_alpha import GeneralizedAlpha
from workbench.plugins.integrators.projection import Projected, project_state
from workbench.plugins.integrators.rattle import Rattle

warnings.filterwarnings("ignore", category=FutureWarning)

LENGTH, MASS = 1.0, 1.0


# ---- a point-mass pendulum in absolute coordinates, by hand ----------------------------


def pendulum_model(nan_after: float | None = None) -> Model:
    model = Model("point-pendulum", kind="planar", gravity=(0.0, -9.81, 0.0))
    model.add_point_mass("bob", MASS)
    model.add_joint("pivot", "revolute", "ground", "bob", child_frame=Frame.at(0, LENGTH, 0))
    if nan_after is not None:
        model.add_force(AppliedForce("poison", "bob", np.zeros(3), nan_force(nan_after)))
    return model


def nan_force(after: float):
    def function(t, position, rotation, velocity, angular_velocity):
        return ca.vertcat(ca.if_else(t > after, math.nan, 0.0), 0, 0), ca.DM.zeros(3)

    return function


class PendulumProblem(Problem):
    name = "test-point-pendulum"

    def model(self) -> Model:
        return pendulum_model()

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"pivot": 1.0}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"pivot": 0.0}


def absolute_pendulum(model: Model, baumgarte: tuple[float, float] = (0.0, 0.0)):
    """Equations of a point mass at (x, y) on a rod of length l to the origin."""
    t, q, v = ca.SX.sym("t"), ca.SX.sym("q", 2), ca.SX.sym("v", 2)
    theta = ca.atan2(q[0], -q[1])  # the joint angle, for the body's orientation
    rotation = ca.SX.eye(3)
    rotation[0, 0], rotation[0, 1] = ca.cos(theta), -ca.sin(theta)
    rotation[1, 0], rotation[1, 1] = ca.sin(theta), ca.cos(theta)
    omega = ca.vertcat(0, 0, ca.mtimes(ca.jacobian(theta, q), v))
    bob = BodyState(ca.vertcat(q, 0), rotation, ca.vertcat(v, 0), omega)
    bodies = {"bob": bob}
    g = q[0] ** 2 + q[1] ** 2 - LENGTH**2
    system = MechanicalSystem(
        t=t,
        q=q,
        v=v,
        qdot=v,
        mass=MASS * ca.SX.eye(2),
        forces=generalized_forces(model, t, v, bodies, {}),
        q_names=["x", "y"],
        v_names=["vx", "vy"],
        position_constraints=g,
        velocity_constraints=ca.jacobian(g, q) @ v,
        constraint_names=["rod"],
    )
    t_j, q_j, v_j = ca.SX.sym("t"), ca.SX.sym("qj"), ca.SX.sym("vj")
    xy = ca.vertcat(LENGTH * ca.sin(q_j), -LENGTH * ca.cos(q_j))
    joint_map = ([t_j, q_j, v_j], [xy, ca.jacobian(xy, q_j) * v_j])
    assert potential_energy(model, bodies, {}) is not None
    return build_equations(
        "hand-absolute", model, system, bodies, joint_map, dae_index=3, baumgarte=baumgarte
    )


def energy(eq, times, y):
    nq, nv = eq.nq, eq.nv
    return np.array(
        [
            eq.observables.energy(t, r[:nq], r[nq : nq + nv])[0].sum()
            for t, r in zip(times, y, strict=True)
        ]
    )


# ---- slider-crank in joint coordinates ---------------------------------------------------


class SliderCrankProblem(Problem):
    name = "test-slider-crank"
    independent_coordinates = (("j1", 0),)

    def model(self) -> Model:
        m = Model("slider-crank", kind="planar")
        m.add_body("crank", 1, com=(0.05, 0, 0), inertia=0.01)
        m.add_body("rod", 1, com=(0.2, 0, 0), inertia=0.02)
        m.add_body("slider", 1, inertia=0.01)
        m.add_joint("j1", "revolute", "ground", "crank")
        m.add_joint("j2", "revolute", "crank", "rod", parent_frame=Frame.at(0.1))
        m.add_joint("j3", "prismatic", "ground", "slider", axis=(1, 0, 0))
        m.add_joint("j4", "revolute", "rod", "slider", parent_frame=Frame.at(0.4), cut=True)
        return m

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"j1": 1.0, "j3": 0.45, "j2": -1.2}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"j1": 10.0}


@pytest.fixture(scope="module")
def slider_crank():
    problem = SliderCrankProblem()
    eq3 = MinimalOde().build(problem.model(), {"index": 3})
    state = consistent_initial_state(eq3, problem)
    return problem, eq3, state


def registered_formalism_or_skip(name: str):
    try:
        return get_formalism(name)
    except PluginError as error:
        pytest.skip(f"formalism {name!r} is not available: {error}")


def registered_or_skip(name: str):
    try:
        return get_integrator(name)
    except PluginError as error:
        pytest.skip(f"integrator {name!r} is not available yet: {error}")


# ---- (1) rattle keeps the energy bounded, rk4 drifts -------------------------------------


def test_rattle_refuses_what_it_cannot_integrate(slider_crank):
    _, eq3, _ = slider_crank
    reason = Rattle().incompatibility(eq3, Rattle.parse_options())
    assert reason and "constant mass matrix" in reason
    assert Rattle().incompatibility(absolute_pendulum(pendulum_model()), None) is None
    with pytest.raises(PluginError, match="constant mass"):
        Rattle().solve(eq3, np.zeros(6), None, [0.0, 1.0], 1e-6, 1e-6)


def test_rattle_energy_bounded_where_rk4_drifts():
    rk4 = registered_or_skip("rk4")
    eq = absolute_pendulum(pendulum_model())
    state = consistent_initial_state(eq, PendulumProblem())
    times = np.linspace(0.0, 100.0, 5001)
    step = 0.02
    rattle = Rattle().solve(eq, state.y0(eq, "mechanical"), None, times, 1e-6, 1e-6, {"step": step})
    assert rattle.success, rattle.message
    ode = rk4().solve(eq, state.y0(eq, "ode"), None, times, 1e-6, 1e-6, {"step": step}, form="ode")
    assert ode.success, ode.message
    first, last = times <= 10.0, times >= 90.0
    e0 = energy(eq, times[:1], rattle.y[:1])[0]
    rattle_error = np.abs(energy(eq, times, rattle.y) - e0)
    rk4_error = np.abs(energy(eq, times, ode.y) - e0)
    assert rattle_error[last].max() <= 2.0 * rattle_error[first].max()
    assert rattle_error.max() < 1e-2 * abs(e0)
    # rk4 drifts: the error grows over the run (decade maxima increase), last > 5 x first
    decades = [rk4_error[(times > 10 * k) & (times <= 10 * (k + 1))].max() for k in range(10)]
    assert all(b > a for a, b in zip(decades, decades[1:], strict=False))
    assert rk4_error[last].max() > 5 * rk4_error[first].max()
    # the constraint is kept exactly by rattle
    g = [
        eq.forms["mechanical"].position_constraints(t, r[:2])[0]
        for t, r in zip(times, rattle.y, strict=True)
    ]
    assert np.max(np.abs(g)) < 1e-12


class BarPendulum(Problem):
    """A uniform bar on a pivot; body frame at its centre of mass or at the pivot."""

    name = "test-bar-pendulum"

    def __init__(self, frame_at_com: bool = True) -> None:
        super().__init__()
        self.frame_at_com = frame_at_com

    def model(self) -> Model:
        m = Model("bar", kind="planar")
        if self.frame_at_com:
            m.add_body("bar", 2.0, inertia=2.0 / 12)
            m.add_joint("pivot", "revolute", "ground", "bar", child_frame=Frame.at(-0.5))
        else:
            m.add_body("bar", 2.0, com=(0.5, 0, 0), inertia=2.0 / 12)
            m.add_joint("pivot", "revolute", "ground", "bar")
        return m

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"pivot": -0.5}


def test_rattle_on_absolute_dae_planar_rigid_body():
    absolute = registered_formalism_or_skip("absolute-dae")
    offset = absolute().build(BarPendulum(frame_at_com=False).model(), {"index": 3})
    assert "constant mass matrix" in Rattle().incompatibility(offset, None)
    problem = BarPendulum()
    eq = absolute().build(problem.model(), {"index": 3})
    assert Rattle().incompatibility(eq, None) is None
    state = consistent_initial_state(eq, problem)
    times = np.linspace(0.0, 20.0, 1001)
    result = Rattle().solve(eq, state.y0(eq, "mechanical"), None, times, 1e-6, 1e-6, {"step": 0.02})
    assert result.success, result.message
    error = np.abs(energy(eq, times, result.y) - energy(eq, times[:1], result.y[:1])[0])
    assert error[times >= 15].max() <= 2 * error[times <= 5].max() + 1e-12
    assert error.max() < 2e-3 * np.abs(energy(eq, times[:1], result.y[:1])[0])


# ---- (2) generalized-alpha: order 2, g = 0, multipliers ---------------------------------


@pytest.mark.parametrize("rho_inf", [0.6, 0.9])
def test_generalized_alpha_order_two_on_slider_crank(slider_crank, rho_inf):
    problem, eq3, state = slider_crank
    eq1 = MinimalOde().build(problem.model(), {"index": 1})
    t_end = 1.0
    rhs = eq1.forms["ode"].rhs
    reference = solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, t_end),
        np.r_[state.q, state.v],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[:3, -1]
    mech = eq3.forms["mechanical"]
    steps, errors = [4e-3, 2e-3, 1e-3, 5e-4], []
    times = np.linspace(0.0, t_end, 11)
    for step in steps:
        result = GeneralizedAlpha().solve(
            eq3,
            state.y0(eq3, "mechanical"),
            None,
            times,
            1e-6,
            1e-6,
            {"rho_inf": rho_inf, "step": step},
        )
        assert result.success, result.message
        assert result.stats.n_newton >= result.stats.n_steps and result.stats.n_lu > 0
        errors.append(np.abs(result.y[-1, :3] - reference).max())
        residual = max(
            np.abs(mech.position_constraints(t, y[:3])[0]).max()
            for t, y in zip(result.times, result.y, strict=True)
        )
        assert residual < 1e-13
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 2.0) < 0.5, (slope, errors)
    # multipliers: exact at t0, and those of [M W^T; W 0] at every state reached (O(h))
    np.testing.assert_allclose(result.y[0, 6:], state.multipliers, rtol=1e-12, atol=1e-12)
    for t, y in zip(result.times, result.y, strict=True):
        _, lam, _ = accelerations(eq3, t, y[:3], y[3:6])
        assert np.abs(y[6:] - lam).max() < 1e-2 * (1 + np.abs(lam).max())


def test_generalized_alpha_order_two_with_euler_parameters():
    """nq != nv: q' = H(q) omega with Euler parameters (absolute-dae, spatial)."""
    absolute = registered_formalism_or_skip("absolute-dae")

    class SphericalPendulum(Problem):
        name = "test-spherical-pendulum"

        def model(self) -> Model:
            m = Model("sph", kind="spatial")
            m.add_body("b", 1.0, inertia=(0.02, 0.03, 0.04))
            m.add_joint("s", "spherical", "ground", "b", child_frame=Frame.at(0, 0, 0.5))
            return m

        def initial_joint_coordinates(self) -> dict:
            return {"s": np.array([math.cos(0.3), math.sin(0.3), 0.0, 0.0])}

        def initial_joint_velocities(self) -> dict:
            return {"s": np.array([0.0, 2.0, 5.0])}

    problem = SphericalPendulum()
    eq = absolute().build(problem.model(), {"index": 3})
    assert eq.nq == eq.nv + 1
    state = consistent_initial_state(eq, problem)
    rhs = absolute().build(problem.model(), {"index": 1}).forms["ode"].rhs
    reference = solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, 1.0),
        np.r_[state.q, state.v],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[: eq.nq, -1]
    steps, errors = [4e-3, 2e-3, 1e-3], []
    for step in steps:
        result = GeneralizedAlpha().solve(
            eq, state.y0(eq, "mechanical"), None, [0.0, 1.0], 1e-6, 1e-6, {"step": step}
        )
        assert result.success, result.message
        errors.append(np.abs(result.y[-1, : eq.nq] - reference).max())
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 2.0) < 0.5, (slope, errors)


def test_generalized_alpha_adaptive(slider_crank):
    _, eq3, state = slider_crank
    times = np.linspace(0.0, 0.5, 6)
    loose = GeneralizedAlpha().solve(
        eq3, state.y0(eq3, "mechanical"), None, times, 1e-4, 1e-4, {"adaptive": True}
    )
    tight = GeneralizedAlpha().solve(
        eq3, state.y0(eq3, "mechanical"), None, times, 1e-7, 1e-7, {"adaptive": True}
    )
    assert loose.success and tight.success
    assert tight.stats.n_steps > 3 * loose.stats.n_steps
    np.testing.assert_allclose(loose.times, times)


# ---- (3) projection ------------------------------------------------------------------------


def test_projection_keeps_constraints(slider_crank):
    registered_or_skip("rk4")
    problem, _, _ = slider_crank
    eq1 = MinimalOde().build(
        problem.model(), {"index": 1, "baumgarte_alpha": 0.0, "baumgarte_beta": 0.0}
    )
    state = consistent_initial_state(eq1, problem)
    mech = eq1.forms["mechanical"]
    times = np.linspace(0.0, 2.0, 41)

    def residuals(result):
        return np.array(
            [
                [
                    np.abs(mech.position_constraints(t, y[:3])[0]).max(),
                    np.abs(mech.velocity_constraints(t, y[:3], y[3:])[0]).max(),
                ]
                for t, y in zip(result.times, result.y, strict=True)
            ]
        )

    runs = {}
    for projection in ("none", "position", "position+velocity"):
        runs[projection] = Projected().solve(
            eq1,
            state.y0(eq1, "ode"),
            None,
            times,
            1e-6,
            1e-6,
            {"base": "rk4", "projection": projection, "base_options": {"step": 5e-3}},
        )
        assert runs[projection].success, runs[projection].message
    free, position, both = (residuals(runs[k]) for k in ("none", "position", "position+velocity"))
    assert both.max() < 1e-10
    assert position[:, 0].max() < 1e-10
    # without projection the residuals grow (drift of the index-1 formulation)
    assert free[-1, 0] > 100 * max(free[1, 0], 1e-16) and free[-1, 0] > 1e-9
    assert free[:, 1].max() > 1e-8


def test_project_state_metrics(slider_crank):
    _, eq3, state = slider_crank
    mech = eq3.forms["mechanical"]
    y = np.r_[state.q + 0.01, state.v + 0.1]
    for metric in ("mass", "identity"):
        projected, _ = project_state(eq3, 0.0, y, "position+velocity", metric)
        assert np.abs(mech.position_constraints(0.0, projected[:3])[0]).max() < 1e-12
        assert np.abs(mech.velocity_constraints(0.0, projected[:3], projected[3:])[0]).max() < 1e-12


# ---- (4) failures become failed trajectories ----------------------------------------------


def test_nan_force_gives_failed_trajectories():
    model = pendulum_model(nan_after=0.5)
    eq = absolute_pendulum(model, baumgarte=(5.0, 5.0))
    state = consistent_initial_state(eq, PendulumProblem())
    times = np.linspace(0.0, 1.0, 11)
    y0 = state.y0(eq, "mechanical")
    runs = {
        "generalized-alpha": GeneralizedAlpha().solve(eq, y0, None, times, 1e-6, 1e-6),
        "generalized-alpha adaptive": GeneralizedAlpha().solve(
            eq, y0, None, times, 1e-6, 1e-6, {"adaptive": True}
        ),
        "rattle": Rattle().solve(eq, y0, None, times, 1e-6, 1e-6),
    }
    try:
        get_integrator("rk4")
        runs["projected"] = Projected().solve(eq, y0, None, times, 1e-6, 1e-6)
    except PluginError:
        pass
    for name, result in runs.items():
        assert not result.success, name
        assert 0.4 <= result.t_reached <= 0.5, (name, result.t_reached)
        assert "NaN" in result.message or "nan" in result.message.lower(), (name, result.message)
        assert np.all(np.isfinite(result.y)), name


def test_generalized_alpha_follows_the_turntable_2_7_law():
    """Ball on a turntable in minimal velocities: q' = H v + f(t, q) with f from the
    moving plane. Its centre circles at 2/7 of the plane's rate (the problem's analytic
    reference). Dropping f left generalized-alpha 42 m off (a Newton failure, or ok with
    hundreds of metres on other settings); with it the error is second order in h."""
    from workbench.execution.execute import RunSpec, execute_run

    errors = []
    for step in (2e-3, 1e-3):
        spec = RunSpec(
            "ball-on-rotating-plane", "nonholonomic-projection", "generalized-alpha",
            1e-6, 1e-9, integrator_options={"step": step},
        )  # fmt: skip
        row = execute_run(spec).row
        assert row["status"] == "ok", row["message"]
        assert row["reference_kind"] == "analytic"
        errors.append(row["err_max"] / row["length_scale"])
    assert errors[1] < 2e-4
    assert 3.0 < errors[0] / errors[1] < 5.0  # order 2


@pytest.mark.parametrize("problem", ["double-point-pendulum", "point-mass-slider-crank"])
def test_projection_in_the_mass_metric_with_point_masses(problem):
    """Absolute coordinates give a point mass no rotational inertia, so M is singular; the
    mass-metric projection goes through [M B^T; B 0], nonsingular because the joints fix
    those directions (it raised LinAlgError at t = 0 when it solved with M alone)."""
    from workbench.execution.execute import RunSpec, execute_run

    spec = RunSpec(
        problem, "absolute-dae", "projected", 1e-8, 1e-11,
        formalism_options={"index": 1},
        integrator_options={"metric": "mass", "base": "scipy-dop853"},
    )  # fmt: skip
    row = execute_run(spec).row
    assert row["status"] == "ok", row["message"]
    assert row["drift_pos_max"] < 1e-10 and row["drift_vel_max"] < 1e-10
    assert row["energy_err_max"] < 1e-8  # conservative: T + V kept to the tolerance
    assert row["err_max"] < 1e-6  # against the stored reference (m)
