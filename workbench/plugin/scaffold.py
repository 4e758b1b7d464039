"""``workbench new formalism|integrator|problem NAME``: write a ready-to-edit plugin.

Three layouts (:func:`scaffold`):

* ``--package DIR``: a separate installable package: ``DIR/pyproject.toml`` with the
  entry point in the group the registry reads (``workbench.formalisms`` ...),
  ``DIR/<module>/plugin.py`` and ``DIR/tests/test_<module>.py``;
* inside a workbench source tree (the current directory has ``plugins/`` and
  ``problems/``): a built-in plugin, ``plugins/formalisms/<module>.py`` (or
  ``plugins/integrators/``, ``problems/``) and ``tests/test_<module>.py``;
* elsewhere: ``<module>.py`` and ``test_<module>.py`` in the current directory (a
  module-only plugin: ``--plugins <module>.py`` on ``workbench run``, ``describe``,
  ``sweep`` and ``python -m workbench.testing``, or ``plugins = ["<module>"]`` in a sweep).

The plugin module has the contract's methods and docstrings; the physics (a formalism's
mass matrix and forces, an integrator's method) raises NotImplementedError until written.
As generated, the plugin registers, lists and passes the structural checks but
``metadata``, which fails until the TODO summary and docstring are written. A problem is
a planar pendulum, or with ``spatial=True`` a body on a spherical joint (quaternion
coordinates). The test module runs the conformance suite; it needs pytest, which a
package's ``test`` extra installs (``pip install -e "DIR[test]"``). A package ships the
stored references of its ``references/`` directory (package data) in its wheel.
"""

from __future__ import annotations

import keyword
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from string import Template

from workbench.errors import ConfigError
from workbench.plugin.registry import ENTRY_POINT_GROUPS, KINDS, Kind, plugin_names

NAME = re.compile(r"^[a-z][a-z0-9]*(?:[-_][a-z0-9]+)*$")
BUILTIN_DIRECTORIES = {
    "formalism": "plugins/formalisms",
    "integrator": "plugins/integrators",
    "problem": "problems",
}


REFERENCES_README = """Stored references of this package's problem.

`workbench reference NAME` writes NAME.npz and NAME.json here (beside the module that
defines the problem); pyproject.toml ships them in the wheel as package data, so an
installed package compares runs against the same reference.
"""


@dataclass
class Scaffold:
    """What :func:`scaffold` wrote and what to do next."""

    files: list[Path] = field(default_factory=list)
    next_steps: list[str] = field(default_factory=list)


def check_name(name: str) -> str:
    """The Python module name for plugin ``name``; ConfigError if ``name`` is not valid."""
    module = name.replace("-", "_")
    if not NAME.match(name) or keyword.iskeyword(module) or not module.isidentifier():
        raise ConfigError(
            f"plugin name {name!r} is not valid: use lowercase letters, digits and '-' "
            "starting with a letter (e.g. my-formalism); it also names the Python module"
        )
    return module


def _render(template: str, values: dict[str, str]) -> str:
    text = resources.files("workbench.plugin").joinpath("templates", template).read_text("utf-8")
    return Template(text).substitute(values)


def scaffold(
    kind: str,
    name: str,
    package: str | Path | None = None,
    force: bool = False,
    where: str | Path = ".",
    spatial: bool = False,
) -> Scaffold:
    """Write the plugin ``name`` of ``kind`` (see the module docstring); returns the files.

    Refuses (ConfigError) to overwrite an existing file unless ``force``; ``where`` is the
    directory that counts as current; ``spatial``: a problem's spatial placeholder.
    """
    if kind not in KINDS:
        raise ConfigError(f"unknown plugin kind {kind!r}; use one of {', '.join(KINDS)}")
    kind_: Kind = kind  # type: ignore[assignment]
    module = check_name(name)
    if name in plugin_names(kind_):
        article = "an" if kind[0] in "aeiou" else "a"
        raise ConfigError(
            f"{article} {kind} named {name!r} is already registered; choose another name"
        )
    class_name = "".join(part.capitalize() for part in module.split("_"))
    where = Path(where)
    values = {"name": name, "kind": kind, "module": module, "class_name": class_name}
    files: dict[Path, str] = {}
    if spatial and kind != "problem":
        raise ConfigError("--spatial is for problems only (a spatial placeholder mechanism)")
    plugin_text = _render(f"{kind}_spatial.py.tmpl" if spatial else f"{kind}.py.tmpl", values)
    if package is not None:
        root = where / Path(package)
        values |= {
            "package": module,
            "module": "plugin",
            "distribution": f"workbench-{name}",
            "group": ENTRY_POINT_GROUPS[kind_],
        }
        files[root / "pyproject.toml"] = _render("pyproject.toml.tmpl", values)
        files[root / module / "__init__.py"] = f'"""The {kind} {name} for mbs-workbench."""\n'
        files[root / module / "plugin.py"] = plugin_text
        test_path = root / "tests" / f"test_{module}.py"
        import_line = ""  # found through its entry point
        if kind == "problem":
            files[root / module / "references" / "README.md"] = REFERENCES_README
        steps = [
            f'pip install -e "{root}[test]"   # registers {name!r}; [test] installs pytest',
            f"workbench list {kind}s",
            f"python -m workbench.testing {kind} {name}",
            f"pytest {root / 'tests'}",
        ]
    elif all((where / d).is_dir() for d in ("plugins", "problems")):
        directory = BUILTIN_DIRECTORIES[kind_]
        files[where / directory / f"{module}.py"] = plugin_text
        test_path = where / "tests" / f"test_{module}.py"
        import_line = ""  # built-in plugins are discovered
        steps = [
            f"workbench list {kind}s",
            f"python -m workbench.testing {kind} {name}",
            f"pytest {test_path}",
        ]
    else:
        files[where / f"{module}.py"] = plugin_text
        test_path = where / f"test_{module}.py"
        import_line = f"\nimport {module}  # noqa: F401, E402 - importing it registers the plugin\n"
        steps = [
            f"python -m workbench.testing {kind} {name} --plugins {module}.py",
            f"pytest {test_path}   # needs pytest: pip install pytest",
            f"workbench describe {name} --plugins {module}.py",
            f'in a sweep spec: plugins = ["{module}"] or --plugins {module}.py '
            "(or use --package for a package)",
        ]
    files[test_path] = _render(
        "test_plugin.py.tmpl", values | {"import_line": import_line, "module": module}
    )
    existing = [path for path in files if path.exists()]
    if existing and not force:
        raise ConfigError(
            f"{existing[0]} already exists; choose another name or pass --force to overwrite"
        )
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return Scaffold(list(files), steps)
