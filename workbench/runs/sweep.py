"""Sweeps: problems x formalisms (option grids) x integrators (option grids) x tolerances.

A sweep specification is a TOML file (the default: ``workbench/runs/default_sweep.toml``)::

    out = "reports/latest"         # output directory (``--out`` overrides)
    jobs = 2                       # local worker processes (``--jobs`` overrides)
    time_limit = 120.0             # seconds per run; a run over it is killed (``--time-limit``)
    tolerances = [1e-4, 1e-6, 1e-8]  # rtol values
    atol_factor = 1e-3             # atol = rtol * atol_factor
    missing_plugins = "error"      # or "skip": leave out plugin names that are not registered
    plugins = ["my_package.my_plugins"]  # extra plugin modules, imported in every worker

    problems = ["my-problem", { name = "my-top", options = { spin = [50.0, 100.0] } }]
    formalisms = ["all", { name = "my-formalism", options = { index = [1, 3] } }]
    integrators = ["my-implicit", { name = "my-fixed-step", options = { step = 1e-3 } }]

Each of ``problems``, ``formalisms``, ``integrators`` is a list of names, of tables
``{name, options}``, or ``"all"`` (every registered, working plugin of that kind with its
default options, except the ones named explicitly in the same list). A table
``{ name = "all", options = {...} }`` is "all" with options given to every plugin that has
them (the others keep their defaults), e.g. ``{ name = "all", options = { index = 1 } }``
for every formalism with a DAE index; an option that no registered plugin has is an error.
New plugins so join a sweep without editing it. In an options table a
list is a grid: the runs take the cartesian product of all listed values (to pass a list
as one value, wrap it in another list). The runs are every problem x formalism x
integrator x tolerance; pairs that cannot work are recorded as ``skipped`` with the reason.

``plugins`` is a feature for plugin authors: modules (importable from the current
directory or the Python path) whose registration decorators add plugins for this sweep
only, without packaging them with entry points.

Everything is validated before anything is written (:func:`load_spec`): unknown keys,
wrong types, unknown plugins (with close matches), unknown or ill-typed options, tolerances
that are not positive, empty grids and TOML syntax errors (with the line) raise one
:class:`~workbench.errors.ConfigError` naming the key.

Execution (:func:`run_sweep`): run ids whose row exists in ``<out>/runs`` are skipped
(resume). Runs go to a small pool of worker processes of our own (concurrent.futures
cannot kill a running task): each worker builds and caches equations, runs, and writes the
run's files itself; the parent enforces each run's time limit by killing the worker (row
``timeout``) and starting a fresh one, and a worker that dies mid-run (segfault, SIGKILL)
gives a ``failed`` row "worker process died (exit code ...)". With a Dask scheduler
address, runs are submitted through ``distributed.Client(address).get_executor()``; each
task runs its run in a child process (``python -m workbench.runs.sweep --run-one``) under the
time limit and returns the row and series to the client, which writes them. At the end
the rows are consolidated into ``<out>/results.parquet``.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import itertools
import json
import math
import multiprocessing
import multiprocessing.connection
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from collections import Counter, deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from workbench.errors import ConfigError, PluginError, WorkbenchError
from workbench.plugin import registry
from workbench.plugin.registry import Kind
from workbench.runs import store
from workbench.runs.execute import RunSpec, equations_key, execute_run, status_row

DEFAULT_OUT = "reports/latest"
DEFAULT_TIME_LIMIT = 120.0  # s
DEFAULT_ATOL_FACTOR = 1e-3
DEFAULT_JOBS = 2
TOP_LEVEL_KEYS = {
    "out": "output directory (string)",
    "jobs": "number of local worker processes (integer >= 1)",
    "time_limit": "seconds per run (number > 0)",
    "tolerances": "list of rtol values (numbers > 0)",
    "atol_factor": "atol = rtol * atol_factor (number > 0)",
    "missing_plugins": '"error" or "skip"',
    "plugins": "list of plugin module names to import",
    "problems": 'list of problem names or {name, options} tables, or "all"',
    "formalisms": 'list of formalism names or {name, options} tables, or "all"',
    "integrators": 'list of integrator names or {name, options} tables, or "all"',
}
REQUIRED_KEYS = ("problems", "formalisms", "integrators", "tolerances")


@dataclass
class SweepSpec:
    """A validated sweep: the runs (normalized, unique) and how to execute them."""

    runs: list[RunSpec]
    out: Path
    jobs: int = DEFAULT_JOBS
    time_limit: float = DEFAULT_TIME_LIMIT
    plugins: list[str] = field(default_factory=list)
    source: str = ""
    text: str = ""


# ---- loading and validation ---------------------------------------------------------


def default_spec_text() -> str:
    return resources.files("workbench.runs").joinpath("default_sweep.toml").read_text("utf-8")


def load_spec(path: str | os.PathLike[str] | None = None) -> SweepSpec:
    """Read and validate a sweep specification (None: the default one); nothing is written."""
    if path is None:
        return parse_spec(default_spec_text(), "default sweep (workbench/runs/default_sweep.toml)")
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ConfigError(f"cannot read the sweep specification {path}: {error}") from None
    return parse_spec(text, str(path))


def import_plugin_modules(modules: Iterable[str], source: str = "plugins") -> None:
    for index, name in enumerate(modules):
        try:
            importlib.import_module(name)
        except Exception as error:  # noqa: BLE001 - any import failure is a config error
            raise ConfigError(
                f"{source}[{index}]: cannot import plugin module {name!r}: "
                f"{type(error).__name__}: {error}"
            ) from None


def parse_spec(text: str, source: str = "sweep specification") -> SweepSpec:
    """Validate TOML ``text`` and expand it to RunSpecs (ConfigError names the key)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{source}: invalid TOML: {error}") from None

    def fail(key: str, message: str) -> ConfigError:
        line = _key_line(text, key)
        where = f"line {line}: " if line else ""
        return ConfigError(f"{source}: {where}{key}: {message}")

    unknown = sorted(set(data) - set(TOP_LEVEL_KEYS))
    if unknown:
        close = registry.close_matches(unknown[0], list(TOP_LEVEL_KEYS))
        hint = (
            f"did you mean {', '.join(close)}?"
            if close
            else (f"valid keys: {', '.join(TOP_LEVEL_KEYS)}")
        )
        raise fail(unknown[0], f"unknown key; {hint}")
    for key in REQUIRED_KEYS:
        if key not in data:
            raise fail(key, f"missing ({TOP_LEVEL_KEYS[key]})")

    out = data.get("out", DEFAULT_OUT)
    if not isinstance(out, str) or not out.strip():
        raise fail("out", f"must be a non-empty string, not {out!r}")
    jobs = data.get("jobs", DEFAULT_JOBS)
    if not _is_int(jobs) or jobs < 1:
        raise fail("jobs", f"must be an integer >= 1, not {jobs!r}")
    time_limit = _positive(data.get("time_limit", DEFAULT_TIME_LIMIT), "time_limit", fail)
    atol_factor = _positive(data.get("atol_factor", DEFAULT_ATOL_FACTOR), "atol_factor", fail)
    missing = data.get("missing_plugins", "error")
    if missing not in ("error", "skip"):
        raise fail("missing_plugins", f'must be "error" or "skip", not {missing!r}')
    tolerances = data["tolerances"]
    if not isinstance(tolerances, list) or not tolerances:
        raise fail("tolerances", f"must be a non-empty list of numbers > 0, not {tolerances!r}")
    rtols = [_positive(t, f"tolerances[{i}]", fail) for i, t in enumerate(tolerances)]
    if any(r >= 1 for r in rtols):
        raise fail("tolerances", f"relative tolerances must be < 1, got {rtols}")
    plugins = data.get("plugins", [])
    if not isinstance(plugins, list) or not all(isinstance(p, str) and p for p in plugins):
        raise fail("plugins", f"must be a list of module names, not {plugins!r}")
    import_plugin_modules(plugins, f"{source}: plugins")

    problems = _entries(data["problems"], "problem", "problems", missing, fail)
    formalisms = _entries(data["formalisms"], "formalism", "formalisms", missing, fail)
    integrators = _entries(data["integrators"], "integrator", "integrators", missing, fail)

    runs: list[RunSpec] = []
    seen: set[str] = set()
    for (p_name, p_opts, _), (f_name, f_opts, _), (i_name, i_opts, _), rtol in itertools.product(
        problems, formalisms, integrators, rtols
    ):
        spec = RunSpec(p_name, f_name, i_name, rtol, rtol * atol_factor, p_opts, f_opts, i_opts)
        if spec.run_id not in seen:
            seen.add(spec.run_id)
            runs.append(spec)
    if not runs:
        raise ConfigError(f"{source}: the sweep has no runs")
    return SweepSpec(runs, Path(out), int(jobs), time_limit, list(plugins), source, text)


