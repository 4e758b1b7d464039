"""Close calls timed again at moments apart (workbench.runs.retime): the rows' samples, the
ranking's interval, the choice of runs and a sweep end to end."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from tests.test_report_decision import costed
from workbench.errors import ConfigError
from workbench.execution.execute import RunSpec
from workbench.execution.row_schema import SCHEMA_VERSION
from workbench.execution.timing import retimed_columns
from workbench.outputs.report.close_calls import close_calls
from workbench.outputs.report.ranking import decide
from workbench.runs import store
from workbench.runs.retime import (
    CHILD_START_S,
    RETIMED_FILE,
    balanced_bins,
    retime_close_calls,
    retimed_row,
)
from workbench.runs.sweep import parse_spec, run_sweep

OWN = {"integrate_s": 0.021, "integrate_s_min": 0.020, "integrate_s_max": 0.022,
       "integrate_cpu_s": 0.020, "integrate_cpu_s_min": 0.019, "integrate_cpu_s_max": 0.021,
       "repeats": 3, "retimed": 0, "status": "ok", "warnings": "", "n_rhs": 500,
       "n_jac": 0, "n_steps": 40, "n_rejected": 2, "n_lu": 0, "n_newton": 0}  # fmt: skip


def test_the_own_back_to_back_samples_count_as_one_beside_the_new_ones() -> None:
    cpu = [0.030, 0.018, 0.022, 0.050, 0.0185]
    wall = [0.031, 0.019, 0.023, 0.051, 0.0195]
    columns = retimed_columns(OWN, wall, cpu)
    # median of the own median (one sample: they shared their moment) and the five
    assert columns["integrate_cpu_s"] == pytest.approx(0.021)
    assert columns["integrate_cpu_s_min"] == 0.018 and columns["integrate_cpu_s_max"] == 0.050
    assert columns["integrate_s"] == pytest.approx(0.022)
    assert columns["integrate_s_min"] == 0.019 and columns["integrate_s_max"] == 0.051
    assert columns["repeats"] == 8 and columns["retimed"] == 5
    # a row of an older schema without its interval: the new samples give it
    older = retimed_columns(OWN | {"integrate_cpu_s_min": float("nan")}, wall, cpu)
    assert older["integrate_cpu_s_min"] == 0.018


def test_a_sample_of_other_work_warns_and_too_few_leave_the_row() -> None:
    sample = lambda n_rhs, status="ok": ("r", status, 0.02, 0.02,  # noqa: E731
                                         {k: OWN[k] for k in OWN if k.startswith("n_")}
                                         | {"n_rhs": n_rhs})  # fmt: skip
    warned = retimed_row(OWN, [sample(500), sample(512)])
    assert (
        "not reproducible: timed again" in warned["warnings"]
        and "n_rhs 500 then 512" in (warned["warnings"])
    )
    assert warned["retimed"] == 0 and warned["integrate_cpu_s"] == OWN["integrate_cpu_s"]
    older = retimed_row(OWN | {"warnings": float("nan")}, [sample(500), sample(512)])
    assert older["warnings"].startswith("not reproducible")  # (a row read back: NaN)
    assert retimed_row(OWN, [sample(500)]) is None  # one sample: no interval to trust
    assert retimed_row(OWN, [sample(500), sample(500, "failed")]) is None
    assert retimed_row(OWN, [sample(500), sample(500)])["retimed"] == 2


def test_a_retimed_interval_runs_from_its_least_sample_to_its_median() -> None:
    # a's greatest sample is a slow spell's: by [min, max] b would be tied with it
    runs = costed([("a / x", 6.0, 0.020, 0.019, 0.030), ("b / y", 6.0, 0.022, 0.0205, 0.025)])
    assert decide(runs, 4.0, "integrate_cpu_s").is_tie
    runs["retimed"] = 5
    decision = decide(runs, 4.0, "integrate_cpu_s")
    assert not decision.is_tie and decision.high == 0.020
    assert decision.verdict() == "1.100x ahead"
    # b's least sample reaches a's median: tied
    runs.loc[1, "integrate_cpu_s_min"] = 0.0199
    assert decide(runs, 4.0, "integrate_cpu_s").is_tie


def test_the_close_calls_are_the_pairs_near_a_cells_cheapest() -> None:
    rows = costed([
        ("a / x", 6.0, 1.0, 0.9, 1.1),
        ("b / y", 6.0, 2.5, 2.4, 2.6),  # within 3x of a: a close call
        ("c / z", 6.0, 4.0, 3.9, 4.1),  # not
        ("d / w", 9.0, 9.0, 8.9, 9.1),  # alone at scd >= 8: nothing to decide there
    ])  # fmt: skip
    rows["warnings"] = ""
    assert close_calls(rows) == ["r0", "r1"]
    rows.loc[1, "warnings"] = "drift: lost its constraints"  # not trusted: not a candidate
    assert close_calls(rows) == []
    assert close_calls(rows.iloc[:0]) == []


def test_the_timing_processes_share_the_work_a_model_in_one() -> None:
    runs = [RunSpec(problem, formalism, "scipy-dop853", rtol, rtol * 1e-3)
            for problem in ("four-bar", "heavy-top") for formalism in ("minimal-ode", "recursive")
            for rtol in (1e-4, 1e-7)]  # fmt: skip
    cost = {spec.run_id: (3.0 if spec.problem == "heavy-top" else 1.0) for spec in runs}
    bins = balanced_bins(runs, cost, 2)
    assert sorted(spec.run_id for b in bins for spec in b) == sorted(cost)
    for each in bins:  # a model's two tolerances in one bin: built by one process
        models = {(spec.problem, spec.formalism) for spec in each}
        assert len(each) == 2 * len(models)
    loads = sorted(sum(cost[spec.run_id] for spec in b) for b in bins)
    assert loads == [8.0, 8.0]  # one heavy-top model (6 s) and one four-bar (2 s) each
    assert len(balanced_bins(runs[:2], cost, 2)) == 1  # one model: one process


def test_the_announced_time_counts_the_processes_start_up_and_their_models_builds(
    tmp_path,
) -> None:
    """A timing process starts and builds each of its models once before its first sample:
    the announced seconds count it, from the rows' build times (each model's most, not
    every row's), shared by the processes; not from a clock (the samples are not taken)."""
    runs = [RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-6, 1e-9),
            RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-6, 1e-9),
            RunSpec("simple-pendulum", "recursive", "scipy-dop853", 1e-6, 1e-9)]  # fmt: skip
    built = [(18.0, 1.0), (20.0, 1.0), (9.0, 1.0)]  # a model built by both workers: 21 s
    for spec, (build, init) in zip(runs, built, strict=True):
        row = {"run_id": spec.run_id, "schema_version": SCHEMA_VERSION, "status": "ok",
               "integrate_cpu_s": 0.01, "retimed": 0, "build_s": build, "init_s": init}  # fmt: skip
        path = store.row_path(tmp_path, spec.run_id)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(row))

    def announced(jobs: int) -> float:
        said: list[str] = []
        done = retime_close_calls(
            tmp_path, runs, lambda frame: list(frame["run_id"]), 2, 3.0, 10.0, [],
            said.append, jobs=jobs, sampler=lambda *args: None,  # (no samples: rows stay)
        )  # fmt: skip
        assert done == [] and len(said) == 1
        assert said[0].startswith("timing 3 close call(s) again: 2 rounds at least 2 s apart")
        return float(said[0].split("(about ")[1].split(" s;")[0])

    builds = 21.0 + 10.0  # each model once (its most); the rounds' gap and CPU about 2 s
    assert CHILD_START_S + builds <= announced(1) <= CHILD_START_S + builds + 3
    assert CHILD_START_S + builds / 2 <= announced(2) <= CHILD_START_S + builds / 2 + 3


