"""Torture test of the sweep's crash safety and input handling (issue 18), with fixed seeds.

Run: ``python -m benchmarks.torture [--quick] [--only kills,disk,fuzz]``. Needs the test
extra (the fuzzers live in ``tests/fuzz_inputs.py``); the disk experiments need root (they
mount small tmpfs file systems) and are reported "not run" without it.

What it does, each against an uninterrupted sweep of the same spec (48 short runs of real
catalog problems through two formalisms and two integrators):

- **kills**: SIGKILL of the sweep's parent process alone, of its whole process group, of
  one local worker, of one Dask worker and of the Dask scheduler, at a seeded moment (after
  k rows), then ``workbench sweep`` again (resume) until it exits 0. Counted: rows lost,
  duplicated or corrupted (a row or series that does not load), rows that differ from the
  uninterrupted sweep (every column but timings), tracebacks printed, hangs, and worker
  processes left alive after their parent was killed; for the local kills also the runs
  the uninterrupted sweep's recording holds and the resumed sweep's does not.
- **disk**: a sweep into a 6 MB tmpfs (full disk: the rows fit, the recording does not),
  then resumed after the file system is grown; a sweep into a read-only OUT that holds
  earlier results (files hashed before and after).
- **fuzz**: seeded specs through ``workbench sweep``, models through validation and
  ``workbench run`` command lines: tracebacks, hangs and silently accepted non-finite values.
- **out**: attacks on the output folder (planted links, two sweeps at once, a stale lock,
  a killed report worker, a killed Dask scheduler): :mod:`benchmarks.torture_out`, printed
  as a table of its own and written to ``benchmarks/results/torture-out.csv``.

Prints one table of figures and writes ``benchmarks/results/torture.csv``. Exit status 1
when any figure that must be zero is not.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import psutil

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).parent / "results"
HANG_S = 600.0  # a sweep or command that takes longer than this is counted as hung

SPEC = """\
out = "{out}"
jobs = 2
time_limit = 300.0
tolerances = [1e-4, 1e-6, 1e-8]
problems = ["simple-pendulum", "double-pendulum", "slider-crank", "four-bar"]
formalisms = [
    {{ name = "minimal-ode", options = {{ index = 1 }} }},
    {{ name = "absolute-dae", options = {{ index = 1 }} }},
]
integrators = ["scipy-dop853", "sundials-cvode-bdf"]
"""
N_RUNS = 4 * 2 * 2 * 3


# ---- helpers --------------------------------------------------------------------------


def workbench(*args: str, cwd: Path, timeout: float = HANG_S) -> subprocess.CompletedProcess:
    """``python -m workbench ARGS`` to completion; a hang raises TimeoutExpired."""
    return subprocess.run(
        [sys.executable, "-m", "workbench", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        start_new_session=True,
    )


def start_sweep(spec: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "workbench", "sweep", str(spec), *extra],
        cwd=spec.parent,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def rows_done(out: Path) -> int:
    runs = out / "runs"
    return len(list(runs.glob("*.json"))) if runs.is_dir() else 0


def wait_for_rows(out: Path, k: int, process: subprocess.Popen) -> bool:
    """Wait until ``k`` rows are written; False if the sweep ended first."""
    deadline = time.monotonic() + HANG_S
    while time.monotonic() < deadline:
        if rows_done(out) >= k:
            return True
        if process.poll() is not None:
            return False
        time.sleep(0.02)
    return False


def kill_tree(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, signal.SIGKILL)


def timing_column(name: str) -> bool:
    from workbench.execution.counted_work import COLUMNS as WORK_COLUMNS
    from workbench.execution.timing import TIMING_COLUMNS

    named = {"equations_cached", "log_s", *TIMING_COLUMNS, *WORK_COLUMNS}
    return name.endswith("_s") or name in named


def comparable(out: Path) -> pd.DataFrame:
    from workbench.runs.store import load_results

    frame = load_results(out)
    keep = [c for c in frame.columns if not timing_column(c)]
    return frame[keep].set_index("run_id").sort_index()


def differing_rows(out: Path, clean: pd.DataFrame) -> int:
    frame = comparable(out)
    common = frame.index.intersection(clean.index)
    columns = [c for c in clean.columns if c in frame.columns]
    a, b = frame.loc[common, columns], clean.loc[common, columns]
    same = (a == b) | (a.isna() & b.isna())
    return int((~same.all(axis=1)).sum())


def integrity(out: Path, expected: set[str]) -> dict:
    """Lost, duplicated and corrupted rows of a finished sweep directory."""
    from workbench.runs import store

    corrupted = 0
    ids = []
    for path in sorted((out / "runs").glob("*.json")):
        try:
            row = json.loads(path.read_text())
            ids.append(row["run_id"])
            series = store.series_path(out, row["run_id"])
            if series.exists() or row.get("status") == "ok":  # an ok row implies its series
                pd.read_parquet(series)
        except Exception:  # noqa: BLE001 - a file that does not load is what is counted
            corrupted += 1
    results = store.load_results(out)
    return {
        "lost": len(expected - set(results["run_id"])),
        "duplicated": int(results["run_id"].duplicated().sum()) + len(ids) - len(set(ids)),
        "corrupted": corrupted,
    }


def resume_until_done(spec: Path, tries: int = 3) -> tuple[int, int]:
    """Re-run the sweep until it exits 0 (resume); returns (tries used, tracebacks seen)."""
    tracebacks = 0
    for attempt in range(1, tries + 1):
        done = workbench("sweep", str(spec), cwd=spec.parent)
        tracebacks += done.stderr.count("Traceback")
        if done.returncode == 0:
            return attempt, tracebacks
    return tries + 1, tracebacks


def write_spec(directory: Path, out: Path) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    spec = directory / "spec.toml"
    spec.write_text(SPEC.format(out=out), encoding="utf-8")
    return spec


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


# ---- kills ------------------------------------------------------------------------------


def clean_sweep(base: Path) -> tuple[pd.DataFrame, set[str]]:
    out = base / "clean" / "out"
    spec = write_spec(base / "clean", out)
    done = workbench("sweep", str(spec), cwd=spec.parent)
    if done.returncode != 0:
        raise SystemExit(f"the uninterrupted sweep failed: {done.stderr.strip()[-500:]}")
    frame = comparable(out)
    return frame, set(frame.index)


def local_kill(base: Path, kind: str, k: int, clean, expected) -> dict:
    """Kill the parent, the group or one worker of a local sweep after ``k`` rows."""
    out = base / f"{kind}-{k}" / "out"
    spec = write_spec(out.parent, out)
    process = start_sweep(spec)
    figures = {"experiment": f"kill {kind}", "k": k, "orphans": 0, "hung": 0, "tracebacks": 0}
    reached = wait_for_rows(out, k, process)
    children = psutil.Process(process.pid).children(recursive=True) if reached else []
    if reached and kind == "parent":
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        time.sleep(1.0)
        gone, alive = psutil.wait_procs(children, timeout=60)  # workers must notice
        figures["orphans"] = len(alive)
    elif reached and kind == "group":
        kill_tree(process.pid)
        process.wait()
    elif reached and kind == "worker":
        workers = [c for c in children if "python" in c.name().lower()]
        if workers:
            with contextlib.suppress(psutil.NoSuchProcess):
                workers[0].kill()
        try:
            _, err = process.communicate(timeout=HANG_S)
            figures["tracebacks"] += err.count("Traceback")
        except subprocess.TimeoutExpired:
            figures["hung"] += 1
    kill_tree(process.pid)
    with contextlib.suppress(Exception):
        process.wait(timeout=10)
    tries, tracebacks = resume_until_done(spec)
    figures["tracebacks"] += tracebacks
    figures["resumes"] = tries
    figures.update(integrity(out, expected))
    figures["differ"] = differing_rows(out, clean)
    figures["recordings_lost"] = len(recorded_runs(base / "clean" / "out") - recorded_runs(out))
    return figures


@contextlib.contextmanager
def dask_cluster(base: Path):
    """A scheduler and two single-threaded workers on 127.0.0.1, as separate processes."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, DASK_DISTRIBUTED__WORKER__DAEMON="False")
    script = Path(sys.executable).parent / "dask"  # else this Python's `-m dask` (a venv
    dask = [str(script)] if script.exists() else [sys.executable, "-m", "dask"]  # without it)
    scheduler = subprocess.Popen(
        [*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        cwd=base, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True, env=env,
    )  # fmt: skip

    def worker() -> subprocess.Popen:
        return subprocess.Popen(
            [*dask, "worker", address, "--nthreads", "1", "--nworkers", "1",
             "--no-dashboard", "--no-nanny"],
            cwd=base, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True, env=env,
        )  # fmt: skip

    workers = [worker(), worker()]
    processes = {"scheduler": scheduler, "workers": workers, "start_worker": worker}
    try:
        time.sleep(5.0)  # the workers connect
        yield address, processes
    finally:
        for process in [scheduler, *processes["workers"]]:
            kill_tree(process.pid)
            with contextlib.suppress(Exception):
                process.wait(timeout=10)


def dask_kill(base: Path, kind: str, k: int, clean, expected) -> dict:
    """Kill one Dask worker (a fresh one joins) or the scheduler after ``k`` rows."""
    out = base / f"dask-{kind}-{k}" / "out"
    spec = write_spec(out.parent, out)
    figures = {"experiment": f"kill dask {kind}", "k": k, "orphans": 0, "hung": 0}
    figures["tracebacks"] = 0
    with dask_cluster(out.parent) as (address, processes):
        process = start_sweep(spec, "--scheduler", address)
        if wait_for_rows(out, k, process):
            if kind == "worker":
                kill_tree(processes["workers"][0].pid)
                processes["workers"].append(processes["start_worker"]())
            else:
                kill_tree(processes["scheduler"].pid)
        try:
            _, err = process.communicate(timeout=HANG_S)
            figures["tracebacks"] += err.count("Traceback")
        except subprocess.TimeoutExpired:
            figures["hung"] += 1
            kill_tree(process.pid)
            process.wait()
    tries, tracebacks = resume_until_done(spec)
    figures["tracebacks"] += tracebacks
    figures["resumes"] = tries
    figures.update(integrity(out, expected))
    figures["differ"] = differing_rows(out, clean)
    # a Dask sweep records its runs too (each run's file comes back with its row)
    figures["recordings_lost"] = len(recorded_runs(base / "clean" / "out") - recorded_runs(out))
    return figures


def recorded_runs(out: Path) -> set[str]:
    """The runs in a finished sweep's ``recording.rrd`` (none if it has none)."""
    from workbench.outputs.recording import RECORDING_FILE, SweepRecorder

    merged = out / RECORDING_FILE
    return set(SweepRecorder().add_recording(merged)) if merged.is_file() else set()


def kills(base: Path, repeats: int, rng: np.random.Generator) -> list[dict]:
    clean, expected = clean_sweep(base)
    rows = []
    for kind in ("parent", "group", "worker"):
        for _ in range(repeats):
            k = int(rng.integers(2, N_RUNS - 6))
            rows.append(local_kill(base, kind, k, clean, expected))
            print(rows[-1], flush=True)
    for kind in ("worker", "scheduler"):
        for _ in range(repeats):
            k = int(rng.integers(2, N_RUNS - 6))
            rows.append(dask_kill(base, kind, k, clean, expected))
            print(rows[-1], flush=True)
    return rows


# ---- disk -------------------------------------------------------------------------------


@contextlib.contextmanager
def tmpfs(path: Path, size: str):
    path.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], check=True)
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def can_mount(base: Path) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    try:
        with tmpfs(base / "probe", "1m"):
            return True
    except (subprocess.CalledProcessError, OSError):
        return False


