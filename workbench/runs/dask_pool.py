"""Running a sweep's runs on a Dask cluster (``workbench sweep --scheduler ADDRESS``).

Runs are submitted through ``distributed.Client(address).get_executor()``, one task a
run. A task hands its run to a long-lived child process of its Dask worker
(:class:`_Child`: the local pool's worker loop, :func:`workbench.runs.local_pool._worker_main`,
started at the worker's first task and kept between tasks), so imports and the
equations' build are paid once per worker, not once per run. The task enforces the time
limit by killing the child (row ``timeout``; the next task starts a fresh one) and
returns the row, series and recording to the client, which writes them, so the cluster
needs no shared file system. A child killed from outside, or a lost Dask worker, is no result
(:class:`~workbench.runs.unfinished.InfrastructureError`): the client retries the run
once. Runs are handed out as the local pool hands them (a worker's own equations first,
two in flight a worker thread, each pinned loosely to its worker: a lost worker's go to
the others), so each model is built by about one child. ``workbench run`` runs its one
run in a fresh child (:func:`run_in_subprocess`).
"""

from __future__ import annotations

import atexit
import contextlib
import json
import logging
import multiprocessing.connection
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

from workbench.errors import ConfigError, WorkbenchError, one_line
from workbench.execution.execute import RunSpec, equations_key, execute_run, status_row
from workbench.execution.run_log import (
    LOG_TEXT,
    CapturedOutput,
    log_path,
    raw_path,
    raw_text,
    store_log,
    write_log,
)
from workbench.execution.run_progress import progress_columns, progress_path, read_progress
from workbench.execution.timing import Timing
from workbench.execution.worker_env import pin_threads, thread_environment
from workbench.files import atomic_write, make_dirs, open_no_follow
from workbench.plugin.local_modules import import_plugin_modules
from workbench.runs import store
from workbench.runs.local_pool import Keyed, _take_next, append_client_paths
from workbench.runs.recording_batches import RECORDINGS_DIR
from workbench.runs.shipping import (
    REFERENCE_FILES,
    ReferenceGate,
    keep_references,
    new_references,
    pack_modules,
    pack_references,
    reference_names,
    unpack_modules,
    unpack_references,
    worker_reference_dir,
)
from workbench.runs.unfinished import (
    RETRIES,
    InfrastructureError,
    died_message,
    killed_from_outside,
    timeout_message,
)


