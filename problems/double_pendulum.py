"""Double pendulum of two rigid uniform links (book 6.7.1), planar, 2 DOF.

Model (planar; x to the right, y up; SI units):

- body ``link1``: uniform bar, length l1 = 1.0 m, mass m1 = 1.0 kg; body frame at its
  upper end (the pivot), the bar along the body's -y axis, centre of mass (0, -l1/2, 0),
  Izz = m1 l1^2 / 12 = 0.08333 kg m^2 about the centre of mass;
- body ``link2``: uniform bar, l2 = 0.8 m, m2 = 0.8 kg (same 1 kg/m), frame at its upper
  end, com (0, -l2/2, 0), Izz = m2 l2^2 / 12 = 0.04267 kg m^2;
- joint ``joint1``: revolute from the ground at the origin (axis +z), angle of link1
  from the downward vertical;
- joint ``joint2``: revolute at link1's lower end (0, -l1, 0), angle of link2 relative to
  link1;
- gravity (0, -9.81, 0) m/s^2.

Initial state: joint angles (pi/2, 0) rad (both links horizontal, pointing along +x), at
rest; t_end = 5 s (the motion is chaotic: errors grow fast, a hard accuracy test).
Energy is conserved; no analytic reference.
"""

from __future__ import annotations

import math

import workbench.plugin.registry
from workbench.model import Frame, Model, Shape
from workbench.plugin.problem import Problem

LENGTHS = (1.0, 0.8)  # m
MASSES = (1.0, 0.8)  # kg
WIDTH = 0.04  # m, visual only
GRAVITY = 9.81  # m/s^2
INITIAL_ANGLES = (math.pi / 2, 0.0)  # rad


@workbench.plugin.registry.problem
class DoublePendulum(Problem):
    name = "double-pendulum"
    summary = "Planar double pendulum of two uniform rigid links (chaotic, 2 DOF)"
    source = "book 6.7.1"
    t_end = 5.0
    n_samples = 501
    conservative = True

    def model(self) -> Model:
        model = Model("double-pendulum", kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        parent, parent_frame = "ground", Frame()
        for i, (length, mass) in enumerate(zip(LENGTHS, MASSES, strict=True), start=1):
            name = f"link{i}"
            model.add_body(
                name,
                mass,
                com=(0.0, -length / 2, 0.0),
                inertia=mass * length**2 / 12,
                shapes=[Shape("box", (WIDTH, length, WIDTH), Frame.at(0, -length / 2, 0))],
            )
            model.add_joint(f"joint{i}", "revolute", parent, name, parent_frame=parent_frame)
            parent, parent_frame = name, Frame.at(0, -length, 0)
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"joint1": INITIAL_ANGLES[0], "joint2": INITIAL_ANGLES[1]}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"joint1": 0.0, "joint2": 0.0}
