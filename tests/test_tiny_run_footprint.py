"""A tiny run's work outside its integration made cheaper (issue 35, item 4) gives the
same row and series: metrics of all samples in one mapped call equal one call a sample,
the series has the same columns, the run id is computed
once and is the hash of the spec."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from workbench.equations import observables as observables_module
from workbench.equations.initial import consistent_initial_state
from workbench.execution import audit
from workbench.execution import metrics as metrics_module
from workbench.execution.execute import (
    RunSpec,
    canonical_json,
    execute_run,
    normalized_spec,
)
from workbench.execution.references import problem_reference
from workbench.execution.row_schema import SERIES_COLUMNS
from workbench.plugin.registry import get_formalism, get_integrator, get_problem


def _one_sample_at_a_time(function, n, args, cache):
    """evaluate_along's contract met by n separate calls (the metrics before Function.map)."""
    outputs = [function.call([np.asarray(a)[:, k] for a in args]) for k in range(n)]
    return [np.stack([np.array(out[i]) for out in outputs]) for i in range(function.n_out())]


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b or abs(a - b) <= 1e-12 * max(abs(a), abs(b))
    return a == b


@pytest.mark.parametrize(
    ("problem", "formalism", "options"),
    [
        ("simple-pendulum", "minimal-ode", {}),  # the tiny run of the benchmark
        ("four-bar", "absolute-dae", {"index": 1}),  # drift, closed loop
    ],
)
def test_metrics_of_all_samples_at_once_equal_one_sample_at_a_time(
    problem, formalism, options, monkeypatch
):
    """Every metric column and series value of a real run, by the mapped call
    (``Observables.along``) and by one call a sample: equal to 1e-12 relative, the same
    columns."""
    problem_ = get_problem(problem)()
    equations = get_formalism(formalism)().build(problem_.model(), options)
    state = consistent_initial_state(equations, problem_)
    integrator = get_integrator("scipy-dop853")()
    parsed = integrator.parse_options({})
    form = integrator.select_form({k: getattr(f, "index", 0) for k, f in equations.forms.items()})
    times = problem_.sample_times()
    trajectory = integrator.solve(
        equations, state.y0(equations, form), state.yp0(equations, form), times, 1e-6, 1e-8,
        parsed, form,
    )  # fmt: skip
    reference = problem_reference(problem_, problem, {}, times, None)

    def measure():
        return metrics_module.trajectory_metrics(
            "run", problem_, equations, np.asarray(trajectory.times),
            np.atleast_2d(trajectory.y), trajectory.success, reference, 1e-6,
        )  # fmt: skip

    row, series = measure()
    monkeypatch.setattr(observables_module, "evaluate_along", _one_sample_at_a_time)
    monkeypatch.setattr(audit, "evaluate_along", _one_sample_at_a_time)
    equations.observables._last = ()  # no poses kept from the mapped call
    row_each, series_each = measure()
    assert list(series.columns) == SERIES_COLUMNS == list(series_each.columns)
    assert row.keys() == row_each.keys()
    for key, value in row.items():
        assert _same(value, row_each[key]), (key, value, row_each[key])
    assert np.isfinite(series["energy_err"]).all()
    numeric = SERIES_COLUMNS[1:]
    np.testing.assert_allclose(
        series[numeric].to_numpy(), series_each[numeric].to_numpy(), rtol=1e-12, atol=1e-300
    )


def test_the_run_id_is_computed_once_and_is_the_hash_of_the_spec():
    spec = normalized_spec(RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-4, 1e-6))
    expected = hashlib.sha256(canonical_json(spec.to_dict()).encode()).hexdigest()[:16]
    assert spec.run_id == expected and spec.__dict__["run_id"] == expected
    result = execute_run(spec)
    assert result.row["run_id"] == expected and result.row["status"] == "ok"
    assert set(result.series["run_id"]) == {expected}


