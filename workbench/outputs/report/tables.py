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

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
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
    "run scd": "its scd [digits]",
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
    "energy_err_max": "max energy error / energy in motion",
    "invariant_err_max": "max relative invariant error",
    "fixed_step_s": "fixed step [s]",
    "integrate_s": "integration wall time [s]",
    "integrate_s_min": "least integration wall time [s]",
    "integrate_s_max": "greatest integration wall time [s]",
    "integrate_cpu_s": "integration CPU time [s]",
    "integrate_cpu_s_min": "least integration CPU time [s]",
    "integrate_cpu_s_max": "greatest integration CPU time [s]",
    "work_s": "counted work [s]",
    "work_s_min": "least counted work [s]",
    "work_s_max": "greatest counted work [s]",
    "repeats": "timed samples",
    "retimed": "samples timed again after the runs",
    "margin": "margin over the runner-up",
    "runner-up": "runner-up (cheapest pair not tied)",
    "tied pairs": "tied pairs",
    "verdict": "verdict",
    "length_scale": "length scale L [m]",
    "formalism_options": "formalism options",
    "integrator_options": "integrator options",
}
"""Readable header (with its unit) of a result column; other columns keep their name."""

SCIENTIFIC = ("rtol", "atol", "fixed_step_s", "reference_accuracy")
"""Columns always in scientific notation (tolerances and steps are powers of ten)."""

RATIOS = ("margin", "geometric mean ratio")
"""Columns of cost ratios, printed as the decision table's margins are (:func:`times_text`);
a table's ``attrs["ratios"]`` names others (True: all its columns)."""


def header(column: Any) -> str:
    """The readable header of ``column`` (:data:`HEADERS`), else its name."""
    return HEADERS.get(str(column), str(column))


def write_table(
    table: pd.DataFrame,
    directory: Path,
    name: str,
    caption: str | None = None,
    latex: pd.DataFrame | None = None,
    notes: Sequence[str] = (),
    keys: int | None = None,
) -> list[Path]:
    """Write ``table`` as ``name``.csv, .md and .tex (booktabs, captioned, labelled
    ``tab:<name>``) into ``directory``; ``latex``: another table for the .tex (one that
    fits a page, e.g. a summary of a wide matrix), ``notes``: lines under it, ``keys``:
    the leading columns a .tex split to fit the page repeats (:func:`latex_table`)."""
    paths = [directory / f"{name}.{ext}" for ext in ("csv", "md", "tex")]
    index = shows_index(table)
    table.to_csv(paths[0], index=index)
    listed = "".join(f"\n- {note}" for note in notes)
    # the caption under the table (pandoc's "Table:"): what was measured, what the
    # empty cells mean (the .md said none of it)
    said = f"\nTable: {markdown_text(caption)}\n" if caption else ""
    paths[1].write_text(
        markdown_table(table, index=index) + (f"\n{listed.lstrip()}\n" if notes else "")
        + said,
        encoding="utf-8",
    )
    printed = table if latex is None else latex
    latex = latex_table(
        printed, index=shows_index(printed), caption=caption or name, label=f"tab:{name}",
        notes=notes, keys=keys,
    )  # fmt: skip
    paths[2].write_text(latex, encoding="utf-8")
    return paths


def leading_keys(table: pd.DataFrame, names: Sequence[str]) -> int:
    """How many of ``table``'s first columns are among ``names`` (the columns that say
    what a row is about: a LaTeX table split into parts repeats them in every part)."""
    count = 0
    for column in table.columns:
        if str(column) not in names:
            break
        count += 1
    return count


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


def ratio_text(value: float) -> str:
    """A cost ratio (a margin, a heat map's cell) with the digits that tell it from 1:
    '1' (exactly), '1.003', '1.40', '12.3', '140' ('.3g' printed 1.003 as '1', the
    winner's own value, and 1.4 beside 1.19)."""
    if value == 1.0:
        return "1"
    if value < 1.1:
        return f"{value:.3f}"
    if value < 10:
        return f"{value:.2f}"
    return f"{value:.1f}" if value < 100 else f"{value:.0f}"


