"""Dask runs in a long-lived child per Dask worker (workbench.runs.dask_pool), on a local
cluster bound to 127.0.0.1: the child keeps its built equations between tasks, a run over
its time limit is a timeout row and the worker's next run gets a fresh child, a child
killed from outside is an infrastructure failure (no row), and a small sweep gives the
local pool's rows."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.test_sweep import spec_text
from workbench.execution.counted_work import COLUMNS as WORK_COLUMNS
from workbench.execution.run_log import raw_path
from workbench.execution.timing import TIMING_COLUMNS
from workbench.runs import store
from workbench.runs.dask_pool import run_on_worker_child
from workbench.runs.sweep import parse_spec, run_sweep
from workbench.runs.unfinished import InfrastructureError

distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")

HUNG = 600  # s: only a hung cluster reaches it


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as local:
        with distributed.Client(local.scheduler_address) as client:
            yield local, client


def workers(client) -> dict:
    """The cluster's two workers, once both are registered: on a loaded machine the client
    can connect before the second worker has (CI once found one)."""
    client.wait_for_workers(2, timeout=HUNG)
    return client.scheduler_info()["workers"]


def submit(client, spec, limit: float, worker: str):
    """One run as a task on ``worker`` (the task run_dask submits)."""
    paths = [os.getcwd(), *sys.path]
    return client.submit(
        run_on_worker_child,
        spec.to_dict(),
        limit,
        ["tests.fake_plugins"],
        "",
        paths,
        workers=[worker],
        pure=False,
    )


def children(client, worker: str) -> list[int]:
    """Pids of the workbench children of a Dask worker."""
    pid = client.run(os.getpid, workers=[worker])[worker]
    return [p.pid for p in psutil.Process(pid).children() if "--serve" in " ".join(p.cmdline())]


def runs_of(tmp_path, integrators: str):
    return parse_spec(spec_text(tmp_path, integrators)).runs


def test_a_worker_child_keeps_its_equations_and_survives_a_timeout(
    fake_plugins,
    cluster,
    tmp_path,
) -> None:
    _, client = cluster
    worker = sorted(workers(client))[0]
    first, second = runs_of(tmp_path, '["test-rk45"]')  # same equations, two tolerances
    (hung, _) = runs_of(tmp_path, '["test-hang"]')
    row, series = submit(client, first, HUNG, worker).result(timeout=HUNG)
    assert row["status"] == "ok" and series is not None and len(series) > 0
    (child,) = children(client, worker)
    row, _ = submit(client, second, HUNG, worker).result(timeout=HUNG)
    assert row["status"] == "ok"
    assert row["equations_cached"]  # built by the first task: a fresh process per run is not
    assert children(client, worker) == [child]
    # a hung run is killed at its limit (2 s; a loaded machine is slow, not hung forever)
    row, series = submit(client, hung, 2.0, worker).result(timeout=HUNG)
    assert row["status"] == "timeout" and "time limit of 2 s" in row["message"]
    assert row["stage"] == "integrate" and "killed in stage 'integrate'" in row["message"]
    assert series is None and not psutil.pid_exists(child)
    row, _ = submit(client, first, HUNG, worker).result(timeout=HUNG)
    assert row["status"] == "ok" and not row["equations_cached"]  # a fresh child
    assert len(children(client, worker)) == 1


def test_a_child_killed_from_outside_is_no_row_and_the_next_run_works(
    fake_plugins,
    cluster,
    tmp_path,
) -> None:
    _, client = cluster
    worker = sorted(workers(client))[1]
    (hung, _) = runs_of(tmp_path, '["test-hang"]')
    future = submit(client, hung, HUNG, worker)
    deadline = time.monotonic() + HUNG
    while not children(client, worker) and time.monotonic() < deadline:
        time.sleep(0.2)
    (child,) = children(client, worker)
    os.kill(child, signal.SIGKILL)  # as an operator or the OOM killer would
    with pytest.raises(InfrastructureError, match="SIGKILL"):
        future.result(timeout=HUNG)
    ok, _ = runs_of(tmp_path, '["test-rk45"]')
    row, _ = submit(client, ok, HUNG, worker).result(timeout=HUNG)
    assert row["status"] == "ok"


def test_a_later_sweeps_child_replaces_an_earlier_sweeps_idle_one(
    fake_plugins,
    cluster,
    tmp_path,
) -> None:
    """A task of another setting (here another OUT's references) starts a child of its own;
    the earlier one, idle, is closed (one idle child a worker thread), not kept until the
    worker stops: a campaign of sweeps on one cluster grew by a child (300 MB) a sweep."""
    _, client = cluster
    worker = sorted(workers(client))[0]
    ok, _ = runs_of(tmp_path, '["test-rk45"]')
    (tmp_path / "references").mkdir()
    for reference_dir in ("", str(tmp_path / "references")):  # two sweeps' settings
        paths = [os.getcwd(), *sys.path]
        future = client.submit(
            run_on_worker_child, ok.to_dict(), HUNG, ["tests.fake_plugins"], reference_dir,
            paths, workers=[worker], pure=False,
        )  # fmt: skip
        row, _ = future.result(timeout=HUNG)
        assert row["status"] == "ok"
    assert len(children(client, worker)) == 1


def test_a_small_sweep_gives_the_local_pools_rows(
    fake_plugins,
    cluster,
    tmp_path,
) -> None:
    local, _ = cluster
    text = spec_text(tmp_path / "local", '["test-rk45", "test-rk4", "test-die"]')
    run_sweep(parse_spec(text), show_progress=False)
    text = spec_text(tmp_path / "dask", '["test-rk45", "test-rk4", "test-die"]')
    run_sweep(parse_spec(text), scheduler=local.scheduler_address, show_progress=False)
    rows = [
        store.load_results(tmp_path / name).set_index("run_id").sort_index()
        for name in ("local", "dask")
    ]
    for frame in rows:  # whichever worker came first computed the reference, others read it
        frame["reference"] = frame["reference"].str.replace(r" \(read from .*\)$", "", regex=True)
        # a crashed worker's row says where it was after how long (wall time: machine's)
        frame["message"] = frame["message"].str.replace(r"; killed in stage .*$", "", regex=True)
    assert len(rows[0]) == 6 and set(rows[0]["status"]) == {"ok", "failed"}
    assert list(rows[0].index) == list(rows[1].index)
    # where a crashed run was is read from its progress file, which it may die before
    # writing: the stage of a crash is not part of the result
    timings = {"equations_cached", "stage", "t_reached", *TIMING_COLUMNS, *WORK_COLUMNS}
    columns = [c for c in rows[0].columns if not c.endswith("_s") and c not in timings]
    different = [
        c
        for c in columns
        if not ((rows[0][c] == rows[1][c]) | (rows[0][c].isna() & rows[1][c].isna())).all()
    ]
    assert different == [], rows[0][different].compare(rows[1][different]).to_string()


def test_the_python_api_sweeps_on_the_cluster(cluster, tmp_path) -> None:
    """``workbench.sweep(..., scheduler=ADDRESS)`` runs on the cluster as ``workbench sweep
    --scheduler`` does: before, the keyword was refused as an unknown specification key."""
    import workbench as wb
    from workbench.errors import ConfigError

    local, _ = cluster
    keys = {"problems": ["simple-pendulum"], "formalisms": ["minimal-ode"],
            "integrators": ["rk4"], "tolerances": [1e-4]}  # fmt: skip
    here = wb.sweep(out=tmp_path / "local", **keys)
    there = wb.sweep(out=tmp_path / "dask", scheduler=local.scheduler_address, **keys)
    assert list(there["status"]) == ["ok"]
    assert (tmp_path / "dask" / "logs" / "dask-client.log").exists()  # it went to Dask
    assert there["scd"].tolist() == here["scd"].tolist()
    assert there["run_id"].tolist() == here["run_id"].tolist()
    with pytest.raises(ConfigError, match="in_process=True"):
        wb.sweep(out=tmp_path / "both", scheduler=local.scheduler_address, in_process=True, **keys)


def test_a_worker_missing_a_plugins_dependency_says_to_install_it(
    cluster, tmp_path, monkeypatch
) -> None:
    """A local plugin module importing a module the client has and the workers have not:
    its runs are left unfinished with a reason that names the module and says to install
    it on the workers, not only that the task failed."""
    import types

    from tests.test_local_plugins import HELPER
    from tests.test_local_plugins import spec_text as local_spec
    from workbench.plugin import local_modules
    from workbench.plugin.registry import REGISTRY
    from workbench.runs.sweep import load_spec

    local, _ = cluster
    monkeypatch.setitem(sys.modules, "labutil", types.ModuleType("labutil"))  # client only
    monkeypatch.delenv(local_modules.NO_LOCAL_PLUGINS_VARIABLE, raising=False)
    REGISTRY.discover()
    for kind, entries in REGISTRY.entries.items():
        monkeypatch.setitem(REGISTRY.entries, kind, dict(entries))
    (tmp_path / "lab.py").write_text("import labutil\n" + HELPER)
    (tmp_path / "sweep.toml").write_text(local_spec(tmp_path / "out", plugins='["lab"]'))
    try:
        summary = run_sweep(
            load_spec(tmp_path / "sweep.toml"), scheduler=local.scheduler_address,
            show_progress=False,
        )  # fmt: skip
    finally:
        sys.modules.pop("lab", None)
        local_modules._FROM_FILES.pop("lab", None)
    (why,) = summary.unfinished.values()
    assert "No module named 'labutil'" in why and "install what it needs on every worker" in why


@pytest.mark.slow  # a cluster started empty, then a worker: about 20 s
def test_a_scheduler_without_workers_is_said_and_the_runs_wait_for_one(
    fake_plugins, tmp_path, monkeypatch
) -> None:
    """Before, a sweep on a scheduler with no worker printed its plan and then nothing at
    all, and gave a run up each time scattering its data found no worker (70 s); it now
    says that it waits for a worker and how to start one, and the runs go when one
    connects, however late (here after the scatter's time, shortened to 3 s)."""
    import threading

    from workbench.runs import dask_pool

    monkeypatch.setattr(dask_pool, "SCATTER_S", 1.0)
    monkeypatch.setattr(dask_pool, "LOST_AFTER_S", 2.0)

    lines: list[str] = []
    with distributed.LocalCluster(
        n_workers=0, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as empty:  # fmt: skip

        def add_a_worker() -> None:  # once the sweep said it waits (or too late: it failed)
            deadline = time.monotonic() + 60
            while not any("waiting for a Dask worker" in line for line in lines):
                if time.monotonic() > deadline:
                    break
                time.sleep(0.2)
            time.sleep(8)  # longer than a scatter may wait
            empty.scale(1)

        helper = threading.Thread(target=add_a_worker)
        helper.start()
        text = spec_text(tmp_path / "dask", '["test-rk45"]')
        summary = run_sweep(
            parse_spec(text), scheduler=empty.scheduler_address, show_progress=False,
            say=lines.append,
        )  # fmt: skip
        helper.join()
    said = [line for line in lines if "waiting for a Dask worker" in line]
    assert len(said) == 1 and f"dask worker {empty.scheduler_address}" in said[0]
    assert not summary.unfinished and summary.counts["ok"] == 2


IMPORTED = """
import os
with open(os.environ["WORKBENCH_TEST_IMPORTS"], "a") as log:
    log.write("{folder} " + __name__ + "\\n")
"""


@pytest.mark.parametrize("child", ["worker child", "run-one"])
def test_the_workers_own_packages_go_before_the_clients_paths(
    fake_plugins, tmp_path, monkeypatch, child
) -> None:
    """A client's sys.path entry that also exists on the worker (another Python's
    site-packages, an old checkout) came first in the child (on its PYTHONPATH, and put in
    front by the worker loop), so it shadowed the worker's installed packages: a module both
    have now resolves to the worker's, and one only the client's path has still imports."""
    from workbench.runs.dask_pool import _Child, run_in_subprocess

    client, worker = tmp_path / "client", tmp_path / "worker"
    for folder in (client, worker):
        folder.mkdir()
        (folder / "shadowed_module.py").write_text(IMPORTED.format(folder=folder.name))
    (client / "client_only_module.py").write_text(IMPORTED.format(folder="client"))
    log = tmp_path / "imports.log"
    monkeypatch.setenv("WORKBENCH_TEST_IMPORTS", str(log))
    own = [str(worker), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(own))  # the worker's own packages
    plugins = ("shadowed_module", "client_only_module", "tests.fake_plugins")
    paths = (str(client), os.getcwd(), *sys.path)  # as run_dask sends them
    if child == "worker child":
        _Child((plugins, paths, None, (), None)).close()  # ready: its plugins imported
    else:
        (spec, _) = runs_of(tmp_path, '["test-rk45"]')
        row, _ = run_in_subprocess(spec.to_dict(), HUNG, list(plugins), "", list(paths))
        assert row["status"] == "ok"
    assert log.read_text().splitlines() == [
        "worker shadowed_module",
        "client client_only_module",
    ]


PARENT = """
import json, sys, time
from workbench.runs.dask_pool import _Child
child = _Child((("tests.fake_plugins",), tuple(sys.path), None, (), None))
if sys.argv[1:]:
    child.conn.send(json.loads(sys.argv[1]))  # a run: the child is busy when we die
print(child.process.pid, child.out, flush=True)
time.sleep(600)
"""


@pytest.mark.parametrize("busy", [False, True], ids=["idle", "mid-run"])
def test_a_child_whose_dask_worker_was_killed_exits_and_removes_its_directory(
    fake_plugins, tmp_path, busy
) -> None:
    """The worker (here a script holding one child) is SIGKILLed, so it cleans nothing up:
    the child notices (its socket closes, or its parent's pid changes while it runs a
    hung run), removes its scratch directory and exits."""
    import json

    (hung, _) = runs_of(tmp_path, '["test-hang"]')
    argv = [json.dumps(hung.to_dict())] if busy else []
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, *argv], stdout=subprocess.PIPE, text=True, cwd=os.getcwd()
    )
    try:
        pid, out = parent.stdout.readline().split()
        child = psutil.Process(int(pid))
        if busy:  # the hung run has started: its raw output file exists
            deadline = time.monotonic() + HUNG
            while not raw_path(Path(out), hung.run_id).exists() and time.monotonic() < deadline:
                time.sleep(0.1)
        assert os.path.isdir(out)
        parent.kill()
        parent.wait()
        child.wait(timeout=HUNG)  # psutil: the child is not ours, it is reaped by init
        assert not os.path.exists(out)
    finally:
        parent.kill()
        parent.wait()
