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

Prints a table with the ratios ours/peer and writes ``benchmarks/results/peers.csv``.
Without ``pin`` or ``mujoco`` (the ``bench`` extra) their columns are left empty and the
table says so.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import tempfile
import time
import timeit
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.peer_models import mujoco_model, pinocchio_model
from workbench.equations.compiled import Compiler
from workbench.equations.evaluate import FastFunction
from workbench.model import Model
from workbench.plugin.registry import get_problem
from workbench.plugins.formalisms.recursive import ode_function
from workbench.problems.scalable import BinaryTree

RESULTS = Path(__file__).parent / "results"
SIZES = (2, 7, 20, 50, 100, 200)
FAMILIES = ("planar", "spatial", "tree")
TOLERANCE = 1e-9


def have(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


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


def measure(family: str, n: int, flags: str) -> dict:
    model = family_model(family, n)
    row: dict = {"family": family, "N": n}
    start = time.perf_counter()
    function = ode_function(model)
    row["build_s"] = time.perf_counter() - start
    vm = FastFunction(function)
    jit = FastFunction(function, Compiler("jit", flags))
    with tempfile.TemporaryDirectory() as cold:
        saved = os.environ.get("WORKBENCH_CACHE")
        os.environ["WORKBENCH_CACHE"] = cold
        try:
            start = time.perf_counter()
            compiled = jit.compile()
            row["compile_s"] = time.perf_counter() - start
        finally:
            if saved is None:
                os.environ.pop("WORKBENCH_CACHE")
            else:
                os.environ["WORKBENCH_CACHE"] = saved
    if not compiled:
        row["note"] = "; ".join(jit.compiler.warnings)
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
    return row


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.peers", description=__doc__)
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    parser.add_argument("--flags", default="-O1", help="C compiler flags (default -O1)")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    missing = [name for name in ("pinocchio", "mujoco") if not have(name)]
    if missing:
        print(f"not installed: {', '.join(missing)} (pip install -e '.[bench]'); skipped")
    rows = []
    for family in args.families:
        for n in args.sizes:
            rows.append(measure(family, n, args.flags))
            print(f"{family} N={n}: done", flush=True)
    table = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "peers.csv", index=False)
    shown = [c for c in table.columns if c not in ("build_s", "max_rel_diff")]
    with pd.option_context("display.width", 160, "display.max_rows", 500):
        print(table[shown].to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return table


if __name__ == "__main__":
    main()
