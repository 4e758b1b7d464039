"""Measure a shipped suite and write its cost table (what ``workbench sweep`` estimates from).

Run: ``python -m benchmarks.suite_costs [SUITE] [--out DIR] [--jobs N] [--time-limit S]
[--missing]`` (default: quick). Runs ``workbench sweep SUITE --fresh`` in a child process,
then writes ``workbench/runs/suites/SUITE.costs.json``: each run's seconds on an idle machine
(:func:`workbench.runs.estimate.run_seconds`: its CPU share of its worker's wall time, so a
busy machine still measures the work; at most the suite's time limit, since a run timed out
costs that much) and ``overhead_s``, the CPU seconds of the whole
command (every process, from ``getrusage``) that its runs do not account for: starting the
workers, the report, the recording. A timeout's CPU is not in its row: it is counted as its
time limit times the median CPU / wall ratio of the other runs. On a busy machine give a
``--time-limit`` above the suite's (default: 3x), so that runs slowed by the load finish and
are measured instead of counted as timeouts. Prints the command's wall
time, its CPU time and the load average before and after, and appends a line to
benchmarks/results/suite_costs.csv.

``--missing`` measures only the runs the suite's table lacks (a suite over ``"all"``
problems gains runs when the catalog grows; a run's id changes with its options) and adds
them to the table, keeping the entries of its other runs and its ``overhead_s``: it sweeps
the suite restricted to the problems of those runs.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from workbench.runs.estimate import cost_table, duration, run_seconds
from workbench.runs.store import load_results
from workbench.runs.sweep_spec import load_spec, suite_text

SUITES = Path(__file__).resolve().parents[1] / "workbench" / "runs" / "suites"
RESULTS = Path(__file__).resolve().parent / "results"


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def restricted_to(suite: str, problems: list[str], folder: Path) -> Path:
    """A copy of the suite's specification over ``problems`` only, written in ``folder``."""
    text, count = re.subn(
        r"^problems\s*=.*$", f"problems = {json.dumps(problems)}", suite_text(suite), flags=re.M
    )
    if count != 1:
        sys.exit(f"suite {suite}: no single-line `problems = ...` to restrict; measure it whole")
    path = folder / f"{suite}-missing.toml"
    path.write_text(text, encoding="utf-8")
    return path


