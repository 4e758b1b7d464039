"""The figures of the report's overview, across problems: the problem x pair heat map of
cost at a fixed accuracy, and the convergence order of the fixed-step methods.

Drawn in the parent process (one figure each), with the Agg backend.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from workbench.outputs.report.figures import FigureFiles, PairStyles, log_axis, save_figure
from workbench.outputs.report.overview import COST_COLUMNS, trusted


def heat_map_figure(ratio: pd.DataFrame, target: float, cost: str, out: Path) -> FigureFiles | None:
    """Problem x pair heat map of ``ratio`` (cost / the problem's best at scd >= target;
    :func:`~workbench.outputs.report.overview.cost_ratio`), the ratio written in each
    cell, "-" where the pair never reached the target without warnings."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from matplotlib.ticker import LogFormatter

    if ratio.empty or not np.isfinite(ratio.to_numpy(dtype=float)).any():
        return None
    values = ratio.to_numpy(dtype=float)
    rows, columns = values.shape
    figure, ax = plt.subplots(figsize=(max(7.5, 2.5 + 0.42 * columns), 1.8 + 0.3 * rows))
    top = float(np.nanmax(values))
    image = ax.imshow(
        np.ma.masked_invalid(values),
        cmap="viridis_r",
        norm=LogNorm(vmin=1.0, vmax=max(top, 10.0)),
        aspect="auto",
    )
    ax.set_facecolor("0.92")
    for i in range(rows):
        for j in range(columns):
            value = values[i, j]
            text = "-" if not np.isfinite(value) else f"{value:.2g}"
            color = "0.4" if not np.isfinite(value) else ("white" if value > 3 else "black")
            ax.text(j, i, text, ha="center", va="center", fontsize=6.5, color=color)
    ax.set_xticks(range(columns), [str(c) for c in ratio.columns], rotation=60, ha="right",
                  fontsize="x-small")  # fmt: skip
    ax.set_yticks(range(rows), [str(r) for r in ratio.index], fontsize="x-small")
    ax.set_xlabel("pair (formalism / integrator)")
    ax.set_ylabel("problem")
    measure = COST_COLUMNS.get(cost, cost)
    name, _, unit = measure.partition(" [")
    bar = figure.colorbar(image, ax=ax, fraction=0.03, pad=0.01)
    bar.set_label(f"{name} / the best on the problem [-]", fontsize="small")
    plain = LogFormatter(labelOnlyBase=False, minor_thresholds=(1.2, 0.6))
    bar.ax.yaxis.set_major_formatter(plain)
    bar.ax.yaxis.set_minor_formatter(plain)
    ax.set_title(f"cost at scd >= {target:g} relative to the best pair of each problem\n"
                 "(1 = best; -: not reached without warnings)", fontsize="small")  # fmt: skip
    return save_figure(
        figure,
        out,
        "overview-heat-map",
        f"Cost ({name}) of each pair at scd >= {target:g}, divided by the least cost of any "
        "pair on that problem",
    )


def fixed_step_rows(runs: pd.DataFrame) -> pd.DataFrame:
    """Trusted runs with a fixed step (column ``fixed_step_s`` finite) and a finite end
    error, of the pairs run at two steps or more on a problem."""
    if "fixed_step_s" not in runs:
        return runs.iloc[:0]
    rows = trusted(runs)
    steps = pd.to_numeric(rows["fixed_step_s"], errors="coerce")
    error = rows["err_end"] / rows["length_scale"] if "length_scale" in rows else rows["err_end"]
    rows = rows.assign(fixed_step_s=steps, relative_error=error)
    rows = rows[np.isfinite(rows["fixed_step_s"]) & np.isfinite(error) & (error > 0)]
    counts = rows.groupby(["problem", "pair"])["fixed_step_s"].transform("nunique")
    return rows[counts >= 2]


def observed_order(steps: np.ndarray, errors: np.ndarray) -> float:
    """The slope of log(error) against log(step), by least squares."""
    slope, _intercept = np.polyfit(np.log(steps), np.log(errors), 1)
    return float(slope)


def convergence_figure(runs: pd.DataFrame, out: Path) -> FigureFiles | None:
    """End error against step size (log-log) of the fixed-step methods, a panel a problem,
    each curve labelled with its observed order (the fitted slope)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    rows = fixed_step_rows(runs)
    if rows.empty:
        return None
    problems = list(dict.fromkeys(rows["problem"]))
    ncols = min(3, len(problems))
    nrows = -(-len(problems) // ncols)
    figure, axes = plt.subplots(nrows, ncols, figsize=(4.3 * ncols, 3.2 * nrows), squeeze=False)
    figure.subplots_adjust(hspace=0.55, wspace=0.3, top=0.9)
    styles = PairStyles(rows)
    for ax, problem in zip(axes.flat, problems, strict=False):
        of_problem = rows[rows["problem"] == problem]
        for pair, curve in of_problem.groupby("pair"):
            curve = curve.sort_values("fixed_step_s")
            order = observed_order(
                curve["fixed_step_s"].to_numpy(), curve["relative_error"].to_numpy()
            )
            style = styles(str(pair)) | {"label": f"{pair}: order {order:.2f}"}
            ax.plot(curve["fixed_step_s"], curve["relative_error"], markersize=4, **style)
        log_axis(ax, "x")
        log_axis(ax, "y")
        ax.set_title(problem, fontsize="small")
        ax.set_xlabel("step h [s]")
        ax.set_ylabel("end pose error / L [-]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="xx-small", frameon=False)
    for ax in list(axes.flat)[len(problems) :]:
        ax.set_visible(False)
    figure.suptitle("Fixed-step methods: convergence order (slope of the end error against h)")
    return save_figure(
        figure,
        out,
        "overview-convergence",
        "End error against the fixed step of the fixed-step methods; the legend gives each "
        "pair's observed order (least-squares slope)",
    )
