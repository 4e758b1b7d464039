"""The local pool: worker processes of our own that can be killed on a time limit.

concurrent.futures cannot kill a running task, so each worker is a process with a pipe:
it builds and caches equations, runs, and writes the run's files itself; the parent
enforces each run's time limit by killing the worker (row ``timeout``) and starting a
fresh one. A worker that crashes mid-run (segfault, abort) gives a ``failed`` row
"worker process died (exit code ...)"; one killed from outside (SIGKILL, SIGTERM) is no
result: its run is tried once more, then left without a row (see
:mod:`workbench.runs.unfinished`). A worker records its runs through the ``recorder`` it
is given (a class with ``begin_file(path)`` / ``fits(spec)`` / ``end_file()``, made once
a worker), a file a batch of runs (:mod:`workbench.runs.recording_batches`), so this
layer knows no recording format; the runs a killed worker had not yet written to a file
are recorded again by another (their rows kept).
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import math
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from workbench.errors import WorkbenchError
from workbench.execution.execute import (
    RunSpec,
    equations_key,
    execute_run,
    freeze_loaded_objects,
)
from workbench.execution.run_log import CapturedOutput, raw_path, release_raw_file, write_log
from workbench.execution.run_progress import (
    ProgressWriter,
    progress_path,
    release_progress_file,
)
from workbench.execution.timing import Timing
from workbench.execution.worker_env import pin_threads
from workbench.files import check_no_links, remove_file
from workbench.plugin import registry
from workbench.plugin.local_modules import import_plugin_modules, imported_from_file
from workbench.runs import store
from workbench.runs.parent_watch import exit_with_parent
from workbench.runs.recording_batches import (
    BATCH_RUNS,
    RECORDINGS_DIR,
    RecordingBatch,
    forget_journals,
    journals,
    listed_runs,
    new_token,
)
from workbench.runs.unfinished import (
    RETRIES,
    died_message,
    killed_from_outside,
    record_unfinished,
    row_stamp,
    timeout_message,
    written_status,
)


def append_client_paths(entries: list[str]) -> None:
    """Add the client's ``sys.path`` entries this process lacks, in their order, after its
    own: they are there for the spec's local plugin modules only; ahead of this process's
    own, a client path that also exists here (another Python's site-packages, an old
    checkout) would shadow the packages installed here."""
    for entry in entries:
        if entry and entry not in sys.path:
            sys.path.append(entry)


def _worker_main(
    conn: Any,
    plugins: list[str],
    out: str,
    sys_path: list[str],
    recorder: Any = None,
    parent: int | None = None,
    reference_dir: str | None = None,
    timing: dict[str, Any] | None = None,
    scratch: bool = False,
    states: bool = True,
    token: str = "",
    batch_runs: int = BATCH_RUNS,
) -> None:
    """A pool worker: ready, then run specs received on ``conn`` until None; a message
    ``("record", spec)`` records a done run again, its row and series left as they are.

    ``parent``: the pid of a parent that is not multiprocessing's (:func:`exit_with_parent`);
    ``scratch``: ``out`` is this worker's own directory, removed if the parent dies;
    ``reference_dir``: where references are cached (default ``<out>/references``);
    ``timing``: how each integration is timed (:meth:`Timing.to_dict`); ``states``: store
    the trajectory in the series (:func:`~workbench.runs.store.write_run`); ``token``: the
    name of its recordings' journal (:mod:`workbench.runs.recording_batches`),
    ``batch_runs`` the runs of a recording file at most. Also the worker loop of a Dask
    worker's child (:mod:`workbench.runs.dask_pool`: a file a run)."""
    pin_threads()  # the same BLAS/OpenMP threads wherever a sweep runs (worker_env)
    append_client_paths(sys_path)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    exit_with_parent(parent, Path(out) if scratch else None)
    import warnings

    warnings.filterwarnings("ignore")
    import_plugin_modules(plugins)
    registry.REGISTRY.discover()
    if recorder is not None and hasattr(recorder, "prepare"):
        with contextlib.suppress(Exception):  # loaded here, not within a run's time limit
            recorder.prepare()
    # what start-up made (modules, plugins, Rerun) lives as long as the worker: kept out of
    # the collector's full passes (every few hundred runs, and each cache eviction's)
    freeze_loaded_objects()
    conn.send(("ready", os.getpid()))
    references = Path(reference_dir) if reference_dir else Path(out) / "references"
    # one recording sink for all of this worker's runs, a file a batch of runs
    batch = (
        RecordingBatch(recorder, Path(out), token or new_token(), batch_runs) if recorder else None
    )
    while True:
        message = conn.recv()
        if message is None:
            if batch is not None:
                batch.close()  # its last runs' file, then its journal goes
            release_raw_file()  # kept for a next run (CapturedOutput's reuse)
            release_progress_file()
            return
        record_only = isinstance(message, tuple)  # ("record", spec)
        spec = RunSpec.from_dict(message[1] if record_only else message)
        try:
            sink = batch.begin_run(spec) if batch is not None else None
            capture = CapturedOutput(raw_path(Path(out), spec.run_id), reuse=True)
            progress = ProgressWriter(progress_path(Path(out), spec.run_id))
            with capture, progress:  # output to its bounded log; progress for a timeout
                result = execute_run(
                    spec, sink=sink, reference_dir=references, timing=Timing.from_dict(timing)
                )
            if batch is not None:
                batch.logged(spec.run_id)  # in its journal before its row is written
            if not record_only:
                result.row["log"] = write_log(Path(out), spec.run_id, capture.kept())
                store.write_run(Path(out), result.row, result.stored_series, states)
            if batch is not None:
                batch.end_run()
            conn.send(("done", spec.run_id, result.row["status"]))
        except Exception as error:  # noqa: BLE001 - reported to the parent as a row
            conn.send(("error", spec.run_id, f"{type(error).__name__}: {error}"))


