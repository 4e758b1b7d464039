"""Unilateral contacts with impacts and Coulomb friction (book 5.1.2, 5.4.2): problems with
analytic references for the nonsmooth integrators (docs/nonsmooth.md).

``bouncing-ball`` -- planar; x right, y up; gravity (0, -9.81, 0) m/s^2. A ball ``ball``
(m = 1 kg, radius r = 0.1 m, Izz = 2/5 m r^2) on a planar joint ``free`` from the ground,
a frictionless unilateral contact ``floor`` of its sphere with the plane y = 0,
restitution e = 0.8. Dropped from rest with its lowest point h0 = 1 m above the floor.
Newton's impact law U+ = -e U- gives impacts at t_1 = sqrt(2 h0 / g) and
t_(k+1) = t_k + 2 e^k v_1 / g (v_1 = g t_1), apex heights h0 e^(2k) and the energy
E_k = m g h0 e^(2k) after the k-th impact: a geometric series accumulating at
t_inf = t_1 (1 + 2 e / (1 - e)) = 4.06 s; t_end = 2.5 s holds 4 impacts.

``incline-block-slide`` and ``incline-block-stop`` -- planar; gravity (0, -9.81, 0). A block
``block`` (m = 1 kg, 0.4 m x 0.1 m) on a plane through the origin inclined at
alpha = 30 degrees (outward normal (-sin alpha, cos alpha, 0)), touching it at its two
lower corners (contacts ``rear`` and ``front``, restitution 0, Coulomb friction mu).
Coulomb's law: with s the distance down the slope and s' >= 0, a sliding block moves with
s'' = g (sin alpha - mu cos alpha); it sticks at rest iff tan(alpha) <= mu.
``-slide``: mu = 0.3 < tan 30 deg, from rest: s = g (sin - mu cos) t^2 / 2 (2.356 m/s^2).
``-stop``: mu = 0.8 > tan 30 deg, launched down the slope at 2 m/s: it decelerates at
g (mu cos - sin) = 1.891 m/s^2, stops at t_s = 1.058 s and sticks from then on (a
slip-to-stick event). t_end = 2 s.

``sliding-sphere`` -- spatial; z up; gravity (0, 0, -9.81). A sphere ``sphere`` (m = 1 kg,
r = 0.1 m, I = 2/5 m r^2) on a free joint ``free``, resting on the plane z = 0 (contact
``floor``, restitution 0, Coulomb mu = 0.2), launched along x at v0 = 2 m/s without spin.
Friction mu m g slows it (x'' = -mu g) and spins it up (omega_y' = 5 mu g / (2 r)) until
its contact point sticks, at t_r = 2 v0 / (7 mu g) = 0.291 s; from then on it rolls at
5/7 v0 = 1.429 m/s: the classic billiard-ball result, a slip-to-stick event in a spatial
contact with two tangents. t_end = 1 s.

``colliding-balls`` -- planar, no gravity (an air table); balls ``a`` (m_A = 1 kg,
r_A = 0.1 m) and ``b`` (m_B = 2 kg, r_B = 0.15 m), each on a planar joint, both centres on a
line at 30 degrees to x, B at rest 0.5875 m from A, A moving towards it at v0 = 1 m/s; a
frictionless sphere-sphere contact ``touch``, restitution e = 0.9. A central impact at
t_c = (0.5875 - r_A - r_B) / v0 = 0.3375 s (between samples); momentum conserved and U+ = -e U- give
v_A+ = (m_A - e m_B) v0 / (m_A + m_B) = -0.267 m/s, v_B+ = m_A (1 + e) v0 / (m_A + m_B) =
0.633 m/s, and the energy lost is (1 - e^2) mu v0^2 / 2 = 0.0633 J, mu = m_A m_B / (m_A +
m_B) the reduced mass. t_end = 1 s.
"""

from __future__ import annotations

import math

import numpy as np

import workbench.plugin.registry
from workbench.model import Model, Shape
from workbench.plugin.problem import Problem, Reference

