"""The results store: one directory, crash-safe and resumable.

Layout of an output directory ``<out>``::

    <out>/runs/<run_id>.json         one result row (JSON object), see
                                     workbench.execution.row_schema.SCHEMA
    <out>/series/<run_id>.parquet    its time series (SERIES_COLUMNS) and its trajectory:
                                     the states at the same output samples, one column
                                     "state:<name>" per named q, v and multiplier
                                     (the sweep key store_trajectories = false leaves them out)
    <out>/references/*.parquet       computed reference poses (see workbench.execution.references)
    <out>/results.parquet            all rows, consolidated at the end of a sweep
    <out>/sweep.toml                 the sweep specification that was run (if any)
    <out>/plan.json                  the run ids the last sweep planned and its source,
                                     so a report can tell planned from present runs
    <out>/environment.json           the full environment of the last sweep started here
                                     (workbench.execution.environment.sweep_environment)

A run's row and series are written in place (:func:`workbench.files.write_new_file`),
the series first, so a whole row implies a whole series; a worker killed mid-write leaves
a row that does not parse or a series without its footer, which read as not done, and a
resumed sweep redoes those runs and skips the run ids whose row is whole. The other files
are written atomically (:func:`workbench.files.atomic_write`: a temporary file renamed
over the target). A reader beside a running sweep (``workbench results``) may meet a row
being written: :func:`read_settled` reads a new file that does not parse again for up
to :data:`SETTLE_S`.

:func:`load_results` returns a DataFrame whose first columns are always those of
:data:`~workbench.execution.row_schema.SCHEMA`, in that order (missing values NaN or
empty), followed by any others. Rows of an older schema are migrated when read
(:func:`~workbench.execution.row_schema.migrate_row`), so old output directories stay
readable; a row of a newer schema than this code knows is refused (:class:`ConfigError`:
upgrade the workbench). What a row holds is the one-run layer's
(:mod:`workbench.execution.row_schema`); this module keeps rows on disk.
"""

from __future__ import annotations

import json
import math
import os
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import pandas as pd

from workbench.errors import ConfigError, one_line
from workbench.execution.row_check import row_defects, series_defect
from workbench.execution.row_schema import (
    SCHEMA_COLUMNS,
    SCHEMA_VERSION,
    SERIES_COLUMNS,
    STATE_PREFIX,
    empty_series,
    migrate_row,
    refuse_newer,
    row_schema_version,
)
from workbench.files import remove_temporaries, write_json_atomic, write_parquet_atomic

T = TypeVar("T")

RUNS_DIR = "runs"
SERIES_DIR = "series"
RESULTS_FILE = "results.parquet"
ENVIRONMENT_FILE = "environment.json"
PLAN_FILE = "plan.json"  # the run ids the last sweep started here planned (load_plan)


# ---- the store -----------------------------------------------------------------------


def row_path(out: Path, run_id: str) -> Path:
    return Path(out) / RUNS_DIR / f"{run_id}.json"


def series_path(out: Path, run_id: str) -> Path:
    return Path(out) / SERIES_DIR / f"{run_id}.parquet"


def write_run(
    out: Path,
    row: dict[str, Any],
    series: pd.DataFrame | dict[str, Any] | None,
    states: bool = True,
) -> None:
    """Persist one run: the series first, then the row (so a row implies its series).

    ``series``: a DataFrame, or its columns (name -> values, a text repeated on every row:
    :func:`workbench.execution.metrics.metric_columns`; the same file as their frame's).
    ``states``: keep the trajectory's state columns in the series (False: drift, energy
    and error only, as before trajectories were stored).

    Both are written in place (:func:`workbench.files.write_new_file`), not renamed into
    place: a worker killed mid-write leaves a row that does not parse or a series without
    its footer, which read as not done, as a lost file does. Neither is synced to disk
    here: after a machine crash a row lost or left corrupt reads as not done
    (:func:`read_row`), and so does a row whose series is not whole (its footer and sample
    count: :func:`workbench.execution.row_check.series_defect`), so the run is simply run
    again; the sweep syncs the output folder's file system once at its end
    (:func:`workbench.files.sync_file_system`). A sync a run cost 2-5 ms, more than a tiny
    run's integration, and made the workers wait on each other's journal commits.
    """
    run_id = row["run_id"]
    if series is not None:
        if not states and isinstance(series, pd.DataFrame):
            series = series[[c for c in series.columns if not c.startswith(STATE_PREFIX)]]
        elif not states:
            series = {k: v for k, v in series.items() if not k.startswith(STATE_PREFIX)}
        path = series_path(out, run_id)
        write_parquet_atomic(
            series, path, root=Path(out), durable=False, lean=True, renamed=False
        )
    write_json_atomic(
        row, row_path(out, run_id), durable=False, root=Path(out), indent=None, renamed=False
    )


