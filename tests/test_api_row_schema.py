"""``workbench.run(...).row`` has every column of the row schema whatever the run's
status, as ``load_results`` does: a skipped pair's row had none of the metrics, so
``row["scd"]`` raised KeyError in a loop over pairs."""

from __future__ import annotations

import math

import pytest

import workbench as wb
from workbench.execution.row_schema import SCHEMA_COLUMNS


def test_a_skipped_runs_row_has_every_schema_column_with_nan_metrics(tmp_path) -> None:
    # absolute-dae offers a dae of index 3 by default: DOP853 takes an ode, so skipped
    with pytest.warns(RuntimeWarning, match="skipped"):
        skipped = wb.run("simple-pendulum", "absolute-dae", "scipy-dop853", out=tmp_path)
    done = wb.run("simple-pendulum", "minimal-ode", "scipy-dop853")
    assert skipped.row["status"] == "skipped" and done.row["status"] == "ok"
    for result in (skipped, done):
        assert set(SCHEMA_COLUMNS) <= set(result.row.index)
    assert math.isnan(skipped.row["scd"]) and math.isnan(skipped.row["err_max"])
    assert done.row["scd"] > 3
    stored = wb.load_results(tmp_path).iloc[0]
    assert stored["run_id"] == skipped.run_id and math.isnan(stored["scd"])
    assert not skipped.ok
