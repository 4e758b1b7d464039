"""Sphere-sphere contacts between two bodies (docs/nonsmooth.md): the element's validation,
its gap Jacobian against finite differences, and ``colliding-balls`` -- a central impact
whose time, velocities, momentum and energy loss are known -- through the three contact
integrator families on both formalisms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.errors import ModelError
from workbench.model import Model
from workbench.plugin import registry
from workbench.problems.ch5_contacts import (
    PAIR_LINE,
    PAIR_MASSES,
    PAIR_RESTITUTION,
    PAIR_SPEED,
    colliding_balls_velocities,
)

LINE = np.array([math.cos(PAIR_LINE), math.sin(PAIR_LINE)])


def _pair_model(kind: str = "planar", friction: float = 0.0) -> Model:
    model = Model("pair", kind=kind, gravity=(0.0, 0.0, 0.0))
    joint = "planar" if kind == "planar" else "free"
    for name in ("a", "b"):
        model.add_body(name, 1.0, inertia=0.1 if kind == "planar" else [0.1, 0.2, 0.3])
        model.add_joint(f"free_{name}", joint, "ground", name)
    model.add_sphere_contact("touch", "a", 0.1, "b", 0.2, centre_a=(0.05, -0.02, 0.0),
                             centre_b=(-0.1, 0.03, 0.0), friction=friction)  # fmt: skip
    return model


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"body_b": "a"}, "body_a and body_b are both 'a'"),
        ({"radius_a": 0.0}, "radius_a must be > 0"),
        ({"radius_b": -0.1}, "radius_b must be > 0"),
        ({"body_b": "nobody"}, "body_b 'nobody' is not a body"),
        ({"body_a": "ground"}, "body_a cannot be 'ground'"),
        ({"restitution": 1.2}, "restitution must be in"),
        ({"friction": -1.0}, "friction must be >= 0"),
        ({"centre_b": (0.0, 0.0, 0.1)}, "same z"),
    ],
)
def test_sphere_contact_validation_names_the_fault(change, message):
    model = Model("m", kind="planar")
    for name in ("a", "b"):
        model.add_body(name, 1.0, inertia=0.1)
        model.add_joint(f"free_{name}", "planar", "ground", name)
    arguments = {"body_a": "a", "radius_a": 0.1, "body_b": "b", "radius_b": 0.1} | change
    model.add_sphere_contact("touch", **arguments)
    with pytest.raises(ModelError, match=message):
        model.validate()


def test_sphere_contact_is_described_with_both_bodies():
    from workbench.model.parameters import model_parameters

    rows = {row[0]: row for row in model_parameters(_pair_model())}
    assert rows["touch"][1] == "unilateral contact of a with b"
    assert "sphere r 0.1 m" in rows["touch"][2] and "sphere r 0.2 m" in rows["touch"][2]


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae"])
@pytest.mark.parametrize("kind", ["planar", "spatial"])
def test_sphere_gap_jacobian_is_the_gaps_derivative(formalism, kind):
    """W_N v = dg_N/dt along q' = H v (central differences) at random states of two spinning
    bodies with off-centre spheres; the tangent rows are orthogonal to the normal one
    (W_T v of a motion along the normal is 0) and their bias is d(W v)/dt at fixed v."""
    equations = registry.get_formalism(formalism)().build(_pair_model(kind, friction=0.3))
    contacts, mech = equations.contacts, equations.forms["mechanical"]
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, v = rng.normal(size=equations.nq), rng.normal(size=equations.nv)
        for block in equations.quaternion_slices:
            q[block] /= np.linalg.norm(q[block])
        h = 1e-6
        qdot = np.asarray(mech.qdot(0.0, q, v)[0]).reshape(-1)
        gap = lambda x: float(np.ravel(contacts.gaps(0.0, x)[0])[0])  # noqa: E731
        fd = (gap(q + h * qdot) - gap(q - h * qdot)) / (2 * h)
        w_n = np.asarray(contacts.normal_jacobian(0.0, q)[0]).reshape(-1)
        assert w_n @ v == pytest.approx(fd, abs=1e-7)
        for jacobian, bias in ((contacts.normal_jacobian, contacts.normal_bias),
                               (contacts.tangent_jacobian, contacts.tangent_bias)):  # fmt: skip
            ahead = np.asarray(jacobian(0.0, q + h * qdot)[0]) @ v
            behind = np.asarray(jacobian(0.0, q - h * qdot)[0]) @ v
            expected = np.asarray(bias(0.0, q, v)[0]).reshape(-1)
            np.testing.assert_allclose((ahead - behind) / (2 * h), expected, atol=1e-6)
    # a pure approach of B's centre along the normal: no tangential velocity
    q0 = consistent_initial_state(equations, _Still(kind)).q
    w_t = np.asarray(contacts.tangent_jacobian(0.0, q0)[0])
    w_n = np.asarray(contacts.normal_jacobian(0.0, q0)[0]).reshape(-1)
    approach = np.zeros(equations.nv)
    approach[equations.nv // 2] = 1.0  # B translating along x, the normal at rest
    assert w_n @ approach == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(w_t @ approach, 0.0, atol=1e-12)


class _Still:
    """Bodies a and b of :func:`_pair_model` at rest on the x axis, centres 1 m apart."""

    t_start = 0.0

    def __init__(self, kind: str) -> None:
        self.kind = kind

    def initial_joint_coordinates(self):
        if self.kind == "planar":
            return {"free_a": [-0.05, 0.02, 0.0], "free_b": [1.1, -0.03, 0.0]}
        return {"free_a": [-0.05, 0.02, 0, 1, 0, 0, 0], "free_b": [1.1, -0.03, 0, 1, 0, 0, 0]}

    def initial_joint_velocities(self):
        return {}


OPTIONS = {
    "event-driven": None,
    "moreau-jean": {"step": 1e-3},
    "compliant-contact": {"stiffness": 1e6},
}


def _solve(formalism: str, integrator: str):
    problem = registry.get_problem("colliding-balls")()
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    rtol = 1e-6 if integrator == "compliant-contact" else 1e-10
    trajectory = registry.get_integrator(integrator)().solve(
        equations, np.concatenate([state.q, state.v]), None, problem.sample_times(), rtol,
        rtol * 1e-3, OPTIONS[integrator],
    )  # fmt: skip
    assert trajectory.success, trajectory.message
    return problem, equations, trajectory


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae"])
@pytest.mark.parametrize("integrator", list(OPTIONS))
def test_colliding_balls_follow_momentum_and_newtons_law(formalism, integrator):
    """One impact at t_c = 0.3375 s; after it v_A = (m_A - e m_B) v0 / (m_A + m_B) and
    v_B = m_A (1 + e) v0 / (m_A + m_B) along the line, nothing across it; momentum
    m_A v0 at every sample; kinetic energy less (1 - e^2) mu v0^2 / 2 after the impact.
    Event-driven: exact to the root-finder; Moreau-Jean (h = 1 ms): the impact within a
    step, its impulse exact; compliant (k = 1e6 N/m): the contact lasts about
    pi sqrt(m_eff / k) = 2.6 ms, so time and velocities within that softness."""
    problem, equations, trajectory = _solve(formalism, integrator)
    nq = equations.nq
    velocities = trajectory.y[:, nq:].reshape(len(trajectory.times), 2, 3)  # (x', y', w)
    m_a, m_b = PAIR_MASSES
    momentum = m_a * velocities[:, 0, :2] + m_b * velocities[:, 1, :2]
    momentum_tolerance = 1e-10 if integrator != "compliant-contact" else 1e-6
    np.testing.assert_allclose(momentum, np.tile(PAIR_SPEED * m_a * LINE, (len(momentum), 1)),
                               atol=momentum_tolerance)  # fmt: skip
    (t_c,) = problem.contact_events()
    assert t_c == pytest.approx(0.3375)
    events = np.array(trajectory.contact["event_times"])
    assert events.size == 1
    time_tolerance = {"event-driven": 1e-9, "moreau-jean": 1e-3, "compliant-contact": 3e-3}
    assert events[0] == pytest.approx(t_c, abs=time_tolerance[integrator])
    after = trajectory.times > t_c + 0.01
    speed_tolerance = {"event-driven": 1e-8, "moreau-jean": 1e-8, "compliant-contact": 5e-3}
    expected = np.array(colliding_balls_velocities())
    along = velocities[after, :, :2] @ LINE
    np.testing.assert_allclose(along, np.tile(expected, (int(after.sum()), 1)),
                               atol=speed_tolerance[integrator])  # fmt: skip
    across = velocities[after, :, :2] @ np.array([-LINE[1], LINE[0]])
    np.testing.assert_allclose(across, 0.0, atol=1e-9)
    energy = 0.5 * (m_a * np.sum(velocities[:, 0, :2] ** 2, axis=1)
                    + m_b * np.sum(velocities[:, 1, :2] ** 2, axis=1))  # fmt: skip
    loss = (1 - PAIR_RESTITUTION**2) * m_a * m_b / (m_a + m_b) * PAIR_SPEED**2 / 2
    assert loss == pytest.approx(0.19 / 3)
    away = np.abs(trajectory.times - t_c) > 0.01
    np.testing.assert_allclose(energy[away], problem.reference_energy(trajectory.times[away]),
                               atol=2 * speed_tolerance[integrator])  # fmt: skip
    # event-driven: none; Moreau-Jean: at most a step's approach h v0; compliant: about
    # v0 sqrt(m_eff / k) = 0.8 mm
    depth = {"event-driven": 1e-8, "moreau-jean": 1e-3 * PAIR_SPEED, "compliant-contact": 2e-3}
    assert trajectory.contact["penetration_max"] < depth[integrator]


def test_recording_draws_both_spheres_and_no_plane(tmp_path):
    """A sphere pair is drawn on each of its bodies (an ellipsoid at the contact's centre,
    one instance of the run's ``contacts`` entity a sphere), not as a contact plane;
    ``describe`` lists it."""
    import rerun as rr

    from workbench.api.catalog import describe
    from workbench.execution.execute import RunSpec, execute_run, normalized_spec
    from workbench.outputs.recording import RerunSink

    sink = RerunSink()
    spec = normalized_spec(RunSpec("colliding-balls", "minimal-ode", "event-driven", 1e-6, 1e-9))
    assert execute_run(spec, sink=sink).row["status"] == "ok"
    chunks = list(rr.chunk.RrdReader(sink.save(tmp_path)).stream())
    paths = {chunk.entity_path for chunk in chunks}
    (spheres,) = [c for c in chunks if c.entity_path.endswith("/contacts") and c.is_static]
    assert len(spheres.to_record_batch().column("Ellipsoids3D:half_sizes")[0]) == 2  # a, b
    assert not any("contact_planes" in p for p in paths)
    assert "touch" in str(describe("colliding-balls"))


@pytest.mark.parametrize("rtol", [1e-3, 1e-7])
def test_event_driven_finds_an_impact_at_loose_tolerances(rtol):
    """In free flight DOP853's steps grow past the whole overlap of the two balls (the gap
    goes negative and positive again within one step), so SciPy's sign test saw no impact
    and the balls passed through each other at the suite's tolerances; steps are now at
    most an output interval."""
    problem = registry.get_problem("colliding-balls")()
    equations = registry.get_formalism("minimal-ode")().build(problem.model())
    state = consistent_initial_state(equations, problem)
    trajectory = registry.get_integrator("event-driven")().solve(
        equations, np.concatenate([state.q, state.v]), None, problem.sample_times(), rtol,
        rtol * 1e-3, None,
    )  # fmt: skip
    assert np.array(trajectory.contact["event_times"]) == pytest.approx(problem.contact_events())
    assert trajectory.contact["penetration_max"] < 1e-8
