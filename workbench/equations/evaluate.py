"""Low-overhead numerical evaluation of CasADi Functions in hot loops.

``Function.__call__`` costs tens of microseconds of Python overhead per call, more than
the dynamics of a small mechanism (docs/performance.md). :class:`FastFunction` binds
preallocated NumPy arrays to a ``Function.buffer()`` once and evaluates into them. Outputs
are dense (the builder must ``densify`` them: buffers hold only structural nonzeros). With
an active :class:`~workbench.equations.compiled.Compiler` the Function is compiled to C at
its first call and the same arrays are bound to the compiled function's buffer; under
``compile = "auto"`` only if the run's expected evaluations repay that, decided anew for
each run (:mod:`workbench.equations.compile_policy`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import casadi as ca
import numpy as np

from workbench.equations import fastcall
from workbench.equations.compile_policy import vm_seconds_estimate
from workbench.equations.compiled import Compiler


class FastFunction:
    """A CasADi Function evaluated through preallocated buffers.

    ``f(*args)`` returns a tuple of NumPy arrays (copies, safe to keep), one per output,
    shaped (rows,) for column outputs and (rows, cols) otherwise. ``f.into(*args)``
    returns the internal arrays themselves (overwritten by the next call).
    """

    def __init__(
        self, function: ca.Function, compiler: Compiler | None = None,
        for_c: ca.Function | None = None,
    ) -> None:  # fmt: skip
        self.function = function  # the symbolic Function (CasADi integrators, pickling)
        self.for_c = for_c if for_c is not None else function  # the graph compiled to C
        self.compiler = compiler if compiler is not None and compiler.active else None
        self.name = function.name()
        self._n_calls = 0  # calls through Python (n_calls adds the direct calls)
        self._direct: object | None = None  # compiled: the C extension's call (fastcall)
        self._library: object | None = None  # the library it calls, kept loaded
        self.vm_seconds = 0.0  # compile=auto: a VM call's estimated seconds
        self._pending_bind = True  # compile=auto: no buffers bound yet
        self._inputs = []
        for i in range(function.n_in()):
            sparsity = function.sparsity_in(i)
            if not sparsity.is_dense():
                raise ValueError(f"{self.name}: input {i} must be dense")
            self._inputs.append(np.zeros(sparsity.numel()))
        self._outputs = []
        self._views = []
        for i in range(function.n_out()):
            sparsity = function.sparsity_out(i)
            if not sparsity.is_dense():
                raise ValueError(f"{self.name}: output {i} must be dense (use casadi.densify)")
            rows, cols = sparsity.shape
            array = np.zeros(rows * cols)
            self._outputs.append(array)
            self._views.append(array if cols == 1 else array.reshape(cols, rows).T)
        self._result = tuple(self._views)
        self.evaluated = function  # what runs: ``function`` or its compiled C
        self._pending = self.compiler is not None
        if self._pending:  # compiled on first use: a run compiles only what is called
            self._evaluate = self._compile_and_evaluate
            self.into = self._specialized_into()  # type: ignore[method-assign]
        else:
            self._bind(function)

    def _bind(self, function: ca.Function) -> None:
        self.evaluated = function
        self._buffer, self._evaluate = function.buffer()
        self._bound_evaluate = self._evaluate
        for i, array in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(array))
        for i, array in enumerate(self._outputs):
            self._buffer.set_res(i, memoryview(array))
        self.into = self._specialized_into()  # type: ignore[method-assign]
        if self._direct is not None:
            self._n_calls += self._direct.calls  # type: ignore[attr-defined]
        self._direct = self._library = None
        # a library of ours: called from C, without CasADi's buffer call (fastcall.py);
        # what the C extension does not take (other types, shapes) goes to _into
        direct = fastcall.caller(function, self._inputs, self._outputs, self._result, self._into)
        if direct is not None:
            self._direct, self._library = direct
            self.into = self._direct  # type: ignore[method-assign]

    @property
    def n_calls(self) -> int:
        """Evaluations so far (through Python and directly from C)."""
        direct = self._direct.calls if self._direct is not None else 0  # type: ignore[attr-defined]
        return self._n_calls + direct

    def _specialized_into(self) -> Callable[..., tuple[np.ndarray, ...]]:
        """:meth:`into` as a closure over the buffers, unrolled for 2 and 3 arguments:
        the Python-side cost per call is then a fraction of a microsecond, less than
        ``pin.aba``'s (benchmarks/overhead.py). A one-element input (the time) is set as
        ``a[0] = x``, cheaper than ``a[...] = x``; a 1-element array given there raises
        ValueError like anything but floats and 1-D arrays, and takes :meth:`into`."""
        inputs, evaluate, result, general = self._inputs, self._evaluate, self._result, self._into
        keys = [0 if array.size == 1 else ... for array in inputs] + [...] * 3
        k0, k1, k2 = keys[:3]
        if len(inputs) == 2:
            a0, a1 = inputs

            def into2(x0: object, x1: object) -> tuple[np.ndarray, ...]:
                try:
                    a0[k0] = x0
                    a1[k1] = x1
                except ValueError:
                    return general(x0, x1)
                evaluate()
                self._n_calls += 1
                return result

            return into2
        if len(inputs) == 3:
            a0, a1, a2 = inputs

            def into3(x0: object, x1: object, x2: object) -> tuple[np.ndarray, ...]:
                try:
                    a0[k0] = x0
                    a1[k1] = x1
                    a2[k2] = x2
                except ValueError:
                    return general(x0, x1, x2)
                evaluate()
                self._n_calls += 1
                return result

            return into3
        return general

    def _compile_and_evaluate(self) -> None:
        self.compile()
        self._evaluate()

    def compile(self) -> bool:
        """Compile now (normally done at the first call; compile=auto: if that repays);
        True if evaluation runs C."""
        if self._pending:
            self._pending = False
            assert self.compiler is not None
            if self.compiler.mode == "auto":
                self.vm_seconds = vm_seconds_estimate(self.function)
                self.compiler.tracked.append(self)
                self.reconsider(self.compiler.expected_calls)
            else:
                self._bind(self.compiler.load(self.for_c) or self.function)
        return self.evaluated is not self.function

    def reconsider(self, calls: float) -> None:
        """compile=auto: run in C if ``calls`` calls (what this run expects) repay the
        compile, else in the VM (:meth:`Compiler.decide`); called between runs, never
        within one: a switch there changed the run's steps, and its repeats then differed
        from it (a row warned "not reproducible" for the compile's sake)."""
        assert self.compiler is not None
        loaded = self.compiler.decide(self.for_c, self.vm_seconds, calls)
        chosen = loaded if loaded is not None else self.function
        if chosen is not self.evaluated or self._pending_bind:
            self._pending_bind = False
            self._bind(chosen)

    def into(self, *args: object) -> tuple[np.ndarray, ...]:
        """Evaluate at ``args``; returns the internal output arrays (see the class)."""
        return self._into(*args)

    def _into(self, *args: object) -> tuple[np.ndarray, ...]:
        # np.ravel/np.ndim on every argument cost microseconds: only on the slow path
        if len(args) != len(self._inputs):
            raise TypeError(f"{self.name}: expected {len(self._inputs)} arguments")
        try:
            for array, value in zip(self._inputs, args, strict=True):
                array[...] = value
        except ValueError:  # columns (n, 1), matrices, CasADi DM
            for array, value in zip(self._inputs, args, strict=True):
                array[:] = np.ravel(value) if np.ndim(value) else value
        self._evaluate()
        self._n_calls += 1
        return self._result

    def __call__(self, *args: object) -> tuple[np.ndarray, ...]:
        return tuple(view.copy() for view in self.into(*args))

    @property
    def outputs(self) -> tuple[np.ndarray, ...]:
        """The internal output arrays: the last call's values (overwritten by the next)."""
        return self._result

    def cpu_per_call(self, batches: int = 5, batch_s: float = 1e-3) -> tuple[float, float]:
        """Least and greatest CPU seconds of one call, over ``batches`` batches of calls at
        the last call's arguments, each batch long enough (``batch_s``) for the clock; the
        calls are not counted in ``n_calls`` (a unit cost of :mod:`counted work
        <workbench.execution.counted_work>`)."""
        if self._pending:
            self.compile()
        # what runs now (VM or C), not compile=auto's counting wrapper: timing is no call
        return cpu_per_call(self._bound_evaluate, batches, batch_s)

    def __getstate__(self) -> dict:
        for_c = self.for_c if self.for_c is not self.function else None
        return {"function": self.function, "compiler": self.compiler, "for_c": for_c}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["function"], state.get("compiler"), state.get("for_c"))  # type: ignore[misc]


