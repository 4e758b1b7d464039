"""lagrange-ad (book 5.8.2) and hamilton (5.8.3): conformance, agreement with minimal-ode
and recursive, properties of canonical equations, and runs in a sweep."""

import numpy as np
import pytest
import scipy.integrate

from workbench.equations.initial import consistent_initial_state
from workbench.errors import PluginError
from workbench.model import JointSpringDamper, Model
from workbench.plugin.registry import get_formalism, get_problem
from workbench.runs import store
from workbench.runs.sweep import parse_spec, run_sweep
from workbench.testing import check_formalism
from workbench.testing.states import formalism_state, random_joint_states

FORMALISMS = [("lagrange-ad", {"index": 1}), ("hamilton", {})]


@pytest.mark.parametrize("name, options", FORMALISMS, ids=[n for n, _ in FORMALISMS])
def test_conformance_on_the_fast_subset(name, options):
    report = check_formalism(name, options=options).raise_if_failed()
    assert sum(r.check == "accelerations" and r.status == "pass" for r in report.results) >= 3


@pytest.mark.slow
@pytest.mark.parametrize("name, options", FORMALISMS, ids=[n for n, _ in FORMALISMS])
def test_conformance_on_the_whole_catalog(name, options):
    check_formalism(name, "all", options).raise_if_failed()


def end_poses(formalism: str, options: dict, problem, t_end: float) -> np.ndarray:
    equations = get_formalism(formalism)().build(problem.model(), options)
    state = consistent_initial_state(equations, problem)
    rhs = equations.forms["ode"].rhs
    solution = scipy.integrate.solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, t_end),
        state.y0(equations, "ode"),
        method="DOP853",
        rtol=1e-11,
        atol=1e-11,
    )
    assert solution.success
    return equations.observables.poses(t_end, solution.y[: equations.nq, -1])


def test_double_pendulum_motion_agrees_with_minimal_ode_and_recursive():
    problem = get_problem("double-pendulum")()
    poses = {
        name: end_poses(name, options, problem, 1.0)
        for name, options in [("minimal-ode", {}), ("recursive", {}), *FORMALISMS]
    }
    for name, value in poses.items():
        assert np.abs(value - poses["minimal-ode"]).max() < 1e-8, name


def test_hamilton_state_holds_momenta_p_equal_m_qdot():
    problem = get_problem("spatial-chain")()
    hamilton = get_formalism("hamilton")().build(problem.model())
    minimal = get_formalism("minimal-ode")().build(problem.model())
    for t, q_joint, v_joint in random_joint_states(problem, 3, seed=4):
        state = formalism_state(hamilton, t, q_joint, v_joint)
        (mass,) = minimal.forms["mechanical"].mass(t, q_joint)
        assert np.allclose(state.q, q_joint)
        assert np.allclose(state.v, mass @ v_joint, rtol=1e-12, atol=1e-12)
        assert np.allclose(state.qdot, v_joint, rtol=1e-10, atol=1e-12)  # q' = dH/dp


def test_canonical_flow_preserves_phase_volume():
    """Liouville: div f = tr(df/dy) = d2H/dqdp - d2H/dpdq = 0 for Hamilton's equations
    (not for Lagrange's in (q, q')); with damping the volume shrinks."""
    problem = get_problem("planar-chain")()
    ode = get_formalism("hamilton")().build(problem.model()).forms["ode"]
    lagrange = get_formalism("lagrange-ad")().build(problem.model(), {"index": 1}).forms["ode"]
    traces = []
    for t, q, v in random_joint_states(problem, 3, seed=2):
        y = np.concatenate([q, v])
        scale = np.abs(ode.jacobian(t, y)[0]).max()
        assert abs(np.trace(ode.jacobian(t, y)[0])) < 1e-12 * scale
        traces.append(abs(np.trace(lagrange.jacobian(t, y)[0])))
    assert max(traces) > 1e-3  # in (q, q') the flow is not divergence-free

    model = Model("damped", kind="planar", gravity=(0.0, -9.81, 0.0))
    model.add_body("link", 1.0, com=(0.5, 0, 0), inertia=0.1)
    model.add_joint("pivot", "revolute", "ground", "link")
    model.add_force(JointSpringDamper("damper", "pivot", stiffness=0.0, damping=0.3))
    damped = get_formalism("hamilton")().build(model).forms["ode"]
    (jacobian,) = damped.jacobian(0.0, np.array([0.4, 1.0]))
    inertia = 0.1 + 0.25  # about the pivot: p' = ... - c q' = ... - c p / I
    assert np.trace(jacobian) == pytest.approx(-0.3 / inertia, rel=1e-12)


