"""scipy-dae against SUNDIALS IDA and generalized-alpha on closed loops: work-precision.

Run: ``python -m benchmarks.dae_comparison [--problems ...] [--tolerances ...]``. On the
catalog's closed-loop mechanisms (``slider-crank``, ``four-bar``, ``andrews``) built by the
``recursive`` formalism (joint coordinates, loops closed by multipliers) at DAE index 1, 2
and 3, integrate each problem's span with

- ``scipy-dae-radau`` and ``scipy-dae-bdf`` on the dae form at index 3, 2 and 1;
- ``sundials-ida`` on the dae form at index 1 and 2 (it accepts no index 3);
- ``generalized-alpha`` on the mechanical form (index 3), its step from the tolerance
  (order 2: :func:`workbench.plugin.integrator.step_for_tolerance`), down to rtol 1e-8
  (h = 0.1 ms; tighter steps take minutes of Python);

at rtol in ``--tolerances`` (atol = rtol / 1000, the default sweep's factor). ``error``
is the largest difference of the final joint coordinates q from a reference (DOP853 at
rtol = atol = 1e-12 on the index-1 ode form, whose Baumgarte-stabilized drift stays at
round-off); ``cpu_s`` is the CPU time of the solve, ``n_rhs`` / ``n_jac`` the residual and
Jacobian evaluations. A failed solve is a row with its message and NaN error. Prints a
table (per problem and pipeline: the cheapest run reaching an error below 1e-4, 1e-6 and 1e-8) and
writes ``benchmarks/results/dae_comparison.csv`` (every run).
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from workbench.equations.initial import consistent_initial_state
from workbench.plugin.registry import get_formalism, get_integrator, get_problem

RESULTS = Path(__file__).parent / "results"
PROBLEMS = ("slider-crank", "four-bar", "andrews")
TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
PIPELINES = [  # (integrator, index, form)
    *((name, index, "dae") for name in ("scipy-dae-radau", "scipy-dae-bdf") for index in (3, 2, 1)),
    ("sundials-ida", 1, "dae"),
    ("sundials-ida", 2, "dae"),
    ("generalized-alpha", 3, "mechanical"),
]
LEVELS = (1e-4, 1e-6, 1e-8)
FIXED_STEP_RTOL = 1e-8  # generalized-alpha's tightest rtol (h = 0.1 ms)


def run_problem(name: str, tolerances: tuple[float, ...]) -> list[dict]:
    problem = get_problem(name)({})
    model = problem.model()
    times = np.linspace(0.0, problem.t_end, 51)
    built = {
        index: get_formalism("recursive")().build(model, {"index": index, "compile": "jit"})
        for index in (1, 2, 3)
    }
    states = {index: consistent_initial_state(e, problem) for index, e in built.items()}
    ode = built[1].forms["ode"].rhs
    y0_ode = states[1].y0(built[1], "ode")
    nq = states[1].q.size
    reference = solve_ivp(
        lambda t, y: ode(t, y)[0], (0.0, problem.t_end), y0_ode, method="DOP853",
        rtol=1e-12, atol=1e-12,
    ).y[:nq, -1]  # fmt: skip
    rows = []
    for integrator_name, index, form in PIPELINES:
        integrator = get_integrator(integrator_name)()
        equations = built[index]
        y0 = states[index].y0(equations, form)
        yp0 = states[index].yp0(equations, form)
        for rtol in tolerances:
            if form == "mechanical" and rtol < FIXED_STEP_RTOL:
                continue  # h = 10 us and below: minutes of Python steps
            row = {"problem": name, "integrator": integrator_name, "index": index, "rtol": rtol}
            try:
                trajectory = integrator.solve(
                    equations, y0, yp0, times, rtol, rtol / 1000, None, form
                )
            except Exception as error:  # a refusal or a crash is a row, not the end of the table
                rows.append(row | {"error": np.nan, "message": f"{type(error).__name__}: {error}"})
                continue
            stats = trajectory.stats
            final = np.asarray(trajectory.y)[-1][:nq] if trajectory.success else None
            rows.append(
                row
                | {
                    "error": np.nan if final is None else float(np.abs(final - reference).max()),
                    "cpu_s": stats.cpu_s, "n_rhs": stats.n_rhs, "n_jac": stats.n_jac,
                    "message": "" if trajectory.success else trajectory.message,
                }
            )  # fmt: skip
    return rows


def cheapest(table: pd.DataFrame) -> pd.DataFrame:
    """Per problem and pipeline, the CPU seconds and rhs evaluations of the cheapest run
    whose error is below each of LEVELS (NaN where none is)."""
    out = []
    for (problem, integrator, index), group in table.groupby(["problem", "integrator", "index"]):
        row = {"problem": problem, "pipeline": f"{integrator} (index {index})"}
        for level in LEVELS:
            good = group[group.error <= level]
            best = good.loc[good.cpu_s.idxmin()] if len(good) else None
            row[f"cpu_s@{level:g}"] = best.cpu_s if best is not None else np.nan
            row[f"n_rhs@{level:g}"] = best.n_rhs if best is not None else np.nan
        row["best_error"] = group.error.min()
        out.append(row)
    return pd.DataFrame(out)


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.dae_comparison", description=__doc__
    )
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS))
    parser.add_argument("--tolerances", type=float, nargs="+", default=list(TOLERANCES))
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    rows = []
    for name in args.problems:
        rows += run_problem(name, tuple(args.tolerances))
        print(f"{name}: done", flush=True)
    table = pd.DataFrame(rows)
    table["load_1min"] = os.getloadavg()[0]
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "dae_comparison.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(cheapest(table).to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return table


if __name__ == "__main__":
    main()
