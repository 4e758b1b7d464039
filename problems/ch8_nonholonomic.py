"""Nonholonomic systems (book 8.3, 8.4.1): a ball on a turntable and a knife-edge cart.

``ball-on-rotating-plane`` (book 8.3) — spatial; z up; gravity (0, 0, -9.81) m/s^2.
A homogeneous ball ``ball`` (radius r = 0.1 m, m = 1.0 kg, I = 2/5 m r^2 = 0.004 kg m^2;
body frame at its centre) rolls without slipping on the plane z = 0, which turns about
the vertical z axis at Omega = 2 rad/s (constraint ``contact``: RollingSphere with
plane_rate = Omega: the centre stays at height r, and the ball's material point at the
contact moves with the plane: two velocity rows). The ball hangs on the ground by the
free joint ``float`` (position of the centre; Euler parameters; velocity of the centre
in the inertial frame; angular velocity in the body frame). Velocities 6 - 1 height row
- 2 rolling rows = 3 DOF. Initial state: centre at (0.5, 0, r) m moving at (0, 0.3, 0)
m/s, spin about the vertical 1.0 rad/s, the horizontal angular velocity that makes the
contact stick (independent coordinates: the centre's x and y and their rates).
t_end = 5 s.

Analytic reference (book 8.3): the contact force F is horizontal, so m a = F and
I w' = -r e_z x F; differentiating the rolling condition gives a = Omega I / (I + m r^2)
e_z x v = (2/7) Omega e_z x v: the centre runs on a circle at the constant angular rate
2 Omega / 7, about the fixed centre c = x + (e_z x v) / (2 Omega / 7). Only the
*position* of the reference pose is analytic: the ball's orientation is not (it follows
from a quadrature of the angular velocity), so the reference quaternion is NaN and
metrics compare positions only. The plane does work on the ball, so energy is not
conserved (conservative = False); the invariants are the circle's centre
``circle_center_x``, ``circle_center_y`` (m) and the vertical spin ``vertical_spin``
(rad/s: the contact force has no moment about the vertical through the centre).

``knife-edge-cart`` (book 8.4.1) — planar model of a cart on a horizontal floor (the model's
x-y plane is the floor, so gravity, normal to it, is (0, 0, 0) here). The cart ``cart``
(m = 2.0 kg, Izz = 0.1 kg m^2 about its centre of mass) rides on two wheels on one axle;
its body frame sits at the axle's midpoint, body x along the heading. Joint ``carrier``:
planar from the ground (x, y, heading). Constraint ``wheels``: KnifeEdge, the axle
midpoint does not move sideways (body y): one velocity row, not integrable. 3 - 1 = 2
DOF. Option ``com_offset`` (m, default 0): the centre of mass ahead of the axle along
body x. Initial state: at the origin, heading 0, speed u = 1 m/s, yaw rate w = 2 rad/s.
t_end = 5 s; energy is conserved (the knife edge's force does no work).
With com_offset = 0 the yaw rate and the speed are constant (invariants ``yaw_rate``
rad/s and ``speed`` m/s) and the analytic reference is a circle of radius u / w:
heading w t, axle midpoint (u/w sin(w t), u/w (1 - cos(w t))). With com_offset != 0 the
cart is the Chaplygin sleigh (it ends up moving straight on); energy is then its only
invariant and there is no reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, KnifeEdge, Model, RollingSphere, Shape
from workbench.plugin.options import with_unit
from workbench.plugin.problem import Invariant, Problem, Reference

GRAVITY = 9.81  # m/s^2

# ball on a rotating plane
BALL_RADIUS = 0.1  # m
BALL_MASS = 1.0  # kg
BALL_INERTIA = 2 / 5 * BALL_MASS * BALL_RADIUS**2  # kg m^2, homogeneous ball
PLANE_RATE = 2.0  # rad/s
BALL_POSITION = (0.5, 0.0)  # m, initial centre (x, y)
BALL_VELOCITY = (0.0, 0.3)  # m/s, initial centre velocity (x, y)
BALL_SPIN = 1.0  # rad/s, initial angular velocity about the vertical


def circle_rate(plane_rate: float = PLANE_RATE) -> float:
    """Angular rate (rad/s) of the centre's circle: Omega I / (I + m r^2) = 2 Omega / 7."""
    return plane_rate * BALL_INERTIA / (BALL_INERTIA + BALL_MASS * BALL_RADIUS**2)


