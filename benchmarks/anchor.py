"""The all-compiled anchor of the whole-simulation benchmark (issue 36, item 4).

Pinocchio's C++ ABA (``pinocchio::aba``, the explicit instantiation in the wheel's
``libpinocchio_default``) as a CasADi external function (``benchmarks/anchor_aba.cpp``),
integrated by CasADi's CVODES: no Python runs between steps. The library is compiled
once with the system C++ compiler from the installed wheels' headers and libraries
(libpinocchio and cmeel-boost under ``cmeel.prefix``, Eigen from CasADi's wheel) and
kept in ``<workbench cache>/anchor/``, keyed by the source, the flags, the compiler and
the header versions (about a minute of CPU cold: Pinocchio's serialization headers).
The model travels as Pinocchio's own text serialization (``Model.saveToText``), read by
``anchor_load``. The integrator is built once per (tolerance, output times) and only
called in the timed rounds: that is what an all-compiled program would do.
:meth:`Anchor.run_c` integrates the same right-hand side with SUNDIALS CVODE driven from
C (the ``sundials-cvode-c`` plugin's driver): no CasADi between steps either.

:func:`build` raises :class:`AnchorUnavailable` with the reason (no compiler, a missing
header or library, a compile error) so that the benchmark says "not measured" and why.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from workbench.files import user_cache_dir

SOURCE = Path(__file__).with_name("anchor_aba.cpp")
# pinocchio's CMake target's interface definitions (pinocchioTargets.cmake), without which
# boost::variant of its 25 joint types does not compile
DEFINES = (
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 "
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12 "
    "-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"
).split()
FLAGS = ["-std=c++17", "-O2", "-DNDEBUG", "-fPIC", "-shared", *DEFINES]
COMPILE_TIMEOUT_S = 900


class AnchorUnavailable(RuntimeError):
    """The anchor cannot be built here; the message says why."""


def _prefixes() -> tuple[Path, Path]:
    """(cmeel.prefix with Pinocchio's and Boost's headers and libraries, Eigen's include)."""
    prefix = eigen = None
    for entry in map(Path, sys.path):
        if prefix is None and (entry / "cmeel.prefix/include/pinocchio/algorithm/aba.hpp").exists():
            prefix = entry / "cmeel.prefix"
        for candidate in (entry / "cmeel.prefix/include/eigen3", entry / "casadi/include/eigen3"):
            if eigen is None and (candidate / "Eigen/Core").exists():
                eigen = candidate
    if prefix is None:
        raise AnchorUnavailable("no Pinocchio C++ headers (the libpinocchio wheel's cmeel.prefix)")
    if eigen is None:
        raise AnchorUnavailable("no Eigen headers (CasADi's wheel or cmeel-eigen)")
    for library in ("libpinocchio_default.so", "libboost_serialization.so"):
        if not (prefix / "lib" / library).exists():
            raise AnchorUnavailable(f"no {library} in {prefix / 'lib'}")
    return prefix, eigen


def _compiler() -> str:
    compiler = shutil.which(os.environ.get("CXX", "g++")) or shutil.which("c++")
    if compiler is None:
        raise AnchorUnavailable("no C++ compiler (g++ or $CXX) on PATH")
    return compiler


def library_path(source: Path = SOURCE, flags: list[str] = FLAGS) -> Path:
    """Where the library of ``source`` is cached (it may not be built yet)."""
    return _library_path(_compiler(), *_prefixes(), source, flags)


def _library_path(
    compiler: str, prefix: Path, eigen: Path, source: Path = SOURCE, flags: list[str] = FLAGS
) -> Path:
    version = subprocess.run([compiler, "--version"], capture_output=True, text=True).stdout
    key = hashlib.sha256()
    for part in (source.read_bytes(), " ".join(flags).encode(), version.encode()):
        key.update(part)
    for header in (prefix / "include/pinocchio/config.hpp", eigen / "Eigen/src/Core/util/Macros.h"):
        key.update(header.read_bytes())
    return user_cache_dir() / "anchor" / f"{source.stem}-{key.hexdigest()[:16]}.so"


def build(source: Path = SOURCE, flags: list[str] = FLAGS) -> Path:
    """The shared library of ``source`` (the anchor's by default) compiled with ``flags``,
    unless the cache holds it."""
    compiler = _compiler()
    prefix, eigen = _prefixes()
    path = _library_path(compiler, prefix, eigen, source, flags)
    folder = path.parent
    if path.exists():
        return path
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as scratch:
        output = Path(scratch) / path.name
        command = [
            compiler, *flags, f"-I{prefix / 'include'}", f"-I{eigen}", str(source),
            "-o", str(output), f"-L{prefix / 'lib'}", "-lpinocchio_default",
            "-lboost_serialization", f"-Wl,-rpath,{prefix / 'lib'}",
        ]  # fmt: skip
        try:
            done = subprocess.run(
                command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S
            )
        except subprocess.TimeoutExpired:
            raise AnchorUnavailable(
                f"compiling the anchor took over {COMPILE_TIMEOUT_S} s"
            ) from None
        if done.returncode != 0:
            errors = [line for line in done.stderr.splitlines() if "error" in line]
            raise AnchorUnavailable(f"the anchor did not compile: {(errors or ['?'])[0].strip()}")
        os.replace(output, path)
    return path


class Anchor:
    """CVODES (CasADi, Adams with fixed-point iteration, as ours) over ``pinocchio::aba``
    in C++ for ``pin_model``, in Pinocchio's coordinates; ``order[i]`` is our index of
    Pinocchio's coordinate i. ``run(rtol)`` integrates ``y0`` (ours) over ``times`` and
    returns the final state in our coordinates."""

    def __init__(self, pin_model, order: np.ndarray, y0: np.ndarray, times: np.ndarray) -> None:
        library = build()
        with tempfile.TemporaryDirectory() as scratch:
            text = Path(scratch) / "model.txt"
            pin_model.saveToText(str(text))
            loader = ctypes.CDLL(str(library))  # the same handle casadi.external opens
            loader.anchor_load.argtypes = [ctypes.c_char_p]
            nv = loader.anchor_load(str(text).encode())
        self.loader = loader
        if nv != order.size:
            raise AnchorUnavailable(f"the anchor read nv = {nv}, expected {order.size}")
        self.rhs = ca.external("anchor_rhs", str(library), {"enable_fd": True})
        self.n, self.times = nv, [float(t) for t in times]
        self.to_pin = np.concatenate([order, order + nv])
        self.back = np.argsort(self.to_pin)
        self.x0 = np.asarray(y0)[self.to_pin]
        self.built: dict[float, ca.Function] = {}

    def accelerations(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """q'' in our coordinates, to check the C++ side against ours before any timing."""
        y = np.concatenate([q, v])[self.to_pin]
        return np.asarray(self.rhs(0.0, y)).ravel()[self.back][self.n :]

    def integrator(self, rtol: float) -> ca.Function:
        if rtol not in self.built:
            t, y = ca.MX.sym("t"), ca.MX.sym("y", 2 * self.n)
            options = {
                "reltol": rtol, "abstol": rtol / 100, "max_num_steps": 100_000,
                "linear_multistep_method": "adams", "nonlinear_solver_iteration": "functional",
                "disable_internal_warnings": True, "show_eval_warnings": False,
            }  # fmt: skip
            dae = {"t": t, "x": y, "ode": self.rhs(t, y)}
            self.built[rtol] = ca.integrator("anchor", "cvodes", dae, 0.0, self.times, options)
        return self.built[rtol]

    def run_c(self, rtol: float) -> tuple[np.ndarray, float, tuple[float, float]]:
        """As :meth:`run` with SUNDIALS CVODE driven from C (the driver of the
        ``sundials-cvode-c`` plugin, Adams with fixed-point iteration) calling
        ``anchor_rhs`` directly: no CasADi between steps either. RuntimeError on a failure
        or where the driver cannot be built."""
        from workbench.plugins.integrators import cvode_c

        try:
            solve = cvode_c.driver().wb_cvode_solve
        except cvode_c.Unavailable as error:
            raise RuntimeError(str(error)) from None
        address = ctypes.cast(self.loader.anchor_rhs, ctypes.c_void_p).value
        grid = np.asarray(self.times, dtype=float)
        y = np.empty((grid.size, 2 * self.n))
        result = cvode_c.Result()
        solve(
            address,
            2 * self.n,
            2,
            1,
            0,
            0,
            grid,
            grid.size,
            self.x0,
            y,
            cvode_c.METHODS["adams"],
            0,
            rtol,
            rtol / 100,
            100_000,
            0.0,
            0,
            ctypes.byref(result),
        )  # fmt: skip  (anchor_rhs_work: sz_arg 2, sz_res 1, no iw, no w)
        if result.flag < 0:
            raise RuntimeError(f"anchor CVODE: {result.flag_name.decode()} ({result.flag})")
        return y[-1][self.back], 0.0, (float(result.steps), float(result.rhs_calls))

    def run(self, rtol: float) -> tuple[np.ndarray, float, tuple[float, float]]:
        """(final state in our coordinates, 0 s excluded, (steps, rhs calls)); RuntimeError
        on a failed step."""
        solve = self.integrator(rtol)
        xf = np.asarray(solve(x0=self.x0)["xf"])
        stats = solve.stats()
        return xf[:, -1][self.back], 0.0, (float(stats["nsteps"]), float(stats["nfevals"]))
