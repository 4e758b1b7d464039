"""HTML reports from synthetic results: files, links, tables and the cheapest-pair choice."""

from __future__ import annotations

import json
import re
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.errors import ConfigError
from workbench.outputs.report import (
    cheapest_pairs,
    latex_table,
    markdown_table,
    middle_tolerance,
    prepare_results,
    status_matrix,
    write_report,
)

SERIES_COLUMNS = ("drift_pos", "drift_vel", "drift_nh", "energy_err", "ref_err")


def synthetic_results(
    problems: tuple[str, ...] = ("simple-pendulum", "heavy-top"),
    formalisms: tuple[str, ...] = ("minimal-ode", "absolute-dae"),
    integrators: tuple[str, ...] = ("radau", "generalized-alpha"),
    rtols: tuple[float, ...] = (1e-3, 1e-5, 1e-7),
    seed: int = 0,
) -> pd.DataFrame:
    """Rows of the results-store schema: scd grows and cost rises as rtol shrinks."""
    rng = np.random.default_rng(seed)
    rows = []
    for p, problem in enumerate(problems):
        for f, formalism in enumerate(formalisms):
            for i, integrator in enumerate(integrators):
                for rtol in rtols:
                    digits = -np.log10(rtol)
                    status = "ok"
                    message = ""
                    if (p + f + i) % 7 == 3 and rtol == rtols[-1]:
                        status, message = "failed", f"Newton iteration diverged at t = {p + 0.5}"
                    elif (p + f + i) % 11 == 5 and rtol == rtols[0]:
                        status, message = "timeout", "run exceeded the time limit of 60 s"
                    scd = digits - 0.5 + 0.3 * f - 0.2 * i + 0.1 * rng.standard_normal()
                    wall = 1e-3 * (1 + f + 2 * i) * digits**2 * (1 + 0.05 * rng.random())
                    rows.append(
                        {
                            "run_id": f"{problem}-{formalism}-{integrator}-{rtol:g}",
                            "problem": problem,
                            "formalism": formalism,
                            "integrator": integrator,
                            "rtol": rtol,
                            "atol": rtol * 1e-2,
                            "status": status,
                            "message": message,
                            "wall_s": wall if status == "ok" else np.nan,
                            "cpu_s": wall,
                            "n_rhs": int(100 * (1 + i) * digits**2),
                            "n_jac": int(5 * digits),
                            "n_steps": int(20 * digits**2),
                            "n_rejected": int(digits),
                            "err_max": 10 ** (-scd + 0.5),
                            "err_end": 10**-scd,
                            "err_l2": 10 ** (-scd + 0.2),
                            "scd": scd if status == "ok" else np.nan,
                            "drift_pos_max": rtol * (1 + f),
                            "drift_vel_max": rtol * (2 + f),
                            "drift_nh_max": 0.0,
                            "energy_err_max": rtol * (3 + i),
                            "invariant_err_max": rtol,
                            "formalism_options": json.dumps({}),
                            "integrator_options": json.dumps({"order": 5}),
                        }
                    )
    return pd.DataFrame(rows)


def synthetic_series(run_id: str, n: int = 200) -> pd.DataFrame:
    """A run's time series: drifts growing like t, a nonholonomic drift of zero."""
    t = np.linspace(0.0, 10.0, n)
    scale = 1e-6 * (1 + (hash(run_id) % 5))
    return pd.DataFrame(
        {
            "run_id": run_id,
            "t": t,
            "drift_pos": scale * t,
            "drift_vel": 2 * scale * t,
            "drift_nh": 0.0,
            "energy_err": scale * np.sqrt(t),
            "ref_err": scale * t**2,
        }
    )


VOID_ELEMENTS = {"meta", "img", "br", "hr", "link", "input"}


class TagBalance(HTMLParser):
    """Checks that every non-void element is closed, in order."""

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []

    def handle_starttag(self, tag: str, attrs: list) -> None:
        if tag not in VOID_ELEMENTS:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        assert self.stack and self.stack[-1] == tag, (tag, self.stack[-3:])
        self.stack.pop()


def assert_well_formed(page: str) -> None:
    parser = TagBalance()
    parser.feed(page)
    parser.close()
    assert parser.stack == []


def image_sources(index: Path) -> list[str]:
    return re.findall(r'<img src="([^"]+)"', index.read_text(encoding="utf-8"))


