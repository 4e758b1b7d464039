"""``workbench.run``: one run in this process, as ``workbench run`` does in a child."""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from workbench.api.result import Result
from workbench.errors import ConfigError
from workbench.execution.execute import RunSpec, execute_run, normalized_spec
from workbench.execution.timing import DEFAULT_REPEAT_BUDGET, DEFAULT_REPEATS, Timing
from workbench.execution.worker_env import threads_as_workers
from workbench.plugin import registry
from workbench.plugin.integrator import tolerance_problem
from workbench.plugin.options import option_fields, unknown_option
from workbench.runs import store
from workbench.runs.out_lock import out_lock

# (kind, name) of the classes registered here, not by importing their module: a worker
# process that imports the module does not find them (workbench.api.sweeps runs them here)
REGISTERED_HERE: set[tuple[str, str]] = set()


def plugin_name(kind: str, plugin: str | type) -> str:
    """The registered name of ``plugin``: a name as it is, or a plugin class, which is
    registered first if it is not (so a class defined in a notebook can be run)."""
    registry.REGISTRY.discover()
    if isinstance(plugin, str):
        return plugin
    if not isinstance(plugin, type):
        raise ConfigError(f"{kind}: expected a name or a {kind} class, not {plugin!r}")
    known = registry.REGISTRY.entries[kind].get(getattr(plugin, "name", None))
    if known is None or known.plugin is not plugin:
        registry.REGISTRY.add(kind, plugin)
        REGISTERED_HERE.add((kind, plugin.name))
    return plugin.name


def route_options(classes: dict[str, type], options: dict[str, Any]) -> dict[str, dict]:
    """Options without a kind to the first plugin that declares them (formalism, then
    integrator, then problem), as ``workbench run -o NAME=VALUE`` does."""
    routed: dict[str, dict[str, Any]] = {kind: {} for kind in classes}
    for option, value in options.items():
        for kind in ("formalism", "integrator", "problem"):
            options_class = getattr(classes[kind], "Options", None)
            names = [n for n, _, _ in option_fields(options_class)] if options_class else []
            if option in names:
                routed[kind][option] = value
                break
        else:
            raise ConfigError(
                f"{option}=: {unknown_option(option, classes)}; see workbench.describe(NAME)"
            )
    return routed


