"""Static HTML reports of a sweep (DESIGN.md, "Runs, results, reports").

:func:`write_report` turns a results DataFrame (one row a run; the columns of
:mod:`workbench.runs.store`) and the runs' time series into a directory::

    index.html              the page: tables shown, figures linked as PNG
    figures/*.png|svg|pdf   work-precision diagrams and drift / energy over time
    tables/*.csv|md|tex     the summary, the status matrix and all result rows

Per problem it draws a work-precision diagram (scd against wall seconds and against
right-hand-side evaluations, log x; one curve per formalism x integrator, one point per
tolerance) and, for every pair at the middle tolerance, the position, velocity and
nonholonomic constraint drift and the energy error over time (log y). The summary names,
for each problem and target accuracy (scd >= 2, 4, 6), the cheapest pair (least wall
time) that reached it; the status matrix counts ok / failed / timeout / skipped runs and
lists the reasons in footnotes. A footer records library versions, the machine, the date
and the command that made the report.

Only pandas and matplotlib (Agg) are used; LaTeX and Markdown tables are written by the
small writers below, so neither jinja2 nor tabulate is needed.
"""

from __future__ import annotations

import html
import importlib.metadata
import json
import math
import os
import platform
import re
import sys
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.errors import ConfigError, WorkbenchError

STATUSES: tuple[str, ...] = ("ok", "failed", "timeout", "skipped")
TARGET_SCD: tuple[float, ...] = (2.0, 4.0, 6.0)
REQUIRED_COLUMNS: tuple[str, ...] = ("problem", "formalism", "integrator", "rtol", "status")
NUMERIC_COLUMNS: tuple[str, ...] = (
    "atol",
    "wall_s",
    "cpu_s",
    "n_rhs",
    "n_jac",
    "n_steps",
    "n_rejected",
    "err_max",
    "err_end",
    "scd",
    "drift_pos_max",
    "drift_vel_max",
    "drift_nh_max",
    "energy_err_max",
    "invariant_err_max",
)
DRIFT_QUANTITIES: tuple[tuple[str, str], ...] = (
    ("drift_pos", "position constraint drift"),
    ("drift_vel", "velocity constraint drift"),
    ("drift_nh", "nonholonomic constraint drift"),
    ("energy_err", "relative energy error"),
)
FIGURE_FORMATS: tuple[str, ...] = ("png", "svg", "pdf")
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

SeriesLoader = Callable[[str], pd.DataFrame | None]


# -- entry point ------------------------------------------------------------------------
def write_report(
    results: pd.DataFrame,
    series_loader: SeriesLoader | None,
    out_dir: str | Path,
    command: str,
    *,
    title: str = "mbs-workbench report",
    progress: bool | None = None,
    jobs: int | None = None,
) -> Path:
    """Write the report of ``results`` into ``out_dir``; return the path of ``index.html``.

    results: one row a run, at least the columns of :data:`REQUIRED_COLUMNS` (missing
        numeric columns count as not measured).
    series_loader: ``run_id -> DataFrame`` (columns t, drift_pos, drift_vel, drift_nh,
        energy_err, ...) or None when a run has no series; ``None`` draws no drift plots.
    command: the exact command line that produced the report (printed in the footer).
    progress: show a rich progress bar on stderr; default: when there are several problems.
    jobs: processes drawing figures; default: one per CPU when there are 4 problems or more.
    """
    runs = prepare_results(results)
    out = Path(out_dir)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "tables").mkdir(parents=True, exist_ok=True)

    problems = list(dict.fromkeys(runs["problem"]))
    summary = cheapest_pairs(runs)
    matrix, footnotes = status_matrix(runs)
    tables = [
        ("summary", "Cheapest pair reaching each accuracy", summary),
        ("status", "Run status (ok / failed / timeout / skipped)", matrix),
    ]
    for name, _caption, table in tables:
        write_table(table, out / "tables", name)
    labels = ["pair", "formalism_label", "integrator_label"]
    runs.drop(columns=labels).to_csv(out / "tables" / "results.csv", index=False)

    jobs = _jobs(len(problems)) if jobs is None else max(1, jobs)
    with _Progress(len(problems), progress) as advance, _executor(jobs) as executor:
        pending = []
        for problem in problems:
            of_problem = runs[runs["problem"] == problem]
            series = _load_series(of_problem, series_loader)
            pending.append(executor.submit(_problem_section, of_problem, series, out))
        sections = []
        for problem, future in zip(problems, pending, strict=True):
            sections.append(future.result())
            advance(problem)

    page = _page(title, runs, tables, footnotes, sections, command)
    index = out / "index.html"
    index.write_text(page, encoding="utf-8")
    return index


