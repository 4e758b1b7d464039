"""``sundials-cvode-c``: SUNDIALS CVODE run from C on the compiled right-hand side.

Oracles: the pendulum's exact angle (Jacobi elliptic functions), the stored reference of
a spatial chain (through a whole run), conservation of energy, CasADi's CVODES at the same
settings, and a right-hand side written in Python that counts its own calls. Skipped only
without a C compiler (the driver and the right-hand side are compiled); the refusal is
tested everywhere.
"""

from __future__ import annotations

import ctypes
import re

import numpy as np
import pytest

from tests.test_integrators import THETA0, Oscillator, Pendulum, pendulum_angle
from workbench.equations import compiled
from workbench.equations.initial import consistent_initial_state
from workbench.errors import PluginError
from workbench.execution.execute import RunSpec, execute_run
from workbench.plugin.registry import get_formalism, get_integrator
from workbench.plugins.integrators import cvode_c

NAME = "sundials-cvode-c"
needs_compiler = pytest.mark.skipif(
    compiled.c_compiler() is None, reason="no C compiler: the driver and the rhs are compiled C"
)
ADAMS = {"method": "adams", "iteration": "functional"}
BDF = {"method": "bdf", "iteration": "newton"}


def compiled_build(problem, formalism: str = "minimal-ode"):
    equations = get_formalism(formalism)().build(problem.model(), {"compile": "jit"})
    return equations, consistent_initial_state(equations, problem)


def solve(equations, state, times, rtol, options, name=NAME):
    y0 = state.y0(equations, "ode")
    plugin = get_integrator(name)()
    return plugin.solve(equations, y0, None, times, rtol, rtol, options, "ode")


@needs_compiler
@pytest.mark.parametrize(("options", "allowance"), [(ADAMS, 50), (BDF, 500)])
def test_pendulum_follows_the_exact_angle_and_casadi_cvodes(options, allowance):
    """Within ``allowance`` rtol of the exact angle everywhere (BDF's phase error grows
    with its steps, as tests/test_integrators.py allows it), and so within twice that of
    CasADi's CVODES at the same settings (the same method of another SUNDIALS build)."""
    equations, state = compiled_build(Pendulum())
    times = np.linspace(0.0, 4.0, 41)
    rtol = 1e-7
    ours = solve(equations, state, times, rtol, options)
    assert ours.success, ours.message
    assert np.array_equal(ours.times, times)
    assert np.abs(ours.y[:, 0] - pendulum_angle(times)).max() <= allowance * rtol * THETA0
    casadi = solve(equations, state, times, rtol, options, "casadi-cvodes")
    assert casadi.success, casadi.message
    assert np.abs(ours.y[:, 0] - casadi.y[:, 0]).max() <= 2 * allowance * rtol * THETA0
    assert ours.stats.n_steps > 0 and ours.stats.n_rhs >= ours.stats.n_steps
    if options is ADAMS:
        assert ours.stats.n_jac == 0 and ours.stats.n_lu == -1
    else:
        assert ours.stats.n_jac > 0 and ours.stats.n_lu >= ours.stats.n_jac


@needs_compiler
def test_a_chain_run_matches_the_stored_reference_and_casadi_cvodes(tmp_path, monkeypatch):
    """In a fresh compile cache: the driver and the right-hand side are compiled in the
    run's compile stage, and the run ends within 1e-6 of the stored reference."""
    from workbench.execution.execute import clear_cache

    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path / "cache"))
    clear_cache()
    cvode_c.driver.cache_clear()
    cvode_c.loaded_rhs.cache_clear()
    before = compiled.STATS.compiled
    rows = {}
    for name in (NAME, "casadi-cvodes"):
        spec = RunSpec(
            "spatial-chain", "recursive", name, 1e-9, 1e-11, {"n_links": 3},
            {"compile": "jit"}, ADAMS,
        )  # fmt: skip
        rows[name] = execute_run(spec, reference_dir=tmp_path).row
    ours, casadi = rows[NAME], rows["casadi-cvodes"]
    assert ours["status"] == casadi["status"] == "ok", ours["message"]
    assert ours["compile_s"] > 0.0 and ours["n_rhs"] > 0
    assert compiled.STATS.compiled >= before + 2  # the rhs and the driver, in the new cache
    assert list((tmp_path / "cache").glob("wb_cvode_driver-*.so"))
    assert ours["err_end"] < 1e-6
    # the same method at the same tolerance: end errors of the same size
    assert ours["err_end"] < 10 * casadi["err_end"] + 1e-9


