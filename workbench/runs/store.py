"""The results store: one directory, crash-safe and resumable.

Layout of an output directory ``<out>``::

    <out>/runs/<run_id>.json         one result row (JSON object), see SCHEMA
    <out>/series/<run_id>.parquet    its time series (SERIES_COLUMNS) and its trajectory:
                                     the states at the same output samples, one column
                                     "state:<name>" per named q, v and multiplier
                                     (the sweep key store_trajectories = false leaves them out)
    <out>/references/*.parquet       computed reference poses (see workbench.runs.metrics)
    <out>/results.parquet            all rows, consolidated at the end of a sweep
    <out>/sweep.toml                 the sweep specification that was run (if any)
    <out>/plan.json                  the run ids the last sweep planned and its source,
                                     so a report can tell planned from present runs
    <out>/environment.json           the full environment of the last sweep started here
                                     (workbench.runs.environment.sweep_environment)

Every file is written atomically (:func:`workbench.files.atomic_write`): to a temporary
file in the same directory, then renamed over the target with :func:`os.replace`. The
series is written before the row, so a row file implies its series; a sweep killed at
any moment leaves only whole files, and a resumed sweep skips the run ids whose row
exists.

:func:`load_results` returns a DataFrame whose first columns are always those of
:data:`SCHEMA`, in that order (missing values NaN or empty), followed by any others.

A row carries the version of its schema (``schema_version``; a row without one is
version 1, written before versions existed). Rows of an older schema are migrated when
read (:data:`MIGRATIONS`), so old output directories stay readable; a row of a newer
schema than this code knows is refused (:class:`ConfigError`: upgrade the workbench).
"""

from __future__ import annotations

import json
import math
import numbers
import os
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pandas as pd

from workbench.errors import ConfigError, one_line
from workbench.files import atomic_write, remove_temporaries
from workbench.runs.row_check import row_defects, series_defect

