"""Holonomic point-mass systems (book 5.7): three worked examples of chapter 5.

``double-point-pendulum`` (book 5.7.1) — planar; x right, y up; gravity (0, -9.81, 0) m/s^2.
Point masses ``mass1`` (m1 = 1.0 kg) and ``mass2`` (m2 = 0.5 kg) on massless rods of
l1 = 1.0 m and l2 = 0.7 m. Joint ``joint1``: revolute from the ground at the origin to
mass1, its child frame l1 above the mass (the mass hangs at (l1 sin a1, -l1 cos a1));
``joint2``: revolute at mass1 to mass2, child frame l2 above mass2, angle a2 relative to
the first rod. 2 DOF, no loops. Initial state: (a1, a2) = (1.2, -0.6) rad at rest;
t_end = 5 s. Energy is conserved; no analytic reference.

``point-mass-slider-crank`` (book 5.7.2) — planar; gravity (0, -9.81, 0) m/s^2. The book's
crank and connecting rod are massless with point masses at the crank pin and the piston.
Massless rigid bodies are not allowed (every mass must be > 0), so: the crank pin is the
point mass ``pin`` (m1 = 0.5 kg) on a massless crank of r = 0.1 m (joint ``crank``:
revolute from the ground at the origin, child frame offset by r, so the crank carries no
body), the connecting rod ``rod`` is a *light* uniform rigid bar of l = 0.3 m and
m_rod = 0.01 kg (2 % of the point masses; Izz = m_rod l^2 / 12) hinged at the pin (joint
``crank_pin``, angle relative to the crank), and the piston is the point mass ``piston``
(m2 = 1.0 kg) on the prismatic joint ``slide`` along x from the origin. The loop closes
with the cut revolute joint ``piston_pin`` between the rod's end (l, 0, 0) and the piston.
1 DOF, 1 loop; independent coordinate: the crank angle. Initial state: crank angle
0.5 rad, crank rate 8 rad/s, the other joints consistent. t_end = 2 s. Energy conserved.

``rotating-ring`` (book 5.7.3) — spatial; z up; gravity (0, 0, -9.81) m/s^2. A thin ring
``ring`` (radius R = 0.5 m, 0.3 kg, in its body x-z plane, centre at the origin) is
driven about the vertical z axis at the constant rate Omega = 5 rad/s by the driven
revolute joint ``spin`` (q = Omega t: rheonomic). The point mass ``bead`` (m = 0.2 kg)
slides without friction on it: joint ``slide`` is a revolute about the ring's normal (body
y) at the ring centre, its child frame R above the bead, so the angle a from the bottom
puts the bead at (-R sin a, 0, -R cos a) in the ring frame. 1 DOF. Since
Omega^2 R = 12.5 m/s^2 > g, the bottom is unstable and the bead swings about the
relative equilibrium cos a = g / (Omega^2 R) (a = 0.67 rad). Initial state: a = 0.2 rad,
at rest relative to the ring; t_end = 5 s. The drive does work, so the energy is not
conserved (conservative = False); the Jacobi integral is: h = T_rel - V_centrifugal + V
= m |v - w x r|^2 / 2 - m |w x r|^2 / 2 - m g.r (J), w the ring's angular velocity.
No analytic reference.
"""

from __future__ import annotations

import math

import numpy as np

import workbench.plugin.registry
from workbench.model import Drive, Frame, Model, Shape
from workbench.plugin.problem import Invariant, Problem
from workbench.problems._parts import planar_rod

GRAVITY = 9.81  # m/s^2

# double point-mass pendulum
PENDULUM_MASSES = (1.0, 0.5)  # kg
PENDULUM_LENGTHS = (1.0, 0.7)  # m
PENDULUM_ANGLES = (1.2, -0.6)  # rad


@workbench.plugin.registry.problem
class DoublePointPendulum(Problem):
    name = "double-point-pendulum"
    summary = "Planar double pendulum of two point masses on massless rods (2 DOF)"
    source = "book 5.7.1"
    t_end = 5.0
    n_samples = 501
    conservative = True

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        parent = "ground"
        for i, (mass, length) in enumerate(zip(PENDULUM_MASSES, PENDULUM_LENGTHS, strict=True)):
            body = f"mass{i + 1}"
            model.add_point_mass(body, mass, shapes=[Shape("sphere", (0.04,))])
            model.add_joint(
                f"joint{i + 1}", "revolute", parent, body, child_frame=Frame.at(0, length, 0)
            )
            parent = body
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"joint1": PENDULUM_ANGLES[0], "joint2": PENDULUM_ANGLES[1]}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"joint1": 0.0, "joint2": 0.0}


# point-mass slider-crank
CRANK_LENGTH = 0.1  # m
ROD_LENGTH = 0.3  # m
PIN_MASS = 0.5  # kg
PISTON_MASS = 1.0  # kg
ROD_MASS = 0.01  # kg, light rigid rod standing in for the book's massless one
CRANK_ANGLE = 0.5  # rad
CRANK_RATE = 8.0  # rad/s


