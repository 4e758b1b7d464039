"""References: the poses a run is measured against (analytic, stored or computed).

:func:`problem_reference` chooses, for one run: the problem's analytic poses
(:meth:`~workbench.plugin.problem.Problem.reference`), else its stored reference (when it
holds the output times asked for), else a computed one; failing all three, ``none`` with
the reason (error columns NaN).

*Stored*: body poses (position + unit quaternion scalar-first) at fixed sample times,
computed twice at tight tolerance by two pipelines that share neither the formalism nor
the integrator (:func:`pipelines`); their pose error (``|dr| + L |dtheta|``,
:func:`workbench.numerics.geometry.pose_error`) relative to the model's length scale L
must stay below a threshold (``1e-7`` by default), else :class:`ReferenceDisagreement`
names the largest disagreement, when and for which body. The first pipeline's poses are
kept. Files (:func:`write_reference`), in ``references/`` beside the module that defines
the problem: ``<problem>.npz`` (``times`` (n,), ``poses`` (n, n_bodies, 7), ``bodies``) and
``<problem>.json`` (command, both pipelines with their cost, tolerances, sample times,
agreement, the problem's fingerprint, library versions). :func:`stored_reference` serves
them while the problem's options and fingerprint (:func:`problem_fingerprint`: model
parameters and initial condition) still match, so an edited problem is never compared
against a stale file.

*Computed*: one tight-tolerance run (REFERENCE_RTOL, REFERENCE_ATOL) of a pipeline,
cached in memory and in ``<out>/references/`` (:func:`computed_reference`).

Which pipelines: the core names none. They are configuration, supplied by the installed
plugins: the built-in package's ``reference_pipelines.toml`` (its comments say why each
was chosen), or another package's entry point in the group ``workbench.reference_pipelines``
(:func:`pipeline_configuration`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import functools
import hashlib
import inspect
import io
import json
import math
import re
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata, resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.equations.initial import consistent_initial_state
from workbench.errors import ConfigError, IntegrationError, WorkbenchError
from workbench.execution.charts import integrate_on_charts
from workbench.execution.environment import environment
from workbench.files import atomic_write, file_lock, write_json_atomic, write_parquet_atomic
from workbench.numerics.geometry import length_scale, rotation_angle
from workbench.plugin import registry
from workbench.plugin.options import options_dict
from workbench.plugin.problem import Reference

BUILTIN_PLUGINS = "workbench.plugins"  # the package whose reference_pipelines.toml is read

REFERENCE_RTOL = 1e-11
REFERENCE_ATOL = 1e-12  # computed references; stored ones use rtol * ATOL_FACTOR
ATOL_FACTOR = 0.1  # atol = rtol * ATOL_FACTOR
AGREEMENT_THRESHOLD = 1e-7  # largest pose disagreement / L
DIRECTORY = "references"
POSE_COLUMNS = ["x", "y", "z", "p0", "p1", "p2", "p3"]
PIPELINES_GROUP = "workbench.reference_pipelines"

# poses, description, accuracy, the pipeline's formalism
_REFERENCE_MEMORY: dict[str, tuple[np.ndarray, str, float, str]] = {}


class ReferenceDisagreement(IntegrationError):
    """The two pipelines of a stored reference do not agree within the threshold."""


class ReferenceTimesMismatch(WorkbenchError):
    """Poses were asked for at times the stored reference does not hold."""


@dataclass(frozen=True)
class Pipeline:
    """A formalism (+ options) and an integrator (+ options): one way of computing the motion.

    ``rtol`` / ``atol``: the pipeline's own tolerances (None: the caller's). ``check``: how
    its accuracy is estimated, as changes to this pipeline ({"integrator_options": ...,
    "rtol": ..., "atol": ...}) for a second, less accurate run; the two runs' largest pose
    difference is the stated accuracy of the first (an over-estimate of its error).
    """

    formalism: str
    formalism_options: dict[str, Any]
    integrator: str
    integrator_options: dict[str, Any] = field(default_factory=dict)
    rtol: float | None = None
    atol: float | None = None
    check: dict[str, Any] | None = None

    @classmethod
    def from_entry(cls, entry: dict[str, Any]) -> Pipeline:
        """From a configuration table or a stored reference's metadata."""
        return cls(
            entry["formalism"],
            dict(entry.get("formalism_options", entry.get("options", {})) or {}),
            entry["integrator"],
            dict(entry.get("integrator_options", {}) or {}),
            entry.get("rtol"),
            entry.get("atol"),
            entry.get("check"),
        )

    def tolerances(self, rtol: float, atol: float) -> tuple[float, float]:
        """(rtol, atol) this pipeline runs at when the caller asks for (rtol, atol)."""
        return (self.rtol or rtol, self.atol or atol)

    def checked(self) -> Pipeline | None:
        """The less accurate run that estimates this one's accuracy, or None."""
        if not self.check:
            return None
        changes = {
            k: v for k, v in self.check.items() if k in ("integrator_options", "rtol", "atol")
        }
        if "integrator_options" in changes:
            changes["integrator_options"] = self.integrator_options | changes["integrator_options"]
        return dataclasses.replace(self, check=None, **changes)

    def label(self) -> str:
        def listed(values: dict[str, Any]) -> str:
            return ",".join(f"{k}={v}" for k, v in sorted(values.items()))

        options, integrator_options = (
            listed(self.formalism_options),
            listed(self.integrator_options),
        )
        tolerance = f" at rtol {self.rtol:g}" if self.rtol else ""
        return (
            f"{self.formalism}{f'({options})' if options else ''} + {self.integrator}"
            f"{f'({integrator_options})' if integrator_options else ''}{tolerance}"
        )


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
            # visual only; the model's initial configuration is the fingerprint's "q0"
            if f.name not in ("shapes", "color", "initial_configuration")
            # a model without contacts or joint friction keeps the fingerprint it had
            # before they existed
            and not (f.name in ("contacts", "joint_frictions") and not getattr(value, f.name))
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


