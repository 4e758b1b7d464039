"""What the three checkers share: naming the subject, choosing problems, structural checks
of any plugin class (registration, name, summary, docstring, options)."""

from __future__ import annotations

import inspect
import re
from typing import Any

from workbench.errors import WorkbenchError, one_line
from workbench.plugin import registry
from workbench.plugin.options import NoOptions, parse_options
from workbench.plugin.problem import Problem
from workbench.testing.report import ConformanceReport

FAST_PROBLEMS = (
    "simple-pendulum",  # planar, point mass
    "double-pendulum",  # planar tree
    "two-joint-robot",  # spatial tree, applied torques
    "rotating-ring",  # spatial, driven joint (rheonomic)
    "heavy-top",  # spherical joint (quaternions)
    "slider-crank",  # closed loop
    "rolling-pendulum",  # nonholonomic
)
"""The default problem subset: one small problem for each model feature (seconds)."""

NAME_PATTERN = re.compile(r"^[a-z0-9][a-z0-9-]*$")
PLACEHOLDER = re.compile(r"\b(TODO|FIXME|XXX|TBD)\b")
"""Words that mark text still to be written (the scaffold's templates use TODO)."""


def resolve_plugin(kind: registry.Kind, plugin: str | type) -> type:
    """The plugin class for a registered name, or ``plugin`` itself if it is a class."""
    if isinstance(plugin, str):
        return registry.REGISTRY.get(kind, plugin)
    if not isinstance(plugin, type):
        raise WorkbenchError(f"give a {kind} name or class, not {plugin!r}")
    return plugin


def problem_instances(problems: Any) -> list[Problem]:
    """None: :data:`FAST_PROBLEMS`; "all": every working registered problem; or a list of
    names, Problem classes or instances (a single one is accepted too)."""
    if problems is None:
        known = set(registry.plugin_names("problem"))
        problems = [name for name in FAST_PROBLEMS if name in known]
    elif problems == "all":
        problems = [i.name for i in registry.list_plugins("problem") if i.plugin is not None]
    elif isinstance(problems, str | Problem) or isinstance(problems, type):
        problems = [problems]
    out = []
    for item in problems:
        if isinstance(item, str):
            item = registry.get_problem(item)
        out.append(item() if isinstance(item, type) else item)
    return out


def check_structure(
    report: ConformanceReport, kind: registry.Kind, plugin: type, base: type
) -> Any:
    """Checks every plugin kind shares; returns the parsed default options (None if bad)."""
    name = getattr(plugin, "name", "")
    # registered under its name, as the class given
    try:
        found = registry.REGISTRY.get(kind, name)
        if found is plugin or (found.__qualname__, found.__module__) == (
            plugin.__qualname__,
            plugin.__module__,
        ):
            report.passed("registered", message=f"as {kind} {name!r} ({plugin.__module__})")
        else:
            report.failed(
                "registered",
                "",
                f"the name {name!r} is registered by "
                f"{found.__module__}.{found.__qualname__}, not by this class",
            )
    except WorkbenchError as error:
        report.failed(
            "registered",
            "",
            f"{one_line(error)}; decorate the class with "
            f"@workbench.plugin.registry.{kind} or add an entry point in the group "
            f"{registry.ENTRY_POINT_GROUPS[kind]!r}",
        )
    # subclass, name, summary, docstring
    problems = []
    if not issubclass(plugin, base):
        problems.append(f"subclass {base.__module__}.{base.__qualname__}")
    if not (isinstance(name, str) and NAME_PATTERN.match(name)):
        problems.append(f"set name to lowercase words joined by '-' (not {name!r})")
    summary = getattr(plugin, "summary", "")
    if not (isinstance(summary, str) and summary.strip() and "\n" not in summary):
        problems.append("set summary to one non-empty line")
    elif PLACEHOLDER.search(summary):
        problems.append(f"write the summary: it is a placeholder ({summary!r})")
    module = inspect.getmodule(plugin)
    docstrings = [(plugin.__doc__ or "").strip(), (getattr(module, "__doc__", "") or "").strip()]
    written = [text for text in docstrings if text and not PLACEHOLDER.search(text.split("\n")[0])]
    if not written:
        problems.append(
            "write a docstring (class or module) saying what it is and its source"
            + (" (its first line is still a placeholder)" if any(docstrings) else "")
        )
    if problems:
        report.failed("metadata", "", "; ".join(problems))
    else:
        report.passed("metadata", message=summary)
    # options: a dataclass whose fields all have defaults
    try:
        options = parse_options(getattr(plugin, "Options", NoOptions), None, f"{kind} {name!r}")
        report.passed("options", message=type(options).__name__)
        return options
    except Exception as error:  # noqa: BLE001 - any failure is the finding
        report.failed(
            "options",
            "",
            f"the default options do not parse: {one_line(error)}; "
            "give every Options field a default",
        )
        return None
