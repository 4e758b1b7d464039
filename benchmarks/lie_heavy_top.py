"""Work-precision of the Lie-group generalized-alpha on the heavy top, against
quaternion-based pipelines that update Euler parameters additively.

Pipelines (``PIPELINES``): lie-generalized-alpha and generalized-alpha on the recursive
formalism's index-3 mechanical form (joint space: one quaternion, no constraint) and
lie-generalized-alpha on absolute-dae (body coordinates, the spherical joint as three
index-3 constraints); DOP853 on the recursive ode; SUNDIALS IDA on absolute-dae at index 2
(GGL). Each runs through :func:`workbench.execution.execute.execute_run`, so error, cost and
drift are the result row's: ``err_max`` (largest pose error over the 401 samples against the
computed reference, m + L rad), ``cpu_s`` (integration CPU seconds), ``invariant_err_max``
and ``energy_err_max`` (relative), ``rotation_defect_max`` (|p^T p - 1| of the quaternions,
|R^T R - I| of the rotations). A first, discarded run of each pipeline builds the
equations and their lazily built Jacobians, so ``cpu_s`` is integration alone. The
fixed-step methods take their step from rtol (1e-3 s at 1e-6, at most the 5 ms between
output samples).

Run: ``python -m benchmarks.lie_heavy_top``. Prints a table, writes
``benchmarks/results/lie_heavy_top.csv`` and ``docs/images/lie-heavy-top.png`` (error
against CPU time; norm drift against CPU time). About two minutes on one busy core.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from benchmarks import help_if_asked
from workbench.execution.execute import RunSpec, execute_run  # noqa: E402

RESULTS = Path(__file__).parent / "results"
FIGURE = Path(__file__).parent.parent / "docs" / "images" / "lie-heavy-top.png"
GA_RTOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
ADAPTIVE_RTOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
PIPELINES = [  # label, formalism, formalism options, integrator, rtols
    ("lie-generalized-alpha / recursive", "recursive", {}, "lie-generalized-alpha", GA_RTOLS),
    ("lie-generalized-alpha / absolute-dae (index 3)", "absolute-dae", {"index": 3},
     "lie-generalized-alpha", GA_RTOLS),
    ("generalized-alpha / recursive", "recursive", {}, "generalized-alpha", GA_RTOLS),
    ("scipy-dop853 / recursive", "recursive", {}, "scipy-dop853", ADAPTIVE_RTOLS),
    ("sundials-ida / absolute-dae (index 2)", "absolute-dae", {"index": 2}, "sundials-ida",
     ADAPTIVE_RTOLS),
]  # fmt: skip
COLUMNS = ["pipeline", "rtol", "status", "err_max", "cpu_s", "n_steps", "energy_err_max",
           "invariant_err_max", "rotation_defect_max", "fixed_step_s"]  # fmt: skip


def measure() -> pd.DataFrame:
    rows = []
    for label, formalism, formalism_options, integrator, rtols in PIPELINES:
        # a first run builds the equations' lazy Jacobians (charged to its CPU time): discarded
        execute_run(RunSpec("heavy-top", formalism, integrator, rtols[0], rtols[0],
                            formalism_options=formalism_options))  # fmt: skip
        for rtol in rtols:
            spec = RunSpec("heavy-top", formalism, integrator, rtol, rtol,
                           formalism_options=formalism_options)  # fmt: skip
            row = execute_run(spec).row
            rows.append({"pipeline": label} | {k: row.get(k) for k in COLUMNS[1:]})
            print(f"{label} @ {rtol:g}: {row['status']} err {row.get('err_max'):.3g} "
                  f"cpu {row.get('cpu_s'):.3g} s", file=sys.stderr, flush=True)  # fmt: skip
    return pd.DataFrame(rows, columns=COLUMNS)


def plot(table: pd.DataFrame) -> None:
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    markers = "osD^v"
    for marker, (label, group) in zip(markers, table.groupby("pipeline", sort=False), strict=False):
        group = group[group.status == "ok"]
        left.loglog(group.cpu_s, group.err_max, marker=marker, label=label)
        right.loglog(group.cpu_s, group.rotation_defect_max.clip(lower=1e-16), marker=marker)
    left.set(xlabel="integration CPU time (s)", ylabel="max pose error (m + L rad)",
             title="heavy top, 2 s: error vs cost")  # fmt: skip
    right.set(xlabel="integration CPU time (s)", ylabel="max |p^T p - 1|, |R^T R - I|",
              title="distance from the rotation group")  # fmt: skip
    left.legend(fontsize=7)
    for axis in (left, right):
        axis.grid(True, which="both", alpha=0.3)
    figure.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(FIGURE, dpi=110)


def main() -> pd.DataFrame:
    warnings.filterwarnings("ignore")
    table = measure()
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "lie_heavy_top.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    plot(table)
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main()
