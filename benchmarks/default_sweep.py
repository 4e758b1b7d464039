"""The default sweep end to end: wall time, peak memory, and where the time goes.

Run: ``python -m benchmarks.default_sweep [--jobs N] [--out DIR]``. Runs the README's
former main command, ``workbench sweep full`` (the full sweep; here into a fresh directory so
nothing is resumed), as a subprocess and measures:

- wall time of the whole command, of its runs phase (as the command reports it) and of
  the rest (report, recording, start-up);
- peak memory of the command and all its worker processes together, sampled every
  0.1 s: the sum of PSS (proportional set size: a page shared by forked workers counts
  once, split between them), and the sum of RSS for comparison (counts shared pages in
  every process). Issue target: < 1 GiB;
- the share of time outside the integrators: of the runs' own stages (pairing, build,
  compile, initial state, integrate, metrics, reference, log: summed over the runs that
  were not skipped), and of the workers' whole time (jobs x runs phase, which also counts idle
  workers at the end and process start-up). Issue target: < 10 %. Beside them: the
  median integration time, the mean seconds a run spends outside the integrator, and
  the share outside for the runs that integrate for at least 0.1 s. Runs killed at the
  time limit (or whose worker died) are counted apart (``runs_killed``, ``killed_s``: no
  stage of theirs was timed). A run's integration
  counts once (its median sample, ``integrate_s``); the extra timed samples
  (:mod:`workbench.execution.timing`) are reported apart (``repeat_s``, estimated from each
  row's min, median and max) and left out of the workers' time, with the median load
  average the runs saw.

Prints a table, writes ``benchmarks/results/default_sweep.csv`` (one row; another
suite's ``default_sweep-SUITE.csv``) and the
seconds spent in each stage summed over runs, per formalism, in
``benchmarks/results/default_sweep_stages.csv``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import psutil

from workbench.execution.environment import cpu_model

RESULTS = Path(__file__).parent / "results"
STAGES = ("build_s", "compile_s", "init_s", "integrate_s", "metrics_s", "reference_s", "log_s")
NOT_IN_WALL = ("reference_s", "log_s")
KILLED = ("timeout", "unfinished")  # rows of runs killed mid-way: wall_s only, no stages
REPEAT_COLUMNS = ("repeats", "integrate_s_min", "integrate_s_max", "integrate_cpu_s", "load_avg")
GIB = 1024**3


def tree_memory(root: psutil.Process) -> tuple[int, int]:
    """(sum of PSS, sum of RSS) in bytes over ``root`` and its descendants."""
    pss = rss = 0
    for process in [root, *root.children(recursive=True)]:
        try:
            info = process.memory_full_info()
        except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
            continue
        pss += getattr(info, "pss", info.rss)
        rss += info.rss
    return pss, rss


def run_sweep_command(out: Path, jobs: int | None, suite: str = "full") -> dict:
    """Run ``workbench sweep SUITE --out OUT`` and sample its memory; returns the
    measurements."""
    command = [sys.executable, "-m", "workbench", "sweep", suite, "--out", str(out)]
    if jobs:
        command += ["--jobs", str(jobs)]
    started = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               text=True)  # fmt: skip
    root = psutil.Process(process.pid)
    peak_pss = peak_rss = 0
    while process.poll() is None:
        pss, rss = tree_memory(root)
        peak_pss, peak_rss = max(peak_pss, pss), max(peak_rss, rss)
        time.sleep(0.1)
    total = time.perf_counter() - started
    output = process.stdout.read() if process.stdout else ""
    if process.returncode != 0:
        raise SystemExit(f"workbench sweep exited with {process.returncode}:\n{output}")
    runs_phase = float(re.search(r"runs in ([0-9.]+) s", output).group(1))
    return {
        "command": " ".join(["workbench", *command[3:]]),
        "wall_s": total,
        "runs_phase_s": runs_phase,
        "after_runs_s": total - runs_phase,
        "peak_pss_gib": peak_pss / GIB,
        "peak_rss_sum_gib": peak_rss / GIB,
        "output": output,
    }


def time_shares(out: Path, jobs: int, runs_phase: float) -> tuple[dict, pd.DataFrame]:
    """Shares of time outside the integrators, and stage seconds per formalism.

    A run killed at the sweep's time limit (``timeout``, or ``unfinished``: its worker
    died) has no stage columns, only the wall time until it was killed (from its
    progress file, ``wall_s``): it is counted apart (``runs_killed``, ``killed_s``), not
    in the stages (it was once all counted as pairing, the residual wall_s less the
    stages: 395 of the full sweep's "pairing" seconds on 2026-11-27 were 13 timeouts)."""
    from workbench import load_results

    return shares_of(load_results(out), jobs, runs_phase)


def shares_of(rows: pd.DataFrame, jobs: int, runs_phase: float) -> tuple[dict, pd.DataFrame]:
    """:func:`time_shares` of a sweep's rows."""
    ran = rows[rows.status != "skipped"].copy()
    for column in (*STAGES, "wall_s", "cpu_s", "retimed", *REPEAT_COLUMNS):
        column_values = ran[column] if column in ran else pd.Series(0.0, index=ran.index)
        ran[column] = pd.to_numeric(column_values, errors="coerce").fillna(0.0)
    killed = ran.status.isin(KILLED)
    ran["killed_s"] = ran.wall_s.where(killed, 0.0)
    timed = ran[~killed].copy()
    timed["repeat_s"] = repeat_seconds(timed)
    # wall_s = pairing + build + compile + init + integrate + metrics (pairing: model,
    # options, compatibility; it has no column of its own)
    in_wall = [s for s in STAGES if s not in NOT_IN_WALL]
    timed["pairing_s"] = timed.wall_s - timed[in_wall].sum(axis=1)
    _own_integration(timed, [s for s in in_wall if s != "integrate_s"])
    stage_total = timed[["pairing_s", *STAGES]].sum()
    in_runs = float(stage_total.sum())
    integrate = float(stage_total["integrate_s"])
    repeats = float(timed.repeat_s.sum())
    shares = {
        "runs": len(rows),
        "ran": len(ran),
        "runs_killed": int(killed.sum()),
        # wall seconds of the killed runs until their limit: in the workers' time, not in
        # the stages (no stage was timed)
        "killed_s": float(ran.killed_s.sum()),
        "jobs": jobs,
        "stages_s": in_runs,
        "integrate_s": integrate,
        "outside_share_of_stages": 1 - integrate / in_runs,
        "outside_share_of_worker_time": 1 - integrate / (jobs * runs_phase - repeats),
        # the same in CPU time (stages pairing .. metrics: reference and log have no CPU
        # column), steadier than wall time on a busy machine
        "outside_share_of_cpu": 1 - float(timed.integrate_cpu_s.sum()) / float(timed.cpu_s.sum()),
        # why the share is what it is: many short runs, each with a fixed cost around it
        "median_integrate_s": float(timed.integrate_s.median()),
        # the integration's extra timed samples (workbench.execution.timing): the integrator
        # runs then, but they are not the run's result; neither inside nor outside
        "repeat_s": repeats,
        "runs_repeated": int((timed.repeats - timed.retimed > 1).sum()),
        "load_avg_median": float(timed.load_avg.median()),
        "outside_per_run_ms": 1e3 * (in_runs - integrate) / max(len(timed), 1),
        "outside_share_runs_over_100ms": _share_outside(timed[timed.integrate_s >= 0.1]),
        **{f"total_{stage}": float(stage_total[stage]) for stage in stage_total.index},
    }
    killed_s = ran.groupby("formalism").killed_s.sum()
    per_formalism = timed.groupby("formalism")[["pairing_s", *STAGES]].sum()
    per_formalism = per_formalism.reindex(killed_s.index).fillna(0.0)
    per_formalism["killed_s"] = killed_s
    return shares, per_formalism


def _own_integration(timed: pd.DataFrame, other_stages: list[str]) -> None:
    """A re-timed row's own integration, in place. The close calls timed again after the
    runs (:mod:`workbench.runs.retime`) have ``integrate_s`` (and its CPU, min, max,
    repeats) over the later samples, while ``wall_s`` and ``cpu_s`` hold the run's own
    integration: wall less stages then left the two timings' difference as "pairing"
    (-6.3 s over 572 re-timed rows in one full sweep, +2.7 s over 522 in another:
    0.01 of the share). Such a row's pairing is taken as the median of the others'
    (0.3 ms), its own integration as the rest of its wall time, its CPU as its CPU less
    the wall time outside it, and its timed samples as its own (``repeats`` less
    ``retimed``) at that integration."""
    retimed = timed.retimed > 0
    if not retimed.any():
        return
    pairing = float(timed.pairing_s[~retimed].median()) if (~retimed).any() else 0.0
    own = timed.wall_s - timed[other_stages].sum(axis=1) - pairing
    outside = timed.wall_s - own
    timed.loc[retimed, "pairing_s"] = pairing
    timed.loc[retimed, "integrate_s"] = own[retimed]
    timed.loc[retimed, "integrate_cpu_s"] = (timed.cpu_s - outside)[retimed]
    samples = (timed.repeats - timed.retimed).clip(lower=1)
    timed.loc[retimed, "repeat_s"] = ((samples - 1) * own)[retimed]


def repeat_seconds(ran: pd.DataFrame) -> pd.Series:
    """Seconds of each run's extra timed samples: their sum less the median, the sum
    taken as min + max + (n - 2) median (exact for n <= 3)."""
    n = ran.repeats.clip(lower=1)
    total = ran.integrate_s_min + ran.integrate_s_max + (n - 2) * ran.integrate_s
    return (total - ran.integrate_s).where(n > 1, 0.0).clip(lower=0.0)


def results_name(suite: str, part: str = "") -> str:
    """The CSV of a suite's measurement: ``default_sweep.csv`` for the full sweep (what
    ``python -m benchmarks`` runs and the summary's targets read), ``default_sweep-quick.csv``
    and so on for the others, so that a quick look never replaces the full measurement."""
    name = "" if suite == "full" else "-" + Path(suite).stem
    return f"default_sweep{part}{name}.csv"


def _share_outside(ran: pd.DataFrame) -> float:
    total = float(ran[["pairing_s", *STAGES]].to_numpy().sum())
    return 1 - float(ran.integrate_s.sum()) / total if total > 0 else float("nan")


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.default_sweep",
                                     description=__doc__)  # fmt: skip
    parser.add_argument("--jobs", type=int, default=None, help="workers (default: the spec's)")
    parser.add_argument("--out", type=Path, default=None, help="keep the sweep here")
    parser.add_argument(
        "--suite", default="full", help="another suite or spec file (default: full)"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="default-sweep-") as scratch:
        out = args.out or Path(scratch) / "sweep"
        if out.exists() and any(out.iterdir()):
            raise SystemExit(f"{out} is not empty: the benchmark needs a sweep from scratch")
        measured = run_sweep_command(out, args.jobs, args.suite)
        jobs = args.jobs or int(re.search(r"jobs\s*=\s*(\d+)", _spec_text(args.suite)).group(1))
        shares, per_formalism = time_shares(out, jobs, measured["runs_phase_s"])
    print(measured.pop("output").strip())
    row = {**measured, **shares, "load_1min": os.getloadavg()[0], "cpu_count": os.cpu_count(),
           "cpu": cpu_model(), "date": time.strftime("%Y-%m-%d")}  # fmt: skip
    table = pd.DataFrame([row])
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / results_name(args.suite), index=False)
    per_formalism.to_csv(RESULTS / results_name(args.suite, "_stages"))
    shown = {k: v for k, v in row.items() if not k.startswith("total_")}
    print(pd.Series(shown).to_string(float_format=lambda x: f"{x:.3g}"))
    print("\nseconds per stage, summed over runs:")
    print(per_formalism.round(1).to_string())
    print(f"peak memory (PSS, all processes): {row['peak_pss_gib']:.2f} GiB (target < 1)")
    print(f"time outside integrators: {row['outside_share_of_stages']:.0%} of the runs' "
          f"stages, {row['outside_share_of_worker_time']:.0%} of the workers' time "
          f"(target < 10 %); of the runs' CPU time {row['outside_share_of_cpu']:.0%} "
          f"(load average {row['load_avg_median']:.1f}, {row['cpu_count']} CPUs)")  # fmt: skip
    print(f"  {row['runs_killed']} runs killed at the time limit held workers "
          f"{row['killed_s']:.0f} s (not in the stages)")  # fmt: skip
    print(f"  median integration {1e3 * row['median_integrate_s']:.0f} ms, "
          f"{row['outside_per_run_ms']:.1f} ms a run outside it; runs integrating >= 0.1 s: "
          f"{row['outside_share_runs_over_100ms']:.0%} outside")  # fmt: skip
    return table


def _spec_text(suite: str = "full") -> str:
    from workbench.runs.sweep_spec import FULL_SUITE, suite_text

    if Path(suite).is_file():
        return Path(suite).read_text()
    return suite_text(FULL_SUITE if suite == "full" else suite)  # full: the former default


if __name__ == "__main__":
    main()
