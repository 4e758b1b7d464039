"""Forward dynamics per call against Pinocchio and MuJoCo, same model in all three.

Run: ``python -m benchmarks.peers [--sizes 2 7 20 50 100 200] [--families ...]``.
For every family and size N:

- ``planar``: the ``planar-chain`` problem (N bars on revolutes about z);
- ``spatial``: the ``spatial-chain`` problem (axes cycling z, y, x; skewed rods, so full
  inertia tensors; centres of mass off the rod axis);
- ``tree``: a branched tree of N bodies, bodies 1..N of the ``binary-tree`` problem
  (body k hangs from body k // 2).

Ours is the ``recursive`` formalism's ode right-hand side [q'; v'] (articulated bodies,
:func:`plugins.formalisms.recursive.ode_function`) through a
:class:`~workbench.equations.evaluate.FastFunction`, in the CasADi VM (``vm``) and compiled to C
(``jit``, ``-O1``); ``jit_raw`` is the compiled buffer call alone, without copying the
arguments in (what the Python-side overhead adds is ``jit - jit_raw``). The peers are
``pinocchio.aba`` (a ``pin.Model`` built from ours) and ``mujoco.mj_forward`` (MJCF from
ours, contacts off) — see :mod:`benchmarks.peer_models`. Before timing, the
accelerations of all of them are checked equal (to 1e-9 relative) at random states.
Each time is the best of 5 repeats of :mod:`timeit` (autoranged). ``compile_s`` is a cold
compile (fresh cache directory: C generation + compiler + load).

General trees and imported robots (issue 21, target 1) against ``pin.aba``:

- ``random``: :func:`benchmarks.peer_models.random_tree` (a free base; revolute, prismatic
  and spherical joints; rotated joint frames, unaligned axes, full inertias), N bodies
  (``--random-sizes``, default 7 20 50 200 500). Pinocchio's ``createData`` allocates
  about 62 nv^3 bytes (Pinocchio 4.1, measured: 30 MB, 249 MB, 1.7 GB, 6.0 GB at
  nv = 75, 157, 301, 459), so at 500 bodies (741 DOF) about 25 GB: a size whose estimate
  exceeds 80 % of the available memory gets a row with ``note`` saying so and no
  timing (:func:`pin_data_too_large`);
- ``robots``: UR5, Panda and Solo12 (free base) of example-robot-data, imported by our URDF
  importer, Pinocchio built from the same file.

Their times are CPU seconds a call (``time.process_time`` over batches of about 20 ms),
ours (``jit``, through ``FastFunction.into``) and ``pin.aba`` interleaved, ``--repeats``
times; ``jit/pin`` is the median ratio over the repeats, ``jit/pin_lo`` and
``jit/pin_hi`` its 10 and 90 % quantiles. Accelerations are checked equal first (states
and free-base accelerations mapped by :class:`~benchmarks.peer_models.PinocchioState`).
``compile_cpu_s`` is the cold compile's CPU time, this process and its children (gcc).

Prints a table with the ratios ours/peer and writes ``benchmarks/results/peers.csv``
(chain families) and ``benchmarks/results/peers_general.csv`` (random trees, robots).
Without ``pin`` or ``mujoco`` (the ``bench`` extra) their columns are left empty and the
table says so.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import resource
import tempfile
import time
import timeit
import warnings
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks.peer_models import mujoco_model, pinocchio_model, random_tree
from workbench.equations.compiled import Compiler
from workbench.equations.evaluate import FastFunction
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import Model
from workbench.plugin.registry import get_problem
from workbench.plugins.formalisms.recursive import ode_function
from workbench.problems.scalable import BinaryTree

RESULTS = Path(__file__).parent / "results"
SIZES = (2, 7, 20, 50, 100, 200)
FAMILIES = ("planar", "spatial", "tree")
GENERAL = ("random", "robots")
RANDOM_SIZES = (7, 20, 50, 200, 500)
PIN_DATA_BYTES_PER_NV3 = 62  # pin.Model.createData(), Pinocchio 4.1: see the docstring
ROBOTS = {
    # name: (file in example-robot-data, import options)
    "ur5": ("ur_description/urdf/ur5_robot.urdf", {}),
    "panda": ("panda_description/urdf/panda.urdf", {"mimic": "independent"}),
    "solo12": ("solo_description/robots/solo12.urdf", {"floating_base": True}),
}
TOLERANCE = 1e-9


def have(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def have_robots() -> bool:
    """Whether example-robot-data (the ``robots`` extra) is installed."""
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return False
    return True


class _Tree(BinaryTree):
    """Bodies 1..n of the binary-tree problem (any n, not only 2^depth - 1)."""

    def __init__(self, n: int) -> None:
        super().__init__({"depth": max(1, n.bit_length())})
        self._n = n

    @property
    def n_bodies(self) -> int:
        return self._n


def family_model(family: str, n: int) -> Model:
    if family == "tree":
        return _Tree(n).model()
    name = {"planar": "planar-chain", "spatial": "spatial-chain"}[family]
    return get_problem(name)({"n_links": n}).model()


def best_us(function, repeat: int = 5) -> float:
    """Best time per call (us) over ``repeat`` autoranged timeit runs."""
    timer = timeit.Timer(function)
    number, _ = timer.autorange()
    return min(timer.repeat(repeat=repeat, number=number)) / number * 1e6


class Peers:
    """Pinocchio and MuJoCo versions of a model (None where not installed)."""

    def __init__(self, model: Model) -> None:
        self.pin = self.mujoco = None
        if have("pinocchio"):
            import pinocchio

            pin_model, order = pinocchio_model(model)
            self.pin = (pinocchio, pin_model, pin_model.createData(), order)
        if have("mujoco"):
            import mujoco

            mj_model, order = mujoco_model(model)
            self.mujoco = (mujoco, mj_model, mujoco.MjData(mj_model), order)

    def aba(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        pin, model, data, order = self.pin
        return pin.aba(model, data, q[order], v[order], np.zeros(q.size))[np.argsort(order)]

    def forward(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        mujoco, model, data, order = self.mujoco
        data.qpos[:], data.qvel[:] = q[order], v[order]
        mujoco.mj_forward(model, data)
        return data.qacc.copy()[np.argsort(order)]


def check_equal(n: int, functions: dict, seed: int = 0) -> float:
    """Largest relative difference of the accelerations of all ``functions`` at random
    states; raises if above TOLERANCE."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(3):
        q, v = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
        values = {name: f(q, v) for name, f in functions.items()}
        reference = values["vm"]
        scale = max(1.0, float(np.abs(reference).max()))
        for name, value in values.items():
            difference = float(np.abs(value - reference).max()) / scale
            if not difference <= TOLERANCE:
                raise AssertionError(f"N={n}: {name} differs from ours by {difference:.2e}")
            worst = max(worst, difference)
    return worst


