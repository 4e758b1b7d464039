"""The woodpecker toy (Glocker 1995; Pfeiffer & Glocker 1996; Leine, Glocker & van Campen
2001, 2003): a sleeve slides down a pole with clearance, a bird hangs on it by a torsion
spring, and the beak's pecking, the sleeve's jamming and Coulomb friction make a
self-sustained limit cycle that walks the toy down the pole (docs/nonsmooth.md).

``woodpecker`` -- planar; x right (towards the bird), y up; gravity (0, -9.81, 0). The
published parameters (Glocker's thesis, TU Munich 1995, pp. 162ff; the same in Leine et
al. and in Acary & Brogliato 2008): sleeve m_M = 3.0e-4 kg, J_M = 5.0e-9 kg m^2; bird
m_S = 4.5e-3 kg, J_S = 7.0e-7 kg m^2 about its centre of mass; pole radius r_0 = 2.5e-3 m;
sleeve inner radius r_M = 3.1e-3 m, half-height h_M = 5.8e-3 m; spring at l_M = 1.0e-2 m
right of the sleeve's centre; the bird's centre of mass l_G = 1.5e-2 m right of the
spring; the beak at (-l_S, h_S) = (-2.01e-2, 2.0e-2) m from the bird's centre of mass;
torsion spring c = 5.6e-3 N m/rad (rest: bird and sleeve aligned).

As a tree (so minimal-ode runs it): ground -> prismatic ``descent`` along y -> a massless
``carriage`` -> revolute ``rock`` -> ``sleeve`` (its centre on the pole's axis: the
sleeve's horizontal play is neglected, as in the published model) -> revolute ``spring``
with a JointSpringDamper ``torsion`` -> ``bird``. Three contacts with the pole's face
x = r_0 (Coulomb mu = 0.3 each): ``beak`` (restitution 0.5), the sleeve's lower edge
``lower`` (r_M, -h_M) and upper edge ``upper`` (r_M, h_M) (restitution 0). The published
model linearizes the gaps and the mass matrix in the angles; ours keeps the exact
geometry (cosines and sines), so its cycle differs from the published one by terms of
order phi^2 ~ 1e-2.

Initial state: the published point of the limit cycle, y' = -0.3411 m/s, phi_M' = 0,
phi_S = -0.2788 rad, phi_S' = -7.4583 rad/s, with phi_M = -0.1009 rad (published
-0.1036, the linear gap's root) chosen so the exact gap of the lower edge is zero.
t_end = 0.5 s: about four cycles (Moreau-Jean, h = 1e-4 s: period 0.1296 s, the sleeve
descending at 0.103 m/s on average). Reference: stored (references/woodpecker.npz), event-driven
on minimal-ode at rtol 1e-12, confirmed by event-driven on absolute-dae at 1e-11 to 4.4e-9 L
(L = 0.054 m), its stated accuracy; its cycle: period 0.1296 s within 2 %.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

import workbench.plugin.registry
from workbench.model import Frame, JointSpringDamper, Model, Shape
from workbench.plugin.problem import Problem

GRAVITY = 9.81  # m/s^2
SLEEVE_MASS, SLEEVE_INERTIA = 3.0e-4, 5.0e-9  # kg, kg m^2
BIRD_MASS, BIRD_INERTIA = 4.5e-3, 7.0e-7
POLE_RADIUS, SLEEVE_RADIUS, SLEEVE_HALF_HEIGHT = 2.5e-3, 3.1e-3, 5.8e-3  # m
SPRING_ARM, BIRD_ARM = 1.0e-2, 1.5e-2  # l_M, l_G (m)
BEAK = (-2.01e-2, 2.0e-2)  # (-l_S, h_S) from the bird's centre of mass (m)
STIFFNESS = 5.6e-3  # N m/rad
FRICTION, BEAK_RESTITUTION = 0.3, 0.5
START_BIRD, START_BIRD_RATE, START_DESCENT = -0.2788, -7.4583, -0.3411  # rad, rad/s, m/s


def lower_edge_gap(angle: float) -> float:
    """Exact gap (m) of the sleeve's lower edge at sleeve angle ``angle`` (rad)."""
    return (SLEEVE_RADIUS * math.cos(angle) + SLEEVE_HALF_HEIGHT * math.sin(angle)
            - POLE_RADIUS)  # fmt: skip


