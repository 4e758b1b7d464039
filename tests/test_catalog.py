"""The whole problem catalog: every registered problem is valid, has the DOF and loops
derived by hand, a consistent initial state, and (when conservative) conserves energy and
its declared invariants along a tight minimal-ode run; analytic references agree with it.
"""

from __future__ import annotations

import functools
import math
import re
from importlib import metadata

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from workbench.equations.initial import consistent_initial_state
from workbench.execution.references import given_reference
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
from workbench.mechanics.topology import analyze
from workbench.plugin.registry import REGISTRY, get_problem
from workbench.plugins.formalisms.minimal_ode import MinimalOde


def _has_robot_data() -> bool:
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return False
    return True


# case: (options, dof from the rank of the constraint Jacobian, independent loops),
# derived by hand (Gruebler / counting velocities minus independent constraint rows).
# A case is a problem name, with "[variant]" appended for non-default options.
EXPECTED = {
    "simple-pendulum": ({}, 1, 0),
    "double-pendulum": ({}, 2, 0),
    "slider-crank": ({}, 1, 1),
    "heavy-top": ({}, 3, 0),
    "torque-free-gyro": ({}, 3, 0),  # spherical joint: 3
    "torque-free-symmetric-gyro": ({}, 3, 0),
    "double-point-pendulum": ({}, 2, 0),  # two revolute joints
    "point-mass-slider-crank": ({}, 1, 1),  # 3 tree joints - 2 rows of the cut revolute
    "rotating-ring": ({}, 1, 0),  # driven revolute (0) + revolute (1)
    "rolling-pendulum": ({}, 2, 0),  # planar 3 + revolute 1 - height 1 - rolling 1
    "two-joint-robot": ({}, 2, 0),
    "ball-on-rotating-plane": ({}, 3, 0),  # free 6 - height 1 - rolling 2
    "knife-edge-cart": ({}, 2, 0),  # planar 3 - knife edge 1
    "bouncing-ball": ({}, 3, 0),  # planar 3; unilateral contacts remove no DOF
    "incline-block-slide": ({}, 3, 0),
    "incline-block-stop": ({}, 3, 0),
    "sliding-sphere": ({}, 6, 0),  # free 6
    "slider-crank-friction": ({}, 1, 1),  # point-mass-slider-crank with slide friction
    "rocking-block": ({}, 3, 0),  # planar 3
    "colliding-balls": ({}, 6, 0),  # two planar free bodies, 3 each; the contact removes none
    "woodpecker": ({}, 3, 0),  # prismatic 1 + revolute 1 + revolute 1
    "knife-edge-cart[sleigh]": ({"com_offset": 0.1}, 2, 0),
    "articulated-arm": ({}, 6, 0),
    "four-bar": ({}, 1, 1),  # 3 revolutes - 2 rows of the cut revolute
    "four-bar[near-change-point]": ({"near_change_point": True}, 1, 1),
    "rsrrr": ({}, 1, 1),  # 4 revolutes in the tree - 3 rows of the cut spherical joint
    "parallel-robot": ({}, 3, 2),  # 7 revolutes in the tree - 2 x 2 rows
    "planar-chain": ({"n_links": 4}, 4, 0),
    "spatial-chain": ({"n_links": 4}, 4, 0),
    "binary-tree": ({"depth": 2}, 3, 0),  # 2^2 - 1 bodies, one revolute each
    # N + 1 cranks and N couplers: 3N + 1 revolutes, 2 rows each for N cut ones
    "iftomm-a02": ({}, 1, 2),
    "iftomm-a02[n=5]": ({"n": 5}, 1, 5),
    # 7 revolutes in the tree - 3 cut revolutes at E x 2 rows
    "andrews": ({}, 1, 3),
    "iftomm-a03": ({}, 1, 3),
    # driven revolute (0) + prismatic (1) + revolute (1)
    "car-axis": ({}, 2, 0),
    "rssr-linkage": ({}, 2, 1),  # revolute 1 + ball 3 + revolute 1 - 3 rows of the connect
    "iftomm-a01": ({}, 1, 0),
    # 5 revolutes in the tree - 5 rows of the cut revolute + 1 redundant row (Bricard)
    "iftomm-a04": ({}, 1, 1),
    "iftomm-a05": ({}, 4, 0),  # shaft, slider and two rods
}
if _has_robot_data():  # the robots extra
    EXPECTED["ur5"] = ({}, 6, 0)  # 6 revolutes, fixed base
    EXPECTED["solo12"] = ({}, 18, 0)  # free base 6 + 12 revolutes
