"""When ``compile = "auto"`` compiles a function to C: when its evaluations repay the compile.

Compiling costs CPU once (the C compiler: about 0.08 s plus 3 s a megabyte of generated C
at ``-O1``) and saves a part of each call (compiled C ran 1.1-12.7x faster than the
CasADi VM on the quick suite's right-hand sides: assumed :data:`COMPILED_SPEEDUP`, a
low end, so that a compile is not bought on hope). Measured figures: docs/performance.md.

A function is compiled when its calls would save more than the smallest compile costs
(:func:`worth_a_look`) and its library is already in the cache (loading costs
milliseconds), or when the run's expected evaluations
(:func:`expected_evaluations`, from the problem's span and the tolerance) times the
saving a call exceed the compile's estimated CPU. Otherwise it stays in the VM and is
compiled once its calls (counted over every run of the same equations in the process)
have spent in the VM what the compile would cost (:func:`calls_to_repay`): the
rent-or-buy rule, which pays at most twice the best choice made with hindsight, whatever
the number of calls turns out to be.
"""

from __future__ import annotations

import math

COMPILE_CPU_FIXED_S = 0.08
"""CPU of compiling the smallest generated function (gcc -O1, measured 0.086-0.11 s)."""
COMPILE_CPU_S_PER_BYTE = 3.0e-6
"""CPU a byte of generated C (measured 2.7-3.1 s a megabyte between 0.16 and 0.5 MB)."""
COMPILED_SPEEDUP = 2.0
"""VM time / compiled time a call assumed before compiling (measured 1.1-12.7)."""
GENERATE_VM_CALLS = 500.0
"""Generating a function's C costs about this many of its VM calls (measured 420-630 on
right-hand sides of 0.13-0.5 MB of C; a large MX Jacobian took seconds)."""
EVALUATIONS_PER_SECOND = 300.0
"""Right-hand-side evaluations a second of simulated time at rtol 1e-4 (the quick suite's
non-stiff runs: 130-650)."""
EVALUATIONS_RTOL_EXPONENT = 0.125
"""Evaluations grow as rtol^-0.125 (the quick suite: about 2x from 1e-4 to 1e-7)."""


def compile_cpu_estimate(code_bytes: int) -> float:
    """Estimated CPU seconds to compile ``code_bytes`` of generated C."""
    return COMPILE_CPU_FIXED_S + COMPILE_CPU_S_PER_BYTE * code_bytes


def saving_per_call(vm_seconds: float) -> float:
    """Seconds a call saves compiled, from its measured VM time."""
    return vm_seconds * (1.0 - 1.0 / COMPILED_SPEEDUP)


def calls_to_repay(vm_seconds: float, code_bytes: int) -> float:
    """Calls after which compiling (generating the C included) has paid for itself (inf
    for a free VM call); ``code_bytes`` 0: before the C is generated."""
    saving = saving_per_call(vm_seconds)
    cost = compile_cpu_estimate(code_bytes) + GENERATE_VM_CALLS * vm_seconds
    return cost / saving if saving > 0 else math.inf


def worth_a_look(calls: float, vm_seconds: float) -> bool:
    """Whether ``calls`` VM calls save enough compiled to repay generating their C (to
    look for it in the cache, which is keyed by it) and the smallest compile, so that
    neither is wasted on a short run."""
    generating = GENERATE_VM_CALLS * vm_seconds
    return calls * saving_per_call(vm_seconds) >= COMPILE_CPU_FIXED_S + generating


def expected_evaluations(span: float, rtol: float) -> float:
    """A run's expected evaluations from the problem's span (s) and the relative tolerance:
    a prior only (a stiff problem under an explicit method takes 100x more); the calls
    themselves decide later (module docstring)."""
    if not (span > 0 and rtol > 0):
        return 0.0
    return EVALUATIONS_PER_SECOND * span * (1e-4 / rtol) ** EVALUATIONS_RTOL_EXPONENT
