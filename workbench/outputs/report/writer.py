"""Writing a report: tables, figures (in worker processes) and the page, into a directory.

:func:`write_report` takes a results DataFrame and the runs' time series;
:func:`report_directory` the directory a sweep wrote.
"""

from __future__ import annotations

import contextlib
import json
import os
import warnings
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from pathlib import Path

import pandas as pd

from workbench.errors import ConfigError, WorkbenchError
from workbench.files import (
    LinkRefusedError,
    check_folder_target,
    check_no_links,
    open_no_follow,
    refuse_links,
    write_json_atomic,
)
from workbench.outputs.report.analysis import (
    LABEL_COLUMNS,
    cheapest_pairs,
    coverage_heading,
    coverage_notice,
    drift_left_out,
    drift_runs,
    drift_table,
    drift_table_contents,
    oversubscription_warning,
    prepare_results,
    reference_source,
    stalled_pairs,
    status_by_problem,
    status_counts,
    status_matrix,
)
from workbench.outputs.report.cost import COST_MEASURES, Cost, resolve_cost, tie_rule
from workbench.outputs.report.decision import decision_frame, decision_rows, decision_targets
from workbench.outputs.report.figures import (
    FIGURE_FORMATS,
    REPORT_FORMATS,
    drift_figure,
    error_figure,
    figure_formats,
    slug,
    work_precision_figure,
)
from workbench.outputs.report.overview import (
    NOT_REACHED,
    NOT_RUN,
    SKIPPED,
    UNREACHED_MEANING,
    cost_at_target,
    cost_ratio,
    pareto_mask,
    recommend,
    trusted,
    unreached_reasons,
)
from workbench.outputs.report.overview_figures import convergence_figure, heat_map_figure
from workbench.outputs.report.page import (
    DecisionPage,
    Overview,
    PageTable,
    ProblemSection,
    decision_note,
    render_page,
)
from workbench.outputs.report.paper import PaperSection, write_paper
from workbench.outputs.report.picture import Sketch, mechanism_picture, mechanism_sketch
from workbench.outputs.report.pool import (
    figure_executor,
    figure_jobs,
    results_or_redone,
    submit_or_none,
)
from workbench.outputs.report.ranking import NOT_TIMED, NOT_TIMED_NOTE
from workbench.outputs.report.scorecards import scorecards
from workbench.outputs.report.section_cache import (
    drawing_code_key,
    keep_section,
    kept_section,
    section_key,
)
from workbench.outputs.report.tables import leading_keys, write_table
from workbench.outputs.report.traits import Traits, problem_traits
from workbench.runs import output_keys
from workbench.runs.progress import progress_bar

SeriesLoader = Callable[[str], pd.DataFrame | None]
SUMMARY_CAPTION = (
    "Cheapest pair (least {cost}) reaching each target scd, among the runs without "
    "warnings; tie: pairs where {tie}; runner-up: the cheapest pair not tied with it, and "
    "the margin its cost over the cheapest; errors (in the CSV and Markdown) are pose "
    "errors over the samples (L2: root mean square); {statement}"
)
DECISION_CAPTION = (
    "Cheapest trusted pair (formalism / integrator) per problem and accuracy target, with "
    "its cost and how far ahead of the runner-up it is; tie: pairs where {tie}; {statement}"
)
STATUS_CAPTION = "Runs by status, per problem (the report's table splits them by pair)"
STATUS_NOTES = "; the numbers in brackets refer to the reasons listed below"


