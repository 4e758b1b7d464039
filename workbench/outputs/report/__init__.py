"""Static HTML reports of a sweep (docs/architecture.md, "Runs, results, reports").

:func:`write_report` turns a results DataFrame (one row a run; the columns of
:mod:`workbench.runs.store`) and the runs' time series into a directory::

    index.html              the page: tables shown, figures linked as PNG
    figures/*.png|svg       work-precision diagrams and drift / energy over time
    tables/*.csv|md|tex     the summary, the status matrix and all result rows

The page opens with the answer per mechanism (:mod:`.decision`): a table, a row a problem
grouped by family with a picture of it, a column an accuracy target (scd 4, 8, 10, or the
targets the sweep reaches), a cell the cheapest trusted pair with its cost and its margin
over the runner-up -- or "tie" and the tied pairs where their timed samples overlap
(:mod:`.ranking`, the one ranking the tables, ``workbench results`` and the LaTeX share)
-- and a "why" a problem from its traits and the kinds of pairs that won. A sweep whose
rows are not all its planned runs says so above it. Then the overview across problems
(:mod:`.overview`): the pair within 2x of the best on the most problems, a problem x pair
heat map of the top pairs, the Pareto fronts and the convergence order of fixed-step
methods. Per problem it draws its picture, a work-precision diagram (Pareto front and the
reference's accuracy marked), the error along the trajectory, and the drift and energy
error over time at the middle tolerance (one panel a formalism). The summary names, for
each problem and target accuracy (scd >= 2, 4, 6, 8, 10), the cheapest pair; the status
matrix counts ok / failed / timeout / skipped runs and lists each kind of reason once. A
footer records library versions, the machine, the date and the command that made the
report. ``paper=`` (``workbench paper``) also writes a paper folder (:mod:`.paper`).

One idea a module:

    trust      which runs count: ok and without audit warnings
    ranking    the cheapest pair a problem and target, its margin, ties (the one ranking)
    analysis   what the tables say: labels, cheapest pairs, status matrix, drift at the
               middle tolerance, the partial-sweep notice
    traits     a problem's family and traits (model, stiffness from the statistics)
    decision   the first screen: the decision table and its "why"
    picture    a mechanism drawn at its initial pose
    overview   which pair to use: Pareto fronts, cost at a target accuracy, recommendation
    overview_figures  the heat map and the convergence-order plot
    tables     CSV, Markdown and LaTeX (booktabs, captioned) files, readable headers
    figures    work-precision and drift / energy figures (matplotlib, Agg)
    pool       the worker processes that draw the figures
    page       the HTML page, rendered from templates/report.html.j2 (Jinja2): edit the
               template to change the page
    paper      main.tex inputting the LaTeX tables and PDF figures; compiling it
    writer     write_report and report_directory: all of the above into a directory
"""

from workbench.outputs.report.analysis import (
    DRIFT_TABLE_COLUMNS,
    NUMERIC_COLUMNS,
    REQUIRED_COLUMNS,
    STATUSES,
    TARGET_SCD,
    cheapest_pairs,
    drift_runs,
    drift_table,
    middle_tolerance,
    pair_labels,
    prepare_results,
    run_environment,
    status_matrix,
)
from workbench.outputs.report.figures import (
    DRIFT_QUANTITIES,
    FIGURE_FORMATS,
    REPORT_FORMATS,
    FigureFiles,
    PairStyles,
    drift_figure,
    work_precision_figure,
)
from workbench.outputs.report.page import LIBRARIES, library_versions, machine_description
from workbench.outputs.report.tables import latex_table, markdown_table, write_table
from workbench.outputs.report.writer import (
    SeriesLoader,
    current_report,
    kept_cost,
    report_directory,
    write_report,
)

__all__ = [
    "DRIFT_QUANTITIES",
    "DRIFT_TABLE_COLUMNS",
    "FIGURE_FORMATS",
    "REPORT_FORMATS",
    "LIBRARIES",
    "NUMERIC_COLUMNS",
    "REQUIRED_COLUMNS",
    "STATUSES",
    "TARGET_SCD",
    "FigureFiles",
    "PairStyles",
    "SeriesLoader",
    "cheapest_pairs",
    "current_report",
    "drift_figure",
    "drift_runs",
    "drift_table",
    "kept_cost",
    "latex_table",
    "library_versions",
    "machine_description",
    "markdown_table",
    "middle_tolerance",
    "pair_labels",
    "prepare_results",
    "report_directory",
    "run_environment",
    "status_matrix",
    "work_precision_figure",
    "write_report",
    "write_table",
]
