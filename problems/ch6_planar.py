"""Holonomic planar multibody systems (book 6.7): the rolling pendulum (6.7.2).

(The double pendulum of 6.7.1 is ``double-pendulum`` in :mod:`problems.double_pendulum`.)

``rolling-pendulum`` — planar; x right, y up; gravity (0, -9.81, 0) m/s^2.

- body ``disk``: homogeneous disk, radius r = 0.2 m, m_d = 2.0 kg, Izz = m_d r^2 / 2 =
  0.04 kg m^2; body frame at its centre (= centre of mass);
- joint ``carrier``: planar joint from the ground, coordinates (x, y, angle): the disk's
  centre and rotation;
- constraint ``contact``: RollingDisk, the disk rolls without slipping on the line y = 0:
  the centre stays at height r (holonomic row) and x' + r angle' = 0 (one velocity row;
  integrable, but kept as a velocity constraint as in the book);
- body ``pendulum``: uniform bar, l = 0.5 m, m_p = 1.0 kg, Izz = m_p l^2 / 12; body frame
  at the hinge, the bar along body -y, centre of mass (0, -l/2, 0);
- joint ``hinge``: revolute at the disk's centre, angle of the bar relative to the disk.

Velocities: 3 + 1 = 4; one holonomic and one rolling row: 2 DOF (Gruebler count of
positions: 3). Independent coordinates: the disk's x (carrier index 0) and the hinge.
Initial state: disk centre at (0, r), disk angle 0, bar angle 1.0 rad from the downward
vertical (the hinge angle equals it at disk angle 0); all at rest. t_end = 5 s. Rolling
without slip does no work: energy is conserved. No analytic reference.
"""

from __future__ import annotations

import workbench.plugin.registry
from workbench.model import Frame, Model, RollingDisk, Shape
from workbench.plugin.problem import Problem

GRAVITY = 9.81  # m/s^2
DISK_RADIUS = 0.2  # m
DISK_MASS = 2.0  # kg
BAR_LENGTH = 0.5  # m
BAR_MASS = 1.0  # kg
BAR_ANGLE = 1.0  # rad, initial, from the downward vertical


@workbench.plugin.registry.problem
class RollingPendulum(Problem):
    name = "rolling-pendulum"
    summary = "Disk rolling on a line with a pendulum hinged at its centre (2 DOF)"
    source = "book 6.7.2"
    t_end = 5.0
    n_samples = 501
    conservative = True
    independent_coordinates = (("carrier", 0), ("hinge", 0))

    def model(self) -> Model:
        r, l = DISK_RADIUS, BAR_LENGTH
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_body(
            "disk",
            DISK_MASS,
            inertia=DISK_MASS * r**2 / 2,
            shapes=[Shape("cylinder", (r, 0.02))],
        )
        model.add_body(
            "pendulum",
            BAR_MASS,
            com=(0.0, -l / 2, 0.0),
            inertia=BAR_MASS * l**2 / 12,
            shapes=[Shape("box", (0.02, l, 0.02), Frame.at(0, -l / 2, 0), color=(220, 140, 60))],
        )
        model.add_joint("carrier", "planar", "ground", "disk")
        model.add_joint("hinge", "revolute", "disk", "pendulum")
        model.add_nonholonomic(RollingDisk("contact", "disk", radius=r))
        return model

    def initial_joint_coordinates(self) -> dict[str, object]:
        return {"carrier": (0.0, DISK_RADIUS, 0.0), "hinge": BAR_ANGLE}

    def initial_joint_velocities(self) -> dict[str, object]:
        return {"carrier": (0.0, 0.0, 0.0), "hinge": 0.0}
