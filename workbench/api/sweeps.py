"""``workbench.sweep``: a sweep from a specification or keyword arguments, its results frame.

Worker processes find a plugin by importing its module. A plugin class defined in the
running kernel (``__main__``, a notebook cell) or in a module that cannot be imported by
name has no module to import: a sweep with one runs in this process instead, one run after
another and without the time limit (chosen automatically; ``in_process`` forces either).
"""

from __future__ import annotations

import importlib.util
import os
import sys
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

from workbench import files
from workbench.api.runs import REGISTERED_HERE, plugin_name, results_directory
from workbench.errors import ConfigError
from workbench.execution.environment import sweep_environment
from workbench.execution.execute import execute_run
from workbench.execution.timing import Timing
from workbench.files import sync_file_system
from workbench.outputs.report.close_calls import close_calls
from workbench.plugin import registry
from workbench.runs import store
from workbench.runs.dask_pool import check_scheduler_address
from workbench.runs.out_lock import out_lock
from workbench.runs.resume import plan_resume
from workbench.runs.retime import retime_close_calls
from workbench.runs.sweep import run_sweep
from workbench.runs.sweep_spec import SUITE_NAME, SweepSpec, parse_spec, suite_text

KINDS = {"problems": "problem", "formalisms": "formalism", "integrators": "integrator"}


def sweep(
    spec: str | os.PathLike[str] | dict[str, Any] | None = None,
    *,
    out: str | os.PathLike[str] | None = None,
    progress: Callable[[int, int], Any] | Any = None,
    in_process: bool | None = None,
    fresh: bool = False,
    wait: bool = False,
    scheduler: str | None = None,
    **keys: Any,
) -> pd.DataFrame:
    """Run a sweep and return its runs' rows (the frame ``workbench.load_results`` gives).

    ``spec``: a sweep specification file, a suite name (``"iftomm"``), a dict of its keys,
    or None; ``keys`` add or replace keys (``problems=[...]``, ``formalisms=[...]``,
    ``integrators=[...]``, ``tolerances=[...]``, ``jobs=2``, ``store_trajectories=False``;
    see the sweep specification's keys). In the three lists a plugin class may stand for
    its name (registered if it is not). ``out``: the results directory (default the
    specification's ``out``, ``reports/latest`` under the current folder without one); runs
    already there are not redone unless ``fresh``, and are returned with the new ones; rows
    of other sweeps in the same ``out`` are not returned (``load_results(out)`` gives all).
    ``progress``: called as ``progress(done, total)`` after each run, or a tqdm-like bar
    (an object with ``update``: its ``total`` is set and it advances one a run).
    ``in_process``: run here instead of in worker processes (default: only when a
    plugin cannot be imported by a worker, e.g. a class defined in a notebook).
    ``scheduler``: a Dask scheduler's address (``tcp://host:port``): the runs go to its
    cluster, as with ``workbench sweep --scheduler`` (the user guide's Dask section);
    ConfigError for an address Dask cannot read or a plugin a worker cannot import.

    It writes the results store (rows, series, trajectories), not the HTML report or the
    Rerun recording that ``workbench sweep`` adds: ``workbench report OUT`` makes the
    report from it, :func:`record` the recording. Bad input (a spec, key, ``out`` or
    ``progress`` of the wrong kind) raises ``ConfigError`` before any run. Like
    ``workbench sweep`` it holds ``out``'s lock (:mod:`workbench.runs.out_lock`):
    ``OutputBusyError`` if another process writes there, unless ``wait`` (then it waits
    for it).
    """
    if progress is not None and not (callable(progress) or hasattr(progress, "update")):
        raise ConfigError(
            f"progress: expected a function progress(done, total) or a tqdm-like bar, "
            f"not {progress!r}"
        )
    if scheduler is not None:  # named as given here, not as the CLI's --scheduler
        check_scheduler_address(scheduler, "scheduler=")  # before out is made
    data = _spec_data(spec)
    for key, value in keys.items():
        data[key] = value
    for key, kind in KINDS.items():
        if key in data:
            data[key] = _named(kind, data[key])
    if out is not None:
        data["out"] = str(results_directory(out))
    is_file = isinstance(spec, str | os.PathLike) and Path(spec).is_file()
    source = str(spec) if is_file else "workbench.sweep"  # robot files are found beside it
    # (no line numbers: the text parsed is made here from the file and the keywords)
    parsed = parse_spec(
        toml_text(data), source, Path(spec).parent if is_file else None, lines=False
    )
    results_directory(parsed.out, make=True)  # ConfigError for a file or a folder not made
    local = local_plugins(parsed)
    here = bool(local) if in_process is None else in_process
    if scheduler is not None and (here or local):
        raise ConfigError(
            "scheduler: the runs cannot go to a Dask cluster "
            + (f"with plugins its workers cannot import ({', '.join(local)}): define them in "
               "a module file named in the specification's plugins" if local else
               "and run in this process (in_process=True): leave one of them out")
        )  # fmt: skip
    callback = _progress(progress)
    rows = None
    if here:
        with out_lock(parsed.out, wait=wait, command="workbench.sweep (Python)"):
            run_here(parsed, callback, fresh)
    else:
        summary = run_sweep(parsed, show_progress=False, fresh=fresh, progress=callback,
                            say=lambda line: None, wait=wait, close_calls=close_calls,
                            scheduler=scheduler)  # fmt: skip
        rows = summary.rows  # what the consolidation read: not read again
    if rows is None:
        rows = store.load_results(parsed.out)
    return this_sweeps_rows(rows, parsed)