def test_report_files_and_links(tmp_path: Path) -> None:
    results = synthetic_results()
    index = write_report(results, synthetic_series, tmp_path / "report", "workbench report x")
    assert index == tmp_path / "report" / "index.html"
    sources = image_sources(index)
    # the heat map, two problems x (picture, work-precision, error, drift)
    assert len(sources) == 9
    for source in sources:
        assert (index.parent / source).is_file(), source
    links = re.findall(r'href="([^"#]+)"', index.read_text(encoding="utf-8"))
    assert any(link.endswith(".svg") for link in links)
    for link in links:
        assert (index.parent / link).is_file(), link
    # PDFs are a paper's (workbench paper): a report alone neither writes nor links them
    assert not any(link.endswith(".pdf") for link in links)
    assert not list((index.parent / "figures").glob("*.pdf"))
    for name in (
        "summary",
        "status",
        "drift-simple-pendulum-rtol-1e-05",
        "drift-heavy-top-rtol-1e-05",
    ):
        for ext in ("csv", "md", "tex"):
            assert (index.parent / "tables" / f"{name}.{ext}").is_file()
        assert "\\toprule" in (index.parent / "tables" / f"{name}.tex").read_text()
    assert (index.parent / "tables" / "results.csv").is_file()
    page = index.read_text(encoding="utf-8")
    assert_well_formed(page)
    assert "workbench report x" in page
    assert "matplotlib" in page and "pandas" in page
    assert "Newton iteration diverged" in page  # a failure reason in the footnotes


def test_report_without_series_draws_no_drift(tmp_path: Path) -> None:
    index = write_report(synthetic_results(), None, tmp_path, "cmd")
    assert len(image_sources(index)) == 5  # the heat map, pictures, work-precision diagrams
    assert "no drift plot" in index.read_text(encoding="utf-8")


def test_cheapest_pair_on_a_constructed_case() -> None:
    base = {"problem": "p", "status": "ok", "rtol": 1e-6, "n_rhs": 10}
    rows = [
        # fast but inaccurate
        dict(base, formalism="a", integrator="x", scd=3.0, wall_s=0.1),
        # reaches 4 and is the cheaper of the two that do
        dict(base, formalism="b", integrator="y", scd=4.5, wall_s=0.5),
        dict(base, formalism="c", integrator="z", scd=6.5, wall_s=0.9),
        # cheaper still, but failed: never chosen
        dict(base, formalism="d", integrator="w", scd=9.0, wall_s=0.01, status="failed"),
    ]
    summary = cheapest_pairs(prepare_results(pd.DataFrame(rows)))
    chosen = dict(zip(summary["target scd"], summary["pair"], strict=True))
    assert chosen == {
        2.0: "a / x",
        4.0: "b / y",
        6.0: "c / z",
        8.0: "none reached",
        10.0: "none reached",
    }

    rows[2]["scd"] = 5.0
    summary = cheapest_pairs(prepare_results(pd.DataFrame(rows)))
    assert summary.loc[summary["target scd"] == 6.0, "pair"].item() == "none reached"


def test_status_matrix_counts_and_footnotes() -> None:
    results = synthetic_results()
    failed = results.index[results["status"] == "failed"][0]
    other = results.index[(results["status"] == "ok") & (results["problem"] == "simple-pendulum")]
    results.loc[other[0], ["status", "message"]] = [
        "failed",
        "Newton iteration diverged at t = 7.25",
    ]
    assert results.loc[failed, "message"] != results.loc[other[0], "message"]
    runs = prepare_results(results)
    matrix, footnotes = status_matrix(runs)
    assert list(matrix.index) == ["simple-pendulum", "heavy-top"]
    assert matrix.shape[1] == 4
    total = 0
    for cell in matrix.to_numpy().ravel():
        total += sum(int(n) for n in re.findall(r"(\d+) (?:ok|failed|timeout|skipped)", cell))
    assert total == len(runs)
    not_ok = runs[runs["status"] != "ok"]
    # the failures differ only in the time reached: one reason for all of them
    assert not_ok.groupby(["status", "message"]).ngroups > not_ok["status"].nunique()
    assert len(footnotes) == not_ok["status"].nunique() > 0
    failure = next(note for note in footnotes if "] failed:" in note)
    # (the times reached as their least and greatest, not '#')
    assert re.search(r"Newton iteration diverged at t = [\d.]+ to 7\.25 \(", failure)


def test_labels_include_options_only_when_they_vary() -> None:
    results = synthetic_results(problems=("p",), formalisms=("f",), integrators=("i",))
    assert set(prepare_results(results)["pair"]) == {"f / i"}
    other = results.copy()
    other["integrator_options"] = json.dumps({"order": 3})
    pairs = set(prepare_results(pd.concat([results, other]))["pair"])
    assert pairs == {"f / i[order=5]", "f / i[order=3]"}


def test_table_writers() -> None:
    table = pd.DataFrame({"name": ["a_b", "c|d"], "value": [1.5, float("nan")]})
    latex = latex_table(table)
    assert "\\toprule" in latex and "\\bottomrule" in latex and "a\\_b" in latex
    assert "{lr}" in latex
    markdown = markdown_table(table)
    assert markdown.splitlines()[0] == "| name | value |"
    assert "c\\|d" in markdown