def run_in_subprocess(
    spec_data: dict[str, Any],
    limit: float,
    plugins: list[str],
    reference_dir: str,
    sys_path: list[str],
    timing: dict[str, Any] | None = None,
) -> tuple[dict[str, Any], Any]:
    """Run one spec in a child process under ``limit`` seconds: (row, series or None).

    Used as the task of a Dask (or any concurrent.futures) executor: the child can be
    killed where a thread cannot, and the result is returned rather than written, so the
    cluster needs no shared file system. InfrastructureError if the child was killed
    from outside (no result of the run; see :mod:`workbench.runs.unfinished`).
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
            "timing": timing or {},
        }
        # the client's paths are not put on PYTHONPATH, ahead of this host's packages: the
        # child adds them after its own (append_client_paths)
        env = dict(os.environ) | thread_environment()  # read by BLAS/OpenMP as they load
        try:
            completed = subprocess.run(
                [sys.executable, "-m", "workbench.runs.dask_pool", "--run-one"],
                input=json.dumps(request),
                text=True,
                capture_output=True,
                timeout=limit,
                env=env,
            )
        except subprocess.TimeoutExpired:
            row = status_row(spec, "timeout", timeout_message(limit))
            return row | {LOG_TEXT: raw_text(Path(directory), spec.run_id)}, None
        row = store.read_row(store.row_path(Path(directory), spec.run_id))
        if row is None:
            tail = (completed.stderr or "").strip().splitlines()[-1:] or [""]
            message = died_message(completed.returncode)
            if tail[0]:
                message += f": {tail[0]}"
            if killed_from_outside(completed.returncode):
                raise InfrastructureError(f"run {spec.run_id}: {message}")
            row = status_row(spec, "failed", message)
            return row | {LOG_TEXT: raw_text(Path(directory), spec.run_id)}, None
        if row.get("log"):  # returned with the row; store_log writes it beside the row
            row[LOG_TEXT] = (Path(directory) / row["log"]).read_text("utf-8", "replace")
        series_file = store.series_path(Path(directory), spec.run_id)
        series = pd.read_parquet(series_file) if series_file.exists() else None
        return row, series


def _run_one_main() -> None:
    """``python -m workbench.runs.dask_pool --run-one``: one run from a JSON request on stdin."""
    import warnings

    warnings.filterwarnings("ignore")
    pin_threads()
    request = json.loads(sys.stdin.read())
    append_client_paths(request.get("sys_path", []))
    import_plugin_modules(request.get("plugins", []))
    spec = RunSpec.from_dict(request["spec"])
    out = Path(request["out"])
    capture = CapturedOutput(raw_path(out, spec.run_id))
    with capture:  # the run's stdout/stderr (C's too) to its bounded log
        timing = Timing.from_dict(request.get("timing"))
        result = execute_run(spec, reference_dir=request.get("reference_dir"), timing=timing)
    result.row["log"] = write_log(out, spec.run_id, capture.kept())
    store.write_run(out, result.row, result.stored_series)


# ---- a long-lived child per Dask worker -----------------------------------------------

DEPTH = 2  # runs handed to a Dask worker thread at a time: the next waits there, not here
START_LIMIT = 600.0  # s for a child to import and discover its plugins (not a run's limit)


class _Child:
    """A child process of this Dask worker running the local pool's worker loop on a socket
    pair, with its own scratch directory where it writes each run's files (read back and
    removed by :meth:`run`). ``setting``: (plugins, sys_path, reference_dir, timing items,
    recorder) it was made for; a task of another sweep starts its own. With a recorder
    (:func:`workbench.runs.sweep.run_sweep`'s) it records each run into a file of its own,
    returned with the row."""

    def __init__(self, setting: tuple) -> None:
        plugins, sys_path, reference_dir, timing, recorder = setting
        self.setting = setting
        self.out = Path(tempfile.mkdtemp(prefix="workbench-dask-"))
        ours, theirs = socket.socketpair()
        # the client's paths are not put on PYTHONPATH, ahead of this host's packages: the
        # child adds them after its own (append_client_paths)
        env = dict(os.environ) | thread_environment()  # read by BLAS/OpenMP as they load
        with open(self.out / "child.stderr", "wb") as stderr:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "workbench.runs.dask_pool", "--serve", str(theirs.fileno())],
                pass_fds=(theirs.fileno(),),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=stderr,
                env=env,
            )
        theirs.close()
        self.conn = multiprocessing.connection.Connection(ours.detach())
        self.conn.send(
            {
                "plugins": list(plugins),
                "out": str(self.out),
                "sys_path": list(sys_path),
                "parent": os.getpid(),
                "reference_dir": reference_dir,
                "timing": dict(timing),
                "recorder": recorder,  # a class, pickled by name: importable in the child
            }
        )
        message = self._receive(START_LIMIT)
        if message is None or message[0] != "ready":  # too slow, or died importing
            self._kill()
            reason = self._stopped()
            self.close()
            raise InfrastructureError(f"the Dask worker's child process did not start: {reason}")

    def _receive(self, seconds: float) -> Any:
        """The child's next message; ``("died",)`` if it closed its end (it died), None if
        it sent nothing for ``seconds``."""
        try:
            if not self.conn.poll(seconds):
                return None
            return self.conn.recv()
        except (EOFError, OSError):
            return ("died",)

    def _stopped(self) -> str:
        """Why the child stopped (its exit code and last line on stderr), once it has."""
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=10)
        message = died_message(self.process.returncode)
        with contextlib.suppress(OSError):
            lines = (self.out / "child.stderr").read_text("utf-8", "replace").strip()
            if lines:
                message += f": {lines.splitlines()[-1]}"
        return message

    def _unfinished_row(self, spec: RunSpec, status: str, reason: str) -> dict[str, Any]:
        """The row of a run whose child stopped without one: where it was (its stage, the
        time reached; :mod:`workbench.execution.run_progress`), as the local pool says it."""
        where, clause = progress_columns(read_progress(progress_path(self.out, spec.run_id)))
        return status_row(spec, status, f"{reason}; {clause}" if clause else reason, **where)

    def run(self, spec: RunSpec, limit: float) -> tuple[dict[str, Any], Any]:
        """(row, series or None) of one run within ``limit`` seconds; on a timeout or a
        crash the child is gone (:attr:`alive` False) and the row says so;
        InfrastructureError if it was killed from outside. The run's recording file, if
        the child wrote one, goes in the row under :data:`RECORDING_FILES`."""
        import pandas as pd

        self.conn.send(spec.to_dict())
        message = self._receive(limit)
        reason = "the worker loop wrote no row for the run"  # (not seen: a bug if it is)
        try:
            if message is None or message[0] == "died":
                reason = self._stopped() if message else timeout_message(limit)
                self._kill()  # a row it wrote before dying or running out of time stands
            row = store.read_row(store.row_path(self.out, spec.run_id))
            if row is None and message is None:  # where the killed run was (run_progress)
                row = self._unfinished_row(spec, "timeout", reason)
                return row | {LOG_TEXT: raw_text(self.out, spec.run_id)}, None
            if row is None and message[0] == "error":
                row = status_row(spec, "failed", message[2])
                return row | {LOG_TEXT: raw_text(self.out, spec.run_id)}, None
            if row is None:  # it died without writing the run's row
                if killed_from_outside(self.process.returncode):
                    raise InfrastructureError(f"run {spec.run_id}: {reason}")
                row = self._unfinished_row(spec, "failed", reason)
                return row | {LOG_TEXT: raw_text(self.out, spec.run_id)}, None
            if row.get("log"):  # returned with the row; store_log writes it beside the row
                row[LOG_TEXT] = (self.out / row["log"]).read_text("utf-8", "replace")
            series_file = store.series_path(self.out, spec.run_id)
            series = pd.read_parquet(series_file) if series_file.exists() else None
            recordings = self._take_recordings()
            if recordings:
                row[RECORDING_FILES] = recordings
            return row, series
        finally:
            for path in (
                store.row_path(self.out, spec.run_id),
                store.series_path(self.out, spec.run_id),
                log_path(self.out, spec.run_id),
                raw_path(self.out, spec.run_id),
            ):
                path.unlink(missing_ok=True)
            if not self.alive:
                self.close()

    def _take_recordings(self) -> dict[str, bytes]:
        """The recording files the child has written (name -> bytes), removed here."""
        recorder = self.setting[4]
        directory = self.out / RECORDINGS_DIR
        if recorder is None or not directory.is_dir():
            return {}
        taken = {}
        for path in sorted(directory.glob(f"*.{recorder.suffix}")):
            with contextlib.suppress(OSError):  # a view of the results: never a failed run
                taken[path.name] = path.read_bytes()
                path.unlink()
        return taken

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def _kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        self.conn.close()

    def close(self) -> None:
        """Kill the child and remove its directory (its built equations go with it)."""
        self._kill()
        shutil.rmtree(self.out, ignore_errors=True)


_IDLE: list[_Child] = []  # this Dask worker's children waiting for a task
_IDLE_LOCK = threading.Lock()  # a worker with several threads runs tasks side by side
_PLUGINS_IMPORTED: set[tuple] = set()  # settings whose plugins this Dask worker imported


def _import_plugins(plugins: tuple, sys_path: tuple) -> None:
    """Import the sweep's plugin modules here too, once: a row this process writes (timeout,
    crash) names their producers as the local pool's parent does."""
    with _IDLE_LOCK:
        if (plugins, sys_path) in _PLUGINS_IMPORTED:
            return
        append_client_paths(list(sys_path))
        import_plugin_modules(list(plugins))
        _PLUGINS_IMPORTED.add((plugins, sys_path))


