"""Resuming a sweep: broken rows and series are found and redone, stale rows are found,
``--rerun`` and ``--fresh`` redo what they name, infrastructure failures are no results."""

from __future__ import annotations

import json
import warnings

import pandas as pd
import pytest

from tests.test_sweep import fake_plugins, spec_text  # noqa: F401 - the fixture
from workbench.runs import store
from workbench.runs.sweep import parse_spec, run_sweep

FALLING = '["test-falling"]'  # an analytic reference: no reference pipeline to run


def sweep_lines(text: str, **options) -> tuple[object, list[str]]:
    lines: list[str] = []
    summary = run_sweep(parse_spec(text), show_progress=False, say=lines.append, **options)
    return summary, lines


def test_broken_rows_and_series_are_named_and_redone(fake_plugins, tmp_path) -> None:  # noqa: F811
    text = spec_text(tmp_path, '["test-rk45"]', problems=FALLING)
    first, _ = sweep_lines(text)
    assert first.counts["ok"] == 2
    frame = store.load_results(tmp_path)
    a, b = sorted(frame["run_id"])
    samples = int(frame.set_index("run_id").loc[b, "n_samples"])
    assert samples == 11  # the problem's output times, all stored
    # a "row" with nothing but its id (counted as done before, then a TypeError in the report)
    store.row_path(tmp_path, a).write_text(json.dumps({"run_id": a}))
    # a truncated series
    series_b = store.series_path(tmp_path, b)
    whole = series_b.read_bytes()
    series_b.write_bytes(whole[: len(whole) // 2])
    with pytest.warns(UserWarning, match=f"{a}.json .*no problem"):
        frame = store.load_results(tmp_path)
    assert list(frame["run_id"]) == [b]
    with pytest.warns(UserWarning, match=f"{b}.parquet"):
        assert len(store.load_series(tmp_path)) == samples  # a's, whole; b's left out
    assert store.completed_run_ids(tmp_path) == set()
    again, lines = sweep_lines(text)
    assert again.total == 2 and again.counts["ok"] == 2 and again.already_done == 0
    assert any(line.startswith(f"run {a} (test-falling") and "no problem" in line for line in lines)
    assert any(f"run {b}" in line and "unreadable" in line for line in lines), lines
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sorted(store.load_results(tmp_path)["run_id"]) == [a, b]
        assert len(store.load_series(tmp_path)) == 2 * samples
    # a whole Parquet file, but fewer samples than the row says
    pd.read_parquet(series_b).iloc[:3].to_parquet(series_b, index=False)
    third, lines = sweep_lines(text)
    assert third.total == 1
    assert any(f"has 3 samples, the row says {samples}" in line for line in lines), lines
    assert len(store.load_series(tmp_path, b)) == samples