def cpu_per_call(call: Callable[[], object], batches: int, batch_s: float) -> tuple[float, float]:
    """Least and greatest CPU seconds of ``call()`` over ``batches`` batches, each of as many
    calls as make it last ``batch_s`` of CPU (doubling from one call)."""
    clock = time.process_time
    calls = 1
    while True:
        start = clock()
        for _ in range(calls):
            call()
        spent = clock() - start
        if spent >= batch_s or calls >= 1 << 20:
            break
        calls *= 2
    samples = [spent / calls]
    for _ in range(batches - 1):
        start = clock()
        for _ in range(calls):
            call()
        samples.append((clock() - start) / calls)
    return min(samples), max(samples)


def dense_function(
    name: str,
    inputs: list,
    outputs: list,
    input_names: list[str] | None = None,
    output_names: list[str] | None = None,
    compiler: Compiler | None = None,
    for_c: tuple[list, list] | None = None,
) -> FastFunction:
    """Build a CasADi Function with dense outputs and wrap it for fast evaluation
    (compiled to C on first use if ``compiler`` is active). ``for_c``: (inputs, outputs)
    of another graph of the same function to compile (one CasADi can generate C for)."""

    def function_of(inputs: list, outputs: list) -> ca.Function:
        outputs = [ca.densify(o) for o in outputs]
        if input_names and output_names:
            return ca.Function(name, inputs, outputs, input_names, output_names)
        return ca.Function(name, inputs, outputs)

    c_function = function_of(*for_c) if for_c is not None else None
    return FastFunction(function_of(inputs, outputs), compiler, c_function)


