"""Does the cheapest pair survive a second sweep, and a loaded machine? (issue 33 item 3)

Run: ``python -m benchmarks.ranking_agreement [--reduced | --wide] [--busy N] [--keep DIR]``.
Runs the same small sweep three times into fresh directories: twice as it is ("idle":
whatever else the machine runs, its load average is printed) and once with ``N`` (default
2) busy loops beside it (``multiprocessing`` processes spinning on the CPU, stopped when
the sweep ends and in any case after ``--busy-limit`` seconds). Each sweep runs first with
``--retime 0`` (each run's own back-to-back samples; its rows kept) and is then resumed,
which times the close calls again at moments apart (:mod:`workbench.runs.retime`). Then,
for each sweep, each problem and each accuracy target (scd >= 4, 6, 8), the report's own
ranking (:func:`workbench.outputs.report.ranking.decide`) names the cheapest trusted pair
by the median integration CPU time (``integrate_cpu_s``, the report's cost measure), or a
*tie* when the intervals cannot tell pairs apart.

Printed and written to ``benchmarks/results/ranking_agreement.csv`` (a line a comparison of
two sweeps): the cells where both sweeps name a winner (not a tie), and the share of them
where they name the same pair (the issue's target: >= 95 %); beside it, for contrast, the
agreement of the old ranking (one winner a cell, no ties, by the integration's wall time,
``integrate_s``). Full spec (the issue's): 6 problems x 3 formalisms x DOP853 and CVODE
BDF x rtol 1e-4, 1e-7 = 72 runs; ``--reduced``: 4 problems, 48 runs; ``--wide``: 16
problems, 192 runs.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from workbench.outputs.report.analysis import prepare_results
from workbench.outputs.report.ranking import decide
from workbench.runs.store import load_results

RESULTS = Path(__file__).resolve().parent / "results"
TARGETS = (4.0, 6.0, 8.0)
PROBLEMS = ["four-bar", "heavy-top", "spatial-chain", "rolling-pendulum", "slider-crank",
            "double-pendulum"]  # fmt: skip
REDUCED = PROBLEMS[:4]
WIDE = [*PROBLEMS, "rssr-linkage", "iftomm-a01", "double-point-pendulum", "planar-chain",
        "point-mass-slider-crank", "rotating-ring", "knife-edge-cart", "parallel-robot",
        "iftomm-a05", "binary-tree"]  # fmt: skip
SPEC = """
jobs = 2
time_limit = 60.0
tolerances = [1e-4, 1e-7]
atol_factor = 1e-3
problems = {problems}
formalisms = [
    {{ name = "minimal-ode", options = {{ index = 1 }} }},
    {{ name = "recursive", options = {{ index = 1 }} }},
    {{ name = "absolute-dae", options = {{ index = 1 }} }},
]
integrators = ["scipy-dop853", "sundials-cvode-bdf"]
"""


def spin(deadline: float) -> None:
    """A busy loop: the CPU held until ``deadline`` (time.monotonic)."""
    count = 0
    while time.monotonic() < deadline:
        count += 1


def sweep(spec: Path, out: Path, busy: int, busy_limit: float) -> dict:
    """Run the sweep into ``out`` with ``busy`` busy loops beside it, first without the
    close calls timed again (``--retime 0``: each run's own back-to-back samples), then
    resumed, which times them again (the default rounds); the rows of both, the loads."""
    deadline = time.monotonic() + busy_limit
    loops = [multiprocessing.Process(target=spin, args=(deadline,), daemon=True)
             for _ in range(busy)]  # fmt: skip
    for loop in loops:
        loop.start()
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    command = [sys.executable, "-m", "workbench", "sweep", str(spec), "--out", str(out),
               "--no-report", "--no-recording"]  # fmt: skip
    try:
        subprocess.run([*command, "--fresh", "--retime", "0"], check=True,
                       stdout=subprocess.DEVNULL)  # fmt: skip
        before = load_results(out)
        before.to_parquet(out / "before-retime.parquet")  # (kept with --keep)
        runs_s = time.perf_counter() - started
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    finally:
        for loop in loops:
            loop.terminate()
            loop.join()
    rows = load_results(out)
    return {
        "before": before,
        "rows": rows,
        "runs_s": runs_s,
        "retime_s": time.perf_counter() - started - runs_s,
        "retimed": int((pd.to_numeric(rows["retimed"], errors="coerce") > 0).sum()),
        "load_before": load_before,
        "load_runs": float(pd.to_numeric(rows["load_avg"], errors="coerce").median()),
    }


def ranking(rows: pd.DataFrame, cost: str, ties: bool) -> dict[tuple[str, float], str]:
    """(problem, target) -> the cheapest trusted pair reaching the target, or "tie" (when
    ``ties`` and the report's ranking calls one: its intervals, ``decide``)."""
    runs = prepare_results(rows)
    cells = {}
    for problem, group in runs.groupby("problem"):
        for target in TARGETS:
            decision = decide(group, target, cost)
            if decision.pair is not None:
                cells[(problem, target)] = "tie" if ties and decision.is_tie else decision.pair
    return cells


def ratio_reproduction(a: pd.DataFrame, b: pd.DataFrame, runs: set[str]) -> dict:
    """How two sweeps reproduce the ratio of two runs' costs (``integrate_cpu_s``): over
    every two of ``runs`` of the same problem, the factor between the two sweeps' ratios,
    its median and 90th and 95th percentiles (1: the same ratio)."""
    cost = {
        name: rows.set_index("run_id")["integrate_cpu_s"] for name, rows in (("a", a), ("b", b))
    }
    problem = a.set_index("run_id")["problem"]
    factors = []
    for _, ids in problem[problem.index.isin(runs)].groupby(problem[problem.index.isin(runs)]):
        ids = list(ids.index)
        for i, first in enumerate(ids):
            for second in ids[i + 1 :]:
                ratio_a = cost["a"][first] / cost["a"][second]
                ratio_b = cost["b"][first] / cost["b"][second]
                factors.append(math.exp(abs(math.log(ratio_a / ratio_b))))
    quantiles = pd.Series(factors, dtype=float).quantile([0.5, 0.9, 0.95])
    return {"pairs": len(factors), "median": quantiles[0.5], "p90": quantiles[0.9],
            "p95": quantiles[0.95]}  # fmt: skip


def agreement(a: dict, b: dict) -> dict:
    """How two rankings agree on the cells both rank and neither calls a tie."""
    common = sorted(set(a) & set(b))
    decided = [cell for cell in common if a[cell] != "tie" and b[cell] != "tie"]
    same = sum(a[cell] == b[cell] for cell in decided)
    return {
        "cells": len(common),
        "ties_either": len(common) - len(decided),
        "decided": len(decided),
        "same": same,
        "agreement": same / len(decided) if decided else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reduced", action="store_true", help="4 problems instead of 6")
    parser.add_argument("--wide", action="store_true", help="16 problems (48 cells) instead of 6")
    parser.add_argument("--busy", type=int, default=2, help="busy loops beside the third sweep")
    parser.add_argument("--busy-limit", type=float, default=1800.0, help="s they spin at most")
    parser.add_argument("--keep", type=Path, help="keep the three sweeps in this directory")
    args = parser.parse_args()
    problems = REDUCED if args.reduced else WIDE if args.wide else PROBLEMS
    with tempfile.TemporaryDirectory(prefix="ranking-") as scratch:
        folder = args.keep or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        spec = folder / "spec.toml"
        spec.write_text(SPEC.format(problems=problems), encoding="utf-8")
        sweeps = {}
        for name, busy in (("idle 1", 0), ("idle 2", 0), ("loaded", args.busy)):
            sweeps[name] = sweep(spec, folder / name.replace(" ", ""), busy, args.busy_limit)
            found = sweeps[name]
            print(f"{name}: {len(found['rows'])} runs in {found['runs_s']:.0f} s, "
                  f"{found['retimed']} close calls timed again in {found['retime_s']:.0f} s; "
                  f"load average {found['load_before']:.1f} at the start, median "
                  f"{found['load_runs']:.1f} during the runs ({busy} busy loops)")  # fmt: skip
    lines = []
    for first, second in (("idle 1", "idle 2"), ("idle 1", "loaded"), ("idle 2", "loaded")):
        for measure, rows, cost, ties in (
            ("CPU median, ties, close calls timed again", "rows", "integrate_cpu_s", True),
            ("CPU median, no ties, close calls timed again", "rows", "integrate_cpu_s", False),
            ("CPU median, ties by [min, max], back-to-back samples", "before",
             "integrate_cpu_s", True),
            ("CPU median, no ties, back-to-back samples", "before", "integrate_cpu_s", False),
            ("counted work, ties by [min, max]", "before", "work_s", True),
            ("wall median, no ties (old)", "before", "integrate_s", False),
        ):  # fmt: skip
            a = ranking(sweeps[first][rows], cost, ties)
            b = ranking(sweeps[second][rows], cost, ties)
            lines.append({"comparison": f"{first} vs {second}", "ranking": measure}
                         | agreement(a, b))  # fmt: skip
    retimed = {name: set(found["rows"].loc[found["rows"]["retimed"] > 0, "run_id"])
               for name, found in sweeps.items()}  # fmt: skip
    ratios = []
    for first, second in (("idle 1", "idle 2"), ("idle 1", "loaded"), ("idle 2", "loaded")):
        both = retimed[first] & retimed[second]
        for samples in ("before", "rows"):
            found = ratio_reproduction(sweeps[first][samples], sweeps[second][samples], both)
            ratios.append({"comparison": f"{first} vs {second}",
                           "samples": "timed again" if samples == "rows" else "back to back"}
                          | found)  # fmt: skip
    ratio_table = pd.DataFrame(ratios)
    print("the ratio of two close calls' costs, one sweep's against the other's (factor):")
    print(ratio_table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    table = pd.DataFrame(lines)
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    table["runs"] = len(sweeps["idle 1"]["rows"])
    table["busy_loops"] = args.busy
    table["cpu_count"] = os.cpu_count()
    for name in sweeps:
        table[f"load {name}"] = round(sweeps[name]["load_runs"], 2)
        table[f"retime_s {name}"] = round(sweeps[name]["retime_s"], 1)
    table["measured"] = when
    print(table.drop(columns=["measured", "cpu_count"]).to_string(index=False,
          float_format=lambda v: f"{v:.2f}"))  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "ranking_agreement.csv"
    table.to_csv(path, mode="a", header=not path.exists(), index=False)
    ratio_table["measured"] = when
    ratio_path = RESULTS / "ranking_agreement_ratios.csv"
    ratio_table.to_csv(ratio_path, mode="a", header=not ratio_path.exists(), index=False)
    print(f"appended to {path} (target: agreement >= 0.95 on the decided cells)")


if __name__ == "__main__":
    main()
