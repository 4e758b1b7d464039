"""IFToMM multibody benchmark library, group A: problems with a published specification.

**A02, N-four-bar mechanism** (M. González, D. Dopico, U. Lugrís, J. Cuadrado, "A
benchmarking system for MBS simulation software", Multibody System Dynamics 16 (2006)
179-190; specification A02 of the IFToMM benchmark library, lim.ii.udc.es/mbsbenchmark).
N four-bar windows of 2N+1 links, each 1 m long with 1 kg uniformly distributed
(Izz = m L^2 / 12 about its centre): N+1 cranks pinned to the ground at x = 0, 1, ..., N
and N couplers joining the tips of neighbouring cranks. Gravity 9.81 m/s^2 along -y.
Initially the cranks stand vertical and the tip B0 of the first crank moves at 1 m/s
along +x; 20 s, 400 output steps.

The mechanism has one degree of freedom, but whenever all bars are horizontal (crank
angle 0 or pi) the constraint Jacobian loses N rows of rank and the mechanism has N+1
instantaneous degrees of freedom: a formalism or an integrator can leave the
parallelogram branch there. On the branch every crank has the angle phi and every
coupler translates, so T = (4N+1)/6 m L^2 phi'^2 and V = (3N+1)/2 m g L sin(phi), and

    phi'' = -((9N+3)/(8N+2)) g cos(phi) / L.

With psi = phi + pi/2 this is a pendulum, psi'' = -k sin psi; the initial energy makes it
circulate, and theta = psi/2 obeys theta'^2 = A - k sin^2 theta = A (1 - m sin^2 theta)
with A = theta'(0)^2 + k sin^2 theta(0) and m = k / A < 1, so
theta(t) = am(F(theta(0) | m) + sign(theta'(0)) sqrt(A) t | m) (:func:`a02_crank_angle`):
the reference poses are exact up to the evaluation of the elliptic functions.

The default is N = 2, the two-four-bar mechanism of Bayo and Avello (1994) that the
benchmark extends, so that the default sweep stays short; the benchmark's case is the
option ``n = 40``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ellipj, ellipkinc

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, Model, Shape
from workbench.plugin.problem import Problem, Reference

GRAVITY = 9.81  # m/s^2
A02_LENGTH = 1.0  # m, every link
A02_MASS = 1.0  # kg, every link
A02_TIP_SPEED = 1.0  # m/s, initial velocity of B0 along +x


@dataclass(frozen=True)
class A02Options:
    n: int = 2  # four-bar windows; the benchmark is n = 40 (see the module docstring)

    def __post_init__(self) -> None:
        if not 1 <= int(self.n) <= 1000:
            raise ConfigError(f"n (four-bar windows) must be between 1 and 1000, not {self.n}")


def a02_coefficient(n: int) -> float:
    """k (1/s^2) of phi'' = -k cos(phi) on the parallelogram branch."""
    return (9 * n + 3) / (8 * n + 2) * GRAVITY / A02_LENGTH


def a02_crank_angle(times: np.ndarray, n: int, phi0: float, rate0: float) -> np.ndarray:
    """Exact crank angle phi(t) (rad) of phi'' = -k cos(phi) from (phi0, rate0), when the
    motion circulates (the initial energy exceeds the top of the potential)."""
    k = a02_coefficient(n)
    theta0 = (phi0 + math.pi / 2) / 2  # theta = psi / 2, psi = phi + pi/2
    theta_rate0 = rate0 / 2
    amplitude = theta_rate0**2 + k * math.sin(theta0) ** 2  # A: theta'^2 = A - k sin^2
    parameter = k / amplitude  # m
    if not parameter < 1.0:
        raise ValueError("the A02 reference covers circulating motion only (m < 1)")
    u0 = float(ellipkinc(theta0, parameter))
    direction = math.copysign(1.0, theta_rate0)
    _, _, _, am = ellipj(u0 + direction * math.sqrt(amplitude) * np.asarray(times), parameter)
    return 2 * am - math.pi / 2


def _z_quaternions(angles: np.ndarray) -> np.ndarray:
    half = np.asarray(angles) / 2
    zeros = np.zeros_like(half)
    return np.stack([np.cos(half), zeros, zeros, np.sin(half)], axis=-1)


def _add_link(model: Model, name: str, color: tuple[int, int, int]) -> None:
    model.add_body(
        name,
        A02_MASS,
        com=(A02_LENGTH / 2, 0.0, 0.0),
        inertia=A02_MASS * A02_LENGTH**2 / 12,
        shapes=[Shape("box", (A02_LENGTH, 0.03, 0.03), Frame.at(A02_LENGTH / 2, 0, 0), color)],
    )


@workbench.plugin.registry.problem
class IftommA02(Problem):
    name = "iftomm-a02"
    summary = "IFToMM A02 N-four-bar (1 DOF, N loops) through singular horizontal positions"
    source = "IFToMM multibody benchmark A02 (Gonzalez et al. 2006); book 11.1"
    Options = A02Options
    t_end = 20.0
    n_samples = 401
    conservative = True
    independent_coordinates = (("pin_0", 0),)

    @property
    def n(self) -> int:
        return int(self.options.n)

    def model(self) -> Model:
        model = Model(self.name, kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        for i in range(self.n + 1):
            _add_link(model, f"crank_{i}", (120, 160, 220))
            model.add_joint(f"pin_{i}", "revolute", "ground", f"crank_{i}", Frame.at(i, 0, 0))
        for i in range(1, self.n + 1):
            _add_link(model, f"coupler_{i}", (220, 140, 60))
            tip = Frame.at(A02_LENGTH, 0, 0)
            model.add_joint(f"left_{i}", "revolute", f"crank_{i - 1}", f"coupler_{i}", tip)
            model.add_joint(
                f"right_{i}", "revolute", f"coupler_{i}", f"crank_{i}", tip, tip, cut=True
            )
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        angles = {f"pin_{i}": math.pi / 2 for i in range(self.n + 1)}
        return angles | {f"left_{i}": -math.pi / 2 for i in range(1, self.n + 1)}

    def initial_joint_velocities(self) -> dict[str, float]:
        rate = -A02_TIP_SPEED / A02_LENGTH  # x of B0 = L cos(phi): x' = -L sin(phi) phi'
        rates = {f"pin_{i}": rate for i in range(self.n + 1)}
        return rates | {f"left_{i}": -rate for i in range(1, self.n + 1)}  # couplers translate

    def reference(self) -> Reference:
        n = self.n
        rate0 = -A02_TIP_SPEED / A02_LENGTH

        def poses(times: np.ndarray) -> np.ndarray:
            times = np.asarray(times, dtype=float)
            phi = a02_crank_angle(times - self.t_start, n, math.pi / 2, rate0)
            out = np.zeros((times.size, 2 * n + 1, 7))
            # bodies in the order added: crank_0 .. crank_n, coupler_1 .. coupler_n
            for i in range(n + 1):
                out[:, i, 0] = i
                out[:, i, 3:] = _z_quaternions(phi)
            for i in range(1, n + 1):
                out[:, n + i, 0] = (i - 1) + A02_LENGTH * np.cos(phi)
                out[:, n + i, 1] = A02_LENGTH * np.sin(phi)
                out[:, n + i, 3] = 1.0
            return out

        return Reference(
            "analytic",
            poses,
            "exact one-DOF reduction on the parallelogram branch: phi'' = "
            "-((9N+3)/(8N+2)) g cos(phi), in Jacobi elliptic functions",
        )
