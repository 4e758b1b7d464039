"""``workbench.report`` and ``workbench.paper``: the report and the paper folder of a sweep's
results, from a notebook or a script (the CLI's ``workbench report`` and ``paper``)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from workbench.errors import ConfigError


def report(
    results: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    cost: str | None = None,
    wait: bool = False,
) -> Path:
    """Write the HTML report of a results folder (or a results.parquet) and return its
    ``index.html``, as ``workbench report``: figures, and tables as CSV, Markdown and LaTeX.

    ``out``: the report folder (default ``RESULTS/report``). ``cost``: the cost measure of
    its diagrams, tables and recommendation (``integrate_cpu``, the default,
    ``integrate_wall``, ``n_rhs`` or ``work``); without it, the measure the folder's report
    was last made in, so that report and paper agree. A folder is read under its lock
    (``OutputBusyError`` while a sweep writes it, unless ``wait``). What the report finds
    wrong with rows (unreadable files) comes as warnings; ConfigError when there are no
    results.
    """
    return _write(results, out, cost, wait, None)


def paper(
    results: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    cost: str | None = None,
    wait: bool = False,
    compile: bool = True,
) -> Path:
    """Write a paper folder of a results folder (``main.tex`` with the report's LaTeX tables
    and PDF figures, as ``workbench paper``) and return the compiled PDF's path, or
    ``main.tex``'s when ``compile`` is False or pdflatex is not installed (a warning says
    so). ``out``: the paper folder (default ``RESULTS/paper``); ``cost`` and ``wait`` as
    :func:`report`. ConfigError with the end of pdflatex's output when it fails.
    """
    from workbench.outputs.report.paper import MAIN, compile_paper, pdflatex

    source = Path(results) if isinstance(results, str | os.PathLike) else Path()
    folder = Path(out) if out is not None else (
        source if source.is_dir() else source.parent) / "paper"  # fmt: skip
    _write(results, folder / "report", cost, wait, folder)
    main = folder / MAIN
    if not compile:
        return main
    if pdflatex() is None:
        warnings.warn(f"pdflatex not found: compile {main} elsewhere", stacklevel=2)
        return main
    compiled = compile_paper(main)
    if compiled.pdf is None:
        raise ConfigError(f"pdflatex failed on {main}:\n{compiled.log_tail}")
    return compiled.pdf


def _write(
    results: str | os.PathLike[str],
    out: str | os.PathLike[str] | None,
    cost: str | None,
    wait: bool,
    paper_folder: Path | None,
) -> Path:
    """The report, under the results folder's lock when it is a folder."""
    from workbench.outputs.report import kept_cost, report_directory
    from workbench.outputs.report.cost import check_cost
    from workbench.runs.out_lock import out_lock

    check_cost(cost)  # before anything is read
    if not isinstance(results, str | os.PathLike) or not str(results):
        raise ConfigError(f"results: expected the path of a sweep's out, not {results!r}")
    source = Path(results)
    if not source.exists():
        raise ConfigError(f"results: no results folder or file {source}: give a sweep's out")
    if not source.is_dir():
        return report_directory(source, out, cost=cost, paper=paper_folder)
    with out_lock(source, wait=wait, command="workbench.report (Python)"):
        cost = cost if cost is not None else kept_cost(source)
        return report_directory(source, out, cost=cost, paper=paper_folder)