def test_hamiltonian_is_conserved_along_the_canonical_flow():
    problem = get_problem("binary-tree")()
    equations = get_formalism("hamilton")().build(problem.model())
    state = consistent_initial_state(equations, problem)
    rhs, energy = equations.forms["ode"].rhs, equations.observables.energy
    solution = scipy.integrate.solve_ivp(
        lambda t, y: rhs(t, y)[0],
        (0.0, 0.5),
        state.y0(equations, "ode"),
        method="DOP853",
        rtol=1e-11,
        atol=1e-11,
        dense_output=True,
    )
    n = equations.nq
    totals = [
        energy(t, y[:n], y[n:])[0].sum() for t, y in zip(solution.t, solution.y.T, strict=True)
    ]
    kinetic = max(
        energy(t, y[:n], y[n:])[0][0] for t, y in zip(solution.t, solution.y.T, strict=True)
    )
    assert np.ptp(totals) < 1e-9 * kinetic


def test_unsupported_features_are_declared_and_named():
    hamilton, lagrange = get_formalism("hamilton"), get_formalism("lagrange-ad")
    with pytest.raises(PluginError, match=r"loop-closing .* use .*lagrange-ad"):
        hamilton().build(get_problem("slider-crank")().model())
    assert not lagrange.unsupported(get_problem("slider-crank")().model())
    top = get_problem("heavy-top")().model()
    for formalism in (hamilton, lagrange):
        assert formalism.unsupported(top) == {
            "spherical or free joints (quaternion coordinates, q' != v)"
        }


def test_both_run_in_a_sweep(tmp_path):
    text = f"""
out = "{tmp_path}"
jobs = 1
tolerances = [1e-7]
problems = ["double-pendulum", "slider-crank"]
formalisms = [{{ name = "lagrange-ad", options = {{ index = 2 }} }}, "hamilton", "minimal-ode"]
integrators = ["scipy-dop853", "sundials-ida"]
"""
    summary = run_sweep(parse_spec(text), show_progress=False)
    frame = store.load_results(tmp_path).set_index(["problem", "formalism", "integrator"])
    assert summary.total == 12
    baseline = frame.loc[("double-pendulum", "minimal-ode", "scipy-dop853"), "err_max"]
    for formalism in ("lagrange-ad", "hamilton"):
        row = frame.loc[("double-pendulum", formalism, "scipy-dop853")]
        assert row["status"] == "ok", row["message"]
        assert row["err_max"] < max(1e-4, 10 * baseline) and row["energy_err_max"] < 1e-6
    assert frame.loc[("slider-crank", "hamilton", "scipy-dop853"), "status"] == "skipped"
    assert frame.loc[("slider-crank", "lagrange-ad", "sundials-ida"), "status"] == "ok"


def test_hamilton_beyond_the_symbolic_solve_limit_uses_a_numeric_solve():
    """10 links > SYMBOLIC_SOLVE_LIMIT: q' = M^-1 p by LU inside an MX graph, same physics."""
    problem = get_problem("planar-chain")({"n_links": 10})
    equations = get_formalism("hamilton")().build(problem.model())
    assert equations.forms["ode"].rhs.function.is_a("MXFunction")
    check_formalism("hamilton", [problem], checks=["agreement"], n_states=2).raise_if_failed()
