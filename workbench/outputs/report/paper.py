"""A paper folder of a report: ``main.tex`` that ``\\input``s the report's LaTeX tables
and includes its figures as PDF, beside ``tables/*.tex`` and ``figures/*.pdf`` a user can
``\\input`` and include in their own document.

The document is plain ``article`` with booktabs, longtable and graphicx (all in TeX
Live's latex-base / latex-recommended), and compiles with ``pdflatex main.tex`` (run
twice: a longtable's columns line up from the second pass); :func:`compile_paper` does
so where pdflatex is installed, as often as the log asks, and reads it for overfull
boxes. Written by ``workbench paper`` (:func:`write_paper`).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from workbench.errors import ConfigError
from workbench.outputs.report.figures import FigureFiles
from workbench.outputs.report.tables import latex_escape

MAIN = "main.tex"
PREAMBLE = r"""\documentclass{article}
\usepackage{booktabs}
\usepackage{longtable}
\usepackage{graphicx}
"""
OVERFULL = re.compile(r"Overfull \\hbox \((\d+(?:\.\d+)?)pt too wide\)")
RERUN = re.compile(r"Rerun (?:LaTeX|to get)")
"""What pdflatex's log says when the document needs another pass: longtable sets a part's
columns from the widths the previous pass wrote to main.aux (one pass left every split
table's columns out of line with its rules)."""
PASSES = 3  # pdflatex passes at most (longtable settles in two, labels in one more)


@dataclass
class PaperSection:
    """What the paper shows of one problem: its figures and its tables' stems."""

    problem: str
    figures: list[FigureFiles]
    tables: list[str]


def figure_block(figure: FigureFiles) -> str:
    """A figure float including the PDF of ``figure`` at the text width."""
    return "\n".join([
        r"\begin{figure}[htbp]",
        r"\centering",
        rf"\includegraphics[width=\linewidth,height=0.75\textheight,keepaspectratio]"
        rf"{{figures/{figure.stem}.pdf}}",
        rf"\caption{{{latex_escape(figure.caption)}}}",
        r"\end{figure}",
    ])  # fmt: skip


def write_paper(
    report: Path,
    paper: Path,
    title: str,
    intro: Sequence[str],
    tables: Sequence[str],
    figures: Sequence[FigureFiles],
    sections: Sequence[PaperSection],
    closing_tables: Sequence[str] = (),
) -> Path:
    """Copy the LaTeX tables and PDF figures of the report in ``report`` into ``paper``
    and write ``main.tex``: ``intro`` paragraphs, ``tables`` and ``figures`` (stems of
    tables/, figures), a subsection a problem, then ``closing_tables``. Returns main.tex."""
    (paper / "tables").mkdir(parents=True, exist_ok=True)
    (paper / "figures").mkdir(exist_ok=True)
    stems = [*tables, *closing_tables, *(t for s in sections for t in s.tables)]
    for stem in stems:
        shutil.copyfile(report / "tables" / f"{stem}.tex", paper / "tables" / f"{stem}.tex")
    for figure in [*figures, *(f for s in sections for f in s.figures)]:
        source = report / figure.link("pdf")
        shutil.copyfile(source, paper / "figures" / source.name)
    body = [PREAMBLE, r"\begin{document}", rf"\section*{{{latex_escape(title)}}}"]
    body += [latex_escape(paragraph) + "\n" for paragraph in intro]
    body += [rf"\input{{tables/{stem}}}" for stem in tables]
    body += [figure_block(figure) for figure in figures]
    body.append(r"\clearpage")
    for section in sections:
        body.append(rf"\subsection*{{{latex_escape(section.problem)}}}")
        body += [figure_block(figure) for figure in section.figures]
        body += [rf"\input{{tables/{stem}}}" for stem in section.tables]
        body.append(r"\clearpage")  # floats stay with their problem
    body += [rf"\input{{tables/{stem}}}" for stem in closing_tables]
    body.append(r"\end{document}")
    main = paper / MAIN
    main.write_text("\n".join(body) + "\n", encoding="utf-8")
    return main


@dataclass
class Compiled:
    """The outcome of :func:`compile_paper`: the PDF (None: not made), the widest
    overfull box in pt (0: none) and the end of pdflatex's output when it failed."""

    pdf: Path | None
    overfull_pt: float
    log_tail: str = ""


def pdflatex() -> str | None:
    """The pdflatex on PATH, or None."""
    return shutil.which("pdflatex")


def compile_paper(main: Path, timeout: float = 600.0) -> Compiled:
    """Run pdflatex on ``main`` in its folder (ConfigError when pdflatex is missing), again
    while its log asks for another pass (:data:`RERUN`), :data:`PASSES` times at most."""
    engine = pdflatex()
    if engine is None:
        raise ConfigError(
            "pdflatex is not installed: apt-get install texlive-latex-base "
            "texlive-latex-recommended, or compile main.tex elsewhere"
        )
    log = main.with_suffix(".log")
    for _ in range(PASSES):
        run = subprocess.run(
            [engine, "-interaction=nonstopmode", "-halt-on-error", main.name],
            cwd=main.parent,
            capture_output=True,
            text=True,
            timeout=timeout,
            stdin=subprocess.DEVNULL,
        )
        text = log.read_text(encoding="utf-8", errors="replace") if log.is_file() else run.stdout
        if run.returncode != 0 or not RERUN.search(text):
            break
    widths = [float(width) for width in OVERFULL.findall(text)]
    pdf = main.with_suffix(".pdf")
    made = run.returncode == 0 and pdf.is_file()
    return Compiled(pdf if made else None, max(widths, default=0.0), "" if made else text[-3000:])
