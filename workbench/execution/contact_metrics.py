"""Metrics of a run with unilateral contacts (docs/nonsmooth.md), beside the smooth ones.

* ``penetration_max`` (m): the deepest gap g_N < 0, over the integrator's own steps
  where it reports them (``Trajectory.contact``), else over the output samples;
* ``complementarity_max``: the worst residual |min(P_N D_NN, U_N+ + e U_N-)| of the
  contact problems solved, relative to the normal velocities they changed, and for
  spatial contacts the worst of Coulomb's disc (its natural map, docs/nonsmooth.md)
  relative to the slip speeds they changed (NaN: the method solves none, e.g. a
  compliant contact);
* ``n_events``: the impacts and stick/slip switches the method reported;
* ``event_time_err_max`` (s): the largest distance from a reference event (the problem's
  ``contact_events()``) reached by the run to the nearest event of the run;
* ``energy_balance_err``: max over samples of |(E - E0) - (E_ref - E_ref0)| / E_scale, the
  energy the run lost against what the restitution and friction laws take
  (``reference_energy(times)``), E_scale the larger of the energy those laws take over
  the run and the largest kinetic energy reached.

The run's time series gets ``penetration`` (m): the deepest penetration at each output
sample (:func:`penetration_series`; a contact model's series only), drawn in the recording.

Warnings (so ``ok`` means nothing is wrong): penetration over PENETRATION_LIMIT of the
model's length scale; complementarity over COMPLEMENTARITY_LIMIT; a reference event missed
or misplaced by more than EVENT_TIME_LIMIT of the time span; energy off by more than
ENERGY_LIMIT of its scale.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

PENETRATION_LIMIT = 1e-2  # of the length scale
COMPLEMENTARITY_LIMIT = 1e-6
EVENT_TIME_LIMIT = 1e-2  # of the time span
ENERGY_LIMIT = 5e-2  # of the energy scale

CONTACT_COLUMNS = (
    "penetration_max",
    "complementarity_max",
    "n_events",
    "event_time_err_max",
    "energy_balance_err",
)


def penetration_series(equations: Any, times: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The deepest penetration max(0, -g_N) (m) over the contacts at each sample (n,); an
    empty array without contacts. The row's time series ``penetration``."""
    contacts = getattr(equations, "contacts", None)
    if contacts is None:
        return np.zeros(0)
    nq = equations.nq
    samples = zip(np.asarray(times, dtype=float), np.atleast_2d(y), strict=False)
    gaps = [contacts.gaps(t, s[:nq])[0].reshape(-1) for t, s in samples]
    return np.array([max(0.0, float(np.max(-g, initial=0.0))) for g in gaps])


def contact_metrics(
    problem: Any,
    equations: Any,
    times: np.ndarray,
    y: np.ndarray,
    own: dict[str, Any] | None,
    energy: np.ndarray,
    length: float,
) -> tuple[dict[str, float], list[str]]:
    """The contact columns of a row and its warnings; NaN columns without contacts.

    ``times`` (n,), ``y`` (n, >= nq): the output samples reached; ``own``: what the
    integrator measured itself (``Trajectory.contact``); ``energy`` (n, 2): kinetic and
    potential energy at the samples; ``length``: the model's length scale (m).
    """
    row = dict.fromkeys(CONTACT_COLUMNS, math.nan)
    contacts = getattr(equations, "contacts", None)
    if contacts is None:
        return row, []
    times = np.asarray(times, dtype=float)
    y = np.atleast_2d(y)[: len(times)]
    own = own or {}
    depth = penetration_series(equations, times, y)
    sampled = float(np.max(depth, initial=0.0)) if depth.size else math.nan
    row["penetration_max"] = max(sampled, float(own.get("penetration_max", 0.0)))
    row["complementarity_max"] = float(own.get("complementarity_max", math.nan))
    events = np.sort(np.asarray(own.get("event_times", []), dtype=float))
    row["n_events"] = float(len(events)) if "event_times" in own else math.nan
    warnings = []
    span = float(problem.t_end - problem.t_start)
    reference_events = getattr(problem, "contact_events", None)
    if reference_events is not None and len(times):
        expected = np.asarray(reference_events(), dtype=float)
        expected = expected[expected <= times[-1]]
        if expected.size:
            nearest = (
                np.min(np.abs(expected[:, None] - events[None, :]), axis=1)
                if events.size
                else np.full(expected.size, math.inf)
            )
            row["event_time_err_max"] = float(np.max(nearest))
            if row["event_time_err_max"] > EVENT_TIME_LIMIT * span:
                warnings.append(
                    f"contact events off the reference by up to {row['event_time_err_max']:.3g} s"
                )
        else:
            row["event_time_err_max"] = 0.0
    reference_energy = getattr(problem, "reference_energy", None)
    if reference_energy is not None and len(times) and len(energy):
        total = np.asarray(energy, dtype=float).sum(axis=1)[: len(times)]
        expected_energy = np.asarray(reference_energy(times[: len(total)]), dtype=float)
        kinetic = float(np.max(np.asarray(energy)[:, 0]))
        scale = max(float(np.ptp(expected_energy)), kinetic, 1e-12)
        lost = (total - total[0]) - (expected_energy - expected_energy[0])
        row["energy_balance_err"] = float(np.max(np.abs(lost)) / scale)
        if row["energy_balance_err"] > ENERGY_LIMIT:
            warnings.append(
                f"energy off the restitution/friction laws by {row['energy_balance_err']:.3g} "
                "of its scale"
            )
    if row["penetration_max"] > PENETRATION_LIMIT * length:
        warnings.append(f"penetration {row['penetration_max']:.3g} m")
    if row["complementarity_max"] > COMPLEMENTARITY_LIMIT:
        warnings.append(f"complementarity residual {row['complementarity_max']:.3g}")
    return row, warnings
