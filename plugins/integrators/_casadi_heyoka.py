"""Translate a CasADi Function into heyoka expressions, instruction by instruction.

heyoka's Taylor integrators take the right-hand side as an expression tree, which it
differentiates (automatically, to the order of the method) and compiles with LLVM. The
equations hold it as a CasADi Function; an SX Function is a straight-line program over a
work array ``w`` (``Function.instruction_id / _input / _output / _constant``): reading it
once and mapping each operation onto the heyoka one rebuilds the same graph, with common
subexpressions shared (heyoka expressions are shared nodes). An MX Function is expanded
to SX first; one holding a numeric linear solve (large systems) cannot be, and
:class:`TranslationError` says so.

Comparisons and ``if_else`` become heyoka's ``select``; ``fabs``, ``sign``, ``fmin`` and
``fmax`` are written with it. An operation without a heyoka counterpart raises
:class:`TranslationError` naming it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import casadi as ca
import heyoka as hy


class TranslationError(ValueError):
    """The CasADi graph uses something heyoka cannot express (named in the message)."""


def _select(condition: Any, a: Any, b: Any) -> Any:
    return hy.select(condition, a, b)


_ZERO, _ONE = hy.expression(0.0), hy.expression(1.0)

_UNARY: dict[int, Callable[[Any], Any]] = {
    ca.OP_ASSIGN: lambda x: x,
    ca.OP_NEG: lambda x: -x,
    ca.OP_SQ: lambda x: x * x,
    ca.OP_TWICE: lambda x: 2.0 * x,
    ca.OP_INV: lambda x: 1.0 / x,
    ca.OP_SQRT: hy.sqrt,
    ca.OP_SIN: hy.sin,
    ca.OP_COS: hy.cos,
    ca.OP_TAN: hy.tan,
    ca.OP_ASIN: hy.asin,
    ca.OP_ACOS: hy.acos,
    ca.OP_ATAN: hy.atan,
    ca.OP_SINH: hy.sinh,
    ca.OP_COSH: hy.cosh,
    ca.OP_TANH: hy.tanh,
    ca.OP_ASINH: hy.asinh,
    ca.OP_ACOSH: hy.acosh,
    ca.OP_ATANH: hy.atanh,
    ca.OP_EXP: hy.exp,
    ca.OP_LOG: hy.log,
    ca.OP_EXPM1: hy.expm1,
    ca.OP_LOG1P: hy.log1p,
    ca.OP_ERF: hy.erf,
    ca.OP_FABS: lambda x: _select(hy.lt(x, _ZERO), -x, x),
    ca.OP_SIGN: lambda x: _select(hy.gt(x, _ZERO), _ONE, _select(hy.lt(x, _ZERO), -_ONE, _ZERO)),
    ca.OP_NOT: lambda x: hy.eq(x, _ZERO),
}

_BINARY: dict[int, Callable[[Any, Any], Any]] = {
    ca.OP_ADD: lambda a, b: a + b,
    ca.OP_SUB: lambda a, b: a - b,
    ca.OP_MUL: lambda a, b: a * b,
    ca.OP_DIV: lambda a, b: a / b,
    ca.OP_POW: lambda a, b: a**b,
    ca.OP_CONSTPOW: lambda a, b: a**b,
    ca.OP_ATAN2: hy.atan2,
    ca.OP_HYPOT: lambda a, b: hy.sqrt(a * a + b * b),
    ca.OP_LT: hy.lt,
    ca.OP_LE: hy.lte,
    ca.OP_EQ: hy.eq,
    ca.OP_NE: hy.neq,
    ca.OP_AND: lambda a, b: hy.logical_and([hy.neq(a, _ZERO), hy.neq(b, _ZERO)]),
    ca.OP_OR: lambda a, b: hy.logical_or([hy.neq(a, _ZERO), hy.neq(b, _ZERO)]),
    ca.OP_FMIN: lambda a, b: _select(hy.lt(a, b), a, b),
    ca.OP_FMAX: lambda a, b: _select(hy.gt(a, b), a, b),
    ca.OP_IF_ELSE_ZERO: lambda c, x: _select(hy.neq(c, _ZERO), x, _ZERO),
    ca.OP_COPYSIGN: lambda a, b: _select(
        hy.lt(b, _ZERO), -_UNARY[ca.OP_FABS](a), _UNARY[ca.OP_FABS](a)
    ),
}

_NAMES = {
    getattr(ca, name): name.removeprefix("OP_").lower()
    for name in dir(ca)
    if name.startswith("OP_")
}


def as_sx_function(function: ca.Function) -> ca.Function:
    """``function`` as an SX Function (an MX one expanded); TranslationError if it cannot be."""
    if function.is_a("SXFunction"):
        return function
    try:
        return function.expand()
    except RuntimeError as error:
        reason = str(error).strip().splitlines()[-1] if str(error).strip() else type(error).__name__
        raise TranslationError(
            f"{function.name()} is an MX graph that cannot be expanded to SX (a numeric linear "
            f"solve of a large system?): {reason}"
        ) from None


def translate(function: ca.Function, inputs: Sequence[Sequence[Any]]) -> list[list[Any]]:
    """Every output of ``function`` (its nonzeros, column-major) as heyoka expressions.

    ``inputs``: for each input of ``function``, one heyoka expression a nonzero (e.g.
    ``[[hy.time], hy.make_vars(...)]``). Outputs must be dense.
    """
    function = as_sx_function(function)
    if len(inputs) != function.n_in():
        raise TranslationError(f"{function.name()} has {function.n_in()} inputs, not {len(inputs)}")
    for i, given in enumerate(inputs):
        if len(given) != function.nnz_in(i):
            raise TranslationError(
                f"{function.name()}: input {i} has {function.nnz_in(i)} nonzeros, not {len(given)}"
            )
    outputs: list[list[Any]] = [[_ZERO] * function.nnz_out(i) for i in range(function.n_out())]
    work: dict[int, Any] = {}
    for k in range(function.n_instructions()):
        op = function.instruction_id(k)
        args, results = function.instruction_input(k), function.instruction_output(k)
        if op == ca.OP_INPUT:
            work[results[0]] = inputs[args[0]][args[1]]
        elif op == ca.OP_OUTPUT:
            outputs[results[0]][results[1]] = work[args[0]]
        elif op == ca.OP_CONST:
            work[results[0]] = hy.expression(float(function.instruction_constant(k)))
        elif op in _UNARY:
            work[results[0]] = _UNARY[op](work[args[0]])
        elif op in _BINARY:
            work[results[0]] = _BINARY[op](work[args[0]], work[args[1]])
        else:
            raise TranslationError(
                f"{function.name()}: CasADi operation {_NAMES.get(op, op)!r} has no heyoka "
                "counterpart in this translator"
            )
    return outputs
