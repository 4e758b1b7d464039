"""The close calls of a Dask sweep timed again on the cluster (:mod:`workbench.runs.retime`).

The runs were timed on the workers' machines: timed again on the client, the close calls
would be compared in another machine's costs. So each bin of close calls (a model's runs
together: :func:`~workbench.runs.retime.balanced_bins`, a bin a worker thread) goes to a
worker as one task, which times its rounds in a fresh child process
(:func:`~workbench.runs.retime.sample_rounds`): the child's CPU time is the runs' alone,
not the Dask worker's threads'. The local plugin modules go with the task
(:mod:`workbench.runs.shipping`); the rounds need no reference (they stop after the
integration). A task whose worker is lost, or a sample slower than the time limit, leaves
its runs' rows as they were.
"""

from __future__ import annotations

import multiprocessing.connection
import os
import socket
import subprocess
import sys
from collections.abc import Callable
from typing import Any

from workbench.execution.execute import RunSpec
from workbench.execution.worker_env import thread_environment
from workbench.runs.dask_pool import client_paths
from workbench.runs.retime import SAMPLE_OVERHEAD_S, Sample, balanced_bins, timer_main
from workbench.runs.shipping import pack_modules, unpack_modules

START_S = 120.0  # a child's imports and plugins: its first message comes within this


class ClusterSampler:
    """A ``sampler`` for :func:`~workbench.runs.retime.retime_close_calls` that times the
    close calls on the Dask cluster at ``scheduler`` (see the module docstring); ``jobs``:
    its worker threads, a bin of runs each. Made, it has connected (a scheduler gone
    since the runs raises the client's error here)."""

    def __init__(self, scheduler: str, say: Callable[[str], None] = print) -> None:
        import distributed

        self.say = say
        self.client = distributed.Client(scheduler, timeout="10s")
        self.jobs = max(1, sum(self.client.nthreads().values()))

    def __call__(self, runs: list[RunSpec], cost: dict[str, float], rounds: int, gap: float,
                 limit: float, plugins: list[str],
                 take: Callable[[Sample | None], None]) -> None:  # fmt: skip
        import distributed

        paths = client_paths()
        modules = pack_modules(plugins)
        bins = balanced_bins(runs, cost, self.jobs)
        futures = [
            self.client.submit(time_on_worker, [spec.to_dict() for spec in runs_of_bin],
                               rounds, gap, limit, plugins, paths, modules, pure=False)
            for runs_of_bin in bins
        ]  # fmt: skip
        seconds = phase_limit(bins, cost, rounds, gap, limit)
        try:
            for future in distributed.as_completed(futures, timeout=seconds):
                try:
                    samples = future.result()
                except Exception:  # noqa: BLE001, S112 - a lost worker: its runs' rows stay
                    continue
                for sample in samples:
                    take(tuple(sample))
        except TimeoutError:  # (no worker left, or one far slower): the rows stay
            self.client.cancel(futures)
            self.say(
                f"close calls: the cluster's timing did not end within {seconds:.0f} s (no "
                "worker, or one far slower than the runs); the runs not timed again keep "
                "their own samples"
            )

    def close(self) -> None:
        self.client.close()


SLACK = 4.0  # times the bins' measured cost a task may take before the phase gives up


def phase_limit(bins: list[list[RunSpec]], cost: dict[str, float], rounds: int, gap: float,
                limit: float) -> float:  # fmt: skip
    """Seconds the cluster's timing tasks may take in all: a child's start-up, the gaps,
    and :data:`SLACK` times the largest bin's rounds (its runs' measured integration and
    set-up), at least one time limit. Past it the phase ends, the rows keeping what they
    had: runs wait for a worker however late, an optional phase does not (a cluster
    whose workers left after the runs would wait forever)."""
    largest = max(sum(cost[spec.run_id] + SAMPLE_OVERHEAD_S for spec in runs) for runs in bins)
    return START_S + rounds * gap + max(limit, SLACK * (rounds + 1) * largest)


def time_on_worker(specs: list[dict[str, Any]], rounds: int, gap: float, limit: float,
                   plugins: list[str], sys_path: list[str],
                   modules: dict[str, Any]) -> list[Sample]:  # fmt: skip
    """A Dask task: :func:`~workbench.runs.retime.sample_rounds` of ``specs`` in a fresh
    child of this worker; its samples, those taken before a sample ran longer than
    ``limit`` s (the child is then killed) or the child died."""
    plugins = unpack_modules(list(plugins), modules or {})
    ours, theirs = socket.socketpair()
    env = dict(os.environ) | thread_environment()  # read by BLAS/OpenMP as they load
    process = subprocess.Popen(
        [sys.executable, "-m", "workbench.runs.dask_retime", "--time", str(theirs.fileno())],
        pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL, env=env,
    )  # fmt: skip
    theirs.close()
    conn = multiprocessing.connection.Connection(ours.detach())
    samples: list[Sample] = []
    try:
        conn.send((plugins, sys_path, specs, rounds, gap))
        wait = START_S + limit  # the first message follows the imports and a first run
        while conn.poll(wait):
            kind, sample = conn.recv()
            if kind == "done":
                break
            if sample is not None:
                samples.append(sample)
            wait = limit + gap
    except (EOFError, OSError):  # the child died: the samples taken stand
        pass
    finally:
        if process.poll() is None:
            process.kill()
        process.wait()
        conn.close()
    return samples


def _time_main(fd: int) -> None:
    """``python -m workbench.runs.dask_retime --time FD``: the timing rounds of the
    request received on the socket ``FD`` (see :func:`time_on_worker`)."""
    conn = multiprocessing.connection.Connection(fd)
    plugins, sys_path, specs, rounds, gap = conn.recv()
    timer_main(conn, plugins, sys_path, specs, rounds, gap)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--time":
        _time_main(int(sys.argv[2]))
    else:
        sys.exit("usage: python -m workbench.runs.dask_retime --time FD")
