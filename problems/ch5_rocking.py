"""Housner's rocking block (Housner 1963): a rigid block rocking on a rigid floor, two
corner contacts, impacts that take energy with no restitution coefficient of their own
(docs/nonsmooth.md).

``rocking-block`` -- planar; x right, y up; gravity (0, -9.81, 0) m/s^2. A block ``block``
(m = 1 kg, half-width b = 0.1 m, half-height h = 0.3 m, Izz = m (b^2 + h^2) / 3) on a
planar joint ``free`` from the ground; its lower corners are point contacts ``left`` and
``right`` with the floor y = 0 (restitution 0, Coulomb mu = 0.7: enough to stick).
Released from rest tilted by theta_0 = alpha / 2 about its left corner, alpha =
atan(b / h) = 18.43 deg (the slenderness angle). With R = sqrt(b^2 + h^2) and p^2 =
3 g / (4 R), between impacts it rotates about one corner by the exact (not linearized)
rocking equation theta'' = -p^2 sin(alpha sgn(theta) - theta); when theta reaches 0 the
other corner strikes, the old one lifts off, and angular momentum about the new corner
is conserved: theta'+ = r theta'-, r = 1 - 3/2 sin^2(alpha) = 0.85 (no bounce, no slip).
t_end = 2 s holds 9 impacts (they accumulate near t = 2.5 s).

Newton's law with e = 0 at both corners and Moreau's impact law over the two closed
contacts (what every contact integrator here solves) gives exactly Housner's r: for a
slender block (h > sqrt(2) b) the only solution of the impact problem puts the impulse
at the striking corner, since stopping the block dead would need a pulling impulse at
the other corner (docs/nonsmooth.md). The reference is independent of the multibody
model: the one-degree-of-freedom rocking equation integrated by SciPy (DOP853, rtol
1e-12) from impact to impact with Housner's coefficient.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.integrate import solve_ivp

import workbench.plugin.registry
from workbench.model import Model, Shape
from workbench.plugin.problem import Problem, Reference

GRAVITY = 9.81  # m/s^2
MASS, HALF_WIDTH, HALF_HEIGHT, FRICTION = 1.0, 0.1, 0.3, 0.7
SLENDERNESS = math.atan(HALF_WIDTH / HALF_HEIGHT)  # alpha, rad
DIAGONAL = math.hypot(HALF_WIDTH, HALF_HEIGHT)  # R, m
HOUSNER_R = 1 - 1.5 * math.sin(SLENDERNESS) ** 2  # theta'+ / theta'- at an impact
START_TILT = SLENDERNESS / 2  # rad


@functools.cache
def rocking_phases(t_end: float, tilt: float = START_TILT) -> tuple:
    """The rocking equation solved from impact to impact: ((impact times), (dense
    solutions of theta, theta' of every phase, with its start time))."""
    p2 = 3 * GRAVITY / (4 * DIAGONAL)
    t, y, impacts, phases = 0.0, np.array([tilt, 0.0]), [], []
    while t < t_end:
        side = np.sign(y[0]) if y[0] != 0 else np.sign(y[1])  # the pivot: sgn(theta)

        def rhs(_t: float, z: np.ndarray, side: float = side) -> list[float]:
            return [z[1], -p2 * math.sin(side * SLENDERNESS - z[0])]

        def upright(_t: float, z: np.ndarray) -> float:
            return z[0]

        upright.terminal, upright.direction = True, -side
        solution = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=1e-12, atol=1e-14,
                             events=upright, dense_output=True)  # fmt: skip
        phases.append((t, solution.sol))
        if solution.status != 1:
            break
        t = float(solution.t_events[0][0])
        impacts.append(t)
        y = np.array([0.0, HOUSNER_R * solution.y_events[0][0][1]])
    return tuple(impacts), tuple(phases)


def rocking_angle(times: np.ndarray, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """(theta, theta') (rad, rad/s) of the rocking reference at ``times``."""
    _, phases = rocking_phases(t_end)
    starts = np.array([start for start, _ in phases])
    times = np.asarray(times, dtype=float)
    which = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(phases) - 1)
    angle, rate = np.empty(times.size), np.empty(times.size)
    for k in np.unique(which):
        values = phases[k][1](times[which == k])
        angle[which == k], rate[which == k] = values[0], values[1]
    return angle, rate


@workbench.plugin.registry.problem
class RockingBlock(Problem):
    name = "rocking-block"
    summary = "Housner's rocking block: corner impacts take r = 1 - 3/2 sin^2(alpha) of the rate"
    source = "book 5.1.2 (unilateral constraints); Housner 1963, Bull. Seismol. Soc. Am. 53"
    t_end = 2.0
    n_samples = 201
    conservative = False

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        size = (2 * HALF_WIDTH, 2 * HALF_HEIGHT, 0.1)
        inertia = MASS * DIAGONAL**2 / 3
        model.add_body("block", MASS, inertia=inertia, shapes=[Shape("box", size)])
        model.add_joint("free", "planar", "ground", "block")
        for name, x in (("left", -HALF_WIDTH), ("right", HALF_WIDTH)):
            model.add_contact(name, "block", point=(x, -HALF_HEIGHT, 0.0), friction=FRICTION)
        return model

    def centre(self, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of the block's centre tilted by ``angle`` about the corner it rests on."""
        side = np.where(angle >= 0, 1.0, -1.0)  # theta > 0: on the left corner (-b, 0)
        offset_x, offset_y = side * HALF_WIDTH, HALF_HEIGHT
        x = -side * HALF_WIDTH + np.cos(angle) * offset_x - np.sin(angle) * offset_y
        y = np.sin(angle) * offset_x + np.cos(angle) * offset_y
        return x, y

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        x, y = self.centre(np.array([START_TILT]))
        return {"free": [float(x[0]), float(y[0]), START_TILT]}

    def contact_events(self) -> np.ndarray:
        """The reference impact times (s) within the time span."""
        return np.array(rocking_phases(self.t_end)[0])

    def reference_energy(self, times: np.ndarray) -> np.ndarray:
        """Energy (J) of the rocking reference: 1/2 I_O theta'^2 + m g y_centre; each
        impact takes 1 - r^2 of the kinetic energy."""
        angle, rate = rocking_angle(times, self.t_end)
        inertia_about_corner = 4 * MASS * DIAGONAL**2 / 3
        return inertia_about_corner * rate**2 / 2 + MASS * GRAVITY * self.centre(angle)[1]

    def reference(self) -> Reference:
        def poses(times: np.ndarray) -> np.ndarray:
            angle, _ = rocking_angle(times, self.t_end)
            x, y = self.centre(angle)
            zero = np.zeros_like(x)
            quaternion = [np.cos(angle / 2), zero, zero, np.sin(angle / 2)]
            return np.stack([x, y, zero, *quaternion], axis=-1)[:, None, :]

        return Reference(
            "analytic",
            poses,
            "the exact rocking equation (SciPy DOP853, rtol 1e-12) with Housner's r at impacts",
            accuracy=1e-10,
        )
