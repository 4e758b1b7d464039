"""The report's figures as a reader sees them: the Pareto band of each work-precision
panel lies on that panel's own axis, and no two tick labels overlap (their boxes measured
with the renderer that draws them)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.test_report_overview import rows
from workbench.outputs.report.figures import (
    shown_tick_labels,
    thin_tick_labels,
    work_precision_drawing,
)


@pytest.fixture(autouse=True)
def agg() -> None:
    import matplotlib

    matplotlib.use("Agg", force=True)


def two_pairs(low: float, high: float):
    """Two pairs, CPU times from ``low`` to ``high`` and rhs counts of 300 to 20,000."""
    runs = rows([
        ("p", "a / x", 4.0, low), ("p", "a / x", 6.0, high / 2), ("p", "a / x", 8.0, high),
        ("p", "b / y", 3.5, low * 1.5), ("p", "b / y", 7.0, high * 0.8),
    ])  # fmt: skip
    runs["n_rhs"] = [300.0, 2000.0, 20000.0, 900.0, 4000.0]
    return runs


def band(ax):
    """The x and y of the Pareto band of a panel: its thick translucent step line."""
    (line,) = [line for line in ax.get_lines() if line.get_linewidth() >= 5]
    return line.get_xdata(), line.get_ydata()


def test_the_pareto_band_sits_on_each_panels_own_axis() -> None:
    runs = two_pairs(3e-2, 6e-1)
    figure, _caption = work_precision_drawing(runs, "p", "wall_s")
    time_panel, rhs_panel = figure.axes[:2]
    for ax, column in ((time_panel, "wall_s"), (rhs_panel, "n_rhs")):
        x, y = band(ax)
        front = runs[[float(v) in set(map(float, y)) for v in runs["scd"]]]
        assert set(np.asarray(x, dtype=float)) <= set(front[column].astype(float)), column
        low, high = ax.get_xlim()
        assert low <= np.min(x) and np.max(x) <= high
    # the rhs axis spans the rhs counts, not the CPU seconds of the other panel
    assert rhs_panel.get_xlim()[0] > 100


def overlaps(figure) -> list[tuple[str, str]]:
    renderer = figure.canvas.get_renderer()
    found = []
    for ax in figure.axes:
        for axis in (ax.xaxis, ax.yaxis):
            labels = shown_tick_labels(axis, renderer)
            for i, (_m1, v1, box1) in enumerate(labels):
                for _m2, v2, box2 in labels[i + 1 :]:
                    if box1.overlaps(box2):
                        found.append((f"{v1:g}", f"{v2:g}"))
    return found


@pytest.mark.parametrize("span", [(3e-2, 6e-1), (3e-2, 2e-1), (1.5e-2, 9e-2), (2e-4, 3e-1)])
def test_no_two_tick_labels_overlap(span: tuple[float, float]) -> None:
    """CPU times over about a decade (the issue's '3e-024e-026e-02') and more."""
    drawn, _caption = work_precision_drawing(two_pairs(*span), "p", "wall_s")
    drawn.canvas.draw()
    before = overlaps(drawn)
    # as save_figure does: thinned before anything drew it (the ticks laid out in there)
    figure, _caption = work_precision_drawing(two_pairs(*span), "p", "wall_s")
    thin_tick_labels(figure)
    figure.canvas.draw()
    assert overlaps(figure) == [], f"overlapping tick labels (before thinning: {before})"
    time_panel = figure.axes[0]
    shown = shown_tick_labels(time_panel.xaxis, figure.canvas.get_renderer())
    assert len(shown) >= 2  # thinned, never emptied


def test_the_heat_map_shows_the_top_pairs_readably(tmp_path) -> None:
    """42 pairs made a 1,800 px heat map of 7 px labels; now at most 10 pair columns, no
    wider than the 1400 px screen, and one number format in the printed ratio table (a
    margin's: :func:`~workbench.outputs.report.tables.times_text`)."""
    import struct

    from tests.test_paper import wide_results
    from workbench.outputs.report import prepare_results
    from workbench.outputs.report.tables import times_text
    from workbench.outputs.report.writer import overview_of

    runs = prepare_results(wide_results())
    runs["scd"] += 4.0  # most pairs reach the overview's target
    (tmp_path / "figures").mkdir()
    (tmp_path / "tables").mkdir()
    overview_of(runs, tmp_path)
    png = (tmp_path / "figures" / "overview-heat-map.png").read_bytes()
    width, _height = struct.unpack(">II", png[16:24])
    assert width <= 1400
    latex = (tmp_path / "tables" / "cost-at-target.tex").read_text(encoding="utf-8")
    headers = [line for line in latex.splitlines() if line.startswith("problem &")]
    assert 5 <= sum(header.count(" & ") for header in headers) <= 10  # over the table's parts
    rows = [line for line in latex.splitlines() if line.startswith(("simple", "four", "heavy"))]
    numbers = [cell.strip(" \\") for row in rows for cell in row.split(" & ")[1:]]
    ratios = [n for n in numbers if n[:1].isdigit()]  # not 'not reached'
    # one format, the margins': 3 significant digits and 'x', '1x' the best's own
    full = pd.read_csv(tmp_path / "tables" / "cost-at-target.csv", index_col="problem")
    assert set(ratios) <= {times_text(v) for v in full.to_numpy().ravel()}, numbers
    assert "1x" in ratios and "1.000x" not in ratios
    assert len(full.columns) == 42  # the CSV keeps every pair


def test_under_rhs_evaluations_the_time_panel_is_the_default_time_measure() -> None:
    """`--cost n_rhs` drew integration wall time beside CPU time everywhere else, and the
    caption did not say which time it was or why."""
    runs = two_pairs(3e-2, 6e-1)
    runs["integrate_cpu_s"] = runs["wall_s"]
    runs["integrate_s"] = 10 * runs["wall_s"]  # wall time: a decade off CPU time
    figure, caption = work_precision_drawing(runs, "p", "n_rhs")
    x, _y = band(figure.axes[0])
    assert set(np.asarray(x, dtype=float)) <= set(runs["integrate_cpu_s"].astype(float))
    assert "time panel shows integration CPU time, the default measure" in caption
    assert "integration CPU time" in figure.axes[0].get_xlabel()
    _figure, caption = work_precision_drawing(runs, "p", "integrate_cpu_s")
    assert "time panel" not in caption


def test_a_quantity_not_measured_says_why_for_its_own_kind() -> None:
    """The flyball governor's drift caption read 'energy error / energy in motion: not
    measured (no such constraint, or not conservative)': an energy has no constraint."""
    from workbench.outputs.report.figures import measured_quantities

    chosen = pd.DataFrame({"run_id": ["a"]})
    series = {"a": pd.DataFrame({"t": [0.0, 1.0], "drift_pos": [0.0, 1e-9],
                                 "drift_vel": [0.0, 1e-8], "drift_nh": [np.nan] * 2,
                                 "energy_err": [np.nan] * 2})}  # fmt: skip
    drawn, absent = measured_quantities(chosen, series)
    assert [column for column, _ in drawn] == ["drift_pos", "drift_vel"]
    assert absent["drift_nh"].endswith("not measured (no such constraint)")
    assert absent["energy_err"].endswith("not measured (not conservative)")