def merge_run_recordings(recorder: Any, out: Path) -> tuple[Path | None, bool]:
    """Merge the per-run recordings of ``out`` into one file (``recorder.merge``):
    (its path or None, merged now). With ``recorder.merged_file`` the merge adds the runs'
    files to that file (runs redone replace their old copy) and the files are removed once
    the merged file is durable, so the disk holds one copy; a crash before that leaves
    them for the next merge. Without new files the merged file is kept as it is."""
    directory = out / RECORDINGS_DIR
    files = list(directory.glob(f"*.{recorder.suffix}")) if directory.is_dir() else []
    # the newest file first: a run recorded again (redone) is taken from its last file
    files.sort(key=lambda file: (file.stat().st_mtime_ns, file.name), reverse=True)
    merged = getattr(recorder, "merged_file", None)
    if not files:
        kept = out / merged if merged is not None else None
        return (kept if kept is not None and kept.is_file() else None), False
    check_no_links(directory, out)  # read and written below out, never through
    check_no_links(out / "recording.rrd", out)  # a link (workbench.files)
    path = recorder.merge(files, out)
    if merged is not None:
        for file in files:  # in the merged file now (synced to disk by the merge)
            remove_file(file, out)
    return path, True


@dataclass
class _Worker:
    process: Any
    conn: Any
    ready: bool = False
    spec: RunSpec | None = None
    deadline: float = math.inf
    pair: tuple[str, ...] | None = None  # equations_key of its last run: built, cached
    stamp: tuple[int, int] | None = None  # row_stamp of its run when it was handed over
    token: str = ""  # its recordings' journal (workbench.runs.recording_batches)
    record_only: bool = False  # its run is a done run recorded again
    recorded: list[str] = field(default_factory=list)  # runs it recorded (done, not failed)


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


# imported in the parent before forking workers, so a worker starts in milliseconds
# instead of importing CasADi, SciPy, SUNDIALS, pandas and the plugins
WORKER_MODULES = (
    "workbench.execution.execute",
    "workbench.execution.metrics",
    "workbench.equations.initial",
    "workbench.runs.store",
)


# modules that start threads of their own: a parent that loaded one forks no workers
FORK_UNSAFE_MODULES = ("rerun", "distributed", "torch")


def worker_context() -> Any:
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
            if info.plugin is not None and info.module and not imported_from_file(info.module)
        ]  # a local plugin module is imported by each worker from its file
        context.set_forkserver_preload([*WORKER_MODULES, *dict.fromkeys(plugin_modules)])
        return context
    return multiprocessing.get_context("spawn")