def times_text(value: Any) -> str:
    """A ratio of costs as the report prints it wherever a reader sees one (a margin in
    the decision table, the summary, the ranking, ``workbench results``): '1.70x',
    '1.003x'; '' when missing. One format, so the summary's '2.103' and the decision's
    '2.10x' cannot both name one margin."""
    return "" if _missing(value) else f"{ratio_text(float(value))}x"


def ratio_columns(table: pd.DataFrame) -> set[str]:
    """The columns of ``table`` holding cost ratios (:data:`RATIOS`, ``attrs["ratios"]``)."""
    named = table.attrs.get("ratios", ())
    if named is True:
        return {str(c) for c in table.columns}
    return {str(c) for c in table.columns if str(c) in RATIOS or c in named}


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


def distinct_formatter(column: Any, values: pd.Series) -> Callable[[Any], str]:
    """:func:`column_formatter`'s fixed decimals, more where two different values would
    print alike (up to 12): a Pareto front held two runs of scd '2.992', the dearer one
    on it by 3e-6 digits, and read as a duplicated row."""
    base = column_formatter(column, values)
    numbers = pd.to_numeric(values, errors="coerce") if values.dtype != object else None
    if numbers is None or numbers.isna().all():
        return base
    unique = np.unique(numbers[np.isfinite(numbers)].to_numpy(dtype=float))
    sample = base(unique[0]) if unique.size else "e"
    if "e" in sample or "." not in sample:  # scientific or whole numbers: as they are
        return base
    decimals = len(sample.partition(".")[2])
    while decimals < 12 and len({f"{v:.{decimals}f}" for v in unique}) < unique.size:
        decimals += 1
    return lambda value: "" if _missing(value) else f"{float(value):.{decimals}f}"


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float | np.floating) and math.isnan(value))


def table_cells(table: pd.DataFrame, index: bool = False) -> tuple[list[str], list[list[str]]]:
    """The readable header and the rows of ``table`` as text, one format a column
    (:func:`column_formatter`), the index first when ``index``; cost ratios
    (:func:`ratio_columns`) as the decision table prints margins (:func:`times_text`);
    the columns ``attrs["distinct"]`` names with the digits that tell their values apart
    (:func:`distinct_formatter`). A missing value is an empty cell, or the text
    ``attrs["missing"][row label][column]`` says why it is missing (the CSV, for pandas,
    keeps it empty)."""
    head = ([header(table.index.name or "")] if index else []) + [header(c) for c in table.columns]
    missing = table.attrs.get("missing") or {}
    ratios, distinct = ratio_columns(table), set(table.attrs.get("distinct", ()))
    formats = [
        times_text if str(c) in ratios
        else distinct_formatter(c, table[c]) if c in distinct
        else column_formatter(c, table[c])
        for c in table.columns
    ]  # fmt: skip
    rows = []
    for label, row in zip(table.index, table.itertuples(index=False), strict=True):
        cells = [fmt(value) for fmt, value in zip(formats, row, strict=True)]
        why = missing.get(label, {})
        cells = [
            str(why.get(column, "")) if _missing(value) else cell
            for column, value, cell in zip(table.columns, row, cells, strict=True)
        ]
        rows.append(([str(label)] if index else []) + cells)
    return head, rows


def markdown_text(text: str) -> str:
    """``text`` for Markdown outside a table: one line, & and < as entities (no tag)."""
    return " ".join(str(text).split()).replace("&", "&amp;").replace("<", "&lt;")


