"""IFToMM benchmark problems A01, A04, A05 (problems/iftomm.py), the ``iftomm`` sweep suite
and the report's benchmark scorecards (workbench/outputs/report/scorecards.py).

A02 is tested in tests/test_catalog.py beside the rest of the catalog.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

from workbench.errors import ConfigError
from workbench.execution.execute import RunSpec, execute_run
from workbench.execution.references import read_reference
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
from workbench.mechanics.topology import analyze
from workbench.outputs.report.analysis import prepare_results
from workbench.outputs.report.scorecards import NOT_REACHED, cheapest_meeting, scorecards
from workbench.plugin.registry import REGISTRY, get_formalism, get_problem
from workbench.runs import store
from workbench.runs.sweep_spec import load_spec, parse_spec, suite_names


def run(problem, formalism, integrator, rtol, formalism_options=None, problem_options=None):
    spec = RunSpec(problem, formalism, integrator, rtol, rtol * 1e-3,
                   problem_options or {}, formalism_options or {})  # fmt: skip
    return execute_run(spec).row


# ---- A01 ---------------------------------------------------------------------------


def test_a01_reference_is_the_exact_pendulum():
    """The Jacobi-elliptic reference against an independent tight integration of
    theta'' = -(g/l) sin(theta) from the horizontal at rest: P1's x, y agree to 1e-10 m."""
    problem = get_problem("iftomm-a01")({"duration": 20.0})
    times = problem.sample_times()
    poses = problem.reference().poses(times)[:, 0, :]
    solution = solve_ivp(
        lambda t, y: [y[1], -9.81 * np.sin(y[0])], (0.0, 20.0), [np.pi / 2, 0.0],
        method="DOP853", rtol=1e-13, atol=1e-14, t_eval=times,
    )  # fmt: skip
    theta = solution.y[0]
    assert np.abs(poses[:, 0] - np.sin(theta)).max() < 1e-10
    assert np.abs(poses[:, 1] + np.cos(theta)).max() < 1e-10
    assert poses[0, :2] == pytest.approx([1.0, 0.0], abs=1e-15)  # P1 at x = +1 m


def test_a01_spans_the_specification_on_request():
    full = get_problem("iftomm-a01")({"duration": 2000.0})
    assert (full.t_end, full.n_samples) == (2000.0, 4001)  # 4000 output steps
    assert get_problem("iftomm-a01")().n_samples == 41  # 20 s, one every 0.5 s
    with pytest.raises(ConfigError, match="duration"):
        get_problem("iftomm-a01")({"duration": -1.0})


# ---- A04 ---------------------------------------------------------------------------


def test_a04_is_overconstrained_with_one_dof_and_one_redundant_row():
    problem = get_problem("iftomm-a04")()
    model = problem.model()
    kinematics = TreeKinematics(model)
    q0 = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    topology = analyze(model, q=q0)
    assert (topology.dof_gruebler, topology.dof, topology.n_loops) == (0, 1, 1)
    # one of the cut joint's five rows is implied by the other four
    assert len(topology.redundant_constraints) == 1
    assert topology.redundant_constraints[0].startswith("pin_6[")


A04_RTOL = 1e-8


def a04_pipelines():
    """(formalism, options, integrator) for every registered formalism: its dae form at
    index 1 through IDA, or its ode form through DOP853 when it offers no dae form."""
    names = [info.name for info in REGISTRY.list("formalism") if info.plugin is not None]
    return [(name, {"index": 1} if "index" in _options(name) else {}) for name in names]


def _options(name):
    return {f for f in get_formalism(name).Options.__dataclass_fields__}


