"""A sweep without a recording, and ``workbench record`` afterwards (workbench.runs.record)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import rerun as rr
from typer.testing import CliRunner

from workbench.cli import app
from workbench.outputs.recording import SweepRecorder, split_entity_path
from workbench.runs import store
from workbench.runs.record import chosen_runs, record_runs
from workbench.runs.sweep import parse_spec, run_sweep


def spec_text(out: Path) -> str:
    return f"""
out = "{out.as_posix()}"
jobs = 2
time_limit = 300.0  # only a hung run reaches it
tolerances = [1e-4, 1e-7]
problems = ["simple-pendulum"]
formalisms = ["minimal-ode"]
integrators = ["scipy-dop853", "scipy-rk45"]
"""


def run_values(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """Run entity (below the problem) -> each of its temporal columns' values, by time."""
    values: dict[str, dict[str, np.ndarray]] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        parts = split_entity_path(chunk.entity_path)
        if parts[:1] != ["runs"] or len(parts) < 6 or chunk.is_static:
            continue
        frame = chunk.to_record_batch().to_pandas().sort_values("sim_time")
        for name in frame.columns:
            if name.startswith(("InstancePoses3D:", "Scalars:")):
                flat = [np.asarray(np.stack(list(v)), dtype=float) for v in frame[name]]
                values.setdefault(chunk.entity_path, {})[name] = np.stack(flat)
    return values


def test_a_run_recorded_afterwards_shows_what_the_sweep_would_have(tmp_path: Path) -> None:
    """The same runs swept with a recording and without one then recorded by running
    them again: the same poses and series (a rerun of the same code reproduces its
    trajectory), their rows untouched, and a sweep without a recording writes no file."""
    recorded, later = tmp_path / "recorded", tmp_path / "later"
    run_sweep(parse_spec(spec_text(recorded)), show_progress=False, recorder=SweepRecorder)
    summary = run_sweep(parse_spec(spec_text(later)), show_progress=False, recorder=None)
    assert summary.recording is None and summary.counts == {"ok": 4}
    assert not list(later.rglob("*.rrd"))
    rows = {path.name: path.read_bytes() for path in (later / store.RUNS_DIR).glob("*.json")}

    def dop853(frame):
        return frame[frame["integrator"] == "scipy-dop853"]

    done = record_runs(later, SweepRecorder, dop853, jobs=2, show_progress=False)
    assert done.recorded == 2 and not done.failed and not done.left_out
    assert done.recording == later / "recording.rrd"
    assert rows == {p.name: p.read_bytes() for p in (later / store.RUNS_DIR).glob("*.json")}
    expected = {k: v for k, v in run_values(recorded / "recording.rrd").items() if "dop853" in k}
    found = run_values(done.recording)
    assert sorted(found) == sorted(expected) and len(found) == 6  # 2 runs: shapes, frames, series
    for entity, columns in expected.items():
        assert sorted(found[entity]) == sorted(columns)
        for name, values in columns.items():
            np.testing.assert_allclose(found[entity][name], values, rtol=1e-9, atol=1e-12)

    # recording the rest adds them; the runs recorded before are there once
    assert record_runs(later, SweepRecorder, jobs=1, show_progress=False).recorded == 4
    assert sorted(run_values(done.recording)) == sorted(run_values(recorded / "recording.rrd"))


def test_only_runs_that_can_be_run_again_as_they_were_are_recorded(tmp_path: Path) -> None:
    """A run not ok has no whole trajectory to show; a stale row (its producer changed)
    would be shown with another trajectory than its row's; a row whose keys do not make
    its run id again is not a run of this workbench's."""
    out = tmp_path / "out"
    run_sweep(parse_spec(spec_text(out)), show_progress=False)
    files = sorted((out / store.RUNS_DIR).glob("*.json"))
    edits = [
        {"status": "failed"},
        {"producer_formalism": "sha256:0000000000000000"},
        {"rtol": 0.5},
    ]
    for path, edit in zip(files, edits, strict=False):
        path.write_text(json.dumps(json.loads(path.read_text()) | edit))
    specs, left_out = chosen_runs(out)
    assert len(specs) == 1 and sum(left_out.values()) == 3
    assert set(left_out) == {
        "status failed",
        "stale (`workbench sweep --rerun stale` first)",
        "not made again from its row's keys",
    }


