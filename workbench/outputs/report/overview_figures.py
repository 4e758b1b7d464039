"""The figures of the report's overview, across problems: the problem x pair heat map of
cost at a fixed accuracy, and the convergence order of the fixed-step methods.

Drawn in the parent process (one figure each), with the Agg backend.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.outputs.report.figures import FigureFiles, PairStyles, log_axis, save_figure
from workbench.outputs.report.overview import (
    COST_COLUMNS,
    NOT_REACHED,
    NOT_RUN,
    SKIPPED,
    UNREACHED_MEANING,
    trusted,
)
from workbench.outputs.report.tables import times_text


def heat_map_figure(
    ratio: pd.DataFrame,
    target: float,
    cost: str,
    out: Path,
    pairs: int | None = None,
    reasons: pd.DataFrame | None = None,
) -> FigureFiles | None:
    """The heat map of :func:`heat_map_drawing`, saved into ``out`` (None: nothing reached
    the target)."""
    drawn = heat_map_drawing(ratio, target, cost, pairs, reasons)
    if drawn is None:
        return None
    figure, caption = drawn
    return save_figure(figure, out, "overview-heat-map", caption)


def heat_map_drawing(
    ratio: pd.DataFrame,
    target: float,
    cost: str,
    pairs: int | None = None,
    reasons: pd.DataFrame | None = None,
) -> tuple[Any, str] | None:
    """The figure and caption of the problem x pair heat map of ``ratio`` (cost / the
    problem's best at scd >= target; :func:`~workbench.outputs.report.overview.cost_ratio`;
    give it the top pairs, and the number of pairs in all as ``pairs``), the ratio written
    in each cell (None: no cell has one). An empty cell says why, from ``reasons``
    (:func:`~workbench.outputs.report.overview.unreached_reasons`, default: all "not
    reached"): a hatched grey "not reached" where the pair ran but never reached the
    target without warnings, a white "skipped (not supported)" (dotted border) where every
    run of the pair was skipped, as it does not support the problem, a white "not run"
    where it has no run there; the title and the caption say which is which. Sized to be
    read at its natural width (about 1100 px): 9-10 pt labels at 90 dpi."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import LogFormatter

    if ratio.empty or not np.isfinite(ratio.to_numpy(dtype=float)).any():
        return None
    values = ratio.to_numpy(dtype=float)
    rows, columns = values.shape
    width = max(8.0, 3.0 + 0.95 * columns)
    figure, ax = plt.subplots(figsize=(width, 2.4 + 0.42 * rows))
    top = float(np.nanmax(values))
    image = ax.imshow(
        np.ma.masked_invalid(values),
        cmap="viridis_r",
        norm=LogNorm(vmin=1.0, vmax=max(top, 10.0)),
        aspect="auto",
    )
    shown_reasons: list[str] = []
    for i in range(rows):
        for j in range(columns):
            value = values[i, j]
            if not np.isfinite(value):
                reason = NOT_REACHED if reasons is None else str(reasons.iat[i, j] or NOT_REACHED)
                shown_reasons.append(reason)
                _empty_cell(ax, Rectangle, i, j, reason)
                continue
            color = "white" if value > 3 else "black"
            ax.text(j, i, times_text(value), ha="center", va="center", fontsize=9, color=color)
    labels = [str(c).replace(" / ", "\n/ ") for c in ratio.columns]
    ax.set_xticks(range(columns), labels, rotation=30, ha="right", rotation_mode="anchor",
                  fontsize=9)  # fmt: skip
    ax.set_yticks(range(rows), [str(r) for r in ratio.index], fontsize=9)
    ax.set_xlabel("pair (formalism / integrator)")
    ax.set_ylabel("problem")
    measure = COST_COLUMNS.get(cost, cost)
    name, _, unit = measure.partition(" [")
    bar = figure.colorbar(image, ax=ax, fraction=0.03, pad=0.01)
    bar.set_label(f"{name} / the best on the problem [-]", fontsize=9)
    plain = LogFormatter(labelOnlyBase=False, minor_thresholds=(1.2, 0.6))
    bar.ax.yaxis.set_major_formatter(plain)
    bar.ax.yaxis.set_minor_formatter(plain)
    bar.ax.tick_params(labelsize=8)
    shown = "" if pairs is None or pairs <= columns else f"the {columns} best of {pairs} pairs; "
    present = [reason for reason in EMPTY_CELLS if reason in shown_reasons]
    legend = "; ".join(EMPTY_CELLS[reason][0] for reason in present)
    ax.set_title(f"cost at scd >= {target:g} relative to the best pair of each problem\n"
                 f"({shown}1 = best" + (f"; {legend}" if legend else "") + ")",
                 fontsize=10)  # fmt: skip
    meanings = [f"{EMPTY_CELLS[reason][1]} {UNREACHED_MEANING[reason]}" for reason in present]
    return (
        figure,
        f"Cost ({name}) of each pair at scd >= {target:g}, divided by the least cost of any "
        "pair on that problem"
        + (
            f"; {columns} of the {pairs} pairs: those reaching the target, in the order of "
            "the ranking (most problems within reach of the best first)"
            if shown
            else ""
        )
        + "".join(f"; {meaning}" for meaning in meanings),  # fmt: skip
    )


# how an empty cell is told in the title and the caption, and drawn: (title, the look
# the caption names, text in the cell, face colour, hatch, border style)
EMPTY_CELLS: dict[str, tuple[str, str, str, str, str | None, str]] = {
    NOT_REACHED: ("hatched: not reached without warnings", "hatched grey:", "not\nreached",
                  "0.88", "///", "solid"),
    SKIPPED: ("white 'skipped': not supported", "white, 'skipped':", "skipped\n(not\nsupported)",
              "white", None, "dotted"),
    NOT_RUN: ("white 'not run': no run", "white, 'not run':", "not\nrun", "white", None,
              "dotted"),
}  # fmt: skip


def _empty_cell(ax, rectangle, i: int, j: int, reason: str) -> None:
    """Draw the cell (row ``i``, column ``j``) of a pair without a value at the target,
    in the look of its ``reason`` (:data:`EMPTY_CELLS`), the reason written in it."""
    _title, _look, text, face, hatch, border = EMPTY_CELLS.get(reason, EMPTY_CELLS[NOT_REACHED])
    ax.add_patch(rectangle((j - 0.5, i - 0.5), 1, 1, facecolor=face, edgecolor="0.55",
                           hatch=hatch, linewidth=0 if hatch else 1, linestyle=border))  # fmt: skip
    ax.text(j, i, text, ha="center", va="center", fontsize=8,
            color="0.15" if hatch else "0.35", style="normal" if hatch else "italic",
            linespacing=0.9, bbox={"facecolor": face, "edgecolor": "none", "pad": 0.5})  # fmt: skip


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
