"""Imported robots and their peers: Pinocchio built from the same URDF, and the map between
our joint coordinates and Pinocchio's (used by tests/test_urdf_peers.py).

Coordinates, joint by joint (ours -> Pinocchio's):

* revolute / prismatic: the same angle or displacement and rate;
* continuous: ours is the angle theta (a revolute joint); Pinocchio's ``RUB`` joints use
  q = (cos theta, sin theta) and v = theta';
* planar (Pinocchio ``JointModelPlanar``): ours q = (x, y, angle) in the joint frame's
  x-y plane, v = their rates in that frame; Pinocchio's q = (x, y, cos, sin), v = (R^T
  (x', y'), angle'), so T = diag(R^T, 1) and a_pin = T a - (omega x R^T (x', y'), 0);
* free (URDF floating base, Pinocchio ``JointModelFreeFlyer``): ours q = (position of the
  base in the world, Euler parameters scalar-first (w, x, y, z)), v = (the position's rate
  in the world, angular velocity in the base frame); Pinocchio's q = (position, quaternion
  (x, y, z, w)), v = (R^T p', angular velocity in the base frame), both local. So
  v_pin = T(q) v with T = diag(R^T, 1, ...), and a_pin = T a + T' v where
  T' v = (-omega x R^T p', 0, ...).

Mass matrices compare as M_pin = T M T^T (T is orthogonal), torques as tau = T^T tau_pin.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from workbench.mechanics.kinematics import TreeKinematics
from workbench.model.importers.common import ImportedRobot


def example_robot(relative: str) -> Path:
    """The path of a file shipped by the example-robot-data wheel (skip if not installed)."""
    try:
        distribution = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'mbs-workbench[robots]')")
    path = Path(
        distribution.locate_file(f"cmeel.prefix/share/example-robot-data/robots/{relative}")
    )
    assert path.is_file(), f"example-robot-data has no {relative}"
    return path


def pinocchio_model(imported: ImportedRobot) -> Any:
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    if "free" in {joint.type for joint in imported.model.tree_joints[:1]}:
        return pin.buildModelFromUrdf(str(imported.source), pin.JointModelFreeFlyer())
    return pin.buildModelFromUrdf(str(imported.source))


def random_state(
    kinematics: TreeKinematics, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Joint coordinates (angles in (-pi, pi), displacements of a few cm, a random base
    pose, unit Euler parameters) and velocities of order 1."""
    q, v = np.zeros(kinematics.nq), rng.uniform(-2.0, 2.0, kinematics.nv)
    for joint in kinematics.free_joints:
        q_slice, _ = kinematics.joint_slices[joint.name]
        if joint.type == "revolute":
            q[q_slice] = rng.uniform(-np.pi, np.pi)
        elif joint.type == "prismatic":
            q[q_slice] = rng.uniform(0.0, 0.04)
        elif joint.type == "planar":
            q[q_slice] = [*rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi)]
        elif joint.type == "free":
            quaternion = rng.standard_normal(4)
            q[q_slice] = np.concatenate(
                [rng.uniform(-1, 1, 3), quaternion / np.linalg.norm(quaternion)]
            )
        else:
            raise NotImplementedError(joint.type)
    return q, v


def quaternion_matrix(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def planar_rotation(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


class PinocchioMap:
    """Our joint state -> Pinocchio's, joint by joint by name (see the module docstring)."""

    def __init__(self, imported: ImportedRobot, pin_model: Any) -> None:
        self.imported, self.pin_model = imported, pin_model
        self.kinematics = TreeKinematics(imported.model)
        names = list(pin_model.names)
        self.joints = [
            (joint, pin_model.joints[names.index(joint.name)])
            for joint in self.kinematics.free_joints
        ]
        assert pin_model.nv == self.kinematics.nv, (pin_model.nv, self.kinematics.nv)

    def state(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q_pin, v_pin, T) with v_pin = T v."""
        q_pin, v_pin = np.zeros(self.pin_model.nq), np.zeros(self.pin_model.nv)
        t_matrix = np.zeros((self.pin_model.nv, self.kinematics.nv))
        for joint, theirs in self.joints:
            q_slice, v_slice = self.kinematics.joint_slices[joint.name]
            qi, vi = q[q_slice], v[v_slice]
            pq = slice(theirs.idx_q, theirs.idx_q + theirs.nq)
            pv = slice(theirs.idx_v, theirs.idx_v + theirs.nv)
            block = np.eye(vi.size)
            if joint.type == "free":
                rotation = quaternion_matrix(qi[3:])
                q_pin[pq] = np.concatenate([qi[:3], qi[[4, 5, 6, 3]]])
                block[:3, :3] = rotation.T
            elif joint.type == "planar":  # JointModelPlanar: (x, y, cos, sin), local rates
                q_pin[pq] = [qi[0], qi[1], np.cos(qi[2]), np.sin(qi[2])]
                block[:2, :2] = planar_rotation(qi[2]).T
            elif (
                theirs.nq == 2 * theirs.nv
            ):  # continuous: RUBX/RUBY/RUBZ/RevoluteUnboundedUnaligned
                q_pin[pq] = [np.cos(qi[0]), np.sin(qi[0])]
            else:
                q_pin[pq] = qi
            t_matrix[pv, v_slice] = block
            v_pin[pv] = block @ vi
        return q_pin, v_pin, t_matrix

    def accelerations(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Our accelerations a at (q, v) as Pinocchio's: T a + T' v."""
        _, _, t_matrix = self.state(q, v)
        result = t_matrix @ a
        for joint, theirs in self.joints:
            q_slice, v_slice = self.kinematics.joint_slices[joint.name]
            if joint.type == "free":
                rotation = quaternion_matrix(q[q_slice][3:])
                body_velocity = rotation.T @ v[v_slice][:3]
                omega = v[v_slice][3:]
                result[theirs.idx_v : theirs.idx_v + 3] -= np.cross(omega, body_velocity)
            elif joint.type == "planar":  # d/dt (R^T p') = R^T p'' - omega x R^T p'
                local = planar_rotation(q[q_slice][2]).T @ v[v_slice][:2]
                omega = v[v_slice][2]
                result[theirs.idx_v : theirs.idx_v + 2] -= omega * np.array([-local[1], local[0]])
        return result
