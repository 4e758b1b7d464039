"""One progress bar on stderr (rich) for every long task: sweeps, references, reports.

``with progress_bar("sweep", total) as bar:`` then ``bar.step(text)`` after each item, or
``bar.update(completed, note)`` when the caller counts itself. The bar reads
``<name>[: <text>]  ━━━━━  3/10  0:00:04  <note>``; a disabled bar (``show=False``) has the
same methods and draws nothing, so callers never test whether it is shown.

``threaded=False`` draws without rich's refresh thread: the bar is redrawn on each call
(and by :meth:`ProgressBar.tick`), for callers that fork processes while it is shown.
"""

from __future__ import annotations

import contextlib
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
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    # markup off: plugin labels such as "radau[order=5]" are text, not rich markup
    progress = Progress(
        TextColumn("{task.description}", markup=False),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[note]}", markup=False),
        console=Console(stderr=True, highlight=False, markup=False),
        transient=transient,
        auto_refresh=threaded,
    )
    bar = ProgressBar(name, total, progress, threaded)
    with progress:
        yield bar
