"""What the report's captions say matches what their tables and figures show: a status
table without notes points to none, a drift table's caption names only the quantities it
has columns of, and an empty drift panel says why it is empty (exactly zero, not
measured) on the panel and in the caption (the double pendulum's minimal-coordinate
panels were empty, unexplained)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tests.test_report import synthetic_results, synthetic_series
from workbench.outputs.report import write_report
from workbench.outputs.report.analysis import drift_runs, prepare_results
from workbench.outputs.report.figures import drift_figure


def all_ok() -> pd.DataFrame:
    """One problem, 2 x 2 pairs, every run ok; no invariant measured."""
    runs = synthetic_results(problems=("simple-pendulum",), integrators=("radau", "bdf"))
    assert (runs["status"] == "ok").all()
    return runs.assign(invariant_err_max=np.nan)


def test_the_status_caption_points_to_notes_only_when_there_are_some(tmp_path: Path) -> None:
    write_report(all_ok(), synthetic_series, tmp_path / "ok", "cmd", progress=False)
    status = (tmp_path / "ok" / "tables" / "status.tex").read_text(encoding="utf-8")
    assert "Runs by status" in status and "listed below" not in status
    drift = next((tmp_path / "ok" / "tables").glob("drift-*.tex")).read_text(encoding="utf-8")
    assert "position drift" in drift and "energy error" in drift
    assert "invariant" not in drift  # no column of it
    assert "drift in m and m/s: every position constraint" in drift  # a planar revolute
    failing = synthetic_results(problems=("simple-pendulum", "heavy-top"))
    assert (failing["status"] != "ok").any()
    write_report(failing, synthetic_series, tmp_path / "failed", "cmd", progress=False)
    status = (tmp_path / "failed" / "tables" / "status.tex").read_text(encoding="utf-8")
    assert "listed below" in status and "[1]" in status


def test_an_empty_drift_panel_says_why(tmp_path: Path) -> None:
    runs = prepare_results(all_ok())

    def series(run_id: str) -> pd.DataFrame:  # minimal coordinates: no position drift
        frame = synthetic_series(run_id)
        return frame.assign(drift_pos=0.0) if "minimal-ode" in run_id else frame

    _rtol, chosen = drift_runs(runs)
    (tmp_path / "figures").mkdir()
    figure, _ = drift_figure(runs, {r: series(r) for r in chosen["run_id"]}, tmp_path, "p")
    assert figure is not None
    assert "empty panels: minimal-ode's position constraint drift exactly zero at every sample" in (
        figure.caption
    )
    assert "absolute-dae's position" not in figure.caption  # drawn there


def test_the_drift_legend_lists_only_what_is_drawn_and_the_caption_says_why(
    tmp_path: Path,
) -> None:
    """Every run of one integrator at the middle rtol without a stored series (or all of
    its runs failed there): its legend entry stood beside no curve, and no word said why.
    The legend (read from the SVG's text) names only integrators with a curve; the caption
    names the pairs without one, and those left out, as the drift table's does."""
    import re

    runs = all_ok()
    middle = np.isclose(runs["rtol"], 1e-5) & (runs["integrator"] == "bdf")
    failed = middle & (runs["formalism"] == "absolute-dae")
    runs.loc[failed, ["status", "message"]] = ["timeout", "time limit of 60 s exceeded"]
    runs = prepare_results(runs)
    _rtol, chosen = drift_runs(runs)
    series = {r: None if "bdf" in r else synthetic_series(r) for r in chosen["run_id"]}
    (tmp_path / "figures").mkdir()
    figure, _ = drift_figure(runs, series, tmp_path, "p")
    assert figure is not None
    svg = (tmp_path / "figures" / f"{figure.stem}.svg").read_text(encoding="utf-8")
    legend = re.findall(r"<!-- ((?:integrator|formalism) [^ ]+) -->", svg)
    assert "integrator radau" in legend and "integrator bdf" not in legend, legend
    assert "no curve: minimal-ode / bdf (no stored time series)" in figure.caption
    assert "not in it, no ok run there: absolute-dae / bdf (timeout)" in figure.caption


def test_a_drift_caption_says_the_unit_of_its_problems_drift() -> None:
    """The headers say 'm or rad' for every problem (qa3c F13): the caption says which,
    from the model's constraints (a planar revolute keeps points together: m; a spatial
    revolute also keeps axes aligned: both, the column holding the larger)."""
    from workbench.outputs.report.analysis import drift_table_contents
    from workbench.outputs.report.traits import drift_units, problem_model

    expected = {"double-pendulum": {"m"}, "heavy-top": {"m"}, "slider-crank": {"m", "rad"},
                "rsrrr": {"m", "rad"}}  # fmt: skip
    for problem, units in expected.items():
        assert drift_units(problem_model(problem)) == units, problem
    table = pd.DataFrame(columns=["pair", "drift_pos_max", "drift_vel_max", "err_max"])
    assert drift_table_contents(table, {"m"}).endswith(
        "; drift in m and m/s: every position constraint of this model is a distance"
    )
    assert "drift in m: every" in drift_table_contents(table.drop(columns="drift_vel_max"), {"m"})
    assert "a distance (m) or an axis misalignment" in drift_table_contents(table, {"m", "rad"})
    assert "drift in" not in drift_table_contents(table)  # model unknown: nothing claimed
    assert "drift in" not in drift_table_contents(table[["pair", "err_max"]], {"m"})


def test_the_drift_figure_axis_says_the_unit_of_its_problems_drift(tmp_path: Path) -> None:
    """The drift figure's axis said "[m or rad]" for every problem (qa3c F13, left then):
    a model whose position constraints are all distances is drawn in m and m/s; one that
    also aligns axes keeps both; an unknown model claims nothing."""
    runs = prepare_results(all_ok())
    _rtol, chosen = drift_runs(runs)
    series = {r: synthetic_series(r) for r in chosen["run_id"]}
    (tmp_path / "figures").mkdir()

    def labels(units: set[str]) -> list[str]:
        figure, _ = drift_figure(runs, series, tmp_path, "p", units)
        assert figure is not None
        return [axis.label for axis in figure.axes]

    distances = labels({"m"})
    assert any("position constraint drift\n[m]" in label for label in distances), distances
    assert not any("rad" in label for label in distances)
    for units in ({"m", "rad"}, set()):
        assert any("[m or rad]" in label for label in labels(units))


def test_a_drift_table_names_the_pairs_it_leaves_out(tmp_path: Path) -> None:
    """iftomm-a05's drift table said 'every pair at rtol = 0.0001' over the 8 pairs that
    finished there; the ninth had timed out, and no word said so."""
    runs = all_ok()
    middle = np.isclose(runs["rtol"], 1e-5) & (runs["formalism"] == "absolute-dae")
    middle &= runs["integrator"] == "bdf"
    runs.loc[middle, ["status", "message"]] = ["timeout", "time limit of 60 s exceeded"]
    write_report(runs, synthetic_series, tmp_path, "cmd", progress=False)
    drift = next((tmp_path / "tables").glob("drift-*-rtol-1e-05.tex")).read_text(encoding="utf-8")
    caption = " ".join(drift.split(r"\caption{", 1)[1].split(r"\label", 1)[0].split())
    assert "not in it, no ok run there: absolute-dae / bdf (timeout)" in caption
    assert "absolute-dae / bdf" not in drift.split(r"\midrule", 1)[1]  # no row of it
