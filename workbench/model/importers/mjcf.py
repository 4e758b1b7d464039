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
* joint ``stiffness`` and ``damping`` -> a JointSpringDamper on every joint type, as
  MuJoCo's ``mj_passive``: about ``springref`` on a hinge or slide, and for a ball or free
  joint on the rotation vector of the quaternion difference to its compiled pose
  (``mju_subQuat``), the damping on every velocity; the ``spring``, ``damper``,
  ``gravity`` and ``equality`` disable flags are honoured.
* What changes the smooth dynamics but the model cannot hold (:data:`DROPPABLE`:
  armature, frictionloss, gravcomp, fluid forces, nonlinear or plastic springs, actuator
  armature and damping, engine plugins) refuses the file in one line naming the first
  element, unless ``drop`` names it: then it is left out and noted.
* Outside the compared dynamics by definition (the passive robot, free of contacts and
  limits: docs/robots.md): actuators (the robot moves unactuated), contacts and geom
  contact parameters, joint limits (recorded in :attr:`ImportedRobot.limits`, not
  enforced); each present is listed in :attr:`ImportedRobot.notes`. Sensors, sites,
  cameras, lights and materials are not dynamics.
* equality ``connect`` -> a spherical loop-closing joint between its two anchors;
  ``weld`` -> a fixed loop-closing joint at the relative pose MuJoCo compiled; other
  equalities, tendons and flexes are refused (ModelError naming them).
