"""Closed multibody systems (book 11.1.3, 11.7, 11.8): four-bar, RSRRR, parallel robot.

(The slider-crank of 11.6 is ``slider-crank`` in :mod:`problems.slider_crank`.) Every
mechanism here is cut open at one joint per loop (``cut=True``); the cut joints' implicit
constraints close the loops. Each is given in an assembled configuration, and the
initial velocities of the independent coordinates determine the others.

``four-bar`` (book 11.1.3) — planar, lying in a horizontal plane: gravity (0, 0, 0)
(normal to the plane of motion), so the crank keeps revolving and passes every crank
angle. Ground pivots A = (0, 0) and B = (d, 0); uniform bars of 2 kg/m (Izz = m L^2 /
12): ``crank_link`` (length a) from A, ``coupler`` (b) from the crank pin, ``rocker`` (c)
from B. Joints: revolute ``crank`` (ground -> crank_link at A), ``crank_pin``
(crank_link (a, 0) -> coupler, angle relative to the crank), ``rocker_pivot`` (ground at
B -> rocker), and the cut revolute ``coupler_pin`` (coupler (b, 0) -> rocker (c, 0)).
1 DOF, 1 loop; independent coordinate: the crank. Lengths (m), option ``near_change_point``:

- False (default): d = 0.4, a = 0.1, b = 0.35, c = 0.3; Grashof s + l = 0.5 < p + q =
  0.65, a crank-rocker far from singular positions;
- True: d = 0.4, a = 0.1, b = 0.3, c = 0.202, so s + l = 0.5 falls short of p + q by only
  2 mm: at crank angle pi the coupler and rocker are within 2 mm of being stretched out
  (the Grashof change point s + l = p + q, where the closure Jacobian loses rank and the
  mechanism could switch branches). Once a revolution the closure Jacobian is then
  nearly rank-deficient and the rocker reverses abruptly: a hard case for projections,
  index reduction and drift.

Initial state: crank angle 0, crank rate 10 rad/s, coupler and rocker on the branch
with the coupler pin above the line A B; the crank makes about 3 revolutions in
t_end = 2 s. Energy is conserved; no analytic reference.

``rsrrr`` (book 11.7) — spatial; z up; gravity (0, 0, -9.81) m/s^2. A single loop of five
joints and four moving links: the link ``crank_link`` turns about the vertical z
axis at A = (0, 0, 0) (revolute ``crank``), the ``coupler`` meets it at the spherical joint
``ball`` at B = (0.05, 0, 0) (the cut joint: 3 constraint rows), and the coupler returns
to the ground through the revolutes ``knuckle`` (C, axis (1, 1, 0)/sqrt 2), ``elbow``
(D, axis y) and ``foot`` (E, axis x) with the links ``link3`` (C-D) and ``link4`` (D-E).
In the assembled pose, where all body frames are parallel to the inertial frame:
C = (0.3, 0.1, 0.15), D = (0.35, 0.35, 0.25), E = (0.35, 0.35, 0) m. Links are uniform
solid rods of radius 0.01 m between their joints: masses 0.2 (crank_link), 1.0 (coupler), 0.6
(link3), 0.5 (link4) kg. Tree DOF 4, minus 3 rows: 1 DOF (Gruebler 6 x 4 - 23 = 1),
1 loop; independent coordinate: the crank. Initial state: assembled pose, crank rate
5 rad/s; the mechanism then swings under gravity (the crank oscillates through 3.6 rad).
t_end = 2 s. Energy is conserved; no analytic reference.

``parallel-robot`` (book 11.8) — a planar 3-RRR parallel robot, free (not driven), in
the vertical plane; gravity (0, -9.81, 0) m/s^2. Three legs join the base pivots A_i (on
a circle of 0.5 m at 90, 210, 330 degrees) to the platform's pins P_i (on a circle of
0.1 m about the platform centre, at 150, 270, 30 degrees); each leg is a proximal link
A_i-E_i and a distal link E_i-P_i (uniform bars, 0.5 kg each), the elbows E_i 0.15 m to
the left of the midpoints of A_i P_i. The triangular platform (1.0 kg, Izz = 0.005 kg m^2,
centre of mass at its centre, starting at the origin) hangs on leg 1 in the spanning tree;
legs 2 and 3 close on it with the cut revolutes ``pin2``, ``pin3``. Revolute joints:
``base_i`` (ground -> proximal_i at A_i), ``elbow_i`` (proximal_i -> distal_i at E_i),
``pin1`` (distal_1 -> platform at P_1) and the cuts. The base joints carry torsion
springs (JointSpringDamper, 20 N m/rad, no damping, rest at the assembled angles) that
hold the robot up. 7 tree DOF - 2 x 2 rows = 3 DOF, 2 loops; no redundant constraints
(the rank of the closure Jacobian is 4). Independent coordinates: the three base angles.
Initial state: the assembled pose, base rates (1.0, -0.5, 0.3) rad/s. t_end = 2 s.
Energy (gravity and springs) is conserved; no analytic reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, JointSpringDamper, Model, Shape
from workbench.plugin.problem import Problem
from workbench.problems._parts import planar_rod, rod
from workbench.problems.ch10_open_trees import rod_shape

GRAVITY = 9.81  # m/s^2

# ---- four-bar ------------------------------------------------------------------------

BAR_DENSITY = 2.0  # kg/m
FOUR_BAR_LENGTHS = {  # (ground d, crank a, coupler b, rocker c), m
    False: (0.4, 0.1, 0.35, 0.3),
    True: (0.4, 0.1, 0.3, 0.202),
}
FOUR_BAR_CRANK_ANGLE = 0.0  # rad
FOUR_BAR_CRANK_RATE = 10.0  # rad/s


@dataclass(frozen=True)
class FourBarOptions:
    near_change_point: bool = False


def four_bar_state(
    phi: float, phi_rate: float, lengths: tuple[float, float, float, float]
) -> dict[str, tuple[float, float]]:
    """{joint: (angle, rate)} of the tree joints closing the four-bar exactly.

    The coupler pin Q is the intersection of the circles of radius b about the crank pin
    P and of radius c about B on the side to the left of P -> B.
    """
    d, a, b, c = lengths
    p = np.array([a * math.cos(phi), a * math.sin(phi)])
    e = np.array([d, 0.0]) - p
    distance = float(np.linalg.norm(e))
    along = (b**2 - c**2 + distance**2) / (2 * distance)
    height_squared = b**2 - along**2
    if height_squared < 0:
        raise ConfigError(f"four-bar: no assembly at crank angle {phi} rad")
    unit = e / distance
    q = p + along * unit + math.sqrt(height_squared) * np.array([-unit[1], unit[0]])
    theta = math.atan2(q[1] - p[1], q[0] - p[0])  # coupler, absolute
    psi = math.atan2(q[1], q[0] - d)  # rocker, absolute

    def perp(angle: float) -> np.ndarray:
        return np.array([-math.sin(angle), math.cos(angle)])

    # a phi' perp(phi) + b theta' perp(theta) = c psi' perp(psi)
    matrix = np.column_stack([b * perp(theta), -c * perp(psi)])
    theta_rate, psi_rate = np.linalg.solve(matrix, -a * phi_rate * perp(phi))
    return {
        "crank": (phi, phi_rate),
        "crank_pin": (theta - phi, theta_rate - phi_rate),
        "rocker_pivot": (psi, psi_rate),
    }


def add_planar_bar(model: Model, name: str, length: float, color=(120, 160, 220)) -> None:
    mass = BAR_DENSITY * length
    com, izz = planar_rod(mass, (0, 0, 0), (length, 0, 0))
    model.add_body(
        name,
        mass,
        com=com,
        inertia=izz,
        shapes=[Shape("box", (length, 0.02, 0.02), Frame.at(length / 2, 0, 0), color)],
    )


@workbench.plugin.registry.problem
class FourBar(Problem):
    name = "four-bar"
    summary = "Planar four-bar crank-rocker (1 DOF, 1 loop); option: near the change point"
    source = "book 11.1.3"
    Options = FourBarOptions
    t_end = 2.0
    n_samples = 201
    conservative = True
    independent_coordinates = (("crank", 0),)

    @property
    def lengths(self) -> tuple[float, float, float, float]:
        return FOUR_BAR_LENGTHS[bool(self.options.near_change_point)]

    def model(self) -> Model:
        d, a, b, c = self.lengths
        model = Model(self.name, kind="planar", gravity=(0.0, 0.0, 0.0))
        add_planar_bar(model, "crank_link", a)
        add_planar_bar(model, "coupler", b, (220, 140, 60))
        add_planar_bar(model, "rocker", c)
        model.add_joint("crank", "revolute", "ground", "crank_link")
        model.add_joint("crank_pin", "revolute", "crank_link", "coupler", parent_frame=Frame.at(a))
        model.add_joint("rocker_pivot", "revolute", "ground", "rocker", parent_frame=Frame.at(d))
        model.add_joint(
            "coupler_pin",
            "revolute",
            "coupler",
            "rocker",
            parent_frame=Frame.at(b),
            child_frame=Frame.at(c),
            cut=True,
        )
        return model

    def _state(self) -> dict[str, tuple[float, float]]:
        return four_bar_state(FOUR_BAR_CRANK_ANGLE, FOUR_BAR_CRANK_RATE, self.lengths)

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {joint: value for joint, (value, _) in self._state().items()}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {joint: rate for joint, (_, rate) in self._state().items()}


# ---- RSRRR ---------------------------------------------------------------------------

RSRRR_POINTS = {  # assembled pose, m
    "A": (0.0, 0.0, 0.0),
    "B": (0.05, 0.0, 0.0),
    "C": (0.3, 0.1, 0.15),
    "D": (0.35, 0.35, 0.25),
    "E": (0.35, 0.35, 0.0),
}
RSRRR_MASSES = {"crank_link": 0.2, "coupler": 1.0, "link3": 0.6, "link4": 0.5}  # kg
RSRRR_RADIUS = 0.01  # m
RSRRR_CRANK_RATE = 5.0  # rad/s


def add_rod_between(model: Model, name: str, origin, start, end, mass: float) -> None:
    """A rod body from ``start`` to ``end`` (inertial, assembled pose), frame at ``origin``."""
    origin = np.asarray(origin, dtype=float)
    start, end = np.asarray(start, float) - origin, np.asarray(end, float) - origin
    com, inertia = rod(mass, start, end, RSRRR_RADIUS)
    shape = rod_shape(end - start, RSRRR_RADIUS)
    shape = Shape(shape.kind, shape.size, Frame(start + shape.frame.position, shape.frame.rotation))
    model.add_body(name, mass, com=com, inertia=inertia, shapes=[shape])


@workbench.plugin.registry.problem
class Rsrrr(Problem):
    name = "rsrrr"
    summary = "Spatial RSRRR single-loop mechanism swinging under gravity (1 DOF)"
    source = "book 11.7"
    t_end = 2.0
    n_samples = 201
    conservative = True
    independent_coordinates = (("crank", 0),)

    def model(self) -> Model:
        p = {k: np.array(v) for k, v in RSRRR_POINTS.items()}
        model = Model(self.name, kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        add_rod_between(model, "crank_link", p["A"], p["A"], p["B"], RSRRR_MASSES["crank_link"])
        add_rod_between(model, "link4", p["E"], p["E"], p["D"], RSRRR_MASSES["link4"])
        add_rod_between(model, "link3", p["D"], p["D"], p["C"], RSRRR_MASSES["link3"])
        add_rod_between(model, "coupler", p["C"], p["C"], p["B"], RSRRR_MASSES["coupler"])
        model.add_joint("crank", "revolute", "ground", "crank_link", axis=(0.0, 0.0, 1.0))
        model.add_joint(
            "foot", "revolute", "ground", "link4", parent_frame=Frame(p["E"]), axis=(1, 0, 0)
        )
        model.add_joint(
            "elbow",
            "revolute",
            "link4",
            "link3",
            parent_frame=Frame(p["D"] - p["E"]),
            axis=(0.0, 1.0, 0.0),
        )
        model.add_joint(
            "knuckle",
            "revolute",
            "link3",
            "coupler",
            parent_frame=Frame(p["C"] - p["D"]),
            axis=(1.0, 1.0, 0.0),
        )
        model.add_joint(
            "ball",
            "spherical",
            "crank_link",
            "coupler",
            parent_frame=Frame(p["B"] - p["A"]),
            child_frame=Frame(p["B"] - p["C"]),
            cut=True,
        )
        return model

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"crank": RSRRR_CRANK_RATE}


# ---- planar 3-RRR parallel robot -----------------------------------------------------

BASE_RADIUS = 0.5  # m
PLATFORM_RADIUS = 0.1  # m
BASE_ANGLES = (90.0, 210.0, 330.0)  # deg
PLATFORM_ANGLES = (150.0, 270.0, 30.0)  # deg
ELBOW_OFFSET = 0.15  # m, to the left of A_i -> P_i
LEG_LINK_MASS = 0.5  # kg
PLATFORM_MASS = 1.0  # kg
PLATFORM_INERTIA = 0.005  # kg m^2
BASE_STIFFNESS = 20.0  # N m/rad
BASE_RATES = (1.0, -0.5, 0.3)  # rad/s


def parallel_robot_points() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(A_i, E_i, P_i) of the three legs in the assembled pose, (3,) each, m."""
    legs = []
    for base, pin in zip(BASE_ANGLES, PLATFORM_ANGLES, strict=True):
        a = BASE_RADIUS * np.array([math.cos(math.radians(base)), math.sin(math.radians(base)), 0])
        p = PLATFORM_RADIUS * np.array(
            [math.cos(math.radians(pin)), math.sin(math.radians(pin)), 0.0]
        )
        direction = (p - a) / np.linalg.norm(p - a)
        left = np.array([-direction[1], direction[0], 0.0])
        legs.append((a, (a + p) / 2 + ELBOW_OFFSET * left, p))
    return legs


