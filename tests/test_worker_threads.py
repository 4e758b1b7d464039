"""Workers run with a fixed, recorded BLAS/OpenMP thread count, so a run gives the same
numbers wherever it runs (issue 18.14: under Dask 2 of 36 rows differed from the local
pool, n_rhs 1064 against 1062, and OMP_NUM_THREADS=1 reproduced them)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.execution.worker_env import LIBRARY_VARIABLES, THREADS_VARIABLE
from workbench.runs import store

ROOT = Path(__file__).resolve().parents[1]
# Radau's complex LU (LAPACK through OpenBLAS): with 1 and 2 BLAS threads this run's
# err_max differs in the 5th digit (2.518763e-08 against 2.518683e-08, measured in-process)
RUN = ("binary-tree", "minimal-ode", "scipy-radau")
COMPARED = ["status", "n_rhs", "n_jac", "n_steps", "n_rejected", "err_max", "err_end"]


def environment(threads: str | None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in (*LIBRARY_VARIABLES, THREADS_VARIABLE)}
    if threads is not None:
        env |= {name: threads for name in LIBRARY_VARIABLES}
    return env


def test_pinned_process_limits_loaded_blas_to_one_thread() -> None:
    code = (
        "import numpy, scipy.linalg\n"
        "from workbench.execution.worker_env import pin_threads, threads_in_force\n"
        "before = threads_in_force(); pin_threads()\n"
        "print(before, threads_in_force())\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], env=environment("2"), capture_output=True, text=True,
        timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    before, after = result.stdout.split()
    assert (before, after) == ("2", "1")


@pytest.mark.parametrize(
    ("sweep_threads", "child_threads"),
    [("2", "1"), pytest.param("4", None, marks=pytest.mark.slow)],
    ids=["sweep-2-child-1", "sweep-4-child-unset"],
)
def test_local_pool_and_child_process_rows_agree_bit_for_bit(
    tmp_path, sweep_threads, child_threads
) -> None:
    problem, formalism, integrator = RUN
    local, child = tmp_path / "local", tmp_path / "child"
    spec = tmp_path / "sweep.toml"
    spec.write_text(
        f'out = "{local.as_posix()}"\njobs = 1\ntime_limit = 300.0\n'
        f'problems = ["{problem}"]\n'
        f'formalisms = [{{ name = "{formalism}", options = {{ index = [1] }} }}]\n'
        f'integrators = ["{integrator}"]\ntolerances = [1e-6]\n'
    )
    swept = subprocess.run(
        [sys.executable, "-m", "workbench", "sweep", "--no-report", str(spec)], cwd=ROOT,
        env=environment(sweep_threads), capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert swept.returncode == 0, swept.stderr
    # `workbench run` executes in a child process, as a Dask task does
    ran = subprocess.run(
        [sys.executable, "-m", "workbench", "run", problem, "-f", formalism, "-i", integrator,
         "--rtol", "1e-6", "-o", "formalism.index=1", "--out", str(child)],
        # (no compile option: `run` and sweeps share the default, compile=auto)
        cwd=ROOT, env=environment(child_threads),
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert ran.returncode == 0, ran.stderr
    a = store.load_results(local).iloc[0]
    b = store.load_results(child).iloc[0]
    assert a["run_id"] == b["run_id"]
    assert a["threads"] == b["threads"] == 1
    assert a["status"] == "ok"
    for column in COMPARED:
        assert a[column] == b[column], column
