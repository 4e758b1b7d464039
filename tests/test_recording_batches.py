"""A worker's recordings a batch of runs a file (issue 35.4): the merged recording is the
one per-run files made, and the runs a killed worker had not written are recorded again
(in the sweep, or by the resume of a sweep killed as a whole), their rows kept."""

from __future__ import annotations

import json
import os
import signal
from collections import defaultdict
from pathlib import Path

import pytest
import rerun as rr

from tests.test_recording import fake_equations, fake_run
from tests.test_sweep import spec_text
from workbench.outputs.recording import SweepRecorder, merge_recordings, split_entity_path
from workbench.runs import store
from workbench.runs.recording_batches import (
    RECORDINGS_DIR,
    RecordingBatch,
    journal_path,
    journals,
    unwritten_runs,
)
from workbench.runs.sweep import parse_spec, run_sweep

FALLING = '["test-falling"]'
KILL_MARKER = "WORKBENCH_TEST_KILL_MARKER"


@pytest.fixture(autouse=True)
def fresh_workers(monkeypatch):
    """Workers started by spawn: they import this module, whose recorder they are given."""
    import multiprocessing

    from workbench.runs import local_pool

    monkeypatch.setattr(local_pool, "worker_context", lambda: multiprocessing.get_context("spawn"))


def content(path: Path) -> dict[str, list[str]]:
    """What a recording holds of its runs: each entity's rows (static or not, values
    and times; not Rerun's row and chunk ids, which differ between writes), sorted."""
    rows: dict[str, list[str]] = defaultdict(list)
    for chunk in rr.chunk.RrdReader(path).stream():
        if split_entity_path(chunk.entity_path)[:1] != ["runs"]:
            continue
        batch = chunk.to_record_batch()
        names = [name for name in batch.schema.names if "RowId" not in name]
        for row in batch.select(names).to_pylist():
            rows[chunk.entity_path].append(json.dumps([chunk.is_static, row], default=str))
    return {entity: sorted(values) for entity, values in rows.items()}


def record(directory: Path, runs: list, equations, batched: bool) -> list[Path]:
    """The runs' recordings as a sweep's worker writes them: a file a batch
    (:class:`RecordingBatch`), or a file a run (as before batches)."""
    directory.mkdir()
    batch = RecordingBatch(SweepRecorder, directory, "test")
    for spec, trajectory, series in runs:
        sink = batch.begin_run(spec)
        sink.log_run(spec, equations, None, trajectory, series)
        batch.logged(spec.run_id)
        if not batched:
            batch.write()
    batch.close()
    assert not journals(directory)  # gone with the worker's clean stop
    return sorted((directory / RECORDINGS_DIR).glob("*.rrd"))


def test_a_run_filling_its_batch_is_on_disk_before_its_row(tmp_path) -> None:
    """A run that fills its batch (a Dask worker's child: a run a file) has its file
    written when it is logged, before its row: a child killed between the two leaves no
    row without a recording (the run is redone), and needs no journal."""
    batch = RecordingBatch(SweepRecorder, tmp_path, "test", most=1)
    files = []
    for spec, trajectory, series in [fake_run(1e-3), fake_run(1e-4)]:
        batch.begin_run(spec).log_run(spec, fake_equations(), None, trajectory, series)
        batch.logged(spec.run_id)
        files = sorted((tmp_path / RECORDINGS_DIR).glob("*.rrd"))
        assert len(SweepRecorder().add_recording(files[-1])) == 1
        assert not journal_path(tmp_path, "test").exists()
    assert len(files) == 2


def test_a_batch_file_merges_to_the_recording_per_run_files_make(tmp_path) -> None:
    runs = [fake_run(10.0**-k) for k in range(3, 7)]
    per_run = record(tmp_path / "per-run", runs, fake_equations(), batched=False)
    batched = record(tmp_path / "batched", runs, fake_equations(), batched=True)
    assert len(per_run) == 4 and len(batched) == 1  # one file for the four runs
    merged = content(merge_recordings(per_run, tmp_path / "a.rrd"))
    assert sum(entity.endswith("/series") for entity in merged) == 4
    assert content(batched[0]) == merged
    assert content(merge_recordings(batched, tmp_path / "b.rrd")) == content(tmp_path / "a.rrd")


def test_a_robots_run_and_a_runs_second_copy_end_a_batch(tmp_path) -> None:
    """A file holds one run whose poses instance a shared mesh (a file's runs share one
    time grid) and one run a path (a file a run kept the first): the merge is unchanged."""
    from tests.test_recording_meshes import meshed_equations

    runs = [fake_run(1e-3, n=50), fake_run(1e-4, n=80), fake_run(1e-4, n=60)]
    equations = meshed_equations(tmp_path)
    per_run = record(tmp_path / "per-run", runs, equations, batched=False)
    batched = record(tmp_path / "batched", runs, equations, batched=True)
    assert len(batched) == 3
    merged = content(merge_recordings(batched, tmp_path / "b.rrd"))
    assert merged == content(merge_recordings(per_run, tmp_path / "a.rrd"))


class KillingRecorder(SweepRecorder):
    """Kills its worker (SIGKILL, as an operator would) the first time it would write a
    batch's file: after a run (the batch full or old enough) or as the worker stops,
    whichever comes first at the machine's load; the batch's rows are done."""

    def end_file(self):
        marker = Path(os.environ[KILL_MARKER])
        if not marker.exists():
            marker.touch()
            os.kill(os.getpid(), signal.SIGKILL)
        return super().end_file()


