"""The one ranking of pairs the report, ``workbench results`` and the LaTeX tables share:
for a problem and a target accuracy, the cheapest trusted pair, the pairs tied with it,
and how far ahead it is of the runner-up, the cheapest pair not tied with it.

A pair's cost at a target is that of its cheapest trusted run (status ``ok``, no audit
warning, finite scd and cost) whose scd reaches the target. Each timed cost has an
interval, the least and greatest of the run's timed samples (:func:`cost_interval`; for
a run timed again at moments apart, the least and the median);
pairs whose intervals overlap the winner's are **tied** with it: the timings cannot tell
them apart, so the report names them all rather than one winner by noise. Rows without
an interval (one sample, or written before intervals were recorded) cannot be told tied;
the decision then says so (``tie_known`` False). A margin under :data:`CLOSE` resting on
a run the sweep did not time again at moments apart (``retimed`` 0: over the repeat
budget, or ``--retime 0``) says so too (``timed_apart`` False): back-to-back samples share
the machine's moment, so such a margin may not survive a second sweep.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from workbench.outputs.report.tables import times_text
from workbench.outputs.report.trust import ok_runs, warned

NOT_REACHED = "none reached"
NOT_TIMED = "not timed again: may not hold"
CLOSE = 3.0
"""A pair within this many times a cheapest's cost is a close call: a run's back-to-back
samples, taken in a slow spell of a shared machine, read up to about 1.7x its usual cost
(5-95 % on a KVM Xeon: docs/performance.md), so a pair 3x behind cannot be one."""
NOT_TIMED_NOTE = (
    f"'{NOT_TIMED}': a margin under {CLOSE:g}x whose runs were not timed again after the "
    "runs (over the repeat budget, or --retime 0); their samples were taken back to back, "
    "in one moment of the machine, so it may not survive a second sweep"
)
"""What a caption or the "why" says of a verdict that carries :data:`NOT_TIMED`."""


def sampled_cost(cost: str) -> bool:
    """Whether ``cost`` is read from timed samples (CPU or wall seconds), which a second
    sweep may not reproduce and the sweep times again; not counted work or counts."""
    return cost.endswith("_s") and cost != "work_s"


def cost_interval(runs: pd.DataFrame, cost: str) -> tuple[pd.Series, pd.Series]:
    """The least and greatest value of ``cost`` over each run's timed samples.

    ``<cost>_min`` / ``<cost>_max`` where the rows carry them (``integrate_cpu_s_min``,
    ``integrate_s_min``); for CPU time without its own, the wall-time interval scaled by
    CPU / wall time; a counted cost (``n_rhs``) is exact (its interval is the value). A run
    timed again at moments apart (``retimed`` > 0, :mod:`workbench.runs.retime`): from the
    least to the median, its greatest being a slow spell's (pairs a few per cent apart
    then agree from sweep to sweep: docs/performance.md).
    NaN where unknown, and for runs timed once (a single sample has no spread).
    """
    value = pd.to_numeric(runs[cost], errors="coerce") if cost in runs else None
    nan = pd.Series(np.nan, index=runs.index)
    if value is None:
        return nan, nan
    if not cost.endswith("_s"):  # a count: no noise
        return value, value
    low, high = _column(runs, f"{cost}_min"), _column(runs, f"{cost}_max")
    if cost == "integrate_cpu_s":
        scale = value / _column(runs, "integrate_s")
        low = low.fillna(_column(runs, "integrate_s_min") * scale)
        high = high.fillna(_column(runs, "integrate_s_max") * scale)
    if cost == "work_s":  # its interval comes from the unit costs' batches, not repeats
        return low, high
    once = _column(runs, "repeats") < 2
    # timed again at moments apart (workbench.runs.retime): from the least sample, which a
    # slow spell did not reach, to the median; the greatest is a slow spell's
    retimed = _column(runs, "retimed") > 0
    high = high.mask(retimed, np.minimum(high, value))
    return low.mask(once), high.mask(once)


def _column(runs: pd.DataFrame, name: str) -> pd.Series:
    if name not in runs:
        return pd.Series(np.nan, index=runs.index)
    return pd.to_numeric(runs[name], errors="coerce")


def pair_costs(runs: pd.DataFrame, target: float, cost: str) -> pd.DataFrame:
    """One problem's pairs that reach scd >= ``target`` with a trusted run, cheapest
    first: the run (``run_id``, rtol, scd, errors, n_rhs), its ``cost`` and interval
    (``low``, ``high``)."""
    trusted = ok_runs(runs[~warned(runs)])
    if cost not in trusted:
        return trusted.iloc[:0].assign(low=np.nan, high=np.nan)
    values = pd.to_numeric(trusted[cost], errors="coerce")
    keep = np.isfinite(trusted["scd"]) & np.isfinite(values) & (trusted["scd"] >= target)
    reached = trusted[keep]
    low, high = cost_interval(reached, cost)
    reached = reached.assign(low=low, high=high)
    best = reached.sort_values([cost, "rtol"], kind="stable").drop_duplicates("pair")
    return best.reset_index(drop=True)


@dataclass
class Decision:
    """The answer for one problem at one target accuracy.

    pair: the cheapest pair (None: no trusted run reached the target); cost, low, high:
    its cost and interval; tied: the pairs (the cheapest first) indistinguishable from
    it by their intervals, itself included when any other is; runner_up, runner_cost:
    the cheapest pair not tied with it (without a tie, the next cheapest; a pair named
    beside "tie" is never one of the tied ones); margin: runner_cost / cost (NaN: no
    runner-up); tie_known: the intervals needed to tell ties were there; timed_apart:
    False when the margin is under :data:`CLOSE` and the winner's or runner-up's run was
    not timed again at moments apart (``retimed`` 0).
    """

    problem: str
    target: float
    pair: str | None = None
    cost: float = np.nan
    low: float = np.nan
    high: float = np.nan
    rtol: float = np.nan
    scd: float = np.nan
    runner_up: str = ""
    runner_cost: float = np.nan
    margin: float = np.nan
    tied: list[str] = field(default_factory=list)
    tie_known: bool = True
    timed_apart: bool = True
    run: pd.Series | None = None

    @property
    def is_tie(self) -> bool:
        return len(self.tied) > 1

    def verdict(self) -> str:
        """'tie', 'only pair', '1.8x ahead', '1.8x ahead (one sample: tie unknown)',
        '1.8x ahead (not timed again: may not hold)' or 'none reached'."""
        if self.pair is None:
            return NOT_REACHED
        if self.is_tie:
            return "tie"
        if not self.runner_up:
            return "only pair"
        ahead = f"{times_text(self.margin)} ahead"
        if not self.tie_known:
            return f"{ahead} (one sample: tie unknown)"
        return ahead if self.timed_apart else f"{ahead} ({NOT_TIMED})"

    def ahead_of(self) -> str:
        """:meth:`verdict` naming the runner-up before its caveat: '1.8x ahead of B (one
        sample: tie unknown)' ('1.093x ahead (not timed again: may not hold) of B' read as
        if the caveat were B's); the verdict alone without a runner-up, or in a tie."""
        verdict = self.verdict()
        if not self.runner_up or self.is_tie:
            return verdict
        head, caveat, rest = verdict.partition(" (")
        return f"{head} of {self.runner_up}" + (f" ({rest}" if caveat else "")


