"""CasADi Functions compiled to C and loaded back (formalism option ``compile = "jit"``).

The CasADi virtual machine interprets a graph instruction by instruction; the same graph
as C, compiled with the machine's C compiler (``$CC``, else ``cc``) at ``-O1``, runs
several times faster (benchmarks/peers.py). Compiling a large graph takes seconds, so
the shared library is kept in an on-disk cache (``$WORKBENCH_CACHE``, else
``~/.cache/mbs-workbench``) under a hash of the generated C code, the flags, the
compiler and the CasADi version: a sweep compiles each model once, whatever the number
of processes. A library is written to a temporary file in the cache directory and
renamed into place (:func:`os.replace` is atomic), so concurrent processes never see a
partial file; two that compile the same code at once both produce the same bytes. Long
straight-line bodies are cut into parts before compiling (:func:`split_long_bodies`), which
keeps the compile time about linear in the size of the graph.

Without a C compiler, or when CasADi cannot generate C for a graph, evaluation stays in
the virtual machine and a warning is recorded (:attr:`Compiler.warnings`) for the run's
message. Seconds spent generating, compiling and loading are counted in
:data:`STATS`, so the runner can report them as their own stage.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shlex
import shutil
import subprocess
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi as ca

from workbench.files import atomic_write, user_cache_dir

MODES = ("none", "jit")
DEFAULT_FLAGS = "-O1"


class CompileWarning(UserWarning):
    """Compilation was asked for but evaluation stays in the CasADi virtual machine."""


@dataclass
class CompileStats:
    """Process-wide counters: libraries compiled, loaded (compiled or from the cache) and
    seconds spent generating C, compiling and loading."""

    compiled: int = 0
    loaded: int = 0
    seconds: float = 0.0


STATS = CompileStats()


def cache_dir() -> Path:
    """Where compiled libraries are kept: ``$WORKBENCH_CACHE`` or ~/.cache/mbs-workbench."""
    return user_cache_dir()


def c_compiler() -> str | None:
    """Full path of the C compiler (``$CC``, else ``cc``), or None if there is none."""
    command = shlex.split(os.environ.get("CC", "") or "cc")
    return shutil.which(command[0]) if command else None


STATEMENTS_PER_PART = 100
_BODY_START = re.compile(
    r"^static int (casadi_f\d+)\(const casadi_real\*\* arg, casadi_real\*\* res, "
    r"casadi_int\* iw, casadi_real\* w, int mem\) \{$"
)
_SIMPLE_STATEMENT = re.compile(
    r"^  (w\[\d+\]=[^;{}]*;|if \(res\[\d+\]!=0\) res\[\d+\]\[\d+\]=w\[\d+\];)$"
)


def generate_c(function: ca.Function, statements_per_part: int = STATEMENTS_PER_PART) -> str:
    """The C source of ``function`` (and what it calls), as CasADi generates it, with long
    straight-line bodies cut into parts (:func:`split_long_bodies`)."""
    generator = ca.CodeGenerator(function.name(), {"with_header": False, "avoid_stack": True})
    generator.add(function)
    return split_long_bodies(generator.dump(), statements_per_part)


def split_long_bodies(code: str, statements_per_part: int) -> str:
    """Cut every long straight-line function body of CasADi's C into sequential parts.

    Generated with ``avoid_stack``, an SX function is one statement a line over the work
    array ``w`` (``w[7]=(w[3]*w[5]);``): a body of such statements can run as several
    functions in a row sharing ``w``, with nothing copied. Why: the C compiler's register
    allocation grows faster than linearly with a function's size, so compile time becomes
    about linear in the graph's size, and evaluation is no slower (docs/performance.md).
    A body with anything else in it (loops, calls) is left whole.
    """
    lines = code.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        start = _BODY_START.match(lines[i])
        if start is None:
            out.append(lines[i])
            i += 1
            continue
        end = lines.index("}", i)
        statements, last = lines[i + 1 : end - 1], lines[end - 1]
        simple = last == "  return 0;" and all(map(_SIMPLE_STATEMENT.match, statements))
        if not simple or len(statements) <= statements_per_part:
            out.extend(lines[i : end + 1])
            i = end + 1
            continue
        parts = []
        for first in range(0, len(statements), statements_per_part):
            part = f"{start.group(1)}_part{len(parts)}"
            out.append(f"static void {part}(const casadi_real** arg, casadi_real** res, "
                       "casadi_real* w) {")  # fmt: skip
            out.extend(statements[first : first + statements_per_part])
            out.extend(("}", ""))
            parts.append(part)
        out.append(lines[i])
        out.extend(f"  {part}(arg, res, w);" for part in parts)
        out.extend(("  return 0;", "}"))
        i = end + 1
    return "\n".join(out)


def library_path(code: str, flags: str, compiler: str, name: str) -> Path:
    """Cache path of the library of ``code``: keyed by code, flags, compiler, CasADi."""
    key = "\0".join((code, flags, compiler, ca.__version__))
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    return cache_dir() / f"{name}-{digest}.so"


def build_library(code: str, flags: str, compiler: str, path: Path) -> None:
    """Compile ``code`` into the shared library ``path`` (temporary file + atomic rename;
    not synced to disk: the cache can always compile again)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".build-") as work:
        source = Path(work) / "code.c"
        source.write_text(code)
        command = [compiler, *shlex.split(flags), "-fPIC", "-shared", str(source), "-o"]

        def compile_to(output: str) -> None:
            done = subprocess.run([*command, output, "-lm"], capture_output=True, text=True)
            if done.returncode != 0:
                first = (done.stderr.strip().splitlines() or ["no output"])[0]
                raise RuntimeError(f"{Path(compiler).name} {flags} failed: {first}")

        atomic_write(path, compile_to, durable=False)
    STATS.compiled += 1


