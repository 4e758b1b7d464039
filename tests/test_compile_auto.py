"""compile="auto": C where a run's evaluations repay the compile, the VM otherwise, decided
for each run alone (not by earlier runs, not by the cache); the default of sweeps and of
`workbench run`; its numbers are the VM's; a failure stays in the VM with a note; the
compile stage's CPU is this process's, not the compiler's wall time."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.equations import compile_policy, compiled
from workbench.execution.execute import RunSpec, _Stages, clear_cache, execute_run
from workbench.plugin.registry import get_formalism, get_problem


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    """A fresh compile cache and equations cache for every test."""
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path / "cache"))
    clear_cache()
    yield tmp_path / "cache"
    clear_cache()


def chain(compile_mode: str):
    problem = get_problem("spatial-chain")({"n_links": 3})
    return get_formalism("recursive")().build(problem.model(), {"compile": compile_mode})


ARGS = (0.3, np.linspace(-0.8, 0.9, 6))


def test_a_run_expecting_many_evaluations_compiles_at_the_first_call():
    expected = chain("none").forms["ode"].rhs(*ARGS)[0]
    equations = chain("auto")
    equations.compiler.expect(1e12)
    rhs = equations.forms["ode"].rhs
    value = rhs(*ARGS)[0]
    assert rhs.compile() and equations.compiler.in_c == {"ode_rhs": "C"}
    np.testing.assert_allclose(value, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    assert "in C ode_rhs" in equations.compiler.summary()


def test_each_run_decides_alone_whatever_earlier_runs_chose(monkeypatch):
    """A worker keeps built equations across runs: a run's choice must not depend on them
    (it did: a short run after a long one ran in C, after a short one in the VM, and the
    VM calls of earlier runs counted towards a compile). Never switched within a run: a
    switch there changed the run's steps (iftomm-a05 absolute-dae CVODE BDF at 1e-4, n_rhs
    1745 then 1748 in its repeats)."""
    monkeypatch.setattr(compile_policy, "calls_to_repay", lambda vm_seconds, code_bytes: 50.0)
    expected = chain("none").forms["ode"].rhs(*ARGS)[0]
    equations = chain("auto")
    equations.compiler.expect(10)  # fewer than the 50 calls that repay
    rhs = equations.forms["ode"].rhs
    kept = rhs.into  # an integrator holds this for its run
    for _ in range(60):
        kept(*ARGS)
    assert not rhs.compile()  # 60 calls made, yet the run stays in the VM
    assert "1 function in the VM" in equations.compiler.summary()
    equations.compiler.expect(10)  # the next short run: still the VM
    assert not rhs.compile() and equations.compiler.waiting == [rhs]
    equations.compiler.expect(100)  # a long run: C
    assert rhs.compile() and equations.compiler.in_c == {"ode_rhs": "C"}
    value = rhs.into(*ARGS)[0]
    np.testing.assert_allclose(value, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    equations.compiler.expect(10)  # a short run after it: the VM again, as in a fresh worker
    assert not rhs.compile() and equations.compiler.in_c == {}
    assert "in C" not in equations.compiler.summary()


def test_the_vm_cost_of_a_call_is_estimated_from_the_graph_not_timed():
    rhs = chain("auto").forms["ode"].rhs
    first = compile_policy.vm_seconds_estimate(rhs.function)
    assert first == compile_policy.vm_seconds_estimate(rhs.function) > 0
    assert compile_policy.instruction_count(rhs.function) == rhs.function.n_instructions()


def test_a_later_run_expecting_more_compiles_what_repays(monkeypatch):
    monkeypatch.setattr(compile_policy, "calls_to_repay", lambda vm_seconds, code_bytes: 1e4)
    equations = chain("auto")
    equations.compiler.expect(100)
    rhs = equations.forms["ode"].rhs
    rhs(*ARGS)
    assert not rhs.compile()
    equations.compiler.expect(1e5)  # the next run of the same equations in this worker
    assert rhs.compile() and equations.compiler.waiting == []


def test_a_cached_library_does_not_move_a_short_run_to_c(monkeypatch):
    """The cache makes C cheaper to get, never changes where a function runs (it did: a
    run too short to repay a compile loaded a cached library, so rows depended on what
    earlier sweeps had left in the cache)."""
    first = chain("jit")
    first.forms["ode"].rhs(*ARGS)
    clear_cache()
    monkeypatch.setattr(compile_policy, "calls_to_repay", lambda vm_seconds, code_bytes: 1e15)
    equations = chain("auto")
    equations.compiler.expect(1e9)
    rhs = equations.forms["ode"].rhs
    rhs(*ARGS)
    assert not rhs.compile() and equations.compiler.in_c == {}


def test_a_compile_failure_stays_in_the_vm_with_a_note(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", "false")  # a compiler that always fails
    equations = chain("auto")
    equations.compiler.expect(1e12)
    rhs = equations.forms["ode"].rhs
    with pytest.warns(compiled.CompileWarning, match="compile=auto: ode_rhs stays in the CasADi"):
        value = rhs(*ARGS)[0]
    assert not rhs.compile() and np.all(np.isfinite(value))

    spec = RunSpec(
        "spatial-chain", "recursive", "scipy-dop853", 1e-6, 1e-9, {"n_links": 3},
        {"compile": "auto"},
    )  # fmt: skip
    clear_cache()
    monkeypatch.setattr(compile_policy, "expected_evaluations", lambda span, rtol: 1e12)
    with pytest.warns(compiled.CompileWarning):
        row = execute_run(spec, reference_dir=tmp_path).row
    assert row["status"] == "ok" and "stays in the CasADi VM" in row["message"]


def test_auto_rows_agree_with_vm_rows_and_say_what_ran_in_c(tmp_path, monkeypatch):
    rows = {}
    for mode in ("none", "auto"):
        spec = RunSpec(
            "spatial-chain", "recursive", "scipy-dop853", 1e-8, 1e-11, {"n_links": 3},
            {"compile": mode},
        )  # fmt: skip
        rows[mode] = execute_run(spec, reference_dir=tmp_path).row
    plain, auto = rows["none"], rows["auto"]
    assert plain["status"] == auto["status"] == "ok"
    assert "compile=auto" in auto["notes"] and "compile=auto" not in plain["notes"]
    # whatever auto chose, the numbers are the VM's to far below the run's tolerance
    assert auto["err_end"] == pytest.approx(plain["err_end"], rel=1e-4, abs=1e-12)


def test_a_long_run_compiles_and_a_trivially_short_one_does_not(tmp_path, monkeypatch):
    """Through the runner: the expected evaluations come from the problem's span and rtol."""
    spec = RunSpec(
        "spatial-chain", "recursive", "scipy-dop853", 1e-6, 1e-9, {"n_links": 3},
        {"compile": "auto"},
    )  # fmt: skip
    short = execute_run(spec, reference_dir=tmp_path).row
    assert short["status"] == "ok" and "in C" not in short["notes"], short["notes"]
    assert "in the VM" in short["notes"]
    clear_cache()
    assert compile_policy.expected_evaluations(2.0, 1e-6) < 1e4
    monkeypatch.setattr(compile_policy, "EVALUATIONS_PER_SECOND", 1e9)  # a very long run
    long = execute_run(spec, reference_dir=tmp_path).row
    assert long["status"] == "ok" and "ode_rhs" in long["notes"].split("in C ")[1]
    assert long["compile_s"] > 0 and long["n_rhs"] == short["n_rhs"]


