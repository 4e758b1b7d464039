"""Accelerations are solved with the factorization the system's structure allows (issue 32).

IFToMM A02 (N four-bar windows) on its parallelogram branch at crank angle phi and rate w:
every crank has phi'' = -((9N+3)/(8N+2)) g cos(phi) / L exactly (problems/iftomm.py), and
every crank the same one, bit for bit, because the motion is the same for each. A
least-squares solve of the regular KKT system lost 1.5-2 digits of it and gave the cranks
different accelerations (1e-14 apart); Cholesky of M and of W M^-1 W^T keeps both.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from workbench.equations.initial import (
    accelerations_and_method,
    consistent_initial_state,
    solve_accelerations,
)
from workbench.errors import IntegrationError
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
from workbench.model import Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import get_formalism, get_problem
from workbench.problems.iftomm import a02_coefficient

PHI, RATE = 0.7, -2.3  # rad, rad/s: a generic state on the parallelogram branch


def a02_accelerations(n: int, formalism: str, options: dict) -> tuple[np.ndarray, np.ndarray, str]:
    """(theta'' of crank_0 .. crank_n, the other accelerations, method) at (PHI, RATE)."""
    model = get_problem("iftomm-a02")({"n": n}).model()
    equations = get_formalism(formalism)().build(model, options)
    kinematics = TreeKinematics(model)
    angles = {f"pin_{i}": PHI for i in range(n + 1)} | {f"left_{i}": -PHI for i in range(1, n + 1)}
    rates = {f"pin_{i}": RATE for i in range(n + 1)} | {f"left_{i}": -RATE for i in range(1, n + 1)}
    q_joint = initial_joint_values(model, kinematics, angles, False)
    v_joint = initial_joint_values(model, kinematics, rates, True)
    q, v = (np.ravel(x) for x in equations.joint_space_map(0.0, q_joint, v_joint))
    acceleration, _, _, method = accelerations_and_method(equations, 0.0, q, v)
    if formalism == "absolute-dae":  # x, y, theta of each body, the cranks first
        cranks = np.arange(2, 3 * (n + 1), 3)
    else:  # joint coordinates: pin_0 .. pin_n, then left_1 .. left_n
        cranks = np.arange(n + 1)
    return acceleration[cranks], np.delete(acceleration, cranks), method


@pytest.mark.parametrize(
    ("formalism", "options", "digits"),
    [("absolute-dae", {"index": 3}, 8e-15), ("lagrange-ad", {}, 2e-15),
     ("recursive", {"index": 3}, 2e-15)],
)  # fmt: skip
def test_forty_windows_accelerate_to_the_analytic_value(formalism, options, digits) -> None:
    """N = 40: relative error of every crank's phi'' (least squares: 1.6e-14, 8.2e-15 and
    6.0e-15; Cholesky: 3.8e-15, 4.4e-16, 4.4e-16)."""
    crank, _, method = a02_accelerations(40, formalism, options)
    exact = -a02_coefficient(40) * math.cos(PHI)
    assert method == "cholesky of M and W M^-1 W^T"
    assert np.max(np.abs(crank / exact - 1)) < digits


def test_a_symmetric_motion_keeps_exact_symmetry() -> None:
    """N = 2 in joint coordinates: the three cranks turn alike, to the bit (least squares
    gave them accelerations 7e-15 apart)."""
    crank, _, _ = a02_accelerations(2, "recursive", {"index": 3})
    assert np.ptp(crank) == 0.0, crank - crank[0]


def test_least_squares_only_for_a_rank_deficient_system_and_said() -> None:
    mass = np.diag([2.0, 3.0])
    forces = np.array([1.0, -1.0])
    regular = solve_accelerations(mass, forces, np.array([[1.0, 1.0]]), np.zeros(1))
    assert regular[2] == "cholesky of M and W M^-1 W^T"
    assert regular[0][0] == -regular[0][1]  # W v' = 0
    redundant = solve_accelerations(mass, forces, np.array([[1.0, 1.0], [2.0, 2.0]]), np.zeros(2))
    assert redundant[2].startswith("least squares: the KKT matrix is rank-deficient")
    np.testing.assert_allclose(redundant[0], regular[0], rtol=1e-14)
    indefinite = solve_accelerations(
        np.diag([1.0, 0.0]), forces, np.array([[0.0, 1.0]]), np.zeros(1)
    )
    assert indefinite[2] == "LU of the KKT matrix"
    np.testing.assert_array_equal(indefinite[0], [1.0, 0.0])


class Slides:
    """A massless carriage on a slide along x carrying a 1 kg block: on a second slide
    along x (``parallel``: M singular, the carriage's x is not determined) or on a
    revolute joint 0.5 m from the block's centre (a pendulum on a massless cart: M is
    singular in absolute coordinates, regular where the joints tie the carriage)."""

    name, t_start = "slides", 0.0
    independent_coordinates = None

    def __init__(self, parallel: bool) -> None:
        self.parallel = parallel

    def model(self) -> Model:
        model = Model(self.name, kind="planar")
        model.add_point_mass("carriage", 0.0)
        model.add_body("block", 1.0, com=(0.0, -0.5, 0.0), inertia=0.1)
        model.add_joint("rail", "prismatic", "ground", "carriage", axis=(1, 0, 0))
        kind, axis = ("prismatic", (1, 0, 0)) if self.parallel else ("revolute", (0, 0, 1))
        model.add_joint("second", kind, "carriage", "block", axis=axis)
        return model.validate()

    def initial_joint_coordinates(self) -> dict:
        return {}

    def initial_joint_velocities(self) -> dict:
        return {"rail": 1.0}


@pytest.mark.parametrize("formalism, options", [("minimal-ode", {"index": 1}),
                                                ("recursive", {}),
                                                ("absolute-dae", {"index": 1})])  # fmt: skip
def test_a_mass_matrix_singular_where_the_joints_allow_motion_is_refused(
    formalism: str, options: dict
) -> None:
    """Two slides along x with a massless carriage between them: the initial state named
    no culprit (minimal-ode and lagrange-ad then failed at once with a NaN right-hand
    side, absolute-dae with LAPACK's 'row is exactly zero', recursive ran 'ok' on one of
    infinitely many motions). A massless cart under a pendulum is not refused."""
    for parallel in (True, False):
        problem = Slides(parallel)
        equations = get_formalism(formalism)().build(problem.model(), options)
        if not parallel:
            state = consistent_initial_state(equations, problem)
            assert np.all(np.isfinite(state.acceleration))
            continue
        with pytest.raises(IntegrationError, match=r"problem 'slides': the mass matrix is "
                           r"singular on the motions the constraints allow at t = 0 s: a "
                           r"motion of .* has no inertia"):
            consistent_initial_state(equations, problem)


def slides_problem(parallel: bool) -> type[Problem]:
    """:class:`Slides` as a registrable problem (``describe`` takes a Problem class)."""

    class SlidesProblem(Problem):
        """Slides (test)."""

        name = "test-parallel-slides" if parallel else "test-massless-cart"
        summary = "a massless carriage between two slides (test)"
        source = "test suite"
        t_end = 1.0

        def model(self) -> Model:
            return Slides(parallel).model()

        def initial_joint_velocities(self) -> dict:
            return {"rail": 1.0}

    return SlidesProblem


def test_describe_says_the_mass_matrix_is_singular_as_the_run_does(monkeypatch) -> None:
    """``describe`` of the two slides said "DOF 2" like any model; it now adds the finding
    the run's initial state raises, word for word, in the API and the CLI. The massless
    cart under a pendulum (regular) stays a plain DOF 2."""
    from typer.testing import CliRunner

    import workbench
    from workbench import cli
    from workbench.plugin.registry import REGISTRY, PluginInfo

    parallel, cart = slides_problem(True), slides_problem(False)
    dof = workbench.describe(parallel).facts["DOF"]
    assert re.fullmatch(r"2; the mass matrix is singular on the motions the constraints "
                        r"allow at t = 0 s: a motion of .*rail.* has no inertia, so the "
                        r"accelerations are not determined", dof)  # fmt: skip
    equations = get_formalism("minimal-ode")().build(parallel().model(), {"index": 1})
    with pytest.raises(IntegrationError) as raised:
        consistent_initial_state(equations, parallel())
    assert dof.removeprefix("2; ") in str(raised.value)
    assert workbench.describe(cart).facts["DOF"] == "2"
    REGISTRY.discover()
    for plugin in (parallel, cart):
        info = PluginInfo("problem", plugin.name, plugin, plugin.__module__)
        monkeypatch.setitem(REGISTRY.entries["problem"], plugin.name, info)
    monkeypatch.setenv("COLUMNS", "400")
    out = CliRunner().invoke(cli.app, ["describe", parallel.name]).stdout
    assert "the mass matrix is singular on the motions the constraints allow" in out
    out = CliRunner().invoke(cli.app, ["describe", cart.name]).stdout
    assert "DOF" in out and "singular" not in out