def read_row(path: Path, settle: bool = False) -> dict[str, Any] | None:
    """One row file, or None if it is unreadable (truncated, corrupt, not an object).
    ``settle``: a new file is read again while it does not parse (:func:`read_settled`)."""
    if settle:
        return read_settled(path, read_row)
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(data.get("run_id"), str):
        return None
    return data


SETTLE_S = 1.0
"""Seconds after its last change within which a file that does not read may still be
being written (a run's row or series, written in place in well under a millisecond)."""


def read_settled(path: Path, read: Callable[[Path], T | None]) -> T | None:
    """``read(path)``, and again after short waits while it gives None or raises and the
    file changed less than :data:`SETTLE_S` ago: a reader beside a running sweep meets a
    row or series in the middle of its write (an empty file, a part), which a moment later
    is whole. A file older than that is what a killed writer left: not waited for. The
    last attempt's error is raised, None given as it is."""
    pause = 0.005
    while True:
        try:
            value, error = read(path), None
        except Exception as raised:  # noqa: BLE001 - whatever ``read`` raises, re-raised below
            value, error = None, raised
        if value is not None:
            return value
        try:
            age = time.time() - Path(path).stat().st_mtime
        except OSError:  # gone meanwhile (a run done again unlinks it first)
            age = SETTLE_S
        if not 0 <= age < SETTLE_S:
            if error is not None:
                raise error
            return None
        time.sleep(pause)
        pause = min(2 * pause, 0.1)