# redundant constraint rows found at the initial configuration (overconstrained loops)
REDUNDANT = {"iftomm-a04": 1}

RTOL = 1e-10
ATOL = 1e-12
SIMULATION_LIMIT = 5.0  # s of simulated time in tests
# problems that pass singular configurations: the generic checks below integrate them only
# up to before the first one (A02: all bars horizontal at t = 0.45 s); what a pipeline
# does through it is checked by the trust tests (tests/test_singular_passage.py)
SINGULAR_AFTER = {"iftomm-a02": 0.3}
# s, as published (the catalog's own are <= 10 s)
BENCHMARK_SPAN = {"iftomm-a02": 20.0, "iftomm-a01": 20.0}


def registered_problems() -> list[str]:
    return [info.name for info in REGISTRY.list("problem") if info.plugin is not None]


def problem_name(case: str) -> str:
    return case.split("[")[0]


def test_every_registered_problem_has_expected_values() -> None:
    assert sorted(registered_problems()) == sorted({problem_name(c) for c in EXPECTED})


def make(case: str):
    options, _, _ = EXPECTED[case]
    return get_problem(problem_name(case))(options)


@functools.cache
def simulate(name: str):
    """(problem, equations, times, q, v) of a tight minimal-ode (index 1) run."""
    problem = make(name)
    equations = MinimalOde().build(problem.model(), {"index": 1})
    state = consistent_initial_state(equations, problem)
    ode = equations.forms["ode"]
    limit = SINGULAR_AFTER.get(problem_name(name), SIMULATION_LIMIT)
    t_end = min(problem.t_end, problem.t_start + limit)
    times = np.linspace(problem.t_start, t_end, 41)
    solution = solve_ivp(
        lambda t, y: ode.rhs(t, y)[0],
        (problem.t_start, t_end),
        state.y0(equations, "ode"),
        method="DOP853",
        rtol=RTOL,
        atol=ATOL,
        t_eval=times,
    )
    assert solution.success, solution.message
    nq = equations.nq
    return problem, equations, times, solution.y[:nq].T, solution.y[nq:].T


def observed(equations, t: float, q: np.ndarray, v: np.ndarray):
    poses = equations.observables.poses(t, q)
    (twists,) = equations.observables.twists(t, q, v)
    return poses, np.reshape(twists, (-1, 6)) if twists.ndim == 1 else twists.T


@pytest.mark.parametrize("name", list(EXPECTED))
def test_model_valid_with_dof_and_loops(name: str) -> None:
    problem = make(name)
    assert problem.name == problem_name(name) and problem.summary and problem.source
    assert problem.__doc__ or type(problem).__module__
    model = problem.model()
    assert model.validate() is model
    _, dof, loops = EXPECTED[name]
    kinematics = TreeKinematics(model)
    q0 = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    topology = analyze(model, q=q0)  # at the initial (assembled) configuration
    assert topology.assembled is not False
    assert topology.n_loops == loops
    assert topology.dof == dof
    assert len(topology.redundant_constraints) == REDUNDANT.get(problem_name(name), 0)
    assert 0 < problem.t_end - problem.t_start <= BENCHMARK_SPAN.get(problem_name(name), 10.0)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_consistent_initial_state(name: str) -> None:
    problem = make(name)
    equations = MinimalOde().build(problem.model(), {"index": 1})
    state = consistent_initial_state(equations, problem)
    residuals = equations.observables.residuals(problem.t_start, state.q, state.v)
    scale = max(1.0, float(np.abs(state.v).max(initial=0.0)))
    for residual in residuals:
        assert np.all(np.abs(residual) < 1e-9 * scale)
    # the problem's own values are kept for the independent coordinates and velocities
    model = equations.model
    kinematics = TreeKinematics(model)
    q0 = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    v0 = initial_joint_values(model, kinematics, problem.initial_joint_velocities(), True)
    for joint, index in problem.independent_coordinates or ():
        q_slice, v_slice = kinematics.joint_slices[joint]
        assert state.q_joint[q_slice.start + index] == pytest.approx(q0[q_slice.start + index])
        assert state.v_joint[v_slice.start + index] == pytest.approx(v0[v_slice.start + index])


