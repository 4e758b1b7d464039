"""Rerun recordings read back with Rerun's chunk reader: entities, sim_time, values."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

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
        f"{base}/bodies/arm",  # its pose and, static, its shapes
        f"{base}/bodies/tip",
        "/runs/fake-problem/model/ground/joints",  # the same in every run: once
        f"{base}/bodies/arm/joints",  # both joint frames on the arm, one batch
        f"{base}/series",
    }
    assert expected <= set(chunks)
    assert f"{base}/bodies/tip/joints" not in chunks  # its one frame: at its origin
    (arm_shapes,) = [frame for frame in chunks[f"{base}/bodies/arm"] if "sim_time" not in frame]
    # the arm's box, capsule and cylinder in one chunk (each costs the reader per column)
    assert {"Boxes3D:half_sizes", "Capsules3D:lengths", "Cylinders3D:radii"} <= set(arm_shapes)
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

    arm = column(chunks[f"{base}/bodies/arm"], "Transform3D:quaternion")
    t = seconds(arm["sim_time"])
    np.testing.assert_allclose(t, trajectory.times, atol=1e-9)
    quaternions = np.array([v[0] for v in arm["Transform3D:quaternion"]])
    expected_xyzw = np.column_stack([0 * t, 0 * t, np.sin(t / 2), np.cos(t / 2)])
    np.testing.assert_allclose(quaternions, expected_xyzw, atol=1e-6)
    tip = column(chunks[f"{base}/bodies/tip"], "Transform3D:translation")
    translations = np.array([v[0] for v in tip["Transform3D:translation"]])
    np.testing.assert_allclose(translations[:, 0], trajectory.times, rtol=1e-6)

    # the arm's frames: the hinge's child frame at its origin, the slide's parent frame
    # at (1, 0, 0); one TransformAxes3D drawn at each instance pose
    joints = column(chunks[f"{base}/bodies/arm/joints"], "InstancePoses3D:translations")
    np.testing.assert_allclose(
        np.stack(joints["InstancePoses3D:translations"].iloc[0]), [[0, 0, 0], [1, 0, 0]]
    )
    assert "TransformAxes3D:axis_length" in joints
    # the tip's one frame (the slide's child frame) is at its origin: axes drawn at its
    # pose, from its own static chunk (beside its sphere), no entity of their own
    (tip_static,) = [frame for frame in chunks[f"{base}/bodies/tip"] if "sim_time" not in frame]
    assert {"TransformAxes3D:axis_length", "Ellipsoids3D:half_sizes"} <= set(tip_static)
    assert not any(name.startswith("InstancePoses3D") for name in tip_static)


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
    arm = column(chunks[f"/{paths[0]}/bodies/arm"], "Transform3D:quaternion")
    assert len(arm) == 10  # poses strided to max_frames; series are whole
    assert len(series_of(chunks[f"/{paths[0]}/series"], "ref_err")[1]) == 50


def _args(run: tuple) -> tuple:
    spec, trajectory, series = run
    return spec, fake_equations(), None, trajectory, series


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
    assert any(p.startswith(f"{base}/bodies/") for p in chunks)


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


def test_a_runs_static_data_leaves_out_what_the_views_default(tmp_path: Path) -> None:
    """Each component column of a run's data costs Python's reader about 4 KiB (the
    footer's manifest): a shape at its body's origin has no centers, an unrotated one no
    quaternions, no shape carries a fill mode (solid is the 3D views' default) nor the
    default colour (a view default too), and joint frames on unrotated frames no
    rotation."""
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
    assert "Ellipsoids3D:centers" not in columns[f"{base}/bodies/tip"]
    assert "quantities" not in columns[f"{base}/series"]  # read from the values
    assert "Cylinders3D:quaternions" not in columns[f"{base}/bodies/arm"]
    assert "Boxes3D:centers" in columns[f"{base}/bodies/arm"]
    assert "InstancePoses3D:mat3x3" not in columns[f"{base}/bodies/arm/joints"]
    # the arm's shapes have the default colour (a view default), the tip's sphere the
    # model's one sphere colour (its problem's view default): no run's shape has colours
    assert not any(name.endswith(":colors") for name in columns[f"{base}/bodies/arm"])
    assert not any(name.endswith(":colors") for name in columns[f"{base}/bodies/tip"])
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
    assert defaults["Ellipsoids3D:colors"] == [[int.from_bytes(bytes([200, 50, 50, 255]), "big")]]


def test_a_run_holds_one_component_column_a_thing_it_draws(tmp_path: Path) -> None:
    """Python's reader holds about 5 KiB for each (entity, component) pair of a recording
    whatever its bytes (docs/performance.md): a run of the 2-body model has 17 of them,
    each needed to draw it (19 before its series' ``quantities`` were read from their
    values, the tip's one sphere colour became its view's default and its one joint frame,
    at its origin, moved to its own entity)."""
    sink = RerunSink()
    run = sink.log_run(*_args(fake_run()))
    pairs = {
        (chunk.entity_path.removeprefix(f"/{run}/"), name)
        for chunk in rr.chunk.RrdReader(sink.save(tmp_path)).stream()
        if chunk.entity_path.startswith(f"/{run}/")
        for name in chunk.to_record_batch().schema.names
        if name not in ("rerun.controls.RowId", "sim_time")
    }
    pose = {"Transform3D:translation", "Transform3D:quaternion"}
    assert pairs == {
        *(("bodies/arm", name) for name in pose),
        ("bodies/arm", "Boxes3D:half_sizes"), ("bodies/arm", "Boxes3D:centers"),
        ("bodies/arm", "Capsules3D:radii"), ("bodies/arm", "Capsules3D:lengths"),
        ("bodies/arm", "Capsules3D:translations"),
        ("bodies/arm", "Cylinders3D:radii"), ("bodies/arm", "Cylinders3D:lengths"),
        ("bodies/arm/joints", "TransformAxes3D:axis_length"),
        ("bodies/arm/joints", "InstancePoses3D:translations"),
        *(("bodies/tip", name) for name in pose),
        ("bodies/tip", "Ellipsoids3D:half_sizes"), ("bodies/tip", "TransformAxes3D:axis_length"),
        ("series", "Scalars:scalars"), ("series", "SeriesLines:names"),
    }  # fmt: skip


def test_a_file_of_runs_holds_every_sample_and_its_problems_view_once(tmp_path: Path) -> None:
    """Runs of at most max_frames samples keep every sample's pose, at its own time; a
    file of several runs of a problem holds the problem's view (its up axis and shape
    colours) once, made once (not a run)."""
    sink = RerunSink(max_frames=50)
    sink.begin_file(tmp_path / "batch.rrd")
    runs = [sink.log_run(*_args(fake_run(rtol, n=n))) for rtol, n in ((1e-3, 50), (1e-6, 7))]
    chunks = read_chunks(sink.end_file())
    for run, n in zip(runs, (50, 7), strict=True):
        arm = column(chunks[f"/{run}/bodies/arm"], "Transform3D:quaternion")
        assert np.allclose(seconds(arm["sim_time"]), np.linspace(0.0, 2.0, n))
    problem = chunks["/runs/fake-problem"]
    assert len(problem) == 1 and "ViewCoordinates:xyz" in problem[0].columns
    assert SHAPE_COLORS in problem[0].columns  # the tip's one sphere colour
