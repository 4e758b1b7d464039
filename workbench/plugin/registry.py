"""Three registries of plugins: problems, formalisms and integrators.

Built-in plugins register with the decorators :func:`problem`, :func:`formalism` and
:func:`integrator`; the workbench finds them by importing every module of the built-in
packages (``workbench.problems``, ``workbench.plugins.formalisms``,
``workbench.plugins.integrators``) and then the
entry-point groups ``workbench.problems``, ``workbench.formalisms`` and
``workbench.integrators`` of other installed packages. A module that fails to import is
listed as *broken* with its error; the others keep working.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import importlib
import pkgutil
import traceback
import warnings
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, Literal

from workbench.errors import PluginError, WorkbenchError, one_line
from workbench.plugin import discovery
from workbench.plugin.options import option_fields

Kind = Literal["problem", "formalism", "integrator"]
KINDS: tuple[Kind, ...] = ("problem", "formalism", "integrator")
BUILTIN_PACKAGES: dict[Kind, str] = {
    "problem": "workbench.problems",
    "formalism": "workbench.plugins.formalisms",
    "integrator": "workbench.plugins.integrators",
}
ENTRY_POINT_GROUPS: dict[Kind, str] = {
    "problem": "workbench.problems",
    "formalism": "workbench.formalisms",
    "integrator": "workbench.integrators",
}


@dataclass
class PluginInfo:
    """One registry entry: the plugin class, or the error of a module that failed to import
    (``error``: its traceback; ``error_line``: the error on one line, ``''`` if none)."""

    kind: Kind
    name: str
    plugin: type | None
    module: str
    error: str | None = None
    error_line: str = ""

    @property
    def status(self) -> str:
        return "broken" if self.error else "ok"

    @property
    def summary(self) -> str:
        if self.plugin is None:
            return f"failed to import: {self.error_line}"
        return getattr(self.plugin, "summary", "") or ""


def check_kind(kind: str) -> Kind:
    """``kind`` itself if it is one of KINDS; PluginError otherwise."""
    if kind not in KINDS:
        raise PluginError(f"unknown plugin kind {kind!r}; use one of {', '.join(KINDS)}")
    return kind  # type: ignore[return-value]


@dataclass
class Registry:
    """Plugins by kind and name.

    ``builtin_packages`` and ``entry_point_groups`` say where :meth:`discover` looks
    (tests give a fresh registry their own, or none).
    """

    entries: dict[Kind, dict[str, PluginInfo]] = field(
        default_factory=lambda: {kind: {} for kind in KINDS}
    )
    discovered: bool = False
    builtin_packages: dict[Kind, str] = field(default_factory=lambda: dict(BUILTIN_PACKAGES))
    entry_point_groups: dict[Kind, str] = field(default_factory=lambda: dict(ENTRY_POINT_GROUPS))

    def add(self, kind: Kind, plugin: type) -> None:
        check_kind(kind)
        name = getattr(plugin, "name", None)
        if not isinstance(plugin, type):
            raise PluginError(f"{kind} plugin {plugin!r} must be a class")
        if not isinstance(name, str) or not name:
            raise PluginError(
                f"{kind} plugin {plugin.__qualname__} has no name; set the class attribute name"
            )
        _check_options(kind, name, plugin)
        existing = self.entries[kind].get(name)
        if existing is not None and existing.plugin is not plugin:
            if existing.plugin is None or existing.module == plugin.__module__:
                # a broken placeholder of the same name, or the same module imported again
                # (e.g. reload): the newest working class wins
                pass
            else:
                warnings.warn(
                    f"{kind} {name!r} from {plugin.__module__} ignored: the name is already "
                    f"registered by {existing.module}",
                    stacklevel=3,
                )
                return
        self.entries[kind][name] = PluginInfo(kind, name, plugin, plugin.__module__)

    def add_broken(self, kind: Kind, name: str, module: str, error: BaseException | str) -> None:
        """Record a plugin module that failed to import with ``error`` (an exception, or
        the reason it was not imported at all); a working entry is never replaced."""
        check_kind(kind)
        if name not in self.entries[kind]:
            if isinstance(error, str):
                text, line = error, error
            else:
                text, line = "".join(traceback.format_exception(error)), one_line(error)
            self.entries[kind][name] = PluginInfo(kind, name, None, module, text, line)

    def discover(self) -> None:
        """Import built-in plugin modules and entry points once (idempotent)."""
        if self.discovered:
            return
        self.discovered = True
        for kind, package_name in self.builtin_packages.items():
            try:
                package = importlib.import_module(package_name)
            except Exception as error:  # noqa: BLE001 - a broken package must not stop the others
                self.add_broken(kind, package_name, package_name, error)
                continue
            for module in pkgutil.iter_modules(
                getattr(package, "__path__", []), package_name + "."
            ):
                self._import(kind, module.name.rsplit(".", 1)[-1], module.name)
        if "problem" in self.builtin_packages:  # the core's own: a robot read from a file
            self._import("problem", "robot", "workbench.plugin.robot_problem")
        found = [
            (kind, entry_point)
            for kind, group in self.entry_point_groups.items()
            for entry_point in metadata.entry_points(group=group)
        ]
        # one that crashes or hangs on import is known from a child process (discovery)
        unsafe = discovery.verdicts([entry_point for _, entry_point in found])
        with discovery.importing() if found else contextlib.nullcontext():
            for kind, entry_point in found:
                reason = unsafe.get(discovery.entry_point_key(entry_point))
                if reason:
                    self.add_broken(kind, entry_point.name, entry_point.value, reason)
                    continue
                try:
                    loaded = entry_point.load()
                    # an entry point may name a class, or a module whose decorators register
                    if isinstance(loaded, type) and getattr(loaded, "name", None):
                        self.add(kind, loaded)
                except Exception as error:  # noqa: BLE001
                    self.add_broken(kind, entry_point.name, entry_point.value, error)

    def _import(self, kind: Kind, name: str, module_name: str) -> None:
        if name.startswith("_"):
            return
        try:
            importlib.import_module(module_name)
        except Exception as error:  # noqa: BLE001
            self.add_broken(kind, name.replace("_", "-"), module_name, error)

    def list(self, kind: Kind) -> list[PluginInfo]:
        check_kind(kind)
        self.discover()
        # a plugin with ``listed = False`` (the robot-file problem, which needs its file) is
        # found by name but left out of listings and "all"
        listed = [i for i in self.entries[kind].values() if getattr(i.plugin, "listed", True)]
        return sorted(listed, key=lambda info: info.name)

    def find(self, kind: Kind, name: str) -> PluginInfo | None:
        """The entry registered as ``name`` (broken or not), or None: a lookup that may
        miss, without :meth:`get`'s hint (which reads every imported module: 0.1-0.2 s)."""
        check_kind(kind)
        self.discover()
        info = self.entries[kind].get(name)
        if info is None and kind == "problem" and _robot_problem_name(name):
            info = self.entries[kind].get("robot")  # a robot run's name: its file's
        return info

    def get(self, kind: Kind, name: str) -> type:
        """The plugin class registered as ``name``; PluginError with close matches otherwise."""
        info = self.find(kind, name)
        if info is None:
            names = sorted(self.entries[kind])
            close = close_matches(name, names)
            if close:
                hint = f"did you mean {', '.join(close)}?"
            else:
                hint = f"known: {', '.join(names)}" if names else f"no {kind} is registered"
            raise PluginError(f"unknown {kind} {name!r}; {unregistered_hint(kind, name) or hint}")
        if info.plugin is None:
            raise PluginError(
                f"{kind} {name!r} is broken: {info.error_line} (module {info.module})"
            )
        return info.plugin


