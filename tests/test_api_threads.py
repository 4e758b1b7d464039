"""``wb.run`` in a notebook is timed as a sweep's worker times it: its BLAS/OpenMP pools
hold the workers' thread count during the run (a first run with 2 threads a pool took
68 ms of CPU in 35 ms of wall time: the pools' threads spun beside the integration), and
the caller's limits and variables are back afterwards."""

from __future__ import annotations

import os

import pytest
from threadpoolctl import ThreadpoolController, threadpool_limits

import workbench as wb
from workbench.execution.worker_env import LIBRARY_VARIABLES, worker_threads


def pool_threads() -> dict[str, int]:
    return {lib.filepath: lib.num_threads for lib in ThreadpoolController().lib_controllers}


def test_a_run_in_this_process_uses_the_workers_threads_and_gives_the_callers_back() -> None:
    import scipy.linalg  # noqa: F401 - the pools a run uses, loaded as a notebook has them

    variables = {name: os.environ.get(name) for name in LIBRARY_VARIABLES}
    with threadpool_limits(limits=2):
        if max(pool_threads().values(), default=1) < 2:
            pytest.skip("no BLAS/OpenMP pool here can hold 2 threads (one CPU, or pinned)")
        callers = pool_threads()
        result = wb.run("simple-pendulum", "minimal-ode", "scipy-dop853", rtol=1e-6)
        assert result.row["status"] == "ok"
        assert result.row["threads"] == worker_threads() == 1  # as a sweep's row says
        after = pool_threads()
        assert {path: after[path] for path in callers} == callers  # the caller's limits back
    assert {name: os.environ.get(name) for name in LIBRARY_VARIABLES} == variables
