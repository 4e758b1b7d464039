"""A problem plugin that breaks the contract of workbench.plugin.problem gets one line
naming the method and the fix, from a run and from ``workbench describe`` alike (they
were an AttributeError on None and dict()'s TypeError, a traceback from describe); an
invariant or a reference of the wrong shape is named with its shape."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

import workbench
from workbench.cli import app
from workbench.errors import PluginError
from workbench.model import Model
from workbench.plugin.problem import Invariant, Problem, Reference
from workbench.plugin.registry import REGISTRY


def rod(name: str) -> Model:
    """A rod on a revolute joint from the ground."""
    model = Model(name, kind="planar")
    model.add_body("rod", 1.0, com=(0.5, 0.0, 0.0), inertia=0.1)
    model.add_joint("pivot", "revolute", "ground", "rod")
    return model


class ForgetsToReturn(Problem):
    """model() builds a pendulum and forgets its return."""

    name = "forgets-to-return"
    summary = "model() without its return"
    source = "tests"

    def model(self):
        rod(self.name)


class ListOfCoordinates(Problem):
    """initial_joint_coordinates() gives a list instead of {joint: value}."""

    name = "list-of-coordinates"
    summary = "initial coordinates as a list"
    source = "tests"

    def model(self):
        return rod(self.name)

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


class Pendulum(Problem):
    """A rod (1 kg, 1 m) on a revolute joint, released at 0.3 rad: a correct problem that
    the two below break in one method each."""

    name = "contract-pendulum"
    summary = "a pendulum for the contract's tests"
    source = "tests"
    t_end, n_samples = 0.5, 11

    def model(self):
        model = Model(self.name, kind="planar")
        model.add_body("rod", 1.0, com=(0.5, 0.0, 0.0), inertia=1.0 / 12)
        model.add_joint("pivot", "revolute", "ground", "rod")
        return model

    def initial_joint_coordinates(self):
        return {"pivot": -1.27}


class VectorInvariant(Pendulum):
    """An invariant written for a whole trajectory (twists[:, 3:6], the angular velocity
    at every sample) but not declared vectorized: at one sample it gives every body's."""

    name = "contract-vector-invariant"

    def invariants(self):
        return [Invariant("spin", lambda model, t, poses, twists: twists[:, 3:6])]


class FlatReference(Pendulum):
    """An analytic reference without the bodies' axis: (n, 7) for (n, 1, 7)."""

    name = "contract-flat-reference"

    def reference(self):
        return Reference("analytic", lambda times: np.tile([0.0, 0, 0, 1, 0, 0, 0],
                                                           (len(times), 1)))


def test_an_invariant_giving_a_vector_names_its_shape() -> None:
    """It was 'TypeError: only 0-dimensional arrays can be converted to Python scalars'."""
    row = workbench.run(VectorInvariant, "minimal-ode", "scipy-dop853", rtol=1e-6).row
    assert row["status"] == "failed"
    assert "invariant 'spin' returned shape (1, 3) for one sample (expected a number)" in (
        row["message"]
    )


def test_a_reference_of_the_wrong_shape_is_named_and_left_out() -> None:
    """The run fails no more with 'operands could not be broadcast together': it runs
    without a reference and its notes give the shapes."""
    row = workbench.run(FlatReference, "minimal-ode", "scipy-dop853", rtol=1e-6).row
    assert row["status"] == "ok" and math.isnan(row["scd"])
    assert "no reference: the analytic reference's poses(times) has shape (11, 7), expected " \
        "(11, 1, 7)" in row["notes"]