def test_a_results_folder_cannot_make_record_read_files_outside_it(tmp_path: Path) -> None:
    """A results folder is data: a row naming a robot file (or a folder it may read)
    outside OUT is not run again unless the user names that folder; a link inside OUT
    leading out counts as outside."""
    out = tmp_path / "out"
    run_sweep(parse_spec(spec_text(out)), show_progress=False)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (out / "link").symlink_to(elsewhere)
    files = sorted((out / store.RUNS_DIR).glob("*.json"))
    named = [
        {"file": str(elsewhere / "robot.urdf")},
        {"file": str(out / "robot.urdf"), "allow_roots": ["/"]},
        {"file": "link/robot.urdf"},
    ]
    for path, options in zip(files, named, strict=False):
        row = json.loads(path.read_text())
        path.write_text(json.dumps(row | {"problem_options": json.dumps(options)}))
    outside = "names files outside OUT and the folders given with --allow-root"
    assert chosen_runs(out)[1][outside] == 3
    # named by the user: no longer refused for it (the edited rows then fail their run id)
    left_out = chosen_runs(out, allow_roots=[elsewhere])[1]
    assert left_out[outside] == 1 and left_out["not made again from its row's keys"] == 2


def test_the_commands_say_what_they_did(tmp_path: Path) -> None:
    runner = CliRunner()
    spec = tmp_path / "spec.toml"
    out = tmp_path / "out"
    spec.write_text(spec_text(out))
    result = runner.invoke(app, ["sweep", str(spec), "--no-report", "--no-recording"])
    assert result.exit_code == 0, result.output
    assert f"recording: none written (--no-recording); `workbench record {out}" in result.output
    assert not (out / "recording.rrd").exists()

    missing = tmp_path / "missing"
    result = runner.invoke(app, ["record", str(missing)])
    assert result.exit_code != 0 and "no output directory" in result.output
    assert not missing.exists()  # not made by the command's lock

    result = runner.invoke(app, ["record", str(out), "--where", "problem=nope"])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert "no run of the 4 in" in result.output and "meets --where problem=nope" in result.output

    result = runner.invoke(app, ["record", str(out), "--where", "rtol<1e-5", "-j", "1"])
    assert result.exit_code == 0, result.output
    assert f"2 run(s) recorded; recording: {out / 'recording.rrd'}" in result.output
    assert len(SweepRecorder().add_recording(out / "recording.rrd")) == 2
    # the columns of `workbench results --where`: the pair's label, an option's column
    pair = ["--where", "pair=minimal-ode / scipy-rk45", "--where", "formalism.index=3"]
    result = runner.invoke(app, ["results", str(out), "--by", "run", *pair])
    assert result.exit_code == 0 and "2 of the 4 runs" in result.output, result.output
    result = runner.invoke(app, ["record", str(out), *pair, "-j", "1"])
    assert result.exit_code == 0, result.output
    assert "2 run(s) recorded" in result.output
    assert len(SweepRecorder().add_recording(out / "recording.rrd")) == 3  # one new
    result = runner.invoke(app, ["record", str(out), "--where", "sdc>=3"])
    assert result.exit_code != 0 and "no column 'sdc' (did you mean scd?)" in result.output

    for path in (out / store.RUNS_DIR).glob("*.json"):  # every row stale: none recorded
        path.write_text(json.dumps(json.loads(path.read_text()) | {"producer_formalism": "x:0"}))
    result = runner.invoke(app, ["record", str(out)])
    assert result.exit_code == 1, result.output
    assert "no run recorded (4 left out: stale" in result.output
    assert f"{out / 'recording.rrd'} as it was" in result.output


def test_the_python_api_records_a_sweep_it_ran(tmp_path: Path) -> None:
    """``wb.sweep`` writes no recording; ``wb.record`` makes one of the runs chosen, and
    says what is wrong with its input or why nothing was recorded."""
    import pytest

    import workbench as wb
    from workbench.errors import ConfigError

    out = tmp_path / "out"
    frame = wb.sweep(
        problems=["simple-pendulum"], formalisms=["minimal-ode"],
        integrators=["scipy-dop853", "scipy-rk45"], tolerances=[1e-4, 1e-7], out=out,
    )  # fmt: skip
    assert len(frame) == 4 and not (out / "recording.rrd").exists()
    path = wb.record(out, "rtol<1e-5", jobs=1)
    assert path == out / "recording.rrd"
    assert len(SweepRecorder().add_recording(path)) == 2
    for where, message in ((5, "where: expected"), ("problem=nope", "meets")):
        with pytest.raises(ConfigError, match=message):
            wb.record(out, where)
    with pytest.raises(ConfigError, match="jobs"):
        wb.record(out, jobs=0)
    for path in (out / store.RUNS_DIR).glob("*.json"):  # every row stale: none recorded
        path.write_text(json.dumps(json.loads(path.read_text()) | {"producer_formalism": "x:0"}))
    with pytest.raises(ConfigError, match="4 stale"):
        wb.record(out)
