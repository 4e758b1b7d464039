"""The report's figures, each written as PNG (shown), SVG and PDF (linked).

Per problem: a work-precision diagram (scd against wall seconds and against right-hand-side
evaluations, log x; one curve per formalism x integrator, one point per tolerance) and the
position, velocity and nonholonomic constraint drift and the energy error over time (log y)
of every pair at the middle tolerance. Matplotlib is imported inside the functions, which
run in the figure workers (:mod:`workbench.outputs.report.pool`) with the Agg backend.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.outputs.report.analysis import drift_runs, ok_runs, warned

DRIFT_QUANTITIES: tuple[tuple[str, str], ...] = (
    ("drift_pos", "position constraint drift"),
    ("drift_vel", "velocity constraint drift"),
    ("drift_nh", "nonholonomic constraint drift"),
    ("energy_err", "relative energy error"),
)
FIGURE_FORMATS: tuple[str, ...] = ("png", "svg", "pdf")


@dataclass
class FigureFiles:
    """A figure written in every format; ``png`` is shown, the others linked."""

    stem: str
    caption: str

    def link(self, fmt: str) -> str:
        """The file in format ``fmt``, relative to the page."""
        return f"figures/{self.stem}.{fmt}"

    @property
    def linked_formats(self) -> list[str]:
        """The formats linked beside the PNG shown."""
        return [fmt for fmt in FIGURE_FORMATS if fmt != "png"]


def _save(figure: Any, out: Path, stem: str, caption: str) -> FigureFiles:
    import matplotlib.pyplot as plt

    # Cropped to what is drawn (the legend's column would leave a blank margin); the box is
    # measured once, since savefig(bbox_inches="tight") would lay out every format again.
    box = figure.get_tightbbox(figure.canvas.get_renderer()).padded(0.1)
    for fmt in FIGURE_FORMATS:
        figure.savefig(
            out / "figures" / f"{stem}.{fmt}", dpi=90 if fmt == "png" else None, bbox_inches=box
        )
    plt.close(figure)
    return FigureFiles(stem, caption)


def slug(text: str) -> str:
    """``text`` as a file name and HTML id: runs of other characters become one ``-``."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "problem"


class PairStyles:
    """Colour by integrator, marker and line style by formalism.

    The legend then has one entry per integrator and one per formalism instead of one per
    pair, which keeps it readable (and cheap to draw) for dozens of pairs.
    """

    MARKERS = "osD^v<>pPX*h"
    LINES = ("-", "--", "-.", ":")

    def __init__(self, runs: pd.DataFrame) -> None:
        import matplotlib.pyplot as plt

        parts = runs[["pair", "formalism_label", "integrator_label"]].drop_duplicates("pair")
        self.formalisms = sorted(parts["formalism_label"].unique())
        self.integrators = sorted(parts["integrator_label"].unique())
        colors = plt.get_cmap("tab10" if len(self.integrators) <= 10 else "tab20").colors
        self.colors = {name: colors[k % len(colors)] for k, name in enumerate(self.integrators)}
        self.marks = {
            name: (self.MARKERS[k % len(self.MARKERS)], self.LINES[k % len(self.LINES)])
            for k, name in enumerate(self.formalisms)
        }
        self.parts = dict(
            zip(
                parts["pair"],
                zip(parts["formalism_label"], parts["integrator_label"], strict=True),
                strict=True,
            )
        )

    def __call__(self, pair: str, markers: bool = True) -> dict[str, Any]:
        formalism, integrator = self.parts[pair]
        marker, linestyle = self.marks[formalism]
        style = {"color": self.colors[integrator], "linestyle": linestyle, "label": pair}
        if markers:
            style["marker"] = marker
        return style

    def legend(self, figure: Any, markers: bool = True) -> None:
        """Integrators (colours) and formalisms (line styles) right of the axes."""
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], color=self.colors[name]) for name in self.integrators]
        handles += [
            Line2D(
                [],
                [],
                color="black",
                linestyle=self.marks[name][1],
                marker=self.marks[name][0] if markers else None,
            )
            for name in self.formalisms
        ]
        labels = [f"integrator {name}" for name in self.integrators]
        labels += [f"formalism {name}" for name in self.formalisms]
        figure.legend(
            handles,
            labels,
            loc="upper left",
            bbox_to_anchor=(0.71, 0.92),
            fontsize="small" if len(labels) <= 12 else "x-small",
            ncols=1 if len(labels) <= 30 else 2,
            frameon=False,
        )


