"""Simple pendulum: a point mass on a massless rod, swinging in a vertical plane.

Book: 5.2 (point mass with a holonomic constraint), modelled as a planar system (ch. 6;
its examples in 6.7 are the double and the rolling pendulum); the small-angle limit is
the linear oscillator theta'' = -(g / l) theta.

Model (planar; x to the right, y up; SI units):

- body ``bob``: point mass m = 1 kg;
- joint ``pivot``: revolute from the ground at the origin, axis +z; the child frame sits
  l = 1 m above the bob (``child_frame = Frame.at(0, l, 0)``), so at angle 0 the bob hangs
  straight down at (0, -l) and at angle theta it is at (l sin theta, -l cos theta);
- gravity (0, -9.81, 0) m/s^2.

Initial state: angle ``initial_angle`` (option, rad, default 0.5 rad ~ 28.6 deg: far
enough from the linear regime that the period is 1.6 % longer), at rest. t_end = 10 s.
Energy is conserved. ``reference()`` is None; :func:`exact_solution` gives the exact
finite-amplitude motion through Jacobi elliptic functions and
:func:`small_angle_solution` the linear one, for tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.special

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, Model, Shape
from workbench.plugin.options import with_unit
from workbench.plugin.problem import Problem

MASS = 1.0  # kg
LENGTH = 1.0  # m
GRAVITY = 9.81  # m/s^2


def small_angle_solution(t: np.ndarray | float, theta0: float, l: float, g: float) -> np.ndarray:
    """Angle (rad) of the linearized pendulum released at rest from theta0 (rad).

    theta(t) = theta0 cos(sqrt(g / l) t); l in m, g in m/s^2, t in s.
    """
    return theta0 * np.cos(np.sqrt(g / l) * np.asarray(t, dtype=float))


def exact_solution(t: np.ndarray | float, theta0: float, l: float, g: float) -> np.ndarray:
    """Angle (rad) of the pendulum released at rest from |theta0| < pi, exactly.

    theta(t) = 2 arcsin(k sn(K(m) - sqrt(g / l) t, m)), k = sin(theta0 / 2), m = k^2,
    with K the complete elliptic integral of the first kind.
    """
    k = math.sin(theta0 / 2)
    m = k * k
    u = scipy.special.ellipk(m) - math.sqrt(g / l) * np.asarray(t, dtype=float)
    sn, _, _, _ = scipy.special.ellipj(u, m)
    return 2 * np.arcsin(k * sn)


def period(theta0: float, l: float, g: float) -> float:
    """Period (s) of the finite-amplitude pendulum: 4 K(sin^2(theta0 / 2)) sqrt(l / g)."""
    return 4 * scipy.special.ellipk(math.sin(theta0 / 2) ** 2) * math.sqrt(l / g)


@dataclass(frozen=True)
class SimplePendulumOptions:
    initial_angle: float = with_unit(0.5, "rad")  # released at rest

    def __post_init__(self) -> None:
        if not math.isfinite(self.initial_angle) or abs(self.initial_angle) >= math.pi:
            raise ConfigError(
                f"initial_angle must be a finite angle in (-pi, pi) rad, not {self.initial_angle}"
            )


@workbench.plugin.registry.problem
class SimplePendulum(Problem):
    name = "simple-pendulum"
    summary = "Point mass on a massless rod (planar, 1 DOF), released at rest"
    source = "book 5.2; linear limit: harmonic oscillator"
    Options = SimplePendulumOptions
    t_end = 10.0
    n_samples = 201
    conservative = True

    def model(self) -> Model:
        model = Model("simple-pendulum", kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_point_mass("bob", MASS, shapes=[Shape("sphere", (0.05,))])
        model.add_joint("pivot", "revolute", "ground", "bob", child_frame=Frame.at(0, LENGTH, 0))
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"pivot": self.options.initial_angle}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"pivot": 0.0}
