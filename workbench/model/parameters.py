"""A model's physical parameters as rows of text, in SI units, for ``workbench describe``.

Read from the :class:`~workbench.model.Model` itself rather than from a docstring, so what
is shown is what the formalisms integrate: gravity; every body's mass, centre of mass and
inertia; every joint's type, parents, location and axis (and drive); force elements;
nonholonomic constraints and contacts. Each row is ``(element, quantity, value with unit)``.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import casadi as ca
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
# per joint type: (count, unit) groups of its coordinates, then of its velocities, in the
# order of workbench.mechanics.joints ("" for the Euler parameters, which have none)
STATE_UNITS: dict[str, tuple[tuple[tuple[int, str], ...], tuple[tuple[int, str], ...]]] = {
    "revolute": (((1, "rad"),), ((1, "rad/s"),)),
    "prismatic": (((1, "m"),), ((1, "m/s"),)),
    "cylindrical": (((1, "m"), (1, "rad")), ((1, "m/s"), (1, "rad/s"))),
    "universal": (((2, "rad"),), ((2, "rad/s"),)),
    "spherical": (((4, ""),), ((3, "rad/s"),)),
    "planar": (((2, "m"), (1, "rad")), ((2, "m/s"), (1, "rad/s"))),
    "free": (((3, "m"), (4, "")), ((3, "m/s"), (3, "rad/s"))),
    "fixed": ((), ()),
}
QUATERNION_STATE = (
    "q: Euler parameters (p0, p1, p2, p3), scalar first, of the child frame in the parent "
    "frame (a free joint: after the position (x, y, z) of the child's origin in the parent "
    "frame); v: angular velocity (wx, wy, wz) of the child in the child frame (a free joint: "
    "after the velocity (vx, vy, vz) of its origin in the parent frame)"
)
"""How ``describe`` reads the state of spherical and free joints (workbench.mechanics.joints)."""


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


def joint_state(joint_type: str, value: Any, velocities: bool) -> str:
    """A joint's initial coordinates (or velocities) with their units (:data:`STATE_UNITS`):
    ``0.5 rad``, ``(0.5, 0, 0.1) m, (1, 0, 0, 0)``; without units if the sizes differ."""
    array = np.atleast_1d(np.asarray(value, dtype=float)) + 0.0  # + 0.0: -0 reads 0
    groups = STATE_UNITS.get(joint_type, ((), ()))[velocities]
    if sum(count for count, _ in groups) != array.size:
        groups = ((array.size, ""),)
    parts, start = [], 0
    for count, unit in groups:
        numbers = ", ".join(number(x) for x in array[start : start + count])
        start += count
        parts.append((numbers if count == 1 else f"({numbers})") + (f" {unit}" if unit else ""))
    return ", ".join(parts)


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
        rows.append((joint.name, "driven (rheonomic)", _drive_law(joint)))
    return rows


def _drive_law(joint: Joint) -> str:
    """The prescribed motion as the model computes it, ``q(t) = 5*t rad, q'(t) = 5 rad/s``
    (the drive's functions on a symbol t), else the function's name."""
    (coordinates, velocities) = STATE_UNITS.get(joint.type, ((), ()))
    unit = f" {coordinates[0][1]}" if len(coordinates) == 1 else ""
    rate_unit = f" {velocities[0][1]}" if len(velocities) == 1 else ""
    position = _law(joint.drive.position, [])
    if position is None:
        return _function_name(joint.drive.position)
    velocity = _law(joint.drive.velocity, []) if joint.drive.velocity is not None else None
    text = f"q(t) = {position}{unit}"
    return text + (f", q'(t) = {velocity}{rate_unit}" if velocity is not None else "")


LAW_LENGTH = 200
"""The longest law ``describe`` prints as a formula (longer ones: the function's name)."""


def _law(function: Callable[..., Any], vectors: list[tuple[str, int]]) -> str | None:
    """``function`` of a symbol t and of the named vectors (name, size), as text: the law
    the formalisms integrate, ``5*t``. None when it does not take CasADi symbols or reads
    longer than :data:`LAW_LENGTH`, with shared subexpressions or a NaN."""
    symbols = [ca.SX.sym("t"), *(ca.SX.sym(name, size) for name, size in vectors)]
    try:
        value = function(*symbols)
        text = str(ca.SX(ca.vertcat(*value) if isinstance(value, list | tuple) else value))
    except Exception:  # noqa: BLE001 - a user function that takes no symbols: its name instead
        return None
    while text.startswith("(") and text.endswith(")") and _closes_at_end(text):
        text = text[1:-1]
    shared = "@" in text  # CasADi's shared subexpressions (@1=10, ...) read as code
    # nan: a function that turned the symbol into a number (np.interp does) never read it
    unread = re.search(r"\b(nan|inf)\b", text) is not None
    return text if len(text) <= LAW_LENGTH and not shared and not unread else None


def _closes_at_end(text: str) -> bool:
    """True if the opening bracket of ``text`` closes at its last character."""
    depth = 0
    for i, char in enumerate(text):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if depth == 0:
            return i == len(text) - 1
    return False


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
        joint_type = model.joints[element.joint].type if element.joint in model.joints else ""
        coordinates, velocities = STATE_UNITS.get(joint_type, ((), ()))
        nq, nv = sum(n for n, _ in coordinates), sum(n for n, _ in velocities)
        law = _law(element.function, [("q", nq), ("v", nv)]) if nv else None
        unit = {"revolute": " N m", "prismatic": " N"}.get(joint_type, "")
        text = f"Q(t, q, v) = {law}{unit}" if law else _function_name(element.function)
        return [(name, f"joint force on {element.joint}", text)]
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
