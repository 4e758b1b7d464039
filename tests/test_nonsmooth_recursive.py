"""The recursive formalism offers the contact form (docs/nonsmooth.md): on every problem of
the ``nonsmooth`` suite it has the pieces the contact integrators use (M by composite rigid
bodies, Q by recursive Newton-Euler, the gaps and their Jacobians from the core) and walks
the same trajectory as minimal-ode, whose coordinates it shares."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.errors import PluginError
from workbench.plugin import registry
from workbench.runs.sweep_spec import load_spec

SUITE = load_spec("nonsmooth").runs
PROBLEMS = sorted({run.problem for run in SUITE})


def _build(name: str, formalism: str):
    problem = registry.get_problem(name)()
    equations = registry.get_formalism(formalism)().build(problem.model())
    return problem, equations


def _solve(problem, equations, integrator: str, rtol: float, options=None, until=np.inf):
    state = consistent_initial_state(equations, problem)
    method = registry.get_integrator(integrator)()
    times = problem.sample_times()
    times = times[times <= until]
    trajectory = method.solve(equations, state.y0(equations, "mechanical"), None, times, rtol,
                              rtol * 1e-3, options)  # fmt: skip
    assert trajectory.success, trajectory.message
    return trajectory


def _pair(name: str, integrator: str, rtol: float, options=None, until=np.inf):
    """(minimal-ode's trajectory, recursive's) on problem ``name`` up to time ``until``."""
    runs = []
    for formalism in ("minimal-ode", "recursive"):
        problem, equations = _build(name, formalism)
        runs.append(_solve(problem, equations, integrator, rtol, options, until))
    return runs


def test_the_suite_runs_recursive_on_every_contact_problem():
    """The suite pairs recursive with every contact problem, trees and a closed loop."""
    assert {run.problem for run in SUITE if run.formalism == "recursive"} == set(PROBLEMS)
    assert {"bouncing-ball", "rocking-block", "woodpecker", "slider-crank-friction"} <= set(
        PROBLEMS
    )


@pytest.mark.parametrize("name", PROBLEMS)
def test_recursive_contact_form_is_minimal_odes(name):
    """Same coordinates, same numbers: M (CRBA against the projected Newton-Euler sum), Q
    (RNEA), the gaps, W_N, W_T, W_F and their biases agree at random states to round-off;
    a closed loop (slider-crank-friction) keeps its loop rows in both."""
    _, minimal = _build(name, "minimal-ode")
    _, recursive = _build(name, "recursive")
    assert recursive.contacts is not None
    assert recursive.q_names == minimal.q_names and recursive.v_names == minimal.v_names
    assert recursive.n_constraints == minimal.n_constraints
    rng = np.random.default_rng(3)
    for _ in range(3):
        t, q, v = rng.uniform(0, 1), rng.normal(size=minimal.nq), rng.normal(size=minimal.nv)
        for block in minimal.quaternion_slices:
            q[block] /= np.linalg.norm(q[block])
        pieces = {}
        for label, equations in (("minimal", minimal), ("recursive", recursive)):
            mech, contacts = equations.forms["mechanical"], equations.contacts
            values = [
                mech.mass(t, q)[0],
                mech.forces(t, q, v)[0],
                mech.velocity_matrix(t, q)[0],
                contacts.gaps(t, q)[0],
                contacts.normal_jacobian(t, q)[0],
                contacts.tangent_jacobian(t, q)[0],
                contacts.normal_bias(t, q, v)[0],
                contacts.tangent_bias(t, q, v)[0],
            ]
            if contacts.n_joint_frictions:
                values.append(contacts.joint_rate_jacobian(t, q)[0])
                values.append(contacts.joint_rate_bias(t, q, v)[0])
            pieces[label] = [np.asarray(value, dtype=float) for value in values]
        for ours, theirs in zip(pieces["recursive"], pieces["minimal"], strict=True):
            scale = max(1.0, float(np.max(np.abs(theirs), initial=0.0)))
            np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("name", PROBLEMS)
def test_event_driven_recursive_agrees_with_minimal_ode(name):
    """Event-driven at rtol 1e-12: the same events (impacts, lift-offs, stick/slip) within
    1e-9 s and the same end state within 1e-8 (measured: at most 7e-11 s and 5e-10, on the
    rocking block, where errors grow towards its accumulation point)."""
    minimal, recursive = _pair(name, "event-driven", 1e-12)
    events_m = np.array(minimal.contact["event_times"])
    events_r = np.array(recursive.contact["event_times"])
    assert events_r.size == events_m.size
    np.testing.assert_allclose(events_r, events_m, rtol=0, atol=1e-9)
    np.testing.assert_allclose(recursive.times, minimal.times)
    scale = max(1.0, float(np.max(np.abs(minimal.y[-1]))))
    np.testing.assert_allclose(recursive.y[-1], minimal.y[-1], rtol=0, atol=1e-8 * scale)


@pytest.mark.parametrize("name", PROBLEMS)
def test_moreau_jean_recursive_agrees_with_minimal_ode(name):
    """Moreau-Jean with the same steps (h = 1e-3 s, the first 1.2 s: the incline's block
    sticks at 1.06 s): the same step-by-step trajectory and contact closings, to the contact
    problem's solver accuracy (impulses to 1e-10 N s; measured within 2e-10)."""
    minimal, recursive = _pair(name, "moreau-jean", 1e-7, {"step": 1e-3}, until=1.2)
    events_m = np.array(minimal.contact["event_times"])
    events_r = np.array(recursive.contact["event_times"])
    assert events_r.size == events_m.size
    np.testing.assert_allclose(events_r, events_m, rtol=0, atol=1e-12)
    scale = max(1.0, float(np.max(np.abs(minimal.y))))
    np.testing.assert_allclose(recursive.y, minimal.y, rtol=0, atol=1e-8 * scale)


def test_formalisms_without_the_contact_form_still_refuse():
    """A formalism that does not declare the capability gets a clear refusal naming the
    ones that offer the contact form, recursive among them."""
    model = registry.get_problem("bouncing-ball")().model()
    with pytest.raises(PluginError, match="does not support unilateral contacts") as error:
        registry.get_formalism("hamilton")().build(model)
    assert "recursive" in str(error.value) and "minimal-ode" in str(error.value)