def _log_axis(ax: Any, which: str) -> None:
    """Log scale with plain-text labels (1e-06): mathtext labels cost most of the drawing."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    getattr(ax, f"set_{which}scale")("log")
    axis = getattr(ax, f"{which}axis")
    axis.set_major_locator(LogLocator(numticks=8))
    axis.set_major_formatter(FuncFormatter(lambda value, _position: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def work_precision_figure(runs: pd.DataFrame, out: Path, problem: str) -> FigureFiles | None:
    """scd against wall seconds and against rhs evaluations (log x), one curve a pair."""
    import matplotlib.pyplot as plt

    ok = ok_runs(runs)
    ok = ok[np.isfinite(ok["scd"])]
    if ok.empty:
        return None
    pairs = sorted(ok["pair"].unique())
    styles = PairStyles(ok)
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    figure.subplots_adjust(left=0.06, right=0.70, bottom=0.12, top=0.88, wspace=0.08)
    for pair in pairs:
        curve = ok[ok["pair"] == pair].sort_values("rtol", ascending=False)
        for ax, cost in zip(axes, ("wall_s", "n_rhs"), strict=True):
            points = curve[np.isfinite(curve[cost]) & (curve[cost] > 0)]
            if not points.empty:
                ax.plot(points[cost], points["scd"], markersize=4, linewidth=1, **styles(pair))
                flagged = points[warned(points)]
                ax.scatter(flagged[cost], flagged["scd"], s=70, facecolors="none",
                           edgecolors="red", linewidths=1.2, zorder=3)  # fmt: skip
    for ax, xlabel in zip(axes, ("wall time [s]", "right-hand-side evaluations"), strict=True):
        _log_axis(ax, "x")
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("scd (correct digits at the end)")
    title = f"{problem}: work-precision (one point per tolerance)"
    if warned(ok).any():
        title += "\nred ring: the run carries warnings (it may be wrong; see the status table)"
    figure.suptitle(title, x=0.38)
    styles.legend(figure)
    return _save(
        figure,
        out,
        f"{slug(problem)}-work-precision",
        f"{problem}: work-precision diagrams (scd against wall time and rhs evaluations)",
    )


def drift_figure(
    runs: pd.DataFrame, series: Mapping[str, pd.DataFrame | None] | None, out: Path, problem: str
) -> tuple[FigureFiles | None, float | None]:
    """Drift and energy error over time for every pair at the middle tolerance (log y).

    series: run_id -> that run's time series (None or missing: not drawn).
    """
    import matplotlib.pyplot as plt

    rtol, chosen = drift_runs(runs)
    if series is None or rtol is None:
        return None, rtol
    styles = PairStyles(chosen)
    figure, axes = plt.subplots(2, 2, figsize=(12, 7.5), sharex=True)
    figure.subplots_adjust(left=0.07, right=0.70, bottom=0.08, top=0.91, wspace=0.22, hspace=0.18)
    drawn: set[str] = set()
    for row in chosen.itertuples():
        run_series = series.get(row.run_id)
        if run_series is None or len(run_series) == 0 or "t" not in run_series:
            continue
        if "run_id" in run_series:
            run_series = run_series[run_series["run_id"].astype(str) == row.run_id]
        t = run_series["t"].to_numpy(dtype=float)
        for ax, (column, _label) in zip(axes.flat, DRIFT_QUANTITIES, strict=True):
            if column not in run_series:
                continue
            values = np.abs(run_series[column].to_numpy(dtype=float))
            keep = np.isfinite(values) & (values > 0)
            if keep.any():
                ax.plot(t[keep], values[keep], linewidth=1, **styles(row.pair, markers=False))
                drawn.add(column)
    if not drawn:
        plt.close(figure)
        return None, rtol
    for ax, (column, label) in zip(axes.flat, DRIFT_QUANTITIES, strict=True):
        ax.set_title(label, fontsize="medium")
        if column in drawn:
            _log_axis(ax, "y")
        else:
            ax.text(
                0.5,
                0.5,
                "none (zero or not measured)",
                ha="center",
                va="center",
                transform=ax.transAxes,
                color="gray",
            )
            ax.set_yticks([])
        ax.grid(True, alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    figure.suptitle(f"{problem}: drift and energy error at rtol = {rtol:g}", x=0.385)
    styles.legend(figure, markers=False)
    caption = f"{problem}: constraint drift and energy error over time at rtol = {rtol:g}"
    return _save(figure, out, f"{slug(problem)}-drift", caption), rtol
