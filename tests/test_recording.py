"""Rerun recordings read back with Rerun's chunk reader: entities, sim_time, values."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd
import pytest
import rerun as rr
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from workbench.cli import app
from workbench.model import Frame, Model, Shape
from workbench.outputs.recording import (
    SERIES_QUANTITIES,
    SHAPE_COLORS,
    RerunSink,
    _column,
    entity_path,
    merge_recordings,
    quaternion_xyzw,
    series_quantities,
    split_entity_path,
)


class FakeObservables:
    """Body 'arm' spins about z at 1 rad/s at the origin; 'tip' sits at (t, 0, 0) unrotated."""

    body_names = ["arm", "tip"]

    def poses(self, t: float, q: np.ndarray) -> np.ndarray:
        half = 0.5 * t
        return np.array(
            [
                [0.0, 0.0, 0.0, np.cos(half), 0.0, 0.0, np.sin(half)],
                [t, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
            ]
        )

    def poses_along(self, times: np.ndarray, q: np.ndarray) -> np.ndarray:
        return np.stack([self.poses(t, qi) for t, qi in zip(times, q, strict=True)])


def fake_equations() -> SimpleNamespace:
    model = Model("fake", kind="spatial")
    model.add_body(
        "arm",
        1.0,
        inertia=(1.0, 1.0, 1.0),
        shapes=[
            Shape("box", (1.0, 0.1, 0.1), Frame.at(0.5, 0, 0)),
            Shape("capsule", (0.02, 1.0), Frame.at(0, 0, 0.5)),
            Shape("cylinder", (0.05, 0.2)),
        ],
    )
    model.add_point_mass("tip", 0.5, shapes=[Shape("sphere", (0.05,), color=(200, 50, 50))])
    model.add_joint("hinge", "revolute", "ground", "arm")
    model.add_joint("slide", "prismatic", "arm", "tip", parent_frame=Frame.at(1.0, 0, 0))
    return SimpleNamespace(model=model, observables=FakeObservables(), nq=2)


def fake_run(
    rtol: float = 1e-6, n: int = 50
) -> tuple[SimpleNamespace, SimpleNamespace, pd.DataFrame]:
    spec = SimpleNamespace(
        problem="fake-problem",
        formalism="minimal-ode",
        integrator="radau",
        rtol=rtol,
        run_id=f"run-{rtol:g}",
    )
    times = np.linspace(0.0, 2.0, n)
    trajectory = SimpleNamespace(times=times, y=np.zeros((n, 4)))
    series = pd.DataFrame(
        {
            "run_id": spec.run_id,
            "t": times,
            "drift_pos": 1e-9 * times,
            "drift_vel": 2e-9 * times,
            "drift_nh": np.nan,  # no nonholonomic constraint: not logged
            "energy_err": 1e-7 * np.sin(times),
            "ref_err": rtol * times**2,
        }
    )
    return spec, trajectory, series


def read_chunks(path: Path) -> dict[str, list[pd.DataFrame]]:
    """Entity path -> the record batches (as DataFrames) logged to it."""
    chunks: dict[str, list[pd.DataFrame]] = {}
    for chunk in rr.chunk.RrdReader(path).stream().to_chunks():
        chunks.setdefault(chunk.entity_path, []).append(chunk.to_record_batch().to_pandas())
    return chunks


def column(frames: list[pd.DataFrame], name: str) -> pd.DataFrame:
    """The rows of ``frames`` that carry ``name``, sorted by sim_time when it is there."""
    rows = pd.concat([f for f in frames if name in f.columns], ignore_index=True)
    return rows.sort_values("sim_time") if "sim_time" in rows else rows


def seconds(values: pd.Series) -> np.ndarray:
    return values.to_numpy().astype("timedelta64[ns]").astype(np.int64) / 1e9


def series_of(frames: list[pd.DataFrame], quantity: str) -> tuple[np.ndarray, np.ndarray]:
    """(times s, values) of ``quantity`` in a run's ``series`` entity (one instance a
    quantity, in the order of SERIES_QUANTITIES), its NaN samples left out."""
    logged = column(frames, "Scalars:scalars")
    values = np.array([row[SERIES_QUANTITIES.index(quantity)] for row in logged["Scalars:scalars"]])
    keep = ~np.isnan(values)
    return seconds(logged["sim_time"])[keep], values[keep]


def instance_poses(frames: list[pd.DataFrame]) -> tuple[np.ndarray, np.ndarray, Any]:
    """(times s, translations (n, k, 3), quaternions x, y, z, w (n, k, 4)) of an entity's
    instance poses, a row a sample time; quaternions None when it has none (spheres)."""
    rows = column(frames, "InstancePoses3D:translations")
    translations = np.array([np.stack(v) for v in rows["InstancePoses3D:translations"]])
    if "InstancePoses3D:quaternions" not in rows:
        return seconds(rows["sim_time"]), translations, None
    quaternions = np.array([np.stack(v) for v in rows["InstancePoses3D:quaternions"]])
    return seconds(rows["sim_time"]), translations, quaternions


def static_columns(frames: list[pd.DataFrame]) -> pd.DataFrame:
    (static,) = [frame for frame in frames if "sim_time" not in frame]
    return static


def series_present(path: Path, run: str) -> list[str]:
    """The quantities a run's ``series`` entity has values of (read from its values)."""
    return [
        quantity
        for chunk in rr.chunk.RrdReader(path).stream()
        if chunk.entity_path == f"/{run}/series"
        for quantity in series_quantities(chunk.to_record_batch())
    ]