def report_directory(
    results_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str] | None = None,
    command: str | None = None,
    *,
    progress: bool | None = None,
) -> Path:
    """The report of a results directory written by :mod:`workbench.runs.store` (or of a
    results.parquet); return the path of its ``index.html``.

    out_dir: default ``<results directory>/report``. command: for the footer; default the
    equivalent ``workbench report`` command line. Time series are read from the directory's
    ``series/``; runs without one get no drift curve. Raises ConfigError when there are no
    results. Warnings of :func:`workbench.runs.store.load_results` (unreadable rows) pass through.
    """
    import shlex

    from workbench.runs.store import load_results, load_series

    source = Path(results_path)
    if not source.exists():
        raise ConfigError(f"no results at {source}: give the output directory of `workbench sweep`")
    frame = load_results(source)
    if len(frame) == 0:
        raise ConfigError(f"no result rows in {source}: run `workbench sweep --out {source}` first")
    directory = source if source.is_dir() else source.parent
    target = Path(out_dir) if out_dir is not None else directory / "report"

    def series_loader(run_id: str) -> pd.DataFrame | None:
        try:
            return load_series(directory, run_id)
        except (ConfigError, OSError, ValueError):  # no or unreadable series: no curve
            return None

    if command is None:
        command = shlex.join(["workbench", "report", str(source), "-o", str(target)])
    return write_report(frame, series_loader, target, command, progress=progress)


def _load_series(
    runs: pd.DataFrame, series_loader: SeriesLoader | None
) -> dict[str, pd.DataFrame | None] | None:
    """The time series of the runs a problem's drift figure draws (read in this process)."""
    if series_loader is None:
        return None
    _rtol, chosen = drift_runs(runs)
    series: dict[str, pd.DataFrame | None] = {}
    for run_id in chosen["run_id"]:
        try:
            series[run_id] = series_loader(run_id)
        except (WorkbenchError, OSError, ValueError, KeyError) as error:
            # A missing or unreadable series costs one curve, never the report.
            warnings.warn(f"no time series for run {run_id}: {error}", stacklevel=2)
            series[run_id] = None
    return series


def _jobs(n_problems: int) -> int:
    """Figures are drawn in worker processes only when there are enough problems to pay
    for starting them (about a second each)."""
    return min(os.cpu_count() or 1, n_problems, 8) if n_problems >= 4 else 1


def _executor(jobs: int) -> Executor:
    """A spawn-based process pool (fork is unsafe with the threads of rich and rerun), or an
    executor running each task at once in this process."""
    if jobs <= 1:
        return _InlineExecutor()
    import multiprocessing

    return ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"))


class _InlineExecutor(Executor):
    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as error:  # handed to the caller by future.result()
            future.set_exception(error)
        return future


