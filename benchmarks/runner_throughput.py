"""Runner throughput and overhead: 200 short runs on 1 and on 2 local workers.

Run: ``python -m benchmarks.runner_throughput [N_RUNS] [REPEATS]`` (defaults 200 and 3).
The runs are the simple pendulum (minimal-ode, scipy-dop853) at N_RUNS distinct
tolerances, so each is short and the runner's own cost (hand-off to a worker, initial
state, metrics, Rerun logging, atomic writes) is visible. Each repeat runs the sweep on 1
and then on 2 workers, end to end (``run_sweep``: worker start, runs, consolidation of
the results and merge of the recordings). On a shared machine single timings mean
little, so the table gives, per number of workers, the best and the median of the
repeats, and the speed-up of 2 workers over 1 from both.

Prints the table and the load average; writes ``benchmarks/results/runner_throughput.csv``
(one row a sweep) and ``runner_throughput_summary.csv``. Columns: wall time of the sweep,
runs per second, the median integration time and the median per-run overhead (everything
but the integrator, ``wall_s - integrate_s``, plus the Rerun logging ``log_s``).
"""

from __future__ import annotations

import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks import help_if_asked
from workbench.outputs.recording import SweepRecorder
from workbench.runs.store import load_results
from workbench.runs.sweep import parse_spec, run_sweep

RESULTS = Path(__file__).parent / "results"


def spec_text(n_runs: int) -> str:
    tolerances = ", ".join(f"{t:.6e}" for t in np.logspace(-4, -9, n_runs))
    return (
        f"tolerances = [{tolerances}]\n"
        'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
        'integrators = ["scipy-dop853"]\n'
    )


def one_sweep(sweep, jobs: int) -> dict:
    with tempfile.TemporaryDirectory() as out:
        summary = run_sweep(sweep, jobs=jobs, out=out, show_progress=False, recorder=SweepRecorder)
        results = load_results(out)
    overhead = results["wall_s"] - results["integrate_s"] + results["log_s"].fillna(0.0)
    return {
        "jobs": jobs,
        "runs": summary.total,
        "ok": int((results["status"] == "ok").sum()),
        "sweep_s": summary.seconds,
        "runs_per_s": summary.total / summary.seconds,
        "median_integrate_s": results["integrate_s"].median(),
        "median_overhead_s": overhead.median(),
        "load_1min": os.getloadavg()[0],
    }


def summarize(trials: pd.DataFrame) -> pd.DataFrame:
    table = trials.groupby("jobs")["runs_per_s"].agg(best="max", median="median").reset_index()
    for column in ("best", "median"):
        table[f"speedup_{column}"] = table[column] / table[column].iloc[0]
    table["median_overhead_s"] = trials.groupby("jobs")["median_overhead_s"].median().values
    return table


def main(argv: list[str]) -> pd.DataFrame:
    warnings.filterwarnings("ignore")
    n_runs = int(argv[0]) if argv else 200
    repeats = int(argv[1]) if len(argv) > 1 else 3
    sweep = parse_spec(spec_text(n_runs), "throughput benchmark")
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    trials = pd.DataFrame([one_sweep(sweep, jobs) for _ in range(repeats) for jobs in (1, 2)])
    table = summarize(trials)
    RESULTS.mkdir(exist_ok=True)
    trials.to_csv(RESULTS / "runner_throughput.csv", index=False)
    table.to_csv(RESULTS / "runner_throughput_summary.csv", index=False)
    print(trials.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print()
    print(table.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main(sys.argv[1:])
