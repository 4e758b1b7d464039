"""SUNDIALS CVODE called from C on the equations' compiled right-hand side (``sundials-cvode-c``).

The fastest whole-simulation pipeline before it, CasADi's CVODES on the compiled
right-hand side, spends most of a call outside the generated function: CasADi reads the
process CPU clock twice a call (docs/performance.md, "Where the best pipeline's time
goes"). Here a small fixed C driver (``cvode_driver.c``) runs SUNDIALS CVODE itself and
calls the generated C function of the ode form's right-hand side directly, with no CasADi
and no Python between steps: Python calls the driver once a solve (ctypes) and gets the
states at every output time and CVODE's statistics back.

* SUNDIALS: the shared libraries of scikit-sundae's wheel (SUNDIALS 7, found at run time in
  ``scikit_sundae.libs``, names with a hash suffix), linked by path with an rpath. The
  wheel has no C headers: the driver declares the few prototypes it uses (SUNDIALS 7).
* The driver is compiled once with the machine's C compiler and kept in the compile cache
  (:mod:`workbench.equations.compiled`, keyed by its source, flags, libraries, compiler and
  CPU); the right-hand side is the very library the formalism's compile loaded (from the
  cache; under ``compile = "auto"`` one loaded once a process if the run left it in the
  VM), whose symbol's address is handed to the driver with its work sizes, checked here
  first: its C is generated once a process, and a process that finds both in the cache
  compiles nothing. Both count as the run's compile stage, never as integration.
* Methods (options as ``casadi-cvodes``'): Adams-Moulton (orders 1-12; the default) or BDF
  (1-5); the implicit stages solved by fixed-point iteration (``iteration =
  "functional"``, the default: no Jacobian) or Newton with a dense linear solver on
  CVODE's difference-quotient Jacobian (``"newton"``: its n right-hand sides a Jacobian
  are counted in ``n_rhs``). ``max_num_steps`` counts steps towards each output time.

It is offered only where the ode right-hand side can run in C: a formalism built with
``compile = "jit"`` or ``"auto"`` (auto compiles it for this integrator whatever the run's
expected calls) and a C compiler; otherwise the pairing is refused with the reason. A
CVODE failure (flag < 0) is a failed trajectory naming CVODE's flag, message and the time
it reached, with the states at the output times reached and CVODE's statistics up to the
failure (-1, not known, if CVODE could not even allocate its memory); a right-hand side
that is NaN or infinite (or returns an error) stops the integration there, named in the
message, as the other integrators stop at a NaN.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.util
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import casadi as ca
import numpy as np

from workbench.equations import compiled
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.registry import integrator
from workbench.plugins.integrators.casadi_integrators import CvodesOptions

DRIVER = Path(__file__).with_name("cvode_driver.c")
DRIVER_FLAGS = "-O2"
# scikit-sundae's wheel: the libraries the driver links, each lib<name>-<hash>.so.<version>
SUNDIALS = ("sundials_cvode", "sundials_nvecserial", "sundials_sunmatrixdense",
            "sundials_sunlinsoldense", "sundials_core")  # fmt: skip
SUNDIALS_MAJOR = 7  # the driver's declarations are SUNDIALS 7's
METHODS = {"adams": 1, "bdf": 2}  # CV_ADAMS, CV_BDF
MAX_WORK = 1 << 31  # a generated function's work sizes above this are not believed
PREPARED_LIMIT = 8  # right-hand side libraries whose address is kept, least recent out


class Unavailable(RuntimeError):
    """The C route cannot run here (no compiler, no SUNDIALS libraries); says why."""


class Result(ctypes.Structure):
    """``wb_cvode_result`` of the driver."""

    _fields_ = [
        *((name, ctypes.c_longlong) for name in (
            "steps", "rhs_evals", "lin_rhs_evals", "err_test_fails", "nonlin_iters",
            "nonlin_conv_fails", "lin_setups", "jac_evals", "rhs_calls")),
        ("t_reached", ctypes.c_double),
        ("flag", ctypes.c_int),
        ("reached", ctypes.c_int),
        ("flag_name", ctypes.c_char * 32),
        ("message", ctypes.c_char * 512),
    ]  # fmt: skip


@functools.cache
def sundials_libraries() -> tuple[Path, ...]:
    """The SUNDIALS 7 libraries of the installed scikit-sundae wheel, in :data:`SUNDIALS`'s
    order; :class:`Unavailable` if scikit-sundae or one of them is missing."""
    spec = importlib.util.find_spec("sksundae")
    if spec is None or spec.origin is None:
        raise Unavailable("scikit-sundae is not installed (its wheel carries SUNDIALS)")
    folder = Path(spec.origin).parent.parent / "scikit_sundae.libs"
    found = []
    for name in SUNDIALS:
        matches = sorted(folder.glob(f"lib{name}-*.so*")) or sorted(folder.glob(f"lib{name}.so*"))
        if not matches:
            raise Unavailable(f"no lib{name} in {folder} (scikit-sundae's wheel libraries)")
        found.append(matches[-1])
    version = re.search(r"\.so\.(\d+)\.", found[0].name)
    if version is None or int(version.group(1)) != SUNDIALS_MAJOR:
        raise Unavailable(
            f"{found[0].name} is not SUNDIALS {SUNDIALS_MAJOR} (the driver's declarations are)"
        )
    return tuple(found)


@functools.cache
def driver() -> ctypes.CDLL:
    """The C driver, compiled once (cached by source, flags, libraries, compiler and CPU)
    and loaded; :class:`Unavailable` without a compiler or the libraries, RuntimeError
    naming the compiler's error if it does not compile."""
    compiler = compiled.c_compiler()
    if compiler is None:
        raise Unavailable("no C compiler ($CC or cc) to build its C driver")
    libraries = sundials_libraries()
    link = (*map(str, libraries), f"-Wl,-rpath,{libraries[0].parent}")
    code = DRIVER.read_text()
    path = compiled.library_path(code, f"{DRIVER_FLAGS} {' '.join(link)}", compiler,
                                 "wb_cvode_driver")  # fmt: skip
    with compiled.counted():
        compiled.built(code, DRIVER_FLAGS, compiler, path, link)
        library = ctypes.CDLL(str(path))
    solve = library.wb_cvode_solve
    real = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
    longlong, c_int, c_double = ctypes.c_longlong, ctypes.c_int, ctypes.c_double
    solve.argtypes = [
        ctypes.c_void_p, c_int, longlong, longlong, longlong, longlong, real, c_int, real,
        real, c_int, c_int, c_double, c_double, ctypes.c_long, c_double, c_int,
        ctypes.POINTER(Result),
    ]  # fmt: skip
    solve.restype = c_int
    return library


