"""Formalism ``nonholonomic-projection``: knife edge, rolling disk, ball on a rotating plane."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from workbench.equations.initial import project_joint_state
from workbench.errors import ConfigError
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import KnifeEdge, Model, RollingDisk, RollingSphere
from workbench.plugin.registry import get_formalism

PROBLEM = SimpleNamespace(name="test", independent_coordinates=())


def build(model: Model, options: dict | None = None):
    return get_formalism("nonholonomic-projection")().build(model, options)


def start(model: Model, equations, q_joint, v_joint, t0: float = 0.0) -> np.ndarray:
    """A consistent (q, s) from joint values, through the equations' joint-space map."""
    kinematics = TreeKinematics(model)
    q, v = project_joint_state(
        kinematics, PROBLEM, t0, np.asarray(q_joint, float), np.asarray(v_joint, float)
    )
    q, s = equations.joint_space_map(t0, q, v)
    return np.concatenate([q, s])


def integrate(equations, y0: np.ndarray, t_end: float):
    rhs = equations.forms["ode"].rhs
    solution = solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, t_end),
        y0,
        method="DOP853",
        rtol=1e-11,
        atol=1e-12,
        dense_output=True,
    )
    assert solution.status == 0, solution.message
    return solution.sol


def check_invariants(equations, sol, t_end: float, nq: int, conservative: bool) -> None:
    obs = equations.observables
    energies = []
    for t in np.linspace(0.0, t_end, 21):
        y = sol(t)
        q, s = y[:nq], y[nq:]
        position, velocity, nonholonomic = obs.residuals(t, q, s)
        assert np.max(np.abs(nonholonomic)) < 1e-13
        assert np.max(np.abs(velocity), initial=0.0) < 1e-13
        assert np.max(np.abs(position), initial=0.0) < 1e-9  # drift of the height only
        energies.append(obs.energy(t, q, s)[0].sum())
    if conservative:
        assert np.ptp(energies) < 1e-9 * max(1.0, abs(energies[0]))


def knife_edge_sled() -> Model:
    """A sled on a 'planar' joint in a spatial model; the blade is 1.5 m ahead of the frame
    so the partition (heading rate dependent) never becomes singular."""
    model = Model("knife-edge", kind="spatial")
    model.add_body("sled", 2.0, com=(0.3, 0.0, 0.0), inertia=(0.1, 0.2, 0.25))
    model.add_joint("plane", "planar", "ground", "sled")
    model.add_nonholonomic(KnifeEdge("blade", "sled", np.array([1.5, 0, 0]), np.array([0, 1.0, 0])))
    return model


def test_knife_edge_conserves_energy_and_matches_minimal_ode() -> None:
    model = knife_edge_sled()
    equations = build(model)
    assert equations.v_names == ["plane.v[0]", "plane.v[1]"]
    assert equations.n_constraints == 0 and set(equations.forms) == {"ode", "dae", "mechanical"}
    y0 = start(model, equations, [0.0, 0.0, 0.3], [1.0, 0.5, 2.0])
    sol = integrate(equations, y0, 5.0)
    check_invariants(equations, sol, 5.0, 3, conservative=True)
    # the same motion from minimal-ode's index-1 ode (multipliers, Baumgarte)
    minimal = get_formalism("minimal-ode")().build(model, {"index": 1})
    kinematics = TreeKinematics(model)
    q0, v0 = project_joint_state(
        kinematics, PROBLEM, 0.0, np.array([0, 0, 0.3]), np.array([1.0, 0.5, 2.0])
    )
    reference = integrate(minimal, np.concatenate([q0, v0]), 2.0)
    assert np.allclose(sol(2.0)[:3], reference(2.0)[:3], atol=1e-8)


def test_rolling_disk_conserves_energy() -> None:
    radius, mass = 0.3, 1.0
    model = Model("rolling-disk", kind="spatial")
    model.add_body(
        "disk", mass, inertia=(mass * radius**2 / 4, mass * radius**2 / 4, mass * radius**2 / 2)
    )
    model.add_joint("free", "free", "ground", "disk")
    model.add_nonholonomic(RollingDisk("roll", "disk", radius))
    equations = build(model)
    assert len(equations.v_names) == 3  # 6 - height rate - two rolling rows
    tilted = Rotation.from_euler("x", np.pi / 2 - 0.3).as_quat()[[3, 0, 1, 2]]
    y0 = start(model, equations, np.r_[0.0, 0.0, radius, tilted], [0, 0, 0, 0.5, 0.0, 8.0])
    sol = integrate(equations, y0, 2.0)
    check_invariants(equations, sol, 2.0, 7, conservative=True)


