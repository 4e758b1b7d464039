"""The equations contract: forms derived from the mechanical form are consistent with each
other, Jacobians match finite differences, buffered evaluation matches CasADi, and the
consistent initial state satisfies every formulation."""

import pickle

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from workbench.errors import IntegrationError
from workbench.evaluate import dense_function
from workbench.initial import consistent_initial_state
from workbench.model import Frame, Model
from workbench.problem import Problem
from workbench.registry import get_formalism, get_problem


def build(problem_name: str, **options):
    problem = get_problem(problem_name)()
    equations = get_formalism("minimal-ode")().build(problem.model(), options)
    return problem, equations


@pytest.mark.parametrize("index", [1, 2, 3])
def test_dae_residual_vanishes_at_the_consistent_state(index):
    problem, equations = build("slider-crank", index=index)
    state = consistent_initial_state(equations, problem)
    dae = equations.forms["dae"]
    assert dae.index == index
    (residual,) = dae.residual(0.0, state.y0(equations, "dae"), state.yp0(equations, "dae"))
    assert np.abs(residual).max() < 1e-10
    assert dae.algebraic.sum() == dae.n - equations.nq - equations.nv
    assert len(equations.y_names("dae")) == dae.n


def test_ode_and_dae_jacobians_match_finite_differences():
    problem, equations = build("slider-crank", index=1)
    state = consistent_initial_state(equations, problem)
    ode = equations.forms["ode"]
    y = state.y0(equations, "ode") + 0.01
    (jacobian,) = ode.jacobian(0.3, y)
    h = 1e-6
    columns = [
        (ode.rhs(0.3, y + h * e)[0] - ode.rhs(0.3, y - h * e)[0]) / (2 * h) for e in np.eye(y.size)
    ]
    assert np.allclose(jacobian, np.array(columns).T, rtol=1e-5, atol=1e-6)
    dae = equations.forms["dae"]
    y, yp = state.y0(equations, "dae"), state.yp0(equations, "dae")
    (combined,) = dae.jacobian(0.0, y, yp, 2.5)
    columns = [
        (
            dae.residual(0.0, y + h * e, yp + 2.5 * h * e)[0]
            - dae.residual(0.0, y - h * e, yp - 2.5 * h * e)[0]
        )
        / (2 * h)
        for e in np.eye(y.size)
    ]
    assert np.allclose(combined, np.array(columns).T, rtol=1e-5, atol=1e-6)


def test_mass_matrix_is_symmetric_positive_definite():
    problem, equations = build("double-pendulum")
    mechanical = equations.forms["mechanical"]
    for q in np.random.default_rng(1).normal(size=(5, 2)):
        (mass,) = mechanical.mass(0.0, q)
        assert np.allclose(mass, mass.T, atol=1e-14)
        assert np.linalg.eigvalsh(mass).min() > 0


def test_index1_ode_with_baumgarte_holds_the_loop_and_conserves_energy():
    problem, equations = build("slider-crank", index=1)
    state = consistent_initial_state(equations, problem)
    ode = equations.forms["ode"]
    solution = solve_ivp(
        lambda t, y: ode.rhs(t, y)[0],
        (0, 1.0),
        state.y0(equations, "ode"),
        method="DOP853",
        rtol=1e-10,
        atol=1e-10,
    )
    nq = equations.nq
    energies, drift = [], []
    for t, y in zip(solution.t, solution.y.T, strict=True):
        energies.append(equations.observables.energy(t, y[:nq], y[nq:])[0].sum())
        drift.append(np.abs(equations.observables.residuals(t, y[:nq], y[nq:])[0]).max())
    assert np.ptp(energies) < 1e-6 * abs(energies[0])
    assert max(drift) < 1e-8


def test_fast_function_matches_casadi_and_survives_pickling():
    x = ca.SX.sym("x", 3)
    t = ca.SX.sym("t")
    fast = dense_function("f", [t, x], [ca.sin(x) * t, ca.jacobian(ca.sin(x) * t, x)])
    args = (0.7, np.array([0.1, -2.0, 3.0]))
    reference = [np.asarray(r) for r in fast.function(*args)]
    for ours, theirs in zip(fast(*args), reference, strict=True):
        assert np.array_equal(ours.reshape(theirs.shape), theirs)
    restored = pickle.loads(pickle.dumps(fast))
    assert np.array_equal(restored(*args)[1], fast(*args)[1])
    assert fast.n_calls == 2
    # the time as any scalar-like value, the state as a row or a column: same numbers
    x0 = args[1]
    for time in (0.7, np.float64(0.7), np.array([0.7]), np.array(0.7), [0.7]):
        for state in (x0, x0.reshape(3, 1), list(x0)):
            assert np.array_equal(fast(time, state)[0], reference[0].ravel())
    assert np.array_equal(fast(2, x0)[0], np.sin(x0) * 2)


class ImpossibleLoop(Problem):
    """A 1 m link whose tip should close on a pin 5 m away: cannot be assembled."""

    name = "impossible-loop"

    def model(self) -> Model:
        model = Model("impossible", kind="planar")
        model.add_body("link", 1.0, com=(0.5, 0, 0), inertia=0.1)
        model.add_joint("hinge", "revolute", "ground", "link")
        model.add_joint(
            "pin",
            "revolute",
            "link",
            "ground",
            parent_frame=Frame.at(1.0),
            child_frame=Frame.at(5.0),
            cut=True,
        )
        return model


def test_unassemblable_loop_names_the_worst_constraint():
    problem = ImpossibleLoop()
    equations = get_formalism("minimal-ode")().build(problem.model(), {"index": 1})
    with pytest.raises(IntegrationError, match=r"pin\[\d\]"):
        consistent_initial_state(equations, problem)
