"""Rerun recordings of runs: bodies moving in 3D beside their drift and energy error.

:class:`RerunSink` is the runner's log sink (stage 5 of :mod:`workbench.execution.execute`):
the runner calls ``sink.log_run(spec, equations, problem, trajectory, series)`` after the
metrics, and ``sink.save(path)`` writes every logged run and a blueprint to one ``.rrd``
file. Open it with ``workbench view PATH`` (or ``rerun PATH``).

Entity layout of one run (``<run>`` = ``runs/<problem>/<formalism>/<integrator>/rtol=<r>``,
each plugin with its options if it has any: ``rk4[step=0.01]``)::

    <run>/boxes, <run>/ellipsoids,     the run's primitive shapes of one kind, on all its
    <run>/cylinders, <run>/capsules    bodies (Boxes3D, Ellipsoids3D, Cylinders3D,
                                       Capsules3D): static, their sizes and labels (each
                                       shape's body; colours when not the view's default);
                                       on ``sim_time``, InstancePoses3D: shape i at its
                                       body's pose times its place in the body
                                       (spheres: translations only)
    <run>/joints                       each joint's frame on its child body: a static
                                       TransformAxes3D drawn at every frame's instance pose
    <run>/contacts                     the spheres of sphere-sphere contacts on its bodies
                                       (Ellipsoids3D, placed as the shapes)
    <run>/series                       Scalars on ``sim_time``, one instance a quantity:
                                       drift_pos, drift_vel, drift_nh, energy_err,
                                       ref_err, penetration (m; a contact model's deepest
                                       penetration), NaN where the run has none (the
                                       quantities it has: :func:`series_quantities`). The
                                       blueprint's plot of a quantity shows its instance
                                       only (SeriesLines' ``visible_series``, a view default)

An entity a kind rather than a body: Python's reader holds about 5 KiB for each (entity,
component) pair of a file, whatever its bytes (docs/performance.md). Files written before
2026-11-27 hold ``<run>/bodies/<body>`` (its Transform3D and static shapes) and
``<run>/bodies/<body>/joints``; the merge and :func:`extract_run` copy them as they are.

What the runs of a model share, stored once (a robot's meshes are most of its bytes)::

    runs/<problem>                     static: the view's up axis (ViewCoordinates) and,
                                       when a shape kind has one colour in the whole model
                                       other than the default, ``shape_colors`` (JSON: the
                                       3D view's default colour a kind; the runs' shapes
                                       then carry none)
    runs/<problem>/model/bodies/<body>/meshes/<i>   the mesh (Asset3D / Mesh3D), static, and
                                       InstancePoses3D on ``sim_time``: that body's pose in
                                       every run (an instance a run), so each run is drawn
    .../meshes/<i>/instance_runs       which run each instance is (static)
    runs/<problem>/model/ground/joints the joint frames fixed on the ground (static)
    runs/<problem>/model/contact_planes/<contact>  a plane the contacts touch (a thin box,
                                       static; named by its first contact)
    runs/<problem>/model/ground/contacts/<contact>  a contact sphere on the ground (static)

And once a file, outside the runs::

    series_index                       static JSON: the quantities each run of the file
                                       has (:data:`SERIES_INDEX`), so that a merge need
                                       not read every run's series to make the plots

A run's entities are sent as chunks built here (``rerun.chunk.Chunk``: its shapes' one
static chunk made once per model and copied to each run's path, its poses and series in
Arrow), several at a time (:meth:`RerunSink._send`): the recording's share of a tiny
run's cost is mostly Rerun's encoding of them (docs/performance.md).

``sim_time`` is a duration timeline in seconds of simulated time. Poses come from
``equations.observables.poses`` (Euler parameters scalar-first, converted here to Rerun's
x, y, z, w). Runs logged twice under the same path (same keys, other options) get the
run id appended.

The recording is kept in memory until :meth:`RerunSink.save`; a sink used in worker
processes must be saved by each worker (one file each, same recording id: the viewer
merges files of one recording id), since a recording stream cannot be pickled. A sweep's
worker keeps one sink for all its runs and writes a file a batch of runs with
:meth:`RerunSink.begin_file` / :meth:`RerunSink.end_file` (:meth:`RerunSink.fits` says
whether a run may join the file begun; :mod:`workbench.runs.recording_batches`): one
recording stream given a new in-memory binary stream a file, because a new recording
stream a run leaks memory in rerun-sdk (docs/performance.md has the figures).
:func:`merge_recordings` adds those files to the sweep's one ``recording.rrd`` (after
which the sweep removes them) and :func:`extract_run` copies one run back out of it.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import re
import uuid
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.files import atomic_write

SERIES_QUANTITIES: tuple[str, ...] = (
    "drift_pos", "drift_vel", "drift_nh", "energy_err", "ref_err", "penetration",
)  # fmt: skip
TIMELINE = "sim_time"
APPLICATION_ID = "mbs-workbench"
RECORDING_FILE = "recording.rrd"
MODEL_PART = "model"
"""``runs/<problem>/model/...``: what the runs of a model share, stored once (its meshes)."""
INSTANCE_RUNS = "instance_runs"
"""The component naming the run of each instance pose of a shared mesh entity; static, on
its child entity of that name (a chunk of its own: Rerun's batcher may join static rows
of one entity into one chunk, and the mesh must be copied without it)."""
SERIES_ENTITY = "series"
"""``<run>/series``: all of a run's time series, one Scalars instance a quantity in the
order of :data:`SERIES_QUANTITIES` (NaN where the run has none), sent in one column
chunk: a chunk a quantity cost the reader about 11 KiB each (its footer's manifest)."""
CHUNKS_HELD = 64
"""Chunks a sink holds before sending them to its stream together (:meth:`RerunSink._send`)."""
FILE_VALUES_LIMIT = 2**22
"""Values (instance poses, 4 bytes each; series, 8) a file of several runs takes before
it is written (:meth:`RerunSink.fits`): its runs are held in memory until then."""
SERIES_INDEX = "series_index"
"""A file's static entity (and component, JSON text) saying which quantities each of its
runs has series values of: ``{"runs": {run path: [quantity, ...]}}``, logged at the end
of the file. A first copy without ``runs`` is logged before any run, so that a merge
reading the file knows an index follows and skips looking into every run's series (the
blueprint's plots: a third of a tiny run's merge; docs/performance.md)."""
SERIES_PRESENT = "quantities"
"""The static component of ``<run>/series`` that named the quantities a run has values of
in files written before 2026-11-27 (now read from its values: :func:`series_quantities`)."""
SHAPE_COLORS = "shape_colors"
"""The static component of ``runs/<problem>`` (JSON: archetype -> RGBA) giving the 3D
view's default colour of each shape kind that has one colour in the whole model."""
SHAPE_ARCHETYPES = {
    "box": "Boxes3D", "sphere": "Ellipsoids3D", "cylinder": "Cylinders3D",
    "capsule": "Capsules3D",
}  # fmt: skip
SHAPE_ENTITIES = {"box": "boxes", "sphere": "ellipsoids", "cylinder": "cylinders",
                  "capsule": "capsules"}  # fmt: skip
"""``<run>/<entity>`` of each primitive shape kind: all the run's shapes of that kind."""
JOINTS_ENTITY = "joints"
"""``<run>/joints``: the run's joint frames, each on its joint's child body."""
CONTACTS_ENTITY = "contacts"
"""``<run>/contacts``: the spheres of the run's sphere-sphere contacts on its bodies."""


@dataclass(frozen=True)
class Placed:
    """What one entity of a run draws, each instance fixed in a body: its static component
    batches, and each instance's body and place in it (drawn at the body's pose times that
    place, :meth:`RerunSink._log_poses`)."""

    batches: list[Any]
    bodies: tuple[str, ...]
    positions: np.ndarray  # (k, 3) in the body
    quaternions: np.ndarray  # (k, 4) x, y, z, w in the body
    turns: bool = True
    """Whether an instance's rotation shows: not for spheres, whose poses are then
    translations only (a column fewer to build, encode and merge a run)."""

    @functools.cached_property
    def chunk(self) -> Any:
        """The batches as one static chunk (a row of all instances), made once and copied
        to each run's entity (:meth:`rerun.chunk.Chunk.with_entity_path`: 2 us against
        about 0.1 ms for a ``log`` call a run)."""
        return static_chunk("template", self.batches)


@dataclass(frozen=True)
class RunLayout:
    """A model's entities: ``placed`` below each run (name -> :class:`Placed`) and
    ``shared`` (relative path, component batches) once per model below
    ``runs/<problem>/model``; ``bodies``, ``positions`` and ``quaternions``: those of
    every placed instance, entity after entity (their poses are computed at once)."""

    shared: list[tuple[str, list[Any]]]
    placed: dict[str, Placed]

    @functools.cached_property
    def bodies(self) -> tuple[str, ...]:
        return tuple(body for placed in self.placed.values() for body in placed.bodies)

    @functools.cached_property
    def positions(self) -> np.ndarray:
        return np.concatenate([placed.positions for placed in self.placed.values()])

    @functools.cached_property
    def quaternions(self) -> np.ndarray:
        return np.concatenate([placed.quaternions for placed in self.placed.values()])


def entity_path(*parts: str) -> str:
    """Join path parts, each escaped for Rerun (so '/', '=' or spaces in names are kept)."""
    import rerun as rr

    return "/".join(rr.escape_entity_path_part(str(part)) for part in parts)


def run_parts(spec: Any) -> tuple[str, ...]:
    """The path parts of a run: runs, problem, formalism, integrator, rtol=<r>; a plugin
    run with options carries them (``rk4[step=0.01]``), so runs that differ only in
    options are distinct entities, also once the files of several workers are merged."""
    return (
        "runs",
        problem_part(spec),
        with_options("formalism", spec.formalism, getattr(spec, "formalism_options", None)),
        with_options("integrator", spec.integrator, getattr(spec, "integrator_options", None)),
        f"rtol={float(spec.rtol):g}",
    )


def problem_part(spec: Any) -> str:
    """The problem's path part: a robot run's name already says its file and options."""
    from workbench.plugin.robot_problem import is_robot_problem_name

    if is_robot_problem_name(spec.problem):
        return str(spec.problem)
    return with_options("problem", spec.problem, getattr(spec, "problem_options", None))


def with_options(kind: str, name: str, options: dict[str, Any] | None) -> str:
    """``name[key=value,...]`` with the options that differ from the plugin's defaults
    (keys sorted, values as JSON; all of them if the plugin is not registered here), or
    ``name`` when there are none."""
    from workbench.plugin.registry import non_default_options

    options = non_default_options(kind, name, dict(options or {}))
    if not options:
        return str(name)
    text = ",".join(f"{key}={json.dumps(options[key], default=str)}" for key in sorted(options))
    return f"{name}[{text.replace(chr(34), '')}]"


def quaternion_xyzw(scalar_first: np.ndarray) -> np.ndarray:
    """(..., 4) Euler parameters (p0, p1, p2, p3) -> Rerun's (x, y, z, w)."""
    return np.asarray(scalar_first, dtype=float)[..., [1, 2, 3, 0]]


def matrix_xyzw(rotation: np.ndarray) -> np.ndarray:
    """A rotation matrix (3, 3) as a quaternion (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_quat()


class RerunSink:
    """Logs runs into one Rerun recording (see the module docstring for the layout).

    application_id / recording_id: Rerun's; pass the same recording_id to sinks in several
        processes to have their files merged by the viewer.
    max_frames: at most this many poses per run (evenly strided); series are logged whole.
    """

    # log_run reads a series given as its columns (name -> values, ``run_id`` one text:
    # workbench.execution.metrics.metric_columns) as well as a DataFrame: the runner then
    # hands it the columns and makes no frame
    takes_series_columns = True

    def __init__(
        self,
        application_id: str = APPLICATION_ID,
        recording_id: str | uuid.UUID | None = None,
        max_frames: int = 2000,
    ) -> None:
        import rerun as rr

        self.recording_id = str(recording_id or uuid.uuid4())
        self.recording = rr.RecordingStream(application_id, recording_id=self.recording_id)
        self.max_frames = max(2, int(max_frames))
        self.runs: dict[str, tuple[str, str]] = {}  # run path -> (problem, label)
        self.quantities: set[str] = set()  # series logged by at least one run
        self.run_quantities: dict[str, list[str]] = {}  # run path -> its quantities
        self.shape_colors: dict[str, dict[str, list[int]]] = {}  # problem part -> archetype
        self._file = Path()  # the file of begin_file
        self._file_values = 0  # values (poses, series) logged to it: its size in memory
        self._stream: Any = None  # its binary stream, until end_file
        self._chunks: list[Any] = []  # a run's chunks not yet sent (_send)
        self._layouts: dict[str, RunLayout] = {}  # per model key
        self._colors_cache: dict[str, dict[str, list[int]]] = {}  # per model key
        self._geometry_warnings: dict[str, list[str]] = {}  # per model key: unreadable meshes
        self.run_warnings: list[str] = []  # of the last run logged (for its row)
        self._last_parts: tuple[Any, tuple[str, ...]] = (None, ())  # (spec, its run_parts)
        # per model key: mesh entity below the run -> (body, position, 3x3 incl. scale)
        self._mesh_places: dict[str, dict[str, tuple[str, np.ndarray, np.ndarray]]] = {}
        # shared entities logged to the current file (-> the file copied from, when merging)
        self._shared_logged: dict[str, str] = {}
        # shared mesh entity -> run path -> (times s, translations (n, 3), mat3x3 (n, 9) by columns)
        self.instances: dict[str, dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}

    # -- logging --------------------------------------------------------------------------
    def log_run(
        self, spec: Any, equations: Any, problem: Any, trajectory: Any, series: pd.DataFrame | None
    ) -> str:
        """Log one run: body poses, shapes and joint frames, and its time series.

        spec: .problem, .formalism, .integrator, .rtol (and .run_id);
        equations: a :class:`workbench.equations.Equations` (``observables.poses``,
            ``model``, ``nq``); trajectory: ``times`` (n,) and ``y`` (n, >= nq) rows [q, v, ...];
        series: columns t and :data:`SERIES_QUANTITIES` (a ``run_id`` column is filtered on),
            a DataFrame or its columns (name -> values; a text, ``run_id``, for every row).
        Returns the run's entity path.
        """
        import rerun as rr

        parts = self._run_parts(spec)
        path = entity_path(*parts)
        run_id = getattr(spec, "run_id", None)  # a hash: computed once
        if path in self.runs:
            suffix = run_id if run_id is not None else len(self.runs)
            parts = parts[:-1] + (f"{parts[-1]} {suffix}",)
            path = entity_path(*parts)
        label = f"{parts[2]} / {parts[3]} {parts[4]}"
        if not self.runs:  # the file's first run: its index will follow (SERIES_INDEX)
            self.begin_index()
        self.runs[path] = (parts[1], label)
        self.run_quantities[path] = []
        model = equations.model
        options = json.dumps(getattr(spec, "problem_options", {}), sort_keys=True, default=str)
        key = f"{spec.problem} {options} {model.name}"
        colors = self._model_colors(model, key)
        if colors:  # one component for the problem, none in each run's shapes
            self.shape_colors[parts[1]] = colors
        problem_path = entity_path("runs", parts[1])
        if problem_path not in self._shared_logged:  # once a file: shared by its runs
            self._shared_logged[problem_path] = ""
            problem_data = [view_coordinates(model)]  # (made once a file too)
            if colors:
                problem_data.append(rr.AnyValues(**{SHAPE_COLORS: json.dumps(colors)}))
            self.recording.log(problem_path, *problem_data, static=True)
        shared = entity_path("runs", parts[1], MODEL_PART)
        self._log_geometry(path, shared, model, key)
        self.run_warnings = list(self._geometry_warnings.get(key, []))
        self._log_poses(path, equations, trajectory, shared, key)
        self._log_series(path, series, label, run_id)
        return path

    def _log_geometry(self, path: str, shared: str, model: Any, key: str) -> None:
        """A run's shapes and joint frames (static; placed by :meth:`_log_poses`) below the
        run; what every run of the model draws alike (a mesh, the ground's joint frames, a
        contact plane) once per model and file below ``shared`` (``runs/<problem>/model``)."""
        layout = self._layout(model, key)
        for relative, archetypes in _contact_planes(model):  # fixed: drawn once per model
            if f"{shared}/{relative}" not in self._shared_logged:
                self._shared_logged[f"{shared}/{relative}"] = ""
                self.recording.log(f"{shared}/{relative}", *archetypes, static=True)
        for relative, batches in layout.shared:
            if f"{shared}/{relative}" not in self._shared_logged:
                self._shared_logged[f"{shared}/{relative}"] = ""
                self.recording.log(f"{shared}/{relative}", batches, static=True)
        for name, placed in layout.placed.items():  # one chunk an entity
            self._send(placed.chunk.with_entity_path(f"{path}/{name}"))

    def _model_colors(self, model: Any, key: str) -> dict[str, list[int]]:
        """Archetype -> colour of each primitive shape kind that has one colour in the whole
        model other than the default: the model's 3D view default (:func:`shape_defaults`),
        so that no run's shapes carry it (each component of a run's static data costs
        Python's reader about 5 KiB; docs/performance.md)."""
        if key not in self._colors_cache:
            by_kind: dict[str, set[tuple[int, ...]]] = {}
            for body in model.bodies.values():
                for shape in body.shapes:
                    if shape.kind in SHAPE_ARCHETYPES:
                        by_kind.setdefault(shape.kind, set()).add(tuple(shape.color))
            self._colors_cache[key] = {
                SHAPE_ARCHETYPES[kind]: [int(c) for c in next(iter(colors))]
                for kind, colors in by_kind.items()
                if len(colors) == 1 and next(iter(colors)) != tuple(default_shape_color())
            }
        return self._colors_cache[key]

    def _layout(self, model: Any, key: str) -> RunLayout:
        """The entities of a run of ``model`` and what the runs share, made once per model
        ``key`` (problem and options): the runs of a sweep share models.

        A run's primitive shapes are an entity a kind (``boxes``, ``capsules``, ...: one
        instance a shape, labelled with its body's name) and its joint frames one more
        (``joints``), each drawn at instance poses (a body's pose times the shape's or
        frame's place in it), not an entity a body: Python's reader holds about 5 KiB a
        (entity, component) pair of the file's manifest, which a body's own entities
        multiplied (docs/performance.md). A robot's meshes are shared per model."""
        if key in self._layouts:
            return self._layouts[key]
        warnings: list[str] = self._geometry_warnings.setdefault(key, [])
        axis_length = 0.3 * _model_scale(model)
        shared: list[tuple[str, list[Any]]] = []
        ground = [joint.parent_frame for joint in model.joints.values() if joint.parent == "ground"]
        ground += [joint.child_frame for joint in model.joints.values() if joint.child == "ground"]
        if ground:  # the same in every run: once per model
            shared.append(("ground/joints", _batches(_joint_axes(ground, axis_length))))
        shapes: list[tuple[str, Any]] = []  # (body, shape) of the primitive shapes
        for name, body in model.bodies.items():
            shapes += [(name, shape) for shape in body.shapes if shape.kind in SHAPE_ARCHETYPES]
            meshes = [shape for shape in body.shapes if shape.kind == "mesh"]
            for index, shape in enumerate(meshes):  # a robot file's visual meshes
                relative = f"{entity_path('bodies', name)}/meshes/{index}"
                archetypes, warning = _mesh_archetypes(shape)
                if warning:  # a red box where the mesh is, one of the run's boxes
                    warnings.append(f"body {name!r}: {warning}")
                    shapes.append((name, _placeholder(shape)))
                    continue
                # drawn once per model at every run's pose (_log_poses), placed by its
                # instance poses rather than its transform (archetypes[0])
                place = (name, shape.frame.position, shape.frame.rotation @ np.diag(shape.size))
                self._mesh_places.setdefault(key, {})[relative] = place
                shared.append((relative, _batches(archetypes[1:])))
        placed = _placed_shapes(shapes, self._model_colors(model, key))
        frames = _child_frames(model)
        if frames:  # one TransformAxes3D drawn at every frame's pose
            placed[JOINTS_ENTITY] = _placed(frames, [_transform_axes(axis_length)])
        spheres, on_ground = _contact_spheres(model)
        shared += on_ground
        if spheres:
            places = [(body, centre, np.eye(3)) for body, centre, _radius in spheres]
            placed[CONTACTS_ENTITY] = _placed(places, [_contact_ellipsoids(spheres)], turns=False)
        self._layouts[key] = RunLayout(shared, placed)
        return self._layouts[key]

    def _log_poses(
        self, path: str, equations: Any, trajectory: Any, shared: str = "", key: str = ""
    ) -> None:
        import rerun as rr
        from rerun.chunk import Chunk

        times = np.asarray(trajectory.times, dtype=float).reshape(-1)
        y = np.atleast_2d(np.asarray(trajectory.y, dtype=float))
        n = min(len(times), len(y))
        if n == 0:
            return
        if n <= self.max_frames:  # every sample
            rows = np.arange(n)
        else:  # steps of (n - 1) / (max_frames - 1) > 1: rounded, distinct and increasing
            rows = np.linspace(0, n - 1, self.max_frames).round().astype(int)
        observables = equations.observables
        if hasattr(observables, "poses_of_rows"):  # the metrics' poses of these states
            poses = observables.poses_of_rows(times[:n], y[:n, : equations.nq], rows)
        else:
            poses = observables.poses_along(times[rows], y[rows, : equations.nq])
        timeline = rr.TimeColumn(TIMELINE, duration=times[rows])
        bodies = {name: b for b, name in enumerate(observables.body_names)}
        # each body's pose as (x, y, z, qx, qy, qz, qw); last, the identity (for a shape
        # whose body has none)
        body_poses = np.zeros((len(rows), len(bodies) + 1, 7))
        body_poses[:, :-1, :3] = poses[..., :3]
        body_poses[:, :-1, 3:] = quaternion_xyzw(poses[..., 3:])
        body_poses[:, -1, 6] = 1.0
        layout = self._layouts.get(key)
        if layout is not None and layout.placed:
            # every instance of the run's entities at once (a call each: 0.1 ms more)
            at = [bodies.get(body, len(bodies)) for body in layout.bodies]
            translations, quaternions = _compose(
                body_poses[:, at], layout.positions, layout.quaternions
            )
            self._file_values += translations.size + quaternions.size
            start = 0
            for name, placed in layout.placed.items():
                end = start + len(placed.bodies)
                columns = [_column("translations", translations[:, start:end])]
                if placed.turns:
                    columns.append(_column("quaternions", quaternions[:, start:end]))
                self._send(Chunk.from_columns(f"{path}/{name}", [timeline], columns))
                start = end
        for relative, (body, position, matrix) in self._mesh_places.get(key, {}).items():
            if body not in bodies:
                continue
            pose = poses[:, bodies[body]]
            rotation = _rotation_matrices(pose[:, 3:])  # (n, 3, 3)
            self.instances.setdefault(f"{shared}/{relative}", {})[path] = (
                times[rows],
                (pose[:, :3] + rotation @ np.asarray(position, dtype=float)).astype(np.float32),
                # by columns, as Rerun keeps a 3 x 3 matrix (and _instance_poses reads it)
                (rotation @ np.asarray(matrix, dtype=float)).transpose(0, 2, 1)
                .reshape(-1, 9).astype(np.float32),
            )

    def _log_series(
        self, path: str, series: pd.DataFrame | dict[str, Any] | None, label: str,
        run_id: str | None,
    ) -> None:  # fmt: skip
        import rerun as rr
        from rerun.chunk import Chunk

        if series is None or "t" not in series:
            return
        if isinstance(series, pd.DataFrame):
            if run_id is not None and "run_id" in series:
                ids = series["run_id"].to_numpy()
                if not (ids == str(run_id)).all():  # a run's own series is kept whole
                    series = series[series["run_id"].astype(str) == str(run_id)]
            columns = {n: series[n].to_numpy() for n in ("t", *SERIES_QUANTITIES) if n in series}
        else:  # its columns: a run's own (run_id one text), unless they name another run
            columns = series
            ids = columns.get("run_id")
            if (
                run_id is not None
                and ids is not None
                and not (isinstance(ids, str) and ids == str(run_id))
                and np.any(np.asarray(ids) != str(run_id))
            ):
                keep = np.broadcast_to(np.asarray(ids) == str(run_id), len(columns["t"]))
                columns = {k: v[keep] if isinstance(v, np.ndarray) else v
                           for k, v in columns.items()}  # fmt: skip
        t = np.asarray(columns["t"], dtype=float)
        if not len(t):
            return
        # one copy of all quantities (an absent one is NaN, an infinite value a gap too)
        nan = np.full(len(t), np.nan)  # (a pandas reindex cost 0.2 ms a run)
        table = np.column_stack(
            [np.asarray(columns[q], dtype=float) if q in columns else nan
             for q in SERIES_QUANTITIES]
        )  # fmt: skip
        finite = np.isfinite(table)
        present = [q for q, has in zip(SERIES_QUANTITIES, finite.any(axis=0), strict=True) if has]
        keep = np.isfinite(t)
        if not present or not keep.any():
            return
        table[~finite] = np.nan
        self.quantities.update(present)
        self.run_quantities[path] = present
        self._file_values += table.size
        series_path = f"{path}/{SERIES_ENTITY}"
        # the legend's name of each line; which quantities the run has is read from the
        # values (a component column of static data a run costs the reader about 5 KiB)
        names = _names_column(label, len(SERIES_QUANTITIES))
        self._send(Chunk.from_columns(series_path, [], [names]))
        self._send(
            Chunk.from_columns(
                series_path,
                [rr.TimeColumn(TIMELINE, duration=t[keep])],
                [_column("scalars", table[keep])],
            )
        )

    def _send(self, chunk: Any) -> None:
        """Send a run's chunk with the next ones: Rerun encodes a list of chunks for less
        than a ``send_columns`` call each (0.08-0.10 against 0.13-0.15 ms a chunk of 201
        rows, rerun-sdk 0.41; docs/performance.md); :meth:`flush_chunks` sends them."""
        self._chunks.append(chunk)
        if len(self._chunks) >= CHUNKS_HELD:
            self.flush_chunks()

    def flush_chunks(self) -> None:
        """Send the chunks :meth:`_send` holds, in their order."""
        if self._chunks:
            chunks, self._chunks = self._chunks, []
            self.recording.send_chunks(chunks)

    def begin_index(self) -> None:
        """Send the first copy of the file's :data:`SERIES_INDEX` (no runs in it) as a
        static column chunk: it goes to the file at once, before any run's series (sent
        the same way); a ``log`` call would wait in Rerun's batcher, which does not keep
        the order of calls across entities."""
        import rerun as rr

        columns = rr.AnyValues.columns(**{SERIES_INDEX: ["{}"]})
        self.recording.send_columns(SERIES_INDEX, indexes=[], columns=columns)

    def log_index(self) -> None:
        """Log the file's :data:`SERIES_INDEX`: the quantities of each of its runs."""
        import rerun as rr

        if self.runs:
            runs = {run: self.run_quantities.get(run, list(SERIES_QUANTITIES)) for run in self.runs}
            text = json.dumps({"runs": runs}, separators=(",", ":"))
            self.recording.log(SERIES_INDEX, rr.AnyValues(**{SERIES_INDEX: text}), static=True)

    # -- the file -------------------------------------------------------------------------
    def blueprint(self) -> Any:
        """A 3D view per problem (tabs; its runs overlaid, so drift shows as bodies
        parting) beside one time-series plot per quantity that some run logged."""
        import rerun as rr
        import rerun.blueprint as rrb

        problems = list(dict.fromkeys(problem for problem, _label in self.runs.values()))
        spatial = [
            rrb.Spatial3DView(
                origin=entity_path("runs", problem),
                name=problem,
                defaults=shape_defaults(self.shape_colors.get(problem)),
            )
            for problem in problems
        ] or [rrb.Spatial3DView(origin="runs", name="runs", defaults=shape_defaults())]
        plots = [
            rrb.TimeSeriesView(
                name=quantity,
                origin="runs",
                contents=[f"+ /{path}/{SERIES_ENTITY}" for path in self.runs] or "$origin/**",
                # every run's series entity holds all quantities, one line each: the
                # view shows this quantity's (a default, so one entry however many runs)
                defaults=[
                    rr.SeriesLines.from_fields(
                        visible_series=[other == quantity for other in SERIES_QUANTITIES]
                    )
                ],
                plot_legend=rrb.PlotLegend(rrb.Corner2D.LeftTop),  # errors grow to the right
            )
            for quantity in SERIES_QUANTITIES
            if quantity in self.quantities
        ]
        layout = (
            rrb.Horizontal(rrb.Tabs(*spatial), rrb.Vertical(*plots), column_shares=[3, 2])
            if plots
            else rrb.Tabs(*spatial)
        )
        # The views get the room: the selection panel is closed and the time panel shows
        # only its controls (both open with a click).
        return rrb.Blueprint(
            layout,
            rrb.SelectionPanel(state="collapsed"),
            rrb.TimePanel(state="collapsed", timeline=TIMELINE),
            collapse_panels=False,
        )

    def save(self, path: str | Path) -> Path:
        """Write the recording (with its blueprint) to ``path``; a directory gets
        ``recording.rrd``. Returns the file's path. Call once, after the last run.

        The file is written beside the target and renamed over it, so a reader never
        sees half a recording (not synced to disk: a view, made again from the runs).
        The recording is encoded in memory (a Rerun binary stream) and written by Python:
        Rerun's file sink blocks forever on a full disk (rerun-sdk 0.41: it logs ENOSPC and
        its flush never returns), whereas this raises the OSError, leaving ``path`` as
        it was and no temporary file behind.
        """
        target = Path(path)
        if target.is_dir() or target.suffix != ".rrd":
            target = target / RECORDING_FILE
        stream = self.recording.binary_stream()
        self.flush_chunks()
        self.send_instances()
        self.log_index()
        self.recording.send_blueprint(self.blueprint(), make_active=False, make_default=True)
        data = stream.read() or b""
        self.recording.disconnect()
        atomic_write(target, lambda temporary: Path(temporary).write_bytes(data), durable=False)
        return target

    def begin_file(self, path: str | Path) -> None:
        """Send what is logged from now on to the file ``path``, forgetting the runs
        logged before: a file a run, or a batch of runs (:meth:`fits`), through one
        recording stream (see the module docstring). The runs are kept in memory (a Rerun
        binary stream) until :meth:`end_file` writes them, which costs less than a file
        sink (its thread start-up and flush; docs/performance.md)."""
        self._chunks.clear()  # of a file never ended (its writer failed): not this one's
        self._stream = self.recording.binary_stream()
        self._file = Path(path)
        self._file_values = 0
        self.runs.clear()
        self.quantities.clear()
        self.run_quantities.clear()
        self.shape_colors.clear()
        self.instances.clear()
        self._shared_logged.clear()

    def fits(self, spec: Any) -> bool:
        """Whether the run ``spec`` can join the file begun (a file of several runs, as a
        sweep's worker writes them): not when the file holds a run of the same entity path
        (a file a run kept the first of them) or one whose poses instance a shared mesh
        (:meth:`send_instances` puts the runs of one file on one time grid), so that the
        merged recording is the one per-run files make; nor when it holds
        :data:`FILE_VALUES_LIMIT` values (kept in memory until :meth:`end_file`)."""
        return (
            not self.instances
            and self._file_values < FILE_VALUES_LIMIT
            and entity_path(*self._run_parts(spec)) not in self.runs
        )

    def _run_parts(self, spec: Any) -> tuple[str, ...]:
        """:func:`run_parts` of ``spec``, kept for the next call with the same spec (a
        batch's worker asks :meth:`fits` and then logs the run: each a registry lookup and
        the options' defaults compared three times)."""
        if self._last_parts[0] is not spec:
            self._last_parts = (spec, run_parts(spec))
        return self._last_parts[1]

    def end_file(self) -> Path | None:
        """Write what was logged since :meth:`begin_file` to its file (atomically: a
        temporary file renamed into place); None, and no file, when nothing was logged
        (a skipped or failed run)."""
        stream, target = self._stream, self._file
        self._stream = None
        if stream is None:
            return None
        self.flush_chunks()
        self.send_instances()
        self.log_index()
        data = stream.read()
        if not self.runs:
            return None
        atomic_write(target, lambda temporary: Path(temporary).write_bytes(data), durable=False)
        return target

    def send_instances(self) -> None:
        """Log the instance poses gathered for each shared mesh (every run's pose of the
        mesh's body, a row a sample time of the longest run; a run without a sample there
        holds its latest pose) and, static beside them, which run each instance is."""
        import rerun as rr

        for entity, by_run in self.instances.items():
            runs = list(by_run)
            grid = max((by_run[run][0] for run in runs), key=len)
            if len(grid) == 0:
                continue
            translations, matrices = [], []
            for run in runs:
                times, translation, matrix = by_run[run]
                at = np.clip(np.searchsorted(times, grid, side="right") - 1, 0, len(times) - 1)
                translations.append(translation[at])
                matrices.append(matrix[at])
            # (samples, runs, 3 or 9): one row a sample time, an instance a run
            translation, matrix = np.stack(translations, axis=1), np.stack(matrices, axis=1)
            self.recording.log(
                f"{entity}/{INSTANCE_RUNS}", rr.AnyValues(**{INSTANCE_RUNS: runs}), static=True
            )
            self.recording.send_columns(
                entity,
                indexes=[rr.TimeColumn(TIMELINE, duration=grid)],
                columns=[_column("translations", translation), _column("mat3x3", matrix)],
            )
        self.instances.clear()

    # -- several files into one -----------------------------------------------------------
    def add_recording(self, path: str | Path, only_run: str | None = None) -> list[str]:
        """Copy the runs of a saved recording (e.g. one a worker wrote) into this one;
        ``only_run``: that run's path only (with what it shares with others).

        Returns the run paths found. Lets a sweep log each run in its worker process to
        its own file and merge them at the end (see :func:`merge_recordings`). A run
        already added (from a newer file) is left out; an entity shared by runs (a
        problem's view coordinates, a model's meshes) is copied from the first file that
        has it; the instance poses of shared meshes are gathered, to be written by
        :meth:`send_instances`.
        """
        import rerun as rr

        found: list[str] = []
        known = set(self.runs)
        poses: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        named: dict[str, list[str]] = {}  # shared mesh entity -> run of each instance
        with warnings.catch_warnings():  # a large merged file has no footer, by design
            warnings.filterwarnings("ignore", message="RRD file has no footer")
            reader = rr.chunk.RrdReader(path)
        heads: dict[str, tuple[list[str], str]] = {}  # a path's parts but the last, run
        indexed, index = False, None  # an index announced before the runs; its runs
        for chunk in reader.stream():  # one chunk at a time (to_chunks: a list of all)
            parts, run = _parsed_entity(chunk.entity_path, heads)
            if parts == [SERIES_INDEX] and chunk.is_static:
                content = _index_content(chunk.to_record_batch())
                if content is not None and "runs" not in content:
                    indexed = not found  # announced before any run: trusted
                elif content is not None and indexed:
                    index = content["runs"]
                continue
            if parts[:1] != ["runs"]:
                continue  # recording properties and anything not a run or a problem
            if only_run is not None and parts[1:2] != split_entity_path(only_run)[1:2]:
                continue  # another problem's
            if len(parts) == 2 or (len(parts) > 2 and parts[2] == MODEL_PART):
                shared = entity_path(*parts)
                if len(parts) == 2 and chunk.is_static:  # the problem's view defaults
                    batch = chunk.to_record_batch()
                    if SHAPE_COLORS in batch.schema.names:
                        colors = batch.column(SHAPE_COLORS)[0].as_py()
                        text = colors[0] if isinstance(colors, list) else colors
                        self.shape_colors.setdefault(parts[1], json.loads(text))
                if parts[-1] == INSTANCE_RUNS:  # which run each instance of the parent is
                    runs = chunk.to_record_batch().column(INSTANCE_RUNS)[0].as_py()
                    named[entity_path(*parts[:-1])] = [str(run) for run in runs]
                elif not chunk.is_static:
                    poses.setdefault(shared, []).append(_instance_poses(chunk.to_record_batch()))
                elif self._shared_logged.setdefault(shared, str(path)) == str(path):
                    self._send(chunk)  # the first file's copy only
                continue
            if len(parts) < 6:
                continue
            run = run if len(parts) == 6 else entity_path(*parts[:5])
            if run in known or (only_run is not None and run != only_run):
                continue  # a newer file has this run, or another run
            if run not in self.runs:
                label = f"{parts[2]} / {parts[3]} {parts[4]}"
                self.runs[run] = (parts[1], label)
                self.run_quantities[run] = []
                found.append(run)
            if not indexed and len(parts) == 6 and parts[5] == SERIES_ENTITY:
                batch = chunk.to_record_batch()  # a file without an index: its values
                quantities = series_quantities(batch)
                if SERIES_PRESENT in batch.schema.names:  # a file written before 2026-11-27
                    quantities += map(str, batch.column(SERIES_PRESENT)[0].as_py())
                had = self.run_quantities[run]
                had += [quantity for quantity in quantities if quantity not in had]
                self.quantities.update(quantities)
            self._send(chunk)
        self.flush_chunks()
        if indexed:  # a run the index does not name (not written so): every plot offered
            for run in found:
                quantities = (index or {}).get(run, SERIES_QUANTITIES)
                self.run_quantities[run] = [q for q in SERIES_QUANTITIES if q in quantities]
                self.quantities.update(self.run_quantities[run])
        for shared, pieces in poses.items():
            runs = named.get(shared) or found[:1]  # a run's own file names none: its run
            times = np.concatenate([piece[0] for piece in pieces])
            order = np.argsort(times, kind="stable")
            translation = np.concatenate([piece[1] for piece in pieces])[order]
            matrix = np.concatenate([piece[2] for piece in pieces])[order]
            if translation.shape[1] != len(runs):
                continue  # not written by this module: left out
            gathered = self.instances.setdefault(shared, {})
            for k, run in enumerate(runs):
                if only_run is not None and run != only_run:
                    continue
                if run not in known and run not in gathered:
                    gathered[run] = (times[order], translation[:, k], matrix[:, k])
        return found


def _index_content(batch: Any) -> dict[str, Any] | None:
    """A :data:`SERIES_INDEX` chunk's content: ``{}`` (announced) or ``{"runs": {run path:
    [quantity, ...]}}``; None when it is anything else (a file is data: a malformed index
    is no index, its runs then offer every plot)."""
    if SERIES_INDEX not in batch.schema.names or batch.num_rows == 0:
        return None
    text = batch.column(SERIES_INDEX)[0].as_py()
    text = text[0] if isinstance(text, list) and text else text
    try:
        content = json.loads(text) if isinstance(text, str) else None
    except ValueError:
        return None
    if not isinstance(content, dict):
        return None
    runs = content.get("runs", {})
    if not isinstance(runs, dict) or not all(isinstance(q, list) for q in runs.values()):
        return None
    return content


def series_quantities(batch: Any) -> list[str]:
    """The quantities (:data:`SERIES_QUANTITIES`) that have a finite value in a record
    batch of a run's ``series`` entity; none if it holds no such values."""
    name = "Scalars:scalars"
    if name not in batch.schema.names or batch.num_rows == 0:
        return []
    values = np.asarray(batch.column(name).flatten(), dtype=float)
    if values.size != batch.num_rows * len(SERIES_QUANTITIES):
        return []  # not written by this module
    finite = np.isfinite(values.reshape(batch.num_rows, -1)).any(axis=0)
    return [quantity for quantity, has in zip(SERIES_QUANTITIES, finite, strict=True) if has]


def run_path_of_row(row: dict[str, Any]) -> str:
    """The entity path of a result row's run (its options as dicts or JSON text)."""
    from types import SimpleNamespace

    from workbench.runs.store import row_options

    return entity_path(*run_parts(SimpleNamespace(**(dict(row) | row_options(row)))))


def extract_run(recording: str | Path, run: str, target: str | Path) -> Path:
    """Write the run with entity path ``run`` (:func:`run_parts`) of a merged recording to
    its own file ``target``, as the run's file was before the merge (its robot's meshes,
    drawn at its poses, included): to look at one run of a large sweep.
    ConfigError if ``recording`` has no such run."""
    from workbench.errors import ConfigError

    sink = RerunSink()
    if not sink.add_recording(recording, only_run=run):
        raise ConfigError(
            f"{recording} has no run {run}: give a run id of this sweep that logged "
            "a recording (`workbench results` lists them)"
        )
    return sink.save(target)


def _instance_poses(batch: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times s, translations (rows, instances, 3), mat3x3 (rows, instances, 9), each matrix
    by columns as Rerun keeps it) of a chunk of InstancePoses3D rows that all have the same
    number of instances."""
    import pyarrow as pa

    times = batch.column(TIMELINE).cast(pa.int64()).to_numpy() / 1e9
    columns = []
    for name, width in (("InstancePoses3D:translations", 3), ("InstancePoses3D:mat3x3", 9)):
        column = batch.column(name)
        values = np.asarray(column.flatten().flatten(), dtype=np.float32)
        columns.append(values.reshape(len(times), -1, width))
    return times, columns[0], columns[1]


def _rotation_matrices(scalar_first: np.ndarray) -> np.ndarray:
    """(n, 4) Euler parameters -> (n, 3, 3) rotation matrices."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quaternion_xyzw(scalar_first)).as_matrix()


def _parsed_entity(path: str, heads: dict[str, tuple[list[str], str]]) -> tuple[list[str], str]:
    """(parts, run): ``path``'s parts (:func:`split_entity_path`) and the entity path of its
    first five (a run's, when it has six), the parse of all but its last part kept in
    ``heads``: a run's six chunks share it (a 2,000-run merge of tiny runs 4.4-5.0 -> 4.1-4.3
    s of CPU, docs/performance.md)."""
    head, _, last = path.rpartition("/")
    if "\\" in last or head.endswith("\\"):  # an escaped "/" or "\\" near the cut: whole
        parts = split_entity_path(path)
        return parts, entity_path(*parts[:5])
    known = heads.get(head)
    if known is None:
        head_parts = split_entity_path(head)
        known = heads[head] = (head_parts, entity_path(*head_parts[:5]))
    return known[0] + split_entity_path(last), known[1]


def split_entity_path(path: str) -> list[str]:
    """An entity path's parts, unescaped (the inverse of :func:`entity_path`); the
    regular expressions only where a part has an escape (the merge parses every chunk's
    path: they were a fifth of its CPU)."""
    path = path.strip("/")
    parts = re.split(r"(?<!\\)/", path) if "\\/" in path else path.split("/")
    return [re.sub(r"\\(.)", r"\1", part) if "\\" in part else part for part in parts if part]


def merge_recordings(
    files: Iterable[str | Path], target: str | Path, keep_existing: bool = False
) -> Path:
    """Merge saved recordings (one per run or per worker) into one file with a blueprint;
    ``target``: a ``.rrd`` file or a directory (then its ``recording.rrd``).
    ``keep_existing``: an existing ``target`` is merged in too, its runs that ``files``
    hold again left out (they were redone): a sweep merges only its new runs' files.

    Each model's meshes are stored once, drawn at every run's body poses by instance
    poses (:meth:`RerunSink.send_instances`, written at the end: the one part of the merge
    held in memory, about 48 bytes a pose of a meshed body).
    The memory it takes does not otherwise grow with the number of files: the files'
    chunks are streamed through Rerun's file sink into a temporary file beside ``target``,
    flushed after each :data:`FLUSH_BYTES` of inputs; the temporary file is synced and renamed over
    ``target`` at the end, so that the inputs can then be removed.
    The file has a footer (a manifest of its chunks, which ``rerun rrd verify`` and random
    access need) when its inputs are at most :data:`FOOTER_INPUT_LIMIT` bytes: Rerun's
    file sink keeps that manifest in memory until the end, about 3x the inputs' size
    (12-16 KiB a chunk; rerun-sdk 0.41, docs/performance.md), and a larger file goes without
    (the viewer and Python's streaming reader read it whole; ``rerun rrd migrate`` adds
    one to a copy).
    Rerun's file sink blocks forever on a full disk (rerun-sdk 0.41, see
    :meth:`RerunSink.save`), so the free space is checked first (:func:`check_free_space`).
    """
    files = [Path(file) for file in files]
    target = Path(target)
    if target.is_dir() or target.suffix != ".rrd":
        target = target / RECORDING_FILE
    target.parent.mkdir(parents=True, exist_ok=True)
    inputs = files + ([target] if keep_existing and target.is_file() else [])
    input_bytes = sum(file.stat().st_size for file in inputs)
    check_free_space(target, input_bytes)
    sink = RerunSink()

    def write(temporary: str) -> None:
        with _stderr_silenced():  # rerun's warning that a file without footer exists
            sink.recording.save(temporary, write_footer=input_bytes <= FOOTER_INPUT_LIMIT)
        sink.begin_index()
        pending = 0  # bytes read since the last flush
        for file in inputs:  # the newest first: a run is taken from the first file with it
            sink.add_recording(file)
            pending += file.stat().st_size
            if pending >= FLUSH_BYTES:  # these files' chunks leave memory now
                _flush(sink.recording, target)
                pending = 0
        sink.send_instances()
        sink.log_index()
        sink.recording.send_blueprint(sink.blueprint(), make_active=False, make_default=True)
        _flush(sink.recording, target)
        sink.recording.disconnect()  # the file is whole

    atomic_write(target, write, durable=True)
    _sync_directory(target.parent)  # the rename too: the inputs may be removed after it
    return target


def _sync_directory(directory: Path) -> None:
    descriptor = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


FOOTER_INPUT_LIMIT = 96 * 2**20
"""Inputs (bytes) up to which a merged recording gets a footer: its manifest then takes
at most about 270 MiB while the merge runs (2.8x: a run's file holds its series in one
chunk since 2026-11-26, 35 % fewer bytes for about the same manifest)."""
FLUSH_BYTES = 16 * 2**20
"""The merge flushes its file sink after this many bytes of inputs (a flush a file took
2.7 ms: 27 s for 10,000 runs)."""
FLUSH_TIMEOUT = 600.0
"""Seconds a flush of the merge's file sink may take before the merge is given up."""
FREE_SPACE_MARGIN = 1.25
"""Free space a merge needs, as a multiple of its inputs' size (a merged file measured
0.9x the sum of its inputs: one header a file less; the blueprint and footer more)."""


def check_free_space(target: Path, input_bytes: int) -> None:
    """OSError (ENOSPC, naming ``target``) if the disk of ``target`` has less free space
    than :data:`FREE_SPACE_MARGIN` times ``input_bytes`` plus 1 MiB."""
    import errno
    import shutil

    needed = int(FREE_SPACE_MARGIN * input_bytes) + 2**20
    free = shutil.disk_usage(target.parent).free
    if free < needed:
        raise OSError(
            errno.ENOSPC,
            f"{os.strerror(errno.ENOSPC)}: {free / 2**20:.1f} MiB free, "
            f"{needed / 2**20:.1f} MiB needed to merge the recordings; free some space, "
            "then resume the sweep",
            str(target),
        )


@contextlib.contextmanager
def _stderr_silenced() -> Iterator[None]:
    """The process's standard error (file descriptor 2) sent to /dev/null meanwhile: for a
    call of Rust code whose log lines cannot be turned off from Python."""
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def _flush(recording: Any, target: Path) -> None:
    try:
        recording.flush(timeout_sec=FLUSH_TIMEOUT)
    except Exception as error:  # noqa: BLE001 - rerun raises its own kinds
        import errno

        raise OSError(
            errno.EIO, f"Rerun's file sink did not write the recording ({error})", str(target)
        ) from error


def view_coordinates(model: Any) -> Any:
    """Rerun's up axis for a model's 3D view: against gravity, so the mechanism hangs as
    it should; y for a planar model without gravity (the view then faces its plane)."""
    import rerun as rr

    gravity = np.asarray(getattr(model, "gravity", np.zeros(3)), dtype=float).reshape(-1)
    if not np.any(gravity):
        planar = getattr(model, "kind", "spatial") == "planar"
        return getattr(rr.ViewCoordinates, "RIGHT_HAND_Y_UP" if planar else "RIGHT_HAND_Z_UP")
    axis = int(np.argmax(np.abs(gravity)))
    up = "UP" if gravity[axis] < 0 else "DOWN"
    return getattr(rr.ViewCoordinates, f"RIGHT_HAND_{'XYZ'[axis]}_{up}")


def _model_scale(model: Any) -> float:
    """A length typical of the model (largest shape extent or joint offset), for axes."""
    sizes = [
        max(shape.size) for body in model.bodies.values() for shape in body.shapes
        if shape.kind != "mesh"
    ]  # fmt: skip
    offsets = [
        float(np.linalg.norm(frame.position))
        for joint in model.joints.values()
        for frame in (joint.parent_frame, joint.child_frame)
    ]
    scale = max(sizes + offsets, default=0.0)
    return scale if scale > 0 else 1.0


def _contact_planes(model: Any) -> list[tuple[str, list[Any]]]:
    """(entity below the model's shared path, archetypes) of each plane the model's
    contacts touch (one a plane, named by its first contact): a thin box whose top face is
    the plane, 20 model lengths (at least 2 m) each way, so impacts and penetration show."""
    import rerun as rr

    from workbench.equations.contacts import plane_tangents

    planes: dict[tuple[float, ...], str] = {}
    for contact in getattr(model, "contacts", None) or []:
        if not hasattr(contact, "plane_normal"):  # a sphere pair: drawn on its bodies
            continue
        normal = np.asarray(contact.plane_normal, dtype=float)
        normal = normal / np.linalg.norm(normal)
        point = np.asarray(contact.plane_point, dtype=float)
        planes.setdefault((*np.round(point, 12), *np.round(normal, 12)), contact.name)
    scale = _model_scale(model)
    half, thickness = max(2.0, 20 * scale), 0.05 * scale
    entries = []
    for plane, name in planes.items():
        point, normal = np.array(plane[:3]), np.array(plane[3:])
        rotation = np.column_stack([*plane_tangents(normal, planar=False), normal])
        box = rr.Boxes3D(
            half_sizes=[[half, half, thickness / 2]],
            centers=[point - normal * thickness / 2],
            quaternions=[rr.Quaternion(xyzw=matrix_xyzw(rotation))],
            colors=[(150, 150, 150, 120)],
            fill_mode=rr.components.FillMode.Solid,
        )
        entries.append((entity_path("contact_planes", name), [box]))
    return entries


def _contact_spheres(
    model: Any,
) -> tuple[list[tuple[str, np.ndarray, float]], list[tuple[str, list[Any]]]]:
    """Both spheres of each sphere-sphere contact: (body, centre, radius) of those on a
    body, and (entity below the model's shared path, component batches) of those on the
    ground (once per model, as its joint frames)."""
    on_bodies, on_ground = [], []
    for contact in getattr(model, "contacts", None) or []:
        if hasattr(contact, "body_a"):
            for body, centre, radius in (
                (contact.body_a, contact.centre_a, contact.radius_a),
                (contact.body_b, contact.centre_b, contact.radius_b),
            ):
                if body != "ground":
                    on_bodies.append((body, np.asarray(centre, dtype=float), float(radius)))
                    continue
                sphere = _contact_ellipsoids([(body, np.asarray(centre, dtype=float), radius)],
                                             centred=False)  # fmt: skip
                on_ground.append((f"ground/{entity_path('contacts', contact.name)}",
                                  _batches([sphere])))  # fmt: skip
    return on_bodies, on_ground


CONTACT_COLOR = (230, 120, 40, 90)


def _contact_ellipsoids(
    spheres: Sequence[tuple[str, np.ndarray, float]], centred: bool = True
) -> Any:
    """Contact spheres (body, centre, radius) as one Ellipsoids3D: at their instance
    poses (``centred``), or at their centres."""
    import rerun as rr

    placed = {} if centred else {"centers": [centre for _, centre, _ in spheres]}
    return rr.Ellipsoids3D(half_sizes=[[radius] * 3 for *_, radius in spheres],
                           colors=[CONTACT_COLOR], **placed)  # fmt: skip


def _transform_axes(length: float) -> Any:
    import rerun as rr

    return rr.TransformAxes3D(length)


def static_chunk(path: str, batches: Sequence[Any]) -> Any:
    """A static chunk at ``path`` of one row holding ``batches`` (component batches), as a
    ``log(path, batches, static=True)`` call makes it."""
    import rerun as rr
    from rerun.chunk import Chunk

    columns = [
        rr.ComponentColumn(batch.component_descriptor(), batch).partition(
            [len(batch.as_arrow_array())]
        )
        for batch in batches
    ]
    return Chunk.from_columns(path, [], columns)


def _batches(archetypes: Iterable[Any]) -> list[Any]:
    """The component batches of archetypes (``log`` of an archetype makes them again at
    every call: a third of its cost), to be logged as one chunk."""
    return [batch for archetype in archetypes for batch in archetype.as_component_batches()]


def _placed(
    places: Sequence[tuple[str, Any, Any]], archetypes: Sequence[Any], turns: bool = True
) -> Placed:
    """A :class:`Placed` of ``places`` (body, position (3,), rotation (3, 3)) drawing
    ``archetypes``; ``turns``: False for spheres (their poses leave rotations out)."""
    from scipy.spatial.transform import Rotation

    rotations = np.array([np.asarray(rotation, dtype=float) for _, _, rotation in places])
    return Placed(
        batches=_batches(archetypes),
        bodies=tuple(body for body, _, _ in places),
        positions=np.array([np.asarray(position, dtype=float) for _, position, _ in places]),
        quaternions=Rotation.from_matrix(rotations).as_quat().reshape(-1, 4),
        turns=turns,
    )


@dataclass(frozen=True)
class _ArrowBatch:
    """Values already in Arrow, as :class:`rerun.ComponentColumn` takes a component batch."""

    array: Any

    def as_arrow_array(self) -> Any:
        return self.array


@functools.cache
def _column_types() -> dict[str, tuple[Any, Any]]:
    """Field -> (Rerun's component descriptor, Arrow type of one value) of the columns a
    run sends on ``sim_time``: instance translations, quaternions and 3 x 3 matrices (a
    shared mesh's), and scalars, as Rerun's own ``columns()`` makes them (asked once)."""
    import rerun as rr

    poses = rr.InstancePoses3D.columns(
        translations=np.zeros((1, 3), np.float32), quaternions=np.zeros((1, 4), np.float32),
        mat3x3=np.zeros((1, 9), np.float32),
    )  # fmt: skip
    columns = [*poses, *rr.Scalars.columns(scalars=np.zeros((1, 1))),
               *rr.SeriesLines.columns(names=["name"])]  # fmt: skip
    return {
        column.component_descriptor().component.split(":")[-1]: (
            column.component_descriptor(),
            column.as_arrow_array().type.value_type,
        )
        for column in columns
    }


def _column(field: str, values: np.ndarray) -> Any:
    """The column of ``values`` (n, k, d) or (n, k): a row a sample time holding k values
    of ``field`` (a key of :func:`_column_types`), built in Arrow directly: Rerun's
    ``InstancePoses3D.columns(...).partition(...)`` checked and copied them again (0.07
    ms a column, a fifth of a tiny run's recording in Python)."""
    import pyarrow as pa
    import rerun as rr

    descriptor, value_type = _column_types()[field]
    n, k = values.shape[:2]
    vector = pa.types.is_fixed_size_list(value_type)  # (x, y, z): a list of 3 numbers
    number = value_type.value_type if vector else value_type
    flat = pa.array(np.ascontiguousarray(values, dtype=number.to_pandas_dtype()).reshape(-1))
    if vector:
        flat = pa.FixedSizeListArray.from_arrays(flat, type=value_type)
    offsets = np.arange(0, n * k + 1, k, dtype=np.int32)
    return rr.ComponentColumn(descriptor, _ArrowBatch(flat), offsets=offsets)


def _names_column(label: str, count: int) -> Any:
    """A column of one row: ``count`` times ``label``, the series lines' names, built in
    Arrow directly (Rerun's ``SeriesLines.columns(...).partition(...)``: about 0.1 ms a run)."""
    import pyarrow as pa
    import rerun as rr

    descriptor, value_type = _column_types()["names"]
    names = _ArrowBatch(pa.array([label] * count, type=value_type))
    return rr.ComponentColumn(descriptor, names, offsets=np.array([0, count], np.int32))


def _child_frames(model: Any) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(body, position, rotation) of each joint's frame on its child body (its frame on
    the parent coincides with it while the joint holds; on the ground it is drawn once per
    model), frames that coincide on a body once."""
    frames: dict[tuple[Any, ...], tuple[str, np.ndarray, np.ndarray]] = {}
    for joint in model.joints.values():
        if joint.child == "ground":
            continue
        frame = joint.child_frame
        key = (joint.child, *np.round(np.concatenate([frame.position, frame.rotation.ravel()]), 12))
        frames.setdefault(key, (joint.child, frame.position, frame.rotation))
    return list(frames.values())


def _compose(
    body_poses: np.ndarray, positions: np.ndarray, quaternions: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(n, k, 3) translations and (n, k, 4) x, y, z, w quaternions (float32) of k things
    at ``positions`` (k, 3) / ``quaternions`` (k, 4) in their bodies, whose poses are
    ``body_poses`` (n, k, 7: x, y, z and a quaternion x, y, z, w)."""
    t, q = body_poses[..., :3], body_poses[..., 3:]
    ax, ay, az, aw = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    px, py, pz = positions[:, 0], positions[:, 1], positions[:, 2]
    # the body's rotation applied to each position: p + 2 w (v x p) + 2 v x (v x p)
    cx, cy, cz = 2 * (ay * pz - az * py), 2 * (az * px - ax * pz), 2 * (ax * py - ay * px)
    translations = np.stack([
        t[..., 0] + px + aw * cx + ay * cz - az * cy,
        t[..., 1] + py + aw * cy + az * cx - ax * cz,
        t[..., 2] + pz + aw * cz + ax * cy - ay * cx,
    ], axis=-1)  # fmt: skip
    bx, by, bz, bw = quaternions[:, 0], quaternions[:, 1], quaternions[:, 2], quaternions[:, 3]
    product = np.stack([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ], axis=-1)  # fmt: skip
    return translations.astype(np.float32), product.astype(np.float32)