def test_one_progress_thread_serves_every_run_and_none_writes_after_its_stop(tmp_path):
    """The progress file of each run (written at its start) by one thread a process, not a
    thread a run; a stopped run's file is never written again; one file throughout, renamed
    from run to run (no file made and deleted a run), deleted when the process releases it."""
    import os
    import threading
    import time

    from workbench.execution.run_progress import (
        WRITE_EVERY,
        ProgressWriter,
        read_progress,
        release_progress_file,
    )

    (tmp_path / "logs").mkdir()
    paths = [tmp_path / "logs" / f".run{k}.progress" for k in range(4)]
    threads, inodes = [], set()
    for k, path in enumerate(paths):
        with ProgressWriter(path):
            inodes.add(path.stat().st_ino)
            assert json_of(path).keys() >= {"stage", "t_reached", "wall_s"}
            threads += [t for t in threading.enumerate() if t.name == "run-progress"]
        assert [p for p in paths if p.exists()] == [path]  # the earlier runs' names are gone
        stopped = path.read_bytes(), path.stat().st_mtime_ns
        time.sleep(3 * WRITE_EVERY if k == 0 else 0)  # the thread goes on ticking
        assert (path.read_bytes(), path.stat().st_mtime_ns) == stopped  # follows no file
    assert len(threads) == len(paths) and all(t is threads[0] for t in threads)
    assert len(inodes) == 1  # one file, renamed
    assert read_progress(paths[-1])["stage"] is not None  # what a killed run's pool reads
    release_progress_file()
    assert not any(path.exists() for path in paths)
    assert os.listdir(tmp_path / "logs") == []


def json_of(path):
    import json

    return json.loads(path.read_text())


def test_a_workers_raw_output_file_is_renamed_from_run_to_run_not_made_again(tmp_path):
    """CapturedOutput(reuse=True), as a pool worker runs it: each run's output under its
    own raw file's name (where the pool salvages a killed run's output), one file renamed
    and emptied from run to run, each run's kept output its own; released at the end."""
    import os

    from workbench.execution.run_log import CapturedOutput, raw_path, release_raw_file

    inodes, kept = set(), []
    for k in range(3):
        raw = raw_path(tmp_path, f"run{k}")
        capture = CapturedOutput(raw, reuse=True)
        with capture:
            os.write(1, f"output of run {k}\n".encode())
            assert raw.read_bytes() == f"output of run {k}\n".encode()
            inodes.add(raw.stat().st_ino)
        kept.append(capture.kept())
        assert [p.name for p in (tmp_path / "logs").iterdir()] == [raw.name]
    assert kept == [f"output of run {k}\n".encode() for k in range(3)]
    assert len(inodes) == 1
    release_raw_file()
    assert list((tmp_path / "logs").iterdir()) == []


