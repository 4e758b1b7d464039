"""Registry (decorators, close matches, broken entry points) and typed plugin options."""

from __future__ import annotations

import sys
import textwrap
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from workbench.errors import ConfigError, PluginError
from workbench.plugin import registry as registry_module
from workbench.plugin.options import (
    NoOptions,
    option_fields,
    options_dict,
    parse_options,
    type_name,
)
from workbench.plugin.registry import Registry, describe_kind

FAKE_MODULES = ("fake_wb_plugins", "fake_wb_broken")

GOOD_MODULE = """
from dataclasses import dataclass
from typing import Literal

from workbench.model import Frame, Model
from workbench.plugin.problem import Problem


class ToyFormalism:
    name = "toy-formalism"
    summary = "A formalism that exists only in tests."
    capabilities = frozenset({"planar", "tree"})

    @dataclass(frozen=True)
    class Options:
        scheme: Literal["index3", "ggl"] = "index3"
        alpha: float = 5.0


class ToyIntegrator:
    name = "toy-integrator"
    summary = "An integrator that exists only in tests."
    accepts = {"ode": 0, "dae": 1}


class ToyPendulum(Problem):
    name = "toy-pendulum"
    summary = "A planar pendulum that exists only in tests."
    source = "test suite, no book section"

    def model(self):
        model = Model("toy-pendulum", kind="planar")
        model.add_point_mass("bob", 1.0)
        model.add_joint("pivot", "revolute", "ground", "bob", child_frame=Frame.at(1.0, 0.0))
        return model
"""


def write_fake_distribution(directory: Path) -> Path:
    """An installed-looking distribution with entry points in all three groups.

    ``toy-formalism``, ``toy-integrator`` and ``toy-pendulum`` work; ``broken-formalism``
    points to a module that raises ImportError. Put ``directory`` on sys.path (or
    PYTHONPATH) for importlib.metadata to find it.
    """
    info = directory / "fake_wb_plugins-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-wb-plugins\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        textwrap.dedent(
            """\
            [workbench.formalisms]
            toy-formalism = fake_wb_plugins:ToyFormalism
            broken-formalism = fake_wb_broken:BrokenFormalism

            [workbench.integrators]
            toy-integrator = fake_wb_plugins:ToyIntegrator

            [workbench.problems]
            toy-pendulum = fake_wb_plugins:ToyPendulum
            """
        )
    )
    (directory / "fake_wb_plugins.py").write_text(GOOD_MODULE)
    (directory / "fake_wb_broken.py").write_text(
        'raise ImportError("fake_wb_broken needs libfoo; pip install libfoo")\n'
    )
    return directory


@pytest.fixture
def fake_distribution(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(write_fake_distribution(tmp_path)))
    yield tmp_path
    for name in FAKE_MODULES:
        sys.modules.pop(name, None)


def entry_points_only() -> Registry:
    """A fresh registry that discovers entry points but no built-in packages."""
    return Registry(builtin_packages={})


# -- registration ----------------------------------------------------------------------
def test_decorators_register_in_the_global_registry(monkeypatch):
    fresh = entry_points_only()
    fresh.discovered = True  # nothing to discover: only what the decorators add
    monkeypatch.setattr(registry_module, "REGISTRY", fresh)

    @registry_module.formalism
    class Lagrange:
        name = "lagrange-test"
        summary = "test formalism"

    @registry_module.integrator
    class Euler:
        name = "euler-test"

    assert registry_module.get_formalism("lagrange-test") is Lagrange
    assert registry_module.get_integrator("euler-test") is Euler
    assert registry_module.plugin_names("formalism") == ["lagrange-test"]
    assert registry_module.list_plugins("formalism")[0].summary == "test formalism"
    assert registry_module.any_plugin("euler-test") == ("integrator", Euler)


def test_plugin_without_name_is_refused():
    class Nameless:
        pass

    with pytest.raises(PluginError, match="no name"):
        Registry().add("formalism", Nameless)


def test_options_must_be_a_dataclass():
    class BadOptions:
        name = "bad-options"

        class Options:
            rtol: float = 1e-6

    with pytest.raises(PluginError, match="dataclass"):
        Registry().add("integrator", BadOptions)


