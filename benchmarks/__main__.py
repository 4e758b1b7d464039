"""The performance benchmarks of the README in one command, and their summary.

Run: ``python -m benchmarks`` (runs benchmarks.default_sweep,
benchmarks.runner_throughput, benchmarks.overhead, benchmarks.peers and
benchmarks.simulation, then summarizes; about 17 minutes on 2 cores, most of it
compiling the 200-body models) or ``python -m benchmarks --summary`` (summarizes the
CSVs already in benchmarks/results/). The summary gives, per family and N, our
compiled and uncompiled recursive forward dynamics over ``pin.aba`` and over
``mj_forward``, the compile time at N = 50, the whole-simulation ratios (same
integrator; best of ours against the best peer) per mechanism with their 95 %
intervals, the default sweep's
wall time, peak memory and share of time outside the integrators, and the runner's
speed-up on 2 workers, each against the issue's target.
"""

from __future__ import annotations

import argparse
import sys

import pandas as pd

from benchmarks import default_sweep, overhead, peers, runner_throughput, simulation

RESULTS = peers.RESULTS


def verdict(value: float, target: float) -> str:
    if pd.isna(value):
        return "n/a"
    return f"{value:.2f} ({'met' if value <= target else 'missed'}, target <= {target:g})"


def summary() -> None:
    table = pd.read_csv(RESULTS / "peers.csv")
    columns = [c for c in ("jit/pin", "vm/pin", "jit/mj", "vm/mj") if c in table]
    print("forward dynamics per call, ours / peer (lower is faster):")
    print(table.pivot(index="N", columns="family", values=columns).round(2).to_string())
    spatial = table[table.family == "spatial"].set_index("N")
    if "jit/pin" in spatial:
        small = spatial.loc[spatial.index <= 50, "jit/pin"].max()
        print("spatial chain, jit / pin.aba, worst N <= 50:", verdict(small, 0.5))
        if 200 in spatial.index:
            print("spatial chain, jit / pin.aba, N = 200:", verdict(spatial.loc[200, "jit/pin"], 1))
        print("spatial chain, vm / pin.aba, worst N:", verdict(spatial["vm/pin"].max(), 5))
    if 50 in spatial.index:
        print("compile time at N = 50 (s):", verdict(spatial.loc[50, "compile_s"], 2))
        if "compile_cpu_s" in spatial:
            print("compile CPU time at N = 50 (s):", verdict(spatial.loc[50, "compile_cpu_s"], 2))
    general = RESULTS / "peers_general.csv"
    if general.exists():
        frame = pd.read_csv(general)
        print("general trees and robots, jit / pin.aba (CPU a call; median, 10-90 %):")
        for _, row in frame.iterrows():
            target = 0.8 if row["family"] == "random" and row["N"] >= 200 else 0.5
            spread = f"[{row['jit/pin_lo']:.2f}, {row['jit/pin_hi']:.2f}]"
            print(f"  {row['family']} {row['name']}:", verdict(row["jit/pin"], target), spread)
    sim = RESULTS / "simulation_targets.csv"
    if sim.exists():
        pairs = {"a": "same integrator (DOP853 both sides)", "b": "best of ours / best peer"}
        for row in pd.read_csv(sim).itertuples():
            print(
                f"simulation, {row.case}, {pairs[row.pair]}: {row.ratio:.2f} "
                f"[{row.low:.2f}, {row.high:.2f}] ({row.verdict}, target <= {row.target:g}; "
                f"{row.ours} / {row.peer}; load {row.load_1min:.1f})"
            )
    calls = RESULTS / "overhead.csv"
    if calls.exists():
        frame = pd.read_csv(calls)
        print("FastFunction.into overhead per call (us):", frame.overhead_us.round(2).tolist())
    sweep = RESULTS / "default_sweep.csv"
    if sweep.exists():
        row = pd.read_csv(sweep).iloc[0]
        print(f"default sweep: {row.runs} runs in {row.wall_s:.0f} s (report included)")
        print("default sweep, peak memory of all processes (GiB):", verdict(row.peak_pss_gib, 1))
        print(
            "default sweep, share of the runs' time outside the integrators:",
            verdict(row.outside_share_of_stages, 0.1),
        )
        if "outside_share_runs_over_100ms" in row:
            print(
                f"  (median integration {1e3 * row.median_integrate_s:.0f} ms and "
                f"{row.outside_per_run_ms:.1f} ms a run outside it; runs integrating "
                f">= 0.1 s: {row.outside_share_runs_over_100ms:.0%} outside)"
            )
    throughput = RESULTS / "runner_throughput_summary.csv"
    if throughput.exists():
        two = pd.read_csv(throughput).set_index("jobs").loc[2]
        speedup = f"{two.speedup_best:.2f} (best), {two.speedup_median:.2f} (median)"
        met = "met" if two.speedup_best >= 1.7 else "missed"
        print(f"200 short runs, 2 workers over 1: {speedup} ({met}, target >= 1.7)")


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument("--summary", action="store_true", help="only summarize the CSVs")
    args = parser.parse_args(argv)
    if not args.summary:
        default_sweep.main([])
        runner_throughput.main([])
        overhead.main([])
        peers.main([])
        simulation.main([])
    summary()


if __name__ == "__main__":
    main(sys.argv[1:])
