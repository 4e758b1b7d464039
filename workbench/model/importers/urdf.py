"""URDF to a :class:`~workbench.model.Model`, read by yourdfpy (ROS URDF specification,
http://wiki.ros.org/urdf/XML).

* A link is a body whose frame is the link frame; its ``<inertial>`` (mass, centre of mass
  at the inertial origin, inertia tensor in the rotated inertial frame) becomes the body's
  centre of mass and inertia in the link frame: com = p, I = R I_inertial R^T.
* A joint's ``<origin>`` places the joint frame in the parent link frame; the child link
  frame is the joint frame at zero joint coordinates; ``<axis>`` is in the joint frame.
  So the model joint has parent frame P = the origin, child frame C = identity, axis = the
  URDF axis (normalized).
* revolute and continuous -> revolute (one angle: a continuous joint is not written as
  (cos, sin) as Pinocchio does); prismatic -> prismatic; floating -> free (position of the
  child in the parent's joint frame, Euler parameters scalar-first); planar -> planar in the
  plane normal to the axis (its x and y are the joint frame's turned by the least rotation
  taking z onto the axis: for axis z, q = (x, y, angle) as Pinocchio's ``JointModelPlanar``);
  fixed -> the child link is welded into its parent's body: its mass, centre of mass and
  inertia are combined (parallel-axis theorem) and its visuals move with it. A moving
  link without mass that carries other moving links (a gimbal's link between joints) is a
  massless body; at the end of a chain it is refused. A link with a mass and a zero
  inertia is a point mass at its centre of mass. The root link is fixed to the ground
  unless ``floating_base`` gives it a free joint (Pinocchio's ``JointModelFreeFlyer``
  root); links welded to the ground carry no dynamics.
* ``<limit>`` lower/upper are recorded in :attr:`ImportedRobot.limits`, not enforced;
  ``<dynamics>`` damping and friction are not modelled (the file's joint then moves
  freely); mimic joints are refused unless ``mimic="independent"``.
* Gravity is (0, 0, -9.81) m/s^2 (URDF has none) unless given.

Faults are one-line :class:`~workbench.errors.ModelError`s naming the file, the element
and its line.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

import numpy as np

from workbench.errors import ModelError
from workbench.model.elements import GROUND, Frame, Shape
from workbench.model.importers.common import (
    ImportedRobot,
    MeshVisual,
    RigidInertia,
    frame_of,
    moved_inertia,
)
from workbench.model.importers.file_roots import DEFAULT_MAX_MB, FileRoots
from workbench.model.model import Model

JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
MODEL_TYPES = {
    "revolute": "revolute",
    "continuous": "revolute",
    "prismatic": "prismatic",
    "floating": "free",
    "planar": "planar",
}
# attributes the URDF specification gives as numbers (each checked finite before reading)
NUMERIC_ATTRIBUTES = {
    "xyz", "rpy", "value", "ixx", "ixy", "ixz", "iyy", "iyz", "izz", "lower", "upper",
    "effort", "velocity", "radius", "length", "size", "scale", "multiplier", "offset",
    "damping", "friction", "rgba",
}  # fmt: skip


# elements outside the URDF specification's kinematics and dynamics: never read here
IGNORED_EXTENSIONS = ("gazebo", "transmission")


class _Source:
    """The parsed XML of a URDF file: names elements with their line for messages."""

    def __init__(self, path: Path) -> None:
        from lxml import etree

        self.path = path
        try:
            self.root = etree.parse(str(path), etree.XMLParser(remove_blank_text=True)).getroot()
        except etree.XMLSyntaxError as error:
            raise ModelError(
                f"{path}: broken XML at line {error.lineno}: {error.msg}; fix the file so it "
                "is well-formed XML"
            ) from None
        except OSError as error:
            raise ModelError(f"{path}: cannot read the file: {error}") from None
        if self.root.tag != "robot":
            raise ModelError(
                f"{path}: line {self.root.sourceline}: the root element is <{self.root.tag}>, "
                "not <robot>; is this a URDF file?"
            )
        self.lines: dict[tuple[str, str], int] = {}
        for tag in ("link", "joint"):
            for element in self.root.findall(tag):
                name = element.get("name")
                if not name:
                    raise ModelError(
                        f"{path}: line {element.sourceline}: a <{tag}> has no name; give "
                        f'every <{tag}> a name="..."'
                    )
                if (tag, name) in self.lines:
                    raise ModelError(
                        f"{self.where(tag, name)}: a second <{tag}> named {name!r} at line "
                        f"{element.sourceline}; give every {tag} its own name"
                    )
                self.lines[(tag, name)] = element.sourceline

    def where(self, tag: str, name: str) -> str:
        line = self.lines.get((tag, name))
        return f"{self.path}: {tag} {name!r}" + (f" (line {line})" if line else "")

    def owner(self, element: Any) -> str:
        """The link or joint an element belongs to, with the element's line."""
        node = element
        while node is not None and node.tag not in ("link", "joint"):
            node = node.getparent()
        owner = f"{node.tag} {node.get('name')!r}, " if node is not None else ""
        return f"{self.path}: {owner}<{element.tag}> (line {element.sourceline})"

    def check(self) -> None:
        """Numbers are finite numbers, joints have a known type, a parent and a child.

        Only the URDF specification's own attributes are numbers: ``<gazebo>`` and
        ``<transmission>`` extensions are not read (PR2's ``<material value="PR2/...">``
        names a Gazebo material), and ``value`` is a number on ``<mass>`` only."""
        if not self.root.get("name"):
            raise ModelError(
                f'{self.path}: line {self.root.sourceline}: <robot> has no name="..."; the '
                "URDF specification requires one (Pinocchio and yourdfpy refuse it too)"
            )
        for element in self.root.iter():
            if not isinstance(element.tag, str) or any(
                ancestor.tag in IGNORED_EXTENSIONS for ancestor in element.iterancestors()
            ):
                continue
            if element.tag in IGNORED_EXTENSIONS:
                continue
            for attribute in NUMERIC_ATTRIBUTES & set(element.attrib):
                if attribute == "value" and element.tag != "mass":
                    continue
                text = element.get(attribute)
                try:
                    values = [float(word) for word in text.split()]
                except ValueError:
                    values = None
                if values is None or not all(math.isfinite(v) for v in values):
                    raise ModelError(
                        f"{self.owner(element)}: {attribute}={text!r} is not a finite number "
                        f"(or list of numbers); write it as decimal numbers"
                    )
        for element in self.root.findall("joint"):
            name, kind = element.get("name"), element.get("type")
            if kind not in JOINT_TYPES:
                raise ModelError(
                    f"{self.where('joint', name)}: unknown joint type {kind!r}; URDF joint "
                    f"types are {', '.join(JOINT_TYPES)}"
                )
            for role in ("parent", "child"):
                found = element.find(role)
                if found is None or not found.get("link"):
                    raise ModelError(
                        f'{self.where("joint", name)}: no <{role} link="..."/>; name the '
                        f"{role} link"
                    )
        for element in self.root.findall("link/inertial/inertia"):
            missing = [a for a in ("ixx", "iyy", "izz") if a not in element.attrib]
            if missing:
                raise ModelError(
                    f"{self.owner(element)}: no {', '.join(missing)}; give the six inertia "
                    "components ixx ixy ixz iyy iyz izz (kg m^2)"
                )