def test_latex_table_is_booktabs_with_escaped_cells_and_headers() -> None:
    table = pd.DataFrame({"wall_s": [0.0123456, float("nan")], "pair": ["a & b", "50% ~x"]})
    lines = latex_table(table).splitlines()
    assert lines == [
        "\\begin{tabular}{rl}",
        "\\toprule",
        "wall time [s] & formalism / integrator \\\\",
        "\\midrule",
        "0.01235 & a \\& b \\\\",
        " & 50\\% \\textasciitilde{}x \\\\",
        "\\bottomrule",
        "\\end{tabular}",
    ]
    matrix = pd.DataFrame({"x / y": ["1 ok"]}, index=pd.Index(["p_1"], name="problem"))
    assert "problem & x / y \\\\" in latex_table(matrix, index=True)
    assert "p\\_1 & 1 ok \\\\" in latex_table(matrix, index=True)


def test_page_escapes_what_the_runs_say(tmp_path: Path) -> None:
    results = synthetic_results(problems=("<b>top</b>",), formalisms=("f",), integrators=("i",))
    results.loc[0, ["status", "message"]] = ["failed", "<script>alert(x)</script> & more"]
    index = write_report(results, None, tmp_path, "run <x> & 'y'")
    page = index.read_text(encoding="utf-8")
    assert_well_formed(page)
    assert "<b>top</b>" not in page and "&lt;b&gt;top&lt;/b&gt;" in page
    assert "<script>" not in page and "&lt;script&gt;alert(x)&lt;/script&gt; &amp; more" in page
    assert "run &lt;x&gt; &amp; &#39;y&#39;" in page


def test_middle_tolerance() -> None:
    assert middle_tolerance([1e-3, 1e-5, 1e-7, 1e-5]) == 1e-5
    assert middle_tolerance([float("nan")]) is None


def test_missing_columns_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="status"):
        write_report(pd.DataFrame({"problem": ["p"]}), None, tmp_path, "cmd")


@pytest.mark.slow
def test_two_thousand_runs_report_is_complete_and_small(tmp_path: Path) -> None:
    # speed is measured in benchmarks/default_sweep.py; the limit here is one only a hung
    # report reaches (it took 105 s at load 15, 20 s on a quiet machine). 4 problems of
    # 100 pairs: 55 s of CPU on the Zen 3, against 79 s for 10 problems of 40 pairs
    results = synthetic_results(
        problems=tuple(f"problem-{k}" for k in range(4)),
        formalisms=("minimal-ode", "absolute-dae", "recursive", "lagrange"),
        integrators=tuple(f"integrator-{k}" for k in range(25)),
        rtols=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10),
    )
    assert len(results) == 2000
    start = time.perf_counter()
    index = write_report(results, synthetic_series, tmp_path, "cmd", progress=False)
    elapsed = time.perf_counter() - start
    assert elapsed < 900, elapsed
    assert index.stat().st_size < 20e6
    for source in image_sources(index):
        assert (index.parent / source).is_file()


# -- the command line ---------------------------------------------------------------------
def write_results_directory(directory: Path) -> pd.DataFrame:
    """A results directory as `workbench sweep` writes it: runs/*.json and series/*.parquet."""
    from workbench.runs.store import write_run

    results = synthetic_results(problems=("simple-pendulum",))
    for row in results.to_dict("records"):
        write_run(directory, row, synthetic_series(row["run_id"]))
    return results


