"""The command-line options that say where a robot file may read (docs/robots.md, "What a
robot file may read"): shared by ``workbench run`` and ``workbench describe``."""

from __future__ import annotations

import typer

PACKAGE_PATH_OPTION = typer.Option(
    "--package-path",
    help="A folder holding ROS packages that package:// mesh names refer to (repeatable; "
    "searched before ROS_PACKAGE_PATH).",
)
ALLOW_ROOT_OPTION = typer.Option(
    "--allow-root",
    help="A folder outside the robot file's own that its meshes and includes may read "
    "(repeatable; only for files you trust).",
)

__all__ = ["ALLOW_ROOT_OPTION", "PACKAGE_PATH_OPTION"]
