"""Model validation: every inconsistency becomes a :class:`ModelError` naming the fix.

:func:`validate_model` is what :meth:`workbench.model.Model.validate` calls. It checks, in
this order, so the first message is the most local one:

1. the model: kind, gravity;
2. every body: mass, centre of mass, inertia tensor (symmetric positive definite,
   triangle inequality of the principal moments), visual shapes;
3. every joint: type (and its fit to a planar model), parent and child names, frames
   (finite, orthonormal rotations, planar frames in the x-y plane), axes, drive (as many
   values as the joint has coordinates and velocities, its velocity and acceleration the
   exact time derivatives of its position and velocity);
4. every force element, nonholonomic constraint and contact: names they refer to, finite
   parameters, signs of stiffness, damping and radii, restitution in [0, 1], force
   functions that are not nan on CasADi symbols where they are finite on numbers;
5. the topology: every body is the child of exactly one tree joint and reaches the
   ground through tree joints;
6. point masses whose joint would let them spin with no rotational inertia.

Numbers are compared with a small relative tolerance (``TOLERANCE``).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from workbench.errors import ModelError
from workbench.model.elements import (
    GROUND,
    JOINT_DIMENSIONS,
    JOINT_TYPES,
    PLANAR_JOINT_TYPES,
    AppliedForce,
    Body,
    Frame,
    Joint,
    JointForce,
    JointFriction,
    JointSpringDamper,
    KnifeEdge,
    PlaneContact,
    RollingDisk,
    RollingSphere,
    SphereContact,
    SpringDamper,
    real_array,
)

if TYPE_CHECKING:  # validation judges a Model; it does not need the class to run
    from workbench.model.model import Model

TOLERANCE = 1e-9
"""Relative tolerance of symmetry, orthonormality, planarity and the triangle inequality."""

AXIS_JOINT_TYPES: tuple[str, ...] = ("revolute", "prismatic", "cylindrical", "universal")
"""Joint types whose motion is defined by ``axis`` (and ``axis2`` for universal)."""

JOINT_SPRING_TYPES: tuple[str, ...] = (
    "revolute",
    "prismatic",
    "cylindrical",
    "universal",
    "planar",
    "spherical",
    "free",
)
"""Joint types a JointSpringDamper may act on (spherical and free: rest is a pose)."""

SPINNING_POINT_MASS_TYPES: tuple[str, ...] = ("spherical", "universal", "cylindrical", "free")
"""Joint types that rotate a spatial point mass about an axis through it."""

SHAPE_SIZES: dict[str, int] = {"box": 3, "cylinder": 2, "sphere": 1, "capsule": 2, "mesh": 3}


def validate_model(model: Model) -> None:
    """Raise :class:`ModelError` on the first inconsistency of ``model``; return None if sound."""
    _check_model(model)
    for body in model.bodies.values():
        _check_body(model, body)
    for joint in model.joints.values():
        _check_joint(model, joint)
    for element in model.forces:
        _check_force(model, element)
    for constraint in model.nonholonomic:
        _check_nonholonomic(model, constraint)
    for contact in model.contacts:
        _check_contact(model, contact)
    for friction in model.joint_frictions:
        _check_joint_friction(model, friction)
    _check_tree(model)
    _check_point_mass_joints(model)


# ---- helpers --------------------------------------------------------------------------


def _where(model: Model, what: str) -> str:
    return f"model {model.name!r}, {what}"


def _finite_vector(model: Model, what: str, name: str, value: Any, size: int = 3) -> np.ndarray:
    """``value`` as a float array of ``size`` finite entries, else ModelError."""
    array = real_array(value, _where(model, what), name).reshape(-1)
    if array.shape != (size,):
        raise ModelError(
            f"{_where(model, what)}: {name} must have {size} components, not {array.size}"
        )
    if not np.all(np.isfinite(array)):
        raise ModelError(
            f"{_where(model, what)}: {name} = {array.tolist()} contains NaN or inf; "
            "give finite numbers"
        )
    return array


def _finite_scalar(model: Model, what: str, name: str, value: Any) -> float:
    number = float(real_array(value, _where(model, what), name, ()))
    if not np.isfinite(number):
        raise ModelError(f"{_where(model, what)}: {name} = {number} is not finite; give a number")
    return number


def _known_body(model: Model, what: str, role: str, name: Any, allow_ground: bool) -> None:
    if name == GROUND:
        if not allow_ground:
            raise ModelError(f"{_where(model, what)}: {role} cannot be {GROUND!r}; name a body")
        return
    if name not in model.bodies:
        known = ", ".join(repr(b) for b in model.bodies) or "none"
        ground = f"{GROUND!r} or " if allow_ground else ""
        raise ModelError(
            f"{_where(model, what)}: {role} {name!r} is not a body of the model; "
            f"use {ground}one of the bodies ({known})"
        )


# ---- model and bodies ---------------------------------------------------------------


def _check_model(model: Model) -> None:
    if model.kind not in ("planar", "spatial"):
        raise ModelError(
            f"model {model.name!r}: kind {model.kind!r} is unknown; use 'planar' or 'spatial'"
        )
    gravity = _finite_vector(model, "gravity", "gravity", model.gravity)
    if model.kind == "planar" and abs(gravity[2]) > TOLERANCE * max(1.0, np.linalg.norm(gravity)):
        raise ModelError(
            f"{_where(model, 'gravity')}: a planar model's gravity must lie in the x-y plane "
            f"(got z = {gravity[2]}); set its z component to 0"
        )
    if not model.bodies:
        raise ModelError(f"model {model.name!r} has no bodies; add one with add_body")


def _check_body(model: Model, body: Body) -> None:
    what = f"body {body.name!r}"
    mass = _finite_scalar(model, what, "mass", body.mass)
    if mass < 0 or (mass == 0 and not body.point_mass):  # a massless point: see below
        raise ModelError(
            f"{_where(model, what)}: mass must be > 0 kg (got {mass}); give a positive mass"
        )
    com = _finite_vector(model, what, "com (centre of mass)", body.com)
    if model.kind == "planar" and abs(com[2]) > TOLERANCE * max(1.0, np.linalg.norm(com)):
        raise ModelError(
            f"{_where(model, what)}: in a planar model the centre of mass must lie in the "
            f"x-y plane of the body frame (got z = {com[2]}); set its z component to 0"
        )
    if not body.point_mass:
        _check_inertia(model, what, body.inertia)
    for shape in body.shapes:
        _check_shape(model, what, shape)


def _check_inertia(model: Model, what: str, inertia: Any) -> None:
    matrix = real_array(inertia, _where(model, what), "inertia")
    if matrix.shape != (3, 3) or np.all(np.isnan(matrix)):
        hint = (
            " (a scalar inertia is only accepted in planar models)"
            if model.kind == "spatial"
            else ""
        )
        raise ModelError(
            f"{_where(model, what)}: the inertia is missing or malformed{hint}; give a 3x3 "
            "inertia tensor (kg m^2, about the centre of mass in the body frame), three "
            "principal moments, or use add_point_mass for a point mass"
        )
    if not np.all(np.isfinite(matrix)):
        raise ModelError(
            f"{_where(model, what)}: the inertia tensor contains NaN or inf; give a 3x3 "
            "inertia tensor of finite numbers"
        )
    scale = float(np.max(np.abs(matrix)))
    if scale == 0.0:
        raise ModelError(
            f"{_where(model, what)}: the inertia tensor is zero; give a rigid body a 3x3 "
            "inertia tensor, or use add_point_mass for a point mass"
        )
    if np.max(np.abs(matrix - matrix.T)) > TOLERANCE * scale:
        raise ModelError(
            f"{_where(model, what)}: the inertia tensor is not symmetric; give a symmetric "
            "3x3 tensor (I[i, j] == I[j, i])"
        )
    moments = np.sort(np.linalg.eigvalsh(0.5 * (matrix + matrix.T)))
    if moments[0] <= TOLERANCE * scale:
        raise ModelError(
            f"{_where(model, what)}: the inertia tensor is not positive definite (principal "
            f"moments {moments.tolist()}); every principal moment must be > 0"
        )
    if moments[0] + moments[1] < moments[2] * (1.0 - TOLERANCE):
        raise ModelError(
            f"{_where(model, what)}: the principal moments {moments.tolist()} violate the "
            "triangle inequality (each must be <= the sum of the other two, e.g. "
            "Ixx + Iyy >= Izz); no physical body has this inertia, correct the tensor"
        )


def _check_shape(model: Model, what: str, shape: Any) -> None:
    kind = getattr(shape, "kind", None)
    if kind not in SHAPE_SIZES:
        raise ModelError(
            f"{_where(model, what)}: shape kind {kind!r} is unknown; use one of "
            f"{', '.join(SHAPE_SIZES)}"
        )
    size = _finite_vector(model, what, f"{kind} shape size", shape.size, SHAPE_SIZES[kind])
    if kind == "mesh":  # a scale: negative mirrors the mesh, zero flattens it
        if np.any(size == 0) or not getattr(shape, "path", ""):
            raise ModelError(
                f"{_where(model, what)}: a mesh shape needs a file path and a non-zero scale "
                f"(got path {getattr(shape, 'path', '')!r}, scale {size.tolist()})"
            )
    elif np.any(size <= 0):
        raise ModelError(
            f"{_where(model, what)}: {kind} shape size {size.tolist()} must be > 0 (m)"
        )
    _check_frame(model, what, f"{kind} shape frame", shape.frame, planar=False)


# ---- joints -------------------------------------------------------------------------


def _check_frame(model: Model, what: str, name: str, frame: Frame, planar: bool) -> None:
    position = _finite_vector(model, what, f"{name} position", frame.position)
    rotation = real_array(frame.rotation, _where(model, what), f"{name} rotation")
    if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
        raise ModelError(
            f"{_where(model, what)}: {name} rotation must be a 3x3 matrix of finite numbers"
        )
    if (
        np.max(np.abs(rotation.T @ rotation - np.eye(3))) > 1e3 * TOLERANCE
        or np.linalg.det(rotation) < 0
    ):
        raise ModelError(
            f"{_where(model, what)}: {name} rotation is not a rotation matrix (it must be "
            "orthonormal with determinant +1); build it with "
            "workbench.numerics.rotations.axis_angle_to_matrix"
        )
    if planar:
        if abs(position[2]) > TOLERANCE * max(1.0, np.linalg.norm(position)):
            raise ModelError(
                f"{_where(model, what)}: in a planar model {name} must have zero z offset "
                f"(got z = {position[2]}); set it to 0"
            )
        if (
            np.max(np.abs(rotation[2, :] - [0, 0, 1])) > 1e3 * TOLERANCE
            or np.max(np.abs(rotation[:, 2] - [0, 0, 1])) > 1e3 * TOLERANCE
        ):
            raise ModelError(
                f"{_where(model, what)}: in a planar model {name} may rotate only about z; "
                "use axis_angle_to_matrix((0, 0, 1), angle)"
            )


def _check_joint(model: Model, joint: Joint) -> None:
    what = f"joint {joint.name!r}"
    if joint.type not in JOINT_TYPES:
        raise ModelError(
            f"{_where(model, what)}: unknown joint type {joint.type!r}; valid types are "
            f"{', '.join(JOINT_TYPES)}"
        )
    planar = model.kind == "planar"
    if planar and joint.type not in PLANAR_JOINT_TYPES:
        raise ModelError(
            f"{_where(model, what)}: a {joint.type} joint does not fit a planar model; planar "
            f"models allow {', '.join(PLANAR_JOINT_TYPES)} joints (or make the model spatial)"
        )
    if joint.parent == joint.child:
        raise ModelError(
            f"{_where(model, what)}: parent and child are both {joint.parent!r}; a joint "
            "connects two different bodies"
        )
    _known_body(model, what, "parent", joint.parent, allow_ground=True)
    # a loop-closing joint may close on the ground; a tree joint's child is always a body
    _known_body(model, what, "child", joint.child, allow_ground=joint.cut)
    _check_frame(model, what, "parent_frame", joint.parent_frame, planar)
    _check_frame(model, what, "child_frame", joint.child_frame, planar)

    if joint.type in AXIS_JOINT_TYPES:
        axis = _check_axis(model, what, "axis", joint.axis)
        if joint.type == "universal":
            axis2 = _check_axis(model, what, "axis2", joint.axis2)
            if np.linalg.norm(np.cross(axis, axis2)) <= 1e-6:
                raise ModelError(
                    f"{_where(model, what)}: a universal joint's axis and axis2 are parallel; "
                    "give two perpendicular axes"
                )
        if planar and joint.type == "revolute" and np.linalg.norm(axis[:2]) > 1e-6:
            raise ModelError(
                f"{_where(model, what)}: in a planar model a revolute axis must be along +z "
                f"or -z (got {axis.tolist()}); use axis=(0, 0, 1)"
            )
        if planar and joint.type == "prismatic" and abs(axis[2]) > 1e-6:
            raise ModelError(
                f"{_where(model, what)}: in a planar model a prismatic axis must lie in the "
                f"x-y plane (got {axis.tolist()}); set its z component to 0"
            )
    _check_drive(model, what, joint)


def _check_axis(model: Model, what: str, name: str, value: Any) -> np.ndarray:
    axis = _finite_vector(model, what, name, value)
    norm = float(np.linalg.norm(axis))
    if norm <= 1e-12:
        raise ModelError(
            f"{_where(model, what)}: {name} has zero length; give a nonzero direction "
            "(e.g. (0, 0, 1))"
        )
    return axis / norm


def _check_drive(model: Model, what: str, joint: Joint) -> None:
    drive = joint.drive
    if drive is None:
        return
    if joint.type == "fixed":
        raise ModelError(
            f"{_where(model, what)}: a fixed joint has no coordinates to drive; remove the drive"
        )
    missing = [
        name
        for name in ("position", "velocity", "acceleration")
        if not callable(getattr(drive, name))
    ]
    if missing:
        raise ModelError(
            f"{_where(model, what)}: the drive lacks its {' and '.join(missing)} function"
            f"{'s' if len(missing) > 1 else ''}; give position, velocity and acceleration "
            "as functions of t (the exact first and second time derivatives)"
        )
    nq, nv = JOINT_DIMENSIONS[joint.type]
    sizes = {"position": (nq, "coordinates"), "velocity": (nv, "velocities"),
             "acceleration": (nv, "velocities")}
    for name, (size, counted) in sizes.items():
        try:
            value = np.asarray(getattr(drive, name)(0.0), dtype=float)
        except Exception as error:  # noqa: BLE001 - any failure of user code is reported
            raise ModelError(
                f"{_where(model, what)}: the drive's {name} function fails at t = 0 "
                f"({type(error).__name__}: {error}); it must accept a float or CasADi symbol"
            ) from None
        if not np.all(np.isfinite(value)):
            raise ModelError(
                f"{_where(model, what)}: the drive's {name} at t = 0 is {value.tolist()}, "
                "not finite; fix the function"
            )
        if value.size != size:
            raise ModelError(
                f"{_where(model, what)}: the drive's {name} gives {value.size} value(s), but "
                f"a {joint.type} joint has {size} {counted}; return {size} value(s)"
            )
    _check_drive_derivatives(model, what, drive, joint.type)


DRIVE_CHECK_TIMES: tuple[float, ...] = (0.0, 0.3183, 0.7071, 1.4142)
"""Times (s) at which a drive's velocity and acceleration are compared with the exact
derivatives of its position and velocity: t = 0 and three that are not round, so a
piecewise drive's switching time is rarely hit."""