# The stable schema of a result row: (column, meaning). Units: seconds, metres, radians.
SCHEMA: list[tuple[str, str]] = [
    ("run_id", "16 hex digits of sha256 of the run's canonical JSON"),
    ("problem", "problem name"),
    ("problem_options", "problem options, JSON"),
    ("formalism", "formalism name"),
    ("formalism_options", "formalism options, JSON"),
    ("integrator", "integrator name"),
    ("integrator_options", "integrator options, JSON"),
    ("rtol", "relative tolerance"),
    ("atol", "absolute tolerance"),
    ("status", "ok | failed | skipped | timeout"),
    ("message", "why a run failed, was skipped or timed out (one line)"),
    ("stage", "the stage that failed: pairing, build, initial state, integrate, metrics, log"),
    ("form", "the form the integrator consumed (ode, dae, mechanical)"),
    ("t_reached", "last output time reached (s)"),
    ("wall_s", "wall time of the run: build_s + compile_s + init_s + integrate_s + metrics_s"),
    ("cpu_s", "CPU time of the same stages"),
    ("build_s", "wall time to build the equations (0 when reused from the worker's cache)"),
    ("compile_s", "wall time to generate, compile and load C (compile=jit; 0 otherwise)"),
    ("init_s", "wall time of the consistent initial state"),
    ("integrate_s", "wall time of the integration: the median of its timed samples (repeats)"),
    ("metrics_s", "wall time of the metrics (without computing the reference)"),
    ("reference_s", "wall time to obtain the reference (0 when cached)"),
    ("equations_cached", "the equations were reused from the worker's cache"),
    ("n_rhs", "right-hand-side / residual evaluations"),
    ("n_jac", "Jacobian evaluations"),
    ("n_steps", "accepted steps"),
    ("n_rejected", "rejected steps"),
    ("n_lu", "LU factorizations (-1: not reported)"),
    ("n_newton", "Newton iterations (-1: not reported)"),
    ("reference_kind", "analytic | stored | computed | none"),
    ("reference", "how the reference was obtained"),
    ("length_scale", "L of the pose error (m)"),
    ("err_max", "max over output times of the pose error (m): its L-infinity norm"),
    ("err_end", "pose error at the end time (m)"),
    ("scd", "-log10(err_end / length_scale)"),
    ("scd_mixed", "min over end-pose components of -log10(|err| / (1 + |ref|)) (test set)"),
    ("drift_pos_max", "max position-level constraint residual"),
    ("drift_pos_final", "final position-level constraint residual"),
    ("drift_vel_max", "max velocity-level constraint residual"),
    ("drift_vel_final", "final velocity-level constraint residual"),
    ("drift_nh_max", "max nonholonomic constraint residual (NaN: none)"),
    ("drift_nh_final", "final nonholonomic constraint residual"),
    ("energy_err_max", "max relative energy error (NaN: not conservative)"),
    ("energy_err_final", "final relative energy error"),
    ("invariant_err_max", "max relative error of the problem's invariants"),
    ("notes", "remarks on the metrics (e.g. what was not computed and why)"),
    ("version_python", "Python version"),
    ("version_numpy", "NumPy version"),
    ("version_scipy", "SciPy version"),
    ("version_casadi", "CasADi version"),
    ("version_sksundae", "scikit-sundae version"),
    ("version_workbench", "mbs-workbench version"),
    ("machine", "platform of the machine that ran it"),
    ("cpu_count", "CPUs of that machine"),
    ("log", "the run's captured stdout/stderr, bounded (logs/<run_id>.log; '': none)"),
    ("threads", "BLAS/OpenMP threads the run's process allowed (WORKBENCH_THREADS, default 1)"),
    ("schema_version", "version of this schema (SCHEMA_VERSION) the row was written in"),
    ("warnings", "what the health audit found wrong ('; '-separated, one line; empty: nothing)"),
    ("jacobian_sv_ratio_min", "smallest sigma_min/sigma_max of the constraint Jacobian W"),
    ("jacobian_sv_ratio_at", "time of that smallest ratio (s)"),
    ("branch_left_at", "first output time off the assembly branch the run started on (s)"),
    ("branch_distance_max", "distance from that branch there, or the most of a run on it"),
    ("dof_start", "nv - rank W at the start"),
    ("dof_max", "the most nv - rank W along the output times"),
    ("rotation_defect_max", "largest |R^T R - I| of the body rotations (0: orthonormal)"),
    ("formalism_notes", "the formalism's notes (rows removed, partitions chosen)"),
    ("reference_accuracy", "relative accuracy the reference states for itself"),
    ("n_samples", "rows of the run's time series (0: none stored)"),
    ("producer_problem", "what produced the row: the problem plugin's source hash or version"),
    ("producer_formalism", "the formalism plugin's source hash or distribution version"),
    ("producer_integrator", "the integrator plugin's source hash or distribution version"),
    ("err_l2", "root mean square over output times of the pose error (m): its L2 norm"),
    ("fixed_step_s", "the step of a fixed-step method (s); NaN for an adaptive one"),
    ("integrate_s_min", "least wall time of the integration's timed samples (s)"),
    ("integrate_s_max", "greatest wall time of the integration's timed samples (s)"),
    ("integrate_cpu_s", "CPU time of the integration: the median of its timed samples (s)"),
    ("repeats", "timed samples of the integration (workbench.runs.timing; NaN: not timed)"),
    ("load_avg", "1-minute load average of the machine when the run started"),
    ("workers", "worker processes of the sweep running runs at the same time"),
    ("integrate_cpu_s_min", "least CPU time of the integration's timed samples (s)"),
    ("integrate_cpu_s_max", "greatest CPU time of the integration's timed samples (s)"),
    ("penetration_max", "deepest contact penetration (m; NaN: no contacts)"),
    ("complementarity_max", "worst relative residual of the contact problems solved"),
    ("n_events", "impacts and stick/slip switches the contact integrator reported"),
    ("event_time_err_max", "largest distance of a reference contact event to the run's (s)"),
    ("energy_balance_err", "energy lost against the restitution and friction laws, relative"),
]
SCHEMA_COLUMNS = [name for name, _ in SCHEMA]
SERIES_COLUMNS = ["run_id", "t", "drift_pos", "drift_vel", "drift_nh", "energy_err", "ref_err"]
# a series column holding a state of the trajectory: STATE_PREFIX + the equations' name
STATE_PREFIX = "state:"
PRODUCER_COLUMNS = ["producer_problem", "producer_formalism", "producer_integrator"]
UNKNOWN_PRODUCER = "unknown"
RUNS_DIR = "runs"
SERIES_DIR = "series"
RESULTS_FILE = "results.parquet"
ENVIRONMENT_FILE = "environment.json"
PLAN_FILE = "plan.json"  # the run ids the last sweep started here planned (load_plan)