def test_duplicate_name_from_another_module_warns_and_keeps_the_first():
    registry = entry_points_only()
    first = type("First", (), {"name": "same", "__module__": "one"})
    second = type("Second", (), {"name": "same", "__module__": "two"})
    registry.add("problem", first)
    with pytest.warns(UserWarning, match="already registered"):
        registry.add("problem", second)
    registry.discovered = True
    assert registry.get("problem", "same") is first


def test_reimported_module_replaces_its_class_silently():
    registry = entry_points_only()
    old = type("Old", (), {"name": "same", "__module__": "mod"})
    new = type("New", (), {"name": "same", "__module__": "mod"})
    registry.add("problem", old)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        registry.add("problem", new)
    registry.discovered = True
    assert registry.get("problem", "same") is new


def test_unknown_name_suggests_close_matches():
    registry = entry_points_only()
    registry.discovered = True
    for name in ("double-pendulum", "simple-pendulum", "heavy-top"):
        registry.add("problem", type(name, (), {"name": name}))
    with pytest.raises(PluginError, match="did you mean double-pendulum") as caught:
        registry.get("problem", "double-pendlum")
    assert "unknown problem 'double-pendlum'" in str(caught.value)
    with pytest.raises(PluginError, match="did you mean heavy-top"):
        registry.get("problem", "Heavy_Top")
    with pytest.raises(PluginError, match="known: double-pendulum, heavy-top"):
        registry.get("problem", "zzz")
    with pytest.raises(PluginError, match="no formalism is registered"):
        registry.get("formalism", "zzz")


def test_unknown_kind_is_a_plugin_error():
    with pytest.raises(PluginError, match="unknown plugin kind"):
        entry_points_only().list("solver")  # type: ignore[arg-type]
    assert describe_kind("Formalisms") == "formalism"
    assert describe_kind("integrator") == "integrator"
    with pytest.raises(PluginError, match="did you mean problems"):
        describe_kind("problemz")


# -- discovery through entry points ----------------------------------------------------
def test_broken_entry_point_is_listed_and_the_others_still_work(fake_distribution):
    registry = entry_points_only()
    formalisms = {info.name: info for info in registry.list("formalism")}
    assert {"toy-formalism", "broken-formalism"} <= set(formalisms)

    broken = formalisms["broken-formalism"]
    assert broken.status == "broken" and broken.plugin is None
    assert broken.error_line == "ImportError: fake_wb_broken needs libfoo; pip install libfoo"
    assert "needs libfoo" in broken.summary
    with pytest.raises(PluginError, match="'broken-formalism' is broken: ImportError"):
        registry.get("formalism", "broken-formalism")

    assert formalisms["toy-formalism"].status == "ok"
    toy = registry.get("formalism", "toy-formalism")
    assert toy.capabilities == frozenset({"planar", "tree"})
    assert registry.get("integrator", "toy-integrator").accepts == {"ode": 0, "dae": 1}
    assert registry.get("problem", "toy-pendulum").source
    # the global registry saw none of it
    assert "toy-formalism" not in registry_module.REGISTRY.entries["formalism"]


def test_discovery_runs_once(fake_distribution):
    registry = entry_points_only()
    registry.list("formalism")
    sys.modules.pop("fake_wb_plugins")
    registry.list("formalism")
    assert "fake_wb_plugins" not in sys.modules