def test_log_run_is_read_back(tmp_path: Path) -> None:
    sink = RerunSink()
    spec, trajectory, series = fake_run()
    run = sink.log_run(spec, fake_equations(), None, trajectory, series)
    assert run == "runs/fake-problem/minimal-ode/radau/rtol\\=1e-06"
    path = sink.save(tmp_path)
    assert path == tmp_path / "recording.rrd"
    assert rr.chunk.RrdReader(path).blueprints(), "the blueprint is in the file"
    chunks = read_chunks(path)
    base = "/" + run
    expected = {
        f"{base}/boxes",  # the run's boxes: sizes and labels (static), instance poses
        f"{base}/capsules",
        f"{base}/cylinders",
        f"{base}/ellipsoids",
        f"{base}/joints",  # each joint's frame on its child body
        "/runs/fake-problem/model/ground/joints",  # the same in every run: once
        "/runs/fake-problem",  # its view's up axis and shape colour
        f"{base}/series",
    }
    assert expected == {key for key in chunks if key.startswith("/runs/")}
    assert list(static_columns(chunks[f"{base}/boxes"])["Boxes3D:labels"].iloc[0]) == ["arm"]
    assert list(static_columns(chunks[f"{base}/ellipsoids"])["Ellipsoids3D:labels"].iloc[0]) == [
        "tip"
    ]
    # drift_nh all NaN (not drawn), penetration not a contact model's (no column)
    assert series_present(path, run) == [
        "drift_pos", "drift_vel", "energy_err", "ref_err"
    ]  # fmt: skip
    assert len(chunks[f"{base}/series"]) == 2  # its names (static) and all its values
    (names,) = [frame for frame in chunks[f"{base}/series"] if "sim_time" not in frame]
    assert set(names) == {"rerun.controls.RowId", "SeriesLines:names"}
    for quantity in ("drift_nh", "penetration"):
        assert len(series_of(chunks[f"{base}/series"], quantity)[1]) == 0
    for quantity in ("drift_pos", "drift_vel", "energy_err", "ref_err"):
        t, values = series_of(chunks[f"{base}/series"], quantity)
        np.testing.assert_allclose(t, series["t"], atol=1e-9)
        np.testing.assert_allclose(values, series[quantity].to_numpy(), rtol=1e-15)

    # each shape at its body's pose times its place in the body: the arm spins about z
    # (angle t) at the origin, its box centred at (0.5, 0, 0) on it, its capsule (Rerun's
    # runs from its origin along +z) from (0, 0, 0); the tip's sphere at (t, 0, 0)
    t, box, box_turn = instance_poses(chunks[f"{base}/boxes"])
    np.testing.assert_allclose(t, trajectory.times, atol=1e-9)
    arm_turn = np.column_stack([0 * t, 0 * t, np.sin(t / 2), np.cos(t / 2)])
    np.testing.assert_allclose(box_turn[:, 0], arm_turn, atol=1e-6)
    np.testing.assert_allclose(
        box[:, 0], np.column_stack([0.5 * np.cos(t), 0.5 * np.sin(t), 0 * t]), atol=1e-6
    )
    _t, capsule, capsule_turn = instance_poses(chunks[f"{base}/capsules"])
    np.testing.assert_allclose(capsule[:, 0], 0.0, atol=1e-6)
    np.testing.assert_allclose(capsule_turn[:, 0], arm_turn, atol=1e-6)
    _t, sphere, sphere_turn = instance_poses(chunks[f"{base}/ellipsoids"])
    np.testing.assert_allclose(sphere[:, 0, 0], trajectory.times, rtol=1e-6)
    assert sphere_turn is None  # a sphere looks the same turned: its poses are translations
    # the joints' frames on their child bodies, one TransformAxes3D drawn at each: the
    # hinge's on the arm (at its origin, turning with it), the slide's on the tip
    _t, frames, frame_turns = instance_poses(chunks[f"{base}/joints"])
    assert frames.shape == (len(t), 2, 3)
    np.testing.assert_allclose(frames[:, 0], 0.0, atol=1e-6)
    np.testing.assert_allclose(frame_turns[:, 0], arm_turn, atol=1e-6)
    np.testing.assert_allclose(frames[:, 1, 0], trajectory.times, rtol=1e-6)
    assert "TransformAxes3D:axis_length" in static_columns(chunks[f"{base}/joints"])


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 5), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_a_column_built_in_arrow_is_the_one_rerun_builds(n: int, k: int, seed: int) -> None:
    """A run's pose and series columns are built in Arrow directly (cheaper): the same
    descriptor and array as Rerun's own ``columns().partition()``, a row a sample time."""
    rng = np.random.default_rng(seed)
    translations = rng.normal(size=(n, k, 3)).astype(np.float32)
    quaternions = rng.normal(size=(n, k, 4)).astype(np.float32)
    scalars = rng.normal(size=(n, k))
    scalars[0, 0] = np.nan  # a quantity a run has not
    rerun_columns = [
        *rr.InstancePoses3D.columns(
            translations=translations.reshape(-1, 3), quaternions=quaternions.reshape(-1, 4)
        ).partition(np.full(n, k)),
        *rr.Scalars.columns(scalars=scalars),
    ]
    ours = [
        _column("translations", translations),
        _column("quaternions", quaternions),
        _column("scalars", scalars),
    ]
    for mine, theirs in zip(ours, rerun_columns, strict=True):
        assert mine.component_descriptor() == theirs.component_descriptor()
        a, b = mine.as_arrow_array(), theirs.as_arrow_array()
        assert a.type == b.type and a.offsets.equals(b.offsets) and a.null_count == 0
        np.testing.assert_array_equal(  # NaN equal to NaN, unlike Arrow's equals
            np.array(a.to_pylist(), dtype=float), np.array(b.to_pylist(), dtype=float)
        )