def test_a_series_file_has_the_bytes_pandas_writes(tmp_path):
    """write_parquet_atomic (pyarrow in memory, its Arrow schema made once per column
    layout) writes what ``DataFrame.to_parquet`` writes, attrs included, for a second
    frame of a layout as for the first: the series and results files read back as before."""
    import pandas as pd

    from workbench.files import write_parquet_atomic

    runs = [
        execute_run(RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", rtol, 1e-6)).series
        for rtol in (1e-4, 1e-3)
    ]  # the same layout twice, other values; then a slice of it
    other = pd.DataFrame({"a": [1, 2], "b": ["x", None], "c": [1.5, math.nan]}, index=[4, 5])
    other.attrs = {"source": "test"}
    kinds = pd.DataFrame(
        {
            "i": np.array([1, 2, 3], dtype=np.int32),
            "f": [math.inf, -0.0, math.nan],
            "flag": [True, False, True],
            "s": pd.array(["x", pd.NA, "z"], dtype="string"),
        }
    )
    objects = pd.DataFrame(  # types inferred from the values (not from no rows)
        {"o": pd.array(["a", None, "c"], dtype=object), "lists": [[1], [2, 3], []]}
    )
    frames = [*runs, runs[1].iloc[1:], other, kinds, kinds.iloc[::-1], objects]
    for k, frame in enumerate(frames):
        frame.to_parquet(tmp_path / f"pandas{k}.parquet", index=False)
        write_parquet_atomic(frame, tmp_path / f"ours{k}.parquet")
        ours = (tmp_path / f"ours{k}.parquet").read_bytes()
        assert ours == (tmp_path / f"pandas{k}.parquet").read_bytes(), k
    assert pd.read_parquet(tmp_path / "ours3.parquet").attrs == {"source": "test"}


def test_a_lean_series_file_reads_back_the_same_without_statistics_or_float_dictionaries(
    tmp_path,
):
    """A run's series file (``lean``) reads back as the series, attrs included, and holds
    no column statistics and no dictionary for a float column (only for text)."""
    import pandas as pd
    import pyarrow.parquet as pq

    from workbench.files import write_parquet_atomic
    from workbench.runs import store

    result = execute_run(RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-4, 1e-6))
    store.write_run(tmp_path, result.row, result.series)
    path = store.series_path(tmp_path, result.row["run_id"])
    pd.testing.assert_frame_equal(pd.read_parquet(path), result.series)
    metadata = pq.read_metadata(path)
    columns = [metadata.row_group(0).column(k) for k in range(metadata.num_columns)]
    assert not any(column.is_stats_set for column in columns)
    dictionaries = {c.path_in_schema for c in columns if c.dictionary_page_offset is not None}
    assert dictionaries == {"run_id"}
    frame = pd.DataFrame({"x": [1.0, math.nan], "name": ["a", None]})
    frame.attrs = {"source": "test"}
    write_parquet_atomic(frame, tmp_path / "lean.parquet", lean=True)
    again = pd.read_parquet(tmp_path / "lean.parquet")
    pd.testing.assert_frame_equal(again, frame)
    assert again.attrs == {"source": "test"}


def test_a_row_file_is_one_line_that_reads_back_as_the_row(tmp_path):
    """A run's row file is written by Python's C JSON encoder (one line, no indent): the
    row read back is the row, inf and NaN included."""
    from workbench.runs import store

    result = execute_run(RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-4, 1e-6))
    row = dict(result.row, extra_inf=math.inf, extra_nan=math.nan, extra_int=np.int64(3))
    store.write_run(tmp_path, row, result.series)
    text = store.row_path(tmp_path, row["run_id"]).read_text(encoding="utf-8")
    assert "\n" not in text
    again = store.read_row(store.row_path(tmp_path, row["run_id"]))
    assert again is not None and again.keys() == row.keys()
    assert all(_same(again[key], value) for key, value in row.items() if key != "extra_int")
    assert again["extra_int"] == 3


class _FrozenProbe:
    """A recorder whose start-up makes an object (``prepare``, as Rerun's import does in a
    worker) and whose first sink writes whether the collector still tracks it."""

    suffix = "rrd"
    made: object = None
    report = ""  # the file it writes to (set before the worker is forked)

    @classmethod
    def prepare(cls) -> None:
        cls.made = [object()]  # a container: tracked by the collector

    def __init__(self) -> None:
        import gc

        tracked = any(o is type(self).made for o in gc.get_objects())  # (frozen: not listed)
        with open(type(self).report, "w") as file:
            file.write(f"tracked={tracked}")
        raise RuntimeError("no recording wanted")  # the run goes on unrecorded


def test_a_workers_start_up_objects_are_frozen_out_of_the_collectors_passes(tmp_path, monkeypatch):
    """A pool worker freezes (gc.freeze) what its start-up made before its first run, so
    the collector's full passes do not walk it every few hundred runs."""
    import multiprocessing

    from workbench.execution.timing import Timing
    from workbench.runs import local_pool

    monkeypatch.setattr(_FrozenProbe, "report", str(tmp_path / "probe.txt"))
    context = multiprocessing.get_context("fork")
    parent_end, child_end = context.Pipe()
    process = context.Process(
        target=local_pool._worker_main,
        args=(child_end, [], str(tmp_path), []),
        kwargs={"recorder": _FrozenProbe, "timing": Timing(repeats=1, workers=1).to_dict()},
    )
    process.start()
    try:
        assert parent_end.recv()[0] == "ready"
        spec = RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-3, 1e-6)
        parent_end.send(spec.to_dict())
        assert parent_end.recv()[:2] == ("done", spec.run_id)
        parent_end.send(None)
        process.join(timeout=60)
    finally:
        if process.is_alive():
            process.kill()
    assert (tmp_path / "probe.txt").read_text() == "tracked=False"


