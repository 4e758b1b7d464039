"""Open multibody systems (book 10.7): the articulated arm robot with six revolute joints.

``articulated-arm`` — spatial; z up; gravity (0, 0, -9.81) m/s^2. A six-axis industrial
arm (joint axes z, y, y, x, y, x: waist, shoulder, elbow, wrist roll, wrist pitch,
flange roll), moving freely (no joint torques) from an initial pose; a benchmark for
the non-recursive (10.5) and recursive (10.6) formalisms on a chain.

Bodies (body frame at the joint to the parent; the links are uniform solid cylinders
(``problems._parts.rod``) whose centres of mass are moved off the axis by the given
offsets; inertia about the centre of mass in the body frame):

=========  ========  ==========================  ===================  =====================
body       mass kg   rod from -> to (m)          radius m             com offset (m)
=========  ========  ==========================  ===================  =====================
column     4.0       (0, 0, 0) -> (0, 0, 0.4)    0.08                 (0, 0, 0)
upper_arm  3.0       (0, 0, 0) -> (0.5, 0, 0)    0.05                 (0, 0.02, 0)
forearm    2.0       (0, 0, 0) -> (0.4, 0, 0)    0.04                 (0, -0.01, 0.01)
wrist      1.0       (0, 0, 0) -> (0.1, 0, 0)    0.06                 (0, 0, 0)
hand       0.6       (0, 0, 0) -> (0.08, 0, 0)   0.05                 (0, 0, 0.005)
tool       0.4       (0, 0, 0) -> (0.1, 0, 0)    0.05                 (0, 0.01, 0.005)
=========  ========  ==========================  ===================  =====================

Joints (revolute; position of the joint on the parent, axis in the parent frame):
``waist`` ground (0, 0, 0) z; ``shoulder`` column (0, 0, 0.4) y; ``elbow`` upper_arm
(0.5, 0, 0) y; ``wrist_roll`` forearm (0.4, 0, 0) x; ``wrist_pitch`` wrist (0.1, 0, 0) y;
``flange`` hand (0.08, 0, 0) x. At zero angles the arm points horizontally along +x.

6 DOF, no loops. Initial state: angles (0, 1.2, 0.3, 0.2, 0.4, 0) rad (the upper arm
1.2 rad below the horizontal), rates (0.5, 0, 0, 0, 0, 0) rad/s; the arm swings under
gravity while the light wrist (its hand and tool off the roll axis) rolls back and forth
at up to ~25 rad/s: fast and slow motions in one chain. t_end = 3 s. Energy is
conserved; so is the angular momentum about the vertical through the waist
(``vertical_angular_momentum``, kg m^2/s: neither gravity nor the waist bearing has a
moment about it). No analytic reference.
"""

from __future__ import annotations

import numpy as np

import workbench.plugin.registry
from workbench.model import Frame, Model, Shape
from workbench.plugin.problem import Invariant, Problem
from workbench.problems._parts import angular_momentum, rod

GRAVITY = 9.81  # m/s^2

# name, mass, rod end, radius, com offset (body frame; rods start at the body origin)
LINKS = (
    ("column", 4.0, (0.0, 0.0, 0.4), 0.08, (0.0, 0.0, 0.0)),
    ("upper_arm", 3.0, (0.5, 0.0, 0.0), 0.05, (0.0, 0.02, 0.0)),
    ("forearm", 2.0, (0.4, 0.0, 0.0), 0.04, (0.0, -0.01, 0.01)),
    ("wrist", 1.0, (0.1, 0.0, 0.0), 0.06, (0.0, 0.0, 0.0)),
    ("hand", 0.6, (0.08, 0.0, 0.0), 0.05, (0.0, 0.0, 0.005)),
    ("tool", 0.4, (0.1, 0.0, 0.0), 0.05, (0.0, 0.01, 0.005)),
)
# name, axis (each joint sits at the end of the previous link's rod)
JOINTS = (
    ("waist", (0.0, 0.0, 1.0)),
    ("shoulder", (0.0, 1.0, 0.0)),
    ("elbow", (0.0, 1.0, 0.0)),
    ("wrist_roll", (1.0, 0.0, 0.0)),
    ("wrist_pitch", (0.0, 1.0, 0.0)),
    ("flange", (1.0, 0.0, 0.0)),
)
INITIAL_ANGLES = (0.0, 1.2, 0.3, 0.2, 0.4, 0.0)  # rad
INITIAL_RATES = (0.5, 0.0, 0.0, 0.0, 0.0, 0.0)  # rad/s


def rod_shape(end: np.ndarray, radius: float) -> Shape:
    """A capsule along the segment from the body origin to ``end`` (visual)."""
    end = np.asarray(end, dtype=float)
    length = float(np.linalg.norm(end))
    z = end / length
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    rotation = np.column_stack([x, np.cross(z, x), z])
    return Shape("capsule", (radius, length), Frame(end / 2, rotation))


def add_link(
    model: Model, name: str, mass: float, end, radius: float, com_offset=(0.0, 0.0, 0.0)
) -> None:
    """A uniform solid rod from the body origin to ``end`` with its com moved by ``com_offset``."""
    com, inertia = rod(mass, np.zeros(3), end, radius)
    model.add_body(
        name,
        mass,
        com=com + np.asarray(com_offset),
        inertia=inertia,
        shapes=[rod_shape(end, radius)],
    )


def vertical_angular_momentum(
    model: Model, t: float, poses: np.ndarray, twists: np.ndarray
) -> np.ndarray:
    """Angular momentum (kg m^2/s) about the vertical axis through the origin (vectorized)."""
    return angular_momentum(model, poses, twists)[..., 2]


@workbench.plugin.registry.problem
class ArticulatedArm(Problem):
    name = "articulated-arm"
    summary = "Six-axis articulated arm robot (axes z y y x y x) moving freely (6 DOF)"
    source = "book 10.7"
    t_end = 3.0
    n_samples = 301
    conservative = True

    def model(self) -> Model:
        model = Model(self.name, kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        parent, at = "ground", np.zeros(3)
        for (name, mass, end, radius, offset), (joint, axis) in zip(LINKS, JOINTS, strict=True):
            add_link(model, name, mass, end, radius, offset)
            model.add_joint(joint, "revolute", parent, name, parent_frame=Frame(at), axis=axis)
            parent, at = name, np.asarray(end, dtype=float)
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {joint: angle for (joint, _), angle in zip(JOINTS, INITIAL_ANGLES, strict=True)}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {joint: rate for (joint, _), rate in zip(JOINTS, INITIAL_RATES, strict=True)}

    def invariants(self) -> list[Invariant]:
        return [Invariant("vertical_angular_momentum", vertical_angular_momentum, vectorized=True)]