@threads_as_workers()  # from the plugins' imports on: BLAS pools start as a worker's
def run(
    problem: str | type,
    formalism: str | type,
    integrator: str | type,
    rtol: float = 1e-6,
    atol: float | None = None,
    *,
    problem_options: dict[str, Any] | None = None,
    formalism_options: dict[str, Any] | None = None,
    integrator_options: dict[str, Any] | None = None,
    out: str | os.PathLike[str] | None = None,
    repeats: int = DEFAULT_REPEATS,
    repeat_budget: float = DEFAULT_REPEAT_BUDGET,
    wait: bool = False,
    **options: Any,
) -> Result:
    """Run ``problem`` with ``formalism`` and ``integrator`` at ``rtol`` and return its
    ``Result`` (row, trajectory, drift and energy, plots).

    Each of the three is a registered name or a plugin class (registered if it is not,
    so a class defined in a notebook runs as it is); ``problem`` may also be a robot
    file (``.urdf``, MJCF ``.xml``), as in ``workbench run robot.urdf``. ``atol``
    defaults to rtol * 1e-3.
    ``options``: option values by name, each given to the formalism, integrator or
    problem that declares it (``index=1``); ``*_options`` name the plugin explicitly.
    ``out``: also store the run in that results directory (as ``workbench run --out``).
    ``repeats``, ``repeat_budget``: how often the integration is timed.

    The run executes in this process, with no time limit (``workbench run`` kills its
    child at ``--time-limit``), its BLAS/OpenMP libraries held meanwhile to a sweep
    worker's threads (``WORKBENCH_THREADS``, default 1), so it is timed as a sweep times it.
    A run that fails or is skipped is returned, not raised:
    its ``row["status"]`` and ``row["message"]`` say what happened, and a RuntimeWarning
    says it too (a script sees it without printing the Result). Bad input raises
    before anything runs: ``PluginError`` for an unknown name, ``ConfigError`` for a bad
    option, tolerance or ``out``; ``OutputBusyError`` (a ConfigError) when another process
    writes into ``out``, unless ``wait``: then it waits for it.
    """
    why = tolerance_problem("rtol", rtol)  # before atol's default is computed from it
    if why:
        raise ConfigError(f"rtol: {why}")
    given = {"problem": problem_options, "formalism": formalism_options,
             "integrator": integrator_options}  # fmt: skip
    for kind, values in given.items():
        if values is not None and not isinstance(values, Mapping):
            raise ConfigError(
                f"{kind}_options: expected a dict of option values by name "
                f"(e.g. {{'index': 1}}), not {type(values).__name__} {values!r}"
            )
    out = results_directory(out)
    problem, problem_options = robot_file(problem, problem_options)
    names = {
        kind: plugin_name(kind, plugin)
        for kind, plugin in (
            ("problem", problem),
            ("formalism", formalism),
            ("integrator", integrator),
        )
    }
    getters = {
        "problem": registry.get_problem,
        "formalism": registry.get_formalism,
        "integrator": registry.get_integrator,
    }
    classes = {kind: getters[kind](name) for kind, name in names.items()}
    routed = route_options(classes, options)
    given["problem"] = problem_options  # with a robot file's own options
    for kind, values in given.items():
        routed[kind].update(values or {})
    spec = normalized_spec(
        RunSpec(
            names["problem"],
            names["formalism"],
            names["integrator"],
            rtol,
            atol if atol is not None else rtol * 1e-3,
            routed["problem"],
            routed["formalism"],
            routed["integrator"],
        )
    )
    reference_dir = None
    lock: Any = contextlib.nullcontext()
    if out is not None:
        reference_dir = results_directory(out, make=True) / "references"
        # as `workbench run --out`: one writer at a time, no link in it (checked before the run)
        lock = out_lock(out, wait=wait, command="workbench.run (Python)")
    sink = _Keep()
    with lock:
        if reference_dir is not None:
            reference_dir.mkdir(exist_ok=True)
        outcome = execute_run(spec, sink=sink, reference_dir=reference_dir,
                              timing=Timing(repeats, repeat_budget))  # fmt: skip
        if out is not None:
            outcome.row.setdefault("log", "")  # nothing captured here: '' as the schema says
            store.write_run(Path(out), outcome.row, outcome.series)
    result = Result(
        # every SCHEMA column, NaN where not measured: a skipped or failed run's row had
        # none of the metrics, so row["scd"] raised KeyError where load_results gives NaN
        store.frame_from_rows([outcome.row]).iloc[0],
        outcome.series.reset_index(drop=True),
        sink.equations,
        sink.problem,
        sink.charts,
    )
    status = outcome.row.get("status")
    if status not in ("ok", None):  # returned, not raised; said, not only in the repr
        message = outcome.row.get("message") or "no message"
        warnings.warn(f"{spec.problem} / {spec.formalism} / {spec.integrator}: {status}: "
                      f"{message}", RuntimeWarning, stacklevel=3)  # fmt: skip
    return result


def results_directory(out: Any, make: bool = False) -> Path | None:
    """``out`` as a Path (None stays None): ConfigError unless it names a folder, existing
    or to be made (not a file); ``make``: made, with its parents (ConfigError if it cannot
    be)."""
    if out is None:
        return None
    if not isinstance(out, str | os.PathLike) or not str(out):
        raise ConfigError(f"out: expected the path of a results directory, not {out!r}")
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"out: {path} is a file, not a directory; name a results directory")
    if make:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise ConfigError(
                f"out: cannot create the results directory {path} ({error.strerror or error}); "
                "name a folder you may write to"
            ) from None
    return path


def robot_file(problem: Any, options: dict[str, Any] | None) -> tuple[Any, dict | None]:
    """A robot file named where a problem is -> the robot problem and its ``file`` option."""
    from workbench.plugin.robot_problem import ROBOT_PROBLEM, robot_format, robot_problem_options

    if isinstance(problem, str | os.PathLike) and robot_format(str(problem)) is not None:
        return ROBOT_PROBLEM, robot_problem_options(problem) | (options or {})
    return problem, options


class _Keep:
    """The run's sink: keeps the equations and problem (for poses) and the charts."""

    equations = problem = charts = None

    def log_run(self, spec: Any, equations: Any, problem: Any, trajectory: Any, series: Any):
        self.equations, self.problem = equations, problem
        self.charts = getattr(trajectory, "charts", None)
