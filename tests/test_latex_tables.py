"""The report's LaTeX tables are ready for a paper: a table float with caption and label,
booktabs rules, readable headers with units, one number format a column, and they compile
in a minimal document (when a TeX engine is installed; the structure is checked always)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.test_report import synthetic_results, synthetic_series
from workbench.outputs.report import write_report
from workbench.outputs.report.tables import TABLE_FONT, column_formatter, latex_table

DOCUMENT = r"""\documentclass{article}
\usepackage[T1]{fontenc}
\usepackage{booktabs}
\usepackage[margin=1cm,landscape]{geometry}
\begin{document}
%s
\end{document}
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report")
    write_report(synthetic_results(), synthetic_series, out, "cmd")
    return out / "tables"


def unescaped_ampersands(line: str) -> int:
    return len(re.findall(r"(?<!\\)&", line))


def joined_headers(text: str) -> str:
    """``text`` with each header broken into lines joined again by spaces."""
    return re.sub(
        r"\\begin\{tabular\}\[b\]\{@\{\}[lr]@\{\}\}(.*?)\\end\{tabular\}",
        lambda m: m.group(1).replace("\\\\{}", " "),
        text,
    )


def test_tables_are_captioned_labelled_booktabs_floats(report: Path) -> None:
    tables = sorted(report.glob("*.tex"))
    names = {path.stem for path in tables}
    assert {"summary", "status", "ranking", "pareto", "cost-at-target"} <= names
    drift = [name for name in names if name.startswith("drift-")]
    assert drift and all(name.endswith("-rtol-1e-05") for name in drift)  # names its rtol
    for path in tables:
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        assert lines[0] in ("\\begin{table}[htbp]", "{" + TABLE_FONT), path
        assert lines[-1] in ("\\end{table}", "}"), path
        assert re.search(r"\\caption\{.+\}", text) and f"\\label{{tab:{path.stem}}}" in text
        parts = re.findall(r"\\begin\{(?:tabular|longtable)\}\{((?:[lr]|p\{\d+pt\})+)\}", text)
        assert parts, path
        assert text.count("\\toprule") == text.count("\\bottomrule") >= len(parts)
        for block, align in zip(text.split("\\toprule")[1:], parts, strict=False):
            body = block.split("\\bottomrule")[0].splitlines()
            rows = [line for line in body if line.endswith("\\\\") and "tabular}[b]" not in line]
            width = len(re.findall(r"[lr]|p\{\d+pt\}", align))
            assert all(unescaped_ampersands(row) == width - 1 for row in rows), path
    drift_text = joined_headers((report / f"{drift[0]}.tex").read_text(encoding="utf-8"))
    assert "rtol = 1e-05" in drift_text  # the caption says which tolerance
    assert "max position drift [m or rad]" in drift_text and "L2 error [m]" in drift_text
    summary = joined_headers((report / "summary.tex").read_text(encoding="utf-8"))
    assert "wall time [s]" in summary and "wall\\_s" not in summary


def test_one_number_format_a_column() -> None:
    fmt = column_formatter("wall_s", pd.Series([0.0123, 1.5, np.nan]))
    assert [fmt(v) for v in (0.0123, 1.5, np.nan)] == ["0.012", "1.500", ""]
    wide = column_formatter("err_max", pd.Series([1e-9, 3e-4]))
    assert [wide(v) for v in (1e-9, 3e-4)] == ["1.00e-09", "3.00e-04"]
    assert column_formatter("n_rhs", pd.Series([120.0, 4000.0]))(120.0) == "120"
    assert column_formatter("rtol", pd.Series([1e-4, 1e-6]))(1e-4) == "1.00e-04"
    lines = latex_table(pd.DataFrame({"scd": [5.25, 12.5]})).splitlines()
    assert lines[4:6] == ["5.25 \\\\", "12.50 \\\\"]  # one format: 2 decimals


