"""The report's figures, each written as PNG (shown) and SVG (linked), and as PDF when the
report makes a paper (:func:`figure_formats`).

Per problem: a work-precision diagram (scd against the cost measure and against right-hand-side
evaluations, log x; one curve per formalism x integrator, one point per tolerance) and the
position, velocity and nonholonomic constraint drift and the energy error over time (log y)
of every pair at the middle tolerance. Matplotlib is imported inside the functions, which
run in the figure workers (:mod:`workbench.outputs.report.pool`) with the Agg backend.
"""

from __future__ import annotations

import contextlib
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.outputs.report.analysis import drift_left_out, drift_runs, ok_runs, warned

DRIFT_QUANTITIES: tuple[tuple[str, str], ...] = (
    ("drift_pos", "position constraint drift [m or rad]"),
    ("drift_vel", "velocity constraint drift [m/s or rad/s]"),
    ("drift_nh", "nonholonomic constraint drift [m/s or rad/s]"),
    ("energy_err", "energy error / energy in motion [-]"),
)
"""Series column and axis label (with units: residual components are lengths or angles,
their rates, or a ratio) of the quantities of the drift figure."""
FIGURE_FORMATS: tuple[str, ...] = ("png", "svg", "pdf")
"""Every format a figure can be written in: PNG shown on the page, SVG linked beside it,
PDF for a paper (:mod:`workbench.outputs.report.paper`)."""
REPORT_FORMATS: tuple[str, ...] = ("png", "svg")
"""The formats a report writes unless it makes a paper: the PDFs were 4.5-11 s of the
quick suite's 37-40 s report on a Zen 3 (25 figures; PNG and SVG 29 s, all three 33-40;
docs/performance.md)."""
_FORMATS: ContextVar[tuple[str, ...]] = ContextVar("figure_formats", default=REPORT_FORMATS)


@contextlib.contextmanager
def figure_formats(formats: tuple[str, ...]) -> Iterator[None]:
    """The figures saved meanwhile (in this thread or task) are written in ``formats``
    (PNG first: it is the one shown)."""
    token = _FORMATS.set(tuple(formats))
    try:
        yield
    finally:
        _FORMATS.reset(token)


@dataclass
class Axis:
    """One axis of a figure that shows tick labels: its label, and whether its ticks are
    numbers (a numeric axis must carry a unit) or names (problems, pairs)."""

    label: str
    numeric: bool


@dataclass
class FigureFiles:
    """A figure written in ``formats``; ``png`` is shown, the others linked.

    axes: every axis that shows tick labels (colour bars included), read from the figure
    when it was saved; the page states them, so a reader (and a test) can see that every
    axis says what it shows and in which unit.
    """

    stem: str
    caption: str
    axes: list[Axis] = field(default_factory=list)
    formats: tuple[str, ...] = REPORT_FORMATS

    def link(self, fmt: str) -> str:
        """The file in format ``fmt``, relative to the page."""
        return f"figures/{self.stem}.{fmt}"

    @property
    def linked_formats(self) -> list[str]:
        """The formats linked beside the PNG shown."""
        return [fmt for fmt in self.formats if fmt != "png"]


def save_figure(figure: Any, out: Path, stem: str, caption: str) -> FigureFiles:
    import matplotlib.pyplot as plt

    thin_tick_labels(figure)
    # Cropped to what is drawn (the legend's column would leave a blank margin); the box is
    # measured once, since savefig(bbox_inches="tight") would lay out every format again.
    box = figure.get_tightbbox(figure.canvas.get_renderer()).padded(0.1)
    formats = _FORMATS.get()
    for fmt in formats:
        figure.savefig(
            out / "figures" / f"{stem}.{fmt}", dpi=90 if fmt == "png" else None, bbox_inches=box
        )
    axes = labelled_axes(figure)
    plt.close(figure)
    return FigureFiles(stem, caption, axes, formats)


