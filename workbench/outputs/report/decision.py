"""The report's first screen: a decision table, a row a problem (grouped by family), a
column an accuracy target, a cell the cheapest trusted pair with its cost and margin over
the runner-up or the pairs tied with it (:mod:`workbench.outputs.report.ranking`), and a
short "why" a problem from its traits and which families of pairs won
(:mod:`workbench.outputs.report.traits`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from workbench.outputs.report.cost import tie_rule
from workbench.outputs.report.overview import trusted
from workbench.outputs.report.ranking import NOT_TIMED, NOT_TIMED_NOTE, Decision, decide
from workbench.outputs.report.traits import FAMILIES, Traits, favoured, problem_traits

DECISION_TARGETS: tuple[float, ...] = (4.0, 8.0, 10.0)
FALLBACK_TARGETS: tuple[float, ...] = (2.0, 4.0, 6.0, 8.0, 10.0)  # to complete them


def decision_targets(runs: pd.DataFrame, cost: str, columns: int = 3) -> list[float]:
    """The accuracy targets of the decision table: those of :data:`DECISION_TARGETS` some
    trusted run reaches, completed up to ``columns`` by the highest other reached ones of
    :data:`FALLBACK_TARGETS` (the lowest of them when no run reaches any)."""
    best = trusted(runs, cost)["scd"].max() if len(runs) else np.nan
    reached = [t for t in FALLBACK_TARGETS if np.isfinite(best) and best >= t]
    chosen = [t for t in DECISION_TARGETS if t in reached]
    for target in reversed(reached):
        if len(chosen) >= columns:
            break
        if target not in chosen:
            chosen.append(target)
    return sorted(chosen) or [FALLBACK_TARGETS[0]]


def cost_text(value: float, cost: str) -> str:
    """A cost with its unit: seconds in s / ms / us / ns to three significant digits,
    trailing zeros kept ('39.0 ms' beside '39.1 ms', not '39 ms': one format a column);
    counts as 'N rhs'."""
    if not np.isfinite(value):
        return ""
    if not cost.endswith("_s"):
        return f"{value:,.0f} rhs"
    value = float(f"{value:.3g}")  # rounded first: 0.9996 s is '1.00 s', not '1e+03 ms'
    units = (("s", 1.0), ("ms", 1e-3), ("\N{MICRO SIGN}s", 1e-6))
    unit, scale = next(((u, s) for u, s in units if value >= s), ("ns", 1e-9))
    return f"{value / scale:#.3g}".rstrip(".") + f" {unit}"


@dataclass
class DecisionRow:
    """One problem's row: its anchor on the page, family, picture (a FigureFiles or
    None), one :class:`Decision` a target and the "why" sentence."""

    problem: str
    anchor: str
    family: str
    cells: list[Decision]
    why: str
    picture: object = None
    traits: list[str] = field(default_factory=list)


def why(traits: Traits, cells: list[Decision], runs: pd.DataFrame, cost: str = "") -> str:
    """Traits, stiffness and the families of the winning pairs, in one or two sentences."""
    parts = list(traits.traits)
    if traits.stiffness:
        parts.append(traits.stiffness)
    text = "; ".join(parts)
    winners = [pair for d in cells for pair in (d.tied or ([d.pair] if d.pair else []))]
    won = favoured(runs, winners)
    if won:
        text += (". " if text else "") + f"Winning pairs by kind: {won}"
    if any(d.is_tie for d in cells):
        text += f". Tied pairs: {tie_rule(cost)}"
    if any(d.pair and not d.tie_known for d in cells):
        text += ". Some costs have one timed sample (or no interval): ties cannot be told there"
    if any(NOT_TIMED in d.verdict() for d in cells):
        text += f". {NOT_TIMED_NOTE[0].upper()}{NOT_TIMED_NOTE[1:]}"
    reached = [d.target for d in cells if d.pair]
    short = short_of(runs, max(reached), cost) if reached and cost else {}
    if short:
        looser = " or looser" if len(set(short.values())) > 1 else ""
        text += (
            f". Not measured: {len(short)} pair(s) still improving at their tightest rtol "
            f"({min(short.values()):g}{looser}) fell short of scd {max(reached):g}; a tighter "
            f"rtol would price them there ({', '.join(sorted(short))})"
        )
    return text + "." if text else "No run of this problem finished without warnings."


def short_of(runs: pd.DataFrame, target: float, cost: str) -> dict[str, float]:
    """Pairs (-> their tightest rtol) whose trusted runs all fall short of ``target`` while
    their best is their tightest run: still improving where the tolerance grid ends, so
    the table's winner at ``target`` won over pairs whose cost there was never measured."""
    found = {}
    tried = runs.groupby("pair")["rtol"].min()  # every run's, failed or warned ones too
    for pair, group in trusted(runs, cost).groupby("pair"):
        tightest = group.loc[group["rtol"].idxmin()]
        if tried.get(pair, tightest["rtol"]) < tightest["rtol"]:
            continue  # a tighter rtol was run and failed or was warned: not "never measured"
        if group["scd"].max() < target and len(group) > 1 and tightest["scd"] >= group["scd"].max():
            found[str(pair)] = float(tightest["rtol"])
    return found


def decision_rows(
    runs: pd.DataFrame, targets: list[float], cost: str, sections: list[Any] = ()
) -> list[DecisionRow]:
    """The rows of the decision table, grouped by family (:data:`FAMILIES` order), in
    order of appearance within a family. ``sections``: the problems' page sections
    (anchor, traits and picture, :class:`~workbench.outputs.report.page.ProblemSection`);
    a problem without one gets its traits here."""
    known = {section.problem: section for section in sections}
    rows = []
    for problem, group in runs.groupby("problem", sort=False):
        section = known.get(str(problem))
        traits = section.traits if section is not None else None
        traits = traits or problem_traits(group)
        cells = [decide(group, target, cost) for target in targets]
        rows.append(
            DecisionRow(
                str(problem),
                section.anchor if section is not None else "",
                traits.family,
                cells,
                why(traits, cells, group, cost),
                picture=section.picture if section is not None else None,
                traits=traits.traits,
            )
        )
    order = {family: k for k, family in enumerate(FAMILIES)}
    return sorted(rows, key=lambda row: order.get(row.family, len(order)))


def decision_frame(rows: list[DecisionRow], targets: list[float], cost: str) -> pd.DataFrame:
    """The decision table as text cells (CSV, Markdown, LaTeX): family, problem, and a
    column a target reading 'pair, cost, verdict' ('tie: A; B, cost')."""
    records = []
    for row in rows:
        record = {"family": row.family, "problem": row.problem}
        for target, d in zip(targets, row.cells, strict=True):
            record[f"scd >= {target:g}"] = cell_summary(d, cost)
        records.append(record)
    return pd.DataFrame(records, columns=["family", "problem", *(f"scd >= {t:g}" for t in targets)])


def cell_summary(d: Decision, cost: str) -> str:
    """One cell in words: 'A / x, 1.2 ms, 1.8x ahead of B / y', 'tie: A / x; B / y, 1.2
    ms' or 'none reached'."""
    if d.pair is None:
        return d.verdict()
    price = cost_text(d.cost, cost)
    if d.is_tie:
        return f"tie: {'; '.join(d.tied)}, {price}"
    if not d.runner_up:
        return f"{d.pair}, {price}, only pair"
    return f"{d.pair}, {price}, {d.ahead_of()}"
