"""Torture of the output folder (issue 31 items 2, 4, 5, 10): attacks on OUT, each tried as
an attacker or a bad day would, with what happens.

Run: ``python -m benchmarks.torture_out [--quick]`` (also ``python -m benchmarks.torture
--only out``). Prints one table (attack, tries, what happens, and the figures that must
be zero) and writes ``benchmarks/results/torture-out.csv``; exit status 1 when a figure
that must be zero is not.

- **planted link**: a symbolic link to a file (or folder) outside OUT planted as each file
  and folder a sweep writes, replaces or deletes in OUT, then ``workbench sweep --fresh``:
  counted are targets touched (bytes or mtime), exits other than 2, errors not one line.
- **two sweeps at once**: two ``workbench sweep`` on one OUT started together, without and
  with ``--wait``: counted are runs done twice.
- **stale lock**: a sweep SIGKILLed (with its workers) while it holds OUT, then a sweep
  again: counted are refusals and hangs.
- **killed report worker**: a figure worker SIGKILLed while ``workbench sweep`` writes
  its report: counted are tracebacks, exits other than 0, reports missing a problem.
- **killed Dask scheduler**: the scheduler SIGKILLed before the first run, mid-sweep and
  near the end: counted are hangs, tracebacks, and rows that differ from a local sweep
  after a resume.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pandas as pd
import psutil

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).parent / "results"
HANG_S = 600.0  # a command that takes longer than this is counted as hung

SPEC = """\
out = "{out}"
jobs = 2
time_limit = 300.0
tolerances = [1e-4, 1e-6]
problems = {problems}
formalisms = [{{ name = "minimal-ode", options = {{ index = 1 }} }}]
integrators = ["scipy-dop853"{more}]
"""
SMALL = '["simple-pendulum"]'
FOUR = '["simple-pendulum", "double-pendulum", "slider-crank", "four-bar"]'

PLANTED = [  # (as what the link is planted, relative to OUT; a folder ends with /)
    "logs/.{id}.raw", "logs/{id}.log", "runs/{id}.json", "series/{id}.parquet",
    "recordings/{id}.rrd", "report/index.html", "report/tables/summary.csv",
    "results.parquet", "environment.json", "sweep.toml", "recording.rrd", ".workbench.lock",
    "runs/", "series/", "logs/", "recordings/", "references/", "report/", "report/tables/",
    "report/figures/",
]  # fmt: skip
MUST_BE_ZERO = ("victims_touched", "wrong_outcome", "tracebacks", "hung", "done_twice", "differ")


def workbench(*args: str, cwd: Path, timeout: float = HANG_S) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "workbench", *args],
        cwd=cwd, capture_output=True, text=True, timeout=timeout, start_new_session=True,
    )  # fmt: skip


def start(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "workbench", *args],
        cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )  # fmt: skip


def write_spec(directory: Path, out: Path, problems: str = SMALL, more: str = "") -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    spec = directory / "spec.toml"
    spec.write_text(SPEC.format(out=out, problems=problems, more=more), encoding="utf-8")
    return spec


def state(path: Path) -> object:
    if path.is_dir():
        return sorted((p.name, p.read_bytes(), p.stat().st_mtime_ns) for p in path.iterdir())
    return path.read_bytes(), path.stat().st_mtime_ns


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("error: ")]


# ---- planted links ----------------------------------------------------------------------


def planted_links(base: Path, quick: bool) -> dict:
    clean = base / "links" / "clean"
    spec = write_spec(base / "links", clean)
    done = workbench("sweep", str(spec), cwd=spec.parent)
    if done.returncode != 0:
        raise SystemExit(f"the sweep to attack failed: {done.stderr.strip()[-500:]}")
    run_id = sorted((clean / "runs").glob("*.json"))[0].stem
    figures = {"attack": "link planted in OUT, then sweep --fresh", "tries": 0}
    figures |= dict.fromkeys(("victims_touched", "wrong_outcome", "tracebacks", "hung"), 0)
    for i, where in enumerate(PLANTED[::4] if quick else PLANTED):
        out = base / "links" / f"try-{i}"
        shutil.copytree(clean, out, symlinks=True)
        victim = base / "links" / f"victim-{i}"
        if where.endswith("/"):
            victim.mkdir()
            (victim / "keep.txt").write_text("precious\n")
        else:
            victim.write_text("precious\n")
        link = out / where.rstrip("/").format(id=run_id)
        if link.is_dir() and not link.is_symlink():
            shutil.rmtree(link)
        link.unlink(missing_ok=True)
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(victim)
        before = state(victim)
        figures["tries"] += 1
        try:
            result = workbench("sweep", str(spec), "--out", str(out), "--fresh", cwd=spec.parent)
        except subprocess.TimeoutExpired:
            figures["hung"] += 1
            continue
        figures["victims_touched"] += state(victim) != before
        figures["tracebacks"] += "Traceback" in result.stderr
        refused = result.returncode == 2 and len(error_lines(result.stderr)) == 1
        figures["wrong_outcome"] += not (refused and "symbolic link" in result.stderr)
    figures["what happens"] = (
        f"{figures['tries'] - figures['wrong_outcome']} of {figures['tries']}: one line naming "
        f"the link, exit 2; {figures['victims_touched']} target(s) touched"
    )
    return figures


# ---- the lock ---------------------------------------------------------------------------


def runs_done(stdout: str) -> int:
    """Runs a sweep did, from its summary line ('N runs in ... ; M already done')."""
    for line in stdout.splitlines():
        if " runs in " in line:
            return int(line.split()[0])
    return 0


def two_sweeps(base: Path, wait: bool) -> dict:
    out = base / f"two-{wait}" / "out"
    spec = write_spec(out.parent, out, FOUR)
    extra = ["--wait"] if wait else []
    figures = {"attack": "two sweeps on one OUT at once" + (" (--wait)" if wait else "")}
    figures |= {"tries": 1, "tracebacks": 0, "hung": 0, "done_twice": 0}
    processes = [start("sweep", str(spec), *extra, cwd=spec.parent) for _ in range(2)]
    outcomes = []
    for process in processes:
        try:
            stdout, stderr = process.communicate(timeout=HANG_S)
            outcomes.append((process.returncode, stdout, stderr))
        except subprocess.TimeoutExpired:
            figures["hung"] += 1
            os.killpg(process.pid, signal.SIGKILL)
            outcomes.append((None, "", ""))
    figures["tracebacks"] = sum("Traceback" in err for _, _, err in outcomes)
    done = sum(runs_done(stdout) for _, stdout, _ in outcomes)
    figures["done_twice"] = max(0, done - 8)
    refused = [err for code, _, err in outcomes if code == 2 and "is in use by pid" in err]
    figures["what happens"] = (
        f"exits {sorted(code for code, _, _ in outcomes)}; {done} runs done for 8 rows"
        + ("; the other: 'OUT is in use by pid ... on host ... since ...'" if refused else "")
    )
    return figures


def stale_lock(base: Path) -> dict:
    out = base / "stale" / "out"
    spec = write_spec(out.parent, out, FOUR)
    figures = {"attack": "sweep SIGKILLed holding OUT, then sweep", "tries": 1}
    figures |= {"tracebacks": 0, "hung": 0, "wrong_outcome": 0}
    holder = start("sweep", str(spec), cwd=spec.parent)
    deadline = time.monotonic() + HANG_S
    while time.monotonic() < deadline and holder.poll() is None:
        lock = out / ".workbench.lock"
        if lock.is_file() and lock.read_text().strip():
            break
        time.sleep(0.05)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(holder.pid, signal.SIGKILL)
    holder.wait()
    try:
        again = workbench("sweep", str(spec), cwd=spec.parent)
    except subprocess.TimeoutExpired:
        figures["hung"] = 1
        return figures | {"what happens": "hung"}
    figures["tracebacks"] = again.stderr.count("Traceback")
    took_over = "taking over the lock" in again.stdout + again.stderr
    figures["what happens"] = f"exit {again.returncode}" + (
        "; 'taking over the lock of OUT left by pid ..., no longer running'" if took_over else ""
    )
    figures["wrong_outcome"] = int(again.returncode != 0 or not took_over)
    return figures


# ---- a killed report worker ---------------------------------------------------------------


def killed_report_worker(base: Path) -> dict:
    out = base / "report-kill" / "out"
    spec = write_spec(out.parent, out, FOUR)
    figures = {"attack": "figure worker SIGKILLed during sweep's report", "tries": 1}
    figures |= {"tracebacks": 0, "hung": 0}
    process = start("sweep", str(spec), cwd=spec.parent)
    killed = 0
    deadline = time.monotonic() + HANG_S
    while process.poll() is None and time.monotonic() < deadline and not killed:
        with contextlib.suppress(psutil.Error):
            for child in psutil.Process(process.pid).children(recursive=True):
                if "spawn_main" in " ".join(child.cmdline()):  # a figure worker (spawned)
                    child.kill()
                    killed += 1
                    break
        time.sleep(0.02)
    try:
        stdout, stderr = process.communicate(timeout=HANG_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        return figures | {"hung": 1, "what happens": "hung"}
    figures["tracebacks"] = stderr.count("Traceback")
    page = (out / "report" / "index.html").read_text() if process.returncode == 0 else ""
    sections = sum(f'id="{p}"' in page for p in ("simple-pendulum", "four-bar", "slider-crank"))
    warned = [line for line in stderr.splitlines() if "report worker" in line]
    figures["what happens"] = (
        f"{killed} worker killed; exit {process.returncode}, {len(warned)} warning line(s), "
        f"report with {sections} of 3 checked problem sections"
    )
    figures["wrong_outcome"] = int(process.returncode != 0 or sections != 3)
    return figures


# ---- a killed Dask scheduler -----------------------------------------------------------


class Logged:
    """A process whose stderr lines a thread collects (its pipe never fills)."""

    def __init__(self, command: list[str], cwd: Path) -> None:
        self.process = subprocess.Popen(
            command, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            start_new_session=True,
        )  # fmt: skip
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        for line in self.process.stderr:
            self.lines.append(line)

    def wait_for(self, text: str) -> str:
        deadline = time.monotonic() + HANG_S
        while time.monotonic() < deadline and self.process.poll() is None:
            found = [line for line in self.lines if text in line]
            if found:
                return found[0]
            time.sleep(0.05)
        raise SystemExit(f"never logged {text!r}: {''.join(self.lines)[-500:]}")

    def kill(self) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait()


def comparable(out: Path) -> pd.DataFrame:
    from workbench.execution.counted_work import COLUMNS as WORK_COLUMNS
    from workbench.execution.timing import TIMING_COLUMNS
    from workbench.runs.store import load_results

    frame = load_results(out).set_index("run_id").sort_index()
    frame["reference"] = frame["reference"].str.replace(r" \(read from .*\)$", "", regex=True)
    timings = {"equations_cached", "workers", "load_avg", "log", *TIMING_COLUMNS, *WORK_COLUMNS}
    return frame[[c for c in frame.columns if not c.endswith("_s") and c not in timings]]


def killed_scheduler(base: Path, moments: list[str]) -> dict:
    local = base / "dask-local" / "out"
    spec = write_spec(local.parent, local, FOUR)
    workbench("sweep", str(spec), cwd=spec.parent)
    clean = comparable(local)
    figures = {"attack": "Dask scheduler SIGKILLed (" + ", ".join(moments) + ")"}
    figures |= {"tries": len(moments), "tracebacks": 0, "hung": 0, "differ": 0}
    exits = []
    for moment in moments:
        out = base / f"dask-{moment}" / "out"
        spec = write_spec(out.parent, out, FOUR)
        python = [sys.executable, "-m"]
        scheduler = Logged(
            [*python, "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
             "--no-dashboard"], out.parent,
        )  # fmt: skip
        address = scheduler.wait_for("Scheduler at:").split()[-1]
        worker = Logged(
            [*python, "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-nanny",
             "--no-dashboard"], out.parent,
        )  # fmt: skip
        try:
            scheduler.wait_for("Register worker")
            sweep = start("sweep", str(spec), "--scheduler", address, cwd=spec.parent)
            if moment == "before the first run":
                scheduler.wait_for("Receive client connection")
            else:
                k = 2 if moment == "mid-sweep" else 7
                deadline = time.monotonic() + HANG_S
                while time.monotonic() < deadline and sweep.poll() is None:
                    if len(list((out / "runs").glob("*.json"))) >= k:
                        break
                    time.sleep(0.02)
            scheduler.kill()
            try:
                _, stderr = sweep.communicate(timeout=HANG_S)
                exits.append(sweep.returncode)
                figures["tracebacks"] += "Traceback" in stderr
            except subprocess.TimeoutExpired:
                figures["hung"] += 1
                os.killpg(sweep.pid, signal.SIGKILL)
        finally:
            scheduler.kill()
            worker.kill()
        resumed = workbench("sweep", str(spec), cwd=spec.parent)
        mine = comparable(out) if resumed.returncode == 0 else clean.iloc[:0]
        columns = [c for c in clean.columns if c in mine.columns]
        if list(mine.index) != list(clean.index):
            figures["differ"] += abs(len(clean) - len(mine)) or 1
        else:
            a, b = mine[columns], clean[columns]
            figures["differ"] += int((~((a == b) | (a.isna() & b.isna())).all(axis=1)).sum())
    figures["what happens"] = (
        f"exits {exits} (1: one line naming the runs left without a row); a resume "
        f"completes, {figures['differ']} row(s) differ from a local sweep"
    )
    return figures


# ---- main -------------------------------------------------------------------------------


def attacks(base: Path, quick: bool = False) -> list[dict]:
    rows = [planted_links(base, quick)]
    rows += [two_sweeps(base, wait=False), two_sweeps(base, wait=True), stale_lock(base)]
    rows.append(killed_report_worker(base))
    moments = ["mid-sweep"] if quick else ["before the first run", "mid-sweep", "near the end"]
    rows.append(killed_scheduler(base, moments))
    for row in rows:
        print(row, flush=True)
    return rows


def report(rows: list[dict]) -> int:
    """Print the table, write the CSV; 1 if a figure that must be zero is not."""
    columns = ["attack", "tries", "what happens", *MUST_BE_ZERO]
    table = pd.DataFrame(rows).reindex(columns=columns)
    for column in MUST_BE_ZERO:  # whole numbers, empty where an attack does not count it
        table[column] = pd.to_numeric(table[column]).astype("Int64")
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "torture-out.csv", index=False)
    with pd.option_context("display.width", 250, "display.max_colwidth", 120):
        print(table.astype(object).fillna("").to_string(index=False))
    bad = {c: int(pd.to_numeric(table[c], errors="coerce").fillna(0).sum()) for c in MUST_BE_ZERO}
    bad = {c: v for c, v in bad.items() if v}
    print("all zero" if not bad else f"NOT ZERO: {bad}")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer links, one Dask moment")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="torture-out-") as tmp:
        rows = attacks(Path(tmp), args.quick)
    status = report(rows)
    print(f"load {os.getloadavg()[0]:.1f}, {time.perf_counter() - started:.0f} s")
    return status


if __name__ == "__main__":
    sys.exit(main())
