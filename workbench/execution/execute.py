"""One run: (problem, formalism + options, integrator + options, rtol, atol) -> a result row.

:func:`execute_run` goes through named stages, each timed (wall and CPU) and recorded as
a column (MuJoCo-style pipeline stages):

1. **pairing/build** — the problem's model; the formalism must support its features
   (``Formalism.unsupported``), the integrator must accept a form the formalism offers
   (``Integrator.select_form``); then the equations are built (``build_s``), or reused
   from this process's cache keyed by (problem, problem options, formalism, formalism
   options); finally ``Integrator.incompatibility`` may refuse them. A refusal makes the
   row ``skipped`` with the reason in ``message``. With the formalism option
   ``compile = "jit"`` or ``"auto"`` the seconds spent generating, compiling and loading C
   (at the first call of each function, or for "auto" once its calls repay it: usually
   in the integrate stage) are taken out of the stage they fall in and reported as
   ``compile_s``; why something was not compiled (no C compiler) is added to
   ``message``, what "auto" ran in C to ``notes``; before the initial state, "auto" is
   told the evaluations the run expects (:func:`expect_evaluations`);
2. **initial state** — :func:`~workbench.equations.initial.consistent_initial_state` (``init_s``),
   kept in the equations cache entry: like ``build_s``, ``init_s`` is the time of the
   first run of a (problem, formalism) in a worker and about 0 for the others;
3. **integrate** — ``Integrator.solve`` at the problem's output times, segment by
   segment on a better chart where the equations' coordinates degrade when they offer an
   atlas (:mod:`workbench.execution.charts`; the switches in ``notes``), repeated as the
   :class:`~workbench.execution.timing.Timing` allows (``integrate_s``: the median sample;
   min, max, CPU median, load and workers beside it, see :mod:`workbench.execution.timing`;
   ``wall_s`` and ``cpu_s`` count the median once); a failed trajectory makes the row
   ``failed`` with its message and ``t_reached``, and the metrics are still taken over
   the part that was reached;
4. **metrics** — :mod:`workbench.execution.metrics` (``metrics_s``; obtaining the reference is
   timed apart as ``reference_s``);
   The series also carries the trajectory: the states at the same samples, one column
   ``state:<name>`` each (:func:`state_arrays`; the store can leave them out);
5. **log** — if a ``sink`` is given, ``sink.log_run(spec, equations, problem, trajectory,
   series)`` (e.g. a Rerun recording): ``series`` the run's DataFrame, or its columns for a
   sink whose ``takes_series_columns`` is true. Logging is passed in, never written into
   formalisms or integrators.

An exception at any stage makes the row ``failed`` with a one-line ``message`` naming the
stage; :func:`execute_run` itself does not raise for a failing plugin.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import gc
import hashlib
import json
import math
import sys
import time
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.equations import compiled
from workbench.errors import one_line, one_line_text
from workbench.execution import metrics as metrics_module
from workbench.execution.charts import integrate_on_charts, switch_note
from workbench.execution.counted_work import counted_work
from workbench.execution.environment import environment
from workbench.execution.producer import producer_columns
from workbench.execution.references import problem_reference
from workbench.execution.row_check import STATUSES
from workbench.execution.row_schema import SCHEMA_VERSION, STATE_PREFIX, empty_series
from workbench.execution.run_progress import PROGRESS
from workbench.execution.timing import Samples, Timing, integrate_repeated, machine_load
from workbench.execution.worker_env import threads_in_force, worker_threads
from workbench.plugin import registry


def canonical_json(value: Any) -> str:
    """JSON with sorted keys and no spaces: the same value always gives the same text."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=True)


