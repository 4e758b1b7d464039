"""Figures of a results frame for notebooks (matplotlib): the work-precision diagram."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd


def plot_work_precision(
    results: pd.DataFrame,
    problem: str | None = None,
    cost: str = "integrate_cpu_s",
    by: tuple[str, ...] = ("formalism", "integrator"),
    ax: Any = None,
) -> Any:
    """scd (correct digits at the end) against ``cost`` (log x), one curve per ``by``
    group, one point per tolerance, of the ok runs of ``problem`` (default: the only
    problem in ``results``). ``results`` as ``workbench.load_results`` returns it;
    ``cost``: any cost column (``integrate_cpu_s``, ``integrate_s``, ``n_rhs``...).
    Returns the Axes."""
    if problem is None:
        names = sorted(results["problem"].unique())
        if len(names) != 1:
            raise ValueError(f"results hold {len(names)} problems; name one: {names}")
        problem = names[0]
    if problem not in set(results["problem"]):  # an empty diagram said nothing of why
        names = sorted(results["problem"].unique())
        raise ValueError(f"no run of problem {problem!r} in these results; they hold {names}")
    runs = results[(results["problem"] == problem) & (results["status"] == "ok")]
    runs = runs[np.isfinite(runs["scd"].astype(float)) & (runs[cost].astype(float) > 0)]
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7, 4.5))
    for label, curve in runs.groupby(list(by)):
        curve = curve.sort_values("rtol", ascending=False)
        name = " / ".join(map(str, label if isinstance(label, tuple) else (label,)))
        ax.plot(curve[cost], curve["scd"], marker="o", markersize=4, label=name)
    ax.set_xscale("log")
    ax.set_xlabel(cost)
    ax.set_ylabel("scd = -log10(relative end error)")
    ax.set_title(f"{problem}: work-precision")
    ax.grid(True, alpha=0.3)
    if len(runs):
        ax.legend(fontsize="small")
    return ax
