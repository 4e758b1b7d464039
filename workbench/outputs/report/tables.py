"""A report's tables as files (CSV, Markdown, LaTeX) and as text cells for the HTML page.

Every writer shows numbers the same way (:func:`cell_text`: 4 significant digits, nothing
for a missing value). A table whose index has a name (the status matrix) shows the index
as its first column.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd


def write_table(table: pd.DataFrame, directory: Path, name: str) -> list[Path]:
    """Write ``table`` as ``name``.csv, .md and .tex (booktabs) into ``directory``."""
    paths = [directory / f"{name}.{ext}" for ext in ("csv", "md", "tex")]
    index = shows_index(table)
    table.to_csv(paths[0], index=index)
    paths[1].write_text(markdown_table(table, index=index), encoding="utf-8")
    paths[2].write_text(latex_table(table, index=index), encoding="utf-8")
    return paths


def shows_index(table: pd.DataFrame) -> bool:
    """A named index is data (the status matrix's problems); an unnamed one is a row number."""
    return table.index.name is not None


def cell_text(value: Any) -> str:
    """A cell as shown: floats to 4 significant digits, NaN as nothing, the rest as str."""
    if isinstance(value, float | np.floating):
        if math.isnan(value):
            return ""
        return f"{value:.4g}"
    return str(value)


def table_cells(table: pd.DataFrame, index: bool = False) -> tuple[list[str], list[list[str]]]:
    """The header and the rows of ``table`` as text (:func:`cell_text`), the index first
    when ``index``."""
    header = ([table.index.name or ""] if index else []) + [str(c) for c in table.columns]
    rows = []
    for label, row in zip(table.index, table.itertuples(index=False), strict=True):
        rows.append(([str(label)] if index else []) + [cell_text(value) for value in row])
    return header, rows


def markdown_table(table: pd.DataFrame, index: bool = False) -> str:
    """A GitHub-flavoured Markdown pipe table (pipes in cells escaped)."""
    header, rows = table_cells(table, index)

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|").replace("\n", " ") for c in cells) + " |"

    return (
        "\n".join(
            [line(header), "|" + "|".join("---" for _ in header) + "|"]
            + [line(row) for row in rows]
        )
        + "\n"
    )


def latex_table(table: pd.DataFrame, index: bool = False) -> str:
    """A booktabs ``tabular`` (needs ``\\usepackage{booktabs}``) through pandas' Styler:
    numbers right-aligned, LaTeX's special characters escaped in cells and headers."""
    if index:
        table = table.reset_index()
    align = "".join(
        "r" if pd.api.types.is_numeric_dtype(table[column]) else "l" for column in table.columns
    )
    styler = (
        table.rename(columns=str)
        .style.format(cell_text, escape="latex")
        .format_index(axis="columns", escape="latex")
        .hide(axis="index")
    )
    return styler.to_latex(column_format=align, hrules=True)
