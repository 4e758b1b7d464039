"""The close calls of a sweep timed again, at moments apart, once its runs are done.

A run's own samples are taken back to back and share their moment: on a shared machine
a slow second slows them all, so they agree with each other far better than with a
second sweep (on a KVM Xeon the same integration's median moved 15.8-27 ms, 5-95 %, over
four minutes while its own three samples agreed within 3 %; slow spells lasted 0.1-4 s:
docs/performance.md). Two sweeps then named different cheapest pairs.

So, after the runs, the runs a decision hinges on (``choose(rows)``: the layers above
name them, e.g. the pairs within a few times of a cell's cheapest) are integrated again
``rounds`` times in ``jobs`` processes (a model's runs in one): a first round builds and
warms them (untimed), then each round times each run once, in a shuffled order, a round
beginning at least :data:`GAP_S` after the one before. A run's row then holds the median
over these samples and its own (which count as one:
:func:`workbench.execution.timing.retimed_columns`), and ``retimed``, how many were
added. Only runs whose samples fit the sweep's repeat budget (CPU seconds a run) are
timed again; a run already re-timed is not again, and a sample that did other work than
the row (another count of steps or evaluations) leaves the row as it was, warned. The
rows are rewritten whole; nothing else changes.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing.connection
import os
import random
import signal
import sys
import time
from collections import defaultdict
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pandas as pd

from workbench import files
from workbench.errors import one_line_text
from workbench.execution.execute import RunSpec, equations_held, equations_key, execute_run
from workbench.execution.row_schema import migrate_row
from workbench.execution.timing import STAT_FIELDS, Timing, retimed_columns
from workbench.execution.worker_env import pin_threads
from workbench.plugin import registry
from workbench.plugin.local_modules import import_plugin_modules
from workbench.runs import store
from workbench.runs.local_pool import append_client_paths

GAP_S = 2.0  # a round begins at least this long after the one before (slow spells: 0.1-4 s)
SAMPLE_OVERHEAD_S = 0.015
"""Seconds a sample costs beside its integration (a run's set-up in ``execute_run``): the
full suite's 495 close calls took 79.6 s in 2 processes against 54 s of their
integrations' CPU (Intel Xeon, 2026-11-29: 17 ms a sample). That excess held the
processes' start-up and builds too, counted apart since (:func:`phase_seconds`), so it
errs high: a quick-suite sample took 0.5-1 ms of CPU beside its integration once built."""
CHILD_START_S = 1.5
"""Seconds a timing process takes before its first run: a fresh interpreter's imports
(Python, workbench, CasADi, SciPy) and plugin discovery, as a Dask worker's child pays
them (1.1-1.6 s alone, 1.2-1.9 s two at once; a local child forked from the pool's
forkserver 0.2 s; Intel Xeon, 2 cores, load 1.5-2.6, 2026-11-29). Its models' builds
come on top: :func:`build_seconds`."""
HELD_MODELS = 32  # models the timing process keeps built (the pool's workers keep 2)
RETIMED_FILE = "retimed.json"  # what the last re-timing did, its key beside it

Sample = tuple[str, str, float, float, dict[str, Any]]  # run id, status, wall, CPU, counts


def sample_rounds(
    specs: list[RunSpec], rounds: int, send: Callable[[Sample | None], None], gap: float = GAP_S
) -> None:
    """Integrate ``specs`` ``rounds`` + 1 times, the first round untimed (builds, warms),
    each timed sample given to ``send``; a timed round begins ``gap`` s after the last
    began.

    A round takes the models in a shuffled order and each model's runs in a shuffled
    order, one after another; the process keeps :data:`HELD_MODELS` models built and
    takes more in chunks of that many (all rounds of one chunk, then the next), so each
    is built once."""
    timing = Timing(repeats=1, repeat_budget=0.0)
    groups: dict[Any, list[RunSpec]] = defaultdict(list)
    for spec in specs:
        groups[equations_key(spec)].append(spec)
    models = list(groups.values())
    shuffle = random.Random(0).shuffle  # (the same order for the same runs)
    with equations_held(min(len(models), HELD_MODELS)):
        # a chunk of models at a time, all its rounds: cycling through more models than
        # are held would build every one again each round
        for first in range(0, len(models), HELD_MODELS):
            chunk = models[first : first + HELD_MODELS]
            for round_ in range(rounds + 1):
                began = time.monotonic()
                shuffle(chunk)
                for runs in chunk:
                    shuffle(runs)
                    for spec in runs:
                        row = execute_run(spec, timing=timing, measure=False).row
                        counts = {name: row.get(name) for name in STAT_FIELDS}
                        if round_:
                            send((spec.run_id, row["status"], row["integrate_s"],
                                  row["integrate_cpu_s"], counts))  # fmt: skip
                        else:
                            send(None)  # (alive: the parent waits a time limit a message)
                if 0 < round_ < rounds:  # (the untimed round needs no distance)
                    time.sleep(max(0.0, gap - (time.monotonic() - began)))


def timer_main(conn: Any, plugins: list[str], sys_path: list[str], specs: list[dict],
                rounds: int, gap: float) -> None:  # fmt: skip
    """The timing process: set up as a pool worker, then :func:`sample_rounds` (also a
    Dask worker's timing child: :mod:`workbench.runs.dask_retime`)."""
    pin_threads()  # the threads the runs had (workbench.execution.worker_env)
    append_client_paths(sys_path)  # after this process's own, as a pool worker does
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    import warnings

    warnings.filterwarnings("ignore")
    with open(os.devnull, "w") as quiet:  # a plugin's prints: the runs' logs have them
        os.dup2(quiet.fileno(), 1)
        os.dup2(quiet.fileno(), 2)
    import_plugin_modules(plugins)
    registry.REGISTRY.discover()
    runs = [RunSpec.from_dict(data) for data in specs]
    sample_rounds(runs, rounds, lambda sample: conn.send(("sample", sample)), gap)
    conn.send(("done", None))


def retime_close_calls(
    out: Path,
    specs: Iterable[RunSpec],
    choose: Callable[[pd.DataFrame], Iterable[str]],
    rounds: int,
    budget: float,
    limit: float,
    plugins: list[str],
    say: Callable[[str], None],
    context: Any = None,
    gap: float = GAP_S,
    jobs: int = 1,
    sampler: Callable[..., None] | None = None,
) -> list[str]:
    """Time the close calls among ``specs``' done runs again (module docstring); return
    the run ids whose rows were rewritten.

    ``budget``: CPU seconds a run's samples may take (the sweep's repeat budget);
    ``limit``: seconds a sample may take (the sweep's time limit): a slower one ends the
    re-timing, the rows keeping what they had; ``context``: the multiprocessing context
    of the timing processes (None: sampled in this process), ``jobs`` of them at once,
    each with its models' runs (:func:`balanced_bins`; a busy core beside a run did not
    slow it: docs/performance.md); ``sampler``: takes the samples instead, called as
    ``sampler(runs, cost, rounds, gap, limit, plugins, take)`` (a Dask cluster's:
    :mod:`workbench.runs.dask_retime`)."""
    by_id = {spec.run_id: spec for spec in specs}
    rows = _rows(out, by_id)
    if rounds < 1 or not rows:
        return []
    # chosen among all the sweep's rows (a resume's new runs beside the earlier ones),
    # then those already timed again left out
    chosen = [
        run_id
        for run_id in dict.fromkeys(choose(store.frame_from_rows(rows.values())))
        if run_id in rows and not rows[run_id].get("retimed")
        and _fits(rows[run_id], rounds, budget)
    ]  # fmt: skip
    if not chosen:
        return []
    children = sampler is not None or context is not None  # (else timed in this process)
    seconds = phase_seconds(rows, by_id, chosen, rounds, gap, jobs, children)
    say(
        f"timing {len(chosen)} close call(s) again: {rounds} rounds at least {gap:g} s apart "
        f"(about {seconds:.0f} s; `--retime 0` skips it)"
    )
    samples: dict[str, list[Sample]] = defaultdict(list)

    def take(sample: Sample | None) -> None:
        if sample is not None:
            samples[sample[0]].append(sample)

    runs = [by_id[run_id] for run_id in chosen]
    cost = {run_id: rows[run_id]["integrate_cpu_s"] for run_id in chosen}
    if sampler is not None:
        sampler(runs, cost, rounds, gap, limit, plugins, take)
    elif context is None:
        sample_rounds(runs, rounds, take, gap)
    else:
        bins = balanced_bins(runs, cost, jobs)
        _sample_in_children(context, bins, rounds, gap, plugins, limit, take)
    rewritten = []
    for run_id in chosen:
        row = retimed_row(rows[run_id], samples[run_id])
        if row is not None:
            files.write_json_atomic(row, store.row_path(out, run_id), durable=False,
                                    root=out, indent=None)  # fmt: skip
            rewritten.append(run_id)
    return rewritten


def phase_seconds(rows: dict[str, dict[str, Any]], specs: dict[str, RunSpec], chosen: list[str],
                  rounds: int, gap: float, jobs: int, children: bool = True) -> float:  # fmt: skip
    """About how long the timing of ``chosen`` takes in ``jobs`` processes (``children``;
    else in this one): a process's start-up (:data:`CHILD_START_S`) and its models' builds
    (:func:`build_seconds`), then as :func:`sample_rounds` goes, an untimed round and
    ``rounds`` timed ones, each but the last at least ``gap`` s; a round is the runs'
    measured integration CPU and :data:`SAMPLE_OVERHEAD_S` each, shared by the processes."""
    jobs = max(1, min(jobs, len({equations_key(specs[r]) for r in chosen})))
    integration = sum(rows[r]["integrate_cpu_s"] for r in chosen)
    round_ = (integration + len(chosen) * SAMPLE_OVERHEAD_S) / jobs
    start = (CHILD_START_S if children else 0.0) + build_seconds(rows, specs, chosen) / jobs
    return start + 2 * round_ + (rounds - 1) * max(gap, round_)


def build_seconds(rows: dict[str, dict[str, Any]], specs: dict[str, RunSpec],
                  chosen: list[str]) -> float:  # fmt: skip
    """Seconds the models of ``chosen`` took to build once each, as the runs measured it:
    a model's most ``build_s`` + ``init_s`` among its rows (a worker's first run of it
    builds it, the others reuse it: 0). A timing process builds each of its models once
    before its first sample; C compiled by a run is loaded from the disk cache, not
    counted."""
    built: dict[Any, float] = defaultdict(float)
    for run_id, row in rows.items():
        seconds = sum(
            value for value in (row.get("build_s"), row.get("init_s"))
            if isinstance(value, int | float) and math.isfinite(value)
        )  # fmt: skip
        key = equations_key(specs[run_id])
        built[key] = max(built[key], seconds)
    return sum(built[key] for key in {equations_key(specs[r]) for r in chosen})


def _rows(out: Path, specs: dict[str, RunSpec]) -> dict[str, dict[str, Any]]:
    """The rows of ``specs`` in ``out`` (those run)."""
    rows = {}
    for run_id in specs:
        path = store.row_path(out, run_id)
        row = store.read_row(path) if path.is_file() else None
        if row is not None:
            rows[run_id] = migrate_row(row, path)
    return rows


def _fits(row: dict[str, Any], rounds: int, budget: float) -> bool:
    """An ok run whose samples (the warming one too) fit ``budget`` CPU seconds."""
    cpu = row.get("integrate_cpu_s")
    finite = isinstance(cpu, int | float) and math.isfinite(cpu)
    return row.get("status") == "ok" and finite and cpu * (rounds + 1) <= budget


def retimed_row(row: dict[str, Any], samples: list[Sample]) -> dict[str, Any] | None:
    """``row`` with ``samples`` (two at least, all ok); warned instead if one did other
    work; None when too few came (a slow sample ended the re-timing)."""
    good = [s for s in samples if s[1] == "ok"]
    other = [s for s in good if any(s[4][k] != row.get(k) for k in STAT_FIELDS)]
    if other:
        counts = ", ".join(
            f"{k} {row.get(k)} then {other[0][4][k]}"
            for k in STAT_FIELDS
            if other[0][4][k] != row.get(k)
        )
        found = f"not reproducible: timed again, the integration did other work ({counts})"
        had = row.get("warnings") if isinstance(row.get("warnings"), str) else ""
        return row | {"warnings": one_line_text("; ".join(filter(None, [had, found])))}
    if len(good) < 2 or len(good) < len(samples):
        return None
    return row | retimed_columns(row, [s[2] for s in good], [s[3] for s in good])


def _sample_in_children(context: Any, bins: list[list[RunSpec]], rounds: int, gap: float,
                        plugins: list[str], limit: float,
                        take: Callable[[Sample | None], None]) -> None:  # fmt: skip
    """:func:`sample_rounds` of each bin in a process of ``context``, all at once; each
    message awaited at most ``limit`` + ``gap`` seconds, a process slower than that
    killed (its runs keep what they had), and every process on the way out."""
    children = []
    for runs in bins:
        parent_end, child_end = context.Pipe()
        specs = [r.to_dict() for r in runs]
        process = context.Process(
            target=timer_main,
            args=(child_end, plugins, list(sys.path), specs, rounds, gap),
            daemon=True,
        )
        process.start()
        child_end.close()
        children.append((process, parent_end))
    waiting = {conn: process for process, conn in children}
    try:
        while waiting:
            ready = multiprocessing.connection.wait(list(waiting), limit + gap)
            if not ready:
                break  # a sample slower than a run may take: the rest keep their rows
            for conn in ready:
                try:
                    kind, sample = conn.recv()
                except (EOFError, OSError):  # the process died
                    kind, sample = "done", None
                if kind == "done":
                    del waiting[conn]
                else:
                    take(sample)
    finally:
        for process, conn in children:
            if process.is_alive():
                process.kill()
            process.join(timeout=10)
            with contextlib.suppress(OSError):
                conn.close()


def balanced_bins(runs: list[RunSpec], cost: dict[str, float], count: int) -> list[list[RunSpec]]:
    """``runs`` in at most ``count`` bins of about equal ``cost`` (run id -> seconds), the
    runs of one model (:func:`equations_key`) in one bin, so each process builds it once."""
    models: dict[Any, list[RunSpec]] = defaultdict(list)
    for spec in runs:
        models[equations_key(spec)].append(spec)
    bins: list[list[RunSpec]] = [[] for _ in range(max(1, min(count, len(models))))]
    loads = [0.0] * len(bins)
    weight = lambda group: sum(cost[spec.run_id] for spec in group)  # noqa: E731
    for group in sorted(models.values(), key=weight, reverse=True):
        lightest = loads.index(min(loads))
        bins[lightest] += group
        loads[lightest] += weight(group)
    return bins
