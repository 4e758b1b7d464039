"""Metrics of one run: error against a reference, constraint drift, energy, invariants, cost.

Everything is measured on formalism-neutral observables (``Equations.observables``) at the
problem's output times, so two formalisms are compared on the same footing.

**Reference** (column ``reference_kind``): ``analytic``, ``stored``, ``computed`` or
``none``, chosen by :func:`workbench.execution.references.problem_reference`.

**Pose error** at one output time: the largest over bodies of ``|dr| + L |dtheta|`` (m),
with ``dr`` the error of the body frame's origin, ``dtheta`` the angle of the relative
rotation between the computed and the reference orientation, and ``L`` the model's
length scale: the largest distance of any body frame origin from the inertial origin
over the reference, of any centre of mass or joint frame from its body frame origin, and
at least 1e-3 m. ``err_max`` is its maximum over the output times, ``err_end`` its value at
the end time, and ``scd = -log10(err_end / L)``: the number of significant correct digits
of the relative end error, as in the test set for IVP solvers of Mazzia and Magherini
(https://archimede.uniba.it/~testset/). ``scd_mixed`` is that test set's mixed measure
beside it: ``min over components of -log10(|err| / (1 + |ref|))`` over the components of
the end poses (positions in m and scalar-first quaternions, each quaternion taken with the
sign nearer its reference; components the reference leaves unknown drop out). It equals
the test set's own number when the poses hold the test set's variables (the car axis'
wheel positions); where they do not (Andrews' angles), it is the same measure on poses.
Both are capped at the digits the reference states for itself (``reference_accuracy``).

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

import math
from typing import Any

import numpy as np
import pandas as pd

from workbench.equations import Equations, SampledObservables
from workbench.execution.audit import (
    MEASURE,
    at_reference_accuracy,
    audit_warnings,
    below_least_rtol,
    health_audit,
    motionless_warning,
)
from workbench.execution.contact_metrics import contact_metrics, penetration_series
from workbench.execution.references import ReferencePoses
from workbench.execution.row_schema import SERIES_COLUMNS
from workbench.mechanics.forces import is_conservative_model
from workbench.numerics.geometry import length_scale, pose_error

# ---- the metrics ---------------------------------------------------------------------


UNMEASURED_WITHOUT_STEPS = [
    "err_max", "err_end", "err_l2", "scd", "scd_mixed",
    "drift_pos_max", "drift_pos_final", "drift_vel_max", "drift_vel_final",
    "drift_nh_max", "drift_nh_final",
    "energy_err_max", "energy_err_final", "invariant_err_max",
]  # fmt: skip


def _max(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.max(finite)) if finite.size else math.nan


def _rms(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite**2))) if finite.size else math.nan


def _final(values: np.ndarray) -> float:
    return float(values[-1]) if values.size else math.nan


def mixed_scd(poses: np.ndarray, reference: np.ndarray) -> float:
    """The test set's mixed significant correct digits of poses (n_bodies, 7) against
    reference poses: min over known components of -log10(|err| / (1 + |ref|))."""
    poses = np.array(poses, dtype=float)
    reference = np.asarray(reference, dtype=float)
    flip = np.nansum(poses[:, 3:] * reference[:, 3:], axis=-1) < 0  # q and -q: one rotation
    poses[flip, 3:] *= -1
    scaled = np.abs(poses - reference) / (1.0 + np.abs(reference))
    known = scaled[np.isfinite(scaled)]
    if not known.size:
        return math.nan
    worst = float(np.max(known))
    return math.inf if worst == 0.0 else -math.log10(worst)


def nonconservative_elements(problem: Any, model: Any) -> str:
    """Why T + V may change in a problem declared conservative ("" when nothing does): its
    model's drives, damping or applied forces, which an "energy not conserved" warning
    names, so that it does not blame the methods for the declaration."""
    if not problem.conservative or is_conservative_model(model):
        return ""
    return (f"the model of {problem.name!r}, declared conservative, has a drive, damping or "
            "applied forces: if they change T + V, declare conservative = False")


def trajectory_metrics(
    run_id: str,
    problem: Any,
    equations: Equations,
    times: np.ndarray,
    y: np.ndarray,
    complete: bool,
    reference: ReferencePoses,
    rtol: float = math.nan,
    charts: list[Any] | None = None,
    contact: dict[str, Any] | None = None,
    states: dict[str, np.ndarray] | None = None,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """The metric columns of a row and the time series as a DataFrame: :func:`metric_columns`
    (same arguments), its series' columns made one frame (:func:`series_frame`)."""
    row, columns = metric_columns(
        run_id, problem, equations, times, y, complete, reference, rtol, charts, contact, states
    )
    return row, series_frame(columns)


