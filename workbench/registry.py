"""Three registries of plugins: problems, formalisms and integrators.

Built-in plugins register with the decorators :func:`problem`, :func:`formalism` and
:func:`integrator`; the workbench finds them by importing every module of the built-in
packages (``problems``, ``plugins.formalisms``, ``plugins.integrators``) and then the
entry-point groups ``workbench.problems``, ``workbench.formalisms`` and
``workbench.integrators`` of other installed packages. A module that fails to import is
listed as *broken* with its error; the others keep working.
"""

from __future__ import annotations

import difflib
import importlib
import pkgutil
import traceback
import warnings
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Literal

from workbench.errors import PluginError

Kind = Literal["problem", "formalism", "integrator"]
KINDS: tuple[Kind, ...] = ("problem", "formalism", "integrator")
BUILTIN_PACKAGES: dict[Kind, str] = {
    "problem": "problems",
    "formalism": "plugins.formalisms",
    "integrator": "plugins.integrators",
}
ENTRY_POINT_GROUPS: dict[Kind, str] = {
    "problem": "workbench.problems",
    "formalism": "workbench.formalisms",
    "integrator": "workbench.integrators",
}


@dataclass
class PluginInfo:
    """One registry entry: the plugin class, or the error of a module that failed to import."""

    kind: Kind
    name: str
    plugin: type | None
    module: str
    error: str | None = None

    @property
    def status(self) -> str:
        return "broken" if self.error else "ok"

    @property
    def summary(self) -> str:
        if self.plugin is None:
            return f"failed to import: {self.error.splitlines()[-1] if self.error else ''}"
        return getattr(self.plugin, "summary", "") or ""


@dataclass
class Registry:
    entries: dict[Kind, dict[str, PluginInfo]] = field(
        default_factory=lambda: {kind: {} for kind in KINDS}
    )
    discovered: bool = False

    def add(self, kind: Kind, plugin: type) -> None:
        name = getattr(plugin, "name", None)
        if not isinstance(name, str) or not name:
            raise PluginError(f"{kind} plugin {plugin!r} has no name; set the class attribute name")
        existing = self.entries[kind].get(name)
        if existing is not None and existing.plugin is not plugin:
            if existing.module == plugin.__module__ and existing.plugin is not None:
                # the same module imported again (e.g. reload): keep the newest class
                pass
            else:
                warnings.warn(
                    f"{kind} {name!r} from {plugin.__module__} ignored: the name is already "
                    f"registered by {existing.module}",
                    stacklevel=3,
                )
                return
        self.entries[kind][name] = PluginInfo(kind, name, plugin, plugin.__module__)

    def add_broken(self, kind: Kind, name: str, module: str, error: str) -> None:
        if name not in self.entries[kind]:
            self.entries[kind][name] = PluginInfo(kind, name, None, module, error)

    def discover(self) -> None:
        """Import built-in plugin modules and entry points once (idempotent)."""
        if self.discovered:
            return
        self.discovered = True
        for kind, package_name in BUILTIN_PACKAGES.items():
            try:
                package = importlib.import_module(package_name)
            except Exception:  # noqa: BLE001 - a broken package must not stop the others
                self.add_broken(kind, package_name, package_name, traceback.format_exc())
                continue
            for module in pkgutil.iter_modules(package.__path__, package_name + "."):
                self._import(kind, module.name.rsplit(".", 1)[-1], module.name)
        for kind, group in ENTRY_POINT_GROUPS.items():
            for entry_point in metadata.entry_points(group=group):
                try:
                    loaded = entry_point.load()
                except Exception:  # noqa: BLE001
                    self.add_broken(kind, entry_point.name, entry_point.value,
                                    traceback.format_exc())
                    continue
                if isinstance(loaded, type) and getattr(loaded, "name", None):
                    self.add(kind, loaded)

    def _import(self, kind: Kind, name: str, module_name: str) -> None:
        if name.startswith("_"):
            return
        try:
            importlib.import_module(module_name)
        except Exception:  # noqa: BLE001
            self.add_broken(kind, name.replace("_", "-"), module_name, traceback.format_exc())

    def list(self, kind: Kind) -> list[PluginInfo]:
        self.discover()
        return sorted(self.entries[kind].values(), key=lambda info: info.name)

    def get(self, kind: Kind, name: str) -> type:
        """The plugin class registered as ``name``; PluginError with close matches otherwise."""
        self.discover()
        info = self.entries[kind].get(name)
        if info is None:
            names = list(self.entries[kind])
            close = difflib.get_close_matches(name, names, n=3, cutoff=0.5)
            hint = f"did you mean {', '.join(close)}?" if close else f"known: {', '.join(names)}"
            raise PluginError(f"unknown {kind} {name!r}; {hint}")
        if info.plugin is None:
            last = (info.error or "").strip().splitlines()[-1:] or [""]
            raise PluginError(f"{kind} {name!r} is broken: {last[0]} (module {info.module})")
        return info.plugin


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
    singular = kind.rstrip("s") if kind.endswith("s") else kind
    if singular not in KINDS:
        raise PluginError(f"unknown plugin kind {kind!r}; use problems, formalisms or integrators")
    return singular  # type: ignore[return-value]


def any_plugin(name: str) -> tuple[Kind, type]:
    """Find ``name`` in any registry (problems first)."""
    for kind in KINDS:
        REGISTRY.discover()
        if name in REGISTRY.entries[kind]:
            return kind, REGISTRY.get(kind, name)
    everything = [n for kind in KINDS for n in REGISTRY.entries[kind]]
    close = difflib.get_close_matches(name, everything, n=3, cutoff=0.5)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise PluginError(f"no problem, formalism or integrator is called {name!r}{hint}")


__all__: list[Any] = [
    "REGISTRY",
    "PluginInfo",
    "Registry",
    "any_plugin",
    "formalism",
    "get_formalism",
    "get_integrator",
    "get_problem",
    "integrator",
    "list_plugins",
    "plugin_names",
    "problem",
]
