"""``workbench.plot_work_precision(frame, problem=...)`` with a problem the results do not
hold (a misspelling) says so: it drew an empty diagram titled with the wrong name."""

from __future__ import annotations

import matplotlib
import pytest

import workbench as wb
from workbench.errors import ConfigError

matplotlib.use("Agg")


def test_a_problem_the_results_do_not_hold_is_named_with_those_they_do(tmp_path) -> None:
    for rtol in (1e-4, 1e-6):
        wb.run("simple-pendulum", "minimal-ode", "scipy-dop853", rtol=rtol, out=tmp_path)
    frame = wb.load_results(tmp_path)
    ax = wb.plot_work_precision(frame, problem="simple-pendulum")
    (line,) = ax.get_lines()  # one pair, one point a tolerance
    assert len(line.get_xdata()) == 2
    with pytest.raises(ConfigError, match=r"no runs of problem 'simple-pendullum'.*pendulum"):
        wb.plot_work_precision(frame, problem="simple-pendullum")


def test_the_default_axis_has_its_unit_and_a_warned_run_is_ringed() -> None:
    """The default cost (the column ``integrate_cpu_s``) labelled the x axis with the bare
    column name, no unit; and a warned run (an scd capped at the reference's accuracy,
    not measured) was drawn as any other point. It is ringed red, as in the report."""
    from tests.test_report import synthetic_results

    frame = synthetic_results(problems=("simple-pendulum",))
    frame["integrate_cpu_s"] = frame["wall_s"]
    frame["warnings"] = ""
    ok = frame.index[frame["status"] == "ok"]
    frame.loc[ok[0], "warnings"] = "end error is below the reference's own accuracy"
    ax = wb.plot_work_precision(frame)
    assert ax.get_xlabel() == "integration CPU time [s]"
    (rings,) = ax.collections
    assert rings.get_offsets().tolist() == [[frame.loc[ok[0], "wall_s"], frame.loc[ok[0], "scd"]]]
    assert "warnings" in rings.get_label()
