"""A process's one daemon thread that acts on what it follows, every few tenths of a second.

A run's progress file and its output capture each need a background action while the run
goes on; a thread started and joined a run cost 0.2-0.3 ms of a tiny run's few, so each
keeps one thread a process (started at its first use, again in a forked child, which has
none of its parent's threads) that a run points at its target and away again.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from typing import Any


class Periodic:
    """Calls ``action(target)`` every ``interval(target)`` s while following a target;
    :meth:`follow` (None) returns only when no action is under way, and none comes after."""

    def __init__(
        self, name: str, action: Callable[[Any], None], interval: Callable[[Any], float]
    ) -> None:
        self.name, self.action, self.interval = name, action, interval
        self._reset()
        # a child forked while the thread held the lock would wait on it for ever: a fresh one
        os.register_at_fork(after_in_child=self._reset)

    def _reset(self) -> None:
        self._lock = threading.Lock()  # held while acting
        self._target: Any = None
        self._thread: threading.Thread | None = None

    def follow(self, target: Any) -> None:
        with self._lock:
            self._target = target
            if target is not None and (self._thread is None or not self._thread.is_alive()):
                self._thread = threading.Thread(target=self._loop, name=self.name, daemon=True)
                self._thread.start()

    def _loop(self) -> None:
        while True:
            target = self._target
            time.sleep(self.interval(target))  # (None: while it waits for a target)
            with self._lock:
                if self._target is not None:
                    self.action(self._target)
