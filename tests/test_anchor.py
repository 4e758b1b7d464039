"""The all-compiled anchor of benchmarks/simulation.py (Pinocchio's C++ ABA under CasADi's
CVODES): it says why when it cannot be built, and once built it gives Pinocchio's Python
accelerations and ends the UR5's simulation where CVODE + ``pin.aba`` does."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import anchor


def test_missing_compiler_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CXX", "no-such-compiler")
    monkeypatch.setenv("PATH", "")
    with pytest.raises(anchor.AnchorUnavailable, match="no C.. compiler"):
        anchor.build()


def test_anchor_agrees_with_pinocchio_on_the_ur5() -> None:
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    pytest.importorskip("workbench.problems.robots", reason="example-robot-data missing")
    try:
        cached = anchor.library_path().exists()
    except anchor.AnchorUnavailable as error:
        pytest.skip(str(error))
    if not cached:  # about a minute of compile: built by python -m benchmarks.simulation
        pytest.skip("the anchor is not built yet (python -m benchmarks.simulation builds it)")
    from benchmarks.simulation_models import case

    bench = case("ur5")
    model, order = bench.pin
    times = np.linspace(0.0, bench.t_end, 11)
    tree = anchor.Anchor(model, order, bench.y0, times)
    data, rng = model.createData(), np.random.default_rng(3)
    for _ in range(3):
        q, v = rng.uniform(-2, 2, model.nv), rng.uniform(-2, 2, model.nv)
        expected = pin.aba(model, data, q, v, np.zeros(model.nv))  # same order (UR5)
        assert np.abs(tree.accelerations(q, v) - expected).max() <= 1e-9 * max(
            1.0, np.abs(expected).max()
        )
    from sksundae.cvode import CVODE

    n = model.nv

    def rhs(t, y, yp):
        yp[:n], yp[n:] = y[n:], pin.aba(model, data, y[:n], y[n:], np.zeros(n))

    peer = CVODE(rhs, method="Adams", rtol=1e-11, atol=1e-13).solve(times, bench.y0)
    end, _, (steps, calls) = tree.run(1e-11)
    assert np.abs(end - np.asarray(peer.y)[-1]).max() < 1e-7
    # the counts are CVODES' own: Adams with fixed-point iteration calls the rhs at least
    # once a step, and the same integrator run again takes the same steps
    assert 0 < steps <= calls
    assert tree.run(1e-11)[2] == (steps, calls)
    # the same right-hand side under SUNDIALS CVODE driven from C (sundials-cvode-c's driver)
    end_c, _, (steps_c, calls_c) = tree.run_c(1e-11)
    assert np.abs(end_c - np.asarray(peer.y)[-1]).max() < 1e-7
    assert 0 < steps_c <= calls_c


def test_pinocchio_aba_call_agrees_with_pin_aba_on_a_general_tree(tmp_path) -> None:
    """The per-call benchmark's like-for-like line (benchmarks/aba_call.cpp): pinocchio::aba
    through CasADi's buffer call gives pin.aba's accelerations on a tree with a free base and
    spherical joints (nq != nv)."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    pytest.importorskip("pyperf", reason="pyperf times the benchmark; not in the test extra")
    from benchmarks import peers_pyperf
    from benchmarks.peer_models import pinocchio_model, random_tree

    try:
        cached = anchor.library_path(peers_pyperf.ABA_CALL, peers_pyperf.ABA_CALL_FLAGS).exists()
    except anchor.AnchorUnavailable as error:
        pytest.skip(str(error))
    if not cached:  # about a minute of compile: built by python -m benchmarks.peers_pyperf
        pytest.skip("pinocchio::aba's call is not built yet (python -m benchmarks.peers_pyperf)")
    pin_model, _ = pinocchio_model(random_tree(7, seed=7), general=True)
    assert pin_model.nq != pin_model.nv
    text = tmp_path / "model.txt"
    pin_model.saveToText(str(text))
    evaluate, bound = peers_pyperf.buffered(peers_pyperf.pinocchio_call(text))
    y, out = bound[1], bound[2]  # (bound kept: the buffer points into its arrays)
    data, rng = pin_model.createData(), np.random.default_rng(4)
    for _ in range(3):
        q = pin.randomConfiguration(pin_model, -np.ones(pin_model.nq), np.ones(pin_model.nq))
        v = rng.uniform(-2, 2, pin_model.nv)
        y[:] = np.concatenate([q, v])
        evaluate()
        expected = pin.aba(pin_model, data, q, v, np.zeros(pin_model.nv))
        assert np.abs(out[pin_model.nv :] - expected).max() <= 1e-9 * max(
            1.0, np.abs(expected).max()
        )
        assert np.array_equal(out[: pin_model.nv], v)


CHILD = """
import sys
from pathlib import Path
from benchmarks import peers_pyperf
prepared, copies = {"kind": "random", "name": "3", "library": sys.argv[1],
                    "symbol": sys.argv[2]}, Path(sys.argv[3])
for who in reversed(peers_pyperf.PYTHON):  # pin.aba first: before anything imports pinocchio
    peers_pyperf.timed_call(prepared, who, copies)()
print("\\n".join(line.split(maxsplit=5)[-1].strip() for line in open("/proc/self/maps")))
"""


def test_each_timing_process_runs_its_own_copies_of_the_libraries(tmp_path) -> None:
    """A library runs slower on some physical pages, and processes that load the same
    file share its pages: one draw for all of pyperf's processes. Each worker loads copies
    of ours (the library, the fastcall extension) and of pin.aba's compiled files."""
    pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    pytest.importorskip("pyperf", reason="pyperf times the benchmark; not in the test extra")
    import subprocess
    import sys

    from benchmarks.peer_models import random_tree
    from workbench.equations import compiled, fastcall
    from workbench.plugins.formalisms.recursive import ode_function

    try:
        with compiled.counted():
            generated = compiled.generate(ode_function(random_tree(3, seed=3), kernels=None))
            compiled.load_generated(generated)
    except RuntimeError as error:  # no C compiler
        pytest.skip(str(error))
    copies = tmp_path / "copies"
    copies.mkdir()
    arguments = [str(generated.path), generated.function.name(), str(copies)]
    done = subprocess.run([sys.executable, "-c", CHILD, *arguments],
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    mapped = set(done.stdout.splitlines())
    assert str(generated.path) not in mapped
    for name in (generated.path.name, "libpinocchio_default.so", "libeigenpy.so"):
        assert any(p.startswith(str(copies)) and p.endswith(name) for p in mapped), name
    assert any(p.startswith(str(copies)) and "pinocchio_pywrap" in p for p in mapped)
    if fastcall.enabled() and fastcall.extension() is not None:
        assert any(p.startswith(str(copies)) and fastcall.MODULE in p for p in mapped)