def _key_line(text: str, key: str) -> int | None:
    """The line (1-based) where the top-level ``key`` of a dotted/indexed key is set."""
    top = re.split(r"[.\[]", key, maxsplit=1)[0]
    pattern = re.compile(rf"^\s*(?:{re.escape(top)}|\[\[?\s*{re.escape(top)}\s*\]\]?)\s*(?:=|$)")
    for number, line in enumerate(text.splitlines(), start=1):
        if pattern.match(line):
            return number
    return None


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _positive(value: Any, key: str, fail: Callable[[str, str], ConfigError]) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise fail(key, f"must be a number > 0, not {value!r}")
    if not math.isfinite(value) or value <= 0:
        raise fail(key, f"must be a finite number > 0, not {value!r}")
    return float(value)


def _entries(
    value: Any, kind: Kind, key: str, missing: str, fail: Callable[[str, str], ConfigError]
) -> list[tuple[str, dict[str, Any], str]]:
    """(name, normalized options, key) of every plugin x option combination of a list."""
    if value == "all":
        value = ["all"]
    if not isinstance(value, list) or not value:
        raise fail(
            key,
            f'must be a non-empty list of names or {{name, options}} tables, or "all"'
            f", not {value!r}",
        )
    named: list[tuple[str, Any, str]] = []
    wants_all, all_options, all_key = False, {}, f"{key}[all]"
    for index, item in enumerate(value):
        item_key = f"{key}[{index}]"
        if item == "all":
            wants_all = True
        elif isinstance(item, dict) and item.get("name") == "all":
            wants_all, all_key = True, item_key
            all_options = item.get("options", {})
            extra = sorted(set(item) - {"name", "options"})
            if extra:
                raise fail(f"{item_key}.{extra[0]}", "unknown key; a table has name and options")
            if not isinstance(all_options, dict):
                raise fail(f"{item_key}.options", f"must be a table, not {all_options!r}")
        elif isinstance(item, str):
            named.append((item, {}, item_key))
        elif isinstance(item, dict):
            extra = sorted(set(item) - {"name", "options"})
            if extra:
                raise fail(f"{item_key}.{extra[0]}", "unknown key; a table has name and options")
            name = item.get("name")
            if not isinstance(name, str) or not name:
                raise fail(f"{item_key}.name", f"must be a plugin name (string), not {name!r}")
            options = item.get("options", {})
            if not isinstance(options, dict):
                raise fail(f"{item_key}.options", f"must be a table, not {options!r}")
            named.append((name, options, item_key))
        else:
            raise fail(item_key, f"must be a name or a {{name, options}} table, not {item!r}")
    explicit = {name for name, _, _ in named}
    if wants_all:
        declared: set[str] = set()
        for info in registry.list_plugins(kind):
            if info.plugin is not None:
                fields = _option_names(info.plugin)
                declared |= fields
                if info.name not in explicit:
                    mine = {k: v for k, v in all_options.items() if k in fields}
                    named.append((info.name, mine, all_key))
        unknown = sorted(set(all_options) - declared)
        if unknown:
            raise fail(f"{all_key}.options.{unknown[0]}", f"no registered {kind} has this option")
    entries = []
    for name, options, item_key in named:
        try:
            registry.REGISTRY.get(kind, name)
        except PluginError as error:
            if missing == "skip" and name not in registry.REGISTRY.entries[kind]:
                continue
            raise fail(item_key, str(error)) from None
        for combination in _grid(options, f"{item_key}.options", fail):
            entries.append(
                (name, _normalized_options(kind, name, combination, item_key, fail), item_key)
            )
    if not entries:
        raise fail(key, f"no registered {kind} left to run (empty grid)")
    return entries


