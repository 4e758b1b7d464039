"""The report's overview: which pair to use, computed from the runs.

Three views, all on the trustworthy runs only (status ``ok`` and no audit warning; a run
with warnings may be wrong, so it never counts as reaching an accuracy):

* the Pareto front of each problem: the runs no other run beats on both cost and scd
  (a run is dominated when another costs no more and has no fewer correct digits, and is
  strictly better in one of the two);
* the cost of each pair at a fixed accuracy: its least cost among runs with scd >= target,
  divided by the least cost of any pair on that problem (1 = the best; NaN = never reached);
* a recommendation: the pair within ``factor`` of the best on the most problems at that
  target (ties broken by the geometric mean of its cost ratios over the problems it reached).

The target is chosen from the data (:func:`overview_target`): the highest of
:data:`OVERVIEW_TARGETS` that trustworthy runs reach on at least two thirds of the problems
(:data:`COVERAGE`), so the recommendation speaks for most of the catalog.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from workbench.outputs.report.analysis import ok_runs, warned
from workbench.outputs.report.cost import COST_LABELS
from workbench.outputs.report.ranking import decide
from workbench.outputs.report.tables import times_text

OVERVIEW_TARGETS: tuple[float, ...] = (10.0, 8.0, 6.0, 4.0, 2.0)
COST_COLUMNS: dict[str, str] = COST_LABELS  # cost column -> label (report.cost)
WITHIN_FACTOR = 2.0
COVERAGE = 2 / 3  # of the problems that must reach the overview's target


def trusted(runs: pd.DataFrame, cost: str = "wall_s") -> pd.DataFrame:
    """Ok runs without warnings whose scd and ``cost`` are finite (cost > 0)."""
    ok = ok_runs(runs[~warned(runs)])
    return ok[np.isfinite(ok["scd"]) & np.isfinite(ok[cost]) & (ok[cost] > 0)]


def pareto_mask(runs: pd.DataFrame, cost: str = "wall_s") -> pd.Series:
    """True for the rows of ``runs`` (one problem's) on the Pareto front of cost against scd;
    False for every other row, including the untrusted ones (:func:`trusted`)."""
    candidates = trusted(runs, cost)
    mask = pd.Series(False, index=runs.index)
    if len(candidates):
        front = ~_dominated(candidates[cost].to_numpy(float), candidates["scd"].to_numpy(float))
        mask[candidates.index] = front
    return mask


def _dominated(costs: np.ndarray, digits: np.ndarray) -> np.ndarray:
    """True where another point costs no more and has no fewer digits, and is better in
    one (finite values). Sorted by cost: a point is dominated by a cheaper one with as
    many digits, or by one of its own cost with more; O(n log n), where comparing every
    pair took 0.6 s of a 3,000-run report's CPU, 0.2 s at 1,000 runs (py-spy;
    docs/performance.md)."""
    order = np.argsort(costs, kind="stable")
    c, d = costs[order], digits[order]
    starts = np.flatnonzero(np.r_[True, c[1:] != c[:-1]])  # groups of equal cost
    group = np.repeat(np.arange(starts.size), np.diff(np.r_[starts, c.size]))
    most = np.maximum.reduceat(d, starts)  # the most digits at each cost
    cheaper = np.r_[-np.inf, np.maximum.accumulate(most)[:-1]][group]
    beaten = ((group > 0) & (cheaper >= d)) | (most[group] > d)
    dominated = np.empty(c.size, dtype=bool)
    dominated[order] = beaten
    return dominated


def cost_at_target(runs: pd.DataFrame, target: float, cost: str = "wall_s") -> pd.DataFrame:
    """Problem x pair table of the least ``cost`` among trusted runs with scd >= ``target``
    (NaN where a pair never reached it)."""
    reached = trusted(runs, cost)
    reached = reached[reached["scd"] >= target]
    problems = list(dict.fromkeys(runs["problem"]))
    pairs = sorted(runs["pair"].unique())
    least = reached.groupby(["problem", "pair"])[cost].min().unstack("pair")
    return least.reindex(index=problems, columns=pairs).rename_axis(index="problem", columns=None)


NOT_REACHED = "not reached"
SKIPPED = "skipped"
NOT_RUN = "not run"
UNREACHED_MEANING: dict[str, str] = {
    NOT_REACHED: "the pair ran but did not reach the target without warnings",
    SKIPPED: "every run of the pair on the problem was skipped, not supported (the status "
    "table gives the reason)",
    NOT_RUN: "the sweep has no run of the pair on the problem",
}
"""What a cell of the cost-at-target table without a value means, by its reason
(:func:`unreached_reasons`), for captions."""


def unreached_reasons(runs: pd.DataFrame, costs: pd.DataFrame) -> pd.DataFrame:
    """Why a cell of ``costs`` (problem x pair, :func:`cost_at_target` or its ratio) has no
    value: :data:`SKIPPED` when every run of the pair on the problem has status
    ``skipped`` (it does not support the problem: a pair that never ran did not fall short
    of the target), :data:`NOT_RUN` when the pair has no run on it, :data:`NOT_REACHED`
    otherwise; '' where the cell has a value."""
    groups = runs.groupby(["problem", "pair"], sort=False)["status"]
    skipped = groups.agg(lambda status: bool((status == "skipped").all())).unstack("pair")
    skipped = skipped.reindex(index=costs.index, columns=costs.columns)
    reasons = pd.DataFrame(NOT_REACHED, index=costs.index, columns=costs.columns, dtype=object)
    reasons = reasons.mask(skipped.isna(), NOT_RUN)
    reasons = reasons.mask(skipped.fillna(False).astype(bool), SKIPPED)
    return reasons.where(costs.isna(), "")


def cost_ratio(costs: pd.DataFrame) -> pd.DataFrame:
    """``costs`` divided by each problem's least cost (rows with no value stay NaN)."""
    return costs.div(costs.min(axis=1), axis=0)