def test_cli_report(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from workbench.cli import app

    write_results_directory(tmp_path / "sweep")
    outcome = CliRunner().invoke(app, ["report", str(tmp_path / "sweep")])
    assert outcome.exit_code == 0, outcome.output
    index = tmp_path / "sweep" / "report" / "index.html"
    assert str(index) in outcome.output
    assert len(image_sources(index)) == 3  # picture; work-precision and drift from the series
    assert f"workbench report {tmp_path / 'sweep'} --out" in index.read_text(encoding="utf-8")

    outcome = CliRunner().invoke(
        app, ["report", str(tmp_path / "sweep"), "--out", str(tmp_path / "r")]
    )
    assert outcome.exit_code == 0, outcome.output
    assert (tmp_path / "r" / "index.html").is_file()


@pytest.mark.parametrize("make", ["missing", "empty"])
def test_cli_report_without_results_is_one_line_error(tmp_path: Path, make: str) -> None:
    from typer.testing import CliRunner

    from workbench.cli import app

    path = tmp_path / "nothing"
    if make == "empty":
        path.mkdir()
    outcome = CliRunner().invoke(app, ["report", str(path)])
    assert outcome.exit_code == 2
    assert "error:" in outcome.output and "results" in outcome.output
    assert "Traceback" not in outcome.output


def test_problem_without_successful_runs_and_broken_series(tmp_path: Path) -> None:
    results = synthetic_results(problems=("p", "q"))
    results.loc[results["problem"] == "q", "status"] = "failed"
    results.loc[results["problem"] == "q", "message"] = "build: formalism raised"

    def loader(run_id: str) -> pd.DataFrame:
        if run_id.endswith("radau-1e-05"):
            raise ConfigError(f"no time series for run {run_id!r}")
        return synthetic_series(run_id)

    with pytest.warns(UserWarning, match="no time series"):
        index = write_report(results, loader, tmp_path, "cmd")
    page = index.read_text(encoding="utf-8")
    assert len(image_sources(index)) == 4  # the heat map; only problem p has figures
    assert "No successful run" in page
    summary = pd.read_csv(tmp_path / "tables" / "summary.csv")
    assert set(summary.loc[summary["problem"] == "q", "pair"]) == {"none reached"}


def test_a_run_with_warnings_is_marked_and_never_recommended() -> None:
    """The cheapest run of a pair reaching scd 2 is the warned one (a singular passage):
    the summary must pick the next trustworthy run, and the status matrix must count it
    as 'ok with warnings' with a footnote naming the warning."""
    from workbench.outputs.report import cheapest_pairs, prepare_results, status_matrix

    results = synthetic_results(problems=("simple-pendulum",), rtols=(1e-3, 1e-5))
    results["warnings"] = ""
    fast = results[results["status"] == "ok"]["wall_s"].idxmin()
    passage = "singular passage: the constraint Jacobian lost rank near t = 1 s (1e-9)"
    results.loc[fast, "warnings"] = passage
    assert results.loc[fast, "scd"] >= 2.0  # it would have won
    runs = prepare_results(results)
    best = cheapest_pairs(runs, targets=(2.0,)).iloc[0]
    assert best["wall_s"] > results.loc[fast, "wall_s"]  # the warned, cheaper run lost
    cells, footnotes = status_matrix(runs)
    assert any("ok with warnings" in cell for cell in cells.to_numpy().ravel())
    assert any(note.startswith("[") and "ok with warnings: singular passage" in note
               for note in footnotes)  # fmt: skip
    # warnings differing only in their numbers are one reason
    other = results["status"].eq("ok") & results["warnings"].eq("")
    results.loc[other[other].index[:2], "warnings"] = [
        "end error 3.2e-12 is below the reference's own accuracy 8.9e-12",
        "end error 8.1e-12 is below the reference's own accuracy 8.9e-12",
    ]
    _cells, footnotes = status_matrix(prepare_results(results))
    below = [note for note in footnotes if "below the reference" in note]
    assert len(below) == 1 and "(2 run(s)" in below[0]


def test_a_report_of_skipped_runs_only_raises_no_pandas_warning(tmp_path: Path) -> None:
    """A store read back from Parquet gives all-empty text columns (warnings, form,
    message, options) the float dtype; filling them with "" is deprecated in pandas and
    printed a warning line per use in every `workbench report` of such a store."""
    results = synthetic_results(problems=("p",))
    results["status"] = "skipped"
    for column in ("warnings", "form", "message", "formalism_options", "integrator_options"):
        results[column] = np.nan
    results[["scd", "wall_s"]] = np.nan
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        index = write_report(results, lambda run_id: None, tmp_path, "cmd")
    assert "No successful run" in index.read_text(encoding="utf-8")


def test_a_status_reason_prints_the_numbers_its_runs_measured() -> None:
    """The quick suite's paper read 'time limit of # s exceeded; ... after # s, at t = # s
    of # s': a reason shared by runs differing in their numbers printed none. It prints
    the one value they share, or their least and greatest."""
    results = synthetic_results(problems=("p",), rtols=(1e-3, 1e-5))
    ok = results.index[results["status"] == "ok"]
    results.loc[ok[:2], "status"] = "timeout"
    results.loc[ok[:2], "message"] = [
        "time limit of 10 s exceeded; killed after 9.9 s, at t = 6.83767 s of 10 s",
        "time limit of 10 s exceeded; killed after 9.77 s, at t = 5.63206 s of 10 s",
    ]
    _cells, footnotes = status_matrix(prepare_results(results))
    (note,) = [note for note in footnotes if "time limit" in note]
    assert "time limit of 10 s exceeded; killed after 9.77 to 9.9 s, at t = 5.63206 to " \
           "6.83767 s of 10 s (2 run(s)" in note  # fmt: skip
    assert "#" not in note