# -- the data ---------------------------------------------------------------------------
def prepare_results(results: pd.DataFrame) -> pd.DataFrame:
    """A copy of ``results``: numeric columns as floats, labels of formalism, integrator, pair.

    Raises ConfigError when a required column is missing.
    """
    if not isinstance(results, pd.DataFrame):
        raise ConfigError(f"results must be a pandas DataFrame, got {type(results).__name__}")
    missing = [column for column in REQUIRED_COLUMNS if column not in results.columns]
    if missing:
        raise ConfigError(
            f"results lack the column(s) {', '.join(missing)}; "
            "give a table written by workbench.runs.store (see DESIGN.md, 'Runs, results, reports')"
        )
    runs = results.copy().reset_index(drop=True)
    for column in NUMERIC_COLUMNS + ("rtol",):
        runs[column] = (
            pd.to_numeric(runs[column], errors="coerce") if column in runs else float("nan")
        )
    for column in ("run_id", "message", "formalism_options", "integrator_options"):
        if column not in runs:
            runs[column] = ""
        runs[column] = runs[column].fillna("").astype(str)
    if not runs["run_id"].str.len().any():
        runs["run_id"] = [f"run-{index}" for index in range(len(runs))]
    for column in ("problem", "formalism", "integrator", "status"):
        runs[column] = runs[column].astype(str)
    runs["formalism_label"], runs["integrator_label"] = pair_labels(runs)
    runs["pair"] = runs["formalism_label"] + " / " + runs["integrator_label"]
    return runs


def pair_labels(runs: pd.DataFrame) -> tuple[pd.Series, pd.Series]:
    """Formalism and integrator labels per row, with the options that vary appended.

    An option appears in the label only when the same plugin was run with different
    values of it, so curves stay distinguishable and labels stay short.
    """
    formalism = _with_varying_options(runs["formalism"], runs["formalism_options"])
    integrator = _with_varying_options(runs["integrator"], runs["integrator_options"])
    return formalism, integrator


def _with_varying_options(names: pd.Series, options: pd.Series) -> pd.Series:
    labels = names.copy()
    for name in names.unique():
        rows = names == name
        distinct = options[rows].unique()
        if len(distinct) < 2:
            continue
        parsed = {text: _parse_options(text) for text in distinct}
        keys = sorted({key for value in parsed.values() for key in value})
        varying = [
            key for key in keys if len({repr(value.get(key)) for value in parsed.values()}) > 1
        ]
        suffix = {
            text: ",".join(f"{key}={value[key]}" for key in varying if key in value)
            for text, value in parsed.items()
        }
        labels[rows] = [f"{name}[{suffix[text]}]" for text in options[rows]]
    return labels


def _parse_options(text: str) -> dict[str, Any]:
    if not text:
        return {}
    try:
        value = json.loads(text)
    except ValueError:
        return {"options": text}
    return value if isinstance(value, dict) else {"options": value}


def _ok(runs: pd.DataFrame) -> pd.DataFrame:
    return runs[runs["status"] == "ok"]


def cheapest_pairs(runs: pd.DataFrame, targets: Sequence[float] = TARGET_SCD) -> pd.DataFrame:
    """For each problem and target scd: the ok run of least wall time with scd >= target.

    One row per (problem, target); problems where no run reached a target say so.
    ``runs`` is the output of :func:`prepare_results`.
    """
    rows = []
    for problem, group in runs.groupby("problem", sort=False):
        ok = _ok(group)
        ok = ok[np.isfinite(ok["scd"]) & np.isfinite(ok["wall_s"])]
        for target in targets:
            reached = ok[ok["scd"] >= target]
            if reached.empty:
                rows.append({"problem": problem, "target scd": target, "pair": "none reached"})
                continue
            best = reached.loc[reached["wall_s"].idxmin()]
            rows.append(
                {
                    "problem": problem,
                    "target scd": target,
                    "pair": best["pair"],
                    "rtol": best["rtol"],
                    "scd": best["scd"],
                    "wall_s": best["wall_s"],
                    "n_rhs": best["n_rhs"],
                }
            )
    columns = ["problem", "target scd", "pair", "rtol", "scd", "wall_s", "n_rhs"]
    return pd.DataFrame(rows, columns=columns)


