"""What a computed reference costs at many output times (issue 18.15).

Run: ``python -m benchmarks.reference_samples [N ...]`` (default 1000 10000 100000). For
problems whose reference is computed (no analytic or stored one at these times) and N
output times it measures, once each (wall seconds):

- ``integrate_s``: the reference pipeline's tight-tolerance integration (rtol 1e-12);
- ``per_sample_s``: body poses one ``Observables.poses`` call per sample (the old way;
  NaN above PER_SAMPLE_MAX samples, where it takes minutes);
- ``mapped_s``: the same poses in one mapped call (``Observables.poses_along``, now used);
- ``max_diff``: the largest difference between the two (they must agree to round-off);
- ``reference_s``: :func:`workbench.execution.references.computed_reference` end to end
  (integration + poses, in memory, nothing cached), the row's ``reference_s``.

Prints a table and writes ``benchmarks/results/reference_samples.csv``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks import help_if_asked
from workbench.equations.initial import consistent_initial_state
from workbench.execution import references
from workbench.plugin import registry

RESULTS = Path(__file__).parent / "results"
PROBLEMS = ["double-pendulum", "four-bar"]
PER_SAMPLE_MAX = 100_000


def measure(name: str, n: int) -> dict:
    problem = registry.get_problem(name)()
    problem.n_samples = n
    times = problem.sample_times()
    model = problem.model()
    pipeline = references.configured_pipeline("computed", model)
    equations = registry.get_formalism(pipeline.formalism)().build(
        model, pipeline.formalism_options
    )
    integrator = registry.get_integrator(pipeline.integrator)()
    offered = {key: getattr(form, "index", 0) for key, form in equations.forms.items()}
    form = integrator.select_form(offered)
    state = consistent_initial_state(equations, problem)
    started = time.perf_counter()
    trajectory = integrator.solve(
        equations, state.y0(equations, form), state.yp0(equations, form), times,
        references.REFERENCE_RTOL, references.REFERENCE_ATOL, None, form,
    )  # fmt: skip
    row = {"problem": name, "samples": n, "integrate_s": time.perf_counter() - started}
    q = trajectory.y[:, : equations.nq]
    started = time.perf_counter()
    mapped = equations.observables.poses_along(times, q)
    row["mapped_s"] = time.perf_counter() - started
    row["per_sample_s"] = row["max_diff"] = float("nan")
    if n <= PER_SAMPLE_MAX:
        started = time.perf_counter()
        pairs = zip(times, q, strict=True)
        one_by_one = np.stack([equations.observables.poses(t, qk) for t, qk in pairs])
        row["per_sample_s"] = time.perf_counter() - started
        row["max_diff"] = float(np.abs(mapped - one_by_one).max())
    references._REFERENCE_MEMORY.clear()
    started = time.perf_counter()
    computed = references.computed_reference(problem, name, {}, times, None)
    row["reference_s"] = time.perf_counter() - started
    assert computed.poses is not None and computed.poses.shape == mapped.shape
    return row


def main(argv: list[str] | None = None) -> pd.DataFrame:
    sizes = [int(a) for a in argv] if argv else [1000, 10_000, 100_000]
    table = pd.DataFrame([measure(name, n) for name in PROBLEMS for n in sizes])
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "reference_samples.csv", index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main(sys.argv[1:])