def load_urdf(
    path: str | os.PathLike[str],
    floating_base: bool = False,
    mimic: Literal["error", "independent"] = "error",
    meshes: bool = True,
    gravity: Any = None,
    package_path: Iterable[str | os.PathLike[str]] = (),
    allow_roots: Iterable[str | os.PathLike[str]] = (),
    max_file_mb: float = DEFAULT_MAX_MB,
) -> ImportedRobot:
    """Read the URDF file at ``path`` into an :class:`ImportedRobot`.

    ``floating_base``: give the root link a free joint (named "root_joint") instead of
    fixing it to the ground; ``mimic``: "independent" imports mimic joints as free
    joints (Pinocchio's default), "error" refuses them; ``meshes``: check that every
    visual mesh file exists (False: import without them); ``gravity`` (3,) m/s^2.
    ``package_path``, ``allow_roots``, ``max_file_mb``: where mesh files may be read
    from and how large they may be (:mod:`workbench.model.importers.file_roots`).
    """
    import yourdfpy

    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: no such file; give the path of a .urdf file")
    if mimic not in ("error", "independent"):
        raise ModelError(f"{path}: mimic must be 'error' or 'independent', not {mimic!r}")
    roots = FileRoots.of(path, package_path, allow_roots, max_file_mb)
    roots.regular_file(Path(os.path.realpath(path)), str(path), str(path), "robot file")
    source = _Source(path)
    source.check()
    try:
        robot = yourdfpy.URDF.load(
            str(path), build_scene_graph=False, load_meshes=False, load_collision_meshes=False,
            filename_handler=_no_file,
        ).robot  # fmt: skip
    except Exception as error:  # noqa: BLE001 - yourdfpy raises many kinds; one line here
        raise ModelError(f"{path}: yourdfpy cannot read it: {error}") from None
    return _Builder(source, robot, floating_base, mimic, meshes, gravity, roots).build()


