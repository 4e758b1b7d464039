"""One progress bar on stderr (rich) for every long task: sweeps, references, reports.

``with progress_bar("sweep", total) as bar:`` then ``bar.step(text)`` after each item, or
``bar.update(completed, note)`` when the caller counts itself. The bar reads
``<name>[: <text>]  ━━━━━  3/10  0:00:04 left 0:00:09  <note>``; a disabled bar
(``show=False``) has the same methods and draws nothing, so callers never test whether
it is shown.

Where stderr is not a terminal (piped, ``nohup``, CI) the same calls print plain lines
instead (:class:`ProgressLines`: every tenth of the total and at least every 30 s).

``threaded=False`` draws without rich's refresh thread: the bar is redrawn on each call
(and by :meth:`ProgressBar.tick`), for callers that fork processes while it is shown.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from typing import Any


class ProgressBar:
    """A started bar (or, with ``progress`` None, one that draws nothing)."""

    def __init__(self, name: str, total: int, progress: Any = None, threaded: bool = True) -> None:
        self.name = name
        self._progress = progress
        self._threaded = threaded
        self._task = progress.add_task(name, total=total, note="") if progress else None

    def step(self, text: str | None = None, steps: int = 1) -> None:
        """``steps`` more items done; ``text`` (e.g. the item's name) follows the bar's name."""
        if self._progress is None:
            return
        description = f"{self.name}: {text}" if text else self.name
        self._progress.update(self._task, advance=steps, description=description)
        self.tick()

    def update(self, completed: int, note: str = "") -> None:
        """``completed`` items done in all; ``note`` is shown right of the time."""
        if self._progress is None:
            return
        self._progress.update(self._task, completed=completed, note=note)
        self.tick()

    def tick(self) -> None:
        """Redraw now if there is no refresh thread to do it."""
        if self._progress is not None and not self._threaded:
            self._progress.refresh()


class ProgressLines(ProgressBar):
    """Progress as plain lines on stderr where no bar can be drawn (stderr not a terminal):
    ``<name>[: <text>]  3/10 (30%)  0:00:12, about 0:00:28 left  <note>`` (the time left at
    the pace so far, once 5 s have passed) at every tenth of the
    total and at least every ``every_s`` seconds while items finish, and once at the end."""

    def __init__(self, name: str, total: int, every_s: float = 30.0, stream: Any = None) -> None:
        super().__init__(name, total)
        self.total, self.every_s = max(0, int(total)), every_s
        self._stream = stream
        self._completed, self._text, self._note = 0, "", ""
        self._started = self._printed_at = time.monotonic()
        self._printed_tenth, self._printed_count = 0, -1

    def step(self, text: str | None = None, steps: int = 1) -> None:
        self._completed += steps
        self._text = text or ""
        self._maybe_print()

    def update(self, completed: int, note: str = "") -> None:
        self._completed, self._note = completed, note
        self._maybe_print()

    def _maybe_print(self) -> None:
        tenth = 10 * self._completed // self.total if self.total else 10
        now = time.monotonic()
        if tenth > self._printed_tenth or now - self._printed_at >= self.every_s:
            self._print(now)
            self._printed_tenth = tenth

    def finish(self) -> None:
        if self._completed != self._printed_count and (self.total or self._completed):
            self._print(time.monotonic())

    def _print(self, now: float) -> None:
        percent = f" ({100 * self._completed // self.total}%)" if self.total else ""
        elapsed = int(now - self._started)
        clock = _clock(elapsed)
        if self.total and 0 < self._completed < self.total and elapsed >= 5:
            # at the pace so far: runs differ, so "about", and only once some are done
            left = elapsed * (self.total - self._completed) / self._completed
            clock += f", about {_clock(int(left))} left"
        name = f"{self.name}: {self._text}" if self._text else self.name
        note = f"  {self._note}" if self._note else ""
        stream = self._stream or sys.stderr
        print(f"{name}  {self._completed}/{self.total}{percent}  {clock}{note}", file=stream)
        stream.flush()
        self._printed_at, self._printed_count = now, self._completed


def _clock(seconds: int) -> str:
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def _is_terminal(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # replaced or closed
        return False


@contextlib.contextmanager
def progress_bar(
    name: str,
    total: int,
    *,
    show: bool = True,
    transient: bool = True,
    threaded: bool = True,
) -> Iterator[ProgressBar]:
    """A bar of ``total`` items on stderr while the block runs.

    show: False draws nothing. transient: remove the bar when done (else it stays as the
    last line). threaded: refresh from rich's thread; False redraws on each call instead.
    """
    if not show:
        yield ProgressBar(name, total)
        return
    if not _is_terminal(sys.stderr):  # piped, nohup, CI: plain lines instead of a bar
        lines = ProgressLines(name, total)
        yield lines
        lines.finish()
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    # markup off: plugin labels such as "radau[order=5]" are text, not rich markup
    progress = Progress(
        TextColumn("{task.description}", markup=False),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),  # at the recent pace (rich's estimate)
        TextColumn("{task.fields[note]}", markup=False),
        console=Console(stderr=True, highlight=False, markup=False),
        transient=transient,
        auto_refresh=threaded,
    )
    bar = ProgressBar(name, total, progress, threaded)
    with progress:
        yield bar
