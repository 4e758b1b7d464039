"""Footprint of a sweep's outputs (issue 35): the merge's memory and a no-op resume's time.

Run: ``python -m benchmarks.footprint [N_MERGE ...] [--resume N_RUNS]`` (defaults: merges
of 100 and 1000 recordings, a resume of a 100-run sweep; about 4 minutes at load 8 on
2 cores with ``100 1000 --resume 1000``, the 1,000-run sweep most of it), or
``python -m benchmarks.footprint --tiny 1000 10000 [--before CHECKOUT]`` for 3, or
``python -m benchmarks.footprint --targets [1000 10000] [--dask 1000]`` for 4, or
``python -m benchmarks.footprint --recording N [--before CHECKOUT]`` for 5, or
``python -m benchmarks.footprint --read-back [--before CHECKOUT]`` for 6, or
``python -m benchmarks.footprint --dask N [N ...]`` for 4's Dask rows alone (10,000
runs: about 7 min at load 4), or ``python -m benchmarks.footprint --loop [N]`` for 7.
(``CHECKOUT``: a worktree of older code, e.g. ``git worktree add --detach /tmp/old REV``;
the sweeps' OUT folders are made in Python's temporary folder: ``TMPDIR=/some/folder`` puts
them elsewhere. On this ext4 a file made in a new folder under /tmp cost 0.79 ms against
0.02 elsewhere, and every file deleted in a block group slows the files made there for
minutes after: say where OUT was, and compare runs made in the same place.)

1. Merge: N per-run recordings like a sweep's workers write (a 2-body model with its
   shapes and joint frames, 200 poses, 5 series a run) are merged into one file in a fresh
   process, by the streaming merge of :func:`workbench.outputs.recording.merge_recordings`
   ("after") and by the merge it replaced ("before": every chunk kept in one in-memory
   binary stream until the file is written). Columns: the process's peak RSS during the
   merge (VmHWM, reset when the merge starts: Linux) and its growth over the RSS at that
   start (imports done), CPU seconds, the merged file's and the inputs' sizes.
2. No-op resume: a sweep of N_RUNS tiny runs (simple pendulum, minimal-ode, DOP853 and
   RK45 at N_RUNS/2 tolerances) is run, then run again with nothing to do: "after" as is,
   "before" with the outputs' keys removed first (``*.inputs``: then the results table, the
   recording and the report are remade, as before keys existed; the code is otherwise
   this one's, e.g. the producer's cheaper distribution lookup helps both). Wall and CPU
   seconds of the command (its workers included), the peak RSS of its largest process,
   and how many outputs it said were unchanged (of recording and report).

3. Tiny runs (:func:`tiny_rows`): runs/s and the CPU a run spends outside its
   integration on 2 workers, before and after; the recording's size and the ``.rrd``
   bytes left on disk.

4. The issue's targets (:func:`targets_table`), each printed as measured / met / missed:
   the default sweep's peak PSS per phase, its recording (one copy, ``rerun rrd verify``,
   Python's reader within 2x its size), the no-op resume at 1,000 runs, tiny runs on the
   local pool (runs/s, time outside the integration, the largest process's peak at 10,000
   against 1,000) and on a local Dask cluster (runs/s); about 25 min at load 4 with
   1,000 and 10,000 runs. Writes ``footprint-targets.csv``.

5. A run's recording (:func:`recording_rows`): chunks a run, the CPU of a run's
   recording, and Python's reader's growth against the merged file's size (the 2x target
   of 4 without a sweep: load-independent but for the CPU), before and after.

6. The default sweep's recording (:func:`readback_rows`): the quick suite's sweep, its
   recording's chunks, component columns and (entity, component) pairs by kind (the
   pairs are what the reader's memory follows), ``rerun rrd verify`` and Python's reader
   (cold, beyond its start-up, anonymous memory), before and after; about 3 min at load 2
   (8 at load 11). Writes ``footprint-readback.csv``, which ``python -m benchmarks
   --summary`` reads for the reader's lines of issue 35.
7. The worker loop in one process (:func:`loop_parts`): a tiny run's CPU outside its
   integration and in each part (recording, metrics, series and row files), no profiler.
8. ``--chunk-cost``: what Rerun charges a chunk (:func:`chunk_cost_rows`): CPU a
   ``send_columns`` of n rows of 7 floats to a binary stream, encoding included, for n
   from 10 to 3,200 (a tiny run's recording is 6 chunks of about 200 rows).

Prints the table and the load average; writes ``benchmarks/results/footprint.csv``
(``footprint-tiny.csv`` for 3).
On a shared machine wall times mean little: compare CPU seconds and memory.
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from benchmarks import help_if_asked
from workbench.execution.environment import cpu_model

RESULTS = Path(__file__).parent / "results"
FRAMES = 200  # poses a run, as SweepRecorder


# ---- merge ------------------------------------------------------------------------------


class _Observables:
    body_names = ("arm", "tip")

    def poses_along(self, times: np.ndarray, q: np.ndarray) -> np.ndarray:
        half = 0.5 * times
        arm = np.stack([0 * times, 0 * times, 0 * times, np.cos(half), 0 * times, 0 * times,
                        np.sin(half)], axis=1)  # fmt: skip
        tip = np.stack([np.cos(times), np.sin(times), 0 * times, 1 + 0 * times, 0 * times,
                        0 * times, 0 * times], axis=1)  # fmt: skip
        return np.stack([arm, tip], axis=1)


def _equations() -> SimpleNamespace:
    from workbench.model import Frame, Model, Shape

    model = Model("benchmark-arm", kind="spatial")
    model.add_body(
        "arm",
        1.0,
        inertia=(1.0, 1.0, 1.0),
        shapes=[Shape("box", (1.0, 0.1, 0.1), Frame.at(0.5, 0, 0)), Shape("cylinder", (0.05, 0.2))],
    )
    model.add_point_mass("tip", 0.5, shapes=[Shape("sphere", (0.05,))])
    model.add_joint("hinge", "revolute", "ground", "arm")
    model.add_joint("slide", "prismatic", "arm", "tip", parent_frame=Frame.at(1.0, 0, 0))
    return SimpleNamespace(model=model, observables=_Observables(), nq=2)


def write_run_recordings(directory: Path, n: int, seconds: list[float] | None = None) -> list[Path]:
    """``n`` per-run recordings, as a sweep's worker writes them (one sink, a file a run);
    ``seconds``: gets the CPU seconds of each run's recording (all threads: Rerun's too)."""
    from workbench.outputs.recording import SweepRecorder

    sink, equations = SweepRecorder(), _equations()
    times = np.linspace(0.0, 10.0, 1001)
    files = []
    for index in range(n):
        rtol = 10 ** (-3 - 6 * index / max(n - 1, 1))
        spec = SimpleNamespace(
            problem="arm", formalism="minimal-ode", integrator="dop853", rtol=rtol,
            run_id=f"run{index:05d}",
        )  # fmt: skip
        series = pd.DataFrame({"run_id": spec.run_id, "t": times} | {
            quantity: rtol * (1 + index) * times
            for quantity in ("drift_pos", "drift_vel", "energy_err", "ref_err")
        })  # fmt: skip
        trajectory = SimpleNamespace(times=times, y=np.zeros((len(times), 4)))
        started = time.process_time()
        sink.begin_file(directory / f"{spec.run_id}.rrd")
        sink.log_run(spec, equations, None, trajectory, series)
        files.append(sink.end_file())
        if seconds is not None:
            seconds.append(time.process_time() - started)
    return files


RECORDING_CHILD = """
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])  # the workbench of that checkout
import importlib.util
spec = importlib.util.spec_from_file_location("footprint_bench", sys.argv[2])
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)
import numpy as np, rerun as rr
from workbench.outputs.recording import merge_recordings
directory, n, seconds = Path(sys.argv[3]), int(sys.argv[4]), []
files = bench.write_run_recordings(directory, n, seconds)
merged = merge_recordings(files, directory / "merged.rrd")  # small: with its footer
chunks = sum(1 for chunk in rr.chunk.RrdReader(merged).stream()
             if chunk.entity_path.startswith("/runs/"))