def test_broken_builtin_module_is_listed(tmp_path, monkeypatch):
    package = tmp_path / "fake_wb_builtin"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "good_one.py").write_text("")
    (package / "bad_one.py").write_text("import numpy_that_does_not_exist\n")
    (package / "_private.py").write_text("raise RuntimeError('never imported')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    registry = Registry(builtin_packages={"formalism": "fake_wb_builtin"}, entry_point_groups={})
    try:
        infos = registry.list("formalism")
    finally:
        for name in [m for m in sys.modules if m.startswith("fake_wb_builtin")]:
            sys.modules.pop(name)
    assert [(info.name, info.status) for info in infos] == [("bad-one", "broken")]
    assert "ModuleNotFoundError" in infos[0].error_line


def test_a_broken_module_s_error_line_is_the_whole_error_on_one_line(tmp_path, monkeypatch):
    package = tmp_path / "fake_wb_multiline"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "bad.py").write_text("raise ImportError('needs libfoo\\ninstall it with pip')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    registry = Registry(builtin_packages={"formalism": "fake_wb_multiline"}, entry_point_groups={})
    try:
        (info,) = registry.list("formalism")
    finally:
        for name in [m for m in sys.modules if m.startswith("fake_wb_multiline")]:
            sys.modules.pop(name)
    assert info.error_line == "ImportError: needs libfoo | install it with pip"
    assert info.error.startswith("Traceback") and "bad.py" in info.error  # the whole story


def test_missing_builtin_package_is_listed_as_broken():
    registry = Registry(builtin_packages={"problem": "no_such_package_wb"}, entry_point_groups={})
    (info,) = registry.list("problem")
    assert info.status == "broken" and "No module named" in info.error_line


# -- options ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SolverOptions:
    rtol: float = 1e-6
    max_steps: int = 10_000
    method: Literal["bdf", "radau"] = "bdf"
    verbose: bool = False
    label: str = ""
    stabilization: float | None = None

    def __post_init__(self) -> None:
        if self.rtol <= 0:
            raise ConfigError(f"rtol must be positive, not {self.rtol}")


def parse(values):
    return parse_options(SolverOptions, values, "integrator 'toy'")


def test_defaults_and_values():
    assert parse(None) == SolverOptions()
    assert parse({}) == SolverOptions()
    options = parse({"rtol": 1e-8, "method": "radau", "verbose": True, "max_steps": 5})
    assert options == SolverOptions(rtol=1e-8, max_steps=5, method="radau", verbose=True)
    assert parse(options) is options
    assert options_dict(options)["method"] == "radau"


def test_unknown_option_suggests_the_close_name():
    with pytest.raises(ConfigError) as caught:
        parse({"rtoll": 1e-3})
    message = str(caught.value)
    assert message.startswith("integrator 'toy': unknown option 'rtoll'")
    assert "did you mean rtol?" in message
    assert "valid options: rtol, max_steps, method, verbose, label, stabilization" in message


def test_wrong_type_names_the_expected_type():
    with pytest.raises(ConfigError, match="option 'max_steps' must be of type int, not str"):
        parse({"max_steps": "10"})
    with pytest.raises(ConfigError, match="option 'max_steps' must be of type int, not float"):
        parse({"max_steps": 10.5})
    with pytest.raises(ConfigError, match="option 'verbose' must be of type bool"):
        parse({"verbose": 1})
    with pytest.raises(ConfigError, match="option 'rtol' must be of type float, not bool"):
        parse({"rtol": True})
    with pytest.raises(ConfigError) as caught:  # -o label=3 reads a number: say how to quote
        parse({"label": 3})
    assert """(text in quotes: -o 'label="3"', in TOML label = "3")""" in str(caught.value)
    with pytest.raises(ConfigError, match="must be a table"):
        parse([("rtol", 1e-3)])



def test_container_options_are_checked_item_by_item():
    """tuple, list and dict options were taken as given: "abc" for a pair of floats ran."""

    @dataclass(frozen=True)
    class Weights:
        pair: tuple[float, float] = (1.0, 2.0)
        many: tuple[float, ...] = ()
        counts: list[int] = field(default_factory=list)
        scales: dict[str, float] = field(default_factory=dict)

    parsed = parse_options(Weights, {"pair": [1, 2], "many": [3], "counts": [4],
                                     "scales": {"a": 1}}, "x")  # fmt: skip
    assert parsed == Weights((1.0, 2.0), (3.0,), [4], {"a": 1.0})
    assert isinstance(parsed.pair[0], float) and isinstance(parsed.pair, tuple)
    for bad in ({"pair": "abc"}, {"pair": "(1,2)"}, {"pair": [1, 2, 3]}, {"pair": ["a", 2]},
                {"many": 3.0}, {"counts": [1.5]}, {"scales": [1]}, {"scales": {"a": "b"}}):
        name = next(iter(bad))
        with pytest.raises(ConfigError, match=f"option '{name}' must be of type"):
            parse_options(Weights, bad, "x")

def test_literal_choices():
    expected = "option 'method' must be one of 'bdf', 'radau', not 'rk4'"
    with pytest.raises(ConfigError, match=expected):
        parse({"method": "rk4"})


def test_literal_does_not_confuse_bool_and_int():
    @dataclass(frozen=True)
    class Order:
        order: Literal[1, 2] = 1

    assert parse_options(Order, {"order": 2}, "x").order == 2
    with pytest.raises(ConfigError, match="must be one of 1, 2"):
        parse_options(Order, {"order": True}, "x")


def test_int_is_coerced_to_float():
    options = parse({"rtol": 1})
    assert options.rtol == 1.0 and isinstance(options.rtol, float)


def test_optional_option():
    assert parse({"stabilization": None}).stabilization is None
    assert parse({"stabilization": 2}).stabilization == 2.0
    with pytest.raises(ConfigError, match="must be of type float | None"):
        parse({"stabilization": "strong"})


def test_post_init_range_check_names_the_owner():
    with pytest.raises(ConfigError, match="integrator 'toy': rtol must be positive"):
        parse({"rtol": -1.0})


def test_option_fields_and_type_names():
    rows = option_fields(SolverOptions)
    assert [name for name, _, _ in rows][:3] == ["rtol", "max_steps", "method"]
    assert rows[0][2] == 1e-6
    names = {name: type_name(annotation) for name, annotation, _ in rows}
    assert names["method"] == "'bdf' | 'radau'"
    assert names["stabilization"] == "float | None"
    assert option_fields(NoOptions) == []


def test_a_plugin_whose_decorator_was_forgotten_is_named_with_the_fix(tmp_path, monkeypatch):
    """`unknown integrator 'my-euler'; known: <26 names>` did not say that my_euler.py,
    imported, defines it without @integrator; the kit even suggested the --plugins flag
    that had been given."""
    import importlib

    (tmp_path / "forgot_decorator.py").write_text(textwrap.dedent('''
        from workbench.plugin.integrator import Integrator

        class Forgotten(Integrator):
            name = "test-forgotten"
            summary = "no decorator (test)"
            accepts = {"ode": 0}
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "forgot_decorator", raising=False)
    importlib.import_module("forgot_decorator")
    try:
        with pytest.raises(PluginError) as caught:
            registry_module.REGISTRY.get("integrator", "test-forgotten")
        message = str(caught.value)
        assert "forgot_decorator.py defines Forgotten(Integrator) named 'test-forgotten'" in message
        assert "put @integrator" in message and "forgot_decorator.py:Forgotten" in message
    finally:
        sys.modules.pop("forgot_decorator", None)


def test_a_plugin_file_here_that_was_not_imported_is_named(tmp_path, monkeypatch):
    """`workbench run ... -i my-midpoint` beside my_midpoint.py listed 26 known names."""
    (tmp_path / "test_not_imported.py").write_text("# a plugin nobody named\n")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(PluginError) as caught:
        registry_module.REGISTRY.get("integrator", "test-not-imported")
    assert "./test_not_imported.py is not imported unless named: add --plugins " in str(
        caught.value
    )


def test_non_default_options_name_only_what_differs_from_a_registered_plugins_defaults():
    """A run's label keeps the options that differ from the plugin's defaults; for a name
    no plugin has here (a run recorded elsewhere), all of them; a robot file's run is the
    robot problem's, whose defaults are known."""
    options = {"index": 3, "compile": "jit", "baumgarte_alpha": 10.0}
    assert registry_module.non_default_options("formalism", "minimal-ode", options) == {
        "compile": "jit"
    }
    assert registry_module.non_default_options("formalism", "no-such-formalism", options) == options
    robot = registry_module.REGISTRY.find("problem", "ur5.urdf")
    assert robot is not None and robot.name == "robot"
    assert registry_module.REGISTRY.find("problem", "no-such-problem") is None
    assert registry_module.non_default_options("nonsense", "minimal-ode", options) == options
