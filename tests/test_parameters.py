"""workbench.model.parameters: the rows ``workbench describe`` prints are the model's numbers."""

from __future__ import annotations

import numpy as np

from workbench.model import Frame, Model
from workbench.model.parameters import model_parameters, vector
from workbench.plugin.registry import get_problem
from workbench.problems import double_pendulum


def rows_of(model: Model) -> dict[tuple[str, str], str]:
    return {(element, quantity): value for element, quantity, value in model_parameters(model)}


def test_double_pendulum_rows_follow_the_book_formulas() -> None:
    rows = rows_of(get_problem("double-pendulum")().model())
    (l1, l2), (m1, m2) = double_pendulum.LENGTHS, double_pendulum.MASSES
    assert rows[("model", "gravity")] == "(0, -9.81) m/s^2"
    assert rows[("link2", "mass")] == f"{m2:.4g} kg"
    assert rows[("link2", "centre of mass (body frame)")] == f"(0, {-l2 / 2:.4g}) m"
    # uniform bar about its centre: m l^2 / 12
    assert rows[("link2", "Izz about the centre of mass")] == f"{m2 * l2**2 / 12:.4g} kg m^2"
    assert rows[("joint2", "type")] == "revolute: link1 -> link2"
    assert rows[("joint2", "location on the parent")] == f"(0, {-l1:.4g}) m"
    assert m1 > 0  # both links listed
    assert ("link1", "mass") in rows


def test_spatial_rows_full_inertia_axes_springs_and_point_masses() -> None:
    model = Model("m", kind="spatial")
    inertia = np.array([[2.0, 0.1, 0.0], [0.1, 3.0, 0.0], [0.0, 0.0, 4.0]])
    model.add_body("a", 1.5, com=(0.0, 0.0, 0.2), inertia=inertia)
    model.add_point_mass("b", 0.25)
    model.add_joint("j", "universal", "ground", "a", axis=(1, 0, 0), axis2=(0, 0, 1))
    model.add_joint("k", "prismatic", "a", "b", parent_frame=Frame.at(0.0, 0.5, 0.0))
    from workbench.model import JointSpringDamper, SpringDamper

    model.add_force(JointSpringDamper("spring", "k", stiffness=100.0, damping=2.0, rest=0.1))
    model.add_force(SpringDamper("rope", "ground", np.zeros(3), "b", np.zeros(3), 50.0))
    rows = rows_of(model)
    assert (
        rows[("a", "inertia about the centre of mass")] == "[2, 0.1, 0; 0.1, 3, 0; 0, 0, 4] kg m^2"
    )
    assert rows[("b", "point mass")] == "0.25 kg" and ("b", "mass") not in rows
    assert rows[("j", "axis")] == "(1, 0, 0)" and rows[("j", "second axis")] == "(0, 0, 1)"
    assert rows[("spring", "joint spring-damper on k")] == "100 N/m, 2 N s/m, rest 0.1 m"
    assert rows[("rope", "stiffness, damping, rest length")] == "50 N/m, 0 N s/m, 0 m"


def test_round_off_shows_as_zero() -> None:
    assert vector([np.cos(np.pi / 2), 0.5, 0.0], planar=True) == "(0, 0.5)"
    assert vector([2e-5, 0.0, 0.0]) == "(2e-05, 0, 0)"  # small, not round-off: kept
