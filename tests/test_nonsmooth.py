"""Unilateral contacts, impacts and Coulomb friction (docs/nonsmooth.md): the contact form,
the element's validation, and the three contact integrators against analytic laws."""

from __future__ import annotations

import math

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.errors import ModelError, PluginError
from workbench.model import Model
from workbench.plugin import registry
from workbench.problems.ch5_contacts import (
    BALL_DROP,
    BALL_RADIUS,
    BALL_RESTITUTION,
    BLOCK_HALF_HEIGHT,
    BLOCK_HALF_LENGTH,
    BLOCK_MASS,
    GRAVITY,
    INCLINE,
    bouncing_ball_impacts,
)


def _run(problem_name: str, formalism: str, integrator: str, rtol: float, **options):
    problem = registry.get_problem(problem_name)()
    equations = registry.get_formalism(formalism)().build(problem.model())
    q0 = problem.initial_joint_coordinates()["free"]
    v0 = problem.initial_joint_velocities().get("free", [0.0, 0.0, 0.0])
    y0 = np.concatenate([q0, v0])
    method = registry.get_integrator(integrator)()
    trajectory = method.solve(equations, y0, None, problem.sample_times(), rtol, rtol * 1e-3,
                              options or None)  # fmt: skip
    assert trajectory.success, trajectory.message
    return problem, equations, trajectory


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae", "recursive"])
def test_contact_jacobians_are_the_gaps_derivatives(formalism):
    """W_N v is dg_N/dt along q' = H v (central differences), for a tilted block's corners."""
    problem = registry.get_problem("incline-block-slide")()
    equations = registry.get_formalism(formalism)().build(problem.model())
    contacts, mech = equations.contacts, equations.forms["mechanical"]
    rng = np.random.default_rng(1)
    q, v = rng.normal(size=3), rng.normal(size=3)
    h = 1e-6
    qdot = mech.qdot(0.0, q, v)[0].reshape(-1)
    fd = (contacts.gaps(0.0, q + h * qdot)[0] - contacts.gaps(0.0, q - h * qdot)[0]) / (2 * h)
    w_n = contacts.normal_jacobian(0.0, q)[0]
    np.testing.assert_allclose(np.asarray(w_n) @ v, np.asarray(fd).reshape(-1), atol=1e-8)
    # a pure slide along the slope (cos a, sin a) at the start: U_T = its speed, U_N = 0
    q0 = np.array(problem.initial_joint_coordinates()["free"])
    slide_rate = np.array([math.cos(INCLINE), math.sin(INCLINE), 0.0])  # (x, y, angle)'
    kinematics = np.asarray(mech.kinematics(0.0, q0)[0])
    slide = np.linalg.lstsq(kinematics, slide_rate, rcond=None)[0]
    np.testing.assert_allclose(np.asarray(contacts.gaps(0.0, q0)[0]).reshape(-1), 0, atol=1e-15)
    w_t = np.asarray(contacts.tangent_jacobian(0.0, q0)[0])
    np.testing.assert_allclose(w_t @ slide, [1.0, 1.0], atol=1e-12)
    w_n0 = np.asarray(contacts.normal_jacobian(0.0, q0)[0])
    np.testing.assert_allclose(w_n0 @ slide, [0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"restitution": 1.5}, "restitution must be in"),
        ({"friction": -0.1}, "friction must be >= 0"),
        ({"radius": -1.0}, "radius must be >= 0"),
        ({"body": "nobody"}, "is not a body"),
        ({"plane_normal": (0.0, 0.0, 1.0)}, "x-y plane"),
    ],
)
def test_contact_validation_names_the_fault(change, message):
    model = Model("m", kind="planar")
    model.add_body("ball", 1.0, inertia=0.1)
    model.add_joint("free", "planar", "ground", "ball")
    model.add_contact("floor", **({"body": "ball"} | change))
    with pytest.raises(ModelError, match=message):
        model.validate()


def test_smooth_integrators_refuse_contacts():
    problem = registry.get_problem("bouncing-ball")()
    equations = registry.get_formalism("minimal-ode")().build(problem.model())
    with pytest.raises(PluginError, match="unilateral contacts"):
        registry.get_integrator("scipy-dop853")().solve(
            equations, np.array([0, 1.1, 0, 0, 0, 0.0]), None, np.array([0, 1.0]), 1e-6, 1e-9
        )


