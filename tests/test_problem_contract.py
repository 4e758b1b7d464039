"""A problem plugin that breaks the contract of workbench.plugin.problem gets one line
naming the method and the fix, from a run and from ``workbench describe`` alike (they
were an AttributeError on None and dict()'s TypeError, a traceback from describe)."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from workbench.cli import app
from workbench.errors import PluginError
from workbench.model import Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import REGISTRY


class ForgetsToReturn(Problem):
    """model() builds a pendulum and forgets its return."""

    name = "forgets-to-return"
    summary = "model() without its return"
    source = "tests"

    def model(self):
        model = Model(self.name, kind="planar")
        model.add_body("rod", 1.0, com=(0.5, 0.0, 0.0), inertia=0.1)
        model.add_joint("pivot", "revolute", "ground", "rod")


class ListOfCoordinates(Problem):
    """initial_joint_coordinates() gives a list instead of {joint: value}."""

    name = "list-of-coordinates"
    summary = "initial coordinates as a list"
    source = "tests"

    def model(self):
        model = Model(self.name, kind="planar")
        model.add_body("rod", 1.0, com=(0.5, 0.0, 0.0), inertia=0.1)
        model.add_joint("pivot", "revolute", "ground", "rod")
        return model

    def initial_joint_coordinates(self):
        return [0.3]


CASES = {
    ForgetsToReturn: r"model\(\) returned NoneType, not a workbench.model.Model",
    ListOfCoordinates: r"initial_joint_coordinates\(\) returned list, not a mapping",
}


@pytest.mark.parametrize("plugin", list(CASES), ids=lambda p: p.name)
def test_model_names_the_broken_method(plugin) -> None:
    with pytest.raises(PluginError, match=rf"problem '{plugin.name}': {CASES[plugin]}"):
        plugin().model()


@pytest.mark.parametrize("plugin", list(CASES), ids=lambda p: p.name)
def test_describe_says_it_in_one_line(plugin) -> None:
    REGISTRY.discover()
    saved = dict(REGISTRY.entries["problem"])
    REGISTRY.add("problem", plugin)
    try:
        result = CliRunner().invoke(app, ["describe", plugin.name])
    finally:
        REGISTRY.entries["problem"] = saved
    assert result.exit_code != 0
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and f"problem '{plugin.name}'" in lines[0], result.output