def _keep_idle(child: _Child) -> None:
    """Keep ``child`` for the next task, and close the idle children beyond one a worker
    thread, least recently used first: a child made for another setting (an earlier
    sweep's OUT or plugins) would otherwise stay, with its memory, until the worker stops."""
    with _IDLE_LOCK:
        _IDLE.append(child)
        surplus = _IDLE[: max(0, len(_IDLE) - _worker_threads())]
        del _IDLE[: len(surplus)]
    for old in surplus:
        with contextlib.suppress(Exception):
            old.close()


def _worker_threads() -> int:
    """The threads of this Dask worker (1 outside one)."""
    try:
        from distributed import get_worker

        return max(1, int(get_worker().state.nthreads))
    except (ImportError, ValueError, AttributeError):
        return 1


def _close_idle() -> None:
    with _IDLE_LOCK:
        while _IDLE:
            with contextlib.suppress(Exception):
                _IDLE.pop().close()


atexit.register(_close_idle)


def run_on_worker_child(
    spec_data: dict[str, Any],
    limit: float,
    plugins: list[str],
    reference_dir: str,
    sys_path: list[str],
    timing: dict[str, Any] | None = None,
    modules: dict[str, Any] | None = None,
    references: dict[str, bytes] | None = None,
    recorder: Any = None,
) -> tuple[dict[str, Any], Any]:
    """A Dask task: run one spec in a long-lived child of this worker: (row, series or None).

    Takes an idle child made for the same plugins and paths (or starts one), and gives it
    back after the run unless the run killed it (timeout, crash). The child's start-up is
    outside the run's time limit, as in the local pool. ``modules`` and ``references``
    (given by :func:`run_dask`; :mod:`workbench.runs.shipping`): the local plugin modules'
    files and the problem's computed references, shipped from the client, so this worker
    reads none of the client's folders; the references computed here go back in the row
    (:data:`~workbench.runs.shipping.REFERENCE_FILES`), as does the run's recording
    (``recorder``: :func:`workbench.runs.sweep.run_sweep`'s; :data:`RECORDING_FILES`)."""
    shipped = modules is not None or references is not None
    if shipped:
        plugins = unpack_modules(list(plugins), modules or {})
        folder = worker_reference_dir(reference_dir)
        unpack_references(folder, references or {})
        here: str | None = str(folder)
    else:
        here = reference_dir if os.path.isdir(reference_dir) else None
    timed = tuple(sorted((timing or {}).items()))
    setting = (tuple(plugins), tuple(sys_path), here, timed, recorder)
    _import_plugins(setting[0], setting[1])
    with _IDLE_LOCK:
        child = next((c for c in _IDLE if c.setting == setting and c.alive), None)
        if child is not None:
            _IDLE.remove(child)
    if child is None:
        child = _Child(setting)
    try:
        result = child.run(RunSpec.from_dict(spec_data), limit)
    except BaseException:
        child.close()
        raise
    if child.alive:
        _keep_idle(child)
    if shipped:
        computed = new_references(folder, str(spec_data.get("problem", "")), references or {})
        if computed:
            result[0][REFERENCE_FILES] = computed
    return result