@pytest.mark.parametrize(
    ("problem", "formalism", "options"),
    [("simple-pendulum", "minimal-ode", {}), ("four-bar", "absolute-dae", {"index": 1})],
)
def test_a_recordings_poses_are_the_metrics_poses_of_those_samples(problem, formalism, options):
    """poses_of_rows after the metrics' along() (the recording of the run just measured,
    200 of its samples) gives the poses computed at those rows alone, bit for bit, and
    computes them when the states are others."""
    problem_ = get_problem(problem)()
    equations = get_formalism(formalism)().build(problem_.model(), options)
    state = consistent_initial_state(equations, problem_)
    integrator = get_integrator("scipy-dop853")()
    form = integrator.select_form({k: getattr(f, "index", 0) for k, f in equations.forms.items()})
    times = problem_.sample_times()
    trajectory = integrator.solve(
        equations, state.y0(equations, form), state.yp0(equations, form), times, 1e-6, 1e-8,
        integrator.parse_options({}), form,
    )  # fmt: skip
    t, y = np.asarray(trajectory.times), np.atleast_2d(trajectory.y)
    q, v = y[:, : equations.nq], y[:, equations.nq : equations.nq + equations.nv]
    rows = np.unique(np.linspace(0, len(t) - 1, 200).round().astype(int))
    observables = equations.observables
    alone = observables.poses_along(t[rows], q[rows])
    observables.along(t, q, v)  # the metrics' call
    cached = observables.poses_of_rows(t, q, rows)
    np.testing.assert_array_equal(cached, alone)
    assert observables.poses_of_rows(t, q + 1e-3, rows).shape == alone.shape  # not the cache
    np.testing.assert_array_equal(
        observables.poses_of_rows(t, q + 1e-3, rows),
        observables.poses_along(t[rows], q[rows] + 1e-3),
    )


class _Keep:
    """A sink that keeps what a run logs (its trajectory and series)."""

    def log_run(self, spec, equations, problem, trajectory, series):
        self.equations, self.trajectory, self.series = equations, trajectory, series


@pytest.mark.parametrize(
    ("problem", "formalism", "options", "integrator"),
    [
        ("simple-pendulum", "minimal-ode", {}, "scipy-dop853"),  # the tiny run
        ("four-bar", "absolute-dae", {"index": 1}, "scipy-dop853"),  # drift, multipliers
        ("bouncing-ball", "minimal-ode", {}, "moreau-jean"),  # a contact model's penetration
    ],
)
def test_a_runs_series_with_its_states_is_the_frame_joined_from_metrics_and_states(
    problem, formalism, options, integrator
):
    """The series made in one frame (the metrics' columns, a contact model's penetration,
    then the trajectory's ``state:`` columns) equals, column for column, value and dtype,
    the metrics' series joined to a frame of the states as before (pd.concat)."""
    import pandas as pd

    from workbench.execution.execute import state_names
    from workbench.execution.row_schema import STATE_PREFIX

    spec = RunSpec(problem, formalism, integrator, 1e-5, 1e-7, formalism_options=options)
    sink = _Keep()
    result = execute_run(spec, sink=sink)
    assert result.row["status"] == "ok", result.row["message"]
    times, y = np.asarray(sink.trajectory.times), np.atleast_2d(sink.trajectory.y)
    reference = problem_reference(get_problem(problem)(), problem, {}, times, None)
    _, metrics_series = metrics_module.trajectory_metrics(
        spec.run_id, get_problem(problem)(), sink.equations, times, y, True, reference,
        spec.rtol, contact=getattr(sink.trajectory, "contact", None),
    )  # fmt: skip
    names = state_names(sink.equations, result.row["form"], y.shape[1])
    states = pd.DataFrame(y[: len(times)], columns=[STATE_PREFIX + n for n in names], dtype=float)
    joined = pd.concat([metrics_series, states], axis=1)
    assert any(c.startswith("state:") for c in result.series.columns)
    assert ("penetration" in result.series) == (problem == "bouncing-ball")
    pd.testing.assert_frame_equal(result.series, joined, check_exact=True)
    assert result.series is sink.series