# ---- schema versions ---------------------------------------------------------------------

# History of the row schema:
#   1  rows without a schema_version column (up to the layered core)
#   2  adds schema_version; no other column changes
#   3  adds the health audit (warnings, jacobian_sv_ratio_*, dof_*, rotation_defect_max,
#      formalism_notes, reference_accuracy); older rows were never audited: their
#      warnings say so instead of reading as "nothing wrong"
#   4  adds scd_mixed (the IVP test set's mixed measure); older rows never measured it: NaN
#   5  adds n_samples (checked against the series on resume) and producer_problem,
#      producer_formalism, producer_integrator (workbench.runs.producer); older rows'
#      producer is "unknown": reported on resume, not stale
#   6  adds err_l2 (the error over the whole trajectory beside err_max and err_end),
#      fixed_step_s, log (the run's captured output) and threads (BLAS/OpenMP threads);
#      older rows did not record them: NaN and no log
#   7  adds the repeated timing of the integration (workbench.runs.timing): integrate_s is
#      the median of the samples, integrate_s_min, integrate_s_max, integrate_cpu_s,
#      repeats, and the machine's load_avg and the sweep's workers; older rows timed one
#      sample: its wall time stays integrate_s, the new columns are NaN (not measured)
#   8  adds integrate_cpu_s_min and integrate_cpu_s_max (the interval of the CPU-time
#      samples, within which pairs tie) and counts the repeat budget in CPU time; older
#      rows did not keep them: NaN (a reader falls back to integrate_cpu_s alone)
#   9  adds the contact metrics (workbench.runs.contact_metrics): penetration_max,
#      complementarity_max, n_events, event_time_err_max, energy_balance_err; older rows
#      had no contacts: NaN
SCHEMA_VERSION = 9


def _migrate_1_to_2(row: dict[str, Any]) -> dict[str, Any]:
    return row | {"schema_version": 2}


def _migrate_2_to_3(row: dict[str, Any]) -> dict[str, Any]:
    not_audited = "not audited (written before schema 3): re-run to audit"
    return row | {"schema_version": 3, "warnings": not_audited}


def _migrate_3_to_4(row: dict[str, Any]) -> dict[str, Any]:
    return row | {"schema_version": 4, "scd_mixed": math.nan}


def _migrate_4_to_5(row: dict[str, Any]) -> dict[str, Any]:
    unknown = dict.fromkeys(PRODUCER_COLUMNS, UNKNOWN_PRODUCER)
    return row | {"schema_version": 5} | unknown


def _migrate_5_to_6(row: dict[str, Any]) -> dict[str, Any]:
    unrecorded = {"err_l2": math.nan, "fixed_step_s": math.nan, "log": "", "threads": math.nan}
    return row | {"schema_version": 6} | unrecorded


def _migrate_6_to_7(row: dict[str, Any]) -> dict[str, Any]:
    columns = ("integrate_s_min", "integrate_s_max", "integrate_cpu_s", "repeats", "load_avg")
    return row | {"schema_version": 7, "workers": math.nan} | dict.fromkeys(columns, math.nan)


def _migrate_7_to_8(row: dict[str, Any]) -> dict[str, Any]:
    unrecorded = dict.fromkeys(
        ("integrate_cpu_s_min", "integrate_cpu_s_max", "branch_left_at", "branch_distance_max"),
        math.nan,
    )  # CPU-time samples' interval and the branch audit: neither existed before schema 8
    return row | {"schema_version": 8} | unrecorded


def _migrate_8_to_9(row: dict[str, Any]) -> dict[str, Any]:
    columns = ("penetration_max", "complementarity_max", "n_events", "event_time_err_max",
               "energy_balance_err")  # fmt: skip
    return row | {"schema_version": 9} | dict.fromkeys(columns, math.nan)


# version -> the function that turns a row of that version into one of the next
MIGRATIONS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {
    1: _migrate_1_to_2,
    2: _migrate_2_to_3,
    3: _migrate_3_to_4,
    4: _migrate_4_to_5,
    5: _migrate_5_to_6,
    6: _migrate_6_to_7,
    7: _migrate_7_to_8,
    8: _migrate_8_to_9,
}


