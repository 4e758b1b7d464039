"""No file the workbench writes, replaces or deletes under OUT goes through a symbolic link
(issue 31.2): a link planted anywhere in OUT, or one of OUT's folders being a link, is one
line and exit 2, and the file or folder it points to is untouched (content and mtime).
``--fresh`` deletes only what the workbench wrote."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tests.test_sweep import spec_text
from workbench import cli, files
from workbench.execution.run_log import CapturedOutput, bounded, salvage_log, write_log
from workbench.runs import store
from workbench.runs.sweep import parse_spec, run_sweep

# (what the link is planted as, relative to OUT); {id} is a run id of the sweep
PLANTED_FILES = [
    "logs/.{id}.raw",  # the raw output of a run: once truncated through the link
    "logs/{id}.log",
    "runs/{id}.json",
    "series/{id}.parquet",
    "recordings/{id}.rrd",
    "references/test-pendulum.parquet",
    "report/index.html",
    "report/tables/summary.csv",
    "report/figures/work-precision-test-pendulum.png",
    "results.parquet",
    "environment.json",
    "sweep.toml",
    "recording.rrd",
    ".workbench.lock",
    "runs/.{id}.json.123-0123abcd.tmp",  # a temporary's name: removed on resume
]
PLANTED_FOLDERS = [
    "runs",
    "series",
    "logs",
    "recordings",
    "references",
    "report",
    "report/tables",
    "report/figures",
]


@pytest.fixture
def runner(monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    return CliRunner()


def state(path: Path) -> object:
    """What must not change: a file's bytes and mtime, or a folder's listing with those."""
    if path.is_dir():
        return sorted((p.name, p.read_bytes(), p.stat().st_mtime_ns) for p in path.iterdir())
    return path.read_bytes(), path.stat().st_mtime_ns


def plant(out: Path, where: str, victim: Path) -> Path:
    link = out / where
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(victim)
    return link


def sweep_spec(tmp_path: Path, out: Path) -> Path:
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(out, '["test-rk45"]'))
    return spec


def assert_refused(result, link: Path) -> None:
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert lines[-1].startswith("error: ") and "symbolic link" in lines[-1], result.output
    assert str(link) in lines[-1]
    assert "Traceback" not in result.output


def victims(tmp_path: Path) -> tuple[Path, Path]:
    """A file and a folder outside OUT that a link may point to."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    folder = tmp_path / "victim-folder"
    folder.mkdir()
    (folder / "keep.txt").write_text("also precious\n")
    os.utime(victim, ns=(10**18, 10**18))  # an mtime a write cannot give by chance
    return victim, folder


@pytest.mark.parametrize("where", PLANTED_FILES + [f + "/" for f in PLANTED_FOLDERS])
def test_a_planted_link_is_one_line_and_exit_2_and_its_target_untouched(
    fake_plugins, tmp_path, runner, where
) -> None:
    victim, folder = victims(tmp_path)
    out = tmp_path / "out"
    spec = sweep_spec(tmp_path, out)
    run_id = parse_spec(spec.read_text()).runs[0].run_id
    target = folder if where.endswith("/") else victim
    link = plant(out, where.rstrip("/").format(id=run_id), target)
    before = state(target)
    result = runner.invoke(cli.app, ["sweep", str(spec), "--out", str(out), "--fresh"])
    assert_refused(result, link)
    assert state(target) == before
    assert link.is_symlink()  # not deleted either: the user decides


@pytest.mark.parametrize("command", ["report", "run"])
def test_report_and_run_refuse_a_planted_link(fake_plugins, tmp_path, runner, command) -> None:
    victim, _ = victims(tmp_path)
    out = tmp_path / "out"
    run_sweep(parse_spec(spec_text(out, '["test-rk45"]')), show_progress=False)
    link = plant(out, "report/index.html" if command == "report" else "logs/x.log", victim)
    before = state(victim)
    if command == "report":
        arguments = ["report", str(out)]
    else:
        arguments = ["run", "test-pendulum", "-f", "minimal-ode", "-i", "test-rk45"]
        arguments += ["--out", str(out)]
    result = runner.invoke(cli.app, arguments)
    assert_refused(result, link)
    assert state(victim) == before


