"""Stored references: body poses from two independent pipelines that must agree.

A problem without an analytic solution is given a *stored* reference: its body poses
(position + unit quaternion scalar-first, the quantities :mod:`workbench.metrics` compares)
at fixed sample times, computed twice at tight tolerance by pipelines that share neither
the formalism nor the integrator (:func:`pipelines`):

- A: joint coordinates (``minimal-ode`` at index 1: the plain ODE of a tree, Baumgarte for
  loops) or, with nonholonomic constraints, minimal velocities
  (``nonholonomic-projection``), integrated by the explicit ``scipy-dop853``;
- B: absolute body coordinates with Euler parameters and every joint as a constraint
  (``absolute-dae`` at index 1: Baumgarte-stabilized, offered as an ODE), integrated by
  the implicit Radau IIA of ``scipy-radau``. (SUNDIALS IDA on the index-2 DAE was tried:
  its BDF at rtol 1e-11 left 2.5e-5 m on the articulated arm, far above the threshold.)

The pose error between them (``|dr| + L |dtheta|``, :func:`workbench.metrics.pose_error`)
relative to the model's length scale L must stay below a threshold (``1e-7`` by default),
else :class:`ReferenceDisagreement` names the largest disagreement, when and for which
body. Pipeline A's poses are kept: DOP853's error is the smaller at the same tolerance.

Files (:func:`write_reference`), beside the module that defines the problem, in
``references/``: ``<problem>.npz`` (``times`` (n,), ``poses`` (n, n_bodies, 7), ``bodies``)
and ``<problem>.json`` (command, both pipelines with their cost, tolerances, sample
times, agreement, the problem's fingerprint, library versions). :func:`stored_reference`
serves them as the problem's :class:`~workbench.plugin.problem.Reference` when the problem's
options and fingerprint (:func:`problem_fingerprint`: model parameters and initial
condition) still match, so an edited problem falls back to a computed reference instead
of being compared against a stale one.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import inspect
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from workbench.errors import ConfigError, IntegrationError, WorkbenchError

REFERENCE_RTOL = 1e-11
ATOL_FACTOR = 0.1  # atol = rtol * ATOL_FACTOR
AGREEMENT_THRESHOLD = 1e-7  # largest pose disagreement / L
DIRECTORY = "references"


class ReferenceDisagreement(IntegrationError):
    """The two pipelines of a stored reference do not agree within the threshold."""


class ReferenceTimesMismatch(WorkbenchError):
    """Poses were asked for at times the stored reference does not hold."""


@dataclass(frozen=True)
class Pipeline:
    """A formalism (+ options) and an integrator: one way of computing the motion."""

    formalism: str
    formalism_options: dict[str, Any]
    integrator: str

    def label(self) -> str:
        options = ",".join(f"{k}={v}" for k, v in sorted(self.formalism_options.items()))
        return f"{self.formalism}{f'({options})' if options else ''} + {self.integrator}"


PIPELINE_JOINT = Pipeline("minimal-ode", {"index": 1}, "scipy-dop853")
PIPELINE_PROJECTION = Pipeline("nonholonomic-projection", {}, "scipy-dop853")
PIPELINE_ABSOLUTE = Pipeline("absolute-dae", {"index": 2}, "sundials-ida")
PIPELINE_ABSOLUTE_ODE = Pipeline("absolute-dae", {"index": 1}, "scipy-radau")


@dataclass
class StoredReference:
    """Reference poses of one problem and how they were obtained (the JSON metadata)."""

    problem: str
    times: np.ndarray
    poses: np.ndarray  # (n_times, n_bodies, 7)
    bodies: list[str]
    metadata: dict[str, Any] = field(default_factory=dict)


# ---- the problem's identity ----------------------------------------------------------


def _canonical(value: Any) -> Any:
    """A JSON-able, rounding-stable description of model data (for the fingerprint)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: _canonical(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if f.name not in ("shapes", "color")  # visual only
        }
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, list | tuple):
        return [_canonical(v) for v in value]
    if isinstance(value, np.ndarray | np.generic | float | int) and not isinstance(value, bool):
        array = np.asarray(value, dtype=float)
        return [float(f"{x:.12g}") for x in array.ravel()] if array.ndim else float(f"{array:.12g}")
    if callable(value):
        # functions by name and their numeric defaults and closure values (not bytecode,
        # which changes between Python versions)
        closure = [c.cell_contents for c in getattr(value, "__closure__", None) or ()]
        numbers = [
            _canonical(v)
            for v in [*(getattr(value, "__defaults__", None) or ()), *closure]
            if isinstance(v, float | int | np.ndarray | tuple)
        ]
        # the qualified name, not the module: where a package is installed is not physics
        name = getattr(value, "__qualname__", "")
        return [name, numbers]
    return value if value is None or isinstance(value, str | bool) else repr(value)


