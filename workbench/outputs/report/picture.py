"""A picture of a mechanism at its initial pose: a matplotlib projection of its geometry.

Every shape of every body (boxes' corners, cylinders' and capsules' end circles, spheres,
meshes' vertices) is placed by the tree's forward kinematics at the problem's initial
joint coordinates, projected (planar models: their x-y plane; spatial ones: an oblique
view, z up) and drawn as the filled convex hull of its points in the shape's colour,
far shapes first; grey lines join each joint's parent frame to its child body. Loop
closures are drawn as they are at those coordinates (the picture is not an assembly).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from workbench.outputs.report.figures import FigureFiles, save_figure, slug

MESH_POINTS = 1500  # vertices kept of a mesh (its hull does not need more)
CIRCLE = 16  # points on a circle of a cylinder, capsule or sphere
AZIMUTH, ELEVATION = np.radians(-55.0), np.radians(22.0)


def shape_points(shape: Any) -> np.ndarray | None:
    """Points (n, 3) of ``shape`` in its body frame, or None (a mesh that cannot be read)."""
    angles = np.linspace(0.0, 2 * np.pi, CIRCLE, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    size = np.asarray(shape.size, dtype=float)
    if shape.kind == "box":
        corners = np.array(np.meshgrid([-0.5, 0.5], [-0.5, 0.5], [-0.5, 0.5])).T.reshape(-1, 3)
        local = corners * size[:3]
    elif shape.kind in ("cylinder", "capsule"):
        radius, length = size[0], size[1]
        ends = [radius * circle + [0, 0, z * length / 2] for z in (-1, 1)]
        local = np.concatenate(ends)
        if shape.kind == "capsule":
            local = np.concatenate(
                [local, [[0, 0, -length / 2 - radius], [0, 0, length / 2 + radius]]]
            )
    elif shape.kind == "sphere":
        radius = size[0]
        local = radius * np.concatenate([circle, circle[:, [0, 2, 1]], circle[:, [2, 0, 1]]])
    elif shape.kind == "mesh":
        local = _mesh_vertices(shape.path)
        if local is None:
            return None
        local = local * size[:3]
    else:
        return None
    return local @ np.asarray(shape.frame.rotation).T + np.asarray(shape.frame.position)


def _mesh_vertices(path: str) -> np.ndarray | None:
    try:
        import trimesh

        vertices = np.asarray(trimesh.load(path, force="mesh").vertices, dtype=float)
    except Exception:  # noqa: BLE001 - an unreadable mesh costs its shape, not the picture
        return None
    if len(vertices) > MESH_POINTS:
        vertices = vertices[:: len(vertices) // MESH_POINTS + 1]
    return vertices if len(vertices) else None


def body_poses(model: Any) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{body: (position (3,), rotation (3, 3))} at the model's initial configuration."""
    import casadi as ca

    from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values

    kinematics = TreeKinematics(model)
    q0 = initial_joint_values(model, kinematics, dict(model.initial_configuration), False)
    names = list(kinematics.bodies)
    outputs = []
    for name in names:
        state = kinematics.bodies[name]
        outputs += [state.position, ca.reshape(state.rotation, 9, 1)]
    values = ca.Function("poses", [kinematics.t, kinematics.q], outputs)(0.0, q0)
    return {
        name: (
            np.asarray(values[2 * k], dtype=float).reshape(3),
            np.asarray(values[2 * k + 1], dtype=float).reshape(3, 3, order="F"),
        )
        for k, name in enumerate(names)
    }


def projection(planar: bool) -> np.ndarray:
    """Rows: the screen's x, y and the depth (towards the viewer) in world coordinates."""
    if planar:
        return np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    ca, sa, ce, se = np.cos(AZIMUTH), np.sin(AZIMUTH), np.cos(ELEVATION), np.sin(ELEVATION)
    right = np.array([-sa, ca, 0.0])
    toward = np.array([ce * ca, ce * sa, se])
    up = np.cross(toward, right)
    return np.stack([right, up, toward])


@dataclass
class Sketch:
    """What a picture draws, as plain data: filled hulls (depth, points (n, 2), colour) far
    ones first, joint lines (2, 2) and the view's name. Made where the model is (the
    kinematics need CasADi), drawn by a figure worker that imports neither."""

    patches: list[tuple[np.ndarray, np.ndarray]]
    lines: list[np.ndarray]
    view: str


def mechanism_sketch(model: Any) -> Sketch | None:
    """The projected geometry of ``model`` at its initial pose (None: nothing to draw)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        poses = body_poses(model)
    except Exception:  # noqa: BLE001 - a model the kinematics refuse gets no picture
        return None
    view = projection(model.kind == "planar")
    patches = []
    for name, body in model.bodies.items():
        position, rotation = poses[name]
        for shape in body.shapes:
            local = shape_points(shape)
            if local is None:
                continue
            points = (local @ rotation.T + position) @ view.T
            try:
                hull = points[ConvexHull(points[:, :2]).vertices, :2]
            except (QhullError, ValueError):  # flat or too few points: their extent
                hull = points[[np.argmin(points[:, 0]), np.argmax(points[:, 0])], :2]
            patches.append((points[:, 2].mean(), hull, np.asarray(shape.color) / 255.0))
    if not patches:
        return None
    lines = []
    for joint in model.joints.values():
        if joint.type in ("free", "planar"):  # no link to draw: the body floats
            continue
        if joint.parent in poses and joint.child in poses:
            p_pos, p_rot = poses[joint.parent]
            start = p_pos + p_rot @ np.asarray(joint.parent_frame.position)
        elif joint.child in poses:
            start = np.asarray(joint.parent_frame.position, dtype=float)
        else:
            continue
        end = poses[joint.child][0]
        lines.append((np.stack([start, end]) @ view.T)[:, :2])
    ordered = [(hull, color) for _depth, hull, color in sorted(patches, key=lambda p: p[0])]
    view_name = "its x-y plane" if model.kind == "planar" else "oblique view, z up"
    return Sketch(ordered, lines, view_name)


def mechanism_picture(sketch: Sketch, out: Path, problem: str) -> FigureFiles:
    """Draw ``sketch`` (:func:`mechanism_sketch`) into ``out``/figures."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    figure, ax = plt.subplots(figsize=(2.6, 2.6))
    for hull, color in sketch.patches:
        ax.add_patch(Polygon(hull, closed=True, facecolor=color, edgecolor="0.25", linewidth=0.5))
    for line in sketch.lines:
        ax.plot(line[:, 0], line[:, 1], color="0.35", linewidth=0.8, zorder=5)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.axis("off")
    return save_figure(
        figure, out, f"{slug(problem)}-picture", f"{problem} at its initial pose ({sketch.view})"
    )
