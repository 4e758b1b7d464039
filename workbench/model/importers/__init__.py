"""Robots from files: URDF (through yourdfpy) and MJCF (through MuJoCo's compiler) to a
formalism-neutral :class:`~workbench.model.Model`.

:func:`load_robot` picks the reader by the file's suffix; each reader returns an
:class:`~workbench.model.importers.common.ImportedRobot` (the model plus what the file
says that the model does not hold: joint limits, meshes, a keyframe). Anything the model
cannot represent is a :class:`~workbench.errors.ModelError` naming the element, never
dropped.
"""

from __future__ import annotations

import os
from pathlib import Path

from workbench.errors import ModelError
from workbench.model.importers.common import ImportedRobot, MeshVisual

ROBOT_SUFFIXES = {".urdf": "urdf", ".xml": "mjcf", ".mjcf": "mjcf"}


def robot_format(path: str | os.PathLike[str]) -> str | None:
    """ "urdf" or "mjcf" for a path with a robot file's suffix, else None."""
    return ROBOT_SUFFIXES.get(Path(path).suffix.lower())


def load_robot(path: str | os.PathLike[str], **options: object) -> ImportedRobot:
    """Read a URDF or MJCF file (by suffix); ``options`` go to the reader."""
    kind = robot_format(path)
    if kind == "urdf":
        from workbench.model.importers.urdf import load_urdf

        return load_urdf(path, **options)  # type: ignore[arg-type]
    if kind == "mjcf":
        from workbench.model.importers.mjcf import load_mjcf

        return load_mjcf(path, **options)  # type: ignore[arg-type]
    raise ModelError(f"{path}: not a robot file; give a .urdf file or an MJCF .xml file")


__all__ = ["ROBOT_SUFFIXES", "ImportedRobot", "MeshVisual", "load_robot", "robot_format"]
