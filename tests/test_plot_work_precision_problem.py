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
