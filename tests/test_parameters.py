"""workbench.model.parameters: the rows ``workbench describe`` prints are the model's numbers."""

from __future__ import annotations

import numpy as np

from workbench.model import Frame, Model
from workbench.model.parameters import joint_state, model_parameters, vector
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


def test_joint_states_carry_the_units_of_their_joint_type() -> None:
    assert joint_state("revolute", -0.0, velocities=True) == "0 rad/s"
    assert joint_state("prismatic", 0.5, velocities=False) == "0.5 m"
    assert joint_state("spherical", [1, 0, 0, 0], velocities=False) == "(1, 0, 0, 0)"
    assert (
        joint_state("free", [1, 2, 3, 4, 5, 6], velocities=True) == "(1, 2, 3) m/s, (4, 5, 6) rad/s"
    )
    assert joint_state("planar", [1, 2, 3], velocities=False) == "(1, 2) m, 3 rad"
    assert joint_state("revolute", [1, 2], velocities=False) == "(1, 2)"  # sizes differ: no unit


def test_a_drive_and_a_joint_torque_are_shown_as_the_laws_the_model_integrates() -> None:
    """qa3d F5: ``function RotatingRing.model.<locals>.<lambda>(...)`` hid the ring's rate."""
    from workbench.problems import ch5_point_masses, ch7_spatial

    rows = rows_of(get_problem("rotating-ring")().model())
    rate = ch5_point_masses.RING_RATE
    assert rows[("spin", "driven (rheonomic)")] == f"q(t) = {rate:g}*t rad, q'(t) = {rate:g} rad/s"
    rows = rows_of(get_problem("two-joint-robot")().model())
    amplitude, frequency = ch7_spatial.BASE_TORQUE_AMPLITUDE, ch7_spatial.BASE_TORQUE_FREQUENCY
    law = rows[("base_torque", "joint force on base")]
    assert law == f"Q(t, q, v) = {amplitude:g}.*sin(({frequency:g}.*t)) N m"
    pd = rows[("shoulder_torque", "joint force on shoulder")]
    assert f"{ch7_spatial.SHOULDER_STIFFNESS:g}*(q-{ch7_spatial.SHOULDER_TARGET:g})" in pd
    assert f"{ch7_spatial.SHOULDER_DAMPING:g}*v" in pd and pd.endswith(" N m")


def test_a_law_that_takes_no_symbols_is_shown_by_its_name() -> None:
    from workbench.model import Drive

    def table(t: float) -> float:
        return float(np.interp(t, [0.0, 1.0], [0.0, 2.0]))  # float(): no CasADi symbol

    model = Model("m", kind="planar")
    model.add_body("a", 1.0, inertia=1.0)
    model.add_joint("j", "revolute", "ground", "a", drive=Drive(position=table))
    text = rows_of(model)[("j", "driven (rheonomic)")]
    assert "table" in text and text.startswith("function ")
