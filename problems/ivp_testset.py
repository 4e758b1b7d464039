"""Mechanical problems of the Test Set for IVP Solvers (F. Mazzia, C. Magherini, Univ. Bari,
release 2.4, 2008, https://archimede.uniba.it/~testset/), in the test set's own coordinates
and parameters, so that its published end states are directly comparable
(``problems/references/published/*.toml``, read by :mod:`problems.published`).

**Andrews' squeezing mechanism** (``andrews``; Hairer & Wanner, Solving ODEs II, §VII.7;
test set file ``andrews.f``, revision 1.2 of 2006-10-02): seven planar rigid bodies and
seven revolute joints to the ground or between bodies, no gravity, driven by a constant
motor torque mom = 0.033 N m on the crank and pulled by a spring (c0 = 4530 N/m, rest
length l0 = 0.07785 m) between point D of the triangle BDE and the fixed point C. The tree
joints are the test set's seven angles: ``beta`` (crank OF about O), ``Theta`` (FE relative
to OF, at F), ``gamma`` (triangle about B), ``Phi`` (EG relative to AG, at G), ``delta``
(AG about A), ``Omega`` (HE relative to AH, at H), ``epsilon`` (AH about A); with body
frames at the joints and every angle zero in the body frames used here, each joint
coordinate *is* the test set's variable y(1..7). Three cut revolute joints meet at E
(FE's end with the triangle, with EG and with HE): the test set's six constraints g(1..6),
index 3, 1 DOF. Body geometry: the points and centres of mass follow from the test set's
constraint functions and mass matrix (parameter names as in ``andrews.f``: rr, d, da,
ss, sa, sb, sc, sd, e, ea, zt, ta, tb, u, ua, ub, zf, fa, ra, all in m); a centre of mass
the dynamics fix only in distance (no gravity) lies along the body's x axis.
Initial state: the test set's y0 (31 digits), at rest; t_end = 0.03 s.

**Car axis** (``car-axis``; test set file ``caraxis.f``, revision 1.2; Rentrop, Strehmel
and Weiner 1996): two wheels, point masses k = M eps^2 / 2 (M = 10, eps = 0.01) at
(xl, yl) and (xr, yr), joined by a rigid axle of length L = 1; each wheel hangs on a
spring of stiffness 1 and rest length L0 = 0.5, the left one from the origin, the right
one from the point B(t) = (sqrt(L^2 - yb^2), yb), yb = r sin(w t) (r = 0.1, w = 10) that
an excitation moves on the circle of radius L; gravity g = 1 along -y; the left wheel's
position stays perpendicular to OB(t) (xb xl + yb yl = 0). Model: a driven revolute joint
``excitation`` turns a massless-in-effect frame ``guide`` (a point mass at the origin: its motion is
prescribed, so its mass never enters the wheels' dynamics) to the angle theta(t) =
asin(yb / L) of OB; the left wheel slides along that frame's y axis (``left``, prismatic:
the constraint xb xl + yb yl = 0 exactly) and carries the right wheel on a revolute joint
``axle`` at distance L (the constraint (xl - xr)^2 + (yl - yr)^2 = L^2 exactly); the
spring of the right wheel is anchored at the guide's point (L, 0), which is B(t). Bodies'
frame origins are the wheels, so their positions are the test set's y(1..4).
Initial state: the test set's y0 (xl, yl, xr, yr) = (0, L0, L, L0), (ul, vl, ur, vr) =
(-L0/L, 0, -L0/L, 0); t_end = 3.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

import workbench.plugin.registry
from workbench.model import Drive, Frame, JointForce, Model, Shape, SpringDamper
from workbench.plugin.problem import Problem

PUBLISHED = Path(__file__).parent / "references" / "published"


def published(problem: str) -> dict[str, Any]:
    """The published reference of ``problem`` with its provenance and the checks made here
    (``references/published/<problem>.toml``)."""
    with open(PUBLISHED / f"{problem}.toml", "rb") as file:
        return tomllib.load(file)


def significant_digits(values: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """The test set's (relative, mixed) significant correct digits of ``values`` against
    ``reference``: min over components of -log10(|err| / |ref|) and of
    -log10(|err| / (1 + |ref|))."""
    error = np.abs(np.asarray(values, float) - np.asarray(reference, float))
    relative = np.max(error / np.abs(reference))
    mixed = np.max(error / (1.0 + np.abs(reference)))
    with np.errstate(divide="ignore"):  # equal: infinitely many digits
        return float(-np.log10(relative)), float(-np.log10(mixed))


# ---- Andrews' squeezing mechanism: andrews.f, subroutine andfunc / the R port's defaults
ANDREWS = {
    "m1": 0.04325, "m2": 0.00365, "m3": 0.02373, "m4": 0.00706,
    "m5": 0.07050, "m6": 0.00706, "m7": 0.05498,
    "xa": -0.06934, "ya": -0.00227, "xb": -0.03635, "yb": 0.03273,
    "xc": 0.014, "yc": 0.072, "c0": 4530.0,
    "i1": 2.194e-6, "i2": 4.410e-7, "i3": 5.255e-6, "i4": 5.667e-7,
    "i5": 1.169e-5, "i6": 5.667e-7, "i7": 1.912e-5,
    "d": 28e-3, "da": 115e-4, "e": 2e-2, "ea": 1421e-5,
    "rr": 7e-3, "ra": 92e-5, "l0": 7785e-5,
    "ss": 35e-3, "sa": 1874e-5, "sb": 1043e-5, "sc": 18e-3, "sd": 2e-2,
    "ta": 2308e-5, "tb": 916e-5, "u": 4e-2, "ua": 1228e-5, "ub": 449e-5,
    "zf": 2e-2, "zt": 4e-2, "fa": 1421e-5, "mom": 33e-3,
}  # fmt: skip
# y0(1..7) of the test set (andrews.f, subroutine andinit / Hairer-Wanner (7.12))
ANDREWS_Q0 = {
    "beta": -0.0617138900142764496358948458001,
    "Theta": 0.0,
    "gamma": 0.455279819163070380255912382449,
    "Phi": 0.222668390165885884674473185609,
    "delta": 0.487364979543842550225598953530,
    "Omega": -0.222668390165885884674473185609,
    "epsilon": 1.23054744454982119249735015568,
}
ANDREWS_ANGLES = tuple(ANDREWS_Q0)  # the test set's order y(1..7)
ANDREWS_BODIES = ("OF", "FE", "BDE", "EG", "AG", "HE", "AH")  # K1 .. K7


def _bar(model: Model, name: str, mass: float, inertia: float, com: tuple, tip: tuple) -> None:
    """A planar body with its centre of mass at ``com`` and a bar drawn to ``tip`` (m)."""
    length = math.hypot(*tip)
    angle = math.atan2(tip[1], tip[0])
    rotation = np.array(
        [[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0], [0, 0, 1]]
    )
    shape = Shape("box", (length, 0.002, 0.002), Frame(np.array([*tip, 0.0]) / 2, rotation))
    model.add_body(name, mass, com=(*com, 0.0), inertia=inertia, shapes=[shape])


def andrews_model(name: str) -> Model:
    """Andrews' squeezing mechanism (see the module docstring); ``name``: the model's name."""
    p = ANDREWS
    model = Model(name, kind="planar", gravity=(0.0, 0.0, 0.0))
    _bar(model, "OF", p["m1"], p["i1"], (p["ra"], 0), (p["rr"], 0))
    _bar(model, "FE", p["m2"], p["i2"], (-p["da"], 0), (-p["d"], 0))
    _bar(model, "BDE", p["m3"], p["i3"], (math.hypot(p["sa"], p["sb"]), 0), (0, -p["ss"]))
    _bar(model, "EG", p["m4"], p["i4"], (0, -(p["e"] - p["ea"])), (0, -p["e"]))
    _bar(model, "AG", p["m5"], p["i5"], (math.hypot(p["ta"], p["tb"]), 0), (p["zt"], 0))
    _bar(model, "HE", p["m6"], p["i6"], (p["zf"] - p["fa"], 0), (p["zf"], 0))
    _bar(model, "AH", p["m7"], p["i7"], (math.hypot(p["ua"], p["ub"]), 0), (0, -p["u"]))
    a, b = Frame.at(p["xa"], p["ya"]), Frame.at(p["xb"], p["yb"])
    model.add_joint("beta", "revolute", "ground", "OF")
    model.add_joint("Theta", "revolute", "OF", "FE", Frame.at(p["rr"], 0))
    model.add_joint("gamma", "revolute", "ground", "BDE", b)
    model.add_joint("delta", "revolute", "ground", "AG", a)
    model.add_joint("Phi", "revolute", "AG", "EG", Frame.at(p["zt"], 0))
    model.add_joint("epsilon", "revolute", "ground", "AH", a)
    model.add_joint("Omega", "revolute", "AH", "HE", Frame.at(0, -p["u"]))
    e_on_fe = Frame.at(-p["d"], 0)
    model.add_joint("E_BDE", "revolute", "FE", "BDE", e_on_fe, Frame.at(0, -p["ss"]), cut=True)
    model.add_joint("E_EG", "revolute", "FE", "EG", e_on_fe, Frame.at(0, -p["e"]), cut=True)
    model.add_joint("E_HE", "revolute", "FE", "HE", e_on_fe, Frame.at(p["zf"], 0), cut=True)
    model.add_force(
        SpringDamper(
            "spring_CD",
            "BDE",
            np.array([p["sd"], -p["sc"], 0.0]),
            "ground",
            np.array([p["xc"], p["yc"], 0.0]),
            stiffness=p["c0"],
            rest_length=p["l0"],
        )
    )
    model.add_force(JointForce("motor", "beta", lambda t, q, v: p["mom"]))
    return model


def _planar_pose(x: float, y: float, angle: float) -> np.ndarray:
    return np.array([x, y, 0.0, math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])


def andrews_poses(angles: np.ndarray) -> np.ndarray:
    """Body poses (7, 7) [x, y, z, quaternion] of K1 .. K7 from the test set's angles
    y(1..7) = (beta, Theta, gamma, Phi, delta, Omega, epsilon) (rad)."""
    p = ANDREWS
    beta, theta, gamma, phi, delta, omega, epsilon = (float(a) for a in angles)
    f = (p["rr"] * math.cos(beta), p["rr"] * math.sin(beta))
    g = (p["xa"] + p["zt"] * math.cos(delta), p["ya"] + p["zt"] * math.sin(delta))
    h = (p["xa"] + p["u"] * math.sin(epsilon), p["ya"] - p["u"] * math.cos(epsilon))
    return np.stack(
        [
            _planar_pose(0.0, 0.0, beta),
            _planar_pose(*f, beta + theta),
            _planar_pose(p["xb"], p["yb"], gamma),
            _planar_pose(*g, delta + phi),
            _planar_pose(p["xa"], p["ya"], delta),
            _planar_pose(*h, epsilon + omega),
            _planar_pose(p["xa"], p["ya"], epsilon),
        ]
    )


def _angle(pose: np.ndarray) -> float:
    return 2.0 * math.atan2(float(pose[6]), float(pose[3]))


def andrews_angles(poses: np.ndarray, near: np.ndarray) -> np.ndarray:
    """The test set's angles y(1..7) from the body poses (7, 7) of K1 .. K7 (inverse of
    :func:`andrews_poses`), each taken in the turn nearest ``near`` (rad)."""
    of, fe, bde, eg, ag, he, ah = (_angle(pose) for pose in poses)
    angles = np.array([of, fe - of, bde, eg - ag, ag, he - ah, ah])
    return angles + 2 * math.pi * np.round((np.asarray(near, float) - angles) / (2 * math.pi))


@workbench.plugin.registry.problem
class Andrews(Problem):
    name = "andrews"
    summary = "Andrews' squeezing mechanism: 7 bodies, 3 loops at E, index 3 (IVP test set)"
    source = (
        "Test Set for IVP Solvers (Mazzia, Magherini, Bari 2008) andrews.f; "
        "Hairer & Wanner II §VII.7"
    )
    t_end = 0.03
    n_samples = 31
    conservative = False  # the motor torque does work
    benchmark = {
        "suite": "ivp",
        "measure": "scd",
        "variables": ["y(1..7) at t = 0.03 (here: the body poses they give)"],
    }
    independent_coordinates = (("beta", 0),)

    def model(self) -> Model:
        return andrews_model(self.name)

    def initial_joint_coordinates(self) -> dict[str, float]:
        return dict(ANDREWS_Q0)


# ---- car axis: caraxis.f, subroutine carfunc / carinit ---------------------------------
CAR_AXIS = {"eps": 1e-2, "M": 10.0, "L": 1.0, "L0": 0.5, "r": 0.1, "w": 10.0, "g": 1.0}


def car_axis_guide_angle(t: object) -> tuple[object, object, object]:
    """theta(t) = asin(yb / L) of the excitation point B(t), with its first and second
    time derivatives (CasADi-compatible: floats and symbols)."""
    p = CAR_AXIS
    yb = p["r"] * ca.sin(p["w"] * t)
    yb_rate = p["r"] * p["w"] * ca.cos(p["w"] * t)
    yb_accel = -p["r"] * p["w"] ** 2 * ca.sin(p["w"] * t)
    xb = ca.sqrt(p["L"] ** 2 - yb**2)
    xb_rate = -yb * yb_rate / xb
    return ca.asin(yb / p["L"]), yb_rate / xb, (yb_accel * xb - yb_rate * xb_rate) / xb**2


def car_axis_model(name: str) -> Model:
    """The car axis (see the module docstring)."""
    p = CAR_AXIS
    k = p["M"] * p["eps"] ** 2 / 2  # each wheel's mass
    model = Model(name, kind="planar", gravity=(0.0, -p["g"], 0.0))
    model.add_point_mass("guide", k)  # prescribed motion: its mass does not matter
    wheel = [Shape("sphere", (0.05,), color=(60, 60, 60))]
    model.add_point_mass("left_wheel", k, shapes=wheel)
    model.add_point_mass("right_wheel", k, shapes=wheel)
    drive = Drive(
        lambda t: car_axis_guide_angle(t)[0],
        lambda t: car_axis_guide_angle(t)[1],
        lambda t: car_axis_guide_angle(t)[2],
    )
    model.add_joint("excitation", "revolute", "ground", "guide", drive=drive)
    model.add_joint("left", "prismatic", "guide", "left_wheel", axis=(0.0, 1.0, 0.0))
    model.add_joint(
        "axle", "revolute", "left_wheel", "right_wheel", child_frame=Frame.at(-p["L"], 0, 0)
    )
    model.add_force(
        SpringDamper("left_spring", "ground", np.zeros(3), "left_wheel", np.zeros(3), 1.0,
                     rest_length=p["L0"])
    )  # fmt: skip
    model.add_force(
        SpringDamper("right_spring", "guide", np.array([p["L"], 0.0, 0.0]), "right_wheel",
                     np.zeros(3), 1.0, rest_length=p["L0"])
    )  # fmt: skip
    return model


def car_axis_poses(t: float, wheels: np.ndarray) -> np.ndarray:
    """Body poses (3, 7) of guide, left and right wheel at time t from the test set's
    positions y(1..4) = (xl, yl, xr, yr)."""
    xl, yl, xr, yr = (float(x) for x in wheels)
    theta = float(car_axis_guide_angle(float(t))[0])
    return np.stack(
        [
            _planar_pose(0.0, 0.0, theta),
            _planar_pose(xl, yl, theta),
            _planar_pose(xr, yr, math.atan2(yr - yl, xr - xl)),
        ]
    )


@workbench.plugin.registry.problem
class CarAxis(Problem):
    name = "car-axis"
    summary = "Car axis: two wheels on springs, rigid axle, excited end (IVP test set)"
    source = "Test Set for IVP Solvers (Mazzia, Magherini, Bari 2008) caraxis.f"
    t_end = 3.0
    n_samples = 301
    conservative = False  # the excitation drives it
    benchmark = {
        "suite": "ivp",
        "measure": "scd",
        "variables": ["xl, yl, xr, yr at t = 3 (the wheels' positions)"],
    }

    def model(self) -> Model:
        return car_axis_model(self.name)

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"left": CAR_AXIS["L0"], "axle": 0.0}

    def initial_joint_velocities(self) -> dict[str, float]:
        # theta'(0) = r w / L = 1 rad/s; ul = -s theta' = -L0/L; vl = s' = 0; the right
        # wheel's vr = vl + L cos(phi) phi' = 0 gives phi' = 0, so axle' = -theta'(0)
        theta_rate0 = float(car_axis_guide_angle(0.0)[1])
        return {"left": 0.0, "axle": -theta_rate0}


@workbench.plugin.registry.problem
class IftommA03(Andrews):
    """IFToMM benchmark A03 is Andrews' squeezer (González, Dopico, Lugrís, Cuadrado 2006:
    group A of the IFToMM multibody benchmark library) over 0.05 s, with the same bodies,
    spring and motor. The benchmark's own specification file was not at hand: its time
    and initial crank angle (beta0 = -0.0620 rad, the test set's y0 rounded to three
    digits) are read from the description of the benchmark in the OpenSim reproduction
    (rehabenggroup.github.io/MBSbenchmarksInOpenSim, A03_AndrewsMechanism); the test
    set's exact consistent y0 is used, so this problem differs from ``andrews`` only in
    its time span. Reference: stored, two pipelines (no published end state at 0.05 s)."""

    name = "iftomm-a03"
    summary = "IFToMM A03: Andrews' squeezing mechanism over 0.05 s (the andrews model)"
    source = (
        "IFToMM multibody benchmark A03 (Gonzalez et al. 2006), as described in the OpenSim "
        "reproduction of the benchmarks; model and y0 of the IVP test set's andrews.f"
    )
    t_end = 0.05
    n_samples = 51
    # the specification's own bound was not at hand: 1e-3 of the mechanism's size (about
    # 0.035 m), as A01's 1e-3 m is of its 1 m pendulum
    benchmark = {
        "suite": "iftomm",
        "precision": 3.5e-5,
        "measure": "err_max",
        "variables": ["every body's pose error (m); bound 1e-3 of the 0.035 m mechanism"],
    }
