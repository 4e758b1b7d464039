"""Faults end in one honest line with nothing lost (issue 18 items 2, 7, 11, 12; 22.8-10).

Full disk (a real tmpfs when this machine lets us mount one, and an ENOSPC injected at our
own file-writing boundary), OS errors at the command line, Ctrl-C and a killed parent,
stale temporary files, permissions under the umask. Every time bound here is one only a
hung process reaches.
"""

from __future__ import annotations

import errno
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from workbench import files
from workbench.outputs import recording as recording_module
from workbench.outputs.recording import RECORDING_FILE, SweepRecorder
from workbench.runs.sweep import parse_spec, run_sweep

REPO = Path(__file__).resolve().parents[1]
HANG = 600  # s: only a hung process takes this long
SPEC = (
    'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
    'integrators = ["scipy-dop853"]\ntolerances = [1e-4, 1e-6]\n'
)


def workbench(*args: str, **kwargs) -> subprocess.CompletedProcess:
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    return subprocess.run(
        [sys.executable, "-m", "workbench", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=HANG,
        **kwargs,
    )


def one_error_line(stderr: str) -> str:
    """The one error line, last on stderr (after any plain progress lines)."""
    lines = stderr.strip().splitlines()
    errors = [line for line in lines if line.startswith("error: ")]
    assert errors == lines[-1:], stderr
    assert "Traceback" not in stderr
    return lines[-1]


def snapshot(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.glob("*.json"))}


def temporaries(directory: Path) -> list[Path]:
    return [p for p in directory.rglob(".*.tmp")]


def recorded_runs(out: Path) -> int:
    """Runs in the recordings' files a sweep's workers left in ``out`` (a file a batch)."""
    files = (out / "recordings").glob("*.rrd")
    return sum(len(SweepRecorder().add_recording(file)) for file in files)


# -- a full disk -------------------------------------------------------------------------
def test_enospc_while_merging_the_recording_is_raised_and_resume_finishes_it(
    tmp_path, monkeypatch
) -> None:
    """ENOSPC injected in the writer of workbench.files.atomic_write: the sweep raises it
    (the CLI makes it one line) instead of hiding it, the rows and the runs' own
    recordings stay, no temporary is left; the next sweep, with room, merges them."""
    sweep = parse_spec(SPEC)
    out = tmp_path / "out"
    real_atomic_write = files.atomic_write

    def full_disk(path, write, durable=True):
        def half_then_enospc(temporary: str) -> None:
            Path(temporary).write_bytes(b"\0" * 1000)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), temporary)

        merge = Path(path).name == RECORDING_FILE  # the runs' own files are written
        real_atomic_write(path, half_then_enospc if merge else write, durable)

    monkeypatch.setattr(recording_module, "atomic_write", full_disk)
    with pytest.raises(OSError) as raised:
        run_sweep(sweep, out=out, show_progress=False, recorder=SweepRecorder)
    assert raised.value.errno == errno.ENOSPC
    assert len(snapshot(out / "runs")) == 2 and recorded_runs(out) == 2
    assert not (out / RECORDING_FILE).exists() and temporaries(out) == []

    monkeypatch.setattr(recording_module, "atomic_write", real_atomic_write)
    again = run_sweep(sweep, out=out, show_progress=False, recorder=SweepRecorder)
    assert again.already_done == 2 and again.recording == out / RECORDING_FILE
    assert len(SweepRecorder().add_recording(again.recording)) == 2
    assert list((out / "recordings").iterdir()) == []  # merged: one copy on disk