def _ball_height(equations, trajectory):
    return trajectory.y[:, 1] - BALL_RADIUS  # both formalisms: q = (x, y, angle)


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae", "recursive"])
def test_event_driven_ball_follows_newtons_law(formalism):
    """Impact times t_k and apex heights h0 e^(2k): the geometric series of Newton's law."""
    problem, equations, trajectory = _run("bouncing-ball", formalism, "event-driven", 1e-10)
    expected = bouncing_ball_impacts(problem.t_end, BALL_DROP, BALL_RESTITUTION)
    events = np.array(trajectory.contact["event_times"])
    assert events.size == expected.size == 4
    np.testing.assert_allclose(events, expected, atol=1e-8)
    # apex after the k-th impact: the speed leaving it is e^k v_1
    v_1 = GRAVITY * expected[0]
    for k, t_k in enumerate(expected[:-1], start=1):
        apex_time = t_k + BALL_RESTITUTION**k * v_1 / GRAVITY
        index = np.argmin(np.abs(trajectory.times - apex_time))
        apex = BALL_DROP * BALL_RESTITUTION ** (2 * k)
        flight = apex - GRAVITY * (trajectory.times[index] - apex_time) ** 2 / 2
        assert _ball_height(equations, trajectory)[index] == pytest.approx(flight, abs=1e-7)
    assert trajectory.contact["penetration_max"] < 1e-9


def test_moreau_jean_ball_converges_to_newtons_law():
    """First order in the step: impact times within a few steps, no energy gained."""
    problem, _, trajectory = _run("bouncing-ball", "minimal-ode", "moreau-jean", 1e-6,
                                  step=2e-4)  # fmt: skip
    expected = bouncing_ball_impacts(problem.t_end, BALL_DROP, BALL_RESTITUTION)
    events = np.array(trajectory.contact["event_times"])
    assert events.size == expected.size
    np.testing.assert_allclose(events, expected, atol=5e-3)
    assert trajectory.contact["complementarity_max"] < 1e-6
    # the apex after the first impact: h0 e^2 within the step's error
    first_flight = trajectory.times > expected[0]
    apex = trajectory.y[first_flight, 1].max() - BALL_RADIUS
    assert apex == pytest.approx(BALL_DROP * BALL_RESTITUTION**2, abs=2e-3)


def _slope_distance(trajectory):
    start = trajectory.y[0, :2]
    up = np.array([math.cos(INCLINE), math.sin(INCLINE)])
    return -(trajectory.y[:, :2] - start) @ up


@pytest.mark.parametrize("integrator", ["event-driven", "moreau-jean"])
def test_block_slides_with_coulomb_acceleration(integrator):
    """mu = 0.3 < tan 30 deg: s = g (sin a - mu cos a) t^2 / 2, the block stays on the slope."""
    options = {"step": 1e-3} if integrator == "moreau-jean" else {}
    problem, _, trajectory = _run("incline-block-slide", "absolute-dae", integrator, 1e-8,
                                  **options)  # fmt: skip
    acceleration = GRAVITY * (math.sin(INCLINE) - 0.3 * math.cos(INCLINE))
    expected = acceleration * trajectory.times**2 / 2
    tolerance = 1e-8 if integrator == "event-driven" else 1e-2
    np.testing.assert_allclose(_slope_distance(trajectory), expected, atol=tolerance)
    # no tipping (Moreau-Jean's first step turns the block by 1.3e-5 rad, then holds it)
    np.testing.assert_allclose(trajectory.y[:, 2], INCLINE, atol=tolerance * 1e-2)


@pytest.mark.parametrize("integrator", ["event-driven", "moreau-jean"])
def test_block_stops_then_sticks(integrator):
    """mu = 0.8 > tan 30 deg, launched at 2 m/s: decelerates at g (mu cos a - sin a), sticks
    at t_s = 2 / that, and stays (the slip-to-stick transition)."""
    options = {"step": 1e-3} if integrator == "moreau-jean" else {}
    problem, _, trajectory = _run("incline-block-stop", "minimal-ode", integrator, 1e-8,
                                  **options)  # fmt: skip
    deceleration = GRAVITY * (0.8 * math.cos(INCLINE) - math.sin(INCLINE))
    t_stop = 2.0 / deceleration
    (stick,) = problem.contact_events()
    assert stick == pytest.approx(t_stop)
    events = np.array(trajectory.contact["event_times"])
    assert np.min(np.abs(events - t_stop)) < (1e-8 if integrator == "event-driven" else 3e-3)
    s = _slope_distance(trajectory)
    after = trajectory.times >= t_stop + 0.01
    np.testing.assert_allclose(s[after], 2.0 * t_stop / 2, atol=1e-7 if integrator ==
                               "event-driven" else 5e-3)  # fmt: skip
    before = trajectory.times < t_stop
    tau = trajectory.times[before]
    np.testing.assert_allclose(s[before], 2.0 * tau - deceleration * tau**2 / 2,
                               atol=1e-8 if integrator == "event-driven" else 5e-3)  # fmt: skip


