"""Timing a run's integration so that a reader can trust its cost.

One wall-time sample of a short integration on a busy machine says little: another
process may have held the core. :func:`integrate_repeated` times the same integration
(same inputs) several times and keeps the first trajectory; the row carries the median
and the spread of the wall-time samples (``integrate_s``, ``integrate_s_min``,
``integrate_s_max``), the median and the spread of the CPU-time samples
(``integrate_cpu_s``, ``integrate_cpu_s_min``, ``integrate_cpu_s_max``: the interval within
which two pairs are called a tie), how many samples were taken (``repeats``), and
what the machine was doing: the 1-minute load average when the run started (``load_avg``)
and the worker processes of the sweep (``workers``), from which a report tells whether the
workers had an idle core each (:func:`oversubscribed`).

The policy (:class:`Timing`): at most ``repeats`` samples, and another only while the
samples so far plus one more of the same length stay within ``repeat_budget`` seconds of
*CPU time*: short integrations (where the noise is largest) are repeated, long ones are
timed once, so repeating costs a sweep at most about ``repeat_budget`` a run. The budget
counts CPU time, not wall time, so that a busy machine (where a sample waits for a core)
does not take the repeats away exactly when they are needed: with the defaults (3 samples,
3 s) every integration under 1 s of CPU gets its 3 samples, on an idle machine or a loaded
one. One-off costs (build, compile, initial state, reference) are never in the samples:
they have their own columns.

Back-to-back samples share their moment: on a shared machine a slow second slows all of
them, so they agree with each other far better than with a second sweep. The runs a
report's decisions hinge on are therefore timed again after the runs, at moments apart
(:mod:`workbench.runs.retime`, :func:`retimed_columns`).

A repeat that does not reproduce the first one's statistics (steps, evaluations) or
trajectory is reported as a warning: the integrator is not deterministic, and its samples
did not time the same work.
"""

from __future__ import annotations

import math
import os
import statistics
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from workbench.errors import ConfigError

DEFAULT_REPEATS = 3
DEFAULT_REPEAT_BUDGET = 3.0  # CPU s of integration a run may spend on its samples
MAX_REPEATS = 1000
DEFAULT_RETIME = 5  # times a sweep's close calls are timed again (workbench.runs.retime)
MAX_RETIME = 100

# the row columns this module fills (see workbench.execution.row_schema.SCHEMA)
TIMING_COLUMNS = (
    "integrate_s",
    "integrate_s_min",
    "integrate_s_max",
    "integrate_cpu_s",
    "repeats",
    "integrate_cpu_s_min",
    "integrate_cpu_s_max",
    "load_avg",
    "workers",
    "retimed",  # (filled by retimed_columns, after the runs)
)
SAMPLE_COLUMNS = TIMING_COLUMNS[:7]  # the ones the samples give (not load_avg, workers...)
STAT_FIELDS = ("n_rhs", "n_jac", "n_steps", "n_rejected", "n_lu", "n_newton")