DRIVE_DERIVATIVE_TOLERANCE = 1e-6
"""Relative difference allowed between a drive's given and exact derivatives."""


ROTATION_DRIVES: dict[str, slice] = {"spherical": slice(0, 4), "free": slice(3, 7)}
"""Where the Euler parameters are in the coordinates of a joint type that has them."""


def _check_drive_derivatives(model: Model, what: str, drive: Any, joint_type: str) -> None:
    """The drive's velocity is the rate of its position (d(position)/dt where q' = v; for
    Euler parameters p the angular velocity of C in C, 2 G(p) p') and its acceleration
    d(velocity)/dt, by CasADi's exact derivatives; Euler parameters are of unit norm. An
    inconsistent drive gives every formalism incoherent physics that no run would
    notice."""
    from workbench.numerics.rotations import quaternion_angular_velocity

    t = ca.SX.sym("t")
    try:
        q, v, a = (_symbolic_column(f(t)) for f in (drive.position, drive.velocity,
                                                    drive.acceleration))
    except Exception as error:  # noqa: BLE001 - any failure of user code is reported
        raise ModelError(
            f"{_where(model, what)}: the drive's functions fail on a CasADi symbol t "
            f"({type(error).__name__}: {error}); write them with casadi functions "
            "(casadi.sin ...), which accept floats and symbols alike"
        ) from None
    functions = {"position": q, "velocity": v, "acceleration": a}
    for name, expression in functions.items():
        on_symbol = ca.Function("drive_" + name, [t], [expression])
        at_zero = np.asarray(on_symbol(0.0), dtype=float).reshape(-1)
        if not np.all(np.isfinite(at_zero)):  # finite on the float 0.0 (checked before)
            raise ModelError(
                f"{_where(model, what)}: the drive's {name} gives {at_zero.tolist()} at t = 0 "
                "when t is a CasADi symbol (the math module turns a symbol into nan); write "
                "it with casadi functions (casadi.sin ...), which accept floats and symbols"
            )
    rate = ca.jacobian(q, t)
    euler = ROTATION_DRIVES.get(joint_type)
    if euler is not None:  # the angular velocity the parameters' rate gives, the norm
        omega = quaternion_angular_velocity(q[euler], rate[euler])
        rate = ca.vertcat(rate[: euler.start], omega)
        _check_unit_parameters(model, what, ca.Function("drive_euler", [t], [q[euler]]))
    pairs = {
        ("velocity", "position"): (rate, v),
        ("acceleration", "velocity"): (ca.jacobian(v, t), a),
    }
    for (name, of), (exact, given) in pairs.items():
        difference = ca.Function("drive_derivative", [t], [exact, given])
        for time in DRIVE_CHECK_TIMES:
            derivative, value = (np.asarray(x, dtype=float).reshape(-1)
                                 for x in difference(time))
            if not (np.all(np.isfinite(derivative)) and np.all(np.isfinite(value))):
                continue  # a singular instant (sqrt(t) at 0): nothing to compare
            scale = 1.0 + max(np.abs(derivative).max(initial=0), np.abs(value).max(initial=0))
            if np.abs(derivative - value).max(initial=0) > DRIVE_DERIVATIVE_TOLERANCE * scale:
                raise ModelError(
                    f"{_where(model, what)}: the drive's {name} is not the time derivative "
                    f"of its {of}: at t = {time:g} s, d({of})/dt = "
                    f"{np.round(derivative, 6).tolist()} but {name} = "
                    f"{np.round(value, 6).tolist()}; give the exact derivative"
                )


