"""Cost of one ode right-hand-side evaluation against the number of bodies N.

Compares the formalisms ``recursive`` (articulated bodies, O(n)) and ``minimal-ode``
(mass matrix by Jacobians and a symbolic solve, O(n^3)) on N-link pendulum chains:

- planar: N uniform links (1 kg, 1 m) on revolute joints about z;
- spatial: the same links on revolute joints whose axes alternate between z and x.

For each (chain, formalism, N) the ode right-hand side [q'; v'] is built exactly as
:func:`workbench.equations.build_equations` builds it for an unconstrained model (only
that function: the other forms' Jacobians would dominate the build time of large
models), wrapped in a :class:`~workbench.equations.evaluate.FastFunction`, and timed through
``.into`` with :mod:`timeit` (best of several repeats). minimal-ode is skipped at the
sizes whose build time, extrapolated as N^3 (minimal-ode; N^1.5 for recursive) from
the last size built,, exceeds
``--max-build`` seconds (60 by default).

Prints a table and the fitted exponent p of cost ~ N^p (log-log least squares over
N >= 10); writes ``benchmarks/results/scaling.csv``.

Run: ``python -m benchmarks.scaling [--sizes 2 5 10 ...] [--max-build 60]``.
"""

from __future__ import annotations

import argparse
import csv
import gc
import time
import timeit
from pathlib import Path

import casadi as ca
import numpy as np

from workbench.equations.evaluate import FastFunction
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import Frame, Model
from workbench.plugins.formalisms import recursive as rec
from workbench.plugins.formalisms.minimal_ode import minimal_mechanical_system

SIZES = (2, 5, 10, 20, 50, 100, 200)
FORMALISMS = ("recursive", "minimal-ode")
RESULTS = Path(__file__).parent / "results" / "scaling.csv"
# assumed growth of the build time in N, to predict the next size's build
BUILD_EXPONENT = {"recursive": 1.5, "minimal-ode": 3.0}


def pendulum_chain(n: int, kind: str) -> Model:
    """N uniform links of 1 kg and 1 m hanging from the ground (see the module doc)."""
    model = Model(f"{kind}-chain-{n}", kind=kind)
    parent = "ground"
    for i in range(n):
        model.add_body(f"link{i}", 1.0, com=(0.0, -0.5, 0.0), inertia=(0.0834, 0.001, 0.0834))
        axis = (0, 0, 1) if kind == "planar" or i % 2 == 0 else (1, 0, 0)
        offset = Frame.at(0, -1.0, 0) if i else Frame()
        model.add_joint(f"joint{i}", "revolute", parent, f"link{i}", offset, axis=axis)
        parent = f"link{i}"
    return model.validate()


def ode_rhs(model: Model, formalism: str) -> ca.Function:
    """The ode right-hand side f(t, y) of ``formalism`` for an unconstrained model."""
    if formalism == "recursive":
        return rec.ode_function(model, "aba")
    k = TreeKinematics(model)
    system = minimal_mechanical_system(model, k)
    acceleration = ca.solve(system.mass, system.forces)  # as build_equations does
    y = ca.vertcat(k.q, k.v)
    return ca.Function("ode_rhs", [k.t, y], [ca.densify(ca.vertcat(k.qdot, acceleration))])


def time_evaluation(function: ca.Function, n_y: int, repeats: int = 7) -> float:
    """Best per-call time in seconds of ``FastFunction.into`` at a random state."""
    fast = FastFunction(function)
    y = np.random.default_rng(0).uniform(-1, 1, n_y)
    timer = timeit.Timer(lambda: fast.into(0.1, y))
    number, _ = timer.autorange()  # calls per repeat so that one repeat takes >= 0.2 s
    return min(timer.repeat(repeat=repeats, number=number)) / number


def fitted_exponent(sizes: list[int], seconds: list[float], smallest: int = 10) -> float:
    """p in seconds ~ N^p by least squares on log-log data with N >= ``smallest``."""
    points = [(n, s) for n, s in zip(sizes, seconds, strict=True) if n >= smallest]
    if len(points) < 2:
        return float("nan")
    x, y = np.log([p[0] for p in points]), np.log([p[1] for p in points])
    return float(np.polyfit(x, y, 1)[0])