def write_report(
    results: pd.DataFrame,
    series_loader: SeriesLoader | None,
    out_dir: str | Path,
    command: str,
    *,
    title: str = "mbs-workbench report",
    progress: bool | None = None,
    jobs: int | None = None,
    cost: str | None = None,
    plan: dict | None = None,
    paper: str | Path | None = None,
) -> Path:
    """Write the report of ``results`` into ``out_dir``; return the path of ``index.html``.

    results: one row a run, at least the columns of
        :data:`~workbench.outputs.report.analysis.REQUIRED_COLUMNS` (missing numeric
        columns count as not measured).
    series_loader: ``run_id -> DataFrame`` (columns t, drift_pos, drift_vel, drift_nh,
        energy_err, ...) or None when a run has no series; ``None`` draws no drift plots.
    command: the exact command line that produced the report (printed in the footer).
    progress: show a rich progress bar on stderr; default: when there are several problems.
    jobs: processes drawing figures; default: :func:`~workbench.outputs.report.pool.figure_jobs`.
    cost: the cost measure of the diagrams, tables and recommendation, a key of
        :data:`~workbench.outputs.report.cost.COST_MEASURES` (default: see that module).
    plan: the sweep's plan (:func:`workbench.runs.store.load_plan`): the first screen then
        says how many of the planned runs are present.
    paper: also write a paper folder there (:mod:`workbench.outputs.report.paper`).
    """
    runs = prepare_results(results)
    measure = resolve_cost(runs, cost)
    out = Path(out_dir)
    refuse_links(out)  # the report may go into a folder from someone else (workbench.files)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "tables").mkdir(parents=True, exist_ok=True)

    problems = list(dict.fromkeys(runs["problem"]))
    summary = cheapest_pairs(runs, cost=measure.column)
    matrix, footnotes = status_matrix(runs)
    caption = SUMMARY_CAPTION.format(
        cost=measure.name, tie=tie_rule(measure.column), statement=measure.statement()
    )
    # the runner-up is printed: a margin beside "tie" names whom it is over
    printed = [c for c in summary.columns if c not in ("err_l2", "err_max", "n_rhs")]
    # a row is a problem at a target: both repeated when the LaTeX is split into parts
    keys = leading_keys(summary[printed], ("problem", "target scd"))
    if summary["verdict"].str.contains(NOT_TIMED, regex=False).any():
        caption += f"; {NOT_TIMED_NOTE}"
    write_table(summary, out / "tables", "summary", caption, latex=summary[printed], keys=keys)
    status_caption = STATUS_CAPTION + (STATUS_NOTES if footnotes else "")  # none: no notes
    write_table(
        matrix, out / "tables", "status", status_caption,
        latex=status_by_problem(runs, matrix), notes=footnotes,
    )  # fmt: skip
    runs.drop(columns=list(LABEL_COLUMNS)).to_csv(out / "tables" / "results.csv", index=False)
    cards = scorecards(runs)
    for card in cards:
        write_table(card.table, out / "tables", card.name, card.title)
    # a paper takes its figures as PDF; a report alone writes PNG and SVG (figures.py)
    formats = FIGURE_FORMATS if paper is not None else REPORT_FORMATS
    with figure_formats(formats):
        overview = overview_of(runs, out, measure)

    show = len(problems) > 1 if progress is None else progress
    drawn: dict[str, str] = {}  # problem -> the key of its section, drawn in this report
    code = drawing_code_key()
    with progress_bar("report", len(problems), show=show) as bar, contextlib.ExitStack() as stack:
        executor, tasks = None, []
        for index, problem in enumerate(problems):
            of_problem = runs[runs["problem"] == problem]
            series = _load_series(of_problem, series_loader, measure.column)
            # the model is built here, where the plugins are loaded: a figure worker then
            # imports matplotlib and pandas only (a sweep's peak memory is two of them)
            traits = problem_traits(of_problem)
            sketch = mechanism_sketch(traits.model) if traits.model is not None else None
            traits.model = None
            arguments = (of_problem, series, out, measure.column, traits, sketch, formats)
            key = section_key(of_problem, series, measure.column, traits, sketch, formats, code)
            kept = kept_section(out, problem, key)
            if kept is None:  # drawn (again): what it is drawn from changed
                if executor is None:  # workers for this problem and those after it at most
                    count = figure_jobs(len(problems) - index) if jobs is None else max(1, jobs)
                    executor = stack.enter_context(figure_executor(count))
                drawn[problem] = key
                future = submit_or_none(executor, problem_section, *arguments)
            else:  # as the last report into this folder drew it
                future = Future()
                future.set_result(kept)
            tasks.append((problem, future, arguments))
        # a worker killed from outside: its problems are drawn again here (one warning)
        sections = results_or_redone(tasks, problem_section, bar.step)
    for section in sections:
        if section.problem in drawn:
            keep_section(out, section, drawn[section.problem])

    targets = decision_targets(runs, measure.column)
    decided = decision_rows(runs, targets, measure.column, sections)
    decision_table = decision_frame(decided, targets, measure.column)
    caption = DECISION_CAPTION.format(tie=tie_rule(measure.column), statement=measure.statement())
    if any(NOT_TIMED in d.verdict() for row in decided for d in row.cells):
        caption += f"; {NOT_TIMED_NOTE}"
    write_table(
        decision_table,
        out / "tables",
        "decision",
        caption,
        latex=decision_table.drop(columns="family"),  # rows stay in family order
    )
    stalled = stalled_pairs(runs)
    page = render_page(
        title,
        runs,
        overview,
        summary,
        matrix,
        footnotes,
        sections,
        command,
        cards,
        cost=measure,
        timing_warning=oversubscription_warning(runs),
        decision=DecisionPage(decided, targets, measure.column),
        coverage=coverage_notice(runs, plan),
        stalled=stalled,
        coverage_heading=coverage_heading(runs, plan),
    )
    index = out / "index.html"
    index.write_text(page, encoding="utf-8")
    if paper is not None:
        intro = [
            f"{len(runs)} runs of {len(problems)} problem(s) and {runs['pair'].nunique()} "
            f"formalism / integrator pair(s); {measure.statement()}.",
            *([f"{coverage_heading(runs, plan)}: {coverage_notice(runs, plan)}."]
              if plan and coverage_notice(runs, plan) else []),  # fmt: skip
            *(f"Not converging: {line}." for line in stalled),
            overview.sentence,
            decision_note(runs, measure),  # the page's words above the decision table
        ]
        write_paper(
            out,
            Path(paper),
            title,
            intro,
            ["decision", "summary", "status"],
            [overview.heat_map] if overview.heat_map else [],
            [
                PaperSection(
                    section.problem,
                    [f for f in (section.work_precision, section.drift) if f is not None],
                    [section.drift_table.name] if section.drift_table else [],
                )
                for section in sections
            ],
            ["ranking", "pareto", *(card.name for card in cards)],
        )
    return index


