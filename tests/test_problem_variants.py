"""A problem swept over several option sets is several mechanisms: each gets its own line
in `workbench results`, its own part of the report and its own answer (they were ranked
as one problem, the Pareto table and diagrams mixing the two)."""

from __future__ import annotations

import json

import pandas as pd

from workbench.outputs.report.analysis import prepare_results
from workbench.outputs.results_table import changed_options, with_option_columns


def rows() -> pd.DataFrame:
    angles = [0.5, 0.3, 0.5, 0.3]
    return pd.DataFrame({
        "problem": ["simple-pendulum"] * 4,
        "problem_options": [json.dumps({"initial_angle": a}) for a in angles],
        "formalism": ["recursive"] * 4, "integrator": ["scipy-dop853"] * 4,
        "rtol": [1e-6, 1e-6, 1e-8, 1e-8], "status": ["ok"] * 4,
    })  # fmt: skip


def test_each_option_set_of_a_problem_is_its_own_problem() -> None:
    runs = prepare_results(rows())
    assert list(runs["problem"]) == [
        "simple-pendulum[initial_angle=0.5]", "simple-pendulum[initial_angle=0.3]"
    ] * 2  # fmt: skip
    assert set(runs["problem_name"]) == {"simple-pendulum"}  # the plugin, for lookups
    assert runs.groupby("problem").ngroups == 2


def test_a_problem_run_with_one_option_set_keeps_its_name() -> None:
    same = rows().assign(problem_options=json.dumps({"initial_angle": 0.3}))
    assert set(prepare_results(same)["problem"]) == {"simple-pendulum"}


def test_the_problem_options_are_columns_and_named_where_not_default() -> None:
    runs = prepare_results(rows())
    spread = with_option_columns(runs)
    assert list(spread["problem.initial_angle"]) == [0.5, 0.3, 0.5, 0.3]
    changed = changed_options(runs)
    assert changed[1] == {"problem.initial_angle": "0.3"} and changed[0] == {}  # 0.5: default


def test_a_work_precision_plot_asks_which_variant() -> None:
    import pytest

    from workbench.api.plots import plot_work_precision
    from workbench.errors import ConfigError

    frame = rows().assign(scd=[5.0, 6.0, 7.0, 8.0], integrate_cpu_s=[1e-3, 1e-3, 2e-3, 2e-3])
    with pytest.raises(ConfigError, match="results hold 2 problems"):
        plot_work_precision(frame)
    ax = plot_work_precision(frame, problem="simple-pendulum[initial_angle=0.3]")
    (line,) = ax.get_lines()
    assert list(line.get_ydata()) == [6.0, 8.0]