def tree_hashes(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


PROGRESS_LINE = re.compile(r"  \d+/\d+( \(\d+%\))?  \d+:\d\d:\d\d")  # runs/progress off a TTY


def one_line(stderr: str) -> bool:
    """The error is one line (the plain progress lines printed off a terminal aside)."""
    lines = [x for x in stderr.splitlines() if x.strip() and not PROGRESS_LINE.search(x)]
    return len(lines) == 1 and "Traceback" not in stderr


def full_disk(base: Path, expected: set[str]) -> dict:
    mount = base / "full"
    figures = {"experiment": "full disk (6 MB)", "hung": 0}
    with tmpfs(mount, "6m"):
        out = mount / "out"
        spec = write_spec(base / "full-spec", out)
        try:
            done = workbench("sweep", str(spec), cwd=spec.parent)
            figures["exit"] = done.returncode
            figures["one_line"] = one_line(done.stderr) if done.returncode else "exit 0"
            figures["tracebacks"] = done.stderr.count("Traceback")
        except subprocess.TimeoutExpired:
            figures["hung"] = 1
        ok_rows = rows_done(out)
        subprocess.run(["mount", "-o", "remount,size=2g", str(mount)], check=True)
        tries, tracebacks = resume_until_done(spec)
        figures["resumes"] = tries
        figures["tracebacks"] = figures.get("tracebacks", 0) + tracebacks
        figures.update(integrity(out, expected))
        figures["rows_before_resume"] = ok_rows
        figures["recording"] = (out / "recording.rrd").is_file()
        figures["partial_left"] = len(list(out.rglob("*.partial")))
    return figures


def read_only(base: Path) -> dict:
    mount = base / "ro"
    figures = {"experiment": "read-only OUT", "hung": 0}
    with tmpfs(mount, "500m"):
        out = mount / "out"
        spec = write_spec(base / "ro-spec", out)
        workbench("sweep", str(spec), cwd=spec.parent)
        before = tree_hashes(out)
        subprocess.run(["mount", "-o", "remount,ro", str(mount)], check=True)
        more = spec.parent / "more.toml"
        more.write_text(spec.read_text().replace("1e-8]", "1e-8, 1e-10]"), encoding="utf-8")
        try:
            done = workbench("sweep", str(more), cwd=spec.parent)
            figures["exit"] = done.returncode
            figures["one_line"] = one_line(done.stderr)
            figures["tracebacks"] = done.stderr.count("Traceback")
        except subprocess.TimeoutExpired:
            figures["hung"] = 1
        figures["files_changed"] = sum(
            1 for name, digest in tree_hashes(out).items() if before.get(name) != digest
        ) + len(set(before) - set(tree_hashes(out)))
    return figures


# ---- fuzz -------------------------------------------------------------------------------


class Hang(Exception):
    pass


@contextlib.contextmanager
def alarm(seconds: int):
    def raise_hang(signum, frame):
        raise Hang

    previous = signal.signal(signal.SIGALRM, raise_hang)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def fuzz(n_specs: int, n_models: int, n_commands: int, base: Path) -> list[dict]:
    from typer.testing import CliRunner

    from tests import fuzz_inputs
    from workbench.cli.app import app
    from workbench.errors import ConfigError, ModelError
    from workbench.runs.sweep import parse_spec

    runner = CliRunner()
    spec_figures = {"experiment": f"fuzz {n_specs} specs", "tracebacks": 0, "hung": 0}
    slowest = 0.0
    for seed in range(n_specs):
        text, _kind = fuzz_inputs.sweep_spec(seed)
        begin = time.perf_counter()
        try:
            with alarm(120):
                try:
                    parse_spec(text)
                except ConfigError as error:
                    spec_figures["tracebacks"] += "\n" in str(error)
        except Hang:
            spec_figures["hung"] += 1
        except Exception:  # noqa: BLE001 - an escaped exception is a traceback for a user
            spec_figures["tracebacks"] += 1
        slowest = max(slowest, time.perf_counter() - begin)
    spec_figures["slowest_s"] = round(slowest, 2)

    model_figures = {"experiment": f"fuzz {n_models} models", "tracebacks": 0, "hung": 0}
    model_figures["non_finite_accepted"] = 0
    for seed in range(n_models):
        slot, element, value = fuzz_inputs.model_case(seed)
        try:
            with alarm(120):
                fuzz_inputs.build_model(slot, value)
            if non_finite(value):
                model_figures["non_finite_accepted"] += 1
        except ModelError as error:
            model_figures["tracebacks"] += element not in str(error) or "\n" in str(error)
        except Hang:
            model_figures["hung"] += 1
        except Exception:  # noqa: BLE001
            model_figures["tracebacks"] += 1

    command_figures = {"experiment": f"fuzz {n_commands} run lines", "tracebacks": 0}
    command_figures["hung"] = 0
    for seed in range(n_commands):
        args = fuzz_inputs.run_command(seed)
        try:
            with alarm(int(HANG_S)):
                result = runner.invoke(app, args)
            bad = result.exit_code not in (0, 1, 2) or (
                result.exception is not None and not isinstance(result.exception, SystemExit)
            )
            command_figures["tracebacks"] += bool(bad)
        except Hang:
            command_figures["hung"] += 1
    return [spec_figures, model_figures, command_figures]


def non_finite(value) -> bool:
    """True if ``value`` holds a NaN or an infinity anywhere."""
    if isinstance(value, bool):
        return False
    if isinstance(value, float):
        return not math.isfinite(value)
    if isinstance(value, list | tuple):
        return any(non_finite(v) for v in value)
    return False


# ---- main -------------------------------------------------------------------------------


MUST_BE_ZERO = (
    "lost", "duplicated", "corrupted", "differ", "tracebacks", "hung", "orphans",
    "recordings_lost",
    "non_finite_accepted", "files_changed", "partial_left",
)  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 kill of each kind, fewer fuzz")
    parser.add_argument("--only", default="kills,disk,fuzz,out", help="comma list of experiments")
    parser.add_argument("--seed", type=int, default=18)
    args = parser.parse_args(argv)
    only = set(args.only.split(","))
    rng = np.random.default_rng(args.seed)
    rows: list[dict] = []
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="torture-") as tmp:
        base = Path(tmp)
        if "kills" in only:
            rows += kills(base, 1 if args.quick else 2, rng)
        if "disk" in only:
            if can_mount(base):
                clean = comparable(base / "clean" / "out") if "kills" in only else None
                expected = set(clean.index) if clean is not None else clean_sweep(base)[1]
                rows.append(full_disk(base, expected))
                rows.append(read_only(base))
            else:
                rows.append({"experiment": "disk: not run (needs root to mount a tmpfs)"})
        if "fuzz" in only:
            counts = (200, 200, 50) if args.quick else (1100, 1300, 240)
            rows += fuzz(*counts, base)
        if "out" in only:  # the output folder's attacks: their own table (torture_out)
            from benchmarks import torture_out

            (base / "out").mkdir()
            out_status = torture_out.report(torture_out.attacks(base / "out", args.quick))
    if not rows:
        return out_status if "out" in only else 0
    table = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "torture.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(table.astype(object).fillna("").to_string(index=False))
    bad = {
        column: int(pd.to_numeric(table[column], errors="coerce").fillna(0).sum())
        for column in MUST_BE_ZERO
        if column in table
    }
    bad = {column: value for column, value in bad.items() if value}
    print(f"load {os.getloadavg()[0]:.1f}, {time.perf_counter() - started:.0f} s")
    print("all zero" if not bad else f"NOT ZERO: {bad}")
    return 1 if bad or ("out" in only and out_status) else 0


if __name__ == "__main__":
    sys.exit(main())