def test_the_rounds_are_checked_in_the_specification(tmp_path) -> None:
    text = 'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
    text += 'integrators = ["scipy-dop853"]\ntolerances = [1e-6]\n'
    assert parse_spec(text).retime == 5
    assert parse_spec(text + "retime = 0\n").retime == 0
    for bad in ("-1", "101", "2.5", "true"):
        with pytest.raises(ConfigError, match="retime: must be an integer from 0 to 100"):
            parse_spec(text + f"retime = {bad}\n")


def two_pairs(out, extra: str = "") -> str:
    """A sweep of two close pairs (the double pendulum, two formalisms, DOP853), timed
    again twice."""
    return f"""
out = "{out.as_posix()}"
{extra}time_limit = 300.0  # only a hung run reaches it
retime = 2
problems = ["double-pendulum"]
formalisms = ["minimal-ode", "recursive"]
integrators = ["scipy-dop853"]
tolerances = [1e-6]
"""


def test_a_sweep_times_its_close_calls_again_once(tmp_path) -> None:
    out = tmp_path / "out"
    spec = parse_spec(two_pairs(out, "jobs = 2\n"))
    said: list[str] = []
    seen: list[set[str]] = []

    def choose_all(frame: pd.DataFrame) -> list[str]:  # (close_calls' own test is above)
        seen.append(set(frame["run_id"]))
        return list(frame["run_id"])

    summary = run_sweep(spec, show_progress=False, say=said.append, close_calls=choose_all)
    assert summary.counts["ok"] == 2
    assert any("then the close calls timed again: 2 rounds" in line for line in said)
    assert any("timing 2 close call(s) again: 2 rounds" in line for line in said)
    rows = store.load_results(out)
    assert rows.attrs["unreadable"] == []  # the rewritten rows pass the row check
    assert list(rows["retimed"]) == [2, 2]
    assert list(rows["repeats"]) == [5, 5]  # three of its own, two again
    for _, row in rows.iterrows():
        assert row["integrate_cpu_s_min"] <= row["integrate_cpu_s"] <= row["integrate_cpu_s_max"]
    # the same work each time: the double pendulum's DOP853 counts are the row's
    assert not rows["warnings"].fillna("").str.contains("not reproducible").any()
    results = pd.read_parquet(out / store.RESULTS_FILE)
    assert list(results["retimed"]) == [2, 2]  # consolidated after the re-timing
    record = json.loads((out / RETIMED_FILE).read_text())
    assert sorted(record["runs"]) == sorted(rows["run_id"]) and record["rounds"] == 2
    before = {p.name: p.read_bytes() for p in (out / store.RUNS_DIR).glob("*.json")}
    said.clear()
    run_sweep(spec, show_progress=False, say=said.append, close_calls=choose_all)
    assert not any("close call" in line for line in said)  # a resume: nothing again
    assert len(seen) == 1  # (not even chosen: the rows are those the re-timing left)
    assert {p.name: p.read_bytes() for p in (out / store.RUNS_DIR).glob("*.json")} == before
    with pytest.raises(ConfigError, match="--retime must be an integer"):
        run_sweep(spec, show_progress=False, retime=-1, close_calls=close_calls)
    # a resume adding a formalism: the choice sees every row, only the new one is timed
    seen.clear()
    index_1 = '{ name = "absolute-dae", options = { index = 1 } }'  # (an ODE for DOP853)
    more = parse_spec(spec.text.replace('"recursive"]', f'"recursive", {index_1}]'))
    run_sweep(more, show_progress=False, say=said.append, close_calls=choose_all)
    assert seen == [{run.run_id for run in more.runs}]
    rows = store.load_results(out).set_index("run_id")
    new = next(run.run_id for run in more.runs if run.formalism == "absolute-dae")
    assert rows.loc[new, "retimed"] == 2
    assert {p.name: p.read_bytes() for p in (out / store.RUNS_DIR).glob("*.json")
            if p.stem != new} == before  # fmt: skip


