"""The same mechanism for the peers: a Pinocchio ``pin.Model`` and MuJoCo MJCF from ours.

Trees of revolute joints (the scalable problems); for Pinocchio with ``general=True`` also
prismatic and spherical joints and a free root joint (:func:`random_tree`, issue 21), with
:class:`PinocchioState` mapping states and accelerations. Our joint sits at frame P on the
parent body, moves by M(q) (about or along ``axis``, P coordinates) and carries the child
body whose frame is C^-1 from the moved joint frame: X_child = X_parent P M(q) C^-1.

* Pinocchio: one joint frame per body, equal to our rotated P; its placement in the
  parent's joint frame is C_parent^-1 P, and the body (mass, centre of mass, inertia about
  it) is appended at C^-1. Axes along +x, +y, +z use the specialised R*, P* joints.
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

GENERAL = ("revolute", "prismatic", "spherical", "free")


def _check(model: Model, kinematics: TreeKinematics, types: tuple = ("revolute",)) -> None:
    others = [
        j.name
        for j in kinematics.order
        if j.type not in types or j.drive is not None or (j.type == "free" and j.parent != GROUND)
    ]
    if others or model.cut_joints or model.nonholonomic:
        raise ValueError(
            f"model {model.name!r}: the peer models handle trees of free {', '.join(types)} "
            f"joints only "
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


def _pinocchio_joint(pin: Any, joint: Any) -> Any:
    """Pinocchio's joint model of ours (axis in the joint frame P)."""
    if joint.type in ("spherical", "free"):
        return pin.JointModelSpherical() if joint.type == "spherical" else pin.JointModelFreeFlyer()
    axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
    letter = {(1.0, 0.0, 0.0): "X", (0.0, 1.0, 0.0): "Y", (0.0, 0.0, 1.0): "Z"}.get(tuple(axis))
    prefix = "R" if joint.type == "revolute" else "P"
    if letter:
        return getattr(pin, f"JointModel{prefix}{letter}")()
    if joint.type == "revolute":
        return pin.JointModelRevoluteUnaligned(axis)
    return pin.JointModelPrismaticUnaligned(axis)


def pinocchio_model(model: Model, general: bool = False) -> tuple[Any, Any]:
    """(pin.Model, order): order[i] is our velocity index of Pinocchio's v[i].

    ``general``: also prismatic and spherical joints and a free root joint; then the
    second item is a :class:`PinocchioState` (the map of states and accelerations)."""
    kinematics = TreeKinematics(model.validate())
    _check(model, kinematics, GENERAL if general else ("revolute",))
    import pinocchio as pin

    built = pin.Model()
    built.gravity = pin.Motion(np.asarray(model.gravity, dtype=float), np.zeros(3))
    ids = {GROUND: 0}
    body_in_joint = {GROUND: np.eye(4)}  # body frame in its joint frame: C^-1
    order = np.zeros(kinematics.nv, dtype=int)
    for joint in depth_first(kinematics):
        placement = body_in_joint[joint.parent] @ _transform(joint.parent_frame)
        joint_id = built.addJoint(
            ids[joint.parent],
            _pinocchio_joint(pin, joint),
            pin.SE3(placement[:3, :3], placement[:3, 3]),
            joint.name,
        )
        body = model.bodies[joint.child]
        body_in_joint[joint.child] = np.linalg.inv(_transform(joint.child_frame))
        at = body_in_joint[joint.child]
        inertia = pin.Inertia(body.mass, np.asarray(body.com, float), np.asarray(body.inertia))
        built.appendBodyToJoint(joint_id, inertia, pin.SE3(at[:3, :3], at[:3, 3]))
        ids[joint.child] = joint_id
        order[built.joints[joint_id].idx_v] = kinematics.joint_slices[joint.name][1].start
    if general:
        return built, PinocchioState(kinematics, built)
    return built, order