def relative_drift(values: np.ndarray, scale: float) -> float:
    return float(np.max(np.abs(values - values[0])) / scale)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_energy_and_invariants_conserved(name: str) -> None:
    problem = make(name)
    if problem.conservative:
        _, equations, times, q, v = simulate(name)
        energies = energy_series(equations, times, q, v)
        total = energies.sum(axis=1)
        scale = max(np.abs(energies).max(), 1e-12)
        assert relative_drift(total, scale) < 1e-6
    invariants = problem.invariants()
    if not invariants:
        return
    _, equations, times, q, v = simulate(name)
    model = equations.model
    samples = [observed(equations, t, qi, vi) for t, qi, vi in zip(times, q, v, strict=True)]
    poses = np.stack([p for p, _ in samples])
    twists = np.stack([w for _, w in samples])
    for invariant in invariants:
        pairs = zip(times, samples, strict=True)
        values = np.array([float(invariant.function(model, t, p, w)) for t, (p, w) in pairs])
        scale = max(np.abs(values).max(), invariant_scale(name, equations, times, q, v))
        assert relative_drift(values, scale) < 1e-6, invariant.name
        # what metrics use: one call along the whole run (vectorized) gives the same values
        along = invariant.along(model, times, poses, twists)
        np.testing.assert_allclose(along, values, rtol=1e-13, atol=1e-13 * scale)


def invariant_scale(name, equations, times, q, v) -> float:
    """A floor for relative errors: kinetic-plus-potential energy scale of the run."""
    energies = energy_series(equations, times, q, v)
    return max(float(np.abs(energies).max()) * 1e-3, 1e-12)


def energy_series(equations, times, q, v) -> np.ndarray:
    """(n_times, 2) kinetic and potential energy along a run."""
    energy = equations.observables.energy
    return np.array([energy(t, qi, vi)[0] for t, qi, vi in zip(times, q, v, strict=True)])


