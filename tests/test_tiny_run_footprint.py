"""A tiny run's work outside its integration made cheaper (issue 35, item 4) gives the
same row and series: metrics of all samples in one mapped call equal one call a sample,
the series is built column by column as ``pd.concat`` built it, the run id is computed
once and is the hash of the spec."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pandas as pd
import pytest

from workbench.equations import observables as observables_module
from workbench.equations.initial import consistent_initial_state
from workbench.execution import audit
from workbench.execution import metrics as metrics_module
from workbench.execution.execute import (
    RunSpec,
    canonical_json,
    execute_run,
    normalized_spec,
    state_columns,
    with_state_columns,
)
from workbench.execution.references import problem_reference
from workbench.execution.row_schema import SERIES_COLUMNS, STATE_PREFIX
from workbench.plugin.registry import get_formalism, get_integrator, get_problem


def _one_sample_at_a_time(function, n, args, cache):
    """evaluate_along's contract met by n separate calls (the metrics before Function.map)."""
    outputs = [function.call([np.asarray(a)[:, k] for a in args]) for k in range(n)]
    return [np.stack([np.array(out[i]) for out in outputs]) for i in range(function.n_out())]


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b or abs(a - b) <= 1e-12 * max(abs(a), abs(b))
    return a == b


@pytest.mark.parametrize(
    ("problem", "formalism", "options"),
    [
        ("simple-pendulum", "minimal-ode", {}),  # the tiny run of the benchmark
        ("four-bar", "absolute-dae", {"index": 1}),  # drift, closed loop
    ],
)
def test_metrics_of_all_samples_at_once_equal_one_sample_at_a_time(
    problem, formalism, options, monkeypatch
):
    """Every metric column and series value of a real run, by the mapped call
    (``Observables.along``) and by one call a sample: equal to 1e-12 relative, the same
    columns."""
    problem_ = get_problem(problem)()
    equations = get_formalism(formalism)().build(problem_.model(), options)
    state = consistent_initial_state(equations, problem_)
    integrator = get_integrator("scipy-dop853")()
    parsed = integrator.parse_options({})
    form = integrator.select_form({k: getattr(f, "index", 0) for k, f in equations.forms.items()})
    times = problem_.sample_times()
    trajectory = integrator.solve(
        equations, state.y0(equations, form), state.yp0(equations, form), times, 1e-6, 1e-8,
        parsed, form,
    )  # fmt: skip
    reference = problem_reference(problem_, problem, {}, times, None)

    def measure():
        return metrics_module.trajectory_metrics(
            "run", problem_, equations, np.asarray(trajectory.times),
            np.atleast_2d(trajectory.y), trajectory.success, reference, 1e-6,
        )  # fmt: skip

    row, series = measure()
    monkeypatch.setattr(observables_module, "evaluate_along", _one_sample_at_a_time)
    monkeypatch.setattr(audit, "evaluate_along", _one_sample_at_a_time)
    equations.observables._last = ()  # no poses kept from the mapped call
    row_each, series_each = measure()
    assert list(series.columns) == SERIES_COLUMNS == list(series_each.columns)
    assert row.keys() == row_each.keys()
    for key, value in row.items():
        assert _same(value, row_each[key]), (key, value, row_each[key])
    assert np.isfinite(series["energy_err"]).all()
    numeric = SERIES_COLUMNS[1:]
    np.testing.assert_allclose(
        series[numeric].to_numpy(), series_each[numeric].to_numpy(), rtol=1e-12, atol=1e-300
    )


def test_the_series_with_states_is_the_concat_of_both():
    """:func:`with_state_columns` (one frame made from the columns) gives the frame
    ``pd.concat([series, state_columns(...)], axis=1)`` gave: names, order, dtypes, values."""
    problem = get_problem("four-bar")()
    equations = get_formalism("absolute-dae")().build(problem.model(), {"index": 1})
    n = 7
    rng = np.random.default_rng(3)
    series = pd.DataFrame({"run_id": "abc", "t": np.linspace(0, 1, n)} | {
        name: rng.standard_normal(n) for name in SERIES_COLUMNS[2:]
    })  # fmt: skip
    for form in ("ode", "dae"):
        width = len(equations.y_names("dae" if form == "dae" else "ode")) + 2
        y = rng.standard_normal((n, width))
        made = with_state_columns(series, equations, form, y)
        expected = pd.concat([series, state_columns(equations, form, y)], axis=1)
        pd.testing.assert_frame_equal(made, expected)
        assert list(made.columns[: len(SERIES_COLUMNS)]) == SERIES_COLUMNS
        assert all(c.startswith(STATE_PREFIX) for c in made.columns[len(SERIES_COLUMNS) :])


def test_the_run_id_is_computed_once_and_is_the_hash_of_the_spec():
    spec = normalized_spec(RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-4, 1e-6))
    expected = hashlib.sha256(canonical_json(spec.to_dict()).encode()).hexdigest()[:16]
    assert spec.run_id == expected and spec.__dict__["run_id"] == expected
    result = execute_run(spec)
    assert result.row["run_id"] == expected and result.row["status"] == "ok"
    assert set(result.series["run_id"]) == {expected}