def slider_crank_state(
    phi: float, phi_rate: float, r: float = CRANK_LENGTH, l: float = ROD_LENGTH
) -> dict[str, tuple[float, float]]:
    """{joint: (coordinate, velocity)} closing the loop exactly (piston on the x axis)."""
    beta = -math.asin(r * math.sin(phi) / l)
    beta_rate = -r * math.cos(phi) * phi_rate / (l * math.cos(beta))
    s = r * math.cos(phi) + l * math.cos(beta)
    s_rate = -r * math.sin(phi) * phi_rate - l * math.sin(beta) * beta_rate
    return {
        "crank": (phi, phi_rate),
        "crank_pin": (beta - phi, beta_rate - phi_rate),
        "slide": (s, s_rate),
    }


@workbench.plugin.registry.problem
class PointMassSliderCrank(Problem):
    name = "point-mass-slider-crank"
    summary = (
        "Planar slider-crank with point masses at pin and piston, a light rod (0.01 kg) "
        "standing in for the book's massless one (1 DOF)"
    )
    source = "book 5.7.2"
    t_end = 2.0
    n_samples = 201
    conservative = True
    independent_coordinates = (("crank", 0),)

    def model(self) -> Model:
        r, l = CRANK_LENGTH, ROD_LENGTH
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_point_mass("pin", PIN_MASS, shapes=[Shape("sphere", (0.02,))])
        com, izz = planar_rod(ROD_MASS, (0, 0, 0), (l, 0, 0))
        model.add_body(
            "rod",
            ROD_MASS,
            com=com,
            inertia=izz,
            shapes=[Shape("box", (l, 0.01, 0.01), Frame.at(l / 2, 0, 0))],
        )
        model.add_point_mass("piston", PISTON_MASS, shapes=[Shape("box", (0.06, 0.04, 0.04))])
        model.add_joint("crank", "revolute", "ground", "pin", child_frame=Frame.at(-r, 0, 0))
        model.add_joint("crank_pin", "revolute", "pin", "rod")
        model.add_joint("slide", "prismatic", "ground", "piston", axis=(1.0, 0.0, 0.0))
        model.add_joint(
            "piston_pin", "revolute", "rod", "piston", parent_frame=Frame.at(l, 0, 0), cut=True
        )
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        state = slider_crank_state(CRANK_ANGLE, CRANK_RATE)
        return {joint: value for joint, (value, _) in state.items()}

    def initial_joint_velocities(self) -> dict[str, float]:
        state = slider_crank_state(CRANK_ANGLE, CRANK_RATE)
        return {joint: rate for joint, (_, rate) in state.items()}


# point mass on a rotating ring
RING_RADIUS = 0.5  # m
RING_MASS = 0.3  # kg
RING_RATE = 5.0  # rad/s, Omega about the vertical
BEAD_MASS = 0.2  # kg
BEAD_ANGLE = 0.2  # rad from the bottom of the ring


def jacobi_integral(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    """h = m |v_rel|^2 / 2 - m |w x r|^2 / 2 + V (J) of the bead on the rotating ring.

    v_rel = v - w x r is the bead's velocity relative to the ring (which turns at w
    about an axis through the origin), V = -m g.r its potential energy. Vectorized over
    leading sample axes.
    """
    names = list(model.bodies)
    ring, bead = names.index("ring"), names.index("bead")
    mass = model.bodies["bead"].mass
    poses, twists = np.asarray(poses, dtype=float), np.asarray(twists, dtype=float)
    r, v = poses[..., bead, :3], twists[..., bead, :3]
    carried = np.cross(twists[..., ring, 3:6], r)
    relative = v - carried
    kinetic = np.sum(relative * relative - carried * carried, axis=-1) / 2
    return mass * kinetic - mass * (r @ model.gravity)


@workbench.plugin.registry.problem
class RotatingRing(Problem):
    name = "rotating-ring"
    summary = "Bead sliding on a ring driven about the vertical (rheonomic, 1 DOF)"
    source = "book 5.7.3"
    t_end = 5.0
    n_samples = 501
    conservative = False

    def model(self) -> Model:
        R, omega = RING_RADIUS, RING_RATE
        model = Model(self.name, kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        # thin ring in its x-z plane: moments m R^2 / 2 about the diameters x and z,
        # m R^2 about the normal y
        model.add_body(
            "ring",
            RING_MASS,
            inertia=(RING_MASS * R**2 / 2, RING_MASS * R**2, RING_MASS * R**2 / 2),
            shapes=[Shape("cylinder", (R, 0.01), Frame(rotation=_x_to_y_normal()))],
        )
        model.add_point_mass("bead", BEAD_MASS, shapes=[Shape("sphere", (0.03,))])
        model.add_joint(
            "spin",
            "revolute",
            "ground",
            "ring",
            axis=(0.0, 0.0, 1.0),
            drive=Drive(
                position=lambda t: omega * t,
                velocity=lambda t: omega + 0 * t,
                acceleration=lambda t: 0 * t,
            ),
        )
        model.add_joint(
            "slide",
            "revolute",
            "ring",
            "bead",
            axis=(0.0, 1.0, 0.0),
            child_frame=Frame.at(0, 0, R),
        )
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"slide": BEAD_ANGLE}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"slide": 0.0}

    def invariants(self) -> list[Invariant]:
        return [Invariant("jacobi_integral", jacobi_integral, vectorized=True)]


def _x_to_y_normal() -> np.ndarray:
    """Rotation taking a cylinder's z axis to the ring's normal y (visual only)."""
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