def row_options(row: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """A row's ``problem_options``, ``formalism_options`` and ``integrator_options`` as
    dicts (a row file holds them as JSON text, a run's row in memory as dicts); ValueError
    if one is not a JSON object."""
    options = {}
    for kind in ("problem", "formalism", "integrator"):
        value = row.get(f"{kind}_options") or {}
        value = json.loads(value) if isinstance(value, str) else value
        if not isinstance(value, dict):
            raise ValueError(f"{kind}_options is not an object: {value!r}")
        options[f"{kind}_options"] = value
    return options


def remove_stale_temporaries(out: Path) -> list[Path]:
    """Delete temporary files left by writers killed mid-write (never read as results):
    only files named as :func:`workbench.files.atomic_write` names them, no link followed."""
    return remove_temporaries(out)


def check_rows(out: Path) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """(whole, bad): the rows of ``out`` that are whole, by run id (migrated to the
    current schema), and what is wrong with each of the others, by run id (the file's
    name): unreadable, not a row of the schema (:func:`~workbench.execution.row_check.row_defects`)
    or its series broken (:func:`~workbench.execution.row_check.series_defect`).

    ConfigError if a row is of a newer schema: an older workbench must not add rows
    to a directory that a newer one wrote (it could not read the whole afterwards).
    """
    directory = Path(out) / RUNS_DIR
    if not directory.is_dir():
        return {}, {}
    whole, bad, newer = {}, {}, []
    for path in sorted(directory.glob("*.json")):
        row = read_row(path)
        if row is None:
            bad[path.stem] = "its row file is unreadable (truncated, corrupt or not a row)"
            continue
        version = row_schema_version(row, path)
        if version > SCHEMA_VERSION:
            newer.append((str(path), version))
            continue
        defects = row_defects(row, SCHEMA_COLUMNS, path.stem)
        defect = "; ".join(defects) or series_defect(
            series_path(out, path.stem), row, SERIES_COLUMNS
        )
        if defect:
            bad[path.stem] = defect
        else:
            whole[path.stem] = migrate_row(row, path)
    refuse_newer(newer)
    return whole, bad


def completed_run_ids(out: Path) -> set[str]:
    """Run ids whose row and series are whole (:func:`check_rows`): what a resumed sweep
    may skip."""
    return set(check_rows(out)[0])


def frame_from_rows(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """Rows as a DataFrame with the SCHEMA columns first (missing ones NaN)."""
    frame = pd.DataFrame(list(rows))
    missing = [c for c in SCHEMA_COLUMNS if c not in frame.columns]
    if missing:  # added at once: a column at a time took 41 ms for a row of 10 columns
        blank = pd.DataFrame(math.nan, index=frame.index, columns=missing)
        frame = pd.concat([frame, blank], axis=1)
    extra = [c for c in frame.columns if c not in SCHEMA_COLUMNS]
    frame = frame[SCHEMA_COLUMNS + extra]
    if len(frame) > 1:
        frame = frame.sort_values(
            ["problem", "formalism", "integrator", "rtol", "run_id"],
            kind="stable",
            ignore_index=True,
        )
    return frame


def _parquet_safe(frame: pd.DataFrame) -> pd.DataFrame:
    """Object columns of mixed types (e.g. NaN in a text column) as strings for Parquet."""
    frame = frame.copy()
    for column in frame.columns:
        if frame[column].dtype == object:
            frame[column] = frame[column].map(
                lambda v: (
                    ""
                    if v is None or (isinstance(v, float) and math.isnan(v))
                    else v
                    if isinstance(v, str)
                    else json.dumps(v)
                )
            )
    return frame


def consolidate(out: Path, loaded: list[pd.DataFrame] | None = None) -> Path:
    """Write ``<out>/results.parquet`` (atomically) from the row files; return its path.
    ``loaded``: the rows read (:func:`load_results`' frame) are appended to it, so that a
    caller can use them again (the sweep's report) rather than read every row file twice."""
    frame = load_results(out)
    path = Path(out) / RESULTS_FILE
    write_parquet_atomic(_parquet_safe(frame), path, root=Path(out))
    if loaded is not None:
        loaded.append(frame)
    return path


def load_results(path: str | os.PathLike[str]) -> pd.DataFrame:
    """All result rows of an output directory (``runs/*.json``), or of a results.parquet.

    The columns start with :data:`SCHEMA_COLUMNS` in that order. A row file that cannot
    be read (truncated or corrupt) is left out with a warning naming it; the names of such
    files are in ``frame.attrs["unreadable"]``. Rows of an older schema are migrated to
    the current one (their files, or the results file, are listed in
    ``frame.attrs["migrated"]``); if any row is of a newer schema than this code knows,
    nothing is loaded: ConfigError naming its file (upgrade the workbench).
    """
    path = _results_path(path)
    if path.is_file():
        try:
            frame = pd.read_parquet(path)
        except Exception as error:  # noqa: BLE001 - pyarrow raises several kinds
            raise ConfigError(f"cannot read results file {path}: {error}") from None
        records = frame.to_dict("records")
        old = any(row_schema_version(row, path) < SCHEMA_VERSION for row in records)
        frame = frame_from_rows([migrate_row(row, path) for row in records])
        frame.attrs["migrated"] = [str(path)] if old else []
        return frame
    directory = path / RUNS_DIR
    if not directory.is_dir():
        if (path / RESULTS_FILE).is_file():
            return load_results(path / RESULTS_FILE)
        raise ConfigError(
            f"no results in {path}: expected a directory with runs/*.json "
            "(the output of `workbench sweep`) or a results.parquet file"
        )
    rows, unreadable, migrated, newer = [], [], [], []
    for row_file in sorted(directory.glob("*.json")):
        row = read_row(row_file, settle=True)  # beside a running sweep: a row mid-write
        version = 0 if row is None else row_schema_version(row, row_file)
        defects = ["unreadable"] if row is None else row_defects(row, SCHEMA_COLUMNS, row_file.stem)
        if version > SCHEMA_VERSION:
            newer.append((str(row_file), version))
        elif defects:
            unreadable.append(f"{row_file} ({'; '.join(defects)})")
        else:
            if version < SCHEMA_VERSION:
                migrated.append(str(row_file))
            rows.append(migrate_row(row, row_file))
    refuse_newer(newer)
    if unreadable:
        warnings.warn(
            f"{len(unreadable)} unreadable result file(s) left out (re-run the sweep to "
            f"redo them): {', '.join(unreadable[:5])}",
            stacklevel=2,
        )
    frame = frame_from_rows(rows)
    frame.attrs["unreadable"] = [entry.partition(" (")[0] for entry in unreadable]
    frame.attrs["migrated"] = migrated
    return frame


def load_series(
    path: str | os.PathLike[str], run_id: str | None = None, states: bool = False
) -> pd.DataFrame:
    """Time series of one run (``run_id``) or of all runs of an output directory.

    ``states``: also the trajectory's columns ``state:<name>`` (one run's only; see
    :func:`load_trajectory`); without it the columns are :data:`SERIES_COLUMNS`.
    One run's: ConfigError if it is missing or unreadable. All runs': a file that cannot
    be read is left out with a warning naming it (a resumed sweep redoes its run); a
    ``path`` that is no results directory: ConfigError."""
    directory = _results_path(path) / SERIES_DIR
    if run_id is not None:
        _check_run_id(run_id)
        file = directory / f"{run_id}.parquet"
        if not Path(path).exists():
            raise ConfigError(f"no results at {path}: no such file or folder")
        if not file.is_file():
            raise ConfigError(f"no time series for run {run_id!r} in {path}")
        try:
            frame = read_settled(file, pd.read_parquet)
        except Exception as error:  # noqa: BLE001 - pyarrow raises several kinds
            raise ConfigError(
                f"time series {file} is unreadable ({one_line(error)}); "
                "re-run the sweep to redo its run"
            ) from None
        return frame if states else _without_states(frame)
    if not directory.is_dir() and not (Path(path) / RUNS_DIR).is_dir():
        raise ConfigError(
            f"no results in {path}: expected a directory with series/*.parquet "
            "(the output of `workbench sweep` or `workbench.run(..., out=...)`)"
        )
    frames, unreadable = [], []
    for file in sorted(directory.glob("*.parquet")):
        try:
            frames.append(_without_states(read_settled(file, pd.read_parquet)))
        except Exception:  # noqa: BLE001 - pyarrow raises several kinds
            unreadable.append(str(file))
    if unreadable:
        warnings.warn(
            f"{len(unreadable)} unreadable time series file(s) left out (re-run the sweep "
            f"to redo their runs): {', '.join(unreadable[:5])}",
            stacklevel=2,
        )
    frames = [f for f in frames if len(f)]
    if not frames:
        return empty_series("")
    return pd.concat(frames, ignore_index=True)


def _without_states(frame: pd.DataFrame) -> pd.DataFrame:
    return frame[[c for c in frame.columns if not c.startswith(STATE_PREFIX)]]


def load_trajectory(path: str | os.PathLike[str], run_id: str) -> pd.DataFrame:
    """The trajectory of run ``run_id`` stored in output directory ``path``: column ``t``
    (s) and one column per state, named as the equations name it (q, v, then
    ``lambda:<constraint>`` where the form integrated has multipliers), one row per output
    sample reached. ConfigError if the run stored none (``store_trajectories = false``,
    a run written before trajectories were stored, or one that never integrated)."""
    _check_run_id(run_id)  # None would read every run's series
    frame = load_series(path, run_id, states=True)
    names = [c for c in frame.columns if c.startswith(STATE_PREFIX)]
    if (not names and len(frame)) or "t" not in frame.columns:  # (no samples: an empty one)
        raise ConfigError(
            f"run {run_id!r} in {path} has no stored trajectory (swept with "
            "store_trajectories = false, or by a workbench that did not store them): "
            "run it again to have one"
        )
    trajectory = frame[["t", *names]].rename(columns=lambda c: c.removeprefix(STATE_PREFIX))
    return trajectory.reset_index(drop=True)


def _results_path(path: Any) -> Path:
    if not isinstance(path, str | os.PathLike) or not str(path):
        raise ConfigError(
            f"expected the path of a results directory (or results.parquet), not {path!r}"
        )
    return Path(path)


def _check_run_id(run_id: Any) -> None:
    if not isinstance(run_id, str):
        raise ConfigError(
            f"run_id: expected a run id (text, e.g. results['run_id'].iloc[0]), "
            f"not {type(run_id).__name__}"
        )


__all__ = [
    "ENVIRONMENT_FILE",
    "check_rows",
    "completed_run_ids",
    "consolidate",
    "frame_from_rows",
    "load_results",
    "load_series",
    "load_trajectory",
    "read_row",
    "row_options",
    "row_path",
    "series_path",
    "write_run",
]


def write_plan(
    out: str | os.PathLike[str],
    run_ids: Iterable[str],
    source: str,
    stale: Mapping[str, dict[str, Any]] | None = None,
) -> None:
    """Record the run ids a sweep planned in ``out`` (its source: a file or a suite) and
    the done rows it found stale (run id -> {"reason", "row": its producer columns})."""
    ids = list(dict.fromkeys(str(run_id) for run_id in run_ids))
    plan = {"source": source, "runs": len(ids), "run_ids": ids, "stale": dict(stale or {})}
    write_json_atomic(plan, Path(out) / PLAN_FILE, root=Path(out))


def load_plan(out: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The plan of the last sweep started in ``out`` ({source, runs, run_ids}); None when
    none was recorded or the file is unreadable (a report then cannot tell it)."""
    try:
        data = json.loads((Path(out) / PLAN_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(data.get("run_ids"), list):
        return None
    return data
