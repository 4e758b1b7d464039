"""Metrics of one run: error against a reference, constraint drift, energy, invariants, cost.

Everything is measured on formalism-neutral observables (``Equations.observables``) at the
problem's output times, so two formalisms are compared on the same footing.

**Reference** (column ``reference_kind``):

- ``analytic`` or ``stored``: the problem's own :meth:`~workbench.plugin.problem.Problem.reference`
  (stored: two independent pipelines that agree, :mod:`workbench.references`; used when
  it holds the output times asked for, else the computed reference below);
- ``computed``: when the problem gives none, a tight-tolerance run (rtol 1e-11,
  atol 1e-12) of a fixed pipeline: formalism ``minimal-ode`` at index 1 (for a tree this
  is the plain ODE in joint coordinates; for a closed loop the index-1 system with
  Baumgarte stabilization) integrated by ``scipy-dop853`` (trees) or ``scipy-radau``
  (closed loops or nonholonomic constraints). If that integrator is not registered, the
  same method is called directly through :func:`scipy.integrate.solve_ivp`. The body
  poses are cached in memory and on disk under ``<reference_dir>/<problem>-<hash>.parquet``
  (the hash covers the problem's options, output times, pipeline, tolerances and its
  fingerprint: model parameters and initial condition; the file is written atomically,
  and a lock file keeps concurrent workers from computing it twice);
- ``none``: no reference could be obtained (error columns are NaN, the reason is in
  ``notes``).

**Pose error** at one output time: the largest over bodies of ``|dr| + L |dtheta|`` (m),
with ``dr`` the error of the body frame's origin, ``dtheta`` the angle of the relative
rotation between the computed and the reference orientation, and ``L`` the model's
length scale: the largest distance of any body frame origin from the inertial origin
over the reference, of any centre of mass or joint frame from its body frame origin, and
at least 1e-3 m. ``err_max`` is its maximum over the output times, ``err_end`` its value at
the end time, and ``scd = -log10(err_end / L)``: the number of significant correct digits
of the relative end error, as in the test set for IVP solvers of Mazzia and Magherini
(https://archimede.uniba.it/~testset/).

**Drift**: at each output time the largest absolute component of the position-level
(m or rad), velocity-level and nonholonomic constraint residuals of
``observables.residuals`` (NaN when the model has no such constraint); ``*_max`` and
``*_final``.

**Energy**: for a conservative problem, ``|E(t) - E(t0)| / S`` with E = T + V and
``S = max(T(t0) + |V(t0)|, max_t T(t))`` (the energy present in the motion, independent
of the zero level of V). For a non-conservative problem the energy balance (work of the
non-conservative forces) is not computed yet: ``energy_err_max`` is NaN and ``notes``
says so.

**Invariants**: for each of the problem's invariants ``I``, ``max_t |I(t) - I(t0)| / |I(t0)|``
(absolute when ``|I(t0)| < 1e-12``); ``invariant_err_max`` is the largest over invariants.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.equations import Equations
from workbench.references import ReferenceTimesMismatch, problem_fingerprint

REFERENCE_RTOL = 1e-11
REFERENCE_ATOL = 1e-12
REFERENCE_FORMALISM = ("minimal-ode", {"index": 1})
MIN_LENGTH_SCALE = 1e-3  # m
SERIES_COLUMNS = ["run_id", "t", "drift_pos", "drift_vel", "drift_nh", "energy_err", "ref_err"]
POSE_COLUMNS = ["x", "y", "z", "p0", "p1", "p2", "p3"]

_REFERENCE_MEMORY: dict[str, tuple[str, np.ndarray, str]] = {}


@dataclass
class ReferencePoses:
    """Reference body poses (n_times, n_bodies, 7) at the output times, or None."""

    kind: str  # analytic | stored | computed | none
    poses: np.ndarray | None
    description: str = ""
    seconds: float = 0.0


# ---- pose error ----------------------------------------------------------------------


def rotation_angle(quat_a: np.ndarray, quat_b: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation between unit quaternions (..., 4) scalar-first, in [0, pi].

    2 atan2(|vector part|, |scalar part|) of the relative quaternion conj(a) b: accurate
    for small angles too (arccos of the dot product loses half the digits).
    """
    w_a, v_a = quat_a[..., :1], quat_a[..., 1:]
    w_b, v_b = quat_b[..., :1], quat_b[..., 1:]
    scalar = np.sum(quat_a * quat_b, axis=-1)
    vector = w_a * v_b - w_b * v_a - np.cross(v_a, v_b)
    return 2.0 * np.arctan2(np.linalg.norm(vector, axis=-1), np.abs(scalar))