def report_directory(
    results_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str] | None = None,
    command: str | None = None,
    *,
    progress: bool | None = None,
    stale: Mapping[str, str] | None = None,
    cost: str | None = None,
    paper: str | os.PathLike[str] | None = None,
    rows: pd.DataFrame | None = None,
) -> Path:
    """The report of a results directory written by :mod:`workbench.runs.store` (or of a
    results.parquet); return the path of its ``index.html``.

    stale: rows made by other code than the sweep's (run id -> what changed, as
    :func:`workbench.runs.resume.plan_resume` found them), marked with a ``stale``
    warning (:func:`workbench.runs.resume.mark_stale`); None: those the folder's last
    sweep found, while their rows are unchanged (:func:`~workbench.runs.resume.stale_in_plan`).

    out_dir: default ``<results directory>/report``. command: for the footer; default the
    equivalent ``workbench report`` command line. Time series are read from the directory's
    ``series/``; runs without one get no drift curve. Raises ConfigError when there are no
    results. Warnings of :func:`workbench.runs.store.load_results` (unreadable rows) pass through.
    cost: the report's cost measure (:func:`write_report`); paper: also write a paper
    folder there (:func:`write_report`). rows: the directory's rows as
    :func:`~workbench.runs.store.load_results` read them just before (a sweep's consolidation:
    every row file read once, not twice); default: read here.
    """
    import shlex

    from workbench.runs.store import load_plan, load_results, load_series

    source = Path(results_path)
    if not source.exists():
        raise ConfigError(f"no results at {source}: give the output directory of `workbench sweep`")
    frame = load_results(source) if rows is None else rows
    if len(frame) == 0:
        raise ConfigError(f"no result rows in {source}: run `workbench sweep --out {source}` first")
    directory = source if source.is_dir() else source.parent
    plan = load_plan(directory)
    if stale is None:  # `workbench report`: the marks of the folder's last sweep
        from workbench.runs.resume import stale_in_plan

        stale = stale_in_plan(plan, frame)
    if stale:
        from workbench.runs.resume import mark_stale

        frame = mark_stale(frame, stale)
    if source.is_dir():
        _say_missing_series(directory, frame)
    target = Path(out_dir) if out_dir is not None else directory / "report"
    check_folder_target(target)  # before the report's seconds of work, not after them
    if out_dir is None:
        check_no_links(target, directory)  # RESULTS/report a link: refused (workbench.files)

    def series_loader(run_id: str) -> pd.DataFrame | None:
        try:
            return load_series(directory, run_id)
        except (ConfigError, OSError, ValueError):  # no or unreadable series: no curve
            return None

    if command is None:
        command = shlex.join(["workbench", "report", str(source), "--out", str(target)])
    index = target / "index.html"
    key = report_key(source, stale, cost) if source.is_dir() else None
    output_keys.forget(index)
    index = write_report(
        frame, series_loader, target, command, progress=progress, cost=cost, plan=plan,
        paper=paper,
    )  # fmt: skip
    if key is not None:
        output_keys.remember(index, key, root=target)
    write_json_atomic({"cost": cost}, target / SETTINGS_FILE, durable=False, root=target)
    return index