def _robot_problem_name(name: str) -> bool:
    """A run of the robot problem is named after its file (``ur5.urdf[t_end=2]``)."""
    from workbench.model.importers import robot_format

    return robot_format(name.split("[", 1)[0]) is not None


def unregistered_hint(kind: Kind, name: str) -> str:
    """How to get an unknown ``kind`` plugin ``name`` registered, or "": an imported module
    defines a class of that name that was never registered (its decorator forgotten), or
    a file of this folder named after it was not imported (no ``--plugins``)."""
    import sys

    base = kind.capitalize()  # workbench.plugin.<kind>.<Kind>, known by name (no cycle)

    def is_plugin(value: Any) -> bool:
        return isinstance(value, type) and any(
            c.__name__ == base and c.__module__ == f"workbench.plugin.{kind}"
            for c in value.__mro__[1:]
        )

    for module in list(sys.modules.values()):
        for value in list(getattr(module, "__dict__", {}).values()):
            if (is_plugin(value) and getattr(value, "name", None) == name
                    and getattr(value, "__module__", None) == module.__name__):  # fmt: skip
                where = getattr(module, "__file__", None) or module.__name__
                return (
                    f"{where} defines {value.__name__}({base}) named {name!r} but "
                    f"does not register it: put @{kind} (from workbench.plugin.registry "
                    f"import {kind}) above its class, or name it as "
                    f"{Path(where).name if where.endswith('.py') else module.__name__}:"
                    f"{value.__name__}"
                )
    module_name = name.replace("-", "_")  # what `workbench new` names its file
    if Path(f"{module_name}.py").is_file() and module_name not in sys.modules:
        return (
            f"./{module_name}.py is not imported unless named: add --plugins "
            f"{module_name}.py (in a sweep specification: plugins = [\"{module_name}.py\"])"
        )
    return ""