def _serve_main(fd: int) -> None:
    """``python -m workbench.runs.dask_pool --serve FD``: the local pool's worker loop on
    the socket ``FD``, set up by the first message (see :class:`_Child`)."""
    from workbench.runs.local_pool import _worker_main

    conn = multiprocessing.connection.Connection(fd)
    setting = conn.recv()
    try:
        _worker_main(
            conn,
            setting["plugins"],
            setting["out"],
            setting["sys_path"],
            setting.get("recorder"),
            setting["parent"],
            setting["reference_dir"],
            setting["timing"],
            scratch=True,  # its directory goes with it if the Dask worker dies mid-run
            batch_runs=1,  # a run's recording goes back with its row (RECORDING_FILES)
        )
    finally:  # the socket closed (the Dask worker is gone) or it said stop
        shutil.rmtree(setting["out"], ignore_errors=True)


def client_paths() -> list[str]:
    """This process's ``sys.path`` as absolute folders, for a worker's children (its
    current folder for the empty entry): where the spec's local plugin modules are."""
    return [str(Path(p).resolve()) if p else os.getcwd() for p in sys.path]


def check_scheduler_address(scheduler: str, option: str = "--scheduler") -> None:
    """ConfigError for an address Dask cannot read (a host without its port): said before
    a sweep writes its plan and logs into OUT, not after (an address that reads well but
    answers nothing is found when the sweep connects). ``option``: what the user gave it
    as, named in the message: the CLI's ``--scheduler``, the Python API's ``scheduler=``."""
    from distributed.comm.addressing import parse_address, parse_host_port

    given = f"{option}{scheduler!r}" if option.endswith("=") else f"{option} {scheduler!r}"
    try:
        if not scheduler.strip():
            unset = "without --scheduler" if option == "--scheduler" else "with scheduler=None"
            raise ValueError(f"an empty address (the local pool is used {unset})")
        scheme, location = parse_address(scheduler)
        if scheme in ("tcp", "tls"):
            _host, port = parse_host_port(location)
            if not 0 < int(port) < 65536:
                raise ValueError(f"port {port} is not a TCP port (1-65535)")
    except (ValueError, TypeError) as error:
        raise ConfigError(
            f"{given}: {error}; give the address a `dask scheduler` prints (tcp://host:port)"
        ) from None