def markdown_table(table: pd.DataFrame, index: bool = False) -> str:
    """A GitHub-flavoured Markdown pipe table (pipes in cells escaped, and HTML: Markdown
    passes raw HTML through, so a plugin named ``<img onerror=...>`` would be markup in
    a rendered table; & and < become entities: no tag or entity can start without them,
    and "> 1000 rtol" stays readable in the plain text)."""
    head, rows = table_cells(table, index)

    def cell(text: str) -> str:
        text = text.replace("&", "&amp;").replace("<", "&lt;")
        return text.replace("|", "\\|").replace("\n", " ")

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
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    "\N{MICRO SIGN}": r"$\mu$",
    "\N{GREEK SMALL LETTER MU}": r"$\mu$",
    "\N{MINUS SIGN}": "-",
}
# Comparisons as mathematics: under the default OT1 encoding '>' prints as an inverted
# question mark and '>=' as '¿='.
LATEX_COMPARISONS = {">=": r"$\geq$", "<=": r"$\leq$", "!=": r"$\neq$"}


def latex_escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped, comparisons as $\\geq$ etc."""
    out, text, k = [], str(text), 0
    while k < len(text):
        pair = text[k : k + 2]
        if pair in LATEX_COMPARISONS:
            out.append(LATEX_COMPARISONS[pair])
            k += 2
            continue
        char = text[k]
        out.append(LATEX_SPECIAL.get(char, char) if ord(char) < 128 or char in LATEX_SPECIAL
                   else "?")  # fmt: skip
        k += 1
    return "".join(out)


# How a LaTeX table is laid out to fit a page of plain ``article`` (10 pt, \textwidth
# 345 pt): \footnotesize, 3 pt column separation, characters at most CHAR_PT wide.
TEXT_WIDTH_PT = 345.0
CHAR_PT = 4.3  # a generous mean width of a \footnotesize character (cmr8: 4.0-4.25)
COLUMN_GAP_PT = 6.0  # 2 x \tabcolsep
WRAP_CHARS = 26  # a text column wider than this wraps in a p{} column
MIN_WRAP_CHARS = 12  # a text column is never wrapped narrower
HEADER_CHARS = 12  # a header longer than its column and this breaks into lines
LONG_ROWS = 40  # more lines of rows: a longtable (breaks across pages; \usepackage{longtable})
TABLE_FONT = r"\footnotesize\setlength{\tabcolsep}{3pt}"


def header_words(text: str) -> list[str]:
    """The pieces a header may break between: its words, a unit in brackets one piece
    ('[m or rad]'), so no line ends inside a unit ('drift [m or' over 'rad]')."""
    words: list[str] = []
    for word in text.split():
        if words and words[-1].count("[") > words[-1].count("]"):  # inside a unit
            words[-1] += " " + word
        else:
            words.append(word)
    return words


def unbroken_units(text: str) -> str:
    """``text`` with the spaces inside its units made no-break spaces: a browser breaks
    a header only where :func:`header_words` allows."""
    return " ".join(word.replace(" ", "\N{NO-BREAK SPACE}") for word in header_words(text))


def _words_lines(text: str, width: int) -> list[str]:
    """``text`` broken between :func:`header_words` into lines of at most ``width``
    characters (a longer piece stays whole)."""
    lines: list[str] = []
    for word in header_words(text):
        if lines and len(lines[-1]) + 1 + len(word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return lines or [""]


@dataclass
class _Column:
    header: list[str]  # its lines
    numeric: bool
    chars: int  # width in characters
    wrapped: bool  # a p{} column

    @property
    def spec(self) -> str:
        if self.wrapped:
            return f"p{{{self.chars * CHAR_PT:.0f}pt}}"
        return "r" if self.numeric else "l"

    @property
    def width_pt(self) -> float:
        return self.chars * CHAR_PT + COLUMN_GAP_PT


def _columns(
    head: list[str], rows: list[list[str]], kinds: list[bool], break_headers: bool
) -> list[_Column]:
    columns = []
    for k, (name, numeric) in enumerate(zip(head, kinds, strict=True)):
        cells = [row[k] for row in rows]
        longest = max((len(c) for c in cells), default=0)
        word = max((len(w) for c in cells for w in c.split()), default=0)
        wrapped = not numeric and longest > WRAP_CHARS
        chars = max(WRAP_CHARS, word) if wrapped else longest
        width = max(chars, HEADER_CHARS, max(len(w) for w in header_words(name) or [""]) + 2)
        lines = _words_lines(name, width) if break_headers and len(name) > width else [name]
        chars = max(chars, *(len(line) for line in lines))
        columns.append(_Column(lines, numeric, chars, wrapped))
    return columns


def _laid_out(head: list[str], rows: list[list[str]], kinds: list[bool]) -> list[_Column]:
    """The columns with whole headers when they fit the page, else with broken ones and
    the long text columns wrapped narrower (never below their longest word)."""
    columns = _columns(head, rows, kinds, break_headers=False)
    if sum(column.width_pt for column in columns) <= TEXT_WIDTH_PT:
        return columns
    columns = _columns(head, rows, kinds, break_headers=True)
    narrow = [
        k for k, c in enumerate(columns) if not c.numeric and c.chars > MIN_WRAP_CHARS and k > 0
    ]
    fixed = sum(c.width_pt for k, c in enumerate(columns) if k not in narrow)
    if narrow and fixed < TEXT_WIDTH_PT:
        share = int((TEXT_WIDTH_PT - fixed) / len(narrow) / CHAR_PT) - 2
        for k in narrow:
            column = columns[k]
            cells = [row[k] for row in rows]
            word = max((len(w) for c in cells for w in c.split()), default=0)
            header = max(len(w) for line in column.header for w in header_words(line))
            chars = max(share, word, header, MIN_WRAP_CHARS)
            if chars < column.chars:
                lines = _words_lines(" ".join(column.header), chars)
                columns[k] = _Column(lines, False, chars, True)
    return _fewer_header_lines(columns, head)


def _fewer_header_lines(columns: list[_Column], head: list[str]) -> list[_Column]:
    """``columns`` with their broken headers in as few lines as the page allows: each
    header of more than L lines widened until it takes L, for the least L at which the
    table still fits (a ranking's 'geometric mean of cost / best over the problems
    reached' took 5 lines of 12 characters beside 200 pt of free page)."""
    most = max(len(column.header) for column in columns)
    for limit in range(1, most):
        widened = []
        for column, name in zip(columns, head, strict=True):
            if len(column.header) <= limit:
                widened.append(column)
                continue
            width = column.chars
            while len(lines := _words_lines(name, width)) > limit:
                width += 1
            widened.append(replace(column, header=lines, chars=max(column.chars, width)))
        if sum(column.width_pt for column in widened) <= TEXT_WIDTH_PT:
            return widened
    return columns


def _chunks(columns: list[_Column], keys: int) -> list[list[int]]:
    """Column indices of each part of a table too wide for the page: the first ``keys``
    columns (what a row is about) repeated in every part."""
    key = list(range(min(keys, len(columns))))
    budget = TEXT_WIDTH_PT - sum(columns[k].width_pt for k in key)
    parts: list[list[int]] = []
    current: list[int] = []
    used = 0.0
    for k in range(len(key), len(columns)):
        width = columns[k].width_pt
        if current and used + width > budget:
            parts.append(current)
            current, used = [], 0.0
        current.append(k)
        used += width
    if current or not parts:
        parts.append(current)
    return [key + part for part in parts]


def _text_lines(rows: list[list[str]], columns: list[_Column]) -> int:
    """About how many lines of text the rows take (wrapped cells take several)."""
    return sum(
        max([1] + [math.ceil(len(row[k]) / c.chars) for k, c in enumerate(columns) if c.wrapped])
        for row in rows
    )


def _cell(text: str, column: _Column, last: bool = False) -> str:
    """A body cell; in a wrapped column ragged right (no stretched spaces), and when it
    is the row's ``last`` cell ``\\\\`` made the row's end again (as array's
    \\arraybackslash does: \\raggedright makes it a line break). Not
    ``{\\raggedright text\\par}``: that left a blank line under every row with a wrapped
    cell (the quick suite's summary took twice its pages)."""
    if column.wrapped and text:
        end = r"\let\\\tabularnewline" if last else ""
        return r"\raggedright " + latex_escape(text) + end
    return latex_escape(text)


def _header_cell(column: _Column) -> str:
    lines = [latex_escape(line) for line in column.header]
    if len(lines) == 1:
        return lines[0]
    align = "r" if column.numeric else "l"
    return f"\\begin{{tabular}}[b]{{@{{}}{align}@{{}}}}" + r"\\{}".join(lines) + r"\end{tabular}"


def latex_table(
    table: pd.DataFrame,
    index: bool = False,
    caption: str | None = None,
    label: str | None = None,
    notes: Sequence[str] = (),
    keys: int | None = None,
) -> str:
    """Booktabs LaTeX of ``table`` (needs ``\\usepackage{booktabs}``, and
    ``\\usepackage{longtable}`` for tables of more than :data:`LONG_ROWS` rows): readable
    headers with units, numbers right-aligned in one format a column, LaTeX's special
    characters escaped, laid out to fit the text width of a plain ``article``: long text
    wraps, long headers break into lines, a table still too wide is split into parts
    that repeat its first ``keys`` columns (what a row is about; default its first column
    when that is text). With a ``caption`` (and ``label``) it is a ``table``
    float in \\footnotesize (a ``longtable`` when long); ``notes`` are printed under it."""
    head, rows = table_cells(table, index)
    kinds = ([False] if index else []) + [
        pd.api.types.is_numeric_dtype(table[c]) and table[c].dtype != bool for c in table.columns
    ]
    columns = _laid_out(head, rows, kinds)
    if keys is None:
        keys = 1 if (kinds and not kinds[0]) else 0
    parts = _chunks(columns, keys) if columns else [[]]
    # the parts stack in one float: their lines add up, each part's rows as tall as its
    # own wrapped cells make them
    lines = sum(
        _text_lines([[row[k] for k in part] for row in rows], [columns[k] for k in part])
        for part in parts
    )
    long = caption is not None and lines > LONG_ROWS
    blocks = []
    for number, part in enumerate(parts):
        align = "".join(columns[k].spec for k in part)
        header = " & ".join(_header_cell(columns[k]) for k in part) + r" \\"
        body = [
            " & ".join(_cell(row[k], columns[k], k == part[-1]) for k in part) + r" \\"
            for row in rows
        ]
        if long:
            title = (
                [
                    f"\\caption{{{latex_escape(caption)}}}"
                    + (f"\\label{{{label}}}" if label else "")
                    + r"\\"
                ]
                if number == 0
                else []  # fmt: skip
            )
            blocks.append("\n".join([
                f"\\begin{{longtable}}{{{align}}}", *title, r"\toprule", header, r"\midrule",
                r"\endfirsthead", r"\toprule", header, r"\midrule", r"\endhead",
                r"\bottomrule", r"\endlastfoot", *body, r"\end{longtable}",
            ]))  # fmt: skip
        else:
            blocks.append("\n".join([
                f"\\begin{{tabular}}{{{align}}}", r"\toprule", header, r"\midrule", *body,
                r"\bottomrule", r"\end{tabular}",
            ]))  # fmt: skip
    # plain paragraphs, not indented: a minipage could not break across pages (118 pt
    # too high under the full sweep's status table) and took the paragraph's indent
    notes_text = [
        r"\par\smallskip{\raggedright\setlength{\parindent}{0pt}",
        *(latex_escape(note) + r"\par" for note in notes),
        "}",
    ] if notes else []  # fmt: skip
    if caption is None:
        return "\n\\par\\medskip\n".join(blocks) + "\n" + "\n".join(notes_text)
    if long:
        return "\n".join(["{" + TABLE_FONT, "\n\\medskip\n".join(blocks), *notes_text, "}"]) + "\n"
    wrapped = [r"\begin{table}[htbp]", r"\centering", TABLE_FONT,
               f"\\caption{{{latex_escape(caption)}}}"]  # fmt: skip
    if label:
        wrapped.append(f"\\label{{{label}}}")  # a slug: no special characters
    wrapped.append(r"\par\smallskip")
    return (
        "\n".join([*wrapped, "\n\\par\\medskip\n".join(blocks), *notes_text, r"\end{table}"]) + "\n"
    )