def test_the_series_names_column_is_rerun_s_own() -> None:
    """A run's series names, built in Arrow (``_names_column``), are the column Rerun's
    ``SeriesLines.columns(names=...).partition(...)`` makes: its descriptor, one row of
    the label ``count`` times; and a static chunk of it keeps them (names with a space,
    an accent and a slash, as run labels have)."""
    from rerun.chunk import Chunk

    from workbench.outputs.recording import _names_column

    label = "minimal-ode / scipy-dop853 rtol=1e-06 é"
    mine = _names_column(label, 8)
    (theirs,) = rr.SeriesLines.columns(names=[label] * 8).partition([8])
    assert mine.component_descriptor() == theirs.component_descriptor()
    assert mine.as_arrow_array().equals(theirs.as_arrow_array())
    batch = Chunk.from_columns("runs/x/series", [], [mine]).to_record_batch()
    assert batch.column(batch.num_columns - 1).to_pylist() == [[label] * 8]


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
    st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
    st.lists(st.floats(-2, 2), min_size=6, max_size=6),
)
def test_instance_poses_compose_as_rotations_do(body_turn, place_turn, offsets) -> None:
    """A shape's pose is its body's pose times its place in the body (scipy's Rotation
    as the oracle), whatever the turns."""
    from scipy.spatial.transform import Rotation

    from workbench.outputs.recording import _compose

    body, place = Rotation.from_quat(body_turn), Rotation.from_quat(place_turn)
    body_pose = np.concatenate([offsets[:3], body.as_quat()])[None, None]
    translations, quaternions = _compose(body_pose, np.array([offsets[3:]]), place.as_quat()[None])
    np.testing.assert_allclose(
        translations[0, 0], np.add(offsets[:3], body.apply(offsets[3:])), atol=1e-5
    )
    turned = Rotation.from_quat(quaternions[0, 0].astype(float))
    assert (turned.inv() * body * place).magnitude() < 1e-5


def blueprint_views(path: Path) -> dict[str, dict[str, list]]:
    """View display name -> its class, origin and content queries, from the blueprint."""
    reader = rr.chunk.RrdReader(path)
    fields: dict[str, dict[str, list]] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
        parts = chunk.entity_path.strip("/").split("/")
        if parts[0] == "view":
            data = chunk.to_record_batch().to_pydict()
            fields.setdefault(parts[1], {}).update(
                {k.split(":")[-1]: v[-1] for k, v in data.items() if ":" in k}
            )
    return {view.get("display_name", [""])[0]: view for view in fields.values()}


