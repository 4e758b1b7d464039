"""`workbench paper`: a folder whose main.tex inputs the report's tables and includes its
PDF figures, and which compiles under plain article with booktabs and no overfull box
wider than 10 pt, even for a sweep of 42 pairs (whose cost and status tables were
43-column tabulars, 5,908 pt too wide).

The compiling tests need pdflatex (apt-get install texlive-latex-base
texlive-latex-recommended): skipped with that reason where it is missing, unless CI is set.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from tests.test_report import synthetic_results, synthetic_series
from workbench.cli import app
from workbench.outputs.report import write_report
from workbench.outputs.report.paper import MAIN, PREAMBLE, compile_paper, pdflatex
from workbench.outputs.report.tables import latex_escape, latex_table

WIDEST_OVERFULL_PT = 10.0


def needs_pdflatex() -> None:
    if pdflatex() is None:
        reason = (
            "pdflatex is not installed (apt-get install -y texlive-latex-base "
            "texlive-latex-recommended)"
        )
        if os.environ.get("CI"):
            pytest.fail(f"{reason}; CI is set, so the paper must compile")
        pytest.skip(reason)


def wide_results():
    """3 problems x 6 formalisms x 7 integrators: 42 pairs, as the default sweep has."""
    return synthetic_results(
        problems=("simple-pendulum", "four-bar", "heavy-top"),
        formalisms=("minimal-ode", "absolute-dae", "recursive", "newton-euler-dae",
                    "lagrange-multipliers", "hamilton-constrained"),
        integrators=("scipy-dop853", "scipy-radau", "sundials-cvode-bdf", "sundials-ida",
                     "generalized-alpha", "hht-newmark", "casadi-idas"),
        rtols=(1e-4, 1e-7),
    )  # fmt: skip


def test_comparisons_print_as_mathematics() -> None:
    """'>=' under the default font encoding prints as '¿='."""
    assert latex_escape("scd >= 8, a < b, x != y") == (r"scd $\geq$ 8, a \textless{} b, x $\neq$ y")
    assert latex_escape("12 \N{MICRO SIGN}s") == r"12 $\mu$s"


def test_the_paper_of_a_sweep_of_42_pairs_fits_the_page(tmp_path: Path) -> None:
    needs_pdflatex()
    paper = tmp_path / "paper"
    write_report(wide_results(), synthetic_series, tmp_path / "report", "cmd", paper=paper,
                 progress=False)  # fmt: skip
    main = (paper / MAIN).read_text(encoding="utf-8")
    for stem in re.findall(r"\\input\{tables/([^}]+)\}", main):
        assert (paper / "tables" / f"{stem}.tex").is_file(), stem
    for pdf in re.findall(r"\{(figures/[^}]+\.pdf)\}", main):
        assert (paper / pdf).is_file(), pdf
    assert {"decision", "summary", "status", "ranking", "pareto"} <= set(
        re.findall(r"\\input\{tables/([^}]+)\}", main)
    )
    status = (paper / "tables" / "status.tex").read_text(encoding="utf-8")
    assert "[1]" in status and "Newton iteration diverged" in status  # carries its reasons
    compiled = compile_paper(paper / MAIN)
    assert compiled.pdf is not None, compiled.log_tail
    assert compiled.overfull_pt <= WIDEST_OVERFULL_PT
    log = (paper / "main.log").read_text(encoding="utf-8", errors="replace")
    assert "Undefined control sequence" not in log and "Missing character" not in log
    assert "Float too large" not in log


def test_a_long_table_with_many_notes_breaks_across_pages_within_the_width(
    tmp_path: Path,
) -> None:
    """The full sweep's status table (a longtable, 30 problems) and its 22 reasons: the
    reasons sat in a minipage of the line's width, indented 15 pt and 118 pt too high."""
    needs_pdflatex()
    table = pd.DataFrame(
        {"problem": [f"problem-{k}" for k in range(60)],
         "reasons": [", ".join(f"[{j}]" for j in range(1, 1 + k % 5)) for k in range(60)]}
    )  # fmt: skip
    notes = [
        f"[{k}] skipped: " + "a reason of some length, " * 8 + f"({k} runs)" for k in range(40)
    ]
    text = latex_table(table, caption="status", notes=notes)
    assert r"\begin{longtable}" in text
    (tmp_path / "t.tex").write_text(text, encoding="utf-8")
    main = tmp_path / MAIN
    main.write_text(PREAMBLE + "\\begin{document}\n\\input{t}\n\\end{document}\n", encoding="utf-8")
    compiled = compile_paper(main)
    assert compiled.pdf is not None, compiled.log_tail
    log = (tmp_path / "main.log").read_text(encoding="utf-8", errors="replace")
    assert "Overfull" not in log, log[-3000:]


