"""Resuming a sweep: broken rows and series are found and redone, stale rows are found,
``--rerun`` and ``--fresh`` redo what they name, infrastructure failures are no results."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pandas as pd
import pytest

from tests.test_sweep import spec_text
from workbench.execution import row_schema
from workbench.runs import store
from workbench.runs.sweep import parse_spec, run_sweep

FALLING = '["test-falling"]'  # an analytic reference: no reference pipeline to run


@pytest.fixture(autouse=True)
def fresh_workers(monkeypatch):
    """Workers started by spawn: each imports the plugins anew from their files and sees
    the environment of the moment, as the workers of a new `workbench sweep` do (a fork or
    a forkserver started by an earlier test would hand them the modules it had loaded)."""
    import multiprocessing

    from workbench.runs import local_pool

    monkeypatch.setattr(local_pool, "worker_context", lambda: multiprocessing.get_context("spawn"))


def sweep_lines(text: str, **options) -> tuple[object, list[str]]:
    lines: list[str] = []
    summary = run_sweep(parse_spec(text), show_progress=False, say=lines.append, **options)
    return summary, lines


def test_broken_rows_and_series_are_named_and_redone(fake_plugins, tmp_path) -> None:
    text = spec_text(tmp_path, '["test-rk45"]', problems=FALLING)
    first, _ = sweep_lines(text)
    assert first.counts["ok"] == 2
    frame = store.load_results(tmp_path)
    a, b = sorted(frame["run_id"])
    samples = int(frame.set_index("run_id").loc[b, "n_samples"])
    assert samples == 11  # the problem's output times, all stored
    # a "row" with nothing but its id (counted as done before, then a TypeError in the report)
    store.row_path(tmp_path, a).write_text(json.dumps({"run_id": a}))
    # a truncated series
    series_b = store.series_path(tmp_path, b)
    whole = series_b.read_bytes()
    series_b.write_bytes(whole[: len(whole) // 2])
    with pytest.warns(UserWarning, match=f"{a}.json .*no problem"):
        frame = store.load_results(tmp_path)
    assert list(frame["run_id"]) == [b]
    with pytest.warns(UserWarning, match=f"{b}.parquet"):
        assert len(store.load_series(tmp_path)) == samples  # a's, whole; b's left out
    assert store.completed_run_ids(tmp_path) == set()
    again, lines = sweep_lines(text)
    assert again.total == 2 and again.counts["ok"] == 2 and again.already_done == 0
    assert any(line.startswith(f"run {a} (test-falling") and "no problem" in line for line in lines)
    assert any(f"run {b}" in line and "unreadable" in line for line in lines), lines
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sorted(store.load_results(tmp_path)["run_id"]) == [a, b]
        assert len(store.load_series(tmp_path)) == 2 * samples
    # a whole Parquet file, but fewer samples than the row says
    pd.read_parquet(series_b).iloc[:3].to_parquet(series_b, index=False)
    third, lines = sweep_lines(text)
    assert third.total == 1
    assert any(f"has 3 samples, the row says {samples}" in line for line in lines), lines
    assert len(store.load_series(tmp_path, b)) == samples


# ---- stale rows: a row records what produced it ----------------------------------------

PLANTED = """
import copy

from workbench.plugin.registry import formalism
from workbench.plugins.formalisms.minimal_ode import MinimalOde

GRAVITY_FACTOR = {factor}


@formalism
class Planted(MinimalOde):
    name = "test-planted"
    summary = "minimal-ode with gravity scaled by GRAVITY_FACTOR (a planted bug at 1.05)"

    def build(self, model, options=None):
        model = copy.deepcopy(model)
        model.gravity = model.gravity * GRAVITY_FACTOR
        return super().build(model, options)