@dataclass(frozen=True)
class Timing:
    """How a run's integration is timed, and by how many workers of its sweep.

    repeats: the most samples (>= 1); repeat_budget: CPU seconds of integration (the
    samples so far plus one more of the last one's length) beyond which no more are taken;
    workers: worker processes running runs at the same time (1 for ``workbench run``).
    """

    repeats: int = DEFAULT_REPEATS
    repeat_budget: float = DEFAULT_REPEAT_BUDGET
    workers: int = 1

    def __post_init__(self) -> None:
        check_repeats(self.repeats, "repeats")
        check_budget(self.repeat_budget, "repeat_budget")
        if not (isinstance(self.workers, int) and self.workers >= 1):
            raise ConfigError(f"workers must be an integer >= 1, not {self.workers!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None) -> Timing:
        return cls(**(data or {}))


def _whole_problem(value: Any, low: int, high: int, meaning: str) -> str | None:
    """What is wrong with ``value`` as a whole number from ``low`` to ``high``, or None."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        return f"must be an integer from {low} to {high} ({meaning}), not {value!r}"
    return None


def repeats_problem(value: Any) -> str | None:
    """What is wrong with ``value`` as a count of timed samples, or None."""
    meaning = "timed samples of the integration; 1: time it once"
    return _whole_problem(value, 1, MAX_REPEATS, meaning)


def retime_problem(value: Any) -> str | None:
    """What is wrong with ``value`` as the rounds of :mod:`workbench.runs.retime`, or None."""
    meaning = "times each close call is timed again after the runs, at moments apart; 0: not at all"
    return _whole_problem(value, 0, MAX_RETIME, meaning)


def budget_problem(value: Any) -> str | None:
    """What is wrong with ``value`` as a repeat budget in seconds, or None."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if not (number and math.isfinite(value) and value >= 0):
        return (
            "must be a finite number of seconds >= 0 (integration CPU time a run may spend on "
            f"repeated samples; 0: time it once), not {value!r}"
        )
    return None


def check_repeats(value: Any, key: str = "repeats") -> int:
    """``value`` as a count of samples; ConfigError naming ``key`` otherwise."""
    problem = repeats_problem(value)
    if problem:
        raise ConfigError(f"{key} {problem}")
    return value


def check_budget(value: Any, key: str = "repeat_budget") -> float:
    """``value`` as seconds >= 0; ConfigError naming ``key`` otherwise."""
    problem = budget_problem(value)
    if problem:
        raise ConfigError(f"{key} {problem}")
    return float(value)


@dataclass
class Samples:
    """Wall and CPU seconds of each timed integration, and what differed between them."""

    wall: list[float]
    cpu: list[float]
    difference: str = ""

    def columns(self) -> dict[str, float]:
        """The timing columns of a row (NaN when nothing was timed)."""
        if not self.wall:
            return dict.fromkeys(SAMPLE_COLUMNS, math.nan)
        return {
            "integrate_s": statistics.median(self.wall),
            "integrate_s_min": min(self.wall),
            "integrate_s_max": max(self.wall),
            "integrate_cpu_s": statistics.median(self.cpu),
            "repeats": len(self.wall),
            "integrate_cpu_s_min": min(self.cpu),
            "integrate_cpu_s_max": max(self.cpu),
        }


def integrate_repeated(
    solve: Callable[[], Any], timing: Timing, timed: Callable[[Callable[[], Any]], Any]
) -> tuple[Any, Samples]:
    """(the first trajectory, the samples) of ``solve()`` repeated as ``timing`` allows.

    ``timed(solve)`` runs ``solve`` and returns (result, wall seconds, CPU seconds) with
    one-off costs (C compilation) already taken out. A failed integration is not
    repeated; a repeat that differs from the first stops the repeats."""
    first, wall, cpu = timed(solve)
    samples = Samples([wall], [cpu])
    while (
        getattr(first, "success", False)
        and len(samples.wall) < timing.repeats
        and sum(samples.cpu) + samples.cpu[-1] <= timing.repeat_budget
    ):
        again, wall, cpu = timed(solve)
        samples.wall.append(wall)
        samples.cpu.append(cpu)
        samples.difference = trajectory_difference(first, again)
        if samples.difference:
            samples.difference = f"repeat {len(samples.wall)}: {samples.difference}"
            break
    return first, samples


def trajectory_difference(first: Any, again: Any) -> str:
    """What differs between two integrations of the same inputs ('' if nothing)."""
    differ = [
        f"{name} {getattr(first.stats, name)} then {getattr(again.stats, name)}"
        for name in STAT_FIELDS
        if getattr(first.stats, name, None) != getattr(again.stats, name, None)
    ]
    if differ:
        return "statistics differ (" + ", ".join(differ) + ")"
    a, b = np.asarray(first.y), np.asarray(again.y)
    if a.shape != b.shape or not np.array_equal(a, b, equal_nan=True):
        return "trajectories differ"
    return ""


def machine_load() -> float:
    """The 1-minute load average (NaN where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return math.nan


def oversubscribed(load_avg: Any, workers: Any, cpu_count: Any) -> bool:
    """Did the sweep run more workers than the machine had idle cores?

    The load average counts the sweep's own workers once they have run a while, so the
    others' load is ``load_avg - workers`` (at least 0) and the idle cores
    ``cpu_count - others``. Unknown values (NaN) answer False: nothing was seen."""
    try:
        load, jobs, cores = float(load_avg), float(workers), float(cpu_count)
    except (TypeError, ValueError):
        return False
    if not all(math.isfinite(v) for v in (load, jobs, cores)):
        return False
    idle = cores - max(0.0, load - jobs)
    return jobs > idle


def retimed_columns(row: dict[str, Any], wall: list[float], cpu: list[float]) -> dict[str, Any]:
    """``row``'s timing columns with ``wall`` and ``cpu``: more samples of the same
    integration, each taken at another moment (:mod:`workbench.runs.retime`).

    The row's own samples were taken back to back and share their moment (a slow second
    of a shared machine slows them all), so they count as one sample, their median. The
    medians are then over that and the new samples; least and greatest over every sample;
    ``repeats`` counts every sample, ``retimed`` the new ones."""
    columns: dict[str, Any] = {}
    for median_column, new in (("integrate_s", wall), ("integrate_cpu_s", cpu)):
        own = [row.get(f"{median_column}{end}") for end in ("", "_min", "_max")]
        known = [float(v) for v in own if _finite(v)]
        medians = [float(own[0])] if _finite(own[0]) else []
        columns[median_column] = statistics.median([*medians, *new])
        columns[f"{median_column}_min"] = min([*known, *new])
        columns[f"{median_column}_max"] = max([*known, *new])
    repeats = row.get("repeats")
    columns["repeats"] = (int(repeats) if _finite(repeats) else 1) + len(cpu)
    columns["retimed"] = len(cpu)
    return columns


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