def cpu_seconds() -> float:
    """CPU time of this process and its waited-for children (the C compiler)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def cold_compile(jit: FastFunction, row: dict) -> bool:
    """Compile ``jit`` in a fresh cache directory; wall and CPU seconds into ``row``."""
    with tempfile.TemporaryDirectory() as cold:
        saved = os.environ.get("WORKBENCH_CACHE")
        os.environ["WORKBENCH_CACHE"] = cold
        try:
            start, cpu = time.perf_counter(), cpu_seconds()
            compiled = jit.compile()
            row["compile_s"] = time.perf_counter() - start
            row["compile_cpu_s"] = cpu_seconds() - cpu
        finally:
            if saved is None:
                os.environ.pop("WORKBENCH_CACHE")
            else:
                os.environ["WORKBENCH_CACHE"] = saved
    if not compiled:
        row["note"] = "; ".join(jit.compiler.warnings)
    return compiled


def measure(family: str, n: int, flags: str) -> dict:
    model = family_model(family, n)
    row: dict = {"family": family, "N": n}
    start = time.perf_counter()
    function = ode_function(model)
    row["build_s"] = time.perf_counter() - start
    vm = FastFunction(function)
    jit = FastFunction(function, Compiler("jit", flags))
    cold_compile(jit, row)
    peers = Peers(model)

    def ours(fast: FastFunction):
        return lambda q, v: fast(0.0, np.concatenate([q, v]))[0][n:]

    functions = {"vm": ours(vm), "jit": ours(jit)}
    if peers.pin:
        functions["pin"] = peers.aba
    if peers.mujoco:
        functions["mujoco"] = peers.forward
    row["max_rel_diff"] = check_equal(n, functions)

    rng = np.random.default_rng(1)
    q, v = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    y = np.concatenate([q, v])
    row["vm_us"] = best_us(lambda: vm.into(0.0, y))
    row["jit_us"] = best_us(lambda: jit.into(0.0, y))
    jit.into(0.0, y)
    row["jit_raw_us"] = best_us(jit._evaluate)
    if peers.pin:
        pin, pin_model, data, order = peers.pin
        qp, vp, tau = q[order].copy(), v[order].copy(), np.zeros(n)
        row["pin_aba_us"] = best_us(lambda: pin.aba(pin_model, data, qp, vp, tau))
    if peers.mujoco:
        mujoco, mj_model, data, order = peers.mujoco
        data.qpos[:], data.qvel[:] = q[order], v[order]
        row["mj_forward_us"] = best_us(lambda: mujoco.mj_forward(mj_model, data))
    for peer in ("pin_aba_us", "mj_forward_us"):
        if peer in row:
            short = peer.split("_")[0]
            row[f"jit/{short}"] = row["jit_us"] / row[peer]
            row[f"vm/{short}"] = row["vm_us"] / row[peer]
    row["load1"] = os.getloadavg()[0]  # the compile's wall time grows with it
    return row


def robot_model(name: str) -> tuple[Model, Any]:
    """(our model, pin.Model) of a robot of example-robot-data, from the same URDF."""
    import pinocchio as pin

    from workbench.model.importers.urdf import load_urdf

    relative, options = ROBOTS[name]
    share = metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share")
    path = Path(share) / "example-robot-data" / "robots" / relative
    imported = load_urdf(path, package_path=[share], **options)
    if options.get("floating_base"):
        return imported.model, pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    return imported.model, pin.buildModelFromUrdf(str(path))


def random_states(kinematics: TreeKinematics, count: int, seed: int):
    """(q, v): joint coordinates in (-1, 1) with unit Euler parameters, velocities in
    (-2, 2)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q = rng.uniform(-1, 1, kinematics.nq)
        for joint in kinematics.free_joints:
            if joint.type in ("free", "spherical"):
                q_slice, _ = kinematics.joint_slices[joint.name]
                p = q[q_slice.stop - 4 : q_slice.stop]
                q[q_slice.stop - 4 : q_slice.stop] = p / np.linalg.norm(p)
        yield q, rng.uniform(-2, 2, kinematics.nv)