# ---- which pipelines (configuration supplied by the installed plugins) ---------------


@functools.cache
def pipeline_configuration() -> dict[str, Any]:
    """The reference pipelines: the built-in package's ``reference_pipelines.toml``,
    replaced table by table by an installed package's entry point in PIPELINES_GROUP."""
    configuration: dict[str, Any] = {}
    with contextlib.suppress(ModuleNotFoundError, FileNotFoundError):
        text = resources.files(BUILTIN_PLUGINS).joinpath("reference_pipelines.toml").read_text()
        configuration.update(tomllib.loads(text))
    for entry_point in metadata.entry_points(group=PIPELINES_GROUP):
        configuration.update(entry_point.load())
    return configuration


def has_set_valued_forces(model: Any) -> bool:
    """Whether ``model`` has unilateral contacts or Coulomb friction in a joint."""
    return bool(getattr(model, "contacts", None) or getattr(model, "joint_frictions", None))


def _fits(when: str | None, model: Any) -> bool:
    tree = not model.cut_joints and not model.nonholonomic
    return {
        None: True,
        "tree": tree,
        "nonholonomic": bool(model.nonholonomic),
        "contact": has_set_valued_forces(model),
    }.get(when, False)


def configured_pipelines(purpose: str, model: Any) -> list[Pipeline]:
    """The configured pipelines for ``purpose`` ("stored.first", "stored.second" or
    "computed") that fit ``model``, in the order to try them; ConfigError if none is."""
    entries: Any = pipeline_configuration()
    for part in purpose.split("."):
        entries = entries.get(part, {}) if isinstance(entries, dict) else {}
    fitting = [Pipeline.from_entry(e) for e in entries or [] if _fits(e.get("when"), model)]
    if not fitting:
        raise ConfigError(
            f"no {purpose} reference pipeline is configured for model {model.name!r}: install "
            f"the built-in plugins or a package with a {PIPELINES_GROUP!r} entry point"
        )
    return fitting


def configured_pipeline(purpose: str, model: Any) -> Pipeline:
    """The first configured pipeline for ``purpose`` that fits ``model``."""
    return configured_pipelines(purpose, model)[0]


def pipelines(model: Any) -> tuple[Pipeline, Pipeline]:
    """The first-choice pipelines of a stored reference for ``model``."""
    return configured_pipeline("stored.first", model), configured_pipeline("stored.second", model)


# ---- computing -----------------------------------------------------------------------