@pytest.fixture
def small_disk(tmp_path):
    """A 4 MB tmpfs (needs the right to mount: root in a container that allows it)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    try:
        mounted = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(disk)],
            capture_output=True,
            text=True,
            timeout=60,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        pytest.skip(f"cannot run mount: {error}")
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True, timeout=60)


def fill(disk: Path, leave: int) -> Path:
    """Fill ``disk`` to the last byte, then free about ``leave`` bytes."""
    filler = disk / "filler"
    with open(filler, "wb", buffering=0) as handle:  # unbuffered: the bytes a full disk
        try:  # refused are not written again (and refused again) when the file closes
            while True:
                handle.write(b"\0" * 65536)
        except OSError as error:
            assert error.errno == errno.ENOSPC
    os.truncate(filler, max(0, filler.stat().st_size - leave))
    return filler


def test_a_full_disk_ends_the_sweep_with_one_line_and_resume_finishes(small_disk) -> None:
    """The tester's scenario on a real file system: Rerun's file sink blocked > 600 s on
    ENOSPC; now one line, exit 2, rows intact, and with room again the recording is made
    and a stale temporary file of the crashed writer is gone."""
    spec = small_disk.parent / "sweep.toml"
    spec.write_text(SPEC)
    out = small_disk / "out"
    done = workbench("sweep", str(spec), "--out", str(out), "--no-report")
    assert done.returncode == 0, done.stderr
    merged = (out / RECORDING_FILE).read_bytes()
    # room for the redone runs' rows and recordings, not for a merge (check_free_space)
    filler = fill(small_disk, leave=400_000)

    full = workbench("sweep", str(spec), "--out", str(out), "--fresh")
    assert full.returncode == 2
    line = one_error_line(full.stderr)
    assert "No space left on device" in line and str(out) in line
    assert len(snapshot(out / "runs")) == 2 and recorded_runs(out) == 2
    assert (out / RECORDING_FILE).read_bytes() == merged and temporaries(out) == []

    filler.unlink()
    stale = out / f".{RECORDING_FILE}.12345-deadbeef.tmp"  # a writer killed mid-write
    stale.write_bytes(b"half a recording")
    resumed = workbench("sweep", str(spec), "--out", str(out), "--no-report")
    assert resumed.returncode == 0, resumed.stderr
    assert "2 already done" in resumed.stdout
    assert len(SweepRecorder().add_recording(out / RECORDING_FILE)) == 2
    assert temporaries(out) == [] and list((out / "recordings").iterdir()) == []


# -- OS errors at the command line -----------------------------------------------------
@pytest.mark.parametrize("where", ["/dev/null", "/proc/workbench-x", "file/below"])
def test_an_unusable_out_is_one_line_and_exit_2(tmp_path, where) -> None:
    spec = tmp_path / "sweep.toml"
    spec.write_text(SPEC)
    (tmp_path / "file").write_text("a file where a directory is expected")
    out = where if where.startswith("/") else str(tmp_path / where)
    result = workbench("sweep", str(spec), "--out", out)
    assert result.returncode == 2
    one_error_line(result.stderr)
    assert (tmp_path / "file").read_text() == "a file where a directory is expected"


@pytest.fixture
def not_dask():
    """A plain TCP service on 127.0.0.1 that answers every connection with HTTP."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except TimeoutError:
                continue
            with connection:
                connection.sendall(b"HTTP/1.0 400 Bad Request\r\n\r\nnot a dask scheduler")

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join()
    server.close()


def test_a_service_that_is_not_dask_is_one_line_and_exit_2(tmp_path, not_dask) -> None:
    spec = tmp_path / "sweep.toml"
    spec.write_text(SPEC)
    result = workbench("sweep", str(spec), "--out", str(tmp_path / "out"), "--scheduler", not_dask)
    assert result.returncode == 2
    assert "cannot connect to the Dask scheduler" in one_error_line(result.stderr)


# -- Ctrl-C and a killed parent --------------------------------------------------------
def test_ctrl_c_during_a_sweep_is_one_line_saying_what_was_kept(tmp_path) -> None:
    spec = tmp_path / "sweep.toml"
    spec.write_text(
        'problems = ["simple-pendulum", "double-pendulum", "slider-crank"]\n'
        'formalisms = ["minimal-ode"]\nintegrators = ["scipy-dop853"]\n'
        "tolerances = [1e-4, 1e-6, 1e-8, 1e-10]\n"
    )
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "workbench", "sweep", str(spec), "--out", str(out), "-j", "2"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group: Ctrl-C goes to the whole group
    )
    deadline = time.monotonic() + HANG
    while not list((out / "runs").glob("*.json")) and time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGINT)
    _stdout, stderr = process.communicate(timeout=HANG)
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("interrupted: ") and "again to resume" in last, stderr
    assert [line for line in stderr.splitlines() if line.startswith("interrupted")] == [last]
    kept = len(list((out / "runs").glob("*.json")))
    assert f"{kept} of 12 runs are kept in {out}" in last


EARLY_KILL_SCRIPT = """
import os, signal, sys, time
from workbench.outputs.report.pool import figure_executor
pool = figure_executor(2)
for _ in range(2):  # a pool starts its workers on demand: one a waiting task
    pool.submit(time.sleep, 3600)
while len(pool._processes) < 2:
    time.sleep(0.001)
print(*pool._processes, flush=True)
os.kill(os.getpid(), signal.SIGKILL)  # before the spawned workers have even imported
"""