def problem_fingerprint(problem: Any) -> str:
    """16 hex digits identifying the problem's model parameters and initial condition."""
    description = {
        "model": _canonical(problem.model()),
        "q0": _canonical(problem.initial_joint_coordinates()),
        "v0": _canonical(problem.initial_joint_velocities()),
        "t_start": float(problem.t_start),
        "independent": _canonical(problem.independent_coordinates),
    }
    text = json.dumps(description, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# ---- computing -----------------------------------------------------------------------


def pipelines(model: Any) -> tuple[Pipeline, Pipeline]:
    """The two independent pipelines for ``model`` (see the module docstring)."""
    first = PIPELINE_PROJECTION if model.nonholonomic else PIPELINE_JOINT
    return first, PIPELINE_ABSOLUTE_ODE


def solve_poses(
    problem: Any, pipeline: Pipeline, times: np.ndarray, rtol: float, atol: float
) -> tuple[np.ndarray, list[str], dict[str, Any]]:
    """Body poses (n_times, n_bodies, 7) of ``problem`` along ``pipeline``, body names, cost."""
    from workbench.equations.initial import consistent_initial_state
    from workbench.plugin import registry

    model = problem.model()
    formalism_class = registry.get_formalism(pipeline.formalism)
    formalism_class.check(model)
    integrator = registry.get_integrator(pipeline.integrator)()
    started = time.perf_counter()
    equations = formalism_class().build(model, pipeline.formalism_options)
    offered = {name: getattr(form, "index", 0) for name, form in equations.forms.items()}
    form = integrator.select_form(offered)
    if form is None:
        raise ConfigError(f"{pipeline.label()}: the integrator accepts none of the forms {offered}")
    state = consistent_initial_state(equations, problem)
    built = time.perf_counter()
    trajectory = integrator.solve(
        equations, state.y0(equations, form), state.yp0(equations, form), times, rtol, atol,
        None, form,
    )  # fmt: skip
    if not trajectory.success:
        raise IntegrationError(
            f"{problem.name}: {pipeline.label()} failed at rtol {rtol:g}: {trajectory.message}"
        )
    nq = equations.nq
    rows = zip(times, trajectory.y, strict=True)
    poses = np.stack([equations.observables.poses(t, row[:nq]) for t, row in rows])
    cost = {
        "build_s": round(built - started, 3),
        "integrate_s": round(trajectory.stats.integrate_s, 3),
        "n_steps": int(trajectory.stats.n_steps),
        "n_rhs": int(trajectory.stats.n_rhs),
    }
    return poses, list(equations.observables.body_names), cost


def agreement(
    poses_a: np.ndarray, poses_b: np.ndarray, times: np.ndarray, bodies: list[str], length: float
) -> dict[str, Any]:
    """The largest pose disagreement (m and relative to ``length``), when and for which body."""
    from workbench.metrics import rotation_angle

    per_body = np.linalg.norm(poses_a[..., :3] - poses_b[..., :3], axis=-1) + length * (
        rotation_angle(poses_a[..., 3:], poses_b[..., 3:])
    )
    i, j = np.unravel_index(int(np.argmax(per_body)), per_body.shape)
    worst = float(per_body[i, j])
    return {
        "max_pose_error_m": worst,
        "relative": worst / length,
        "at_time_s": float(times[i]),
        "body": bodies[j],
        "length_scale_m": length,
    }


def compute_reference(
    name: str,
    rtol: float = REFERENCE_RTOL,
    samples: int | None = None,
    threshold: float = AGREEMENT_THRESHOLD,
    chosen: tuple[Pipeline, Pipeline] | None = None,
    progress: Callable[[str], None] | None = None,
) -> StoredReference:
    """Poses of problem ``name`` (default options) by two pipelines that must agree.

    samples: number of equally spaced times over the time span (default: the problem's
    ``n_samples``, so the reference serves the runner's output times). Raises
    :class:`ReferenceDisagreement` if the pipelines differ by more than ``threshold`` L.
    """
    from workbench.metrics import environment, length_scale
    from workbench.plugin import registry
    from workbench.plugin.options import options_dict

    if not (0 < rtol < 1):
        raise ConfigError(f"--rtol must be in (0, 1), not {rtol:g}")
    if samples is not None and samples < 2:
        raise ConfigError(f"--samples must be at least 2, not {samples}")
    problem = registry.get_problem(name)()
    model = problem.model()
    n = samples or problem.n_samples
    times = np.linspace(problem.t_start, problem.t_end, n)
    atol = rtol * ATOL_FACTOR
    chosen = chosen or pipelines(model)
    results = []
    for pipeline in chosen:
        if progress:
            progress(f"{name}: {pipeline.label()}")
        results.append(solve_poses(problem, pipeline, times, rtol, atol))
    (poses_a, bodies, cost_a), (poses_b, bodies_b, cost_b) = results
    if bodies != bodies_b:
        raise ConfigError(f"{name}: the pipelines name different bodies ({bodies} vs {bodies_b})")
    length = length_scale(model, poses_a)
    agreed = agreement(poses_a, poses_b, times, bodies, length) | {"threshold": threshold}
    if not agreed["relative"] <= threshold:
        raise ReferenceDisagreement(
            f"{name}: {chosen[0].label()} and {chosen[1].label()} disagree by "
            f"{agreed['max_pose_error_m']:.3g} m ({agreed['relative']:.3g} of L = {length:.3g} m) "
            f"at t = {agreed['at_time_s']:g} s on body {agreed['body']!r}, above the threshold "
            f"{threshold:g}; try a tighter --rtol or fewer samples of a shorter span"
        )
    versions = {k.removeprefix("version_"): v for k, v in environment().items() if "version" in k}
    command = f"workbench reference {name} --rtol {rtol:g}" + (
        f" --samples {samples}" if samples else ""
    )
    metadata = {
        "problem": name,
        "source": problem.source,
        "options": options_dict(problem.options),
        "fingerprint": problem_fingerprint(problem),
        "command": command,
        "rtol": rtol,
        "atol": atol,
        "times": {"start": float(times[0]), "end": float(times[-1]), "n": int(n)},
        "bodies": bodies,
        "pipelines": [
            {**dataclasses.asdict(p), "label": p.label(), **cost}
            for p, cost in zip(chosen, (cost_a, cost_b), strict=True)
        ],
        "stored_pipeline": 0,
        "agreement": agreed,
        "versions": versions,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }
    return StoredReference(name, times, poses_a, bodies, metadata)


# ---- files ---------------------------------------------------------------------------


def default_directory(name: str) -> Path:
    """``references/`` beside the module that defines problem ``name``."""
    from workbench.plugin import registry

    return Path(inspect.getfile(registry.get_problem(name))).parent / DIRECTORY


def write_reference(reference: StoredReference, directory: Path | str | None = None) -> Path:
    """Write ``<problem>.npz`` and ``<problem>.json`` (atomically); return the .npz path."""
    import io

    from workbench.store import _atomic_write, write_json_atomic

    directory = Path(directory) if directory is not None else default_directory(reference.problem)
    path = directory / f"{reference.problem}.npz"
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer, times=reference.times, poses=reference.poses, bodies=np.array(reference.bodies)
    )
    _atomic_write(path, lambda temp: Path(temp).write_bytes(buffer.getvalue()))
    write_json_atomic(reference.metadata, path.with_suffix(".json"))
    for written in (path, path.with_suffix(".json")):
        written.chmod(0o644)  # package data, readable by all (mkstemp made it 0600)
    return path