def close_matches(name: str, names: list[str]) -> list[str]:
    """Up to three of ``names`` that look like ``name`` (case and _/- insensitive)."""

    def normal(text: str) -> str:
        return text.lower().replace("_", "-")

    by_normal = {normal(n): n for n in names}
    close = difflib.get_close_matches(normal(name), list(by_normal), n=3, cutoff=0.6)
    return [by_normal[c] for c in close]


def _check_options(kind: str, name: str, plugin: type) -> None:
    """A plugin's ``Options`` (if any) must be a dataclass whose hints resolve."""
    options_class = getattr(plugin, "Options", None)
    if options_class is None:
        return
    if not (isinstance(options_class, type) and dataclasses.is_dataclass(options_class)):
        raise PluginError(
            f"{kind} {name!r}: Options must be a dataclass (e.g. @dataclass(frozen=True))"
        )
    try:
        option_fields(options_class)
    except Exception as error:  # noqa: BLE001 - any failure means the hints are unusable
        raise PluginError(f"{kind} {name!r}: cannot read the Options type hints: {error}") from None


REGISTRY = Registry()


def _decorator(kind: Kind):
    def register(plugin: type) -> type:
        REGISTRY.add(kind, plugin)
        return plugin

    return register


problem = _decorator("problem")
formalism = _decorator("formalism")
integrator = _decorator("integrator")


def get_problem(name: str) -> type:
    return REGISTRY.get("problem", name)


def get_formalism(name: str) -> type:
    return REGISTRY.get("formalism", name)


def get_integrator(name: str) -> type:
    return REGISTRY.get("integrator", name)


def list_plugins(kind: Kind) -> list[PluginInfo]:
    return REGISTRY.list(kind)


def plugin_names(kind: Kind) -> list[str]:
    return [info.name for info in REGISTRY.list(kind)]


def describe_kind(kind: str) -> Kind:
    """Accept singular or plural kind names ('formalisms' -> 'formalism')."""
    singular = kind.strip().lower()
    if singular.endswith("s"):
        singular = singular[:-1]
    if singular not in KINDS:
        close = close_matches(kind, [k + "s" for k in KINDS])
        hint = f"did you mean {', '.join(close)}? " if close else ""
        raise PluginError(
            f"unknown plugin kind {kind!r}; {hint}use problems, formalisms or integrators"
        )
    return singular  # type: ignore[return-value]


def any_plugin(name: str) -> tuple[Kind, type]:
    """Find ``name`` in any registry (problems first)."""
    REGISTRY.discover()
    for kind in KINDS:
        if name in REGISTRY.entries[kind]:
            return kind, REGISTRY.get(kind, name)
    everything = sorted({n for kind in KINDS for n in REGISTRY.entries[kind]})
    close = close_matches(name, everything)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise PluginError(f"no problem, formalism or integrator is called {name!r}{hint}")


def non_default_options(kind: str, name: str, options: dict[str, Any]) -> dict[str, Any]:
    """The ``options`` of the ``kind`` plugin ``name`` ("formalism", "integrator",
    "problem") that differ from its defaults; all of them if it is not registered here."""
    defaults = _defaults(kind, name)
    if defaults is None:
        return dict(options)
    return {k: v for k, v in options.items() if k not in defaults or defaults[k] != v}


def _defaults(kind: str, name: str) -> dict[str, Any] | None:
    try:
        info = REGISTRY.find(kind, name)  # type: ignore[arg-type]
        if info is None or info.plugin is None:
            return None  # not registered here, or broken
        return {field: default for field, _type, default in option_fields(info.plugin.Options)}
    except (WorkbenchError, KeyError, AttributeError, TypeError):
        return None


__all__: list[Any] = [
    "REGISTRY",
    "PluginInfo",
    "Registry",
    "any_plugin",
    "check_kind",
    "close_matches",
    "describe_kind",
    "formalism",
    "get_formalism",
    "get_integrator",
    "get_problem",
    "integrator",
    "list_plugins",
    "non_default_options",
    "plugin_names",
    "problem",
]
