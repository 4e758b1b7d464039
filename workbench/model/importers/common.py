"""What the importers share: the result of reading a robot file, and the rigid-body
arithmetic that merges links welded together (fixed joints) into one body."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from workbench.model.elements import Frame
from workbench.model.model import Model


@dataclass(frozen=True)
class MeshVisual:
    """A mesh file drawn on ``body`` (or the ground) at ``frame`` (body coordinates),
    scaled per axis by ``scale``."""

    body: str
    path: Path
    frame: Frame
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass
class ImportedRobot:
    """A model read from ``source`` and what the file says beyond it.

    ``limits``: {joint: (lower, upper)} as written (recorded, not enforced); ``meshes``:
    visual meshes; ``links``: {link or MJCF body: (model body or "ground", the link's frame
    in that body)} (welded links share a body); ``file_joint_types``: {model joint: its
    type in the file} (e.g. "continuous", "hinge"); ``initial_coordinates`` /
    ``initial_velocities``: {joint: values} from the file (an MJCF keyframe), else empty;
    ``notes``: what the file has that the model leaves out (one line each: actuators,
    armature, joint friction, contacts), so that nothing is dropped unsaid.
    """

    model: Model
    source: Path
    limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    meshes: list[MeshVisual] = field(default_factory=list)
    links: dict[str, tuple[str, Frame]] = field(default_factory=dict)
    file_joint_types: dict[str, str] = field(default_factory=dict)
    initial_coordinates: dict[str, Any] = field(default_factory=dict)
    initial_velocities: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def transform(frame: Frame) -> np.ndarray:
    """The 4x4 homogeneous matrix of ``frame``."""
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = frame.rotation, frame.position
    return matrix


def frame_of(matrix: np.ndarray) -> Frame:
    """The frame of a 4x4 homogeneous matrix (its rotation re-orthonormalized, so round-off
    in the file's angles does not leave a slightly skewed frame)."""
    u, _, vt = np.linalg.svd(np.asarray(matrix[:3, :3], dtype=float))
    return Frame(np.array(matrix[:3, 3], dtype=float), u @ vt)


@dataclass
class RigidInertia:
    """Mass, centre of mass (3,) and inertia about it (3, 3), in one body's frame."""

    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def add(self, mass: float, com: np.ndarray, inertia: np.ndarray) -> None:
        """Weld another rigid inertia (same frame) onto this one: masses add, the centre of
        mass is their weighted mean and each inertia moves to it by the parallel-axis
        (Huygens-Steiner) theorem, I_c + m (|d|^2 1 - d d^T)."""
        total = self.mass + mass
        if total <= 0.0:
            return
        com_total = (self.mass * self.com + mass * np.asarray(com, float)) / total
        inertia_total = np.zeros((3, 3))
        for m, c, i in ((self.mass, self.com, self.inertia), (mass, com, inertia)):
            d = np.asarray(c, float) - com_total
            inertia_total += np.asarray(i, float) + m * (d @ d * np.eye(3) - np.outer(d, d))
        self.mass, self.com, self.inertia = total, com_total, inertia_total


def moved_inertia(
    inertia: np.ndarray, com: np.ndarray, placement: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(centre of mass, inertia about it) in a body frame, from an inertial frame placed at
    ``placement`` (4x4, in that body frame): com -> R com + p, I -> R I R^T."""
    rotation, position = placement[:3, :3], placement[:3, 3]
    return rotation @ np.asarray(com, float) + position, rotation @ inertia @ rotation.T
