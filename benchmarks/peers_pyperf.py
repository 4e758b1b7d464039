"""General trees and robots against ``pin.aba``, timed the way pyperf does: by pyperf.

Run: ``python -m benchmarks.peers_pyperf [--sizes 7 20 50 200] [--robots ur5 panda solo12
talos] [--processes 10]`` (any pyperf option after them, e.g. ``--values 3``).

The models are those of :mod:`benchmarks.peers` (``random``: a free base, then revolute,
prismatic and spherical joints, rotated frames, full inertias; robots of
example-robot-data, Talos being the humanoid, imported by our URDF importer). This
process builds each model's ode right-hand side (the ``recursive`` formalism's articulated
bodies, the graph a compiled build compiles: unrolled, or joint-type kernels above their
size threshold, column ``graph``), compiles it (the default flags,
``compiled.default_flags``, through the compile cache) and
checks its accelerations against ``pin.aba`` (to 1e-9); then pyperf times ours
(``FastFunction.into`` on the compiled library) and ``pin.aba`` (same state) each in
``--processes`` fresh worker processes (10 by default: all 8 models in 11-13 minutes on
2 cores), calibrating the loops of a value to 0.1 s, one
warm-up and 3 values a process, in CPU time (``time.process_time``: this machine is
shared). A process's figure is the mean of its values. Like with like: both are called
from Python as an integrator calls them, ours through ``FastFunction.into(t, y)`` (what
the SciPy plugins call: the state copied into a preallocated input and the generated C
called by a small C extension, :mod:`workbench.equations.fastcall`, or through CasADi's
buffer call where that cannot be built: column ``python_call``), ``pin.aba`` through its
boost-python binding on a preallocated ``data`` and state arrays (where a small model's
time goes: docs/performance-targets.md).

A second line, like for like in C: both sides through the same CasADi buffer call
(``Function.buffer()``, the arguments already in place), ours the same compiled library,
Pinocchio's C++ ``pinocchio::aba`` (the libpinocchio wheel's headers) as a CasADi
external function (``benchmarks/aba_call.cpp``, built by :mod:`benchmarks.anchor` at
``-O3``, Pinocchio's own Release flags, and cached):
no Python conversion on either side, so the ratio is that of the two C codes plus the
same call overhead (columns ``buffer_*``). Both lines are checked against ours to 1e-9
before any timing.

Each worker process loads its own copy of the libraries it times, written into a folder
of its own (under ``/dev/shm`` where there is one) and kept until that benchmark's last
process is done: a compiled library runs 1.1-1.6x slower on some physical pages than on
others, and every process shares a cached file's page-cache pages, so processes loading
the same file are one draw of page placement, not several (docs/performance.md,
2026-11-27). A copy deleted when its process ends does not help: the next process's copy
lands on the pages just freed (7 of the N = 7 library's 8 code pages the same in 4
processes in a row). Copied: ours, the compiled library and the ``fastcall`` extension
that calls it; ``pin.aba``, every compiled file on its call path that is Pinocchio's
(the boost-python module ``pinocchio_pywrap_default``, ``libpinocchio_default`` with
``aba``, ``libeigenpy``, ``libboost_python``, about 80 MB: the module imported from a
mirror of the cmeel prefix, links to the other files); the C line, ours and
``aba_call``'s library. Not copied, on both sides alike: the interpreter, NumPy, CasADi,
libc and libstdc++ (column ``copies``).

Ratios ours / pin over every pair of processes (ours' i, pin's j): the median and the
upper end (max, the slowest process of ours against the fastest of pin's), the figure the
targets are held to (issue 36: a single process's median hides the spread between
processes), on each line (``python -m benchmarks --summary`` names the line of each
verdict). Writes ``benchmarks/results/peers_pyperf-l2-<size>.json`` (pyperf's own file:
``python -m pyperf stats`` reads it) and ``.csv``, one pair of files a machine, named by
its L2 cache a core (the issue's second machine differs from the first by its cache: 512
KiB against 1 MiB), with the CPU (model name, family, model) in column ``cpu``; with ``-o
FILE`` pyperf's file is FILE and the table FILE with the suffix ``.csv`` (a run of some
models keeps the committed results of all eight).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyperf

from benchmarks import anchor
from workbench.execution.environment import cpu_model

RESULTS = Path(__file__).parent / "results"
SIZES = (7, 20, 50, 200)
ROBOTS = ("ur5", "panda", "solo12", "talos")
HUMANOID = ("talos_data/robots/talos_reduced.urdf", {"floating_base": True})
PREPARED = Path(tempfile.gettempdir()) / f"mbs-peers-pyperf-{os.getuid()}.json"
ABA_CALL = Path(__file__).with_name("aba_call.cpp")
# Pinocchio's own build flags (CMake's Release: -O3), not the anchor's -O2, under which
# pinocchio::aba in C was slower than the wheel's pin.aba with its Python call (-O2 / -O3,
# one process, load 5: random N = 20 5.68 / 4.57 us, N = 200 58.2 / 45.6, UR5 1.51 / 1.30)
ABA_CALL_FLAGS = [flag.replace("-O2", "-O3") for flag in anchor.FLAGS]
PYTHON = ("ours", "pin.aba")  # each called from Python as an integrator calls it
BUFFER = ("ours buffer", "pinocchio::aba buffer")  # each through CasADi's buffer call
COPIES = Path("/dev/shm") if Path("/dev/shm").is_dir() else Path(tempfile.gettempdir())
COPIED = ("a copy a process: ours' library and fastcall; pin.aba's pinocchio_pywrap, "
          "libpinocchio_default, libeigenpy, libboost_python; aba_call")  # fmt: skip


def l2_kib(cache: str = "/sys/devices/system/cpu/cpu0/cache") -> int | None:
    """KiB of level-2 cache a core (Linux's sysfs), None where not given."""
    for index in sorted(Path(cache).glob("index*")):
        try:
            if (index / "level").read_text().strip() == "2":
                size = (index / "size").read_text().strip().upper()
                return int(size[:-1]) * 1024 if size.endswith("M") else int(size.rstrip("K"))
        except (OSError, ValueError):
            continue
    return None


def results_stem() -> str:
    """``peers_pyperf-l2-<KiB>k`` on a machine whose L2 is known, else ``peers_pyperf``."""
    size = l2_kib()
    return f"peers_pyperf-l2-{size}k" if size else "peers_pyperf"


def model_of(kind: str, name: str):
    """(our model, pin.Model, PinocchioState) of a random tree (``name`` = N) or a robot."""
    from benchmarks import peers
    from benchmarks.peer_models import PinocchioState, pinocchio_model, random_tree
    from workbench.mechanics.kinematics import TreeKinematics

    peers.ROBOTS.setdefault("talos", HUMANOID)
    if kind == "random":
        model = random_tree(int(name), seed=int(name))
        pin_model, state = pinocchio_model(model, general=True)
        return model, pin_model, state
    model, pin_model = peers.robot_model(name)
    return model, pin_model, PinocchioState(TreeKinematics(model), pin_model)


def prepare(kind: str, name: str) -> dict:
    """Build, compile and check one model in this process: what the workers load."""
    import casadi as ca
    import pinocchio as pin

    from benchmarks.peers import TOLERANCE, random_states
    from workbench.equations import compiled
    from workbench.plugins.formalisms.recursive import ode_function

    model, pin_model, state = model_of(kind, name)
    kinematics = state.kinematics
    function = ode_function(model, kernels=None)  # what a compiled build compiles
    start = time.process_time()
    with compiled.counted():
        generated = compiled.generate(function)
        loaded = compiled.load_generated(generated)
    data, zero = pin_model.createData(), np.zeros(kinematics.nv)
    model_text = PREPARED.with_name(f"{PREPARED.stem}-{kind}-{name}.txt")
    pin_model.saveToText(str(model_text))
    library = ca.external(generated.function.name(), str(generated.path))
    evaluate_ours, ours_arrays = buffered(library)
    evaluate_cpp, cpp_arrays = buffered(pinocchio_call(model_text))
    for q, v in random_states(kinematics, 3, seed=2):
        ours = np.asarray(loaded(0.0, np.concatenate([q, v]))).ravel()[kinematics.nq :]
        q_pin, v_pin = state.state(q, v)
        theirs = state.accelerations(pin.aba(pin_model, data, q_pin, v_pin, zero), q, v)
        ours_arrays[1][:] = np.concatenate([q, v])  # the buffer-call line, both sides
        cpp_arrays[1][:] = np.concatenate([q_pin, v_pin])
        evaluate_ours(), evaluate_cpp()
        ours_c = ours_arrays[2][kinematics.nq :]
        theirs_c = state.accelerations(cpp_arrays[2][kinematics.nv :], q, v)
        for who, a, b in (("pin.aba", ours, theirs), ("pinocchio::aba (C)", ours_c, theirs_c)):
            difference = float(np.abs(a - b).max()) / max(1.0, float(np.abs(b).max()))
            if not difference <= TOLERANCE:
                raise AssertionError(f"{kind} {name}: {who} differs from ours by {difference:.2e}")
    return {
        "kind": kind, "name": name, "nv": kinematics.nv, "library": str(generated.path),
        "model_text": str(model_text),
        "symbol": generated.function.name(), "instructions": function.n_instructions(),
        "code_bytes": len(generated.code), "library_bytes": generated.path.stat().st_size,
        "graph": "kernels" if function.is_a("MXFunction") else "unrolled",
        "python_call": python_call(loaded),
        "prepare_cpu_s": time.process_time() - start,
        "types": " ".join(sorted({j.type for j in kinematics.order})),
    }  # fmt: skip


def python_call(loaded) -> str:
    """How ``FastFunction.into`` reaches our library: "direct" (workbench/equations/
    fastcall.c) or "buffer" (CasADi's buffer call: no Python headers, WORKBENCH_FASTCALL=0)."""
    from workbench.equations.evaluate import FastFunction

    return "direct" if type(FastFunction(loaded).into).__name__ == "Caller" else "buffer"


_TIMED: dict[str, object] = {}


def timed_call(prepared: dict, who: str, copies: Path):
    """The call to time in a worker: ours (the compiled library through FastFunction) or
    pin.aba, at one random state (made once a process, outside the timing), from copies
    of their libraries in a new folder under ``copies``."""
    key = f"{prepared['kind']} {prepared['name']} {who}"
    if key not in _TIMED:
        folder = Path(tempfile.mkdtemp(dir=copies))
        if who == PYTHON[1]:
            private_pinocchio(folder)  # before anything imports pinocchio
        import casadi as ca
        import pinocchio as pin

        from benchmarks.peers import random_states
        from workbench.equations import compiled
        from workbench.equations.evaluate import FastFunction

        _, pin_model, state = model_of(prepared["kind"], prepared["name"])
        ((q, v),) = random_states(state.kinematics, 1, seed=3)
        q_pin, v_pin = state.state(q, v)
        if who == PYTHON[0]:
            private_fastcall(folder)
            library = copy_into(folder, prepared["library"])
            fast = FastFunction(compiled.load_library(library, prepared["symbol"]))
            y = np.concatenate([q, v])
            _TIMED[key] = lambda: fast.into(0.0, y)
        elif who == "pin.aba":
            data, zero = pin_model.createData(), np.zeros(state.kinematics.nv)
            _TIMED[key] = lambda: pin.aba(pin_model, data, q_pin, v_pin, zero)
        else:  # the buffer-call line: the arguments in place, CasADi's call into C
            if who == BUFFER[0]:
                library = copy_into(folder, prepared["library"])
                function, y = ca.external(prepared["symbol"], str(library)), [q, v]
            else:
                aba_call = copy_into(folder, anchor.build(ABA_CALL, ABA_CALL_FLAGS))
                function = pinocchio_call(Path(prepared["model_text"]), aba_call)
                y = [q_pin, v_pin]
            _TIMED[key], arrays = buffered(function)
            arrays[1][:] = np.concatenate(y)
            _TIMED[key + " arrays"] = arrays  # kept alive: evaluate points to them
    return _TIMED[key]


def copy_into(folder: Path, path: Path | str) -> Path:
    """A copy of the file ``path`` in ``folder``: new page-cache pages."""
    target = folder / Path(path).name
    shutil.copyfile(path, target)
    return target


def private_fastcall(folder: Path) -> None:
    """Make ``FastFunction`` call through a copy of the ``fastcall`` extension."""
    import importlib.util

    from workbench.equations import fastcall

    module = fastcall.extension()
    if module is not None:
        path = copy_into(folder, module.__file__)
        spec = importlib.util.spec_from_file_location(fastcall.MODULE, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        fastcall.extension = lambda: module


def private_pinocchio(folder: Path) -> None:
    """Make ``import pinocchio`` load copies of Pinocchio's compiled files on ``pin.aba``'s
    call path: its boost-python module (in a copy of the ``pinocchio`` and ``eigenpy``
    packages) and ``libpinocchio_default``, ``libeigenpy``, ``libboost_python`` (copies in a
    mirror of the cmeel prefix's ``lib``, where the module's RUNPATH finds them, the other
    libraries linked). Checked in ``/proc/self/maps``."""
    import importlib.util

    spec = importlib.util.find_spec("pinocchio")
    assert spec is not None and spec.origin is not None and "pinocchio" not in sys.modules
    site = Path(spec.origin).parent.parent  # <prefix>/lib/python3.X/site-packages
    lib = site.parents[1]
    mirror = folder / "lib"
    (mirror / site.relative_to(lib)).mkdir(parents=True)
    copied = []
    for entry in lib.iterdir():
        if entry.name.startswith(("libpinocchio_default.", "libeigenpy.", "libboost_python")):
            copied.append(copy_into(mirror, entry))
        elif not entry.is_dir():
            (mirror / entry.name).symlink_to(entry)
    for package in ("pinocchio", "eigenpy"):
        shutil.copytree(site / package, mirror / site.relative_to(lib) / package)
    sys.path.insert(0, str(mirror / site.relative_to(lib)))
    import pinocchio

    mapped = {line.split(maxsplit=5)[-1].strip() for line in open("/proc/self/maps")}
    module = Path(pinocchio.pinocchio_pywrap_default.__file__)
    originals = [site / "pinocchio" / module.name, *(lib / path.name for path in copied)]
    if str(module) not in mapped or any(os.path.realpath(p) in mapped for p in originals):
        raise RuntimeError(f"pin.aba does not run from the copies in {mirror}")


def pinocchio_call(model_text: Path, library: Path | None = None):
    """``pinocchio::aba`` of the model saved in ``model_text`` as a CasADi external
    function (benchmarks/aba_call.cpp: (t, [q; v]) -> [v; a], Pinocchio's coordinates),
    from ``library`` (a copy of the built one) or the built one."""
    import ctypes

    import casadi as ca

    library = library or anchor.build(ABA_CALL, ABA_CALL_FLAGS)
    loader = ctypes.CDLL(str(library))  # the handle casadi.external opens too
    loader.aba_call_load.argtypes = [ctypes.c_char_p]
    if loader.aba_call_load(str(model_text).encode()) < 0:
        raise RuntimeError(f"aba_call_load could not read {model_text}")
    return ca.external("aba_call", str(library))


def buffered(function):
    """(evaluate, [t, y, out, buffer]) of ``function``'s buffer call bound to those arrays
    (the buffer is kept: ``evaluate`` holds only a pointer to it): ``evaluate()`` is
    CasADi's call into the C with the arguments already in place."""
    buffer, evaluate = function.buffer()
    arrays = [np.zeros(function.nnz_in(0)), np.zeros(function.nnz_in(1)),
              np.zeros(function.nnz_out(0))]  # fmt: skip
    buffer.set_arg(0, memoryview(arrays[0]))
    buffer.set_arg(1, memoryview(arrays[1]))
    buffer.set_res(0, memoryview(arrays[2]))
    return evaluate, [*arrays, buffer]


def time_loops(loops: int, prepared: dict, who: str, copies: str) -> float:
    """CPU seconds of ``loops`` calls (pyperf's time function; the set-up is not timed)."""
    call = timed_call(prepared, who, Path(copies))
    start = time.process_time()
    for _ in range(loops):
        call()
    return time.process_time() - start


def process_means(benchmark: pyperf.Benchmark) -> np.ndarray:
    """Mean seconds a call of each worker process (runs with values; calibration left out)."""
    return np.array([np.mean(run.values) for run in benchmark.get_runs() if run.values])


def summarize(suite: pyperf.BenchmarkSuite, prepared: list[dict], load: list[float]) -> list:
    rows = []
    for item in prepared:
        label = f"{item['kind']} {item['name']}"
        row = {k: item[k] for k in ("kind", "name", "nv", "types", "graph", "python_call",
                                    "instructions", "code_bytes", "library_bytes")}  # fmt: skip
        for prefix, (us, them) in (("", PYTHON), ("buffer_", BUFFER)):
            ours = process_means(suite.get_benchmark(f"{label} {us}"))
            pin = process_means(suite.get_benchmark(f"{label} {them}"))
            ratios = (ours[:, None] / pin[None, :]).ravel()
            row.update({
                f"{prefix}ours_us": float(np.median(ours) * 1e6),
                f"{prefix}pin_aba_us": float(np.median(pin) * 1e6),
                f"{prefix}ratio_median": float(np.median(ratios)),
                f"{prefix}ratio_min": float(ratios.min()),
                f"{prefix}ratio_max": float(ratios.max()),
            })  # fmt: skip
        row.update({"processes": f"{len(ours)}+{len(pin)}", "load1_before": load[0],
                    "load1_after": load[1], "copies": COPIED, "cpu": cpu_model(),
                    "l2_kib": l2_kib(),
                    "date": time.strftime("%Y-%m-%d", time.gmtime())})  # fmt: skip
        rows.append(row)
    return rows


def main() -> None:
    def worker_args(cmd: list[str], args) -> None:
        cmd.extend(["--sizes", *map(str, args.sizes), "--robots", *args.robots])
        cmd.extend(["--copies", args.copies, "--prepared", str(PREPARED)])

    runner = pyperf.Runner(
        processes=10, program_args=("-m", "benchmarks.peers_pyperf"), add_cmdline_args=worker_args
    )
    runner.argparser.add_argument("--sizes", nargs="*", default=[str(n) for n in SIZES])
    runner.argparser.add_argument("--robots", nargs="*", default=list(ROBOTS))
    runner.argparser.add_argument("--copies", default="", help=argparse.SUPPRESS)
    # the parent's file, named to the workers: pyperf gives them no TMPDIR of the parent's
    runner.argparser.add_argument("--prepared", default=str(PREPARED), help=argparse.SUPPRESS)
    args = runner.parse_args()
    models = [("random", n) for n in args.sizes] + [("robots", r) for r in args.robots]
    if not args.worker:
        import warnings

        warnings.filterwarnings("ignore")
        load_before = os.getloadavg()[0]
        prepared = []
        for kind, name in models:
            prepared.append(prepare(kind, name))
            print(f"prepared {kind} {name}", file=sys.stderr, flush=True)
        PREPARED.write_text(json.dumps(prepared))
    prepared = json.loads(Path(args.prepared).read_text())
    if not args.worker:  # the workers' copies, a benchmark's kept until its last process ends
        args.copies = tempfile.mkdtemp(prefix=PREPARED.stem + "-", dir=COPIES)
    suite = []
    try:
        for item in prepared:
            label = f"{item['kind']} {item['name']}"
            for who in (*PYTHON, *BUFFER):
                name = f"{label} {who}"
                suite.append(runner.bench_time_func(name, time_loops, item, who, args.copies))
                if not args.worker:
                    for folder in Path(args.copies).iterdir():
                        shutil.rmtree(folder)
    finally:
        if not args.worker:
            shutil.rmtree(args.copies, ignore_errors=True)
    if args.worker:
        return
    result = pyperf.BenchmarkSuite([b for b in suite if b is not None])
    if args.output:  # pyperf wrote its file there; the table goes beside it
        table_path = Path(args.output).with_suffix(".csv")
    else:
        RESULTS.mkdir(exist_ok=True)
        result.dump(str(RESULTS / f"{results_stem()}.json"), replace=True)
        table_path = RESULTS / f"{results_stem()}.csv"
    import pandas as pd

    rows = summarize(result, prepared, [load_before, os.getloadavg()[0]])
    table = pd.DataFrame(rows)
    table.to_csv(table_path, index=False)
    with pd.option_context("display.width", 200):
        print(table.drop(columns=["types"]).to_string(index=False, float_format="{:.3g}".format))


if __name__ == "__main__":
    main()