@needs_compiler
def test_energy_is_conserved_at_a_tight_tolerance():
    """A 3-link spatial chain without friction: T + V constant to rtol's order."""
    from workbench.plugin.registry import get_problem

    problem = get_problem("spatial-chain")({"n_links": 3})
    equations, state = compiled_build(problem, "recursive")
    times = np.linspace(0.0, 2.0, 21)
    rtol = 1e-10
    trajectory = solve(equations, state, times, rtol, ADAMS)
    assert trajectory.success, trajectory.message
    nq = equations.nq
    energy = np.array([
        sum(equations.observables.energy(t, y[:nq], y[nq:])[0])
        for t, y in zip(trajectory.times, trajectory.y, strict=True)
    ])  # fmt: skip
    scale = max(np.abs(energy).max(), 1.0)
    assert np.abs(energy - energy[0]).max() / scale < 1e3 * rtol


CASADI_SIGNATURE = ctypes.CFUNCTYPE(
    ctypes.c_int,
    ctypes.POINTER(ctypes.POINTER(ctypes.c_double)),
    ctypes.POINTER(ctypes.POINTER(ctypes.c_double)),
    ctypes.c_void_p,
    ctypes.c_void_p,
    ctypes.c_int,
)


@needs_compiler
@pytest.mark.parametrize(("options", "allowance"), [(ADAMS, 50), (BDF, 500)])
def test_right_hand_side_calls_equal_a_counter_in_the_function(options, allowance):
    """The driver called on a pendulum right-hand side written in Python (CasADi's C
    calling convention through ctypes), which counts its calls: CVODE's counts (and its
    difference-quotient Jacobian's) add up to the counter, and the angle is exact."""
    calls = [0]
    omega2 = 9.81 / 1.0  # g / l

    def pendulum(arg, res, iw, w, mem):
        calls[0] += 1
        y, out = arg[1], res[0]
        out[0], out[1] = y[1], -omega2 * np.sin(y[0])
        return 0

    function = CASADI_SIGNATURE(pendulum)
    times = np.linspace(0.0, 4.0, 41)
    y = np.empty((times.size, 2))
    result = cvode_c.Result()
    newton = int(options["iteration"] == "newton")
    reached = cvode_c.driver().wb_cvode_solve(
        ctypes.cast(function, ctypes.c_void_p).value, 2, 2, 1, 0, 0, times, times.size,
        np.array([THETA0, 0.0]), y, cvode_c.METHODS[options["method"]], newton, 1e-7, 1e-7,
        10_000, 0.0, 0, ctypes.byref(result),
    )  # fmt: skip
    assert reached == times.size and result.flag == 0
    assert result.rhs_calls == calls[0] > 0
    assert result.rhs_evals + result.lin_rhs_evals == calls[0]
    assert result.lin_rhs_evals == (2 * result.jac_evals if newton else 0)
    assert np.abs(y[:, 0] - pendulum_angle(times)).max() <= allowance * 1e-7 * THETA0


@needs_compiler
def test_too_few_steps_give_a_failed_row_naming_cvodes_flag():
    equations, state = compiled_build(Pendulum())
    times = np.linspace(0.0, 4.0, 41)
    trajectory = solve(equations, state, times, 1e-8, {**ADAMS, "max_num_steps": 5})
    assert not trajectory.success
    assert "CV_TOO_MUCH_WORK" in trajectory.message and "mxstep" in trajectory.message
    assert trajectory.times.size == trajectory.y.shape[0] >= 1
    assert trajectory.stats.n_steps >= 5