def _check_unit_parameters(model: Model, what: str, euler: ca.Function) -> None:
    """A drive's Euler parameters are of unit norm at :data:`DRIVE_CHECK_TIMES`: the
    formalisms take them as a rotation, and one of norm 2 gave orthonormal rotations with
    a velocity check that holds for it (the rate's part along p does not count)."""
    for time in DRIVE_CHECK_TIMES:
        parameters = np.asarray(euler(time), dtype=float).reshape(-1)
        norm = float(np.linalg.norm(parameters))
        if np.isfinite(norm) and abs(norm - 1.0) > TOLERANCE:
            raise ModelError(
                f"{_where(model, what)}: the drive's Euler parameters at t = {time:g} s are "
                f"{np.round(parameters, 6).tolist()}, of norm {norm:.6g}; give a unit "
                "quaternion (scalar first) at every t"
            )


def _symbolic_column(value: Any) -> ca.SX:
    """A drive function's value on a symbol t as an SX column (floats become constants)."""
    if isinstance(value, ca.SX | ca.DM):
        return ca.vec(ca.SX(value))
    if isinstance(value, list | tuple):
        return ca.vertcat(*[ca.SX(item) for item in value])
    return ca.vec(ca.SX(np.asarray(value, dtype=float)))


# ---- force elements and nonholonomic constraints -------------------------------------