def _option_names(plugin: Any) -> set[str]:
    from workbench.plugin.options import option_fields

    return {name for name, _, _ in option_fields(plugin.Options)}


def _grid(
    options: dict[str, Any], key: str, fail: Callable[[str, str], ConfigError]
) -> list[dict[str, Any]]:
    names, axes = [], []
    for name, value in options.items():
        values = value if isinstance(value, list) else [value]
        if not values:
            raise fail(f"{key}.{name}", "empty list of values (empty grid)")
        names.append(name)
        axes.append(values)
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*axes)]


def _normalized_options(
    kind: Kind,
    name: str,
    options: dict[str, Any],
    key: str,
    fail: Callable[[str, str], ConfigError],
) -> dict[str, Any]:
    from workbench.plugin.options import options_dict

    plugin = registry.REGISTRY.get(kind, name)
    try:
        if kind == "problem":
            parsed = plugin(options).options
        else:
            parsed = plugin.parse_options(options)
    except ConfigError as error:
        raise fail(f"{key}.options", str(error)) from None
    except Exception as error:  # noqa: BLE001 - a plugin's own checks may raise anything
        raise fail(f"{key}.options", f"{type(error).__name__}: {error}") from None
    return json.loads(json.dumps(options_dict(parsed), default=_jsonable_value))