@dataclass(frozen=True)
class RunSpec:
    """What to run. Options are plain dicts of option name -> value (JSON-able)."""

    problem: str
    formalism: str
    integrator: str
    rtol: float
    atol: float
    problem_options: dict[str, Any] = field(default_factory=dict)
    formalism_options: dict[str, Any] = field(default_factory=dict)
    integrator_options: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain data (what ``dataclasses.asdict`` gives: options copied
        deeply, so the dict shares nothing with the spec), tolerances as floats; made
        field by field (asdict's recursion was half a tiny run's cost in the parent)."""
        return {
            "problem": self.problem,
            "formalism": self.formalism,
            "integrator": self.integrator,
            "rtol": float(self.rtol),
            "atol": float(self.atol),
            "problem_options": _copied(self.problem_options),
            "formalism_options": _copied(self.formalism_options),
            "integrator_options": _copied(self.integrator_options),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunSpec:
        return cls(**{k: data[k] for k in cls.__dataclass_fields__ if k in data})

    @functools.cached_property
    def run_id(self) -> str:
        """Stable short id: the first 16 hex digits of sha256 of the canonical JSON
        (computed once a spec: a run asked for it 8 times, 0.4 ms of a tiny run's 10)."""
        return hashlib.sha256(canonical_json(self.to_dict()).encode()).hexdigest()[:16]

    def label(self) -> str:
        def opts(options: dict[str, Any]) -> str:
            return (
                "(" + ",".join(f"{k}={v}" for k, v in sorted(options.items())) + ")"
                if options
                else ""
            )

        return (
            f"{self.problem}{opts(self.problem_options)} / "
            f"{self.formalism}{opts(self.formalism_options)} / "
            f"{self.integrator}{opts(self.integrator_options)} @ rtol {self.rtol:g}"
        )


def _copied(options: dict[str, Any]) -> dict[str, Any]:
    """``options`` copied as ``dataclasses.asdict`` copies a field's dict (deeply)."""
    return copy.deepcopy(options) if options else {}


class RunResult:
    """A result row (see :data:`workbench.execution.row_schema.SCHEMA`) and the run's time
    series: ``series`` a DataFrame; for a run with metrics made from ``columns`` (name -> n
    values, ``run_id`` one text: :func:`~workbench.execution.metrics.metric_columns`) when
    first asked for. A sweep's worker writes the columns (:func:`workbench.runs.store.write_run`
    takes either) and never makes the frame: pandas' frame, made and taken apart again for
    the series file and the recording, was a fifth of a tiny run's time outside its
    integration (docs/performance.md)."""

    def __init__(
        self,
        row: dict[str, Any],
        series: pd.DataFrame | None = None,
        columns: dict[str, Any] | None = None,
    ) -> None:
        self.row = row
        self.columns = columns
        self._series = series

    @property
    def series(self) -> pd.DataFrame:
        if self._series is None:
            self._series = metrics_module.series_frame(self.columns or {})
        return self._series

    @property
    def stored_series(self) -> pd.DataFrame | dict[str, Any]:
        """What :func:`workbench.runs.store.write_run` writes: the columns when the series
        was made as columns, else the frame."""
        return self.columns if self.columns is not None else self.series


def normalized_spec(spec: RunSpec) -> RunSpec:
    """``spec`` with every option table completed with defaults (checked: ConfigError).

    Two specs that mean the same run then have the same id.
    """
    from workbench.files import usable_cache_dir
    from workbench.plugin.integrator import check_tolerances
    from workbench.plugin.options import options_dict

    check_tolerances(spec.rtol, spec.atol)
    usable_cache_dir()  # before the run, not as its failure
    problem = registry.get_problem(spec.problem)(spec.problem_options)
    from workbench.plugin.robot_problem import check_robot_file, run_problem_names

    check_robot_file(problem)  # a robot's file and q0 now, not as the run's failure
    problem_options = options_dict(problem.options)
    formalism_options = options_dict(
        registry.get_formalism(spec.formalism).parse_options(spec.formalism_options)
    )
    integrator_class = registry.get_integrator(spec.integrator)
    parsed = integrator_class.parse_options(spec.integrator_options)
    integrator_class.check_step_count(parsed, problem_span(problem))
    integrator_options = options_dict(parsed)
    return RunSpec(
        run_problem_names([(spec.problem, problem_options)])[0],
        spec.formalism,
        spec.integrator,
        float(spec.rtol),
        float(spec.atol),
        problem_options,
        formalism_options,
        integrator_options,
    )


def expect_evaluations(equations: Any, problem: Any, rtol: float) -> None:
    """Tell compile=auto how many evaluations this run expects (from span and rtol)."""
    from workbench.equations.compile_policy import expected_evaluations

    compiler = getattr(equations, "compiler", None)
    if compiler is not None:
        compiler.expect(expected_evaluations(problem_span(problem), rtol))


def problem_span(problem: Any) -> float:
    """The length in seconds of a problem's time span (its output times')."""
    try:
        return abs(float(problem.t_end) - float(problem.t_start))
    except (AttributeError, TypeError, ValueError):
        return 0.0


# ---- equations cache (one per worker process) ---------------------------------------

# A sweep lists the runs of one (problem, formalism) together (integrators x tolerances),
# so a few entries keep nearly every hit; unbounded, a worker of the default sweep held
# every model it had seen (hundreds of MB of CasADi graphs and built Jacobians). A
# worker takes the runs of the equations it built last first (runs.local_pool._take_next):
# two entries keep the hits, and an evicted entry's memory goes back to the system
# (quick suite, load 4-5: the larger worker 266 -> 219 MiB PSS, the runs phase 540 -> 468 MiB).
EQUATIONS_CACHE_SIZE = 2


@dataclass
class _Cached:
    """A cache entry: the built equations and, once computed, the consistent initial
    state (it depends on the problem and the equations, not on integrator or tolerance)."""

    equations: Any
    initial: Any = None


_EQUATIONS: OrderedDict[tuple[str, str, str, str], _Cached] = OrderedDict()


# What depends on the problem and its options only, not on formalism or integrator: its
# model (checked at every run's pairing; a URDF problem parses its file to make it) and
# its reference (the stored one is checked against a fingerprint of the model). The runs
# of a problem follow one another in a sweep, so a few entries keep the hits.
_PROBLEMS: OrderedDict[tuple[str, str], dict[str, Any]] = OrderedDict()


def clear_cache() -> None:
    _EQUATIONS.clear()
    _PROBLEMS.clear()


def cached_problem_part(spec: RunSpec, part: str, make: Any) -> tuple[Any, bool]:
    """(``make()``, reused?) for ``part`` of the spec's problem (+ options), made once a
    worker process."""
    key = (spec.problem, canonical_json(spec.problem_options))
    entry = _PROBLEMS.setdefault(key, {})
    _PROBLEMS.move_to_end(key)
    if len(_PROBLEMS) > EQUATIONS_CACHE_SIZE:
        while len(_PROBLEMS) > EQUATIONS_CACHE_SIZE:
            _PROBLEMS.popitem(last=False)  # the least recently used
        _after_eviction()
    if part in entry:
        return entry[part], True
    modules = len(sys.modules)
    entry[part] = value = make()
    if len(sys.modules) - modules >= FREEZE_AFTER_MODULES and gc.get_freeze_count():
        _freeze_new_modules(key)  # in a worker, which froze its start-up's
    return value, False


FREEZE_AFTER_MODULES = 50
"""A problem part whose making imported this many modules (a robot's: yourdfpy, trimesh and
networkx, about 500 modules and 30,000 objects) has them frozen: else each later cache
eviction's collection visits them (16-26 ms a collection against 1-2 ms; Zen 3,
2026-11-29). Only in a process that froze its start-up's objects (a sweep's worker): a
notebook's objects are never frozen."""


def _freeze_new_modules(key: tuple[str, str]) -> None:
    """What a problem's making imported kept out of the collector's full passes, as a worker
    does with its start-up's (:func:`freeze_loaded_objects`). The other problems' entries and
    the equations are dropped first: frozen, an evicted entry's reference cycles (its
    evaluators') would never be collected; this problem's model stays."""
    for other in [k for k in _PROBLEMS if k != key]:
        del _PROBLEMS[other]
    _EQUATIONS.clear()
    release_freed_memory()
    gc.freeze()


def equations_key(spec: RunSpec) -> tuple[str, str, str, str]:
    """What the equations (and the initial state) of a run depend on."""
    return (
        spec.problem,
        canonical_json(spec.problem_options),
        spec.formalism,
        canonical_json(spec.formalism_options),
    )


def cached_equations(spec: RunSpec, model: Any) -> tuple[Any, bool]:
    """(equations, reused?) for the spec's problem and formalism (+ options)."""
    key = equations_key(spec)
    if key in _EQUATIONS:
        _EQUATIONS.move_to_end(key)
        return _EQUATIONS[key].equations, True
    formalism = registry.get_formalism(spec.formalism)()
    equations = formalism.build(model, spec.formalism_options)
    _EQUATIONS[key] = _Cached(equations)
    if len(_EQUATIONS) > EQUATIONS_CACHE_SIZE:
        while len(_EQUATIONS) > EQUATIONS_CACHE_SIZE:
            _EQUATIONS.popitem(last=False)  # the least recently used
        _after_eviction()
    return equations, False


@contextlib.contextmanager
def equations_held(count: int) -> Iterator[None]:
    """Meanwhile the caches hold ``count`` equations and problems at least: a process
    that cycles through a few models again and again (:mod:`workbench.runs.retime`)
    builds each once."""
    global EQUATIONS_CACHE_SIZE
    before = EQUATIONS_CACHE_SIZE
    EQUATIONS_CACHE_SIZE = max(before, count)
    try:
        yield
    finally:
        EQUATIONS_CACHE_SIZE = before


def _after_eviction() -> None:
    """A sweep's worker (one that froze its start-up, :func:`freeze_loaded_objects`) hands
    an evicted entry's memory back at once (:func:`release_freed_memory`); any other
    process (a notebook, a test) leaves it to Python's own collector: a full collection
    there visits everything its user holds (0.1-0.3 s in a test process, at each eviction:
    2.5 % of the test suite's CPU)."""
    if gc.get_freeze_count():
        release_freed_memory()


def release_freed_memory() -> None:
    """Hand the heap's free pages back to the system (glibc's ``malloc_trim``; elsewhere
    nothing): freed CasADi graphs otherwise stay in the worker's resident memory."""
    import ctypes

    gc.collect()
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


def freeze_loaded_objects() -> None:
    """Exempt what this process holds now (imported modules, discovered plugins, a
    recorder's library) from every later garbage collection (``gc.freeze``): a worker
    calls it once it is ready, before its first run. Each eviction from the caches above
    collects garbage (:func:`release_freed_memory`), and a full collection visits every
    tracked object: 31,000 in a worker of the full sweep that had loaded Rerun, 18-25 ms
    a collection; frozen, the few thousand a run's caches hold. Objects made later (the
    equations, references) are collected as before."""
    gc.collect()
    gc.freeze()


def cached_initial_state(spec: RunSpec, equations: Any, problem: Any) -> Any:
    """The consistent initial state of ``problem`` in ``equations``' coordinates, computed
    once per cache entry (Newton iterations are not the integrator's cost)."""
    from workbench.equations.initial import consistent_initial_state

    entry = _EQUATIONS.get(equations_key(spec))
    if entry is None or entry.equations is not equations:
        return consistent_initial_state(equations, problem)
    if entry.initial is None:
        entry.initial = consistent_initial_state(equations, problem)
    return entry.initial


# ---- the run -------------------------------------------------------------------------


class _Stages:
    """Wall and CPU time of named stages; ``current`` names the stage for error messages."""

    def __init__(self) -> None:
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {}
        self.current = "pairing"
        self.running = False

    def start(self, name: str) -> None:
        self.current, self.running = name, True
        PROGRESS.enter(name)
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        self._compile = compiled.STATS.seconds
        self._compile_cpu = compiled.STATS.cpu_seconds

    def timed(self, solve: Any) -> tuple[Any, float, float]:
        """(solve(), wall s, CPU s) of one sample of the integrate stage, C compilation
        taken out (into ``compile``)."""
        sample = _Stages()
        sample.start("integrate")
        try:
            result = solve()
        finally:  # an integrator that raises: its time is still the stage's
            sample.stop()
            for name in ("integrate", "compile"):
                self.wall[name] = self.wall.get(name, 0.0) + sample.wall.get(name, 0.0)
                self.cpu[name] = self.cpu.get(name, 0.0) + sample.cpu.get(name, 0.0)
        return result, sample.wall["integrate"], sample.cpu["integrate"]

    def stop(self) -> None:
        if not self.running:
            return
        self.running = False
        self.wall[self.current] = self.wall.get(self.current, 0.0) + (
            time.perf_counter() - self._wall
        )
        self.cpu[self.current] = self.cpu.get(self.current, 0.0) + (time.process_time() - self._cpu)
        compile_s = compiled.STATS.seconds - self._compile  # C compilation in this stage
        if compile_s > 0:  # CPU: this process's (the C compiler is a child process)
            compile_cpu = compiled.STATS.cpu_seconds - self._compile_cpu
            self.wall[self.current] -= compile_s
            self.cpu[self.current] = max(0.0, self.cpu[self.current] - compile_cpu)
            self.wall["compile"] = self.wall.get("compile", 0.0) + compile_s
            self.cpu["compile"] = self.cpu.get("compile", 0.0) + compile_cpu


def base_row(spec: RunSpec) -> dict[str, Any]:
    """The key columns of a row (options as canonical JSON text) and its schema version:
    every row, finished or not, starts here."""
    return {
        "schema_version": SCHEMA_VERSION,
        "run_id": spec.run_id,
        "problem": spec.problem,
        "problem_options": canonical_json(spec.problem_options),
        "formalism": spec.formalism,
        "formalism_options": canonical_json(spec.formalism_options),
        "integrator": spec.integrator,
        "integrator_options": canonical_json(spec.integrator_options),
        "rtol": float(spec.rtol),
        "atol": float(spec.atol),
        "retimed": 0,
    }


def status_row(spec: RunSpec, status: str, message: str, **extra: Any) -> dict[str, Any]:
    """A row without metrics (skipped, timeout, a worker that died). Its ``threads`` is the
    count every worker is pinned to (``worker_threads``), not the writing process's."""
    row = base_row(spec) | {"status": status, "message": one_line_text(message), "n_samples": 0}
    row.update(environment())
    row["threads"] = worker_threads()
    row.update(extra)
    row.update(producer_columns(spec.problem, spec.formalism, spec.integrator))
    return row


def execute_run(
    spec: RunSpec,
    sink: Any = None,
    reference_dir: Path | str | None = None,
    timing: Timing | None = None,
    measure: bool = True,
) -> RunResult:
    """Run ``spec`` through the stages of the module docstring; never raises for a plugin.

    ``reference_dir``: where computed references are cached on disk (usually
    ``<out>/references``); None keeps them in memory only. ``timing``: how often the
    integration is timed (:class:`~workbench.execution.timing.Timing`; default its defaults).
    ``measure`` False: stop after the integration, the row holding its status, counts and
    timing only (another sample of a done run's cost: :mod:`workbench.runs.retime`).
    """
    timing = timing or Timing()
    PROGRESS.begin_run()
    load_avg = machine_load()
    stages = _Stages()
    row = base_row(spec)
    row.update(
        {"status": "ok", "message": "", "stage": "", "equations_cached": False, "reference_s": 0.0}
    )
    series = columns = None  # (an empty frame made only for a run without metrics)
    state: dict[str, Any] = {}
    try:
        stages.start("pairing")
        problem = registry.get_problem(spec.problem)(spec.problem_options)
        formalism_class = registry.get_formalism(spec.formalism)
        integrator = registry.get_integrator(spec.integrator)()
        formalism_options = formalism_class.parse_options(spec.formalism_options)
        integrator_options = integrator.parse_options(spec.integrator_options)
        missing = problem.unavailable()  # files of an extra that is not installed
        if missing:
            skip = f"problem {spec.problem!r}: {missing}"
        else:
            model, _ = cached_problem_part(spec, "model", problem.model)
            skip = _pairing(spec, model, formalism_class, formalism_options, integrator)
        stages.stop()
        if skip:
            row.update(status="skipped", message=skip)
        else:
            stages.start("build")
            equations, reused = cached_equations(spec, model)
            state["equations"] = equations
            row["equations_cached"] = reused
            stages.stop()
            # pair on the forms actually built: a model without constraints has an ode
            # form at every index, which forms(options) cannot know
            offered = {name: getattr(f, "index", 0) for name, f in equations.forms.items()}
            form = integrator.select_form(offered)
            reason = (
                _form_mismatch(spec, integrator, offered)
                if form is None
                else integrator.contact_mismatch(equations)
                or integrator.incompatibility(equations, integrator_options)
            )
            if reason:
                row.update(status="skipped", message=f"integrator {spec.integrator!r}: {reason}")
            else:
                row["form"] = form
                stages.start("initial state")
                expect_evaluations(equations, problem, spec.rtol)
                initial = cached_initial_state(spec, equations, problem)
                y0, yp0 = initial.y0(equations, form), initial.yp0(equations, form)
                stages.stop()
                compiler = getattr(equations, "compiler", None)
                if hasattr(compiler, "count_calls_from_now"):  # notes: this run's calls
                    compiler.count_calls_from_now()
                solve_note = getattr(initial, "acceleration_solve", "")
                if solve_note.startswith("least squares"):  # a rank-deficient system
                    state["notes"] = f"initial accelerations by {solve_note}"

                stages.current = "integrate"
                times = problem.sample_times()
                PROGRESS.watch_times(equations, form, times[-1])

                def solve() -> Any:
                    if getattr(equations, "atlas", None) is not None:
                        return integrate_on_charts(
                            integrator, equations, y0, yp0, times, spec.rtol, spec.atol,
                            integrator_options, form,
                        )  # fmt: skip
                    return integrator.solve(
                        equations, y0, yp0, times, spec.rtol, spec.atol, integrator_options, form
                    )

                trajectory, samples = integrate_repeated(solve, timing, stages.timed)
                state["samples"] = samples
                state["trajectory"] = trajectory
                _record_trajectory(row, trajectory)
                if not measure:
                    return RunResult(row | samples.columns())

                stages.start("metrics")
                row.update(counted_work(equations, form, row))
                PROGRESS.enter("reference")
                reference = _reference(spec, problem, times, reference_dir)
                PROGRESS.enter("metrics")
                row["reference_s"] = reference.seconds
                sample_times = np.asarray(trajectory.times)
                states = np.atleast_2d(trajectory.y)[: len(sample_times)]
                metric_row, columns = metrics_module.metric_columns(
                    spec.run_id,
                    problem,
                    equations,
                    sample_times,
                    np.atleast_2d(trajectory.y),
                    trajectory.success,
                    reference,
                    spec.rtol,
                    charts=getattr(trajectory, "charts", None),
                    contact=getattr(trajectory, "contact", None),
                    # the trajectory in the same frame (when it has a state a sample)
                    states=state_arrays(equations, form, states)
                    if len(states) == len(sample_times)
                    else None,
                )
                row.update(metric_row)
                atlas = getattr(equations, "atlas", None)
                switched = switch_note(atlas, trajectory) if atlas is not None else ""
                own_reference = (
                    f"the reference was computed with this formalism ({spec.formalism}): "
                    "the error measures its integration, not its equations (the other "
                    "formalisms' agreement with the reference checks those)"
                    if reference.formalism == spec.formalism
                    else ""
                )
                row["notes"] = "; ".join(
                    filter(None, [row.get("notes", ""), state.get("notes", ""), switched,
                                  own_reference])
                )  # fmt: skip
                own = "; ".join(getattr(trajectory, "warnings", None) or [])
                if own:  # the integrator's own (e.g. the accuracy asked was not attempted)
                    found = "; ".join(filter(None, [row.get("warnings", ""), own]))
                    row["warnings"] = one_line_text(found)
                if samples.difference:  # the samples did not time the same work
                    found = "; ".join(
                        filter(
                            None,
                            [row.get("warnings", ""), f"not reproducible: {samples.difference}"],
                        )
                    )
                    row["warnings"] = one_line_text(found)  # fmt: skip
                stages.stop()
                stages.wall["metrics"] = max(0.0, stages.wall["metrics"] - reference.seconds)

                if sink is not None:
                    stages.start("log")
                    # a sink that reads the series' columns (takes_series_columns) is given
                    # them; any other the DataFrame, as the sink's contract says
                    if getattr(sink, "takes_series_columns", False):
                        logged_series = columns
                    else:
                        logged_series = series = metrics_module.series_frame(columns)
                    sink.log_run(spec, equations, problem, trajectory, logged_series)
                    logged = getattr(sink, "run_warnings", [])  # e.g. a mesh it could not draw
                    if logged:
                        found = "; ".join(filter(None, [row.get("warnings", ""), *logged]))
                        row["warnings"] = one_line_text(found)
                    stages.stop()
    except Exception as error:  # noqa: BLE001 - a failing plugin is a result, not a crash
        stages.stop()
        said = f"{stages.current}: {one_line(error)}"
        if row.get("status") == "failed" and row.get("stage") == "integrate":
            # the integration's own failure first: the metrics of the part reached failed
            # after it (it was replaced by theirs, the run's cause lost)
            row["message"] = f"{row['message']}; then {said}"
        else:
            row.update(status="failed", stage=stages.current, message=said)
    compile_warnings = getattr(state.get("equations"), "compile_warnings", [])
    if compile_warnings:
        row["message"] = " | ".join(filter(None, [row["message"], *compile_warnings]))
        if spec.formalism_options.get("compile") == "jit" and row["status"] == "ok":
            # measured in the VM under a jit label: not a compiled run to recommend
            found = f"not compiled: {compile_warnings[0]} (its cost is the VM's)"
            row["warnings"] = one_line_text("; ".join(filter(None, [row["warnings"], found])))
    compiler = getattr(state.get("equations"), "compiler", None)
    if compiler is not None and compiler.summary() and row.get("status") != "skipped":
        row["notes"] = "; ".join(filter(None, [row.get("notes", ""), compiler.summary()]))
    row["build_s"] = stages.wall.get("build", 0.0)
    row["compile_s"] = stages.wall.get("compile", 0.0)
    row["init_s"] = stages.wall.get("initial state", 0.0)
    if "samples" not in state and "integrate" in stages.wall:  # the integrator raised
        state["samples"] = Samples([stages.wall["integrate"]], [stages.cpu["integrate"]])
    row.update(state.get("samples", Samples([], [])).columns())
    row["load_avg"], row["workers"] = load_avg, timing.workers
    row["metrics_s"] = stages.wall.get("metrics", 0.0)
    row["log_s"] = stages.wall.get("log", 0.0)
    main_stages = ("pairing", "build", "compile", "initial state", "integrate", "metrics")
    wall, cpu = dict(stages.wall), dict(stages.cpu)
    if math.isfinite(row["integrate_s"]):  # one integration (the median), not every repeat
        wall["integrate"], cpu["integrate"] = row["integrate_s"], row["integrate_cpu_s"]
    row["wall_s"] = sum(wall.get(s, 0.0) for s in main_stages)
    row["cpu_s"] = sum(cpu.get(s, 0.0) for s in main_stages)
    row.update(environment())
    row.update(producer_columns(spec.problem, spec.formalism, spec.integrator))
    if series is None and columns is None:
        series = empty_series(spec.run_id)
    row["n_samples"] = len(series) if series is not None else len(columns["t"])
    row["threads"] = threads_in_force()
    # skip reasons, integrator and plugin messages, compile warnings: the row's is one line
    row["message"] = one_line_text(row["message"])
    return RunResult(row, series, columns)


def _reference(spec: RunSpec, problem: Any, times: Any, reference_dir: Any) -> Any:
    """The problem's reference poses at ``times``, obtained once a worker per problem,
    options and reference directory (``reference_s`` 0 when reused); a missing one
    ('none') is asked for again at the next run."""
    directory = Path(reference_dir) if reference_dir is not None else None
    key, part = (spec.problem, canonical_json(spec.problem_options)), f"reference in {directory}"
    cached = _PROBLEMS.get(key, {}).get(part)
    if cached is not None and len(cached.poses) == len(times):
        return replace(cached, seconds=0.0)
    reference = problem_reference(problem, spec.problem, spec.problem_options, times, directory)
    if reference.kind != "none" and reference.poses is not None:
        _PROBLEMS.setdefault(key, {})[part] = reference
    return reference


def _pairing(
    spec: RunSpec, model: Any, formalism_class: type, formalism_options: Any, integrator: Any
) -> str | None:
    """Why this formalism and integrator cannot run this model, or None."""
    from workbench.plugin.formalism import FEATURES

    missing = formalism_class.unsupported(model)
    if missing:
        names = ", ".join(FEATURES.get(f, f) for f in sorted(missing))
        return f"formalism {spec.formalism!r} does not support {names} (model {model.name!r})"
    return None


def _form_mismatch(spec: RunSpec, integrator: Any, offered: dict[str, int]) -> str:
    accepts = ", ".join(f"{k} (index <= {v})" for k, v in integrator.accepts.items())
    offers = ", ".join(f"{k} (index {v})" for k, v in offered.items())
    message = f"accepts {{{accepts}}}; formalism {spec.formalism} offers {{{offers}}}"
    return message + _index_hint(spec, integrator.accepts)


def _index_hint(spec: RunSpec, accepts: dict[str, int]) -> str:
    """How to pair them when the formalism has an ``index`` option (its dae form's index;
    index 1 also gives the ode form): the highest index the integrator accepts."""
    formalism = registry.get_formalism(spec.formalism)
    fields = getattr(getattr(formalism, "Options", None), "__dataclass_fields__", {})
    if "index" not in fields:
        return ""
    wanted = [min(int(accepts["dae"]), 3)] if accepts.get("dae", 0) >= 1 else []
    wanted += [1] if "ode" in accepts else []
    wanted = [i for i in wanted if i != spec.formalism_options.get("index")]
    if not wanted:
        return ""
    index = max(wanted)
    in_sweep = f'{{ name = "{spec.formalism}", options = {{ index = {index} }} }}'
    return (
        f"; pair them with the formalism option index={index} (workbench run: -o index={index};"
        f" a sweep: formalisms = [{in_sweep}])"
    )


def state_names(equations: Any, form: str, width: int) -> list[str]:
    """Names of the ``width`` state components of a trajectory in ``form``: the equations'
    q and v names, then ``lambda:<constraint>`` (and ``mu:<constraint>``) for the
    multipliers a dae or mechanical form carries; ``y[k]`` for any the equations do not
    name."""
    names = equations.y_names("dae" if form == "dae" else "ode")
    extra = [f"lambda:{n}" for n in equations.constraint_names]
    extra += [f"mu:{n}" for n in equations.constraint_names[: equations.n_holonomic]]
    names = list(names) + [n for n in extra if n not in names]
    names = names[:width] + [f"y[{k}]" for k in range(len(names), width)]
    return names


def state_arrays(equations: Any, form: str, y: np.ndarray) -> dict[str, np.ndarray]:
    """The trajectory's states ``y`` (n, width) as series columns ``state:<name>``
    (column name -> values), for the series' one frame."""
    y = np.asarray(y, dtype=float)
    names = state_names(equations, form, y.shape[1] if y.size else 0)
    return {STATE_PREFIX + name: y[:, k] for k, name in enumerate(names)}


def _record_trajectory(row: dict[str, Any], trajectory: Any) -> None:
    stats = trajectory.stats
    row.update(
        {
            "t_reached": float(trajectory.t_reached),
            "n_rhs": int(stats.n_rhs),
            "n_jac": int(stats.n_jac),
            "n_steps": int(stats.n_steps),
            "n_rejected": int(stats.n_rejected),
            "n_lu": int(stats.n_lu),
            "n_newton": int(stats.n_newton),
            "fixed_step_s": float(stats.fixed_step),
        }
    )
    if not trajectory.success:
        message = trajectory.message or "the integration failed"
        row.update(
            status="failed",
            stage="integrate",
            message=f"integrate: {message} (t reached {trajectory.t_reached:g})",
        )


def format_row(row: dict[str, Any]) -> list[tuple[str, str]]:
    """(name, value) pairs of a row for printing (key columns and metrics)."""
    shown = []
    for key, value in row.items():
        if isinstance(value, float):
            text = "nan" if math.isnan(value) else f"{value:.4g}"
        else:
            text = str(value)
        shown.append((key, text))
    return shown


__all__ = [
    "RunResult",
    "RunSpec",
    "STATUSES",
    "canonical_json",
    "execute_run",
    "normalized_spec",
    "status_row",
]