def metric_columns(
    run_id: str,
    problem: Any,
    equations: Equations,
    times: np.ndarray,
    y: np.ndarray,
    complete: bool,
    reference: ReferencePoses,
    rtol: float = math.nan,
    charts: list[Any] | None = None,
    contact: dict[str, Any] | None = None,
    states: dict[str, np.ndarray] | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The metric columns of a row and the time series' columns, from states ``y`` at ``times``.

    ``y`` (n, >= nq + nv) in the layout [q, v, ...]; ``complete``: the run reached the end
    time (else the end error and scd are NaN). ``reference.poses`` covers all the problem's
    output times; the first ``len(times)`` are used. ``rtol``: the run's tolerance, against
    which the health audit (:mod:`workbench.execution.audit`) judges drift and energy.
    ``charts``: the chart of each sample when the run changed chart
    (:mod:`workbench.execution.charts`); each sample is measured with its chart's equations.
    ``contact``: what a contact integrator measured (``Trajectory.contact``), for the
    contact columns (:mod:`workbench.execution.contact_metrics`). ``states``: more series
    columns (name -> n values: the trajectory's states, ``state:<name>``), put last.

    The series is returned as its columns in the series file's order (:data:`SERIES_COLUMNS`,
    a contact model's ``penetration``, then ``states``): name -> n float64 values, and
    ``run_id`` one text for every row; :func:`series_frame` makes them the DataFrame. A
    sweep's worker writes and records them without a frame (docs/performance.md).
    """
    nq, nv = equations.nq, equations.nv
    n = len(times)
    notes: list[str] = []
    sampled = _sampled(equations, times, y[:n, :nq], y[:n, nq : nq + nv], charts)
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
    scd_mixed = math.nan
    if math.isfinite(err_end) and reference.poses is not None:
        scd_mixed = mixed_scd(pose_array[-1], reference.poses[n - 1])

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
        "err_l2": _rms(ref_err),
        "scd": scd,
        "scd_mixed": scd_mixed,
        "drift_pos_max": _max(drift[:, 0]),
        "drift_pos_final": _final(drift[:, 0]),
        "drift_vel_max": _max(drift[:, 1]),
        "drift_vel_final": _final(drift[:, 1]),
        "drift_nh_max": _max(drift[:, 2]),
        "drift_nh_final": _final(drift[:, 2]),
        "energy_err_max": _max(energy_err),
        "energy_err_final": _final(energy_err),
        "invariant_err_max": max(invariant_errors) if invariant_errors else math.nan,
    }
    if not complete and n <= 1:
        # only the initial state: its error and drift are those of the initial condition,
        # not of a method that never took a step; a 0 here read as a perfect run
        row.update({column: math.nan for column in UNMEASURED_WITHOUT_STEPS})
        notes.append("nothing was integrated: no error, drift or energy was measured")
    elif not complete:
        notes.append(f"maxima over the part reached, t <= {float(times[-1]):g} s")
    at_accuracy = at_reference_accuracy(row, reference.accuracy)
    if at_accuracy:
        notes.append(at_accuracy)
    below_least = below_least_rtol(rtol)
    if below_least:
        notes.append(below_least)
    row["notes"] = "; ".join(notes)

    audit = health_audit(equations, times, y[:n], sampled.rotations, rtol, charts)
    audit["reference_accuracy"] = reference.accuracy
    found = audit_warnings(audit, row, rtol, problem.conservative,
                           energy_cause=nonconservative_elements(problem, equations.model))
    still = motionless_warning(np.asarray(y[:n], dtype=float))
    found += [still] if still else []
    audit.pop(MEASURE, None)
    if row["err_end"] / length < reference.accuracy:  # more digits than the reference has
        row["scd"] = -math.log10(reference.accuracy)
    if reference.accuracy > 0 and row["scd_mixed"] > -math.log10(reference.accuracy):
        row["scd_mixed"] = -math.log10(reference.accuracy)
    contact_row, contact_found = contact_metrics(
        problem, equations, times, y[:n], contact, energy, length
    )
    row.update(audit | contact_row, warnings="; ".join(found + contact_found))
    columns = {
        "run_id": run_id,
        "t": np.asarray(times, dtype=float),
        "drift_pos": drift[:, 0],
        "drift_vel": drift[:, 1],
        "drift_nh": drift[:, 2],
        "energy_err": energy_err,
        "ref_err": ref_err,
    }
    # in SERIES_COLUMNS' order already: DataFrame(columns=...) reindexed them (0.3 ms a run)
    series = {name: columns[name] for name in SERIES_COLUMNS}
    if getattr(equations, "contacts", None) is not None:  # a contact model's own series
        series["penetration"] = penetration_series(equations, times, y[:n])
    series.update(states or {})
    return row, series


def series_frame(columns: dict[str, Any]) -> pd.DataFrame:
    """A run's time series as a DataFrame from its columns (:func:`metric_columns`: name ->
    n values, a text such as ``run_id`` repeated on every row), in their order."""
    return pd.DataFrame(columns)


def _sampled(equations: Equations, times: np.ndarray, q: np.ndarray, v: np.ndarray,
             charts: list[Any] | None) -> SampledObservables:  # fmt: skip
    """The observables at every sample, each measured in its own chart's equations."""
    atlas = getattr(equations, "atlas", None)
    if not charts or atlas is None or set(charts) == {atlas.home}:
        return equations.observables.along(times, q, v)
    parts = {}
    for chart in dict.fromkeys(charts):
        rows = np.array([k for k, c in enumerate(charts) if c == chart], dtype=int)
        parts[chart] = (rows, atlas.equations(chart).observables.along(
            times[rows], q[rows], v[rows]))  # fmt: skip
    first = next(iter(parts.values()))[1]

    def joined(get: Any) -> np.ndarray:
        out = np.empty((len(times), *get(first).shape[1:]))
        for rows, part in parts.values():
            out[rows] = get(part)
        return out

    return SampledObservables(
        joined(lambda p: p.poses), joined(lambda p: p.twists), joined(lambda p: p.energy),
        [joined(lambda p, i=i: p.residuals[i]) for i in range(len(first.residuals))],
        joined(lambda p: p.rotations),
    )  # fmt: skip