def test_a_specs_dict_is_what_asdict_gives_and_shares_nothing_with_the_spec():
    """RunSpec.to_dict made field by field equals ``dataclasses.asdict`` (tolerances as
    floats) for specs with empty and nested options, in the same key order, with copies
    of the options (changing the dict leaves the spec and its run id as they were)."""
    import dataclasses

    specs = [
        RunSpec("simple-pendulum", "minimal-ode", "scipy-rk45", 1e-4, 1e-6),
        RunSpec(
            "n-pendulum",
            "recursive-ode",
            "scipy-radau",
            np.float64(1e-6),
            1e-9,
            problem_options={"n": 3, "lengths": [1.0, 0.5, 0.25]},
            formalism_options={"compile": "jit", "flags": {"O": 2, "extra": ("a", "b")}},
            integrator_options={"max_step": 0.1},
        ),  # fmt: skip
    ]
    for spec in specs:
        expected = dataclasses.asdict(spec)
        expected["rtol"], expected["atol"] = float(spec.rtol), float(spec.atol)
        data = spec.to_dict()
        assert data == expected and list(data) == list(expected)
        assert type(data["rtol"]) is float and type(data["atol"]) is float
        run_id = spec.run_id
        data["problem_options"]["added"] = 1
        for value in data["formalism_options"].values():
            if isinstance(value, dict):
                value["O"] = 0
        assert spec.to_dict() == expected and spec.run_id == run_id
        assert RunSpec.from_dict(spec.to_dict()) == spec


def test_compile_auto_estimates_a_functions_c_once_and_decides_as_before(monkeypatch):
    """compile=auto sizes each function's C once per build (the graph does not change),
    and each run's choice of C or VM is what the estimate made afresh gives."""
    from workbench.equations import compile_policy
    from workbench.equations.compiled import c_compiler

    if c_compiler() is None:
        pytest.skip("compile=auto needs a C compiler")
    estimated = []
    original = compile_policy.code_bytes_estimate

    def counting(function):
        estimated.append(function.name())
        return original(function)

    monkeypatch.setattr(compile_policy, "code_bytes_estimate", counting)
    problem = get_problem("simple-pendulum")()
    equations = get_formalism("minimal-ode")().build(problem.model(), {"compile": "auto"})
    compiler = equations.compiler
    assert compiler.mode == "auto"
    state = consistent_initial_state(equations, problem)
    integrator = get_integrator("scipy-dop853")()
    times = problem.sample_times()
    for calls in (10.0, 1e9, 10.0, 1e9):
        compiler.expect(calls)  # as the runner does before each run
        integrator.solve(
            equations, state.y0(equations, "ode"), state.yp0(equations, "ode"), times, 1e-6,
            1e-8, integrator.parse_options({}), "ode",
        )  # fmt: skip
        assert compiler.tracked
        for fast in compiler.tracked:
            needed = compile_policy.calls_to_repay(fast.vm_seconds, original(fast.for_c))
            assert (fast.for_c.name() in compiler.in_c) == (calls >= needed)
        assert bool(compiler.in_c) == (calls > 10)  # both ways taken
    assert sorted(estimated) == sorted(set(estimated))  # once a function
    assert set(compiler.code_bytes) == {fast.for_c.name() for fast in compiler.tracked}