GRAVITY = 9.81  # m/s^2
BALL_MASS, BALL_RADIUS, BALL_DROP, BALL_RESTITUTION = 1.0, 0.1, 1.0, 0.8
SPHERE_MASS, SPHERE_RADIUS, SPHERE_FRICTION, SPHERE_SPEED = 1.0, 0.1, 0.2, 2.0
BLOCK_MASS, BLOCK_HALF_LENGTH, BLOCK_HALF_HEIGHT = 1.0, 0.2, 0.05
INCLINE = math.radians(30.0)


def _planar_poses(x: np.ndarray, y: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(n, 1, 7) poses of one planar body: position and the quaternion about z."""
    angle = np.broadcast_to(angle, x.shape)
    zero = np.zeros_like(x)
    quaternion = [np.cos(angle / 2), zero, zero, np.sin(angle / 2)]
    return np.stack([x, y, zero, *quaternion], axis=-1)[:, None, :]


def bouncing_ball_impacts(t_end: float, drop: float, e: float) -> np.ndarray:
    """Impact times (s) up to ``t_end`` of a ball dropped from ``drop`` m (restitution e)."""
    t_1 = math.sqrt(2 * drop / GRAVITY)
    times, flight = [t_1], 2 * e * GRAVITY * t_1 / GRAVITY
    while times[-1] + flight <= t_end and flight > 1e-9:
        times.append(times[-1] + flight)
        flight *= e
    return np.array([t for t in times if t <= t_end])


def bouncing_ball_height(times: np.ndarray, drop: float, e: float) -> np.ndarray:
    """Height (m) of the ball's lowest point above the floor at ``times`` (analytic)."""
    impacts = bouncing_ball_impacts(float(np.max(times)) + 1.0, drop, e)
    heights = np.empty(len(times))
    for i, t in enumerate(np.asarray(times, dtype=float)):
        k = int(np.searchsorted(impacts, t, side="right"))  # impacts before t
        if k == 0:
            heights[i] = drop - GRAVITY * t**2 / 2
        else:
            up = e**k * GRAVITY * impacts[0]  # speed leaving the k-th impact
            tau = t - impacts[k - 1]
            heights[i] = up * tau - GRAVITY * tau**2 / 2
    return np.maximum(heights, 0.0)


@workbench.plugin.registry.problem
class BouncingBall(Problem):
    name = "bouncing-ball"
    summary = "Ball dropped on a floor, restitution 0.8: impacts in a geometric series"
    source = "book 5.1.2 (unilateral constraints); Newton's impact law"
    t_end = 2.5
    n_samples = 251
    conservative = False

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        inertia = 0.4 * BALL_MASS * BALL_RADIUS**2
        model.add_body("ball", BALL_MASS, inertia=inertia,
                       shapes=[Shape("sphere", (BALL_RADIUS,))])  # fmt: skip
        model.add_joint("free", "planar", "ground", "ball")
        model.add_contact("floor", "ball", radius=BALL_RADIUS, restitution=BALL_RESTITUTION)
        return model

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        return {"free": [0.0, BALL_DROP + BALL_RADIUS, 0.0]}

    def contact_events(self) -> np.ndarray:
        """The reference impact times (s) within the time span."""
        return bouncing_ball_impacts(self.t_end, BALL_DROP, BALL_RESTITUTION)

    def reference_energy(self, times: np.ndarray) -> np.ndarray:
        """Energy (J; zero: at rest on the floor) the restitution law leaves at ``times``:
        m g h0 e^(2k) after the k-th impact."""
        k = np.searchsorted(self.contact_events(), np.asarray(times), side="right")
        return BALL_MASS * GRAVITY * (BALL_DROP * BALL_RESTITUTION ** (2 * k) + BALL_RADIUS)

    def reference(self) -> Reference:
        def poses(times: np.ndarray) -> np.ndarray:
            times = np.asarray(times, dtype=float)
            y = bouncing_ball_height(times, BALL_DROP, BALL_RESTITUTION) + BALL_RADIUS
            return _planar_poses(np.zeros_like(times), y, np.zeros_like(times))

        return Reference("analytic", poses, "impacts of Newton's law: a geometric series in e")


class InclineBlock(Problem):
    """A block on an incline with Coulomb friction (module docstring); subclasses set mu."""

    source = "book 5.4.2 (Coulomb friction)"
    t_end = 2.0
    n_samples = 201
    conservative = False
    friction: float = 0.3
    speed: float = 0.0  # m/s down the slope at t = 0 (a class attribute, not an option)

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        size = (2 * BLOCK_HALF_LENGTH, 2 * BLOCK_HALF_HEIGHT, 0.1)
        inertia = BLOCK_MASS * (size[0] ** 2 + size[1] ** 2) / 12
        model.add_body("block", BLOCK_MASS, inertia=inertia, shapes=[Shape("box", size)])
        model.add_joint("free", "planar", "ground", "block")
        normal = (-math.sin(INCLINE), math.cos(INCLINE), 0.0)
        for name, x in (("rear", BLOCK_HALF_LENGTH), ("front", -BLOCK_HALF_LENGTH)):
            model.add_contact(name, "block", point=(x, -BLOCK_HALF_HEIGHT, 0.0),
                              plane_normal=normal, friction=self.friction)  # fmt: skip
        return model

    def _along(self, s: np.ndarray) -> np.ndarray:
        """Poses (n, 1, 7) of the block at distance ``s`` down the slope from the start."""
        up = np.array([math.cos(INCLINE), math.sin(INCLINE)])
        normal = np.array([-math.sin(INCLINE), math.cos(INCLINE)])
        centre = BLOCK_HALF_HEIGHT * normal - np.outer(s, up)
        return _planar_poses(centre[:, 0], centre[:, 1], np.full(len(s), INCLINE))

    def slope_distance(self, times: np.ndarray) -> np.ndarray:
        """Distance (m) slid down the slope at ``times`` by Coulomb's law."""
        times = np.asarray(times, dtype=float)
        acceleration = GRAVITY * (math.sin(INCLINE) - self.friction * math.cos(INCLINE))
        if acceleration >= 0 or self.speed > 0:
            stop = -self.speed / acceleration if acceleration < 0 else math.inf
            tau = np.minimum(times, stop)
            return self.speed * tau + acceleration * tau**2 / 2
        return np.zeros_like(times)

    def contact_events(self) -> np.ndarray:
        """The slip-to-stick time, if the block stops within the time span."""
        acceleration = GRAVITY * (math.sin(INCLINE) - self.friction * math.cos(INCLINE))
        stop = -self.speed / acceleration if acceleration < 0 else math.inf
        return np.array([stop]) if self.speed > 0 and stop <= self.t_end else np.array([])

    def reference_energy(self, times: np.ndarray) -> np.ndarray:
        """Energy (J) left after friction's work mu m g cos(alpha) s."""
        s = self.slope_distance(times)
        work = self.friction * BLOCK_MASS * GRAVITY * math.cos(INCLINE) * s
        start = BLOCK_MASS * (self.speed**2 / 2 + GRAVITY * self._along(np.zeros(1))[0, 0, 1])
        return start - work

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        pose = self._along(np.zeros(1))[0, 0]
        return {"free": [pose[0], pose[1], INCLINE]}

    def initial_joint_velocities(self) -> dict[str, list[float]]:
        return {"free": [-self.speed * math.cos(INCLINE), -self.speed * math.sin(INCLINE), 0.0]}

    def reference(self) -> Reference:
        return Reference(
            "analytic",
            lambda times: self._along(self.slope_distance(times)),
            f"Coulomb's law: s'' = g (sin a - mu cos a) while sliding, mu = {self.friction:g}",
        )


@workbench.plugin.registry.problem
class InclineBlockSlide(InclineBlock):
    name = "incline-block-slide"
    summary = "Block sliding down a 30 deg incline, Coulomb friction mu = 0.3 < tan 30 deg"
    friction = 0.3


@workbench.plugin.registry.problem
class InclineBlockStop(InclineBlock):
    name = "incline-block-stop"
    summary = "Block launched down a 30 deg incline, mu = 0.8: slides, stops, sticks"
    friction = 0.8
    speed = 2.0


@workbench.plugin.registry.problem
class SlidingSphere(Problem):
    name = "sliding-sphere"
    summary = "Sphere launched without spin on a floor, mu = 0.2: slides, then rolls at 5/7 v0"
    source = "book 5.4.2 (Coulomb friction); the billiard ball's slip-to-roll transition"
    t_end = 1.0
    n_samples = 101
    conservative = False

    def model(self) -> Model:
        model = Model(self.name, kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        inertia = [0.4 * SPHERE_MASS * SPHERE_RADIUS**2] * 3
        model.add_body("sphere", SPHERE_MASS, inertia=inertia,
                       shapes=[Shape("sphere", (SPHERE_RADIUS,))])  # fmt: skip
        model.add_joint("free", "free", "ground", "sphere")
        model.add_contact("floor", "sphere", radius=SPHERE_RADIUS, friction=SPHERE_FRICTION)
        return model

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        return {"free": [0.0, 0.0, SPHERE_RADIUS, 1.0, 0.0, 0.0, 0.0]}

    def initial_joint_velocities(self) -> dict[str, list[float]]:
        return {"free": [SPHERE_SPEED, 0.0, 0.0, 0.0, 0.0, 0.0]}

    def roll_time(self) -> float:
        return 2 * SPHERE_SPEED / (7 * SPHERE_FRICTION * GRAVITY)

    def motion(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(x, x', angle about y, its rate) at ``times`` by Coulomb's law, then rolling."""
        times = np.asarray(times, dtype=float)
        deceleration = SPHERE_FRICTION * GRAVITY
        spin_up = 5 * SPHERE_FRICTION * GRAVITY / (2 * SPHERE_RADIUS)
        t_r = self.roll_time()
        tau, after = np.minimum(times, t_r), np.maximum(times - t_r, 0.0)
        rolling = SPHERE_SPEED - deceleration * t_r  # 5/7 v0
        x = SPHERE_SPEED * tau - deceleration * tau**2 / 2 + rolling * after
        angle = spin_up * tau**2 / 2 + rolling / SPHERE_RADIUS * after
        speed = np.where(times < t_r, SPHERE_SPEED - deceleration * times, rolling)
        rate = np.where(times < t_r, spin_up * times, rolling / SPHERE_RADIUS)
        return x, speed, angle, rate

    def contact_events(self) -> np.ndarray:
        return np.array([self.roll_time()])

    def reference_energy(self, times: np.ndarray) -> np.ndarray:
        """Kinetic energy plus m g r: friction takes mu m g times the slip distance."""
        _, speed, _, rate = self.motion(times)
        inertia = 0.4 * SPHERE_MASS * SPHERE_RADIUS**2
        potential = SPHERE_MASS * GRAVITY * SPHERE_RADIUS
        return SPHERE_MASS * speed**2 / 2 + inertia * rate**2 / 2 + potential

    def reference(self) -> Reference:
        def poses(times: np.ndarray) -> np.ndarray:
            x, _, angle, _ = self.motion(times)
            zero = np.zeros_like(x)
            quaternion = [np.cos(angle / 2), zero, np.sin(angle / 2), zero]
            position = [x, zero, np.full_like(x, SPHERE_RADIUS)]
            return np.stack([*position, *quaternion], axis=-1)[:, None, :]

        return Reference("analytic", poses, "Coulomb's law: slides at -mu g, rolls at 5/7 v0")


PAIR_MASSES, PAIR_RADII, PAIR_RESTITUTION = (1.0, 2.0), (0.1, 0.15), 0.9
PAIR_SPEED, PAIR_DISTANCE, PAIR_LINE = 1.0, 0.5875, math.radians(30.0)


def colliding_balls_motion(times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(s_A, s_B): the two centres' distances (m) along the line at ``times`` by Newton's
    restitution law and conservation of momentum (module docstring)."""
    times = np.asarray(times, dtype=float)
    t_c = colliding_balls_impact()
    after_a, after_b = colliding_balls_velocities()
    tau = np.maximum(times - t_c, 0.0)
    s_a = PAIR_SPEED * np.minimum(times, t_c) + after_a * tau
    s_b = PAIR_DISTANCE + after_b * tau
    return s_a, s_b


def colliding_balls_impact() -> float:
    """The impact time (s): the gap d - r_A - r_B closed at the speed v0."""
    return (PAIR_DISTANCE - sum(PAIR_RADII)) / PAIR_SPEED


def colliding_balls_velocities() -> tuple[float, float]:
    """Velocities (m/s) along the line after the impact: momentum conserved and the
    relative velocity reversed times e."""
    (m_a, m_b), e, v0 = PAIR_MASSES, PAIR_RESTITUTION, PAIR_SPEED
    return (m_a - e * m_b) * v0 / (m_a + m_b), m_a * (1 + e) * v0 / (m_a + m_b)


@workbench.plugin.registry.problem
class CollidingBalls(Problem):
    """Two balls, one struck against the other at rest (module docstring)."""

    name = "colliding-balls"
    summary = "Ball striking a heavier ball at rest, e = 0.9: momentum and Newton's law"
    source = "book 5.1.2 (unilateral constraints); central impact of two spheres"
    t_end = 1.0
    n_samples = 101
    conservative = False

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, 0.0, 0.0))
        for name, mass, radius in zip(("a", "b"), PAIR_MASSES, PAIR_RADII, strict=True):
            model.add_body(name, mass, inertia=0.4 * mass * radius**2,
                           shapes=[Shape("sphere", (radius,))])  # fmt: skip
            model.add_joint(f"free_{name}", "planar", "ground", name)
        model.add_sphere_contact("touch", "a", PAIR_RADII[0], "b", PAIR_RADII[1],
                                 restitution=PAIR_RESTITUTION)  # fmt: skip
        return model

    def _on_line(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return s * math.cos(PAIR_LINE), s * math.sin(PAIR_LINE)

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        x_b, y_b = self._on_line(np.array(PAIR_DISTANCE))
        return {"free_a": [0.0, 0.0, 0.0], "free_b": [float(x_b), float(y_b), 0.0]}

    def initial_joint_velocities(self) -> dict[str, list[float]]:
        x_a, y_a = self._on_line(np.array(PAIR_SPEED))
        return {"free_a": [float(x_a), float(y_a), 0.0], "free_b": [0.0, 0.0, 0.0]}

    def contact_events(self) -> np.ndarray:
        return np.array([colliding_balls_impact()])

    def reference_energy(self, times: np.ndarray) -> np.ndarray:
        """Kinetic energy (J): m_A v0^2 / 2, less (1 - e^2) mu v0^2 / 2 at the impact
        (mu = m_A m_B / (m_A + m_B), the reduced mass)."""
        (m_a, m_b), e, v0 = PAIR_MASSES, PAIR_RESTITUTION, PAIR_SPEED
        loss = (1 - e**2) * m_a * m_b / (m_a + m_b) * v0**2 / 2
        after = np.asarray(times, dtype=float) > colliding_balls_impact()
        return m_a * v0**2 / 2 - loss * after

    def reference(self) -> Reference:
        def poses(times: np.ndarray) -> np.ndarray:
            s_a, s_b = colliding_balls_motion(times)
            zero = np.zeros_like(s_a)
            return np.concatenate(
                [_planar_poses(*self._on_line(s), zero) for s in (s_a, s_b)], axis=1
            )

        return Reference("analytic", poses, "momentum conserved, Newton's law U+ = -e U-")