class LazyFunction:
    """A FastFunction built on first use.

    Jacobians can cost more to build (seconds for a deep spatial chain) than a run that
    never asks for them saves; explicit integrators never do. Same interface as
    :class:`FastFunction`; ``n_calls`` is 0 until built.
    """

    def __init__(self, builder: Callable[[], FastFunction]) -> None:
        self._builder: Callable[[], FastFunction] | None = builder
        self._fast: FastFunction | None = None

    @property
    def fast(self) -> FastFunction:
        if self._fast is None:
            assert self._builder is not None
            self._fast = self._builder()
            self._builder = None
        return self._fast

    @property
    def built(self) -> bool:
        return self._fast is not None

    @property
    def function(self) -> ca.Function:
        return self.fast.function

    @property
    def n_calls(self) -> int:
        return self._fast.n_calls if self._fast is not None else 0

    def into(self, *args: object) -> tuple[np.ndarray, ...]:
        return self.fast.into(*args)

    def compile(self) -> bool:
        return self.fast.compile()

    def __call__(self, *args: object) -> tuple[np.ndarray, ...]:
        return self.fast(*args)

    def __getstate__(self) -> dict:
        return {"fast": self.fast}

    def __setstate__(self, state: dict) -> None:
        self._builder, self._fast = None, state["fast"]


def lazy_dense_function(
    name: str, inputs: list, outputs: Callable[[], list], compiler: Compiler | None = None,
    for_c: tuple[list, Callable[[], list]] | None = None,
) -> LazyFunction:  # fmt: skip
    """:func:`dense_function` deferred until first use; ``outputs`` builds the expressions
    (``for_c``: the inputs and the builder of the graph to compile, if another)."""

    def build() -> FastFunction:
        c_graph = (for_c[0], for_c[1]()) if for_c is not None else None
        return dense_function(name, inputs, outputs(), compiler=compiler, for_c=c_graph)

    return LazyFunction(build)


EXPAND_MAP_LIMIT = 20_000
"""Instructions (n points times the function's) up to which :func:`evaluate_along`
evaluates ``function.map(n)`` expanded into one SX graph: the VM then runs the n copies
straight through instead of calling the function once a point, the same operations and
bits (a simple pendulum's observables at a tiny run's 201 samples: ``Observables.along``
0.66 -> 0.48 ms, a run's metrics 1.29 -> 1.06 ms; medians of 8 rounds, interleaved).
Built once per function and n (4.7 ms -> 24 ms at 29,000 instructions); beyond about
30,000 the copies ran no faster (docs/performance.md)."""


def evaluate_along(function: ca.Function, n: int, args: list[np.ndarray],
                   cache: dict) -> list[np.ndarray]:  # fmt: skip
    """Every output of ``function`` at n points in one call of ``function.map(n)``.

    ``args``: one array per input, its columns side by side ((rows, n) for a column
    input, as ``Function.map`` takes them); returns each output stacked (n, rows, cols),
    values equal to n calls one point at a time. ``cache`` (a dict the caller keeps) holds
    the mapped Function bound to preallocated buffers (:class:`FastFunction`), so its
    outputs come without ``Function.call``'s conversions (4x less on the observables of a
    500-sample run); a Function with sparse outputs goes through ``call``.
    """
    key = (id(function), n)
    if key not in cache or cache[key][0] is not function:  # (an unpickled cache's ids are stale)
        mapped = function.map(n)
        if function.is_a("SXFunction") and n * function.n_instructions() <= EXPAND_MAP_LIMIT:
            mapped = mapped.expand()  # one graph of n copies: no call a point (same bits)
        try:
            cache[key] = (function, FastFunction(mapped))  # function kept: its id stays its own
        except ValueError:  # a sparse output (or input): buffers hold only the nonzeros
            cache[key] = (function, mapped)
    evaluator = cache[key][1]
    if isinstance(evaluator, FastFunction):
        outputs = evaluator.into(*[np.ravel(np.asarray(a, dtype=float), order="F") for a in args])
    else:
        outputs = evaluator.call(list(args))
    stacked = []
    for i, value in enumerate(outputs):
        rows, cols = function.sparsity_out(i).shape
        # a C-ordered copy, as np.asarray(DM) gives: NumPy reductions over these arrays
        # (einsum) sum in an order that follows the memory layout, down to the last bit
        stacked.append(np.array(value, order="C").reshape(rows, n, cols).transpose(1, 0, 2))
    return stacked
