"""The layer contract of the core (docs/architecture.md): imports flow one way only.

Every module under ``workbench/`` belongs to a layer; a module may import its own layer
and the layers below, never one above, and no two modules may import each other through
any chain (imports inside functions count: they hid two cycles before). The built-in
plugins and the catalog import the core, never the other way round; the core names no
built-in plugin outside the built-in reference configuration.
"""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CORE = REPO / "workbench"

# lowest first; a module may import from its own layer and those before it
LAYERS = [
    "foundation",  # workbench.errors, workbench.files
    "numerics",
    "model",
    "mechanics",
    "equations",
    "plugin",
    "execution",  # one run: executed and measured (execute, metrics, references, row schema)
    "testing",  # the conformance kit: runs plugins, compares them with the references
    "runs",  # sweeps: spec, pools, the results store, resume
    "outputs",
    "api",  # the public Python API (workbench.run, sweep...): beside the CLI, not under it
    "cli",
    "facade",  # workbench/__init__.py, __main__.py and the deprecated re-export modules
]
FOUNDATION = {"workbench.errors", "workbench.files"}
FACADE = {
    "workbench",
    "workbench.__main__",
    # deprecated top-level names, kept for one release (docs/plugins.md)
    "workbench.problem",
    "workbench.formalism",
    "workbench.integrator",
    "workbench.registry",
    "workbench.options",
}


def module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer_of(module: str) -> str:
    if module in FOUNDATION:
        return "foundation"
    if module in FACADE:
        return "facade"
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in LAYERS:
        return parts[1]
    if len(parts) > 1 and parts[1] in ("plugins", "problems"):
        return "builtin"
    raise AssertionError(f"{module} belongs to no layer: move it into one of {LAYERS}")


def core_modules() -> dict[str, Path]:
    return {module_name(p): p for p in CORE.rglob("*.py")}


def _type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")
    )


def imports_of(path: Path, known: set[str]) -> set[str]:
    """The workbench modules ``path`` imports anywhere (functions included)."""
    this = module_name(path)
    package = this if path.name == "__init__.py" else this.rpartition(".")[0]
    found: set[str] = set()

    def resolve(name: str) -> str | None:
        while name and name not in known:
            name = name.rpartition(".")[0]
        return name or None

    def visit(node: ast.AST) -> None:
        if _type_checking(node):
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "workbench":
                    found.add(resolve(alias.name))
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            if base.split(".")[0] != "workbench":
                return
            if base == "workbench" and all(a.name == "__version__" for a in node.names):
                return  # a constant of the root package, not an import of its facade
            for alias in node.names:
                target = f"{base}.{alias.name}"
                found.add(target if target in known else resolve(base))
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(encoding="utf-8")))
    found.discard(None)
    found.discard(this)
    # importing a submodule imports its packages too, which import nothing upward by the
    # same contract; the edge that matters is the one to the module itself
    return found


def graph() -> dict[str, set[str]]:
    modules = core_modules()
    known = set(modules)
    return {name: imports_of(path, known) for name, path in modules.items()}


def test_every_core_module_is_in_a_layer():
    for module in core_modules():
        layer_of(module)


def test_no_import_runs_up_the_layers():
    upward = []
    for module, targets in graph().items():
        mine = LAYERS.index(layer_of(module))
        for target in targets:
            theirs = layer_of(target)
            if theirs == "builtin" or LAYERS.index(theirs) > mine:
                upward.append(f"{module} ({layer_of(module)}) imports {target} ({theirs})")
    assert not upward, "imports against the layers:\n" + "\n".join(sorted(upward))


def test_no_import_cycle_in_the_core():
    edges = graph()
    # packages import their own submodules (re-exports): a package -> its submodule edge is
    # not a cycle with a submodule that imports a sibling through the package
    cycles, state = [], {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = "open"
        stack.append(node)
        for target in sorted(edges.get(node, ())):
            if target.startswith(node + "."):
                continue  # a package re-exporting its own submodule
            if state.get(target) == "open":
                cycles.append(stack[stack.index(target) :] + [target])
            elif target not in state:
                visit(target, stack)
        stack.pop()
        state[node] = "done"

    for node in sorted(edges):
        if node not in state:
            visit(node, [])
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_builtins_import_the_core_never_the_reverse():
    # the core may name the built-in *packages* (discovery), never import their modules
    for module, targets in graph().items():
        assert not [t for t in targets if layer_of(t) == "builtin"], module


BUILTIN_NAMES = None


def builtin_plugin_names() -> set[str]:
    names = set()
    for folder in ("plugins", "problems"):
        for path in (REPO / folder).rglob("*.py"):
            names |= set(re.findall(r'^\s+name = "([a-z0-9-]+)"', path.read_text(), re.M))
    return names


def test_the_core_names_no_builtin_plugin():
    names = builtin_plugin_names()
    assert len(names) > 30  # the catalog, the formalisms and the integrators were found
    hyphenated = sorted(n for n in names if "-" in n)  # distinctive even in prose
    plain = sorted(n for n in names if "-" not in n)  # only as a quoted name
    pattern = re.compile(
        r"(?<![\w-])(" + "|".join(map(re.escape, hyphenated)) + r")(?![\w-])"
        + r"|[\"'`](" + "|".join(map(re.escape, plain)) + r")[\"'`]"
    )
    named = []
    for module, path in core_modules().items():
        if layer_of(module) == "testing":
            continue  # the conformance kit compares a plugin with the built-in ones by name
        for number, line in enumerate(path.read_text().splitlines(), 1):
            for match in pattern.finditer(line):
                named.append(f"{path.relative_to(REPO)}:{number}: {match.group(0)}")
    assert not named, "built-in plugin names in the core:\n" + "\n".join(named)


def test_installed_packages_are_namespaced_and_listed():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    listed = set(project["tool"]["setuptools"]["packages"])
    assert all(p == "workbench" or p.startswith("workbench.") for p in listed)
    directories = project["tool"]["setuptools"]["package-dir"]
    on_disk = {module_name(p) for p in CORE.rglob("__init__.py")}
    for package, folder in directories.items():
        for init in (REPO / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(REPO / folder).parts
            on_disk.add(".".join([package, *relative]))
    assert listed == on_disk, f"pyproject packages differ from the tree: {listed ^ on_disk}"


@pytest.mark.parametrize("name", ["plugins", "problems"])
def test_no_generic_top_level_name_is_installed(name):
    import importlib.util
    import sys

    saved = list(sys.path)
    try:
        sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO]
        assert importlib.util.find_spec(name) is None
    finally:
        sys.path[:] = saved


@pytest.mark.parametrize(
    ("old", "name"),
    [
        ("workbench.problem", "Problem"),
        ("workbench.formalism", "Formalism"),
        ("workbench.integrator", "Integrator"),
        ("workbench.registry", "formalism"),
        ("workbench.options", "parse_options"),
        ("workbench.runs.references", "given_reference"),  # one run moved to execution
    ],
)
def test_deprecated_module_names_still_work_and_say_so(old, name):
    import importlib
    import sys
    import warnings

    sys.modules.pop(old, None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert any(issubclass(w.category, DeprecationWarning) for w in caught)
    renamed = {"workbench.runs.references": "workbench.execution.references"}
    new = importlib.import_module(
        renamed.get(old) or old.replace("workbench.", "workbench.plugin.")
    )
    assert getattr(module, name) is getattr(new, name)