def test_a_table_compiles_with_booktabs(report: Path, tmp_path: Path) -> None:
    engine = shutil.which("pdflatex")
    if engine is None:
        pytest.skip(
            "no TeX engine (pdflatex): apt-get install -y texlive-latex-base "
            "texlive-latex-recommended; the structure is checked by the test above"
        )
    body = "\n".join(
        (report / f"{name}.tex").read_text(encoding="utf-8")
        for name in ("summary", "status", "ranking")
    )
    drift = next(report.glob("drift-*.tex")).read_text(encoding="utf-8")
    (tmp_path / "paper.tex").write_text(DOCUMENT % (body + drift), encoding="utf-8")
    run = subprocess.run(
        [engine, "-interaction=nonstopmode", "-halt-on-error", "paper.tex"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stdout[-2000:]
    assert (tmp_path / "paper.pdf").stat().st_size > 1000
    log = (tmp_path / "paper.log").read_text(encoding="utf-8", errors="replace")
    assert "Undefined control sequence" not in log


def test_a_table_taller_than_a_page_breaks_across_pages(tmp_path: Path) -> None:
    """25 rows of cells wrapped over several lines: a longtable, never a float taller
    than the page (pdflatex: 'Float too large for page')."""
    text = "minimal-ode / scipy-dop853, 12.1 ms, 1.15x ahead (one sample: tie unknown) of x"
    table = pd.DataFrame({"problem": [f"p{k}" for k in range(25)],
                          **{f"scd >= {t}": [text] * 25 for t in (4, 8, 10)}})  # fmt: skip
    latex = latex_table(table, caption="decision", label="tab:decision")
    assert "\\begin{longtable}" in latex and "\\begin{table}" not in latex
    engine = shutil.which("pdflatex")
    if engine is None:
        pytest.skip("no TeX engine (pdflatex): apt-get install -y texlive-latex-base")
    document = DOCUMENT.replace("\\usepackage[margin=1cm,landscape]{geometry}\n", "")
    document = document.replace("\\usepackage{booktabs}", "\\usepackage{booktabs,longtable}")
    (tmp_path / "t.tex").write_text(document % latex, encoding="utf-8")
    run = subprocess.run([engine, "-interaction=nonstopmode", "-halt-on-error", "t.tex"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=600)  # fmt: skip
    assert run.returncode == 0, run.stdout[-2000:]
    log = (tmp_path / "t.log").read_text(encoding="utf-8", errors="replace")
    assert "Float too large" not in log and "Overfull \\hbox" not in log


def test_a_header_never_breaks_inside_its_unit(report: Path) -> None:
    """A drift table's header broke as 'max position drift [m or' over 'rad]' (the page)
    and 'drift [m or' over 'rad]' (the LaTeX): each line of a broken LaTeX header holds
    whole units, and the page's units hold no-break spaces only, so the browser breaks
    before '[m or rad]', not inside it; the header still says all it said."""
    from workbench.outputs.report.page import PageTable

    drift = next(report.glob("drift-*.tex")).read_text(encoding="utf-8")
    broken = re.findall(r"\\begin\{tabular\}\[b\]\{@\{\}[lr]@\{\}\}(.*?)\\end\{tabular\}", drift)
    assert any("[m or rad]" in header for header in broken), broken  # broken, unit whole
    for header in broken:
        for line in header.split(r"\\{}"):
            assert line.count("[") == line.count("]"), header
    table = pd.read_csv(next(report.glob("drift-*.csv")))
    header = PageTable.of(table, "drift").header
    assert "max position drift [m\N{NO-BREAK SPACE}or\N{NO-BREAK SPACE}rad]" in header
    assert "max velocity drift [m/s\N{NO-BREAK SPACE}or\N{NO-BREAK SPACE}rad/s]" in header
    assert "max energy error / energy in motion" in header  # breaks between words as before


def test_a_broken_header_takes_as_few_lines_as_the_page_allows() -> None:
    """A ranking's last header took 5 lines of 12 characters ('geometric mean' / 'of cost /
    best' / ...) beside 200 pt of free page: headers now widen to the fewest lines at
    which the table still fits, each whole, nothing lost."""
    from workbench.outputs.report.tables import TEXT_WIDTH_PT, _laid_out

    head = [
        "formalism / integrator",
        "problems within 2x of the best",
        "problems reaching scd >= 6",
        "geometric mean of cost / best over the problems reached",
    ]
    rows = [["minimal-ode / scipy-dop853", "6", "6", "1.24x"],
            ["absolute-dae / sundials-cvode-bdf", "0", "0", ""]]  # fmt: skip
    columns = _laid_out(head, rows, [False, True, True, True])
    assert sum(column.width_pt for column in columns) <= TEXT_WIDTH_PT
    assert max(len(column.header) for column in columns) == 3  # 5 before; 2 do not fit
    assert [" ".join(column.header) for column in columns] == head
    text = latex_table(pd.DataFrame(rows, columns=head))
    assert "geometric mean of cost / best over the problems reached" in joined_headers(text)
    # a table whose headers fit whole keeps them whole
    whole = _laid_out(["rtol", "ok"], [["1e-06", "3"]], [True, True])
    assert all(len(column.header) == 1 for column in whole)
