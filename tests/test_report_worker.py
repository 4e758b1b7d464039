"""A report worker killed from outside (issue 31.5) costs time, not the report: the
problems it took with it are drawn again in the parent, with one warning line, and
``workbench sweep`` ends with its report whole and exit 0 (it was a BrokenProcessPool
traceback and exit 1)."""

from __future__ import annotations

import multiprocessing
import os
import signal
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tests.test_sweep import spec_text
from workbench import cli
from workbench.outputs.report import writer
from workbench.runs import store
from workbench.runs.sweep import parse_spec, run_sweep

PROBLEMS = '["test-pendulum", "test-slider-crank"]'
REAL_SECTION = writer.problem_section  # (a spawned worker imports this module afresh)


def section_killing_its_worker_once(runs, series, out, cost, traits, sketch, formats):
    """problem_section, but the first call in a pool worker SIGKILLs that worker, as the
    OOM killer would (a marker file in the report folder makes it once)."""
    if multiprocessing.parent_process() is not None:
        try:
            os.close(os.open(Path(out) / "killed-once", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            pass
        else:
            os.kill(os.getpid(), signal.SIGKILL)
    return REAL_SECTION(runs, series, out, cost, traits, sketch, formats)


@pytest.fixture
def killing_pool(monkeypatch):
    monkeypatch.setattr(writer, "problem_section", section_killing_its_worker_once)
    monkeypatch.setattr(writer, "figure_jobs", lambda n_problems: 2)  # a pool, not inline


def test_write_report_redraws_what_a_killed_worker_took(fake_plugins, tmp_path, killing_pool):
    out = tmp_path / "out"
    run_sweep(parse_spec(spec_text(out, '["test-rk45"]', PROBLEMS)), show_progress=False)
    frame = store.load_results(out)
    with pytest.warns(UserWarning, match="a report worker process died") as caught:
        index = writer.write_report(
            frame, lambda run_id: store.load_series(out, run_id), tmp_path / "report", "test",
            jobs=2,
        )  # fmt: skip
    assert (tmp_path / "report" / "killed-once").exists()  # a worker was killed
    assert len([w for w in caught if "report worker" in str(w.message)]) == 1
    page = index.read_text()
    for problem in ("test-pendulum", "test-slider-crank"):
        assert f'id="{problem}"' in page
        assert list((tmp_path / "report" / "figures").glob(f"*{problem}*.png"))


def test_sweep_with_a_killed_report_worker_is_one_line_and_a_whole_report(
    fake_plugins, tmp_path, killing_pool, monkeypatch
) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(tmp_path / "out", '["test-rk45"]', PROBLEMS))
    result = CliRunner().invoke(cli.app, ["sweep", str(spec)])
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output and result.exception is None
    lines = [line for line in result.output.splitlines() if "report worker" in line]
    assert len(lines) == 1 and lines[0].startswith("warning: "), result.output
    report = tmp_path / "out" / "report"
    assert (report / "killed-once").exists()
    page = (report / "index.html").read_text()
    assert 'id="test-pendulum"' in page and 'id="test-slider-crank"' in page


def section_that_fails(*arguments):
    raise RuntimeError("drawing failed")


def test_a_report_that_cannot_be_finished_is_one_line_exit_1_and_the_rows_kept(
    fake_plugins, tmp_path, monkeypatch
) -> None:
    monkeypatch.setattr(writer, "problem_section", section_that_fails)
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(tmp_path / "out", '["test-rk45"]', PROBLEMS))
    result = CliRunner().invoke(cli.app, ["sweep", str(spec)])
    assert result.exit_code == 1, result.output
    assert not isinstance(result.exception, RuntimeError)  # said in one line, not raised
    last = result.output.strip().splitlines()[-1]
    assert last.startswith("error: the report of ") and "drawing failed" in last, result.output
    assert f"rebuild it with `workbench report {tmp_path / 'out'}`" in last
    assert len(store.load_results(tmp_path / "out")) == 4


WORKER = """
import pickle, sys
from workbench.outputs.report.writer import problem_section
arguments = pickle.loads(open(sys.argv[1], "rb").read())
section = problem_section(*arguments)
assert section.picture is not None and section.work_precision is not None, section
heavy = ("casadi", "scipy.integrate", "workbench.plugins.", "workbench.problems.")
print(" ".join(sorted(name for name in sys.modules if name.startswith(heavy))))
"""


def test_a_figure_worker_draws_a_problem_without_its_plugin(tmp_path) -> None:
    """A figure worker's task imports neither CasADi nor the plugins (issue 35): the
    problem's traits and picture geometry are made in the parent, which has them loaded.
    A worker that built the model itself was 230 MiB, the default sweep's peak memory."""
    import pickle
    import subprocess
    import sys

    from tests.test_report import synthetic_results
    from workbench.outputs.report.analysis import prepare_results
    from workbench.outputs.report.picture import mechanism_sketch
    from workbench.outputs.report.traits import problem_traits

    runs = prepare_results(synthetic_results(problems=("four-bar",)))
    traits = problem_traits(runs)
    sketch = mechanism_sketch(traits.model)
    assert sketch is not None and traits.family == "closed loops"
    traits.model = None
    for folder in ("figures", "tables"):
        (tmp_path / folder).mkdir()
    (tmp_path / "arguments.pickle").write_bytes(
        pickle.dumps((runs, None, tmp_path, "wall_s", traits, sketch))
    )
    done = subprocess.run(
        [sys.executable, "-c", WORKER, str(tmp_path / "arguments.pickle")],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert done.stdout.split() == [], done.stdout
    assert (tmp_path / "figures" / "four-bar-picture.png").stat().st_size > 0


def test_a_few_problems_are_drawn_without_worker_processes() -> None:
    """The quick suite's 6 problems are drawn in the report's process: two spawned workers
    took more CPU (their start) and twice the memory (issue 35: 604 against 263 MiB PSS)."""
    from workbench.outputs.report.pool import PROBLEMS_PER_WORKER, figure_jobs

    assert figure_jobs(6) == figure_jobs(2 * PROBLEMS_PER_WORKER - 1) == 1
    assert figure_jobs(100) == min(os.cpu_count() or 1, 8) or figure_jobs(100) == 1


def test_a_report_drawn_here_steps_its_progress_after_each_problem() -> None:
    """Drawn in this process (a small report), each problem's figures are made when its
    result is asked for, so the bar steps between problems, not all at the end."""
    from workbench.outputs.report.pool import InlineExecutor, results_or_redone

    events: list[str] = []

    def draw(name: str) -> str:
        events.append(f"draw {name}")
        return name.upper()

    executor = InlineExecutor()
    tasks = [(name, executor.submit(draw, name), (name,)) for name in ("a", "b", "c")]
    assert events == []  # nothing drawn at submission
    done = results_or_redone(tasks, draw, lambda name: events.append(f"done {name}"))
    assert done == ["A", "B", "C"]
    assert events == ["draw a", "done a", "draw b", "done b", "draw c", "done c"]


def test_an_error_in_a_problem_drawn_here_reaches_the_caller() -> None:
    from workbench.outputs.report.pool import InlineExecutor

    def fail() -> None:
        raise RuntimeError("no figure")

    future = InlineExecutor().submit(fail)
    with pytest.raises(RuntimeError, match="no figure"):
        future.result()
    with pytest.raises(RuntimeError, match="no figure"):  # asked again: the same error
        future.result()