@pytest.mark.parametrize(("formalism", "options"), a04_pipelines())
def test_a04_every_formalism_conserves_energy_and_one_dof_or_says_why(formalism, options):
    """The benchmark's measure: the mechanical energy of Bricard's mechanism is conserved
    to the tolerance (relative error < 1000 rtol) and the motion keeps its one DOF, by
    every formalism that accepts the model; one that refuses (hamilton: no cut joints)
    says why. Measured at rtol 1e-8 with DOP853: 1.6e-12 (absolute-dae), 3.7e-10
    (minimal-ode, recursive), 4.3e-10 (lagrange-ad), 2.6e-6 (nonholonomic-projection,
    whose one-velocity state converges more slowly: 9.0e-5 at 1e-6, 7.8e-8 at 1e-10)."""
    row = run("iftomm-a04", formalism, "scipy-dop853", A04_RTOL, options)
    if row["status"] == "skipped":
        assert row["message"], "a skipped pair must say why"
        return
    assert row["status"] == "ok", row["message"]
    assert row["dof_start"] == 1
    assert row["energy_err_max"] < 1000 * A04_RTOL
    assert row["drift_pos_max"] < 1e-6  # every row of pin_6, the removed one included
    assert row["err_max"] < 1e-3  # m: the stored reference; the benchmark's precision


def test_a04_moves_from_rest_under_gravity():
    """Released at rest, gravity drives the one DOF: the stored motion is not a rest."""
    reference = read_reference(Path(__file__).parents[1] / "problems/references/iftomm-a04.npz")
    travel = np.linalg.norm(reference.poses[:, :, :3] - reference.poses[0, :, :3], axis=-1)
    assert travel.max() > 0.1  # m


# ---- A05 ---------------------------------------------------------------------------


def test_a05_stored_reference_comes_from_two_independent_pipelines():
    path = Path(__file__).parents[1] / "problems/references/iftomm-a05.json"
    metadata = json.loads(path.read_text())
    first, second = metadata["pipelines"]
    assert first["formalism"] != second["formalism"]
    assert first["integrator"] != second["integrator"]
    assert metadata["agreement"]["relative"] < 1e-7
    assert metadata["times"]["end"] == get_problem("iftomm-a05")().t_end


def test_a05_a_third_pipeline_reproduces_the_reference():
    """recursive (ABA) + CVODE BDF, sharing neither formalism nor integrator with the two
    stored pipelines, lands on the stored poses."""
    row = run("iftomm-a05", "recursive", "sundials-cvode-bdf", 1e-9, {"index": 1})
    assert row["status"] == "ok", row["message"]
    assert row["reference_kind"] == "stored"
    assert row["err_max"] / row["length_scale"] < 1e-5


# ---- suites ------------------------------------------------------------------------


def test_suites_are_found_by_name_and_unknown_ones_listed():
    assert {"quick", "full", "iftomm", "ivp"} <= set(suite_names())
    iftomm = load_spec("iftomm")
    assert {r.problem for r in iftomm.runs} == {"iftomm-a01", "iftomm-a02", "iftomm-a03",
                                                "iftomm-a04", "iftomm-a05"}  # fmt: skip
    assert load_spec().source == load_spec("quick").source
    listed = "unknown sweep suite 'nope'.*full, iftomm, ivp, nonsmooth, quick"
    with pytest.raises(ConfigError, match=listed):
        load_spec("nope")
    with pytest.raises(ConfigError, match="'default' is now called 'full'.*workbench sweep full"):
        load_spec("default")


# ---- scorecards --------------------------------------------------------------------


def _row(formalism, integrator, rtol, cpu_s, err_max, status="ok", warnings=""):
    return {"problem": "iftomm-a01", "formalism": formalism, "formalism_options": "{}",
            "integrator": integrator, "integrator_options": "{}", "rtol": rtol,
            "status": status, "cpu_s": cpu_s, "wall_s": cpu_s, "err_max": err_max,
            "scd": 3.0, "n_rhs": 10, "message": "", "warnings": warnings}  # fmt: skip