def test_a_captured_runs_folder_is_made_when_missing_even_between_reused_runs(tmp_path):
    """CapturedOutput makes ``<out>/logs`` when it is missing (not checked and made at
    every run): in a new output folder, and when the folder was removed between two runs
    of a worker that reuses its raw file."""
    import os
    import shutil

    from workbench.execution.run_log import CapturedOutput, raw_path, release_raw_file

    out = tmp_path / "new" / "out"
    for k in range(2):
        capture = CapturedOutput(raw_path(out, f"run{k}"), reuse=True)
        with capture:
            os.write(1, f"run {k}\n".encode())
        assert capture.kept() == f"run {k}\n".encode()
        shutil.rmtree(out / "logs")
    release_raw_file()


def test_a_rows_number_columns_are_checked_as_before_with_a_fast_path_for_json_numbers():
    """row_check's kind of a number: JSON's float and int at once, NumPy's numbers by the
    ABC as before, never a bool or text."""
    from workbench.execution.row_check import _kind_ok

    values = (1.5, 3, math.nan, True, False, "x", None, np.float64(2.0), np.int32(2))
    assert [_kind_ok(v, "number") for v in values] == [
        True, True, True, False, False, False, False, True, True,
    ]  # fmt: skip


def test_nearest_quaternions_are_scipys_bits():
    """The poses' quaternions (``nearest_quaternions``: SciPy's checks written out, then its
    conversion) are ``Rotation.from_matrix(m).as_quat()`` bit for bit: rotations, matrices
    off the rotations by round-off (kept) and by more (made rotations by SVD), a mixture;
    a left-handed frame raises as SciPy does."""
    from scipy.spatial.transform import Rotation

    nearest = observables_module.nearest_quaternions
    rng = np.random.default_rng(0)
    rotations = Rotation.random(2000, random_state=1).as_matrix()
    noisy = rotations + 1e-6 * rng.standard_normal(rotations.shape)
    cases = [
        rotations,
        rotations + 1e-13 * rng.standard_normal(rotations.shape),  # within atol 1e-12
        rotations + 1e-11 * rng.standard_normal(rotations.shape),  # beyond: orthogonalized
        rotations + 1e-3 * rng.standard_normal(rotations.shape),
        np.where(rng.random(2000)[:, None, None] < 0.5, rotations, noisy),
        np.tile(np.eye(3), (201, 1, 1)),
        Rotation.from_euler("z", rng.uniform(-4, 4, (201, 1))).as_matrix(),  # planar
        1.001 * rotations[:10],  # M M^T = 1.002 I: beyond rtol 1e-5 on the diagonal
    ]
    for matrices in cases:
        expected = Rotation.from_matrix(matrices).as_quat()
        np.testing.assert_array_equal(nearest(matrices), expected)
    left = rotations[:3].copy()
    left[1, :, 0] *= -1
    with pytest.raises(ValueError, match="determinant"):
        Rotation.from_matrix(left)
    with pytest.raises(ValueError, match="determinant"):
        nearest(left)


@pytest.mark.parametrize(
    ("problem", "formalism", "options"),
    [
        ("simple-pendulum", "minimal-ode", {}),  # the tiny run
        ("four-bar", "absolute-dae", {"index": 1}),  # constrained, closed loop
        ("rotating-ring", "minimal-ode", {}),  # rheonomic (a driven joint)
        ("heavy-top", "absolute-dae", {"index": 1}),  # spatial, Euler parameters
    ],
)
def test_metrics_with_the_written_out_quaternion_checks_equal_scipys(
    problem, formalism, options, monkeypatch
):
    """Every metric column and series value of a real run is the same, bit for bit, with
    the poses' quaternions by SciPy's ``from_matrix`` (the code before) and by
    ``nearest_quaternions``."""
    from scipy.spatial.transform import Rotation

    spec = RunSpec(problem, formalism, "scipy-dop853", 1e-5, 1e-7, formalism_options=options)
    result = execute_run(spec)
    assert result.row["status"] == "ok", result.row["message"]
    monkeypatch.setattr(
        observables_module, "nearest_quaternions", lambda m: Rotation.from_matrix(m).as_quat()
    )
    before = execute_run(spec)
    skip = {"integrate_s", "integrate_s_min", "integrate_s_max", "integrate_cpu_s",
            "integrate_cpu_s_min", "integrate_cpu_s_max", "wall_s", "cpu_s", "metrics_s",
            "build_s", "init_s", "log_s", "reference_s", "compile_s", "load_avg",
            "equations_cached"}  # fmt: skip
    columns = sorted((set(result.row) | set(before.row)) - skip)
    assert [result.row.get(c) for c in columns if not _same(result.row.get(c), before.row.get(c))
            ] == []  # fmt: skip
    import pandas as pd

    pd.testing.assert_frame_equal(result.series, before.series, check_exact=True)


