"""Merging the per-run recordings of a sweep (issue 35.2): the merged file holds every run's
chunks, and the merge's memory does not grow with the number of runs."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
import rerun as rr

from tests.test_recording import _args, fake_run
from workbench.outputs.recording import RerunSink, merge_recordings, split_entity_path


def write_runs(directory: Path, n: int) -> list[Path]:
    """``n`` per-run recordings as a sweep's worker writes them (one sink, a file a run)."""
    sink, files = RerunSink(), []
    for index in range(n):
        sink.begin_file(directory / f"run{index:04d}.rrd")
        sink.log_run(*_args(fake_run(10 ** (-3 - 6 * index / n), n=1000)))
        files.append(sink.end_file())
    return files


def run_chunks(path: Path) -> Counter:
    """(entity path, rows) of each chunk of a run (recording properties left out)."""
    return Counter(
        (chunk.entity_path, chunk.num_rows)
        for chunk in rr.chunk.RrdReader(path).stream().to_chunks()
        if split_entity_path(chunk.entity_path)[:1] == ["runs"]
    )


def test_the_merged_recording_holds_every_runs_chunks(tmp_path) -> None:
    files = write_runs(tmp_path, 5)
    merged = merge_recordings(files, tmp_path / "merged.rrd")
    expected = sum((run_chunks(file) for file in files), Counter())
    # the problem's view coordinates, logged by every run, are kept once
    expected[("/runs/fake-problem", 1)] = 1
    expected[("/runs/fake-problem/model/ground/joints", 1)] = 1  # and the ground's frames
    assert run_chunks(merged) == expected
    assert len({path for path, _ in expected if path.endswith("/series")}) == 5
    assert rr.chunk.RrdReader(merged).blueprints()  # the blueprint joins at the end
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [f.name for f in files] + ["merged.rrd"]
    )  # no temporary file left


def test_a_merge_on_a_full_disk_is_an_oserror_and_leaves_nothing(tmp_path, monkeypatch) -> None:
    import errno
    import shutil
    from collections import namedtuple

    files = write_runs(tmp_path, 2)
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**9, 10**9, 1000))
    with pytest.raises(OSError) as raised:
        merge_recordings(files, tmp_path / "merged.rrd")
    assert raised.value.errno == errno.ENOSPC and "MiB needed to merge" in str(raised.value)
    assert not (tmp_path / "merged.rrd").exists() and len(list(tmp_path.iterdir())) == 2


MERGE_CHILD = """
import json, sys
from pathlib import Path
import rerun
from workbench.outputs import recording
from workbench.outputs.recording import merge_recordings

recording.FOOTER_INPUT_LIMIT = int(sys.argv[3])  # a footer's manifest is held to the end
# chunks not yet written wait in memory until the next flush, as many as the file sink's
# writer thread is behind (on a loaded machine, all of them): flushed every 1 MiB of inputs
# (about 9 runs), that is bounded whatever the load, far below the 150 runs' bytes
recording.FLUSH_BYTES = 2**20

def status(field):
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024

files = sorted(Path(sys.argv[1]).glob("run*.rrd"))[: int(sys.argv[2])]
Path("/proc/self/clear_refs").write_text("5")  # the peak restarts here
start = status("VmRSS")
merge_recordings(files, Path(sys.argv[1]) / "merged.rrd")
print(json.dumps({"growth": status("VmHWM") - start,
                  "inputs": sum(f.stat().st_size for f in files)}))
"""