def test_the_first_screen_says_whether_the_close_calls_were_timed_again(tmp_path) -> None:
    from tests.test_report import synthetic_results
    from workbench.outputs.report import write_report

    results = synthetic_results(problems=("simple-pendulum",))
    page = write_report(results, None, tmp_path / "a", "cmd", progress=False).read_text()
    decision = page[page.index('id="decision"') :]
    assert "No run was timed again after the runs" in decision
    results["retimed"] = [5, 5] + [0] * (len(results) - 2)
    page = write_report(results, None, tmp_path / "b", "cmd", progress=False).read_text()
    decision = page[page.index('id="decision"') :]
    assert "2 close call(s), the runs of pairs within 3x of a cheapest, were timed again" in (
        decision
    )
    assert "5 times at moments apart" in decision
    # a counted cost has no timing to trust or doubt
    page = write_report(results, None, tmp_path / "c", "cmd", progress=False, cost="n_rhs")
    assert "timed again" not in page.read_text()


@pytest.mark.slow
def test_a_dask_sweep_times_its_close_calls_again_on_the_workers(tmp_path) -> None:
    """With a scheduler the close calls are timed again on the cluster's workers (the
    machines that timed the runs), not skipped as before: each row gains the rounds'
    samples, and the plan and the progress lines say so."""
    distributed = pytest.importorskip("distributed")
    out = tmp_path / "out"
    spec = parse_spec(two_pairs(out))
    said: list[str] = []
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        summary = run_sweep(spec, show_progress=False, say=said.append,
                            scheduler=cluster.scheduler_address,
                            close_calls=lambda frame: list(frame["run_id"]))  # fmt: skip
    assert summary.counts["ok"] == 2
    assert any("close calls timed again on the cluster's workers: 2 rounds" in line
               for line in said)  # fmt: skip
    assert any("timing 2 close call(s) again: 2 rounds" in line for line in said)
    rows = store.load_results(out)
    assert rows.attrs["unreadable"] == []
    assert list(rows["retimed"]) == [2, 2] and list(rows["repeats"]) == [5, 5]
    for _, row in rows.iterrows():
        assert row["integrate_cpu_s_min"] <= row["integrate_cpu_s"] <= row["integrate_cpu_s_max"]
    assert not rows["warnings"].fillna("").str.contains("not reproducible").any()
    record = json.loads((out / RETIMED_FILE).read_text())
    assert sorted(record["runs"]) == sorted(rows["run_id"])