def circle_center(position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Centre (..., 2) of the circle the ball's centre runs on, from its position and
    velocity (..., 3)."""
    rate = circle_rate()
    position, velocity = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
    turned = np.stack([-velocity[..., 1], velocity[..., 0]], axis=-1)
    return position[..., :2] + turned / rate


def _ball_index(model: Model) -> int:
    return list(model.bodies).index("ball")


def circle_center_x(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    i = _ball_index(model)
    return circle_center(np.asarray(poses)[..., i, :3], np.asarray(twists)[..., i, :3])[..., 0]


def circle_center_y(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    i = _ball_index(model)
    return circle_center(np.asarray(poses)[..., i, :3], np.asarray(twists)[..., i, :3])[..., 1]


def vertical_spin(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    return np.asarray(twists, dtype=float)[..., _ball_index(model), 5]


def ball_initial_angular_velocity() -> np.ndarray:
    """Angular velocity (3,) with the contact point moving with the plane (identity pose)."""
    (x, y), (vx, vy) = BALL_POSITION, BALL_VELOCITY
    # v + w x (-r e_z) = Omega e_z x (x, y, 0):  vx - r wy = -Omega y,  vy + r wx = Omega x
    return np.array(
        [(PLANE_RATE * x - vy) / BALL_RADIUS, (vx + PLANE_RATE * y) / BALL_RADIUS, BALL_SPIN]
    )


def ball_reference_poses(times: np.ndarray) -> np.ndarray:
    """(n_times, 1, 7): the centre on its circle; quaternion NaN (not analytic)."""
    times = np.atleast_1d(np.asarray(times, dtype=float))
    position = np.array(BALL_POSITION)
    center = circle_center(position, np.array(BALL_VELOCITY))
    angle = circle_rate() * times
    offset = position - center
    poses = np.full((times.size, 1, 7), np.nan)
    poses[:, 0, 0] = center[0] + np.cos(angle) * offset[0] - np.sin(angle) * offset[1]
    poses[:, 0, 1] = center[1] + np.sin(angle) * offset[0] + np.cos(angle) * offset[1]
    poses[:, 0, 2] = BALL_RADIUS
    return poses


@workbench.plugin.registry.problem
class BallOnRotatingPlane(Problem):
    name = "ball-on-rotating-plane"
    summary = "Homogeneous ball rolling on a turntable: its centre circles at 2/7 the rate"
    source = "book 8.3"
    t_end = 5.0
    n_samples = 501
    conservative = False
    independent_coordinates = (("float", 0), ("float", 1))

    def model(self) -> Model:
        model = Model(self.name, kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        model.add_body(
            "ball",
            BALL_MASS,
            inertia=(BALL_INERTIA,) * 3,
            shapes=[Shape("sphere", (BALL_RADIUS,))],
        )
        model.add_joint("float", "free", "ground", "ball")
        model.add_nonholonomic(
            RollingSphere("contact", "ball", radius=BALL_RADIUS, plane_rate=PLANE_RATE)
        )
        return model

    def initial_joint_coordinates(self) -> dict[str, np.ndarray]:
        x, y = BALL_POSITION
        return {"float": np.array([x, y, BALL_RADIUS, 1.0, 0.0, 0.0, 0.0])}

    def initial_joint_velocities(self) -> dict[str, np.ndarray]:
        vx, vy = BALL_VELOCITY
        return {"float": np.concatenate([[vx, vy, 0.0], ball_initial_angular_velocity()])}

    def invariants(self) -> list[Invariant]:
        return [
            Invariant("circle_center_x", circle_center_x, vectorized=True),
            Invariant("circle_center_y", circle_center_y, vectorized=True),
            Invariant("vertical_spin", vertical_spin, vectorized=True),
        ]

    def reference(self) -> Reference:
        return Reference(
            "analytic",
            ball_reference_poses,
            "centre on a circle at 2/7 of the plane's rate (book 8.3); position only, "
            "quaternion NaN (orientation not analytic)",
        )


# knife-edge cart
CART_MASS = 2.0  # kg
CART_INERTIA = 0.1  # kg m^2 about the centre of mass
CART_SPEED = 1.0  # m/s, initial, along the heading
CART_YAW_RATE = 2.0  # rad/s, initial


@dataclass(frozen=True)
class KnifeEdgeOptions:
    com_offset: float = with_unit(0.0, "m")  # centre of mass ahead of the axle along the heading

    def __post_init__(self) -> None:
        if not math.isfinite(self.com_offset):
            raise ConfigError(f"com_offset must be finite, not {self.com_offset}")


def _cart(model: Model, poses: np.ndarray, twists: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    i = list(model.bodies).index("cart")
    return np.asarray(poses, dtype=float)[..., i, :], np.asarray(twists, dtype=float)[..., i, :]


def yaw_rate(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    return _cart(model, poses, twists)[1][..., 5]


def speed(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    """Speed (m/s) of the axle midpoint (the body frame's origin)."""
    return np.linalg.norm(_cart(model, poses, twists)[1][..., :3], axis=-1)


def cart_reference_poses(times: np.ndarray) -> np.ndarray:
    """(n_times, 1, 7): the axle midpoint on a circle of radius u / w, heading w t."""
    times = np.atleast_1d(np.asarray(times, dtype=float))
    heading = CART_YAW_RATE * times
    radius = CART_SPEED / CART_YAW_RATE
    poses = np.zeros((times.size, 1, 7))
    poses[:, 0, 0] = radius * np.sin(heading)
    poses[:, 0, 1] = radius * (1 - np.cos(heading))
    quaternions = np.stack(
        [np.cos(heading / 2), 0 * heading, 0 * heading, np.sin(heading / 2)], axis=-1
    )
    poses[:, 0, 3:] = quaternions * np.where(quaternions[:, :1] < 0, -1.0, 1.0)
    return poses


@workbench.plugin.registry.problem
class KnifeEdgeCart(Problem):
    name = "knife-edge-cart"
    summary = "Two-wheeled cart on a floor: knife-edge constraint at the axle (2 DOF)"
    source = "book 8.4.1"
    Options = KnifeEdgeOptions
    t_end = 5.0
    n_samples = 501
    conservative = True
    independent_coordinates = (("carrier", 0), ("carrier", 1), ("carrier", 2))

    def model(self) -> Model:
        a = self.options.com_offset
        model = Model(self.name, kind="planar", gravity=(0.0, 0.0, 0.0))
        model.add_body(
            "cart",
            CART_MASS,
            com=(a, 0.0, 0.0),
            inertia=CART_INERTIA,
            shapes=[
                Shape("box", (0.4, 0.3, 0.1), Frame.at(a, 0, 0)),
                Shape("cylinder", (0.08, 0.02), Frame.at(0, 0.17, 0), color=(60, 60, 60)),
                Shape("cylinder", (0.08, 0.02), Frame.at(0, -0.17, 0), color=(60, 60, 60)),
            ],
        )
        model.add_joint("carrier", "planar", "ground", "cart")
        model.add_nonholonomic(
            KnifeEdge("wheels", "cart", point=np.zeros(3), direction=np.array([0.0, 1.0, 0.0]))
        )
        return model

    def initial_joint_coordinates(self) -> dict[str, tuple[float, float, float]]:
        return {"carrier": (0.0, 0.0, 0.0)}

    def initial_joint_velocities(self) -> dict[str, tuple[float, float, float]]:
        return {"carrier": (CART_SPEED, 0.0, CART_YAW_RATE)}

    def invariants(self) -> list[Invariant]:
        if self.options.com_offset != 0.0:
            return []
        return [
            Invariant("yaw_rate", yaw_rate, vectorized=True),
            Invariant("speed", speed, vectorized=True),
        ]

    def reference(self) -> Reference | None:
        if self.options.com_offset != 0.0:
            return None
        return Reference(
            "analytic",
            cart_reference_poses,
            "centre of mass on the axle: constant speed and yaw rate, a circle of radius u/w",
        )
