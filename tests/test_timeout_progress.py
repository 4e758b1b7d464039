"""A run killed at its time limit says where its time went (issue 32 item 11).

The worker writes its stage and the time its integration reached to a progress file; the
pool reads it when it kills the worker, so the ``timeout`` row carries ``stage``,
``t_reached`` and ``wall_s`` (they were empty).
"""

from __future__ import annotations

import math

from workbench.execution.execute import RunSpec
from workbench.runs import store
from workbench.runs.local_pool import run_local

LIMIT = 4.0  # s: the run below needs minutes (2000 s of pendulum at rtol 1e-10 by Radau)


def test_a_timed_out_run_keeps_its_stage_and_how_far_it_got(tmp_path) -> None:
    spec = RunSpec("iftomm-a01", "minimal-ode", "scipy-radau", 1e-10, 1e-13,
                   {"duration": 2000.0}, {"index": 1})  # fmt: skip
    statuses: list[str] = []
    run_local([spec], tmp_path, LIMIT, [], 1, statuses.append)
    assert statuses == ["timeout"]
    row = store.load_results(tmp_path).iloc[0]
    assert row["status"] == "timeout"
    assert row["stage"] in {"pairing", "build", "initial state", "integrate", "reference"}
    assert 0.0 < row["wall_s"] <= LIMIT + 1.0
    assert f"killed in stage '{row['stage']}'" in row["message"]
    if row["stage"] == "integrate":  # where an unloaded machine gets to in 4 s
        assert 0.0 <= row["t_reached"] < 2000.0
        assert f"at t = {row['t_reached']:.6g} s of 2000 s" in row["message"]
    else:
        assert math.isnan(row["t_reached"])
    assert not list(tmp_path.rglob("*.progress*"))  # read and removed


def test_a_run_killed_before_its_first_evaluation_reports_no_time(tmp_path, fake_plugins) -> None:
    """A worker reuses the equations it built for the run before (same problem and
    formalism); a run that hangs before evaluating them must not report the time the
    earlier run's integration ended at (it read "at t = 2 s of 2 s")."""
    finished = RunSpec("test-pendulum", "minimal-ode", "test-rk45", 1e-6, 1e-9)
    hung = RunSpec("test-pendulum", "minimal-ode", "test-hang", 1e-6, 1e-9)
    statuses: list[str] = []
    run_local([finished, hung], tmp_path, 3.0, ["tests.fake_plugins"], 1, statuses.append)
    assert statuses == ["ok", "timeout"]
    rows = store.load_results(tmp_path).set_index("integrator")
    assert rows.loc["test-rk45", "t_reached"] == 2.0
    assert rows.loc["test-hang", "stage"] == "integrate"
    assert math.isnan(rows.loc["test-hang", "t_reached"])
    assert "at t =" not in rows.loc["test-hang", "message"]
