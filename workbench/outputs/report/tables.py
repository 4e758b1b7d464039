"""A report's tables as files (CSV, Markdown, LaTeX) and as text cells for the HTML page.

CSV keeps the result store's column names and full precision (for pandas). Markdown,
LaTeX and the page show readable headers with units (:data:`HEADERS`) and one number
format a column (:func:`column_formatter`): whole numbers as integers, tolerances and
quantities spanning decades in scientific notation, the rest with a fixed number of
decimals; a missing value is an empty cell. A table whose index has a name (the status
matrix) shows the index as its first column. LaTeX tables are booktabs ``tabular``s inside
a ``table`` float with a caption and a label.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

HEADERS: dict[str, str] = {
    "problem": "problem",
    "pair": "formalism / integrator",
    "formalism": "formalism",
    "integrator": "integrator",
    "rtol": "rtol",
    "atol": "atol",
    "status": "status",
    "target scd": "target scd",
    "scd": "scd [digits]",
    "wall_s": "wall time [s]",
    "cpu_s": "CPU time [s]",
    "n_rhs": "rhs evaluations",
    "n_jac": "Jacobians",
    "n_steps": "steps",
    "n_rejected": "rejected steps",
    "err_end": "end error [m]",
    "err_l2": "L2 error [m]",
    "err_max": "max error [m]",
    "drift_pos_max": "max position drift [m or rad]",
    "drift_vel_max": "max velocity drift [m/s or rad/s]",
    "drift_nh_max": "max nonholonomic drift [m/s or rad/s]",
    "energy_err_max": "max relative energy error",
    "invariant_err_max": "max relative invariant error",
    "fixed_step_s": "fixed step [s]",
    "length_scale": "length scale L [m]",
    "formalism_options": "formalism options",
    "integrator_options": "integrator options",
}
"""Readable header (with its unit) of a result column; other columns keep their name."""

SCIENTIFIC = ("rtol", "atol", "fixed_step_s", "reference_accuracy")
"""Columns always in scientific notation (tolerances and steps are powers of ten)."""


def header(column: Any) -> str:
    """The readable header of ``column`` (:data:`HEADERS`), else its name."""
    return HEADERS.get(str(column), str(column))


def write_table(
    table: pd.DataFrame, directory: Path, name: str, caption: str | None = None
) -> list[Path]:
    """Write ``table`` as ``name``.csv, .md and .tex (booktabs, captioned, labelled
    ``tab:<name>``) into ``directory``."""
    paths = [directory / f"{name}.{ext}" for ext in ("csv", "md", "tex")]
    index = shows_index(table)
    table.to_csv(paths[0], index=index)
    paths[1].write_text(markdown_table(table, index=index), encoding="utf-8")
    latex = latex_table(table, index=index, caption=caption or name, label=f"tab:{name}")
    paths[2].write_text(latex, encoding="utf-8")
    return paths


def shows_index(table: pd.DataFrame) -> bool:
    """A named index is data (the status matrix's problems); an unnamed one is a row number."""
    return table.index.name is not None


def cell_text(value: Any) -> str:
    """A single value as shown: floats to 4 significant digits, NaN as nothing."""
    if isinstance(value, float | np.floating):
        if math.isnan(value):
            return ""
        return f"{value:.4g}"
    return str(value)


def column_formatter(column: Any, values: pd.Series) -> Callable[[Any], str]:
    """One number format for a whole column: integers when every value is whole;
    scientific (3 significant digits) for :data:`SCIENTIFIC` columns and for values
    spanning more than three decades or outside [1e-3, 1e5); otherwise fixed decimals
    giving the largest value 4 significant digits. Text columns are shown as they are."""
    numbers = pd.to_numeric(values, errors="coerce") if values.dtype != object else None
    if numbers is None or not pd.api.types.is_numeric_dtype(values) or values.dtype == bool:
        return lambda value: "" if _missing(value) else str(value)
    finite = np.abs(numbers[np.isfinite(numbers)].to_numpy(dtype=float))
    if finite.size and np.all(finite == np.round(finite)) and str(column) not in SCIENTIFIC:
        return lambda value: "" if _missing(value) else f"{float(value):.0f}"
    positive = finite[finite > 0]
    wide = positive.size and (
        positive.max() / positive.min() > 1e3 or positive.min() < 1e-3 or positive.max() >= 1e5
    )
    if str(column) in SCIENTIFIC or wide:
        return lambda value: "" if _missing(value) else f"{float(value):.2e}"
    top = positive.max() if positive.size else 1.0
    decimals = max(0, 3 - math.floor(math.log10(top)))
    return lambda value: "" if _missing(value) else f"{float(value):.{decimals}f}"


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float | np.floating) and math.isnan(value))


def table_cells(table: pd.DataFrame, index: bool = False) -> tuple[list[str], list[list[str]]]:
    """The readable header and the rows of ``table`` as text, one format a column
    (:func:`column_formatter`), the index first when ``index``."""
    head = ([header(table.index.name or "")] if index else []) + [header(c) for c in table.columns]
    formats = [column_formatter(c, table[c]) for c in table.columns]
    rows = []
    for label, row in zip(table.index, table.itertuples(index=False), strict=True):
        cells = [fmt(value) for fmt, value in zip(formats, row, strict=True)]
        rows.append(([str(label)] if index else []) + cells)
    return head, rows


def markdown_table(table: pd.DataFrame, index: bool = False) -> str:
    """A GitHub-flavoured Markdown pipe table (pipes in cells escaped, and HTML: Markdown
    passes raw HTML through, so a plugin named ``<img onerror=...>`` would be markup in
    a rendered table; &, < and > become entities, as in the HTML report)."""
    head, rows = table_cells(table, index)

    def cell(text: str) -> str:
        return html.escape(text, quote=False).replace("|", "\\|").replace("\n", " ")

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(cell(c) for c in cells) + " |"

    return (
        "\n".join(
            [line(head), "|" + "|".join("---" for _ in head) + "|"] + [line(row) for row in rows]
        )
        + "\n"
    )


LATEX_SPECIAL = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
}


def latex_escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped."""
    return "".join(LATEX_SPECIAL.get(char, char) for char in str(text))


def latex_table(
    table: pd.DataFrame,
    index: bool = False,
    caption: str | None = None,
    label: str | None = None,
) -> str:
    """A booktabs ``tabular`` (needs ``\\usepackage{booktabs}``): readable headers with
    units, numbers right-aligned in one format a column, LaTeX's special characters
    escaped. With a ``caption`` (and ``label``) it is wrapped in a ``table`` float."""
    head, rows = table_cells(table, index)
    kinds = ([False] if index else []) + [
        pd.api.types.is_numeric_dtype(table[c]) and table[c].dtype != bool for c in table.columns
    ]
    align = "".join("r" if numeric else "l" for numeric in kinds)
    lines = [f"\\begin{{tabular}}{{{align}}}", "\\toprule"]
    lines.append(" & ".join(latex_escape(cell) for cell in head) + " \\\\")
    lines.append("\\midrule")
    lines += [" & ".join(latex_escape(cell) for cell in row) + " \\\\" for row in rows]
    lines += ["\\bottomrule", "\\end{tabular}"]
    if caption is None:
        return "\n".join(lines) + "\n"
    wrapped = ["\\begin{table}[htbp]", "\\centering", f"\\caption{{{latex_escape(caption)}}}"]
    if label:
        wrapped.append(f"\\label{{{label}}}")  # a slug: no special characters
    return "\n".join([*wrapped, *lines, "\\end{table}"]) + "\n"