def run_dask(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    scheduler: str,
    record: Callable[[str], None],
    timing: Timing | None = None,
    states: bool = True,
    recorder: Any = None,
    say: Callable[[str], None] | None = None,
) -> dict[str, str]:
    """Run ``todo`` on the cluster (timed as ``timing`` says; its ``workers`` become the
    cluster's worker threads, over all its machines; ``states``: store the trajectories,
    :func:`~workbench.runs.store.write_run`; ``recorder``: record each run as the local
    pool does, a file a run written into ``OUT/recordings`` by the client; ``say``: where
    a line for the user goes, e.g. that the scheduler has no worker); return the
    runs left without a row (run id -> why): those whose task was lost twice
    (:mod:`workbench.runs.unfinished`)."""
    try:
        import distributed  # noqa: F401 - its loggers exist once it is imported
    except ImportError as error:
        raise ConfigError(
            f"a Dask scheduler needs the 'distributed' package: {error} "
            "(pip install distributed; or run on the local pool, without a scheduler)"
        ) from None
    with dask_log_in(out):
        return _run_dask(
            todo, out, limit, plugins, scheduler, record, timing, states, recorder, say
        )  # fmt: skip


CLIENT_LOG = "dask-client.log"  # under OUT/logs: what distributed says in the client


@contextlib.contextmanager
def dask_log_in(out: Path) -> Iterator[None]:
    """Send what distributed logs in this process (a lost connection's traceback at INFO,
    reconnection attempts) to ``OUT/logs/dask-client.log`` instead of the terminal: the
    sweep says itself what a lost scheduler or worker means for the runs."""
    logs = out / "logs"
    make_dirs(logs, out)
    fd = open_no_follow(logs / CLIENT_LOG, os.O_WRONLY | os.O_CREAT | os.O_APPEND, out)
    handler = logging.StreamHandler(os.fdopen(fd, "a", encoding="utf-8"))
    handler.setFormatter(logging.Formatter("%(asctime)s - %(name)s - %(levelname)s - %(message)s"))
    loggers = [  # distributed gives each of its loggers (and tornado's) a stderr handler
        logger
        for name, logger in logging.Logger.manager.loggerDict.items()
        if name.split(".")[0] in ("distributed", "tornado")
        and isinstance(logger, logging.Logger)
        and (logger.handlers or name == "distributed")
    ]
    saved = [(logger, logger.handlers[:], logger.propagate) for logger in loggers]
    for logger in loggers:
        logger.handlers[:] = [handler]
        logger.propagate = False
    try:
        yield
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers[:], logger.propagate = handlers, propagate
        handler.close()