def _no_file(filename: str, **_: Any) -> str:
    """yourdfpy's file name handler: it resolves nothing (meshes go through FileRoots)."""
    raise ModelError(f"yourdfpy was asked to open {filename!r}; meshes are read by the workbench")


class _Builder:
    def __init__(
        self, source: _Source, robot: Any, floating_base: bool, mimic: str, meshes: bool,
        gravity: Any, roots: FileRoots,
    ) -> None:  # fmt: skip
        self.source, self.robot, self.roots = source, robot, roots
        self.floating_base, self.mimic, self.check_meshes = floating_base, mimic, meshes
        kwargs = {} if gravity is None else {"gravity": gravity}
        self.model = Model(robot.name or source.path.stem, "spatial", **kwargs)
        self.imported = ImportedRobot(self.model, source.path)
        self.link_of: dict[str, str] = {}  # body -> the link it is named after
        self.joint_names = {joint.name for joint in robot.joints}  # what a body must not be
        if floating_base:
            self.joint_names.add("root_joint")

    # -- the tree ---------------------------------------------------------------------
    def root_link(self) -> tuple[str, dict[str, list[Any]]]:
        links = {link.name for link in self.robot.links}
        children: dict[str, list[Any]] = {}
        parent_joint: dict[str, str] = {}
        for joint in self.robot.joints:
            for role in ("parent", "child"):
                link = getattr(joint, role)
                if link not in links:
                    raise ModelError(
                        f"{self.source.where('joint', joint.name)}: unknown {role} link "
                        f"{link!r}; name one of the file's <link>s"
                    )
            if joint.child in parent_joint:
                raise ModelError(
                    f"{self.source.where('joint', joint.name)}: link {joint.child!r} is "
                    f"already the child of joint {parent_joint[joint.child]!r}; a URDF is a "
                    "tree (each link has one parent joint): close loops in MJCF instead"
                )
            parent_joint[joint.child] = joint.name
            children.setdefault(joint.parent, []).append(joint)
        roots = [link.name for link in self.robot.links if link.name not in parent_joint]
        if not roots:
            raise ModelError(
                f"{self.source.path}: the joints form a cycle (every link is some joint's "
                "child, so there is no root link); a URDF must be a tree"
            )
        if len(roots) > 1:
            raise ModelError(
                f"{self.source.where('link', roots[1])}: not connected to the root link "
                f"{roots[0]!r} (the file has {len(roots)} links without a parent joint: "
                f"{', '.join(roots[:5])}); connect every link by a joint"
            )
        return roots[0], children

    def body_name(self, link: str) -> str:
        """The body of a moving link: the link's name, unless a joint has that name too
        (URDF allows it; the model does not): then ``<link>_link``."""
        name = link
        while name in self.joint_names:
            name += "_link"
        self.link_of[name] = link
        return name

    def build(self) -> ImportedRobot:
        root, children = self.root_link()
        if all(j.type == "fixed" for j in self.robot.joints) and not self.floating_base:
            raise ModelError(
                f"{self.source.where('link', root)}: the file has no moving joint, so its "
                "links are fixed to the ground and nothing moves; import with "
                "floating_base=True (option floating_base = true) to let it fly freely"
            )
        # host[link] = (body or GROUND, 4x4 link frame in that body's frame)
        host: dict[str, tuple[str, np.ndarray]] = {}
        inertias: dict[str, RigidInertia] = {}
        moved_by: dict[str, str] = {}  # body -> the file joint that moves it
        if self.floating_base:
            body = self.body_name(root)
            host[root] = (body, np.eye(4))
            inertias[body] = RigidInertia()
            moved_by[body] = "root_joint"
        else:
            host[root] = (GROUND, np.eye(4))
        order = [root]
        stack = list(reversed(children.get(root, [])))
        while stack:  # depth first, in file order
            joint = stack.pop()
            parent_body, parent_placement = host[joint.parent]
            placement = parent_placement @ _origin(joint.origin)
            if joint.type == "fixed":
                host[joint.child] = (parent_body, placement)
            else:
                body = self.body_name(joint.child)
                host[joint.child] = (body, np.eye(4))
                inertias[body] = RigidInertia()
                moved_by[body] = joint.name
            order.append(joint.child)
            stack.extend(reversed(children.get(joint.child, [])))
        reached = set(order)
        unreached = [link.name for link in self.robot.links if link.name not in reached]
        if unreached:
            raise ModelError(
                f"{self.source.where('link', unreached[0])}: on a cycle of joints not "
                f"connected to the root link {root!r}; a URDF must be a tree"
            )
        links = {link.name: link for link in self.robot.links}
        shapes: dict[str, list[Shape]] = {body: [] for body in inertias}
        for name in order:
            body, placement = host[name]
            self.imported.links[name] = (body, frame_of(placement))
            self.add_inertial(links[name], body, placement, inertias)
            self.add_visuals(links[name], body, placement, shapes)
        carrying = {host[j.parent][0] for j in self.robot.joints if j.type != "fixed"}
        for body, inertia in inertias.items():
            if inertia.mass <= 0.0 and body in carrying:  # a massless link between joints
                self.model.add_point_mass(body, 0.0, shapes[body])
                continue
            if inertia.mass <= 0.0:
                raise ModelError(
                    f"{self.source.where('link', self.link_of[body])}: moves with joint "
                    f"{moved_by[body]!r} but has no mass (no <inertial>, or mass 0, on it and "
                    "on the links fixed to it) and carries no moving link, so that joint "
                    "moves nothing (its mass matrix is singular); give it an <inertial> "
                    "with a mass > 0"
                )
            if np.abs(inertia.inertia).max() <= 1e-12 * inertia.mass:  # a zero inertia:
                # a point mass (1e-12 kg m^2 a kg: round-off of rotated zero inertias)
                self.model.add_point_mass(body, inertia.mass, shapes[body], com=inertia.com)
                continue
            self.model.add_body(body, inertia.mass, inertia.com, inertia.inertia, shapes[body])
        if self.floating_base:
            self.model.add_joint(
                self.unique_joint_name("root_joint"), "free", GROUND, host[root][0]
            )
            self.imported.file_joint_types["root_joint"] = "floating"
        joint_to = {joint.child: joint for joint in self.robot.joints}
        for name in order[1:]:
            joint = joint_to[name]
            if joint.type != "fixed":
                self.add_joint(joint, host)
        try:
            self.model.validate()
        except ModelError as error:
            raise ModelError(f"{self.where_model(str(error))}: {error}") from None
        return self.imported

    def where_model(self, message: str) -> str:
        """The file and, when the model's message names a body or joint, its element
        and line in the file."""
        found = re.search(r"\b(body|joint) '([^']+)'", message)
        if found is None:
            return str(self.source.path)
        kind, name = found.groups()
        if kind == "body":
            return self.source.where("link", self.link_of.get(name, name))
        return self.source.where("joint", name)

    def unique_joint_name(self, name: str) -> str:
        if name in self.model.joints:  # "root_joint" of floating_base, and a file joint
            raise ModelError(
                f"{self.source.where('joint', name)}: the name {name!r} is the free base's "
                "(floating_base); rename the joint"
            )
        return name

    # -- elements ---------------------------------------------------------------------
    def add_inertial(
        self, link: Any, body: str, placement: np.ndarray, inertias: dict[str, RigidInertia]
    ) -> None:
        inertial = link.inertial
        if inertial is None:
            return
        where = self.source.where("link", link.name)
        if inertial.mass is None:
            raise ModelError(f"{where}: <inertial> has no <mass>; give its mass in kg")
        if inertial.inertia is None:
            raise ModelError(
                f"{where}: <inertial> has no <inertia>; give the six components ixx ixy ixz "
                "iyy iyz izz (kg m^2, about the centre of mass in the inertial frame)"
            )
        if inertial.mass < 0:
            raise ModelError(f"{where}: negative mass {inertial.mass}; give a mass >= 0 kg")
        if body == GROUND:
            return  # welded to the ground: no dynamics
        com, inertia = moved_inertia(
            np.asarray(inertial.inertia, float), np.zeros(3), placement @ _origin(inertial.origin)
        )
        inertias[body].add(float(inertial.mass), com, inertia)

    def add_visuals(
        self, link: Any, body: str, placement: np.ndarray, shapes: dict[str, list[Shape]]
    ) -> None:
        for visual in link.visuals:
            frame = frame_of(placement @ _origin(visual.origin))
            geometry = visual.geometry
            if geometry is None:
                continue
            if geometry.mesh is not None:
                where = self.source.where("link", link.name)
                filename = geometry.mesh.filename
                try:
                    resolved = self.roots.resolve(filename, where)
                except ModelError:
                    if not self.check_meshes:
                        continue
                    raise
                if resolved is None:
                    if not self.check_meshes:
                        continue
                    raise ModelError(
                        f"{where}: mesh {filename!r} not found ({self.roots.where_looked(filename)}"
                        "); install the robot's meshes, or import with meshes=False"
                    )
                scale = np.broadcast_to(
                    np.asarray(1.0 if geometry.mesh.scale is None else geometry.mesh.scale), 3
                )
                scale = tuple(float(s) for s in scale)
                self.imported.meshes.append(MeshVisual(body, resolved, frame, scale))
                if body != GROUND:
                    shapes[body].append(Shape("mesh", scale, frame, path=str(resolved)))
            elif body != GROUND:
                shape = _shape(geometry, frame)
                if shape is not None:
                    shapes[body].append(shape)

    def add_joint(self, joint: Any, host: dict[str, tuple[str, np.ndarray]]) -> None:
        where = self.source.where("joint", joint.name)
        if joint.mimic is not None and self.mimic == "error":
            raise ModelError(
                f"{where}: mimic joint (it copies joint {joint.mimic.joint!r}), which the "
                "model cannot represent; import with mimic='independent' to make it a joint "
                "of its own (as pin.buildModelFromUrdf does by default)"
            )
        parent_body, parent_placement = host[joint.parent]
        placement = parent_placement @ _origin(joint.origin)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), float)
        if np.linalg.norm(axis) < 1e-12:
            raise ModelError(f"{where}: the <axis> is zero; give a direction xyz")
        axis = axis / np.linalg.norm(axis)
        child_frame = Frame()
        if joint.type == "planar":  # the plane's normal becomes the joint frame's z
            align = _z_to(axis)
            placement = placement @ _homogeneous(align)
            child_frame = Frame(np.zeros(3), align)
        name = self.unique_joint_name(joint.name)
        self.model.add_joint(
            name,
            MODEL_TYPES[joint.type],
            parent_body,
            host[joint.child][0],
            frame_of(placement),
            child_frame,
            axis=axis,
        )
        self.imported.file_joint_types[name] = joint.type
        dynamics = joint.dynamics
        if dynamics is not None and (dynamics.damping or dynamics.friction):
            self.imported.notes.append(
                f"joint {name!r}: <dynamics> damping/friction not modelled (moves freely)"
            )
        limit = joint.limit
        if joint.type in ("revolute", "prismatic") and limit is not None:
            if limit.lower is not None and limit.upper is not None:
                self.imported.limits[name] = (float(limit.lower), float(limit.upper))


def _origin(origin: Any) -> np.ndarray:
    return np.eye(4) if origin is None else np.asarray(origin, dtype=float)


def _homogeneous(rotation: np.ndarray) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    return matrix


def _z_to(axis: np.ndarray) -> np.ndarray:
    """The least rotation taking z onto the unit ``axis`` (Rodrigues): the identity for
    axis z, so the plane's x and y are the joint frame's, as in URDF and Pinocchio's
    ``JointModelPlanar``; for axis -z a half turn about x."""
    z = np.array([0.0, 0.0, 1.0])
    cosine = float(axis @ z)
    if cosine < -1.0 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(z, axis)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + cross + cross @ cross / (1.0 + cosine)


def _shape(geometry: Any, frame: Frame) -> Shape | None:
    if geometry.box is not None:
        return Shape("box", tuple(float(s) for s in geometry.box.size), frame)
    if geometry.cylinder is not None:
        cylinder = geometry.cylinder
        return Shape("cylinder", (float(cylinder.radius), float(cylinder.length)), frame)
    if geometry.sphere is not None:
        return Shape("sphere", (float(geometry.sphere.radius),), frame)
    return None


__all__ = ["load_urdf"]
