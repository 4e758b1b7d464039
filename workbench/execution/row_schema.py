"""The result row a run produces: its columns, its series' columns, and its version.

:data:`SCHEMA` lists a row's columns with their meaning (the stable order of
:func:`workbench.runs.store.load_results`), :data:`SERIES_COLUMNS` those of the run's time
series, beside which its trajectory is kept as ``state:<name>`` columns
(:data:`STATE_PREFIX`). A row carries the version of this schema (``schema_version``; a
row without one is version 1, written before versions existed). A row of an older
schema becomes one of this version through :data:`MIGRATIONS` (:func:`migrate_row`), so old
output directories stay readable; one of a newer schema is refused (:class:`ConfigError`:
upgrade the workbench).

What a run produces belongs to the one-run layer; how rows are kept on disk is the
store's (:mod:`workbench.runs.store`).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Callable
from typing import Any

import pandas as pd

from workbench.errors import ConfigError

ENERGY_ERROR = (
    "|E - E0| / S with E = T + V and S = max(T0 + |V0|, max over t of T), the energy in "
    "the motion (not |E0|, which is 0 when a body starts at rest at the zero of V)"
)
"""The energy error's definition (:mod:`workbench.execution.metrics` computes it), said
where the columns and series are described."""

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
    ("compile_s", "wall time to generate, compile and load C (compile=jit or auto; else 0)"),
    ("init_s", "wall time of the consistent initial state"),
    ("integrate_s", "wall time of the integration: the median of its timed samples (repeats)"),
    ("metrics_s", "wall time of the metrics (without computing the reference)"),
    ("reference_s", "wall time to obtain the reference (0 when cached)"),
    ("equations_cached", "the equations were reused from the worker's cache"),
    ("n_rhs", "right-hand-side / residual evaluations"),
    ("n_jac", "Jacobian evaluations"),
    ("n_steps", "accepted steps"),
    ("n_rejected", "rejected steps (-1: not reported)"),
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
    ("energy_err_max", f"max over output times of {ENERGY_ERROR} (NaN: not conservative)"),
    ("energy_err_final", "energy error at the end time, as energy_err_max"),
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
    ("fixed_step_s", "the longest step a fixed-step method took (s); NaN for an adaptive one"),
    ("integrate_s_min", "least wall time of the integration's timed samples (s)"),
    ("integrate_s_max", "greatest wall time of the integration's timed samples (s)"),
    ("integrate_cpu_s", "CPU time of the integration: the median of its timed samples (s)"),
    ("repeats", "timed samples of the integration (workbench.execution.timing; NaN: not timed)"),
    ("load_avg", "1-minute load average of the machine when the run started"),
    ("workers", "worker processes of the sweep running runs at the same time"),
    ("integrate_cpu_s_min", "least CPU time of the integration's timed samples (s)"),
    ("integrate_cpu_s_max", "greatest CPU time of the integration's timed samples (s)"),
    ("work_s", "counted work: the counts of evaluations weighted by their unit CPU costs (s)"),
    ("work_s_min", "counted work with each unit cost's least timed batch (s; = work_s)"),
    ("work_s_max", "counted work with each unit cost's greatest timed batch (s)"),
    ("penetration_max", "deepest contact penetration (m; NaN: no contacts)"),
    ("complementarity_max", "worst relative residual of the contact problems solved"),
    ("n_events", "impacts and stick/slip switches the contact integrator reported"),
    ("event_time_err_max", "largest distance of a reference contact event to the run's (s)"),
    ("energy_balance_err", "energy lost against the restitution and friction laws, relative"),
    (
        "retimed",
        "samples of the integration timed again after the runs, at moments apart "
        "(workbench.runs.retime; 0: none)",
    ),
]
SCHEMA_COLUMNS = [name for name, _ in SCHEMA]
SERIES_COLUMNS = ["run_id", "t", "drift_pos", "drift_vel", "drift_nh", "energy_err", "ref_err"]
# a series column holding a state of the trajectory: STATE_PREFIX + the equations' name
STATE_PREFIX = "state:"
PRODUCER_COLUMNS = ["producer_problem", "producer_formalism", "producer_integrator"]
UNKNOWN_PRODUCER = "unknown"


# ---- schema versions ---------------------------------------------------------------------

# History of the row schema:
#   1  rows without a schema_version column (up to the layered core)
#   2  adds schema_version; no other column changes
#   3  adds the health audit (warnings, jacobian_sv_ratio_*, dof_*, rotation_defect_max,
#      formalism_notes, reference_accuracy); older rows were never audited: their
#      warnings say so instead of reading as "nothing wrong"
#   4  adds scd_mixed (the IVP test set's mixed measure); older rows never measured it: NaN
#   5  adds n_samples (checked against the series on resume) and producer_problem,
#      producer_formalism, producer_integrator (workbench.execution.producer); older rows'
#      producer is "unknown": reported on resume, not stale
#   6  adds err_l2 (the error over the whole trajectory beside err_max and err_end),
#      fixed_step_s, log (the run's captured output) and threads (BLAS/OpenMP threads);
#      older rows did not record them: NaN and no log
#   7  adds the repeated timing of the integration (workbench.execution.timing): integrate_s is
#      the median of the samples, integrate_s_min, integrate_s_max, integrate_cpu_s,
#      repeats, and the machine's load_avg and the sweep's workers; older rows timed one
#      sample: its wall time stays integrate_s, the new columns are NaN (not measured)
#   8  adds integrate_cpu_s_min and integrate_cpu_s_max (the interval of the CPU-time
#      samples, within which pairs tie) and counts the repeat budget in CPU time; older
#      rows did not keep them: NaN (a reader falls back to integrate_cpu_s alone)
#   9  adds work_s, work_s_min, work_s_max (workbench.execution.counted_work) and the
#      contact metrics (workbench.execution.contact_metrics): penetration_max,
#      complementarity_max, n_events, event_time_err_max, energy_balance_err; older rows
#      did not time unit costs and had no contacts: NaN
#  10  adds retimed (the close calls' samples timed again at moments apart, after the
#      runs: workbench.runs.retime); older rows were not: 0
SCHEMA_VERSION = 10


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
    unrecorded = dict.fromkeys(
        ("work_s", "work_s_min", "work_s_max", "penetration_max", "complementarity_max",
         "n_events", "event_time_err_max", "energy_balance_err"),
        math.nan,
    )  # fmt: skip
    return row | {"schema_version": 9} | unrecorded


def _migrate_9_to_10(row: dict[str, Any]) -> dict[str, Any]:
    return row | {"schema_version": 10, "retimed": 0}


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
    9: _migrate_9_to_10,
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


def refuse_newer(newer: list[tuple[str, int]]) -> None:
    """ConfigError naming the first of the (file, version) rows of a newer schema
    (nothing if ``newer`` is empty)."""
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
    refuse_newer([(str(source), version)] if version > SCHEMA_VERSION else [])
    while version < SCHEMA_VERSION:
        row = MIGRATIONS[version](row)
        version += 1
    return row | {"schema_version": version}  # an int (a Parquet column may hold 2.0)


def empty_series(run_id: str) -> pd.DataFrame:
    """A time series with no rows (skipped and failed-before-integration runs); a copy of
    one made once (making it took 1.6 ms, a run's start)."""
    return _EMPTY_SERIES.copy()


_EMPTY_SERIES = pd.DataFrame({c: pd.Series(dtype="float64") for c in SERIES_COLUMNS}).assign(
    run_id=pd.Series(dtype="object")
)[SERIES_COLUMNS]


__all__ = [
    "MIGRATIONS",
    "PRODUCER_COLUMNS",
    "SCHEMA",
    "SCHEMA_COLUMNS",
    "SCHEMA_VERSION",
    "SERIES_COLUMNS",
    "STATE_PREFIX",
    "UNKNOWN_PRODUCER",
    "empty_series",
    "migrate_row",
    "refuse_newer",
    "row_schema_version",
]