@needs_compiler
@pytest.mark.parametrize("options", [ADAMS, BDF])
def test_a_failure_reports_cvodes_steps_calls_and_time_up_to_it(options):
    """The pendulum to 0.1, 0.2, 0.3, then 4 s at 60 steps an output at most: the last
    interval exhausts them. CVODE's statistics after its failure are those of the run to
    0.3 s (the same steps, states equal to the bit) plus the 60 steps of the failed call,
    and the message gives the time CVODE reached, inside the failed interval. CasADi's
    CVODES loses a failed call's statistics: its row says -1 (not known), not the steps
    before the failed interval (nor 0 when that is the first), and names the interval."""
    equations, state = compiled_build(Pendulum())
    times, steps = np.array([0.0, 0.1, 0.2, 0.3, 4.0]), 60
    options = {**options, "max_num_steps": steps}
    failed = solve(equations, state, times, 1e-10, options)
    reached = solve(equations, state, times[:4], 1e-10, options)
    assert not failed.success and reached.success, reached.message
    assert "CV_TOO_MUCH_WORK" in failed.message
    assert np.array_equal(failed.times, times[:4]) and np.array_equal(failed.y, reached.y)
    assert failed.stats.n_steps == reached.stats.n_steps + steps
    assert failed.stats.n_rhs > reached.stats.n_rhs + steps  # one or more a step
    t_cvode = float(re.search(r"at t = (\S+):", failed.message).group(1))
    assert 0.3 < t_cvode < 4.0
    casadi = solve(equations, state, times, 1e-10, options, "casadi-cvodes")
    assert not casadi.success and "between t = 0.3 and 4:" in casadi.message, casadi.message
    stats = casadi.stats
    assert stats.n_steps == stats.n_rhs == stats.n_rejected == stats.n_jac == -1
    first = solve(equations, state, times, 1e-10, {**options, "max_num_steps": 2},
                  "casadi-cvodes")  # fmt: skip
    assert "between t = 0 and 0.1:" in first.message, first.message
    assert first.stats.n_steps == first.stats.n_rhs == -1


@needs_compiler
def test_without_cvode_memory_the_statistics_are_not_known():
    """CVodeCreate refuses the method (as it would fail to allocate): the driver reports
    a failure with -1 (not read) for CVODE's counts, 0 right-hand-side calls (its own
    count) and the initial state."""
    times, y = np.linspace(0.0, 1.0, 3), np.full((3, 2), np.nan)
    result = cvode_c.Result()
    rhs = CASADI_SIGNATURE(lambda arg, res, iw, w, mem: 0)
    reached = cvode_c.driver().wb_cvode_solve(
        ctypes.cast(rhs, ctypes.c_void_p).value, 2, 2, 1, 0, 0, times, times.size,
        np.array([THETA0, 0.0]), y, 3, 0, 1e-7, 1e-7, 100, 0.0, 0, ctypes.byref(result),
    )  # fmt: skip
    assert reached == 1 and result.flag < 0
    assert result.steps == result.rhs_evals == result.err_test_fails == -1
    assert result.nonlin_iters == -1 and result.rhs_calls == 0
    assert result.lin_setups == result.jac_evals == 0  # no linear solver: none of its work
    assert np.array_equal(y[0], [THETA0, 0.0])


@needs_compiler
def test_a_nan_right_hand_side_fails_where_it_becomes_nan():
    equations, state = compiled_build(Oscillator(failing=True))
    times = np.linspace(0.0, 1.0, 11)
    trajectory = solve(equations, state, times, 1e-6, ADAMS)
    assert not trajectory.success and trajectory.message.startswith(NAME)
    assert "flag -" in trajectory.message and "NaN or infinite at t = 0.5" in trajectory.message
    assert trajectory.stats.n_steps < 100  # stopped at the NaN, not by shrinking the step
    assert trajectory.t_reached <= 0.6 + 1e-12
    assert np.all(np.isfinite(trajectory.y))
    assert np.allclose(trajectory.y[:, 0], 0.3 * np.cos(2.0 * trajectory.times), atol=1e-4)