@dataclass
class CompiledRhs:
    """The generated C function of a right-hand side: its address and CasADi work sizes
    (``sz_arg``, ``sz_res``, ``sz_iw``, ``sz_w``), with the library that holds it."""

    address: int
    sizes: tuple[int, int, int, int]
    library: ctypes.CDLL


def compiled_rhs(rhs: Any, n: int) -> CompiledRhs:
    """The compiled C of the ode right-hand side ``rhs`` (a FastFunction built with an
    active compiler): the library the formalism's compile loaded (:meth:`Compiler.library
    <workbench.equations.compiled.Compiler.library>`: from the compile cache, or compiled,
    once a process), its signature and work sizes checked so that the driver cannot be
    handed a wrong one. RuntimeError if it cannot be compiled or does not have the ode
    signature."""
    check_signature(rhs.for_c, n)
    with compiled.counted():  # loading or compiling it is the compile stage
        path, symbol = rhs.compiler.library(rhs)
        return loaded_rhs(path, symbol)


@functools.lru_cache(maxsize=PREPARED_LIMIT)
def loaded_rhs(path: str, symbol: str) -> CompiledRhs:
    """The function ``symbol`` of the compiled library ``path``: its address and work
    sizes, read once a process. RuntimeError unless it takes (t, y) to y' with plausible
    work sizes."""
    library = ctypes.CDLL(path)
    counts = getattr(library, f"{symbol}_n_in"), getattr(library, f"{symbol}_n_out")
    for count in counts:
        count.restype = ctypes.c_longlong
    if (counts[0](), counts[1]()) != (2, 1):
        raise RuntimeError(f"{symbol}: the compiled function does not take (t, y) to y'")
    sizes = [ctypes.c_longlong() for _ in range(4)]
    work = getattr(library, f"{symbol}_work")
    if work(*map(ctypes.byref, sizes)) != 0:
        raise RuntimeError(f"{symbol}: its work sizes could not be read")
    values = tuple(int(size.value) for size in sizes)
    if not (values[0] >= 2 and values[1] >= 1 and all(0 <= v < MAX_WORK for v in values)):
        raise RuntimeError(f"{symbol}: implausible work sizes {values} (sz_arg, sz_res, iw, w)")
    address = ctypes.cast(getattr(library, symbol), ctypes.c_void_p).value
    return CompiledRhs(int(address or 0), values, library)  # type: ignore[arg-type]


