"""The results store: atomic files, stable schema, corrupt files reported, not fatal."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

import workbench
from workbench import files
from workbench.errors import ConfigError
from workbench.execution import row_schema
from workbench.execution.row_schema import SERIES_COLUMNS
from workbench.runs import store


def row(run_id: str, **extra) -> dict:
    base = {
        "run_id": run_id,
        "problem": "p",
        "formalism": "f",
        "integrator": "i",
        "rtol": 1e-6,
        "atol": 1e-9,
        "status": "ok",
        "message": "",
        "err_max": 1e-5,
    }
    return base | extra


def series(run_id: str) -> pd.DataFrame:
    return pd.DataFrame({c: [0.0, 1.0] for c in SERIES_COLUMNS}).assign(run_id=run_id)


def test_write_run_leaves_no_temporary_files(tmp_path) -> None:
    store.write_run(tmp_path, row("a" * 16), series("a" * 16))
    store.write_run(tmp_path, row("b" * 16, status="skipped"), None)
    files = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())
    assert files == [
        "runs/" + "a" * 16 + ".json",
        "runs/" + "b" * 16 + ".json",
        "series/" + "a" * 16 + ".parquet",
    ]
    assert not list(tmp_path.rglob("*.tmp"))
    assert store.completed_run_ids(tmp_path) == {"a" * 16, "b" * 16}


def test_failed_write_leaves_no_temporary_file(tmp_path) -> None:
    with pytest.raises(TypeError):
        files.write_json_atomic({"run_id": object()}, tmp_path / "x.json")
    assert list(tmp_path.iterdir()) == []


def test_load_results_schema_and_the_top_level_export(tmp_path) -> None:
    store.write_run(tmp_path, row("a" * 16, custom=3), series("a" * 16))
    frame = workbench.load_results(tmp_path)
    assert list(frame.columns[: len(row_schema.SCHEMA_COLUMNS)]) == row_schema.SCHEMA_COLUMNS
    assert frame.loc[0, "custom"] == 3 and math.isnan(frame.loc[0, "scd"])
    for column in [
        "run_id",
        "problem",
        "formalism",
        "integrator",
        "rtol",
        "atol",
        "status",
        "message",
        "wall_s",
        "cpu_s",
        "n_rhs",
        "n_jac",
        "n_steps",
        "n_rejected",
        "err_max",
        "err_end",
        "scd",
        "drift_pos_max",
        "drift_vel_max",
        "drift_nh_max",
        "energy_err_max",
        "invariant_err_max",
    ]:
        assert column in frame.columns
    # consolidated parquet reads back the same rows
    path = store.consolidate(tmp_path)
    again = workbench.load_results(path)
    assert list(again["run_id"]) == list(frame["run_id"])
    assert list(again.columns[: len(row_schema.SCHEMA_COLUMNS)]) == row_schema.SCHEMA_COLUMNS
    assert len(workbench.load_series(tmp_path, "a" * 16)) == 2
    assert len(store.load_series(tmp_path)) == 2


def test_corrupt_row_is_reported_not_fatal(tmp_path) -> None:
    store.write_run(tmp_path, row("a" * 16), series("a" * 16))
    good = store.row_path(tmp_path, "a" * 16).read_text()
    store.row_path(tmp_path, "b" * 16).write_text(good[: len(good) // 2])  # truncated
    store.row_path(tmp_path, "c" * 16).write_text(json.dumps([1, 2]))  # not a row
    with pytest.warns(UserWarning, match="2 unreadable result file"):
        frame = store.load_results(tmp_path)
    assert list(frame["run_id"]) == ["a" * 16]
    assert len(frame.attrs["unreadable"]) == 2
    # a resumed sweep redoes them
    assert store.completed_run_ids(tmp_path) == {"a" * 16}


def test_a_row_and_series_read_mid_write_are_read_whole(tmp_path, monkeypatch) -> None:
    """`workbench results` beside a running sweep: a worker writes a run's files in place
    (files.write_new_file), so a reader can open a series that is a part and a row that is
    still empty; both are whole a moment later and read so, with no warning. (The settling
    time raised: a timer thread late on a busy machine still finishes the file within it.)"""
    import threading
    import warnings

    monkeypatch.setattr(store, "SETTLE_S", 60.0)

    store.write_run(tmp_path, row("a" * 16), series("a" * 16))
    row_file = store.row_path(tmp_path, "a" * 16)
    series_file = store.series_path(tmp_path, "a" * 16)
    whole_row, whole_series = row_file.read_bytes(), series_file.read_bytes()
    for part, path, whole in ((whole_series[: len(whole_series) // 2], series_file, whole_series),
                              (b"", row_file, whole_row)):  # a series without footer, a row empty
        path.write_bytes(part)
        finish = threading.Timer(0.2, path.write_bytes, [whole])
        finish.start()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # "unreadable ... file" would fail here
                frame = store.load_results(tmp_path)
                one = store.load_series(tmp_path, "a" * 16)
        finally:
            finish.join()
        assert list(frame["run_id"]) == ["a" * 16] and frame.attrs["unreadable"] == []
    assert list(one["t"]) == [0.0, 1.0]


def test_an_old_broken_row_is_not_waited_for(tmp_path, monkeypatch) -> None:
    """A part left by a killed writer long ago is unreadable at once (no settling wait);
    a new one is read again, then given up once it is older than SETTLE_S (a fake clock
    that the waits advance: no real time in the test)."""
    from types import SimpleNamespace

    broken = store.row_path(tmp_path, "b" * 16)
    broken.parent.mkdir(parents=True)
    broken.write_text("{")
    changed = broken.stat().st_mtime
    clock, waits = [changed + 60.0], []

    def sleep(seconds: float) -> None:
        waits.append(seconds)
        clock[0] += seconds

    monkeypatch.setattr(store, "time", SimpleNamespace(time=lambda: clock[0], sleep=sleep))
    assert store.read_row(broken, settle=True) is None and waits == []
    clock[0] = changed + 0.5  # half a second after its last change
    assert store.read_row(broken, settle=True) is None
    assert waits and clock[0] >= changed + store.SETTLE_S  # waited until it was old


def test_missing_results_is_a_config_error(tmp_path) -> None:
    with pytest.raises(ConfigError, match="no results"):
        store.load_results(tmp_path / "nothing")
    (tmp_path / "bad.parquet").write_text("not parquet")
    with pytest.raises(ConfigError, match="cannot read"):
        store.load_results(tmp_path / "bad.parquet")


# -- schema versions -------------------------------------------------------------------
def write_row_file(out, data: dict) -> None:
    """A row file as some version of the workbench wrote it (no migration on the way)."""
    path = store.row_path(out, data["run_id"])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data))


def test_rows_are_written_with_the_current_schema_version(tmp_path) -> None:
    from workbench.execution.execute import RunSpec, status_row

    spec = RunSpec("p", "f", "i", 1e-6, 1e-9)
    store.write_run(tmp_path, status_row(spec, "timeout", "too slow"), None)
    written = json.loads(store.row_path(tmp_path, spec.run_id).read_text())
    assert written["schema_version"] == row_schema.SCHEMA_VERSION == 10
    frame = store.load_results(tmp_path)
    assert frame.loc[0, "schema_version"] == 10 and frame.attrs["migrated"] == []


def test_an_old_schema_directory_loads_migrated(tmp_path) -> None:
    old = row("a" * 16, custom="kept")  # version 1: no schema_version
    write_row_file(tmp_path, old)
    frame = store.load_results(tmp_path)
    assert frame.attrs["migrated"] == [str(store.row_path(tmp_path, "a" * 16))]
    loaded = frame.iloc[0].to_dict()
    assert loaded["schema_version"] == 10
    assert math.isnan(loaded["scd_mixed"])  # never measured before schema 4
    # never audited: the warnings say so instead of reading as "nothing wrong"
    assert loaded["warnings"].startswith("not audited")
    assert {k: loaded[k] for k in old} == old  # nothing else changed
    # a results.parquet consolidated before schema versions existed
    parquet = tmp_path / "old.parquet"
    pd.DataFrame([old, row("b" * 16)]).to_parquet(parquet)
    again = store.load_results(parquet)
    assert list(again["schema_version"]) == [10, 10]
    assert again.attrs["migrated"] == [str(parquet)]


def test_a_schema_3_row_gets_the_trajectory_error_and_step_as_not_measured(tmp_path) -> None:
    write_row_file(tmp_path, row("e" * 16, schema_version=3, warnings=""))
    loaded = store.load_results(tmp_path).iloc[0]
    assert loaded["schema_version"] == 10 and loaded["warnings"] == ""
    assert np.isnan(loaded["err_l2"]) and np.isnan(loaded["fixed_step_s"])


def test_a_schema_6_row_gets_the_repeated_timing_as_not_measured(tmp_path) -> None:
    # a row of schema 6 timed its integration once: that sample stays integrate_s, and
    # the spread, CPU time, samples, load and workers were never measured (NaN, not 0)
    write_row_file(tmp_path, row("f" * 16, schema_version=6, integrate_s=0.25, warnings=""))
    loaded = store.load_results(tmp_path).iloc[0]
    assert loaded["schema_version"] == 10 and loaded["integrate_s"] == 0.25
    new = ["integrate_s_min", "integrate_s_max", "integrate_cpu_s", "repeats", "load_avg"]
    assert all(np.isnan(loaded[column]) for column in [*new, "workers"])
    assert row_schema.MIGRATIONS[6](row("f" * 16, schema_version=6)).keys() >= {*new, "workers"}


def test_a_schema_7_row_gets_the_cpu_interval_as_not_measured(tmp_path) -> None:
    # a row of schema 7 kept the median CPU time only: its interval was never measured
    write_row_file(
        tmp_path, row("9" * 16, schema_version=7, integrate_cpu_s=0.5, repeats=1, warnings="")
    )
    loaded = store.load_results(tmp_path).iloc[0]
    assert loaded["schema_version"] == 10 and loaded["integrate_cpu_s"] == 0.5
    assert np.isnan(loaded["integrate_cpu_s_min"]) and np.isnan(loaded["integrate_cpu_s_max"])


def test_a_schema_8_row_gets_the_counted_work_as_not_measured(tmp_path) -> None:
    write_row_file(tmp_path, row("8" * 16, schema_version=8, n_rhs=120, warnings=""))
    loaded = store.load_results(tmp_path).iloc[0]
    assert loaded["schema_version"] == 10 and loaded["n_rhs"] == 120
    never = ("work_s", "work_s_min", "work_s_max", "penetration_max", "n_events")
    assert all(np.isnan(loaded[c]) for c in never)


def test_a_newer_schema_is_refused_naming_the_file(tmp_path) -> None:
    write_row_file(tmp_path, row("c" * 16, schema_version=row_schema.SCHEMA_VERSION + 1))
    newer = str(store.row_path(tmp_path, "c" * 16))
    with pytest.raises(ConfigError, match="upgrade the workbench") as error:
        store.load_results(tmp_path)
    newest = f"schema version {row_schema.SCHEMA_VERSION + 1}"
    assert newer in str(error.value) and newest in str(error.value)
    # a resumed sweep refuses too (it would add rows of an older schema)
    with pytest.raises(ConfigError, match="upgrade the workbench"):
        store.completed_run_ids(tmp_path)
    parquet = tmp_path / "new.parquet"
    pd.DataFrame([row("d" * 16, schema_version=row_schema.SCHEMA_VERSION + 1)]).to_parquet(parquet)
    with pytest.raises(ConfigError, match=f"{parquet}.*upgrade the workbench"):
        store.load_results(parquet)


def test_mixed_directories(tmp_path) -> None:
    # old and current rows load together, all in the current schema
    write_row_file(tmp_path, row("a" * 16))
    write_row_file(tmp_path, row("b" * 16, schema_version=row_schema.SCHEMA_VERSION))
    frame = store.load_results(tmp_path)
    assert list(frame["schema_version"]) == [10, 10]
    assert frame.attrs["migrated"] == [str(store.row_path(tmp_path, "a" * 16))]
    for run_id in ("a" * 16, "b" * 16):  # an ok row is done with its series only
        files.write_parquet_atomic(series(run_id), store.series_path(tmp_path, run_id))
    assert store.completed_run_ids(tmp_path) == {"a" * 16, "b" * 16}
    # one newer row refuses the whole directory (no silently partial results), naming it
    for run_id in ("c" * 16, "d" * 16):
        write_row_file(tmp_path, row(run_id, schema_version=row_schema.SCHEMA_VERSION + 1))
    with pytest.raises(ConfigError, match="and 1 other row file") as error:
        store.load_results(tmp_path)
    assert str(store.row_path(tmp_path, "c" * 16)) in str(error.value)


@pytest.mark.parametrize("value", ["2", 0, 1.5, True, [2]])
def test_a_schema_version_that_is_not_one_is_refused(tmp_path, value) -> None:
    write_row_file(tmp_path, row("a" * 16, schema_version=value))
    with pytest.raises(ConfigError, match="is not a schema version"):
        store.load_results(tmp_path)


def test_a_schema_8_row_gets_the_contact_metrics_as_not_measured(tmp_path) -> None:
    # rows before schema 9 had no contacts: their contact columns are NaN, not 0
    write_row_file(tmp_path, row("8" * 16, schema_version=8, warnings=""))
    loaded = store.load_results(tmp_path).iloc[0]
    assert loaded["schema_version"] == 10 and loaded["warnings"] == ""
    columns = ["penetration_max", "complementarity_max", "n_events", "event_time_err_max",
               "energy_balance_err"]  # fmt: skip
    assert all(np.isnan(loaded[column]) for column in columns)
