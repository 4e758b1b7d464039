"""Counted work (workbench.execution.counted_work): a run's evaluations weighted by their unit
CPU costs, a cost measure that moves little with the machine's load (issue 33)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from workbench.execution import counted_work
from workbench.execution.execute import (
    RunSpec,
    cached_equations,
    cached_problem_part,
    clear_cache,
    execute_run,
)
from workbench.outputs.report import prepare_results
from workbench.outputs.report.cost import resolve_cost
from workbench.outputs.report.ranking import decide
from workbench.plugin import registry


def row_of(spec: RunSpec) -> dict:
    result = execute_run(spec)
    return result.row if hasattr(result, "row") else result[0]


def equations_of(spec: RunSpec) -> object:
    """The equations a run of ``spec`` in this process used (the worker's cache)."""
    problem = registry.get_problem(spec.problem)(spec.problem_options)
    model, _ = cached_problem_part(spec, "model", problem.model)
    return cached_equations(spec, model)[0]


def test_counted_work_is_the_counts_weighted_by_the_unit_costs() -> None:
    clear_cache()  # one worker: the same equations for both runs, unit costs timed once
    loose = row_of(RunSpec("double-pendulum", "minimal-ode", "scipy-dop853", 1e-4, 1e-7))
    tight = row_of(RunSpec("double-pendulum", "minimal-ode", "scipy-dop853", 1e-9, 1e-12))
    assert loose["status"] == tight["status"] == "ok"
    assert loose["n_jac"] == tight["n_jac"] == 0  # explicit: right-hand sides only
    # the same unit cost: the work is proportional to the counted right-hand sides
    ratio = tight["work_s"] / loose["work_s"]
    assert ratio == pytest.approx(tight["n_rhs"] / loose["n_rhs"], rel=1e-12)
    assert tight["n_rhs"] > 3 * loose["n_rhs"]
    for row in (loose, tight):
        assert 0 < row["work_s_min"] == row["work_s"] <= row["work_s_max"]
        # the right-hand sides are a part of the integration's CPU time, not 10x more
        # (a unit cost not divided by its batch's calls would be thousands of times more)
        assert row["work_s"] < 2 * row["integrate_cpu_s_max"]


def test_an_implicit_run_counts_jacobians_and_factorizations() -> None:
    row = row_of(RunSpec("iftomm-a05", "recursive", "scipy-radau", 1e-6, 1e-9))
    assert row["status"] == "ok" and row["n_jac"] > 0 and row["n_lu"] > 0
    # the unit costs the row used are the ones kept for its equations
    equations = equations_of(RunSpec("iftomm-a05", "recursive", "scipy-radau", 1e-6, 1e-9))
    units = {u: counted_work.unit_cost(equations, "ode", u) for u in ("rhs", "jac", "lu")}
    expected = sum(row[f"n_{u}"] * units[u][0] for u in ("rhs", "jac", "lu"))
    assert row["work_s"] == pytest.approx(expected, rel=1e-12)
    assert all(0 < low <= high for low, high in units.values())


def test_timing_a_unit_cost_does_not_count_as_an_evaluation() -> None:
    clear_cache()
    equations = equations_of(RunSpec("double-pendulum", "minimal-ode", "scipy-dop853", 1e-6, 1e-9))
    rhs = equations.forms["ode"].rhs
    before = rhs.n_calls
    low, high = counted_work.unit_cost(equations, "ode", "rhs")
    assert rhs.n_calls == before and 0 < low <= high


def test_a_mechanical_form_run_has_no_counted_work() -> None:
    row = row_of(RunSpec("double-pendulum", "absolute-dae", "generalized-alpha", 1e-4, 1e-7))
    assert row["form"] == "mechanical"
    assert all(math.isnan(row[c]) for c in counted_work.COLUMNS)


def test_the_report_ranks_by_counted_work_with_its_interval() -> None:
    records = [
        {"run_id": f"r{k}", "problem": "p", "formalism": f, "integrator": "i", "rtol": 1e-6,
         "status": "ok", "scd": 6.0, "integrate_cpu_s": 1.0, "repeats": 1, "n_rhs": 100,
         "work_s": low, "work_s_min": low, "work_s_max": high}
        for k, (f, low, high) in enumerate([("a", 1.0, 1.1), ("b", 1.05, 1.2), ("c", 3.0, 3.1)])
    ]  # fmt: skip
    runs = prepare_results(pd.DataFrame(records))
    cost = resolve_cost(runs, "work")
    assert cost.column == "work_s" and "counted work" in cost.statement()
    decision = decide(runs, 4.0, cost.column)  # one timed sample, yet an interval
    assert decision.tie_known and decision.tied == ["a / i", "b / i"]
    apart = decide(runs[runs["formalism"] != "b"], 4.0, cost.column)
    assert apart.margin == pytest.approx(3.0) and not apart.is_tie
    assert np.isfinite(apart.high)


def test_timing_a_unit_cost_under_compile_auto_neither_counts_nor_compiles() -> None:
    """The timing batches are no calls of the run and never move a compile=auto function
    to C (they once counted towards a compile, and could set one off inside the
    measurement)."""
    import casadi as ca

    from workbench.equations.compiled import Compiler
    from workbench.equations.evaluate import dense_function

    x = ca.SX.sym("x", 4)
    fast = dense_function("f", [x], [ca.sin(x) * ca.cos(x)], compiler=Compiler(mode="auto"))
    fast.into(np.ones(4))
    state = (fast.n_calls, fast.evaluated)
    low, high = fast.cpu_per_call()
    assert (fast.n_calls, fast.evaluated) == state
    assert 0 < low <= high


def test_a_unit_cost_is_timed_again_once_compile_auto_moved_its_function_to_c(
    monkeypatch,
) -> None:
    """A worker's first runs time the right-hand side in the VM; once compile=auto has
    put it in C for a longer run (between runs), that run's counted work must weight its
    calls with the C call's cost, not the VM's."""
    from tests.test_compile_auto import ARGS, chain
    from workbench.equations import compile_policy

    monkeypatch.setattr(compile_policy, "calls_to_repay", lambda vm_seconds, code_bytes: 50.0)
    equations = chain("auto")
    equations.compiler.expect(10)
    rhs = equations.forms["ode"].rhs
    for _ in range(60):
        rhs.into(*ARGS)
    in_vm = counted_work.unit_cost(equations, "ode", "rhs")
    assert counted_work.unit_cost(equations, "ode", "rhs") is in_vm  # kept while in the VM
    equations.compiler.expect(100)  # the next run, a longer one, starts in C
    assert rhs.compile()
    in_c = counted_work.unit_cost(equations, "ode", "rhs")
    assert in_c is not in_vm and 0 < in_c[0] <= in_c[1]
