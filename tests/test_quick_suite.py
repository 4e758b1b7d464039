"""The first look: ``workbench sweep`` runs the quick suite (workbench/runs/suites/quick.toml),
one mechanism of each family, says beforehand how many runs and how long, and its run count
does not depend on installed extras (workbench.runs.estimate, Problem.unavailable)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from workbench.cli import app
from workbench.execution.execute import RunSpec
from workbench.plugin.registry import get_problem
from workbench.runs.estimate import (
    Costs,
    duration,
    estimate_lines,
    known_costs,
    run_seconds,
    shipped_tables,
)
from workbench.runs.sweep_spec import DEFAULT_SUITE, load_spec

QUICK_RUNS = 6 * 3 * 3 * 2  # problems x formalisms x integrators x tolerances


def families(name: str) -> set[str]:
    """The traits of problem ``name`` that the quick suite must cover, from its model."""
    problem = get_problem(name)()
    model = problem.model()
    traits = set()
    if model.cut_joints:
        traits.add("closed loop")
    else:
        traits.add("tree")
    if model.nonholonomic:
        traits.add("nonholonomic")
    if any(joint.type in ("spherical", "free") for joint in model.joints.values()):
        traits.add("quaternions")
    stiffness = [getattr(force, "stiffness", 0.0) for force in model.forces]
    if max(stiffness, default=0.0) >= 1e5:  # N/m: the governor's 8e5 springs
        traits.add("stiff")
    if "robot_files" in problem.source or "MJCF" in problem.source:
        traits.add("robot file shipped")
    return traits


def test_the_default_sweep_is_the_quick_suite_and_covers_every_family() -> None:
    quick = load_spec(None)
    assert DEFAULT_SUITE == "quick" and quick.suite == "quick"
    assert len(quick.runs) == QUICK_RUNS
    problems = sorted({run.problem for run in quick.runs})
    covered = set().union(*(families(name) for name in problems))
    wanted = {"tree", "closed loop", "stiff", "nonholonomic", "quaternions", "robot file shipped"}
    assert wanted <= covered, wanted - covered
    assert len({run.formalism for run in quick.runs}) == 3
    assert len({run.integrator for run in quick.runs}) == 3
    assert len({run.rtol for run in quick.runs}) == 2
    # the spec plans only: nothing about the machine or the extras enters its count
    assert str(quick.out) == "reports/quick"


def test_a_suite_plans_the_same_runs_without_the_robots_extra(monkeypatch, tmp_path) -> None:
    """Without example-robot-data (simulated where its problems look for it) the full suite
    plans the same runs, and the robots' runs become skipped rows naming the install."""
    pytest.importorskip("workbench.problems.robots", reason="example-robot-data missing")
    from workbench.execution.execute import execute_run
    from workbench.problems import robots

    counts = {}
    for installed in (True, False):
        if not installed:
            monkeypatch.setattr(robots, "_ROBOTS", None)
        assert (robots.UR5().unavailable() is None) is installed
        counts[installed] = {name: len(load_spec(name).runs) for name in ("quick", "full")}
    assert counts[True] == counts[False]
    assert counts[False]["quick"] == QUICK_RUNS
    full = load_spec("full")
    assert {"ur5", "solo12"} <= {run.problem for run in full.runs}
    solo = next(run for run in full.runs if run.problem == "solo12")
    row = execute_run(solo, reference_dir=tmp_path).row
    assert row["status"] == "skipped"
    assert 'pip install "mbs-workbench[robots]"' in row["message"]


# ---- the estimate -----------------------------------------------------------------------


def spec(problem: str, rtol: float = 1e-4) -> RunSpec:
    return RunSpec(problem, "minimal-ode", "scipy-dop853", rtol, rtol * 1e-3)


def test_run_seconds_count_a_runs_own_work_not_its_wait() -> None:
    idle = {"status": "ok", "wall_s": 1.0, "cpu_s": 1.0, "reference_s": 0.5, "log_s": 0.1,
            "repeats": 3, "integrate_s": 0.2}  # fmt: skip
    assert run_seconds(idle, 30.0) == pytest.approx(1.0 + 0.5 + 0.1 + 2 * 0.2)
    # the same run on a machine where it got a quarter of a core: the same work
    busy = {k: v * 4 if k.endswith("_s") else v for k, v in idle.items()} | {"cpu_s": 1.0}
    assert run_seconds(busy, 30.0) == pytest.approx(run_seconds(idle, 30.0))
    assert run_seconds({"status": "timeout"}, 30.0) == 30.0


