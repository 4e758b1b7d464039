"""Heavy symmetric top with a fixed point (book 4.8.2, 7.7.1), spatial, 3 DOF.

Model (spatial; z up; SI units):

- body ``top``: mass m = 1.0 kg; body frame at the tip (the fixed point), symmetry axis
  along body z; centre of mass (0, 0, a) with a = 0.1 m; inertia about the centre of
  mass diag(A, A, C) with A = 4.0e-3 kg m^2 (transverse) and C = 6.0e-3 kg m^2 (about
  the symmetry axis), so about the tip the transverse moment is A + m a^2 = 0.014 kg m^2;
- joint ``tip``: spherical, ground (origin) -> top; coordinates: the unit quaternion
  (scalar first) of the top's frame relative to the inertial frame; velocity: the top's
  angular velocity in its own frame;
- gravity (0, 0, -9.81) m/s^2.

Initial state (options): the symmetry axis tilted by ``initial_tilt`` (rad, default 0.3)
about the inertial x axis, quaternion (cos(tilt/2), sin(tilt/2), 0, 0); spinning at
``spin`` (rad/s, default 50) about the symmetry axis, angular velocity (0, 0, spin) in
the body frame, no initial precession. C * spin = 0.3 kg m^2/s exceeds
sqrt(4 (A + m a^2) m g a) = 0.23 kg m^2/s (upright, it would sleep); released tilted, it
nutates between tilts 0.30 and 0.46 rad (period 0.44 s) while precessing about the
vertical. t_end = 2 s.

Invariants: energy (conservative); the angular momentum about the vertical axis through
the fixed point (kg m^2/s; gravity has no moment about it); the spin, the angular
velocity component along the symmetry axis (rad/s; Euler's equation C w3' = 0 for a
symmetric body whose gravity moment is perpendicular to its axis). No analytic reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, Model, Shape
from workbench.plugin.options import with_unit
from workbench.plugin.problem import Invariant, Problem
from workbench.problems._parts import angular_momentum, rotation_matrices

MASS = 1.0  # kg
COM_DISTANCE = 0.1  # m, tip to centre of mass along the symmetry axis
TRANSVERSE_INERTIA = 4.0e-3  # kg m^2, A about the centre of mass
AXIAL_INERTIA = 6.0e-3  # kg m^2, C about the symmetry axis
GRAVITY = 9.81  # m/s^2
FIXED_POINT = np.zeros(3)  # m, inertial


def vertical_angular_momentum(
    model: Model, t: float, poses: np.ndarray, twists: np.ndarray
) -> np.ndarray:
    """Angular momentum (kg m^2/s) about the vertical (against gravity) through the tip
    (vectorized)."""
    up = -model.gravity / np.linalg.norm(model.gravity)
    return angular_momentum(model, poses, twists, FIXED_POINT) @ up


def spin(model: Model, t: float, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    """Angular velocity component (rad/s) along the top's symmetry axis (body z)
    (vectorized)."""
    i = list(model.bodies).index("top")
    axis = rotation_matrices(np.asarray(poses, dtype=float)[..., i, 3:7])[..., :, 2]
    return np.sum(axis * np.asarray(twists, dtype=float)[..., i, 3:6], axis=-1)


@dataclass(frozen=True)
class HeavyTopOptions:
    initial_tilt: float = with_unit(0.3, "rad")  # symmetry axis from the vertical, about x
    spin: float = with_unit(50.0, "rad/s")  # about the symmetry axis

    def __post_init__(self) -> None:
        for name in ("initial_tilt", "spin"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError(f"{name} must be finite, not {getattr(self, name)}")


@workbench.plugin.registry.problem
class HeavyTop(Problem):
    name = "heavy-top"
    summary = (
        "Heavy symmetric top on a fixed point (spherical joint, 3 DOF), spinning above the "
        "sleeping limit, not in the fast-top limit"
    )
    source = "book 4.8.2, 7.7.1"
    Options = HeavyTopOptions
    t_end = 2.0
    n_samples = 401
    conservative = True

    def model(self) -> Model:
        a = COM_DISTANCE
        model = Model("heavy-top", kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        model.add_body(
            "top",
            MASS,
            com=(0.0, 0.0, a),
            inertia=(TRANSVERSE_INERTIA, TRANSVERSE_INERTIA, AXIAL_INERTIA),
            shapes=[
                Shape("capsule", (0.005, a), Frame.at(0, 0, a / 2)),
                Shape("cylinder", (0.08, 0.02), Frame.at(0, 0, a), color=(220, 140, 60)),
            ],
        )
        model.add_joint("tip", "spherical", "ground", "top")
        return model

    def initial_joint_coordinates(self) -> dict[str, np.ndarray]:
        half = self.options.initial_tilt / 2
        return {"tip": np.array([math.cos(half), math.sin(half), 0.0, 0.0])}

    def initial_joint_velocities(self) -> dict[str, np.ndarray]:
        return {"tip": np.array([0.0, 0.0, self.options.spin])}

    def invariants(self) -> list[Invariant]:
        return [
            Invariant("vertical_angular_momentum", vertical_angular_momentum, vectorized=True),
            Invariant("spin", spin, vectorized=True),
        ]
