"""Runner throughput and overhead: 200 short runs on 1 and on 2 local workers.

Run: ``python -m benchmarks.runner_throughput [N_RUNS]``. The runs are the simple pendulum
(minimal-ode, scipy-dop853) at N_RUNS distinct tolerances, so each is short and the
runner's own cost (process hand-off, initial state, metrics, atomic writes) is visible.
Prints a table and writes ``benchmarks/results/runner_throughput.csv``: wall time per
sweep, runs per second, the speed-up of 2 workers over 1, and the median per-run overhead
(everything but the integrator: ``wall_s - integrate_s``).
"""

from __future__ import annotations

import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.store import load_results
from workbench.sweep import parse_spec, run_sweep

RESULTS = Path(__file__).parent / "results"


def spec_text(n_runs: int) -> str:
    tolerances = ", ".join(f"{t:.6e}" for t in np.logspace(-4, -9, n_runs))
    return (
        f"tolerances = [{tolerances}]\n"
        'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
        'integrators = ["scipy-dop853"]\n'
    )


def main(argv: list[str]) -> pd.DataFrame:
    warnings.filterwarnings("ignore")
    n_runs = int(argv[0]) if argv else 200
    sweep = parse_spec(spec_text(n_runs), "throughput benchmark")
    rows = []
    for jobs in (1, 2):
        with tempfile.TemporaryDirectory() as out:
            summary = run_sweep(sweep, jobs=jobs, out=out, show_progress=False)
            results = load_results(out)
            overhead = (results["wall_s"] - results["integrate_s"]).median()
            rows.append(
                {
                    "jobs": jobs,
                    "runs": summary.total,
                    "ok": int((results["status"] == "ok").sum()),
                    "sweep_s": summary.seconds,
                    "runs_per_s": summary.total / summary.seconds,
                    "median_integrate_s": results["integrate_s"].median(),
                    "median_overhead_s": overhead,
                }
            )
    table = pd.DataFrame(rows)
    table["speedup"] = table["runs_per_s"] / table["runs_per_s"].iloc[0]
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "runner_throughput.csv", index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    return table


if __name__ == "__main__":
    main(sys.argv[1:])
