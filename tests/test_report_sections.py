"""A report rebuilt problem by problem (issue 35, workbench.outputs.report.section_cache):
a problem whose rows did not change keeps its figures and tables, the others are drawn
again, and the page is the one a report drawn from nothing gives; a section description
that does not match its files, or that came from someone else, is drawn again."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

from tests.test_report import synthetic_results, synthetic_series, write_results_directory
from workbench.outputs.report import write_report
from workbench.outputs.report.section_cache import SUFFIX

PROBLEMS = ("simple-pendulum", "heavy-top")


def results_of(problems: tuple[str, ...]):
    """Rows of one formalism (a drift figure of one column: less to draw)."""
    return synthetic_results(problems=problems, formalisms=("minimal-ode",))


def written(out: Path) -> dict[str, int]:
    """Every figure and table file: name -> its modification time (ns)."""
    return {
        f"{path.parent.name}/{path.name}": path.stat().st_mtime_ns
        for folder in ("figures", "tables")
        for path in (out / folder).iterdir()
        if not path.name.endswith(SUFFIX)
    }


def page(out: Path) -> str:
    """The page without its date and the folder it is in."""
    text = (out / "index.html").read_text(encoding="utf-8").replace(str(out), "OUT")
    return re.sub(r"Date: [0-9: -]+UTC", "Date: -", text)


def of_problem(names: dict[str, int], problem: str) -> set[str]:
    return {name for name in names if f"{problem}-" in name.split("/")[1]}


def test_only_the_problems_whose_rows_changed_are_drawn_again(tmp_path: Path) -> None:
    results = results_of(PROBLEMS)
    out = tmp_path / "report"
    write_report(results, synthetic_series, out, "cmd", progress=False)
    before = written(out)
    # heavy-top's runs redone: their costs change, so do its figures and tables
    redone = results["problem"] == "heavy-top"
    results.loc[redone, "cpu_s"] *= 1.5
    results.loc[redone, "wall_s"] *= 1.5
    write_report(results, synthetic_series, out, "cmd", progress=False)
    after = written(out)
    kept = of_problem(before, "simple-pendulum")  # the same files, not written again
    assert kept and {n: after[n] for n in kept} == {n: before[n] for n in kept}
    drawn = of_problem(before, "heavy-top")
    assert drawn and all(after[n] != before[n] for n in drawn)
    # the same page and figures as a report of the changed rows drawn from nothing
    fresh = tmp_path / "fresh"
    write_report(results, synthetic_series, fresh, "cmd", progress=False)
    assert page(out) == page(fresh)
    for name in written(fresh):
        if name.endswith(".png"):
            assert (out / name).read_bytes() == (fresh / name).read_bytes(), name


TAMPERED = ("garbage", "a stem outside the folder", "another key", "a figure changed",
            "a table gone")  # fmt: skip


def tamper(out: Path, how: str) -> None:
    """Spoil simple-pendulum's section in ``out`` as ``how`` says."""
    description = out / "figures" / f"simple-pendulum{SUFFIX}"
    kept = json.loads(description.read_text(encoding="utf-8"))
    if how == "garbage":
        description.write_text("{not json", encoding="utf-8")
    elif how == "a stem outside the folder":
        kept["section"]["drift"]["stem"] = "../../elsewhere"
        description.write_text(json.dumps(kept), encoding="utf-8")
    elif how == "another key":
        kept["key"] = "0" * 64
        description.write_text(json.dumps(kept), encoding="utf-8")
    elif how == "a figure changed":
        (out / "figures" / "simple-pendulum-drift.png").write_bytes(b"not the figure it drew")
    else:
        next((out / "tables").glob("drift-simple-pendulum-*.tex")).unlink()


def test_a_section_that_does_not_match_its_files_is_drawn_again(tmp_path: Path) -> None:
    results = results_of(PROBLEMS[:1])
    out = tmp_path / "report"
    write_report(results, synthetic_series, out, "cmd", progress=False)
    drift_png = out / "figures" / "simple-pendulum-drift.png"
    for how in TAMPERED:  # each one drawn again, which mends the section for the next
        tamper(out, how)
        before = drift_png.stat().st_mtime_ns
        write_report(results, synthetic_series, out, "cmd", progress=False)
        assert drift_png.stat().st_mtime_ns != before, how  # drawn again
        assert drift_png.read_bytes().startswith(b"\x89PNG"), how
        assert len(list((out / "tables").glob("drift-simple-pendulum-*.tex"))) == 1, how
        description = json.loads((out / "figures" / f"simple-pendulum{SUFFIX}").read_text())
        assert description["key"] != "0" * 64, how
    assert not (tmp_path / "elsewhere.png").exists()


def test_workbench_report_twice_keeps_every_problems_figures(tmp_path: Path) -> None:
    """Across processes (each its own hash seed): nothing changed, nothing drawn again."""
    write_results_directory(tmp_path / "sweep")
    command = [sys.executable, "-m", "workbench", "report", str(tmp_path / "sweep")]
    environment = dict(os.environ)
    for seed in ("1", "2"):
        environment["PYTHONHASHSEED"] = seed
        done = subprocess.run(command, capture_output=True, text=True, env=environment)
        assert done.returncode == 0, done.stderr
        if seed == "1":
            first = written(tmp_path / "sweep" / "report")
    second = written(tmp_path / "sweep" / "report")
    sections = {n: t for n, t in first.items() if "simple-pendulum-" in n}
    assert sections and {n: second[n] for n in sections} == sections