def _joint_axes(frames: Sequence[Any], length: float) -> list[Any]:
    """The joint frames on the ground as one entity (static: the same in every run): a
    TransformAxes3D drawn at each pose of an InstancePoses3D (Rerun draws axes instanced
    since rerun-io/rerun#11970), one batch rather than an entity a frame: each chunk and
    component column costs the reader more than its bytes (docs/performance.md).
    Frames that coincide are drawn once; translations are left out when every frame is
    at the origin, rotations when none is rotated."""
    import rerun as rr

    unique: dict[tuple[float, ...], Any] = {}
    for frame in frames:
        key = tuple(np.round(np.concatenate([frame.position, frame.rotation.ravel()]), 12))
        unique.setdefault(key, frame)
    placed = list(unique.values())
    poses: dict[str, Any] = {}
    if any(np.any(frame.position) for frame in placed):
        poses["translations"] = [frame.position for frame in placed]
    if any(np.any(frame.rotation != np.eye(3)) for frame in placed):
        poses["mat3x3"] = [frame.rotation for frame in placed]
    axes = [rr.TransformAxes3D(length)]
    return axes + [rr.InstancePoses3D(**poses)] if poses else axes


PLACEHOLDER_HALF_SIZE = 0.05
"""Half the edge (m) of the box drawn where a mesh file cannot be read."""


