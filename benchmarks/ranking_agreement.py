"""Does the cheapest pair survive a second sweep, and a loaded machine? (issue 33 item 3)

Run: ``python -m benchmarks.ranking_agreement [--reduced] [--busy N] [--keep DIR]``.
Runs the same small sweep three times into fresh directories: twice as it is ("idle":
whatever else the machine runs, its load average is printed) and once with ``N`` (default
2) busy loops beside it (``multiprocessing`` processes spinning on the CPU, stopped when
the sweep ends and in any case after ``--busy-limit`` seconds). Then, for each sweep, each
problem and each accuracy target (scd >= 4, 6, 8), it ranks the trusted pairs (ok runs
without warnings) by the cheapest run of each pair that reaches the target, by the median
integration CPU time (``integrate_cpu_s``, the report's cost measure): the cell's winner
is the cheapest pair, or a *tie* when another pair's [min, max] interval of CPU samples
(``integrate_cpu_s_min``, ``integrate_cpu_s_max``) overlaps the winner's.

Printed and written to ``benchmarks/results/ranking_agreement.csv`` (a line a comparison of
two sweeps): the cells where both sweeps name a winner (not a tie), and the share of them
where they name the same pair (the issue's target: >= 95 %); beside it, for contrast, the
agreement of the old ranking (one winner a cell, no ties, by the integration's wall time,
``integrate_s``). Full spec (the issue's): 6 problems x 3 formalisms x DOP853 and CVODE
BDF x rtol 1e-4, 1e-7 = 72 runs; ``--reduced``: 4 problems, 48 runs.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.runs.store import load_results

RESULTS = Path(__file__).resolve().parent / "results"
TARGETS = (4.0, 6.0, 8.0)
PROBLEMS = ["four-bar", "heavy-top", "spatial-chain", "rolling-pendulum", "slider-crank",
            "double-pendulum"]  # fmt: skip
REDUCED = PROBLEMS[:4]
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
    """Run the sweep into ``out`` with ``busy`` busy loops beside it; the loads seen."""
    deadline = time.monotonic() + busy_limit
    loops = [multiprocessing.Process(target=spin, args=(deadline,), daemon=True)
             for _ in range(busy)]  # fmt: skip
    for loop in loops:
        loop.start()
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    try:
        command = [sys.executable, "-m", "workbench", "sweep", str(spec), "--out", str(out)]
        subprocess.run([*command, "--fresh"], check=True, stdout=subprocess.DEVNULL)
    finally:
        for loop in loops:
            loop.terminate()
            loop.join()
    rows = load_results(out)
    return {
        "rows": rows,
        "wall_s": time.perf_counter() - started,
        "load_before": load_before,
        "load_runs": float(pd.to_numeric(rows["load_avg"], errors="coerce").median()),
    }


def ranking(rows: pd.DataFrame, cost: str, ties: bool) -> dict[tuple[str, float], str]:
    """(problem, target) -> the cheapest trusted pair reaching the target, or "tie" (when
    ``ties`` and another pair's [min, max] interval of ``cost`` overlaps the winner's)."""
    warned = rows["warnings"].fillna("").astype(str) != ""
    trusted = rows[(rows["status"] == "ok") & ~warned & np.isfinite(rows["scd"])].copy()
    trusted["pair"] = trusted["formalism"] + " / " + trusted["integrator"]
    low = trusted.get(f"{cost}_min", trusted[cost]).fillna(trusted[cost])
    high = trusted.get(f"{cost}_max", trusted[cost]).fillna(trusted[cost])
    trusted["low"], trusted["high"] = low, high
    cells = {}
    for problem, group in trusted.groupby("problem"):
        for target in TARGETS:
            reaching = group[group["scd"] >= target]
            if reaching.empty:
                continue
            best = reaching.sort_values(cost).groupby("pair").head(1)  # each pair's cheapest
            best = best.sort_values(cost)
            winner = best.iloc[0]
            others = best.iloc[1:]
            overlap = (others["low"] <= winner["high"]) & (others["high"] >= winner["low"])
            cells[(problem, target)] = "tie" if ties and overlap.any() else winner["pair"]
    return cells


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
    parser.add_argument("--busy", type=int, default=2, help="busy loops beside the third sweep")
    parser.add_argument("--busy-limit", type=float, default=1800.0, help="s they spin at most")
    parser.add_argument("--keep", type=Path, help="keep the three sweeps in this directory")
    args = parser.parse_args()
    problems = REDUCED if args.reduced else PROBLEMS
    with tempfile.TemporaryDirectory(prefix="ranking-") as scratch:
        folder = args.keep or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        spec = folder / "spec.toml"
        spec.write_text(SPEC.format(problems=problems), encoding="utf-8")
        sweeps = {}
        for name, busy in (("idle 1", 0), ("idle 2", 0), ("loaded", args.busy)):
            sweeps[name] = sweep(spec, folder / name.replace(" ", ""), busy, args.busy_limit)
            found = sweeps[name]
            print(f"{name}: {len(found['rows'])} runs in {found['wall_s']:.0f} s, load average "
                  f"{found['load_before']:.1f} at the start, median {found['load_runs']:.1f} "
                  f"during the runs ({busy} busy loops)")  # fmt: skip
    lines = []
    for first, second in (("idle 1", "idle 2"), ("idle 1", "loaded"), ("idle 2", "loaded")):
        for measure, cost, ties in (
            ("CPU median, ties by [min, max]", "integrate_cpu_s", True),
            ("CPU median, no ties", "integrate_cpu_s", False),
            ("counted work, ties by [min, max]", "work_s", True),
            ("counted work, no ties", "work_s", False),
            ("wall median, no ties (old)", "integrate_s", False),
        ):
            a = ranking(sweeps[first]["rows"], cost, ties)
            b = ranking(sweeps[second]["rows"], cost, ties)
            lines.append({"comparison": f"{first} vs {second}", "ranking": measure}
                         | agreement(a, b))  # fmt: skip
    table = pd.DataFrame(lines)
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    table["runs"] = len(sweeps["idle 1"]["rows"])
    table["busy_loops"] = args.busy
    table["cpu_count"] = os.cpu_count()
    for name in sweeps:
        table[f"load {name}"] = round(sweeps[name]["load_runs"], 2)
    table["measured"] = when
    print(table.drop(columns=["measured", "cpu_count"]).to_string(index=False,
          float_format=lambda v: f"{v:.2f}"))  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "ranking_agreement.csv"
    table.to_csv(path, mode="a", header=not path.exists(), index=False)
    print(f"appended to {path} (target: agreement >= 0.95 on the decided cells)")


if __name__ == "__main__":
    main()