def test_blueprint_has_a_3d_view_beside_the_plots(tmp_path: Path) -> None:
    sink = RerunSink()
    run = sink.log_run(*_args(fake_run()))
    views = blueprint_views(sink.save(tmp_path))
    assert views["fake-problem"]["class_identifier"] == ["3D"]
    assert views["fake-problem"]["space_origin"] == ["runs/fake-problem"]
    assert set(views) == {"fake-problem", "drift_pos", "drift_vel", "energy_err", "ref_err"}
    assert views["ref_err"]["class_identifier"] == ["TimeSeries"]
    assert views["ref_err"]["query"] == [f"+ /{run}/series"]


def test_runs_with_other_tolerances_and_repeated_keys(tmp_path: Path) -> None:
    sink = RerunSink(max_frames=10)
    paths = [sink.log_run(*_args(fake_run(rtol))) for rtol in (1e-3, 1e-6)]
    repeated = sink.log_run(*_args(fake_run(1e-6)))
    assert len({*paths, repeated}) == 3 and "run-1e-06" in repeated
    chunks = read_chunks(sink.save(tmp_path / "r.rrd"))
    assert len(instance_poses(chunks[f"/{paths[0]}/boxes"])[0]) == 10  # poses strided
    # to max_frames; series are whole
    assert len(series_of(chunks[f"/{paths[0]}/series"], "ref_err")[1]) == 50


def _args(run: tuple) -> tuple:
    spec, trajectory, series = run
    return spec, fake_equations(), None, trajectory, series


def test_a_file_never_ended_leaves_nothing_in_the_next(tmp_path: Path) -> None:
    """A run logged to a file whose writing then failed (``end_file`` never reached) is not
    in the next file: its chunks still held by the sink are dropped with the file, as its
    stream was (the runs of a file begun are its own)."""
    sink = RerunSink()
    sink.begin_file(tmp_path / "lost.rrd")
    lost = sink.log_run(*_args(fake_run(1e-3)))
    assert sink._chunks  # held, not yet sent
    sink.begin_file(tmp_path / "next.rrd")
    kept = sink.log_run(*_args(fake_run(1e-6)))
    chunks = read_chunks(sink.end_file())
    assert f"/{kept}/series" in chunks
    assert not any(path.startswith(f"/{lost}") for path in chunks)


def test_merge_recordings_of_workers(tmp_path: Path) -> None:
    files = []
    for rtol in (1e-3, 1e-6):
        sink = RerunSink()
        sink.log_run(*_args(fake_run(rtol)))
        files.append(sink.save(tmp_path / f"worker-{rtol:g}.rrd"))
    merged = merge_recordings(files, tmp_path / "all.rrd")
    chunks = read_chunks(merged)
    for rtol in ("0.001", "1e-06"):
        assert f"/runs/fake-problem/minimal-ode/radau/rtol\\={rtol}/series" in chunks
    assert rr.chunk.RrdReader(merged).blueprints()


