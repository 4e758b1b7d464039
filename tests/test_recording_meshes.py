"""A model's meshes are stored once in a sweep's recording, however many runs use it, and
each run's robot is still drawn at that run's poses (issue 35.1); the per-run files are
removed once merged, the merged file keeping their runs (issue 35.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from scipy.spatial.transform import Rotation

from tests.test_recording import fake_equations, fake_run
from workbench.files import write_json_atomic
from workbench.model import Frame, Shape
from workbench.outputs.recording import (
    INSTANCE_RUNS,
    SweepRecorder,
    entity_path,
    merge_recordings,
    run_parts,
)
from workbench.runs.local_pool import RECORDINGS_DIR, merge_run_recordings

trimesh = pytest.importorskip("trimesh", reason="trimesh reads meshes (a dependency of yourdfpy)")

MESH = "runs/fake-problem/model/bodies/arm/meshes/0"
OFFSET = np.array([0.2, 0.0, 0.0])  # the mesh's place on the arm
SCALE = 2.0


def meshed_equations(tmp_path: Path):
    """The fake arm (spinning about z at 1 rad/s) with an STL mesh at OFFSET, scaled."""
    mesh = tmp_path / "link.stl"
    if not mesh.exists():
        trimesh.creation.box(extents=(0.1, 0.2, 0.3)).export(mesh)
    equations = fake_equations()
    arm = equations.model.bodies["arm"]
    shape = Shape("mesh", (SCALE,) * 3, Frame.at(*OFFSET), path=str(mesh))
    equations.model.bodies["arm"] = type(arm)(**{**arm.__dict__, "shapes": (*arm.shapes, shape)})
    return equations


def write_run_files(directory: Path, rtols: list[float], equations) -> list[Path]:
    """A file a run, as a sweep's worker writes them."""
    sink, files = SweepRecorder(), []
    for rtol in rtols:
        spec, trajectory, series = fake_run(rtol)
        sink.begin_file(directory / f"{rtol:g}.rrd")
        sink.log_run(spec, equations, None, trajectory, series)
        files.append(sink.end_file())
    return files


def chunks_of(path: Path) -> list:
    return list(rr.chunk.RrdReader(path).stream().to_chunks())


def mesh_bytes(path: Path) -> tuple[int, int]:
    """(chunks holding a mesh, bytes of the mesh blobs in them)."""
    count = size = 0
    for chunk in chunks_of(path):
        batch = chunk.to_record_batch()
        blobs = [name for name in batch.schema.names if name.startswith(("Asset3D:", "Mesh3D:"))]
        count += bool(blobs)
        size += sum(batch.column(name).nbytes for name in blobs)
    return count, size


def instances(path: Path) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """(run of each instance, times, translations (times, runs, 3), matrices (times, runs,
    3, 3)) of the shared mesh."""
    runs, times, translations, matrices = [], [], [], []
    for chunk in chunks_of(path):
        if chunk.entity_path == f"/{MESH}/{INSTANCE_RUNS}":
            runs = chunk.to_record_batch().column(INSTANCE_RUNS)[0].as_py()
        if chunk.entity_path != "/" + MESH:
            continue
        batch = chunk.to_record_batch()
        if "InstancePoses3D:translations" in batch.schema.names:
            times.append(batch.column("sim_time").cast("int64").to_numpy() / 1e9)
            translations += batch.column("InstancePoses3D:translations").to_pylist()
            matrices += batch.column("InstancePoses3D:mat3x3").to_pylist()
    # Rerun keeps a 3 x 3 matrix by columns
    matrices = np.array(matrices).reshape(len(matrices), -1, 3, 3).transpose(0, 1, 3, 2)
    return runs, np.concatenate(times), np.array(translations), matrices


def run_path(rtol: float) -> str:
    return entity_path(*run_parts(fake_run(rtol)[0]))