def pin_data_too_large(nv: int) -> str | None:
    """Why ``pin.Model.createData()`` cannot be made for ``nv`` velocities here (its
    estimate, PIN_DATA_BYTES_PER_NV3 nv^3, over 80 % of the available memory), or None."""
    import psutil

    need, available = PIN_DATA_BYTES_PER_NV3 * nv**3, psutil.virtual_memory().available
    if need <= 0.8 * available:
        return None
    return (
        f"Pinocchio's createData would need about {need / 2**30:.0f} GiB "
        f"(~{PIN_DATA_BYTES_PER_NV3} nv^3 bytes at nv = {nv}), {available / 2**30:.0f} GiB "
        "available"
    )


def cpu_per_call(function, number: int) -> float:
    """CPU seconds a call over ``number`` calls."""
    start = time.process_time()
    for _ in range(number):
        function()
    return (time.process_time() - start) / number


def interleaved(ours, peer, repeats: int) -> tuple[np.ndarray, np.ndarray]:
    """CPU us a call of ``ours`` and ``peer``, timed in turn ``repeats`` times (batches of
    about 20 ms), so that a change of the machine's load hits both alike."""
    sizes = []
    for function in (ours, peer):
        number, _ = timeit.Timer(function).autorange()  # >= 0.2 s
        sizes.append(max(1, number // 10))
    times = np.array(
        [
            [cpu_per_call(f, k) for f, k in zip((ours, peer), sizes, strict=True)]
            for _ in range(repeats)
        ]
    )
    return times[:, 0] * 1e6, times[:, 1] * 1e6


def measure_general(family: str, name: str, flags: str, repeats: int) -> dict:
    """A random tree (``name`` = N) or a robot against pin.aba: see the module docstring."""
    from benchmarks.peer_models import PinocchioState

    if family == "random":
        model = random_tree(int(name), seed=int(name))
        pin_model, peer = pinocchio_model(model, general=True)
    else:
        model, pin_model = robot_model(name)
        peer = PinocchioState(TreeKinematics(model), pin_model)
    import pinocchio as pin

    kinematics = peer.kinematics
    row: dict = {"family": family, "name": name, "N": len(kinematics.order)}
    row["nv"] = kinematics.nv
    row["types"] = " ".join(sorted({j.type for j in kinematics.order}))
    row["load1"] = os.getloadavg()[0]
    reason = pin_data_too_large(pin_model.nv)
    if reason:
        row["jit/pin"] = row["jit/pin_lo"] = row["jit/pin_hi"] = float("nan")
        row["note"] = reason
        return row
    start = time.perf_counter()
    function = ode_function(model)
    row["build_s"] = time.perf_counter() - start
    row["instructions"] = function.n_instructions()
    jit = FastFunction(function, Compiler("jit", flags))
    cold_compile(jit, row)
    data = pin_model.createData()
    zero = np.zeros(kinematics.nv)
    worst = 0.0
    for q, v in random_states(kinematics, 3, seed=2):
        ours = jit(0.0, np.concatenate([q, v]))[0][kinematics.nq :]
        q_pin, v_pin = peer.state(q, v)
        theirs = peer.accelerations(pin.aba(pin_model, data, q_pin, v_pin, zero), q, v)
        difference = float(np.abs(ours - theirs).max()) / max(1.0, float(np.abs(theirs).max()))
        if not difference <= TOLERANCE:
            raise AssertionError(f"{family} {name}: pin.aba differs from ours by {difference:.2e}")
        worst = max(worst, difference)
    row["max_rel_diff"] = worst
    ((q, v),) = random_states(kinematics, 1, seed=3)
    y = np.concatenate([q, v])
    q_pin, v_pin = peer.state(q, v)
    ours_us, pin_us = interleaved(
        lambda: jit.into(0.0, y), lambda: pin.aba(pin_model, data, q_pin, v_pin, zero), repeats
    )
    ratio = ours_us / pin_us
    row["jit_cpu_us"], row["pin_aba_cpu_us"] = np.median(ours_us), np.median(pin_us)
    row["jit/pin"] = float(np.median(ratio))
    row["jit/pin_lo"], row["jit/pin_hi"] = np.quantile(ratio, [0.1, 0.9])
    row["repeats"] = repeats
    row["load1"] = os.getloadavg()[0]
    return row


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.peers", description=__doc__)
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--random-sizes", type=int, nargs="+", default=list(RANDOM_SIZES))
    parser.add_argument(
        "--families", nargs="+", choices=FAMILIES + GENERAL, default=list(FAMILIES + GENERAL)
    )
    parser.add_argument("--robots", nargs="+", choices=list(ROBOTS), default=list(ROBOTS))
    parser.add_argument("--repeats", type=int, default=15, help="interleaved repeats")
    parser.add_argument("--flags", default="-O1", help="C compiler flags (-O1: the default's)")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    missing = [name for name in ("pinocchio", "mujoco") if not have(name)]
    if missing:
        print(f"not installed: {', '.join(missing)} (pip install -e '.[bench]'); skipped")
    rows, general = [], []
    RESULTS.mkdir(exist_ok=True)
    for family in args.families:
        if family in GENERAL:
            names = [str(n) for n in args.random_sizes] if family == "random" else args.robots
            if not have("pinocchio") or (family == "robots" and not have_robots()):
                print(f"{family}: needs pinocchio (and example-robot-data for robots); skipped")
                continue
            for name in names:
                general.append(measure_general(family, name, args.flags, args.repeats))
                pd.DataFrame(general).to_csv(RESULTS / "peers_general.csv", index=False)
                print(f"{family} {name}: done", flush=True)
            continue
        for n in args.sizes:
            rows.append(measure(family, n, args.flags))
            pd.DataFrame(rows).to_csv(RESULTS / "peers.csv", index=False)
            print(f"{family} N={n}: done", flush=True)
    tables = [pd.DataFrame(found) for found in (rows, general) if found]
    for table in tables:
        hidden = ("build_s", "max_rel_diff", "types", "note")
        shown = [c for c in table.columns if c not in hidden]
        with pd.option_context("display.width", 200, "display.max_rows", 500):
            print(table[shown].to_string(index=False, float_format=lambda x: f"{x:.3g}"))
        notes = table[table["note"].notna()] if "note" in table else table.iloc[:0]
        for row in notes.to_dict("records"):
            print(f"{row['family']} {row.get('name', row['N'])}: {row['note']}")
    return pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()


if __name__ == "__main__":
    main()