def _mesh_archetypes(shape: Any) -> tuple[list[Any], str]:
    """(archetypes, warning) of a mesh file at its frame, scaled: Rerun reads glTF, GLB,
    OBJ and STL itself (Asset3D); other formats (COLLADA .dae of many URDFs) go through
    trimesh (Mesh3D). The file is read once, as a regular file (the importer checked where
    it is), and parsed by trimesh; a file that cannot be read or holds no triangles gives
    no archetype and a one-line warning (a red box is drawn there: :func:`_placeholder`),
    never a failed run (the dynamics do not depend on it)."""
    import rerun as rr
    import trimesh

    from workbench.errors import one_line
    from workbench.model.importers.file_roots import read_regular_file

    place = rr.Transform3D(
        translation=shape.frame.position, mat3x3=shape.frame.rotation @ np.diag(shape.size)
    )
    suffix = Path(shape.path).suffix.lower()
    try:
        data = read_regular_file(shape.path)
        mesh = trimesh.load(io.BytesIO(data), file_type=suffix.lstrip("."), force="mesh")
        if len(getattr(mesh, "faces", ())) == 0:
            raise ValueError("no triangles in it")
    except Exception as error:  # noqa: BLE001 - any reader's failure: a placeholder
        return [], f"mesh {shape.path} cannot be read ({one_line(error)}): drawn as a box"
    if suffix in (".glb", ".gltf", ".obj", ".stl"):
        media_type = rr.components.MediaType.guess_from_path(shape.path)
        return [place, rr.Asset3D(contents=data, media_type=media_type)], ""
    return [
        place,
        rr.Mesh3D(
            vertex_positions=np.asarray(mesh.vertices, dtype=np.float32),
            triangle_indices=np.asarray(mesh.faces, dtype=np.uint32),
            vertex_normals=np.asarray(mesh.vertex_normals, dtype=np.float32),
            albedo_factor=tuple(shape.color),
        ),
    ], ""