def this_sweeps_rows(rows: pd.DataFrame, sweep: SweepSpec) -> pd.DataFrame:
    """The rows of ``sweep``'s runs, in the order of the folder's table: an ``out`` may hold
    other sweeps' runs, which a notebook's plot of this sweep must not mix in."""
    if rows.empty or "run_id" not in rows:
        return rows
    ours = {spec.run_id for spec in sweep.runs}
    return rows[rows["run_id"].isin(ours)].reset_index(drop=True)


def record(
    out: str | os.PathLike[str],
    where: str | list[str] = (),
    *,
    jobs: int = 2,
    wait: bool = False,
    allow_roots: list[str | os.PathLike[str]] = (),
) -> Path:
    """Record done runs of the sweep in ``out`` into ``out/recording.rrd`` (as
    ``workbench record``), which :func:`sweep` writes none of: the runs meeting ``where``
    (conditions ``COLUMN OP VALUE`` as ``workbench results --where`` takes them, e.g.
    ``"rtol<1e-6"``; all runs without it) whose status is ok and whose row is not
    stale are run again in ``jobs`` worker processes, their rows kept; a run whose robot
    file is outside ``out`` only when its folder is in ``allow_roots`` (a results folder is
    data: it may not make the workbench read other files). Returns the
    recording's path (open it with ``rerun`` or ``workbench view``). ConfigError when no
    run could be recorded (naming why) or for bad input.
    """
    from workbench.outputs.recording import SweepRecorder
    from workbench.outputs.results_table import rows_where
    from workbench.runs.record import record_runs

    conditions = [where] if isinstance(where, str) else where
    if not isinstance(conditions, list | tuple) or not all(
        isinstance(condition, str) for condition in conditions
    ):
        raise ConfigError(f"where: expected conditions such as 'scd>=6', not {where!r}")
    if not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1:
        raise ConfigError(f"jobs: expected a number of worker processes >= 1, not {jobs!r}")
    directory = results_directory(out)
    if not directory.is_dir():
        raise ConfigError(f"out: no output directory {directory}: give a sweep's out")

    def choose(frame: pd.DataFrame) -> pd.DataFrame:
        kept = rows_where(frame, conditions)
        if kept.empty:
            raise ConfigError(f"no run of the {len(frame)} in {directory} meets {conditions}")
        return kept

    summary = record_runs(
        directory, SweepRecorder, choose, jobs, [],
        show_progress=False, wait=wait, say=lambda line: None, allow_roots=list(allow_roots),
    )  # fmt: skip
    if summary.recording is None or not summary.recorded:
        why = "; ".join(f"{count} {reason}" for reason, count in summary.left_out.items())
        failed = f"{len(summary.failed)} failed when run again" if summary.failed else ""
        raise ConfigError(
            f"no run of {directory} recorded ({'; '.join(filter(None, [why, failed]))})"
        )
    return summary.recording