def test_expected_evaluations_grow_with_span_and_tolerance():
    e = compile_policy.expected_evaluations
    assert e(2.0, 1e-7) > e(2.0, 1e-4) > e(1.0, 1e-4) > 0 == e(0.0, 1e-4)
    assert compile_policy.calls_to_repay(0.0, 1000) == float("inf")
    # a compile repays only calls that take longer in the VM than it costs
    repay = compile_policy.calls_to_repay(1e-4, 100_000)
    assert repay * 1e-4 > compile_policy.compile_cpu_estimate(100_000)


@pytest.mark.parametrize("kernels", [False, True])
def test_the_size_of_the_c_is_estimated_within_2x_kernels_included(kernels):
    """compile=auto prices a compile by the estimated size of its C. A joint-type kernel is
    written once but called at every link: counted at each call, a 20-link chain's C was
    estimated 7.9x its size (a 200-body tree's 7.3x, 17.6 s of compile for 4.4)."""
    from workbench.plugins.formalisms.recursive import ode_function

    model = get_problem("spatial-chain")({"n_links": 20}).model()
    function = ode_function(model, kernels=kernels)
    assert function.is_a("MXFunction") == kernels
    actual = len(compiled.generate_c(compiled.exported(function)))
    assert 0.5 <= compile_policy.code_bytes_estimate(function) / actual <= 2.0