def compile_function(function: ca.Function, flags: str = DEFAULT_FLAGS) -> ca.Function:
    """``function`` as compiled C loaded with ``casadi.external`` (from the cache if there).

    Raises RuntimeError if there is no C compiler, CasADi cannot generate C for the graph,
    or the compiler fails.
    """
    compiler = c_compiler()
    if compiler is None:
        raise RuntimeError(f"no C compiler ({os.environ.get('CC') or 'cc'} not found)")
    start = time.perf_counter()
    try:
        code = generate_c(function)
        path = library_path(code, flags, compiler, function.name())
        if not path.exists():
            build_library(code, flags, compiler, path)
        # finite differences where a CasADi solver needs derivatives (Newton in CVODES)
        loaded = ca.external(function.name(), str(path), {"enable_fd": True})
        STATS.loaded += 1
        return loaded
    finally:
        STATS.seconds += time.perf_counter() - start


@dataclass
class Compiler:
    """How the equations of one build are evaluated: ``mode`` "none" or "jit", C compiler
    ``flags``; ``warnings`` collects why something stayed in the virtual machine.

    Part of the plugin API: what a formalism needs to honour its ``compile`` option.
    :func:`~workbench.equations.build_joint_space_equations` makes one from the options; a
    formalism that calls :func:`~workbench.equations.build_equations` itself passes
    ``compiler=Compiler.from_options(options)`` (options with the fields of
    :class:`workbench.plugin.formalism.CompileOptions`), and every function of its forms
    and observables is then compiled (:meth:`load`) or kept in the virtual machine with a
    warning that reaches the run's message. ``mode`` "jit" without a C compiler falls back
    to "none" with a warning."""

    mode: str = "none"
    flags: str = DEFAULT_FLAGS
    warnings: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"compile must be one of {', '.join(MODES)}, not {self.mode!r}")
        if self.mode == "jit" and c_compiler() is None:
            self.warn(
                f"compile=jit: no C compiler ({os.environ.get('CC') or 'cc'} not found); "
                "evaluating in the CasADi virtual machine (compile=none)"
            )
            self.mode = "none"

    @classmethod
    def from_options(cls, options: Any) -> Compiler:
        """From a formalism's options (fields ``compile`` and ``compile_flags``, if any)."""
        return cls(
            getattr(options, "compile", "none"), getattr(options, "compile_flags", DEFAULT_FLAGS)
        )

    @property
    def active(self) -> bool:
        return self.mode == "jit"

    def warn(self, message: str) -> None:
        if message not in self.warnings:
            self.warnings.append(message)
            warnings.warn(message, CompileWarning, stacklevel=3)

    def load(self, function: ca.Function) -> ca.Function | None:
        """The compiled ``function``, or None (with a warning) if it cannot be compiled."""
        try:
            return compile_function(function, self.flags)
        except RuntimeError as error:
            text = str(error).strip().splitlines()[0] if str(error).strip() else "error"
            self.warn(f"compile=jit: {function.name()} stays in the CasADi VM ({text})")
            return None


def clear_cache() -> int:
    """Remove every cached library; returns how many were removed."""
    removed = 0
    for path in cache_dir().glob("*.so"):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed += 1
    return removed
