"""Running a sweep's runs on a Dask cluster (``workbench sweep --scheduler ADDRESS``).

Runs are submitted through ``distributed.Client(address).get_executor()``; each task runs
its run in a child process (``python -m workbench.runs.dask_pool --run-one``) under the
time limit and returns the row and series to the client, which writes them, so the
cluster needs no shared file system.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from workbench.errors import ConfigError, one_line
from workbench.runs import store
from workbench.runs.execute import RunSpec, execute_run, status_row
from workbench.runs.sweep_spec import import_plugin_modules
from workbench.runs.unfinished import died_message, timeout_message


def run_in_subprocess(
    spec_data: dict[str, Any],
    limit: float,
    plugins: list[str],
    reference_dir: str,
    sys_path: list[str],
) -> tuple[dict[str, Any], Any]:
    """Run one spec in a child process under ``limit`` seconds: (row, series or None).

    Used as the task of a Dask (or any concurrent.futures) executor: the child can be
    killed where a thread cannot, and the result is returned rather than written, so the
    cluster needs no shared file system.
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
        }
        env = dict(os.environ)
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
            return status_row(spec, "timeout", timeout_message(limit)), None
        row = store.read_row(store.row_path(Path(directory), spec.run_id))
        if row is None:
            tail = (completed.stderr or "").strip().splitlines()[-1:] or [""]
            message = died_message(completed.returncode)
            if tail[0]:
                message += f": {tail[0]}"
            return status_row(spec, "failed", message), None
        series_file = store.series_path(Path(directory), spec.run_id)
        series = pd.read_parquet(series_file) if series_file.exists() else None
        return row, series


def _run_one_main() -> None:
    """``python -m workbench.runs.dask_pool --run-one``: one run from a JSON request on stdin."""
    import warnings

    warnings.filterwarnings("ignore")
    request = json.loads(sys.stdin.read())
    for entry in reversed(request.get("sys_path", [])):
        if entry not in sys.path:
            sys.path.append(entry)
    import_plugin_modules(request.get("plugins", []))
    spec = RunSpec.from_dict(request["spec"])
    result = execute_run(spec, reference_dir=request.get("reference_dir"))
    store.write_run(Path(request["out"]), result.row, result.series)


def run_dask(
    todo: list[RunSpec],
    out: Path,
    limit: float,
    plugins: list[str],
    scheduler: str,
    record: Callable[[str], None],
) -> None:
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
    try:
        executor = client.get_executor(pure=False)
        futures = {
            executor.submit(
                run_in_subprocess, spec.to_dict(), limit, plugins, reference_dir, paths
            ): spec
            for spec in todo
        }
        for future in concurrent.futures.as_completed(futures):
            spec = futures[future]
            try:
                row, series = future.result()
            except Exception as error:  # noqa: BLE001 - a lost task is a failed row
                row, series = status_row(spec, "failed", f"dask task failed: {error}"), None
            store.write_run(out, row, series)
            record(row.get("status", "failed"))
    finally:
        client.close()


if __name__ == "__main__":
    if sys.argv[1:] == ["--run-one"]:
        _run_one_main()
    else:
        sys.exit("usage: python -m workbench.runs.dask_pool --run-one < request.json")
