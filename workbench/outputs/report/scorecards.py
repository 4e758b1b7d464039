"""Scorecards of published benchmark suites, read like the suites' own result tables.

A problem declares that it belongs to a suite through data (``Problem.benchmark``:
suite, precision, measure, variables); nothing here names a problem.

- **IFToMM** (``suite = "iftomm"``; Gonzalez, Dopico, Lugris, Cuadrado, Multibody System
  Dynamics 16 (2006) 179-190): a code is scored by the CPU time it needs to keep the
  benchmark's variables within the required precision. For each formalism x integrator
  pair and problem: the least integration CPU time (:func:`scored_cpu`) among the pair's
  ``ok`` runs whose ``measure`` column is at most ``precision`` -- over a sweep's tolerance
  grid, the cheapest tolerance that meets it -- or "not reached".
- **IVP test set** (``suite = "ivp"``; Mazzia and Magherini): significant correct digits
  (scd) against CPU time and against right-hand-side evaluations, one row a run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import pandas as pd

from workbench.plugin import registry

NOT_REACHED = "not reached"


@dataclass
class Scorecard:
    """A table of the page: its file stem, heading, explanation and the table itself."""

    name: str
    title: str
    note: str
    table: pd.DataFrame


def declared_benchmarks(problems: list[str]) -> dict[str, dict[str, Any]]:
    """``{problem: benchmark}`` for the named problems that declare one (registered ones)."""
    declared = {}
    for name in problems:
        try:
            benchmark = getattr(registry.get_problem(name), "benchmark", None)
        except Exception:  # noqa: BLE001 - a problem no longer installed has no scorecard
            continue
        if isinstance(benchmark, dict) and benchmark.get("suite"):
            declared[name] = benchmark
    return declared


def cheapest_meeting(runs: pd.DataFrame, measure: str, precision: float) -> pd.DataFrame:
    """One row per pair of one problem's runs: the ``ok`` run of least CPU time
    (:func:`scored_cpu`) whose ``measure`` is at most ``precision`` (columns pair, rtol,
    cpu_s: that CPU time, measure, verdict);
    pairs without such a run have NaN rtol / cpu_s and the reason in ``verdict``."""
    rows = []
    for pair, group in runs.groupby("pair", sort=True):
        ok = group[group["status"] == "ok"]
        values = pd.to_numeric(ok.get(measure, pd.Series(math.nan, index=ok.index)))
        meeting = ok[values <= precision]
        if meeting.empty:
            verdict = NOT_REACHED if not ok.empty else _no_ok_run(group)
            rows.append({"pair": pair, "rtol": math.nan, "cpu_s": math.nan,
                         measure: math.nan, "verdict": verdict})  # fmt: skip
            continue
        cpu = scored_cpu(meeting)
        best = meeting.loc[cpu.idxmin()]
        warned = bool(str(best.get("warnings", "") or "").strip())
        rows.append({"pair": pair, "rtol": float(best["rtol"]), "cpu_s": float(cpu[best.name]),
                     measure: float(best[measure]), "verdict": "met" + " *" * warned})  # fmt: skip
    return pd.DataFrame(rows, columns=["pair", "rtol", "cpu_s", measure, "verdict"])


def scored_cpu(runs: pd.DataFrame) -> pd.Series:
    """The CPU seconds a run is scored by: its integration's (``integrate_cpu_s``, the
    median of its timed samples), ``cpu_s`` where a row has none (written before schema 7).
    Not ``cpu_s``: it holds building and compiling the equations, which depend on what the
    worker ran before (0.38 s or 3e-5 s for the same run), so the scorecard changed with
    the order a sweep's runs were taken in; the rest of the report counts no one-off cost."""
    whole = pd.to_numeric(runs["cpu_s"], errors="coerce")
    if "integrate_cpu_s" not in runs:
        return whole
    integration = pd.to_numeric(runs["integrate_cpu_s"], errors="coerce")
    return integration.where(integration.notna(), whole)


def _no_ok_run(group: pd.DataFrame) -> str:
    statuses = sorted(set(group["status"]))
    return "/".join(statuses)


def iftomm_scorecard(runs: pd.DataFrame, benchmarks: dict[str, dict[str, Any]]) -> pd.DataFrame:
    """Pairs x problems: CPU seconds of the cheapest run meeting each problem's precision
    (with its rtol), "not reached", or the statuses of a pair that never finished ok."""
    problems = [p for p in dict.fromkeys(runs["problem"]) if p in benchmarks]
    cells: dict[str, dict[str, str]] = {}
    for problem in problems:
        spec = benchmarks[problem]
        found = cheapest_meeting(runs[runs["problem"] == problem], spec["measure"],
                                 float(spec["precision"]))  # fmt: skip
        for row in found.itertuples(index=False):
            if row.verdict.startswith("met"):
                mark = " *" if row.verdict.endswith("*") else ""
                text = f"{row.cpu_s:.3g} s (rtol {row.rtol:.0e}){mark}"
            else:
                text = row.verdict
            cells.setdefault(row.pair, {})[problem] = text
    table = (
        pd.DataFrame.from_dict(cells, orient="index")
        .reindex(columns=problems)
        .astype(object)
        .fillna("")
    )
    table.index.name = "formalism / integrator"
    return table.sort_index()


def ivp_scorecard(runs: pd.DataFrame, benchmarks: dict[str, dict[str, Any]]) -> pd.DataFrame:
    """One row per run of the IVP-test-set problems: scd against CPU time and function
    evaluations, as the test set reports them."""
    chosen = runs[runs["problem"].isin(list(benchmarks)) & (runs["status"] == "ok")]
    columns = ["problem", "pair", "rtol", "scd", "scd_mixed", "cpu_s", "n_rhs"]
    present = [c for c in columns if c in chosen.columns]
    return chosen[present].sort_values(["problem", "pair", "rtol"]).reset_index(drop=True)


def scorecards(runs: pd.DataFrame) -> list[Scorecard]:
    """The scorecards of the suites the runs' problems declare (empty when none does)."""
    benchmarks = declared_benchmarks(list(dict.fromkeys(runs["problem"])))
    cards = []
    iftomm = {p: b for p, b in benchmarks.items() if b["suite"] == "iftomm"}
    if iftomm:
        measures = "; ".join(
            f"{p}: {b['measure']} <= {float(b['precision']):g} "
            f"({', '.join(b.get('variables', []))})"
            for p, b in iftomm.items()
        )
        cards.append(Scorecard(
            "iftomm_scorecard",
            "IFToMM benchmark scorecard: CPU time to reach the required precision",
            "For each pair, the integration CPU time (median of its timed samples; building "
            "and compiling the equations not counted) of its cheapest ok run (over the "
            "sweep's tolerance grid) that meets the problem's precision; \"not reached\" "
            "when no tolerance of the grid does; * the run carries audit warnings (see the "
            f"status table). {measures}.",
            iftomm_scorecard(runs, iftomm),
        ))  # fmt: skip
    ivp = {p: b for p, b in benchmarks.items() if b["suite"] == "ivp"}
    if ivp:
        cards.append(Scorecard(
            "ivp_scorecard",
            "IVP test set scorecard: scd against CPU time and function evaluations",
            "Every ok run of the test-set problems: significant correct digits at the end "
            "(scd) with its CPU time and right-hand-side evaluations.",
            ivp_scorecard(runs, ivp),
        ))  # fmt: skip
    return cards
