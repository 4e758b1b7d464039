"""Resuming a sweep: which of its runs are done, which to redo, and what to tell the user.

A run counts as done only if its row and series are whole
(:func:`workbench.runs.store.check_rows`); a broken one is named in one line and redone.
A done row whose producer differs from this process's
(:func:`workbench.execution.producer.stale_reason`) is *stale*. By default a stale row is kept
and the sweep says so loudly (a stale row is still a measurement, of other code, and a
long sweep should not silently start over because a plugin's comment changed); the
report marks it stale. ``rerun`` redoes the done rows of the named kinds
(:data:`RERUN_KINDS`: a status, or ``stale``); ``fresh`` redoes every run. An existing
row is never deleted: its replacement is written over it atomically when its run
finishes, so an interrupted re-run keeps the old row.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from workbench.errors import ConfigError
from workbench.execution.execute import RunSpec
from workbench.execution.producer import (
    LIBRARY_COLUMNS,
    PLUGIN_COLUMNS,
    stale_reason,
    unknown_producer,
)
from workbench.runs import store

RERUN_KINDS = ("failed", "timeout", "skipped", "stale")
PRODUCER_COLUMNS = (*PLUGIN_COLUMNS, *LIBRARY_COLUMNS)
SHOWN = 10  # broken or stale runs named one a line; the rest counted


def parse_rerun(text: str | None) -> frozenset[str]:
    """``"failed,timeout,stale"`` -> the kinds; ConfigError naming an unknown one."""
    kinds = [word.strip() for word in (text or "").split(",") if word.strip()]
    unknown = [kind for kind in kinds if kind not in RERUN_KINDS]
    if unknown:
        raise ConfigError(
            f"--rerun {text!r}: unknown kind {unknown[0]!r}; "
            f"a comma-separated list of {', '.join(RERUN_KINDS)}"
        )
    return frozenset(kinds)


@dataclass
class ResumePlan:
    """What a sweep of ``total`` runs finds in its output directory and will do."""

    total: int
    todo: list[RunSpec]
    done: int = 0  # runs of this sweep with a whole row (stale ones included)
    broken: dict[str, str] = field(default_factory=dict)  # run id -> what is wrong
    stale: dict[str, str] = field(default_factory=dict)  # run id -> what changed
    # run id -> its row's producer columns then: a later report keeps the mark while the
    # row is the same (:func:`stale_in_plan`)
    stale_rows: dict[str, dict[str, str]] = field(default_factory=dict)
    unknown: int = 0  # done rows whose producer is unknown (written before schema 4)
    rerun: frozenset[str] = frozenset()
    fresh: bool = False
    labels: dict[str, str] = field(default_factory=dict)
    others: int = 0  # rows in the folder that are not runs of this sweep
    others_source: str = ""  # what the folder's last sweep was run from, if known

    def lines(self) -> list[str]:
        """One line a finding, for the start of the sweep."""
        lines = [
            f"run {run_id} ({self.labels.get(run_id, '?')}): {reason}; redoing it"
            for run_id, reason in list(self.broken.items())[:SHOWN]
        ]
        if len(self.broken) > SHOWN:
            lines.append(f"... and {len(self.broken) - SHOWN} more broken row(s), redone")
        if self.fresh:
            return lines + [
                f"fresh: redoing all {self.total} runs (an existing row is replaced only "
                "when its run finishes)"
            ]
        if self.done:
            lines.append(f"resuming: {self.done} of {self.total} done ({len(self.stale)} stale)")
        if self.stale:
            first, why = next(iter(self.stale.items()))
            example = f"e.g. run {first} ({self.labels.get(first, '?')}): {why}"
            if "stale" in self.rerun:
                lines.append(
                    f"redoing {len(self.stale)} stale row(s), made by other code: {example}"
                )
            else:
                lines.append(
                    f"warning: {len(self.stale)} done row(s) are STALE, made by other code "
                    f"({example}); kept and marked stale in the report: redo them with "
                    "`--rerun stale`"
                )
        if self.others:
            last = f" (its last sweep: {self.others_source})" if self.others_source else ""
            lines.append(
                f"the folder holds {self.others} row(s) of other sweeps{last}: kept beside "
                "this sweep's, and its results and report show them too (another --out "
                "keeps sweeps apart)"
            )
        if self.unknown:
            lines.append(
                f"{self.unknown} done row(s) do not record what produced them (written "
                "before producers were recorded); kept: `--fresh` redoes every run"
            )
        return lines


def plan_resume(
    runs: list[RunSpec], out: Path, rerun: frozenset[str] = frozenset(), fresh: bool = False
) -> ResumePlan:
    """The runs of ``runs`` to do now, given the rows in ``out`` (see the module docstring)."""
    whole, broken = store.check_rows(out)
    labels = {spec.run_id: spec.label() for spec in runs}
    plan = ResumePlan(len(runs), [], rerun=rerun, fresh=fresh, labels=labels)
    plan.broken = {run_id: why for run_id, why in broken.items() if run_id in labels}
    plan.others = sum(run_id not in labels for run_id in whole)
    last = store.load_plan(out) if plan.others else None
    if last and last.get("source") and not set(last["run_ids"]) <= set(labels):
        plan.others_source = str(last["source"])
    for spec in runs:
        row = whole.get(spec.run_id)
        if fresh or row is None:
            plan.todo.append(spec)
            continue
        plan.done += 1
        stale = stale_reason(row)
        if stale:
            plan.stale[spec.run_id] = stale
            plan.stale_rows[spec.run_id] = {c: row[c] for c in PRODUCER_COLUMNS
                                            if isinstance(row.get(c), str)}  # fmt: skip
        plan.unknown += unknown_producer(row)
        if row.get("status") in rerun or (stale and "stale" in rerun):
            plan.todo.append(spec)
    return plan


def stale_in_plan(plan: Mapping[str, Any] | None, frame: pd.DataFrame) -> dict[str, str]:
    """The stale rows (run id -> what changed) the last sweep found in its folder
    (``plan``: :func:`workbench.runs.store.load_plan`) whose row in ``frame`` is still the
    one it judged: what a report made later by ``workbench report`` marks stale, as the
    sweep's own report did (that command imports none of the sweep's own plugins)."""
    stored = (plan or {}).get("stale")
    if not isinstance(stored, dict) or len(frame) == 0:
        return {}
    rows = frame.drop_duplicates("run_id").set_index("run_id")
    kept = {}
    for run_id, entry in stored.items():
        if not isinstance(entry, dict) or run_id not in rows.index:
            continue
        row = rows.loc[run_id]
        then = entry.get("row", {})
        if all(str(row.get(column)) == str(value) for column, value in then.items()):
            kept[run_id] = str(entry.get("reason", ""))
    return kept


def mark_stale(frame: pd.DataFrame, stale: Mapping[str, str]) -> pd.DataFrame:
    """``frame`` with a ``stale`` warning added to the rows of ``stale`` (run id -> what
    changed), so a report shows them as runs with warnings and never recommends them."""
    frame = frame.copy()
    reasons = frame["run_id"].map(dict(stale))
    marked = reasons.notna()
    notes = (
        "stale: made by other code than this sweep's (" + reasons[marked] + "); "
        "redo with `workbench sweep --rerun stale`"
    )
    old = frame.loc[marked, "warnings"].astype(object).fillna("").astype(str)
    frame.loc[marked, "warnings"] = [
        f"{o}; {n}" if o else n for o, n in zip(old, notes, strict=True)
    ]
    return frame


__all__ = ["RERUN_KINDS", "ResumePlan", "mark_stale", "parse_rerun", "plan_resume", "stale_in_plan"]
