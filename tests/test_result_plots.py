"""``Result.plot_error``, ``plot_energy`` and ``plot_drift`` on a log axis show the values
measured, nothing else: an error that is 0 at t = 0 was clamped to 1e-300 and squashed the
curve to a flat line at the top; an unconstrained run's drift was drawn as a line at
1e-300; and the x label fell off the bottom of the figure."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

import workbench as wb

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)


@pytest.fixture(scope="module")
def free() -> wb.Result:
    """A tree without constraints; its error and energy error start at exactly 0."""
    result = wb.run("double-pendulum", "recursive", "scipy-dop853", rtol=1e-6)
    assert result.row["status"] == "ok", result.row["message"]
    return result


@pytest.fixture(scope="module")
def closed() -> wb.Result:
    """A closed loop in absolute coordinates at index 1: it has constraints that drift."""
    result = wb.run("slider-crank", "absolute-dae", "sundials-ida", rtol=1e-6, index=1)
    assert result.row["status"] == "ok", result.row["message"]
    return result


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _positive(values) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values) & (values > 0)]


@pytest.mark.parametrize(
    ("plot", "column"), [("plot_error", "ref_err"), ("plot_energy", "energy_err")]
)
def test_a_log_plot_spans_the_measured_values(free, plot, column) -> None:
    values = free.series[column].to_numpy(dtype=float)
    if column == "energy_err":  # |E(0) - E(0)| / scale: 0 on every machine, the case that
        assert values[0] == 0  # broke the axis (the reference error's first sample too, here)
    measured = _positive(values)
    low, high = measured.min(), measured.max()
    ax = getattr(free, plot)()
    (line,) = ax.get_lines()
    drawn = np.asarray(line.get_ydata(), dtype=float)
    # the positive values and only they are drawn, at their times; 0 is left out
    np.testing.assert_array_equal(_positive(drawn), measured)
    assert np.isnan(drawn[values <= 0]).all()
    assert drawn[np.isfinite(drawn)].min() >= low
    bottom, top = ax.get_ylim()
    assert low / 10 <= bottom <= low and high <= top <= high * 10


def test_drift_of_a_run_without_constraints_draws_nothing_and_says_why(free) -> None:
    drift = free.drift
    assert not _positive(drift[["drift_pos", "drift_vel", "drift_nh"]].to_numpy().ravel()).size
    assert (drift["drift_pos"] == 0).all() and drift["drift_nh"].isna().all()
    ax = free.plot_drift()
    assert not ax.get_lines()
    (text,) = ax.texts
    note = text.get_text()
    assert "drift_pos: exactly 0" in note and "drift_nh: not measured (NaN)" in note
    assert ax.get_xlim() == (drift["t"].min(), drift["t"].max())


def test_drift_of_a_constrained_run_is_drawn(closed) -> None:
    drift = closed.drift
    ax = closed.plot_drift()
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert set(lines) == {"drift_pos", "drift_vel"}  # drift_nh: this mechanism has none
    for name, line in lines.items():
        measured = _positive(drift[name])
        assert measured.size > len(drift) // 2  # a measured residual, not an exact zero
        np.testing.assert_array_equal(_positive(line.get_ydata()), measured)
    legend = [entry.get_text() for entry in ax.get_legend().get_texts()]
    assert legend == ["drift_pos", "drift_vel", "drift_nh: not measured (NaN)"]
    assert not ax.texts


@pytest.mark.parametrize("plot", ["plot", "plot_drift", "plot_energy", "plot_error"])
def test_labels_and_title_fit_in_the_figure(free, plot) -> None:
    ax = getattr(free, plot)()
    figure = ax.figure
    figure.canvas.draw()
    box = figure.bbox
    for label in (ax.xaxis.label, ax.yaxis.label, ax.title):
        if not label.get_text():  # plot() has no y label
            continue
        extent = label.get_window_extent()
        assert extent.y0 >= box.y0 and extent.y1 <= box.y1, label.get_text()
        assert extent.x0 >= box.x0 and extent.x1 <= box.x1, label.get_text()


def test_two_plots_side_by_side_keep_their_titles_apart(free) -> None:
    """A notebook's ``fig, (a, b) = plt.subplots(1, 2)``: the titles name the run and do
    not run into each other (on one line, each was 515 px wide over a 225 px panel)."""
    figure, (left, right) = plt.subplots(1, 2)
    free.plot(ax=left)
    free.plot_energy(ax=right)
    figure.canvas.draw()
    first, second = left.title.get_window_extent(), right.title.get_window_extent()
    assert first.x1 < second.x0
    for part in ("double-pendulum", "recursive / scipy-dop853", "rtol 1e-06"):
        assert part in left.title.get_text() and part in right.title.get_text()
    assert left.get_ylabel() == "coordinates (SI units)"  # it had none
    assert free.plot(["joint1.v"]).get_ylabel() == "velocities (SI units)"
