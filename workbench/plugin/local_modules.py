"""Plugin modules named by a sweep specification or ``--plugins``: found, trusted, imported.

A plugin module is code: importing it runs it, as pytest runs a ``conftest.py``. So running
someone's specification runs the modules beside it, and that must be a visible choice:

* an entry is a module name or a ``.py`` file, optionally followed by ``:Class`` (a plugin
  class of it, registered if its module does not register it itself);
* a name (``helper``, ``my_pkg.plugins``) is looked for first among the installed modules
  (the Python path, without the current directory that ``python -m`` and ``python -c`` put
  first), then in the current directory, then in the specification's folder; a ``.py``
  path (``my_problem.py``, relative to the current directory or, in a specification, to
  its folder) names its file. A module found in a folder rather than installed is
  *local*;
* a local module is imported from its file (``importlib.util.spec_from_file_location``),
  under its own name, without adding its folder to ``sys.path``: nothing else there
  becomes importable. Each import is said on stderr, one line naming the module and its
  file;
* ``WORKBENCH_NO_LOCAL_PLUGINS=1`` (or ``--no-local-plugins``, as pytest's ``--noconftest``
  and Python's ``-P``) switches local modules off: only installed modules and entry points
  load, and a specification naming a local one is refused with one line saying how to
  allow it.

:func:`find_plugin_modules` decides, :func:`import_plugin_modules` imports; what it returns
(:class:`PluginModule`, as text: ``name[:Class]`` or ``name[:Class]=FILE``) is what
worker processes receive, so they import the very same files without searching again.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from workbench.errors import ConfigError, one_line

NO_LOCAL_PLUGINS_VARIABLE = "WORKBENCH_NO_LOCAL_PLUGINS"
_FROM_FILES: dict[str, str] = {}  # top-level module name -> the file this process imported


def imported_from_file(module_name: str) -> bool:
    """``module_name`` belongs to a local plugin module this process imported from its file
    (found by no search path: a worker must be given the file, not the name)."""
    return module_name.partition(".")[0] in _FROM_FILES


def local_plugins_allowed() -> bool:
    """False when ``WORKBENCH_NO_LOCAL_PLUGINS`` is set to anything but ``""`` or ``0``."""
    return os.environ.get(NO_LOCAL_PLUGINS_VARIABLE, "").strip() in ("", "0")


@dataclass(frozen=True)
class PluginModule:
    """A plugin module to import: ``name``, for a local module the ``file`` of its
    top-level module or package (``helper.py``, ``my_pkg/__init__.py``; ``""`` for an
    installed one), and the plugin class ``attribute`` named with it (``""``: none)."""

    name: str
    file: str = ""
    attribute: str = ""

    @property
    def local(self) -> bool:
        return bool(self.file)

    def text(self) -> str:
        """``name[:Class]`` or ``name[:Class]=FILE``: how workers receive it."""
        named = f"{self.name}:{self.attribute}" if self.attribute else self.name
        return f"{named}={self.file}" if self.file else named

    @classmethod
    def from_text(cls, text: str) -> PluginModule:
        named, _, file = text.partition("=")
        name, _, attribute = named.partition(":")
        return cls(name, file, attribute)


def _is_path(entry: str) -> bool:
    return entry.endswith(".py") or "/" in entry or os.sep in entry


def _top_level_file(folder: Path, top: str) -> Path | None:
    """``folder/top.py`` or ``folder/top/__init__.py``, whichever is a file."""
    for candidate in (folder / f"{top}.py", folder / top / "__init__.py"):
        if candidate.is_file():
            return candidate.resolve()
    return None


def _installed(top: str, folders: list[Path]) -> bool:
    """``top`` is importable from the environment, not only from one of ``folders``
    (found without running any code: a top-level name's spec is only looked up)."""
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return False
    if spec is None:
        return False
    origin = spec.origin if spec.has_location and spec.origin else None
    locations = [origin] if origin else list(spec.submodule_search_locations or [])
    if not locations:
        return True  # built-in or frozen
    for location in locations:
        path = Path(location).resolve()
        root = path.parent.parent if path.name == "__init__.py" else path.parent
        if root not in folders:
            return True
    return False


def find_plugin_modules(
    entries: Iterable[str],
    source: str = "--plugins",
    folder: str | os.PathLike[str] | None = None,
    allow_local: bool | None = None,
) -> list[PluginModule]:
    """Where each of ``entries`` (module names or ``.py`` paths) is, without importing any.

    ``folder``: the specification's (searched after the current directory; relative paths
    are taken from it); ``allow_local``: None reads ``WORKBENCH_NO_LOCAL_PLUGINS``.
    ConfigError (naming ``source[i]``) for a module found nowhere, or a local one while
    local modules are off."""
    allow = local_plugins_allowed() if allow_local is None else allow_local
    cwd = Path.cwd().resolve()
    base = Path(folder).resolve() if folder is not None else cwd
    folders = list(dict.fromkeys([cwd, base]))
    found = []
    for index, entry in enumerate(entries):
        where = f"{source}[{index}]"
        if not isinstance(entry, str) or not entry.strip():
            raise ConfigError(f"{where}: must be a module name or a .py file, not {entry!r}")
        entry, colon, attribute = entry.rpartition(":") if ":" in entry else (entry, "", "")
        if colon and not (entry and attribute.isidentifier()):
            raise ConfigError(
                f"{where}: {entry}{colon}{attribute!r}: write MODULE_OR_FILE:Class "
                "(e.g. my_problem.py:MyProblem)"
            )
        if _is_path(entry):
            path = (base / entry).resolve()
            if not path.is_file() or path.suffix != ".py":
                raise ConfigError(f"{where}: no Python file {path} (give an existing .py file)")
            module = PluginModule(path.stem, str(path), attribute)
        else:
            top = entry.partition(".")[0]
            if top in _FROM_FILES:  # imported from its file already (found from elsewhere)
                module = PluginModule(entry, _FROM_FILES[top], attribute)
            elif _installed(top, folders):
                module = PluginModule(entry, "", attribute)
            else:
                file = next((f for f in map(lambda d: _top_level_file(d, top), folders) if f), None)
                if file is None:
                    places = " or in ".join(str(folder) for folder in folders)
                    raise ConfigError(
                        f"{where}: cannot import plugin module {entry!r}: No module named "
                        f"{top!r} on the Python path or in {places}"
                    )
                module = PluginModule(entry, str(file), attribute)
        if module.local and not allow:
            raise ConfigError(
                f"{where}: {module.name!r} is a local plugin module ({module.file}) and local "
                f"plugin modules are off ({NO_LOCAL_PLUGINS_VARIABLE} or --no-local-plugins): "
                "read it, then run without the switch if you trust it, or install it as a package"
            )
        found.append(module)
    return found


def _beside_hint(module: PluginModule, error: Exception) -> str:
    """Why a local plugin cannot import a module of its own folder, if that is the error:
    its folder is not put on sys.path (a plugin file never shadows installed modules)."""
    missing = getattr(error, "name", None)
    if not module.local or not isinstance(error, ModuleNotFoundError) or not missing:
        return ""
    folder = Path(module.file).parent
    beside = next((p for p in (folder / f"{missing}.py", folder / missing / "__init__.py")
                   if p.is_file()), None)  # fmt: skip
    if beside is None:
        return ""
    return (
        f" ({beside.relative_to(folder)} beside it is not importable: a local plugin's "
        f"folder is not put on sys.path; name it with --plugins too, before "
        f"{Path(module.file).name}, or make the two a package)"
    )


def import_plugin_modules(
    modules: Iterable[PluginModule | str],
    source: str = "plugins",
    say: Callable[[str], None] | None = None,
) -> list[tuple[str, str]]:
    """Import ``modules`` (:class:`PluginModule` or their text); a local one from its file,
    said through ``say`` (e.g. printed on stderr; None: silent, as in workers). Returns the
    (kind, name) of each plugin class named with ``:Class``, registered if its module did
    not register it. ConfigError naming the one that fails."""
    named = []
    for index, item in enumerate(modules):
        module = PluginModule.from_text(item) if isinstance(item, str) else item
        try:
            if module.local:
                _import_file(module)
            loaded = importlib.import_module(module.name)
        except ConfigError:
            raise
        except Exception as error:  # noqa: BLE001 - any import failure is a config error
            raise ConfigError(
                f"{source}[{index}]: cannot import plugin module {module.name!r}: "
                f"{one_line(error)}{_beside_hint(module, error)}"
            ) from None
        if module.local and say is not None:
            where = getattr(loaded, "__file__", None) or module.file
            say(f"plugins: imported local module {module.name} from {where}")
        if module.attribute:
            named.append(_register(loaded, module.attribute, f"{source}[{index}]"))
    return named


def _register(module: object, attribute: str, where: str) -> tuple[str, str]:
    """(kind, name) of the plugin class ``module.attribute``, registered unless it is."""
    from workbench.plugin.formalism import Formalism
    from workbench.plugin.integrator import Integrator
    from workbench.plugin.problem import Problem
    from workbench.plugin.registry import REGISTRY

    plugin = getattr(module, attribute, None)
    bases = {"problem": Problem, "formalism": Formalism, "integrator": Integrator}
    kind = next(
        (k for k, base in bases.items() if isinstance(plugin, type) and issubclass(plugin, base)),
        None,
    )
    if kind is None:
        raise ConfigError(
            f"{where}: {getattr(module, '__name__', '?')}.{attribute} is not a problem, "
            "formalism or integrator class (a subclass of Problem, Formalism or Integrator)"
        )
    name = getattr(plugin, "name", "")
    REGISTRY.discover()
    existing = REGISTRY.entries[kind].get(name)
    if existing is not None and existing.plugin is not None and existing.plugin is not plugin:
        raise ConfigError(
            f"{where}: {kind} name {name!r} of {plugin.__qualname__} is already registered by "
            f"{existing.module}; give the class another name"
        )
    if existing is None or existing.plugin is not plugin:
        REGISTRY.add(kind, plugin)  # type: ignore[arg-type]
    return kind, name


def _import_file(module: PluginModule) -> None:
    """Import the top-level module or package of ``module`` from its file (once)."""
    top = module.name.partition(".")[0]
    file = Path(module.file)
    existing = sys.modules.get(top)
    if existing is not None:
        loaded = getattr(existing, "__file__", None)
        if loaded and Path(loaded).resolve() == file:
            return
        raise ConfigError(
            f"plugin module {top!r} ({file}): the name is taken by the module already "
            f"imported from {loaded or 'elsewhere'}; rename the file"
        )
    package = file.name == "__init__.py" and top != "__init__"
    spec = importlib.util.spec_from_file_location(
        top, file, submodule_search_locations=[str(file.parent)] if package else None
    )
    if spec is None or spec.loader is None:
        raise ConfigError(f"plugin module {top!r}: cannot import {file}")
    loaded_module = importlib.util.module_from_spec(spec)
    sys.modules[top] = loaded_module
    try:
        spec.loader.exec_module(loaded_module)
    except BaseException:
        sys.modules.pop(top, None)
        raise
    _FROM_FILES[top] = str(file)


def stderr_line(text: str) -> None:
    """Print one line on stderr (how the command line says which local modules it imported)."""
    print(text, file=sys.stderr, flush=True)


def is_class_reference(text: str) -> bool:
    """``text`` names a plugin class (``my_problem.py:MyProblem``, ``pkg.mod:Class``)
    where a registered name is expected (names never hold a colon)."""
    return ":" in text


def load_plugins(
    entries: Iterable[str] = (), references: Iterable[str] = (), allow_local: bool | None = None
) -> tuple[list[PluginModule], dict[str, str]]:
    """What ``--plugins`` and a ``MODULE_OR_FILE:Class`` argument do on the command line:
    find and import ``entries`` and the class ``references`` (local modules said on
    stderr, refused when ``allow_local`` is False, or None and ``WORKBENCH_NO_LOCAL_PLUGINS``
    is set); returns the modules (their
    :meth:`PluginModule.text` is what a worker process is given) and reference ->
    registered name."""
    references = [text for text in references if is_class_reference(text)]
    modules = find_plugin_modules(entries, "--plugins", None, allow_local)
    modules += find_plugin_modules(references, "plugin class", None, allow_local)
    named = import_plugin_modules(modules, "--plugins", say=stderr_line)
    if not references:
        return modules, {}
    # the references come last, one registered class each
    pairs = zip(references, named[-len(references) :], strict=True)
    return modules, {reference: name for reference, (_, name) in pairs}
