"""A sweep specification: problems x formalisms x integrators (option grids) x tolerances.

A sweep specification is a TOML file, or the name of a suite shipped with the workbench in
``workbench/runs/suites/NAME.toml`` (``quick``, the default sweep: a first look in about a
minute; ``full``, the full comparison; ``iftomm``, the IFToMM benchmark problems; ``ivp``,
the IVP test set's; ``nonsmooth``, the contact integrators; :func:`suite_names` lists
them)::

    out = "reports/latest"         # output directory (``--out`` overrides)
    jobs = 2                       # local worker processes (``--jobs`` overrides)
    time_limit = 120.0             # seconds per run; a run over it is killed (``--time-limit``)
    repeats = 3                    # most timed samples of each integration (``--repeats``)
    repeat_budget = 3.0            # CPU s of integration for them (``--repeat-budget``)
    retime = 5                     # close calls timed again after the runs (``--retime``)
    tolerances = [1e-4, 1e-6, 1e-8]  # rtol values
    atol_factor = 1e-3             # atol = rtol * atol_factor
    missing_plugins = "error"      # or "skip": leave out plugin names that are not registered
    plugins = ["my_package.my_plugins", "helper.py"]  # extra plugin modules (code: see below)
    store_trajectories = true      # the states at the output samples beside the series

    problems = ["my-problem", { name = "my-top", options = { spin = [50.0, 100.0] } }]
    formalisms = ["all", { name = "my-formalism", options = { index = [1, 3] } }]
    integrators = ["my-implicit", { name = "my-fixed-step", options = { step = 1e-3 } },
                   { name = "my-slow-one", tolerances = [1e-4] }]  # its own rtol values

Each of ``problems``, ``formalisms``, ``integrators`` is a list of names, of tables
``{name, options}``, or ``"all"`` (every registered, working plugin of that kind with its
default options, except the ones named explicitly in the same list). A table
``{ name = "all", options = {...} }`` is "all" with options given to every plugin that has
them (the others keep their defaults), e.g. ``{ name = "all", options = { index = 1 } }``
for every formalism with a DAE index; an option that no registered plugin has is an error.
New plugins so join a sweep without editing it. In an options table a
list is a grid: the runs take the cartesian product of all listed values (to pass a list
as one value, wrap it in another list). The runs are every problem x formalism x
integrator x tolerance; pairs that cannot work are recorded as ``skipped`` with the reason.
An integrator entry (a table, ``"all"`` included) may list its own ``tolerances``, which
replace the sweep's for it: so a costly integrator can join a sweep at the tolerances
where it is affordable.

``plugins`` is a feature for plugin authors: modules (installed, or a module or ``.py``
file in the current directory or beside the specification) whose registration decorators
add plugins for this sweep only, without packaging them with entry points. They are code:
they are imported only after everything else in the specification that needs no plugin
is valid, a local one from its file (said on stderr), and ``--no-local-plugins`` /
``WORKBENCH_NO_LOCAL_PLUGINS=1`` refuses them (:mod:`workbench.plugin.local_modules`).

Everything is validated before anything is written (:func:`load_spec`): unknown keys,
wrong types, unknown plugins (with close matches), unknown or ill-typed options, tolerances
that are not positive, empty grids, duplicates (a value repeated in a grid or in
``tolerances``, a plugin listed twice with the same options), grids larger than
``MAX_RUNS``, tables nested deeper than ``MAX_DEPTH`` and TOML syntax errors (with the line;
also integers too long to read) raise one :class:`~workbench.errors.ConfigError` naming the
key. Validation never expands a grid before it has counted it, so it stays fast.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import re
import reprlib
import sys
import tomllib
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from workbench.errors import ConfigError, PluginError, one_line
from workbench.execution.execute import RunSpec, problem_span
from workbench.execution.timing import (
    DEFAULT_REPEAT_BUDGET,
    DEFAULT_REPEATS,
    DEFAULT_RETIME,
    budget_problem,
    repeats_problem,
    retime_problem,
)
from workbench.plugin import registry
from workbench.plugin.integrator import tolerance_problem
from workbench.plugin.local_modules import (
    find_plugin_modules,
    import_plugin_modules,
    stderr_line,
)
from workbench.plugin.registry import Kind

DEFAULT_OUT = "reports/latest"


DEFAULT_TIME_LIMIT = 120.0  # s


DEFAULT_ATOL_FACTOR = 1e-3


DEFAULT_JOBS = 2


MAX_JOBS = 1024


MAX_RUNS = 100_000
"""The most runs a specification may expand to (counted before anything is expanded)."""


MAX_DEPTH = 16
"""The deepest nesting of tables and lists a specification may have (options included)."""


TOP_LEVEL_KEYS = {
    "out": "output directory (string)",
    "jobs": "number of local worker processes (integer >= 1)",
    "time_limit": "seconds per run (number > 0)",
    "repeats": "most timed samples of each run's integration (integer >= 1)",
    "repeat_budget": "CPU seconds of integration a run may spend on repeated samples (number >= 0)",
    "retime": "times each close call is timed again after the runs, at moments apart "
    "(integer from 0 to 100)",
    "tolerances": "list of rtol values (numbers > 0)",
    "atol_factor": "atol = rtol * atol_factor (number > 0)",
    "missing_plugins": '"error" or "skip"',
    "plugins": "list of plugin module names or .py files to import",
    "store_trajectories": "store each run's states at its output samples (true or false)",
    "problems": 'list of problem names or {name, options} tables, or "all"',
    "formalisms": 'list of formalism names or {name, options} tables, or "all"',
    "integrators": 'list of integrator names or {name, options} tables, or "all"',
}


REQUIRED_KEYS = ("problems", "formalisms", "integrators", "tolerances")


KIND_KEYS: tuple[tuple[Kind, str], ...] = (
    ("problem", "problems"),
    ("formalism", "formalisms"),
    ("integrator", "integrators"),
)


@dataclass
class SweepSpec:
    """A validated sweep: the runs (normalized, unique) and how to execute them."""

    runs: list[RunSpec]
    out: Path
    jobs: int = DEFAULT_JOBS
    time_limit: float = DEFAULT_TIME_LIMIT
    # the plugin modules imported, as workers receive them (PluginModule.text())
    plugins: list[str] = field(default_factory=list)
    source: str = ""
    text: str = ""
    repeats: int = DEFAULT_REPEATS
    repeat_budget: float = DEFAULT_REPEAT_BUDGET
    retime: int = DEFAULT_RETIME  # rounds of workbench.runs.retime
    store_trajectories: bool = True  # each run's states beside its series (store.write_run)
    suite: str = ""  # the name of the shipped suite it is ('' for a file)


DEFAULT_SUITE = "quick"
"""The suite of ``workbench sweep`` without an argument: a first look in about a minute."""

FULL_SUITE = "full"
"""The full comparison (every problem and formalism; the default sweep before ``quick``)."""

RENAMED_SUITES = {"default": FULL_SUITE}


SUITE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]*")


def _suites() -> Any:
    return resources.files("workbench.runs").joinpath("suites")


def suite_names() -> list[str]:
    """The sweep suites shipped with the workbench (``workbench/runs/suites/*.toml``)."""
    return sorted(f.name[:-5] for f in _suites().iterdir() if f.name.endswith(".toml"))


def suite_text(name: str) -> str:
    """The TOML text of suite ``name``; an unknown name is a ConfigError listing the suites."""
    if SUITE_NAME.fullmatch(name) and name in suite_names():
        return _suites().joinpath(f"{name}.toml").read_text("utf-8")
    if name in RENAMED_SUITES:
        raise ConfigError(
            f"the sweep suite {name!r} is now called {RENAMED_SUITES[name]!r}: run "
            f"`workbench sweep {RENAMED_SUITES[name]}` (`workbench sweep` alone runs the "
            f"{DEFAULT_SUITE!r} suite, a first look in about a minute)"
        )
    raise ConfigError(
        f"unknown sweep suite {name!r} (and no such file): the suites are "
        f"{', '.join(suite_names())}; or give the path of a TOML specification"
    )


def default_spec_text() -> str:
    return suite_text(DEFAULT_SUITE)


def load_spec(
    path: str | os.PathLike[str] | None = None,
    plugins: Iterable[str] = (),
    allow_local: bool | None = None,
) -> SweepSpec:
    """Read and validate a sweep specification: a TOML file, or the name of a shipped suite
    (None: the default one); nothing is written. A name that is both an existing file and
    a suite is read as the file. ``plugins``: more plugin modules (``--plugins``), found
    from the current directory; ``allow_local``: see :func:`parse_spec`."""
    if path is None:
        path = DEFAULT_SUITE
    if isinstance(path, str) and SUITE_NAME.fullmatch(path) and not Path(path).exists():
        source = f"suite {path} (workbench/runs/suites/{path}.toml)"
        spec = parse_spec(suite_text(path), source, None, plugins, allow_local)
        spec.suite = path
        return spec
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ConfigError(f"cannot read the sweep specification {path}: {error}") from None
    return parse_spec(text, str(path), path.parent, plugins, allow_local)


def parse_spec(
    text: str,
    source: str = "sweep specification",
    directory: str | Path | None = None,
    extra_plugins: Iterable[str] = (),
    allow_local: bool | None = None,
    lines: bool = True,
) -> SweepSpec:
    """Validate TOML ``text`` and expand it to RunSpecs (ConfigError names the key, and
    its line unless ``lines`` is False: text the caller made, not the user's file).

    ``directory`` (the specification file's) is searched for its plugin modules too;
    ``extra_plugins`` (``--plugins``) are found from the current directory. The plugin
    modules are imported only once everything that needs no plugin is valid; a local one
    is said on stderr, and refused when ``allow_local`` is False (None: unless
    ``WORKBENCH_NO_LOCAL_PLUGINS`` is set; :mod:`workbench.plugin.local_modules`)."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ConfigError(
            f"{source}: invalid TOML: tables or arrays nested too deeply to read "
            f"(a specification needs at most {MAX_DEPTH} levels)"
        ) from None
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{source}: invalid TOML: {one_line(error, with_type=False)}") from None
    except ValueError:  # Python refuses to convert integers of more than 4300 digits
        raise ConfigError(
            f"{source}: invalid TOML: an integer has too many digits to read "
            f"(at most {sys.get_int_max_str_digits()}); no setting needs such a number"
        ) from None

    def fail(key: str, message: str) -> ConfigError:
        line = _key_line(text, key) if lines else None
        where = f"line {line}: " if line else ""
        return ConfigError(one_line(ConfigError(f"{source}: {where}{key}: {message}"), False))

    _check_depth(data, fail)

    unknown = sorted(set(data) - set(TOP_LEVEL_KEYS))
    if unknown:
        close = registry.close_matches(unknown[0], list(TOP_LEVEL_KEYS))
        hint = (
            f"did you mean {', '.join(close)}?"
            if close
            else (f"valid keys: {', '.join(TOP_LEVEL_KEYS)}")
        )
        raise fail(unknown[0], f"unknown key; {hint}")
    for key in REQUIRED_KEYS:
        if key not in data:
            raise fail(key, f"missing ({TOP_LEVEL_KEYS[key]})")

    out = data.get("out", DEFAULT_OUT)
    if not isinstance(out, str) or not out.strip():
        raise fail("out", f"must be a non-empty string, not {_show(out)}")
    jobs = data.get("jobs", DEFAULT_JOBS)
    if not _is_int(jobs) or not 1 <= jobs <= MAX_JOBS:
        raise fail("jobs", f"must be an integer from 1 to {MAX_JOBS}, not {_show(jobs)}")
    time_limit = _positive(data.get("time_limit", DEFAULT_TIME_LIMIT), "time_limit", fail)
    atol_factor = _positive(data.get("atol_factor", DEFAULT_ATOL_FACTOR), "atol_factor", fail)
    repeats = data.get("repeats", DEFAULT_REPEATS)
    repeat_budget = data.get("repeat_budget", DEFAULT_REPEAT_BUDGET)
    retime = data.get("retime", DEFAULT_RETIME)
    for key, problem in (
        ("repeats", repeats_problem(repeats)),
        ("repeat_budget", budget_problem(repeat_budget)),
        ("retime", retime_problem(retime)),
    ):
        if problem:
            raise fail(key, problem)
    missing = data.get("missing_plugins", "error")
    if missing not in ("error", "skip"):
        raise fail("missing_plugins", f'must be "error" or "skip", not {_show(missing)}')
    rtols = _tolerance_list(data["tolerances"], "tolerances", atol_factor, fail)
    plugins = data.get("plugins", [])
    if not isinstance(plugins, list) or not all(isinstance(p, str) and p for p in plugins):
        raise fail("plugins", f"must be a list of module names or .py files, not {_show(plugins)}")
    store_trajectories = data.get("store_trajectories", True)
    if not isinstance(store_trajectories, bool):
        raise fail("store_trajectories", f"must be true or false, not {_show(store_trajectories)}")

    from workbench.plugin.robot_problem import robot_entries

    base = Path(source).parent if Path(source).is_file() else Path.cwd()
    data["problems"] = robot_entries(data["problems"], base, fail)  # { urdf = PATH } entries
    # the plugin modules are code: everything that needs none is checked before any runs
    for kind, key in KIND_KEYS:
        named, all_entry = _listed(data[key], kind, key, fail, atol_factor)
        grids = [(options, item_key) for _, options, item_key, _ in named]
        if all_entry is not None:
            grids.append(all_entry[:2])
        for options, item_key in grids:
            _grid_size(options, f"{item_key}.options", fail)
    modules = find_plugin_modules(plugins, f"{source}: plugins", directory, allow_local)
    modules += find_plugin_modules(extra_plugins, "--plugins", None, allow_local)
    import_plugin_modules(modules, f"{source}: plugins", say=stderr_line)
    # every list is resolved and its grids counted before any grid is expanded
    plans = {
        key: _plan(data[key], kind, key, missing, fail, (atol_factor, rtols))
        for kind, key in KIND_KEYS
    }
    sizes = {
        key: sum(size * len(tols) for _, _, _, size, tols in plan) for key, plan in plans.items()
    }
    count = math.prod(sizes.values())
    if count > MAX_RUNS:
        raise fail(
            max(sizes, key=lambda key: sizes[key]),
            f"the sweep would have {count} runs ({sizes['problems']} problems x "
            f"{sizes['formalisms']} formalisms x {sizes['integrators']} integrator and "
            f"tolerance pairs); at most {MAX_RUNS}: make the grids smaller or split the sweep",
        )
    problems = _expand(plans["problems"], "problem", "problems", fail)
    formalisms = _expand(plans["formalisms"], "formalism", "formalisms", fail)
    integrators = _expand(plans["integrators"], "integrator", "integrators", fail)
    span = max(problem_span(instance) for _, _, _, instance, _ in problems)
    for name, _, item_key, parsed, _ in integrators:
        try:
            registry.get_integrator(name).check_step_count(parsed, span)
        except ConfigError as error:
            raise fail(f"{item_key}.options", one_line(error, with_type=False)) from None

    from workbench.plugin.robot_problem import run_problem_names

    # a robot file's runs are named after it (and its options), so robots stay distinct
    names = run_problem_names([(p_name, p_opts) for p_name, p_opts, *_ in problems])
    problems = [(name, *rest) for name, (_, *rest) in zip(names, problems, strict=True)]
    # entries and tolerances are free of repeats, so every run is distinct (no ids to hash)
    runs = [
        RunSpec(p_name, f_name, i_name, rtol, rtol * atol_factor, p_opts, f_opts, i_opts)
        for (p_name, p_opts, *_), (f_name, f_opts, *_), (i_name, i_opts, _, _, i_rtols) in (
            itertools.product(problems, formalisms, integrators)
        )
        for rtol in i_rtols
    ]
    if not runs:
        raise ConfigError(f"{source}: the sweep has no runs")
    return SweepSpec(
        runs,
        Path(out),
        int(jobs),
        time_limit,
        [module.text() for module in modules],
        source,
        text,
        repeats,
        float(repeat_budget),
        retime,
        store_trajectories,
    )


def _key_line(text: str, key: str) -> int | None:
    """The line (1-based) where the top-level ``key`` of a dotted/indexed key is set."""
    top = re.split(r"[.\[]", key, maxsplit=1)[0]
    pattern = re.compile(rf"^\s*(?:{re.escape(top)}|\[\[?\s*{re.escape(top)}\s*\]\]?)\s*(?:=|$)")
    for number, line in enumerate(text.splitlines(), start=1):
        if pattern.match(line):
            return number
    return None


_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlong = 60, 60, 40
_SHORT.maxlist, _SHORT.maxdict, _SHORT.maxlevel = 6, 6, 3


def _show(value: Any) -> str:
    """``repr(value)`` cut short: messages stay one readable line whatever the input."""
    return _SHORT.repr(value)


def _check_depth(data: Any, fail: Callable[[str, str], ConfigError]) -> None:
    """Refuse nesting deeper than MAX_DEPTH (walked without recursion)."""
    stack = [(data, "", 0)]
    while stack:
        value, key, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise fail(key, f"nested more than {MAX_DEPTH} levels deep; no setting needs that")
        if isinstance(value, dict):
            stack.extend((v, f"{key}.{k}" if key else str(k), depth + 1) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, f"{key}[{i}]", depth + 1) for i, v in enumerate(value))


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _positive(value: Any, key: str, fail: Callable[[str, str], ConfigError]) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise fail(key, f"must be a number > 0, not {_show(value)}")
    try:
        value = float(value)
    except OverflowError:  # an integer beyond the float range
        raise fail(key, f"must be a finite number > 0, not {_show(value)}") from None
    if not math.isfinite(value) or value <= 0:
        raise fail(key, f"must be a finite number > 0, not {_show(value)}")
    return float(value)


def _tolerance_list(
    value: Any, key: str, atol_factor: float, fail: Callable[[str, str], ConfigError]
) -> list[float]:
    """The rtol values of ``tolerances`` (or an integrator entry's own), checked as
    `workbench run` checks them: numbers > 0 whose atol is one too, none repeated."""
    if not isinstance(value, list) or not value:
        raise fail(key, f"must be a non-empty list of numbers > 0, not {_show(value)}")
    for index, rtol in enumerate(value):
        problem = tolerance_problem("rtol", rtol)
        if problem:
            raise fail(f"{key}[{index}]", problem)
        problem = tolerance_problem("atol", float(rtol) * atol_factor)
        if problem:
            raise fail("atol_factor", f"atol = {rtol!r} * atol_factor {problem}")
    rtols = [float(t) for t in value]
    for index, rtol in enumerate(rtols):
        if rtol in rtols[:index]:
            raise fail(
                f"{key}[{index}]",
                f"{rtol!r} is listed twice (also {key}[{rtols.index(rtol)}]); "
                "give every tolerance once",
            )
    return rtols


def _plan(
    value: Any,
    kind: Kind,
    key: str,
    missing: str,
    fail: Callable[[str, str], ConfigError],
    tolerances: tuple[float, list[float]],
) -> list[tuple[str, dict[str, Any], str, int, list[float]]]:
    """(name, option grid, key, grid size, rtols) of every plugin a list names (grids
    unexpanded). ``tolerances`` is (atol_factor, the sweep's rtols): an integrator entry may
    list its own ``tolerances`` instead. Problems and formalisms get ``[nan]``, a
    placeholder never read, so that every kind counts its runs as size x len(rtols)."""
    atol_factor, sweep_rtols = tolerances
    named, all_entry = _listed(value, kind, key, fail, atol_factor)
    explicit = {name for name, *_ in named}
    if all_entry is not None:
        all_options, all_key, all_rtols = all_entry
        declared: set[str] = set()
        plugins = registry.list_plugins(kind)
        broken = [info for info in plugins if info.plugin is None]
        if broken:  # "all" is every working one: say which were left out, and why
            warnings.warn(
                f'{key} = "all" leaves out the broken {kind} plugin'
                f"{'s' if len(broken) > 1 else ''} "
                + "; ".join(f"{info.name} ({info.error_line})" for info in broken)
                + " (`workbench list` shows why)",
                stacklevel=2,
            )  # fmt: skip
        for info in plugins:
            if info.plugin is not None:
                fields = _option_names(info.plugin)
                declared |= fields
                if info.name not in explicit:
                    mine = {k: v for k, v in all_options.items() if k in fields}
                    named.append((info.name, mine, all_key, all_rtols))
        unknown = sorted(set(all_options) - declared)
        if unknown:
            raise fail(f"{all_key}.options.{unknown[0]}", f"no registered {kind} has this option")
    resolved = []
    for name, options, item_key, rtols in named:
        if kind != "integrator":
            rtols = [math.nan]
        try:
            registry.REGISTRY.get(kind, name)
        except PluginError as error:
            if missing == "skip" and name not in registry.REGISTRY.entries[kind]:
                continue
            raise fail(item_key, str(error)) from None
        size = _grid_size(options, f"{item_key}.options", fail)
        resolved.append((name, options, item_key, size, rtols or sweep_rtols))
    if not resolved:
        raise fail(key, f"no registered {kind} left to run (empty grid)")
    return resolved


def _listed(
    value: Any, kind: Kind, key: str, fail: Callable[[str, str], ConfigError], atol_factor: float
) -> tuple[list[tuple[str, Any, str, list[float] | None]], tuple[Any, str, Any] | None]:
    """The entries of one list, checked without the registry: ((name, options, key, own
    rtols) of every named entry, (options, key, rtols) of an "all" entry or None)."""
    table_keys = {"name", "options", "tolerances"} if kind == "integrator" else {"name", "options"}

    def own_tolerances(item: dict[str, Any], item_key: str) -> list[float] | None:
        extra = sorted(set(item) - table_keys)
        if extra:
            hint = (
                "; only integrator entries take their own tolerances"
                if extra[0] == "tolerances"
                else ""
            )
            keys = " and ".join(sorted(table_keys))
            raise fail(f"{item_key}.{extra[0]}", f"unknown key; a table has {keys}{hint}")
        if "tolerances" not in item:
            return None
        return _tolerance_list(item["tolerances"], f"{item_key}.tolerances", atol_factor, fail)

    if value == "all":
        value = ["all"]
    if not isinstance(value, list) or not value:
        raise fail(
            key,
            f'must be a non-empty list of names or {{name, options}} tables, or "all"'
            f", not {_show(value)}",
        )
    named: list[tuple[str, Any, str, list[float] | None]] = []
    wants_all, all_options, all_key, all_rtols = False, {}, f"{key}[all]", None
    for index, item in enumerate(value):
        item_key = f"{key}[{index}]"
        if item == "all":
            wants_all = True
        elif isinstance(item, dict) and item.get("name") == "all":
            wants_all, all_key = True, item_key
            all_options = item.get("options", {})
            all_rtols = own_tolerances(item, item_key)
            if not isinstance(all_options, dict):
                raise fail(f"{item_key}.options", f"must be a table, not {_show(all_options)}")
        elif isinstance(item, str):
            named.append((item, {}, item_key, None))
        elif isinstance(item, dict):
            rtols = own_tolerances(item, item_key)
            name = item.get("name")
            if not isinstance(name, str) or not name:
                raise fail(f"{item_key}.name", f"must be a plugin name (string), not {_show(name)}")
            options = item.get("options", {})
            if not isinstance(options, dict):
                raise fail(f"{item_key}.options", f"must be a table, not {_show(options)}")
            named.append((name, options, item_key, rtols))
        else:
            raise fail(item_key, f"must be a name or a {{name, options}} table, not {_show(item)}")
    return named, ((all_options, all_key, all_rtols) if wants_all else None)


def _expand(
    plan: list[tuple[str, dict[str, Any], str, int, list[float]]],
    kind: Kind,
    key: str,
    fail: Callable[[str, str], ConfigError],
) -> list[tuple[str, dict[str, Any], str, Any, list[float]]]:
    """(name, normalized options, key, parsed, rtols) of every plugin x option combination;
    no repeats. ``parsed``: the problem instance, or the options instance of a formalism or
    integrator."""
    entries = []
    seen: dict[str, str] = {}
    for name, options, item_key, _, rtols in plan:
        for combination in _grid(options, f"{item_key}.options", fail):
            normalized, parsed = _normalized_options(kind, name, combination, item_key, fail)
            identity = json.dumps([name, normalized], sort_keys=True)
            if identity in seen:
                raise fail(
                    item_key,
                    f"{kind} {name!r} with options {_show(normalized)} is listed twice "
                    f"(also {seen[identity]}); list every {kind} and option value once",
                )
            seen[identity] = item_key
            entries.append((name, normalized, item_key, parsed, rtols))
    return entries


def _option_names(plugin: Any) -> set[str]:
    from workbench.plugin.options import option_fields

    return {name for name, _, _ in option_fields(plugin.Options)}


def _grid_values(name: str, value: Any, key: str, fail: Callable[[str, str], ConfigError]) -> list:
    """The values of one grid axis (a list is a grid; anything else one value); no repeats."""
    values = value if isinstance(value, list) else [value]
    if not values:
        raise fail(f"{key}.{name}", "empty list of values (empty grid)")
    shown: dict[str, int] = {}
    for index, item in enumerate(values):
        # the type is part of the value: 1 and 1.0 (and true) are told apart here; options
        # that coerce them alike meet again as a repeated plugin after normalization
        identity = f"{type(item).__name__}:{json.dumps(item, sort_keys=True, default=str)}"
        if identity in shown:
            raise fail(
                f"{key}.{name}",
                f"the value {_show(item)} is listed twice (positions {shown[identity]} and "
                f"{index}); give every value of a grid once",
            )
        shown[identity] = index
    return values


def _grid_size(options: dict[str, Any], key: str, fail: Callable[[str, str], ConfigError]) -> int:
    size = 1
    for name, value in options.items():
        size *= len(_grid_values(name, value, key, fail))
        if size > MAX_RUNS:
            raise fail(key, f"the option grid has more than {MAX_RUNS} combinations")
    return size


def _grid(
    options: dict[str, Any], key: str, fail: Callable[[str, str], ConfigError]
) -> list[dict[str, Any]]:
    names = list(options)
    axes = [_grid_values(name, options[name], key, fail) for name in names]
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*axes)]


def _normalized_options(
    kind: Kind,
    name: str,
    options: dict[str, Any],
    key: str,
    fail: Callable[[str, str], ConfigError],
) -> tuple[dict[str, Any], Any]:
    from workbench.plugin.options import options_dict
    from workbench.plugin.robot_problem import check_robot_file

    plugin = registry.REGISTRY.get(kind, name)
    try:
        if kind == "problem":
            instance = plugin(options)
            check_robot_file(instance)  # its file and q0 now, not as every run's failure
            parsed = instance.options
        else:
            if kind == "formalism" and "compile" not in options:
                options = {**options, **_sweep_compile_default(plugin)}
            instance = parsed = plugin.parse_options(options)
    except ConfigError as error:
        raise fail(f"{key}.options", one_line(error, with_type=False)) from None
    except Exception as error:  # noqa: BLE001 - a plugin's own checks may raise anything
        raise fail(f"{key}.options", one_line(error)) from None
    normalized = json.loads(json.dumps(options_dict(parsed), default=_jsonable_value))
    return normalized, instance


SWEEP_COMPILE = "auto"
"""A sweep's formalisms compile where that repays (``compile = "auto"``) unless the
specification says otherwise: cost figures of code no one would deploy in the VM mislead."""


def _sweep_compile_default(plugin: Any) -> dict[str, Any]:
    """{"compile": SWEEP_COMPILE} for a formalism whose options have ``compile``, else {}."""
    return {"compile": SWEEP_COMPILE} if "compile" in _option_names(plugin) else {}


def _jsonable_value(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)
