"""The one progress bar of sweeps, references and reports (workbench/runs/progress.py)."""

from __future__ import annotations

import pytest

from workbench.runs.progress import progress_bar


@pytest.mark.parametrize("threaded", [True, False])
def test_bar_shows_name_text_count_and_note(capsys: pytest.CaptureFixture, threaded: bool) -> None:
    with progress_bar("sweep", 3, transient=False, threaded=threaded) as bar:
        bar.step("radau[order=5]")  # brackets are text, not rich markup
        bar.update(3, "ok 2  failed 1")
        bar.tick()
    err = capsys.readouterr().err
    assert "sweep" in err and "3/3" in err and "ok 2  failed 1" in err


def test_step_text_follows_the_name(capsys: pytest.CaptureFixture) -> None:
    with progress_bar("report", 2, transient=False) as bar:
        bar.step("heavy-top")
        bar.step("radau[order=5]")
    err = capsys.readouterr().err
    assert "report: radau[order=5]" in err and "2/2" in err


def test_hidden_bar_draws_nothing(capsys: pytest.CaptureFixture) -> None:
    with progress_bar("references", 2, show=False) as bar:
        bar.step("x")
        bar.update(2, "note")
        bar.tick()
    assert capsys.readouterr().err == ""


def test_plain_lines_say_the_time_left_at_the_pace_so_far(monkeypatch) -> None:
    """A 800-run sweep printed only the time elapsed; once 5 s have passed the lines add
    what is left at the pace so far (none at the end, none before any run is done)."""
    import io

    from workbench.runs import progress

    clock = iter([0.0, 10.0, 20.0])
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    stream = io.StringIO()
    lines = progress.ProgressLines("sweep", 4, stream=stream)  # started at t = 0
    lines.update(1)  # t = 10 s: 1 of 4 done
    lines.update(4)  # t = 20 s: done
    first, last = stream.getvalue().splitlines()
    assert first == "sweep  1/4 (25%)  0:00:10, about 0:00:30 left"
    assert last == "sweep  4/4 (100%)  0:00:20"
