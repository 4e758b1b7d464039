"""When ``compile = "auto"`` compiles a function to C: when its evaluations repay the compile.

Compiling costs CPU once (the C compiler: about 0.04 s plus 3.2 s a megabyte of generated
C at the default flags) and saves a part of each call (compiled C ran 1.1-12.7x faster
than the CasADi VM on the quick suite's right-hand sides: assumed :data:`COMPILED_SPEEDUP`, a
low end, so that a compile is not bought on hope). Measured figures: docs/performance.md.

The decision is a function of the run alone, so that a row does not depend on which runs
its worker did before nor on what the cache holds: each run (:meth:`Compiler.expect
<workbench.equations.compiled.Compiler.expect>`) puts a function in C when the run's
expected evaluations (:func:`expected_evaluations`, from the problem's span and the
tolerance) times the saving a call exceed the compile's estimated CPU
(:func:`calls_to_repay`, with the C's size estimated from the graph:
:func:`code_bytes_estimate`), and in the VM otherwise, even if an earlier run in the same
worker compiled it. A call's VM cost is estimated from the graph's size
(:func:`vm_seconds_estimate`), not timed, so the load cannot tip the decision. A cached
library only makes the C cheaper to get (it is loaded, not compiled), never changes
where a function runs. (Until 2026-11-26 a cached library was loaded by any run and the
VM calls of earlier runs counted towards a compile: rows depended on the worker's history.)
"""

from __future__ import annotations

import math
from typing import Any

COMPILE_CPU_FIXED_S = 0.04
"""CPU of compiling the smallest generated function (0.054-0.077 s below 10 kB of C)."""
COMPILE_CPU_S_PER_BYTE = 3.2e-6
"""CPU a byte of generated C at the default flags (``compiled.default_flags``). Both
constants: the line of least relative error over 42 functions of 6-830 kB of C (the quick
suite's right-hand sides and residuals, random trees N = 7-200, UR5, Panda, Solo12,
Talos): 0.038 s + 3.20 s a MB and 0.036 + 3.42 in two runs (``benchmarks.compile_cost``,
2026-11-27, gcc 12, AMD EPYC, load 1.6-1.9 and 1.0-1.1), 0.53-1.37x the measure, median
0.98. Graphs with locals at ``-O2`` cost 4.9 s a MB of their C (1.19-1.49x the same C at
``-O1``), those at ``-O1`` 3.2. From the graph alone (:func:`code_bytes_estimate`) the
estimate is 0.46-1.44x the measure, median 1.06. Before (gcc -O1 only, 2026-11-26):
0.08 s + 3.0 s a MB."""
COMPILED_SPEEDUP = 2.0
"""VM time / compiled time a call assumed before compiling (measured 1.1-12.7)."""
GENERATE_VM_CALLS = 500.0
"""Generating a function's C costs about this many of its VM calls (measured 420-630 on
right-hand sides of 0.13-0.5 MB of C; a large MX Jacobian took seconds)."""
VM_CALL_SECONDS = 0.7e-6
"""Fixed cost of a CasADi VM call through ``FastFunction.into`` (right-hand sides of 280
and 531 instructions: 1.8 and 2.0 us; measured 2026-11-26 at load 3)."""
VM_SECONDS_PER_INSTRUCTION = 3.7e-9
"""VM seconds an SX instruction (3.65-3.73 ns on right-hand sides of 531 and 5,815)."""
EVALUATIONS_PER_SECOND = 300.0
"""Right-hand-side evaluations a second of simulated time at rtol 1e-4 (the quick suite's
non-stiff runs: 130-650)."""
EVALUATIONS_RTOL_EXPONENT = 0.125
"""Evaluations grow as rtol^-0.125 (the quick suite: about 2x from 1e-4 to 1e-7)."""


def instruction_count(function: Any) -> int:
    """SX instructions a call of ``function`` runs: its own, and for an MX graph those of
    the Functions it calls (a linear solve or other MX node counts one, as does a call of a
    Function that has no instruction list: a rootfinder, an external)."""
    if function.is_a("SXFunction"):
        return int(function.n_instructions())
    if not function.is_a("MXFunction"):
        return 1
    count = 0
    for k in range(function.n_instructions()):
        node = function.instruction_MX(k)
        count += instruction_count(node.which_function()) if node.is_call() else 1
    return count


def vm_seconds_estimate(function: Any) -> float:
    """Estimated VM seconds of one call of ``function``, from its size alone (a function
    of the graph, so the same on every machine and at any load)."""
    return VM_CALL_SECONDS + VM_SECONDS_PER_INSTRUCTION * instruction_count(function)


CODE_BYTES_PER_INSTRUCTION = 30.0
"""Bytes of generated C an SX instruction (28 at 3,872 instructions, 30 at 121,617;
2026-11-26, docs/performance.md)."""
CODE_BYTES_PER_MX_NODE = 200.0
"""Bytes of generated C an MX node or call beside the SX Functions' instructions (random
trees with joint-type kernels, N = 7-200: 118-219; 2026-11-27, docs/performance.md)."""


def code_bytes_estimate(function: Any) -> float:
    """Estimated bytes of ``function``'s generated C, from its size: the decision to
    compile needs no code generated (generating costs about 500 VM calls). Each Function
    it calls counts once, as its C is written once (the recursive formalism's joint-type
    kernels, called at every link: random tree N = 200, 752 kB of C, estimated 707 kB,
    and 5.5 MB when a kernel counted at each call)."""
    seen: set[str] = set()

    def size(function: Any) -> float:
        if function.is_a("SXFunction"):
            return CODE_BYTES_PER_INSTRUCTION * function.n_instructions()
        if not function.is_a("MXFunction"):
            return CODE_BYTES_PER_MX_NODE
        total = 0.0
        for k in range(function.n_instructions()):
            total += CODE_BYTES_PER_MX_NODE
            node = function.instruction_MX(k)
            if node.is_call() and node.which_function().name() not in seen:
                seen.add(node.which_function().name())
                total += size(node.which_function())
        return total

    return size(function)


def compile_cpu_estimate(code_bytes: float) -> float:
    """Estimated CPU seconds to compile ``code_bytes`` of generated C."""
    return COMPILE_CPU_FIXED_S + COMPILE_CPU_S_PER_BYTE * code_bytes


def saving_per_call(vm_seconds: float) -> float:
    """Seconds a call saves compiled, from its (estimated) VM time."""
    return vm_seconds * (1.0 - 1.0 / COMPILED_SPEEDUP)


def calls_to_repay(vm_seconds: float, code_bytes: float) -> float:
    """Calls after which compiling ``code_bytes`` of C (generating it included) has paid
    for itself (inf for a free VM call)."""
    saving = saving_per_call(vm_seconds)
    cost = compile_cpu_estimate(code_bytes) + GENERATE_VM_CALLS * vm_seconds
    return cost / saving if saving > 0 else math.inf


def expected_evaluations(span: float, rtol: float) -> float:
    """A run's expected evaluations from the problem's span (s) and the relative tolerance:
    a prior only (a stiff problem under an explicit method takes 100x more), and all that
    decides: the calls a run actually makes never move a function (module docstring)."""
    if not (span > 0 and rtol > 0):
        return 0.0
    return EVALUATIONS_PER_SECOND * span * (1e-4 / rtol) ** EVALUATIONS_RTOL_EXPONENT
