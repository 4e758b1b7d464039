"""The same mechanism for the peers: a Pinocchio ``pin.Model`` and MuJoCo MJCF from ours.

Only trees of revolute joints (the scalable problems). Our joint sits at frame P on the
parent body, rotates about ``axis`` (P coordinates) and carries the child body whose
frame is C^-1 from the rotated joint frame: X_child = X_parent P R(axis, q) C^-1.

* Pinocchio: one joint frame per body, equal to our rotated P; its placement in the
  parent's joint frame is C_parent^-1 P, and the body (mass, centre of mass, inertia about
  it) is appended at C^-1. Axes along +x, +y, +z use the specialised RX, RY, RZ joints.
  Joints are added depth first: Pinocchio's CRBA assumes every subtree's velocities are
  contiguous (a breadth-first tree gives a wrong ``crba`` although ``aba`` is right).
* MuJoCo: nested bodies whose frames are ours; at q = 0 a child sits at P C^-1 in its
  parent and its hinge is at C's origin about R_C axis (child body coordinates).

Both map q and v by joint name (``*_order``: our index of each of their coordinates).
Gravity is the model's; MuJoCo's contacts and constraints are disabled.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import GROUND, Frame, Model


def _check(model: Model, kinematics: TreeKinematics) -> None:
    others = [j.name for j in kinematics.order if j.type != "revolute" or j.drive is not None]
    if others or model.cut_joints or model.nonholonomic:
        raise ValueError(
            f"model {model.name!r}: the peer models handle trees of free revolute joints only "
            f"(not {', '.join(others) or 'closed loops or nonholonomic constraints'})"
        )


def _transform(frame: Frame) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = frame.rotation, frame.position
    return matrix


def depth_first(kinematics: TreeKinematics) -> list[Any]:
    """The tree joints parents first, each subtree before the next sibling."""
    children: dict[str, list] = {}
    for joint in kinematics.order:
        children.setdefault(joint.parent, []).append(joint)
    ordered: list[Any] = []
    stack = list(reversed(children.get(GROUND, [])))
    while stack:
        joint = stack.pop()
        ordered.append(joint)
        stack.extend(reversed(children.get(joint.child, [])))
    return ordered


def pinocchio_model(model: Model) -> tuple[Any, np.ndarray]:
    """(pin.Model, order): order[i] is our velocity index of Pinocchio's v[i]."""
    kinematics = TreeKinematics(model.validate())
    _check(model, kinematics)
    import pinocchio as pin

    built = pin.Model()
    built.gravity = pin.Motion(np.asarray(model.gravity, dtype=float), np.zeros(3))
    ids = {GROUND: 0}
    body_in_joint = {GROUND: np.eye(4)}  # body frame in its joint frame: C^-1
    order = np.zeros(kinematics.nv, dtype=int)
    for joint in depth_first(kinematics):
        axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
        unit = {(1.0, 0.0, 0.0): "RX", (0.0, 1.0, 0.0): "RY", (0.0, 0.0, 1.0): "RZ"}
        kind = unit.get(tuple(axis))
        joint_model = getattr(pin, f"JointModel{kind}")() if kind else None
        if joint_model is None:
            joint_model = pin.JointModelRevoluteUnaligned(axis)
        placement = body_in_joint[joint.parent] @ _transform(joint.parent_frame)
        joint_id = built.addJoint(
            ids[joint.parent], joint_model, pin.SE3(placement[:3, :3], placement[:3, 3]), joint.name
        )
        body = model.bodies[joint.child]
        body_in_joint[joint.child] = np.linalg.inv(_transform(joint.child_frame))
        at = body_in_joint[joint.child]
        inertia = pin.Inertia(body.mass, np.asarray(body.com, float), np.asarray(body.inertia))
        built.appendBodyToJoint(joint_id, inertia, pin.SE3(at[:3, :3], at[:3, 3]))
        ids[joint.child] = joint_id
        order[built.joints[joint_id].idx_v] = kinematics.joint_slices[joint.name][1].start
    return built, order


def _numbers(values: Any) -> str:
    return " ".join(f"{float(x):.17g}" for x in np.ravel(values))


def mujoco_xml(model: Model) -> str:
    """MJCF of ``model``: nested bodies with hinges, explicit inertials, no contacts."""
    kinematics = TreeKinematics(model.validate())
    _check(model, kinematics)
    children: dict[str, list] = {}
    for joint in kinematics.order:
        children.setdefault(joint.parent, []).append(joint)

    def body_xml(joint: Any, indent: str) -> list[str]:
        body = model.bodies[joint.child]
        p, c = joint.parent_frame, joint.child_frame
        rotation = p.rotation @ c.rotation.T  # P C^-1 at q = 0
        position = p.position - rotation @ c.position
        quat = Rotation.from_matrix(rotation).as_quat()[[3, 0, 1, 2]]
        axis = c.rotation @ (np.asarray(joint.axis, float) / np.linalg.norm(joint.axis))
        inertia = np.asarray(body.inertia, dtype=float)
        full = [inertia[0, 0], inertia[1, 1], inertia[2, 2]]
        full += [inertia[0, 1], inertia[0, 2], inertia[1, 2]]
        lines = [
            f'{indent}<body name="{body.name}" pos="{_numbers(position)}" quat="{_numbers(quat)}">',
            f'{indent}  <joint name="{joint.name}" type="hinge" pos="{_numbers(c.position)}" '
            f'axis="{_numbers(axis)}"/>',
            f'{indent}  <inertial pos="{_numbers(body.com)}" mass="{body.mass:.17g}" '
            f'fullinertia="{_numbers(full)}"/>',
        ]
        for child in children.get(joint.child, []):
            lines += body_xml(child, indent + "  ")
        return [*lines, f"{indent}</body>"]

    bodies = [line for joint in children.get(GROUND, []) for line in body_xml(joint, "    ")]
    return "\n".join(
        [
            f'<mujoco model="{model.name}">',
            '  <compiler angle="radian" inertiafromgeom="false" balanceinertia="false"/>',
            f'  <option gravity="{_numbers(model.gravity)}">',
            '    <flag contact="disable" constraint="disable" limit="disable"/>',
            "  </option>",
            "  <worldbody>",
            *bodies,
            "  </worldbody>",
            "</mujoco>",
        ]
    )


def mujoco_model(model: Model) -> tuple[Any, np.ndarray]:
    """(mujoco.MjModel, order): order[i] is our velocity index of MuJoCo's qvel[i]."""
    import mujoco

    built = mujoco.MjModel.from_xml_string(mujoco_xml(model))
    kinematics = TreeKinematics(model)
    order = np.zeros(built.nv, dtype=int)
    for joint in kinematics.order:
        order[built.joint(joint.name).dofadr[0]] = kinematics.joint_slices[joint.name][1].start
    return built, order