def test_ball_on_rotating_plane_circles_at_two_sevenths_of_the_plane_rate() -> None:
    """A homogeneous ball on a plane turning at rate Omega: its centre's velocity turns at
    2 Omega / 7, so the centre runs round a fixed circle in 7 pi / Omega (book 8.3)."""
    radius, rate = 0.2, 2.0
    model = Model("ball-on-turntable", kind="spatial")
    model.add_body("ball", 1.0, inertia=np.full(3, 0.4 * radius**2))
    model.add_joint("free", "free", "ground", "ball")
    model.add_nonholonomic(RollingSphere("roll", "ball", radius, plane_rate=rate))
    equations = build(model)
    y0 = start(model, equations, [0.5, 0.0, radius, 1, 0, 0, 0], [0.2, 0.3, 0, 1.0, -2.0, 0.5])
    period = 7 * np.pi / rate
    sol = integrate(equations, y0, period)
    check_invariants(equations, sol, period, 7, conservative=False)
    obs = equations.observables
    headings, centres = [], []
    for t in np.linspace(0.0, period, 13):
        y = sol(t)
        (twist,) = obs.twists(t, y[:7], y[7:])
        headings.append(np.arctan2(twist[1], twist[0]))
        centres.append(y[:2])
    turned = np.unwrap(headings) - headings[0]
    assert np.allclose(turned, 2 * rate / 7 * np.linspace(0.0, period, 13), atol=1e-8)
    centres = np.array(centres)
    assert np.allclose(centres[-1], centres[0], atol=1e-8)
    middle = centres[:-1].mean(axis=0)  # 12 samples evenly spaced round the circle
    distances = np.linalg.norm(centres[:-1] - middle, axis=1)
    assert np.ptp(distances) < 1e-8


def test_independent_velocities_option() -> None:
    model = knife_edge_sled()
    equations = build(model, {"independent": ["plane.v[0]", "plane.v[2]"]})
    assert equations.v_names == ["plane.v[0]", "plane.v[2]"]
    with pytest.raises(ConfigError):
        build(model, {"independent": ["plane.v[9]"]})
    with pytest.raises(ConfigError):
        build(model, {"independent": ["plane.v[0]"]})  # two left for one constraint


def test_closed_loop_projection_matches_minimal_ode() -> None:
    """Closed loops go through the same projection (slider-crank: one minimal velocity)."""
    from workbench.plugin.registry import get_problem

    problem = get_problem("slider-crank")()
    model = problem.model()
    equations = build(model)
    assert len(equations.v_names) == 1
    kinematics = TreeKinematics(model)
    from workbench.mechanics.kinematics import initial_joint_values

    q0 = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    v0 = initial_joint_values(model, kinematics, problem.initial_joint_velocities(), True)
    q0, v0 = project_joint_state(kinematics, problem, 0.0, q0, v0)
    q, s = equations.joint_space_map(0.0, q0, v0)
    sol = integrate(equations, np.concatenate([q, s]), 0.5)
    minimal = get_formalism("minimal-ode")().build(model, {"index": 1})
    reference = integrate(minimal, np.concatenate([q0, v0]), 0.5)
    assert np.allclose(sol(0.5)[: q.size], reference(0.5)[: q.size], atol=1e-7)


# ---- a fixed velocity partition along a knife edge's turn (Bloch 2003, book 8.4.1) --------


def knife_edge_run(formalism: str, options: dict, integrator: str = "sundials-cvode-adams",
                   rtol: float = 1e-12):  # fmt: skip
    from workbench.execution.execute import RunSpec, execute_run

    spec = RunSpec("knife-edge-cart", formalism, integrator, rtol, rtol / 100, {}, options)
    return execute_run(spec).row


def test_knife_edge_turning_through_90_degrees_reports_its_singular_partition() -> None:
    """Heading w t (w = 2 rad/s): the dependent velocity y' has W_d = cos(heading), zero at
    t = pi/4 s. With one partition kept for the run (repartition = false) the run must say
    where it turned singular instead of losing digits silently."""
    from workbench.problems.ch8_nonholonomic import CART_YAW_RATE

    row = knife_edge_run("nonholonomic-projection", {"repartition": False})
    assert row["status"] == "ok"
    assert "singular velocity partition" in row["warnings"]
    quarter_turn = (np.pi / 2) / CART_YAW_RATE
    assert abs(row["jacobian_sv_ratio_at"] - quarter_turn) < 1e-6
    assert row["jacobian_sv_ratio_min"] < 1e-6