def test_compliant_contact_states_its_stiffness_and_approaches_the_rigid_law():
    """A penalty contact penetrates about m g / k at rest and rebounds with e."""
    problem, _, trajectory = _run("incline-block-slide", "minimal-ode", "compliant-contact",
                                  1e-6, stiffness=1e6)  # fmt: skip
    acceleration = GRAVITY * (math.sin(INCLINE) - 0.3 * math.cos(INCLINE))
    np.testing.assert_allclose(_slope_distance(trajectory), acceleration *
                               trajectory.times**2 / 2, atol=1e-4)  # fmt: skip
    static = GRAVITY * math.cos(INCLINE) / 1e6  # m g cos a / k shared by two corners (m = 1)
    assert trajectory.contact["penetration_max"] < 2 * static
    _, _, ball = _run("bouncing-ball", "minimal-ode", "compliant-contact", 1e-6, stiffness=1e6)
    expected = bouncing_ball_impacts(2.5, BALL_DROP, BALL_RESTITUTION)
    np.testing.assert_allclose(ball.contact["event_times"][:2], expected[:2], atol=1e-2)


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae"])
def test_sliding_sphere_rolls_at_five_sevenths(formalism):
    """Spatial Coulomb friction (two tangents): a sphere launched at v0 without spin slides
    at -mu g until t_r = 2 v0 / (7 mu g), then rolls at 5/7 v0 (Moreau-Jean, step 5e-4 s: the
    roll starts 2.5e-4 s late, x is off by 6e-8; 1e-4 took 3-5x as long for 5e-5 and 3e-9)."""
    problem = registry.get_problem("sliding-sphere")()
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    method = registry.get_integrator("moreau-jean")()
    times = problem.sample_times()
    trajectory = method.solve(equations, state.y0(equations, "mechanical"), None, times, 1e-6,
                              1e-9, {"step": 5e-4})  # fmt: skip
    assert trajectory.success, trajectory.message
    poses = np.stack([equations.observables.poses(t, y[: equations.nq])
                      for t, y in zip(times, trajectory.y, strict=True)])  # fmt: skip
    x, _, _, _ = problem.motion(times)
    np.testing.assert_allclose(poses[:, 0, 0], x, atol=1e-3)
    np.testing.assert_allclose(poses[:, 0, 2], 0.1, atol=1e-9)  # stays on the floor
    speed = (poses[-1, 0, 0] - poses[-11, 0, 0]) / (times[-1] - times[-11])
    assert speed == pytest.approx(5 / 7 * 2.0, rel=1e-4)
    (stick,) = trajectory.contact["event_times"]
    assert stick == pytest.approx(problem.roll_time(), abs=2e-3)


def _sphere_run(formalism: str, spin_x: float = 0.0):
    """The sliding sphere by the event-driven method, optionally with side spin about x."""
    base = registry.get_problem("sliding-sphere")

    class Spun(base):
        def initial_joint_velocities(self):
            return {"free": [2.0, 0.0, 0.0, spin_x, 0.0, 0.0]}

    problem = Spun()
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()
    trajectory = registry.get_integrator("event-driven")().solve(
        equations, state.y0(equations, "mechanical"), None, times, 1e-10, 1e-13
    )
    assert trajectory.success, trajectory.message
    poses = np.stack([equations.observables.poses(t, y[: equations.nq])
                      for t, y in zip(times, trajectory.y, strict=True)])  # fmt: skip
    return problem, times, poses[:, 0], trajectory


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae", "recursive"])
def test_event_driven_sphere_rolls_at_five_sevenths(formalism):
    """Spatial stick/slip (two tangents): the slip-to-stick event at t_r = 2 v0 / (7 mu g)
    to round-off, then rolling at 5/7 v0; the pose follows the analytic reference."""
    problem, times, pose, trajectory = _sphere_run(formalism)
    (stick,) = trajectory.contact["event_times"]
    assert stick == pytest.approx(problem.roll_time(), abs=1e-9)
    reference = problem.reference().poses(times)[:, 0]
    np.testing.assert_allclose(pose[:, :3], reference[:, :3], atol=1e-9)
    sign = np.sign(np.sum(pose[:, 3:] * reference[:, 3:], axis=1, keepdims=True))
    np.testing.assert_allclose(sign * pose[:, 3:], reference[:, 3:], atol=1e-8)
    assert trajectory.contact["penetration_max"] < 1e-12


