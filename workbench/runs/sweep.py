"""Running a sweep: the runs not yet done, through a local pool or a Dask cluster.

Execution (:func:`run_sweep`): runs whose row and series in ``<out>`` are whole are
skipped (resume; :mod:`workbench.runs.resume` says what is broken, stale or redone).
Runs go to a small pool of worker processes of our own (concurrent.futures
cannot kill a running task): each worker builds and caches equations, runs, and writes the
run's files itself; the parent enforces each run's time limit by killing the worker (row
``timeout``) and starting a fresh one, and a worker that dies mid-run (segfault, SIGKILL)
gives a ``failed`` row "worker process died (exit code ...)". With a Dask scheduler
address, runs are submitted through ``distributed.Client(address).get_executor()``; each
task hands its run to a long-lived child of its Dask worker (the local pool's worker loop,
killed and restarted on a time limit) and returns the row and series to the client, which
writes them (:mod:`workbench.runs.dask_pool`). At the start
the full environment is written to ``<out>/environment.json``; at the end the close calls
are timed again at moments apart (:mod:`workbench.runs.retime`) and the rows are
consolidated into ``<out>/results.parquet``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from workbench import files
from workbench.errors import ConfigError, one_line
from workbench.execution.environment import sweep_environment
from workbench.execution.timing import Timing, check_budget, check_repeats, retime_problem
from workbench.files import make_dirs, sync_file_system
from workbench.runs import local_pool, output_keys, store
from workbench.runs.dask_pool import check_scheduler_address, dask_log_in, run_dask
from workbench.runs.dask_retime import ClusterSampler
from workbench.runs.estimate import estimate_lines, known_costs
from workbench.runs.local_pool import merge_run_recordings, run_local
from workbench.runs.out_lock import out_lock
from workbench.runs.progress import progress_bar
from workbench.runs.recording_batches import unwritten_runs
from workbench.runs.resume import plan_resume
from workbench.runs.retime import GAP_S, RETIMED_FILE, retime_close_calls
from workbench.runs.sweep_spec import SweepSpec, load_spec, parse_spec

__all__ = ["SweepSpec", "SweepSummary", "load_spec", "parse_spec", "run_sweep"]

# ---- execution ----------------------------------------------------------------------


@dataclass
class SweepSummary:
    out: Path
    counts: Counter
    already_done: int
    seconds: float
    results: Path | None = None
    recording: Path | None = None
    # stale rows kept, not redone (run id -> what changed): the report marks them
    stale: dict[str, str] = field(default_factory=dict)
    # runs left without a row by the infrastructure (run id -> why): a resume redoes them
    unfinished: dict[str, str] = field(default_factory=dict)
    # outputs kept as they were, their inputs unchanged (results.parquet, recording.rrd)
    unchanged: list[str] = field(default_factory=list)
    # the rows as results.parquet was remade from them (store.load_results), when every row
    # file was readable: the sweep's report uses them rather than read the files again
    rows: Any = field(default=None, repr=False, compare=False)

    @property
    def total(self) -> int:
        """Runs attempted, completed or not."""
        return sum(self.counts.values())


def run_sweep(
    sweep: SweepSpec,
    jobs: int | None = None,
    out: str | os.PathLike[str] | None = None,
    time_limit: float | None = None,
    scheduler: str | None = None,
    show_progress: bool = True,
    recorder: Any = None,
    rerun: frozenset[str] | set[str] = frozenset(),
    fresh: bool = False,
    say: Callable[[str], None] | None = None,
    repeats: int | None = None,
    repeat_budget: float | None = None,
    wait: bool = False,
    progress: Callable[[int, int], None] | None = None,
    close_calls: Callable[[Any], Any] | None = None,
    retime: int | None = None,
) -> SweepSummary:
    """Execute the runs of ``sweep`` not yet in ``out`` and consolidate the results.

    ``recorder``: what records each run (a class, made once a worker; with ``scheduler``
    importable by the Dask workers, a file a run sent back with its row:
    ``recorder()`` with ``begin_file(path)``, ``log_run(...)``, ``fits(spec)`` (whether
    a run may join the file begun: :mod:`workbench.runs.recording_batches`) and
    ``end_file()``; class attributes ``suffix`` and ``merge(files, out) -> Path``, and optionally
    ``prepare()`` and ``merged_file``, the name of merge's file in ``out``: it is then
    merged again only when the runs' files changed), e.g.
    :class:`workbench.outputs.recording.SweepRecorder`; None records nothing. Passed in, so
    the runs layer knows no recording format.

    ``rerun`` (kinds of :data:`workbench.runs.resume.RERUN_KINDS`) and ``fresh`` redo done
    runs (:func:`workbench.runs.resume.plan_resume`); ``say`` receives the one-line
    findings of the resume (default: printed on stderr). ``repeats`` and ``repeat_budget``
    override the specification's timing of each integration (:mod:`workbench.execution.timing`).

    ``out`` is locked while the sweep runs (:func:`workbench.runs.out_lock.out_lock`):
    OutputBusyError if another process holds it, or with ``wait`` wait for it.
    ``progress(done, total)`` is called as each run finishes (e.g. a notebook's bar).

    ``close_calls(rows)``: the run ids the sweep's decisions hinge on (a DataFrame of its
    done rows); they are timed again ``retime`` times (default the specification's) at
    moments apart once the runs are done (:mod:`workbench.runs.retime`; with a Dask
    scheduler on its workers, whose machines timed the runs:
    :mod:`workbench.runs.dask_retime`). Passed in, as ``recorder`` is: the runs layer
    knows no report."""

    started = time.perf_counter()
    out_dir = Path(out) if out is not None else sweep.out
    jobs = int(jobs or sweep.jobs)
    limit = float(time_limit or sweep.time_limit)
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, not {jobs}")
    if not limit > 0:
        raise ConfigError(f"--time-limit must be > 0 s, not {limit}")
    files.usable_cache_dir()  # a file there failed every run, one by one
    if scheduler:
        check_scheduler_address(scheduler)  # before anything is written into out_dir
    rounds = sweep.retime if retime is None else retime
    if retime_problem(rounds):
        raise ConfigError(f"--retime {retime_problem(rounds)}")
    timing = Timing(
        check_repeats(sweep.repeats if repeats is None else repeats, "--repeats"),
        check_budget(
            sweep.repeat_budget if repeat_budget is None else repeat_budget, "--repeat-budget"
        ),
        jobs,
    )
    # one command at a time on out_dir, and no symbolic link in it (workbench.runs.out_lock)
    with out_lock(out_dir, wait=wait, say=say):
        store.remove_stale_temporaries(out_dir)  # from a sweep killed mid-write
        plan = plan_resume(sweep.runs, out_dir, frozenset(rerun), fresh)
        todo = plan.todo
        rebuild = _unwritten_recordings(sweep, todo, out_dir) if recorder and not scheduler else []
        lines = plan.lines() + _estimate(sweep, todo, out_dir, jobs, limit, scheduler)
        if close_calls is not None and rounds and todo:
            where = " on the cluster's workers" if scheduler else ""
            lines.append(
                f"then the close calls timed again{where}: {rounds} rounds at least "
                f"{GAP_S:g} s apart, "
                f"at least {(rounds - 1) * GAP_S:g} s more (`--retime 0` skips it)"
            )
        if rebuild:
            lines.append(
                f"{len(rebuild)} done run(s) have no recording (their worker was killed "
                "before writing it): recording them again, rows kept"
            )
        for line in lines:
            (say or _stderr)(line)
        make_dirs(out_dir / store.RUNS_DIR, out_dir)
        make_dirs(out_dir / "references", out_dir)
        # the machine that starts the sweep (with Dask, the client; rows name their workers)
        environment = sweep_environment()
        files.write_json_atomic(environment, out_dir / store.ENVIRONMENT_FILE, root=out_dir)
        if sweep.text:
            files.write_text_atomic(sweep.text, out_dir / "sweep.toml", root=out_dir)
        stale = {run_id: {"reason": why, "row": plan.stale_rows[run_id]}
                 for run_id, why in plan.stale.items()}  # fmt: skip
        store.write_plan(out_dir, (spec.run_id for spec in sweep.runs), sweep.source, stale)
        counts: Counter = Counter()
        states = sweep.store_trajectories
        # the local pool forks its workers: no thread may be running then (see worker_context)
        with _progress(len(todo), show_progress, threaded=bool(scheduler)) as advance:

            def record(status: str) -> None:
                counts[status] += 1
                advance(counts)
                if progress is not None:
                    progress(sum(counts.values()), len(todo))

            if scheduler:
                unfinished = run_dask(
                    todo, out_dir, limit, sweep.plugins, scheduler, record, timing, states,
                    recorder, say or _stderr,
                )  # fmt: skip
            else:
                tick = lambda: advance(None)  # noqa: E731
                unfinished = run_local(
                    todo,
                    out_dir,
                    limit,
                    sweep.plugins,
                    jobs,
                    record,
                    tick,
                    recorder,
                    timing,
                    states,
                    rebuild,
                )
        key = output_keys.rows_key(out_dir)
        if close_calls is not None and rounds:
            key = _retime(sweep, out_dir, key, close_calls, rounds, timing, limit, say, scheduler)
        sync_file_system(out_dir)  # the runs' rows and series, written without a sync each
        # remade only if their inputs changed (workbench.runs.output_keys): a resume with
        # nothing to do returns in seconds
        loaded: list[Any] = []  # the rows read by the consolidation, if it is done
        results, remade = output_keys.remake(
            out_dir / store.RESULTS_FILE,
            key,
            lambda: store.consolidate(out_dir, loaded),
            root=out_dir,
        )
        rows = loaded[0] if loaded and not loaded[0].attrs.get("unreadable") else None
        unchanged = [] if remade else [store.RESULTS_FILE]
        recording = None
        if recorder is not None:
            try:  # a recording is a view, never fatal to the results ...
                recording, remade = merge_run_recordings(recorder, out_dir)
                unchanged += [] if remade or recording is None else [recording.name]
            except OSError:
                raise  # ... but a full or read-only disk is said (rows kept; resume merges)
            except Exception:  # noqa: BLE001, S110
                pass
    return SweepSummary(
        out_dir,
        counts,
        len(sweep.runs) - len(todo),
        time.perf_counter() - started,
        results,
        recording,
        stale={} if "stale" in plan.rerun or fresh else plan.stale,
        unfinished=unfinished,
        unchanged=unchanged,
        rows=rows,
    )


def _retime(
    sweep: SweepSpec,
    out_dir: Path,
    key: str,
    close_calls: Callable[[Any], Any],
    rounds: int,
    timing: Timing,
    limit: float,
    say: Callable[[str], None] | None,
    scheduler: str | None = None,
) -> str:
    """The close calls timed again (:mod:`workbench.runs.retime`; with a Dask
    ``scheduler`` on its workers, :mod:`workbench.runs.dask_retime`) unless the rows are
    those the last re-timing left; the rows' key after it."""
    marker = out_dir / RETIMED_FILE
    if output_keys.is_current(marker, key):
        return key
    sampler, jobs = None, timing.workers
    # what distributed logs goes to OUT/logs/dask-client.log, as in the runs' phase
    with dask_log_in(out_dir) if scheduler else contextlib.nullcontext():
        if scheduler:
            try:
                sampler = ClusterSampler(scheduler, say or _stderr)
            except Exception as error:  # noqa: BLE001 - the scheduler gone since the runs
                (say or _stderr)(f"close calls not timed again: {one_line(error)[:200]}")
                return key
            jobs = sampler.jobs
        try:
            done = retime_close_calls(
                out_dir, sweep.runs, close_calls, rounds, timing.repeat_budget, limit,
                sweep.plugins, say or _stderr,
                None if sampler else local_pool.worker_context(), jobs=jobs, sampler=sampler,
            )  # fmt: skip
        finally:
            if sampler is not None:
                sampler.close()
    files.write_json_atomic({"rounds": rounds, "gap_s": GAP_S, "runs": done}, marker,
                            root=out_dir)  # fmt: skip
    key = output_keys.rows_key(out_dir) if done else key
    output_keys.remember(marker, key, out_dir)
    return key


def _unwritten_recordings(sweep: SweepSpec, todo: list[Any], out_dir: Path) -> list[Any]:
    """The done runs of ``sweep`` (not in ``todo``) whose recording a killed worker left
    unwritten (:mod:`workbench.runs.recording_batches`): to be recorded again."""
    unwritten = unwritten_runs(out_dir)
    if not unwritten:
        return []
    doing = {spec.run_id for spec in todo}
    return [spec for spec in sweep.runs if spec.run_id in unwritten - doing]


def _estimate(
    sweep: SweepSpec,
    todo: list[Any],
    out_dir: Path,
    jobs: int,
    limit: float,
    scheduler: str | None,
) -> list[str]:
    """The planned runs and how long they should take (:mod:`workbench.runs.estimate`)."""
    if scheduler:  # a cluster's workers are not counted here
        return [f"plan: {len(sweep.runs)} runs, {len(todo)} to run on the Dask cluster"]
    files = sorted((out_dir / store.RUNS_DIR).glob("*.json")) if todo else []
    rows = {path.stem: row for path in files if (row := store.read_row(path)) is not None}
    costs = known_costs(rows, limit, sweep.suite)
    return estimate_lines(todo, len(sweep.runs), jobs, costs)


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _progress(total: int, show: bool, threaded: bool = True):
    """advance(counts) for the shared bar (:mod:`workbench.runs.progress`); ``threaded=False``
    redraws it on each call instead of from rich's refresh thread (the local pool calls
    advance(None) at every wake-up)."""
    with progress_bar("sweep", total, show=show, transient=False, threaded=threaded) as bar:

        def advance(counts: Counter | None) -> None:
            if counts is None:
                bar.tick()
                return
            text = "  ".join(
                f"{s} {counts[s]}"
                for s in ("ok", "failed", "skipped", "timeout", "unfinished")
                if counts[s]
            )
            bar.update(sum(counts.values()), text)

        yield advance