def solve_poses(
    problem: Any, pipeline: Pipeline, times: np.ndarray, rtol: float, atol: float
) -> tuple[np.ndarray, list[str], dict[str, Any]]:
    """Body poses (n_times, n_bodies, 7) of ``problem`` along ``pipeline``, body names, cost
    (which records the tolerances used: the pipeline's own, else ``rtol`` and ``atol``)."""
    rtol, atol = pipeline.tolerances(rtol, atol)
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
    solve = (
        integrator.solve
        if getattr(equations, "atlas", None) is None
        else functools.partial(integrate_on_charts, integrator)
    )  # a formalism with charts (velocity partitions): re-partitioned like any run
    trajectory = solve(
        equations, state.y0(equations, form), state.yp0(equations, form), times, rtol, atol,
        pipeline.integrator_options or None, form,
    )  # fmt: skip
    if not trajectory.success:
        raise IntegrationError(
            f"{problem.name}: {pipeline.label()} failed at rtol {rtol:g}: {trajectory.message}"
        )
    # one mapped evaluation for all samples: a call per sample made the reference cost
    # 24 s at 10^5 output times against 0.05 s for the integration itself
    poses = equations.observables.poses_along(times, trajectory.y[:, : equations.nq])
    cost = {
        "rtol": rtol,
        "atol": atol,
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


def solve_checked(
    problem: Any, pipeline: Pipeline, times: np.ndarray, rtol: float, atol: float
) -> tuple[np.ndarray, list[str], dict[str, Any], dict[str, Any] | None]:
    """:func:`solve_poses` and, when the pipeline has a ``check``, its accuracy estimate: the
    largest pose difference from the check run (an :func:`agreement` dict naming the check
    pipeline and its cost), else None."""
    poses, bodies, cost = solve_poses(problem, pipeline, times, rtol, atol)
    check = pipeline.checked()
    if check is None:
        return poses, bodies, cost, None
    check_poses, _, check_cost = solve_poses(problem, check, times, rtol, atol)
    length = length_scale(problem.model(), poses)
    accuracy = agreement(poses, check_poses, times, bodies, length)
    accuracy["estimated_by"] = f"difference from {check.label()}"
    accuracy["check_cost"] = check_cost
    return poses, bodies, cost, accuracy


def solve_first_available(
    problem: Any, candidates: list[Pipeline], times: np.ndarray, rtol: float, atol: float
) -> tuple[Pipeline, np.ndarray, list[str], dict[str, Any], dict[str, Any] | None]:
    """The first of ``candidates`` that can compute ``problem`` (:func:`solve_checked`):
    one whose plugins are not installed, that refuses the model or fails moves on to the
    next; ConfigError naming every reason when none can."""
    reasons = []
    for pipeline in candidates:
        try:
            return (pipeline, *solve_checked(problem, pipeline, times, rtol, atol))
        except WorkbenchError as error:
            line = (str(error).strip().splitlines() or [type(error).__name__])[-1]
            reasons.append(f"{pipeline.label()}: {line}")
    raise ConfigError(
        f"{problem.name}: no reference pipeline could compute it ({'; '.join(reasons)})"
    )


def compute_reference(
    name: str,
    rtol: float = REFERENCE_RTOL,
    samples: int | None = None,
    threshold: float = AGREEMENT_THRESHOLD,
    chosen: tuple[Pipeline, Pipeline] | None = None,
    progress: Callable[[str], None] | None = None,
) -> StoredReference:
    """Poses of problem ``name`` (default options) by two pipelines that must agree.

    The first pipeline's poses are kept; its accuracy is estimated by its ``check`` run
    (:func:`solve_checked`; metadata ``accuracy``), and the second pipeline, sharing
    neither formalism nor integrator, confirms it to within ``threshold`` L (metadata
    ``agreement``). Each is the first configured one that can compute the problem
    (:func:`solve_first_available`), unless ``chosen`` names both.

    samples: number of equally spaced times over the time span (default: the problem's
    ``n_samples``, so the reference serves the runner's output times). Raises
    :class:`ReferenceDisagreement` if the pipelines differ by more than ``threshold`` L.
    """

    if not (0 < rtol < 1):
        raise ConfigError(f"--rtol must be in (0, 1), not {rtol:g}")
    if samples is not None and samples < 2:
        raise ConfigError(f"--samples must be at least 2, not {samples}")
    problem = registry.get_problem(name)()
    model = problem.model()
    n = samples or problem.n_samples
    times = np.linspace(problem.t_start, problem.t_end, n)
    atol = rtol * ATOL_FACTOR
    candidates = (
        ([chosen[0]], [chosen[1]])
        if chosen
        else (
            configured_pipelines("stored.first", model),
            configured_pipelines("stored.second", model),
        )
    )
    results = []
    for purpose in candidates:
        if progress:
            progress(f"{name}: {purpose[0].label()}")
        results.append(solve_first_available(problem, purpose, times, rtol, atol))
    (first, poses_a, bodies, cost_a, accuracy), (second, poses_b, bodies_b, cost_b, _) = results
    chosen = (first, second)
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
        # the stored poses' accuracy: the first pipeline's check, else the agreement
        "accuracy": stored_accuracy(model, accuracy, agreed),
        "versions": versions,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }
    return StoredReference(name, times, poses_a, bodies, metadata)