def test_a_models_mesh_is_stored_once_however_many_runs_use_it(tmp_path: Path) -> None:
    equations = meshed_equations(tmp_path)
    one_run = write_run_files(tmp_path / "one", [1e-3], equations)[0]
    files = write_run_files(tmp_path / "six", [10.0**-k for k in range(3, 9)], equations)
    merged = merge_recordings(files, tmp_path / "merged.rrd")
    assert mesh_bytes(one_run)[0] == 1
    assert mesh_bytes(merged) == mesh_bytes(one_run)  # one copy, not six
    # each run still shows its robot: instance k of the mesh is run k's arm, spinning
    # about z (angle t) with the mesh's offset on it
    runs, times, translations, matrices = instances(merged)
    assert sorted(runs) == sorted(run_path(10.0**-k) for k in range(3, 9))
    expected = np.column_stack([0.2 * np.cos(times), 0.2 * np.sin(times), 0 * times])
    turned = SCALE * Rotation.from_euler("z", times[:, None]).as_matrix()  # the arm's turn, scaled
    assert translations.shape == (len(times), 6, 3) and matrices.shape == (len(times), 6, 3, 3)
    for k in range(6):
        np.testing.assert_allclose(translations[:, k], expected, atol=1e-6)
        np.testing.assert_allclose(matrices[:, k], turned, atol=1e-6)
    _runs, times, _translations, matrices = instances(one_run)  # a worker's file, not merged
    turned = SCALE * Rotation.from_euler("z", times[:, None]).as_matrix()
    np.testing.assert_allclose(matrices[:, 0], turned, atol=1e-6)
    # and the run's own entities keep its shapes (static) and their poses
    kinds = {(chunk.entity_path, chunk.is_static) for chunk in chunks_of(merged)}
    for k in range(3, 9):
        assert {(f"/{run_path(10.0**-k)}/boxes", static) for static in (True, False)} <= kinds


def test_a_sweep_keeps_one_copy_and_redone_runs_replace_theirs(tmp_path: Path) -> None:
    """Merging removes the runs' files; a later merge adds new runs to the merged file,
    a redone run replacing its old copy (its robot drawn once, not twice)."""
    equations = meshed_equations(tmp_path)
    directory = tmp_path / RECORDINGS_DIR
    directory.mkdir()
    write_run_files(directory, [1e-3, 1e-4], equations)
    merged, remade = merge_run_recordings(SweepRecorder, tmp_path)
    assert remade and merged == tmp_path / "recording.rrd" and not list(directory.iterdir())
    assert merge_run_recordings(SweepRecorder, tmp_path) == (merged, False)  # nothing new

    write_run_files(directory, [1e-4, 1e-5], equations)  # 1e-4 redone, 1e-5 new
    merge_run_recordings(SweepRecorder, tmp_path)
    assert not list(directory.iterdir())
    runs, _times, translations, _matrices = instances(merged)
    assert sorted(runs) == sorted(run_path(r) for r in (1e-3, 1e-4, 1e-5))
    assert translations.shape[1] == 3 and mesh_bytes(merged)[0] == 1
    series = [  # one copy of each run's values: the redone run's old one is left out
        chunk.entity_path
        for chunk in chunks_of(merged)
        if "Scalars:scalars" in chunk.to_record_batch().schema.names
        and chunk.entity_path.endswith("/series")
    ]
    assert sorted(series) == sorted(f"/{run_path(r)}/series" for r in (1e-3, 1e-4, 1e-5))


def test_view_opens_one_run_of_a_sweeps_recording(tmp_path: Path, monkeypatch) -> None:
    """``workbench view OUT --run ID``: the run copied out of the merged recording, its
    robot with it; an unknown id is one line naming where the ids are."""
    import subprocess

    from typer.testing import CliRunner

    from workbench.cli import app
    from workbench.runs import store

    equations = meshed_equations(tmp_path)
    out = tmp_path / "out"
    (out / RECORDINGS_DIR).mkdir(parents=True)
    write_run_files(out / RECORDINGS_DIR, [1e-3, 1e-4], equations)
    merge_run_recordings(SweepRecorder, out)
    spec = fake_run(1e-4)[0]
    row = {"run_id": "abc", "problem": spec.problem, "formalism": spec.formalism,
           "integrator": spec.integrator, "rtol": spec.rtol, "problem_options": "{}"}  # fmt: skip
    write_json_atomic(row, store.row_path(out, "abc"), root=out)
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("DISPLAY", ":0")
    started: list = []
    monkeypatch.setattr(subprocess, "Popen", lambda args, **kwargs: started.append(args))
    outcome = CliRunner().invoke(app, ["view", str(out), "--run", "abc"])
    assert outcome.exit_code == 0, outcome.output
    one = Path(started[0][-1])
    runs, _times, translations, _matrices = instances(one)
    assert runs == [run_path(1e-4)] and translations.shape[1] == 1 and mesh_bytes(one)[0] == 1
    assert {
        c.entity_path.removesuffix("/series")
        for c in chunks_of(one)
        if c.entity_path.endswith("/series")
    } == {"/" + run_path(1e-4)}
    unknown = CliRunner().invoke(app, ["view", str(out), "--run", "nope"])
    assert unknown.exit_code == 2 and "error: no run 'nope'" in unknown.output
    # a run of the sweep that is not in its recording (swept with --no-recording)
    write_json_atomic(row | {"run_id": "def", "rtol": 1e-5}, store.row_path(out, "def"), root=out)
    unrecorded = CliRunner().invoke(app, ["view", str(out), "--run", "def"])
    assert unrecorded.exit_code == 2, unrecorded.output
    assert f"`workbench record {out} -w run_id=def` records it" in unrecorded.output