def row_schema_version(row: dict[str, Any], source: str | os.PathLike[str]) -> int:
    """The schema version of ``row`` (1 when it has none); ConfigError naming ``source``
    if the value is not a positive whole number."""
    value = row.get("schema_version")
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return 1
    whole = isinstance(value, numbers.Real) and not isinstance(value, bool)  # NumPy's too
    if whole and math.isfinite(value) and value == int(value) and value >= 1:
        return int(value)
    raise ConfigError(
        f"{source}: schema_version {value!r} is not a schema version (a whole number >= 1); "
        "the file is not a result row of mbs-workbench, or was edited by hand"
    )


def _refuse_newer(newer: list[tuple[str, int]]) -> None:
    """ConfigError naming the first of the (file, version) rows of a newer schema."""
    if newer:
        (source, version), others = newer[0], len(newer) - 1
        also = f" (and {others} other row file(s) of a newer schema)" if others else ""
        raise ConfigError(
            f"{source}{also}: result row of schema version {version}, newer than this "
            f"workbench reads (up to {SCHEMA_VERSION}); upgrade the workbench "
            "(pip install --upgrade mbs-workbench) to read it"
        )


def migrate_row(row: dict[str, Any], source: str | os.PathLike[str]) -> dict[str, Any]:
    """``row`` in the current schema (:data:`SCHEMA_VERSION`), migrated step by step
    from its own; ConfigError naming ``source`` if it is of a newer schema."""
    version = row_schema_version(row, source)
    _refuse_newer([(str(source), version)] if version > SCHEMA_VERSION else [])
    while version < SCHEMA_VERSION:
        row = MIGRATIONS[version](row)
        version += 1
    return row | {"schema_version": version}  # an int (a Parquet column may hold 2.0)


# ---- atomic writes (workbench.files.atomic_write) ----------------------------------------


def write_json_atomic(
    data: dict[str, Any], path: Path, durable: bool = True, root: Path | None = None
) -> None:
    """``root``: the output folder ``path`` is in (no link followed below it)."""
    text = json.dumps(_jsonable(data), indent=1, allow_nan=True)
    write = lambda name: Path(name).write_text(text, encoding="utf-8")  # noqa: E731
    atomic_write(path, write, durable, root=root)


def write_parquet_atomic(frame: pd.DataFrame, path: Path, root: Path | None = None) -> None:
    atomic_write(path, lambda name: frame.to_parquet(name, index=False), root=root)


