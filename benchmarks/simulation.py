"""A whole simulation against SciPy's DOP853 driving ``pinocchio.aba``.

Run: ``python -m benchmarks.simulation [--repeat 3]``. The ``spatial-chain`` problem with
7 links (axes z, y, x, ...) from its initial state over t in [0, 5] s, 51 output times,
rtol 1e-8 and atol 1e-10 for everyone:

- the peer: ``scipy.integrate.solve_ivp(method="DOP853")`` whose right-hand side calls
  ``pin.aba`` on a ``pin.Model`` built from ours (:mod:`benchmarks.peer_models`);
- ours: the ``recursive`` formalism compiled to C (``compile = "jit"``) and in the CasADi
  VM, through our integrator plugins (``scipy-dop853``, ``sundials-cvode-adams``,
  ``casadi-cvodes`` with Adams and fixed-point iteration), exactly as a run calls them
  (``Integrator.solve``).

``end_error`` is the largest difference of the final state (q, v) from a reference
(DOP853 at rtol = atol = 1e-13 on our compiled right-hand side). The chain is chaotic, so
errors at t = 5 s are large and not monotonic in the tolerance: for the same final
accuracy each of ours is run at the largest rtol of 1e-8, 1e-9, 1e-10, 1e-11 (atol =
rtol / 100) whose end error is at most the peer's (``rtol`` column). ``wall_s`` is the
best of ``--repeat`` integrations (the build and the compilation are excluded and
reported apart). ``ratio`` is wall_s over the peer's. Prints a table and writes
``benchmarks/results/simulation.csv``.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from benchmarks.peer_models import pinocchio_model
from workbench.equations.initial import consistent_initial_state
from workbench.plugin.registry import get_formalism, get_integrator, get_problem

RESULTS = Path(__file__).parent / "results"
T_END, RTOL, ATOL = 5.0, 1e-8, 1e-10
OURS = {
    "scipy-dop853": None,
    "sundials-cvode-adams": None,
    "casadi-cvodes": {"method": "adams", "iteration": "functional"},
}
LADDER = (1e-8, 1e-9, 1e-10, 1e-11)


def best_wall(run, repeat: int) -> tuple[float, np.ndarray]:
    best, final = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        final = run()
        best = min(best, time.perf_counter() - start)
    return best, final


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.simulation", description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--links", type=int, default=7)
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    problem = get_problem("spatial-chain")({"n_links": args.links})
    model = problem.model()
    times = np.linspace(0.0, T_END, 51)
    rows = []
    equations = {}
    for mode in ("jit", "none"):
        start = time.perf_counter()
        equations[mode] = get_formalism("recursive")().build(model, {"compile": mode})
        build_s = time.perf_counter() - start
        start = time.perf_counter()
        equations[mode].forms["ode"].rhs.compile()
        compile_s = time.perf_counter() - start
        rows.append({"pipeline": f"(build recursive, compile={mode})", "wall_s": build_s})
        if mode == "jit":
            rows.append({"pipeline": "(compile ode rhs, cached or cold)", "wall_s": compile_s})
    y0 = consistent_initial_state(equations["jit"], problem).y0(equations["jit"], "ode")
    n = y0.size // 2
    rhs = equations["jit"].forms["ode"].rhs
    reference = solve_ivp(
        lambda t, y: rhs(t, y)[0], (0.0, T_END), y0, method="DOP853", rtol=1e-13, atol=1e-13
    ).y[:, -1]

    def error(final: np.ndarray) -> float:
        return float(np.abs(final - reference).max())

    peer_wall = np.nan
    if importlib.util.find_spec("pinocchio"):
        import pinocchio as pin

        pin_model, order = pinocchio_model(model)
        data, tau, back = pin_model.createData(), np.zeros(n), np.argsort(order)

        def pin_rhs(t: float, y: np.ndarray) -> np.ndarray:
            a = pin.aba(pin_model, data, y[:n][order], y[n:][order], tau)
            return np.concatenate([y[n:], a[back]])

        def peer() -> np.ndarray:
            solution = solve_ivp(
                pin_rhs, (0.0, T_END), y0, method="DOP853", t_eval=times, rtol=RTOL, atol=ATOL
            )
            return solution.y[:, -1]

        peer_wall, final = best_wall(peer, args.repeat)
        peer_error = error(final)
        rows.append(
            {"pipeline": "scipy DOP853 + pin.aba", "rtol": RTOL, "wall_s": peer_wall}
            | {"end_error": peer_error}
        )
    else:
        peer_error = np.inf
        print("not installed: pinocchio (pip install -e '.[bench]'); the peer is skipped")
    for mode in ("jit", "none"):
        for name, options in OURS.items():
            integrator = get_integrator(name)()
            for rtol in LADDER:

                def ours(integrator=integrator, mode=mode, rtol=rtol, options=options):
                    trajectory = integrator.solve(
                        equations[mode], y0, None, times, rtol, rtol / 100, options, "ode"
                    )
                    if not trajectory.success:
                        raise RuntimeError(f"{integrator.name}: {trajectory.message}")
                    return np.asarray(trajectory.y)[-1]

                if error(ours()) <= peer_error or rtol == LADDER[-1]:
                    break
            wall, final = best_wall(ours, args.repeat)
            label = name + (" (adams, functional)" if options else "")
            rows.append(
                {"pipeline": f"recursive {mode} + {label}", "rtol": rtol, "wall_s": wall}
                | {"end_error": error(final)}
            )
    table = pd.DataFrame(rows)
    table["ratio"] = table["wall_s"] / peer_wall
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "simulation.csv", index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return table


if __name__ == "__main__":
    main()