def run(sizes: tuple[int, ...], max_build: float) -> list[dict]:
    rows: list[dict] = []
    for kind in ("planar", "spatial"):
        for formalism in FORMALISMS:
            last: tuple[int, float] | None = None
            for n in sizes:
                predicted = (
                    0.0 if last is None else last[1] * (n / last[0]) ** BUILD_EXPONENT[formalism]
                )
                if predicted > max_build:
                    rows.append(
                        dict(
                            chain=kind,
                            formalism=formalism,
                            n=n,
                            status="skipped",
                            build_s="",
                            instructions="",
                            eval_us="",
                        )
                    )
                    print(
                        f"{kind:8s} {formalism:12s} N={n:4d}  skipped: predicted build "
                        f"{predicted:.0f} s > {max_build:.0f} s",
                        flush=True,
                    )
                    continue
                model = pendulum_chain(n, kind)
                gc.collect()  # free the previous (large) graphs outside the timed build
                start = time.perf_counter()
                function = ode_rhs(model, formalism)
                fast = FastFunction(function)  # part of the build: allocates the buffers
                build = time.perf_counter() - start
                del fast
                last = (n, build)
                seconds = time_evaluation(function, 2 * n)
                if build > max_build:
                    print(
                        f"{kind:8s} {formalism:12s} N={n:4d}  built in {build:.0f} s > "
                        f"{max_build:.0f} s: larger sizes skipped",
                        flush=True,
                    )
                    last = (n, float("inf"))
                instructions = function.n_instructions()
                del function  # free the graph here, not inside the next timed build
                rows.append(
                    dict(
                        chain=kind,
                        formalism=formalism,
                        n=n,
                        status="ok",
                        build_s=f"{build:.3f}",
                        instructions=instructions,
                        eval_us=f"{seconds * 1e6:.3f}",
                    )
                )
                print(
                    f"{kind:8s} {formalism:12s} N={n:4d}  build {build:8.2f} s  "
                    f"{instructions:9d} instr  {seconds * 1e6:10.2f} us",
                    flush=True,
                )
    return rows


def summary(rows: list[dict]) -> None:
    print()
    print(f"{'chain':8s} {'formalism':12s} " + " ".join(f"{n:>9d}" for n in SIZES_RUN))
    for kind in ("planar", "spatial"):
        for formalism in FORMALISMS:
            cells = {r["n"]: r for r in rows if r["chain"] == kind and r["formalism"] == formalism}
            line = " ".join(
                f"{float(cells[n]['eval_us']):9.1f}"
                if cells[n]["status"] == "ok"
                else f"{'skipped':>9s}"
                for n in SIZES_RUN
            )
            ok = [r for r in cells.values() if r["status"] == "ok"]
            p = fitted_exponent([r["n"] for r in ok], [float(r["eval_us"]) for r in ok])
            p_instr = fitted_exponent([r["n"] for r in ok], [float(r["instructions"]) for r in ok])
            print(
                f"{kind:8s} {formalism:12s} {line}   (us per call; N >= 10: time "
                f"N^{p:.2f}, instructions N^{p_instr:.2f})"
            )
        both = {
            n: {
                r["formalism"]: float(r["eval_us"])
                for r in rows
                if r["chain"] == kind and r["n"] == n and r["status"] == "ok"
            }
            for n in SIZES_RUN
        }
        compared = [n for n, t in both.items() if len(t) == 2]
        # crossover: the smallest N from which recursive is faster at every size compared
        faster = [
            n
            for n in compared
            if all(both[m]["recursive"] < both[m]["minimal-ode"] for m in compared if m >= n)
        ]
        print(
            f"{kind:8s} recursive faster than minimal-ode from N = "
            f"{min(faster) if faster else 'never (in the sizes run)'}"
        )


def write_csv(rows: list[dict], path: Path = RESULTS) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"\nwrote {path}")


SIZES_RUN: tuple[int, ...] = SIZES


def main() -> None:
    global SIZES_RUN
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--max-build", type=float, default=60.0)
    args = parser.parse_args()
    SIZES_RUN = tuple(args.sizes)
    rows = run(SIZES_RUN, args.max_build)
    summary(rows)
    write_csv(rows)


if __name__ == "__main__":
    main()