def _jsonable(value: Any) -> Any:
    """Plain JSON values (NumPy scalars to Python; inf and NaN kept, JSON5 style)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "item") and callable(value.item):
        return value.item()
    return value


def empty_series(run_id: str) -> pd.DataFrame:
    """A time series with no rows (skipped and failed-before-integration runs)."""
    return pd.DataFrame({c: pd.Series(dtype="float64") for c in SERIES_COLUMNS}).assign(
        run_id=pd.Series(dtype="object")
    )[SERIES_COLUMNS]


# ---- the store -----------------------------------------------------------------------


def row_path(out: Path, run_id: str) -> Path:
    return Path(out) / RUNS_DIR / f"{run_id}.json"


def series_path(out: Path, run_id: str) -> Path:
    return Path(out) / SERIES_DIR / f"{run_id}.parquet"


def write_run(
    out: Path, row: dict[str, Any], series: pd.DataFrame | None, states: bool = True
) -> None:
    """Persist one run: the series first, then the row (so a row implies its series).

    ``states``: keep the trajectory's state columns in the series (False: drift, energy
    and error only, as before trajectories were stored).

    The series is synced to disk before the row is renamed into place; the row itself is
    not: after a machine crash a row lost or left corrupt reads as not done
    (:func:`read_row`), so the run is simply run again (and two syncs a run made two
    workers wait on each other's journal commits).
    """
    run_id = row["run_id"]
    if series is not None:
        if not states:
            series = series[[c for c in series.columns if not c.startswith(STATE_PREFIX)]]
        write_parquet_atomic(series, series_path(out, run_id), root=Path(out))
    write_json_atomic(row, row_path(out, run_id), durable=False, root=Path(out))


def read_row(path: Path) -> dict[str, Any] | None:
    """One row file, or None if it is unreadable (truncated, corrupt, not an object)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(data.get("run_id"), str):
        return None
    return data


def remove_stale_temporaries(out: Path) -> list[Path]:
    """Delete temporary files left by writers killed mid-write (never read as results):
    only files named as :func:`workbench.files.atomic_write` names them, no link followed."""
    return remove_temporaries(out)


def check_rows(out: Path) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """(whole, bad): the rows of ``out`` that are whole, by run id (migrated to the
    current schema), and what is wrong with each of the others, by run id (the file's
    name): unreadable, not a row of the schema (:func:`~workbench.runs.row_check.row_defects`)
    or its series broken (:func:`~workbench.runs.row_check.series_defect`).

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
    _refuse_newer(newer)
    return whole, bad


def completed_run_ids(out: Path) -> set[str]:
    """Run ids whose row and series are whole (:func:`check_rows`): what a resumed sweep
    may skip."""
    return set(check_rows(out)[0])


def frame_from_rows(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """Rows as a DataFrame with the SCHEMA columns first (missing ones NaN)."""
    frame = pd.DataFrame(list(rows))
    for column in SCHEMA_COLUMNS:
        if column not in frame.columns:
            frame[column] = math.nan
    extra = [c for c in frame.columns if c not in SCHEMA_COLUMNS]
    frame = frame[SCHEMA_COLUMNS + extra]
    if len(frame):
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


def consolidate(out: Path) -> Path:
    """Write ``<out>/results.parquet`` (atomically) from the row files; return its path."""
    frame = load_results(out)
    path = Path(out) / RESULTS_FILE
    write_parquet_atomic(_parquet_safe(frame), path, root=Path(out))
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
    path = Path(path)
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
        row = read_row(row_file)
        version = 0 if row is None else row_schema_version(row, row_file)
        defects = ["unreadable"] if row is None else row_defects(row, SCHEMA_COLUMNS)
        if version > SCHEMA_VERSION:
            newer.append((str(row_file), version))
        elif defects:
            unreadable.append(f"{row_file} ({'; '.join(defects)})")
        else:
            if version < SCHEMA_VERSION:
                migrated.append(str(row_file))
            rows.append(migrate_row(row, row_file))
    _refuse_newer(newer)
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
    be read is left out with a warning naming it (a resumed sweep redoes its run)."""
    directory = Path(path) / SERIES_DIR
    if run_id is not None:
        file = directory / f"{run_id}.parquet"
        if not file.is_file():
            raise ConfigError(f"no time series for run {run_id!r} in {path}")
        try:
            frame = pd.read_parquet(file)
        except Exception as error:  # noqa: BLE001 - pyarrow raises several kinds
            raise ConfigError(
                f"time series {file} is unreadable ({one_line(error)}); "
                "re-run the sweep to redo its run"
            ) from None
        return frame if states else _without_states(frame)
    frames, unreadable = [], []
    for file in sorted(directory.glob("*.parquet")):
        try:
            frames.append(_without_states(pd.read_parquet(file)))
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


__all__ = [
    "ENVIRONMENT_FILE",
    "MIGRATIONS",
    "PRODUCER_COLUMNS",
    "SCHEMA",
    "SCHEMA_COLUMNS",
    "SCHEMA_VERSION",
    "STATE_PREFIX",
    "check_rows",
    "completed_run_ids",
    "consolidate",
    "frame_from_rows",
    "load_results",
    "load_series",
    "load_trajectory",
    "migrate_row",
    "read_row",
    "row_path",
    "series_path",
    "write_json_atomic",
    "write_parquet_atomic",
    "write_run",
    "write_text_atomic",
]


def write_text_atomic(text: str, path: Path, root: Path | None = None) -> None:
    def write(name: str) -> None:
        with open(name, "w", encoding="utf-8") as out:
            out.write(text)

    atomic_write(path, write, root=root)


def write_plan(out: str | os.PathLike[str], run_ids: Iterable[str], source: str) -> None:
    """Record the run ids a sweep planned in ``out`` (its source: a file or a suite)."""
    ids = list(dict.fromkeys(str(run_id) for run_id in run_ids))
    plan = {"source": source, "runs": len(ids), "run_ids": ids}
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