def stored_accuracy(
    model: Any, check: dict[str, Any] | None, agreed: dict[str, Any]
) -> dict[str, Any]:
    """The accuracy a stored reference states: its first pipeline's check, else the two
    pipelines' agreement. With contacts or joint friction the larger of the two: both
    pipelines may share the one integrator exact on contacts (see the configured pipelines),
    whose event times near grazing depend on the formalism more than on the tolerance (the
    woodpecker:
    check 6e-12 L, formalisms 4.4e-9 L), so the agreement is the honest bound."""
    by_agreement = {**agreed, "estimated_by": "agreement of the two pipelines"}
    if check is None:
        return by_agreement
    if has_set_valued_forces(model) and agreed["relative"] > check["relative"]:
        return by_agreement | {"tolerance_check": check}
    return check


# ---- files ---------------------------------------------------------------------------


def default_directory(name: str) -> Path:
    """``references/`` beside the module that defines problem ``name``."""
    return Path(inspect.getfile(registry.get_problem(name))).parent / DIRECTORY


def write_reference(reference: StoredReference, directory: Path | str | None = None) -> Path:
    """Write ``<problem>.npz`` and ``<problem>.json`` (atomically); return the .npz path."""
    directory = Path(directory) if directory is not None else default_directory(reference.problem)
    path = directory / f"{reference.problem}.npz"
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer, times=reference.times, poses=reference.poses, bodies=np.array(reference.bodies)
    )
    atomic_write(path, lambda temp: Path(temp).write_bytes(buffer.getvalue()))
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
    # the first pipeline's own accuracy estimate; files written before it: the agreement
    accuracy = stated_accuracy(float(metadata.get("accuracy", agreed).get("relative", math.nan)))
    labels = " vs ".join(p.get("label", "?") for p in metadata.get("pipelines", []))
    description = (
        f"stored {path.name}: {labels}, rtol {metadata.get('rtol', math.nan):g}, "
        f"accuracy {accuracy:.2g} L, agreement {agreed.get('relative', math.nan):.2g} L"
    )
    return Reference("stored", lambda times: poses_at(stored, times), description, accuracy)


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


# ---- the reference of a run: analytic, stored or computed ---------------------------


def given_reference(problem: Any) -> Any:
    """The problem's own reference: its analytic poses, else its stored file; or None."""
    return problem.reference() or stored_reference(problem)


@dataclass
class ReferencePoses:
    """Reference body poses (n_times, n_bodies, 7) at the output times, or None."""

    kind: str  # analytic | stored | computed | none
    poses: np.ndarray | None
    description: str = ""
    seconds: float = 0.0
    accuracy: float = math.nan  # relative to the length scale; see ACCURACY
    formalism: str = ""  # a computed reference's: whose equations it integrated


# The relative accuracy an analytic reference states when it does not say: exact up to the
# round-off of its evaluation. Stored and computed references state what was measured, but
# never less than ROUND_OFF_ACCURACY: their poses come from states in double precision
# through the observables' arithmetic (two runs that agree to the last bit do not make a
# reference exact).
ANALYTIC_ACCURACY = 1e-13
ROUND_OFF_ACCURACY = 1e-15