def test_the_estimate_says_how_long_and_warns_when_long() -> None:
    costs = Costs(overhead_s=10.0, sources=["a table"])
    costs.add(spec("p").run_id, "p|minimal-ode|scipy-dop853|1.000e-04", "p", 2.0)
    lines = estimate_lines([spec("p")] * 10, 10, 2, costs)
    assert lines == [
        "plan: 10 runs on 2 worker(s); estimated 20 s on an idle machine "
        "(from measured costs: a table)"
    ]
    # a problem without a measured run takes its problem's median, else everyone's: rough
    assert "no estimate of the time" in estimate_lines([spec("q")], 1, 2, costs)[0]
    lines = estimate_lines([spec("p", 1e-8)] * 400, 1000, 2, costs)
    assert lines[0].startswith("plan: 1000 runs, 400 to run on 2 worker(s); estimated 6 min")
    assert "rough: 400 of 400 runs have no measured cost" in lines[0]
    assert lines[1].startswith("warning: this sweep is long (about 6 min")
    assert "`workbench sweep` (the quick suite)" in lines[1]
    nothing = estimate_lines([spec("p")], 1, 2, Costs())
    assert "no estimate of the time" in nothing[0]
    assert duration(59) == "59 s" and duration(75) == "1 min 15 s" and duration(4000) == "1 h 6 min"


def test_the_shipped_tables_estimate_the_quick_suite_short_and_the_full_one_long() -> None:
    """The quick suite's own measured costs cover every one of its runs; the full suite is
    estimated from its own table, nearly all its runs measured, beyond the five minutes
    that warn."""
    tables = shipped_tables()
    shipped = {"full.costs.json", "quick.costs.json", "nonsmooth.costs.json"}
    assert shipped <= {t.name for t in tables}
    for shipped in tables:
        table = json.loads(shipped.read_text("utf-8"))
        assert table["measured"] and table["overhead_s"] >= 0
    quick = load_spec("quick")
    costs = known_costs({}, quick.time_limit, "quick")
    assert {s.run_id for s in quick.runs} <= set(costs.by_id)  # every run measured
    lines = estimate_lines(quick.runs, len(quick.runs), quick.jobs, costs)
    assert len(lines) == 1 and "from measured costs" in lines[0]
    # the tables that gave costs, not every table there is
    assert lines[0].endswith("(from measured costs: workbench/runs/suites/quick.costs.json)")
    full = load_spec("full")
    lines = estimate_lines(full.runs, len(full.runs), full.jobs, known_costs({}, 30.0, "full"))
    assert "full.costs.json" in lines[0] and lines[1].startswith("warning: this sweep is long")
    # not rough: the catalog grew by 8 problems without their runs in the table once (fix:
    # python -m benchmarks.suite_costs full --missing)
    assert "rough" not in lines[0], lines[0]


def test_the_sweep_prints_its_plan_before_it_starts_and_the_way_to_the_full_one(
    fake_plugins, tmp_path
) -> None:
    spec_file = tmp_path / "s.toml"
    spec_file.write_text(
        'problems = ["test-pendulum"]\nformalisms = [{ name = "minimal-ode", options = '
        '{ index = 1 } }]\nintegrators = ["test-rk45"]\ntolerances = [1e-4, 1e-6]\n'
        "jobs = 1\n"
    )
    out = tmp_path / "out"
    first = CliRunner().invoke(app, ["sweep", str(spec_file), "--out", str(out)])
    assert first.exit_code == 0, first.output
    assert "plan: 2 runs on 1 worker(s); no estimate of the time" in first.output
    assert "full comparison: workbench sweep full" in first.output
    # resumed with --fresh: its own rows are the measured costs
    again = CliRunner().invoke(app, ["sweep", str(spec_file), "--out", str(out), "--fresh"])
    assert again.exit_code == 0, again.output
    assert "plan: 2 runs on 1 worker(s); estimated" in again.output
    assert "the rows already in the output directory" in again.output


# ---- the quick suite end to end ------------------------------------------------------------


@pytest.mark.slow  # about 50 s on 2 idle cores (docs/suites.md); minutes on a loaded machine
@pytest.mark.timeout(3600)
def test_workbench_sweep_runs_the_quick_suite_end_to_end(tmp_path) -> None:
    import subprocess
    import sys

    from workbench.runs.store import load_results

    out = tmp_path / "quick"
    done = subprocess.run(
        [sys.executable, "-m", "workbench", "sweep", "--out", str(out)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    said = done.stdout + done.stderr
    assert f"plan: {QUICK_RUNS} runs on 2 worker(s); estimated" in said
    assert "from measured costs" in said and "warning: this sweep is long" not in said
    assert "full comparison: workbench sweep full" in said
    rows = load_results(out)
    assert len(rows) == QUICK_RUNS and set(rows["run_id"]) == {r.run_id for r in load_spec().runs}
    assert (out / "report" / "index.html").is_file()
    # every problem answers: an ok run of each, three timed samples where it is short
    ok = rows[rows["status"] == "ok"]
    assert set(ok["problem"]) == set(rows["problem"])
    short = ok[ok["integrate_cpu_s_max"] < 0.5]
    assert len(short) and (short["repeats"] >= 3).all()
    assert (ok["integrate_cpu_s_min"] <= ok["integrate_cpu_s"]).all()
    assert (ok["integrate_cpu_s"] <= ok["integrate_cpu_s_max"]).all()
    # the skipped rows say why: the recursive formalism has no nonholonomic rows
    skipped = rows[rows["status"] == "skipped"]
    assert set(skipped["problem"]) <= {"rolling-pendulum"}
