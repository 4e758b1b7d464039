"""Comparing poses: the angle between orientations, the pose error, a model's length scale.

A pose is a position (3,) and a unit quaternion scalar-first (4,): (..., 7). The pose
error at one time is the largest over bodies of ``|dr| + L |dtheta|`` (m), with ``dr`` the
error of the body frame's origin, ``dtheta`` the angle of the relative rotation and ``L``
the model's length scale: the largest distance of any body frame origin from the inertial
origin over the reference, of any centre of mass or joint frame from its body frame
origin, and at least ``MIN_LENGTH_SCALE``. Metrics, stored references and the conformance
suite all measure with these, so an error means the same thing everywhere.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

MIN_LENGTH_SCALE = 1e-3  # m


def rotation_angle(quat_a: np.ndarray, quat_b: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation between unit quaternions (..., 4) scalar-first, in [0, pi].

    2 atan2(|vector part|, |scalar part|) of the relative quaternion conj(a) b: accurate
    for small angles too (arccos of the dot product loses half the digits).
    """
    w_a, v_a = quat_a[..., :1], quat_a[..., 1:]
    w_b, v_b = quat_b[..., :1], quat_b[..., 1:]
    scalar = np.sum(quat_a * quat_b, axis=-1)
    vector = w_a * v_b - w_b * v_a - np.cross(v_a, v_b)
    return 2.0 * np.arctan2(np.linalg.norm(vector, axis=-1), np.abs(scalar))


def pose_error(poses: np.ndarray, reference: np.ndarray, length: float) -> np.ndarray:
    """Per output time, max over bodies of |dr| + L |dtheta| (m). Shapes (n, n_bodies, 7).

    A reference orientation given as NaN (not known analytically, e.g. the rolling ball's)
    counts the position error alone.
    """
    position_error = np.linalg.norm(poses[..., :3] - reference[..., :3], axis=-1)
    angle_error = rotation_angle(poses[..., 3:], reference[..., 3:])
    known = np.all(np.isfinite(reference[..., 3:]), axis=-1)
    angle_error = np.where(known, angle_error, 0.0)
    return np.max(position_error + length * angle_error, axis=-1)


def length_scale(model: Any, reference: np.ndarray | None) -> float:
    """The model's length scale L (m), see the module docstring;
    ``model`` needs only ``bodies`` and ``joints``."""
    lengths = [MIN_LENGTH_SCALE]
    if reference is not None and reference.size:
        # positions left unknown (NaN) in a reference drop out, not the whole reference
        distances = np.linalg.norm(reference[..., :3], axis=-1)
        if np.isfinite(distances).any():
            lengths.append(float(np.nanmax(distances)))
    for body in getattr(model, "bodies", {}).values():
        lengths.append(float(np.linalg.norm(body.com)))
    for joint in getattr(model, "joints", {}).values():
        lengths.append(float(np.linalg.norm(joint.parent_frame.position)))
        lengths.append(float(np.linalg.norm(joint.child_frame.position)))
    return max(x for x in lengths if math.isfinite(x))