"""


def plant(directory: Path, factor: str) -> None:
    """(Re)write and (re)import the formalism module ``planted_formalism``."""
    import importlib
    import sys

    from workbench.plugin.registry import REGISTRY

    (directory / "planted_formalism.py").write_text(PLANTED.format(factor=factor))
    sys.modules.pop("planted_formalism", None)
    REGISTRY.entries["formalism"].pop("test-planted", None)
    importlib.invalidate_caches()
    importlib.import_module("planted_formalism")


def test_a_fixed_plugin_makes_its_rows_stale_and_rerun_stale_redoes_them(
    fake_plugins,
    tmp_path,
    monkeypatch,
) -> None:
    """The scenario of issue 22: plant a bug, sweep, fix it, sweep again."""
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    text = spec_text(out, '["test-rk45"]', problems=FALLING).replace(
        '"minimal-ode", options = { index = [1] }', '"test-planted"'
    )
    text = text.replace(
        'plugins = ["tests.fake_plugins"]', 'plugins = ["tests.fake_plugins", "planted_formalism"]'
    )
    plant(tmp_path, "1.05")  # the bug: gravity 5 % too strong
    first, _ = sweep_lines(text)
    assert first.counts["ok"] == 2
    buggy = store.load_results(out).set_index("run_id")
    # the analytic reference y = -g t^2 / 2 at t = 1 s: the planted bug is 0.05 g / 2 off
    assert buggy["err_end"].to_numpy() == pytest.approx(0.05 * 9.81 / 2, rel=1e-3)
    plant(tmp_path, "1.0")  # fixed
    kept, lines = sweep_lines(text)
    assert kept.total == 0 and len(kept.stale) == 2
    assert "resuming: 2 of 2 done (2 stale)" in lines
    warning = next(line for line in lines if "STALE" in line)
    assert "producer_formalism sha256:" in warning and "--rerun stale" in warning
    assert store.load_results(out).set_index("run_id")["scd"].equals(buggy["scd"])
    # the report marks them (a warning: shown as such and never recommended)
    from workbench.outputs.report.analysis import warning_kinds
    from workbench.runs.resume import mark_stale

    marked = mark_stale(store.load_results(out), kept.stale)
    assert all("stale" in warning_kinds(w) for w in marked["warnings"])
    # and so does a report made later by `workbench report`, which imports no plugin of
    # the sweep's (it showed the rows as trusted again)
    from workbench.outputs.report.writer import report_directory
    from workbench.runs.resume import stale_in_plan

    assert stale_in_plan(store.load_plan(out), store.load_results(out)) == kept.stale
    index = report_directory(out, tmp_path / "later-report")
    assert "ok with warnings: stale, redo with `workbench sweep --rerun stale`" in (
        index.read_text()
    )
    redone, lines = sweep_lines(text, rerun={"stale"})
    assert redone.total == 2 and redone.counts["ok"] == 2 and redone.stale == {}
    assert stale_in_plan(store.load_plan(out), store.load_results(out)) == {}
    assert any(line.startswith("redoing 2 stale row(s)") for line in lines)
    fixed = store.load_results(out).set_index("run_id")
    assert (fixed["scd"] > buggy["scd"] + 3).all()  # 0.05 g/2 off -> the rk45 tolerance
    assert (fixed["producer_formalism"] != buggy["producer_formalism"]).all()
    assert (fixed["producer_problem"] == buggy["producer_problem"]).all()
    _, lines = sweep_lines(text)
    assert "resuming: 2 of 2 done (0 stale)" in lines


def test_a_producer_does_not_depend_on_where_the_plugin_file_lies(tmp_path) -> None:
    """Moving files (as the split of runs/ into execution/ did) makes no row stale: a
    producer hashes the modules of a plugin's class hierarchy by name and source, never by
    path; an edited source does change it."""
    import importlib
    import sys

    from workbench.execution.producer import plugin_producer

    source = "from workbench.plugin.formalism import Formalism\n\n\nclass Moved(Formalism):\n"
    producers, files = [], []
    for folder, body in [
        ("here", "    pass\n"),
        ("there/deeper", "    pass\n"),
        ("edited", "    x = 1\n"),
    ]:
        directory = tmp_path / folder
        directory.mkdir(parents=True)
        (directory / "moved_plugin.py").write_text(source + body)
        sys.path.insert(0, str(directory))
        sys.modules.pop("moved_plugin", None)
        importlib.invalidate_caches()
        try:
            module = importlib.import_module("moved_plugin")
            files.append(module.__file__)
            producers.append(plugin_producer(module.Moved))  # reads sys.modules' file
        finally:
            sys.path.remove(str(directory))
            sys.modules.pop("moved_plugin", None)
    assert len(set(files)) == 3  # three files, each imported from its own folder
    assert producers[0].startswith("sha256:")
    assert producers[0] == producers[1] != producers[2]


def test_rows_of_an_older_schema_have_an_unknown_producer_not_stale(
    fake_plugins,
    tmp_path,
) -> None:
    text = spec_text(tmp_path, '["test-rk45"]', problems=FALLING)
    sweep_lines(text)
    for path in (tmp_path / "runs").glob("*.json"):  # as schema 3 wrote them
        row = json.loads(path.read_text())
        for column in [*row_schema.PRODUCER_COLUMNS, "n_samples"]:
            row.pop(column)
        path.write_text(json.dumps(row | {"schema_version": 3}))
    again, lines = sweep_lines(text)
    assert again.total == 0 and again.stale == {}
    assert "resuming: 2 of 2 done (0 stale)" in lines
    assert any("2 done row(s) do not record what produced them" in line for line in lines)
    assert set(store.load_results(tmp_path)["producer_formalism"]) == {"unknown"}


# ---- --rerun failed, timeout; --fresh ---------------------------------------------------


def test_rerun_redoes_timeouts_and_failures_and_fresh_redoes_all(
    fake_plugins,
    tmp_path,
    monkeypatch,
) -> None:
    from tests.fake_plugins import FLAKY

    text = spec_text(tmp_path, '["test-flaky"]', problems=FALLING)
    monkeypatch.setenv(FLAKY, "hang")
    # a limit only the hung runs reach: whatever the load, they time out
    hung, _ = sweep_lines(text, time_limit=3.0)
    assert hung.counts["timeout"] == 2
    monkeypatch.setenv(FLAKY, "raise")
    again, _ = sweep_lines(text)
    assert again.total == 0  # a timeout row is done unless told otherwise
    failed, _ = sweep_lines(text, rerun={"timeout"})
    assert failed.counts["failed"] == 2
    assert set(store.load_results(tmp_path)["status"]) == {"failed"}
    monkeypatch.delenv(FLAKY)
    assert sweep_lines(text, rerun={"timeout"})[0].total == 0  # none left
    ok, _ = sweep_lines(text, rerun={"failed"})
    assert ok.counts["ok"] == 2
    frame = store.load_results(tmp_path)
    assert set(frame["status"]) == {"ok"} and len(frame) == 2
    # each row file written again: (inode, mtime) as the pool's row_stamp tells them (a
    # row is written in place after the old one is removed, which may free its inode)
    stamp = lambda p: (p.stat().st_ino, p.stat().st_mtime_ns)  # noqa: E731
    before = {p.name: stamp(p) for p in (tmp_path / "runs").glob("*.json")}
    fresh, lines = sweep_lines(text, fresh=True)
    assert fresh.counts["ok"] == 2 and any(
        line.startswith("fresh: redoing all 2") for line in lines
    )
    after = {p.name: stamp(p) for p in (tmp_path / "runs").glob("*.json")}
    assert before.keys() == after.keys() and all(before[k] != after[k] for k in before)


def test_a_rerun_that_times_out_replaces_the_old_row(fake_plugins, tmp_path, monkeypatch) -> None:
    """The old row of a re-run is not mistaken for one its attempt wrote."""
    from tests.fake_plugins import FLAKY

    text = spec_text(tmp_path, '["test-flaky"]', problems=FALLING)
    monkeypatch.setenv(FLAKY, "raise")
    sweep_lines(text)
    monkeypatch.setenv(FLAKY, "hang")
    summary, _ = sweep_lines(text, rerun={"failed"}, time_limit=3.0)
    assert summary.counts == {"timeout": 2}
    assert set(store.load_results(tmp_path)["status"]) == {"timeout"}


def test_rerun_kinds_are_checked() -> None:
    from workbench.errors import ConfigError
    from workbench.runs.resume import parse_rerun

    assert parse_rerun("failed, stale") == {"failed", "stale"}
    with pytest.raises(ConfigError, match="unknown kind 'stal'"):
        parse_rerun("failed,stal")


# ---- infrastructure failures are not results --------------------------------------------


def test_a_worker_killed_from_outside_is_retried_once(fake_plugins, tmp_path, monkeypatch) -> None:
    from tests.fake_plugins import FLAKY, FLAKY_MARKER

    text = spec_text(tmp_path, '["test-flaky"]', problems=FALLING).replace(
        "tolerances = [1e-4, 1e-6]", "tolerances = [1e-6]"
    )
    monkeypatch.setenv(FLAKY, "kill-once")
    monkeypatch.setenv(FLAKY_MARKER, str(tmp_path / "killed"))
    summary, _ = sweep_lines(text)
    assert (tmp_path / "killed").exists()  # its first worker was SIGKILLed
    assert summary.counts == {"ok": 1} and summary.unfinished == {}
    assert list(store.load_results(tmp_path)["status"]) == ["ok"]


def test_a_run_whose_worker_is_killed_twice_has_no_row_and_resume_redoes_it(
    fake_plugins,
    tmp_path,
    monkeypatch,
) -> None:
    from typer.testing import CliRunner

    from tests.fake_plugins import FLAKY
    from workbench.cli import app

    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(tmp_path / "out", '["test-flaky"]', problems=FALLING))
    monkeypatch.setenv(FLAKY, "kill")
    monkeypatch.setattr("sys.argv", ["workbench", "sweep", str(spec), "--rerun", "failed"])
    result = CliRunner().invoke(app, ["sweep", str(spec), "--rerun", "failed"])
    assert result.exit_code == 1, result.output
    assert "2 run(s) could not be completed, not by their own fault" in result.output
    assert "worker process died (exit code -9, SIGKILL) 2 times" in result.output
    assert f"resume with `workbench sweep {spec}`" in result.output.replace("\n", "")
    assert not list((tmp_path / "out" / "runs").glob("*.json"))  # no failed rows
    monkeypatch.delenv(FLAKY)
    summary, _ = sweep_lines(spec.read_text())
    assert summary.counts == {"ok": 2} and summary.already_done == 0


@pytest.mark.slow
@pytest.mark.timeout(900)  # 52-108 s at load 7-10; a hung scatter held it forever
def test_dask_lost_tasks_are_retried_once_then_left_unfinished(
    fake_plugins,
    tmp_path,
    monkeypatch,
) -> None:
    """A Dask worker killed under its task, and a run's child killed from outside."""
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    from tests.fake_plugins import FLAKY, FLAKY_MARKER

    text = spec_text(tmp_path, '["test-flaky"]', problems=FALLING).replace(
        "tolerances = [1e-4, 1e-6]", "tolerances = [1e-6]"
    )
    monkeypatch.setenv(FLAKY_MARKER, str(tmp_path / "killed"))
    # the keys of the data the sweep ships: one reused just after its release could be
    # freed under the retry (its run left unfinished) or hang the broadcast's replication
    keys = []
    scatter = distributed.Client.scatter

    def scatter_and_note(client, *args, **kwargs):
        futures = scatter(client, *args, **kwargs)
        keys.extend(future.key for future in futures)
        return futures

    monkeypatch.setattr(distributed.Client, "scatter", scatter_and_note)

    def sweep_on_a_cluster(mode: str, **options):
        monkeypatch.setenv(FLAKY, mode)  # before the cluster: its workers' environment
        with distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster:
            # 120 s: a task's limit covers its child's start-up; only a hung run reaches it
            return sweep_lines(
                text, time_limit=120.0, scheduler=cluster.scheduler_address, **options
            )[0]

    # the scheduler gives up on a task at its first lost worker (KilledWorker): our retry
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        lost_once = sweep_on_a_cluster("kill-parent-once")
    assert (tmp_path / "killed").exists()  # a Dask worker was killed
    assert lost_once.counts == {"ok": 1} and lost_once.unfinished == {}, lost_once.unfinished
    assert len(keys) >= 4 and len(set(keys)) == len(keys), keys  # shipped again, new keys
    killed = sweep_on_a_cluster("kill", fresh=True)
    assert killed.counts == {"unfinished": 1}
    (reason,) = killed.unfinished.values()
    assert "SIGKILL" in reason and "(2 attempts)" in reason
    assert list(store.load_results(tmp_path)["status"]) == ["ok"]  # the old row is kept