def _jsonable_value(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


# ---- execution ----------------------------------------------------------------------


@dataclass
class SweepSummary:
    out: Path
    counts: Counter
    already_done: int
    seconds: float
    results: Path | None = None
    recording: Path | None = None

    @property
    def total(self) -> int:
        return sum(self.counts.values())


def run_sweep(
    sweep: SweepSpec,
    jobs: int | None = None,
    out: str | os.PathLike[str] | None = None,
    time_limit: float | None = None,
    scheduler: str | None = None,
    show_progress: bool = True,
) -> SweepSummary:
    """Execute the runs of ``sweep`` not yet in ``out`` and consolidate the results."""
    started = time.perf_counter()
    out_dir = Path(out) if out is not None else sweep.out
    jobs = int(jobs or sweep.jobs)
    limit = float(time_limit or sweep.time_limit)
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, not {jobs}")
    if not limit > 0:
        raise ConfigError(f"--time-limit must be > 0 s, not {limit}")
    store.remove_stale_temporaries(out_dir)  # from a sweep killed mid-write
    done = store.completed_run_ids(out_dir)
    todo = [spec for spec in sweep.runs if spec.run_id not in done]
    (out_dir / store.RUNS_DIR).mkdir(parents=True, exist_ok=True)
    (out_dir / "references").mkdir(exist_ok=True)
    if sweep.text:
        store.write_text_atomic(sweep.text, out_dir / "sweep.toml")
    counts: Counter = Counter()
    # the local pool forks its workers: no thread may be running then (see _context)
    with _progress(len(todo), show_progress, threaded=bool(scheduler)) as advance:

        def record(status: str) -> None:
            counts[status] += 1
            advance(counts)

        if scheduler:
            _run_dask(todo, out_dir, limit, sweep.plugins, scheduler, record)
        else:
            _run_local(todo, out_dir, limit, sweep.plugins, jobs, record, lambda: advance(None))
    results = store.consolidate(out_dir)
    recording = None
    with contextlib.suppress(Exception):  # a recording is a view of the results, never fatal
        recording = merge_run_recordings(out_dir)
    return SweepSummary(
        out_dir,
        counts,
        len(sweep.runs) - len(todo),
        time.perf_counter() - started,
        results,
        recording,
    )


@contextlib.contextmanager
def _progress(total: int, show: bool, threaded: bool = True):
    """advance(counts) for the bar; ``threaded=False`` redraws it on each call instead of
    from rich's refresh thread (the local pool calls advance(None) at every wake-up)."""
    if not show:
        yield lambda counts: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    progress = Progress(
        TextColumn("sweep"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[counts]}"),
        console=Console(file=sys.stderr, highlight=False, markup=False),
        transient=False,
        auto_refresh=threaded,
    )
    task = progress.add_task("sweep", total=total, counts="")

    def advance(counts: Counter | None) -> None:
        if counts is not None:
            text = "  ".join(
                f"{s} {counts[s]}" for s in ("ok", "failed", "skipped", "timeout") if counts[s]
            )
            progress.update(task, completed=sum(counts.values()), counts=text)
        if not threaded:
            progress.refresh()

    with progress:
        yield advance


def _died_message(exit_code: int | None) -> str:
    message = f"worker process died (exit code {exit_code}"
    if exit_code is not None and exit_code < 0:
        with contextlib.suppress(ValueError):
            message += f", {signal.Signals(-exit_code).name}"
    return message + ")"


def _timeout_message(limit: float) -> str:
    return f"time limit of {limit:g} s exceeded; the run's worker process was killed"


def _record_row(out: Path, spec: RunSpec, status: str, message: str) -> str:
    """Write a row for a run that produced none (timeout, dead worker); keep a real one."""
    existing = store.read_row(store.row_path(out, spec.run_id))
    if existing is not None:
        return existing.get("status", status)
    store.write_run(out, status_row(spec, status, message), None)
    return status


# -- local worker processes --


def _worker_main(conn: Any, plugins: list[str], out: str, sys_path: list[str]) -> None:
    """A pool worker: ready, then run specs received on ``conn`` until None."""
    for entry in reversed(sys_path):
        if entry not in sys.path:
            sys.path.insert(0, entry)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    _exit_with_parent()
    import warnings

    warnings.filterwarnings("ignore")
    import_plugin_modules(plugins)
    registry.REGISTRY.discover()
    with contextlib.suppress(Exception):  # imported here, not within a run's time limit
        importlib.import_module("workbench.recording")
        importlib.import_module("rerun")
    conn.send(("ready", os.getpid()))
    reference_dir = Path(out) / "references"
    sink = None  # one Rerun sink for all of this worker's runs, a file a run
    while True:
        message = conn.recv()
        if message is None:
            return
        spec = RunSpec.from_dict(message)
        try:
            sink = _begin_recording(sink, Path(out), spec.run_id)
            try:
                result = execute_run(spec, sink=sink, reference_dir=reference_dir)
                store.write_run(Path(out), result.row, result.series)
            finally:
                _end_recording(sink)
            conn.send(("done", spec.run_id, result.row["status"]))
        except Exception as error:  # noqa: BLE001 - reported to the parent as a row
            conn.send(("error", spec.run_id, f"{type(error).__name__}: {error}"))


RECORDINGS_DIR = "recordings"


def _begin_recording(sink: Any, out: Path, run_id: str) -> Any:
    """The worker's Rerun sink (made at its first run), now writing the file of one run
    beside its row (merged into recording.rrd at the end); None where rerun-sdk cannot be
    used: a recording is a view of the results, never a failure."""
    try:
        if sink is None:
            from workbench.recording import RerunSink

            sink = RerunSink(max_frames=200)
        sink.begin_file(out / RECORDINGS_DIR / f"{run_id}.rrd")
        return sink
    except Exception:  # noqa: BLE001
        return None


def _end_recording(sink: Any) -> None:
    """Close the run's file (none is left for a run skipped or failed before integrating)."""
    if sink is not None:
        with contextlib.suppress(Exception):
            sink.end_file()


def merge_run_recordings(out: Path) -> Path | None:
    """Merge the per-run recordings of ``out`` into ``out/recording.rrd``."""
    files = sorted((out / RECORDINGS_DIR).glob("*.rrd"))
    if not files:
        return None
    from workbench.recording import merge_recordings

    return merge_recordings(files, out / "recording.rrd")


def _exit_with_parent() -> None:
    """Exit when the process that started this one dies (no orphan keeps running a run)."""
    import threading

    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


@dataclass
class _Worker:
    process: Any
    conn: Any
    ready: bool = False
    spec: RunSpec | None = None
    deadline: float = math.inf
    pair: tuple[str, ...] | None = None  # equations_key of its last run: built, cached


Keyed = tuple[tuple[str, ...], RunSpec]  # (equations_key, run), the key computed once


def _take_next(queue: deque[Keyed], own: tuple[str, ...] | None, others: set) -> Keyed:
    """Pop the next run for a worker: a run of the equations it built last (in its cache),
    else the first of equations no other worker is on, else the first. Each model is
    then built (and its initial state found) by about one worker instead of every one."""
    chosen = None
    for i, (key, _spec) in enumerate(queue):
        if key == own:
            chosen = i
            break
        if chosen is None and key not in others:
            chosen = i
    chosen = 0 if chosen is None else chosen
    taken = queue[chosen]
    del queue[chosen]
    return taken


# imported in the parent before forking workers (so a worker starts in milliseconds
# instead of importing CasADi, SciPy, SUNDIALS, pandas and the plugins: ~2 s a worker)
WORKER_MODULES = (
    "workbench.runs.execute",
    "workbench.runs.metrics",
    "workbench.equations.initial",
    "workbench.runs.store",
)
# modules that start threads of their own: a parent that loaded one forks no workers
FORK_UNSAFE_MODULES = ("rerun", "distributed", "torch")


def _context() -> Any:
    """fork when it is safe, else forkserver (preloaded), else spawn.

    A forked worker inherits the parent's imported modules and discovered plugins, so it
    is ready at once (forkserver and spawn re-import them in a fresh interpreter: seconds
    of fixed cost per sweep, which capped the 2-worker speed-up of short sweeps). Forking
    is only safe while the parent runs no other thread (a lock held by one stays held in
    the child): the sweep's progress bar then redraws without its thread, and a parent
    that loaded a module with threads of its own (Rerun, Dask) uses the forkserver.
    """
    import threading

    methods = multiprocessing.get_all_start_methods()
    for name in WORKER_MODULES:
        importlib.import_module(name)
    registry.REGISTRY.discover()
    loaded = [m for m in FORK_UNSAFE_MODULES if m in sys.modules]
    if "fork" in methods and threading.active_count() == 1 and not loaded:
        return multiprocessing.get_context("fork")
    if "forkserver" in methods:
        context = multiprocessing.get_context("forkserver")
        plugin_modules = [
            info.module
            for kind in ("problem", "formalism", "integrator")
            for info in registry.list_plugins(kind)
            if info.plugin is not None and info.module
        ]
        context.set_forkserver_preload([*WORKER_MODULES, *dict.fromkeys(plugin_modules)])
        return context
    return multiprocessing.get_context("spawn")


def _run_local(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    jobs: int,
    record: Callable[[str], None],
    tick: Callable[[], None] = lambda: None,
) -> None:
    context = _context()
    queue: deque[Keyed] = deque((equations_key(spec), spec) for spec in todo)
    workers: list[_Worker] = []
    start_failures = 0

    def start() -> _Worker:
        parent_end, child_end = context.Pipe()
        process = context.Process(
            target=_worker_main,
            args=(child_end, plugins, str(out), list(sys.path)),
            daemon=True,
        )
        # a forked worker's garbage collector would visit every object it inherited and
        # so copy their pages (copy-on-write): frozen, they stay shared with the parent
        gc.freeze()
        try:
            process.start()
        finally:
            gc.unfreeze()
        child_end.close()
        return _Worker(process, parent_end)

    def retire(worker: _Worker) -> None:
        if worker.process.is_alive():
            worker.process.kill()
        worker.process.join(timeout=10)
        worker.conn.close()
        workers.remove(worker)

    try:
        while queue or any(w.spec for w in workers):
            busy = sum(1 for w in workers if w.spec)
            while len(workers) < min(jobs, len(queue) + busy):
                workers.append(start())
            now = time.monotonic()
            for worker in workers:
                if worker.ready and worker.spec is None and queue:
                    others = {w.pair for w in workers if w is not worker}
                    worker.pair, worker.spec = _take_next(queue, worker.pair, others)
                    worker.deadline = now + limit
                    worker.conn.send(worker.spec.to_dict())
            deadline = min((w.deadline for w in workers), default=math.inf)
            timeout = max(0.0, min(deadline - now, 1.0))
            waitables = [w.conn for w in workers] + [w.process.sentinel for w in workers]
            multiprocessing.connection.wait(waitables, timeout)
            tick()
            for worker in list(workers):
                try:
                    while worker.conn.poll():
                        message = worker.conn.recv()
                        if message[0] == "ready":
                            worker.ready, start_failures = True, 0
                        elif message[0] == "done" and worker.spec is not None:
                            record(message[2])
                            worker.spec, worker.deadline = None, math.inf
                        elif message[0] == "error" and worker.spec is not None:
                            record(_record_row(out, worker.spec, "failed", message[2]))
                            worker.spec, worker.deadline = None, math.inf
                except (EOFError, OSError):
                    pass  # the process died: handled below
            now = time.monotonic()
            for worker in list(workers):
                if not worker.process.is_alive():
                    worker.process.join()
                    code = worker.process.exitcode
                    if worker.spec is not None:
                        record(_record_row(out, worker.spec, "failed", _died_message(code)))
                    elif not worker.ready:
                        start_failures += 1
                        if start_failures >= 3:
                            raise WorkbenchError(
                                f"worker processes fail to start ({_died_message(code)}); "
                                "check that the plugin modules import"
                            )
                    retire(worker)
                elif worker.spec is not None and now > worker.deadline:
                    spec = worker.spec
                    retire(worker)
                    record(_record_row(out, spec, "timeout", _timeout_message(limit)))
    finally:
        for worker in list(workers):
            with contextlib.suppress(Exception):
                if worker.spec is None and worker.process.is_alive():
                    worker.conn.send(None)
            worker.process.join(timeout=1)
            retire(worker)


# -- Dask --


def run_in_subprocess(
    spec_data: dict[str, Any],
    limit: float,
    plugins: list[str],
    reference_dir: str,
    sys_path: list[str],
) -> tuple[dict[str, Any], Any]:
    """Run one spec in a child process under ``limit`` seconds: (row, series or None).

    Used as the task of a Dask (or any concurrent.futures) executor: the child can be
    killed where a thread cannot, and the result is returned rather than written, so the
    cluster needs no shared file system.
    """
    import pandas as pd

    spec = RunSpec.from_dict(spec_data)
    with tempfile.TemporaryDirectory(prefix="workbench-run-") as directory:
        request = {
            "spec": spec_data,
            "plugins": plugins,
            "reference_dir": reference_dir if os.path.isdir(reference_dir) else None,
            "sys_path": sys_path,
            "out": directory,
        }
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            [p for p in sys_path if p] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])
        )
        try:
            completed = subprocess.run(
                [sys.executable, "-m", "workbench.runs.sweep", "--run-one"],
                input=json.dumps(request),
                text=True,
                capture_output=True,
                timeout=limit,
                env=env,
            )
        except subprocess.TimeoutExpired:
            return status_row(spec, "timeout", _timeout_message(limit)), None
        row = store.read_row(store.row_path(Path(directory), spec.run_id))
        if row is None:
            tail = (completed.stderr or "").strip().splitlines()[-1:] or [""]
            message = _died_message(completed.returncode)
            if tail[0]:
                message += f": {tail[0]}"
            return status_row(spec, "failed", message), None
        series_file = store.series_path(Path(directory), spec.run_id)
        series = pd.read_parquet(series_file) if series_file.exists() else None
        return row, series