POOL_SCRIPT = """
import sys, time
from workbench.outputs.report.pool import figure_executor
with figure_executor(2) as pool:
    futures = [pool.submit(time.sleep, 3600) for _ in range(2)]
    while len(pool._processes) < 2:
        time.sleep(0.05)
    time.sleep(3)  # the workers have imported and picked up their tasks
    print(*pool._processes, flush=True)
    futures[0].result()
"""


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie (dead, not yet reaped by init) counts as gone
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def launch(script: str) -> subprocess.Popen:
    """``python -c script`` in its own session, its stdout and stderr piped."""
    return subprocess.Popen(
        [sys.executable, "-c", script],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def start_pool() -> tuple[subprocess.Popen, list[int]]:
    process = launch(POOL_SCRIPT)
    line = process.stdout.readline()
    assert line.strip(), process.communicate(timeout=HANG)
    return process, [int(pid) for pid in line.split()]


def test_report_workers_die_with_their_parent() -> None:
    process, workers = start_pool()
    assert all(alive(pid) for pid in workers)
    process.kill()  # SIGKILL: no cleanup code of the parent runs
    process.wait(timeout=HANG)
    assert_no_orphans(workers)  # they wait on their parent's sentinel pipe


def test_report_workers_started_after_their_parent_died_exit() -> None:
    """A parent killed while its workers are still starting (seconds of imports on a
    loaded machine): they must not take init, their new parent, for theirs."""
    process = launch(EARLY_KILL_SCRIPT)
    workers = [int(pid) for pid in process.stdout.readline().split()]  # the workers keep
    process.wait(timeout=HANG)  # the pipe open while they live: no communicate()
    assert process.returncode == -signal.SIGKILL
    assert len(workers) == 2
    assert_no_orphans(workers)


def assert_no_orphans(workers: list[int]) -> None:
    """Every pid in ``workers`` exits (polled every 0.1 s; survivors are killed)."""
    deadline = time.monotonic() + HANG  # only a worker that never exits reaches it
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    orphans = [pid for pid in workers if alive(pid)]
    for pid in orphans:
        os.kill(pid, signal.SIGKILL)
    assert orphans == []


def test_ctrl_c_reaches_no_report_worker_and_stops_them() -> None:
    process, workers = start_pool()
    os.killpg(process.pid, signal.SIGINT)  # what the terminal does on Ctrl-C
    _stdout, stderr = process.communicate(timeout=HANG)
    assert stderr.count("Traceback") == 1  # the parent's own KeyboardInterrupt, no worker's
    assert "KeyboardInterrupt" in stderr and "_process_worker" not in stderr
    deadline = time.monotonic() + HANG
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(pid) for pid in workers)


# -- permissions -----------------------------------------------------------------------
@pytest.mark.parametrize("umask", [0o022, 0o027, 0o077])
def test_atomic_files_respect_the_umask(tmp_path, umask) -> None:
    old = os.umask(umask)
    try:
        files.atomic_write(tmp_path / "row.json", lambda name: Path(name).write_text("{}"))
    finally:
        os.umask(old)
    assert (tmp_path / "row.json").stat().st_mode & 0o777 == 0o666 & ~umask


@pytest.mark.parametrize(
    ("address", "said"),
    [
        ("notaurl", "missing port number"),
        ("tcp://host-without-port", "missing port number"),
        ("tcp://127.0.0.1:99999", "port 99999 is not a TCP port"),  # waited 10 s for it
        ("", "an empty address"),  # ran on the local pool
    ],
)
def test_a_scheduler_address_dask_cannot_read_is_one_line_before_out_is_made(
    tmp_path, address, said
) -> None:
    """Not an address (no port): exit 2 naming it, and OUT untouched (it used to get the
    plan, the logs and the spec before the connection failed)."""
    spec = tmp_path / "sweep.toml"
    spec.write_text(SPEC)
    result = workbench("sweep", str(spec), "--out", str(tmp_path / "out"), "--scheduler", address)
    assert result.returncode == 2
    line = one_error_line(result.stderr)
    assert f"--scheduler {address!r}: {said}" in line and "tcp://host:port" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("address", "said"),
    [
        ("tcp://host-without-port", "missing port number"),
        ("tcp://127.0.0.1:99999", "port 99999 is not a TCP port"),
        ("", "an empty address (the local pool is used with scheduler=None)"),  # ran locally
    ],
)
def test_the_python_api_names_its_scheduler_argument_not_the_clis_option(
    tmp_path, address, said
) -> None:
    """``workbench.sweep(..., scheduler=ADDRESS)`` said "--scheduler", an option its caller
    never gave; as the CLI, it says so before ``out`` is made."""
    import workbench as wb
    from workbench.errors import ConfigError

    spec = tmp_path / "sweep.toml"
    spec.write_text(SPEC)
    with pytest.raises(ConfigError) as raised:
        wb.sweep(spec, out=tmp_path / "out", scheduler=address)
    message = str(raised.value)
    assert message.startswith(f"scheduler={address!r}: {said}") and "tcp://host:port" in message
    assert "--scheduler" not in message
    assert not (tmp_path / "out").exists()
