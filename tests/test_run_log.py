"""A run's stdout and stderr (C libraries' too) go to a bounded per-run log named in its
row, never to the sweep's terminal (issue 18.16: 125 MB from one plugin reached it)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from workbench.execution.execute import RunSpec, normalized_spec
from workbench.execution.run_log import (
    KEEP_BYTES,
    LOG_TEXT,
    CapturedOutput,
    bounded,
    raw_path,
    salvage_log,
    store_log,
)
from workbench.runs import store

ROOT = Path(__file__).resolve().parents[1]
# what tests/noisy_plugins.py's test-noisy writes first and last (not imported here:
# importing it registers its plugins in this process's registry)
FIRST_LINE = "noisy plugin: first line"
LAST_LINE = "noisy plugin: last line"
LOG_LIMIT = 2 * KEEP_BYTES + 200  # head, tail and the line saying what was left out


def check_noisy_log(path: Path) -> None:
    data = path.read_bytes()
    assert len(data) <= LOG_LIMIT
    text = data.decode()
    assert text.startswith(FIRST_LINE + "\n")
    assert text.rstrip().endswith(LAST_LINE)
    assert "bytes of output left out" in text


def test_local_pool_keeps_a_bounded_log_per_run(tmp_path) -> None:
    out = tmp_path / "out"
    spec = tmp_path / "sweep.toml"
    spec.write_text(
        f'out = "{out.as_posix()}"\njobs = 1\ntime_limit = 300.0\n'
        'plugins = ["tests.noisy_plugins"]\nproblems = ["test-nan-force"]\n'
        'formalisms = [{ name = "minimal-ode", options = { index = [1] } }]\n'
        'integrators = ["test-noisy", "casadi-idas"]\ntolerances = [1e-6]\n'
    )
    result = subprocess.run(
        [sys.executable, "-m", "workbench", "sweep", "--no-report", str(spec)],
        cwd=ROOT, capture_output=True, timeout=900,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-2000:]
    # the 50 MB and IDA's complaint stayed out of the sweep's own output
    assert len(result.stdout) + len(result.stderr) < 64 * 1024
    assert b"xxxxxxxx" not in result.stdout + result.stderr
    assert b"mxstep" not in result.stdout + result.stderr
    rows = store.load_results(out).set_index("integrator")
    noisy = rows.loc["test-noisy"]
    assert noisy["log"] == f"logs/{noisy['run_id']}.log"
    check_noisy_log(out / noisy["log"])
    ida = rows.loc["casadi-idas"]  # a real IDA failure: its C-level message is in the log
    assert ida["status"] == "failed" and "t = 0.5" in ida["message"]
    ida_log = (out / ida["log"]).read_text()
    assert "mxstep steps taken before reaching tout" in ida_log
    assert not list((out / "logs").glob(".*.raw"))  # the whole output is not kept


def test_a_run_in_a_child_process_returns_its_bounded_log(tmp_path) -> None:
    import tests.noisy_plugins  # noqa: F401 - normalized_spec needs the problem here too
    from workbench.runs.dask_pool import run_in_subprocess

    spec = normalized_spec(
        RunSpec("test-nan-force", "minimal-ode", "test-noisy", 1e-6, 1e-9, {}, {"index": 1}, {})
    )
    paths = [str(ROOT), *sys.path]
    row, _ = run_in_subprocess(spec.to_dict(), 300.0, ["tests.noisy_plugins"], "", paths)
    assert len(row[LOG_TEXT].encode()) <= LOG_LIMIT  # bounded before it left the child
    store_log(tmp_path, row)
    assert LOG_TEXT not in row
    check_noisy_log(tmp_path / row["log"])


def test_bounded_keeps_short_output_whole_and_long_output_head_and_tail(tmp_path) -> None:
    short = tmp_path / "short"
    short.write_bytes(b"a" * 10)
    assert bounded(short, keep=8) == b"a" * 10
    long = tmp_path / "long"
    long.write_bytes(b"H" * 8 + b"m" * 100 + b"T" * 8)
    kept = bounded(long, keep=8)
    assert kept.startswith(b"H" * 8 + b"\n[... 100 bytes") and kept.endswith(b"]\n" + b"T" * 8)


def test_the_raw_file_is_emptied_past_its_limit_keeping_head_and_tail(tmp_path) -> None:
    raw = tmp_path / "raw"
    # the test empties the file itself (no timing): a watcher that never wakes
    capture = CapturedOutput(raw, keep=100, raw_limit=1000, interval=3600.0)
    written = b""
    with capture:
        for i in range(400):
            line = f"line {i:05d}\n".encode()
            os.write(1 if i % 2 else 2, line)  # as C code writes, to both descriptors
            written += line
            if i % 150 == 149:
                assert raw.stat().st_size == 150 * len(line)  # what came since the last
                capture._empty()
    kept = capture.kept()
    omitted = len(written) - 200
    assert (
        kept
        == written[:100]
        + f"\n[... {omitted} bytes of output left out ...]\n".encode()
        + (written[-100:])
    )
    assert not raw.exists()


def test_a_killed_runs_raw_output_becomes_its_log(tmp_path) -> None:
    raw = raw_path(tmp_path, "abc")
    raw.parent.mkdir()
    raw.write_bytes(b"A" * KEEP_BYTES + b"B" * 10 + b"C" * KEEP_BYTES)
    assert salvage_log(tmp_path, "abc") == "logs/abc.log"
    assert (tmp_path / "logs" / "abc.log").read_bytes() == (
        b"A" * KEEP_BYTES + b"\n[... 10 bytes of output left out ...]\n" + b"C" * KEEP_BYTES
    )
    assert not raw.exists() and salvage_log(tmp_path, "none") == ""


def test_a_run_killed_at_its_time_limit_keeps_what_it_printed(tmp_path) -> None:
    out = tmp_path / "out"
    spec = tmp_path / "sweep.toml"
    spec.write_text(
        f'out = "{out.as_posix()}"\njobs = 1\ntime_limit = 10.0  # only the hung run reaches it\n'
        'plugins = ["tests.noisy_plugins"]\nproblems = ["test-nan-force"]\n'
        'formalisms = [{ name = "minimal-ode", options = { index = [1] } }]\n'
        'integrators = ["test-noisy-hang"]\ntolerances = [1e-6]\n'
    )
    result = subprocess.run(
        [sys.executable, "-m", "workbench", "sweep", "--no-report", str(spec)],
        cwd=ROOT, capture_output=True, timeout=900,
    )  # fmt: skip
    assert b"about to hang" not in result.stdout + result.stderr
    row = store.load_results(out).iloc[0]
    assert row["status"] == "timeout"
    assert (out / row["log"]).read_text() == "about to hang\n"
    assert not list((out / "logs").glob(".*.raw"))
