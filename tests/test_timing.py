"""Cost a reader can trust: repeated timing of the integration, the report's cost measure
and its warning about a crowded machine (workbench.execution.timing, outputs.report.cost)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from workbench.cli import app
from workbench.errors import ConfigError
from workbench.execution.execute import RunSpec, execute_run
from workbench.execution.row_check import row_defects
from workbench.execution.row_schema import SCHEMA_COLUMNS
from workbench.execution.timing import Samples, Timing, integrate_repeated, oversubscribed
from workbench.outputs.report import write_report
from workbench.outputs.report.analysis import (
    cheapest_pairs,
    oversubscription_warning,
    prepare_results,
)
from workbench.outputs.report.cost import resolve_cost
from workbench.runs.sweep_spec import parse_spec


def pendulum(rtol: float = 1e-6) -> RunSpec:
    return RunSpec(
        "test-pendulum", "minimal-ode", "test-rk45", rtol, rtol * 1e-3, {}, {"index": 1}, {}
    )


# ---- repeats --------------------------------------------------------------------------


def test_repeats_time_the_same_integration_and_keep_its_results(fake_plugins, tmp_path) -> None:
    once = execute_run(pendulum(), reference_dir=tmp_path, timing=Timing(1, 60.0))
    thrice = execute_run(pendulum(), reference_dir=tmp_path, timing=Timing(3, 60.0, workers=2))
    assert once.row["status"] == thrice.row["status"] == "ok"
    assert once.row["repeats"] == 1 and thrice.row["repeats"] == 3
    # the same work, the same answer: statistics, metrics and series identical
    for column in ("n_rhs", "n_steps", "n_rejected", "err_end", "err_max", "energy_err_max"):
        assert once.row[column] == thrice.row[column], column
    pd.testing.assert_frame_equal(once.series, thrice.series)
    assert thrice.row["warnings"] == once.row["warnings"]  # reproducible: nothing added
    row = thrice.row
    assert row["integrate_s_min"] <= row["integrate_s"] <= row["integrate_s_max"]
    low, median, high = (row[c] for c in ("integrate_cpu_s_min", "integrate_cpu_s",
                                          "integrate_cpu_s_max"))  # fmt: skip
    assert 0 <= low <= median <= high
    assert row["integrate_cpu_s"] >= 0 and row["workers"] == 2
    assert math.isfinite(row["load_avg"]) and row["load_avg"] >= 0
    # a single sample is its own median, min and max
    assert once.row["integrate_s_min"] == once.row["integrate_s"] == once.row["integrate_s_max"]
    assert row_defects(row, SCHEMA_COLUMNS) == []
    # the run's wall_s counts the stages with one integration (the median); its pairing
    # stage has no column, and its time grows with the load, so no upper bound is asserted
    # here (one failed at load 16: pairing 0.02 s longer than the longest sample)
    stages = ("build_s", "compile_s", "init_s", "integrate_s", "metrics_s")
    assert row["wall_s"] >= sum(row[s] for s in stages) - 1e-9


def test_a_skipped_run_has_no_timing(fake_plugins, tmp_path) -> None:
    skipped = RunSpec("test-pendulum", "minimal-ode", "test-picky", 1e-6, 1e-9, {}, {"index": 1})
    row = execute_run(skipped, reference_dir=tmp_path).row
    assert row["status"] == "skipped"
    assert all(math.isnan(row[c]) for c in ("integrate_s", "integrate_cpu_s", "repeats"))


def trajectory(n_rhs: int, y: float = 1.0, success: bool = True) -> SimpleNamespace:
    stats = SimpleNamespace(n_rhs=n_rhs, n_jac=0, n_steps=10, n_rejected=0, n_lu=0, n_newton=0)
    return SimpleNamespace(stats=stats, y=np.array([[0.0], [y]]), success=success)


def clock(results: list, seconds: list[float]):
    """A ``timed`` giving ``results`` and ``seconds`` in turn (wall = CPU)."""
    calls = iter(zip(results, seconds, strict=True))

    def timed(solve):
        result, wall = next(calls)
        return result, wall, wall

    return timed


def test_the_budget_and_the_count_bound_the_samples() -> None:
    same = [trajectory(100)] * 5
    # 3 samples of 0.01 s fit a budget of 0.05 s; the count stops them
    first, samples = integrate_repeated(None, Timing(3, 0.05), clock(same[:3], [0.01] * 3))
    assert len(samples.wall) == 3 and first is same[0] and samples.difference == ""
    # a 0.03 s sample: a second would make 0.06 s > 0.05 s: timed once
    _, samples = integrate_repeated(None, Timing(3, 0.05), clock(same[:1], [0.03]))
    assert samples.wall == [0.03]
    # a failed integration is not repeated
    failed = [trajectory(100, success=False)]
    _, samples = integrate_repeated(None, Timing(3, 60.0), clock(failed, [0.001]))
    assert len(samples.wall) == 1
    columns = Samples([0.3, 0.1, 0.2], [0.25, 0.1, 0.3]).columns()
    assert columns == {
        "integrate_s": 0.2,
        "integrate_s_min": 0.1,
        "integrate_s_max": 0.3,
        "integrate_cpu_s": 0.25,
        "repeats": 3,
        "integrate_cpu_s_min": 0.1,
        "integrate_cpu_s_max": 0.3,
    }


def busy_clock(results: list, wall: float, cpu: float):
    """A ``timed`` of a busy machine: each sample waits for a core (wall >> CPU)."""
    calls = iter(results)
    return lambda solve: (next(calls), wall, cpu)


def test_the_budget_counts_cpu_time_so_a_busy_machine_keeps_its_samples() -> None:
    same = [trajectory(100)] * 3
    # a 0.01 s CPU integration that waited 0.2 s for a core: still 3 samples (it got one
    # when the budget counted wall time: 0.2 + 0.2 > 0.05)
    _, samples = integrate_repeated(None, Timing(3, 0.05), busy_clock(same, 0.2, 0.01))
    assert len(samples.wall) == 3
    # the default policy: every integration under 1 s of CPU gets at least 3 samples
    for cpu in (0.001, 0.3, 0.9):
        _, samples = integrate_repeated(None, Timing(), busy_clock(same, 5 * cpu, cpu))
        assert len(samples.cpu) >= 3, cpu
    # a long one is timed once: repeating it would cost more than the budget
    _, samples = integrate_repeated(None, Timing(), busy_clock(same, 2.0, 2.0))
    assert len(samples.cpu) == 1
    columns = samples.columns()
    assert columns["integrate_cpu_s_min"] == columns["integrate_cpu_s_max"] == 2.0


def test_a_repeat_that_differs_is_reported() -> None:
    _, samples = integrate_repeated(
        None, Timing(3, 60.0), clock([trajectory(100), trajectory(120)], [0.01, 0.01])
    )
    assert "statistics differ" in samples.difference and "n_rhs 100 then 120" in samples.difference
    _, samples = integrate_repeated(
        None, Timing(3, 60.0), clock([trajectory(100), trajectory(100, y=2.0)], [0.01, 0.01])
    )
    assert samples.difference == "repeat 2: trajectories differ"


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("repeats = 0", "repeats"),
        ("repeats = 2.5", "repeats"),
        ("repeat_budget = -1", "repeat_budget"),
    ],
)
def test_bad_timing_options_are_config_errors(text: str, key: str) -> None:
    spec = f'{text}\nproblems = ["x"]\nformalisms = ["y"]\nintegrators = ["z"]\ntolerances = [1e-6]'
    with pytest.raises(ConfigError, match=f"{key}: must be"):
        parse_spec(spec)
    with pytest.raises(ConfigError, match="repeats must be an integer"):
        Timing(repeats=0)


def test_a_row_whose_median_is_outside_its_spread_is_not_whole() -> None:
    row = {"run_id": "a" * 16, "problem": "p", "formalism": "f", "integrator": "i",
           "rtol": 1e-6, "atol": 1e-9, "status": "ok", "message": ""}  # fmt: skip
    good = row | {"integrate_s": 0.2, "integrate_s_min": 0.1, "integrate_s_max": 0.3}
    assert row_defects(good, SCHEMA_COLUMNS) == []
    bad = good | {"integrate_s": 0.4}
    assert "not within [integrate_s_min, integrate_s_max]" in row_defects(bad, SCHEMA_COLUMNS)[0]
    assert row_defects(good | {"repeats": 0}, SCHEMA_COLUMNS)
    cpu = good | {"integrate_cpu_s": 0.2, "integrate_cpu_s_min": 0.1, "integrate_cpu_s_max": 0.3}
    assert row_defects(cpu, SCHEMA_COLUMNS) == []
    outside = row_defects(cpu | {"integrate_cpu_s_max": 0.15}, SCHEMA_COLUMNS)
    assert "integrate_cpu_s 0.2 is not within [integrate_cpu_s_min, integrate_cpu_s_max]" in (
        outside[0]
    )


def test_a_row_whose_scd_contradicts_its_own_error_is_not_whole(fake_plugins, tmp_path) -> None:
    """A row edited to a better scd was shown, trusted, beside the end error it
    contradicts: the row check now recomputes scd from err_end / length_scale (capped at
    the digits the reference has), so such a row is left out with a warning naming it."""
    from workbench.runs import store

    spec = RunSpec("test-pendulum", "minimal-ode", "test-rk45", 1e-6, 1e-9, {}, {"index": 1})
    result = execute_run(spec, reference_dir=tmp_path)
    row = result.row
    assert row["status"] == "ok" and row_defects(row, SCHEMA_COLUMNS) == []
    edited = row | {"scd": row["scd"] + 2.0}
    (defect,) = row_defects(edited, SCHEMA_COLUMNS)
    assert defect.startswith(f"scd {edited['scd']!r} does not follow from err_end / length")
    capped = row | {"err_end": 1e-30 * row["length_scale"]}  # below the reference's digits
    capped["scd"] = -math.log10(capped["reference_accuracy"])
    assert row_defects(capped, SCHEMA_COLUMNS) == []
    older = {k: v for k, v in capped.items() if k != "reference_accuracy"}  # cap not kept
    assert row_defects(older, SCHEMA_COLUMNS) == []  # fewer digits than its error: a cap
    assert row_defects(older | {"scd": 40.0}, SCHEMA_COLUMNS)  # more: never
    out = tmp_path / "out"
    store.write_run(out, edited, result.stored_series)
    with pytest.warns(UserWarning, match="does not follow from err_end"):
        assert len(store.load_results(out)) == 0
    # a row copied under another file name was counted twice
    store.write_run(out, row, result.stored_series)
    copy = store.row_path(out, row["run_id"]).with_name("f" * 16 + ".json")
    copy.write_bytes(store.row_path(out, row["run_id"]).read_bytes())
    with pytest.warns(UserWarning, match="is not the file's name"):
        assert list(store.load_results(out)["run_id"]) == [row["run_id"]]


# ---- the report's cost measure ----------------------------------------------------------


def disagreeing_runs(load: float = 0.5, workers: int = 1, cpus: int = 2) -> pd.DataFrame:
    """Two pairs reaching scd 5 on one problem: a / x cheaper in integration CPU time,
    b / y in integration wall time (a waited for a core), c / z in rhs evaluations."""
    base = {"problem": "p", "rtol": 1e-6, "status": "ok", "scd": 5.0, "warnings": "",
            "load_avg": load, "workers": workers, "cpu_count": cpus}  # fmt: skip
    return pd.DataFrame(
        [
            base
            | {
                "run_id": "a",
                "formalism": "a",
                "integrator": "x",
                "integrate_cpu_s": 0.1,
                "integrate_s": 0.3,
                "n_rhs": 500,
                "wall_s": 0.35,
            },  # fmt: skip
            base
            | {
                "run_id": "b",
                "formalism": "b",
                "integrator": "y",
                "integrate_cpu_s": 0.2,
                "integrate_s": 0.15,
                "n_rhs": 400,
                "wall_s": 0.2,
            },  # fmt: skip
            base
            | {
                "run_id": "c",
                "formalism": "c",
                "integrator": "z",
                "integrate_cpu_s": 0.4,
                "integrate_s": 0.45,
                "n_rhs": 100,
                "wall_s": 0.5,
            },  # fmt: skip
        ]
    )


def test_the_cost_switch_changes_the_cheapest_pair() -> None:
    runs = prepare_results(disagreeing_runs())
    winners = {}
    for key in ("integrate_cpu", "integrate_wall", "n_rhs"):
        cost = resolve_cost(runs, key)
        table = cheapest_pairs(runs, targets=(4.0,), cost=cost.column)
        winners[key] = table["pair"].item()
        assert cost.column in table.columns
    assert winners == {"integrate_cpu": "a / x", "integrate_wall": "b / y", "n_rhs": "c / z"}
    assert resolve_cost(runs).key == "integrate_cpu"  # the default
    # rows without the CPU time (before schema 7): the default says what it fell back to
    old = resolve_cost(runs.assign(integrate_cpu_s=np.nan))
    assert old.key == "integrate_wall" and "schema 7" in old.statement()
    with pytest.raises(ConfigError, match="unknown cost measure 'wall'"):
        resolve_cost(runs, "wall")


def test_the_report_states_its_cost_measure(tmp_path) -> None:
    pages = {}
    for key in ("integrate_cpu", "integrate_wall"):
        index = write_report(disagreeing_runs(), None, tmp_path / key, "cmd", progress=False,
                             jobs=1, cost=key)  # fmt: skip
        pages[key] = index.read_text()
        summary = pd.read_csv(tmp_path / key / "tables" / "summary.csv")
        assert summary.loc[summary["target scd"] == 4.0, "pair"].item() == (
            "a / x" if key == "integrate_cpu" else "b / y"
        )
    assert "cost measure: integration CPU time" in pages["integrate_cpu"]
    assert "cost measure: integration wall time" in pages["integrate_wall"]
    assert "least integration CPU time" in pages["integrate_cpu"]


# ---- the idle-core warning ----------------------------------------------------------------


def test_the_idle_core_warning(tmp_path) -> None:
    # 2 CPUs: 2 workers at load 3.5 (1.5 of it others'): 0.5 idle core -> warned;
    # 2 workers at load 2.0 (their own): 2 idle cores -> not; 1 worker at load 1.5 -> not
    assert oversubscribed(3.5, 2, 2) and not oversubscribed(2.0, 2, 2)
    assert not oversubscribed(1.5, 1, 2) and oversubscribed(0.0, 3, 2)
    assert not oversubscribed(float("nan"), 2, 2)  # not recorded: nothing seen
    crowded = prepare_results(disagreeing_runs(load=3.5, workers=2))
    quiet = prepare_results(disagreeing_runs(load=2.0, workers=2))
    assert "3 of 3 runs were timed with more workers than idle cores" in (
        oversubscription_warning(crowded)
    )
    assert oversubscription_warning(quiet) == ""
    old = prepare_results(disagreeing_runs().drop(columns=["load_avg", "workers"]))
    assert oversubscription_warning(old) == ""
    page = write_report(disagreeing_runs(load=3.5, workers=2), None, tmp_path / "a", "cmd",
                        progress=False, jobs=1).read_text()  # fmt: skip
    assert 'id="timing-warning"' in page and "more workers than idle cores" in page
    page = write_report(disagreeing_runs(load=2.0, workers=2), None, tmp_path / "b", "cmd",
                        progress=False, jobs=1).read_text()  # fmt: skip
    assert 'id="timing-warning"' not in page


def test_report_cli_refuses_an_unknown_cost(tmp_path) -> None:
    result = CliRunner().invoke(app, ["report", str(tmp_path), "--cost", "seconds"])
    assert result.exit_code == 2
    assert "unknown cost measure 'seconds'" in result.output