SETTINGS_FILE = "settings.json"
"""A report's choices (its cost measure: ``{"cost": key or null}``), beside its index."""


def _say_missing_series(directory: Path, frame: pd.DataFrame) -> None:
    """A warning naming the ok rows whose time series file is gone: their curves are left
    out of the report (a deleted file changed nothing it said; a resume redoes the run)."""
    from workbench.runs.store import series_path

    ok = frame[frame["status"] == "ok"]
    missing = [run_id for run_id in ok["run_id"].astype(str)
               if not series_path(directory, run_id).is_file()]  # fmt: skip
    if missing:
        warnings.warn(
            f"{len(missing)} ok run(s) have no time series file (e.g. {missing[0]}): their "
            "drift and energy curves are left out; `workbench sweep` into this folder "
            "redoes them",
            stacklevel=3,
        )


def kept_cost(results_dir: str | os.PathLike[str]) -> str | None:
    """The cost measure the report in ``results_dir/report`` was asked for (``workbench
    report --cost``), so that a sweep's resume remakes it in the same measure; None: the
    default, no report, or a settings file that names no known measure or is reached
    through a link (it is data in someone's folder: nothing outside it is read)."""
    path = Path(results_dir) / "report" / SETTINGS_FILE
    try:
        descriptor = open_no_follow(path, os.O_RDONLY, results_dir)
        with os.fdopen(descriptor, "rb") as file:
            cost = json.loads(file.read(4096)).get("cost")
    except (OSError, ValueError, AttributeError, LinkRefusedError):
        return None
    return cost if isinstance(cost, str) and cost in COST_MEASURES else None


def report_key(
    results_dir: str | os.PathLike[str],
    stale: Mapping[str, str] | None = None,
    cost: str | None = None,
) -> str:
    """What a report of the results directory is made from: its rows' content
    (:func:`workbench.runs.output_keys.rows_key`; a run's series is rewritten only with
    its row), the stale rows, the cost measure and the report's code."""
    return output_keys.key_of(
        output_keys.rows_key(results_dir),
        repr(sorted((stale or {}).items())),
        str(cost),
        output_keys.source_key("workbench.outputs.report"),
    )


def current_report(
    results_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str] | None = None,
    *,
    stale: Mapping[str, str] | None = None,
    cost: str | None = None,
) -> Path | None:
    """The ``index.html`` of the report of ``results_dir`` (in ``out_dir``, default
    ``<results_dir>/report``) if :func:`report_directory` made it from the same inputs
    (:func:`report_key`), else None: a resume with nothing new keeps the report."""
    source = Path(results_dir)
    if not source.is_dir():
        return None
    index = (Path(out_dir) if out_dir is not None else source / "report") / "index.html"
    return index if output_keys.is_current(index, report_key(source, stale, cost)) else None