START_SLEEVE = brentq(lower_edge_gap, -0.2, 0.0, xtol=1e-15)  # -0.10353 rad


def cycle_lag(
    times: np.ndarray, poses: np.ndarray, start_t: float = 0.15
) -> tuple[int, int, float]:
    """(start sample, lag in samples, mismatch) of the limit cycle in a 1 ms output grid:
    the lag between 0.100 and 0.160 s after ``start_t`` that best repeats the sleeve's and
    the bird's orientations over 0.15 s (mismatch: their largest difference there, rad).
    Ours keeps the exact geometry, so the period is found rather than assumed."""
    angles = poses[:, 1:, 3:]
    start = int(np.searchsorted(times, start_t))
    lags = np.arange(100, 161)
    window = angles[start : start + 150]
    mismatch = [np.max(np.abs(angles[start + lag : start + lag + 150] - window)) for lag in lags]
    best = int(np.argmin(mismatch))
    return start, int(lags[best]), float(mismatch[best])


@workbench.plugin.registry.problem
class Woodpecker(Problem):
    name = "woodpecker"
    summary = "Woodpecker toy: beak impacts, sleeve jamming and friction in a limit cycle"
    source = "book 5.1.2, 5.4.2; Glocker 1995, Pfeiffer & Glocker 1996, Leine et al. 2003"
    t_end = 0.5
    n_samples = 501
    conservative = False

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_point_mass("carriage", 0.0)
        size = (2 * SLEEVE_RADIUS, 2 * SLEEVE_HALF_HEIGHT, 0.01)
        model.add_body("sleeve", SLEEVE_MASS, inertia=SLEEVE_INERTIA,
                       shapes=[Shape("box", size)])  # fmt: skip
        model.add_body("bird", BIRD_MASS, com=(BIRD_ARM, 0.0, 0.0), inertia=BIRD_INERTIA,
                       shapes=[Shape("sphere", (0.004,))])  # fmt: skip
        model.add_joint("descent", "prismatic", "ground", "carriage", axis=(0.0, 1.0, 0.0))
        model.add_joint("rock", "revolute", "carriage", "sleeve")
        model.add_joint("spring", "revolute", "sleeve", "bird",
                        parent_frame=Frame.at(SPRING_ARM, 0.0, 0.0))  # fmt: skip
        model.add_force(JointSpringDamper("torsion", "spring", STIFFNESS))
        face = (POLE_RADIUS, 0.0, 0.0)
        normal = (1.0, 0.0, 0.0)
        beak = (BIRD_ARM + BEAK[0], BEAK[1], 0.0)
        model.add_contact("beak", "bird", point=beak, plane_point=face, plane_normal=normal,
                          restitution=BEAK_RESTITUTION, friction=FRICTION)  # fmt: skip
        for name, y in (("lower", -SLEEVE_HALF_HEIGHT), ("upper", SLEEVE_HALF_HEIGHT)):
            model.add_contact(name, "sleeve", point=(SLEEVE_RADIUS, y, 0.0), plane_point=face,
                              plane_normal=normal, friction=FRICTION)  # fmt: skip
        return model

    def initial_joint_coordinates(self) -> dict[str, list[float]]:
        return {"descent": [0.0], "rock": [START_SLEEVE], "spring": [START_BIRD - START_SLEEVE]}

    def initial_joint_velocities(self) -> dict[str, list[float]]:
        return {"descent": [START_DESCENT], "rock": [0.0], "spring": [START_BIRD_RATE]}
