"""Coulomb friction in a joint (Model.add_joint_friction; docs/nonsmooth.md): validation,
and a pendulum whose pivot holds it where gravity's torque stays within the bound and
otherwise lets it swing until the bound's work bound * |angle travelled| has taken the
energy it lost."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from workbench.api.catalog import model_facts
from workbench.equations.initial import consistent_initial_state
from workbench.errors import ModelError
from workbench.model import Frame, Model
from workbench.plugin import registry
from workbench.plugin.problem import Problem
from workbench.problems.ch5_joint_friction import SLIDE_FRICTION

LENGTH, GRAVITY, MASS = 1.0, 9.81, 1.0
WEIGHT = MASS * GRAVITY * LENGTH  # the largest gravity torque (N m), rod horizontal


class FrictionPendulum(Problem):
    """A point mass on a 1 m rod from a pivot with Coulomb friction ``bound`` (N m),
    released at rest at ``start`` rad from the horizontal (x > 0; y = L sin angle)."""

    name = "friction-pendulum"
    t_end = 5.0  # it comes to rest for good at 3.3 s
    n_samples = 501
    conservative = False

    def __init__(self, bound: float, start: float) -> None:
        self.bound, self.start = bound, start

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_point_mass("bob", MASS)
        model.add_joint("pivot", "revolute", "ground", "bob", child_frame=Frame.at(-LENGTH))
        model.add_joint_friction("pivot", self.bound)
        return model

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        return {"pivot": [self.start]}


def swings(bound: float, start: float) -> list[float]:
    """The angles where the pendulum comes to rest, swing after swing, by the work law
    m g L (sin a - sin b) = bound |b - a| from rest at a to rest at b; it stays at the
    last, where |m g L cos b| <= bound (gravity's torque within the friction's bound)."""
    rests = [start]
    while abs(WEIGHT * math.cos(rests[-1])) > bound and len(rests) < 50:
        a = rests[-1]

        def lost(b: float, a: float = a) -> float:
            return WEIGHT * (math.sin(a) - math.sin(b)) - bound * abs(b - a)

        bottom = -math.pi / 2 + 2 * math.pi * round((a + math.pi / 2) / (2 * math.pi))
        far = bottom + (bottom - a)  # the frictionless turning point: lost(far) < 0
        rests.append(brentq(lost, bottom, far, xtol=1e-14))
    return rests


def _run(formalism: str, integrator: str, bound: float, start: float, options=None):
    problem = FrictionPendulum(bound, start)
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    trajectory = registry.get_integrator(integrator)().solve(
        equations, state.y0(equations, "mechanical"), None, problem.sample_times(), 1e-9,
        1e-12, options,
    )  # fmt: skip
    assert trajectory.success, trajectory.message
    nq = equations.nq
    sampled = equations.observables.along(
        trajectory.times, trajectory.y[:, :nq], trajectory.y[:, nq : nq + equations.nv]
    )
    position = sampled.poses[:, 0, :2]
    angle = np.unwrap(np.arctan2(position[:, 1], position[:, 0]))
    return angle, sampled.energy.sum(axis=1)


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae"])
@pytest.mark.parametrize(("integrator", "options"),
                         [("event-driven", None), ("moreau-jean", {"step": 1e-3})])  # fmt: skip
def test_pendulum_sticks_where_gravity_stays_within_the_bound(formalism, integrator, options):
    """At 1.4 rad below the horizontal gravity's torque m g L cos(1.4) = 1.66 N m is within
    the bound 2 N m: the pivot holds it. From the horizontal (9.81 N m) a bound of 12 N m
    holds it too."""
    for bound, start in ((2.0, -1.4), (12.0, 0.0)):
        angle, energy = _run(formalism, integrator, bound, start, options)
        np.testing.assert_allclose(angle, start, atol=1e-9)
        np.testing.assert_allclose(energy, energy[0], atol=1e-9)


@pytest.mark.parametrize("formalism", ["minimal-ode", "absolute-dae", "recursive"])
def test_event_driven_friction_pendulum_stops_by_the_work_law(formalism):
    """Released horizontal with a bound of 2 N m it swings to and fro until, at rest at
    an angle b with |m g L cos b| <= 2 N m, it sticks; there E0 - E = bound * |angle
    travelled|, the turning points from the work law (to 1e-7 rad and 1e-6 J)."""
    bound = 2.0
    rests = swings(bound, 0.0)
    angle, energy = _run(formalism, "event-driven", bound, 0.0)
    travelled = float(np.sum(np.abs(np.diff(rests))))
    assert len(rests) >= 3  # it turns at least once before it sticks
    np.testing.assert_allclose(angle[-1], rests[-1], atol=1e-7)
    np.testing.assert_allclose(energy[0] - energy[-1], bound * travelled, atol=1e-6)
    assert abs(WEIGHT * math.cos(angle[-1])) <= bound


def test_moreau_jean_friction_pendulum_stops_near_the_work_law():
    """Moreau-Jean (h = 1e-3 s, first order) stops it within 5e-3 rad of the same angle."""
    rests = swings(2.0, 0.0)
    for formalism in ("minimal-ode", "absolute-dae"):
        angle, _ = _run(formalism, "moreau-jean", 2.0, 0.0, {"step": 1e-3})
        np.testing.assert_allclose(angle[-1], rests[-1], atol=5e-3)


@pytest.mark.parametrize(
    ("joint", "bound", "message"),
    [
        ("nojoint", 1.0, "is not a joint of the model"),
        ("slide", 1.0, "needs a one-coordinate joint"),
        ("pivot", -1.0, "bound must be >= 0"),
    ],
)
def test_joint_friction_validation_names_the_fault(joint, bound, message):
    model = Model("m", kind="planar")
    model.add_body("link", 1.0, inertia=0.1)
    model.add_body("puck", 1.0, inertia=0.1)
    model.add_joint("pivot", "revolute", "ground", "link")
    model.add_joint("slide", "planar", "ground", "puck")
    model.add_joint_friction(joint, bound)
    with pytest.raises(ModelError, match=message):
        model.validate()


def test_joint_friction_is_added_once_and_described():
    problem = FrictionPendulum(2.0, 0.0)
    model = problem.model()
    with pytest.raises(ModelError, match="has friction already"):
        model.add_joint_friction("pivot", 3.0)
    assert model_facts(problem, model)["joint friction"] == "pivot (bound 2)"


def _slider_crank(formalism: str):
    problem = registry.get_problem("slider-crank-friction")()
    problem.n_samples = 2001  # travel from the samples: turning points within 1e-6 m
    equations = registry.get_formalism(formalism)().build(problem.model())
    state = consistent_initial_state(equations, problem)
    trajectory = registry.get_integrator("event-driven")().solve(
        equations, state.y0(equations, "mechanical"), None, problem.sample_times(), 1e-9, 1e-12
    )
    assert trajectory.success, trajectory.message
    nq = equations.nq
    sampled = equations.observables.along(
        trajectory.times, trajectory.y[:, :nq], trajectory.y[:, nq : nq + equations.nv]
    )
    piston = sampled.poses[:, list(equations.model.bodies).index("piston"), 0]
    return trajectory, piston, sampled.energy.sum(axis=1), sampled.residuals[0]


def test_slider_crank_with_slide_friction_loses_what_the_friction_works():
    """The closed loop with Coulomb friction F = 2 N in the piston's slide: E0 - E(t) =
    F * (distance slid by t) at every sample (1e-4 J), in absolute coordinates (8 joint
    rows) as in minimal ones (the loop's 2), which agree on the piston's path (1e-6 m),
    the loop closed to 1e-7 m; the piston passes its dead centres (its rate turns there
    whatever the friction) and the slide's friction switches at each turn."""
    runs = {f: _slider_crank(f) for f in ("minimal-ode", "absolute-dae")}
    for trajectory, piston, energy, residuals in runs.values():
        slid = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(piston)))])
        np.testing.assert_allclose(energy[0] - energy, SLIDE_FRICTION * slid, atol=1e-4)
        assert np.max(np.abs(residuals), initial=0.0) < 1e-7
        assert len(trajectory.contact["event_times"]) >= 3  # the slide turns, and turns back
    np.testing.assert_allclose(runs["absolute-dae"][1], runs["minimal-ode"][1], atol=1e-6)
