"""A direct call from Python into a compiled library of ours, without CasADi's buffer call.

``FastFunction.into`` on a compiled function spends about 0.3 µs in Python around the C
(copying the state, setting the time, CasADi's buffer call through SWIG), as long as the
C itself for a small robot (docs/performance-targets.md). :func:`caller` gives instead a
small C extension object (``fastcall.c``) that takes the same arguments, copies a float
or a float64 buffer into the bound input arrays and calls the generated symbol itself;
anything else goes to the Python path, so results, conversions and errors are the same.

The extension is compiled once per Python, compiler and CPU into the compile cache
(``fastcall/`` in :func:`workbench.equations.compiled.cache_dir`), under a lock and with
an atomic rename like the libraries. Without a C compiler or Python's headers
(``Python.h``), or with ``WORKBENCH_FASTCALL=0``, :func:`caller` returns None and
``FastFunction`` keeps CasADi's buffer call.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import importlib.machinery
import importlib.util
import os
import subprocess
import sys
import sysconfig
from pathlib import Path
from typing import Any

from workbench.equations import compiled
from workbench.files import atomic_write, file_lock

SOURCE = Path(__file__).with_name("fastcall.c")
MODULE = "workbench_fastcall"


def enabled() -> bool:
    """False if ``WORKBENCH_FASTCALL=0`` (CasADi's buffer call everywhere)."""
    return os.environ.get("WORKBENCH_FASTCALL", "1") != "0"


@functools.cache
def extension() -> Any | None:
    """The compiled extension module, built on first use; None if it cannot be built."""
    include = sysconfig.get_paths().get("include")
    compiler = compiled.c_compiler()
    if compiler is None or not include or not Path(include, "Python.h").exists():
        return None
    if not SOURCE.exists():  # an install without the package data
        return None
    source = SOURCE.read_text()
    key = "\0".join((source, sys.version, include, compiler, compiled.cpu()))
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    # a folder of its own: the cache's size, trimming and clearing count the libraries only
    path = compiled.cache_dir() / "fastcall" / f"{MODULE}-{digest}{suffix}"
    try:
        if not path.exists():
            with compiled.counted(), file_lock(path.with_suffix(".lock")):
                if not path.exists():
                    _build(source, compiler, include, path)
        loader = importlib.machinery.ExtensionFileLoader(MODULE, str(path))
        spec = importlib.util.spec_from_file_location(MODULE, path, loader=loader)
        assert spec is not None
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
        return module
    except (OSError, RuntimeError, ImportError):
        return None


def _build(source: str, compiler: str, include: str, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    work = path.with_suffix(".c")
    work.write_text(source)

    def compile_to(output: str) -> None:
        command = [compiler, "-O2", "-fPIC", "-shared", f"-I{include}", str(work), "-o", output]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(compiled.compiler_error(done.stderr))

    try:
        atomic_write(path, compile_to, durable=False)
    finally:
        work.unlink(missing_ok=True)


def caller(
    function: Any, inputs: list, outputs: list, result: tuple, fallback: Any
) -> tuple[Any, ctypes.CDLL] | None:
    """(call, library): ``call(*args) -> result`` runs ``function``'s compiled symbol on
    the bound ``inputs`` and ``outputs`` (float64 arrays), ``fallback(*args)`` for what it
    does not take; None unless ``function`` was loaded from a library of ours
    (:func:`compiled.library_of`) and the extension is available. Its ``calls`` counts
    the direct calls; keep ``library`` (the loaded library) as long as ``call``."""
    library = compiled.library_of(function)
    module = extension() if library is not None and enabled() else None
    if module is None:
        return None
    path, symbol = library
    handle = ctypes.CDLL(path)  # the handle casadi.external holds: the same library
    sizes = [ctypes.c_longlong() for _ in range(4)]
    work = getattr(handle, f"{symbol}_work")
    work.argtypes = [ctypes.POINTER(ctypes.c_longlong)] * 4
    if work(*map(ctypes.byref, sizes)) != 0:
        return None
    checkout = getattr(handle, f"{symbol}_checkout")
    address = ctypes.cast(getattr(handle, symbol), ctypes.c_void_p).value
    call = module.Caller(address, checkout(), tuple(inputs), tuple(outputs),
                         tuple(s.value for s in sizes), result, fallback)  # fmt: skip
    return call, handle