def test_a_runs_series_columns_make_its_frame_and_the_same_series_file(tmp_path):
    """A run without a sink keeps its series as columns (no frame made): ``series`` made
    from them is the metrics' frame, and ``write_run`` of the columns writes the bytes of
    ``write_run`` of the frame, with and without the states; an empty run has its empty
    frame as before."""
    import pandas as pd

    from workbench.runs import store

    spec = RunSpec("four-bar", "absolute-dae", "scipy-dop853", 1e-5, 1e-7,
                   formalism_options={"index": 1})  # fmt: skip
    result = execute_run(spec)
    assert result.row["status"] == "ok", result.row["message"]
    assert result._series is None and result.columns is not None  # no frame made yet
    assert result.columns["run_id"] == spec.run_id
    assert result.row["n_samples"] == len(result.columns["t"]) == len(result.series)
    assert result.stored_series is result.columns
    assert result.series is result.series  # made once
    assert list(result.series.columns) == list(result.columns)
    pd.testing.assert_frame_equal(result.series, pd.DataFrame(result.columns), check_exact=True)
    assert str(result.series["run_id"].dtype) == "str" or result.series["run_id"].dtype == object
    for states in (True, False):
        store.write_run(tmp_path / "columns", result.row, result.columns, states)
        store.write_run(tmp_path / "frame", result.row, result.series, states)
        written = [store.series_path(tmp_path / k, spec.run_id).read_bytes()
                   for k in ("columns", "frame")]  # fmt: skip
        assert written[0] == written[1]
        read = store.load_series(tmp_path / "columns", spec.run_id, states=True)
        assert any(c.startswith("state:") for c in read.columns) == states
    skipped = execute_run(RunSpec("four-bar", "minimal-ode", "no-such-integrator", 1e-5, 1e-7))
    assert skipped.columns is None and len(skipped.series) == 0
    assert list(skipped.series.columns) == SERIES_COLUMNS