def status_matrix(runs: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Problem x pair table of status counts, and the footnotes giving the reasons.

    A cell reads e.g. ``4 ok, 1 failed [2]``: footnote 2 is the message of that failure.
    Footnotes group runs with the same status and message.
    """
    footnote_ids: dict[tuple[str, str], int] = {}
    footnote_runs: dict[tuple[str, str], list[str]] = {}
    for row in runs[runs["status"] != "ok"].itertuples():
        key = (row.status, _one_line(row.message) or "no reason recorded")
        footnote_ids.setdefault(key, len(footnote_ids) + 1)
        footnote_runs.setdefault(key, []).append(f"{row.problem}: {row.pair}")
    problems = list(dict.fromkeys(runs["problem"]))
    pairs = sorted(runs["pair"].unique())
    cells = pd.DataFrame("", index=pd.Index(problems, name="problem"), columns=pairs)
    for (problem, pair), group in runs.groupby(["problem", "pair"], sort=False):
        parts = []
        for status in _statuses(group["status"]):
            of_status = group[group["status"] == status]
            text = f"{len(of_status)} {status}"
            if status != "ok":
                keys = {
                    (status, _one_line(message) or "no reason recorded")
                    for message in of_status["message"]
                }
                text += " [" + ",".join(str(i) for i in sorted(footnote_ids[k] for k in keys)) + "]"
            parts.append(text)
        cells.loc[problem, pair] = ", ".join(parts)
    cells = cells.replace("", "-")
    footnotes = []
    for key, number in footnote_ids.items():
        where = list(dict.fromkeys(footnote_runs[key]))
        shown = "; ".join(where[:5]) + (f"; ... ({len(where) - 5} more)" if len(where) > 5 else "")
        runs_count = len(footnote_runs[key])
        footnotes.append(f"[{number}] {key[0]}: {key[1]} ({runs_count} run(s): {shown})")
    return cells, footnotes


def _statuses(values: Iterable[str]) -> list[str]:
    present = set(values)
    return [s for s in STATUSES if s in present] + sorted(present - set(STATUSES))


def _one_line(text: str, limit: int = 300) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def middle_tolerance(rtols: Iterable[float]) -> float | None:
    """The middle of the distinct finite tolerances (the larger middle one if even)."""
    values = sorted({float(r) for r in rtols if np.isfinite(r)})
    return values[len(values) // 2] if values else None


# -- tables -----------------------------------------------------------------------------
def write_table(table: pd.DataFrame, directory: Path, name: str) -> list[Path]:
    """Write ``table`` as ``name``.csv, .md and .tex (booktabs) into ``directory``."""
    paths = [directory / f"{name}.{ext}" for ext in ("csv", "md", "tex")]
    index = table.index.name is not None
    table.to_csv(paths[0], index=index)
    paths[1].write_text(markdown_table(table, index=index), encoding="utf-8")
    paths[2].write_text(latex_table(table, index=index), encoding="utf-8")
    return paths


def _cell(value: Any) -> str:
    if isinstance(value, float | np.floating):
        if math.isnan(value):
            return ""
        return f"{value:.4g}"
    return str(value)


def _rows(table: pd.DataFrame, index: bool) -> tuple[list[str], list[list[str]]]:
    header = ([table.index.name or ""] if index else []) + [str(c) for c in table.columns]
    rows = []
    for label, row in zip(table.index, table.itertuples(index=False), strict=True):
        rows.append(([str(label)] if index else []) + [_cell(value) for value in row])
    return header, rows


def markdown_table(table: pd.DataFrame, index: bool = False) -> str:
    """A GitHub-flavoured Markdown pipe table (pipes in cells escaped)."""
    header, rows = _rows(table, index)

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|").replace("\n", " ") for c in cells) + " |"

    return (
        "\n".join(
            [line(header), "|" + "|".join("---" for _ in header) + "|"]
            + [line(row) for row in rows]
        )
        + "\n"
    )


_LATEX_SPECIALS = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
}


def latex_escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped."""
    return "".join(_LATEX_SPECIALS.get(char, char) for char in text)


def latex_table(table: pd.DataFrame, index: bool = False) -> str:
    """A booktabs ``tabular`` (needs ``\\usepackage{booktabs}``); numbers right-aligned."""
    header, rows = _rows(table, index)
    kinds = ([False] if index else []) + [
        pd.api.types.is_numeric_dtype(table[column]) for column in table.columns
    ]
    align = "".join("r" if numeric else "l" for numeric in kinds)
    lines = [
        f"\\begin{{tabular}}{{{align}}}",
        "\\toprule",
        " & ".join(latex_escape(cell) for cell in header) + " \\\\",
        "\\midrule",
    ]
    lines += [" & ".join(latex_escape(cell) for cell in row) + " \\\\" for row in rows]
    lines += ["\\bottomrule", "\\end{tabular}"]
    return "\n".join(lines) + "\n"


# -- figures ----------------------------------------------------------------------------
@dataclass
class FigureFiles:
    """A figure written in every format; ``png`` is shown, the others linked."""

    stem: str
    caption: str

    def link(self, fmt: str) -> str:
        return f"figures/{self.stem}.{fmt}"


def _save(figure: Any, out: Path, stem: str, caption: str) -> FigureFiles:
    import matplotlib.pyplot as plt

    # Cropped to what is drawn (the legend's column would leave a blank margin); the box is
    # measured once, since savefig(bbox_inches="tight") would lay out every format again.
    box = figure.get_tightbbox(figure.canvas.get_renderer()).padded(0.1)
    for fmt in FIGURE_FORMATS:
        figure.savefig(
            out / "figures" / f"{stem}.{fmt}", dpi=90 if fmt == "png" else None, bbox_inches=box
        )
    plt.close(figure)
    return FigureFiles(stem, caption)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "problem"


class PairStyles:
    """Colour by integrator, marker and line style by formalism.

    The legend then has one entry per integrator and one per formalism instead of one per
    pair, which keeps it readable (and cheap to draw) for dozens of pairs.
    """

    MARKERS = "osD^v<>pPX*h"
    LINES = ("-", "--", "-.", ":")

    def __init__(self, runs: pd.DataFrame) -> None:
        import matplotlib.pyplot as plt

        parts = runs[["pair", "formalism_label", "integrator_label"]].drop_duplicates("pair")
        self.formalisms = sorted(parts["formalism_label"].unique())
        self.integrators = sorted(parts["integrator_label"].unique())
        colors = plt.get_cmap("tab10" if len(self.integrators) <= 10 else "tab20").colors
        self.colors = {name: colors[k % len(colors)] for k, name in enumerate(self.integrators)}
        self.marks = {
            name: (self.MARKERS[k % len(self.MARKERS)], self.LINES[k % len(self.LINES)])
            for k, name in enumerate(self.formalisms)
        }
        self.parts = dict(
            zip(
                parts["pair"],
                zip(parts["formalism_label"], parts["integrator_label"], strict=True),
                strict=True,
            )
        )

    def __call__(self, pair: str, markers: bool = True) -> dict[str, Any]:
        formalism, integrator = self.parts[pair]
        marker, linestyle = self.marks[formalism]
        style = {"color": self.colors[integrator], "linestyle": linestyle, "label": pair}
        if markers:
            style["marker"] = marker
        return style

    def legend(self, figure: Any, markers: bool = True) -> None:
        """Integrators (colours) and formalisms (line styles) right of the axes."""
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], color=self.colors[name]) for name in self.integrators]
        handles += [
            Line2D(
                [],
                [],
                color="black",
                linestyle=self.marks[name][1],
                marker=self.marks[name][0] if markers else None,
            )
            for name in self.formalisms
        ]
        labels = [f"integrator {name}" for name in self.integrators]
        labels += [f"formalism {name}" for name in self.formalisms]
        figure.legend(
            handles,
            labels,
            loc="upper left",
            bbox_to_anchor=(0.71, 0.92),
            fontsize="small" if len(labels) <= 12 else "x-small",
            ncols=1 if len(labels) <= 30 else 2,
            frameon=False,
        )