def overview_target(runs: pd.DataFrame, targets: Sequence[float] = OVERVIEW_TARGETS) -> float:
    """The highest target scd that trusted runs reach on at least :data:`COVERAGE` of the
    problems (the lowest of ``targets`` when none is)."""
    problems = runs["problem"].nunique()
    reached = trusted(runs)
    best = reached.groupby("problem")["scd"].max()
    for target in sorted(targets, reverse=True):
        if problems and (best >= target).sum() >= COVERAGE * problems - 1e-9:
            return float(target)
    return float(min(targets))


@dataclass
class Recommendation:
    """The pair to use at a target accuracy, and how it compares on every problem."""

    target: float
    cost: str
    factor: float
    pair: str | None  # None: no trusted run reached the target anywhere
    within: int  # problems where the pair is within factor of the best
    reached: int  # problems where some pair reached the target
    problems: int  # problems in the sweep
    table: pd.DataFrame  # one row a pair: problems within, reached, geometric mean ratio
    # of the problems every pair scoring as ``pair`` reached, those where the ranking of
    # the cheapest pairs (ranking.decide) ties all their costs: (tied, all reached)
    costs_tied: tuple[int, int] = (0, 0)

    @property
    def sentence(self) -> str:
        """The recommendation in one sentence, with the numbers it rests on."""
        measure = COST_COLUMNS.get(self.cost, self.cost).split(" [")[0]
        if self.pair is None:
            return (
                f"No run without warnings reached scd >= {self.target:g} on any of the "
                f"{self.problems} problems: no recommendation."
            )
        missing = self.problems - self.reached
        tail = (
            f" ({missing} problem(s) where no pair reached it without warnings)" if missing else ""
        )
        sentence = (
            f"{self.pair} is within {self.factor:g}x of the best {measure} on {self.within} "
            f"of {self.reached} problems at scd >= {self.target:g}{tail}"
        )
        level = same_score(self.table)
        if len(level) > 1:  # named first only by the geometric mean: say so, and who else
            others = [str(p) for p in level.index[1:4]] + ["..."] * (len(level) > 4)
            gm = level["geometric mean ratio"]
            sentence += (
                f"; so {'is' if len(others) == 1 else 'are'} {', '.join(others)}: "
                f"{self.pair} is named for the lower geometric mean of its cost ratios to "
                f"the best ({times_text(gm.iloc[0])} against {times_text(gm.iloc[1])})"
            )
            tied, shared = self.costs_tied
            if tied:  # the geometric mean then orders costs the ranking cannot tell apart
                sentence += (
                    f"; their costs tie at scd >= {self.target:g} on {tied} of the {shared} "
                    f"problems they {'both' if len(level) == 2 else 'all'} reached (as in the "
                    "table of the cheapest pairs)"
                    + (", so that order does not say which is cheaper" if tied == shared else "")
                )
        return sentence + "."


def same_score(table: pd.DataFrame) -> pd.DataFrame:
    """The rows of a recommendation's ``table`` that score as its first: as many problems
    within the factor and reached (the geometric mean alone orders them)."""
    top = table.iloc[0]
    return table[(table["within"] == top["within"]) & (table["reached"] == top["reached"])]


def recommend(
    runs: pd.DataFrame,
    target: float | None = None,
    cost: str = "wall_s",
    factor: float = WITHIN_FACTOR,
) -> Recommendation:
    """The pair within ``factor`` of the best ``cost`` on the most problems at scd >=
    ``target`` (default :func:`overview_target`); runs with warnings never count."""
    target = overview_target(runs) if target is None else float(target)
    ratio = cost_ratio(cost_at_target(runs, target, cost))
    reached = int(ratio.notna().any(axis=1).sum())
    with np.errstate(divide="ignore"):
        table = pd.DataFrame(
            {
                "within": (ratio <= factor).sum(axis=0),
                "reached": ratio.notna().sum(axis=0),
                "geometric mean ratio": np.exp(np.log(ratio).mean(axis=0, skipna=True)),
            }
        )
    table = table.sort_values(
        ["within", "reached", "geometric mean ratio"], ascending=[False, False, True]
    )
    table.index.name = "pair"
    pair = None if reached == 0 or table.empty else str(table.index[0])
    within = int(table["within"].iloc[0]) if pair is not None else 0
    costs_tied = (0, 0)
    level = list(same_score(table).index) if pair is not None else []
    if len(level) > 1:  # does the ranking of each problem tell their costs apart?
        shared = ratio.index[ratio[level].notna().all(axis=1)]
        tied = sum(
            set(level) <= set(decide(runs[runs["problem"] == problem], target, cost).tied)
            for problem in shared
        )
        costs_tied = (tied, len(shared))
    return Recommendation(
        target, cost, factor, pair, within, reached, runs["problem"].nunique(), table, costs_tied
    )