def decide(runs: pd.DataFrame, target: float, cost: str) -> Decision:
    """The :class:`Decision` for ``runs`` (one problem's, prepared) at ``target``."""
    problem = str(runs["problem"].iloc[0]) if len(runs) else ""
    ranked = pair_costs(runs, target, cost)
    if ranked.empty:
        return Decision(problem, target)
    best = ranked.iloc[0]
    decision = Decision(
        problem,
        target,
        pair=str(best["pair"]),
        cost=float(best[cost]),
        low=float(best["low"]),
        high=float(best["high"]),
        rtol=float(best["rtol"]),
        scd=float(best["scd"]),
        run=best,
    )
    if len(ranked) < 2:
        return decision
    # A pair is tied when its interval reaches down into the winner's (costs are sorted).
    known = np.isfinite(ranked["low"]) & np.isfinite(ranked["high"])
    decision.tie_known = bool(known.iloc[0] and known.iloc[1])
    overlapping = known & known.iloc[0] & (ranked["low"] <= decision.high)
    overlapping |= ranked[cost] == decision.cost  # equal costs tie, interval or not
    tied = ranked[overlapping]
    decision.tied = [str(p) for p in tied["pair"]] if len(tied) > 1 else []
    # The runner-up is the cheapest pair not tied: the next cheapest may be tied, or be
    # apart (a narrow interval above the winner's) while a dearer, wider one is tied.
    apart = ranked[~overlapping]
    if apart.empty:  # every pair that reached the target is tied
        return decision
    runner = apart.iloc[0]
    decision.runner_up, decision.runner_cost = str(runner["pair"]), float(runner[cost])
    decision.margin = decision.runner_cost / decision.cost if decision.cost > 0 else np.nan
    if sampled_cost(cost) and decision.margin < CLOSE:
        # a close call priced from back-to-back samples alone (workbench.runs.retime)
        retimed = _column(ranked.loc[[0, runner.name]], "retimed")
        decision.timed_apart = not bool((retimed == 0).any())
    return decision


def decisions(runs: pd.DataFrame, targets: Sequence[float], cost: str) -> list[Decision]:
    """A :class:`Decision` for every problem (in order of appearance) and target."""
    return [
        decide(group, float(target), cost)
        for _problem, group in runs.groupby("problem", sort=False)
        for target in targets
    ]


def cheapest_table(runs: pd.DataFrame, targets: Sequence[float], cost: str) -> pd.DataFrame:
    """One row a problem and target: the cheapest pair and its run, its cost, the
    runner-up (the cheapest pair not tied) and margin, and the tie (the per-problem
    cheapest-pair table)."""
    rows = []
    for d in decisions(runs, targets, cost):
        row = {"problem": d.problem, "target scd": d.target, "pair": d.pair or NOT_REACHED}
        if d.run is not None:
            row |= {k: d.run[k] for k in ("rtol", "scd", "err_l2", "err_max", cost, "n_rhs")}
        row |= {"runner-up": d.runner_up, "margin": d.margin, "verdict": d.verdict()}
        row["tied pairs"] = ", ".join(d.tied)
        rows.append(row)
    run_columns = ["rtol", "scd", "err_l2", "err_max", *dict.fromkeys([cost, "n_rhs"])]
    columns = ["problem", "target scd", "pair", *run_columns]
    columns += ["runner-up", "margin", "verdict", "tied pairs"]
    return pd.DataFrame(rows, columns=columns)
