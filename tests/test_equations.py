"""The equations contract: forms derived from the mechanical form are consistent with each
other, Jacobians match finite differences, buffered evaluation matches CasADi, and the
consistent initial state satisfies every formulation."""

import pickle

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from workbench.equations.evaluate import dense_function
from workbench.equations.initial import consistent_initial_state
from workbench.errors import IntegrationError
from workbench.model import Frame, Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import get_formalism, get_problem


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


@pytest.mark.parametrize(
    ("problem", "formalism"),
    [
        ("double-pendulum", "minimal-ode"),
        ("slider-crank", "absolute-dae"),
        ("heavy-top", "recursive"),
        ("rolling-pendulum", "nonholonomic-projection"),
        ("spatial-chain", "absolute-dae"),
    ],
)
def test_observables_along_states_equal_one_state_at_a_time(problem, formalism):
    """Observables.along (one mapped call a quantity) gives what the per-state functions
    give, at perturbed states: poses, twists, energy and every residual."""
    from workbench.plugin.registry import get_formalism, get_problem

    problem_ = get_problem(problem)()
    equations = get_formalism(formalism)().build(problem_.model(), {})
    state = consistent_initial_state(equations, problem_)
    rng = np.random.default_rng(7)
    nq, nv = equations.nq, equations.nv
    times = np.linspace(0.0, 1.0, 6)
    q = state.q + 0.05 * rng.standard_normal((6, nq))
    v = state.v + 0.05 * rng.standard_normal((6, nv))
    sampled = equations.observables.along(times, q, v)
    observables = equations.observables
    for k, t in enumerate(times):
        np.testing.assert_allclose(sampled.poses[k], observables.poses(t, q[k]), atol=1e-14)
        twists = np.reshape(observables.twists(t, q[k], v[k])[0], (6, -1)).T
        np.testing.assert_allclose(sampled.twists[k], twists, atol=1e-13)
        energy = np.ravel(observables.energy(t, q[k], v[k])[0])[:2]
        np.testing.assert_allclose(sampled.energy[k], energy, rtol=1e-14, atol=1e-14)
        for mapped, single in zip(
            sampled.residuals, observables.residuals(t, q[k], v[k]), strict=True
        ):
            np.testing.assert_allclose(mapped[k], np.ravel(single), atol=1e-14)
    assert sampled.poses.shape == (6, len(observables.body_names), 7)
    assert observables.along(times[:0], q[:0], v[:0]).poses.shape[0] == 0
    np.testing.assert_array_equal(observables.poses_along(times, q), sampled.poses)
    assert observables.poses_along(times[:0], q[:0]).shape == (0, len(observables.body_names), 7)


