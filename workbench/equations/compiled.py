"""CasADi Functions compiled to C and loaded back (formalism option ``compile = "jit"``).

The CasADi virtual machine interprets a graph instruction by instruction; the same graph
as C, compiled with the machine's C compiler (``$CC``, else ``cc``; flags below), runs
several times faster (benchmarks/peers.py). Compiling a large graph takes seconds, so
the shared library is kept in an on-disk cache (``$WORKBENCH_CACHE``, else
``~/.cache/mbs-workbench``) under a hash of the generated C code, the flags, the
compiler and the CasADi version: a sweep compiles each model once, whatever the number
of processes. The key holds the CPU too, so a cache on a shared home directory never
hands one machine's ``-march=native`` code to another. A library is compiled under a lock
(one process compiles, the others wait and load it), written to a temporary file in the
cache directory and renamed into place (:func:`os.replace` is atomic), so no process sees a
partial file; the least recently used libraries are removed when the cache outgrows
``$WORKBENCH_CACHE_LIMIT_MB`` (2048 by default). Generated symbols carry a prefix
(:data:`SYMBOL_PREFIX`), so a graph named ``gamma`` does not clash with libm. Long
straight-line bodies are cut into parts before compiling (:func:`split_long_bodies`), which
keeps the compile time about linear in the size of the graph; small graphs keep their values
in local variables instead (:func:`generate_c`). The default flags (:func:`default_flags`)
are ``-O2`` for those small graphs, ``-O1`` for the rest, and on an x86-64 CPU with AVX its
three-operand instructions (``-mavx``, no fused multiply-adds: every result the same).
Outputs of the same shape (mirrored limbs) run two at a time in vector lanes, the same
operations lane by lane (:mod:`workbench.equations.lanes`).

Without a C compiler, or when CasADi cannot generate C for a graph (the formalisms' linear
solves use CasADi's own LDL^T and QR, which it can), evaluation stays in the virtual
machine and a warning naming the compiler's own error is recorded
(:attr:`Compiler.warnings`) for the run's message. Seconds spent generating, compiling
and loading are counted in :data:`STATS`, so the runner can report them as their own stage.
``compile = "auto"`` compiles only what repays its compile
(:mod:`workbench.equations.compile_policy`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import math
import os
import platform
import re
import shlex
import shutil
import subprocess
import tempfile
import threading
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi as ca

from workbench.equations import lanes
from workbench.files import atomic_write, file_lock, user_cache_dir

MODES = ("none", "jit", "auto")
DEFAULT_FLAGS = "-O1"  # compile_flags' default: the workbench chooses (:func:`default_flags`)
SYMBOL_PREFIX = "wb_"  # generated C symbols never clash with libc/libm (gamma, j0, y1, ...)


class CompileWarning(UserWarning):
    """Compilation was asked for but evaluation stays in the CasADi virtual machine."""


@dataclass
class CompileStats:
    """Process-wide counters: libraries compiled, loaded (compiled or from the cache),
    wall seconds spent generating C, compiling and loading, and of those the CPU seconds
    of this process (the compiler itself runs in a child process)."""

    compiled: int = 0
    loaded: int = 0
    seconds: float = 0.0
    cpu_seconds: float = 0.0


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


def exported(function: ca.Function) -> ca.Function:
    """``function`` under the name its C symbol gets: :data:`SYMBOL_PREFIX` + its name.

    CasADi exports a generated function under its own name, so a graph named ``gamma``
    would define ``int gamma(...)`` and clash with the C library's ``gamma()``. An SX graph
    is rebuilt under the new name (the same instructions); an MX graph is wrapped in one
    call."""
    name = SYMBOL_PREFIX + function.name()
    symbols = function.sx_in() if function.is_a("SXFunction") else function.mx_in()
    return ca.Function(
        name, symbols, function.call(symbols), function.name_in(), function.name_out()
    )


LOCALS_MAX_INSTRUCTIONS = 15_000


def generate_c(
    function: ca.Function, statements_per_part: int = STATEMENTS_PER_PART,
    locals_max_instructions: int = LOCALS_MAX_INSTRUCTIONS,
) -> str:  # fmt: skip
    """The C source of ``function`` (and what it calls), as CasADi generates it. Pass it
    through :func:`exported` first: the exported symbol is the function's own name.

    An SX graph of at most ``locals_max_instructions`` keeps its intermediate values in
    local variables, which the compiler can hold in registers, and so do the SX functions
    an MX graph calls (the joint-type kernels) when each is that small (:func:`uses_locals`;
    the MX graph's own values are in the work array either way); otherwise the work array
    (CasADi's ``avoid_stack``), its long straight-line bodies cut into parts
    (:func:`split_long_bodies`), which bounds the compile time. Locals ran
    4-22 % faster (Solo12 1.17 -> 0.92 µs, Talos 2.67 -> 2.51, random tree N = 20 2.22 ->
    2.14, N = 50 5.61 -> 5.38; N = 7 the same) but compile 30-60 % longer above about
    10,000 instructions (N = 50: 3.7 against 2.3 s CPU; docs/performance-targets.md)."""
    small = uses_locals(function, locals_max_instructions)
    generator = ca.CodeGenerator(
        function.name(), {"with_header": False, "avoid_stack": not small, "verbose": False}
    )
    generator.add(function)
    if small:  # mirrored limbs' operations two at a time, the same numbers
        return lanes.pair_lanes(generator.dump())
    return split_long_bodies(generator.dump(), statements_per_part)


def uses_locals(
    function: ca.Function, locals_max_instructions: int = LOCALS_MAX_INSTRUCTIONS
) -> bool:
    """Whether :func:`generate_c` keeps the values of ``function``'s SX code in local
    variables, not in the work array: an SX graph of at most ``locals_max_instructions``,
    or a graph whose SX functions (an MX graph's joint-type kernels) are each that small.
    Kernels with locals: random tree N = 200 36.0 -> 24.0 µs a call, the same numbers
    (one process, interleaved, load 1.5; docs/performance-targets.md)."""
    if function.is_a("SXFunction"):
        return function.n_instructions() <= locals_max_instructions
    called = [f for f in function.find_functions() if f.is_a("SXFunction")]
    return all(f.n_instructions() <= locals_max_instructions for f in called)


def default_flags(function: ca.Function) -> str:
    """The flags ``function`` is compiled with unless the formalism's ``compile_flags`` say
    otherwise: ``-O2`` for a graph with local variables (:func:`uses_locals`: Talos's ABA
    2.49 -> 2.39 µs a call, -O2 alone), ``-O1`` for larger ones (whose large straight-line
    body ran no faster at ``-O2`` and compiled 1.5x longer; their kernels get ``-O2`` by
    :func:`optimize_callees`), and this CPU's :func:`host_flags` (Talos 1.87 µs with both;
    docs/performance-targets.md)."""
    level = "-O2" if function.is_a("SXFunction") and uses_locals(function) else "-O1"
    return f"{level} {host_flags()}".strip()


@functools.cache
def host_flags() -> str:
    """``-mavx -ffp-contract=off`` on an x86-64 CPU whose kernel reports AVX, else "".

    Why: compiled for baseline x86-64, every copy of a value the next operation overwrites
    is an instruction of its own (SSE2's two-operand ``mulsd``: 4,292 register copies
    beside 9,800 operations in Talos's ABA); AVX's three-operand forms of the same scalar
    IEEE operations need none (Talos 2.49 -> 2.18 µs at -O1, Panda 0.43 -> 0.32, random
    tree N = 50 5.80 -> 5.08, all models faster). ``-ffp-contract=off``: no fused
    multiply-add, so each product and sum is rounded as written and the results equal the
    virtual machine's bit for bit. The cache key holds the flags and the CPU, so such a
    library is never loaded on a CPU without AVX."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return ""
    return "-mavx -ffp-contract=off" if "avx" in cpu_flags() else ""


@functools.cache
def cpu_flags() -> frozenset[str]:
    """The instruction-set flags the kernel reports for this CPU (/proc/cpuinfo; empty
    where there is none)."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return frozenset(line.split(":", 1)[1].split())
    return frozenset()


def compiler_error(stderr: str) -> str:
    """The line of a C compiler's output that says what went wrong: the first ``#error``
    or ``error:`` line (the first line is often only "In function ..."), else the first."""
    lines = [line.strip() for line in stderr.strip().splitlines() if line.strip()]
    for marker in ("#error", "error:"):
        for line in lines:
            if marker in line:
                return line
    return lines[0] if lines else "no output"


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


CALLEE_FLAG = "O2"
CALLEE_MAX_BYTES = 100_000
_FUNCTION_START = re.compile(r"^static (?:int|void) casadi_f(\d+)(?:_part\d+)?\(", re.M)


def optimize_callees(code: str, level: str = CALLEE_FLAG,
                     max_bytes: int = CALLEE_MAX_BYTES) -> str:  # fmt: skip
    """``code`` with the functions its entry calls (``casadi_f1``, ... with their parts:
    an MX graph's kernels, called many times a call) marked for GCC's ``-{level}``,
    those of at most ``max_bytes`` of C each; the entry (``casadi_f0``) keeps the
    command line's flags. Why: the recursive formalism's joint-type kernels
    (plugins/formalisms/recursive_kernels.py) ran 6 % faster at ``-O2`` while a whole
    library at ``-O2`` ran slower (its large entry) and compiled twice as long; small
    functions cost little to compile (random tree N = 200: 36.3 against 38.9 µs a
    call, 4.0 against 3.4 s CPU to compile; docs/performance-targets.md). Other compilers
    ignore the mark (the macro is empty)."""
    starts = [(m.start(), int(m.group(1))) for m in _FUNCTION_START.finditer(code)]
    sizes: dict[int, int] = {}
    for (start, number), end in zip(starts, [s for s, _ in starts[1:]] + [len(code)], strict=True):
        sizes[number] = sizes.get(number, 0) + end - start
    marked = {n for n, size in sizes.items() if n != 0 and size <= max_bytes}
    if not marked:
        return code

    def mark(match: re.Match) -> str:
        return "WB_CALLEE " + match.group(0) if int(match.group(1)) in marked else match.group(0)

    macro = (f"#if defined(__GNUC__) && !defined(__clang__)\n"
             f"#define WB_CALLEE __attribute__((optimize(\"{level}\")))\n"
             f"#else\n#define WB_CALLEE\n#endif\n")  # fmt: skip
    return macro + _FUNCTION_START.sub(mark, code)


@functools.cache
def cpu(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The machine's architecture and CPU: model name, family, model and stepping, and a
    digest of the instruction-set flags the kernel reports. A virtual machine's name alone
    ("AMD EPYC") is the same on CPUs of several generations, and a cache shared between
    them (a home folder on a cluster) must not hand a library built with ``-march=native``
    on one to the other."""
    fields: dict[str, str] = {}
    with contextlib.suppress(OSError):
        for line in Path(cpuinfo).read_text().splitlines():
            key, _, value = line.partition(":")
            if not key.strip() and fields:
                break  # the first processor's block is enough
            fields.setdefault(key.strip(), value.strip())
    model = fields.get("model name") or platform.processor()
    ids = " ".join(f"{k} {fields[k]}" for k in ("cpu family", "model", "stepping") if k in fields)
    isa = " ".join(sorted(fields.get("flags", "").split()))
    digest = hashlib.sha256(isa.encode()).hexdigest()[:12] if isa else ""
    return " ".join(
        part for part in (platform.machine(), model, ids, digest and f"isa {digest}") if part
    )


def library_path(code: str, flags: str, compiler: str, name: str) -> Path:
    """Cache path of the library of ``code``: keyed by code, flags, compiler, CPU, CasADi."""
    key = "\0".join((code, flags, compiler, cpu(), ca.__version__))
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    return cache_dir() / f"{name}-{digest}.so"


def build_library(
    code: str, flags: str, compiler: str, path: Path, link: tuple[str, ...] = ()
) -> None:
    """Compile ``code`` into the shared library ``path`` (temporary file + atomic rename;
    not synced to disk: the cache can always compile again); ``link``: libraries and
    linker options after the source."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".build-") as work:
        source = Path(work) / "code.c"
        source.write_text(code)
        command = [compiler, *shlex.split(flags), "-fPIC", "-shared", str(source), "-o"]

        def compile_to(output: str) -> None:
            arguments = [*command, output, *link, "-lm"]
            done = subprocess.run(arguments, capture_output=True, text=True)
            if done.returncode != 0:
                cause = compiler_error(done.stderr)
                raise RuntimeError(f"{Path(compiler).name} {flags} failed: {cause}")

        atomic_write(path, compile_to, durable=False)
    STATS.compiled += 1


@dataclass
class Generated:
    """The C of a Function, ready to compile: the exported Function (its symbol's name),
    the code and the library's cache path (``path.exists()``: compiled before)."""

    function: ca.Function
    code: str
    path: Path
    compiler: str
    flags: str


_COUNTING = threading.local()  # depth of counted() blocks open in this thread


@contextlib.contextmanager
def counted() -> Any:
    """Count the wall and CPU time of the block in :data:`STATS` (the compile stage); a
    block inside another (a library loaded for a caller that counts its own) is counted
    once, by the outer one."""
    wall, cpu_start = time.perf_counter(), time.process_time()
    depth = getattr(_COUNTING, "depth", 0)
    _COUNTING.depth = depth + 1
    try:
        yield
    finally:
        _COUNTING.depth = depth
        if depth == 0:
            STATS.seconds += time.perf_counter() - wall
            STATS.cpu_seconds += time.process_time() - cpu_start


def generate(function: ca.Function, flags: str = DEFAULT_FLAGS) -> Generated:
    """The C of ``function`` and where its library is cached (call inside :func:`counted`).
    ``flags``: the compiler's; :data:`DEFAULT_FLAGS` (the formalisms' default) stands for
    :func:`default_flags` and kernels marked for ``-O2`` (:func:`optimize_callees`), and
    for code with vector lanes :func:`~workbench.equations.lanes.compiler_flags`.

    Raises RuntimeError if there is no C compiler or CasADi cannot generate C for the graph.
    """
    compiler = c_compiler()
    if compiler is None:
        raise RuntimeError(f"no C compiler ({os.environ.get('CC') or 'cc'} not found)")
    function = exported(function)
    code = generate_c(function)
    if flags == DEFAULT_FLAGS:  # flags of one's own apply to every function
        code, flags = optimize_callees(code), default_flags(function) + lanes.compiler_flags(code)
    if "#error" in code:  # e.g. LAPACK's LU: CasADi writes an #error, not C for it
        cause = next(line for line in code.splitlines() if "#error" in line).strip()
        raise RuntimeError(f"CasADi cannot generate C for it: {cause}")
    return Generated(function, code, library_path(code, flags, compiler, function.name()),
                     compiler, flags)  # fmt: skip


def built(code: str, flags: str, compiler: str, path: Path, link: tuple[str, ...] = ()) -> Path:
    """``path``, the library of ``code``, compiled first unless the cache holds it: one
    process compiles under a lock, the others wait and find it (call inside
    :func:`counted`). Raises RuntimeError if the compiler fails."""
    if not path.exists():
        with file_lock(path.with_suffix(".lock")):  # one process compiles, others wait
            if not path.exists():
                build_library(code, flags, compiler, path, link)
                trim_cache(keep=path)
    with contextlib.suppress(OSError):
        os.utime(path)  # last use, for trim_cache
    return path


def load_generated(generated: Generated) -> ca.Function:
    """The library of ``generated`` loaded with ``casadi.external``, compiled first unless
    cached (call inside :func:`counted`). Raises RuntimeError if the compiler fails."""
    path = generated.path
    built(generated.code, generated.flags, generated.compiler, path)
    loaded = load_library(path, generated.function.name())
    STATS.loaded += 1
    return loaded


def load_library(path: Path | str, symbol: str) -> ca.Function:
    """The compiled library ``path``'s function ``symbol`` (``casadi.external``), marked as
    ours (:func:`library_of`)."""
    # finite differences where a CasADi solver needs derivatives (Newton in CVODES)
    loaded = ca.external(symbol, str(path), {"enable_fd": True})
    loaded._workbench_library = (str(path), symbol)
    return loaded


def library_of(function: ca.Function) -> tuple[str, str] | None:
    """(library path, symbol) of a Function loaded by :func:`load_generated`, else None
    (what :mod:`~workbench.equations.fastcall` calls directly)."""
    return getattr(function, "_workbench_library", None)


def compile_function(function: ca.Function, flags: str = DEFAULT_FLAGS) -> ca.Function:
    """``function`` as compiled C loaded with ``casadi.external`` (from the cache if there).

    Raises RuntimeError if there is no C compiler, CasADi cannot generate C for the graph,
    or the compiler fails.
    """
    with counted():
        return load_generated(generate(function, flags))


@dataclass
class Compiler:
    """How the equations of one build are evaluated: ``mode`` "none", "jit" or "auto", C
    compiler ``flags``; ``warnings`` collects why something stayed in the virtual machine.

    Part of the plugin API: what a formalism needs to honour its ``compile`` option.
    :func:`~workbench.equations.build_joint_space_equations` makes one from the options; a
    formalism that calls :func:`~workbench.equations.build_equations` itself passes
    ``compiler=Compiler.from_options(options)`` (options with the fields of
    :class:`workbench.plugin.formalism.CompileOptions`), and every function of its forms
    and observables is then compiled (:meth:`load`) or kept in the virtual machine with a
    warning that reaches the run's message. ``mode`` "jit" or "auto" without a C compiler
    falls back to "none" with a warning.

    "auto" decides for each run, from that run alone, which functions run in C
    (:mod:`workbench.equations.compile_policy`): those whose compile the evaluations the
    run expects (:meth:`expect`, set by the runner) repay; the others run in the VM, even
    if an earlier run of the same equations compiled them."""

    mode: str = "none"
    flags: str = DEFAULT_FLAGS
    warnings: list[str] = field(default_factory=list)
    expected_calls: float = 0.0
    in_c: dict[str, str] = field(default_factory=dict)  # name -> "C" (this run's choice)
    tracked: list[Any] = field(default_factory=list)  # auto: FastFunctions called so far
    loaded: dict[str, ca.Function] = field(default_factory=dict)  # auto: libraries loaded
    loaded_bytes: dict[str, int] = field(default_factory=dict)  # auto: their C's size
    # auto: the estimated size of each function's C, from its graph (the same every run:
    # an MX graph's count walks its instructions in Python, 0.04 ms a tiny run)
    code_bytes: dict[str, float] = field(default_factory=dict)
    # auto: each tracked function's calls when this run's integration began (id ->
    # n_calls): a run's notes name the functions it called, not those a worker's earlier
    # runs did
    calls_at_start: dict[int, int] = field(default_factory=dict)
    ran_directly: set[str] = field(default_factory=set)  # this run's ran_in_c names

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"compile must be one of {', '.join(MODES)}, not {self.mode!r}")
        if self.mode != "none" and c_compiler() is None:
            self.warn(
                f"compile={self.mode}: no C compiler ({os.environ.get('CC') or 'cc'} not "
                "found); evaluating in the CasADi virtual machine (compile=none)"
            )
            self.mode = "none"

    def __getstate__(self) -> dict:
        return {"mode": self.mode, "flags": self.flags, "warnings": list(self.warnings),
                "expected_calls": self.expected_calls, "in_c": {}, "tracked": [],
                "loaded": {}, "loaded_bytes": {}, "code_bytes": {},
                "calls_at_start": {}, "ran_directly": set()}  # fmt: skip

    @classmethod
    def from_options(cls, options: Any) -> Compiler:
        """From a formalism's options (fields ``compile`` and ``compile_flags``, if any)."""
        return cls(
            getattr(options, "compile", "none"), getattr(options, "compile_flags", DEFAULT_FLAGS)
        )

    @property
    def active(self) -> bool:
        """Functions may run compiled (the graphs are built so that C can be generated)."""
        return self.mode != "none"

    def ran_in_c(self, name: str) -> None:
        """compile=auto: ``name`` ran in C this run by another route than its FastFunction
        (an integrator that calls the compiled library itself), for the row's notes."""
        self.in_c[name] = "C"
        self.ran_directly.add(name)  # (its FastFunction does not count those calls)

    @property
    def waiting(self) -> list[Any]:
        """compile=auto: the FastFunctions called so far that run in the VM this run."""
        return [fast for fast in self.tracked if fast.evaluated is fast.function]

    def warn(self, message: str) -> None:
        if message not in self.warnings:
            self.warnings.append(message)
            warnings.warn(message, CompileWarning, stacklevel=3)

    def load(self, function: ca.Function) -> ca.Function | None:
        """The compiled ``function``, or None (with a warning) if it cannot be compiled."""
        try:
            loaded = compile_function(function, self.flags)
        except RuntimeError as error:
            self._failed(function, error)
            return None
        self.in_c.setdefault(function.name(), "compiled")
        return loaded

    def _failed(self, function: ca.Function, error: Exception) -> None:
        text = str(error).strip().splitlines()[0] if str(error).strip() else "error"
        self.warn(f"compile={self.mode}: {function.name()} stays in the CasADi VM ({text})")

    def expect(self, calls: float) -> None:
        """compile=auto: a run is about to make about ``calls`` evaluations: every function
        called so far is put in C or in the VM for it (:meth:`decide`), whatever earlier
        runs chose; functions first called during the run decide at their first call."""
        self.expected_calls = calls
        self.in_c.clear()
        self.ran_directly.clear()
        self.count_calls_from_now()
        for fast in self.tracked:
            fast.reconsider(calls)

    def count_calls_from_now(self) -> None:
        """compile=auto: the notes (:meth:`summary`) name the functions called from now on:
        the runner calls it when the integration starts, after the initial state (which a
        worker computes at the first run of cached equations only)."""
        self.calls_at_start = {id(fast): fast.n_calls for fast in self.tracked}

    def called_this_run(self, fast: Any) -> bool:
        """compile=auto: ``fast`` was called since :meth:`count_calls_from_now`."""
        return fast.n_calls > self.calls_at_start.get(id(fast), 0)

    def decide(self, function: ca.Function, vm_seconds: float, calls: float) -> ca.Function | None:
        """compile=auto: the compiled ``function`` if ``calls`` calls that each take
        ``vm_seconds`` in the VM repay its compile, else None (the VM). The size of its C
        is estimated from the graph (``compile_policy.code_bytes_estimate``), so the
        decision needs no code generated; the library is then loaded from the cache if
        there (which changes only the cost) or compiled, once a process."""
        from workbench.equations.compile_policy import calls_to_repay, code_bytes_estimate

        name = function.name()
        if self.loaded_bytes.get(name) == -1:  # it cannot be compiled (warned once)
            return None
        if name not in self.code_bytes:
            self.code_bytes[name] = code_bytes_estimate(function)
        if calls < calls_to_repay(vm_seconds, self.code_bytes[name]):
            return None
        try:
            loaded = self.loaded_once(function)
        except RuntimeError as error:
            self._failed(function, error)
            self.loaded_bytes[name] = -1
            return None
        self.in_c[name] = "C"
        return loaded

    def loaded_once(self, function: ca.Function) -> ca.Function:
        """The compiled ``function``, loaded once a process (:attr:`loaded`) from the cache
        or compiled; RuntimeError if it cannot be compiled."""
        name = function.name()
        if name not in self.loaded:
            with counted():
                generated = generate(function, self.flags)
                self.loaded[name] = load_generated(generated)
                self.loaded_bytes[name] = len(generated.code)
        return self.loaded[name]

    def library(self, fast: Any) -> tuple[str, str]:
        """(library path, symbol) of the compiled C of the FastFunction ``fast``, for a
        caller that runs it itself (an integrator's C driver): the library its own
        compile loaded if it runs in C, else (compile=auto, left in the VM for this run)
        the one loaded once a process for that. Its C is generated once a process, not
        again to find the library. RuntimeError if it cannot be compiled."""
        if self.mode == "jit":
            fast.compile()  # what its first call does (a no-op after it)
        found = library_of(fast.evaluated)
        if found is None:
            found = library_of(self.loaded_once(fast.for_c))
        assert found is not None, "load_library marks what it loads"
        return found

    def summary(self) -> str:
        """compile=auto: which functions run in C and which in the VM (for a row's notes)."""
        if self.mode != "auto":
            return ""
        # the functions this run called (a worker's earlier runs, e.g. an implicit
        # integrator's Jacobian, are not this run's: a row's notes depended on them)
        tracked = {fast.name: fast for fast in self.tracked}
        in_c = ", ".join(
            sorted(
                name
                for name in self.in_c
                if name not in tracked
                or name in self.ran_directly
                or self.called_this_run(tracked[name])
            )
        )
        vm = sum(fast.name not in self.in_c and self.called_this_run(fast) for fast in self.waiting)
        parts = [f"in C {in_c}" if in_c else "",
                 f"{vm} function{'s' * (vm != 1)} in the VM (too few calls to repay a compile)"
                 if vm else ""]  # fmt: skip
        return "compile=auto: " + "; ".join(filter(None, parts)) if any(parts) else ""


DEFAULT_CACHE_LIMIT_MB = 2048


def cache_limit_bytes() -> int:
    """The compile cache's size limit: ``$WORKBENCH_CACHE_LIMIT_MB`` (default 2048 MB)."""
    return cache_limit()[0]


def cache_limit() -> tuple[int, str]:
    """(the compile cache's size limit in bytes, what is wrong with its setting or ""):
    ``$WORKBENCH_CACHE_LIMIT_MB`` when it is a number of megabytes >= 0, else the default
    (a compile never fails for it; ``workbench cache info`` says so)."""
    text = os.environ.get("WORKBENCH_CACHE_LIMIT_MB", "")
    try:
        megabytes = float(text) if text else DEFAULT_CACHE_LIMIT_MB
    except ValueError:
        megabytes = math.nan
    if not megabytes >= 0 or math.isinf(megabytes):
        wrong = (
            f"WORKBENCH_CACHE_LIMIT_MB={text!r} is not a number of megabytes >= 0: "
            f"the default, {DEFAULT_CACHE_LIMIT_MB} MB, is used"
        )
        return DEFAULT_CACHE_LIMIT_MB * 2**20, wrong
    return int(megabytes * 2**20), ""


def trim_cache(keep: Path | None = None, limit: int | None = None) -> int:
    """Remove the least recently used libraries until the cache fits its limit (the one
    just built, ``keep``, stays); returns how many were removed. A process that still has
    a removed library loaded keeps it: unlinking does not unmap."""
    limit = cache_limit_bytes() if limit is None else limit
    entries = []
    for path in cache_dir().glob("*.so"):
        with contextlib.suppress(FileNotFoundError):
            entries.append((path.stat().st_mtime, path.stat().st_size, path))
    total = sum(size for _, size, _ in entries)
    removed = 0
    for _, size, path in sorted(entries):
        if total <= limit:
            break
        if path == keep:
            continue
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            path.with_suffix(".lock").unlink(missing_ok=True)
            removed += 1
        total -= size
    return removed


def cache_size() -> tuple[int, int]:
    """(libraries, bytes) in the compile cache."""
    sizes = [path.stat().st_size for path in cache_dir().glob("*.so")]
    return len(sizes), sum(sizes)


def clear_cache() -> int:
    """Remove every cached library; returns how many were removed."""
    removed = 0
    for path in cache_dir().glob("*.so"):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed += 1
        path.with_suffix(".lock").unlink(missing_ok=True)
    return removed