* Gravity is ``opt.gravity``; the initial state is the first keyframe, if any.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
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
DROPPABLE = {
    "armature": "rotor inertia added to the mass matrix's diagonal",
    "frictionloss": "dry joint friction, a constraint force",
    "gravcomp": "gravity compensation of bodies",
    "fluid": "fluid forces of option density / viscosity",
    "nonlinear-springs": "nonlinear joint springs and dampers (stiffnesspoly, dampingpoly)",
    "plasticity": "plastic joint springs (springyield)",
    "actuator-passive": "actuator armature and damping, which act without control",
    "plugins": "engine plugins, which may add passive forces",
}
"""Terms of an MJCF file that change the smooth dynamics but that the model cannot hold:
a file with any is refused, unless the import is told to ``drop`` them."""
MJCF_TYPES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def load_mjcf(
    path: str | os.PathLike[str],
    keyframe: int | None = 0,
    package_path: Iterable[str | os.PathLike[str]] = (),
    allow_roots: Iterable[str | os.PathLike[str]] = (),
    max_file_mb: float = DEFAULT_MAX_MB,
    drop: Sequence[str] = (),
) -> ImportedRobot:
    """Read the MJCF file at ``path`` into an :class:`ImportedRobot`; ``keyframe``: the
    index of the keyframe giving the initial state (None: start at qpos0); ``drop``: names
    of :data:`DROPPABLE` terms of the file to leave out (each listed in the notes) rather
    than refuse the file.

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
    unknown = sorted(set(drop) - set(DROPPABLE))
    if unknown:
        raise ModelError(
            f"{path}: drop {unknown[0]!r} is not a term that can be left out; choose among "
            f"{', '.join(DROPPABLE)}"
        )
    return _Builder(path, compiled, tuple(drop)).build(keyframe)


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
    def __init__(self, path: Path, compiled: Any, drop: tuple[str, ...] = ()) -> None:
        import mujoco

        self.mujoco, self.path, self.m, self.drop = mujoco, path, compiled, drop
        gravity = np.array(compiled.opt.gravity, float)
        if self.disabled("mjDSBL_GRAVITY"):
            gravity = np.zeros(3)
        self.model = Model(path.stem, "spatial", gravity=gravity)
        self.imported = ImportedRobot(self.model, path)

    def disabled(self, flag: str) -> bool:
        """The file's <option><flag> switches ``flag`` (an mjtDisableBit name) off."""
        return bool(self.m.opt.disableflags & getattr(self.mujoco.mjtDisableBit, flag))

    def refuse_unmodelled(self) -> None:
        """Refuse (one line naming the first element) each :data:`DROPPABLE` term the file
        has, unless it is in ``drop``: then it is left out and noted."""
        m = self.m
        dof_joint = np.asarray(m.dof_jntid, int)
        checks = [  # (term, values a row per element, element kind, element of a row, name)
            ("armature", m.dof_armature, "joint", dof_joint, "armature"),
            ("nonlinear-springs", m.jnt_stiffnesspoly, "joint", None, "stiffnesspoly"),
            ("nonlinear-springs", m.dof_dampingpoly, "joint", dof_joint, "dampingpoly"),
            ("plasticity", m.jnt_springyield, "joint", None, "springyield"),
            ("actuator-passive", m.actuator_armature, "actuator", None, "armature"),
            ("actuator-passive", m.actuator_damping, "actuator", None, "damping"),
        ]
        if not (self.disabled("mjDSBL_FRICTIONLOSS") or self.disabled("mjDSBL_CONSTRAINT")):
            checks.append(("frictionloss", m.dof_frictionloss, "joint", dof_joint, "frictionloss"))
        if not self.disabled("mjDSBL_GRAVITY") and np.any(m.opt.gravity):
            checks.append(("gravcomp", m.body_gravcomp, "body", None, "gravcomp"))
        found: dict[str, str] = {}
        for term, values, kind, owners, attribute in checks:
            rows = np.asarray(values, float)
            rows = rows.reshape(rows.shape[0], -1) if rows.size else rows.reshape(0, 1)
            hits = np.flatnonzero(np.any(rows != 0, axis=1))
            if term in found or not hits.size:
                continue
            if term == "nonlinear-springs" and self.disabled(
                "mjDSBL_SPRING" if attribute == "stiffnesspoly" else "mjDSBL_DAMPER"
            ):
                continue
            index = int(hits[0] if owners is None else owners[hits[0]])
            kind_object = getattr(self.mujoco.mjtObj, f"mjOBJ_{kind.upper()}")
            shown = " ".join(f"{x:g}" for x in rows[hits[0]])
            found[term] = f"{kind} {self.name(kind_object, index, kind)!r}: {attribute} {shown}"
        if m.opt.density > 0 or m.opt.viscosity > 0:
            found["fluid"] = f"<option> density {m.opt.density:g}, viscosity {m.opt.viscosity:g}"
        if m.nplugin:
            found["plugins"] = f"{m.nplugin} engine plugin(s)"
        for term, where in found.items():
            if term in self.drop:
                self.imported.notes.append(f"{where}: left out ({DROPPABLE[term]}; drop)")
                continue
            raise ModelError(
                f"{self.path}: {where} ({DROPPABLE[term]}) cannot be represented in the "
                f"model; remove it from the file, or import with drop=[{term!r}] (the robot "
                f"problem's option drop) to compare the robot without it"
            )

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
        self.refuse_unmodelled()
        names = [self.name(obj.mjOBJ_BODY, b, "body") for b in range(m.nbody)]
        names[0] = GROUND
        # MJCF names bodies, joints and equalities apart; the model does not: a body that
        # shares a joint's or an equality's name becomes <name>_body
        taken = {self.name(obj.mjOBJ_JOINT, j, "joint") for j in range(m.njnt)}
        taken |= {self.name(obj.mjOBJ_EQUALITY, e, "equality") for e in range(m.neq)}
        bodies = list(names)
        for index in range(1, m.nbody):
            while bodies[index] in taken:
                bodies[index] += "_body"
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
                host[body] = (bodies[body], np.eye(4))
                inertias[bodies[body]] = RigidInertia()
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
                joint, bodies[body], parent, _placement(m.body_pos[body], m.body_quat[body])
            )
        if m.neq and (self.disabled("mjDSBL_EQUALITY") or self.disabled("mjDSBL_CONSTRAINT")):
            self.imported.notes.append("equality constraints disabled in the file: none imported")
        else:
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
        if kind in (2, 3) and m.jnt_limited[joint]:
            self.imported.limits[name] = tuple(float(x) for x in m.jnt_range[joint])
        self.add_spring_damper(joint, name, kind)

    def add_spring_damper(self, joint: int, name: str, kind: int) -> None:
        """MuJoCo's joint spring (``stiffness`` about ``qpos_spring``: ``springref`` of a
        hinge or slide, the compiled pose qpos0 of a ball or free joint) and damper
        (``damping`` on every velocity of the joint), unless the file disables them."""
        m, disabled = self.m, self.m.opt.disableflags
        nq, nv = {0: (7, 6), 1: (4, 3), 2: (1, 1), 3: (1, 1)}[kind]
        dof, address = int(m.jnt_dofadr[joint]), int(m.jnt_qposadr[joint])
        stiffness = float(m.jnt_stiffness[joint])
        dampings = np.array(m.dof_damping[dof : dof + nv], float)
        if disabled & self.mujoco.mjtDisableBit.mjDSBL_SPRING:
            stiffness = 0.0
        if disabled & self.mujoco.mjtDisableBit.mjDSBL_DAMPER:
            dampings[:] = 0.0
        if np.ptp(dampings) > 0:  # MJCF gives one damping a joint; refuse what differs
            raise ModelError(
                f"{self.path}: joint {name!r}: damping differs between its degrees of freedom "
                f"({dampings.tolist()}); the model takes one damping a joint"
            )
        damping = float(dampings[0])
        if not (stiffness or damping):
            return
        rest = np.array(m.qpos_spring[address : address + nq], float)
        if kind in (2, 3):  # our angle or displacement is qpos - qpos0
            rest = float(rest[0] - m.qpos0[address])
        else:
            rest = tuple(float(x) for x in rest)
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
        """What the compared dynamics leaves out by definition (the passive robot, free of
        contacts and limits; docs/robots.md): noted, not refused."""
        m, notes = self.m, self.imported.notes
        if m.nu:
            notes.append(f"{m.nu} actuator(s) not modelled (the robot moves unactuated)")
        if np.any(m.jnt_limited):
            notes.append("joint limits are recorded, not enforced")
        if m.ngeom and not self.disabled("mjDSBL_CONTACT"):
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