def overview_of(runs: pd.DataFrame, out: Path, measure: Cost | None = None) -> Overview:
    """The overview of the page: the recommendation, the heat map of cost at its target
    (figure and table ``cost-at-target``), the Pareto fronts (table ``pareto``) and the
    convergence of the fixed-step methods, all in the cost ``measure`` (default: the
    default of :mod:`workbench.outputs.report.cost`)."""
    measure = measure or resolve_cost(runs)
    recommendation = recommend(runs, cost=measure.column)
    target, cost = recommendation.target, recommendation.cost
    ratio = cost_ratio(cost_at_target(runs, target, cost))
    reasons = unreached_reasons(runs, ratio)
    top = top_pairs(ratio, recommendation.table.index)
    heat_map = heat_map_figure(
        ratio[top], target, cost, out, pairs=ratio.shape[1], reasons=reasons[top]
    )
    ratio_table = ratio.copy()
    ratio_table.index.name = "problem"
    ratio_table.attrs["ratios"] = True  # every cell a cost ratio, printed as margins are
    # a cell without a value says why (Markdown and LaTeX; the CSV keeps numbers for
    # pandas): an empty one read the same as 'not run' or 'skipped' left out
    ratio_table.attrs["missing"] = {
        problem: {pair: text for pair, text in row.items() if text}
        for problem, row in reasons.iterrows()
        if (row != "").any()
    }
    shown = (
        f"{len(top)} of the {ratio.shape[1]} pairs, those reaching the target in the order of "
        "the ranking (most problems within reach of the best first)"
    )
    written = [r for r in (NOT_REACHED, SKIPPED, NOT_RUN) if (reasons == r).any().any()]
    meanings = "".join(f"; {reason}: {UNREACHED_MEANING[reason]}" for reason in written)
    write_table(
        ratio_table,
        out / "tables",
        "cost-at-target",
        f"Cost at scd >= {target:g} as a ratio to the best pair's: the {measure.name} of each "
        f"pair's cheapest run reaching the target divided by the least of any pair on the "
        f"problem (1: the best pair{meanings}); {measure.statement()}"
        + (f"; printed: {shown}" if len(top) < ratio.shape[1] else ""),
        latex=ratio_table[top],
    )
    fronts = []
    for _problem, group in runs.groupby("problem", sort=False):
        front = group[pareto_mask(group, measure.column)].sort_values(measure.column)
        costs = list(dict.fromkeys([measure.column, "n_rhs"]))
        columns = ["problem", "pair", "rtol", "scd", "err_l2", "err_max", *costs]
        fronts.append(front[columns])
    pareto = pd.concat(fronts, ignore_index=True) if fronts else pd.DataFrame()
    # two runs a hair apart in scd are both on the front: their scd must not print alike
    pareto.attrs["distinct"] = ["scd"]
    write_table(
        pareto,
        out / "tables",
        "pareto",
        "Pareto front of each problem: the runs without warnings that no other run beats "
        f"on both {measure.name} and scd (printed with the digits that tell its runs "
        f"apart); {measure.statement()}",
        keys=leading_keys(pareto, ("problem", "pair", "rtol")),  # a row is a run
    )
    factor = f"{recommendation.factor:g}x"
    ranked = len(recommendation.table)
    mean = "geometric mean of cost / best over the problems reached"
    ranking = recommendation.table.reset_index().rename(
        columns={
            "within": f"problems within {factor} of the best",
            "reached": f"problems reaching scd >= {target:g}",
            # of the problems a pair reached: one problem's 1.3 beside two problems' 1.16
            "geometric mean ratio": mean,
        }
    )
    ranking.attrs["ratios"] = [mean]
    # the page, CSV and Markdown list every pair; the LaTeX, on a page of a paper, the
    # first RANKED_SHOWN, and says so and where the others are
    write_table(
        ranking,
        out / "tables",
        "ranking",
        f"Pairs at scd >= {target:g}: {recommendation.sentence} ({measure.statement()})"
        + (
            f"; printed: the first {RANKED_SHOWN} of {ranked} pairs (all {ranked} in the "
            "report's tables/ranking.csv and ranking.md)"
            if ranked > RANKED_SHOWN
            else ""
        ),
        latex=ranking.head(RANKED_SHOWN),
    )
    return Overview(
        sentence=recommendation.sentence,
        target=target,
        heat_map=heat_map,
        ranking=PageTable.of(ranking, "ranking"),
        pareto=PageTable.of(pareto, "pareto"),
        convergence=convergence_figure(runs, out),
        trusted_runs=len(trusted(runs)),
    )