def _run_dask(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    scheduler: str,
    record: Callable[[str], None],
    timing: Timing | None,
    states: bool,
    recorder: Any = None,
    say: Callable[[str], None] | None = None,
) -> dict[str, str]:
    import concurrent.futures

    import distributed

    try:
        client = distributed.Client(scheduler, timeout="10s")
    except Exception as error:  # noqa: BLE001 - nothing there, or a service that is not Dask
        reason = one_line(error)[:200]  # (another service's reply can be any error)
        raise ConfigError(
            f"cannot connect to the Dask scheduler {scheduler!r}: {reason}; "
            "give the address a `dask scheduler` prints (tcp://host:port)"
        ) from None
    reference_dir = str((out / "references").resolve())
    shipped: dict[str | None, tuple[list[str], Any]] = {}  # problem -> files, their future
    paths = client_paths()
    queue: deque[Keyed] = deque((equations_key(spec), spec) for spec in todo)
    gate = ReferenceGate(queue, Path(reference_dir))  # a reference computed once, not a worker
    futures: dict[concurrent.futures.Future, tuple[RunSpec, str | None]] = {}
    pairs: dict[str | None, tuple[str, ...] | None] = {}  # worker -> equations of its last run
    executors: dict[str | None, Any] = {}
    unfinished: dict[str, str] = {}
    failures: Counter[str] = Counter()

    def give_up(spec: RunSpec, reason: str) -> None:
        unfinished[spec.run_id] = f"{reason} ({failures[spec.run_id]} attempts)"
        record("unfinished")
        gate.returned(spec, None)

    def submit(spec: RunSpec, worker: str | None) -> None:
        if worker not in executors:  # a preference: a lost worker's tasks go to the others
            where = {} if worker is None else {"workers": [worker], "allow_other_workers": True}
            executors[worker] = client.get_executor(pure=False, **where)
        future = executors[worker].submit(
            run_on_worker_child, spec.to_dict(), limit, plugins, reference_dir, paths, timed,
            ship(None), ship(spec.problem), recorder,
        )  # fmt: skip
        futures[future] = (spec, worker)

    def ship(problem: str | None) -> Any:
        """The local plugin modules' files (``problem`` None, read once) or the problem's
        computed references in ``OUT/references`` (read again when they change), scattered
        once: sent to every worker, not with every task (a copy on each, so a lost worker
        does not take the only one; a task that fails scatters them again).

        Each scatter has a key of its own (``hash=False``): scattered again under its
        content's hash, the data took the key the client had just released, and the
        release could reach the scheduler or the workers after the new copy, which it
        then freed: the retried task lost its input (left unfinished), or the broadcast's
        replication waited for that copy forever (a sweep hung, seen at load 9)."""
        names = [] if problem is None else reference_names(Path(reference_dir), problem)
        if problem not in shipped or shipped[problem][0] != names:
            packed = pack_modules(plugins) if problem is None else pack_references(
                Path(reference_dir), problem
            )  # fmt: skip
            if not _has_workers(client):  # nothing to scatter to: scatter waited 70 s and
                return packed  # failed, the run given up; sent with a task, it waits
            try:
                future = client.scatter([packed], hash=False, broadcast=True, timeout=SCATTER_S)[0]
            except Exception:  # noqa: BLE001 - e.g. a lost worker still restarting: one copy
                future = client.scatter([packed], hash=False, timeout=LOST_AFTER_S)[0]
            shipped[problem] = (names, future)
        return shipped[problem][1]

    def fill() -> None:
        """Give each worker thread up to DEPTH runs, chosen as the local pool chooses
        (:func:`workbench.runs.local_pool._take_next`): a worker's child keeps the
        equations of its last runs, so each model is built by about one worker."""
        try:
            threads: dict[str | None, int] = dict(client.nthreads())
        except Exception:  # noqa: BLE001 - a lost scheduler: the submits below say it
            threads = {}
        for worker, count in (threads or {None: 1}).items():  # None: whichever comes
            while queue and sum(w == worker for _, w in futures.values()) < DEPTH * count:
                others = {p for w, p in pairs.items() if w != worker}
                pairs[worker], spec = _take_next(queue, pairs.get(worker), others)
                try:
                    submit(spec, worker)
                except Exception as error:  # noqa: BLE001 - a lost client: left unfinished
                    failures[spec.run_id] += 1
                    give_up(spec, _lost_message(error))

    def abandon(reason: str) -> None:
        """The scheduler is gone: every run not done is left without a row (a resume redoes
        them), instead of waiting for futures that never resolve once the client closed."""
        pending = [spec for spec, _worker in futures.values()]
        pending += [spec for _key, spec in [*queue, *gate.take_all()]]
        futures.clear()
        queue.clear()
        for spec in pending:
            failures[spec.run_id] += 1
            give_up(spec, reason)

    watch = _ClientWatch(client, scheduler)
    idle = _IdleWatch(client, scheduler, say or (lambda line: None))
    try:
        try:
            threads = sum(client.nthreads().values()) or 1
        except Exception:  # noqa: BLE001 - lost already: the watch below says so
            threads = 1
        timed = replace(timing or Timing(), workers=threads).to_dict()  # read by submit
        idle.check(now=True)  # (the first runs' data waits for a worker to take it)
        fill()
        while futures:
            finished, _ = concurrent.futures.wait(
                futures, timeout=WATCH_S, return_when=concurrent.futures.FIRST_COMPLETED
            )
            if not finished:
                lost = watch.lost()  # the client, not only the futures: they may never end
                if lost:
                    abandon(lost)
                else:
                    idle.check()
                continue
            idle.finished()
            for future in finished:
                spec, _worker = futures.pop(future)
                try:
                    row, series = future.result()
                except Exception as error:  # noqa: BLE001 - lost worker, scheduler, child
                    # not a result of the run: once more, then left without a row
                    failures[spec.run_id] += 1
                    shipped.clear()  # the data it was given may have gone with its worker
                    if failures[spec.run_id] <= RETRIES:
                        queue.appendleft((equations_key(spec), spec))
                    else:
                        give_up(spec, _lost_message(error))
                    continue
                returned = row.pop(REFERENCE_FILES, None)
                if returned:  # computed by a worker: kept, and shipped with the later runs
                    keep_references(Path(reference_dir), returned)
                # before the row: a client killed between the two leaves the run to redo
                write_recordings(out, row.pop(RECORDING_FILES, None) or {})
                store_log(out, row)
                store.write_run(out, row, series, states)
                record(row.get("status", "failed"))
                gate.returned(spec, row)
            fill()
    finally:
        with contextlib.suppress(Exception):  # (a lost scheduler: nothing to say goodbye to)
            client.close(timeout=CLOSE_S)
    return unfinished


