"""What the report leaves out, it says (an outside tester's findings): a pair whose runs
were all skipped is drawn and named 'skipped', not 'not reached', in the heat map and the
cost-at-target table; the ranking lists every pair where there is room and says how many
the LaTeX leaves out; a LaTeX table split into parts repeats the columns that say what
a row is (the cheapest-pair table's target, the Pareto table's pair and rtol); a count
column prints 0."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.test_report import synthetic_results, synthetic_series
from workbench.outputs.report import prepare_results, write_report
from workbench.outputs.report.overview import (
    NOT_REACHED,
    SKIPPED,
    cost_at_target,
    cost_ratio,
    unreached_reasons,
)
from workbench.outputs.report.overview_figures import heat_map_drawing
from workbench.outputs.report.writer import RANKED_SHOWN, overview_of


@pytest.fixture(autouse=True)
def agg() -> None:
    import matplotlib

    matplotlib.use("Agg", force=True)


def with_skipped_pair() -> pd.DataFrame:
    """Two problems, three pairs: on 'p2' the pair 'b / y' runs and stays at scd 2, and
    every run of 'c / z' is skipped (it does not support the problem)."""
    rows = []
    for problem in ("p1", "p2"):
        for pair, scd, wall in (("a / x", 7.0, 1.0), ("b / y", 7.0, 2.0), ("c / z", 7.5, 1.5)):
            status, message = "ok", ""
            if problem == "p2" and pair == "b / y":
                scd = 2.0
            if problem == "p2" and pair == "c / z":
                status, message = "skipped", "the formalism does not support the constraints"
            for k, rtol in enumerate((1e-4, 1e-6)):
                rows.append({
                    "run_id": f"{problem}-{pair}-{k}", "problem": problem,
                    "formalism": pair.split(" / ")[0], "integrator": pair.split(" / ")[1],
                    "rtol": rtol, "status": status, "message": message,
                    "scd": scd if status == "ok" else np.nan,
                    "wall_s": wall * (1 + k) if status == "ok" else np.nan, "n_rhs": 100.0,
                })  # fmt: skip
    return prepare_results(pd.DataFrame(rows))


def test_a_skipped_pair_is_drawn_and_named_apart_from_one_that_fell_short() -> None:
    runs = with_skipped_pair()
    ratio = cost_ratio(cost_at_target(runs, 6.0, "wall_s"))
    reasons = unreached_reasons(runs, ratio)
    assert reasons.loc["p2", "b / y"] == NOT_REACHED and reasons.loc["p2", "c / z"] == SKIPPED
    figure, caption = heat_map_drawing(ratio, 6.0, "wall_s", reasons=reasons)
    (ax,) = [ax for ax in figure.axes if ax.get_xlabel().startswith("pair")]
    cells = {(round(t.get_position()[1]), round(t.get_position()[0])): t for t in ax.texts}
    rows, columns = list(ratio.index), list(ratio.columns)
    short = cells[rows.index("p2"), columns.index("b / y")]
    skipped = cells[rows.index("p2"), columns.index("c / z")]
    assert short.get_text() == "not\nreached"
    assert "skipped" in skipped.get_text() and "not supported" in skipped.get_text().replace(
        "\n", " "
    )
    hatches = {
        (round(p.get_y() + 0.5), round(p.get_x() + 0.5)): p.get_hatch()
        for p in ax.patches
        if hasattr(p, "get_hatch")
    }
    assert hatches[rows.index("p2"), columns.index("b / y")] == "///"
    assert not hatches[rows.index("p2"), columns.index("c / z")]  # drawn differently
    title = ax.get_title()
    assert "hatched: not reached" in title and "skipped" in title and "not supported" in title
    assert "skipped" in caption and "not reached" in caption or "did not reach" in caption
    import matplotlib.pyplot as plt

    plt.close(figure)


def test_the_cost_at_target_table_says_why_a_cell_has_no_ratio(tmp_path: Path) -> None:
    """'skipped' and 'not run' were written, 'not reached' left an empty cell; the caption
    began 'Integration cpu time' and named no best pair (qa3c F12)."""
    (tmp_path / "figures").mkdir(), (tmp_path / "tables").mkdir()
    overview_of(with_skipped_pair(), tmp_path, None)
    markdown = (tmp_path / "tables" / "cost-at-target.md").read_text(encoding="utf-8")
    (p2,) = [line for line in markdown.splitlines() if line.startswith("| p2 ")]
    assert [cell.strip() for cell in p2.strip("| ").split("|")] == [
        "p2", "1x", "not reached", "skipped",
    ]  # fmt: skip
    (caption,) = [line for line in markdown.splitlines() if line.startswith("Table: ")]
    assert "Cost at scd >= 6 as a ratio to the best pair's" in caption
    assert "wall time" in caption and "cost measure: " in caption
    assert "not reached: the pair ran but did not reach" in caption
    latex = (tmp_path / "tables" / "cost-at-target.tex").read_text(encoding="utf-8")
    assert re.search(r"^p2 & 1x & skipped & not reached", latex, re.M)  # ranking order
    assert "skipped: every run of the pair" in latex  # the caption says what it means
    csv = pd.read_csv(tmp_path / "tables" / "cost-at-target.csv", index_col=0)
    assert csv.loc["p2"].isna().sum() == 2  # the CSV stays numbers for pandas


def test_the_ranking_lists_every_pair_and_the_latex_says_how_many_it_leaves_out(
    tmp_path: Path,
) -> None:
    results = synthetic_results(
        formalisms=("minimal-ode", "absolute-dae", "recursive"),
        integrators=("radau", "generalized-alpha", "scipy-dop853"),
    )
    write_report(results, synthetic_series, tmp_path, "cmd", progress=False)
    tables = tmp_path / "tables"
    assert len(pd.read_csv(tables / "ranking.csv")) == 9
    markdown = (tables / "ranking.md").read_text(encoding="utf-8").splitlines()
    assert len([line for line in markdown if line.startswith("| ")]) == 1 + 9
    assert markdown[-1].startswith("Table: ")  # the caption: what the table measures
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    section = page.split("within reach of the best</h3>", 1)[1].split("</table>", 1)[0]
    assert section.count("<tr>") == 1 + 9
    latex = (tables / "ranking.tex").read_text(encoding="utf-8")
    body = latex.split(r"\midrule", 1)[1].split(r"\bottomrule", 1)[0]
    assert body.count(r"\\") == RANKED_SHOWN < 9
    assert f"the first {RANKED_SHOWN} of 9 pairs" in latex and "ranking.csv" in latex


def test_a_split_latex_table_repeats_what_a_row_is_about(tmp_path: Path) -> None:
    """The cheapest-pair table split into parts repeated only the problem: five lines of
    one problem in the second part could not be told apart by their target."""
    write_report(synthetic_results(), synthetic_series, tmp_path, "cmd", progress=False)
    for stem, keys in (("summary", "problem & target scd & "),
                       ("pareto", "problem & formalism / integrator & rtol & ")):  # fmt: skip
        latex = (tmp_path / "tables" / f"{stem}.tex").read_text(encoding="utf-8")
        headers = list(dict.fromkeys(
            plain_header(line) for line in latex.splitlines() if line.startswith("problem &")
        ))  # fmt: skip
        assert len(headers) >= 2, stem  # split into parts
        assert all(line.startswith(keys) for line in headers), (stem, headers)


def plain_header(line: str) -> str:
    """A LaTeX header line with its broken headers joined again."""
    line = re.sub(r"\\begin\{tabular\}\[b\]\{@\{\}[lr]@\{\}\}|\\end\{tabular\}", "", line)
    return line.replace("\\\\{}", " ")


def test_a_count_column_prints_zero(tmp_path: Path) -> None:
    results = synthetic_results(problems=("simple-pendulum",), integrators=("radau", "bdf"))
    write_report(results, synthetic_series, tmp_path, "cmd", progress=False)
    latex = (tmp_path / "tables" / "status.tex").read_text(encoding="utf-8")
    head = next(line for line in latex.splitlines() if line.startswith("problem &"))
    column = [c.strip() for c in head.rstrip(" \\").split(" & ")].index("ok with warnings")
    row = next(line for line in latex.splitlines() if line.startswith("simple-pendulum &"))
    assert [c.strip() for c in row.rstrip(" \\").split(" & ")][column] == "0"