def _check_nonnegative(model: Model, what: str, name: str, value: Any) -> float:
    number = _finite_scalar(model, what, name, value)
    if number < 0:
        raise ModelError(
            f"{_where(model, what)}: {name} must be >= 0 (got {number}); a negative "
            f"{name} adds energy, give a value >= 0"
        )
    return number


def _check_force(model: Model, element: Any) -> None:
    what = f"force {getattr(element, 'name', element)!r}"
    if isinstance(element, SpringDamper):
        _known_body(model, what, "body1", element.body1, allow_ground=True)
        _known_body(model, what, "body2", element.body2, allow_ground=True)
        if element.body1 == element.body2:
            raise ModelError(
                f"{_where(model, what)}: body1 and body2 are both {element.body1!r}; a "
                "spring-damper connects two different bodies"
            )
        _finite_vector(model, what, "point1", element.point1)
        _finite_vector(model, what, "point2", element.point2)
        _check_nonnegative(model, what, "stiffness", element.stiffness)
        _check_nonnegative(model, what, "damping", element.damping)
        _check_nonnegative(model, what, "rest_length", element.rest_length)
    elif isinstance(element, JointSpringDamper):
        joint = _known_joint(model, what, element.joint)
        if joint.type not in JOINT_SPRING_TYPES:
            raise ModelError(
                f"{_where(model, what)}: a joint spring-damper cannot act on the {joint.type} "
                f"joint {joint.name!r}; use it on {', '.join(JOINT_SPRING_TYPES)} joints"
            )
        _check_nonnegative(model, what, "stiffness", element.stiffness)
        _check_nonnegative(model, what, "damping", element.damping)
        rest = np.atleast_1d(real_array(element.rest, _where(model, what), "rest"))
        if not np.all(np.isfinite(rest)):
            raise ModelError(f"{_where(model, what)}: rest = {rest.tolist()} is not finite")
        if joint.type in ("spherical", "free"):
            size = 4 if joint.type == "spherical" else 7
            if rest.size != size or abs(np.linalg.norm(rest[-4:]) - 1.0) > 1e-6:
                raise ModelError(
                    f"{_where(model, what)}: rest = {rest.tolist()}; on the {joint.type} joint "
                    f"{joint.name!r} give the rest pose as its {size} coordinates (a unit "
                    "quaternion, scalar first" + (", after the position)" if size == 7 else ")")
                )
    elif isinstance(element, JointForce):
        joint = _known_joint(model, what, element.joint)
        _check_callable(model, what, element.function)
        nq, nv = JOINT_DIMENSIONS[joint.type]
        q = np.zeros(nq)  # the neutral coordinates: a unit quaternion where there is one
        if joint.type in ("spherical", "free"):
            q[nq - 4] = 1.0
        _check_symbolic(model, what, element.function, [0.0, q, np.zeros(nv)])
    elif isinstance(element, AppliedForce):
        _known_body(model, what, "body", element.body, allow_ground=False)
        _finite_vector(model, what, "point", element.point)
        _check_callable(model, what, element.function)
        _check_symbolic(model, what, element.function,
                        [0.0, np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3)])
    else:
        raise ModelError(
            f"{_where(model, what)}: {type(element).__name__} is not a force element; use "
            "SpringDamper, JointSpringDamper, JointForce or AppliedForce"
        )


