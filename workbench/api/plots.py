"""Figures of a results frame for notebooks (matplotlib): the work-precision diagram."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from workbench.errors import ConfigError


def plot_work_precision(
    results: pd.DataFrame,
    problem: str | None = None,
    cost: str = "integrate_cpu_s",
    by: str | tuple[str, ...] = ("formalism", "integrator"),
    ax: Any = None,
) -> Any:
    """scd (correct digits at the end) against ``cost`` (log x), one curve per ``by``
    group (a column or a tuple of columns), one point per tolerance, of the ok runs of
    ``problem`` (default: the only problem in ``results``); a red ring marks a run with
    warnings (its scd may be capped by the reference's accuracy: not a measurement), as
    the report's diagrams do. ``results`` as
    ``workbench.load_results`` returns it; ``cost``: a cost measure as ``workbench.report``
    takes it (``integrate_cpu``, ``integrate_wall``, ``n_rhs``, ``work``) or any cost
    column (``integrate_cpu_s``, ``n_steps``...). Returns the Axes; ConfigError for a
    problem or a column that ``results`` do not have."""
    if not isinstance(results, pd.DataFrame):
        raise ConfigError(
            "results: expected the results frame (workbench.load_results(OUT) or "
            f"workbench.sweep(...)), not {type(results).__name__}"
        )
    by = (by,) if isinstance(by, str) else tuple(by)
    from workbench.outputs.report.cost import COST_LABELS, COST_MEASURES

    cost, cost_label = COST_MEASURES.get(cost, (cost, cost))  # a measure by its name too
    cost_label = COST_LABELS.get(cost, cost_label)  # a column too: its label with its unit
    for column in ("problem", "status", "scd", "rtol", cost, *by):
        if column not in results.columns:
            numeric = [c for c in results.columns if c.startswith(("n_", "integrate_", "work_"))]
            raise ConfigError(
                f"results have no column {column!r}"
                + (f"; cost measures: {', '.join(COST_MEASURES)}; cost columns: "
                   f"{', '.join(numeric)}" if column == cost else "")  # fmt: skip
            )
    from workbench.outputs.report.analysis import problem_labels
    from workbench.outputs.report.trust import warned

    results = results.assign(problem=problem_labels(results))  # one label a mechanism
    names = sorted(results["problem"].unique())
    if problem is None:
        if not names:
            raise ConfigError("results hold no runs: nothing to plot")
        if len(names) != 1:
            raise ConfigError(f"results hold {len(names)} problems; name one: {names}")
        problem = names[0]
    elif problem not in names:
        raise ConfigError(f"results hold no runs of problem {problem!r}; they hold {names}")
    runs = results[(results["problem"] == problem) & (results["status"] == "ok")]
    runs = runs[np.isfinite(runs["scd"].astype(float)) & (runs[cost].astype(float) > 0)]
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")  # labels inside
    for label, curve in runs.groupby(list(by)):
        curve = curve.sort_values("rtol", ascending=False)
        name = " / ".join(map(str, label if isinstance(label, tuple) else (label,)))
        ax.plot(curve[cost], curve["scd"], marker="o", markersize=4, label=name)
    flagged = runs[warned(runs)]
    if len(flagged):
        ax.scatter(flagged[cost], flagged["scd"], s=70, facecolors="none", edgecolors="red",
                   linewidths=1.2, zorder=3, label="warnings (see status)")  # fmt: skip
    ax.set_xscale("log")
    ax.set_xlabel(cost_label)
    ax.set_ylabel("scd = -log10(relative end error)")
    ax.set_title(f"{problem}: work-precision")
    ax.grid(True, alpha=0.3)
    if len(runs):
        ax.legend(fontsize="small")
    return ax
