"""The runner and metrics: run ids, stages, pairing, failures, physics of the metrics."""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import numpy as np
import pytest

from workbench.execution import references, row_schema
from workbench.execution.execute import RunSpec, execute_run, normalized_spec
from workbench.numerics import geometry


def spec(
    problem="test-pendulum", formalism="minimal-ode", integrator="test-rk45", rtol=1e-6, **kwargs
):
    kwargs.setdefault("formalism_options", {"index": 1})
    return RunSpec(problem, formalism, integrator, rtol, rtol * 1e-3, **kwargs)


def test_run_id_is_stable_short_and_distinct() -> None:
    a = RunSpec("p", "f", "i", 1e-6, 1e-9, {"x": 1, "y": 2})
    same = RunSpec("p", "f", "i", 1e-6, 1e-9, {"y": 2, "x": 1})
    assert a.run_id == same.run_id
    assert len(a.run_id) == 16 and int(a.run_id, 16) >= 0
    # the hash of the canonical JSON is part of the contract: it must not change
    assert a.run_id == RunSpec.from_dict(a.to_dict()).run_id
    others = [
        RunSpec("q", "f", "i", 1e-6, 1e-9, {"x": 1, "y": 2}),
        RunSpec("p", "g", "i", 1e-6, 1e-9, {"x": 1, "y": 2}),
        RunSpec("p", "f", "j", 1e-6, 1e-9, {"x": 1, "y": 2}),
        RunSpec("p", "f", "i", 1e-7, 1e-9, {"x": 1, "y": 2}),
        RunSpec("p", "f", "i", 1e-6, 1e-10, {"x": 1, "y": 2}),
        RunSpec("p", "f", "i", 1e-6, 1e-9, {"x": 1, "y": 3}),
        RunSpec("p", "f", "i", 1e-6, 1e-9, {"x": 1, "y": 2}, {"index": 1}),
        RunSpec("p", "f", "i", 1e-6, 1e-9, {"x": 1, "y": 2}, {}, {"a": 1}),
    ]
    ids = {a.run_id} | {o.run_id for o in others}
    assert len(ids) == len(others) + 1


def test_normalized_spec_fills_defaults(fake_plugins) -> None:
    short = normalized_spec(spec(formalism_options={"index": 1}))
    full = normalized_spec(spec(formalism_options=short.formalism_options))
    assert short.run_id == full.run_id
    assert short.formalism_options["baumgarte_alpha"] == 10.0
    assert short.problem_options == {"initial_angle": 1.0}


def test_conservative_run_errors_shrink_with_tolerance(fake_plugins, tmp_path, monkeypatch) -> None:
    # a reference an earlier test computed in this process would be served from memory
    monkeypatch.setattr(references, "_REFERENCE_MEMORY", {})
    rows = [execute_run(spec(rtol=rtol), reference_dir=tmp_path).row for rtol in (1e-3, 1e-6, 1e-9)]
    assert [r["status"] for r in rows] == ["ok"] * 3
    assert all(r["reference_kind"] == "computed" for r in rows)
    energy = [r["energy_err_max"] for r in rows]
    error = [r["err_max"] for r in rows]
    assert energy[0] > energy[1] > energy[2]
    assert error[0] > error[1] > error[2]
    assert energy[2] < 1e-7 and error[2] < 1e-6 and energy[0] > 1e-6
    assert rows[2]["scd"] > rows[0]["scd"] + 4
    # minimal coordinates of a tree: no drift by construction
    assert rows[2]["drift_pos_max"] < 1e-12 and math.isnan(rows[2]["drift_nh_max"])
    assert all(r["n_rhs"] > 0 and r["n_steps"] > 0 for r in rows)
    assert rows[0]["n_rhs"] < rows[2]["n_rhs"]
    # stage times, versions, machine
    for column in ("build_s", "init_s", "integrate_s", "metrics_s", "wall_s", "cpu_s"):
        assert rows[2][column] >= 0
    assert rows[1]["equations_cached"] and rows[1]["build_s"] < rows[0]["build_s"]
    assert rows[0]["version_numpy"] == np.__version__ and rows[0]["cpu_count"] >= 1
    # the reference is cached on disk
    assert len(list(tmp_path.glob("test-pendulum-*.parquet"))) == 1