def test_the_compile_stage_takes_this_process_cpu_not_the_compilers_wall_time(monkeypatch):
    """The C compiler runs in a child process: its wall seconds are not this process's CPU
    (before, they were subtracted from the stage's CPU, hiding integration cost)."""
    stages = _Stages()
    stages.start("integrate")
    compiled.STATS.seconds += 5.0  # a compile that waited 5 s for the compiler
    stages.stop()
    assert stages.wall["compile"] == 5.0 and stages.cpu["compile"] == 0.0
    assert stages.cpu["integrate"] >= 0.0 and stages.wall["integrate"] < 0.0


def test_a_sweep_and_a_single_run_compile_automatically_unless_told_otherwise():
    from workbench.runs.sweep_spec import parse_spec

    assert get_formalism("recursive").parse_options({}).compile == "auto"  # workbench run

    text = (
        'problems = ["double-pendulum"]\nintegrators = ["scipy-dop853"]\ntolerances = [1e-6]\n'
        'formalisms = ["recursive", {name = "minimal-ode", options = {compile = "none"}}]\n'
    )
    runs = parse_spec(text).runs
    options = {run.formalism: run.formalism_options["compile"] for run in runs}
    assert options == {"recursive": "auto", "minimal-ode": "none"}


def test_the_vm_keeps_lapack_lu_and_c_gets_a_graph_it_can_be_generated_for():
    """A KKT system solved numerically (absolute coordinates): LAPACK's LU, faster in the
    VM, cannot be generated as C, so "auto" builds the QR graph beside it for C."""
    problem = get_problem("slider-crank")({})
    auto = {"compile": "auto", "index": 1}
    equations = get_formalism("absolute-dae")().build(problem.model(), auto)
    rhs = equations.forms["ode"].rhs
    assert rhs.for_c is not rhs.function
    assert "#error" in compiled.generate_c(compiled.exported(rhs.function))  # LapackLu
    assert "#error" not in compiled.generate_c(compiled.exported(rhs.for_c))
    plain = get_formalism("absolute-dae")().build(problem.model(), {**auto, "compile": "none"})
    assert plain.forms["ode"].rhs.for_c is plain.forms["ode"].rhs.function


def test_a_runs_notes_name_what_it_called_not_what_the_workers_earlier_runs_did():
    """A run's compile=auto notes are the same in a fresh worker and in one whose cached
    equations an implicit integrator used before (its Jacobian was counted "in the VM"
    in the explicit run's notes: 9 against 8 functions; benchmarks.torture's Dask worker
    kill counted that row as differing from the uninterrupted sweep)."""
    from workbench.execution.execute import RunSpec, clear_cache, execute_run

    def spec(integrator: str) -> RunSpec:
        return RunSpec("slider-crank", "absolute-dae", integrator, 1e-4, 1e-7,
                       formalism_options={"index": 1})  # fmt: skip

    clear_cache()
    fresh = execute_run(spec("scipy-dop853")).row
    clear_cache()
    first = execute_run(spec("sundials-cvode-bdf")).row
    after = execute_run(spec("scipy-dop853")).row
    clear_cache()
    assert first["status"] == fresh["status"] == after["status"] == "ok"
    assert after["equations_cached"] and not fresh["equations_cached"]
    assert "compile=auto" in fresh["notes"]
    assert after["notes"] == fresh["notes"]