def _known_joint(model: Model, what: str, name: Any) -> Joint:
    if name not in model.joints:
        known = ", ".join(repr(j) for j in model.joints) or "none"
        raise ModelError(
            f"{_where(model, what)}: joint {name!r} is not a joint of the model; use one of {known}"
        )
    return model.joints[name]


def _check_callable(model: Model, what: str, function: Any) -> None:
    if not callable(function):
        raise ModelError(f"{_where(model, what)}: function must be callable, not {function!r}")


def _check_symbolic(model: Model, what: str, function: Any, values: list[Any]) -> None:
    """A force function is evaluated on CasADi symbols: one that is nan there but finite on
    the same numbers (written with the math module, which turns a symbol into nan without a
    word) is refused. Failures of the function itself are left to the build, which names
    them; ``values``: a state to compare at (t, then the arguments' numbers)."""
    symbols = [ca.SX.sym(f"x{k}", *np.shape(v)) if np.ndim(v) else ca.SX.sym(f"x{k}")
               for k, v in enumerate(values)]
    try:
        on_symbols = _flattened(function(*symbols))
        on_numbers = np.concatenate([np.asarray(x, dtype=float).reshape(-1)
                                     for x in _as_parts(function(*values))])
    except Exception:  # noqa: BLE001 - the build reports the function's own failure
        return
    evaluate = ca.Function("force_on_symbols", symbols, [on_symbols])
    at_values = np.asarray(evaluate(*values), dtype=float).reshape(-1)
    if np.all(np.isfinite(on_numbers)) and not np.all(np.isfinite(at_values)):
        raise ModelError(
            f"{_where(model, what)}: the function gives {at_values.tolist()} when its arguments "
            f"are CasADi symbols but {on_numbers.tolist()} on the same numbers (the math "
            "module turns a symbol into nan); write it with casadi functions (casadi.sin ...)"
        )


