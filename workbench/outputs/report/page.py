"""The report's HTML page, rendered from ``templates/report.html.j2`` (Jinja2).

The layout, wording and style of the page live in the template, so a person changes the
page without touching Python; this module hands it plain data (:class:`PageTable`,
:class:`ProblemSection`, text) and Jinja escapes every value (autoescape on).
"""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import pandas as pd
from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape

from workbench.execution.environment import cpu_model, distribution_versions
from workbench.outputs.report.analysis import run_environment
from workbench.outputs.report.close_calls import retime_note
from workbench.outputs.report.cost import Cost, resolve_cost, tie_rule
from workbench.outputs.report.figures import FigureFiles, slug
from workbench.outputs.report.scorecards import Scorecard
from workbench.outputs.report.tables import shows_index, table_cells, unbroken_units

TEMPLATE = "report.html.j2"
LIBRARIES: tuple[str, ...] = (
    "mbs-workbench",
    "numpy",
    "scipy",
    "casadi",
    "pandas",
    "pyarrow",
    "matplotlib",
    "rerun-sdk",
)


@dataclass
class PageTable:
    """A table as the page shows it: text cells, and the stem of its CSV / Markdown /
    LaTeX files in ``tables/``."""

    name: str
    header: list[str]
    rows: list[list[str]]

    @classmethod
    def of(cls, table: pd.DataFrame, name: str) -> PageTable:
        header, rows = table_cells(table, index=shows_index(table))
        return cls(name, [unbroken_units(cell) for cell in header], rows)


@dataclass
class ProblemSection:
    """What the page shows of one problem (made in a figure worker, so plain data).

    rtol: the middle tolerance of the problem's ok runs (None: no ok run); drift: its
    figure (None: no time series) and table (None when rtol is None).
    """

    problem: str
    anchor: str
    runs: int
    status_counts: str
    work_precision: FigureFiles | None
    rtol: float | None
    drift: FigureFiles | None
    drift_table: PageTable | None
    error: FigureFiles | None = None
    picture: FigureFiles | None = None  # the mechanism at its initial pose
    traits: Any = None  # its Traits (workbench.outputs.report.traits), model left out
    reference: str = ""  # where its reference came from (analysis.reference_source)


@dataclass
class Overview:
    """The top of the page: which pair to use (:mod:`workbench.outputs.report.overview`).

    sentence: the recommendation; target: the scd it is made at; heat_map: cost of each
    pair at the target relative to the best (None: no run reached it); ranking: the pairs
    by problems within the factor of the best; pareto: every problem's Pareto front;
    convergence: the fixed-step methods' order plot (None: no fixed-step runs).
    """

    sentence: str
    target: float
    heat_map: FigureFiles | None
    ranking: PageTable
    pareto: PageTable
    convergence: FigureFiles | None
    trusted_runs: int


@dataclass
class DecisionPage:
    """The decision table as the page shows it (:mod:`workbench.outputs.report.decision`):
    rows grouped by family, a column a target; ``cost_text`` formats a cost with its unit."""

    rows: list[Any]
    targets: list[float]
    cost: str

    def cost_text(self, value: float) -> str:
        from workbench.outputs.report.decision import cost_text

        return cost_text(value, self.cost)

    def families(self) -> list[tuple[str, list[Any]]]:
        """(family, its rows) in the rows' order."""
        grouped: dict[str, list[Any]] = {}
        for row in self.rows:
            grouped.setdefault(row.family, []).append(row)
        return list(grouped.items())


def decision_note(runs: pd.DataFrame, cost: Cost) -> str:
    """The paragraph above the decision table, on the page and in the paper: what a cell
    shows, when pairs tie (:func:`~workbench.outputs.report.cost.tie_rule`) and whether the
    close calls were timed again after the runs (:func:`retime_note`)."""
    note = (
        "For each problem and accuracy target (scd: correct digits at the end), the cheapest "
        f"pair among the runs that finished without warnings, its cost ({cost.name}) and how "
        f"far ahead of the next pair it is; 'tie' where {tie_rule(cost.column)}, so the cost "
        "cannot tell them apart."
    )
    retimed = retime_note(runs, cost.column)
    return f"{note} {retimed}." if retimed else note


def environment() -> Environment:
    """The Jinja environment of the report's templates: HTML escaped, undefined names an
    error (so a misspelt name in an edited template fails loudly)."""
    return Environment(
        loader=PackageLoader("workbench.outputs.report", "templates"),
        autoescape=select_autoescape(enabled_extensions=("html", "htm", "xml", "html.j2")),
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def render_page(
    title: str,
    runs: pd.DataFrame,
    overview: Overview,
    summary: pd.DataFrame,
    status: pd.DataFrame,
    footnotes: list[str],
    sections: list[ProblemSection],
    command: str,
    scorecards: Sequence[Scorecard] = (),
    cost: Cost | None = None,
    timing_warning: str = "",
    decision: DecisionPage | None = None,
    coverage: str = "",
    stalled: Sequence[str] = (),
    coverage_heading: str = "Not the whole sweep",
) -> str:
    """The page of a report whose tables are in ``tables/`` and figures in ``figures/``.

    overview: the recommendation and the figures above everything else.
    footnotes: as :func:`workbench.outputs.report.analysis.status_matrix` gives them,
    ``"[n] text"``; the page numbers them itself. cost: the cost measure in force (stated
    on the page); timing_warning: shown at the top when not empty. decision: the first
    screen's table (none: not shown); coverage: the partial-sweep notice ('' : none)
    under ``coverage_heading``;
    stalled: pairs whose error does not shrink with the tolerance
    (:func:`~workbench.outputs.report.analysis.stalled_pairs`), shown at the top.
    """
    cost = cost or resolve_cost(runs)
    problems = list(dict.fromkeys(runs["problem"]))
    return (
        environment()
        .get_template(TEMPLATE)
        .render(
            title=title,
            n_runs=len(runs),
            n_pairs=runs["pair"].nunique(),
            problems=[(problem, slug(problem)) for problem in problems],
            overview=overview,
            summary=PageTable.of(summary, "summary"),
            status=PageTable.of(status, "status"),
            footnotes=[note.split("] ", 1)[1] for note in footnotes],
            sections=sections,
            scorecards=[(c.title, c.note, PageTable.of(c.table, c.name)) for c in scorecards],
            command=command,
            cost_name=cost.name,
            tie_rule=tie_rule(cost.column),
            decision_note=decision_note(runs, cost),
            cost_statement=cost.statement(),
            timing_warning=timing_warning,
            stalled=list(stalled),
            decision=decision,
            coverage=coverage,
            coverage_heading=coverage_heading,
            run_environment="; ".join(run_environment(runs)),
            versions=", ".join(f"{name} {version}" for name, version in library_versions().items()),
            machine=machine_description(),
            date=datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
        )
    )


def library_versions() -> dict[str, str]:
    """Installed versions of the libraries a report depends on ('not installed' if absent)."""
    return {"python": platform.python_version(), **distribution_versions(LIBRARIES)}


def machine_description() -> str:
    """Host, OS, CPU model and count, on one line."""
    return (
        f"{platform.node()} ({platform.platform()}, {cpu_model()}, {os.cpu_count()} CPUs, "
        f"{sys.implementation.name})"
    )