def stated_accuracy(measured: float) -> float:
    """The accuracy a stored or computed reference states for a measured estimate."""
    return max(float(measured), ROUND_OFF_ACCURACY) if not math.isnan(measured) else math.nan


def _problem_key(problem_name: str, problem_options: dict[str, Any], times: np.ndarray) -> dict:
    return {
        "problem": problem_name,
        "options": problem_options,
        "times": [float(times[0]), float(times[-1]), int(times.size)],
    }


def computed_reference_file(
    problem: Any, problem_name: str, problem_options: dict[str, Any], times: np.ndarray
) -> str:
    """The file name :func:`computed_reference` keeps ``problem``'s reference under in a
    reference folder (its description beside it, ``.json``)."""
    candidates = configured_pipelines("computed", problem.model())
    key = _computed_key(problem, problem_name, problem_options, times, candidates)
    return f"{reference_prefix(problem_name)}-{reference_hash(key)}.parquet"


def _computed_key(
    problem: Any, problem_name: str, problem_options: dict[str, Any], times: np.ndarray,
    candidates: list[Any],
) -> dict[str, Any]:  # fmt: skip
    """What a computed reference is made from: the problem's name, options and output
    times, the configured pipelines (``candidates``), tolerances and fingerprint."""
    key = _problem_key(problem_name, problem_options, times)
    key["pipelines"] = [dataclasses.asdict(p) for p in candidates]
    key["tolerances"] = [REFERENCE_RTOL, REFERENCE_ATOL]
    # the model and initial condition too: a cached reference of an edited problem (same
    # name, options and times) was served as its reference before
    key["fingerprint"] = problem_fingerprint(problem)
    return key


