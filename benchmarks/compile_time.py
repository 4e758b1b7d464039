"""The compile time of the N = 50 spatial chain (issue 36's "paid once"), machine by machine.

Run: ``python -m benchmarks.compile_time [--compiles 3] [--n 50]``. Builds the
``recursive`` formalism's right-hand side of the ``spatial-chain`` problem as
:mod:`benchmarks.peers` does and compiles it ``--compiles`` times, each in a fresh cache
directory (C generation, the compiler and the load: :func:`benchmarks.peers.cold_compile`),
then checks the compiled accelerations against the VM's at a random state. Appends a row a
compile to ``benchmarks/results/compile_time.csv`` with the CPU, its L2 a core, the date
and the load, so that each machine's figure stays beside the others'
(``python -m benchmarks --summary`` holds the target to the slowest machine's median).
"""

from __future__ import annotations

import argparse
import datetime
import os
import warnings

import numpy as np
import pandas as pd

from benchmarks.peers import RESULTS, cold_compile, family_model
from benchmarks.peers_pyperf import l2_kib
from workbench.equations.compiled import Compiler
from workbench.equations.evaluate import FastFunction
from workbench.execution.environment import cpu_model
from workbench.plugins.formalisms.recursive import ode_function

TABLE = RESULTS / "compile_time.csv"


def compile_rows(n: int, compiles: int, flags: str = "-O1") -> list[dict]:
    """A row a cold compile of the ``n``-link spatial chain's jit right-hand side."""
    function = ode_function(family_model("spatial", n))
    vm = FastFunction(function)
    rng = np.random.default_rng(1)
    y = rng.uniform(-1, 1, 2 * n)
    expected = vm(0.0, y)[0]
    rows = []
    for index in range(compiles):
        jit = FastFunction(function, Compiler("jit", flags))
        row: dict = {"model": f"spatial chain N = {n}", "compile": index + 1}
        load = os.getloadavg()[0]
        if not cold_compile(jit, row):
            raise RuntimeError(f"the N = {n} chain did not compile: {row.get('note')}")
        difference = float(np.abs(jit(0.0, y)[0] - expected).max())
        if not difference <= 1e-9 * max(1.0, float(np.abs(expected).max())):
            raise AssertionError(f"compiled and VM right-hand sides differ by {difference:.2e}")
        row |= {"instructions": function.n_instructions(), "load1_before": load,
                "load1_after": os.getloadavg()[0], "cpu": cpu_model(), "l2_kib": l2_kib(),
                "date": datetime.date.today().isoformat()}  # fmt: skip
        rows.append(row)
        print(f"compile {index + 1}: {row['compile_cpu_s']:.2f} s CPU, "
              f"{row['compile_s']:.2f} s wall (load {load:.1f})", flush=True)  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.compile_time", description=__doc__)
    parser.add_argument("--compiles", type=int, default=3, help="cold compiles (default 3)")
    parser.add_argument("--n", type=int, default=50, help="links of the chain (default 50)")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    new = pd.DataFrame(compile_rows(args.n, args.compiles))
    table = pd.concat([pd.read_csv(TABLE), new]) if TABLE.exists() else new
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(TABLE, index=False)
    summary = table.groupby(["model", "cpu", "l2_kib"])["compile_cpu_s"].agg(
        ["median", "min", "max", "count"]
    )
    with pd.option_context("display.width", 200):
        print(summary.to_string(float_format="{:.2f}".format))
    print(f"wrote {TABLE}")
    return table


if __name__ == "__main__":
    main()