class KillingRecorderOfSingleRuns(KillingRecorder):
    """As :class:`KillingRecorder`, a file a run: killed at the second run's start (or at
    the end of a run), while the pool waits for that run."""

    def fits(self, spec) -> bool:
        return False


@pytest.mark.parametrize("recorder", [KillingRecorder, KillingRecorderOfSingleRuns])
def test_a_worker_killed_with_runs_unwritten_has_them_recorded_again(
    fake_plugins, tmp_path, monkeypatch, recorder
) -> None:
    text = spec_text(tmp_path, '["test-rk45"]', problems=FALLING).replace(
        "tolerances = [1e-4, 1e-6]", "tolerances = [1e-3, 1e-4, 1e-5, 1e-6]"
    )
    monkeypatch.setenv(KILL_MARKER, str(tmp_path / "killed"))
    summary = run_sweep(parse_spec(text), jobs=1, show_progress=False, recorder=recorder)
    assert (tmp_path / "killed").exists()  # a worker was killed with a batch unwritten
    assert summary.counts == {"ok": 4} and summary.unfinished == {}  # each run counted once
    assert len(SweepRecorder().add_recording(summary.recording)) == 4
    assert not list((tmp_path / RECORDINGS_DIR).iterdir())  # merged; no journal left


@pytest.mark.parametrize("recorder", [KillingRecorder, KillingRecorderOfSingleRuns])
def test_workbench_record_records_again_what_a_killed_worker_left_unwritten(
    fake_plugins, tmp_path, monkeypatch, recorder
) -> None:
    """``workbench record`` (a sweep run without a recording) counts a run recorded only
    once it is in a file: a worker killed before writing its batch has its runs recorded
    again, and every run is in the recording once."""
    from workbench.runs.record import record_runs

    text = spec_text(tmp_path, '["test-rk45"]', problems=FALLING).replace(
        "tolerances = [1e-4, 1e-6]", "tolerances = [1e-3, 1e-4, 1e-5, 1e-6]"
    )
    run_sweep(parse_spec(text), show_progress=False)  # rows, no recording
    monkeypatch.setenv(KILL_MARKER, str(tmp_path / "killed"))
    summary = record_runs(
        tmp_path, recorder, jobs=1, plugins=["tests.fake_plugins"], show_progress=False
    )
    assert (tmp_path / "killed").exists()  # a worker was killed with a batch unwritten
    assert summary.recorded == 4 and not summary.failed
    assert len(SweepRecorder().add_recording(summary.recording)) == 4
    assert not journals(tmp_path)


def test_a_resume_records_again_the_runs_a_killed_sweep_left_unwritten(
    fake_plugins, tmp_path
) -> None:
    """A sweep killed as a whole leaves its workers' journals: the next sweep records
    those runs again, their rows untouched, and says so in one line."""
    text = spec_text(tmp_path, '["test-rk45"]', problems=FALLING)
    run_sweep(parse_spec(text), show_progress=False)  # rows, no recording
    rows = {path.name: path.stat().st_mtime_ns for path in (tmp_path / "runs").glob("*.json")}
    run_ids = sorted(store.load_results(tmp_path)["run_id"])
    journal = journal_path(tmp_path, "killed-worker")  # as a worker killed before its batch
    journal.parent.mkdir()
    journal.write_text("".join(f"{run_id}\n" for run_id in run_ids))
    assert unwritten_runs(tmp_path) == set(run_ids)

    lines: list[str] = []
    summary = run_sweep(
        parse_spec(text), show_progress=False, say=lines.append, recorder=SweepRecorder
    )
    assert summary.already_done == 2 and summary.counts == {}
    assert any("2 done run(s) have no recording" in line for line in lines), lines
    assert len(SweepRecorder().add_recording(summary.recording)) == 2
    assert not journals(tmp_path)  # its runs are recorded now
    assert rows == {p.name: p.stat().st_mtime_ns for p in (tmp_path / "runs").glob("*.json")}


def test_a_batch_holding_many_values_is_written_before_the_next_run(tmp_path, monkeypatch):
    """A batch's runs stay in memory until its file is written: bounded by their values."""
    from workbench.outputs import recording

    sink = SweepRecorder()
    sink.begin_file(tmp_path / "batch.rrd")
    first, second = fake_run(1e-3, n=50), fake_run(1e-4, n=50)
    sink.log_run(first[0], fake_equations(), None, *first[1:])
    assert sink.fits(second[0])
    monkeypatch.setattr(recording, "FILE_VALUES_LIMIT", 50 * 6)  # the first run's series
    assert not sink.fits(second[0])


def test_a_journal_larger_than_a_batch_could_write_is_not_read(tmp_path) -> None:
    """A results folder from elsewhere may hold any file: a huge "journal" lists nothing
    (it is not read into memory), a real one its runs."""
    from workbench.runs.recording_batches import JOURNAL_MAX_BYTES, listed_runs

    (tmp_path / RECORDINGS_DIR).mkdir()
    real = journal_path(tmp_path, "a")
    real.write_text("0123456789abcdef\nfedcba9876543210\n")
    huge = journal_path(tmp_path, "b")
    huge.write_bytes(b"0123456789abcdef\n" * (JOURNAL_MAX_BYTES // 17 + 2))
    assert listed_runs([real]) == {"0123456789abcdef", "fedcba9876543210"}
    assert listed_runs([huge]) == set()
