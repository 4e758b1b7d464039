"""The elements of a mechanism: frames, bodies, joints, force elements, constraints.

Plain frozen data (docs/architecture.md, "The model"), with no behaviour beyond normalizing their
inputs; :class:`~workbench.model.model.Model` gathers them and validation judges them.
Units: SI; vectors (3,) and tensors (3, 3) in body coordinates.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from workbench.errors import ModelError

GROUND = "ground"

JointType = Literal[
    "revolute", "prismatic", "cylindrical", "universal", "spherical", "planar", "free", "fixed"
]
JOINT_TYPES: tuple[str, ...] = (
    "revolute",
    "prismatic",
    "cylindrical",
    "universal",
    "spherical",
    "planar",
    "free",
    "fixed",
)
PLANAR_JOINT_TYPES: tuple[str, ...] = ("revolute", "prismatic", "planar", "fixed")
JOINT_DIMENSIONS: dict[str, tuple[int, int]] = {
    "revolute": (1, 1),
    "prismatic": (1, 1),
    "cylindrical": (2, 2),
    "universal": (2, 2),
    "spherical": (4, 3),
    "planar": (3, 3),
    "free": (7, 6),
    "fixed": (0, 0),
}
"""(nq, nv) of each joint type: its coordinates and velocities (the table of
:mod:`workbench.mechanics.joints`); a drive gives nq positions and nv velocities."""


def real_array(
    value: Any, where: str, name: str, shape: tuple[int, ...] | None = None
) -> np.ndarray:
    """``value`` as a float array (of ``shape`` if given) of real numbers, else ModelError.

    Strings, booleans, complex numbers and objects are refused (``np.asarray(value,
    dtype=float)`` would read ``"1"`` as 1.0); ``where`` names the element, ``name`` the
    parameter. Finiteness is validation's to judge (it names the element too).
    """
    expected = "a number" if shape == () else f"numbers of shape {shape}" if shape else "numbers"
    try:
        array = np.asarray(value)
        kind = array.dtype.kind
        if _not_numbers(value):
            kind = "?"
        elif kind == "O":  # e.g. a list of NumPy and Python numbers: try a float array
            array, kind = np.asarray(value, dtype=float), "f"
    except (TypeError, ValueError, OverflowError):
        kind = "?"
    if kind not in ("i", "u", "f"):
        raise ModelError(
            f"{where}: {name} must be {expected} (float), not {type(value).__name__} "
            f"{_short(value)}"
        )
    array = array.astype(float)
    if shape is not None and array.shape != shape:
        if array.size == int(np.prod(shape)) and shape != ():
            return array.reshape(shape)
        raise ModelError(f"{where}: {name} must be {expected}, not an array of shape {array.shape}")
    return array


def _not_numbers(value: Any) -> bool:
    """Holds a string, boolean or None (NumPy would read them as numbers or NaN)."""
    if value is None or isinstance(value, str | bytes | bool | np.bool_):
        return True
    if isinstance(value, list | tuple):
        return any(_not_numbers(item) for item in value)
    return False


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _vector(value: Any, size: int = 3) -> np.ndarray:
    array = np.asarray(value, dtype=float).reshape(-1)
    if array.shape != (size,):
        raise ValueError(f"expected {size} components, got {array.shape[0]}")
    return array


@dataclass(frozen=True)
class Frame:
    """A frame fixed on a body: origin ``position`` (3,), ``rotation`` (3, 3), body coordinates."""

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    @staticmethod
    def at(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Frame:
        """A frame translated to (x, y, z), not rotated."""
        return Frame(np.array([x, y, z], dtype=float), np.eye(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", real_array(self.position, "frame", "position", (3,)))
        rotation = real_array(self.rotation, "frame", "rotation", (3, 3))
        object.__setattr__(self, "rotation", rotation)


@dataclass(frozen=True)
class Shape:
    """Visual geometry for 3D logging, placed at ``frame`` in the body frame.

    kind: "box" (size = full edge lengths x, y, z), "cylinder" (radius, length along the
    frame's z), "sphere" (radius), "capsule" (radius, length along z), "mesh" (size = the
    scale along x, y, z of the mesh file at ``path``, e.g. a robot file's visual mesh).
    """

    kind: Literal["box", "cylinder", "sphere", "capsule", "mesh"]
    size: tuple[float, ...]
    frame: Frame = field(default_factory=Frame)
    color: tuple[int, int, int] = (120, 160, 220)
    path: str = ""


@dataclass(frozen=True)
class Body:
    """A rigid body, or a point mass (``point_mass=True``, zero inertia)."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    point_mass: bool = False
    shapes: tuple[Shape, ...] = ()


@dataclass(frozen=True)
class Drive:
    """A prescribed joint motion q(t) with its first and second time derivatives.

    Each callable takes t (a float or a CasADi symbol) and returns the joint's nq
    coordinates (position) or nv velocities (velocity, acceleration; ``JOINT_DIMENSIONS``),
    a float for a one-coordinate joint, else a sequence. Write them with ``casadi``
    functions (``casadi.sin`` ...), which accept floats and symbols alike. Validation
    checks the sizes, that velocity and acceleration are the exact time derivatives (of
    Euler parameters p, the angular velocity 2 G(p) p' of the child in its own frame) and
    that Euler parameters are of unit norm.
    """

    position: Callable[[Any], Any]
    velocity: Callable[[Any], Any] | None = None
    acceleration: Callable[[Any], Any] | None = None


@dataclass(frozen=True)
class Joint:
    """A joint between ``parent`` (a body name or ``"ground"``) and ``child``.

    ``axis``: the motion axis of revolute, prismatic and cylindrical joints and the first
    axis of a universal joint, in frame P. ``axis2``: the universal joint's second axis,
    in the frame after the first rotation. ``cut``: a loop-closing joint, not part of the
    spanning tree. ``drive``: prescribed (rheonomic) motion.
    """

    name: str
    type: str
    parent: str
    child: str
    parent_frame: Frame = field(default_factory=Frame)
    child_frame: Frame = field(default_factory=Frame)
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    axis2: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    cut: bool = False
    drive: Drive | None = None


# ---- force elements -------------------------------------------------------------------


@dataclass(frozen=True)
class SpringDamper:
    """Point-to-point spring-damper between ``point1`` on ``body1`` and ``point2`` on ``body2``.

    Force magnitude along the line: stiffness * (length - rest_length) + damping * length'.
    Either body may be ``"ground"`` (point then in the inertial frame).
    """

    name: str
    body1: str
    point1: np.ndarray
    body2: str
    point2: np.ndarray
    stiffness: float
    damping: float = 0.0
    rest_length: float = 0.0


@dataclass(frozen=True)
class JointSpringDamper:
    """Spring-damper acting on a joint's coordinates.

    Generalized force: -stiffness * d - damping * v, one value per joint velocity, where
    the deflection d is q - rest for joints with one coordinate per velocity; on a
    spherical joint (rest: a unit quaternion) d is the rotation vector of rest^-1 q (axis
    times angle, in the child frame), on a free joint (rest: position and unit quaternion)
    the position difference then that rotation vector: MuJoCo's ball and free joint
    springs. Energy 1/2 stiffness |d|^2.
    """

    name: str
    joint: str
    stiffness: float
    damping: float = 0.0
    rest: float | tuple[float, ...] = 0.0


@dataclass(frozen=True)
class JointForce:
    """A generalized force (torque for rotations) on a joint: ``function(t, q, v)``.

    q and v are the joint's own coordinates and velocities (CasADi-compatible
    expressions); the function returns one value per joint velocity.
    """

    name: str
    joint: str
    function: Callable[[Any, Any, Any], Any]


@dataclass(frozen=True)
class AppliedForce:
    """A force and torque on ``body`` at ``point`` (body frame), in inertial coordinates.

    ``function(t, position, rotation, velocity, angular_velocity)`` receives the body's
    reference-frame pose and twist in inertial coordinates and returns (force (3,),
    torque (3,)); write it with CasADi-compatible operations.
    """

    name: str
    body: str
    point: np.ndarray
    function: Callable[..., tuple[Any, Any]]


ForceElement = SpringDamper | JointSpringDamper | JointForce | AppliedForce


# ---- nonholonomic constraints -------------------------------------------------------


@dataclass(frozen=True)
class RollingSphere:
    """A sphere (centre ``center`` in the body frame) rolling without slip on the plane z = 0.

    The plane rotates about the inertial z axis at ``plane_rate`` (rad/s). Holonomic part:
    the centre stays at height ``radius``; nonholonomic part: the contact point's velocity
    equals the plane's (two rows).
    """

    name: str
    body: str
    radius: float
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    plane_rate: float = 0.0


@dataclass(frozen=True)
class RollingDisk:
    """A thin disk (centre ``center``, normal ``axis`` in the body frame) rolling on z = 0.

    In a planar model the disk rolls on the line y = 0 (its axis is z).
    """

    name: str
    body: str
    radius: float
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))