def _spec_data(spec: Any) -> dict[str, Any]:
    if spec is None:
        return {}
    if isinstance(spec, dict):
        return dict(spec)
    if not isinstance(spec, str | os.PathLike):
        raise ConfigError(
            f"sweep: expected a suite name, the path of a TOML specification or a dict of its "
            f"keys, not {type(spec).__name__} {spec!r} (lists of problems, formalisms... go "
            "in keys: sweep(problems=[...], ...))"
        )
    if isinstance(spec, str) and SUITE_NAME.fullmatch(spec) and not Path(spec).exists():
        return tomllib.loads(suite_text(spec))
    try:
        return tomllib.loads(Path(spec).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ConfigError(f"cannot read the sweep specification {spec}: {error}") from None


def _named(kind: str, entries: Any) -> Any:
    """A list of names, tables and classes with each class replaced by its name."""
    if not isinstance(entries, list):
        return plugin_name(kind, entries) if isinstance(entries, type) else entries
    named = []
    for entry in entries:
        if isinstance(entry, type):
            entry = plugin_name(kind, entry)
        elif isinstance(entry, dict) and isinstance(entry.get("name"), type):
            entry = entry | {"name": plugin_name(kind, entry["name"])}
        named.append(entry)
    return named


def local_plugins(sweep: SweepSpec) -> list[str]:
    """Names of the sweep's plugins a worker process would not find: defined in
    ``__main__`` or in a module not found by name, or registered by the API rather than
    by importing their module."""
    found = []
    for run in sweep.runs:
        for kind, name in (("problem", run.problem), ("formalism", run.formalism),
                           ("integrator", run.integrator)):  # fmt: skip
            module = registry.REGISTRY.get(kind, name).__module__  # a robot file's name too
            here = (kind, name) in REGISTERED_HERE
            if name not in found and (here or not _importable(module)):
                found.append(name)
    return found


def _importable(module: str) -> bool:
    if module == "__main__":
        return False
    loaded = sys.modules.get(module)
    if loaded is not None and getattr(loaded, "__spec__", None) is None:
        return False  # an exec'd or hand-made module: no file a worker could import
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def run_here(sweep: SweepSpec, progress: Callable[[int, int], Any] | None, fresh: bool) -> None:
    """The sweep's runs not yet done, one after another in this process, stored as a pool
    stores them (the time limit is not enforced: nothing can stop a run in this process)."""
    out = Path(sweep.out)
    store.remove_stale_temporaries(out)
    todo = plan_resume(sweep.runs, out, frozenset(), fresh).todo
    (out / store.RUNS_DIR).mkdir(parents=True, exist_ok=True)
    (out / "references").mkdir(exist_ok=True)
    files.write_json_atomic(sweep_environment(), out / store.ENVIRONMENT_FILE)
    files.write_text_atomic(sweep.text, out / "sweep.toml")
    timing = Timing(sweep.repeats, sweep.repeat_budget)
    for done, spec in enumerate(todo, 1):
        result = execute_run(spec, reference_dir=out / "references", timing=timing)
        result.row["log"] = ""
        store.write_run(out, result.row, result.stored_series, sweep.store_trajectories)
        if progress is not None:
            progress(done, len(todo))
    if sweep.retime:  # (in this process too: a class of this session cannot be forked)
        retime_close_calls(out, sweep.runs, close_calls, sweep.retime, sweep.repeat_budget,
                           sweep.time_limit, sweep.plugins, lambda line: None)  # fmt: skip
    sync_file_system(out)  # the rows and series, written without a sync each
    store.consolidate(out)


def _progress(progress: Any) -> Callable[[int, int], Any] | None:
    """``progress`` as a callback ``(done, total)``: a tqdm-like bar is advanced."""
    if progress is None or not hasattr(progress, "update"):
        return progress

    def advance(done: int, total: int) -> None:
        progress.total = total
        progress.update(done - progress.n if hasattr(progress, "n") else 1)

    return advance


# ---- a sweep specification as TOML text --------------------------------------------------


def toml_text(data: dict[str, Any]) -> str:
    """``data`` (strings, numbers, booleans, lists and tables) as TOML text."""
    return "".join(f"{key} = {_toml_value(value, key)}\n" for key, value in data.items())


def _toml_value(value: Any, key: str) -> str:
    if type(value).__module__ == "numpy" and hasattr(value, "tolist"):
        value = value.tolist()  # an array (np.logspace) or a NumPy scalar: Python's own
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str | os.PathLike):
        return '"' + str(value).replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v, key) for v in value) + "]"
    if isinstance(value, dict):
        items = ", ".join(f"{k} = {_toml_value(v, key)}" for k, v in value.items())
        return "{ " + items + " }"
    raise ConfigError(f"sweep key {key}: {value!r} is not a TOML value (text, number, list, table)")