def _placed_shapes(
    shapes: Sequence[tuple[str, Any]], model_colors: dict[str, list[int]] | None = None
) -> dict[str, Placed]:
    """Entity name (:data:`SHAPE_ENTITIES`) -> :class:`Placed` of all the (body, shape)
    primitive shapes of one kind: one archetype a kind, labelled with each shape's body,
    its sizes; its place in the body goes into the instance poses. ``model_colors``:
    archetype -> the colour its 3D view draws by default (the model's own, when all its
    shapes of that kind have it), which the shapes then leave out, as the views' default
    one (:func:`shape_defaults`)."""
    import rerun as rr

    by_kind: dict[str, list[tuple[str, Any]]] = {}
    for body, shape in shapes:
        by_kind.setdefault(shape.kind, []).append((body, shape))
    placed: dict[str, Placed] = {}
    for kind, group in by_kind.items():
        colors = [tuple(shape.color) for _, shape in group]
        view_color = (model_colors or {}).get(SHAPE_ARCHETYPES[kind])
        view_color = tuple(view_color) if view_color else tuple(default_shape_color())
        fields: dict[str, Any] = {"labels": [body for body, _ in group]}
        if any(color != view_color for color in colors):
            fields["colors"] = colors
        sizes = [np.asarray(shape.size, dtype=float) for _, shape in group]
        places = [(body, shape.frame.position, shape.frame.rotation) for body, shape in group]
        if kind == "box":
            archetype = rr.Boxes3D(half_sizes=[size / 2 for size in sizes], **fields)
        elif kind == "sphere":
            archetype = rr.Ellipsoids3D(half_sizes=[[size[0]] * 3 for size in sizes], **fields)
        elif kind == "cylinder":
            archetype = rr.Cylinders3D(
                radii=[size[0] for size in sizes], lengths=[size[1] for size in sizes], **fields
            )
        else:  # Rerun's capsule runs from its origin along +z; ours is centred on its frame
            archetype = rr.Capsules3D(
                radii=[size[0] for size in sizes], lengths=[size[1] for size in sizes], **fields
            )
            places = [
                (body, position - rotation @ np.array([0.0, 0.0, size[1] / 2]), rotation)
                for (body, position, rotation), size in zip(places, sizes, strict=True)
            ]
        placed[SHAPE_ENTITIES[kind]] = _placed(places, [archetype], turns=kind != "sphere")
    return placed