@pytest.mark.parametrize(
    ("problem", "options", "formalism"),
    [
        ("binary-tree", {"depth": 2}, "absolute-dae"),  # [M W^T; W 0] by LU, 35 unknowns
        ("slider-crank", {}, "absolute-dae"),  # planar, LU
        ("spatial-chain", {"n_links": 10}, "minimal-ode"),  # M alone by LDL^T, 10 unknowns
    ],
)
def test_ode_jacobian_through_a_numeric_solve_equals_casadis(problem, options, formalism):
    """Beyond SYMBOLIC_SOLVE_LIMIT the ode Jacobian comes from the implicit function
    theorem (ds/dy = -K^-1 d(Ks - b)/dy): equal to CasADi's derivative of the solve and to
    central differences of the right-hand side, at a perturbed state."""
    from workbench.equations import SYMBOLIC_SOLVE_LIMIT
    from workbench.plugin.registry import get_formalism, get_problem

    problem_ = get_problem(problem)(options)
    equations = get_formalism(formalism)().build(problem_.model(), {"index": 1})
    form = equations.forms["ode"]
    assert equations.nv + equations.n_constraints > SYMBOLIC_SOLVE_LIMIT
    state = consistent_initial_state(equations, problem_)
    y = state.y0(equations, "ode") + 0.01 * np.random.default_rng(2).standard_normal(form.n)
    ours = form.jacobian(0.3, y)[0]
    rhs = form.rhs.function
    t_sym, y_sym = ca.MX.sym("t"), ca.MX.sym("y", form.n)
    automatic = ca.Function("automatic", [t_sym, y_sym], [ca.jacobian(rhs(t_sym, y_sym), y_sym)])
    expected = np.asarray(automatic(0.3, y))
    np.testing.assert_allclose(ours, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    step = 1e-6
    columns = [
        (form.rhs(0.3, y + step * e)[0] - form.rhs(0.3, y - step * e)[0]) / (2 * step)
        for e in np.eye(form.n)
    ]
    np.testing.assert_allclose(ours, np.column_stack(columns), atol=1e-5 * np.abs(ours).max())


def test_kkt_residual_jacobian_is_made_once_and_only_for_the_ode_jacobian(monkeypatch):
    """compile=auto builds two graphs of the ode right-hand side (LAPACK's LU for the VM,
    CasADi's QR for C): the Jacobian of the KKT residuals K s - b that both ode Jacobians
    use is made when the ode Jacobian is first asked for, once, not at build time twice;
    the C graph's Jacobian equals the VM's."""
    from workbench.plugin.registry import get_formalism, get_problem

    problem = get_problem("binary-tree")({"depth": 2})
    made = []
    jacobian = ca.jacobian

    def counting(expression, wrt, *args):
        made.append((expression.numel(), wrt.numel()))
        return jacobian(expression, wrt, *args)

    monkeypatch.setattr(ca, "jacobian", counting)
    equations = get_formalism("absolute-dae")().build(
        problem.model(), {"index": 1, "compile": "auto"}
    )
    nq, nv, nc = equations.nq, equations.nv, equations.n_constraints
    kkt_residual = (nv + nc, nq + nv)
    assert made.count(kkt_residual) == 0
    form = equations.forms["ode"]
    fast = form.jacobian.fast  # (built now: the VM's graph and the C's)
    assert made.count(kkt_residual) == 1 and fast.for_c is not fast.function
    state = consistent_initial_state(equations, problem)
    y = state.y0(equations, "ode") + 0.01 * np.random.default_rng(4).standard_normal(form.n)
    vm, for_c = np.asarray(fast.function(0.3, y)), np.asarray(fast.for_c(0.3, y))
    np.testing.assert_allclose(for_c, vm, rtol=1e-9, atol=1e-9 * np.abs(vm).max())


@pytest.mark.parametrize("expand", [True, False], ids=["expanded", "mapped"])
def test_evaluate_along_equals_one_point_at_a_time_bit_for_bit(expand, monkeypatch):
    """evaluate_along (Function.map(n) through preallocated buffers, expanded into one SX
    graph when small, or through Function.call when an output is sparse) gives exactly
    what n separate calls give: the metrics computed from it are the same numbers, not
    merely close ones."""
    from workbench.equations import evaluate
    from workbench.equations.evaluate import evaluate_along

    if not expand:
        monkeypatch.setattr(evaluate, "EXPAND_MAP_LIMIT", 0)

    problem = get_problem("four-bar")()
    equations = get_formalism("absolute-dae")().build(problem.model(), {"index": 1})
    state = consistent_initial_state(equations, problem)
    rng = np.random.default_rng(3)
    n, nq, nv = 7, equations.nq, equations.nv
    times = np.linspace(0.0, 1.0, n)
    q = state.q + 0.1 * rng.standard_normal((n, nq))
    v = state.v + 0.1 * rng.standard_normal((n, nv))
    residuals = equations.observables.residuals.function
    sparse = ca.Function("sparse_jacobian", [ca.SX.sym("t"), x := ca.SX.sym("q", nq)],
                         [ca.jacobian(ca.sin(x[:2]) * x[2], x)])  # fmt: skip
    assert not sparse.sparsity_out(0).is_dense()
    velocity_matrix = equations.forms["mechanical"].velocity_matrix.function
    cache: dict = {}
    for function, args in [(residuals, [times, q, v]), (sparse, [times, q]),
                           (velocity_matrix, [times, q])]:  # fmt: skip
        columns = [np.atleast_2d(a).T if a.ndim == 2 else a[None] for a in args]
        before = []  # what the observables did before: Function.call, np.asarray(DM)
        for i, value in enumerate(function.map(n).call(columns)):
            rows, cols = function.sparsity_out(i).shape
            before.append(np.asarray(value).reshape(rows, n, cols).transpose(1, 0, 2))
        for _ in range(2):  # again, from the cache's buffers
            mapped = evaluate_along(function, n, columns, cache)
            for old, new in zip(before, mapped, strict=True):  # memory layout too: NumPy's
                np.testing.assert_array_equal(new, old)  # reductions follow it to the last bit
                assert new.strides == old.strides
            for k in range(n):
                single = function.call([np.atleast_1d(a[k]) for a in args])
                for i, value in enumerate(single):
                    np.testing.assert_array_equal(mapped[i][k], np.array(value))
    assert len(cache) == 3
    # the two dense functions went the way asked: n copies in one SX graph, or a map
    kinds = {cache[(id(f), n)][1].function.class_name() for f in (residuals, velocity_matrix)}
    assert kinds == ({"SXFunction"} if expand else {"Map"})


def test_poses_along_the_states_just_measured_are_those_of_along_and_no_others():
    """poses_along at the states of the last along() (a run's recording after its metrics)
    returns those poses, as a copy; at any other states it computes them."""
    problem = get_problem("heavy-top")()
    equations = get_formalism("recursive")().build(problem.model(), {})
    state = consistent_initial_state(equations, problem)
    rng = np.random.default_rng(5)
    times = np.linspace(0.0, 1.0, 5)
    q = state.q + 0.05 * rng.standard_normal((5, equations.nq))
    v = np.tile(state.v, (5, 1))
    observables = equations.observables
    sampled = observables.along(times, q, v)
    mapped = []  # the frames evaluated again (not for the states just measured)
    evaluate = type(observables)._map
    observables._map = lambda *args: mapped.append(args[0]) or evaluate(observables, *args)
    kept = observables.poses_along(times, q)
    np.testing.assert_array_equal(kept, sampled.poses)
    assert mapped == []
    kept[:] = 0.0  # a copy: the next caller gets the poses again
    np.testing.assert_array_equal(observables.poses_along(times, q), sampled.poses)
    other = q.copy()
    other[-1, 0] = np.nextafter(other[-1, 0], 1.0)  # one bit off
    moved = observables.poses_along(times, other)
    assert mapped == ["frames"]
    fresh = get_formalism("recursive")().build(problem.model(), {}).observables
    # evaluated again, as a fresh copy would (one bit of a quaternion may leave the pose
    # itself unchanged: it is normalized)
    np.testing.assert_array_equal(moved, fresh.poses_along(times, other))
    other[-1, 0] += 1e-6  # and states that differ in the pose give other poses
    assert not np.array_equal(observables.poses_along(times, other), sampled.poses)
    np.testing.assert_array_equal(observables.poses_along(times[:3], q[:3]), sampled.poses[:3])
