"""Cost of the energy-based formalisms (lagrange-ad, hamilton) against minimal-ode and
recursive: time to build the equations and per-evaluation time of the ode right-hand
side and of its Jacobian, on every catalog problem each supports.

Run: ``python -m benchmarks.energy_formalisms [PROBLEM ...]``. Prints a table and writes
``benchmarks/results/energy_formalisms.csv``. Builds and evaluations as in
:mod:`benchmarks.build_and_eval` (best of 5 repeats through preallocated buffers); all
four use index-1 options, so closed loops have an ode form too.
"""

from __future__ import annotations

import sys
import time
import timeit
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks import help_if_asked
from workbench.equations.initial import consistent_initial_state
from workbench.plugin.registry import get_formalism, list_plugins

RESULTS = Path(__file__).parent / "results"
FORMALISMS = {
    "minimal-ode": {"index": 1},
    "recursive": {"index": 1},
    "lagrange-ad": {"index": 1},
    "hamilton": {},
}


def measure(problem: object, name: str) -> dict:
    formalism = get_formalism(name)
    model = problem.model()
    row = {"problem": problem.name, "formalism": name}
    if formalism.unsupported(model):
        return row | {"note": "unsupported"}
    start = time.perf_counter()
    equations = formalism().build(model, FORMALISMS[name])
    row["build_s"] = time.perf_counter() - start
    ode = equations.forms["ode"]
    y = consistent_initial_state(equations, problem).y0(equations, "ode")
    row["n_states"] = int(np.size(y))
    for key, function in (("rhs_us", ode.rhs), ("jac_us", ode.jacobian)):
        function.into(0.0, y)  # a lazy Jacobian is built here, outside the timing
        number = 1000
        best = min(timeit.repeat(lambda f=function: f.into(0.0, y), number=number, repeat=5))
        row[key] = best / number * 1e6
    row["rhs_instructions"] = int(ode.rhs.function.n_instructions())
    return row


def main(argv: list[str]) -> pd.DataFrame:
    warnings.filterwarnings("ignore")
    problems = [i.plugin() for i in list_plugins("problem") if i.plugin is not None]
    if argv:
        problems = [p for p in problems if p.name in argv]
    table = pd.DataFrame([measure(p, f) for p in problems for f in FORMALISMS])
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "energy_formalisms.csv", index=False)
    with pd.option_context("display.width", 140, "display.max_rows", 500):
        print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main(sys.argv[1:])