def read_reference(path: Path | str) -> StoredReference:
    """A stored reference from its ``.npz`` (the ``.json`` beside it holds the metadata)."""
    path = Path(path)
    with np.load(path, allow_pickle=False) as data:
        times, poses, bodies = data["times"], data["poses"], [str(b) for b in data["bodies"]]
    metadata = json.loads(path.with_suffix(".json").read_text())
    return StoredReference(metadata.get("problem", path.stem), times, poses, bodies, metadata)


_LOADED: dict[tuple[str, float], StoredReference | None] = {}


def stored_reference(problem: Any) -> Any:
    """The problem's stored :class:`~workbench.plugin.problem.Reference`, or None when there is no
    file, or it was made for other options or an earlier version of the problem."""
    from workbench.plugin.options import options_dict
    from workbench.plugin.problem import Reference

    try:
        path = Path(inspect.getfile(type(problem))).parent / DIRECTORY / f"{problem.name}.npz"
        key = (str(path), path.stat().st_mtime)
    except (OSError, TypeError):
        return None
    if key not in _LOADED:
        _LOADED[key] = read_reference(path)
    stored = _LOADED[key]
    metadata = stored.metadata
    if metadata.get("options") != options_dict(problem.options):
        return None
    if metadata.get("fingerprint") != problem_fingerprint(problem):
        return None
    agreed = metadata.get("agreement", {})
    labels = " vs ".join(p.get("label", "?") for p in metadata.get("pipelines", []))
    description = (
        f"stored {path.name}: {labels}, rtol {metadata.get('rtol', math.nan):g}, "
        f"agreement {agreed.get('relative', math.nan):.2g} L"
    )
    return Reference("stored", lambda times: poses_at(stored, times), description)


