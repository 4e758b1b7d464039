"""The cost measure of a report: what a work-precision point, the cheapest pair, the
Pareto fronts and the recommendation count as a run's cost.

Selectable (``workbench report --cost``, :data:`COST_MEASURES`):

- ``integrate_cpu`` (the default): CPU seconds of the integration, the median of its
  timed samples (``integrate_cpu_s``, :mod:`workbench.execution.timing`). Chosen because the
  workbench runs on shared machines: wall time also counts the time a worker waited for
  a core while other processes ran, CPU time mostly not; and the median of several
  samples is steadier than one;
- ``integrate_wall``: wall seconds of the integration, the median of its samples
  (``integrate_s``): what a user waits for on an idle machine;
- ``n_rhs``: right-hand-side evaluations: independent of the machine, blind to the cost
  of each evaluation (Jacobians, linear solves);
- ``work``: counted work (``work_s``, :mod:`workbench.execution.counted_work`): the counts of
  right-hand sides, Jacobians and LU factorizations weighted by their unit CPU costs,
  timed in short batches: moves little with the machine's load, but leaves out the
  integrator's own work between evaluations (step control, a Python loop).

One-off costs (building the equations, compiling C, the consistent initial state, the
reference) are never in any of them: they have their own columns. Rows written before the
integration's CPU time was recorded (schema < 7) have it NaN; then the default falls back
to the integration's wall time, and says so (:class:`Cost` ``note``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from workbench.errors import ConfigError

# key -> (column, label with unit)
COST_MEASURES: dict[str, tuple[str, str]] = {
    "integrate_cpu": ("integrate_cpu_s", "integration CPU time [s]"),
    "integrate_wall": ("integrate_s", "integration wall time [s]"),
    "n_rhs": ("n_rhs", "rhs evaluations [-]"),
    "work": ("work_s", "counted work [s]"),
}
DEFAULT_COST = "integrate_cpu"
# what the default falls back to, in order, for rows that lack the default's column
FALLBACKS = ("integrate_wall",)
LEGACY_COLUMN, LEGACY_LABEL = "wall_s", "wall time [s]"  # of the whole run, build included
# cost column -> its label with unit
COST_LABELS: dict[str, str] = {LEGACY_COLUMN: LEGACY_LABEL} | dict(COST_MEASURES.values())


@dataclass(frozen=True)
class Cost:
    """The cost measure in force: its key, the row column and the label with unit;
    ``note`` says why it is not the one asked for ('' when it is)."""

    key: str
    column: str
    label: str
    note: str = ""

    @property
    def name(self) -> str:
        """The label without its unit, e.g. 'integration CPU time'."""
        return self.label.split(" [")[0]

    def statement(self) -> str:
        """One sentence for a caption: the measure and, if any, why it was chosen."""
        text = f"cost measure: {self.name} (median of the timed samples)"
        if self.key == "n_rhs":
            text = f"cost measure: {self.name}"
        if self.key == "work":
            text = (
                "cost measure: counted work (evaluations and factorizations weighted by "
                "their unit CPU costs; the integrator's own work left out)"
            )
        return text + (f"; {self.note}" if self.note else "")


def tie_rule(column: str) -> str:
    """When two pairs tie in the cost ``column``: a clause for captions and the page
    (:mod:`workbench.outputs.report.ranking` compares the runs' cost intervals)."""
    if column == "n_rhs":  # a count has no spread: its interval is the count itself
        return "their right-hand-side counts are equal"
    if column == "work_s":
        return "their counted work's intervals (from the unit costs' timed batches) overlap"
    return (
        "their timed samples' ranges overlap (for a close call timed again after the runs, "
        "at moments apart: from its least sample to its median)"
    )


def check_cost(key: str | None) -> str | None:
    """``key`` if it names a cost measure (None: the default); ConfigError otherwise."""
    if key is not None and key not in COST_MEASURES:
        raise ConfigError(
            f"unknown cost measure {key!r}: give one of {', '.join(COST_MEASURES)} "
            f"(default {DEFAULT_COST})"
        )
    return key


def resolve_cost(runs: pd.DataFrame, key: str | None = None) -> Cost:
    """The cost measure for ``runs``: ``key`` (checked), or the default; the default
    falls back (stated in ``note``) when no ok row has a value of its column."""
    key = check_cost(key)
    if key is not None:
        column, label = COST_MEASURES[key]
        return Cost(key, column, label)
    for candidate in (DEFAULT_COST, *FALLBACKS):
        column, label = COST_MEASURES[candidate]
        if _measured(runs, column):
            note = (
                ""
                if candidate == DEFAULT_COST
                else (
                    f"the rows carry no {COST_MEASURES[DEFAULT_COST][1].split(' [')[0]} "
                    "(written before schema 7)"
                )
            )
            return Cost(candidate, column, label, note)
    return Cost(
        "wall",
        LEGACY_COLUMN,
        LEGACY_LABEL,
        "the rows carry no integration time: the whole run's wall time is used",
    )


def _measured(runs: pd.DataFrame, column: str) -> bool:
    if column not in runs:
        return False
    ok = runs[runs["status"] == "ok"] if "status" in runs else runs
    values = pd.to_numeric(ok[column], errors="coerce")
    return bool(np.isfinite(values).any())


__all__ = [
    "COST_LABELS",
    "COST_MEASURES",
    "DEFAULT_COST",
    "Cost",
    "check_cost",
    "resolve_cost",
    "tie_rule",
]