TOP_PAIRS = 10  # pair columns of the heat map and of the printed cost-at-target table
RANKED_SHOWN = 8  # pairs the LaTeX ranking table prints (its caption says when there are more)


def top_pairs(ratio: pd.DataFrame, ranked: pd.Index, count: int = TOP_PAIRS) -> list[str]:
    """At most ``count`` pairs of ``ratio``'s columns, in the recommendation's order
    (``ranked``: the most problems within reach of the best first), that reached the
    target somewhere."""
    reached = [pair for pair in ranked if pair in ratio and ratio[pair].notna().any()]
    return reached[:count] or list(ratio.columns[:count])


def _load_series(
    runs: pd.DataFrame, series_loader: SeriesLoader | None, cost: str = "integrate_s"
) -> dict[str, pd.DataFrame | None] | None:
    """The time series of the runs a problem's figures draw (read in this process): the
    pairs at the middle tolerance and the runs of the error figure."""
    if series_loader is None:
        return None
    _rtol, chosen = drift_runs(runs)
    wanted = list(chosen["run_id"])
    candidates = trusted(runs, cost)
    if not candidates.empty:
        front = candidates[pareto_mask(candidates, cost)].sort_values(cost)
        wanted += [candidates.loc[candidates["scd"].idxmax(), "run_id"], front["run_id"].iloc[0]]
    series: dict[str, pd.DataFrame | None] = {}
    for run_id in dict.fromkeys(wanted):
        try:
            series[run_id] = series_loader(run_id)
        except (WorkbenchError, OSError, ValueError, KeyError) as error:
            # A missing or unreadable series costs one curve, never the report.
            warnings.warn(f"no time series for run {run_id}: {error}", stacklevel=2)
            series[run_id] = None
    return series


def problem_section(
    runs: pd.DataFrame,
    series: Mapping[str, pd.DataFrame | None] | None,
    out: Path,
    cost: str,
    traits: Traits,
    sketch: Sketch | None,
    formats: tuple[str, ...] = REPORT_FORMATS,
) -> ProblemSection:
    """One problem's part of the report (a figure worker's task): draws its figures into
    ``out``/figures in ``formats``, writes its drift table into ``out``/tables. ``traits``
    and ``sketch`` (the model's) come from the parent, so a worker needs no plugin."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    problem = str(runs["problem"].iloc[0])
    with figure_formats(formats):
        work_precision = work_precision_figure(runs, out, problem, cost)
        picture = mechanism_picture(sketch, out, problem) if sketch is not None else None
        drift, rtol = drift_figure(runs, series, out, problem, traits.drift_units)
        error = error_figure(runs, series, out, problem, cost)
    table = None
    if rtol is not None:
        name = f"drift-{slug(problem)}-rtol-{rtol:g}"
        frame = drift_table(runs)
        contents = drift_table_contents(frame, traits.drift_units)
        caption = f"{problem}, every pair at rtol = {rtol:g}: {contents}"
        left_out = drift_left_out(runs, rtol)
        if left_out:
            caption += f"; not in it, no ok run there: {', '.join(left_out)}"
        write_table(frame, out / "tables", name, caption)
        table = PageTable.of(frame, name)
    return ProblemSection(
        problem=problem,
        anchor=slug(problem),
        runs=len(runs),
        status_counts=status_counts(runs),
        work_precision=work_precision,
        rtol=rtol,
        drift=drift,
        drift_table=table,
        error=error,
        picture=picture,
        traits=traits,
        reference=reference_source(runs),
    )
