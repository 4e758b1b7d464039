"""The default sweep through a local Dask cluster against the local pool: wall time, rows.

Run: ``python -m benchmarks.dask_sweep [N_RUNS] [REPEATS]`` (defaults: the whole default
sweep, 1,080 runs, and 2 repeats). N_RUNS takes the first N runs of the default sweep, in
its order. Each repeat runs the sweep (``run_sweep``, into a fresh directory, no
recording, each in a fresh process, so the local pool forks its workers as
``workbench sweep`` does) on the local pool with 2 workers, then through a fresh
``LocalCluster`` (scheduler and 2 single-threaded worker processes on 127.0.0.1; its start-up is not
timed, the start of each Dask worker's child is), interleaved so that a change of the
machine's load hits both. Issue target: Dask within 1.3x of the local pool.

The rows must agree: the same run ids, statuses and every column but timings
(``*_s``, ``equations_cached``) and where the run executed (host, pid, ...), compared as
``benchmarks.torture`` does. Prints the table and writes
``benchmarks/results/dask_sweep.csv`` (one row a sweep).
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import pandas as pd

from benchmarks import help_if_asked
from workbench.execution.counted_work import COLUMNS as WORK_COLUMNS
from workbench.execution.timing import TIMING_COLUMNS
from workbench.runs.store import load_results
from workbench.runs.sweep import load_spec, run_sweep

RESULTS = Path(__file__).parent / "results"
# columns that say where or when a run executed, not what it computed
PLACE_COLUMNS = {"hostname", "host", "pid", "worker", "python", "platform", "started", "finished"}


def computed(frame: pd.DataFrame) -> pd.DataFrame:
    """The rows' computed columns (no timings, no place), indexed by run id."""
    columns = [
        c
        for c in frame.columns
        if not (
            c.endswith("_s")
            or c in {"equations_cached", "log", *TIMING_COLUMNS, *WORK_COLUMNS}
            or c in PLACE_COLUMNS
        )
    ]
    frame = frame[columns].set_index("run_id").sort_index()
    if "reference" in frame:  # whichever worker came first computed it, the others read it
        frame["reference"] = frame["reference"].str.replace(r" \(read from .*\)$", "", regex=True)
    return frame


def differences(local: pd.DataFrame, dask: pd.DataFrame) -> list[str]:
    """What differs between two sweeps' rows (empty: they agree)."""
    a, b = computed(local), computed(dask)
    if set(a.index) != set(b.index):
        return [f"run ids: {len(set(a.index) ^ set(b.index))} not in both"]
    found = []
    for column in sorted(set(a.columns) | set(b.columns)):
        if column not in a or column not in b:
            found.append(f"column {column} in one only")
            continue
        left, right = a[column], b[column].reindex(a.index)
        same = (left == right) | (left.isna() & right.isna())
        if not same.all():
            shown = [f"{i} {left[i]!r} / {right[i]!r}" for i in a.index[~same][:3]]
            found.append(
                f"{column}: {int((~same).sum())} rows"
                + (f" ({'; '.join(shown)})" if column == "status" else "")
            )
    return found


def one_sweep(n_runs: int, scheduler: str | None) -> tuple[float, pd.DataFrame]:
    """Wall time and rows of the first ``n_runs`` runs, swept in a fresh process: one that
    has loaded Dask (with its threads) starts local workers by forkserver, not fork."""
    with tempfile.TemporaryDirectory() as out:
        command = [sys.executable, "-m", "benchmarks.dask_sweep", "--one", str(n_runs), out]
        done = subprocess.run([*command, scheduler or ""], capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"the sweep failed: {done.stderr.strip()[-2000:]}")
        return float(done.stdout.split()[-1]), load_results(out)


def sweep_once(n_runs: int, out: str, scheduler: str) -> None:
    """``--one N OUT SCHEDULER``: run the sweep, print its wall time."""
    sweep = load_spec()
    sweep = dataclasses.replace(sweep, runs=sweep.runs[:n_runs])
    started = time.perf_counter()
    run_sweep(sweep, jobs=2, out=out, scheduler=scheduler or None, show_progress=False)
    print(time.perf_counter() - started)


def dask_sweep(n_runs: int) -> tuple[float, pd.DataFrame]:
    import distributed

    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as cluster:
        return one_sweep(n_runs, cluster.scheduler_address)


def main(argv: list[str]) -> pd.DataFrame:
    warnings.filterwarnings("ignore")
    sweep = load_spec()
    n_runs = int(argv[0]) if argv else len(sweep.runs)
    repeats = int(argv[1]) if len(argv) > 1 else 2
    sweep = dataclasses.replace(sweep, runs=sweep.runs[:n_runs])
    print(f"{len(sweep.runs)} runs of the default sweep, {repeats} repeats")
    trials = []
    for repeat in range(repeats):
        load = os.getloadavg()[0]
        local_s, local_rows = one_sweep(len(sweep.runs), None)
        dask_s, dask_rows = dask_sweep(len(sweep.runs))
        found = differences(local_rows, dask_rows)
        trials.append(
            {
                "repeat": repeat,
                "runs": len(sweep.runs),
                "local_s": local_s,
                "dask_s": dask_s,
                "ratio": dask_s / local_s,
                "rows_agree": not found,
                "differences": "; ".join(found),
                "ok_local": int((local_rows["status"] == "ok").sum()),
                "ok_dask": int((dask_rows["status"] == "ok").sum()),
                "load_1min": load,
            }
        )
        print(
            pd.DataFrame(trials[-1:]).to_string(index=False, float_format="{:.3g}".format),
            flush=True,
        )
    table = pd.DataFrame(trials)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "dask_sweep.csv", index=False)
    print()
    print(table.to_string(index=False, float_format="{:.3g}".format))
    print(
        f"Dask / local pool: best {table.dask_s.min() / table.local_s.min():.2f}x, "
        f"median {table.ratio.median():.2f}x (target <= 1.3x); rows agree: "
        f"{bool(table.rows_agree.all())}"
    )
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    if sys.argv[1:2] == ["--one"]:
        sweep_once(int(sys.argv[2]), sys.argv[3], sys.argv[4])
    else:
        main(sys.argv[1:])
