"""Planar slider-crank mechanism as one closed loop of rigid bodies (book 11.6, cf. 5.7.2).

Model (planar; x along the slider's line, y up; SI units):

- body ``crank_arm``: uniform bar, r = 0.1 m, m = 1.0 kg; body frame at the crankshaft
  axis, the bar along body +x, com (r/2, 0, 0), Izz = m r^2 / 12 about the com;
- body ``rod`` (connecting rod): uniform bar, l = 0.4 m, m = 1.0 kg; body frame at the
  crank pin, the bar along body +x, com (l/2, 0, 0), Izz = m l^2 / 12;
- body ``slider``: block of 2.0 kg, 0.1 m x 0.05 m, Izz = m (0.1^2 + 0.05^2) / 12; body
  frame at the piston pin;
- joint ``crank``: revolute, ground (origin) -> crank_arm, the crank angle phi;
- joint ``crank_pin``: revolute, crank_arm at (r, 0, 0) -> rod, angle of the rod
  relative to the crank;
- joint ``slide``: prismatic along x, ground (origin) -> slider, the slider position s;
- joint ``piston_pin``: cut (loop-closing) revolute, rod at (l, 0, 0) -> slider origin;
- gravity (0, -9.81, 0) m/s^2.

One loop, Gruebler count 3 - 2 = 1 DOF. The crank angle is the independent coordinate.
Initial state (options): crank angle ``initial_crank_angle`` (rad, default 0: crank and
rod aligned along +x, slider at r + l) and crank rate ``initial_crank_rate`` (rad/s,
default 10); the other joints get the exactly consistent values (closure and its time
derivative), see :func:`consistent_state`. t_end = 2 s. Energy is conserved (no
friction, no drive). No analytic reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, Model, Shape
from workbench.plugin.options import with_unit
from workbench.plugin.problem import Problem

CRANK_LENGTH = 0.1  # m
ROD_LENGTH = 0.4  # m
CRANK_MASS = 1.0  # kg
ROD_MASS = 1.0  # kg
SLIDER_MASS = 2.0  # kg
SLIDER_SIZE = (0.1, 0.05)  # m
GRAVITY = 9.81  # m/s^2


def consistent_state(
    phi: float, phi_rate: float, r: float = CRANK_LENGTH, l: float = ROD_LENGTH
) -> dict[str, tuple[float, float]]:
    """{joint: (coordinate, velocity)} of the tree joints closing the loop exactly.

    The rod's absolute angle beta solves r sin(phi) + l sin(beta) = 0 (the piston pin on
    the x axis), with cos(beta) > 0; s = r cos(phi) + l cos(beta).
    """
    beta = -math.asin(r * math.sin(phi) / l)
    beta_rate = -r * math.cos(phi) * phi_rate / (l * math.cos(beta))
    s = r * math.cos(phi) + l * math.cos(beta)
    s_rate = -r * math.sin(phi) * phi_rate - l * math.sin(beta) * beta_rate
    return {
        "crank": (phi, phi_rate),
        "crank_pin": (beta - phi, beta_rate - phi_rate),
        "slide": (s, s_rate),
    }


@dataclass(frozen=True)
class SliderCrankOptions:
    initial_crank_angle: float = with_unit(0.0, "rad")
    initial_crank_rate: float = with_unit(10.0, "rad/s")

    def __post_init__(self) -> None:
        for name in ("initial_crank_angle", "initial_crank_rate"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError(f"{name} must be finite, not {getattr(self, name)}")


@workbench.plugin.registry.problem
class SliderCrank(Problem):
    name = "slider-crank"
    summary = "Planar slider-crank: one closed loop of rigid bodies (1 DOF), free motion"
    source = "book 11.6 (cf. 5.7.2)"
    Options = SliderCrankOptions
    t_end = 2.0
    n_samples = 201
    conservative = True
    independent_coordinates = (("crank", 0),)

    def model(self) -> Model:
        r, l = CRANK_LENGTH, ROD_LENGTH
        model = Model("slider-crank", kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        model.add_body(
            "crank_arm",
            CRANK_MASS,
            com=(r / 2, 0.0, 0.0),
            inertia=CRANK_MASS * r**2 / 12,
            shapes=[Shape("box", (r, 0.02, 0.02), Frame.at(r / 2, 0, 0))],
        )
        model.add_body(
            "rod",
            ROD_MASS,
            com=(l / 2, 0.0, 0.0),
            inertia=ROD_MASS * l**2 / 12,
            shapes=[Shape("box", (l, 0.02, 0.02), Frame.at(l / 2, 0, 0))],
        )
        a, b = SLIDER_SIZE
        model.add_body(
            "slider",
            SLIDER_MASS,
            inertia=SLIDER_MASS * (a**2 + b**2) / 12,
            shapes=[Shape("box", (a, b, 0.05), color=(200, 120, 80))],
        )
        model.add_joint("crank", "revolute", "ground", "crank_arm")
        model.add_joint("crank_pin", "revolute", "crank_arm", "rod", parent_frame=Frame.at(r, 0, 0))
        model.add_joint("slide", "prismatic", "ground", "slider", axis=(1.0, 0.0, 0.0))
        model.add_joint(
            "piston_pin", "revolute", "rod", "slider", parent_frame=Frame.at(l, 0, 0), cut=True
        )
        return model

    def _state(self) -> dict[str, tuple[float, float]]:
        return consistent_state(self.options.initial_crank_angle, self.options.initial_crank_rate)

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {joint: value for joint, (value, _) in self._state().items()}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {joint: rate for joint, (_, rate) in self._state().items()}