def check_signature(function: ca.Function, n: int) -> None:
    """RuntimeError unless ``function`` is (t: 1, y: n) -> (y': n), all dense."""
    shapes = [function.sparsity_in(i) for i in range(function.n_in())]
    shapes += [function.sparsity_out(i) for i in range(function.n_out())]
    expected = [1, n, n]
    if (
        len(shapes) != 3
        or [s.nnz() for s in shapes] != expected
        or not all(s.is_dense() for s in shapes)
    ):
        got = ", ".join(f"{s.size1()}x{s.size2()} ({s.nnz()} nonzeros)" for s in shapes)
        raise RuntimeError(
            f"{function.name()}: expected dense (t: 1, y: {n}) -> (y': {n}), got {got}"
        )


@dataclass(frozen=True)
class CvodeCOptions(CvodesOptions):
    """``casadi-cvodes``' options, with the non-stiff fast path as the default: Adams with
    fixed-point iteration (no Jacobian). For a stiff mechanism: method bdf, iteration
    newton."""

    method: Literal["bdf", "adams"] = "adams"
    iteration: Literal["newton", "functional"] = "functional"


@integrator
class CvodeC(Integrator):
    name = "sundials-cvode-c"
    summary = "SUNDIALS CVODE (Adams or BDF) run in C on the compiled ode right-hand side"
    Options = CvodeCOptions
    accepts: ClassVar[dict[str, int]] = {"ode": 0}

    def incompatibility(self, equations: Any, options: Any) -> str | None:
        form = equations.forms.get("ode")
        if form is None:
            return None  # the form check speaks
        if getattr(form.rhs, "compiler", None) is None or not hasattr(form.rhs, "for_c"):
            if compiled.c_compiler() is None:
                return "runs CVODE in C on the compiled right-hand side: no C compiler here"
            return (
                "runs CVODE in C on the compiled right-hand side, and formalism "
                f"{equations.formalism!r} evaluates it in CasADi's virtual machine: set its "
                "option compile to jit (or auto)"
            )
        try:
            sundials_libraries()
        except Unavailable as error:
            return str(error)
        return None

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        n, times = task.form.n, task.times
        y0 = np.ascontiguousarray(task.y0, dtype=float)
        if y0.shape != (n,):
            raise ValueError(f"y0 has shape {y0.shape}, the ode form has {n} states")
        try:
            solve = driver().wb_cvode_solve
            rhs = compiled_rhs(task.form.rhs, n)
            task.form.rhs.compiler.ran_in_c(task.form.rhs.name)  # for the row's notes
        except (Unavailable, RuntimeError) as error:
            trajectory.success = False
            trajectory.message = f"{self.name}: {error}"
            return
        options = task.options
        grid = np.ascontiguousarray(times, dtype=float)
        y = np.empty((grid.size, n))
        result = Result()
        reached = solve(
            rhs.address, n, *rhs.sizes, grid, grid.size, y0, y, METHODS[options.method],
            int(options.iteration == "newton"), float(task.rtol), float(task.atol),
            int(options.max_num_steps), float(options.max_step), 0, ctypes.byref(result),
        )  # fmt: skip
        reached = max(1, min(int(reached), grid.size))
        trajectory.times, trajectory.y = grid[:reached].copy(), y[:reached]
        self.fill_stats(trajectory, result, options.iteration == "newton")
        if result.flag < 0:
            trajectory.success = False
            name = result.flag_name.decode(errors="replace") or "CVODE error"
            detail = result.message.decode(errors="replace").strip()
            trajectory.message = (
                f"{self.name}: at t = {result.t_reached:g}: {name} (flag {result.flag})"
                + (f": {detail}" if detail else "")
            )

    @staticmethod
    def fill_stats(trajectory: Trajectory, result: Result, newton: bool) -> None:
        s = trajectory.stats
        s.n_steps = int(result.steps)
        s.n_rhs = int(result.rhs_calls)  # CVODE's and its difference-quotient Jacobians'
        s.n_rejected = int(result.err_test_fails)
        s.n_newton = int(result.nonlin_iters)
        s.n_lu = int(result.lin_setups) if newton else -1
        s.n_jac = int(result.jac_evals) if newton else 0
