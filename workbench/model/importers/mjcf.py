"""MJCF to a :class:`~workbench.model.Model`, read from the compiled ``mujoco.MjModel``
(MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html), so
defaults, includes, ``childclass`` and frame conventions are resolved the way MuJoCo
resolves them.

* A MuJoCo body is a body whose frame is MuJoCo's body frame; ``body_ipos`` /
  ``body_iquat`` place its principal inertia ``body_inertia``: com = ipos,
  I = R diag(inertia) R^T. A body without a joint is welded to its parent (inertias
  combined by the parallel-axis theorem). A body with more than one joint is refused.
* hinge -> revolute, slide -> prismatic: parent frame P = the child's body frame at
  qpos0 moved to the joint's ``pos``, child frame C = that point in the child, axis in P.
  MuJoCo turns a hinge by qpos - qpos0 (the ``ref`` attribute), so our angle is
  qpos - qpos0; ball -> spherical (qpos is our Euler parameters, scalar-first as in MuJoCo;
  qvel the angular velocity in the child frame, as ours); free -> free (qpos = position and
  Euler parameters in the world; qvel = world velocity of the body origin and body-frame
  angular velocity, as ours).
* joint ``stiffness`` (about ``springref``) and ``damping`` -> a JointSpringDamper;
  ``armature``, ``frictionloss``, actuators, contacts and joint limits are not modelled:
  each one present is listed in :attr:`ImportedRobot.notes`; limits are recorded.
* equality ``connect`` -> a spherical loop-closing joint between its two anchors;
  ``weld`` -> a fixed loop-closing joint at the relative pose MuJoCo compiled; other
  equalities, tendons and flexes are refused (ModelError naming them).
* Gravity is ``opt.gravity``; the initial state is the first keyframe, if any.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from workbench.errors import ModelError
from workbench.model.elements import GROUND, Frame, JointSpringDamper, Shape
from workbench.model.importers.common import ImportedRobot, RigidInertia, frame_of, moved_inertia
from workbench.model.importers.file_roots import DEFAULT_MAX_MB, FileRoots
from workbench.model.importers.mjcf_source import check_mjcf_source
from workbench.model.model import Model

TYPES = {0: "free", 1: "spherical", 2: "prismatic", 3: "revolute"}  # mjtJoint
MJCF_TYPES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def load_mjcf(
    path: str | os.PathLike[str],
    keyframe: int | None = 0,
    package_path: Iterable[str | os.PathLike[str]] = (),
    allow_roots: Iterable[str | os.PathLike[str]] = (),
    max_file_mb: float = DEFAULT_MAX_MB,
) -> ImportedRobot:
    """Read the MJCF file at ``path`` into an :class:`ImportedRobot`; ``keyframe``: the
    index of the keyframe giving the initial state (None: start at qpos0).

    Before MuJoCo compiles it, the XML (and every file it includes) is checked: the files
    it names stay inside its folder or ``allow_roots`` (``package_path`` is accepted for
    symmetry with URDF: MJCF has no package:// references), each at most ``max_file_mb``,
    and its numbers are finite (:mod:`workbench.model.importers.mjcf_source`)."""
    import mujoco

    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: no such file; give the path of an MJCF .xml file")
    roots = FileRoots.of(path, package_path, allow_roots, max_file_mb)
    roots.regular_file(Path(os.path.realpath(path)), str(path), str(path), "robot file")
    check_mjcf_source(path, roots)
    try:
        compiled = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as error:  # MuJoCo's compiler names the element and line
        message = " ".join(str(error).split())
        raise ModelError(f"{path}: MuJoCo cannot compile it: {message}") from None
    return _Builder(path, compiled).build(keyframe)


def _quat_matrix(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(wxyz, float) / np.linalg.norm(wxyz)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def _placement(position: np.ndarray, wxyz: np.ndarray) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = _quat_matrix(wxyz), position
    return matrix


class _Builder:
    def __init__(self, path: Path, compiled: Any) -> None:
        import mujoco

        self.mujoco, self.path, self.m = mujoco, path, compiled
        self.model = Model(path.stem, "spatial", gravity=np.array(compiled.opt.gravity))
        self.imported = ImportedRobot(self.model, path)

    def name(self, kind: Any, index: int, fallback: str) -> str:
        name = self.mujoco.mj_id2name(self.m, kind, index)
        return name if name else f"{fallback}{index}"

    def refuse_unsupported(self) -> None:
        m, obj = self.m, self.mujoco.mjtObj
        if m.ntendon:
            raise ModelError(
                f"{self.path}: tendon {self.name(obj.mjOBJ_TENDON, 0, 'tendon')!r}: tendons "
                "cannot be represented in the model; remove the <tendon> section"
            )
        if getattr(m, "nflex", 0):
            raise ModelError(f"{self.path}: flex {self.name(obj.mjOBJ_FLEX, 0, 'flex')!r}: "
                             "deformable bodies cannot be represented in the model")  # fmt: skip
        for index in range(m.neq):
            kind = int(m.eq_type[index])
            if kind not in (0, 1) or m.eq_objtype[index] != obj.mjOBJ_BODY:
                names = {2: "joint", 3: "tendon", 4: "flex"}
                raise ModelError(
                    f"{self.path}: equality {self.name(obj.mjOBJ_EQUALITY, index, 'equality')!r}"
                    f" ({names.get(kind, kind)}) cannot be represented in the model; only "
                    "<connect> and <weld> between bodies are imported"
                )

    def build(self, keyframe: int | None) -> ImportedRobot:
        m, obj = self.m, self.mujoco.mjtObj
        self.refuse_unsupported()
        names = [self.name(obj.mjOBJ_BODY, b, "body") for b in range(m.nbody)]
        names[0] = GROUND
        host: dict[int, tuple[str, np.ndarray]] = {0: (GROUND, np.eye(4))}
        inertias: dict[str, RigidInertia] = {}
        joint_of: dict[int, int] = {}
        for body in range(1, m.nbody):
            count = int(m.body_jntnum[body])
            if count > 1:
                first = int(m.body_jntadr[body])
                listed = [self.name(obj.mjOBJ_JOINT, first + k, "joint") for k in range(count)]
                raise ModelError(
                    f"{self.path}: body {names[body]!r} has {count} joints ({', '.join(listed)});"
                    " the model takes one joint a body: nest a body per joint (each with mass)"
                )
            parent_body, parent_placement = host[int(m.body_parentid[body])]
            placement = parent_placement @ _placement(m.body_pos[body], m.body_quat[body])
            if count == 0:
                host[body] = (parent_body, placement)
            else:
                host[body] = (names[body], np.eye(4))
                inertias[names[body]] = RigidInertia()
                joint_of[body] = int(m.body_jntadr[body])
        shapes: dict[str, list[Shape]] = {name: [] for name in inertias}
        for body in range(1, m.nbody):
            owner, placement = host[body]
            self.imported.links[names[body]] = (owner, frame_of(placement))
            if owner == GROUND:
                continue
            inertial = placement @ _placement(m.body_ipos[body], m.body_iquat[body])
            com, inertia = moved_inertia(np.diag(m.body_inertia[body]), np.zeros(3), inertial)
            inertias[owner].add(float(m.body_mass[body]), com, inertia)
        for geom in range(m.ngeom):
            owner, placement = host[int(m.geom_bodyid[geom])]
            if owner != GROUND:
                shape = self.shape(geom, placement)
                if shape is not None:
                    shapes[owner].append(shape)
        for name, inertia in inertias.items():
            if inertia.mass <= 0.0:
                raise ModelError(
                    f"{self.path}: body {name!r} moves with a joint but has no mass; give it "
                    'a geom with density or an <inertial mass="...">'
                )
            self.model.add_body(name, inertia.mass, inertia.com, inertia.inertia, shapes[name])
        for body, joint in joint_of.items():
            parent = host[int(m.body_parentid[body])]
            self.add_joint(
                joint, names[body], parent, _placement(m.body_pos[body], m.body_quat[body])
            )
        for index in range(m.neq):
            self.add_equality(index, names, host)
        self.note_unmodelled()
        if keyframe is not None and m.nkey > keyframe:
            self.read_keyframe(keyframe)
        self.model.initial_configuration = dict(self.imported.initial_coordinates)
        try:
            self.model.validate()
        except ModelError as error:
            raise ModelError(f"{self.path}: {error}") from None
        return self.imported

    def add_joint(
        self, joint: int, child: str, parent: tuple[str, np.ndarray], local: np.ndarray
    ) -> None:
        m = self.m
        name = self.name(self.mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
        kind = int(m.jnt_type[joint])
        parent_body, parent_placement = parent
        anchor = np.array(m.jnt_pos[joint], float)
        if kind == 0:  # free: the body's pose in the world is the coordinates
            parent_frame, child_frame = Frame(), Frame()
        else:
            at = parent_placement @ local
            parent_frame = frame_of(at @ _translation(anchor))
            child_frame = Frame(anchor, np.eye(3))
        if name in self.model.bodies:
            raise ModelError(f"{self.path}: joint {name!r} has a body's name; rename one")
        self.model.add_joint(
            name, TYPES[kind], parent_body, child, parent_frame, child_frame,
            axis=np.array(m.jnt_axis[joint], float),
        )  # fmt: skip
        self.imported.file_joint_types[name] = MJCF_TYPES[kind]
        if kind in (2, 3):
            if m.jnt_limited[joint]:
                self.imported.limits[name] = tuple(float(x) for x in m.jnt_range[joint])
            dof, address = int(m.jnt_dofadr[joint]), int(m.jnt_qposadr[joint])
            stiffness, damping = float(m.jnt_stiffness[joint]), float(m.dof_damping[dof])
            if stiffness or damping:
                rest = float(m.qpos_spring[address] - m.qpos0[address])
                self.model.add_force(
                    JointSpringDamper(f"{name} spring-damper", name, stiffness, damping, rest)
                )

    def add_equality(self, index: int, names: list[str], host: dict) -> None:
        m, obj = self.m, self.mujoco.mjtObj
        name = self.name(obj.mjOBJ_EQUALITY, index, "equality")
        if not m.eq_active0[index]:
            self.imported.notes.append(f"equality {name!r} is inactive in the file: not imported")
            return
        body1, body2 = int(m.eq_obj1id[index]), int(m.eq_obj2id[index])
        owner1, place1 = host[body1]
        owner2, place2 = host[body2]
        data = np.array(m.eq_data[index], float)
        if int(m.eq_type[index]) == 0:  # connect: anchor in body1, anchor in body2
            parent = Frame(place1[:3, :3] @ data[0:3] + place1[:3, 3], np.eye(3))
            child = Frame(place2[:3, :3] @ data[3:6] + place2[:3, 3], np.eye(3))
            kind = "spherical"
        else:  # weld: data[0:3] the anchor in body2, data[3:6] the point of body1 that
            # coincides with it and data[6:10] body2's orientation in body1, both at rest
            parent = frame_of(place1 @ _placement(data[3:6], data[6:10]))
            child = frame_of(place2 @ _translation(data[0:3]))
            kind = "fixed"
        self.model.add_joint(name, kind, owner1, owner2, parent, child, cut=True)
        self.imported.file_joint_types[name] = "connect" if kind == "spherical" else "weld"

    def shape(self, geom: int, placement: np.ndarray) -> Shape | None:
        m = self.m
        frame = frame_of(placement @ _placement(m.geom_pos[geom], m.geom_quat[geom]))
        size, kind = np.array(m.geom_size[geom], float), int(m.geom_type[geom])
        rgba = np.clip(np.array(m.geom_rgba[geom][:3]) * 255, 0, 255).astype(int)
        color = (int(rgba[0]), int(rgba[1]), int(rgba[2]))
        geom_types = self.mujoco.mjtGeom
        if kind == geom_types.mjGEOM_SPHERE:
            return Shape("sphere", (size[0],), frame, color)
        if kind == geom_types.mjGEOM_BOX:
            return Shape("box", tuple(2 * size), frame, color)
        if kind == geom_types.mjGEOM_CAPSULE:
            return Shape("capsule", (size[0], 2 * size[1]), frame, color)
        if kind == geom_types.mjGEOM_CYLINDER:
            return Shape("cylinder", (size[0], 2 * size[1]), frame, color)
        return None

    def note_unmodelled(self) -> None:
        m, notes = self.m, self.imported.notes
        if np.any(m.dof_armature):
            notes.append("joint armature (rotor inertia) is not modelled")
        if np.any(m.dof_frictionloss):
            notes.append("joint frictionloss is not modelled")
        if m.nu:
            notes.append(f"{m.nu} actuator(s) not modelled (the robot moves unactuated)")
        if np.any(m.jnt_limited):
            notes.append("joint limits are recorded, not enforced")
        if m.ngeom and not m.opt.disableflags & self.mujoco.mjtDisableBit.mjDSBL_CONTACT:
            notes.append("contacts are not modelled")

    def read_keyframe(self, key: int) -> None:
        m = self.m
        qpos, qvel = np.array(m.key_qpos[key], float), np.array(m.key_qvel[key], float)
        for joint in range(m.njnt):
            name = self.name(self.mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
            if name not in self.model.joints:
                continue
            kind, address, dof = (
                int(m.jnt_type[joint]),
                int(m.jnt_qposadr[joint]),
                int(m.jnt_dofadr[joint]),
            )
            nq, nv = {0: (7, 6), 1: (4, 3), 2: (1, 1), 3: (1, 1)}[kind]
            q = qpos[address : address + nq]
            if kind in (2, 3):
                q = q - m.qpos0[address : address + nq]
            self.imported.initial_coordinates[name] = q.tolist() if nq > 1 else float(q[0])
            v = qvel[dof : dof + nv]
            self.imported.initial_velocities[name] = v.tolist() if nv > 1 else float(v[0])


def _translation(vector: np.ndarray) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, 3] = vector
    return matrix


__all__ = ["load_mjcf"]
