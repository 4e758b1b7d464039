"""Does each model's compiled forward dynamics stay in the caches of other x86-64 CPUs?
Simulated by cachegrind, for want of a second machine.

Run: ``python -m benchmarks.cache_fit [--sizes 7 20 50 200] [--robots ur5 panda solo12
talos]`` (needs valgrind; about 5 min).

Issue 36 found per-call ratios that did not travel to a machine with 512 KiB of L2 a core,
bimodal from run to run at N = 50, and suspected the generated straight-line code outgrowing
the cache. This builds the models of :mod:`benchmarks.peers_pyperf` (ours compiled at the
default flags, and Pinocchio's C++ ``pinocchio::aba`` of ``benchmarks/aba_call.cpp``), calls
each from a small C driver (``benchmarks/cache_fit_driver.c``) under valgrind's cachegrind
with the cache geometry of three CPUs, and reports the misses a call in steady state (the
difference between 600 and 100 calls, over 500): first-level instruction misses (each costs
an L2 hit) and misses of the simulated L2 (each goes to L3 or memory), instructions a call,
and the code's size (``.text``). cachegrind models two levels, so "L2" is its last level; it
counts, it does not time: a count is what the simulated cache would do, not a measured
speed. Writes ``benchmarks/results/cache_fit.csv``.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd

from benchmarks import help_if_asked

RESULTS = Path(__file__).parent / "results"
DRIVER = Path(__file__).with_name("cache_fit_driver.c")
CACHES = {  # name: cachegrind's --I1, --D1, --LL (bytes, ways, line)
    "256K": ("32768,8,64", "32768,8,64", "262144,4,64"),  # Intel Skylake client
    "512K": ("32768,8,64", "32768,8,64", "524288,8,64"),  # AMD Zen 2/3 (issue 36's second)
    "1M": ("32768,8,64", "49152,12,64", "1048576,16,64"),  # this machine (AMD EPYC, Zen 5)
}
CALLS = (100, 600)
COUNTERS = {"instructions": r"I\s+refs:", "i1_misses": r"I1\s+misses:",
            "l2i_misses": r"LLi misses:", "l2d_misses": r"LLd misses:"}  # fmt: skip


def driver(folder: Path) -> Path:
    """The C driver, compiled into ``folder``."""
    executable = folder / "cache_fit_driver"
    subprocess.run(["cc", "-O2", "-o", str(executable), str(DRIVER), "-ldl"], check=True)
    return executable


def counts(command: list[str], cache: tuple[str, str, str]) -> dict[str, int]:
    """cachegrind's totals for one run of ``command`` with the cache geometry ``cache``."""
    i1, d1, ll = cache
    done = subprocess.run(
        ["valgrind", "--tool=cachegrind", "--cache-sim=yes", "--cachegrind-out-file=/dev/null",
         f"--I1={i1}", f"--D1={d1}", f"--LL={ll}", *command],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    totals = {}
    for key, label in COUNTERS.items():
        found = re.search(label + r"\s+([\d,]+)", done.stderr)
        if found is None:
            raise RuntimeError(f"cachegrind printed no '{label}' line:\n{done.stderr[-2000:]}")
        totals[key] = int(found.group(1).replace(",", ""))
    return totals


def text_bytes(library: str) -> int:
    """Size of the library's ``.text`` section (binutils' ``size``)."""
    listing = subprocess.run(["size", "-A", library], capture_output=True, text=True).stdout
    return next(int(line.split()[1]) for line in listing.splitlines() if line.startswith(".text"))


def main(argv: list[str]) -> None:
    help_if_asked(__doc__, argv)
    import argparse

    from benchmarks import peers_pyperf

    parser = argparse.ArgumentParser(prog="python -m benchmarks.cache_fit")
    parser.add_argument("--sizes", nargs="*", default=[str(n) for n in peers_pyperf.SIZES])
    parser.add_argument("--robots", nargs="*", default=list(peers_pyperf.ROBOTS))
    args = parser.parse_args(argv)
    missing = [tool for tool in ("valgrind", "cc", "size") if shutil.which(tool) is None]
    if missing:
        sys.exit(f"cache_fit needs {', '.join(missing)} on PATH (e.g. apt install valgrind)")
    from benchmarks import anchor

    models = [("random", n) for n in args.sizes] + [("robots", r) for r in args.robots]
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        executable = str(driver(Path(scratch)))
        pin_library = str(anchor.build(peers_pyperf.ABA_CALL, peers_pyperf.ABA_CALL_FLAGS))
        for kind, name in models:
            prepared = peers_pyperf.prepare(kind, name)  # checked against pin.aba
            sides = {
                "ours": (prepared["library"], prepared["symbol"]),
                "pinocchio::aba": (pin_library, "aba_call", prepared["model_text"]),
            }
            for side, (library, symbol, *model_text) in sides.items():
                row = {"model": f"{kind} {name}", "side": side}
                row["text_kib"] = text_bytes(library) / 1024
                for cache_name, cache in CACHES.items():
                    few, many = (counts([executable, library, symbol, str(n), *model_text], cache)
                                 for n in CALLS)  # fmt: skip
                    per_call = {k: (many[k] - few[k]) / (CALLS[1] - CALLS[0]) for k in few}
                    row["instructions"] = per_call["instructions"]
                    row[f"i1_misses_{cache_name}"] = per_call["i1_misses"]
                    row[f"l2_misses_{cache_name}"] = per_call["l2i_misses"] + per_call["l2d_misses"]
                rows.append(row)
                print(f"{kind} {name} {side}: done", file=sys.stderr, flush=True)
    table = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "cache_fit.csv", index=False)
    print("misses a call in steady state, simulated by cachegrind (L2 = its last level):")
    with pd.option_context("display.width", 200):
        print(table.to_string(index=False, float_format="{:.1f}".format))


if __name__ == "__main__":
    main(sys.argv[1:])
