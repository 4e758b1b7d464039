"""Each problem's part of the report says where its reference came from, and when it was
computed with a formalism that is also swept, that this formalism's runs are scored
against their own equations (the rows said so; the page did not)."""

from __future__ import annotations

from pathlib import Path

from tests.test_report import synthetic_results
from workbench.outputs.report import prepare_results, write_report
from workbench.outputs.report.analysis import reference_source

COMPUTED = (
    "computed: minimal-ode + heyoka-taylor(precision=extended) at rtol 1e-19, atol 1e-19, "
    "accuracy 1e-15 L (difference from minimal-ode + heyoka-taylor(precision=extended) at "
    "rtol 1e-17)"
)


def test_each_problem_names_its_reference(tmp_path: Path) -> None:
    runs = synthetic_results()
    pendulum = runs["problem"] == "simple-pendulum"
    runs.loc[pendulum, "reference"] = "stored: simple-pendulum (two pipelines agree to 1e-13)"
    runs.loc[~pendulum, "reference"] = COMPUTED + " (read from heavy-top-0123abcd.parquet)"
    runs.loc[runs.index[-1], "reference"] = COMPUTED  # the run that computed it
    runs = prepare_results(runs)
    top = reference_source(runs[~pendulum])
    assert top.startswith(COMPUTED) and "read from" not in top
    assert "minimal-ode's runs are scored against their own equations" in top
    assert "scored against" not in reference_source(runs[pendulum])
    others = runs[~pendulum & (runs["formalism"] != "minimal-ode")]
    assert "scored against" not in reference_source(others)  # not swept: nothing to say
    assert reference_source(runs.drop(columns="reference")) == ""
    page = write_report(runs, None, tmp_path / "report", "cmd", progress=False).read_text("utf-8")
    assert "Reference: stored: simple-pendulum (two pipelines agree to 1e-13)." in page
    assert f"Reference: {COMPUTED}; minimal-ode&#39;s runs are scored" in page
