"""The direct call into our compiled libraries (workbench/equations/fastcall.py): the same
numbers, conversions, errors and call counts as CasADi's buffer call, and the buffer call
whenever the extension cannot be built."""

from __future__ import annotations

import gc
import pickle
import weakref

import casadi as ca
import numpy as np
import pytest

from workbench.equations import compiled, fastcall
from workbench.equations.evaluate import FastFunction


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path / "cache"))
    yield
    fastcall.extension.cache_clear()  # built in this test's cache


@pytest.fixture
def library():
    """A compiled function of a time and a state with a column and a matrix output."""
    t, y = ca.SX.sym("t"), ca.SX.sym("y", 4)
    column = ca.vertcat(y[2:], ca.sin(y[:2]) * t - y[2:] ** 2)
    matrix = ca.reshape(ca.vertcat(y, t * y[0], 1 / (1 + y[1] ** 2)), 2, 3)
    if compiled.c_compiler() is None:
        pytest.skip("no C compiler")
    return compiled.compile_function(ca.Function("rhs", [t, y], [column, matrix]))


def is_direct(fast: FastFunction) -> bool:
    return type(fast.into).__name__ == "Caller"


def test_a_compiled_library_is_called_directly_with_the_buffer_calls_numbers(library):
    if fastcall.extension() is None:
        pytest.skip("no Python headers: the buffer call is the only path")
    direct, buffered = FastFunction(library), FastFunction(library)
    buffered.into = buffered._specialized_into()  # CasADi's buffer call, as before
    assert is_direct(direct) and not is_direct(buffered)
    y = np.array([0.3, -1.2, 0.5, 2.0])
    for t in (0.0, 0.7, -3.5):
        ours, theirs = direct.into(t, y), buffered.into(t, y)
        assert ours is direct.outputs and ours[1].shape == (2, 3)
        for a, b in zip(ours, theirs, strict=True):
            np.testing.assert_array_equal(a, b)
    assert direct.n_calls == buffered.n_calls == 3


@pytest.mark.parametrize(
    "t, y",
    [
        (1, [0.3, -1.2, 0.5, 2.0]),  # an int, a list
        (np.float64(0.5), np.array([[0.3], [-1.2], [0.5], [2.0]])),  # a column
        (np.array(0.5), np.array([0.3, -1.2, 0.5, 2.0], dtype=np.float32)),  # 0-d, float32
        (0.5, np.arange(8.0)[::2]),  # not contiguous
        (np.array([0.5]), ca.DM([0.3, -1.2, 0.5, 2.0])),  # a 1-element array, a CasADi DM
    ],
)
def test_what_the_direct_call_does_not_take_goes_the_python_way(library, t, y):
    fast, vm = FastFunction(library), FastFunction(library)
    vm.into = vm._specialized_into()
    for a, b in zip(fast(t, y), vm(t, y), strict=True):
        np.testing.assert_array_equal(a, b)
    assert fast.n_calls == vm.n_calls == 1


def test_wrong_arguments_raise_as_on_the_python_path(library):
    fast = FastFunction(library)
    with pytest.raises(ValueError):
        fast.into(0.0, np.zeros(5))
    with pytest.raises(TypeError, match="expected 2 arguments"):
        fast.into(0.0)
    with pytest.raises(TypeError, match="expected 2 arguments"):
        fast.into(0.0, np.zeros(4), np.zeros(4))
    assert fast.n_calls == 0


def test_without_python_headers_the_buffer_call_is_kept(library, monkeypatch, tmp_path):
    monkeypatch.setattr(fastcall.sysconfig, "get_paths", lambda: {"include": str(tmp_path)})
    fastcall.extension.cache_clear()
    assert fastcall.extension() is None
    fast = FastFunction(library)
    assert not is_direct(fast)
    expected = np.concatenate([np.ones(2), np.sin(np.ones(2)) * 0.5 - 1.0])
    np.testing.assert_allclose(fast.into(0.5, np.ones(4))[0], expected, rtol=1e-15)


def test_switched_off_by_the_environment(library, monkeypatch):
    monkeypatch.setenv("WORKBENCH_FASTCALL", "0")
    assert not is_direct(FastFunction(library))


def test_compiled_on_first_call_then_direct_counting_every_call(library):
    t, y = ca.SX.sym("t"), ca.SX.sym("y", 2)
    function = ca.Function("f", [t, y], [ca.vertcat(y[1], -ca.sin(y[0]) * t)])
    fast = FastFunction(function, compiled.Compiler("jit"))
    for _ in range(3):
        fast.into(0.5, np.array([0.1, 0.2]))
    assert fast.n_calls == 3
    assert is_direct(fast) == (fastcall.extension() is not None)
    again = pickle.loads(pickle.dumps(fast))
    np.testing.assert_array_equal(again(0.5, np.array([0.1, 0.2]))[0], fast.outputs[0])
    np.testing.assert_allclose(fast.outputs[0], [0.2, -np.sin(0.1) * 0.5], rtol=1e-15)


def test_a_dropped_function_is_collected(library):
    """The caller's fallback is a method of the FastFunction holding it: the cycle is
    collected (the caller is known to the garbage collector)."""
    fast = FastFunction(library)
    fast.into(0.5, np.ones(4))
    gone = weakref.ref(fast)
    del fast
    gc.collect()
    assert gone() is None