def _log_axis(ax: Any, which: str) -> None:
    """Log scale with plain-text labels (1e-06): mathtext labels cost most of the drawing."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    getattr(ax, f"set_{which}scale")("log")
    axis = getattr(ax, f"{which}axis")
    axis.set_major_locator(LogLocator(numticks=8))
    axis.set_major_formatter(FuncFormatter(lambda value, _position: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def work_precision_figure(runs: pd.DataFrame, out: Path, problem: str) -> FigureFiles | None:
    """scd against wall seconds and against rhs evaluations (log x), one curve a pair."""
    import matplotlib.pyplot as plt

    ok = _ok(runs)
    ok = ok[np.isfinite(ok["scd"])]
    if ok.empty:
        return None
    pairs = sorted(ok["pair"].unique())
    styles = PairStyles(ok)
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    figure.subplots_adjust(left=0.06, right=0.70, bottom=0.12, top=0.88, wspace=0.08)
    for pair in pairs:
        curve = ok[ok["pair"] == pair].sort_values("rtol", ascending=False)
        for ax, cost in zip(axes, ("wall_s", "n_rhs"), strict=True):
            points = curve[np.isfinite(curve[cost]) & (curve[cost] > 0)]
            if not points.empty:
                ax.plot(points[cost], points["scd"], markersize=4, linewidth=1, **styles(pair))
    for ax, xlabel in zip(axes, ("wall time [s]", "right-hand-side evaluations"), strict=True):
        _log_axis(ax, "x")
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("scd (correct digits at the end)")
    figure.suptitle(f"{problem}: work-precision (one point per tolerance)", x=0.38)
    styles.legend(figure)
    return _save(
        figure,
        out,
        f"{_slug(problem)}-work-precision",
        f"{problem}: work-precision diagrams (scd against wall time and rhs evaluations)",
    )


def drift_runs(runs: pd.DataFrame) -> tuple[float | None, pd.DataFrame]:
    """The middle tolerance of a problem's ok runs and one ok run per pair at it."""
    ok = _ok(runs)
    rtol = middle_tolerance(ok["rtol"])
    if rtol is None:
        return None, ok.iloc[:0]
    chosen = ok[np.isclose(ok["rtol"], rtol, rtol=1e-9, atol=0)]
    return rtol, chosen.drop_duplicates("pair").sort_values("pair")


