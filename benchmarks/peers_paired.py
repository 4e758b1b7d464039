"""Ours against ``pin.aba`` timed in turn within each process: the ratio's spread over processes.

Run: ``python -m benchmarks.peers_paired [--sizes 7 20 50 200] [--robots ur5 panda solo12
talos] [--processes 10] [--rounds 20] [-o FILE]`` (all 8 models: about 6 minutes on 2
cores).

:mod:`benchmarks.peers_pyperf` times ours in some processes and ``pin.aba`` in others, one
benchmark after the other, and holds the target to the slowest process of ours against
the fastest of Pinocchio's: two draws of the machine's state minutes apart. On a virtual
machine whose speed comes and goes (docs/performance-targets.md, "The second machine":
a process of ours 2-3x another, with nothing of ours changed), that upper end is set by
which draw each side got. Here each worker process times both, in turn: the same models,
libraries and states as :mod:`benchmarks.peers_pyperf` (its :func:`~benchmarks.peers_pyperf.
prepare` and :func:`~benchmarks.peers_pyperf.timed_call`: each process its own copies of
both sides' libraries), loops calibrated to about 10 ms of CPU a block, one warm-up round,
then ``--rounds`` rounds of a block of each, their order alternating (ABBA). A process's
ratio is the median of its blocks' CPU a call, ours over Pinocchio's; the table gives the
median of the processes' ratios and their range (the upper end: the worst process), and,
from the same timings, pyperf's statistic (the slowest process of ours over the fastest
of Pinocchio's) for comparison. Both lines: from Python (``FastFunction.into`` / ``pin.aba``)
and in C (both through CasADi's buffer call). Writes ``benchmarks/results/
peers_paired-l2-<size>k.csv`` (one file a machine, as :mod:`benchmarks.peers_pyperf`).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.peers_pyperf import (
    BUFFER,
    COPIES,
    PYTHON,
    RESULTS,
    ROBOTS,
    SIZES,
    l2_kib,
    prepare,
    timed_call,
)
from workbench.execution.environment import cpu_model

BLOCK_CPU_S = 0.01  # CPU seconds a block of calls, about


def loops_for(call) -> int:
    """Calls a block of about :data:`BLOCK_CPU_S` of CPU (doubling from 1, as pyperf does)."""
    loops = 1
    while True:
        start = time.process_time()
        for _ in range(loops):
            call()
        if time.process_time() - start >= BLOCK_CPU_S or loops >= 1 << 24:
            return loops
        loops *= 2


def block(call, loops: int) -> float:
    """CPU seconds a call over one block of ``loops`` calls."""
    start = time.process_time()
    for _ in range(loops):
        call()
    return (time.process_time() - start) / loops


def worker(prepared: dict, rounds: int, copies: str) -> dict:
    """One process's timings of both lines: CPU seconds a call, a value a round and side."""
    # Pinocchio's copies first: private_pinocchio needs pinocchio not yet imported
    calls = {who: timed_call(prepared, who, Path(copies)) for who in (PYTHON[1], PYTHON[0],
                                                                      *BUFFER)}  # fmt: skip
    out = {}
    for ours, theirs in (PYTHON, BUFFER):
        pair = (calls[ours], calls[theirs])
        loops = [loops_for(call) for call in pair]
        for call, n in zip(pair, loops, strict=True):  # warm-up
            block(call, n)
        times: list[list[float]] = [[], []]
        for round_ in range(rounds):
            order = (0, 1) if round_ % 2 == 0 else (1, 0)
            for side in order:
                times[side].append(block(pair[side], loops[side]))
        out[ours], out[theirs] = times
    return out


def run_model(prepared: dict, processes: int, rounds: int) -> list[dict]:
    """``processes`` fresh worker processes for one model, one after another."""
    copies = tempfile.mkdtemp(prefix="mbs-peers-paired-", dir=COPIES)
    results = []
    try:
        for _ in range(processes):
            done = subprocess.run(
                [sys.executable, "-m", "benchmarks.peers_paired", "--worker",
                 json.dumps(prepared), "--rounds", str(rounds), "--copies", copies],
                capture_output=True, text=True, check=True,
            )  # fmt: skip
            results.append(json.loads(done.stdout.strip().splitlines()[-1]))
            for folder in Path(copies).iterdir():
                shutil.rmtree(folder)
    finally:
        shutil.rmtree(copies, ignore_errors=True)
    return results


def summarize(prepared: dict, results: list[dict], load: tuple[float, float]) -> dict:
    row = {k: prepared[k] for k in ("kind", "name", "nv", "graph", "python_call",
                                    "instructions", "code_bytes")}  # fmt: skip
    for prefix, (us, them) in (("", PYTHON), ("buffer_", BUFFER)):
        ours = np.array([np.median(r[us]) for r in results])
        pin = np.array([np.median(r[them]) for r in results])
        paired = ours / pin
        row.update({
            f"{prefix}ours_us": float(np.median(ours) * 1e6),
            f"{prefix}pin_aba_us": float(np.median(pin) * 1e6),
            f"{prefix}paired_median": float(np.median(paired)),
            f"{prefix}paired_min": float(paired.min()),
            f"{prefix}paired_max": float(paired.max()),
            # pyperf's statistic from these timings: two processes' draws apart
            f"{prefix}crossed_max": float(ours.max() / pin.min()),
            f"{prefix}ours_spread": float(ours.max() / ours.min()),
            f"{prefix}pin_spread": float(pin.max() / pin.min()),
        })  # fmt: skip
    rounds = len(results[0][PYTHON[0]]) if results else 0
    row.update({"processes": len(results), "rounds": rounds, "load1_before": load[0],
                "load1_after": load[1], "cpu": cpu_model(), "l2_kib": l2_kib()})  # fmt: skip
    return row


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.peers_paired")
    parser.add_argument("--sizes", nargs="*", default=[str(n) for n in SIZES])
    parser.add_argument("--robots", nargs="*", default=list(ROBOTS))
    parser.add_argument("--processes", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("-o", "--output", help="the table's file (default: one a machine)")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--copies", default="", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker), args.rounds, args.copies)))
        return
    import warnings

    import pandas as pd

    warnings.filterwarnings("ignore")
    models = [("random", n) for n in args.sizes] + [("robots", r) for r in args.robots]
    rows = []
    for kind, name in models:
        prepared = prepare(kind, name)
        load = os.getloadavg()[0]
        results = run_model(prepared, args.processes, args.rounds)
        rows.append(summarize(prepared, results, (load, os.getloadavg()[0])))
        shown = {k: rows[-1][k] for k in ("kind", "name", "paired_median", "paired_max",
                                          "crossed_max", "buffer_paired_max")}  # fmt: skip
        print(shown, file=sys.stderr, flush=True)
    table = pd.DataFrame(rows)
    size = l2_kib()
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / (f"peers_paired-l2-{size}k.csv" if size else "peers_paired.csv")
    path = Path(args.output) if args.output else path
    table.to_csv(path, index=False)
    columns = ["kind", "name", "ours_us", "pin_aba_us", "paired_median", "paired_min",
               "paired_max", "crossed_max", "ours_spread", "pin_spread",
               "buffer_paired_median", "buffer_paired_max", "buffer_crossed_max",
               "load1_before", "load1_after"]  # fmt: skip
    with pd.option_context("display.width", 250):
        print(table[columns].to_string(index=False, float_format="{:.3g}".format))
    print(f"wrote {path}")


if __name__ == "__main__":
    main(sys.argv[1:])
