"""A sweep's merged recording reads back (issue 35.3): Rerun's own check (``rerun rrd
verify``) passes, and Python's reader reads it whole within 2x its size in memory."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import rerun as rr

from workbench.cli.outputs import rerun_command
from workbench.outputs.recording import RECORDING_FILE, SweepRecorder, merge_recordings
from workbench.runs.sweep import parse_spec, run_sweep

SPEC = (
    'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
    'integrators = ["scipy-dop853", "scipy-rk45"]\ntolerances = [1e-4, 1e-6]\n'
)


def test_a_sweeps_recording_passes_rerun_rrd_verify(tmp_path: Path) -> None:
    rerun = rerun_command(shutil.which)
    try:
        usable = subprocess.run([*rerun, "--version"], capture_output=True, timeout=300)
    except OSError as error:
        pytest.skip(f"no rerun command ({error})")
    if usable.returncode != 0:
        pytest.skip("the rerun command of rerun-sdk does not start here")
    summary = run_sweep(
        parse_spec(SPEC), out=tmp_path / "out", show_progress=False, recorder=SweepRecorder
    )
    assert summary.counts["ok"] == 4 and summary.recording == tmp_path / "out" / RECORDING_FILE
    verified = subprocess.run(
        [*rerun, "rrd", "verify", str(summary.recording)], capture_output=True, text=True,
        timeout=600,
    )  # fmt: skip
    assert verified.returncode == 0, verified.stdout + verified.stderr


READ_CHILD = """
import json, sys
from pathlib import Path
import rerun as rr

def status(field):
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024

def read(path):  # a chunk at a time, as the merge reads; and the anonymous memory at
    reader = rr.chunk.RrdReader(path)  # its end, the reader (its manifest) still held
    return sum(chunk.to_record_batch().num_rows for chunk in reader.stream()), status("RssAnon")

Path("/proc/self/clear_refs").write_text("5")  # the peak restarts here
start = startup_end = status("VmRSS")
anon_start = status("RssAnon")
startup = 0
if len(sys.argv) > 2:  # a one-chunk recording first: the reader's start-up, whatever the file
    read(sys.argv[2])
    startup, startup_end = status("VmHWM") - start, status("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")
rows, anon_end = read(sys.argv[1])
peak = status("VmHWM")
print(json.dumps({"growth": max(startup, peak - start), "startup": startup,
                  "beyond_startup": peak - startup_end, "anon": anon_end - anon_start,
                  "rows": rows}))
"""


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="Linux's peak RSS")
def test_pythons_reader_reads_a_merged_recording_within_twice_its_size(tmp_path: Path) -> None:
    from benchmarks.footprint import write_run_recordings

    files = write_run_recordings(tmp_path, 300)  # about 20 MB merged (7 MiB of growth is fixed)
    merged = merge_recordings(files, tmp_path / "merged.rrd")  # with its footer (manifest)
    assert rr.chunk.RrdReader(merged).store() is not None  # which only a footer allows
    child = tmp_path / "read.py"
    child.write_text(READ_CHILD)
    done = subprocess.run(
        [sys.executable, str(child), str(merged)], capture_output=True, text=True, timeout=600,
        check=True,
    )  # fmt: skip
    measured = json.loads(done.stdout.strip().splitlines()[-1])
    assert measured["rows"] > 300 * 200  # every run's poses at least: it read it all
    assert measured["growth"] < 2 * merged.stat().st_size, measured