@workbench.plugin.registry.problem
class ParallelRobot(Problem):
    name = "parallel-robot"
    summary = "Planar 3-RRR parallel robot on base springs, free motion (3 DOF, 2 loops)"
    source = "book 11.8"
    t_end = 2.0
    n_samples = 201
    conservative = True
    independent_coordinates = (("base1", 0), ("base2", 0), ("base3", 0))

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_body(
            "platform",
            PLATFORM_MASS,
            inertia=PLATFORM_INERTIA,
            shapes=[Shape("cylinder", (PLATFORM_RADIUS, 0.02), color=(220, 140, 60))],
        )
        for i, (a, e, p) in enumerate(parallel_robot_points(), start=1):
            for name, start, end in ((f"proximal{i}", a, e), (f"distal{i}", e, p)):
                com, izz = planar_rod(LEG_LINK_MASS, np.zeros(3), end - start)
                model.add_body(name, LEG_LINK_MASS, com=com, inertia=izz)
            model.add_joint(f"base{i}", "revolute", "ground", f"proximal{i}", parent_frame=Frame(a))
            model.add_joint(
                f"elbow{i}", "revolute", f"proximal{i}", f"distal{i}", parent_frame=Frame(e - a)
            )
            model.add_joint(
                f"pin{i}",
                "revolute",
                f"distal{i}",
                "platform",
                parent_frame=Frame(p - e),
                child_frame=Frame(p),
                cut=i > 1,
            )
            model.add_force(JointSpringDamper(f"spring{i}", f"base{i}", BASE_STIFFNESS))
        return model

    def initial_joint_velocities(self) -> dict[str, float]:
        return {f"base{i}": rate for i, rate in enumerate(BASE_RATES, start=1)}