def test_a_merge_takes_the_runs_quantities_from_each_files_index(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file announces its index before its runs and gives it at the end: the merge then
    takes each run's quantities from it without looking into the run's series; a file
    without one (written before the index) is read from its values, as before. Either way
    the merged file's index and plots are the quantities the runs' values have (read back
    from the merged file: the oracle)."""
    from workbench.outputs import recording

    def run_without(rtol: float, *quantities: str) -> tuple:
        spec, trajectory, series = fake_run(rtol)
        series[list(quantities)] = np.nan
        return spec, fake_equations(), None, trajectory, series

    sink = RerunSink()
    sink.begin_file(tmp_path / "a.rrd")  # two runs: one file, one index
    first = sink.log_run(*run_without(1e-3, "energy_err"))
    second = sink.log_run(*run_without(1e-4, "drift_pos", "drift_vel"))
    indexed = [sink.end_file()]
    sink.begin_file(tmp_path / "b.rrd")
    third = sink.log_run(*run_without(1e-5))
    indexed.append(sink.end_file())
    with monkeypatch.context() as patched:  # a file as written before the index
        patched.setattr(RerunSink, "begin_index", lambda self: None)
        patched.setattr(RerunSink, "log_index", lambda self: None)
        sink.begin_file(tmp_path / "c.rrd")
        fourth = sink.log_run(*run_without(1e-6, "ref_err", "drift_pos"))
        old = sink.end_file()
    looked_into: list[int] = []  # series chunks read for their values

    def counted(batch: Any) -> list[str]:
        looked_into.append(batch.num_rows)
        return series_quantities(batch)

    monkeypatch.setattr(recording, "series_quantities", counted)
    merged = merge_recordings(indexed, tmp_path / "all.rrd")
    assert not looked_into
    RerunSink().add_recording(old)
    in_old = len(looked_into)  # the old file's series chunks
    assert in_old
    merged = merge_recordings([old], merged, keep_existing=True)  # a resume's merge
    assert len(looked_into) == 2 * in_old  # the old file's again, the merged file's none
    monkeypatch.setattr(recording, "series_quantities", series_quantities)
    expected = {run: series_present(merged, run) for run in (first, second, third, fourth)}
    assert expected[first] == ["drift_pos", "drift_vel", "ref_err"]
    assert expected[fourth] == ["drift_vel", "energy_err"]
    reader = RerunSink()
    monkeypatch.setattr(recording, "series_quantities", counted)
    assert sorted(reader.add_recording(merged)) == sorted(expected)
    assert len(looked_into) == 2 * in_old  # the merged file has an index: no series read
    assert reader.run_quantities == expected
    plots = set(blueprint_views(merged)) - {"fake-problem"}
    assert plots == {q for quantities in expected.values() for q in quantities}


@pytest.mark.parametrize(
    "garbage", ["not json", "[1, 2]", '{"runs": 5}', '{"runs": {"x": 3}}', '"text"']
)
def test_a_malformed_index_is_no_index(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, garbage: str
) -> None:
    """A recording is data from whoever made the folder: an index that is not one is
    ignored, the merge goes on and offers every plot for the file's runs (none is lost)."""

    def bad_index(self: RerunSink) -> None:
        self.recording.log("series_index", rr.AnyValues(series_index=garbage), static=True)

    monkeypatch.setattr(RerunSink, "log_index", bad_index)
    sink = RerunSink()
    sink.begin_file(tmp_path / "bad.rrd")
    run = sink.log_run(*_args(fake_run(1e-3)))
    bad = sink.end_file()
    monkeypatch.undo()
    merged = merge_recordings([bad], tmp_path / "all.rrd")
    reader = RerunSink()
    assert reader.add_recording(merged) == [run]
    assert reader.run_quantities[run] == list(SERIES_QUANTITIES)
    assert set(blueprint_views(merged)) - {"fake-problem"} == set(SERIES_QUANTITIES)


def test_one_sink_writes_a_file_a_run(tmp_path: Path) -> None:
    """A worker's sink: each file holds its own run's values only (read back), a file
    with nothing logged is not left behind, and the files merge as separate ones do."""
    sink = RerunSink()
    files = []
    for rtol in (1e-3, 1e-6, 1e-9):
        sink.begin_file(tmp_path / f"{rtol:g}.rrd")
        if rtol != 1e-9:  # the last run is skipped: nothing logged
            sink.log_run(*_args(fake_run(rtol)))
        files.append(sink.end_file())
    assert files[2] is None and sorted(p.name for p in tmp_path.iterdir()) == [
        "0.001.rrd",
        "1e-06.rrd",
    ]
    for path, rtol in zip(files[:2], (1e-3, 1e-6), strict=True):
        chunks = read_chunks(path)
        runs = {key.removesuffix("/series") for key in chunks if key.endswith("/series")}
        assert runs == {f"/runs/fake-problem/minimal-ode/radau/rtol\\={rtol:g}"}
        _t, ref_err = series_of(chunks[f"{runs.pop()}/series"], "ref_err")
        times = np.linspace(0.0, 2.0, 50)
        np.testing.assert_allclose(ref_err, rtol * times**2)
    merged = read_chunks(merge_recordings(files[:2], tmp_path / "all.rrd"))
    assert sum(key.endswith("/series") for key in merged) == 2


def test_entity_paths_escape_and_split() -> None:
    path = entity_path("runs", "a/b", "rtol=1e-06", "x y")
    assert split_entity_path(path) == ["runs", "a/b", "rtol=1e-06", "x y"]
    np.testing.assert_array_equal(quaternion_xyzw(np.array([1.0, 2, 3, 4])), [2, 3, 4, 1])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.text(alphabet="ab/=\\ .[]", max_size=6), min_size=1, max_size=5))
def test_split_entity_path_parses_as_the_regular_expressions_do(parts) -> None:
    """The split without regular expressions where no part has an escape is the split
    with them, on Rerun's escaped paths and on raw text."""
    import re

    def by_regex(path: str) -> list[str]:
        pieces = re.split(r"(?<!\\)/", path.strip("/"))
        return [re.sub(r"\\(.)", r"\1", piece) for piece in pieces if piece]

    for path in (entity_path(*parts), "/".join(parts)):
        assert split_entity_path(path) == by_regex(path)