def test_fresh_deletes_only_what_the_workbench_wrote(fake_plugins, tmp_path, runner) -> None:
    out = tmp_path / "out"
    spec = sweep_spec(tmp_path, out)
    run_id = parse_spec(spec.read_text()).runs[0].run_id
    theirs = [
        out / "notes.txt",
        out / ".backup.tmp",  # a hidden .tmp of the user's, not of atomic_write's pattern
        out / "runs" / ".my-draft.tmp",
        out / "logs" / "other.raw",
    ]
    for path in theirs:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("the user's\n")
    ours = out / "runs" / f".{run_id}.json.4242-deadbeef.tmp"  # left by a killed writer
    ours.write_text("{")
    result = runner.invoke(cli.app, ["sweep", str(spec), "--out", str(out), "--fresh"])
    assert result.exit_code == 0, result.output
    assert all(path.read_text() == "the user's\n" for path in theirs)
    assert not ours.exists()


# -- the writers themselves (a link planted while a command runs) ----------------------
def test_captured_output_does_not_follow_a_link_at_the_raw_file(tmp_path) -> None:
    victim, _ = victims(tmp_path)
    out = tmp_path / "out"
    raw = plant(out, "logs/.abc.raw", victim)
    before = state(victim)
    with pytest.raises(files.LinkRefusedError, match="symbolic link"):
        with CapturedOutput(raw):
            print("a run's output")
    assert state(victim) == before
    with pytest.raises(OSError):
        bounded(raw)  # reading a killed run's output does not follow it either
    assert salvage_log(out, "abc") == ""  # nothing of the victim's copied into a log
    assert not (out / "logs" / "abc.log").exists()


def test_writers_refuse_a_linked_folder_or_file_below_out(tmp_path) -> None:
    victim, folder = victims(tmp_path)
    out = tmp_path / "out"
    plant(out, "logs", folder)
    before = state(folder)
    with pytest.raises(files.LinkRefusedError):
        write_log(out, "abc", b"output")
    plant(out, "runs", folder)
    row = {"run_id": "abc", "status": "ok"}
    with pytest.raises(files.LinkRefusedError):
        store.write_run(out, row, None)
    assert state(folder) == before
    link = plant(out, "series/abc.parquet", victim)
    with pytest.raises(files.LinkRefusedError):
        files.atomic_write(link, lambda name: Path(name).write_text("x"), root=out)
    with pytest.raises(files.LinkRefusedError):
        files.remove_file(link, out)
    assert link.is_symlink() and victim.read_text() == "precious\n"


def test_a_runs_files_written_in_place_never_write_through_a_link(tmp_path) -> None:
    """A run's row and series are written in place, not renamed into place (a tiny run's
    cost): a hard link planted at either is replaced by a new file, its target untouched,
    and a symbolic link there is refused as by every other writer."""
    victim, _folder = victims(tmp_path)
    out = tmp_path / "out"
    row = {"run_id": "abc", "status": "ok"}
    series = {"run_id": "abc", "t": np.linspace(0.0, 1.0, 5), "drift_pos": np.zeros(5)}
    for where in ("runs/abc.json", "series/abc.parquet"):
        planted = out / where
        planted.parent.mkdir(parents=True, exist_ok=True)
        planted.unlink(missing_ok=True)  # (written by the last turn)
        os.link(victim, planted)  # the same inode as the file outside OUT
        before = state(victim)
        store.write_run(out, row, series)
        assert state(victim) == before
        assert planted.stat().st_ino != victim.stat().st_ino
    assert store.read_row(store.row_path(out, "abc")) == row
    assert list(pd.read_parquet(store.series_path(out, "abc"))["t"]) == list(series["t"])
    for where in ("runs/abc.json", "series/abc.parquet"):
        (out / where).unlink()
        link = plant(out, where, victim)
        with pytest.raises(files.LinkRefusedError):
            store.write_run(out, row, series)
        assert link.is_symlink() and state(victim) == before
        link.unlink()


def test_a_file_written_in_place_is_removed_when_its_write_fails(tmp_path, monkeypatch) -> None:
    """:func:`files.write_new_file` on an error leaves no part of the file, and names it."""
    out = tmp_path / "out"
    target = out / "runs" / "abc.json"
    written = []

    def full_disk(descriptor, data):  # a disk that fills after the first bytes
        if written:
            raise OSError(28, "No space left on device")
        written.append(data[:1])
        return 1

    monkeypatch.setattr(os, "write", full_disk)
    with pytest.raises(OSError, match="abc.json"):
        files.write_new_file(target, b'{"run_id": "abc"}', out)
    assert written and target.parent.is_dir() and not target.exists()