def test_closed_loop_drift_and_energy_with_inline_rk4(fake_plugins, tmp_path) -> None:
    coarse = execute_run(
        spec(
            "test-slider-crank", integrator="test-rk4", integrator_options={"steps_per_sample": 2}
        ),
        reference_dir=tmp_path,
    )
    fine = execute_run(
        spec(
            "test-slider-crank", integrator="test-rk4", integrator_options={"steps_per_sample": 20}
        ),
        reference_dir=tmp_path,
    )
    assert coarse.row["status"] == fine.row["status"] == "ok"
    assert fine.row["drift_pos_max"] < coarse.row["drift_pos_max"]
    assert fine.row["energy_err_max"] < coarse.row["energy_err_max"]
    assert fine.row["drift_pos_max"] < 1e-5 and fine.row["energy_err_max"] < 1e-4
    series = fine.series
    # then the trajectory's states (tests/test_trajectory_store.py)
    n = len(row_schema.SERIES_COLUMNS)
    assert list(series.columns[:n]) == row_schema.SERIES_COLUMNS
    assert all(c.startswith(row_schema.STATE_PREFIX) for c in series.columns[n:])
    assert len(series) == 26 and (series["run_id"] == fine.row["run_id"]).all()
    assert series["drift_pos"].iloc[0] < 1e-10 and series["energy_err"].iloc[0] == 0


def test_analytic_reference_and_non_conservative_notes(fake_plugins) -> None:
    falling = execute_run(spec("test-falling", rtol=1e-8)).row
    assert falling["reference_kind"] == "analytic"
    assert falling["err_max"] < 1e-6 and falling["scd"] > 6
    loose = execute_run(spec("test-nonconservative", rtol=1e-4)).row
    assert loose["status"] == "ok" and math.isnan(loose["energy_err_max"])
    assert "not computed" in loose["notes"]


def test_skip_reasons(fake_plugins) -> None:
    # a closed loop at index 3 has no ode form; a tree has one at every index
    form = execute_run(spec("test-slider-crank", formalism_options={"index": 3})).row
    assert form["status"] == "skipped"
    assert "'test-rk45': accepts" in form["message"]
    assert "minimal-ode offers" in form["message"]
    tree = execute_run(spec(formalism_options={"index": 3})).row
    assert tree["status"] == "ok" and tree["form"] == "ode"
    loops = execute_run(spec("test-slider-crank", formalism="test-trees-only")).row
    assert loops["status"] == "skipped" and "loop-closing" in loops["message"]
    picky = execute_run(spec(integrator="test-picky")).row
    assert picky["status"] == "skipped" and "constant mass matrix" in picky["message"]


@pytest.mark.parametrize(
    "formalism, integrator, stage, text",
    [
        ("test-broken-build", "test-rk45", "build", "always fails to build"),
        ("minimal-ode", "test-raise", "integrate", "the test integrator raised"),
        ("minimal-ode", "test-nan", "integrate", "NaN"),
    ],
)
def test_failures_are_rows(fake_plugins, formalism, integrator, stage, text) -> None:
    result = execute_run(spec(formalism=formalism, integrator=integrator))
    row = result.row
    assert row["status"] == "failed" and row["stage"] == stage
    assert text in row["message"] and row["message"].startswith(stage)
    assert "\n" not in row["message"]


@pytest.mark.parametrize("integrator", ["test-raise", "test-nan"])
def test_a_run_that_never_stepped_measured_nothing(fake_plugins, integrator) -> None:
    """A method that failed at t0 has no error, drift or energy: NaN, never 0 (which reads
    as a perfect run in a table); the note says why."""
    row = execute_run(spec(formalism="minimal-ode", integrator=integrator)).row
    assert row["status"] == "failed"
    for column in ("err_max", "scd", "drift_pos_max", "drift_vel_max", "energy_err_max"):
        assert math.isnan(row[column]), column
    assert "nothing was integrated" in row["notes"]