def reference_hash(key: dict[str, Any]) -> str:
    text = json.dumps(key, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _poses_to_frame(times: np.ndarray, poses: np.ndarray, bodies: list[str]) -> pd.DataFrame:
    n_times, n_bodies, _ = poses.shape
    frame = pd.DataFrame(poses.reshape(n_times * n_bodies, 7), columns=POSE_COLUMNS)
    frame.insert(0, "body", np.tile(np.array(bodies, dtype=object), n_times))
    frame.insert(0, "t", np.repeat(times, n_bodies))
    return frame


def _frame_to_poses(frame: pd.DataFrame, n_times: int) -> np.ndarray:
    values = frame[POSE_COLUMNS].to_numpy(dtype=float)
    return values.reshape(n_times, -1, 7)


def reference_prefix(problem_name: str) -> str:
    """The start of a computed reference's file name, then ``-DIGEST.parquet``: a short,
    plain name (a robot run's name holds its file's folders and options)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", problem_name)[:60]


def computed_reference(
    problem: Any,
    problem_name: str,
    problem_options: dict[str, Any],
    times: np.ndarray,
    reference_dir: Path | None = None,
) -> ReferencePoses:
    """A tight-tolerance run of the first configured ``computed`` pipeline that can compute
    the problem (rtol REFERENCE_RTOL, atol REFERENCE_ATOL unless the pipeline sets its own),
    its accuracy estimated by the pipeline's ``check`` run (NaN, unknown, without one).

    Cached in memory and on disk under ``<reference_dir>/<problem>-<hash>.parquet`` with the
    description and accuracy in a ``.json`` beside it (the hash covers the problem's options,
    output times, the configured pipelines, tolerances and fingerprint; written atomically,
    and a lock file keeps concurrent workers from computing it twice)."""
    model = problem.model()
    candidates = configured_pipelines("computed", model)
    key = _computed_key(problem, problem_name, problem_options, times, candidates)
    digest = reference_hash(key)
    if digest in _REFERENCE_MEMORY:
        poses, description, accuracy, formalism = _REFERENCE_MEMORY[digest]
        return ReferencePoses(
            "computed", poses, description, accuracy=accuracy, formalism=formalism
        )
    path = None
    if reference_dir is not None:
        # a robot run's name holds its file's folders and options: keep the file name one
        # short, plain file name (the digest tells the runs apart)
        path = Path(reference_dir) / f"{reference_prefix(problem_name)}-{digest}.parquet"
    started = time.perf_counter()
    lock = file_lock(path.with_suffix(".lock")) if path else contextlib.nullcontext()
    with lock:
        if path is not None and path.exists():
            try:
                frame = pd.read_parquet(path)
                poses = _frame_to_poses(frame, times.size)
                about = json.loads(path.with_suffix(".json").read_text())
                description = f"{about['description']} (read from {path.name})"
                accuracy = float(about["accuracy"])
                formalism = str(about.get("formalism", ""))
                _REFERENCE_MEMORY[digest] = (poses, description, accuracy, formalism)
                seconds = time.perf_counter() - started
                return ReferencePoses(
                    "computed", poses, description, seconds, accuracy, formalism
                )
            except Exception:  # noqa: BLE001 - an unreadable cache file is recomputed
                pass
        pipeline, poses, bodies, cost, estimate = solve_first_available(
            problem, candidates, times, REFERENCE_RTOL, REFERENCE_ATOL
        )
        accuracy = stated_accuracy(float(estimate["relative"])) if estimate else math.nan
        description = (
            f"computed: {pipeline.label()}"  # the label says the pipeline's own rtol
            + ("" if pipeline.rtol else f", rtol {cost['rtol']:g}")
            + f", atol {cost['atol']:g}, "
            + (f"accuracy {accuracy:.2g} L ({estimate['estimated_by']})" if estimate else
               "accuracy not estimated (the pipeline has no check)")
        )  # fmt: skip
        if path is not None:
            try:
                write_parquet_atomic(_poses_to_frame(times, poses, bodies), path)
                about = {"description": description, "accuracy": accuracy, "estimate": estimate,
                         "formalism": pipeline.formalism}  # fmt: skip
                write_json_atomic(about, path.with_suffix(".json"))
            except OSError:  # a read-only output dir only costs the recomputation
                pass
    _REFERENCE_MEMORY[digest] = (poses, description, accuracy, pipeline.formalism)
    seconds = time.perf_counter() - started
    return ReferencePoses("computed", poses, description, seconds, accuracy, pipeline.formalism)


def problem_reference(
    problem: Any,
    problem_name: str,
    problem_options: dict[str, Any],
    times: np.ndarray,
    reference_dir: Path | None = None,
) -> ReferencePoses:
    """The problem's own reference if it gives one, else the computed one; never raises.

    A stored reference without samples at ``times`` (stored for other output times) gives
    way to the computed one.
    """
    started = time.perf_counter()
    try:
        given = given_reference(problem)
        if given is not None:
            try:
                poses = np.asarray(given.poses(times), dtype=float)
                shape = (times.size, len(problem.model().bodies), 7)
                if poses.shape != shape:
                    raise ValueError(
                        f"the {given.kind} reference's poses(times) has shape {poses.shape}, "
                        f"expected {shape} (times, bodies, position and unit quaternion)"
                    )
                accuracy = given.accuracy
                if math.isnan(accuracy) and given.kind == "analytic":
                    accuracy = ANALYTIC_ACCURACY
                seconds = time.perf_counter() - started
                return ReferencePoses(given.kind, poses, given.description, seconds, accuracy)
            except ReferenceTimesMismatch:
                pass
        reason = getattr(problem, "no_reference", "")  # a problem that says why it has none
        if given is None and reason:
            seconds = time.perf_counter() - started
            return ReferencePoses("none", None, f"no reference: {reason}", seconds)
        return computed_reference(problem, problem_name, problem_options, times, reference_dir)
    except Exception as error:  # noqa: BLE001 - a missing reference leaves NaN, not a crash
        line = str(error).strip().splitlines()[-1:] or [type(error).__name__]
        return ReferencePoses(
            "none", None, f"no reference: {line[0]}", time.perf_counter() - started
        )


# ---- the command ---------------------------------------------------------------------


def reference_names(problem: str | None, every: bool) -> list[str]:
    """The problems ``workbench reference`` works on: one name, or with ``--all`` every
    registered problem without an analytic reference."""
    if (problem is None) == (not every):
        raise ConfigError("give either a PROBLEM name or --all (not both, not neither)")
    if problem is not None:
        registry.get_problem(problem)  # unknown name: a PluginError listing the known ones
        return [problem]
    names = []
    for info in registry.list_plugins("problem"):
        if info.plugin is None:
            continue
        if info.plugin().reference() is None:  # not analytic
            names.append(info.name)
    return names