print(json.dumps({"chunks_per_run": chunks / n, "recording_ms": 1000 * float(np.median(seconds)),
                  "run_file_kb": np.mean([f.stat().st_size for f in files]) / 1000,
                  "merged": str(merged)}))
"""


def recording_rows(n: int, before: str) -> list[dict]:
    """The recording of ``n`` runs of :func:`write_run_recordings` (the 2-body model, 200
    poses, 4 series of 1,001 samples), with this code ("after") and a checkout's
    ("before"), each in a fresh process: chunks a run, the CPU a run's recording takes
    (median; logging and writing its file), the merged file's size with its footer, and
    ``rerun rrd verify`` and Python's reader's growth on it (:func:`read_back`)."""
    rows = []
    for code, checkout in (("before", before), ("after", str(Path(__file__).parents[1]))):
        if not checkout:
            continue
        with tempfile.TemporaryDirectory() as directory:
            command = [sys.executable, "-c", RECORDING_CHILD, checkout, __file__, directory,
                       str(n)]  # fmt: skip
            done = subprocess.run(command, capture_output=True, text=True, check=True)
            measured = json.loads(done.stdout.strip().splitlines()[-1])
            merged = Path(measured.pop("merged"))
            size = merged.stat().st_size / 2**20
            back = read_back(merged)
        row = {"measure": "recording", "n": n, "code": code} | measured | {
            "size_mib": size, **back, "read_growth_x": back["read_growth_mib"] / size,
            "read_beyond_startup_x": back["read_beyond_startup_mib"] / size,
            "load_1min": os.getloadavg()[0],
        }  # fmt: skip
        rows.append(row)
        print(row, flush=True)
    return rows


def merge_before(files: list[Path], target: Path) -> Path:
    """The merge this module replaced: every chunk in one in-memory binary stream."""
    from workbench.outputs.recording import RerunSink

    sink = RerunSink()
    for file in files:
        sink.add_recording(file)
    return sink.save(target)


def _merge_child(method: str, directory: str, n: int) -> None:
    """In a fresh process: merge the first ``n`` files, print the measures as JSON."""
    import rerun  # noqa: F401 - imported before the baseline, as in a sweep

    from workbench.outputs.recording import merge_recordings

    files = sorted(Path(directory).glob("run*.rrd"))[:n]
    Path("/proc/self/clear_refs").write_text("5")  # the peak (VmHWM) restarts from here
    baseline = _status_kib("VmRSS")
    started = time.process_time()
    merge = merge_recordings if method == "after" else merge_before
    target = merge(files, Path(directory) / f"merged-{method}-{n}.rrd")
    peak = _status_kib("VmHWM")
    print(json.dumps({
        "peak_rss_mib": peak / 1024, "growth_mib": (peak - baseline) / 1024,
        "cpu_s": time.process_time() - started, "size_mib": target.stat().st_size / 2**20,
        "inputs_mib": sum(f.stat().st_size for f in files) / 2**20,
    }))  # fmt: skip
    target.unlink()


def _status_kib(field: str) -> int:
    """A field of /proc/self/status in KiB (Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise RuntimeError(f"no {field} in /proc/self/status")


def merge_rows(counts: list[int]) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        write_run_recordings(Path(directory), max(counts))
        for n in counts:
            for method in ("before", "after"):
                command = [sys.executable, "-m", "benchmarks.footprint", "--merge-child",
                           method, directory, str(n)]  # fmt: skip
                done = subprocess.run(command, capture_output=True, text=True, check=True)
                measured = json.loads(done.stdout.strip().splitlines()[-1])
                rows.append({"measure": "merge", "n": n, "code": method} | measured)
                rows[-1]["load_1min"] = os.getloadavg()[0]
                print(rows[-1], flush=True)
    return rows


# ---- no-op resume -----------------------------------------------------------------------


def resume_spec(out: Path, n_runs: int) -> str:
    tolerances = ", ".join(f"{t:.6e}" for t in np.logspace(-3, -8, max(1, n_runs // 2)))
    return (
        f'out = "{out.as_posix()}"\ntolerances = [{tolerances}]\n'
        'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
        'integrators = ["scipy-dop853", "scipy-rk45"]\n'
    )


def _sweep(spec: Path, code: str = "", *extra: str) -> dict:
    """Run ``workbench sweep SPEC`` (2 workers, 1 timed sample a run) from a fresh process
    of this module, so that the peak RSS is this command's: its measures. ``code``: a
    checkout whose ``workbench`` runs it (``python -m workbench`` in that folder)."""
    command = [sys.executable, "-m", "benchmarks.footprint", "--sweep-child", str(spec), code,
               *extra]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _sweep_child(spec: str, code: str = "", *extra: str) -> None:
    workbench = [sys.executable, "-m", "workbench"] if code else [
        str(Path(sys.executable).with_name("workbench"))
    ]  # fmt: skip
    started = time.perf_counter()
    done = subprocess.run(
        # the close calls timed again after the runs (this code; not a checkout's before
        # it) are a phase of their own, about 10 s of gaps whatever N: not a run's cost
        [*workbench, "sweep", spec, "-j", "2", "--repeats", "1", *extra,
         *([] if code else ["--retime", "0"])],
        capture_output=True, text=True, check=True, cwd=code or None,
    )  # fmt: skip
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(json.dumps({
        "wall_s": time.perf_counter() - started,
        "cpu_s": used.ru_utime + used.ru_stime,  # the command and its workers
        "peak_rss_mib": used.ru_maxrss / 1024,  # its largest process
        "kept": done.stdout.count("(unchanged"),  # outputs said unchanged
    }))  # fmt: skip


def resume_rows(n_runs: int) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "out"
        spec = Path(directory) / "spec.toml"
        spec.write_text(resume_spec(out, n_runs))
        first = _sweep(spec)
        print(f"first sweep of {n_runs} runs: {first['wall_s']:.1f} s", flush=True)
        for code in ("before", "after"):
            if code == "before":
                for key in out.rglob("*.inputs"):
                    key.unlink()
            row = {"measure": "no-op resume", "n": n_runs, "code": code} | _sweep(spec)
            rows.append(row | {"load_1min": os.getloadavg()[0]})
            print(rows[-1], flush=True)
    return rows


# ---- many tiny runs ---------------------------------------------------------------------


def tiny_rows(counts: list[int], before: str, unrecorded: bool = False) -> list[dict]:
    """A sweep of N tiny runs (:func:`resume_spec`: simple pendulum, 10 s, DOP853 / RK45 at
    loose tolerances) with this code ("after"), given a checkout with its code ("before"),
    and with ``unrecorded`` this code's ``--no-recording`` ("after, no recording"): runs/s
    over the command's wall time, and the CPU a run spends outside its integration, (the
    command's CPU, workers included, minus the rows' integration CPU) / N, which counts the
    sweep's fixed costs too (start-up, report, recording merge) - the difference between
    two N removes them ("marginal")."""
    rows = []
    # every sweep's folder is removed at the end, not after the sweep: on ext4 without a
    # journal (this machine) a new file skips each inode deleted in the last 60-360 s, so
    # removing one sweep's 50,000 files made the next sweep's file writes slower
    kept = contextlib.ExitStack()
    variants = [("before", before, [])] * bool(before) + [("after", "", [])]
    variants += [("after, no recording", "", ["--no-recording"])] * unrecorded
    for n in counts:
        for code, checkout, extra in variants:
            directory = kept.enter_context(tempfile.TemporaryDirectory())
            out = Path(directory) / "out"
            spec = Path(directory) / "spec.toml"
            spec.write_text(resume_spec(out, n))
            measured = _sweep(spec, checkout, *extra)
            results = pd.read_parquet(out / "results.parquet")
            recording = out / "recording.rrd"
            size = recording.stat().st_size if recording.exists() else 0
            on_disk = sum(f.stat().st_size for f in out.rglob("*.rrd"))
            integration = float(results["integrate_cpu_s"].sum())
            row = {"measure": "tiny runs", "n": n, "code": code} | measured | {
                "runs_per_s": n / measured["wall_s"],
                "integration_cpu_ms": 1000 * integration / n,
                "outside_cpu_ms": 1000 * (measured["cpu_s"] - integration) / n,
                "size_mib": size / 2**20,
                "rrd_on_disk_mib": on_disk / 2**20,
                "load_1min": os.getloadavg()[0],
                "cpu": cpu_model(),  # the 5 ms target was set on a Zen 5 EPYC
                "_cpu_outside_s": measured["cpu_s"] - integration,
            }  # fmt: skip
            rows.append(row)
            print({k: v for k, v in row.items() if not k.startswith("_")}, flush=True)
    kept.close()
    for code, _checkout, _extra in variants:
        mine = sorted((r for r in rows if r["code"] == code), key=lambda r: r["n"])
        for small, large in zip(mine, mine[1:], strict=False):
            large["marginal_outside_cpu_ms"] = (
                1000
                * (large["_cpu_outside_s"] - small["_cpu_outside_s"])
                / (large["n"] - small["n"])
            )
    for row in rows:
        row.pop("_cpu_outside_s")
    return rows


def loop_parts(n: int, recorded: bool = True) -> dict[str, float]:
    """The worker loop of a tiny sweep (:func:`resume_spec`'s runs) in this process, as
    :func:`workbench.runs.local_pool._worker_main` runs it (``recorded``: False as under
    ``sweep --no-recording``), ``n`` runs after 20 to warm up:
    ms of CPU a run (``time.process_time``, Rerun's threads included wherever they run)
    outside the integration and in each named part. No profiler: cProfile inflated the
    pandas and Rerun calls several times (docs/performance.md)."""
    from collections import defaultdict

    from workbench.execution import execute as execute_module
    from workbench.execution import metrics as metrics_module
    from workbench.execution.execute import RunSpec, execute_run
    from workbench.execution.run_log import CapturedOutput, raw_path, release_raw_file
    from workbench.execution.run_progress import (
        ProgressWriter,
        progress_path,
        release_progress_file,
    )
    from workbench.execution.timing import Timing
    from workbench.outputs.recording import RerunSink, SweepRecorder
    from workbench.plugin import registry
    from workbench.runs import local_pool, store
    from workbench.runs.recording_batches import RecordingBatch

    spent: dict[str, float] = defaultdict(float)

    def timed(name: str, function):
        def part(*args, **kwargs):
            started = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                spent[name] += time.process_time() - started

        return part

    patched = [
        (RerunSink, "log_run", "recording: logging"),
        (RerunSink, "end_file", "recording: the runs' file"),
        (RerunSink, "begin_file", "recording: starting it"),
        (RecordingBatch, "logged", "recording: journal"),
        (metrics_module, "metric_columns", "metrics"),
        (store, "write_parquet_atomic", "series file"),
        (store, "write_json_atomic", "row file"),
        (execute_module, "state_arrays", "series: the states' columns"),
    ]
    saved = [(owner, name, getattr(owner, name)) for owner, name, _ in patched]
    for owner, name, label in patched:
        setattr(owner, name, timed(label, getattr(owner, name)))
    registry.REGISTRY.discover()
    SweepRecorder.prepare()
    tolerances = np.logspace(-3, -8, (n + 21) // 2)
    specs = [
        RunSpec("simple-pendulum", "minimal-ode", integrator, float(t), float(t) * 1e-3)
        for t in tolerances
        for integrator in ("scipy-dop853", "scipy-rk45")
    ][: n + 20]
    timing = Timing(repeats=1, workers=2).to_dict()
    total, integration = 0.0, 0.0
    try:
        with tempfile.TemporaryDirectory() as directory:
            out = Path(directory)
            batch = RecordingBatch(SweepRecorder, out, "loop") if recorded else None
            for index, spec in enumerate(specs):
                if index == 20:
                    spent.clear()
                    total = integration = 0.0
                started = time.process_time()
                sink = batch.begin_run(spec) if batch is not None else None
                capture = CapturedOutput(raw_path(out, spec.run_id), reuse=True)
                progress = ProgressWriter(progress_path(out, spec.run_id))
                with capture, progress:
                    result = execute_run(
                        spec, sink=sink, reference_dir=out / "references",
                        timing=Timing.from_dict(timing),
                    )  # fmt: skip
                if batch is not None:
                    batch.logged(spec.run_id)
                result.row["log"] = local_pool.write_log(out, spec.run_id, capture.kept())
                store.write_run(out, result.row, result.stored_series, True)
                if batch is not None:
                    batch.end_run()
                total += time.process_time() - started
                integration += result.row["integrate_cpu_s"]
            if batch is not None:
                batch.close()
            release_raw_file()
            release_progress_file()
    finally:
        for owner, name, function in saved:
            setattr(owner, name, function)
    runs = len(specs) - 20
    parts = {"outside the integration": 1000 * (total - integration) / runs,
             "integration": 1000 * integration / runs}  # fmt: skip
    return parts | {name: 1000 * seconds / runs for name, seconds in spent.items()}


# ---- the targets ----------------------------------------------------------------


def phase_memory(out: Path) -> dict:
    """``workbench sweep`` (the default, quick suite, 2 workers) into ``out``: the peak PSS
    of all its processes in each phase (runs; merge and report, after the line "N runs in";
    sampled every 0.1 s), its wall time and the largest process at the peak."""
    import psutil

    from benchmarks.default_sweep import tree_memory

    log = out.parent / "sweep.log"
    command = [str(Path(sys.executable).with_name("workbench")), "sweep", "--out", str(out),
               "-j", "2"]  # fmt: skip
    started = time.perf_counter()
    with log.open("w") as sink:
        process = subprocess.Popen(command, stdout=sink, stderr=subprocess.STDOUT)
        root, peaks = psutil.Process(process.pid), {"runs": 0, "merge and report": 0}
        while process.poll() is None:
            phase = "merge and report" if " runs in " in log.read_text() else "runs"
            peaks[phase] = max(peaks[phase], tree_memory(root)[0])
            time.sleep(0.1)
    if process.returncode != 0:
        raise SystemExit(f"workbench sweep exited with {process.returncode}: {log.read_text()}")
    return {
        "wall_s": time.perf_counter() - started,
        "peak_pss_runs_mib": peaks["runs"] / 2**20,
        "peak_pss_report_mib": peaks["merge and report"] / 2**20,
    }


def read_back(recording: Path, repeats: int = 5) -> dict:
    """``rerun rrd verify`` of ``recording`` (its exit code) and the peak RSS growth of
    Python's reader reading it whole, a chunk at a time (tests/test_recording_readback.py):
    from a cold start, and beyond the reader's start-up (a one-chunk recording read first
    in the same process: about 6 MiB whatever the file, docs/performance.md); and, cold,
    the growth of its anonymous memory at the end of the read, the reader still open
    (the start-up is almost all pages of rerun-sdk's library mapped from disk, RssFile,
    not memory the read holds; the kernel keeps no peak of RssAnon). Each the median of
    ``repeats`` fresh processes (they vary by about 2 MiB: the allocator's arenas)."""
    import shutil

    import rerun as rr

    from tests.test_recording_readback import READ_CHILD
    from workbench.cli.outputs import rerun_command

    verified = subprocess.run([*rerun_command(shutil.which), "rrd", "verify", str(recording)],
                              capture_output=True, text=True)  # fmt: skip
    child = recording.parent / "read.py"
    child.write_text(READ_CHILD)
    one_chunk = recording.parent / "one-chunk.rrd"
    stream = rr.RecordingStream("one-chunk")
    stream.save(one_chunk)
    stream.log("box", rr.Boxes3D(half_sizes=[[1.0, 1.0, 1.0]]), static=True)
    stream.flush()
    stream.disconnect()
    measured: dict[str, dict[str, float]] = {}
    for key, extra in (("cold", []), ("warm", [str(one_chunk)])):
        reads = []
        for _ in range(repeats):
            done = subprocess.run([sys.executable, str(child), str(recording), *extra],
                                  capture_output=True, text=True, check=True)  # fmt: skip
            reads.append(json.loads(done.stdout.strip().splitlines()[-1]))
        measured[key] = {name: float(np.median([r[name] for r in reads])) for name in reads[0]}
    one_chunk.unlink()
    return {
        "verify_rc": verified.returncode,
        "read_growth_mib": measured["cold"]["growth"] / 2**20,
        "reader_startup_mib": measured["warm"]["startup"] / 2**20,
        "read_beyond_startup_mib": measured["warm"]["beyond_startup"] / 2**20,
        "read_anon_mib": measured["cold"]["anon"] / 2**20,
    }


def recording_layout(recording: Path) -> dict:
    """Chunks, component columns and (entity, component) pairs of ``recording``'s runs
    (``/runs/...``), in all and by kind: joint frames (a run's ``joints`` entity; before
    2026-11-27 a body's ``joints``), shapes (static: sizes, labels), poses (on
    ``sim_time``: the shapes' instance poses; before, a body's transform), a run's series,
    what the runs of a model share. What Python's reader costs: about 5 KiB a pair (its
    manifest's schema holds a field a pair, plus about 10 bytes a character of its entity
    path), 0.2-0.35 KiB a chunk (docs/performance.md)."""
    import rerun as rr

    from workbench.outputs.recording import MODEL_PART, split_entity_path

    counts = {"chunks": 0, "columns": 0, "pairs": 0}
    seen: set[tuple[str, str]] = set()
    for chunk in rr.chunk.RrdReader(recording).stream():
        parts = split_entity_path(chunk.entity_path)
        if parts[:1] != ["runs"]:
            continue
        if len(parts) < 6 or parts[2] == MODEL_PART:
            kind = "shared"
        elif parts[5] == "series":
            kind = "series"
        elif "joints" in parts:
            kind = "joint_frames"
        elif not chunk.is_static:
            kind = "poses"
        else:
            kind = "shapes"
        index = {"rerun.controls.RowId", *chunk.timeline_names}
        names = [name for name in chunk.to_record_batch().schema.names if name not in index]
        pairs = {(chunk.entity_path, name) for name in names} - seen
        seen |= pairs
        for key, value in (("chunks", 1), ("columns", len(names)), ("pairs", len(pairs)),
                           (f"{kind}_chunks", 1), (f"{kind}_columns", len(names)),
                           (f"{kind}_pairs", len(pairs))):  # fmt: skip
            counts[key] = counts.get(key, 0) + value
    return counts


def readback_rows(before: str) -> list[dict]:
    """The default sweep (quick suite, 2 workers, 1 timed repeat) with this code ("after")
    and a checkout's ("before"), each in a fresh process: the sweep's wall and CPU, its
    recording's size, layout (:func:`recording_layout`) and read-back (:func:`read_back`).
    The reader's figures do not depend on the load; the sweep's times do."""
    rows = []
    for code, checkout in (("before", before), ("after", "")):
        if code == "before" and not before:
            continue
        with tempfile.TemporaryDirectory() as directory:
            out = Path(directory) / "out"
            measured = _sweep("quick", checkout, "--out", str(out))
            results = pd.read_parquet(out / "results.parquet")
            recording = out / "recording.rrd"
            size = recording.stat().st_size / 2**20
            row = {"measure": "default sweep recording", "code": code,
                   "runs": int((results["status"] == "ok").sum()),
                   "sweep_wall_s": measured["wall_s"], "sweep_cpu_s": measured["cpu_s"],
                   "size_mib": size} | recording_layout(recording)  # fmt: skip
            back = read_back(recording)
        row |= back | {
            "read_growth_x": back["read_growth_mib"] / size,
            "read_beyond_startup_x": back["read_beyond_startup_mib"] / size,
            "read_anon_x": back["read_anon_mib"] / size,
            "load_1min": os.getloadavg()[0],
        }
        rows.append(row)
        print(row, flush=True)
    return rows


def dask_tiny(n: int) -> dict:
    """A sweep of ``n`` tiny runs through a local Dask cluster (2 single-threaded worker
    processes): :func:`_sweep`'s measures, runs/s."""
    import distributed

    with tempfile.TemporaryDirectory() as directory, distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as cluster:  # fmt: skip
        spec = Path(directory) / "spec.toml"
        spec.write_text(resume_spec(Path(directory) / "out", n))
        measured = _sweep(spec, "", "--scheduler", cluster.scheduler_address)
        results = pd.read_parquet(Path(directory) / "out" / "results.parquet")
    return measured | {
        "runs_per_s": n / measured["wall_s"],
        "rows": len(results),
        "integration_cpu_ms": 1000 * float(results["integrate_cpu_s"].sum()) / n,
        "load_1min": os.getloadavg()[0],
    }


def targets_table(counts: list[int], dask_counts: list[int] | None = None) -> pd.DataFrame:
    """Measure every target of issue 35's "done when" and print measured / met / missed;
    tiny runs through Dask at ``dask_counts`` (default: ``counts``)."""
    load = os.getloadavg()[0]
    print(f"load average at start: {load:.2f} on {os.cpu_count()} CPUs", flush=True)
    rows: list[dict] = []

    def target(name: str, measured: float, unit: str, limit: float | None, met: bool | None):
        verdict = "measured" if met is None else ("met" if met else "missed")
        rows.append({"target": name, "measured": measured, "unit": unit, "limit": limit,
                     "verdict": verdict, "load_1min": os.getloadavg()[0]})  # fmt: skip
        print(rows[-1], flush=True)
        RESULTS.mkdir(exist_ok=True)  # written as it goes: a long run stopped keeps its rows
        pd.DataFrame(rows).to_csv(RESULTS / "footprint-targets.csv", index=False)

    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "out"
        memory = phase_memory(out)
        peak = max(memory["peak_pss_runs_mib"], memory["peak_pss_report_mib"])
        target("default sweep: peak PSS, all processes", peak, "MiB", 512, peak < 512)
        target("  of it: runs phase", memory["peak_pss_runs_mib"], "MiB", None, None)
        target("  of it: merge and report", memory["peak_pss_report_mib"], "MiB", None, None)
        target("default sweep: wall", memory["wall_s"], "s", None, None)
        recording = out / "recording.rrd"
        copies = [f for f in out.rglob("*.rrd") if f != recording]
        target("default sweep: recording size", recording.stat().st_size / 2**20, "MiB", None,
               None)  # fmt: skip
        target("one copy of the recording (other .rrd files)", len(copies), "files", 0,
               not copies)  # fmt: skip
        back = read_back(recording)
        target("rerun rrd verify (exit code)", back["verify_rc"], "", 0, back["verify_rc"] == 0)
        size = recording.stat().st_size / 2**20
        target("Python reader: peak growth", back["read_growth_mib"], "MiB", 2 * size,
               back["read_growth_mib"] < 2 * size)  # fmt: skip
        target("  of it: the reader's start-up (a one-chunk file)", back["reader_startup_mib"],
               "MiB", None, None)  # fmt: skip
        target("  growth beyond that start-up", back["read_beyond_startup_mib"], "MiB", None,
               None)  # fmt: skip
    resume = next(r for r in resume_rows(1000) if r["code"] == "after")
    target("no-op resume at 1,000 runs", resume["wall_s"], "s", 5, resume["wall_s"] < 5)
    target("  its CPU", resume["cpu_s"], "s", None, None)
    tiny = [r for r in tiny_rows(counts, "") if r["code"] == "after"]
    for row in tiny:
        target(f"local pool, {row['n']:,} tiny runs: runs/s", row["runs_per_s"], "1/s", None,
               None)  # fmt: skip
        target("  outside integration (CPU a run, fixed costs in)", row["outside_cpu_ms"],
               "ms", None, None)  # fmt: skip
        target("  largest process's peak RSS", row["peak_rss_mib"], "MiB", None, None)
    if len(tiny) > 1:
        small, large = tiny[0], tiny[-1]
        ratio = large["peak_rss_mib"] / small["peak_rss_mib"]
        target(f"parent peak at {large['n']:,} / at {small['n']:,} runs", ratio, "x", 1.5,
               ratio <= 1.5)  # fmt: skip
        marginal = large["marginal_outside_cpu_ms"]
        target(f"time outside integration, marginal at {large['n']:,} runs", marginal, "ms",
               5, marginal <= 5)  # fmt: skip
    for n in counts if dask_counts is None else dask_counts:
        measured = dask_tiny(n)
        target(f"Dask, {n:,} tiny runs: runs/s", measured["runs_per_s"], "1/s", None, None)
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(table.round(2).to_string(index=False))
    return table


def chunk_cost_rows(rows: tuple[int, ...] = (10, 50, 200, 800, 3200), chunks: int = 300,
                    repeats: int = 3) -> list[dict[str, float]]:  # fmt: skip
    """CPU ms a chunk (``time.process_time``: Rerun's encoding threads counted in) and bytes
    a chunk of ``chunks`` ``send_columns`` calls of n rows x 7 float64 (a scalar series'
    shape) into a binary stream read at the end, each n the least of ``repeats``."""
    import rerun as rr

    table = []
    for n in rows:
        times, values = np.linspace(0.0, 10.0, n), np.random.default_rng(0).random((n, 7))
        best, size = np.inf, 0.0
        for _ in range(repeats):
            recording = rr.RecordingStream("chunk-cost")
            stream = recording.binary_stream()
            started = time.process_time()
            for k in range(chunks):
                recording.send_columns(
                    f"runs/p/run{k}/series", indexes=[rr.TimeColumn("t", duration=times)],
                    columns=rr.Scalars.columns(scalars=values),
                )  # fmt: skip
            data = stream.read() or b""
            best = min(best, (time.process_time() - started) / chunks * 1e3)
            size = len(data) / chunks
            recording.disconnect()
        table.append({"rows": n, "cpu_ms_a_chunk": best, "bytes_a_chunk": size})
    return table


def main(argv: list[str]) -> pd.DataFrame:
    if argv[:1] == ["--chunk-cost"]:
        print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        table = pd.DataFrame(chunk_cost_rows())
        RESULTS.mkdir(exist_ok=True)
        table.to_csv(RESULTS / "footprint-chunks.csv", index=False)
        print(table.round(3).to_string(index=False))
        return table
    if argv[:1] == ["--sweep-child"]:
        _sweep_child(*argv[1:])
        return pd.DataFrame()
    if argv[:1] == ["--targets"]:  # --targets [N ...] [--dask N ...]
        at = argv.index("--dask") if "--dask" in argv else len(argv)
        dask = [int(a) for a in argv[at + 1 :]] if at < len(argv) else None
        return targets_table([int(a) for a in argv[1:at]] or [1000, 10000], dask)
    if "--tiny" in argv:  # --tiny N [N ...] [--before CHECKOUT] [--no-recording]: tiny runs
        before = argv[argv.index("--before") + 1] if "--before" in argv else ""
        counts = [int(a) for a in argv[argv.index("--tiny") + 1 :] if a.isdigit()]
        print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        table = pd.DataFrame(tiny_rows(counts, before, "--no-recording" in argv))
        RESULTS.mkdir(exist_ok=True)
        table.to_csv(RESULTS / "footprint-tiny.csv", index=False)
        with pd.option_context("display.width", 250, "display.max_columns", 30):
            print(table.round(2).to_string(index=False))
        return table
    if argv[:1] == ["--loop"]:  # --loop N [--no-recording]: the worker loop's parts here
        print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        count = int(argv[1]) if len(argv) > 1 and argv[1].isdigit() else 400
        parts = loop_parts(count, "--no-recording" not in argv)
        for name, ms in parts.items():
            print(f"{name:32s} {ms:7.3f} ms a run")
        print(f"load average at end: {os.getloadavg()[0]:.2f}")
        return pd.DataFrame([parts])
    if argv[:1] == ["--dask"]:  # --dask N [N ...]: tiny runs through a local Dask cluster
        print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        table = pd.DataFrame([{"n": int(a)} | dask_tiny(int(a)) for a in argv[1:]])
        RESULTS.mkdir(exist_ok=True)
        table.to_csv(RESULTS / "footprint-dask.csv", index=False)
        with pd.option_context("display.width", 200, "display.max_columns", 20):
            print(table.round(2).to_string(index=False))
        return table
    if "--recording" in argv:  # --recording N [--before CHECKOUT]: a run's recording only
        before = argv[argv.index("--before") + 1] if "--before" in argv else ""
        table = pd.DataFrame(recording_rows(int(argv[argv.index("--recording") + 1]), before))
        RESULTS.mkdir(exist_ok=True)
        table.to_csv(RESULTS / "footprint-recording.csv", index=False)
        print(f"load average: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        with pd.option_context("display.width", 200, "display.max_columns", 20):
            print(table.round(3).to_string(index=False))
        return table
    if "--read-back" in argv:  # --read-back [--before CHECKOUT]: the default sweep's recording
        before = argv[argv.index("--before") + 1] if "--before" in argv else ""
        print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        table = pd.DataFrame(readback_rows(before))
        RESULTS.mkdir(exist_ok=True)
        table.to_csv(RESULTS / "footprint-readback.csv", index=False)
        with pd.option_context("display.width", 250, "display.max_columns", 40):
            print(table.round(2).T.to_string())
        return table
    if argv[:1] == ["--merge-child"]:
        _merge_child(argv[1], argv[2], int(argv[3]))
        return pd.DataFrame()
    n_runs = 100
    if "--resume" in argv:
        at = argv.index("--resume")
        n_runs = int(argv[at + 1])
        argv = argv[:at] + argv[at + 2 :]
    counts = [int(a) for a in argv] or [100, 1000]
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    table = pd.DataFrame(merge_rows(counts) + resume_rows(n_runs))
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "footprint.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.round(2).to_string(index=False))
    return table


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main(sys.argv[1:])