def _as_parts(value: Any) -> list[Any]:
    """A force function's value as a list of its parts ((force, torque) or one vector)."""
    return list(value) if isinstance(value, tuple) else [value]


def _flattened(value: Any) -> ca.SX:
    """A force function's value on symbols as one SX column."""
    parts = [_symbolic_column(list(p) if isinstance(p, np.ndarray) and p.dtype == object else p)
             for p in _as_parts(value)]
    return ca.vertcat(*parts)


def _check_nonholonomic(model: Model, constraint: Any) -> None:
    what = f"constraint {getattr(constraint, 'name', constraint)!r}"
    if not isinstance(constraint, RollingSphere | RollingDisk | KnifeEdge):
        raise ModelError(
            f"{_where(model, what)}: {type(constraint).__name__} is not a nonholonomic "
            "constraint; use RollingSphere, RollingDisk or KnifeEdge"
        )
    _known_body(model, what, "body", constraint.body, allow_ground=False)
    planar = model.kind == "planar"
    if isinstance(constraint, RollingSphere | RollingDisk):
        radius = _finite_scalar(model, what, "radius", constraint.radius)
        if radius <= 0:
            raise ModelError(
                f"{_where(model, what)}: radius must be > 0 m (got {radius}); give a "
                "positive radius"
            )
        _finite_vector(model, what, "center", constraint.center)
    if isinstance(constraint, RollingSphere):
        _finite_scalar(model, what, "plane_rate", constraint.plane_rate)
        if planar:
            raise ModelError(
                f"{_where(model, what)}: a rolling sphere needs a spatial model; in a planar "
                "model use RollingDisk"
            )
    elif isinstance(constraint, RollingDisk):
        axis = _check_axis(model, what, "axis", constraint.axis)
        if planar and np.linalg.norm(axis[:2]) > 1e-6:
            raise ModelError(
                f"{_where(model, what)}: in a planar model a rolling disk's axis must be "
                f"along z (got {axis.tolist()}); use axis=(0, 0, 1)"
            )
    else:
        _finite_vector(model, what, "point", constraint.point)
        direction = _check_axis(model, what, "direction", constraint.direction)
        if planar and abs(direction[2]) > 1e-6:
            raise ModelError(
                f"{_where(model, what)}: in a planar model a knife edge's direction must lie "
                f"in the x-y plane (got {direction.tolist()}); set its z component to 0"
            )