@dataclass(frozen=True)
class KnifeEdge:
    """No velocity of ``point`` (body frame) along ``direction`` (body frame): one row."""

    name: str
    body: str
    point: np.ndarray
    direction: np.ndarray


NonholonomicConstraint = RollingSphere | RollingDisk | KnifeEdge


# ---- unilateral contacts ------------------------------------------------------------


@dataclass(frozen=True)
class PlaneContact:
    """A sphere of ``body`` (centre ``point`` in the body frame, ``radius`` >= 0; 0: a point)
    against a fixed plane through ``plane_point`` with unit outward ``plane_normal``
    (inertial). Unilateral: the gap g_N = n . (centre - plane_point) - radius stays >= 0.

    ``restitution`` e in [0, 1]: Newton's impact law U_N+ = -e U_N- at a closing contact.
    ``friction`` mu >= 0: Coulomb's law at the contact point, |lambda_T| <= mu lambda_N,
    opposing the sliding velocity when it slides (Glocker's set-valued force laws).
    """

    name: str
    body: str
    point: np.ndarray
    radius: float = 0.0
    plane_point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    plane_normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    restitution: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True)
class SphereContact:
    """A sphere of ``body_a`` (centre ``centre_a`` in its frame, ``radius_a`` > 0) against a
    sphere of ``body_b`` (``centre_b``, ``radius_b`` > 0; ``body_b`` may be the ground: a
    fixed sphere). Unilateral: the gap g_N = |c_B - c_A| - r_A - r_B stays >= 0, along the
    normal n = (c_B - c_A) / |c_B - c_A| from A to B (inertial centres c_A, c_B).

    ``restitution`` and ``friction`` as in :class:`PlaneContact`, at the touching points.
    """

    name: str
    body_a: str
    centre_a: np.ndarray
    radius_a: float
    body_b: str
    centre_b: np.ndarray
    radius_b: float
    restitution: float = 0.0
    friction: float = 0.0


Contact = PlaneContact | SphereContact


@dataclass(frozen=True)
class JointFriction:
    """Coulomb friction in a one-coordinate joint ``joint`` (revolute: a torque in N m;
    prismatic: a force in N) with a given ``bound`` >= 0: while the joint slides it acts
    against the joint rate with magnitude ``bound``; while it sticks it is whatever keeps
    the rate zero, if that stays within the bound (Glocker's set-valued force law)."""

    joint: str
    bound: float

    @property
    def name(self) -> str:
        return f"{self.joint}.friction"
