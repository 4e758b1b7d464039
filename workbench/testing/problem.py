"""Conformance checks of a problem plugin (:func:`check_problem`).

Structural: registered, metadata (plus ``source``), options, ``declarations`` (times,
samples). Then: ``model`` (builds and validates), ``initial-state`` (a consistent state
exists), ``conservative`` (a problem declared conservative has no damping, driving or
applied forces), ``tight-run`` (a minimal-ode run at rtol 1e-10 over the first half
second; if it fails, a FAIL row with the reason, and the checks below that need it are
skipped), ``reference`` (if given: shaped (n_times, n_bodies, 7) with unit quaternions,
the same on a second call, and matching the tight run), ``energy`` and ``invariants``
(conserved over that tight run).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from workbench.equations.initial import consistent_initial_state
from workbench.errors import one_line
from workbench.execution.references import given_reference
from workbench.mechanics.forces import is_conservative_model
from workbench.numerics.geometry import length_scale, pose_error
from workbench.plugin.problem import Problem
from workbench.plugin.registry import get_formalism
from workbench.testing.common import PLACEHOLDER, check_structure, resolve_plugin
from workbench.testing.report import ConformanceReport
from workbench.testing.states import energy_scale, tight_run

TOLERANCES = {
    "reference": 1e-6,
    "energy": 1e-7,
    "invariants": 1e-7,
    "vectorized-invariant": 1e-12,  # relative: the same arithmetic, batched
}
HORIZON = 0.5  # s


def check_problem(problem: str | type | Problem, checks: str = "all") -> Any:
    """Check a problem (registered name, class or instance); returns a ConformanceReport."""
    instance = problem if isinstance(problem, Problem) else None
    plugin = resolve_plugin("problem", type(problem) if instance else problem)
    report = ConformanceReport("problem", getattr(plugin, "name", plugin.__qualname__))
    defaults = check_structure(report, "problem", plugin, Problem)
    problems = []
    source = getattr(plugin, "source", "")
    if not source or PLACEHOLDER.search(str(source)):
        problems.append("set source (the book section or paper it follows)")
    if not plugin.t_end > plugin.t_start:
        problems.append(f"t_end ({plugin.t_end}) must be > t_start ({plugin.t_start})")
    if not (isinstance(plugin.n_samples, int) and plugin.n_samples >= 2):
        problems.append(f"n_samples must be an integer >= 2, not {plugin.n_samples!r}")
    if problems:
        report.failed("declarations", "", "; ".join(problems))
    else:
        report.passed(
            "declarations",
            message=f"t in [{plugin.t_start:g}, {plugin.t_end:g}] s, "
            f"{plugin.n_samples} samples, source {plugin.source}",
        )
    if checks == "structural" or defaults is None or problems:
        return report
    _check_physics(report, instance or plugin())
    return report


def _check_physics(report: ConformanceReport, problem: Problem) -> None:
    name = problem.name
    try:
        model = problem.model()
        model.validate()
    except Exception as error:  # noqa: BLE001
        report.failed("model", name, one_line(error))
        return
    report.passed(
        "model", name, f"{model.kind}, {len(model.bodies)} bodies, {len(model.joints)} joints"
    )
    try:
        equations = get_formalism("minimal-ode")().build(model, {"index": 1})
        state = consistent_initial_state(equations, problem)
    except Exception as error:  # noqa: BLE001
        report.failed("initial-state", name, one_line(error))
        return
    report.passed("initial-state", name, f"{equations.nq} coordinates, {equations.nv} velocities")
    if problem.conservative and not is_conservative_model(model):
        report.failed(
            "conservative",
            name,
            "declared conservative, but the model has damping, "
            "joint or applied forces or driven joints; set conservative = False",
        )
    else:
        report.passed("conservative", name, f"conservative = {problem.conservative}")
    horizon = min(HORIZON, problem.t_end - problem.t_start)
    samples = problem.sample_times()  # a stored reference has only these
    samples = samples[samples <= problem.t_start + horizon + 1e-12]
    if samples.size < 3:
        samples = np.linspace(problem.t_start, problem.t_start + horizon, 21)
    run = f"minimal-ode + DOP853 rtol 1e-10 over {horizon:g} s"
    try:
        times, y = tight_run(equations, state, samples[-1], times=samples)
    except Exception as error:  # noqa: BLE001
        _without_tight_run(report, problem, model, samples, f"{one_line(error)} ({run})")
        return
    report.passed("tight-run", name, f"{run}, {times.size} samples")
    nq, nv, obs = equations.nq, equations.nv, equations.observables
    poses = np.stack([obs.poses(t, r[:nq]) for t, r in zip(times, y, strict=True)])
    _check_reference(report, problem, model, times, poses)
    if problem.conservative:
        energies = np.array(
            [
                np.ravel(obs.energy(t, r[:nq], r[nq : nq + nv])[0])
                for t, r in zip(times, y, strict=True)
            ]
        )
        total = energies.sum(axis=1)
        error = float(np.max(np.abs(total - total[0]))) / energy_scale(energies)
        report.add("energy", name, error, TOLERANCES["energy"], run)
    twists = np.stack(
        [
            np.reshape(obs.twists(t, r[:nq], r[nq : nq + nv])[0], (6, -1)).T
            for t, r in zip(times, y, strict=True)
        ]
    )
    for invariant in problem.invariants():
        try:
            values = invariant.along(model, times, poses, twists)
        except Exception as error:  # noqa: BLE001
            report.failed("invariants", name, f"{invariant.name}: {one_line(error)}")
            continue
        if invariant.vectorized:
            _check_vectorized(report, name, invariant, model, times, poses, twists, values)
        scale = abs(values[0]) if abs(values[0]) >= 1e-12 else 1.0
        error = float(np.max(np.abs(values - values[0]))) / scale
        report.add("invariants", name, error, TOLERANCES["invariants"], f"{invariant.name}, {run}")


def _without_tight_run(
    report: ConformanceReport, problem: Problem, model: Any, times: np.ndarray, reason: str
) -> None:
    """The tight run failed: a FAIL row with its reason, the reference's own checks (shape,
    finite, unit, repeatable) still made, and the checks that need the run skipped."""
    name = problem.name
    report.failed("tight-run", name, reason)
    _check_reference(report, problem, model, times, None)
    if problem.conservative:
        report.skipped("energy", name, "no tight run to measure it on")
    if problem.invariants():
        report.skipped("invariants", name, "no tight run to measure them on")


def _check_vectorized(
    report: ConformanceReport,
    name: str,
    invariant: Any,
    model: Any,
    times: np.ndarray,
    poses: np.ndarray,
    twists: np.ndarray,
    values: np.ndarray,
) -> None:
    """A vectorized invariant gives, in one call, what it gives one sample at a time."""
    one_by_one = replace(invariant, vectorized=False).along(model, times, poses, twists)
    scale = max(float(np.max(np.abs(one_by_one))), 1e-12)
    error = float(np.max(np.abs(values - one_by_one))) / scale
    report.add(
        "vectorized-invariant",
        name,
        error,
        TOLERANCES["vectorized-invariant"],
        f"{invariant.name}: one call along {len(times)} samples vs one call per sample",
    )


def _check_reference(
    report: ConformanceReport,
    problem: Problem,
    model: Any,
    times: np.ndarray,
    poses: np.ndarray | None,
) -> None:
    """The given reference at ``times``: well shaped, finite, unit quaternions, repeatable,
    and matching the tight run's ``poses`` (None: the run failed, so not compared)."""
    name = problem.name
    reference = given_reference(problem)
    if reference is None:
        report.skipped("reference", name, "none given: runs compute one (minimal-ode, tight)")
        return
    try:
        first = np.asarray(reference.poses(times), float)
        second = np.asarray(reference.poses(times), float)
    except Exception as error:  # noqa: BLE001
        report.failed("reference", name, f"poses(times) raised {one_line(error)}")
        return
    shape = (times.size, len(model.bodies), 7)
    if first.shape != shape:
        report.failed("reference", name, f"poses(times) has shape {first.shape}, expected {shape}")
        return
    # a NaN quaternion means "orientation not known" (geometry.pose_error then compares
    # positions only, e.g. the rolling ball's): allowed, but not a NaN position
    norms = np.linalg.norm(first[..., 3:], axis=-1)
    known = np.isfinite(norms)
    problems = []
    if not np.all(np.isfinite(first[..., :3])):
        problems.append("positions are not finite")
    if not np.allclose(norms[known], 1.0, atol=1e-9):
        problems.append("quaternions are not unit")
    if not np.array_equal(first, second, equal_nan=True):
        problems.append("a second call differs")
    if problems:
        report.failed("reference", name, ", ".join(problems))
        return
    if poses is None:
        report.skipped("reference", name, "well shaped; not compared: no tight run")
        return
    length = length_scale(model, first)
    error = float(np.max(pose_error(poses, first, length))) / length
    report.add(
        "reference",
        name,
        error,
        TOLERANCES["reference"],
        f"{reference.kind} reference vs a tight minimal-ode run, pose error / L",
    )
