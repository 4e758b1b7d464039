"""The C compiler's CPU a byte of generated C at the default flags: ``compile = "auto"``'s
estimate (:mod:`workbench.equations.compile_policy`).

Run: ``python -m benchmarks.compile_cost``. Generates the C of the quick suite's
right-hand sides and residuals (each problem x minimal-ode, recursive, absolute-dae at
index 1, as a sweep builds them) and of the per-call benchmark's articulated bodies
(:mod:`benchmarks.peers_pyperf`: random trees N = 7, 20, 50, 200, UR5, Panda, Solo12,
Talos), then compiles each (never from the cache) at its default flags
(``compiled.default_flags``: ``-O2`` up to 15,000 instructions, ``-O1`` beyond, with the
host's ``-mavx -ffp-contract=off``) and at ``-O1`` with the host's flags, twice each,
keeping the lesser CPU of the compiler's processes, beside ``compile = "auto"``'s estimates
(:func:`~workbench.equations.compile_policy.code_bytes_estimate`). Writes
``benchmarks/results/compile_cost.csv`` and prints the least-squares line CPU = fixed +
per byte x bytes of the default flags against the constants in use.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.equations import compile_policy, compiled

RESULTS = Path(__file__).parent / "results"
REPEATS = 2


def functions() -> list[tuple[str, object]]:
    """(label, the graph compile = "auto" would compile) of every measured function."""
    from benchmarks.peers_pyperf import ROBOTS, SIZES, model_of
    from workbench.plugin.registry import get_formalism, get_problem
    from workbench.plugins.formalisms.recursive import ode_function
    from workbench.runs.sweep_spec import suite_text

    found = []
    suite = tomllib.loads(suite_text("quick"))
    for problem_name in suite["problems"]:
        model = get_problem(problem_name)({}).model()
        for formalism in suite["formalisms"]:
            options = {**formalism.get("options", {}), "compile": "auto"}
            try:
                equations = get_formalism(formalism["name"])().build(model, options)
            except Exception as error:  # a combination the formalism does not take
                print(f"skipped {problem_name} {formalism['name']}: {error}")
                continue
            for form, attribute in (("ode", "rhs"), ("dae", "residual")):
                if form in equations.forms:
                    fast = getattr(equations.forms[form], attribute)
                    found.append((f"{problem_name} {formalism['name']} {form}", fast.for_c))
    for kind, names in (("random", SIZES), ("robots", ROBOTS)):
        for name in names:
            model = model_of(kind, str(name))[0]
            found.append((f"{kind} {name} recursive ode", ode_function(model, kernels=None)))
    return found


def compile_cpu(code: str, flags: str, compiler: str) -> float:
    """The least CPU of the compiler's processes over :data:`REPEATS` compiles of ``code``."""
    best = float("inf")
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(REPEATS):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            compiled.build_library(code, flags, compiler, Path(folder) / f"{repeat}.so")
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
            best = min(best, cpu)
    return best


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    warnings.filterwarnings("ignore")
    load_before = os.getloadavg()[0]
    rows = []
    for label, function in functions():
        generated = compiled.generate(function)
        o1 = f"-O1 {compiled.host_flags()}".strip()
        row = {
            "function": label, "instructions": compile_policy.instruction_count(function),
            "code_bytes": len(generated.code),
            "estimated_bytes": compile_policy.code_bytes_estimate(function),
            "flags": generated.flags,
            "cpu_s": compile_cpu(generated.code, generated.flags, generated.compiler),
            "cpu_o1_s": compile_cpu(generated.code, o1, generated.compiler),
        }  # fmt: skip
        rows.append(row)
        print(", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                        for k, v in row.items()), flush=True)  # fmt: skip
    table = pd.DataFrame(rows).drop_duplicates("function")
    table["load1_before"], table["load1_after"] = load_before, os.getloadavg()[0]
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "compile_cost.csv", index=False)
    per_byte, fixed = np.polyfit(table.code_bytes, table.cpu_s, 1)
    print(
        f"default flags: CPU = {fixed:.3f} s + {per_byte * 1e6:.2f} s a MB "
        f"(in use: {compile_policy.COMPILE_CPU_FIXED_S} s + "
        f"{compile_policy.COMPILE_CPU_S_PER_BYTE * 1e6:.2f} s a MB); "
        f"bytes an instruction: median {np.median(table.code_bytes / table.instructions):.1f}"
    )
    print(f"default / -O1 CPU: median {np.median(table.cpu_s / table.cpu_o1_s):.2f}")
    estimated = table.estimated_bytes.map(compile_policy.compile_cpu_estimate) / table.cpu_s
    print(
        f"compile_cpu_estimate(code_bytes_estimate) / CPU: {estimated.min():.2f}-"
        f"{estimated.max():.2f}, median {estimated.median():.2f}"
    )


if __name__ == "__main__":
    main()