def quaternion_distance(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between orientations given as scalar-first quaternions."""
    conjugate = p * np.array([1.0, -1.0, -1.0, -1.0])
    scalar = np.sum(p * q, axis=-1)  # scalar part of conj(p) q: p0 q0 + p_v . q_v
    vector = (
        conjugate[..., :1] * q[..., 1:]
        + q[..., :1] * conjugate[..., 1:]
        + np.cross(conjugate[..., 1:], q[..., 1:])
    )
    return 2 * np.arctan2(np.linalg.norm(vector, axis=-1), np.abs(scalar))


def has_analytic_reference(case: str) -> bool:
    reference = given_reference(make(case))
    return reference is not None and reference.kind == "analytic"


# a smooth run knows no contact forces: tests/test_nonsmooth.py checks those references
SMOOTH_ANALYTIC = [
    n for n in EXPECTED if has_analytic_reference(n) and not make(n).model().contacts
]


@pytest.mark.parametrize("name", SMOOTH_ANALYTIC)
def test_analytic_reference_agrees_with_a_tight_run(name: str) -> None:
    problem, equations, times, q, v = simulate(name)
    reference = given_reference(problem)
    assert reference.kind == "analytic" and reference.description
    expected = reference.poses(times)
    poses = equations.observables.poses
    computed = np.array([poses(t, qi) for t, qi in zip(times, q, strict=True)])
    assert expected.shape == computed.shape
    positions = np.isfinite(expected[..., :3])
    assert positions.any()
    assert np.max(np.abs(expected[..., :3][positions] - computed[..., :3][positions])) < 1e-6
    rotations = np.all(np.isfinite(expected[..., 3:]), axis=-1)
    if rotations.any():
        angle = quaternion_distance(expected[..., 3:][rotations], computed[..., 3:][rotations])
        assert np.max(angle) < 1e-6


# ---- problem-specific checks ------------------------------------------------------


def test_symmetric_gyro_reference_starts_at_the_initial_pose() -> None:
    problem = get_problem("torque-free-symmetric-gyro")()
    pose = given_reference(problem).poses(np.array([0.0]))[0, 0]
    assert np.allclose(pose[3:], problem.initial_joint_coordinates()["pivot"])
    assert math.isclose(np.linalg.norm(pose[3:]), 1.0)


@pytest.mark.parametrize("near", [False, True])
@pytest.mark.parametrize("angle", [0.0, 1.0, 3.0, math.pi, -2.0])
def test_four_bar_state_closes_the_loop(near: bool, angle: float) -> None:
    from workbench.problems.ch11_closed_loops import four_bar_state

    problem = get_problem("four-bar")({"near_change_point": near})
    model = problem.model()
    kinematics = TreeKinematics(model)
    state = four_bar_state(angle, 2.0, problem.lengths)
    q = initial_joint_values(model, kinematics, {j: x for j, (x, _) in state.items()}, False)
    v = initial_joint_values(model, kinematics, {j: x for j, (_, x) in state.items()}, True)
    f = kinematics.function("g", [kinematics.closure_constraints, kinematics.velocity_constraints])
    g, w = (np.asarray(x, dtype=float) for x in f(0.0, q, v))
    assert np.abs(g).max() < 1e-12 and np.abs(w).max() < 1e-12
    # near the change point the closure Jacobian almost loses rank at crank angle pi
    jacobian = kinematics.function("G", [kinematics.closure_jacobian], with_v=False)
    singular = np.linalg.svd(np.asarray(jacobian(0.0, q), dtype=float), compute_uv=False)
    if near and angle == math.pi:
        assert singular.min() < 0.1 * singular.max()
    elif not near:
        assert singular.min() > 0.4 * singular.max()


@pytest.mark.parametrize(
    ("name", "options", "dof"),
    [
        ("planar-chain", {"n_links": 1}, 1),
        ("planar-chain", {}, 5),
        ("spatial-chain", {"n_links": 7}, 7),
        ("binary-tree", {"depth": 1}, 1),
        ("binary-tree", {}, 7),
    ],
)
def test_scalable_sizes(name: str, options: dict, dof: int) -> None:
    model = get_problem(name)(options).model()
    assert len(model.bodies) == dof
    topology = analyze(model)
    assert topology.dof == dof and topology.n_loops == 0


@pytest.mark.parametrize("options", [{"n_links": 0}, {"depth": 0}])
def test_scalable_options_rejected(options: dict) -> None:
    from workbench.errors import ConfigError

    name = "planar-chain" if "n_links" in options else "binary-tree"
    with pytest.raises(ConfigError):
        get_problem(name)(options)


@pytest.mark.parametrize(
    "name", [case for case, (options, _, _) in EXPECTED.items() if not options]
)
def test_describe_shows_dof_parameters_invariants_and_reference(name: str) -> None:
    """``workbench describe`` (default options): the hand-derived DOF at the initial
    configuration (the folded neutral four-bar once showed 2), every body's mass, the
    source section, the invariants and the reference kind."""
    from typer.testing import CliRunner

    from workbench import cli

    result = CliRunner().invoke(cli.app, ["describe", name], env={"COLUMNS": "250"})
    assert result.exit_code == 0, result.output
    out = result.stdout
    problem = make(name)
    _, dof, loops = EXPECTED[name]
    assert re.search(rf"│ DOF\s+│ {dof}( \(Gruebler count \d+\))?\s+│", out), out
    assert re.search(rf"│ loops\s+│ {loops}\s+│", out)
    assert f"source: {problem.source}" in out and "parameters (SI units)" in out
    for body in problem.model().bodies.values():
        assert re.search(rf"│ {body.name}\s+│ (point )?mass\s+│ {body.mass:.4g} kg", out), body.name
    invariants = ["energy"] * problem.conservative + [i.name for i in problem.invariants()]
    assert re.search(rf"│ invariants\s+│ {', '.join(invariants) or 'none'}\s+│", out)
    reference = given_reference(problem)
    assert re.search(rf"│ reference\s+│ {reference.kind if reference else 'none'}\s+│", out)


@pytest.mark.parametrize("n", [1, 2, 40])
def test_a02_reference_is_the_exact_one_dof_reduction(n):
    """The closed form (Jacobi elliptic functions) of phi'' = -((9N+3)/(8N+2)) g cos(phi)
    against an independent tight integration of that ODE over the benchmark's 20 s (they
    agree to 1.1e-10 rad at N = 40, DOP853's own error at rtol 1e-13)."""
    from workbench.problems.iftomm import a02_coefficient, a02_crank_angle

    k = a02_coefficient(n)
    times = np.linspace(0.0, 20.0, 401)
    exact = a02_crank_angle(times, n, np.pi / 2, -1.0)
    solution = solve_ivp(
        lambda t, y: [y[1], -k * np.cos(y[0])], (0.0, 20.0), [np.pi / 2, -1.0],
        method="DOP853", rtol=1e-13, atol=1e-13, t_eval=times,
    )  # fmt: skip
    assert np.abs(exact - solution.y[0]).max() < 1e-9
