"""Running a sweep's runs on a Dask cluster (``workbench sweep --scheduler ADDRESS``).

Runs are submitted through ``distributed.Client(address).get_executor()``; each task runs
its run in a child process (``python -m workbench.runs.dask_pool --run-one``) under the
time limit and returns the row and series to the client, which writes them, so the
cluster needs no shared file system.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from workbench.errors import ConfigError, one_line
from workbench.runs import store
from workbench.runs.execute import RunSpec, execute_run, status_row
from workbench.runs.run_log import (
    LOG_TEXT,
    CapturedOutput,
    raw_path,
    raw_text,
    store_log,
    write_log,
)
from workbench.runs.sweep_spec import import_plugin_modules
from workbench.runs.timing import Timing
from workbench.runs.unfinished import (
    RETRIES,
    InfrastructureError,
    died_message,
    killed_from_outside,
    timeout_message,
)
from workbench.runs.worker_env import pin_threads, thread_environment


def run_in_subprocess(
    spec_data: dict[str, Any],
    limit: float,
    plugins: list[str],
    reference_dir: str,
    sys_path: list[str],
    timing: dict[str, Any] | None = None,
) -> tuple[dict[str, Any], Any]:
    """Run one spec in a child process under ``limit`` seconds: (row, series or None).

    Used as the task of a Dask (or any concurrent.futures) executor: the child can be
    killed where a thread cannot, and the result is returned rather than written, so the
    cluster needs no shared file system. InfrastructureError if the child was killed
    from outside (no result of the run; see :mod:`workbench.runs.unfinished`).
    """
    import pandas as pd

    spec = RunSpec.from_dict(spec_data)
    with tempfile.TemporaryDirectory(prefix="workbench-run-") as directory:
        request = {
            "spec": spec_data,
            "plugins": plugins,
            "reference_dir": reference_dir if os.path.isdir(reference_dir) else None,
            "sys_path": sys_path,
            "out": directory,
            "timing": timing or {},
        }
        env = dict(os.environ) | thread_environment()  # read by BLAS/OpenMP as they load
        env["PYTHONPATH"] = os.pathsep.join(
            [p for p in sys_path if p] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])
        )
        try:
            completed = subprocess.run(
                [sys.executable, "-m", "workbench.runs.dask_pool", "--run-one"],
                input=json.dumps(request),
                text=True,
                capture_output=True,
                timeout=limit,
                env=env,
            )
        except subprocess.TimeoutExpired:
            row = status_row(spec, "timeout", timeout_message(limit))
            return row | {LOG_TEXT: raw_text(Path(directory), spec.run_id)}, None
        row = store.read_row(store.row_path(Path(directory), spec.run_id))
        if row is None:
            tail = (completed.stderr or "").strip().splitlines()[-1:] or [""]
            message = died_message(completed.returncode)
            if tail[0]:
                message += f": {tail[0]}"
            if killed_from_outside(completed.returncode):
                raise InfrastructureError(f"run {spec.run_id}: {message}")
            row = status_row(spec, "failed", message)
            return row | {LOG_TEXT: raw_text(Path(directory), spec.run_id)}, None
        if row.get("log"):  # returned with the row; store_log writes it beside the row
            row[LOG_TEXT] = (Path(directory) / row["log"]).read_text("utf-8", "replace")
        series_file = store.series_path(Path(directory), spec.run_id)
        series = pd.read_parquet(series_file) if series_file.exists() else None
        return row, series


def _run_one_main() -> None:
    """``python -m workbench.runs.dask_pool --run-one``: one run from a JSON request on stdin."""
    import warnings

    warnings.filterwarnings("ignore")
    pin_threads()
    request = json.loads(sys.stdin.read())
    for entry in reversed(request.get("sys_path", [])):
        if entry not in sys.path:
            sys.path.append(entry)
    import_plugin_modules(request.get("plugins", []))
    spec = RunSpec.from_dict(request["spec"])
    out = Path(request["out"])
    capture = CapturedOutput(raw_path(out, spec.run_id))
    with capture:  # the run's stdout/stderr (C's too) to its bounded log
        timing = Timing.from_dict(request.get("timing"))
        result = execute_run(spec, reference_dir=request.get("reference_dir"), timing=timing)
    result.row["log"] = write_log(out, spec.run_id, capture.kept())
    store.write_run(out, result.row, result.series)


def run_dask(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    scheduler: str,
    record: Callable[[str], None],
    timing: Timing | None = None,
) -> dict[str, str]:
    """Run ``todo`` on the cluster (timed as ``timing`` says; its ``workers`` become the
    cluster's worker threads, over all its machines); return the runs left without a row
    (run id -> why): those whose task was lost twice (:mod:`workbench.runs.unfinished`)."""
    import concurrent.futures

    try:
        import distributed
    except ImportError as error:
        raise ConfigError(f"--scheduler needs the 'distributed' package: {error}") from None
    try:
        client = distributed.Client(scheduler, timeout="10s")
    except Exception as error:  # noqa: BLE001 - nothing there, or a service that is not Dask
        reason = one_line(error)[:200]  # (another service's reply can be any error)
        raise ConfigError(
            f"cannot connect to the Dask scheduler {scheduler!r}: {reason}; "
            "give the address a `dask scheduler` prints (tcp://host:port)"
        ) from None
    reference_dir = str((out / "references").resolve())
    paths = [str(Path(p).resolve()) if p else os.getcwd() for p in sys.path]
    unfinished: dict[str, str] = {}
    failures: Counter[str] = Counter()
    try:
        executor = client.get_executor(pure=False)
        threads = sum(client.nthreads().values()) or 1
        timed = replace(timing or Timing(), workers=threads).to_dict()

        def submit(spec: RunSpec) -> concurrent.futures.Future:
            return executor.submit(
                run_in_subprocess, spec.to_dict(), limit, plugins, reference_dir, paths, timed
            )

        futures = {submit(spec): spec for spec in todo}
        while futures:
            finished, _ = concurrent.futures.wait(
                futures, return_when=concurrent.futures.FIRST_COMPLETED
            )
            for future in finished:
                spec = futures.pop(future)
                try:
                    row, series = future.result()
                except Exception as error:  # noqa: BLE001 - lost worker, scheduler, child
                    # not a result of the run: once more, then left without a row
                    failures[spec.run_id] += 1
                    reason = _lost_message(error)
                    if failures[spec.run_id] <= RETRIES:
                        with contextlib.suppress(Exception):  # a lost client: unfinished
                            futures[submit(spec)] = spec
                            continue
                    unfinished[spec.run_id] = f"{reason} ({failures[spec.run_id]} attempts)"
                    record("unfinished")
                    continue
                store_log(out, row)
                store.write_run(out, row, series)
                record(row.get("status", "failed"))
    finally:
        client.close()
    return unfinished


def _lost_message(error: BaseException) -> str:
    """Why a Dask task gave no result, in one line (a lost scheduler raises with no text)."""
    if not str(error).strip():
        return f"dask task lost ({type(error).__name__}: its worker or the scheduler was lost)"
    return f"dask task failed: {one_line(error)}"


if __name__ == "__main__":
    if sys.argv[1:] == ["--run-one"]:
        _run_one_main()
    else:
        sys.exit("usage: python -m workbench.runs.dask_pool --run-one < request.json")
