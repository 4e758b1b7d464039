"""Is a stored result whole? A row file checked against the schema, its series by footer.

A resumed sweep counts a run as done only if its row passes :func:`row_defects` and its
time series :func:`series_defect`; :func:`workbench.runs.store.load_results` leaves out
(with a warning naming the file) a row that does not, so one bad file never breaks a
report. Both answer in words (what is wrong), never by raising.

What is checked: the key columns every row has (``REQUIRED``) with their types; every other
schema column present has its type (text, number or flag; missing values are ``null``/NaN);
the run id is the file's name; the repeated timing (schemas 7, 8) is whole (``repeats`` >= 1,
the median ``integrate_s`` within its min and max). The series file (Parquet) must have a
readable footer with the series columns, and as many samples as the row's ``n_samples``
(rows of schema 4 on); an ``ok`` row of an older schema must have a readable series.
"""

from __future__ import annotations

import math
import numbers
from pathlib import Path
from typing import Any

from workbench.errors import one_line_text

STATUSES = ("ok", "failed", "skipped", "timeout")

# the columns every row has had since schema 1, with their kind
REQUIRED = {
    "run_id": "text",
    "problem": "text",
    "formalism": "text",
    "integrator": "text",
    "rtol": "number",
    "atol": "number",
    "status": "text",
    "message": "text",
}
TEXT_COLUMNS = {
    "problem_options",
    "formalism_options",
    "integrator_options",
    "stage",
    "form",
    "reference_kind",
    "reference",
    "notes",
    "version_python",
    "version_numpy",
    "version_scipy",
    "version_casadi",
    "version_sksundae",
    "version_workbench",
    "machine",
    "warnings",
    "formalism_notes",
    "producer_problem",
    "producer_formalism",
    "producer_integrator",
    "log",
}
FLAG_COLUMNS = {"equations_cached"}


def _kind_ok(value: Any, kind: str) -> bool:
    if kind == "text":
        return isinstance(value, str)
    if kind == "flag":
        return isinstance(value, bool)
    if type(value) is float or type(value) is int:  # JSON's numbers: no ABC check (slow)
        return True
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _is_missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def row_defects(row: dict[str, Any], schema_columns: list[str], name: str = "") -> list[str]:
    """What is wrong with ``row`` (a parsed row file named ``name``.json); [] if nothing."""
    defects = []
    for column, kind in REQUIRED.items():
        if column not in row or _is_missing(row[column]):
            defects.append(f"no {column}")
        elif not _kind_ok(row[column], kind):
            defects.append(f"{column} {row[column]!r} is not a {kind}")
    if not defects:
        if name and row["run_id"] != name:
            defects.append(f"run_id {row['run_id']!r} is not the file's name {name!r}")
        if row["status"] not in STATUSES:
            defects.append(f"status {row['status']!r} is not one of {', '.join(STATUSES)}")
        for column in ("rtol", "atol"):
            if not (math.isfinite(row[column]) and row[column] > 0):
                defects.append(f"{column} {row[column]!r} is not a finite number > 0")
    for column in schema_columns:
        if column in REQUIRED or column == "schema_version" or column not in row:
            continue
        value = row[column]
        if _is_missing(value):
            continue
        kind = "text" if column in TEXT_COLUMNS else "flag" if column in FLAG_COLUMNS else "number"
        if not _kind_ok(value, kind):
            defects.append(f"{column} {value!r} is not a {kind}")
    if not defects:
        defects += _timing_defects(row) + _accuracy_defects(row)
    return defects


def _accuracy_defects(row: dict[str, Any]) -> list[str]:
    """scd follows from the row's own end error: -log10(err_end / length_scale), capped at
    the digits the reference has (-log10(reference_accuracy)). A row edited by hand to a
    better scd showed it beside the error it contradicts, trusted."""
    values = [row.get(c) for c in ("scd", "err_end", "length_scale")]
    if any(_is_missing(v) for v in values):
        return []
    scd, err_end, length = (float(v) for v in values)
    if not (math.isfinite(scd) and err_end > 0 and length > 0):
        return []
    expected = -math.log10(err_end / length)
    accuracy = row.get("reference_accuracy")
    known = not _is_missing(accuracy) and float(accuracy) > 0
    if known and err_end / length < float(accuracy):
        expected = -math.log10(float(accuracy))
    close = abs(scd - expected) <= 1e-9 * max(1.0, abs(expected))
    if close or (not known and scd < expected):  # (older rows: capped, the cap not kept)
        return []
    return [f"scd {scd!r} does not follow from err_end / length_scale (it gives {expected:.6g})"]


def _timing_defects(row: dict[str, Any]) -> list[str]:
    """The repeated timing (schema 7): a whole number of samples >= 1 whose median lies
    between their least and greatest."""
    defects = []
    repeats = row.get("repeats")
    if not _is_missing(repeats) and not (repeats >= 1 and float(repeats).is_integer()):
        defects.append(f"repeats {repeats!r} is not a whole number >= 1")
    for median_column in ("integrate_s", "integrate_cpu_s"):
        low_column, high_column = f"{median_column}_min", f"{median_column}_max"
        low, median, high = (row.get(c) for c in (low_column, median_column, high_column))
        if not any(_is_missing(v) for v in (low, median, high)) and not low <= median <= high:
            defects.append(
                f"{median_column} {median!r} is not within [{low_column}, {high_column}] "
                f"= [{low!r}, {high!r}]"
            )
    return defects


def series_defect(path: Path, row: dict[str, Any], series_columns: list[str]) -> str | None:
    """What is wrong with the series file ``path`` of ``row``, or None if it is whole.

    Reads the Parquet footer only (the row count and the column names), not the data."""
    import pyarrow.parquet as pq

    samples = row.get("n_samples")
    expected = None if _is_missing(samples) else samples
    if not path.is_file():
        if (expected is None and row.get("status") == "ok") or (expected or 0) > 0:
            return f"its time series {path.name} is missing"
        return None
    try:
        metadata = pq.read_metadata(path)
    except Exception as error:  # noqa: BLE001 - pyarrow raises several kinds for a bad file
        reason = one_line_text(str(error))
        return f"its time series {path.name} is unreadable (truncated or corrupt: {reason})"
    missing = [c for c in series_columns if c not in metadata.schema.names]
    if missing:
        return f"its time series {path.name} lacks the column(s) {', '.join(missing)}"
    if expected is not None and metadata.num_rows != expected:
        return (
            f"its time series {path.name} has {metadata.num_rows} samples, "
            f"the row says {expected:g}"
        )
    return None


__all__ = ["REQUIRED", "STATUSES", "row_defects", "series_defect"]