@needs_compiler
def test_a_wrong_signature_is_refused_before_the_driver_runs():
    import casadi as ca

    t, y = ca.SX.sym("t"), ca.SX.sym("y", 3)
    with pytest.raises(RuntimeError, match="expected dense"):
        cvode_c.check_signature(ca.Function("f", [t, y], [y[:2]]), 3)


def test_equations_in_the_virtual_machine_are_refused():
    equations = get_formalism("minimal-ode")().build(Pendulum().model(), {"compile": "none"})
    state = consistent_initial_state(equations, Pendulum())
    plugin = get_integrator(NAME)()
    reason = plugin.incompatibility(equations, plugin.parse_options(None))
    assert reason is not None and ("compile" in reason or "C compiler" in reason)
    with pytest.raises(PluginError, match=NAME):
        solve(equations, state, np.linspace(0.0, 1.0, 3), 1e-6, None)


@needs_compiler
def test_with_compile_auto_the_row_says_the_right_hand_side_ran_in_c(tmp_path):
    """compile=auto leaves a short run's functions in the VM, but this integrator runs the
    right-hand side's C itself: the row's notes must not count it among the VM's."""
    spec = RunSpec("double-pendulum", "recursive", NAME, 1e-6, 1e-8, {}, {"compile": "auto"})
    row = execute_run(spec, reference_dir=tmp_path).row
    assert row["status"] == "ok", row["message"]
    assert "in C ode_rhs" in row["notes"], row["notes"]


def test_a_run_without_compiled_equations_is_a_skipped_row(tmp_path):
    spec = RunSpec("double-pendulum", "recursive", NAME, 1e-6, 1e-8, {}, {"compile": "none"})
    row = execute_run(spec, reference_dir=tmp_path).row
    assert row["status"] == "skipped"
    assert "compile" in row["message"] or "C compiler" in row["message"]


def test_without_a_compiler_the_refusal_says_so(monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.warns(compiled.CompileWarning, match="no C compiler"):
        equations = get_formalism("minimal-ode")().build(Pendulum().model(), {"compile": "jit"})
    plugin = get_integrator(NAME)()
    assert "no C compiler" in plugin.incompatibility(equations, plugin.parse_options(None))


# one run of a fresh process: what the compile cache did, and the run's end state's bits
FRESH_RUN = """
import json, sys
from workbench.equations import compiled
real = compiled.generate_c
generated = []
def counting(function, *args, **kwargs):
    generated.append(function.name())
    return real(function, *args, **kwargs)
compiled.generate_c = counting
from workbench.execution.execute import RunSpec, execute_run
spec = RunSpec("double-pendulum", "recursive", "sundials-cvode-c", 1e-8, 1e-10, {},
               {"compile": "jit"}, {"method": "adams", "iteration": "functional"})
result = execute_run(spec, reference_dir=sys.argv[1])
states = result.series.filter(like="state:").to_numpy()
print(json.dumps({"status": result.row["status"], "message": result.row["message"],
                  "compiled": compiled.STATS.compiled, "generated": generated,
                  "states": states.tobytes().hex(), "shape": list(states.shape)}))
"""


@needs_compiler
def test_the_driver_calls_the_formalisms_library_and_a_second_process_compiles_nothing(tmp_path):
    """The driver runs the library the formalism's compile loaded: the right-hand side's
    C is generated once a process (it was generated a second time to find the driver's
    copy). A second process finds the driver and every library in the compile cache: no
    compiler runs, and the trajectory is the same to the bit."""
    import json
    import os
    import subprocess
    import sys

    env = {**os.environ, "WORKBENCH_CACHE": str(tmp_path / "cache")}
    runs = []
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-c", FRESH_RUN, str(tmp_path)], capture_output=True, text=True,
            env=env,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-2000:]
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    first, second = runs
    for run in runs:
        assert run["status"] == "ok", run["message"]
        assert run["generated"].count(compiled.SYMBOL_PREFIX + "ode_rhs") == 1, run["generated"]
        assert run["shape"][0] > 2
    assert first["compiled"] >= 2  # the right-hand side and the driver, into the new cache
    assert second["compiled"] == 0, second
    assert second["states"] == first["states"]