def shown_tick_labels(axis: Any, renderer: Any) -> list[tuple[bool, float, Any]]:
    """(minor, value, window box) of the labels ``axis`` draws inside its view."""
    low, high = sorted(axis.get_view_interval())
    shown = []
    for minor, ticks in ((False, axis.get_major_ticks()), (True, axis.get_minor_ticks())):
        for tick in ticks:
            label, value = tick.label1, tick.get_loc()
            if label.get_visible() and label.get_text() and low <= value <= high:
                shown.append((minor, value, label.get_window_extent(renderer)))
    return shown


def thin_tick_labels(figure: Any, gap: float = 2.0) -> None:
    """Blank the tick labels that would overlap another (boxes measured with the
    renderer, ``gap`` pixels apart at least): major labels are kept first, in order of
    value, then the minor ones that still fit; names are never blanked. Done by wrapping
    each axis's formatter, so every format saved afterwards draws the same labels. Only
    the ticks are laid out, axes by axes, as a draw would place them: the same files as
    after a whole draw without rendering, and 27 % less time (the quick suite's report)."""
    renderer = figure.canvas.get_renderer()
    for ax in figure.axes:
        locator = ax.get_axes_locator()  # where a draw puts the axes (aspect, colorbar)
        ax.apply_aspect(locator(ax, renderer) if locator else None)
        for axis in (ax.xaxis, ax.yaxis):
            axis.get_tightbbox(renderer)  # places its ticks and their labels
            shown = shown_tick_labels(axis, renderer)
            texts = [label.get_text() for label in axis.get_ticklabels(minor=False)]
            if not all(_is_number(text) for text in texts if text):
                continue  # names (problems, pairs) are never thinned
            kept: list[Any] = []
            blank: dict[bool, list[float]] = {False: [], True: []}
            for minor, value, box in sorted(shown, key=_by_rank):
                if any(box.overlaps(other) for other in kept):
                    blank[minor].append(value)
                else:
                    kept.append(box.expanded(1.0, 1.0).padded(gap / 2))
            if blank[False]:
                axis.set_major_formatter(blanked(axis.get_major_formatter(), blank[False]))
            if blank[True]:
                axis.set_minor_formatter(blanked(axis.get_minor_formatter(), blank[True]))


def _by_rank(label: tuple[bool, float, Any]) -> tuple[bool, float]:
    return label[0], label[1]


def blanked(inner: Any, values: list[float]) -> Any:
    """A matplotlib ``Formatter`` that writes nothing at ``values`` and defers to
    ``inner`` elsewhere (its locations, axis and offset included)."""
    from matplotlib.ticker import Formatter

    class Blanked(Formatter):
        def __call__(self, x: float, pos: Any = None) -> str:
            if np.any(np.isclose(values, x, rtol=1e-9, atol=0.0)):
                return ""
            return inner(x, pos)

        def set_axis(self, axis: Any) -> None:
            super().set_axis(axis)
            inner.set_axis(axis)

        def set_locs(self, locs: Any) -> None:
            super().set_locs(locs)
            inner.set_locs(locs)

        def get_offset(self) -> str:
            return inner.get_offset()

    return Blanked()