def test_the_recording_logs_a_series_given_as_columns_as_it_logs_its_frame(monkeypatch):
    """``RerunSink`` reads a series' columns (what the runner now hands it) as its frame:
    the same time column and the same values, also when the columns carry another run's
    id (filtered out, as the frame's rows); a sink without ``takes_series_columns`` is
    handed the DataFrame, which the result then keeps."""
    import pandas as pd

    from workbench.outputs import recording as recording_module

    spec = RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-5, 1e-7)
    result = execute_run(spec)
    sent = []
    sink = recording_module.RerunSink()
    monkeypatch.setattr(sink, "_send", sent.append)  # the chunks a run's series makes

    def logged(series, run_id):
        sent.clear()
        sink._log_series("runs/x", series, "label", run_id)
        return [
            (chunk.entity_path, chunk.is_static, chunk.to_record_batch().drop_columns(
                ["rerun.controls.RowId"]).to_pydict())
            for chunk in sent
        ]  # fmt: skip

    for run_id in (spec.run_id, None):
        by_columns, by_frame = logged(result.columns, run_id), logged(result.series, run_id)
        assert [static for _, static, _ in by_columns] == [True, False]  # names, then values
        (_, _, names), (_, _, values) = by_columns
        assert names["SeriesLines:names"] == [["label"] * len(recording_module.SERIES_QUANTITIES)]
        assert len(values["sim_time"]) == len(result.series)
        for (path, static, columns), (path_f, static_f, columns_f) in zip(
            by_columns, by_frame, strict=True
        ):
            assert (path, static) == (path_f, static_f)
            assert columns.keys() == columns_f.keys()
            for name in columns:  # NaN (a quantity the run has not) equal to NaN
                if name in ("SeriesLines:names", "sim_time"):
                    assert columns[name] == columns_f[name]
                else:
                    np.testing.assert_array_equal(
                        np.array(columns[name], dtype=float), np.array(columns_f[name], dtype=float)
                    )
    assert logged(result.columns, "another run") == logged(result.series, "another run") == []
    assert logged(dict(result.columns, t=np.zeros(0)), spec.run_id) == []

    class FrameSink:
        def log_run(self, spec, equations, problem, trajectory, series):
            self.series = series

    frame_sink = FrameSink()
    kept = execute_run(spec, sink=frame_sink)
    assert isinstance(frame_sink.series, pd.DataFrame) and kept.series is frame_sink.series


def test_the_recordings_stride_is_the_sorted_distinct_rows_it_was():
    """Poses of a run longer than ``max_frames`` are strided without ``np.unique``: the
    rounded evenly spaced rows are distinct and increasing whenever n > max_frames."""
    for n in range(3, 400):
        for most in (2, 3, 7, 50, 200, n - 1):
            if not 2 <= most < n:
                continue
            rows = np.linspace(0, n - 1, most).round().astype(int)
            np.testing.assert_array_equal(rows, np.unique(rows))
            assert len(rows) == most


def test_a_sink_asks_run_parts_once_a_run(monkeypatch):
    """A batch's sink asks ``fits`` and then logs the same spec: the run's path parts are
    computed once for it, again for another spec."""
    from workbench.outputs import recording as recording_module

    calls = []
    original = recording_module.run_parts
    monkeypatch.setattr(recording_module, "run_parts", lambda s: calls.append(s) or original(s))
    sink = recording_module.RerunSink()
    first = RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-5, 1e-7)
    second = RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-6, 1e-8)
    assert sink.fits(first)
    assert sink._run_parts(first) == original(first)
    assert calls == [first]
    assert sink._run_parts(second) == original(second)
    assert calls == [first, second]


def test_a_rows_json_text_by_the_c_encoder_is_what_the_python_pass_gave():
    """A flat row of text keys is encoded without the pass that made its values plain
    (``_jsonable``), to the same text: real rows (ok, skipped) and NumPy scalars of every
    kind, inf and NaN; nested or indented data take the pass as before."""
    import json

    from workbench.files import _json_text, _jsonable

    rows = [
        execute_run(RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", 1e-5, 1e-7)).row,
        execute_run(RunSpec("four-bar", "minimal-ode", "no-such-integrator", 1e-5, 1e-7)).row,
        {"f64": np.float64(0.1), "f32": np.float32(0.1), "i64": np.int64(-3), "u8": np.uint8(7),
         "b": np.bool_(True), "s": np.str_("text"), "inf": math.inf, "ninf": np.float64(-np.inf),
         "nan": math.nan, "none": None, "t": True, "zero_d": np.array(2.5)},
    ]  # fmt: skip
    for row in rows:
        assert _json_text(row, None) == json.dumps(_jsonable(row), allow_nan=True)
    nested = {"a": {1: np.int64(2)}, "b": [np.float64(1.5)]}
    for indent in (None, 1):
        assert _json_text(nested, indent) == json.dumps(_jsonable(nested), indent=indent)
    assert _json_text(rows[0], 1) == json.dumps(_jsonable(rows[0]), indent=1, allow_nan=True)
    with pytest.raises(TypeError):
        _json_text({"x": object()}, None)