def _run_one_main() -> None:
    """``python -m workbench.runs.sweep --run-one``: one run from a JSON request on stdin."""
    import warnings

    warnings.filterwarnings("ignore")
    request = json.loads(sys.stdin.read())
    for entry in reversed(request.get("sys_path", [])):
        if entry not in sys.path:
            sys.path.append(entry)
    import_plugin_modules(request.get("plugins", []))
    spec = RunSpec.from_dict(request["spec"])
    result = execute_run(spec, reference_dir=request.get("reference_dir"))
    store.write_run(Path(request["out"]), result.row, result.series)


def _run_dask(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    scheduler: str,
    record: Callable[[str], None],
) -> None:
    import concurrent.futures

    try:
        import distributed
    except ImportError as error:
        raise ConfigError(f"--scheduler needs the 'distributed' package: {error}") from None
    try:
        client = distributed.Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as error:
        raise ConfigError(f"cannot connect to the Dask scheduler {scheduler!r}: {error}") from None
    reference_dir = str((out / "references").resolve())
    paths = [str(Path(p).resolve()) if p else os.getcwd() for p in sys.path]
    try:
        executor = client.get_executor(pure=False)
        futures = {
            executor.submit(
                run_in_subprocess, spec.to_dict(), limit, plugins, reference_dir, paths
            ): spec
            for spec in todo
        }
        for future in concurrent.futures.as_completed(futures):
            spec = futures[future]
            try:
                row, series = future.result()
            except Exception as error:  # noqa: BLE001 - a lost task is a failed row
                row, series = status_row(spec, "failed", f"dask task failed: {error}"), None
            store.write_run(out, row, series)
            record(row.get("status", "failed"))
    finally:
        client.close()


if __name__ == "__main__":
    if sys.argv[1:] == ["--run-one"]:
        _run_one_main()
    else:
        sys.exit("usage: python -m workbench.runs.sweep --run-one < request.json")