def labelled_axes(figure: Any) -> list[Axis]:
    """The axes of a drawn ``figure`` that show tick labels (shared axes whose labels are
    hidden are left out), each with its label and whether its ticks are numbers."""
    found = []
    for ax in figure.axes:
        if not (ax.get_visible() and ax.axison):
            continue
        for axis in (ax.xaxis, ax.yaxis):
            shown = [t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            shown += [
                t for t in axis.get_ticklabels(minor=True) if t.get_visible() and t.get_text()
            ]
            if shown:
                numeric = all(_is_number(t.get_text()) for t in shown)
                found.append(Axis(axis.get_label_text(), numeric))
    return found


def _is_number(text: str) -> bool:
    try:
        float(text.replace("\N{MINUS SIGN}", "-"))
    except ValueError:
        return False
    return True


def slug(text: str) -> str:
    """``text`` as a file name and HTML id: runs of other characters become one ``-``."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "problem"


class PairStyles:
    """Colour by integrator, marker and line style by formalism.

    The legend then has one entry per integrator and one per formalism instead of one per
    pair, which keeps it readable (and cheap to draw) for dozens of pairs.
    """

    MARKERS = "osD^v<>pPX*h"
    LINES: tuple[Any, ...] = (
        "-",
        "--",
        "-.",
        ":",
        (0, (6, 1.5, 1, 1.5, 1, 1.5)),
        (0, (8, 3)),
        (0, (1, 3)),
        (0, (3, 1, 3, 1, 1, 1)),
    )

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

    def legend(
        self,
        figure: Any,
        markers: bool = True,
        left: float = 0.71,
        drawn: Iterable[str] | None = None,
    ) -> None:
        """Integrators (colours) and formalisms (line styles) right of the axes, from
        ``left`` (a fraction of the figure's width); ``drawn``: the pairs with a curve,
        whose integrators and formalisms alone are listed (None: every pair's)."""
        from matplotlib.lines import Line2D

        parts = [self.parts[pair] for pair in (self.parts if drawn is None else drawn)]
        integrators = [name for name in self.integrators if any(i == name for _, i in parts)]
        formalisms = [name for name in self.formalisms if any(f == name for f, _ in parts)]
        handles = [Line2D([], [], color=self.colors[name]) for name in integrators]
        handles += [
            Line2D(
                [],
                [],
                color="black",
                linestyle=self.marks[name][1],
                marker=self.marks[name][0] if markers else None,
            )
            for name in formalisms
        ]
        labels = [f"integrator {name}" for name in integrators]
        labels += [f"formalism {name}" for name in formalisms]
        figure.legend(
            handles,
            labels,
            loc="upper left",
            bbox_to_anchor=(left, 0.92),
            fontsize="small" if len(labels) <= 12 else "x-small",
            ncols=1 if len(labels) <= 30 else 2,
            frameon=False,
        )


def log_axis(ax: Any, which: str) -> None:
    """Log scale with plain-text labels (1e-06; mathtext labels cost most of the drawing).

    When the data span less than a decade or two, the minor ticks (2, 3, ... times a power
    of ten) are labelled too, so an axis never shows no number at all.
    """
    from matplotlib.ticker import LogFormatter, LogLocator

    getattr(ax, f"set_{which}scale")("log")
    axis = getattr(ax, f"{which}axis")
    axis.set_major_locator(LogLocator(numticks=8))
    axis.set_major_formatter(LogFormatter(labelOnlyBase=False))
    axis.set_minor_formatter(LogFormatter(labelOnlyBase=False, minor_thresholds=(1.2, 0.6)))


def reference_digits(runs: pd.DataFrame) -> float | None:
    """The scd the problem's reference can confirm, -log10 of its stated relative accuracy
    (None when no row states one)."""
    if "reference_accuracy" not in runs:
        return None
    accuracy = pd.to_numeric(runs["reference_accuracy"], errors="coerce")
    accuracy = accuracy[np.isfinite(accuracy) & (accuracy > 0)]
    return float(-np.log10(accuracy.max())) if not accuracy.empty else None


RHS_AXIS = ("n_rhs", "right-hand-side evaluations [-]")
SCD_LABEL = "scd: correct digits at the end [-]"


def work_precision_figure(
    runs: pd.DataFrame, out: Path, problem: str, cost: str = "integrate_s"
) -> FigureFiles | None:
    """The work-precision diagram of :func:`work_precision_drawing`, saved into ``out``."""
    drawn = work_precision_drawing(runs, problem, cost)
    if drawn is None:
        return None
    figure, caption = drawn
    return save_figure(figure, out, f"{slug(problem)}-work-precision", caption)


def work_precision_drawing(
    runs: pd.DataFrame, problem: str, cost: str = "integrate_s"
) -> tuple[Any, str] | None:
    """The figure and caption of a problem's work-precision diagram (None: no ok run
    with an scd): scd against the ``cost`` column (the report's cost measure,
    :mod:`workbench.outputs.report.cost`; the default time measure when that is rhs
    evaluations, which have the other panel) and against rhs evaluations (log x), one curve a pair.

    The runs on each panel's Pareto front (:func:`~workbench.outputs.report.overview.
    pareto_mask`) are joined by a thick grey line; a dotted line marks the digits the
    reference can confirm; a red ring marks a run with warnings.
    """
    import matplotlib.pyplot as plt

    from workbench.outputs.report.cost import COST_LABELS, resolve_cost
    from workbench.outputs.report.overview import pareto_mask

    # under rhs evaluations the left panel is the time the other measures default to
    # (integration CPU time; wall time for rows without it), said in the caption
    time_axis = cost if cost != RHS_AXIS[0] else resolve_cost(runs).column
    work_axes = ((time_axis, COST_LABELS.get(time_axis, time_axis)), RHS_AXIS)
    ok = ok_runs(runs)
    ok = ok[np.isfinite(ok["scd"])]
    if ok.empty:
        return None
    pairs = sorted(ok["pair"].unique())
    styles = PairStyles(ok)
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    figure.subplots_adjust(left=0.06, right=0.70, bottom=0.12, top=0.86, wspace=0.08)
    for pair in pairs:
        curve = ok[ok["pair"] == pair].sort_values("rtol", ascending=False)
        for ax, (axis, _label) in zip(axes, work_axes, strict=True):
            if axis not in curve:
                continue
            points = curve[np.isfinite(curve[axis]) & (curve[axis] > 0)]
            if not points.empty:
                ax.plot(points[axis], points["scd"], markersize=4, linewidth=1, **styles(pair))
                flagged = points[warned(points)]
                ax.scatter(flagged[axis], flagged["scd"], s=70, facecolors="none",
                           edgecolors="red", linewidths=1.2, zorder=3)  # fmt: skip
    digits = reference_digits(runs)
    for ax, (axis, xlabel) in zip(axes, work_axes, strict=True):
        front = ok[pareto_mask(ok, axis)].sort_values(axis) if axis in ok else ok.iloc[:0]
        if not front.empty:
            ax.step(front[axis], front["scd"], where="post", color="0.45", linewidth=5,
                    alpha=0.35, zorder=0, solid_capstyle="round")  # fmt: skip
        if digits is not None:
            ax.axhline(digits, color="0.2", linestyle=":", linewidth=1)
            ax.annotate("reference accuracy", (0.01, digits), xycoords=("axes fraction", "data"),
                        va="bottom", fontsize="x-small", color="0.2")  # fmt: skip
        log_axis(ax, "x")
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel(SCD_LABEL)
    measure = COST_LABELS.get(cost, cost).split(" [")[0]
    title = (
        f"{problem}: work-precision (one point per tolerance; grey band: Pareto front; "
        f"cost measure: {measure})"
    )
    if warned(ok).any():
        title += "\nred ring: the run carries warnings (it may be wrong; see the status table)"
    figure.suptitle(title, x=0.38)
    styles.legend(figure)
    return (
        figure,
        f"{problem}: work-precision diagrams (scd against {work_axes[0][1].split(' [')[0]} "
        "and rhs evaluations, one-off costs such as building and compiling excluded; grey "
        "band: the Pareto front, runs no other run beats on both cost and accuracy; the "
        f"report's cost measure: {measure}"
        + (f"; the time panel shows {work_axes[0][1].split(' [')[0]}, the default measure"
           if cost == RHS_AXIS[0] else "") + ")",
    )  # fmt: skip


def _run_series(series: Mapping[str, pd.DataFrame | None], run_id: str) -> pd.DataFrame | None:
    run_series = series.get(run_id)
    if run_series is None or len(run_series) == 0 or "t" not in run_series:
        return None
    if "run_id" in run_series:
        run_series = run_series[run_series["run_id"].astype(str) == run_id]
    return run_series


def measured_quantities(
    chosen: pd.DataFrame, series: Mapping[str, pd.DataFrame | None]
) -> tuple[list[tuple[str, str]], dict[str, str]]:
    """The drift quantities with a nonzero value somewhere, and why each other one is not
    drawn: "not measured" (NaN throughout: for a drift no such constraint, for the
    energy error not conservative) is a different thing from "exactly zero" (measured,
    and zero at every sample)."""
    drawn, absent = [], {}
    for column, label in DRIFT_QUANTITIES:
        values = [
            np.abs(s[column].to_numpy(dtype=float))
            for run_id in chosen["run_id"]
            if (s := _run_series(series, run_id)) is not None and column in s
        ]
        finite = np.concatenate([v[np.isfinite(v)] for v in values]) if values else np.array([])
        name = label.split(" [")[0]
        if finite.size == 0:
            why = "not conservative" if column == "energy_err" else "no such constraint"
            absent[column] = f"{name}: not measured ({why})"
        elif not np.any(finite > 0):
            absent[column] = f"{name}: exactly zero at every sample"
        else:
            drawn.append((column, label))
    return drawn, absent


def drift_label(label: str, units: Iterable[str] = ()) -> str:
    """A :data:`DRIFT_QUANTITIES` axis label in the unit of this model's position
    residuals (``units``: traits.drift_units), where they have one: a model whose joints
    only keep points together drifts in m (and m/s), not "m or rad"."""
    units = set(units)
    if units == {"m"}:
        return label.replace("[m or rad]", "[m]").replace("[m/s or rad/s]", "[m/s]")
    if units == {"rad"}:
        return label.replace("[m or rad]", "[rad]").replace("[m/s or rad/s]", "[rad/s]")
    return label


def drift_figure(
    runs: pd.DataFrame,
    series: Mapping[str, pd.DataFrame | None] | None,
    out: Path,
    problem: str,
    units: Iterable[str] = (),
) -> tuple[FigureFiles | None, float | None]:
    """Drift and energy error over time at the middle tolerance (log y), as small multiples:
    one row a measured quantity, one column a formalism, one curve an integrator (so no
    panel overlays more curves than there are integrators). Quantities not drawn are
    named in the caption, "not measured" apart from "exactly zero".

    series: run_id -> that run's time series (None or missing: not drawn);
    units: of the model's position residuals (:func:`drift_label`; none: "m or rad").
    """
    import matplotlib.pyplot as plt

    rtol, chosen = drift_runs(runs)
    if series is None or rtol is None:
        return None, rtol
    drawn, absent = measured_quantities(chosen, series)
    if not drawn:
        return None, rtol
    styles = PairStyles(chosen)
    formalisms = styles.formalisms
    columns = len(formalisms)
    figure, axes = plt.subplots(
        len(drawn),
        columns,
        figsize=(min(3.2 * columns, 16) + 2.5, 2.3 * len(drawn) + 0.9),
        sharex=True,
        sharey="row",
        squeeze=False,
    )
    legend_room = 2.5 / (min(3.2 * columns, 16) + 2.5)
    figure.subplots_adjust(left=0.07, right=0.98 - legend_room, bottom=0.1, top=0.86,
                           wspace=0.08, hspace=0.25)  # fmt: skip
    zero, seen = set(), set()  # panels (row, column) of a run all 0; of a run with data
    curves: dict[str, str] = {}  # pair -> '' (a curve drawn) or why it has none
    for row in chosen.itertuples():
        run_series = _run_series(series, row.run_id)
        curves.setdefault(row.pair, "no stored time series" if run_series is None else
                          "no value above zero")  # fmt: skip
        if run_series is None:
            continue
        formalism, _integrator = styles.parts[row.pair]
        t = run_series["t"].to_numpy(dtype=float)
        for k, (column, _label) in enumerate(drawn):
            if column not in run_series:
                continue
            seen.add((k, formalisms.index(formalism)))
            values = np.abs(run_series[column].to_numpy(dtype=float))
            keep = np.isfinite(values) & (values > 0)
            if keep.any():
                ax = axes[k, formalisms.index(formalism)]
                ax.plot(t[keep], values[keep], linewidth=1, **styles(row.pair, markers=False))
                curves[row.pair] = ""
            elif np.isfinite(values).any():
                zero.add((k, formalisms.index(formalism)))
    empty = []  # an empty panel says why, and so does the caption
    for k, (column, label) in enumerate(drawn):
        for j, formalism in enumerate(formalisms):
            ax = axes[k, j]
            if ax.lines:
                log_axis(ax, "y")
            else:
                why = "exactly zero at every sample" if (k, j) in zero else "not measured"
                why = why if (k, j) in seen else "without a stored time series"
                ax.text(0.5, 0.5, why.replace(" at", "\nat"), transform=ax.transAxes,
                        ha="center", va="center", fontsize="small", color="0.3")  # fmt: skip
                empty.append(f"{formalism}'s {label.split(' [')[0]} {why}")
            if k == 0:
                ax.set_title(formalism, fontsize="small")
            if j == 0 and column in ("drift_pos", "drift_vel"):
                label = drift_label(label, units)
            if j == 0:
                ax.set_ylabel(label.replace(" [", "\n["), fontsize="small")
            if k == len(drawn) - 1:
                ax.set_xlabel("time [s]")
            ax.grid(True, alpha=0.3)
    figure.suptitle(
        f"{problem}: drift and energy error at rtol = {rtol:g} (columns: formalisms)",
        x=0.5 - legend_room / 2,
    )
    # the legend lists what is drawn; the caption says which pairs are not, and why
    styles.legend(figure, markers=False, left=1.0 - legend_room,
                  drawn=[pair for pair, why in curves.items() if not why])  # fmt: skip
    caption = f"{problem}: constraint drift and energy error over time at rtol = {rtol:g}"
    if absent:
        caption += "; not drawn: " + "; ".join(absent.values())
    if empty:
        caption += "; empty panels: " + "; ".join(empty)
    no_curve = [f"{pair} ({why})" for pair, why in sorted(curves.items()) if why]
    if no_curve:
        caption += "; no curve: " + ", ".join(no_curve)
    left_out = drift_left_out(runs, rtol)
    if left_out:
        caption += f"; not in it, no ok run there: {', '.join(left_out)}"
    return save_figure(figure, out, f"{slug(problem)}-drift", caption), rtol


def error_figure(
    runs: pd.DataFrame,
    series: Mapping[str, pd.DataFrame | None] | None,
    out: Path,
    problem: str,
    cost: str = "integrate_s",
) -> FigureFiles | None:
    """The sanity check of a problem's trajectory: the pose error against the reference at
    every sample, for the most accurate trusted run and the run of the Pareto front's
    cheapest end (an error that grows or jumps shows a wrong branch or a bad reference)."""
    import matplotlib.pyplot as plt

    from workbench.outputs.report.overview import pareto_mask, trusted

    if series is None:
        return None
    candidates = trusted(runs, cost)
    if candidates.empty:
        return None
    front = candidates[pareto_mask(candidates, cost)].sort_values(cost)
    picks = [candidates.loc[candidates["scd"].idxmax()], front.iloc[0]]
    length = float(picks[0].get("length_scale", math.nan))
    relative = math.isfinite(length) and length > 0  # else the error in metres
    figure, ax = plt.subplots(figsize=(8, 3.4))
    figure.subplots_adjust(left=0.1, right=0.97, bottom=0.16, top=0.86)
    seen = set()
    for pick, what in zip(picks, ("most accurate", "cheapest on the Pareto front"), strict=True):
        if pick["run_id"] in seen:
            continue
        seen.add(pick["run_id"])
        run_series = _run_series(series, str(pick["run_id"]))
        if run_series is None or "ref_err" not in run_series:
            continue
        t = run_series["t"].to_numpy(dtype=float)
        error = run_series["ref_err"].to_numpy(dtype=float) / (length if relative else 1.0)
        keep = np.isfinite(error) & (error > 0)
        if keep.any():
            ax.plot(t[keep], error[keep], linewidth=1,
                    label=f"{what}: {pick['pair']} @ rtol {pick['rtol']:g}")  # fmt: skip
    if not ax.lines:
        plt.close(figure)
        return None
    log_axis(ax, "y")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("pose error / L [-]" if relative else "pose error [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small", loc="best", frameon=False)
    figure.suptitle(f"{problem}: error along the trajectory", fontsize="medium")
    return save_figure(
        figure,
        out,
        f"{slug(problem)}-error",
        f"{problem}: pose error against the reference along the trajectory (relative to the "
        "length scale L)",
    )