class PinocchioState:
    """Our joint state -> Pinocchio's, joint by joint by name, and its accelerations back.

    Revolute, prismatic: the same. Spherical: Euler parameters (w, x, y, z) -> Pinocchio's
    (x, y, z, w); both take the angular velocity in C. Free: ours (position in P, Euler
    parameters; its rate in P, angular velocity in C), Pinocchio's v = (R^T p', omega):
    v_pin = T v with T = diag(R^T, 1), a_pin = T a + T' v, T' v = (-omega x R^T p', 0).
    Continuous joints (Pinocchio's ``RUB*``): q_pin = (cos q, sin q).
    """

    def __init__(self, kinematics: TreeKinematics, pin_model: Any) -> None:
        self.kinematics, self.pin_model = kinematics, pin_model
        names = list(pin_model.names)
        self.joints = []
        for joint in kinematics.free_joints:
            theirs = pin_model.joints[names.index(joint.name)]
            q_slice, v_slice = kinematics.joint_slices[joint.name]
            pq = slice(theirs.idx_q, theirs.idx_q + theirs.nq)
            pv = slice(theirs.idx_v, theirs.idx_v + theirs.nv)
            self.joints.append((joint.type, q_slice, v_slice, pq, pv))
        if pin_model.nv != kinematics.nv:
            raise ValueError(f"Pinocchio has nv = {pin_model.nv}, ours {kinematics.nv}")

    def state(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q_pin, v_pin) of our (q, v)."""
        q_pin, v_pin = np.zeros(self.pin_model.nq), np.zeros(self.pin_model.nv)
        for kind, q_slice, v_slice, pq, pv in self.joints:
            qi, vi = q[q_slice], v[v_slice]
            v_pin[pv] = vi
            if kind == "free":
                q_pin[pq] = np.concatenate([qi[:3], qi[[4, 5, 6, 3]]])
                v_pin[pv.start : pv.start + 3] = _rotation(qi[3:]).T @ vi[:3]
            elif kind == "spherical":
                q_pin[pq] = qi[[1, 2, 3, 0]]
            elif pq.stop - pq.start == 2 * (pv.stop - pv.start):
                q_pin[pq] = [np.cos(qi[0]), np.sin(qi[0])]
            else:
                q_pin[pq] = qi
        return q_pin, v_pin

    def accelerations(self, a_pin: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Pinocchio's accelerations at our (q, v) as ours."""
        a = np.zeros(self.kinematics.nv)
        for kind, q_slice, v_slice, _, pv in self.joints:
            a[v_slice] = a_pin[pv]
            if kind == "free":
                rotation = _rotation(q[q_slice][3:])
                velocity, omega = rotation.T @ v[v_slice][:3], v[v_slice][3:]
                linear = a_pin[pv.start : pv.start + 3] + np.cross(omega, velocity)
                a[v_slice.start : v_slice.start + 3] = rotation @ linear
        return a


def _rotation(p: np.ndarray) -> np.ndarray:
    """Rotation matrix of Euler parameters (w, x, y, z)."""
    return Rotation.from_quat(np.asarray(p)[[1, 2, 3, 0]]).as_matrix()


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


def random_tree(n: int, seed: int = 0) -> Model:
    """A random tree of n bodies: a free base, then revolute, prismatic and spherical joints
    (about 2 : 1 : 1) on random parents, with random rotated joint frames and axes, and full
    inertia tensors (boxes turned at random, centres of mass off the frame origins)."""
    rng = np.random.default_rng(seed)
    model = Model(f"random-tree-{n}", kind="spatial")

    def frame() -> Frame:
        return Frame(rng.uniform(-0.5, 0.5, 3), Rotation.random(random_state=rng).as_matrix())

    for i in range(n):
        mass = rng.uniform(0.5, 2.0)
        a, b, c = rng.uniform(0.1, 1.0, 3)
        moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        turn = Rotation.random(random_state=rng).as_matrix()
        com = rng.uniform(-0.3, 0.3, 3)
        model.add_body(f"b{i}", mass, com=com, inertia=turn @ np.diag(moments) @ turn.T)
        kind = ("revolute", "revolute", "prismatic", "spherical")[rng.integers(4)]
        if i == 0:
            model.add_joint("j0", "free", GROUND, "b0", child_frame=frame())
            continue
        parent = f"b{rng.integers(max(0, i - 8), i)}"  # depth grows with n, as in robots
        axis = rng.standard_normal(3)
        model.add_joint(
            f"j{i}", kind, parent, f"b{i}", parent_frame=frame(), child_frame=frame(), axis=axis
        )
    return model.validate()