def test_a_workers_timing_child_returns_its_samples_and_is_killed_past_the_limit() -> None:
    """The Dask task's child (workbench.runs.dask_retime): every timed round's sample of
    each run, the same work as the run's; a sample slower than the time limit ends it,
    the samples before it kept."""
    from workbench.runs.dask_retime import time_on_worker

    runs = [RunSpec("simple-pendulum", "minimal-ode", integrator, 1e-8, 1e-11)
            for integrator in ("scipy-dop853", "scipy-rk45")]  # fmt: skip
    specs = [run.to_dict() for run in runs]
    samples = time_on_worker(specs, 2, 0.0, 60.0, [], [], {})
    assert sorted(s[0] for s in samples) == sorted(2 * [run.run_id for run in runs])
    for _run_id, status, wall, cpu, counts in samples:
        assert status == "ok" and wall > 0 and cpu > 0 and counts["n_rhs"] > 0
    by_run = {}
    for run_id, _status, _wall, _cpu, counts in samples:  # each round did the same work
        assert by_run.setdefault(run_id, counts) == counts
    # each sample 0.05-0.2 s of integration against a limit of 5 ms: the child is killed
    # before its second message, whatever the load (a sample comes only once integrated)
    slow = RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-12, 1e-15).to_dict()
    assert len(time_on_worker([slow], 3, 0.0, 0.005, [], [], {})) < 3


def test_the_clusters_retiming_ends_when_no_worker_takes_it(monkeypatch) -> None:
    """A cluster whose workers left after the runs: the runs would wait for one however
    late, the re-timing (optional) gives up after its limit and the rows keep theirs."""
    import time

    distributed = pytest.importorskip("distributed")
    from workbench.runs import dask_retime

    monkeypatch.setattr(dask_retime, "START_S", 1.0)  # (a child's start-up allowance)
    run = RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-6, 1e-9)
    taken: list = []
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        said: list[str] = []
        sampler = dask_retime.ClusterSampler(cluster.scheduler_address, said.append)
        try:
            started = time.monotonic()
            sampler([run], {run.run_id: 0.01}, 2, 0.0, 1.0, [], taken.append)
            waited = time.monotonic() - started
        finally:
            sampler.close()
    limit = dask_retime.phase_limit([[run]], {run.run_id: 0.01}, 2, 0.0, 1.0)
    assert taken == [] and limit <= waited < limit + 30
    assert said == [f"close calls: the cluster's timing did not end within {limit:.0f} s (no "
                    "worker, or one far slower than the runs); the runs not timed again keep "
                    "their own samples"]  # fmt: skip