def test_unknown_plugin_is_a_failed_row(fake_plugins) -> None:
    row = execute_run(spec(integrator="no-such-integrator")).row
    assert row["status"] == "failed" and "unknown integrator" in row["message"]


def test_sink_receives_the_run(fake_plugins) -> None:
    calls = []

    class Sink:
        def log_run(self, run_spec, equations, problem, trajectory, series):
            calls.append(
                (run_spec, equations.formalism, problem.name, trajectory.success, len(series))
            )

    run = spec()
    result = execute_run(run, sink=Sink())
    assert calls == [(run, "minimal-ode", "test-pendulum", True, 41)]
    assert result.row["log_s"] >= 0


def test_pose_error_and_length_scale() -> None:
    reference = np.zeros((2, 1, 7))
    reference[..., 0] = 2.0
    reference[..., 3] = 1.0
    poses = reference.copy()
    poses[1, 0, 1] = 0.003  # 3 mm off
    angle = 0.01
    poses[1, 0, 3:] = [math.cos(angle / 2), 0, 0, math.sin(angle / 2)]
    error = geometry.pose_error(poses, reference, 2.0)
    assert error[0] == 0 and error[1] == pytest.approx(0.003 + 2.0 * angle)
    assert geometry.length_scale(None, reference) == 2.0
    assert geometry.length_scale(None, np.zeros((1, 1, 7))) == geometry.MIN_LENGTH_SCALE
    # an entry left unknown (NaN) drops out, not the whole reference (car axis: L was 1
    # instead of 1.118, every scd 0.048 too high)
    partly_known = np.zeros((2, 2, 7))
    partly_known[0, 0, :3] = [1.0, 0.5, 0.0]
    partly_known[1, 1, :3] = np.nan
    assert geometry.length_scale(None, partly_known) == pytest.approx(np.hypot(1.0, 0.5))


def test_equations_cache_keeps_the_most_recently_used(fake_plugins, monkeypatch) -> None:
    """The worker's equations cache is bounded (least recently used out): a reused entry
    is the same object, an evicted one is built again."""
    from workbench.execution import execute as runs
    from workbench.plugin.registry import get_problem

    runs.clear_cache()
    monkeypatch.setattr(runs, "EQUATIONS_CACHE_SIZE", 2)
    specs = [spec(formalism_options={"index": 1, "baumgarte_alpha": a}) for a in (1.0, 2.0, 3.0)]
    model = get_problem("test-pendulum")().model()
    first, built = runs.cached_equations(specs[0], model)
    second, _ = runs.cached_equations(specs[1], model)
    assert not built and runs.cached_equations(specs[0], model) == (first, True)  # 0 now newest
    runs.cached_equations(specs[2], model)  # evicts 1, the least recently used
    assert len(runs._EQUATIONS) == 2
    assert runs.cached_equations(specs[0], model) == (first, True)
    again, reused = runs.cached_equations(specs[1], model)
    assert not reused and again is not second
    runs.clear_cache()


def test_an_eviction_hands_memory_back_only_in_a_worker(monkeypatch) -> None:
    """A sweep's worker (its start-up frozen) collects and trims at each cache eviction; a
    notebook does not: there a full collection visits all its user holds, and alternating
    three problems took 0.24-0.76 s a run against 0.09-0.12 (docs/performance.md)."""
    import gc

    from workbench.execution import execute as runs

    released = []
    monkeypatch.setattr(runs, "release_freed_memory", lambda: released.append(1))
    monkeypatch.setattr(runs, "EQUATIONS_CACHE_SIZE", 1)
    runs.clear_cache()
    try:
        for length in (1.0, 2.0):
            runs.cached_problem_part(spec(problem_options={"length": length}), "model", object)
        assert len(runs._PROBLEMS) == 1 and not released  # evicted, left to the collector
        gc.freeze()  # as a worker's start-up does
        runs.cached_problem_part(spec(problem_options={"length": 3.0}), "model", object)
        assert len(runs._PROBLEMS) == 1 and released == [1]
    finally:
        gc.unfreeze()
        runs.clear_cache()


