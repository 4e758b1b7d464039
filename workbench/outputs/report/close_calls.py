"""Which runs a sweep times again after its runs (:mod:`workbench.runs.retime`): those
its decisions hinge on.

For each problem and each accuracy target a report may show
(:data:`~workbench.outputs.report.decision.FALLBACK_TARGETS`), the trusted pairs whose
cost is within :data:`CLOSE` times the cheapest's: the run of each that the ranking
prices (:func:`~workbench.outputs.report.ranking.pair_costs`;
:data:`~workbench.outputs.report.ranking.CLOSE` says why 3x).
"""

from __future__ import annotations

import pandas as pd

from workbench.outputs.report.analysis import prepare_results
from workbench.outputs.report.decision import FALLBACK_TARGETS
from workbench.outputs.report.ranking import CLOSE, pair_costs, sampled_cost

__all__ = ["CLOSE", "close_calls", "retime_note"]


def close_calls(
    rows: pd.DataFrame, cost: str = "integrate_cpu_s", close: float = CLOSE
) -> list[str]:
    """The run ids of ``rows`` (a results table) that some decision hinges on: each a
    pair's priced run within ``close`` times a cell's cheapest, in a cell of two such
    pairs at least."""
    if rows.empty:
        return []
    runs = prepare_results(rows)
    chosen: dict[str, None] = {}
    for _problem, group in runs.groupby("problem", sort=False):
        for target in FALLBACK_TARGETS:
            ranked = pair_costs(group, target, cost)
            if len(ranked) < 2:
                continue
            near = ranked[ranked[cost] <= close * ranked[cost].iloc[0]]
            if len(near) > 1:
                chosen.update(dict.fromkeys(near["run_id"]))
    return list(chosen)


def retime_note(runs: pd.DataFrame, cost: str) -> str:
    """What the first screen says of the close calls' timing ('' for a counted cost):
    how many were timed again at moments apart, or that none were, so that a reader
    knows how far a small margin can be trusted."""
    if not sampled_cost(cost):
        return ""
    retimed = pd.to_numeric(runs.get("retimed", pd.Series(dtype=float)), errors="coerce")
    again = retimed[retimed > 0]
    if len(again):
        return (
            f"{len(again)} close call(s), the runs of pairs within {CLOSE:g}x of a cheapest, "
            f"were timed again after the runs, {int(again.max())} times at moments apart "
            "(their cost is the median over these samples and their own); those whose "
            "samples exceed the repeat budget were not, and a margin resting on one says "
            "'not timed again'"
        )
    return (
        "No run was timed again after the runs (`--retime 0`, a Dask sweep, or rows of an "
        "older workbench): each interval is its run's back-to-back samples, which share "
        "the machine's moment, so a margin of a few tens of per cent may not survive a "
        "second sweep (docs/suites.md)"
    )