def pose_error(poses: np.ndarray, reference: np.ndarray, length: float) -> np.ndarray:
    """Per output time, max over bodies of |dr| + L |dtheta| (m). Shapes (n, n_bodies, 7).

    A reference orientation given as NaN (not known analytically, e.g. the rolling ball's)
    counts the position error alone.
    """
    position_error = np.linalg.norm(poses[..., :3] - reference[..., :3], axis=-1)
    angle_error = rotation_angle(poses[..., 3:], reference[..., 3:])
    known = np.all(np.isfinite(reference[..., 3:]), axis=-1)
    angle_error = np.where(known, angle_error, 0.0)
    return np.max(position_error + length * angle_error, axis=-1)


def length_scale(model: Any, reference: np.ndarray | None) -> float:
    """The model's length scale L (m), see the module docstring."""
    lengths = [MIN_LENGTH_SCALE]
    if reference is not None and reference.size:
        lengths.append(float(np.max(np.linalg.norm(reference[..., :3], axis=-1))))
    for body in getattr(model, "bodies", {}).values():
        lengths.append(float(np.linalg.norm(body.com)))
    for joint in getattr(model, "joints", {}).values():
        lengths.append(float(np.linalg.norm(joint.parent_frame.position)))
        lengths.append(float(np.linalg.norm(joint.child_frame.position)))
    return max(x for x in lengths if math.isfinite(x))


# ---- reference -----------------------------------------------------------------------


def _problem_key(problem_name: str, problem_options: dict[str, Any], times: np.ndarray) -> dict:
    return {
        "problem": problem_name,
        "options": problem_options,
        "times": [float(times[0]), float(times[-1]), int(times.size)],
    }