def test_workbench_paper_of_a_small_sweep_compiles(tmp_path: Path) -> None:
    needs_pdflatex()
    spec = tmp_path / "spec.toml"
    spec.write_text(
        'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
        'integrators = ["scipy-dop853", "scipy-radau"]\ntolerances = [1e-4, 1e-7]\njobs = 1\n',
        encoding="utf-8",
    )
    runner = CliRunner()
    swept = runner.invoke(app, ["sweep", str(spec), "--out", str(tmp_path / "out")])
    assert swept.exit_code == 0, swept.output
    chosen = runner.invoke(app, ["report", str(tmp_path / "out"), "--cost", "n_rhs"])
    assert chosen.exit_code == 0, chosen.output
    made = runner.invoke(app, ["paper", str(tmp_path / "out")])
    assert made.exit_code == 0, made.output
    # in the measure the report was made in: report and paper recommend the same
    assert "cost measure n_rhs, as `workbench report --cost` chose before" in made.output
    main = (tmp_path / "out" / "paper" / "main.tex").read_text(encoding="utf-8")
    assert "cost measure: rhs evaluations." in main
    pdf = tmp_path / "out" / "paper" / "main.pdf"
    assert f"paper: {pdf}" in made.output and pdf.stat().st_size > 10_000
    assert "overfull" not in made.output  # none at all
    for name in ("decision", "summary", "status"):
        assert (tmp_path / "out" / "paper" / "tables" / f"{name}.tex").is_file()
    assert list((tmp_path / "out" / "paper" / "figures").glob("*work-precision.pdf"))


def test_the_paper_says_whether_close_calls_were_timed_again(tmp_path: Path) -> None:
    """The page's paragraph above the decision table (the tie rule, the close calls timed
    again after the runs) was not in the paper: main.tex carries the same words, from
    the same source, whether or not the sweep re-timed."""
    results = synthetic_results(problems=("simple-pendulum",))
    results["retimed"] = [5, 5] + [0] * (len(results) - 2)
    retimed = " ".join(
        "2 close call(s), the runs of pairs within 3x of a cheapest, were timed again "
        "after the runs, 5 times at moments apart".split()
    )
    for name, rows in (("again", results), ("once", results.assign(retimed=0))):
        out = tmp_path / name
        page = write_report(rows, None, out / "report", "cmd", progress=False,
                            paper=out / "paper").read_text(encoding="utf-8")  # fmt: skip
        tex = " ".join((out / "paper" / MAIN).read_text(encoding="utf-8").split())
        said = re.search(r'<p id="decision-note">(.*?)</p>', page, re.S).group(1)
        assert latex_escape(said.replace("&#39;", "'")) in tex  # the page's paragraph
        assert "'tie' where their timed samples' ranges overlap" in tex  # the tie rule
        if name == "again":
            assert retimed in tex and "No run was timed again" not in tex
        else:
            assert "No run was timed again after the runs" in tex and retimed not in tex
    out = tmp_path / "counted"  # a counted cost: no timing to trust or doubt
    write_report(results, None, out / "report", "cmd", progress=False, cost="n_rhs",
                 paper=out / "paper")  # fmt: skip
    assert "timed again" not in (out / "paper" / MAIN).read_text(encoding="utf-8")


def test_a_split_longtable_is_compiled_until_its_columns_line_up(tmp_path: Path) -> None:
    """One pdflatex pass left every longtable's columns out of line with its rules (it
    sets them from widths the pass before wrote to main.aux: 'Table widths have changed.
    Rerun LaTeX.'); the summary of the quick suite's paper was unreadable."""
    needs_pdflatex()
    table = pd.DataFrame(
        {"problem": [f"problem-{k}" for k in range(45)], "scd": [k / 7 for k in range(45)]}
    )
    (tmp_path / "t.tex").write_text(latex_table(table, caption="long"), encoding="utf-8")
    main = tmp_path / MAIN
    main.write_text(PREAMBLE + "\\begin{document}\n\\input{t}\n\\end{document}\n", encoding="utf-8")
    compiled = compile_paper(main)
    assert compiled.pdf is not None, compiled.log_tail
    log = (tmp_path / "main.log").read_text(encoding="utf-8", errors="replace")
    assert r"\begin{longtable}" in (tmp_path / "t.tex").read_text(encoding="utf-8")
    assert "Rerun LaTeX" not in log and "widths have changed" not in log


def _table_height_pt(tmp_path: Path, table: pd.DataFrame) -> float:
    """The height pdflatex gives ``latex_table(table)`` (a plain tabular), in pt."""
    (tmp_path / "t.tex").write_text(latex_table(table), encoding="utf-8")
    main = tmp_path / MAIN
    main.write_text(
        PREAMBLE + "\\begin{document}\n\\setbox0=\\vbox{\\input{t}}\n"
        "\\typeout{HEIGHT=\\the\\dimexpr\\ht0+\\dp0\\relax}\n\\end{document}\n",
        encoding="utf-8",
    )
    compiled = compile_paper(main)
    assert compiled.pdf is None or compiled.pdf.is_file()
    log = (tmp_path / "main.log").read_text(encoding="utf-8", errors="replace")
    return float(re.search(r"HEIGHT=([\d.]+)pt", log).group(1))


def test_a_row_with_a_wrapped_cell_is_one_line_high_not_two(tmp_path: Path) -> None:
    """A wrapped (p{}) cell ended '{\\raggedright text\\par}': pdflatex left a blank line
    under every such row, so the quick suite's summary and tied-pairs tables took twice
    their pages. Ten rows of one-line wrapped cells are as high as ten plain rows."""
    needs_pdflatex()
    narrow = "iiii iiii iiii iiii iiii iiii"  # over WRAP_CHARS characters, one line wide
    wrapped = pd.DataFrame({"a": ["x"] * 10, "b": [narrow] * 10, "c": [narrow] * 10})
    plain = pd.DataFrame({"a": ["x"] * 10, "b": ["i"] * 10, "c": ["i"] * 10})
    assert r"p{" in latex_table(wrapped) and r"p{" not in latex_table(plain)
    assert _table_height_pt(tmp_path, wrapped) < 1.1 * _table_height_pt(tmp_path, plain)