def test_a_sweep_into_a_folder_of_another_sweep_says_so(fake_plugins, tmp_path) -> None:
    """A different specification swept into an existing OUT mixed with its rows without
    a word (the report said so only later)."""
    first, _ = sweep_lines(spec_text(tmp_path, '["test-rk45"]', problems=FALLING))
    assert first.counts["ok"] == 2
    again = spec_text(tmp_path, '["test-rk4"]', problems=FALLING)
    second, lines = sweep_lines(again)
    assert second.counts["ok"] == 2 and len(store.load_results(tmp_path)) == 4
    (said,) = [line for line in lines if "of other sweeps" in line]
    assert said.startswith("the folder holds 2 row(s) of other sweeps")
    _, lines = sweep_lines(again)  # the same sweep again: its own 2, the other's 2
    assert any("holds 2 row(s) of other sweeps" in line for line in lines)


def test_a_report_names_ok_runs_whose_series_file_is_gone(fake_plugins, tmp_path) -> None:
    """A deleted series file changed nothing the report said (its curves just went)."""
    from workbench.outputs.report.writer import report_directory

    first, _ = sweep_lines(spec_text(tmp_path, '["test-rk45"]', problems=FALLING))
    assert first.counts["ok"] == 2
    gone = sorted(store.load_results(tmp_path)["run_id"])[0]
    store.series_path(tmp_path, gone).unlink()
    with pytest.warns(UserWarning, match=f"1 ok run.s. have no time series file .e.g. {gone}"):
        report_directory(tmp_path, tmp_path / "report-again")
