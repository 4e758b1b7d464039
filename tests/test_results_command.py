"""`workbench results`: a summary by default, rows on request, filtered, sorted, with
options as columns, and as CSV, Markdown or LaTeX."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tests.test_report import synthetic_results
from workbench.cli import app
from workbench.errors import ConfigError
from workbench.outputs.results_table import results_table, with_option_columns

runner = CliRunner()


@pytest.fixture
def results(tmp_path: Path) -> Path:
    frame = synthetic_results()
    frame["schema_version"] = 4
    frame["warnings"] = ""
    frame.loc[0, "warnings"] = "singular passage: lost rank"
    frame.loc[frame["integrator"] == "generalized-alpha", "integrator_options"] = json.dumps(
        {"rho_inf": 0.9, "step": None}
    )
    path = tmp_path / "results.parquet"
    frame.to_parquet(path)
    return path


def test_default_is_one_line_a_problem_whose_counts_add_up(results: Path) -> None:
    frame = pd.read_parquet(results)
    table = results_table(frame)
    assert list(table["problem"]) == ["simple-pendulum", "heavy-top"]
    counts = table[["ok", "ok with warnings", "failed", "timeout", "skipped"]].sum(axis=1)
    assert list(counts) == list(table["runs"]) == [12, 12]
    assert table.loc[0, "ok with warnings"] == 1
    # the best scd is that of a trusted run, and the pair named is the cheapest reaching it
    trusted = frame[(frame["status"] == "ok") & (frame["warnings"] == "")]
    best = trusted[trusted["problem"] == "heavy-top"]["scd"].max()
    assert table.loc[1, "scd"] == best


def test_rows_filter_sort_and_option_columns(results: Path) -> None:
    frame = pd.read_parquet(results)
    table = results_table(frame, by="run", where=["problem=heavy-top", "scd>=6"], sort=["-scd"])
    assert (table["problem"] == "heavy-top").all() and (table["scd"] >= 6).all()
    assert list(table["scd"]) == sorted(table["scd"], reverse=True)
    assert "options" in table.columns and "integrator_options" not in table.columns
    named = results_table(frame, by="run", columns=["integrator", "integrator.rho_inf"])
    assert set(named["integrator.rho_inf"].astype(str)) == {"0.9", ""}
    spread = with_option_columns(frame)
    assert set(spread["integrator.order"].astype(str)) == {"5", ""}  # radau's only
    with pytest.raises(ConfigError, match="no column 'nonsense'.*the columns are"):
        results_table(frame, by="run", sort=["nonsense"])
    with pytest.raises(ConfigError, match="COLUMN OP VALUE"):
        results_table(frame, where=["scd"])
    with pytest.raises(ConfigError, match="scd holds numbers"):
        results_table(frame, where=["scd>=many"])
    with pytest.raises(ConfigError, match="needs a number"):
        results_table(frame, where=["status>=many"])
    # compared as text, `scd=` matched no row and `scd!=` every row
    for condition in ("scd=", "scd!=", "rtol=1e-10.0"):
        with pytest.raises(ConfigError, match="holds numbers; give one"):
            results_table(frame, where=[condition])
    with_nan = frame.assign(scd=[float("nan")] + list(frame["scd"][1:]))
    unmeasured = int(with_nan["scd"].isna().sum())  # a failed run's too
    assert len(results_table(with_nan, by="run", where=["scd=nan"])) == unmeasured >= 1


def test_an_option_the_same_in_every_row_shown_is_said_once(results: Path) -> None:
    """A column of one value told nothing and pushed the table past a page: it goes into
    the caption; an option that differs between the rows shown stays a column."""
    frame = pd.read_parquet(results)
    frame["formalism_options"] = json.dumps({"compile": "jit", "index": 1})
    shown = results_table(frame, by="run", where=["integrator=generalized-alpha"])
    assert "formalism.compile" not in shown.columns and "integrator.rho_inf" not in shown
    # said once, but only where not the plugins' defaults (rho_inf 0.9 and step null are)
    assert shown.attrs["same"] == "formalism.compile=jit, formalism.index=1"
    every = results_table(frame, by="run")  # rho_inf: 0.9 for one integrator, "" for others
    assert "integrator.rho_inf" not in every.columns and "formalism.index" not in every.columns
    assert "options" in every.columns  # radau: not registered, its options all shown
    named = results_table(frame, by="run", columns=["problem", "formalism.index"])
    assert list(named.columns) == ["problem", "formalism.index"] and "same" not in named.attrs
    frame.to_parquet(results)
    outcome = runner.invoke(app, ["results", str(results), "--by", "run"])
    assert outcome.exit_code == 0, outcome.output
    # the caption wraps where the folder's path ends (under pytest-xdist: a longer path)
    caption = " ".join(outcome.output.split())
    assert "in each of them formalism.compile=jit, formalism.index=1" in caption


def test_a_runs_options_are_one_column_of_those_not_its_plugins_defaults(
    results: Path,
) -> None:
    """A column an option made `--by run` a page wide (160 characters for the quick
    suite, most of them plugins' defaults): one column says what each run changed."""
    frame = pd.read_parquet(results)
    alpha = frame.index[frame["integrator"] == "generalized-alpha"]
    frame.loc[alpha[0], "integrator_options"] = json.dumps({"rho_inf": 0.5, "step": 0.001})
    frame.loc[alpha[1], "formalism_options"] = json.dumps({"index": 1})
    table = results_table(frame, by="run").set_index(frame.index)
    assert table.loc[alpha[0], "options"] == "rho_inf=0.5, step=0.001"
    assert table.loc[alpha[2], "options"] == ""  # rho_inf=0.9, step=None: the defaults
    assert table.loc[alpha[1], "options"] == "index=1"  # the formalisms' default is 3
    # radau is no registered integrator here: all its options are shown
    radau = frame.index[frame["integrator"] == "radau"][0]
    assert table.loc[radau, "options"] == "order=5"
    frame.to_parquet(results)
    outcome = runner.invoke(app, ["results", str(results), "--by", "run"])
    assert outcome.exit_code == 0 and "rho_inf=0.5," in outcome.output
    assert "index=1" in outcome.output and "rho_inf=0.9" not in outcome.output


def test_formats_from_the_command_line(results: Path) -> None:
    outcome = runner.invoke(app, ["results", str(results), "--format", "csv", "--by", "pair"])
    assert outcome.exit_code == 0, outcome.output
    csv = pd.read_csv(io.StringIO(outcome.output))
    assert len(csv) == 2 * 4 and "pair" in csv.columns  # problems x pairs
    latex = runner.invoke(app, ["results", str(results), "-f", "latex", "-c", "problem,scd,wall_s"])
    assert latex.exit_code == 0, latex.output
    assert "\\toprule" in latex.output and "\\caption{" in latex.output
    assert "wall time [s]" in latex.output
    markdown = runner.invoke(
        app, ["results", str(results), "-f", "markdown", "-w", "status=failed", "--by", "run"]
    )
    assert markdown.exit_code == 0 and markdown.output.startswith("| problem |")
    assert markdown.output.count("\n") == 2 + 1  # header, rule, the one failed run
    bad = runner.invoke(app, ["results", str(results), "-f", "xml"])
    assert bad.exit_code == 2 and "choose one of table, csv, markdown, latex" in bad.output
    table = runner.invoke(app, ["results", str(results)])
    assert table.exit_code == 0 and "The 24 runs in" in table.output


def test_a_latex_table_split_to_fit_the_page_says_which_run_each_line_is(
    results: Path,
) -> None:
    """The run table is wider than a page: each of its parts repeats the problem, the
    pair and the tolerance (a part with the problem alone listed a problem four times
    with nothing telling its lines apart)."""
    latex = runner.invoke(app, ["results", str(results), "-f", "latex", "--by", "run"])
    assert latex.exit_code == 0, latex.output
    parts = re.split(r"\\begin\{(?:tabular|longtable)\}\{[a-z0-9.{}]*\}", latex.output)[1:]
    assert len(parts) >= 2, latex.output
    for part in parts:
        header = part.split(r"\midrule")[0]
        for key in ("problem", "formalism", "integrator", "rtol"):
            assert key in header, (key, header)


def test_caption_reads_well_and_names_the_cost_measure(results: Path) -> None:
    """Not '11 runs of 36 runs in out-arm': what a line is, of how many runs, the measure;
    a table for a paper or a page does not name the folder on this machine ('in out')."""
    latex = runner.invoke(app, ["results", str(results), "-f", "latex", "--by", "run",
                                "-w", "problem=heavy-top"])  # fmt: skip
    assert latex.exit_code == 0, latex.output
    assert "\\caption{12 of the 24 runs}" in latex.output
    assert str(results.parent.name) not in latex.output
    terminal = runner.invoke(app, ["results", str(results), "--by", "run"])
    assert "The 24 runs in " in " ".join(terminal.output.split())  # the terminal's says
    summary = runner.invoke(app, ["results", str(results), "-f", "latex"])
    assert "a line a problem" in summary.output and "cost measure: wall time" in summary.output
    assert "runs of" not in summary.output


def test_results_names_the_reports_winner_and_its_tie(results: Path) -> None:
    """`workbench results` ranks with the report's function: same pair, ties called."""
    from workbench.outputs.report.analysis import prepare_results
    from workbench.outputs.report.decision import FALLBACK_TARGETS
    from workbench.outputs.report.ranking import decide

    frame = pd.read_parquet(results)
    frame["repeats"] = 3
    frame["wall_s_min"], frame["wall_s_max"] = frame["wall_s"] * 0.5, frame["wall_s"] * 3
    table = results_table(frame)
    runs = prepare_results(frame)
    for row in table.itertuples():
        group = runs[runs["problem"] == row.problem]
        target = max((t for t in FALLBACK_TARGETS if row.scd >= t), default=row.scd)
        decision = decide(group, target, "wall_s")
        assert row.pair == decision.pair
        expected = decision.verdict() + (f" of {decision.runner_up}" if decision.runner_up else "")
        if decision.is_tie:
            expected = "tie: " + "; ".join(decision.tied)
        assert row.verdict == f"at scd {target:.3g}, {expected}"


def test_the_summary_ranks_by_the_reports_cost_and_names_it() -> None:
    """`workbench results` names the pair the report names: the cheapest by the median
    integration CPU time (a / x), not by wall time (b / y waited less for a core)."""
    from tests.test_timing import disagreeing_runs

    table = results_table(disagreeing_runs())
    assert table.loc[0, "pair"] == "a / x" and table.loc[0, "integrate_cpu_s"] == 0.1
    assert "wall_s" not in table.columns
    assert table.attrs["cost"] == "cheapest by integration CPU time (median of the timed samples)"
    # rows without the CPU time (before schema 7) fall back as the report does, and say so
    old = results_table(disagreeing_runs().drop(columns=["integrate_cpu_s"]))
    assert old.loc[0, "pair"] == "b / y" and "written before schema 7" in old.attrs["cost"]


def test_a_problems_line_ranks_the_pairs_reaching_its_highest_target_not_the_last_digit() -> None:
    """The line names the cheapest pair reaching the highest target of scd 2, 4, 6, 8, 10
    that a trusted run reached: b / y (scd 6.1, 0.1 s), not a / x, which reached the last
    digit (6.3) at twice the cost and so was 'only pair' against nobody."""
    from tests.test_timing import disagreeing_runs

    runs = disagreeing_runs()
    runs.loc[runs["run_id"] == "a", ["scd", "integrate_cpu_s"]] = [6.3, 0.2]
    runs.loc[runs["run_id"] == "b", ["scd", "integrate_cpu_s"]] = [6.1, 0.1]
    runs.loc[runs["run_id"] == "c", ["scd"]] = [3.0]
    (row,) = results_table(runs).itertuples()
    assert (row.scd, row.pair, row.integrate_cpu_s) == (6.3, "b / y", 0.1)
    # the line says the target it names the pair at: b / y did not reach the 6.3 shown
    assert row.verdict.startswith("at scd 6, 2.00x ahead of a / x")  # its caveat after it
    runs["scd"] = [1.5, 1.2, 0.5]  # below every target: ranked at the best scd reached
    (row,) = results_table(runs).itertuples()
    assert row.pair == "a / x" and row.verdict == "at scd 1.5, only pair"


def test_a_count_the_integrator_does_not_report_is_shown_empty_not_minus_one() -> None:
    """-1 (not reported, as stored) is no count: the table shows it empty, as anything not
    measured; a reported count stays as it is."""
    from tests.test_timing import disagreeing_runs

    runs = disagreeing_runs().assign(n_lu=[-1, 7, 0], n_rejected=[-1, -1, 2])
    table = results_table(runs, by="run", columns=["run_id", "n_lu", "n_rejected", "n_rhs"])
    shown = table.set_index("run_id")
    assert np.isnan(shown.loc["a", "n_lu"]) and shown.loc["b", "n_lu"] == 7
    assert shown.loc["c", "n_lu"] == 0 and shown.loc["c", "n_rejected"] == 2
    assert shown["n_rejected"].isna().sum() == 2 and (shown["n_rhs"] > 0).all()


def test_a_line_a_pair_names_its_target_and_where_takes_double_equals() -> None:
    """--by pair has no verdict: its target column says at which scd the run shown (its
    rtol and cost) was chosen, which is not the best scd the pair reached (a / x: best
    6.3, target 6). ``==`` reads as ``=`` (as Python spells it), not as a value '=...'."""
    from tests.test_timing import disagreeing_runs

    runs = disagreeing_runs()
    runs.loc[runs["run_id"] == "a", ["scd", "integrate_cpu_s"]] = [6.3, 0.2]
    table = results_table(runs, by="pair").set_index("pair")
    assert table.loc["a / x", "scd"] == 6.3 and table.loc["a / x", "target"] == 6
    # a tighter, costlier run of a / x reaches 7.8, the line's best scd; the run shown is
    # the cheapest at the target 6, rtol 1e-6: its own scd (6.3) says it did not reach 7.8
    tighter = runs[runs["run_id"] == "a"].assign(run_id="a2", rtol=1e-9, scd=7.8,
                                                 integrate_cpu_s=0.9)  # fmt: skip
    line = results_table(pd.concat([runs, tighter]), by="pair").set_index("pair").loc["a / x"]
    assert (line["scd"], line["target"], line["run scd"], line["rtol"]) == (7.8, 6, 6.3, 1e-6)
    assert table.loc["b / y", "run scd"] == 5.0 and table.loc["b / y", "target"] == 4
    assert "target" not in results_table(runs).columns  # a line a problem: in its verdict
    assert len(results_table(runs, by="run", where=["pair==a / x"])) == 1
    assert results_table(runs, by="run", where=["pair==a / x"]).equals(
        results_table(runs, by="run", where=["pair=a / x"])
    )


@pytest.mark.parametrize("fmt", ["latex", "markdown"])
def test_a_filter_that_keeps_nothing_writes_no_broken_table(results: Path, fmt: str) -> None:
    """An empty LaTeX tabular (``\\begin{tabular}{}``) stops pdflatex and an empty Markdown
    table is ``|  |``: no table is written, and stderr says why."""
    result = runner.invoke(app, ["results", str(results), "-w", "scd>=99", "-f", fmt])
    assert result.exit_code == 0, result.output
    assert "tabular" not in result.stdout and "|" not in result.stdout
    assert "no line to write" in result.output and "meets --where scd>=99" in result.output


def test_results_rank_in_the_measure_the_folders_report_was_made_in(results: Path) -> None:
    """After `workbench report OUT --cost work` the report named one pair ahead and
    `workbench results OUT` another (it ranked by CPU time whatever the report said)."""
    folder = results.parent
    (folder / "report").mkdir()
    (folder / "report" / "settings.json").write_text(json.dumps({"cost": "n_rhs"}))
    kept = runner.invoke(app, ["results", str(folder), "--format", "csv"])
    assert kept.exit_code == 0, kept.output
    assert "cost measure: n_rhs, as the folder's report (--cost to choose)" in kept.stderr
    header = kept.stdout.splitlines()[0].split(",")
    assert "n_rhs" in header and "integrate_cpu_s" not in header  # the cost column
    chosen = runner.invoke(app, ["results", str(folder), "--cost", "integrate_cpu"])
    assert chosen.exit_code == 0 and "as the folder's report" not in chosen.stderr
    assert "integration CPU time" in chosen.stdout
    plain = results_table(pd.read_parquet(results), cost="n_rhs")
    assert plain.attrs["cost"].startswith("cheapest by")


def test_results_of_part_of_the_planned_sweep_say_so_as_the_report_does(results: Path) -> None:
    """With rows of the plan deleted, the report said 'Not the whole sweep' and `workbench
    results` gave its verdicts without a word (qa3c F6)."""
    from workbench.runs import store

    folder = results.parent
    ids = list(pd.read_parquet(results)["run_id"])
    store.write_plan(folder, [*ids, "0000000000000001", "0000000000000002"], "sweep.toml")
    for fmt in ("table", "csv"):
        partial = runner.invoke(app, ["results", str(folder), "--format", fmt])
        assert partial.exit_code == 0, partial.output
        assert partial.stderr.startswith("Not the whole sweep: partial results: the sweep "
                                         "(sweep.toml) planned 26 runs and 24")  # fmt: skip
        assert "2 missing" in partial.stderr and "Not the whole" not in partial.stdout
    assert len(pd.read_csv(io.StringIO(partial.stdout))) == 2  # the CSV stays a CSV
    store.write_plan(folder, ids, "sweep.toml")  # the whole plan: nothing to say
    whole = runner.invoke(app, ["results", str(folder)])
    assert whole.exit_code == 0 and "Not the whole sweep" not in whole.output


def test_results_name_the_rows_outside_the_plan_as_the_report_does(results: Path) -> None:
    """Rows of other sweeps in the folder (not in plan.json) were counted in the verdicts
    with a count at most (qa3c F4): the notice names them and says they count, under a
    heading that says so ("Not the whole sweep" had headed it too)."""
    from workbench.runs import store

    folder = results.parent
    frame = pd.read_parquet(results)
    store.write_plan(folder, list(frame["run_id"].iloc[2:]), "sweep.toml")
    first = frame.iloc[0]  # named in the order of their run_ids ('-0.001' before '-1e-05')
    for fmt in ("table", "csv"):
        extra = runner.invoke(app, ["results", str(folder), "--format", fmt])
        assert extra.exit_code == 0, extra.output
        assert extra.stderr.startswith(
            "Not this sweep alone: 2 row(s) come from other sweeps run in this directory, "
            f"not from this sweep's plan (run {first['run_id']}: {first['problem']}, "
            f"{first['formalism']} / {first['integrator']}, rtol {first['rtol']:g}; run "
            f"{frame['run_id'].iloc[1]}: "
        )
        assert "and count in the verdicts like its own." in extra.stderr
        assert "other sweeps" not in extra.stdout
    assert len(pd.read_csv(io.StringIO(extra.stdout))) == 2  # the CSV stays a CSV


def test_the_terminal_table_says_what_scd_its_scd_and_rtol_are(results: Path) -> None:
    """The headers 'scd [digits]', 'its scd' and 'rtol' were not explained anywhere in
    `workbench results` (qa3c F13): a line under the terminal's table says what each is;
    a CSV or LaTeX table stays as it was."""
    summary = " ".join(runner.invoke(app, ["results", str(results)]).stdout.split())
    assert "scd: correct significant digits at the end, -log10(end error / length scale L)" \
        in summary  # fmt: skip
    assert "its scd: that of the run shown, the cheapest reaching the target" in summary
    assert "rtol: the relative tolerance its integrator was given" in summary
    runs = " ".join(runner.invoke(app, ["results", str(results), "--by", "run"]).stdout.split())
    assert "scd: correct significant digits" in runs and "its scd:" not in runs  # no column
    narrow = runner.invoke(app, ["results", str(results), "-c", "problem,runs"])
    assert "significant digits" not in narrow.output  # neither scd nor rtol shown
    for fmt in ("csv", "latex"):
        other = runner.invoke(app, ["results", str(results), "-f", fmt])
        assert "significant digits" not in other.output, fmt


def test_the_coverage_heading_says_which_way_the_rows_differ_from_the_plan(results: Path) -> None:
    """Missing planned runs, rows of other sweeps, or both: each its own heading, on the
    report's first screen and in `workbench results` alike."""
    from workbench.outputs.report.analysis import coverage_heading
    from workbench.runs import store

    folder = results.parent
    frame = pd.read_parquet(results)
    ids = list(frame["run_id"])
    both = {"run_ids": [*ids[2:], "0000000000000001"]}
    assert coverage_heading(frame, {"run_ids": ids}) == ""
    assert coverage_heading(frame, {"run_ids": [*ids, "0000000000000001"]}) == (
        "Not the whole sweep")
    assert coverage_heading(frame, {"run_ids": ids[2:]}) == "Not this sweep alone"
    assert coverage_heading(frame, both) == "Not the whole sweep, and not it alone"
    assert coverage_heading(frame, None) == ""
    store.write_plan(folder, both["run_ids"], "sweep.toml")
    mixed = runner.invoke(app, ["results", str(folder)])
    assert mixed.stderr.startswith("Not the whole sweep, and not it alone: partial results")
    assert "2 row(s) come from other sweeps" in mixed.stderr


def test_a_warned_run_is_not_shown_as_plain_ok(results: Path) -> None:
    """--by run printed 'ok' beside a warned run's scd (e.g. capped at the reference's
    accuracy): the status says 'ok with warnings', as the report's status table counts it;
    --where still selects by the stored status."""
    frame = pd.read_parquet(results)
    table = results_table(frame, by="run", columns=["run_id", "status", "scd"])
    shown = table.set_index("run_id")["status"]
    assert shown[frame.loc[0, "run_id"]] == "ok with warnings"
    assert (shown.drop(frame.loc[0, "run_id"]) != "ok with warnings").all()
    kept = results_table(frame, by="run", where=["status=ok"], columns=["run_id", "status"])
    assert frame.loc[0, "run_id"] in set(kept["run_id"])