def test_sink_in_the_runner(tmp_path: Path) -> None:
    """A real run: the runner calls log_run after the metrics."""
    from workbench.execution.execute import RunSpec, execute_run, normalized_spec

    sink = RerunSink()
    spec = normalized_spec(
        RunSpec("simple-pendulum", "minimal-ode", "generalized-alpha", 1e-5, 1e-8)
    )
    result = execute_run(spec, sink=sink)
    assert result.row["status"] == "ok", result.row["message"]
    chunks = read_chunks(sink.save(tmp_path))
    base = "/runs/simple-pendulum/minimal-ode/generalized-alpha/rtol\\=1e-05"
    t, energy_err = series_of(chunks[f"{base}/series"], "energy_err")
    expected = result.series.dropna(subset=["energy_err"])
    np.testing.assert_allclose(t, expected["t"], atol=1e-9)
    np.testing.assert_allclose(energy_err, expected["energy_err"])
    assert f"{base}/ellipsoids" in chunks and f"{base}/joints" in chunks


# -- workbench view ---------------------------------------------------------------------
@pytest.fixture
def recording_file(tmp_path: Path) -> Path:
    sink = RerunSink()
    sink.log_run(*_args(fake_run()))
    return sink.save(tmp_path)


def test_view_without_display_says_how(
    recording_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    outcome = CliRunner().invoke(app, ["view", str(recording_file.parent)])
    assert outcome.exit_code == 0, outcome.output
    assert f"rerun {recording_file}" in outcome.output
    assert "--serve-web" in outcome.output


def test_view_of_a_file_that_is_not_a_recording_is_refused(tmp_path: Path) -> None:
    """It printed the viewer's command for it and exited 0 (and with --run named its
    folder as the recording)."""
    text = tmp_path / "notes.txt"
    text.write_text("hello\n")
    for extra in ([], ["--run", "abc"]):
        outcome = CliRunner().invoke(app, ["view", str(text), *extra])
        assert outcome.exit_code == 2, outcome.output
        assert f"{text} is not a Rerun recording (.rrd)" in outcome.output


def test_view_with_display_starts_the_viewer(
    recording_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import subprocess

    started = []
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(subprocess, "Popen", lambda args, **kwargs: started.append(args))
    outcome = CliRunner().invoke(app, ["view", str(recording_file)])
    assert outcome.exit_code == 0, outcome.output
    assert started and started[0][-1] == str(recording_file)


def test_view_without_a_viewer_is_one_line_error(
    recording_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import subprocess

    def missing(args: list, **kwargs: object) -> None:
        raise FileNotFoundError(2, "No such file or directory", args[0])

    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(subprocess, "Popen", missing)
    outcome = CliRunner().invoke(app, ["view", str(recording_file)])
    assert outcome.exit_code == 2
    assert "error: cannot start the Rerun viewer" in outcome.output


def test_view_missing_recording_is_one_line_error(tmp_path: Path) -> None:
    outcome = CliRunner().invoke(app, ["view", str(tmp_path / "none.rrd")])
    assert outcome.exit_code == 2
    assert "error: no recording at" in outcome.output
    # a user's words, not the workbench's internals (it named RerunSink.save)
    assert "RerunSink" not in outcome.output
    assert "`workbench run --out` writes none" in outcome.output
    assert "`workbench record OUT` makes one" in outcome.output


def test_view_up_is_against_gravity() -> None:
    from types import SimpleNamespace

    from workbench.outputs.recording import view_coordinates

    def up(kind: str, gravity: tuple[float, float, float]) -> object:
        return view_coordinates(SimpleNamespace(kind=kind, gravity=np.array(gravity)))

    views = rr.ViewCoordinates
    assert up("planar", (0, -9.81, 0)) == views.RIGHT_HAND_Y_UP
    assert up("spatial", (0, 0, -9.81)) == views.RIGHT_HAND_Z_UP
    assert up("spatial", (0, 0, 9.81)) == views.RIGHT_HAND_Z_DOWN
    assert up("planar", (0, 0, 0)) == views.RIGHT_HAND_Y_UP  # facing a horizontal plane
    assert up("spatial", (0, 0, 0)) == views.RIGHT_HAND_Z_UP


def test_contact_plane_is_drawn_once_per_model(tmp_path: Path) -> None:
    """The incline's plane (both corner contacts touch it) is one static thin box below
    the model's shared path, logged once for two runs, its top face the plane itself: the
    centre lies half its thickness below the plane point along the normal, and the box's
    local z is the normal."""
    from scipy.spatial.transform import Rotation

    from workbench.execution.execute import RunSpec, execute_run, normalized_spec
    from workbench.problems.ch5_contacts import INCLINE

    sink = RerunSink()
    for rtol in (1e-4, 1e-6):
        spec = normalized_spec(RunSpec("incline-block-slide", "minimal-ode", "event-driven",
                                       rtol, rtol * 1e-3))  # fmt: skip
        assert execute_run(spec, sink=sink).row["status"] == "ok"
    chunks = read_chunks(sink.save(tmp_path))
    planes = [p for p in chunks if "contact_planes" in p]
    assert planes == ["/runs/incline-block-slide/model/contact_planes/rear"]
    (frame,) = chunks[planes[0]]  # one static row for both runs
    half = np.array(frame["Boxes3D:half_sizes"].iloc[0][0])
    centre = np.array(frame["Boxes3D:centers"].iloc[0][0])
    xyzw = np.array(frame["Boxes3D:quaternions"].iloc[0][0])
    normal = np.array([-np.sin(INCLINE), np.cos(INCLINE), 0.0])
    np.testing.assert_allclose(centre, -normal * half[2], atol=1e-6)
    np.testing.assert_allclose(Rotation.from_quat(xyzw).apply([0, 0, 1.0]), normal, atol=1e-6)
    assert half[0] >= 2.0 > 100 * half[2]


PLACING = ("centers", "translations", "quaternions", "rotation_axis_angles", "mat3x3")


def test_a_runs_static_data_leaves_out_what_the_views_default(tmp_path: Path) -> None:
    """Each component column of a run's data costs Python's reader about 4 KiB (the
    footer's manifest): a shape's place in its body is in its instance poses (no static
    centers or rotations), no shape carries a fill mode (solid is the 3D views' default)
    nor the default colour (a view default too), nor shows its label over the view."""
    sink = RerunSink()
    run = sink.log_run(*_args(fake_run()))
    path = sink.save(tmp_path)
    columns = {
        chunk.entity_path: set(chunk.to_record_batch().schema.names)
        for chunk in rr.chunk.RrdReader(path).stream()
        if chunk.is_static
    }
    base = "/" + run
    assert not any(name.endswith(":fill_mode") for names in columns.values() for name in names)
    assert "quantities" not in columns[f"{base}/series"]  # read from the values
    # a shape's place in its body is in its instance poses: no static centers, rotations
    for entity in ("boxes", "capsules", "cylinders", "ellipsoids", "joints"):
        placing = {n for n in columns[f"{base}/{entity}"] if n.split(":")[-1] in PLACING}
        assert not placing, (entity, placing)
    # the arm's shapes have the default colour (a view default), the tip's sphere the
    # model's one sphere colour (its problem's view default): no run's shape has colours
    assert not any(name.endswith(":colors") for names in columns.values() for name in names)
    views = blueprint_views(path)
    assert views["fake-problem"]["class_identifier"] == ["3D"]
    # which the 3D views hold as defaults: solid, in a shape's default colour
    reader = rr.chunk.RrdReader(path)
    defaults: dict[str, list] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        if chunk.entity_path.endswith("/defaults"):
            for name, values in chunk.to_record_batch().to_pydict().items():
                defaults.setdefault(name, []).extend(v for v in values if v is not None)
    default_color = int.from_bytes(bytes([*Shape("box", (1.0,) * 3).color, 255]), "big")
    for archetype in ("Boxes3D", "Cylinders3D", "Capsules3D"):
        assert defaults[f"{archetype}:colors"] == [[default_color]]
        assert f"{archetype}:fill_mode" in defaults
        assert defaults[f"{archetype}:show_labels"] == [[False]]  # a body's name on hover
    assert defaults["Ellipsoids3D:colors"] == [[int.from_bytes(bytes([200, 50, 50, 255]), "big")]]


def run_pairs(sink: RerunSink, run: str, path: Path) -> set[tuple[str, str]]:
    """The (entity below the run, component) pairs of ``run`` in the file ``sink`` saves."""
    return {
        (chunk.entity_path.removeprefix(f"/{run}/"), name)
        for chunk in rr.chunk.RrdReader(sink.save(path)).stream()
        if chunk.entity_path.startswith(f"/{run}/")
        for name in chunk.to_record_batch().schema.names
        if name not in ("rerun.controls.RowId", "sim_time")
    }


def test_a_run_holds_one_component_column_a_thing_it_draws(tmp_path: Path) -> None:
    """Python's reader holds about 5 KiB for each (entity, component) pair of a recording
    whatever its bytes (docs/performance.md): a run holds an entity a shape kind (its
    sizes, its bodies' names, its instance poses), one for its joint frames and one for
    its series; here 22 pairs for 2 bodies of 4 shape kinds (17 when each body was an
    entity, 2,485 -> 1,293 pairs in the default sweep, whose bodies share kinds); a
    sphere's poses hold no rotation (it looks the same turned)."""
    sink = RerunSink()
    run = sink.log_run(*_args(fake_run()))
    pose = ("InstancePoses3D:translations", "InstancePoses3D:quaternions")
    assert run_pairs(sink, run, tmp_path) == {
        *(("boxes", name) for name in (*pose, "Boxes3D:half_sizes", "Boxes3D:labels")),
        *(("capsules", name) for name in (*pose, "Capsules3D:radii", "Capsules3D:lengths",
                                          "Capsules3D:labels")),
        *(("cylinders", name) for name in (*pose, "Cylinders3D:radii", "Cylinders3D:lengths",
                                           "Cylinders3D:labels")),
        *(("ellipsoids", name) for name in (pose[0], "Ellipsoids3D:half_sizes",
                                            "Ellipsoids3D:labels")),
        *(("joints", name) for name in (*pose, "TransformAxes3D:axis_length")),
        ("series", "Scalars:scalars"), ("series", "SeriesLines:names"),
    }  # fmt: skip


class ChainObservables:
    """``n`` links, link i at (i, 0, 0) unrotated at every time."""

    def __init__(self, n: int) -> None:
        self.body_names = [f"link{i}" for i in range(n)]

    def poses_along(self, times: np.ndarray, q: np.ndarray) -> np.ndarray:
        poses = np.zeros((len(times), len(self.body_names), 7))
        poses[..., 0] = np.arange(len(self.body_names))
        poses[..., 3] = 1.0
        return poses


def chain_equations(n: int) -> SimpleNamespace:
    """A chain of ``n`` capsule links, each hinged at the end of the one before."""
    model = Model(f"chain{n}", kind="spatial")
    for i in range(n):
        capsule = Shape("capsule", (0.05, 1.0), Frame.at(0.5, 0, 0))
        model.add_body(f"link{i}", 1.0, inertia=(1.0, 1.0, 1.0), shapes=[capsule])
        parent = f"link{i - 1}" if i else "ground"
        model.add_joint(f"hinge{i}", "revolute", parent, f"link{i}",
                        parent_frame=Frame.at(1.0 if i else 0.0, 0, 0))  # fmt: skip
    return SimpleNamespace(model=model, observables=ChainObservables(n), nq=n)


def test_a_runs_pairs_do_not_grow_with_its_bodies(tmp_path: Path) -> None:
    """A chain of 8 links holds as many (entity, component) pairs as one of 2: its
    shapes are one entity, its joint frames one more (an entity a body held 2-7 pairs
    a body, 2,485 pairs for the default sweep's 102 runs); every link is drawn, at its
    own pose, labelled with its name."""
    pairs, chunks = [], {}
    for n in (2, 8):
        sink = RerunSink()
        spec, trajectory, series = fake_run()
        spec.problem = f"chain-{n}"
        run = sink.log_run(spec, chain_equations(n), None, trajectory, series)
        pairs.append(run_pairs(sink, run, tmp_path / f"{n}.rrd"))
        chunks = read_chunks(tmp_path / f"{n}.rrd")
    assert pairs[0] == pairs[1]
    capsules = chunks[f"/{run}/capsules"]
    labels = static_columns(capsules)["Capsules3D:labels"].iloc[0]
    assert list(labels) == [f"link{i}" for i in range(8)]
    _t, starts, _turns = instance_poses(capsules)
    # link i at (i, 0, 0); its capsule, centred at (0.5, 0, 0) along z, starts 0.5 below
    np.testing.assert_allclose(starts[0], [[i + 0.5, 0, -0.5] for i in range(8)], atol=1e-6)


def test_a_file_of_runs_holds_every_sample_and_its_problems_view_once(tmp_path: Path) -> None:
    """Runs of at most max_frames samples keep every sample's pose, at its own time; a
    file of several runs of a problem holds the problem's view (its up axis and shape
    colours) once, made once (not a run)."""
    sink = RerunSink(max_frames=50)
    sink.begin_file(tmp_path / "batch.rrd")
    runs = [sink.log_run(*_args(fake_run(rtol, n=n))) for rtol, n in ((1e-3, 50), (1e-6, 7))]
    chunks = read_chunks(sink.end_file())
    for run, n in zip(runs, (50, 7), strict=True):
        times = instance_poses(chunks[f"/{run}/capsules"])[0]
        assert np.allclose(times, np.linspace(0.0, 2.0, n))
    problem = chunks["/runs/fake-problem"]
    assert len(problem) == 1 and "ViewCoordinates:xyz" in problem[0].columns
    assert SHAPE_COLORS in problem[0].columns  # the tip's one sphere colour