RECORDING_FILES = "recording_files"
"""A row's key (never stored) for the run's recording files a Dask task returns."""


def write_recordings(out: Path, files: dict[str, bytes]) -> None:
    """Write a run's recording files, returned by its task, into ``OUT/recordings`` for the
    sweep's merge (:func:`workbench.runs.local_pool.merge_run_recordings`); a file that
    cannot be written is left out (a recording is a view of the results)."""
    for name, data in files.items():
        if Path(name).name != name or name.startswith("."):
            continue  # a plain file name, as the child makes them: nothing else is written
        target = out / RECORDINGS_DIR / f"{time.time_ns()}-{name}"
        write = lambda temporary, data=data: Path(temporary).write_bytes(data)  # noqa: E731
        with contextlib.suppress(OSError):
            atomic_write(target, write, durable=False, root=out)


WATCH_S = 1.0  # s between looks at the client while no run finishes
LOST_AFTER_S = 60.0  # s the client may stay disconnected (reconnecting) before it is lost
SCATTER_S = 10.0  # s a copy to every worker may take before one copy has to do
CLOSE_S = 10.0  # s to close the client


class _ClientWatch:
    """Whether the client lost its scheduler: closed (distributed closes it when its
    reconnection times out), or not running for :data:`LOST_AFTER_S` seconds."""

    def __init__(self, client: Any, address: str) -> None:
        self.client, self.address = client, address
        self.since: float | None = None  # when it was first seen not running

    def lost(self) -> str | None:
        """Why the runs not done will never finish (one line), or None while they may."""
        status = str(getattr(self.client, "status", "unknown"))
        if status == "running":
            self.since = None
            return None
        now = time.monotonic()
        self.since = now if self.since is None else self.since
        if status in ("closed", "closing", "failed") or now - self.since > LOST_AFTER_S:
            return (
                f"the Dask scheduler {self.address} was lost (client {status}); "
                "start it again (or resume on the local pool, without a scheduler)"
            )
        return None


