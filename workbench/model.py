"""The formalism-neutral description of a mechanism (DESIGN.md, "The model").

A :class:`Model` is plain data: bodies, joints (tree and loop-closing), force elements,
nonholonomic constraints and visual shapes. It knows nothing of coordinates chosen by a
formalism. Build one with the ``add_*`` methods, then call :meth:`Model.validate` (done by
every formalism) which raises :class:`~workbench.errors.ModelError` on bad input.

Conventions: SI units; a body's frame is its reference frame; centre of mass and inertia
tensor are given in the body frame (inertia about the centre of mass). Planar models move
in the x-y plane with rotations about z; they are described with the same 3D data (all
z components zero) so every formalism may treat them as spatial ones.

Joint convention: a joint connects a frame P fixed on the parent (``parent_frame``, in
the parent's body frame; the ground's frame is the inertial frame) and a frame C fixed on
the child (``child_frame``, in the child's body frame). The joint's coordinates q give the
pose of C relative to P; at the neutral q, C coincides with P. See
:mod:`workbench.joints` for each type's coordinates and velocities.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

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
        object.__setattr__(self, "position", np.asarray(self.position, dtype=float).reshape(3))
        object.__setattr__(self, "rotation", np.asarray(self.rotation, dtype=float).reshape(3, 3))


@dataclass(frozen=True)
class Shape:
    """Visual geometry for 3D logging, placed at ``frame`` in the body frame.

    kind: "box" (size = full edge lengths x, y, z), "cylinder" (radius, length along the
    frame's z), "sphere" (radius), "capsule" (radius, length along z).
    """

    kind: Literal["box", "cylinder", "sphere", "capsule"]
    size: tuple[float, ...]
    frame: Frame = field(default_factory=Frame)
    color: tuple[int, int, int] = (120, 160, 220)


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

    Each callable takes t (a float or a CasADi symbol) and returns the joint coordinates
    (a float for a one-coordinate joint, else a sequence). Write them with ``casadi``
    functions (``casadi.sin`` ...), which accept floats and symbols alike.
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
    """Spring-damper acting on a joint's coordinates (one-coordinate-per-velocity joints).

    Generalized force: -stiffness * (q - rest) - damping * v, per joint coordinate.
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


@dataclass
class Model:
    """A mechanism: ``kind`` is "planar" or "spatial"; ``gravity`` in m/s^2 (inertial)."""

    name: str
    kind: Literal["planar", "spatial"] = "spatial"
    gravity: np.ndarray | None = None
    bodies: dict[str, Body] = field(default_factory=dict)
    joints: dict[str, Joint] = field(default_factory=dict)
    forces: list[ForceElement] = field(default_factory=list)
    nonholonomic: list[NonholonomicConstraint] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.gravity is None:
            self.gravity = (
                np.array([0.0, -9.81, 0.0]) if self.kind == "planar" else np.array([0, 0, -9.81])
            )
        self.gravity = np.asarray(self.gravity, dtype=float)

    # -- building ---------------------------------------------------------------------
    def add_body(
        self,
        name: str,
        mass: float,
        com: Any = (0.0, 0.0, 0.0),
        inertia: Any = None,
        shapes: tuple[Shape, ...] | list[Shape] = (),
    ) -> Body:
        """Add a rigid body. ``inertia``: 3x3 about the centre of mass in the body frame,
        three principal moments, or (planar models) a scalar Izz."""
        inertia_matrix = _inertia_matrix(inertia, self.kind)
        body = Body(name, float(mass), np.asarray(com, dtype=float), inertia_matrix, False,
                    tuple(shapes))
        self._add(self.bodies, name, body)
        return body

    def add_point_mass(
        self, name: str, mass: float, shapes: tuple[Shape, ...] | list[Shape] = ()
    ) -> Body:
        """Add a point mass at its body frame's origin (no rotational inertia)."""
        body = Body(name, float(mass), np.zeros(3), np.zeros((3, 3)), True, tuple(shapes))
        self._add(self.bodies, name, body)
        return body

    def add_joint(
        self,
        name: str,
        type: str,
        parent: str,
        child: str,
        parent_frame: Frame | None = None,
        child_frame: Frame | None = None,
        axis: Any = (0.0, 0.0, 1.0),
        axis2: Any = (0.0, 1.0, 0.0),
        cut: bool = False,
        drive: Drive | None = None,
    ) -> Joint:
        """Add a joint; ``cut=True`` marks a loop-closing joint."""
        joint = Joint(
            name,
            type,
            parent,
            child,
            parent_frame or Frame(),
            child_frame or Frame(),
            np.asarray(axis, dtype=float).reshape(-1),
            np.asarray(axis2, dtype=float).reshape(-1),
            cut,
            drive,
        )
        self._add(self.joints, name, joint)
        return joint

    def add_force(self, element: ForceElement) -> ForceElement:
        self._check_new_name(element.name)
        self.forces.append(element)
        return element

    def add_nonholonomic(self, constraint: NonholonomicConstraint) -> NonholonomicConstraint:
        self._check_new_name(constraint.name)
        self.nonholonomic.append(constraint)
        return constraint

    def _add(self, table: dict, name: str, item: Any) -> None:
        self._check_new_name(name)
        table[name] = item

    def _check_new_name(self, name: str) -> None:
        from workbench.errors import ModelError

        if not isinstance(name, str) or not name:
            raise ModelError(f"model {self.name!r}: every element needs a non-empty name")
        if name == GROUND:
            raise ModelError(f"model {self.name!r}: {GROUND!r} is reserved for the inertial frame")
        taken = set(self.bodies) | set(self.joints)
        taken |= {f.name for f in self.forces} | {c.name for c in self.nonholonomic}
        if name in taken:
            raise ModelError(
                f"model {self.name!r}: duplicate name {name!r}; give every body, joint, "
                "force and constraint its own name"
            )

    # -- queries ----------------------------------------------------------------------
    @property
    def body_names(self) -> list[str]:
        return list(self.bodies)

    @property
    def tree_joints(self) -> list[Joint]:
        """The spanning-tree joints, in the order they were added."""
        return [j for j in self.joints.values() if not j.cut]

    @property
    def cut_joints(self) -> list[Joint]:
        return [j for j in self.joints.values() if j.cut]

    def validate(self) -> Model:
        """Raise ModelError naming the fault and its fix; return self when the model is sound."""
        from workbench.validation import validate_model

        validate_model(self)
        return self


def _inertia_matrix(inertia: Any, kind: str) -> np.ndarray:
    if inertia is None:
        return np.zeros((3, 3)) * np.nan  # caught by validation: rigid bodies need inertia
    array = np.asarray(inertia, dtype=float)
    if array.ndim == 0:
        if kind != "planar":
            return np.full((3, 3), np.nan)  # validation says: give a 3x3 tensor
        izz = float(array)
        # a thin disk with this Izz: satisfies the triangle inequality, out-of-plane unused
        return np.diag([izz / 2, izz / 2, izz])
    if array.shape == (3,):
        return np.diag(array)
    return array.reshape(3, 3) if array.size == 9 else np.full((3, 3), np.nan)