def _placeholder(shape: Any) -> Any:
    """A red box of :data:`PLACEHOLDER_HALF_SIZE` at the frame of a mesh that cannot be
    read, as a primitive shape of its body."""
    from types import SimpleNamespace

    return SimpleNamespace(kind="box", size=(2 * PLACEHOLDER_HALF_SIZE,) * 3,
                           frame=shape.frame, color=(220, 60, 60))  # fmt: skip


def default_shape_color() -> tuple[int, int, int]:
    """The colour of a :class:`workbench.model.Shape` given none."""
    import dataclasses

    from workbench.model import Shape

    return next(f.default for f in dataclasses.fields(Shape) if f.name == "color")


def shape_defaults(colors: dict[str, list[int]] | None = None) -> list[Any]:
    """The 3D views' defaults of the primitive shapes: solid (Rerun draws them as
    wireframes otherwise) and a colour, ``colors`` (archetype -> the model's colour of
    that kind, :data:`SHAPE_COLORS`) or a shape's default colour; their labels (each
    shape's body) asked hidden, for hover and selection (Rerun 0.41's web viewer showed
    them over a two-body run's bodies all the same, 2026-11-27). View defaults rather
    than components of every run's shapes (each costs the reader about 5 KiB a run)."""
    import rerun as rr

    solid, colors = rr.components.FillMode.Solid, colors or {}
    return [
        archetype.from_fields(
            fill_mode=solid,
            colors=[tuple(colors.get(archetype.__name__, default_shape_color()))],
            show_labels=False,
        )
        for archetype in (rr.Boxes3D, rr.Ellipsoids3D, rr.Cylinders3D, rr.Capsules3D)
    ]


class SweepRecorder(RerunSink):
    """What a sweep's workers record with (``run_sweep(..., recorder=SweepRecorder)``): at
    most 200 poses a run, a ``.rrd`` file a batch of a worker's runs in ``<out>/recordings``,
    merged at the end into ``<out>/recording.rrd``."""

    suffix = "rrd"
    merged_file = RECORDING_FILE  # merged again only when the runs' files change

    def __init__(self) -> None:
        super().__init__(max_frames=200)

    @staticmethod
    def prepare() -> None:
        """Import rerun-sdk when a worker starts, not within a run's time limit."""
        import rerun  # noqa: F401

    @staticmethod
    def merge(files: Iterable[str | Path], out: str | Path) -> Path:
        """Merge the runs' files into ``<out>/recording.rrd``, keeping the runs it has."""
        return merge_recordings(files, Path(out) / RECORDING_FILE, keep_existing=True)