DRIFT_TABLE_COLUMNS: tuple[str, ...] = (
    "drift_pos_max",
    "drift_vel_max",
    "drift_nh_max",
    "energy_err_max",
    "invariant_err_max",
    "err_max",
    "scd",
)


def drift_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per pair at the middle tolerance: the maxima over time of the drifts and
    errors (columns left out when no run measured them)."""
    _rtol, chosen = drift_runs(runs)
    columns = [c for c in DRIFT_TABLE_COLUMNS if chosen[c].notna().any()]
    return chosen[["pair", *columns]].reset_index(drop=True)


def drift_figure(
    runs: pd.DataFrame, series: Mapping[str, pd.DataFrame | None] | None, out: Path, problem: str
) -> tuple[FigureFiles | None, float | None]:
    """Drift and energy error over time for every pair at the middle tolerance (log y).

    series: run_id -> that run's time series (None or missing: not drawn).
    """
    import matplotlib.pyplot as plt

    rtol, chosen = drift_runs(runs)
    if series is None or rtol is None:
        return None, rtol
    styles = PairStyles(chosen)
    figure, axes = plt.subplots(2, 2, figsize=(12, 7.5), sharex=True)
    figure.subplots_adjust(left=0.07, right=0.70, bottom=0.08, top=0.91, wspace=0.22, hspace=0.18)
    drawn: set[str] = set()
    for row in chosen.itertuples():
        run_series = series.get(row.run_id)
        if run_series is None or len(run_series) == 0 or "t" not in run_series:
            continue
        if "run_id" in run_series:
            run_series = run_series[run_series["run_id"].astype(str) == row.run_id]
        t = run_series["t"].to_numpy(dtype=float)
        for ax, (column, _label) in zip(axes.flat, DRIFT_QUANTITIES, strict=True):
            if column not in run_series:
                continue
            values = np.abs(run_series[column].to_numpy(dtype=float))
            keep = np.isfinite(values) & (values > 0)
            if keep.any():
                ax.plot(t[keep], values[keep], linewidth=1, **styles(row.pair, markers=False))
                drawn.add(column)
    if not drawn:
        plt.close(figure)
        return None, rtol
    for ax, (column, label) in zip(axes.flat, DRIFT_QUANTITIES, strict=True):
        ax.set_title(label, fontsize="medium")
        if column in drawn:
            _log_axis(ax, "y")
        else:
            ax.text(
                0.5,
                0.5,
                "none (zero or not measured)",
                ha="center",
                va="center",
                transform=ax.transAxes,
                color="gray",
            )
            ax.set_yticks([])
        ax.grid(True, alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    figure.suptitle(f"{problem}: drift and energy error at rtol = {rtol:g}", x=0.385)
    styles.legend(figure, markers=False)
    caption = f"{problem}: constraint drift and energy error over time at rtol = {rtol:g}"
    return _save(figure, out, f"{_slug(problem)}-drift", caption), rtol


# -- the page ---------------------------------------------------------------------------
CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0; }
th, td { border-bottom: 1px solid #ccc; padding: 0.2em 0.6em; text-align: left; }
.scroll { overflow-x: auto; }
figure { margin: 1em 0; }
figure img { max-width: 100%; }
figcaption, .links, footer { font-size: 0.85em; color: #555; }
footer { border-top: 1px solid #ccc; margin-top: 3em; padding-top: 1em; }
code { background: #f4f4f4; padding: 0 0.2em; }
"""


