"""A model's physical parameters as rows of text, in SI units, for ``workbench describe``.

Read from the :class:`~workbench.model.Model` itself rather than from a docstring, so what
is shown is what the formalisms integrate: gravity; every body's mass, centre of mass and
inertia; every joint's type, parents, location and axis (and drive); force elements;
nonholonomic constraints and contacts. Each row is ``(element, quantity, value with unit)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from workbench.model.elements import (
    AppliedForce,
    Body,
    Joint,
    JointForce,
    JointSpringDamper,
    KnifeEdge,
    RollingDisk,
    RollingSphere,
    SphereContact,
    SpringDamper,
)
from workbench.model.model import Model

Row = tuple[str, str, str]

AXIS_JOINTS = ("revolute", "prismatic", "cylindrical", "universal")
# per joint type: the unit of its coordinate (for joint springs)
ANGULAR = {"revolute": "rad", "spherical": "rad", "universal": "rad"}


def number(value: float) -> str:
    return f"{float(value):.4g}"


def vector(values: Any, planar: bool = False) -> str:
    """``(x, y, z)`` with 4 significant digits, round-off (cos(pi/2)) shown as 0; planar
    models drop the zero z."""
    array = np.asarray(values, dtype=float).reshape(-1)
    array = np.where(np.abs(array) < 1e-12 * max(1.0, np.abs(array).max()), 0.0, array)
    if planar and array.size == 3 and array[2] == 0.0:
        array = array[:2]
    return "(" + ", ".join(number(x) for x in array) + ")"


def model_parameters(model: Model) -> list[Row]:
    """Every physical parameter of ``model``, one row each (see the module docstring)."""
    planar = model.kind == "planar"
    rows: list[Row] = [("model", "gravity", f"{vector(model.gravity, planar)} m/s^2")]
    for body in model.bodies.values():
        rows += _body_rows(body, planar)
    for joint in model.joints.values():
        rows += _joint_rows(joint, planar)
    for element in model.forces:
        rows += _force_rows(element, model, planar)
    for constraint in model.nonholonomic:
        rows += _nonholonomic_rows(constraint, planar)
    for contact in model.contacts:
        rows.append(_contact_row(contact, planar))
    for friction in model.joint_frictions:
        joint = model.joints.get(friction.joint)
        unit = "N m" if joint is not None and joint.type == "revolute" else "N"
        rows.append((friction.joint, "Coulomb friction bound", f"{number(friction.bound)} {unit}"))
    return rows


def _body_rows(body: Body, planar: bool) -> list[Row]:
    if body.point_mass:
        rows = [(body.name, "point mass", f"{number(body.mass)} kg")]
        if np.any(np.asarray(body.com, float)):
            rows.append((body.name, "at (body frame)", f"{vector(body.com, planar)} m"))
        return rows
    rows = [(body.name, "mass", f"{number(body.mass)} kg")]
    rows.append((body.name, "centre of mass (body frame)", f"{vector(body.com, planar)} m"))
    inertia = np.asarray(body.inertia, dtype=float)
    if planar:
        rows.append((body.name, "Izz about the centre of mass", f"{number(inertia[2, 2])} kg m^2"))
    elif np.count_nonzero(inertia - np.diag(np.diag(inertia))) == 0:
        rows.append((body.name, "inertia about the centre of mass (diagonal)",
                     f"{vector(np.diag(inertia))} kg m^2"))  # fmt: skip
    else:
        rows.append((body.name, "inertia about the centre of mass",
                     "[" + "; ".join(vector(r)[1:-1] for r in inertia) + "] kg m^2"))  # fmt: skip
    return rows


def _joint_rows(joint: Joint, planar: bool) -> list[Row]:
    kind = f"{joint.type}{' (loop-closing cut joint)' if joint.cut else ''}"
    rows = [(joint.name, "type", f"{kind}: {joint.parent} -> {joint.child}")]
    on_parent = vector(joint.parent_frame.position, planar)
    rows.append((joint.name, "location on the parent", f"{on_parent} m"))
    if np.any(joint.child_frame.position):
        on_child = vector(joint.child_frame.position, planar)
        rows.append((joint.name, "location on the child", f"{on_child} m"))
    if joint.type in AXIS_JOINTS and not planar:
        rows.append((joint.name, "axis", vector(joint.axis)))
    if joint.type == "universal":
        rows.append((joint.name, "second axis", vector(joint.axis2)))
    if joint.drive is not None:
        rows.append((joint.name, "driven (rheonomic)", _function_name(joint.drive.position)))
    return rows


def _force_rows(element: Any, model: Model, planar: bool) -> list[Row]:
    name = element.name
    if isinstance(element, SpringDamper):
        return [
            (name, "spring-damper", f"{element.body1} {vector(element.point1, planar)} m -> "
                                    f"{element.body2} {vector(element.point2, planar)} m"),
            (name, "stiffness, damping, rest length",
             f"{number(element.stiffness)} N/m, {number(element.damping)} N s/m, "
             f"{number(element.rest_length)} m"),
        ]  # fmt: skip
    if isinstance(element, JointSpringDamper):
        joint_type = model.joints[element.joint].type if element.joint in model.joints else ""
        angular = joint_type in ANGULAR
        rest = np.atleast_1d(np.asarray(element.rest, dtype=float))
        return [(name, f"joint spring-damper on {element.joint}",
                 f"{number(element.stiffness)} {'N m/rad' if angular else 'N/m'}, "
                 f"{number(element.damping)} {'N m s/rad' if angular else 'N s/m'}, rest "
                 f"{', '.join(number(r) for r in rest)} {'rad' if angular else 'm'}")]  # fmt: skip
    if isinstance(element, JointForce):
        return [(name, f"joint force on {element.joint}", _function_name(element.function))]
    if isinstance(element, AppliedForce):
        return [(name, f"applied force on {element.body} at {vector(element.point, planar)} m",
                 _function_name(element.function))]  # fmt: skip
    return [(name, type(element).__name__, repr(element))]


def _nonholonomic_rows(constraint: Any, planar: bool) -> list[Row]:
    name, body = constraint.name, constraint.body
    if isinstance(constraint, RollingSphere):
        text = f"radius {number(constraint.radius)} m, centre {vector(constraint.center)} m"
        if constraint.plane_rate:
            text += f", plane turning at {number(constraint.plane_rate)} rad/s about z"
        return [(name, f"sphere of {body} rolling on z = 0", text)]
    if isinstance(constraint, RollingDisk):
        return [(name, f"disk of {body} rolling without slip",
                 f"radius {number(constraint.radius)} m, centre {vector(constraint.center, planar)}"
                 f" m, normal {vector(constraint.axis)}")]  # fmt: skip
    if isinstance(constraint, KnifeEdge):
        return [(name, f"knife edge on {body}",
                 f"no velocity of {vector(constraint.point, planar)} m along "
                 f"{vector(constraint.direction, planar)}")]  # fmt: skip
    return [(name, type(constraint).__name__, repr(constraint))]


def _contact_row(contact: Any, planar: bool) -> Row:
    if isinstance(contact, SphereContact):
        return (
            contact.name,
            f"unilateral contact of {contact.body_a} with {contact.body_b}",
            f"sphere r {number(contact.radius_a)} m at {vector(contact.centre_a, planar)} m of "
            f"{contact.body_a}, sphere r {number(contact.radius_b)} m at "
            f"{vector(contact.centre_b, planar)} m of {contact.body_b}; restitution e "
            f"{number(contact.restitution)}, friction mu {number(contact.friction)}",
        )
    shape = f"sphere r {number(contact.radius)} m" if contact.radius else "point"
    return (
        contact.name,
        f"unilateral contact of {contact.body} with a plane",
        f"{shape} at {vector(contact.point, planar)} m; plane through "
        f"{vector(contact.plane_point, planar)} m, normal {vector(contact.plane_normal, planar)};"
        f" restitution e {number(contact.restitution)}, friction mu {number(contact.friction)}",
    )


def _function_name(function: Any) -> str:
    """A user function by its qualified name (its numbers live in the problem's module)."""
    return f"function {getattr(function, '__qualname__', repr(function))}(...)"
