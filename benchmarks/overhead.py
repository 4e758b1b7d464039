"""Per-call overhead of evaluating a CasADi Function from Python (issue: hot loops).

Run: ``python -m benchmarks.overhead``. For a trivial function y -> 2 y + t of n = 2, 14
and 200 states (so the arithmetic itself is negligible) it times, best of 5 autoranged
:mod:`timeit` repeats:

- ``buffer_us``: the bare ``Function.buffer()`` evaluation, arguments already in place;
- ``into_us``: :meth:`FastFunction.into(t, y) <workbench.equations.evaluate.FastFunction.into>`,
  what integrators call (copies t and y into the buffers, evaluates, counts the call);
- ``call_us``: ``FastFunction(t, y)``, the same plus copies of the outputs;
- ``casadi_call_us``: ``Function.__call__(t, y)`` (DM conversion in and out).

``overhead_us`` = into_us - buffer_us: what our Python glue adds to every evaluation.
Prints a table and writes ``benchmarks/results/overhead.csv``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pandas as pd

from benchmarks import help_if_asked
from benchmarks.peers import best_us
from workbench.equations.evaluate import FastFunction

RESULTS = Path(__file__).parent / "results"


def measure(n: int) -> dict:
    t, y = ca.SX.sym("t"), ca.SX.sym("y", n)
    fast = FastFunction(ca.Function("f", [t, y], [2 * y + t]))
    values = np.random.default_rng(0).random(n)
    fast.into(0.5, values)
    row = {"n": n, "buffer_us": best_us(fast._evaluate)}
    row["into_us"] = best_us(lambda: fast.into(0.5, values))
    row["call_us"] = best_us(lambda: fast(0.5, values))
    row["casadi_call_us"] = best_us(lambda: fast.function(0.5, values))
    row["overhead_us"] = row["into_us"] - row["buffer_us"]
    return row


def main(argv: list[str] | None = None) -> pd.DataFrame:
    sizes = [int(a) for a in argv] if argv else [2, 14, 200]
    table = pd.DataFrame([measure(n) for n in sizes])
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "overhead.csv", index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main(sys.argv[1:])