def test_frozen_startup_objects_are_skipped_and_later_garbage_still_collected() -> None:
    """A worker freezes what it loaded before its first run: a collection then no longer
    visits those objects, and garbage made afterwards (an evicted entry's reference
    cycles) is still freed by release_freed_memory."""
    import gc
    import weakref

    from workbench.execution import execute as runs

    class Node:
        pass

    loaded = Node()
    try:
        runs.freeze_loaded_objects()
        tracked = {id(o) for o in gc.get_objects()}
        assert gc.get_freeze_count() > 0 and id(loaded) not in tracked
        cycle = Node()
        cycle.itself = cycle
        freed = weakref.ref(cycle)
        del cycle
        runs.release_freed_memory()
        assert freed() is None
    finally:
        gc.unfreeze()


def test_a_problem_whose_making_imports_many_modules_has_them_frozen_in_a_worker() -> None:
    """A robot's model imports its reader's hundreds of modules after the worker froze its
    start-up: they are frozen too (each later eviction's collection would visit them), the
    equations cached before are dropped and their cycles collected first (frozen, they
    would never be), this problem's model stays; a process that froze nothing (a
    notebook) has nothing frozen."""
    import gc
    import types
    import weakref

    from workbench.execution import execute as runs

    class Node:
        pass

    names = [f"_wb_test_module_{i}" for i in range(runs.FREEZE_AFTER_MODULES)]

    def make() -> Node:
        for name in names:
            module = types.ModuleType(name)
            module.payload = [Node() for _ in range(3)]
            sys.modules[name] = module
        return Node()

    key_spec = spec()
    runs.clear_cache()
    try:
        model, reused = runs.cached_problem_part(key_spec, "model", make)
        assert not reused and gc.get_freeze_count() == 0  # not a worker: nothing frozen
        for name in names:
            del sys.modules[name]
        runs.clear_cache()
        runs.freeze_loaded_objects()  # a worker's start-up
        cycle = Node()
        cycle.itself = cycle
        runs._EQUATIONS[("cached", "", "", "")] = runs._Cached(cycle)
        evicted = weakref.ref(cycle)
        del cycle
        other = replace(key_spec, problem_options={"length": 2.0})
        runs.cached_problem_part(other, "model", Node)
        model, _ = runs.cached_problem_part(key_spec, "model", make)
        tracked = {id(o) for o in gc.get_objects()}
        assert id(sys.modules[names[0]].payload[0]) not in tracked  # frozen
        assert evicted() is None and not runs._EQUATIONS  # collected, not frozen
        assert runs.cached_problem_part(key_spec, "model", make) == (model, True)
        assert len(runs._PROBLEMS) == 1
    finally:
        gc.unfreeze()
        for name in names:
            sys.modules.pop(name, None)
        runs.clear_cache()


def test_initial_state_is_computed_once_per_cached_equations() -> None:
    """The consistent initial state is kept with the cached equations: the same object
    for every integrator and tolerance, equal to a fresh computation, and consistent
    (closure residual of the four-bar ~ 0); other equations get their own."""
    from workbench.equations.initial import consistent_initial_state
    from workbench.execution import execute as runs
    from workbench.plugin.registry import get_problem

    runs.clear_cache()
    specs = [
        normalized_spec(RunSpec("four-bar", "absolute-dae", integrator, rtol, rtol * 1e-3))
        for integrator, rtol in (("scipy-dop853", 1e-4), ("sundials-ida", 1e-8))
    ]
    problem = get_problem("four-bar")()
    equations, _ = runs.cached_equations(specs[0], problem.model())
    first = runs.cached_initial_state(specs[0], equations, problem)
    assert runs.cached_initial_state(specs[1], equations, problem) is first
    fresh = consistent_initial_state(equations, problem)
    np.testing.assert_array_equal(first.q, fresh.q)
    np.testing.assert_array_equal(first.v, fresh.v)
    residuals = equations.observables.residuals(0.0, first.q, first.v)
    assert np.abs(np.asarray(residuals[0])).max() < 1e-10
    other = normalized_spec(RunSpec("four-bar", "minimal-ode", "scipy-dop853", 1e-4, 1e-7))
    other_equations, _ = runs.cached_equations(other, problem.model())
    assert runs.cached_initial_state(other, other_equations, problem) is not first
    runs.clear_cache()