def test_knife_edge_with_multipliers_follows_the_circle_through_the_turn() -> None:
    """The same turn with the constraint row kept (minimal-ode, index 1): no partition, no
    warning, the analytic circle to 10 digits (the reference the projection is held to)."""
    row = knife_edge_run("minimal-ode", {"index": 1})
    assert row["status"] == "ok" and row["warnings"] == ""
    assert row["scd"] > 10


@pytest.mark.parametrize(
    ("integrator", "rtol", "digits"),
    [("sundials-cvode-adams", 1e-12, 10.5), ("scipy-dop853", 1e-12, 11), ("rk4", 1e-6, 11)],
)
def test_knife_edge_changes_partition_through_full_turns(integrator, rtol, digits) -> None:
    """Re-partitioning (Wehage and Haug): the run leaves the partition where W_d degrades
    and goes on with the best one, so the knife edge turns through 10 rad (1.6 turns: W_d
    of either partition vanishes every 90 degrees) with the digits the pipelines with
    multipliers reach (minimal-ode index 1, same integrator; measured: cvode-adams 11.2,
    dop853 13.0 (the reference's cap), rk4 11.5; one fixed partition: 9.4, 8.7 and 2.6).
    Bloch's knife edge without friction: heading rate and speed constant, energy conserved,
    the axle midpoint on the analytic circle of radius u / w, every sample measured in its
    own partition."""
    row = knife_edge_run("nonholonomic-projection", {}, integrator, rtol)
    assert row["status"] == "ok" and row["warnings"] == "", row["warnings"]
    assert "6 chart switches" in row["notes"]  # 10 rad: near 1, 2, ..., 6 times pi/2
    assert row["scd"] > digits and row["err_max"] < 10 ** -(digits - 0.5)
    assert row["invariant_err_max"] < 1e-9  # heading rate and speed
    assert row["energy_err_max"] < 1e-9
    assert row["jacobian_sv_ratio_min"] > 0.2  # the partition used never came near singular
    assert row["drift_nh_max"] < 1e-12
    fixed = knife_edge_run("nonholonomic-projection", {"repartition": False}, integrator, rtol)
    assert "singular velocity partition" in fixed["warnings"]
    assert fixed["n_rhs"] > 0 and fixed["scd"] < row["scd"]


def test_chart_by_chart_integration_adds_up_segments() -> None:
    """The run's solver statistics are the sums over the segments the integrator solved;
    a sample is kept once, in the chart it was computed in, and carries over through the
    full velocities v = F s + f at every switch (the constraint holds to round-off)."""
    from workbench.execution.charts import SWITCH_RATIO, integrate_on_charts
    from workbench.execution.execute import RunSpec, cached_equations, cached_initial_state
    from workbench.plugin.registry import get_integrator, get_problem

    problem = get_problem("knife-edge-cart")()
    spec = RunSpec("knife-edge-cart", "nonholonomic-projection", "scipy-dop853", 1e-10, 1e-12)
    equations, _ = cached_equations(spec, problem.model())
    initial = cached_initial_state(spec, equations, problem)
    inner = get_integrator("scipy-dop853")()
    solved = []

    class Counting:
        def solve(self, *args):
            trajectory = inner.solve(*args)
            solved.append((args[0], trajectory))
            return trajectory

    times = problem.sample_times()
    trajectory = integrate_on_charts(
        Counting(), equations, initial.y0(equations, "ode"), initial.yp0(equations, "ode"),
        times, 1e-10, 1e-12, inner.parse_options({}), "ode",
    )  # fmt: skip
    assert trajectory.success and np.array_equal(trajectory.times, times)
    assert len(trajectory.switches) == 6 and len(solved) > 6
    assert trajectory.stats.n_rhs == sum(t.stats.n_rhs for _, t in solved)
    assert trajectory.stats.n_steps == sum(t.stats.n_steps for _, t in solved)
    atlas = equations.atlas
    assert len({id(e) for e, _ in solved}) == 2  # two partitions, each compiled once
    for k, (t, chart) in enumerate(zip(times, trajectory.charts, strict=True)):
        q, s = trajectory.y[k, :3], trajectory.y[k, 3:]
        (_, _, nonholonomic) = atlas.equations(chart).observables.residuals(t, q, s)
        assert abs(float(np.ravel(nonholonomic)[0])) < 1e-13
        best = atlas.conditioning(atlas.best(t, q), t, q)
        assert atlas.conditioning(chart, t, q) >= SWITCH_RATIO * best


def test_repartition_is_off_with_named_independent_velocities() -> None:
    """``independent`` fixes the partition: no atlas; ``repartition`` must be a boolean."""
    model = knife_edge_sled()
    assert build(model).atlas is not None
    assert build(model, {"independent": ["plane.v[0]", "plane.v[2]"]}).atlas is None
    assert build(model, {"repartition": False}).atlas is None