def reference_hash(key: dict[str, Any]) -> str:
    text = json.dumps(key, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@contextlib.contextmanager
def _file_lock(path: Path) -> Iterator[None]:
    """An exclusive advisory lock (released by the OS if the holder dies)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock, at worst the reference is computed twice
        yield
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _poses_to_frame(times: np.ndarray, poses: np.ndarray, bodies: list[str]) -> pd.DataFrame:
    n_times, n_bodies, _ = poses.shape
    frame = pd.DataFrame(poses.reshape(n_times * n_bodies, 7), columns=POSE_COLUMNS)
    frame.insert(0, "body", np.tile(np.array(bodies, dtype=object), n_times))
    frame.insert(0, "t", np.repeat(times, n_bodies))
    return frame


def _frame_to_poses(frame: pd.DataFrame, n_times: int) -> np.ndarray:
    values = frame[POSE_COLUMNS].to_numpy(dtype=float)
    return values.reshape(n_times, -1, 7)


def computed_reference(
    problem: Any,
    problem_name: str,
    problem_options: dict[str, Any],
    times: np.ndarray,
    reference_dir: Path | None = None,
) -> ReferencePoses:
    """The tight-tolerance reference of the module docstring, cached in memory and on disk."""
    from workbench.plugin import registry  # lazy: the registry discovers plugins

    model = problem.model()
    tree = not model.cut_joints and not model.nonholonomic
    integrator_name = "scipy-dop853" if tree else "scipy-radau"
    formalism_name, formalism_options = REFERENCE_FORMALISM
    key = _problem_key(problem_name, problem_options, times)
    key["pipeline"] = [formalism_name, formalism_options, integrator_name]
    key["tolerances"] = [REFERENCE_RTOL, REFERENCE_ATOL]
    # the model and initial condition too: a cached reference of an edited problem (same
    # name, options and times) was served as its reference before
    key["fingerprint"] = problem_fingerprint(problem)
    digest = reference_hash(key)
    if digest in _REFERENCE_MEMORY:
        kind, poses, description = _REFERENCE_MEMORY[digest]
        return ReferencePoses(kind, poses, description)
    path = None
    if reference_dir is not None:
        path = Path(reference_dir) / f"{problem_name}-{digest}.parquet"
    started = time.perf_counter()
    lock = _file_lock(path.with_suffix(".lock")) if path else contextlib.nullcontext()
    with lock:
        if path is not None and path.exists():
            try:
                frame = pd.read_parquet(path)
                poses = _frame_to_poses(frame, times.size)
                description = f"computed, read from {path.name}"
                _REFERENCE_MEMORY[digest] = ("computed", poses, description)
                return ReferencePoses("computed", poses, description, time.perf_counter() - started)
            except Exception:  # noqa: BLE001 - an unreadable cache file is recomputed
                pass
        formalism_class = registry.get_formalism(formalism_name)
        equations = formalism_class().build(model, formalism_options)
        from workbench.equations.initial import consistent_initial_state

        state = consistent_initial_state(equations, problem)
        method = "DOP853" if tree else "Radau"
        if integrator_name in registry.plugin_names("integrator"):
            integrator = registry.get_integrator(integrator_name)()
            form = integrator.select_form(formalism_class.forms(formalism_options))
            trajectory = integrator.solve(
                equations,
                state.y0(equations, form),
                state.yp0(equations, form),
                times,
                REFERENCE_RTOL,
                REFERENCE_ATOL,
                None,
                form,
            )
            if not trajectory.success:
                raise RuntimeError(f"reference run failed: {trajectory.message}")
            y = trajectory.y
            solver = integrator_name
        else:
            y = _solve_ivp_reference(equations, state.y0(equations, "ode"), times, method)
            solver = f"scipy.integrate.solve_ivp({method})"
        poses = np.stack(
            [
                equations.observables.poses(t, row[: equations.nq])
                for t, row in zip(times, y, strict=True)
            ]
        )
        description = (
            f"computed: {formalism_name} {formalism_options} + {solver}, "
            f"rtol {REFERENCE_RTOL:g}, atol {REFERENCE_ATOL:g}"
        )
        if path is not None:
            from workbench.store import write_parquet_atomic

            try:
                write_parquet_atomic(
                    _poses_to_frame(times, poses, equations.observables.body_names), path
                )
            except OSError:  # a read-only output dir only costs the recomputation
                pass
    _REFERENCE_MEMORY[digest] = ("computed", poses, description)
    return ReferencePoses("computed", poses, description, time.perf_counter() - started)


def _solve_ivp_reference(
    equations: Equations, y0: np.ndarray, times: np.ndarray, method: str
) -> np.ndarray:
    import scipy.integrate

    ode = equations.form("ode")

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return ode.rhs.into(t, y)[0].copy()

    def jacobian(t: float, y: np.ndarray) -> np.ndarray:
        return ode.jacobian.into(t, y)[0].copy()

    extra = {"jac": jacobian} if method != "DOP853" else {}
    solution = scipy.integrate.solve_ivp(
        rhs,
        (times[0], times[-1]),
        y0,
        method=method,
        t_eval=times,
        rtol=REFERENCE_RTOL,
        atol=REFERENCE_ATOL,
        **extra,
    )
    if not solution.success or solution.y.shape[1] != times.size:
        raise RuntimeError(f"reference run failed: {solution.message}")
    return solution.y.T


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
        given = problem.reference()
        if given is not None:
            try:
                poses = np.asarray(given.poses(times), dtype=float)
                return ReferencePoses(
                    given.kind, poses, given.description, time.perf_counter() - started
                )
            except ReferenceTimesMismatch:
                pass
        return computed_reference(problem, problem_name, problem_options, times, reference_dir)
    except Exception as error:  # noqa: BLE001 - a missing reference leaves NaN, not a crash
        line = str(error).strip().splitlines()[-1:] or [type(error).__name__]
        return ReferencePoses(
            "none", None, f"no reference: {line[0]}", time.perf_counter() - started
        )


# ---- the metrics ---------------------------------------------------------------------


def _max(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.max(finite)) if finite.size else math.nan


def _final(values: np.ndarray) -> float:
    return float(values[-1]) if values.size else math.nan


def trajectory_metrics(
    run_id: str,
    problem: Any,
    equations: Equations,
    times: np.ndarray,
    y: np.ndarray,
    complete: bool,
    reference: ReferencePoses,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """The metric columns of a row and the time series, from states ``y`` at ``times``.

    ``y`` (n, >= nq + nv) in the layout [q, v, ...]; ``complete``: the run reached the end
    time (else the end error and scd are NaN). ``reference.poses`` covers all the problem's
    output times; the first ``len(times)`` are used.
    """
    nq, nv = equations.nq, equations.nv
    n = len(times)
    notes: list[str] = []
    sampled = equations.observables.along(times, y[:n, :nq], y[:n, nq : nq + nv])
    drift = np.full((n, 3), math.nan)
    for k, residual in enumerate(sampled.residuals[:3]):
        if residual.shape[1]:
            drift[:, k] = np.abs(residual).max(axis=1)
    energy = sampled.energy if n else np.full((0, 2), math.nan)
    pose_array, twists = sampled.poses, sampled.twists

    # error against the reference
    ref_err = np.full(n, math.nan)
    length = length_scale(equations.model, reference.poses)
    if reference.poses is not None and n:
        ref_err = pose_error(pose_array, reference.poses[:n], length)
    elif reference.poses is None:
        notes.append(reference.description or "no reference")
    err_end = float(ref_err[-1]) if (complete and n) else math.nan
    scd = -math.log10(err_end / length) if err_end > 0 else math.nan
    if err_end == 0.0:
        scd = math.inf

    # energy
    energy_err = np.full(n, math.nan)
    if problem.conservative and n:
        total = energy.sum(axis=1)
        kinetic0, potential0 = energy[0]
        scale = max(kinetic0 + abs(potential0), _max(energy[:, 0]), 1e-300)
        energy_err = np.abs(total - total[0]) / scale
    elif not problem.conservative:
        notes.append("energy balance of a non-conservative problem not computed yet")

    # invariants
    invariant_errors = []
    for invariant in problem.invariants():
        values = invariant.along(equations.model, times, pose_array, twists)
        if not values.size:
            continue
        scale = abs(values[0]) if abs(values[0]) >= 1e-12 else 1.0
        invariant_errors.append(_max(np.abs(values - values[0]) / scale))

    row = {
        "reference_kind": reference.kind,
        "reference": reference.description,
        "length_scale": length,
        "err_max": _max(ref_err),
        "err_end": err_end,
        "scd": scd,
        "drift_pos_max": _max(drift[:, 0]),
        "drift_pos_final": _final(drift[:, 0]),
        "drift_vel_max": _max(drift[:, 1]),
        "drift_vel_final": _final(drift[:, 1]),
        "drift_nh_max": _max(drift[:, 2]),
        "drift_nh_final": _final(drift[:, 2]),
        "energy_err_max": _max(energy_err),
        "energy_err_final": _final(energy_err),
        "invariant_err_max": max(invariant_errors) if invariant_errors else math.nan,
        "notes": "; ".join(notes),
    }
    series = pd.DataFrame(
        {
            "run_id": run_id,
            "t": np.asarray(times, dtype=float),
            "drift_pos": drift[:, 0],
            "drift_vel": drift[:, 1],
            "drift_nh": drift[:, 2],
            "energy_err": energy_err,
            "ref_err": ref_err,
        },
        columns=SERIES_COLUMNS,
    )
    return row, series


def empty_series(run_id: str) -> pd.DataFrame:
    """A time series with no rows (skipped and failed-before-integration runs)."""
    return pd.DataFrame({c: pd.Series(dtype="float64") for c in SERIES_COLUMNS}).assign(
        run_id=pd.Series(dtype="object")
    )[SERIES_COLUMNS]


@functools.cache
def _environment() -> tuple[tuple[str, Any], ...]:
    return tuple(_read_environment().items())


def environment() -> dict[str, Any]:
    """Versions of the libraries used and the machine, as row columns (read once a
    process: importlib.metadata scans the installed distributions on every call)."""
    return dict(_environment())


def _read_environment() -> dict[str, Any]:
    import platform
    from importlib import metadata

    versions: dict[str, Any] = {"version_python": platform.python_version()}
    for column, distribution in [
        ("version_numpy", "numpy"),
        ("version_scipy", "scipy"),
        ("version_casadi", "casadi"),
        ("version_sksundae", "scikit-sundae"),
        ("version_workbench", "mbs-workbench"),
    ]:
        try:
            versions[column] = metadata.version(distribution)
        except metadata.PackageNotFoundError:
            versions[column] = ""
    versions["machine"] = f"{platform.platform()} {platform.machine()}".strip()
    versions["cpu_count"] = os.cpu_count() or 0
    return versions