def test_scorecard_picks_the_cheapest_tolerance_that_meets_the_precision():
    rows = [
        _row("f", "i", 1e-3, 0.1, 5e-2),  # too coarse
        _row("f", "i", 1e-5, 0.3, 8e-4),  # meets 1e-3: the cheapest that does
        _row("f", "i", 1e-7, 0.9, 1e-6),  # meets, dearer
        _row("f", "i", 1e-9, 0.2, 1e-9, status="failed"),  # cheap but not ok
        _row("g", "i", 1e-3, 0.1, 2e-3),
        _row("g", "i", 1e-5, 0.2, 2e-3),  # never meets
    ]
    frame = prepare_results(pd.DataFrame(rows))
    found = cheapest_meeting(frame, "err_max", 1e-3).set_index("pair")
    f_pair, g_pair = sorted(found.index)
    assert found.loc[f_pair, "rtol"] == 1e-5 and found.loc[f_pair, "cpu_s"] == 0.3
    assert found.loc[g_pair, "verdict"] == NOT_REACHED and math.isnan(found.loc[g_pair, "cpu_s"])
    (card,) = scorecards(frame)  # iftomm-a01 declares suite "iftomm"
    assert card.table.loc[f_pair, "iftomm-a01"] == "0.3 s (rtol 1e-05)"
    assert card.table.loc[g_pair, "iftomm-a01"] == NOT_REACHED


def test_ivp_scorecard_lists_scd_against_cost_of_ok_runs():
    from workbench.outputs.report.scorecards import ivp_scorecard

    rows = [_row("f", "i", 1e-6, 0.2, 1e-6), _row("f", "i", 1e-9, 0.5, 1e-9, status="failed")]
    frame = prepare_results(pd.DataFrame(rows))
    table = ivp_scorecard(frame, {"iftomm-a01": {"suite": "ivp"}})
    assert list(table.columns) == ["problem", "pair", "rtol", "scd", "cpu_s", "n_rhs"]
    assert table[["rtol", "cpu_s"]].values.tolist() == [[1e-6, 0.2]]  # the failed run left out


def test_scorecard_of_a_real_tiny_a01_sweep_has_a_finite_entry(tmp_path):
    text = f"""
out = "{tmp_path.as_posix()}"
jobs = 1
tolerances = [1e-6, 1e-9]
problems = [{{ name = "iftomm-a01", options = {{ duration = 5.0 }} }}]
formalisms = [{{ name = "minimal-ode", options = {{ index = 1 }} }}]
integrators = ["scipy-dop853"]
"""
    from workbench.runs.sweep import run_sweep

    run_sweep(parse_spec(text), show_progress=False)
    frame = prepare_results(store.load_results(tmp_path))
    (card,) = scorecards(frame)
    (cell,) = card.table["iftomm-a01"]
    seconds = float(cell.split(" s ")[0])
    assert math.isfinite(seconds) and seconds > 0


def test_scorecard_scores_the_integration_not_the_build_a_worker_may_have_cached():
    """The same sweep taken in another order: a run that built its equations (0.38 s of
    CPU) or found them built (3e-5 s). The scorecard ranks by the integration's CPU time,
    so the build decides nothing; rows without it (before schema 7) fall back to cpu_s."""
    rows = [
        _row("f", "i", 1e-5, 0.40, 8e-4) | {"integrate_cpu_s": 0.02},  # built them
        _row("f", "i", 1e-7, 0.03, 1e-6) | {"integrate_cpu_s": 0.03},  # found them built
        _row("g", "i", 1e-5, 0.25, 8e-4) | {"integrate_cpu_s": math.nan},  # an old row
    ]
    frame = prepare_results(pd.DataFrame(rows))
    found = cheapest_meeting(frame, "err_max", 1e-3).set_index("pair")
    f_pair, g_pair = sorted(found.index)
    assert found.loc[f_pair, "rtol"] == 1e-5 and found.loc[f_pair, "cpu_s"] == 0.02
    assert found.loc[g_pair, "cpu_s"] == 0.25
    (card,) = scorecards(frame)
    assert card.table.loc[f_pair, "iftomm-a01"] == "0.02 s (rtol 1e-05)"
    assert "building and compiling the equations not counted" in card.note
