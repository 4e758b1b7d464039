"""The formalism-neutral description of a mechanism (docs/architecture.md, "The model").

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
:mod:`workbench.mechanics.joints` for each type's coordinates and velocities.

``initial_configuration`` {tree joint: coordinates} is where the model is analysed: the
rank of the constraint Jacobian, hence the degrees of freedom and which constraint rows
are redundant, are decided there (assembled, and confirmed at a few random assembled
configurations near it; :func:`workbench.mechanics.topology.rank_configurations`), by
``workbench describe`` and every formalism alike. Joints left out take their neutral
coordinates. A neutral configuration can be singular (a four-link loop with every angle zero
has all bars along one line), so a problem's model carries the problem's initial joint
coordinates here (:class:`workbench.plugin.problem.Problem` fills it in).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from workbench.errors import ModelError
from workbench.model.elements import (
    GROUND,
    Body,
    Contact,
    Drive,
    ForceElement,
    Frame,
    Joint,
    JointFriction,
    NonholonomicConstraint,
    PlaneContact,
    Shape,
    SphereContact,
    real_array,
)
from workbench.model.validation import validate_model


@dataclass
class Model:
    """A mechanism: ``kind`` is "planar" or "spatial"; ``gravity`` in m/s^2 (inertial);
    ``initial_configuration`` {tree joint: coordinates} where its rank is decided (see the
    module docstring)."""

    name: str
    kind: Literal["planar", "spatial"] = "spatial"
    gravity: np.ndarray | None = None
    bodies: dict[str, Body] = field(default_factory=dict)
    joints: dict[str, Joint] = field(default_factory=dict)
    forces: list[ForceElement] = field(default_factory=list)
    nonholonomic: list[NonholonomicConstraint] = field(default_factory=list)
    contacts: list[Contact] = field(default_factory=list)
    joint_frictions: list[JointFriction] = field(default_factory=list)
    initial_configuration: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.gravity is None:
            self.gravity = (
                np.array([0.0, -9.81, 0.0]) if self.kind == "planar" else np.array([0, 0, -9.81])
            )
        self.gravity = real_array(self.gravity, f"model {self.name!r}, gravity", "gravity")

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
        where = f"model {self.name!r}, body {name!r}"
        if inertia is not None:  # None: validation says a rigid body needs an inertia
            inertia = real_array(inertia, where, "inertia")
        inertia_matrix = _inertia_matrix(inertia, self.kind)
        com_vector = real_array(com, where, "com (centre of mass)")
        body = Body(name, _mass(where, mass), com_vector, inertia_matrix, False, tuple(shapes))
        self._add(self.bodies, name, body)
        return body

    def add_point_mass(
        self,
        name: str,
        mass: float,
        shapes: tuple[Shape, ...] | list[Shape] = (),
        com: Any = (0.0, 0.0, 0.0),
    ) -> Body:
        """Add a point mass (no rotational inertia) at ``com`` in its body frame (default
        the origin; e.g. a robot link whose file gives a mass and a zero inertia). Mass 0
        is a massless link between joints (a gimbal's), which must carry other bodies."""
        where = f"model {self.name!r}, body {name!r}"
        position = real_array(com, where, "com (centre of mass)")
        body = Body(name, _mass(where, mass), position, np.zeros((3, 3)), True, tuple(shapes))
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
        where = f"model {self.name!r}, joint {name!r}"
        for frame_name, frame in (("parent_frame", parent_frame), ("child_frame", child_frame)):
            if frame is not None and not isinstance(frame, Frame):
                raise ModelError(
                    f"{where}: {frame_name} must be a Frame (e.g. Frame.at(x, y, z)), not "
                    f"{frame.__class__.__name__}"  # (type is a parameter here)
                )
        joint = Joint(
            name,
            type,
            parent,
            child,
            parent_frame or Frame(),
            child_frame or Frame(),
            real_array(axis, where, "axis").reshape(-1),
            real_array(axis2, where, "axis2").reshape(-1),
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

    def add_contact(
        self,
        name: str,
        body: str,
        point: Any = (0.0, 0.0, 0.0),
        radius: float = 0.0,
        plane_point: Any = (0.0, 0.0, 0.0),
        plane_normal: Any = None,
        restitution: float = 0.0,
        friction: float = 0.0,
    ) -> PlaneContact:
        """Add a unilateral contact of a sphere (a point if ``radius`` is 0) of ``body``
        against a fixed plane (normal default: +y in a planar model, +z in a spatial one)."""
        self._check_new_name(name)
        where = f"model {self.name!r}, contact {name!r}"
        if plane_normal is None:
            plane_normal = (0.0, 1.0, 0.0) if self.kind == "planar" else (0.0, 0.0, 1.0)
        contact = PlaneContact(
            name,
            body,
            real_array(point, where, "point").reshape(-1),
            float(real_array(radius, where, "radius", ())),
            real_array(plane_point, where, "plane_point").reshape(-1),
            real_array(plane_normal, where, "plane_normal").reshape(-1),
            float(real_array(restitution, where, "restitution", ())),
            float(real_array(friction, where, "friction", ())),
        )
        self.contacts.append(contact)
        return contact

    def add_sphere_contact(
        self,
        name: str,
        body_a: str,
        radius_a: float,
        body_b: str,
        radius_b: float,
        centre_a: Any = (0.0, 0.0, 0.0),
        centre_b: Any = (0.0, 0.0, 0.0),
        restitution: float = 0.0,
        friction: float = 0.0,
    ) -> SphereContact:
        """Add a unilateral contact between a sphere of ``body_a`` and one of ``body_b``
        (centres in the bodies' frames; ``body_b`` may be the ground)."""
        self._check_new_name(name)
        where = f"model {self.name!r}, contact {name!r}"
        contact = SphereContact(
            name,
            body_a,
            real_array(centre_a, where, "centre_a").reshape(-1),
            float(real_array(radius_a, where, "radius_a", ())),
            body_b,
            real_array(centre_b, where, "centre_b").reshape(-1),
            float(real_array(radius_b, where, "radius_b", ())),
            float(real_array(restitution, where, "restitution", ())),
            float(real_array(friction, where, "friction", ())),
        )
        self.contacts.append(contact)
        return contact

    def add_joint_friction(self, joint: str, bound: float) -> JointFriction:
        """Add Coulomb friction to the one-coordinate joint ``joint`` (revolute: a torque
        bound in N m; prismatic: a force bound in N); set-valued, so only integrators that
        take contacts run such a model."""
        where = f"model {self.name!r}, joint friction of {joint!r}"
        if any(f.joint == joint for f in self.joint_frictions):
            raise ModelError(f"{where}: the joint has friction already; add it once")
        friction = JointFriction(joint, float(real_array(bound, where, "bound", ())))
        self.joint_frictions.append(friction)
        return friction

    def _add(self, table: dict, name: str, item: Any) -> None:
        self._check_new_name(name)
        table[name] = item

    def _check_new_name(self, name: str) -> None:
        if not isinstance(name, str) or not name:
            raise ModelError(f"model {self.name!r}: every element needs a non-empty name")
        if name == GROUND:
            raise ModelError(f"model {self.name!r}: {GROUND!r} is reserved for the inertial frame")
        # dictionary look-ups first: building a 10,000-link chain stays O(n)
        taken = name in self.bodies or name in self.joints
        taken = taken or any(f.name == name for f in self.forces)
        taken = taken or any(c.name == name for c in self.contacts)
        if taken or any(c.name == name for c in self.nonholonomic):
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
        validate_model(self)
        return self

    def _repr_html_(self) -> str:
        """Jupyter's view: the joints (type, parent -> child, cut, driven) and the bodies."""
        from html import escape

        joints = "".join(
            f"<tr><td>{escape(j.name)}</td><td>{escape(j.type)}</td>"
            f"<td>{escape(j.parent)} &rarr; {escape(j.child)}</td>"
            f"<td>{'cut' if j.cut else ''}{' driven' if j.drive is not None else ''}</td></tr>"
            for j in self.joints.values()
        )
        bodies = ", ".join(
            f"{escape(b.name)} ({b.mass:g} kg{', point mass' if b.point_mass else ''})"
            for b in self.bodies.values()
        )
        return (
            f"<b>model {escape(self.name)}</b> ({self.kind}; {len(self.bodies)} bodies, "
            f"{len(self.joints)} joints, {len(self.forces)} force elements, "
            f"{len(self.nonholonomic)} nonholonomic constraints)"
            f"<table><tr><th>joint</th><th>type</th><th>parent &rarr; child</th><th></th></tr>"
            f"{joints}</table><p>bodies: {bodies}</p>"
        )


def _mass(where: str, mass: Any) -> float:
    """A mass is a real number (a string such as "1" is refused); its sign is validation's."""
    return float(real_array(mass, where, "mass", ()))


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
