"""One command at a time on an output folder (issue 31.4): a second sweep (or report) on a
busy OUT names the process holding it and exits 2, or waits with --wait; the lock of a
SIGKILLed sweep is taken over at once, saying whose it was; two sweeps started together
with --wait do each run once."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from tests.test_sweep import spec_text
from workbench.runs import store
from workbench.runs.out_lock import LOCK_FILE

REPO = Path(__file__).resolve().parents[1]
HANG = 600  # s: only a hung process takes this long


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "workbench", *args],
        cwd=REPO,
        env=dict(os.environ, COLUMNS="200", NO_COLOR="1"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group: killed with its workers
    )


def finish(process: subprocess.Popen) -> tuple[int, str, str]:
    stdout, stderr = process.communicate(timeout=HANG)
    return process.returncode, stdout, stderr


def write_spec(tmp_path: Path, name: str, out: Path, integrators: str) -> Path:
    spec = tmp_path / f"{name}.toml"
    spec.write_text(spec_text(out, integrators))
    return spec


def wait_for_holder(out: Path, process: subprocess.Popen) -> dict:
    """The holder record ``process`` wrote into OUT's lock file once it holds it."""
    deadline = time.monotonic() + HANG
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()
        try:
            text = (out / LOCK_FILE).read_text()
        except FileNotFoundError:
            text = ""
        if text.strip():
            return json.loads(text)
        time.sleep(0.05)
    raise AssertionError("the sweep never took the lock")


def test_a_busy_out_names_its_holder_and_a_killed_holders_lock_is_taken_over(
    tmp_path,
) -> None:
    out = tmp_path / "out"
    hung = write_spec(tmp_path, "hung", out, '["test-hang"]')  # busy until killed
    quick = write_spec(tmp_path, "quick", out, '["test-rk45"]')
    holder = start("sweep", str(hung))
    try:
        record = wait_for_holder(out, holder)
        assert record["pid"] == holder.pid and record["host"] == socket.gethostname()
        for command in (["sweep", str(quick)], ["report", str(out)]):
            code, _, stderr = finish(start(*command))
            assert code == 2, stderr
            # besides the line naming the local plugin module the spec imports
            (line,) = [x for x in stderr.strip().splitlines() if not x.startswith("plugins: ")]
            assert line.startswith("error: ") and "Traceback" not in stderr
            assert f"is in use by pid {holder.pid} on host {socket.gethostname()}" in line
            assert "workbench sweep" in line and record["started"] in line and "--wait" in line
        waiting = start("sweep", str(quick), "--wait", "--no-report")
        deadline = time.monotonic() + HANG
        while "waiting for" not in (line := waiting.stdout.readline()):
            assert line and time.monotonic() < deadline, finish(waiting)
        assert f"in use by pid {holder.pid}" in line
    finally:
        os.killpg(holder.pid, signal.SIGKILL)  # as the OOM killer would: no clean-up runs
        holder.wait()
    code, stdout, stderr = finish(waiting)
    assert code == 0, stderr
    assert f"taking over the lock of {out} left by pid {holder.pid}" in stdout
    assert "no longer running" in stdout
    assert len(store.load_results(out)) == 2
    code, stdout, stderr = finish(start("sweep", str(quick), "--no-report"))  # released: no notice
    assert code == 0 and "taking over" not in stdout + stderr, stderr
    assert (out / LOCK_FILE).read_text() == ""


def test_two_sweeps_started_together_with_wait_run_each_run_once(tmp_path) -> None:
    out = tmp_path / "out"
    spec = write_spec(tmp_path, "spec", out, '["test-rk45", "test-rk4"]')
    # the rows are the subject, not the report (8 s of CPU each)
    first = start("sweep", str(spec), "--wait", "--no-report")
    second = start("sweep", str(spec), "--wait", "--no-report")
    results = [finish(first), finish(second)]
    assert [code for code, _, _ in results] == [0, 0], results
    summaries = [
        line for _, stdout, _ in results for line in stdout.splitlines() if " runs in " in line
    ]
    # one of them ran the 4 runs, the other found them done (the old code ran 8)
    assert sorted(summary.split(";")[1].strip() for summary in summaries) == [
        "0 already done",
        "4 already done",
    ], summaries
    assert len(store.load_results(out)) == 4