def run_local(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    jobs: int,
    record: Callable[[str], None],
    tick: Callable[[], None] = lambda: None,
    recorder: Any = None,
    timing: Timing | None = None,
    states: bool = True,
    rebuild: list[RunSpec] = (),
    recorded: Callable[[str], None] = lambda run_id: None,
) -> dict[str, str]:
    """Run ``todo`` (timed as ``timing`` says, default :class:`Timing` with ``jobs``
    workers; ``states``: store each trajectory, :func:`~workbench.runs.store.write_run`);
    return the runs left without a row (run id -> why): those whose
    worker was killed from outside twice (:mod:`workbench.runs.unfinished`).

    ``rebuild``: done runs to record again (their recording was left unwritten by a
    killed worker; rows kept); so are those of a worker killed here, once each.
    ``recorded(run_id)``: called as each of them is recorded again."""
    context = worker_context()
    timed = (timing or Timing(workers=jobs)).to_dict()
    queue: deque[Keyed] = deque((equations_key(spec), spec) for spec in todo)
    rebuilds: deque[Keyed] = deque((equations_key(spec), spec) for spec in rebuild)
    specs = {spec.run_id: spec for spec in [*todo, *rebuild]}
    recorded_again: Counter[str] = Counter()  # run id -> times queued to be recorded again
    workers: list[_Worker] = []
    gone: list[_Worker] = []  # workers retired, for their journals
    start_failures = 0
    lost: Counter[str] = Counter()  # run id -> attempts whose worker was killed from outside
    unfinished: dict[str, str] = {}

    def record_again(worker: _Worker) -> None:
        """Queue the runs a retired worker recorded but had not written to a file (its
        journals), except those queued to run again anyway; once each."""
        if recorder is None:
            return
        queued = {spec.run_id for _key, spec in queue}
        for run_id in sorted(listed_runs(journals(out, worker.token))):
            if run_id in specs and run_id not in queued and not recorded_again[run_id]:
                recorded_again[run_id] += 1
                rebuilds.append((equations_key(specs[run_id]), specs[run_id]))

    # a forkserver's child is the forkserver's, not ours (it exits when we do): watched so

    def start() -> _Worker:
        parent_end, child_end = context.Pipe()
        token = new_token()
        process = context.Process(
            target=_worker_main,
            args=(child_end, plugins, str(out), list(sys.path), recorder),
            kwargs={"timing": timed, "states": states, "token": token},
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
        return _Worker(process, parent_end, token=token)

    def retire(worker: _Worker) -> None:
        if worker.process.is_alive():
            worker.process.kill()
        worker.process.join(timeout=10)
        worker.conn.close()
        workers.remove(worker)
        gone.append(worker)

    try:
        while True:  # until no worker left runs unwritten (killed as it stopped too)
            while queue or rebuilds or any(w.spec for w in workers):
                busy = sum(1 for w in workers if w.spec)
                while len(workers) < min(jobs, len(queue) + len(rebuilds) + busy):
                    workers.append(start())
                now = time.monotonic()
                for worker in workers:
                    if worker.ready and worker.spec is None and (queue or rebuilds):
                        others = {w.pair for w in workers if w is not worker}
                        worker.record_only = not queue  # the runs to do first, then those
                        taken = _take_next(queue or rebuilds, worker.pair, others)
                        worker.pair, worker.spec = taken
                        worker.deadline = now + limit
                        worker.stamp = row_stamp(out, worker.spec.run_id)
                        data = worker.spec.to_dict()
                        worker.conn.send(("record", data) if worker.record_only else data)
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
                                if not worker.record_only:  # (recorded again: counted once)
                                    record(message[2])
                                else:
                                    recorded(worker.spec.run_id)
                                worker.recorded.append(worker.spec.run_id)
                                worker.spec, worker.deadline = None, math.inf
                            elif message[0] == "error" and worker.spec is not None:
                                if not worker.record_only:  # its row stands otherwise
                                    status = record_unfinished(
                                        out, worker.spec, "failed", message[2], worker.stamp
                                    )
                                    record(status)
                                worker.spec, worker.deadline = None, math.inf
                    except (EOFError, OSError):
                        pass  # the process died: handled below
                now = time.monotonic()
                for worker in list(workers):
                    if not worker.process.is_alive():
                        worker.process.join()
                        code = worker.process.exitcode
                        spec, stamp = worker.spec, worker.stamp
                        written = spec and written_status(out, spec.run_id, stamp)
                        if spec is not None and worker.record_only:
                            # a done run being recorded again: its row stands; it is
                            # recorded once more if its worker died before logging it
                            if not recorded_again[spec.run_id]:
                                recorded_again[spec.run_id] += 1
                                rebuilds.append((equations_key(spec), spec))
                        elif spec is not None and not written and killed_from_outside(code):
                            lost[spec.run_id] += 1
                            if lost[spec.run_id] <= RETRIES:
                                queue.appendleft((equations_key(spec), spec))  # once more
                            else:
                                unfinished[spec.run_id] = (
                                    f"{died_message(code)} {lost[spec.run_id]} times"
                                )
                                record("unfinished")
                        elif spec is not None:
                            why = died_message(code)
                            record(record_unfinished(out, spec, "failed", why, stamp))
                        elif not worker.ready:
                            start_failures += 1
                            if start_failures >= 3:
                                raise WorkbenchError(
                                    f"worker processes fail to start ({died_message(code)}); "
                                    "check that the plugin modules import"
                                )
                        retire(worker)
                        record_again(worker)
                    elif worker.spec is not None and now > worker.deadline:
                        spec, stamp = worker.spec, worker.stamp
                        retire(worker)
                        if not worker.record_only:
                            status = record_unfinished(
                                out, spec, "timeout", timeout_message(limit), stamp
                            )
                            record(status)
                        record_again(worker)
            _stop(workers, retire)
            for worker in gone:  # (each run once: record_again)
                record_again(worker)
            if not rebuilds:
                break
        if recorder is not None:  # the journals whose runs are now in files go
            written = {  # recorded by a worker and not left in its journals
                run for w in gone for run in set(w.recorded) - listed_runs(journals(out, w.token))
            }
            forget_journals(out, written, set(specs))
        return unfinished
    finally:
        _stop(workers, retire)


STOP_SECONDS = 30.0
"""How long a worker told to stop may take (it writes its last recordings' file)."""


def _stop(workers: list[_Worker], retire: Callable[[_Worker], None]) -> None:
    """Tell the idle workers to stop and wait for them; kill the others (retire)."""
    told = []
    for worker in workers:
        with contextlib.suppress(Exception):
            if worker.spec is None and worker.process.is_alive():
                worker.conn.send(None)
                told.append(worker)
    deadline = time.monotonic() + STOP_SECONDS
    for worker in list(workers):
        if worker in told:
            worker.process.join(timeout=max(0.0, deadline - time.monotonic()))
        retire(worker)