def poses_at(stored: StoredReference, times: np.ndarray) -> np.ndarray:
    """The stored poses at ``times``, each of which must be one of the stored times."""
    times = np.asarray(times, dtype=float)
    index = np.searchsorted(stored.times, times).clip(0, len(stored.times) - 1)
    below = (index - 1).clip(0)
    nearest = np.where(
        np.abs(stored.times[below] - times) < np.abs(stored.times[index] - times), below, index
    )
    scale = max(1.0, float(np.abs(stored.times).max()))
    off = np.abs(stored.times[nearest] - times) > 1e-9 * scale
    if off.any():
        raise ReferenceTimesMismatch(
            f"the stored reference of {stored.problem!r} has no sample at t = "
            f"{times[np.argmax(off)]:g} s ({len(stored.times)} samples over "
            f"{stored.times[0]:g} .. {stored.times[-1]:g} s)"
        )
    return stored.poses[nearest]


# ---- the command ---------------------------------------------------------------------


def reference_names(problem: str | None, every: bool) -> list[str]:
    """The problems ``workbench reference`` works on: one name, or with ``--all`` every
    registered problem without an analytic reference."""
    from workbench.plugin import registry

    if (problem is None) == (not every):
        raise ConfigError("give either a PROBLEM name or --all (not both, not neither)")
    if problem is not None:
        registry.get_problem(problem)  # unknown name: a PluginError listing the known ones
        return [problem]
    names = []
    for info in registry.list_plugins("problem"):
        if info.plugin is None:
            continue
        given = info.plugin().reference()
        if given is None or given.kind != "analytic":
            names.append(info.name)
    return names


def run_command(
    out: Any,
    problem: str | None,
    every: bool,
    rtol: float,
    samples: int | None,
    directory: str | None,
    threshold: float = AGREEMENT_THRESHOLD,
) -> list[Path]:
    """``workbench reference``: compute, check and write; a rich progress bar on stderr and a
    table of the agreement on ``out`` (a rich Console). Raises ReferenceDisagreement at the
    end if any problem's pipelines disagreed (the others are written)."""
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
    from rich.table import Table

    names = reference_names(problem, every)
    table = Table(title="stored references", title_justify="left")
    for column in ("problem", "A (stored)", "B", "agreement / L", "at", "seconds", "file"):
        table.add_column(column, overflow="fold")
    written, failures = [], []
    columns = [SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn()]
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("references", total=2 * len(names))

        def step(text: str) -> None:
            bar.update(task, description=text)
            bar.advance(task)

        for name in names:
            try:
                stored = compute_reference(name, rtol, samples, threshold, progress=step)
            except ReferenceDisagreement as error:
                failures.append(str(error))
                table.add_row(name, "", "", "disagree", "", "", str(error))
                continue
            path = write_reference(stored, directory)
            written.append(path)
            agreed, (first, second) = stored.metadata["agreement"], stored.metadata["pipelines"]
            table.add_row(
                name,
                first["label"],
                second["label"],
                f"{agreed['relative']:.2g}",
                f"t={agreed['at_time_s']:g} s {agreed['body']}",
                f"{sum(p['build_s'] + p['integrate_s'] for p in (first, second)):.1f}",
                str(path),
            )
    out.width = max(out.width, 160)  # a wide table: let a narrow terminal wrap it
    out.print(table)
    if failures:
        raise ReferenceDisagreement(" | ".join(failures))
    return written