def _check_contact(model: Model, contact: Any) -> None:
    """A PlaneContact: a known body, finite geometry, a unit-able normal (in the x-y plane
    of a planar model), radius >= 0, restitution in [0, 1], friction >= 0."""
    what = f"contact {getattr(contact, 'name', contact)!r}"
    if isinstance(contact, SphereContact):
        _check_sphere_contact(model, what, contact)
        return
    if not isinstance(contact, PlaneContact):
        raise ModelError(
            f"{_where(model, what)}: {type(contact).__name__} is not a contact; use "
            "PlaneContact or SphereContact"
        )
    _known_body(model, what, "body", contact.body, allow_ground=False)
    _finite_vector(model, what, "point", contact.point)
    _finite_vector(model, what, "plane_point", contact.plane_point)
    normal = _check_axis(model, what, "plane_normal", contact.plane_normal)
    if model.kind == "planar" and abs(normal[2]) > 1e-6:
        raise ModelError(
            f"{_where(model, what)}: in a planar model the plane's normal must lie in the x-y "
            f"plane (got {normal.tolist()}); set its z component to 0"
        )
    _check_nonnegative(model, what, "radius", contact.radius)
    _check_contact_law(model, what, contact)


def _check_sphere_contact(model: Model, what: str, contact: SphereContact) -> None:
    """A SphereContact: two different known bodies (B may be the ground), finite centres,
    radii > 0, restitution in [0, 1], friction >= 0."""
    _known_body(model, what, "body_a", contact.body_a, allow_ground=False)
    _known_body(model, what, "body_b", contact.body_b, allow_ground=True)
    if contact.body_a == contact.body_b:
        raise ModelError(
            f"{_where(model, what)}: body_a and body_b are both {contact.body_a!r}; a sphere "
            "contact is between two different bodies (a body against a plane: add_contact)"
        )
    for side in ("a", "b"):
        _finite_vector(model, what, f"centre_{side}", getattr(contact, f"centre_{side}"))
        radius = _finite_scalar(model, what, f"radius_{side}", getattr(contact, f"radius_{side}"))
        if not radius > 0:
            raise ModelError(
                f"{_where(model, what)}: radius_{side} must be > 0 m (got {radius}); a sphere "
                "contact needs two spheres"
            )
    if model.kind == "planar" and abs(contact.centre_a[2] - contact.centre_b[2]) > 1e-12:
        raise ModelError(
            f"{_where(model, what)}: in a planar model both centres need the same z (got "
            f"{contact.centre_a[2]} and {contact.centre_b[2]}); the normal must lie in x-y"
        )
    _check_contact_law(model, what, contact)


def _check_contact_law(model: Model, what: str, contact: Any) -> None:
    """Friction >= 0 and restitution in [0, 1] of any contact."""
    _check_nonnegative(model, what, "friction", contact.friction)
    restitution = _finite_scalar(model, what, "restitution", contact.restitution)
    if not 0.0 <= restitution <= 1.0:
        raise ModelError(
            f"{_where(model, what)}: restitution must be in [0, 1] (got {restitution}); "
            "0 is a plastic impact, 1 an elastic one"
        )


