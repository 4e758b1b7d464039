"""A resume with nothing to do keeps the results table, the merged recording and the report
(issue 35.3): they are remade only when their inputs changed (workbench.runs.output_keys)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tests.test_sweep import spec_text
from workbench.outputs.report import current_report, kept_cost
from workbench.runs import output_keys, store

FALLING = '["test-falling"]'  # an analytic reference: no reference pipeline to run


@pytest.fixture(autouse=True)
def fresh_workers(monkeypatch):
    """Workers started by spawn, as in tests/test_resume.py (they import the plugins anew)."""
    import multiprocessing

    from workbench.runs import local_pool

    monkeypatch.setattr(local_pool, "worker_context", lambda: multiprocessing.get_context("spawn"))


def identity(path: Path) -> tuple[int, int]:
    """(inode, modification time in ns): a file replaced or rewritten changes one of them."""
    stat = path.stat()
    return stat.st_ino, stat.st_mtime_ns


def test_a_resume_with_nothing_to_do_keeps_recording_and_report(
    fake_plugins, tmp_path, monkeypatch
) -> None:
    from workbench.cli import app

    out = tmp_path / "out"
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(out, '["test-rk45"]', problems=FALLING))
    monkeypatch.setattr("sys.argv", ["workbench", "sweep", str(spec)])
    outputs = [out / "recording.rrd", out / "report" / "index.html", out / store.RESULTS_FILE]

    def sweep() -> str:
        result = CliRunner().invoke(app, ["sweep", str(spec)])
        assert result.exit_code == 0, result.output
        return result.output

    first = sweep()
    assert "unchanged" not in first
    before = [identity(path) for path in outputs]

    again = sweep()  # every row done and whole: nothing is remade, and it says so
    assert [identity(path) for path in outputs] == before
    assert "report: " in again and "index.html (unchanged: made from the same rows)" in again
    assert "recording.rrd (unchanged: made from the same runs; workbench view" in again

    row = next((out / store.RUNS_DIR).glob("*.json"))
    row.unlink()  # its run is done again: new inputs for every output
    redone = sweep()
    assert "1 runs in" in redone and "unchanged" not in redone
    after = [identity(path) for path in outputs]
    assert all(new != old for new, old in zip(after, before, strict=True))


def test_the_report_key_follows_the_rows_stale_marks_and_cost(tmp_path) -> None:
    """The key is of the rows' content, not their times: a row rewritten with the same
    bytes keeps the report, one byte changed, a stale mark or another cost remakes it."""
    runs = tmp_path / store.RUNS_DIR
    runs.mkdir()
    (runs / "a.json").write_text('{"run_id": "a", "status": "ok"}')
    index = tmp_path / "report" / "index.html"
    index.parent.mkdir()
    index.write_text("<html></html>")
    from workbench.outputs.report.writer import report_key

    output_keys.remember(index, report_key(tmp_path))
    assert current_report(tmp_path) == index
    os.utime(runs / "a.json", ns=(0, 0))  # touched, same content
    assert current_report(tmp_path) == index
    assert current_report(tmp_path, stale={"a": "plugin changed"}) is None
    assert current_report(tmp_path, cost="n_rhs") is None
    (runs / "a.json").write_text('{"run_id": "a", "status": "failed"}')
    assert current_report(tmp_path) is None
    (runs / "a.json").write_text('{"run_id": "a", "status": "ok"}')
    index.unlink()  # the output itself gone: remade whatever its key says
    assert current_report(tmp_path) is None


def test_a_sweep_reads_its_row_files_once_for_table_and_report(
    fake_plugins, tmp_path, monkeypatch
) -> None:
    """The report of a sweep is made from the rows its consolidation read (every row file
    read once, not twice: a quarter of a millisecond a run, issue 35.4), unless a row file
    was unreadable: the report then reads them itself and warns of it."""
    from workbench.cli import app

    out = tmp_path / "out"
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(out, '["test-rk45"]', problems=FALLING))
    monkeypatch.setattr("sys.argv", ["workbench", "sweep", str(spec)])
    reads: list[Path] = []
    load_results = store.load_results

    def counted(path):
        reads.append(Path(path))
        return load_results(path)

    monkeypatch.setattr(store, "load_results", counted)
    result = CliRunner().invoke(app, ["sweep", str(spec)])
    assert result.exit_code == 0, result.output
    assert (out / "report" / "index.html").is_file()
    assert reads == [out]

    reads.clear()  # a row file that cannot be read: the rows change, both read them
    (out / store.RUNS_DIR / f"{'f' * 16}.json").write_text("{")
    result = CliRunner().invoke(app, ["sweep", str(spec)])
    assert result.exit_code == 0, result.output
    assert reads == [out, out]
    assert "warning: 1 unreadable result file" in result.output


def test_a_resume_remakes_the_report_in_the_cost_measure_the_user_chose(
    fake_plugins, tmp_path, monkeypatch
) -> None:
    """`workbench report OUT --cost n_rhs` is kept: a resume with nothing new keeps that
    report (its key has the measure), one with a run redone remakes it in n_rhs, not in the
    default; a settings file naming no known measure is ignored (the default)."""
    from workbench.cli import app

    out = tmp_path / "out"
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(out, '["test-rk45"]', problems=FALLING))
    monkeypatch.setattr("sys.argv", ["workbench", "sweep", str(spec)])
    index = out / "report" / "index.html"

    def invoke(*arguments: str) -> str:
        result = CliRunner().invoke(app, list(arguments))
        assert result.exit_code == 0, result.output
        return result.output

    invoke("sweep", str(spec))
    assert "cost measure: rhs evaluations" not in index.read_text()
    invoke("report", str(out), "--cost", "n_rhs")
    assert "cost measure: rhs evaluations" in index.read_text()

    kept = invoke("sweep", str(spec))
    assert "index.html (unchanged: made from the same rows)" in kept

    next((out / store.RUNS_DIR).glob("*.json")).unlink()  # a run redone: the report remade
    redone = invoke("sweep", str(spec))
    assert "unchanged" not in redone and "(cost measure n_rhs" in redone
    assert "cost measure: rhs evaluations" in index.read_text()

    next((out / store.RUNS_DIR).glob("*.json")).unlink()  # no report: the hint keeps the measure
    hint = invoke("sweep", str(spec), "--no-report")
    assert f"`workbench report {out} --cost n_rhs` writes it" in hint

    elsewhere = tmp_path / "settings.json"  # a link out of OUT: not read
    elsewhere.write_text('{"cost": "n_rhs"}')
    (out / "report" / "settings.json").unlink()
    (out / "report" / "settings.json").symlink_to(elsewhere)
    assert kept_cost(out) is None
    (out / "report" / "settings.json").unlink()
    (out / "report" / "settings.json").write_text('{"cost": "rm -rf"}')  # not a measure
    next((out / store.RUNS_DIR).glob("*.json")).unlink()
    default = invoke("sweep", str(spec))
    assert "(cost measure" not in default
    assert "cost measure: rhs evaluations" not in index.read_text()