def measure(
    suite: str, out: Path, jobs: int | None, time_limit: float | None, spec_file: Path | None = None
) -> dict:
    """Run the suite (or ``spec_file``, a part of it) once into ``out``; its rows and what the
    whole command cost."""
    spec = load_spec(suite)
    limit = time_limit or 3 * spec.time_limit
    source = str(spec_file or suite)
    command = [sys.executable, "-m", "workbench", "sweep", source, "--out", str(out), "--fresh"]
    command += ["--time-limit", str(limit)] + (["--jobs", str(jobs)] if jobs else [])
    load_before, cpu_before, started = os.getloadavg()[0], children_cpu(), time.perf_counter()
    subprocess.run(command, check=False, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    cpu, load_after = children_cpu() - cpu_before, os.getloadavg()[0]
    frame = load_results(out)
    rows = frame.to_dict("records")
    finished = frame[(frame["status"] != "timeout") & (frame["wall_s"] > 0)]
    ratio = statistics.median((finished["cpu_s"] / finished["wall_s"]).clip(upper=1.0))
    timeouts = int((frame["status"] == "timeout").sum())
    runs_cpu = sum(run_seconds(r, limit) for r in rows if r["status"] != "timeout")
    runs_cpu += timeouts * limit * ratio
    table = cost_table(rows, limit)
    for line in table:  # a run costs at most the suite's time limit: then it is a timeout
        line[-1] = min(line[-1], spec.time_limit)
    return {
        "suite": suite,
        "runs": len(rows),
        "timeouts": timeouts,
        "wall_s": round(wall, 1),
        "cpu_s": round(cpu, 1),
        "runs_idle_s": round(sum(line[-1] for line in table), 1),
        "overhead_s": round(max(0.0, cpu - runs_cpu), 1),
        "load_before": round(load_before, 2),
        "load_after": round(load_after, 2),
        "jobs": jobs or spec.jobs,
        "table": table,
        "time_limit": limit,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("suite", nargs="?", default="quick")
    parser.add_argument("--out", help="results directory (default: a temporary one)")
    parser.add_argument("--jobs", type=int)
    parser.add_argument("--time-limit", type=float, help="s per run (default: 3x the suite's)")
    parser.add_argument(
        "--missing", action="store_true", help="measure only the runs the table lacks, add them"
    )
    args = parser.parse_args()
    if args.missing:
        add_missing(args)
        return
    with tempfile.TemporaryDirectory() as scratch:
        found = measure(args.suite, Path(args.out or scratch), args.jobs, args.time_limit)
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    table = {
        "measured": f"{when}, python -m benchmarks.suite_costs {args.suite}, load average "
        f"{found['load_before']} before and {found['load_after']} after on {os.cpu_count()} "
        f"CPUs, time limit {found['time_limit']} s; seconds: a run's worker time on an "
        "idle machine (at most the suite's time limit)",
        "overhead_s": found["overhead_s"],
        "runs": found["table"],
    }
    target = SUITES / f"{args.suite}.costs.json"
    target.write_text(json.dumps(table, indent=0) + "\n", encoding="utf-8")
    summary = {k: v for k, v in found.items() if k != "table"} | {"measured": when}
    RESULTS.mkdir(exist_ok=True)
    csv = RESULTS / "suite_costs.csv"
    pd.DataFrame([summary]).to_csv(csv, mode="a", header=not csv.exists(), index=False)
    idle = found["overhead_s"] + found["runs_idle_s"] / found["jobs"]
    print(
        f"suite {args.suite}: {found['runs']} runs ({found['timeouts']} timeouts) in "
        f"{found['wall_s']} s wall, {found['cpu_s']} s CPU of all its processes, load "
        f"{found['load_before']} -> {found['load_after']} on {os.cpu_count()} CPUs; runs "
        f"{found['runs_idle_s']} s of worker time on an idle machine, overhead "
        f"{found['overhead_s']} s: about {duration(idle)} on {found['jobs']} idle cores"
    )
    print(f"wrote {target} and a line of {csv}")


def add_missing(args: argparse.Namespace) -> None:
    """Measure the suite's runs its cost table lacks and add them to the table."""
    target = SUITES / f"{args.suite}.costs.json"
    table = json.loads(target.read_text(encoding="utf-8"))
    known = {line[0] for line in table["runs"]}
    runs = load_spec(args.suite).runs
    missing = {run.run_id: run for run in runs if run.run_id not in known}
    if not missing:
        print(f"suite {args.suite}: every run has a measured cost in {target}")
        return
    problems = sorted({run.problem for run in missing.values()})
    with tempfile.TemporaryDirectory() as scratch:
        spec_file = restricted_to(args.suite, problems, Path(scratch))
        out = Path(args.out or Path(scratch) / "out")
        found = measure(args.suite, out, args.jobs, args.time_limit, spec_file)
    added = [line for line in found["table"] if line[0] in missing]
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    table["measured"] += (
        f"; {len(added)} runs added {when} (--missing: {len(problems)} problems), load "
        f"{found['load_before']} -> {found['load_after']}"
    )
    current = {run.run_id for run in runs}  # entries of runs the suite no longer has go
    table["runs"] = [line for line in table["runs"] if line[0] in current] + added
    target.write_text(json.dumps(table, indent=0) + "\n", encoding="utf-8")
    left = len(missing) - len(added)
    print(
        f"suite {args.suite}: {len(added)} of {len(missing)} missing runs measured "
        f"({found['wall_s']} s wall, load {found['load_before']} -> {found['load_after']})"
        + (f"; {left} still missing (their runs did not finish)" if left else "")
    )
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
