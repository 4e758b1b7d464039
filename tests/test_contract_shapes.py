"""A formalism's :class:`MechanicalSystem` of the wrong shape is refused at once, naming the
field and the size it should have: a forces vector one row too long reached CasADi and
came back as ``matrix_impl.hpp:2327: Assertion "p.size()==n" failed``, in a run's row and
in the conformance kit alike."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import pytest

import workbench as wb
from tests.test_report_stalled import template_formalism
from tests.test_scaffold import isolated_registry  # noqa: F401 - a fixture
from workbench.equations.contract import MechanicalSystem
from workbench.errors import PluginError
from workbench.testing import check_formalism


def system(**changed) -> MechanicalSystem:
    """A planar two-link system in joint coordinates (nq = nv = 2), with ``changed`` fields."""
    t, q, v = ca.SX.sym("t"), ca.SX.sym("q", 2), ca.SX.sym("v", 2)
    fields = dict(t=t, q=q, v=v, qdot=v, mass=ca.SX.eye(2), forces=-ca.sin(q),
                  q_names=["a", "b"], v_names=["a", "b"])  # fmt: skip
    return MechanicalSystem(**(fields | changed))


@pytest.mark.parametrize(
    "changed, message",
    [
        ({"forces": ca.SX.zeros(3)}, "MechanicalSystem.forces has 3 rows, expected nv = 2"),
        ({"mass": ca.SX.zeros(2, 3)}, "MechanicalSystem.mass is 2 x 3, expected nv x nv = 2 x 2"),
        ({"qdot": ca.SX.zeros(1)}, "MechanicalSystem.qdot has 1 rows, expected nq = 2"),
        ({"forces": ca.SX.zeros(1, 2)}, "MechanicalSystem.forces is 1 x 2, expected nv = 2"),
        ({"v_names": ["a"]}, "MechanicalSystem.v_names has 1 names, expected 2"),
        ({"position_constraints": ca.SX.sym("g", 1)},
         "velocity_constraints has 0 rows, expected a column of at least the 1 position"),
        ({"forces": [0.0, 0.0]}, "MechanicalSystem.forces is list, expected a CasADi expression"),
    ],  # fmt: skip
)
def test_a_field_of_the_wrong_shape_is_named(changed, message) -> None:
    with pytest.raises(PluginError, match=message.replace("(", r"\(")):
        system(**changed)


def test_the_right_shapes_pass() -> None:
    g = ca.SX.sym("g")
    built = system(position_constraints=g, velocity_constraints=ca.vertcat(g, g),
                   constraint_names=["g", "g_dot"], acceleration=ca.SX.zeros(2))  # fmt: skip
    assert (built.n_holonomic, built.n_constraints) == (1, 2)


def test_a_run_and_the_kit_name_the_field(tmp_path: Path, isolated_registry: None) -> None:  # noqa: F811
    # the scaffold's module, written with a forces vector of nv + 1 rows
    formalism = template_formalism(tmp_path, "long-forces", "ca.SX.zeros(k.nv + 1)")
    with pytest.warns(RuntimeWarning):
        row = wb.run("double-pendulum", formalism, "scipy-dop853").row
    assert row["status"] == "failed"
    assert "MechanicalSystem.forces has 3 rows, expected nv = 2" in row["message"]
    assert "matrix_impl" not in row["message"]
    report = check_formalism(formalism, ["double-pendulum"])
    failures = {result.check: result.message for result in report.failures}
    assert "MechanicalSystem.forces has 3 rows, expected nv = 2" in failures["build"]
