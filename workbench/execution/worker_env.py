"""A fixed BLAS/OpenMP thread count in every process that executes runs.

OpenBLAS (NumPy's and SciPy's), MKL and OpenMP split reductions across as many threads as
they are allowed, and a different split rounds differently: a sweep under Dask once gave
n_rhs 1064 where the local pool gave 1062 for the same run (issue 18.14). So a worker
limits them all to :func:`worker_threads` (``WORKBENCH_THREADS``, default 1) before its
first run: through the environment variables the libraries read when they load (for
processes started after this, e.g. the child of a Dask task) and, with threadpoolctl, in
the libraries already loaded. Each row records the count in force (``threads``).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from typing import Any

THREADS_VARIABLE = "WORKBENCH_THREADS"
DEFAULT_THREADS = 1
# the variables BLAS and OpenMP runtimes read at load time
LIBRARY_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


def worker_threads() -> int:
    """The thread count workers use: ``WORKBENCH_THREADS`` if it is an integer >= 1, else 1."""
    text = os.environ.get(THREADS_VARIABLE, "").strip()
    try:
        value = int(text)
    except ValueError:
        return DEFAULT_THREADS
    return value if value >= 1 else DEFAULT_THREADS


def thread_environment(threads: int | None = None) -> dict[str, str]:
    """Environment variables that start a process with ``threads`` BLAS/OpenMP threads."""
    count = str(worker_threads() if threads is None else threads)
    return {name: count for name in (THREADS_VARIABLE, *LIBRARY_VARIABLES)}


def pin_threads(threads: int | None = None) -> int:
    """Limit this process (and its future children) to ``threads`` BLAS/OpenMP threads
    (default :func:`worker_threads`); returns the count."""
    count = worker_threads() if threads is None else threads
    os.environ.update(thread_environment(count))
    _threads_seen.clear()
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # only the variables: right for libraries not loaded yet
        return count
    threadpool_limits(limits=count)
    return count


@contextlib.contextmanager
def threads_as_workers() -> Iterator[int]:
    """Within it, this process's BLAS/OpenMP libraries use :func:`worker_threads` threads,
    as a sweep's workers do; after it, the caller's variables and limits are back, and a
    library first loaded meanwhile gets the threads it would have had. For a run in the
    caller's own process (``wb.run`` in a notebook): its timing then matches a sweep's,
    and no BLAS pool's threads, started by the plugins' imports, spin beside the timed
    integration (a first double pendulum BDF run took 68 ms of CPU in 35 ms of wall
    time with 2 threads a pool)."""
    count = worker_threads()
    saved = {name: os.environ.get(name) for name in thread_environment(count)}
    os.environ.update(thread_environment(count))
    _threads_seen.clear()
    controller = _controller()
    before = {lib.filepath for lib in controller.lib_controllers} if controller else set()
    try:
        with controller.limit(limits=count) if controller else contextlib.nullcontext():
            yield count
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        if controller is not None:
            for lib in _controller().lib_controllers:
                if lib.filepath not in before:
                    lib.set_num_threads(_default_threads(lib.internal_api, saved))
        _threads_seen.clear()


def _default_threads(internal_api: str, saved: dict[str, str | None]) -> int:
    """The threads a library of ``internal_api`` starts with under the variables ``saved``
    (its own variable, else one a CPU, as OpenBLAS and OpenMP start)."""
    name = {"openblas": "OPENBLAS_NUM_THREADS", "mkl": "MKL_NUM_THREADS",
            "blis": "BLIS_NUM_THREADS"}.get(internal_api, "OMP_NUM_THREADS")  # fmt: skip
    value = (saved.get(name) or "").strip()
    return int(value) if value.isdigit() and int(value) >= 1 else os.cpu_count() or 1


_threads_seen: dict[int, int | None] = {}  # modules loaded -> threads_in_force()


def threads_in_force() -> int | None:
    """The most threads any loaded BLAS/OpenMP library may use now (threadpoolctl), else
    what ``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS`` say; None when nothing says.

    Asked again only when modules were imported since (a new library may come with
    them) or :func:`pin_threads` was called: threadpoolctl reads the process's loaded
    libraries each time, 5 ms, more than a tiny run's integration (docs/performance.md)."""
    loaded = len(sys.modules)
    if loaded not in _threads_seen:
        _threads_seen.clear()
        _threads_seen[loaded] = _threads_now()
    return _threads_seen[loaded]


def _threads_now() -> int | None:
    controller = _controller()
    if controller is None:
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
            if os.environ.get(name, "").strip().isdigit():
                return int(os.environ[name])
        return None
    counts = [int(pool.get("num_threads", 0)) for pool in controller.info()]
    return max(counts) if counts else None


_controllers: dict[int, Any] = {}  # modules loaded -> threadpoolctl's controller


def _controller() -> Any:
    """threadpoolctl's controller of the BLAS/OpenMP libraries loaded now, or None without
    threadpoolctl. Made again only when modules were imported since (a new library comes
    with an extension module): making one reads the process's loaded libraries, 5 ms,
    and a notebook's run made three (16 ms of a 66 ms pendulum run); the thread counts it
    reports are asked of the libraries each time."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    loaded = len(sys.modules)
    if loaded not in _controllers:
        _controllers.clear()
        _controllers[loaded] = ThreadpoolController()
    return _controllers[loaded]