def _figure_html(files: FigureFiles) -> str:
    caption = html.escape(files.caption)
    others = " ".join(
        f'<a href="{files.link(fmt)}">{fmt.upper()}</a>' for fmt in FIGURE_FORMATS if fmt != "png"
    )
    return (
        f'<figure><a href="{files.link("png")}"><img src="{files.link("png")}" alt="{caption}" '
        f'loading="lazy"></a><figcaption>{caption}. <span class="links">Also as {others}.'
        "</span></figcaption></figure>"
    )


def _table_html(table: pd.DataFrame, index: bool) -> str:
    if index:  # the index name in the header row, not on a header row of its own
        table, index = table.reset_index(), False
    return (
        '<div class="scroll">'
        + table.to_html(
            index=index, escape=True, na_rep="", float_format=lambda x: f"{x:.4g}", border=0
        )
        + "</div>"
    )


def _links(name: str) -> str:
    return "Download: " + " ".join(
        f'<a href="tables/{name}.{ext}">{label}</a>'
        for ext, label in (("csv", "CSV"), ("md", "Markdown"), ("tex", "LaTeX"))
    )


def _problem_section(
    runs: pd.DataFrame, series: Mapping[str, pd.DataFrame | None] | None, out: Path
) -> str:
    """The HTML section of one problem; draws its figures into ``out``/figures."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    problem = str(runs["problem"].iloc[0])
    counts = runs["status"].value_counts()
    status_text = ", ".join(f"{counts[s]} {s}" for s in _statuses(runs["status"]))
    parts = [
        f'<section id="{html.escape(_slug(problem))}"><h2>{html.escape(problem)}</h2>',
        f"<p>{len(runs)} runs: {html.escape(status_text)}.</p>",
    ]
    work_precision = work_precision_figure(runs, out, problem)
    if work_precision is None:
        parts.append("<p>No successful run with a measured scd: no work-precision diagram.</p>")
    else:
        parts.append(_figure_html(work_precision))
    drift, rtol = drift_figure(runs, series, out, problem)
    if drift is not None:
        parts.append(_figure_html(drift))
    elif rtol is None:
        parts.append("<p>No successful run: no drift plot.</p>")
    else:
        parts.append(f"<p>No time series for the runs at rtol = {rtol:g}: no drift plot.</p>")
    if rtol is not None:
        name = f"drift-{_slug(problem)}"
        table = drift_table(runs)
        write_table(table, out / "tables", name)
        parts += [
            f"<h3>Largest drift and errors at rtol = {rtol:g}</h3>",
            _table_html(table, index=False),
            f'<p class="links">{_links(name)}</p>',
        ]
    parts.append("</section>")
    return "\n".join(parts)


def _page(
    title: str,
    runs: pd.DataFrame,
    tables: list[tuple[str, str, pd.DataFrame]],
    footnotes: list[str],
    sections: list[str],
    command: str,
) -> str:
    problems = list(dict.fromkeys(runs["problem"]))
    contents = " ".join(
        f'<a href="#{html.escape(_slug(problem))}">{html.escape(problem)}</a>'
        for problem in problems
    )
    body = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p>{len(runs)} runs, {len(problems)} problem(s), "
        f"{runs['pair'].nunique()} formalism / integrator pair(s). "
        'All result rows: <a href="tables/results.csv">results.csv</a>.</p>',
        f"<p>Problems: {contents}</p>",
    ]
    for name, caption, table in tables:
        index = table.index.name is not None
        body += [f"<h2>{html.escape(caption)}</h2>", _table_html(table, index)]
        if name == "summary":
            body.append(
                "<p>Among the successful runs whose scd (correct significant digits at the "
                "end) reached the target, the one of least wall time.</p>"
            )
        if name == "status" and footnotes:
            body.append(
                '<ol class="footnotes">'
                + "".join(f"<li>{html.escape(note.split('] ', 1)[1])}</li>" for note in footnotes)
                + "</ol>"
            )
        body.append(f'<p class="links">{_links(name)}</p>')
    body += sections
    body.append(_footer(command, runs))
    body.append("</body></html>")
    return "\n".join(body) + "\n"


def library_versions() -> dict[str, str]:
    """Installed versions of the libraries a report depends on ('not installed' if absent)."""
    versions = {"python": platform.python_version()}
    for name in LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def machine_description() -> str:
    """Host, OS, processor and CPU count, on one line."""
    processor = platform.processor() or platform.machine()
    return (
        f"{platform.node()} ({platform.platform()}, {processor}, {os.cpu_count()} CPUs, "
        f"{sys.implementation.name})"
    )


def run_environment(runs: pd.DataFrame) -> list[str]:
    """What the runs recorded about where they ran: 'name: value[, value...]' per column
    (``version_*``, ``machine``, ``cpu_count`` of the result rows; distinct values)."""
    columns = [c for c in runs.columns if c.startswith("version_")]
    columns += [c for c in ("machine", "cpu_count") if c in runs.columns]
    lines = []
    for column in columns:
        values = [str(v) for v in runs[column].dropna().unique() if str(v) not in ("", "nan")]
        if values:
            name = column.removeprefix("version_")
            lines.append(f"{name}: {', '.join(sorted(values)[:5])}")
    return lines


def _footer(command: str, runs: pd.DataFrame) -> str:
    versions = ", ".join(f"{name} {version}" for name, version in library_versions().items())
    date = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    environment = run_environment(runs)
    ran = f"<p>Runs made with: {html.escape('; '.join(environment))}</p>" if environment else ""
    return (
        "<footer>"
        f"{ran}"
        f"<p>Report made with: {html.escape(versions)}</p>"
        f"<p>Machine: {html.escape(machine_description())}</p>"
        f"<p>Date: {date}</p>"
        f"<p>Command: <code>{html.escape(command)}</code></p>"
        "</footer>"
    )


# -- progress ---------------------------------------------------------------------------
class _Progress:
    """``with _Progress(n, enabled) as advance: advance(name)`` - a rich bar on stderr."""

    def __init__(self, total: int, enabled: bool | None) -> None:
        self.total = total
        self.enabled = total > 1 if enabled is None else enabled
        self.bar: Any = None

    def __enter__(self) -> Callable[[str], None]:
        if not self.enabled:
            return lambda name: None
        from rich.console import Console
        from rich.progress import Progress

        self.bar = Progress(console=Console(stderr=True), transient=True)
        self.bar.start()
        task = self.bar.add_task("report", total=self.total)

        def advance(name: str) -> None:
            self.bar.update(task, advance=1, description=f"report: {name}")

        return advance

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.stop()
