"""The rank is decided at the problem's initial configuration, by describe and every formalism.

IFToMM A02 with N = 40 four-bar windows (problems/iftomm.py): the neutral configuration
(every joint angle 0, all bars along x) is singular, W loses N rows of rank there; the
initial one (cranks vertical) is assembled and regular. The mechanism has 1 DOF. Every
formalism must keep its N closure loops (no constraint row removed as "redundant"), say
1 DOF like ``workbench describe``, and follow the exact one-DOF reduction
phi'' = -((9N+3)/(8N+2)) g cos(phi) (the problem's reference) up to the first singular
position (all bars horizontal at t = 0.45 s; checked up to 0.3 s).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from workbench import cli
from workbench.equations.initial import consistent_initial_state
from workbench.mechanics.topology import analyze
from workbench.plugin.registry import get_formalism, get_integrator, get_problem

N = 40
SPAN = 0.3  # s, before the first singular position (t = 0.45 s)
POSE_TOLERANCE = 1e-6  # m (links 1 m long), against the analytic reference
# index 3 through generalized-alpha (second order, fixed step, slow on 243 coordinates):
GA_SPAN, GA_STEP = 0.1, 5e-3  # s; its error is about 1e-5 m there
GA_TOLERANCE = 1e-3  # m; with a closure row lost the couplers fall about 0.05 m in GA_SPAN

PIPELINES = {
    "absolute-dae index 1": ("absolute-dae", {"index": 1}),
    "absolute-dae index 2": ("absolute-dae", {"index": 2}),
    "absolute-dae index 3": ("absolute-dae", {"index": 3}),
    "minimal-ode index 1": ("minimal-ode", {"index": 1}),
    "minimal-ode index 2": ("minimal-ode", {"index": 2}),
    "minimal-ode index 3": ("minimal-ode", {"index": 3}),
    "minimal-ode state-space": ("minimal-ode", {"loops": "state-space"}),
    "recursive index 1": ("recursive", {"index": 1}),
}


@functools.cache
def problem(n: int = N):
    return get_problem("iftomm-a02")({"n": n})


@functools.cache
def built(case: str, n: int = N):
    """(equations, consistent initial state) of one pipeline, built once per module."""
    formalism, options = PIPELINES[case]
    equations = get_formalism(formalism)().build(problem(n).model(), options)
    return equations, consistent_initial_state(equations, problem(n))


def removed_rows(notes: list[str]) -> list[str]:
    return [note for note in notes if "redundant" in note]


@pytest.mark.parametrize("n", [2, N])
def test_describe_decides_the_rank_at_the_initial_configuration(n: int) -> None:
    topology = analyze(problem(n).model())
    assert topology.assembled
    assert topology.dof == 1
    assert topology.rank == 2 * n  # two rows a cut revolute, all independent
    assert topology.redundant_constraints == []
    # the configuration decided at is the initial one (cranks vertical), not the neutral one
    assert np.allclose(topology.configuration[: n + 1], np.pi / 2)


def test_describe_cli_says_one_dof_for_forty_windows() -> None:
    result = CliRunner().invoke(cli.app, ["describe", "iftomm-a02", "-o", "n=40"])
    assert result.exit_code == 0, result.output
    (dof_line,) = [line for line in result.output.splitlines() if " DOF " in line]
    assert dof_line.split("│")[2].strip() == "1"
    assert "crank_40" in result.output  # the model built with n = 40


@pytest.mark.parametrize("case", list(PIPELINES))
def test_every_formalism_keeps_one_dof_and_every_loop(case: str) -> None:
    equations, state = built(case)
    assert removed_rows(equations.notes) == []
    mechanical = equations.forms["mechanical"]
    nc, nv = mechanical.n_constraints, state.v.size
    if nc:  # the constraint rows the equations keep: all independent at t0, leaving 1 DOF
        (w_matrix,) = mechanical.velocity_matrix(problem().t_start, state.q)
        w_matrix = np.reshape(w_matrix, (nc, nv))
        assert np.linalg.matrix_rank(w_matrix) == nc == nv - 1
    else:  # state space: one independent velocity
        assert nv == 1


def integrate(case: str) -> tuple[np.ndarray, np.ndarray]:
    """(times, body poses) of a tight run over SPAN."""
    equations, state = built(case)
    p = problem()
    formalism, options = PIPELINES[case]
    index = options.get("index", 1)
    times = np.linspace(p.t_start, p.t_start + (GA_SPAN if index == 3 else SPAN), 7)
    if index == 1:  # the ode form (Baumgarte index 1, or the state-space ODE)
        rhs = equations.forms["ode"].rhs
        solution = solve_ivp(
            lambda t, y: np.ravel(rhs(t, y)[0]),
            (times[0], times[-1]),
            state.y0(equations, "ode"),
            method="DOP853",
            rtol=1e-10,
            atol=1e-12,
            t_eval=times,
        )
        assert solution.success, solution.message
        q_path = solution.y[: equations.nq].T
    else:
        # index 2: IDA, adaptive; index 3: generalized-alpha, second order, fixed step
        name, form, opts = ("sundials-ida", "dae", {})
        if index == 3:
            name, form, opts = ("generalized-alpha", "mechanical", {"step": GA_STEP})
        trajectory = get_integrator(name)().solve(
            equations,
            state.y0(equations, form),
            state.yp0(equations, form),
            times,
            1e-9,
            1e-11,
            opts,
            form=form,
        )
        assert trajectory.success, trajectory.message
        q_path = np.asarray(trajectory.y)[:, : equations.nq]
    poses = np.array(
        [np.asarray(equations.observables.poses(t, q)) for t, q in zip(times, q_path, strict=True)]
    )
    return times, poses.reshape(times.size, -1, 7)


@pytest.mark.parametrize("case", list(PIPELINES))
def test_every_formalism_follows_the_exact_one_dof_motion(case: str) -> None:
    times, poses = integrate(case)
    exact = problem().reference().poses(times)
    position_error = np.max(np.abs(poses[..., :3] - exact[..., :3]))
    # quaternions up to sign
    dots = np.abs(np.sum(poses[..., 3:] * exact[..., 3:], axis=-1))
    tolerance = GA_TOLERANCE if PIPELINES[case][1].get("index") == 3 else POSE_TOLERANCE
    assert position_error < tolerance
    assert np.max(1.0 - dots) < tolerance**2
    # the coupler tips really moved (phi went from 90 degrees below 75 in SPAN)
    assert times[-1] < SPAN or exact[-1, N + 1, 1] < np.sin(np.radians(75))


@pytest.mark.parametrize("formalism", ["absolute-dae", "nonholonomic-projection"])
def test_two_windows_keep_every_row_in_every_formalism(formalism: str) -> None:
    equations = get_formalism(formalism)().build(problem(2).model(), {})
    assert removed_rows(equations.notes) == []
    state = consistent_initial_state(equations, problem(2))
    if formalism == "nonholonomic-projection":
        assert state.v.size == 1  # one minimal velocity


def test_state_space_accepts_two_windows() -> None:
    """W has full rank at the initial configuration: not 'redundant' (it was refused)."""
    equations = get_formalism("minimal-ode")().build(problem(2).model(), {"loops": "state-space"})
    assert equations.nv == 1