def _check_joint_friction(model: Model, friction: Any) -> None:
    """A JointFriction: a known revolute or prismatic joint, a finite bound >= 0."""
    what = f"joint friction {getattr(friction, 'name', friction)!r}"
    if not isinstance(friction, JointFriction):
        raise ModelError(
            f"{_where(model, what)}: {type(friction).__name__} is not a joint friction; "
            "use Model.add_joint_friction(joint, bound)"
        )
    joint = model.joints.get(friction.joint)
    if joint is None:
        raise ModelError(
            f"{_where(model, what)}: {friction.joint!r} is not a joint of the model "
            f"(joints: {', '.join(model.joints) or 'none'})"
        )
    if joint.type not in ("revolute", "prismatic"):
        raise ModelError(
            f"{_where(model, what)}: joint {joint.name!r} is {joint.type}; friction with a "
            "bound needs a one-coordinate joint (revolute or prismatic)"
        )
    _check_nonnegative(model, what, "bound", friction.bound)


# ---- topology ---------------------------------------------------------------------


def _check_tree(model: Model) -> None:
    """Every body is the child of exactly one tree joint and reaches the ground.

    O(n): each body's walk towards the ground stops at the first body already known to
    reach it, so every tree joint is followed once (a serial chain of 10,000 links is
    checked in milliseconds; walking every body to the ground was O(n^2), O(n^3) with the
    loop test on a list).
    """
    parent_joint: dict[str, Joint] = {}
    for joint in model.tree_joints:
        earlier = parent_joint.get(joint.child)
        if earlier is not None:
            raise ModelError(
                f"model {model.name!r}, body {joint.child!r}: it is the child of two tree "
                f"joints, {earlier.name!r} and {joint.name!r}; a body has one parent joint, "
                f"so mark one of them as loop-closing (cut=True)"
            )
        parent_joint[joint.child] = joint
    grounded: set[str] = {GROUND}
    for name in model.bodies:
        chain = [name]
        on_chain = {name}
        body = name
        while body not in grounded:
            joint = parent_joint.get(body)
            if joint is None:
                unattached = f" ({body!r} has no tree joint)" if body != name else ""
                raise ModelError(
                    f"model {model.name!r}, body {name!r}: it is not connected to "
                    f"{GROUND!r} through tree joints{unattached}; add a joint from "
                    f"{GROUND!r} or from a connected body (a free joint for a floating "
                    "body; cut joints do not count)"
                )
            body = joint.parent
            if body in on_chain:
                loop = " -> ".join(_quoted(chain + [body]))
                raise ModelError(
                    f"model {model.name!r}, body {name!r}: its tree joints form a closed "
                    f"loop ({loop}) that never reaches {GROUND!r}; mark one joint of the "
                    "loop as cut=True and attach the loop to the ground"
                )
            chain.append(body)
            on_chain.add(body)
        grounded.update(chain)


def _quoted(names: Iterable[str]) -> list[str]:
    return [repr(name) for name in names]


def _check_point_mass_joints(model: Model) -> None:
    """A point mass must not be free to spin about an axis through itself, and a massless
    one (a link between joints) must carry tree children.

    Only point masses without tree children are checked: a child attached at an offset
    may carry the rotation's inertia.
    """
    has_children = {joint.parent for joint in model.tree_joints}
    for joint in model.tree_joints:
        body = model.bodies[joint.child]
        if body.point_mass and body.mass == 0 and body.name not in has_children:
            raise ModelError(
                f"model {model.name!r}, body {body.name!r}: a massless body must carry other "
                f"bodies (a link between joints); at the end of a chain its {joint.type} "
                f"joint {joint.name!r} moves no mass; give it a mass"
            )
        if not body.point_mass or body.name in has_children or joint.drive is not None:
            continue
        spins = False
        if model.kind == "spatial" and joint.type in SPINNING_POINT_MASS_TYPES:
            spins = True
        elif model.kind == "planar" and joint.type == "planar":
            spins = True
        elif joint.type == "revolute":
            # the mass sits at its com (the body origin unless given), relative to frame C
            axis = joint.child_frame.rotation @ (joint.axis / np.linalg.norm(joint.axis))
            arm = np.asarray(body.com, float) - joint.child_frame.position
            offset = np.linalg.norm(np.cross(axis, arm))
            spins = offset <= 1e-9 * max(1.0, np.linalg.norm(arm))
        if spins:
            raise ModelError(
                f"model {model.name!r}, body {body.name!r}: the point mass would spin about "
                f"an axis through itself with no inertia (its {joint.type} joint "
                f"{joint.name!r}); give it rotational inertia with add_body or attach it "
                "with a revolute joint offset from the mass (child_frame away from the axis)"
            )