def test_event_driven_sphere_with_side_spin_slides_along_its_slip():
    """With side spin the contact point slips along u0 = v0 + w0 x (-r e_z), not along v0:
    Coulomb's force -mu m g u0/|u0| keeps that direction (u' = -7/2 mu g u0/|u0|), so the
    slip stops at t_r = 2 |u0| / (7 mu g) and the centre leaves at v0 - mu g t_r u0/|u0|
    (a curved path: the friction disc, not two boxes, and the direction, not its signs)."""
    mu, r, spin = 0.2, 0.1, 10.0
    problem, times, pose, trajectory = _sphere_run("minimal-ode", spin_x=spin)
    u0 = np.array([2.0, spin * r, 0.0])  # (2, 0, 0) + (spin, 0, 0) x (0, 0, -r)
    t_r = 2 * np.linalg.norm(u0) / (7 * mu * GRAVITY)
    (stick,) = trajectory.contact["event_times"]
    assert stick == pytest.approx(t_r, abs=1e-9)
    final = np.array([2.0, 0.0, 0.0]) - mu * GRAVITY * t_r * u0 / np.linalg.norm(u0)
    velocity = (pose[-1, :3] - pose[-11, :3]) / (times[-1] - times[-11])
    np.testing.assert_allclose(velocity, final, atol=1e-8)
    sliding = times <= t_r
    path = (
        np.array([2.0, 0.0, 0.0]) * times[sliding, None]
        - mu * GRAVITY * u0 / np.linalg.norm(u0) * times[sliding, None] ** 2 / 2
    )
    np.testing.assert_allclose(pose[sliding, :3] - pose[0, :3], path, atol=1e-9)


def test_penetration_is_a_time_series_in_the_row_and_the_recording(tmp_path):
    """A compliant block (k = 1e6 N/m) slides on its two corners; friction mu N at the base,
    h below the centre, loads the front corner by mu N h / (2 L) more (L: half length), so
    it sinks N (1 + mu h / L) / (2 k): the series ``penetration`` says so at every sample
    after the first settling, its max is the row's at most; the recording draws it beside
    the drift; a smooth problem's series has no such column."""
    import rerun as rr

    from workbench.execution.execute import RunSpec, execute_run, normalized_spec
    from workbench.outputs.recording import RerunSink, series_quantities

    sink = RerunSink()
    spec = normalized_spec(RunSpec("incline-block-slide", "minimal-ode", "compliant-contact",
                                   1e-6, 1e-9))  # fmt: skip
    result = execute_run(spec, sink=sink)
    series, row = result.series, result.row
    depth = series["penetration"].to_numpy()
    normal = BLOCK_MASS * GRAVITY * math.cos(INCLINE)
    front = normal * (1 + 0.3 * BLOCK_HALF_HEIGHT / BLOCK_HALF_LENGTH) / (2 * 1e6)
    settled = series["t"].to_numpy() > 0.1
    np.testing.assert_allclose(depth[settled], front, rtol=1e-3)
    assert depth.max() <= row["penetration_max"]
    present = [
        series_quantities(chunk.to_record_batch())
        for chunk in rr.chunk.RrdReader(sink.save(tmp_path)).stream()
        if chunk.entity_path.endswith("/series") and not chunk.is_static
    ]
    assert present and "penetration" in present[0]
    smooth = execute_run(RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-5, 1e-8))
    assert "penetration" not in smooth.series.columns