def _has_workers(client: Any) -> bool:
    """Whether the scheduler has a worker (True when it cannot say: scatter tells then)."""
    try:
        return bool(client.nthreads())
    except Exception:  # noqa: BLE001 - a lost scheduler: the submit says it
        return True


NO_WORKER_S = 5.0  # s without a finished run before a scheduler without workers is said


class _IdleWatch:
    """Says once (again after runs finished meanwhile) that the scheduler has no worker
    while no run finishes for :data:`NO_WORKER_S` seconds: the runs wait for one (an
    adaptive cluster starts them on demand), and the sweep showed nothing at all."""

    def __init__(self, client: Any, address: str, say: Callable[[str], None]) -> None:
        self.client, self.address, self.say = client, address, say
        self.since, self.said = time.monotonic(), False

    def finished(self) -> None:
        self.since, self.said = time.monotonic(), False

    def check(self, now: bool = False) -> None:
        """Say it if there is no worker and no run finished lately (``now``: at once)."""
        if self.said or (not now and time.monotonic() - self.since < NO_WORKER_S):
            return
        if str(getattr(self.client, "status", "")) != "running":  # lost: _ClientWatch says it
            return
        try:
            workers = self.client.nthreads()
        except Exception:  # noqa: BLE001 - a lost scheduler: _ClientWatch says it
            return
        if not workers:
            self.said = True
            self.say(
                f"waiting for a Dask worker: the scheduler {self.address} has none; the runs "
                f"start when one connects (`dask worker {self.address}`), or stop with "
                "Ctrl-C and resume later"
            )


def _lost_message(error: BaseException) -> str:
    """Why a Dask task gave no result, in one line (a lost scheduler raises with no text).
    A workbench error the worker raised (not InfrastructureError) is its set-up's, e.g. a
    plugin module importing a package not installed there: said so, with the remedy."""
    if isinstance(error, WorkbenchError) and not isinstance(error, InfrastructureError):
        return (
            f"a Dask worker could not set up the run: {one_line(error)}; install what it "
            "needs on every worker (the specification's local modules are sent with the "
            "work; installed packages and the client's other folders are not)"
        )
    if not str(error).strip():
        return f"dask task lost ({type(error).__name__}: its worker or the scheduler was lost)"
    return f"dask task failed: {one_line(error)}"


if __name__ == "__main__":
    if sys.argv[1:] == ["--run-one"]:
        _run_one_main()
    elif sys.argv[1:2] == ["--serve"] and len(sys.argv) == 3:
        _serve_main(int(sys.argv[2]))
    else:
        sys.exit("usage: python -m workbench.runs.dask_pool --run-one < request.json | --serve FD")
