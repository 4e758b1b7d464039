"""Exit with the parent: a worker process (a sweep's, a report's figure worker) must not
outlive the process that started it. Light on purpose: a figure worker imports it without
the run machinery (CasADi, SciPy)."""

from __future__ import annotations

import multiprocessing
import os
import time
from pathlib import Path


def exit_with_parent(parent_pid: int | None = None, scratch: Path | None = None) -> None:
    """Exit when the process that started this one dies (no orphan keeps running a run),
    removing ``scratch``, a directory of this process's own, first.

    Watched through multiprocessing's parent sentinel, a pipe whose other end only the
    parent holds: it reads as ready once the parent is gone, even if that happened while
    this process was still importing (a pid read with getppid then would already be
    init's), and whatever the start method (a forkserver child's parent is the
    forkserver, but the pipe comes from the process that asked for it). A process not
    started by multiprocessing (a Dask worker's child) polls its parent's pid instead:
    ``parent_pid`` as its parent passed it, or getppid.
    """
    import shutil
    import threading
    from multiprocessing.connection import wait

    def leave() -> None:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
        os._exit(1)

    parent = multiprocessing.parent_process()
    if parent is None:  # not started by multiprocessing: poll the parent pid
        ppid = os.getppid() if parent_pid is None else parent_pid

        def watch() -> None:
            while os.getppid() == ppid:
                time.sleep(0.5)
            leave()

    else:

        def watch() -> None:
            wait([parent.sentinel])
            leave()

    threading.Thread(target=watch, daemon=True).start()