def _sphere_on_incline(mu: float, alpha: float, r: float = 0.1):
    from workbench.model import Shape

    model = Model("sphere-on-incline", kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
    model.add_body("sphere", 1.0, inertia=[0.4 * r * r] * 3, shapes=[Shape("sphere", (r,))])
    model.add_joint("free", "free", "ground", "sphere")
    normal = np.array([-math.sin(alpha), 0.0, math.cos(alpha)])
    model.add_contact("plane", "sphere", radius=r, plane_normal=tuple(normal), friction=mu)
    return registry.get_formalism("minimal-ode")().build(model), normal


def test_event_driven_slip_that_turns_follows_coulombs_disc():
    """A sphere thrown across a 30 deg incline (mu = 0.3): gravity turns its slip u downhill
    while friction opposes it, u' = g sin(a) e_down - 7/2 mu g cos(a) u/|u| (solved here by
    SciPy to 1e-12); the slip turns past 60 degrees (a new phase) and stops at that law's
    t_s, after which the sphere rolls at 5/7 g sin a. A frozen slip direction or a friction
    pyramid misses t_s by tens of ms (Moreau-Jean's old pyramid: 0.224 s against 0.321 s)."""
    from scipy.integrate import solve_ivp

    mu, alpha, across = 0.3, math.radians(30.0), 2.0
    equations, normal = _sphere_on_incline(mu, alpha)
    y0 = np.concatenate([0.1 * normal, [1.0, 0.0, 0.0, 0.0], [0.0, across, 0.0], np.zeros(3)])
    times = np.linspace(0.0, 1.0, 101)
    trajectory = registry.get_integrator("event-driven")().solve(
        equations, y0, None, times, 1e-10, 1e-13)  # fmt: skip
    assert trajectory.success, trajectory.message
    g_t, k = GRAVITY * math.sin(alpha), 3.5 * mu * GRAVITY * math.cos(alpha)

    def slip(t, u):  # (down, across) components of the contact point's slip
        return np.array([g_t, 0.0]) - k * u / np.linalg.norm(u)

    stops = lambda t, u: np.linalg.norm(u) - 1e-10  # noqa: E731
    stops.terminal = True
    law = solve_ivp(slip, (0.0, 1.0), [0.0, across], rtol=1e-12, atol=1e-14, events=stops)
    (t_s,) = law.t_events[0]
    events = trajectory.contact["event_times"]
    assert len(events) == 2 and events[-1] == pytest.approx(t_s, abs=1e-7)  # turn, stick
    down = np.array([-math.cos(alpha), 0.0, -math.sin(alpha)])
    side = np.array([0.0, 1.0, 0.0])
    # the centre at t_s: v0 + g_t e_down t_s - mu g cos(a) * int d = ... (int d from u's law)
    v_s = across * side + g_t * t_s * down - (g_t * t_s * down + across * side) / 3.5
    v_end = v_s + 5 / 7 * g_t * (times[-1] - t_s) * down
    centre = np.array([equations.observables.poses(t, y[: equations.nq])[0, :3]
                       for t, y in zip(times[-3:], trajectory.y[-3:], strict=True)])  # fmt: skip
    velocity = (centre[2] - centre[0]) / (times[-1] - times[-3])  # central: exact here
    np.testing.assert_allclose(velocity + 5 / 7 * g_t * (times[-1] - times[-2]) * down, v_end,
                               atol=1e-7)  # fmt: skip


def test_moreau_jean_slip_that_turns_stops_where_coulombs_disc_says():
    """The turning slip of the test above by Moreau-Jean: with Coulomb's disc (a second-order
    cone per contact, Clarabel) it stops slipping within two steps of the event-driven t_s
    and its path converges to the event-driven one as h shrinks (first order: 10x smaller
    h, >= 5x smaller error); the friction pyramid stopped at 0.225 s and stayed 2.2 cm
    away at any step. The residual, which includes the disc's natural map, stays small."""
    mu, alpha, across = 0.3, math.radians(30.0), 2.0
    equations, normal = _sphere_on_incline(mu, alpha)
    y0 = np.concatenate([0.1 * normal, [1.0, 0.0, 0.0, 0.0], [0.0, across, 0.0], np.zeros(3)])
    times = np.linspace(0.0, 1.0, 101)

    def centres(trajectory):
        assert trajectory.success, trajectory.message
        return np.array([equations.observables.poses(t, y[: equations.nq])[0, :3]
                         for t, y in zip(times, trajectory.y, strict=True)])  # fmt: skip

    exact = registry.get_integrator("event-driven")().solve(equations, y0, None, times,
                                                            1e-10, 1e-13)  # fmt: skip
    reference, t_s = centres(exact), exact.contact["event_times"][-1]
    errors = []
    for h in (1e-2, 1e-3):
        run = registry.get_integrator("moreau-jean")().solve(equations, y0, None, times, 1e-6,
                                                             1e-9, {"step": h})  # fmt: skip
        errors.append(float(np.max(np.abs(centres(run) - reference))))
        (stick,) = run.contact["event_times"]  # no impact: the sphere rests on the plane
        assert stick == pytest.approx(t_s, abs=2 * h)
        assert run.contact["complementarity_max"] < 1e-6
    assert errors[1] < 5e-4 and errors[1] < errors[0] / 5


def test_disc_residual_is_zero_on_coulombs_law_only():
    """The friction part of the complementarity residual (the disc's natural map): zero for
    a force on the disc's edge against the slip, or inside it without slip; not zero for
    the pyramid's corner answer to a diagonal slip (|P_T| = sqrt 2 bound, not against it)."""
    from workbench.plugins.integrators._contact import disc_residual

    slip = np.array([[3.0, 4.0], [0.0, 0.0], [1.0, 1.0], [1.0, 0.0]])
    force = np.array([[-0.6, -0.8], [0.3, -0.2], [-1.0, -1.0], [-1.0, 0.5]])
    residual = disc_residual(force, slip, np.ones(4), np.full(4, 2.0))
    np.testing.assert_allclose(residual[:2], 0.0, atol=1e-15)
    assert residual[2] > 0.5 and residual[3] > 0.1


@pytest.mark.parametrize(("mu", "rolls"), [(0.5, True), (0.1, False)])
def test_event_driven_sphere_on_a_spatial_incline_rolls_or_slips(mu, rolls):
    """A sphere released on a 30 deg plane: rolling needs the friction 2/7 m g sin a, in
    the disc iff mu >= 2/7 tan a (0.165). It then rolls at 5/7 g sin a (the contact sticks:
    the disc holds it); else it starts slipping, against the sticking force, at
    g (sin a - mu cos a). Both to round-off, on the plane throughout."""
    alpha, r = math.radians(30.0), 0.1
    equations, normal = _sphere_on_incline(mu, alpha, r)
    y0 = np.concatenate([r * normal, [1.0, 0.0, 0.0, 0.0], np.zeros(6)])
    times = np.linspace(0.0, 1.0, 11)
    trajectory = registry.get_integrator("event-driven")().solve(
        equations, y0, None, times, 1e-10, 1e-13)  # fmt: skip
    assert trajectory.success, trajectory.message
    centre = np.array([equations.observables.poses(t, y[: equations.nq])[0, :3]
                       for t, y in zip(times, trajectory.y, strict=True)])  # fmt: skip
    down = np.array([-math.cos(alpha), 0.0, -math.sin(alpha)])
    rate = 5 / 7 * math.sin(alpha) if rolls else math.sin(alpha) - mu * math.cos(alpha)
    np.testing.assert_allclose((centre - centre[0]) @ down, rate * GRAVITY * times**2 / 2,
                               atol=1e-9)  # fmt: skip
    np.testing.assert_allclose((centre - centre[0]) @ normal, 0.0, atol=1e-12)


def test_event_driven_contact_that_would_pull_lifts_off():
    """A sphere touching a ceiling (normal down) at rest under gravity: its sticking contact
    would have to pull (lambda_N < 0), so it lifts off at once and falls freely,
    z = -g t^2 / 2 (the mode choice of a spatial contact: lift-off before stick/slip)."""
    from workbench.model import Shape

    r = 0.1
    model = Model("under-a-ceiling", kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
    model.add_body("sphere", 1.0, inertia=[0.4 * r * r] * 3, shapes=[Shape("sphere", (r,))])
    model.add_joint("free", "free", "ground", "sphere")
    model.add_contact("ceiling", "sphere", radius=r, plane_normal=(0.0, 0.0, -1.0), friction=0.5)
    equations = registry.get_formalism("minimal-ode")().build(model)
    y0 = np.concatenate([[0.0, 0.0, -r], [1.0, 0.0, 0.0, 0.0], np.zeros(6)])
    times = np.linspace(0.0, 0.5, 6)
    trajectory = registry.get_integrator("event-driven")().solve(
        equations, y0, None, times, 1e-10, 1e-13)  # fmt: skip
    assert trajectory.success, trajectory.message
    np.testing.assert_allclose(trajectory.y[:, 2], -r - GRAVITY * times**2 / 2, atol=1e-10)