@pytest.mark.skipif(
    not Path("/proc/self/clear_refs").exists(), reason="measures the peak RSS of Linux"
)
def test_the_merge_memory_does_not_grow_with_the_runs(tmp_path) -> None:
    """The peak memory of a merge of 200 runs exceeds that of 50 by far less than the
    150 runs' bytes (the merge that kept every chunk until the end grew by about 4x them).

    At the default flush interval (16 MiB of inputs, two thirds of the 200 runs' 23 MB)
    the peak measured the chunks waiting for a flush: 0.1x the 150 runs' bytes on an idle
    machine, 1.5x beside 3 busy loops (load 6), when the sink's writer thread falls behind.
    The merge flushes every 1 MiB here, so the runs, not the flush interval, would show."""
    write_runs(tmp_path, 200)

    def merge(n: int, footer_limit: int = 0) -> dict[str, int]:
        command = [sys.executable, "-c", MERGE_CHILD, str(tmp_path), str(n), str(footer_limit)]
        done = subprocess.run(command, capture_output=True, text=True, check=True, timeout=600)
        return json.loads(done.stdout.strip().splitlines()[-1])

    few, many = merge(50), merge(200)
    assert many["inputs"] > 3.5 * few["inputs"]
    assert many["growth"] - few["growth"] < 0.5 * (many["inputs"] - few["inputs"]), (few, many)
    # with a footer (small merges) the manifest grows with the chunks: about 2.8x the
    # inputs (a run's series in one chunk: fewer bytes, about the same manifest)
    footer = merge(200, footer_limit=2**40)
    assert footer["growth"] < 3.2 * footer["inputs"], footer


def write_old_layout(path: Path, rtol: str) -> str:
    """A recording as written before 2026-11-27 (an entity a body: its Transform3D on
    sim_time and its shapes static; its joint frames an entity below it), by Rerun's own
    calls; returns the run's path."""
    run = f"runs/fake-problem/minimal-ode/radau/rtol\\={rtol}"
    stream = rr.RecordingStream("mbs-workbench", recording_id="old")
    stream.save(path)
    stream.log("runs/fake-problem", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    stream.log(f"{run}/bodies/arm", rr.Boxes3D(half_sizes=[[0.5, 0.05, 0.05]]), static=True)
    stream.log(f"{run}/bodies/arm/joints", rr.TransformAxes3D(0.3),
               rr.InstancePoses3D(translations=[[1.0, 0, 0]]), static=True)  # fmt: skip
    times = rr.TimeColumn("sim_time", duration=[0.0, 1.0])
    poses = rr.Transform3D.columns(translation=[[0, 0, 0], [1, 0, 0]])
    stream.send_columns(f"{run}/bodies/arm", indexes=[times], columns=poses)
    stream.log(f"{run}/series", rr.SeriesLines(names=["old"] * 6), static=True)
    stream.send_columns(f"{run}/series", indexes=[times],
                        columns=rr.Scalars.columns(scalars=[[1e-9] * 6, [2e-9] * 6]))  # fmt: skip
    stream.flush()
    stream.disconnect()
    return run


def test_a_recording_written_before_still_merges_and_extracts(tmp_path) -> None:
    """A sweep's recording.rrd of the old layout (an entity a body) merges with runs of
    the new one (an entity a shape kind), both runs in the merged file and its plots,
    and either run extracts as it was written."""
    from workbench.outputs.recording import extract_run

    old_run = write_old_layout(tmp_path / "recording.rrd", "0.1")
    sink = RerunSink()
    sink.begin_file(tmp_path / "new.rrd")
    new_run = sink.log_run(*_args(fake_run(1e-6)))
    merged = merge_recordings([sink.end_file()], tmp_path / "recording.rrd", keep_existing=True)
    paths = {chunk.entity_path for chunk in rr.chunk.RrdReader(merged).stream()}
    assert {f"/{old_run}/bodies/arm", f"/{old_run}/bodies/arm/joints", f"/{old_run}/series",
            f"/{new_run}/boxes", f"/{new_run}/joints", f"/{new_run}/series"} <= paths  # fmt: skip
    reader = rr.chunk.RrdReader(merged)
    queries = {
        value
        for chunk in reader.stream(store=reader.blueprints()[0])
        for name, values in chunk.to_record_batch().to_pydict().items()
        if name.endswith(":query")
        for batch in values
        if batch
        for value in batch
    }
    assert {f"+ /{old_run}/series", f"+ /{new_run}/series"} <= queries  # both plotted
    for run, entity in ((old_run, "bodies/arm"), (new_run, "boxes")):
        extracted = extract_run(merged, run, tmp_path / f"{entity.replace('/', '-')}.rrd")
        own = {chunk.entity_path for chunk in rr.chunk.RrdReader(extracted).stream()}
        assert f"/{run}/{entity}" in own and f"/{run}/series" in own
        assert not any(path.startswith(f"/{other}/") for other in (old_run, new_run)
                       if other != run for path in own)  # fmt: skip
