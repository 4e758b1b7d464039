"""Time to build the equations and per-evaluation time of f for every problem x formalism.

Run: ``python -m benchmarks.build_and_eval [PROBLEM ...]``. Prints a table and writes
``benchmarks/results/build_and_eval.csv``. The right-hand side is the ode form where the
formalism offers one (index-1 options for closed loops), else the dae residual; it is
timed through the preallocated buffers (``FastFunction.into``), best of 5 repeats.
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
from workbench.plugin.registry import list_plugins

RESULTS = Path(__file__).parent / "results"
OPTIONS = {"minimal-ode": {"index": 1}, "absolute-dae": {"index": 1}}


def measure(problem_class: type, formalism_class: type) -> dict:
    problem = problem_class()
    model = problem.model()
    row = {"problem": problem.name, "formalism": formalism_class.name}
    if formalism_class.unsupported(model):
        return row | {"note": "unsupported: " + ", ".join(formalism_class.unsupported(model))}
    options = OPTIONS.get(formalism_class.name, {})
    start = time.perf_counter()
    equations = formalism_class().build(model, options)
    row["build_s"] = time.perf_counter() - start
    state = consistent_initial_state(equations, problem)
    if "ode" in equations.forms:
        function, args, row["form"] = (
            equations.forms["ode"].rhs,
            (0.0, state.y0(equations, "ode")),
            "ode",
        )
    else:
        y, yp = state.y0(equations, "dae"), state.yp0(equations, "dae")
        function, args, row["form"] = equations.forms["dae"].residual, (0.0, y, yp), "dae"
    number = 2000
    best = min(timeit.repeat(lambda: function.into(*args), number=number, repeat=5))
    row["eval_us"] = best / number * 1e6
    row["n_states"] = int(np.size(args[1]))
    return row


def main(argv: list[str]) -> pd.DataFrame:
    warnings.filterwarnings("ignore")
    problems = [i.plugin for i in list_plugins("problem") if i.plugin is not None]
    if argv:
        problems = [p for p in problems if p.name in argv]
    formalisms = [i.plugin for i in list_plugins("formalism") if i.plugin is not None]
    rows = [measure(p, f) for p in problems for f in formalisms]
    table = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "build_and_eval.csv", index=False)
    with pd.option_context("display.width", 120, "display.max_rows", 500):
        print(table.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main(sys.argv[1:])
