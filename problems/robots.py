"""Robots family: real robots imported from the URDF files of example-robot-data
(https://github.com/Gepetto/example-robot-data, installed by ``pip install
'mbs-workbench[robots]'``; nothing is downloaded at run time). Without that package the two
problems are still registered, so a sweep plans the same runs on every install; their
availability check (:meth:`_UrdfRobot.unavailable`) makes each run a ``skipped`` row naming
the install command.

``ur5`` — Universal Robots UR5 (``ur_description/urdf/ur5_robot.urdf``): 6 revolute
joints, base fixed to the ground, its fixed links (ee_link, tool0) welded into wrist_3_link.
Gravity (0, 0, -9.81) m/s^2. Unforced from shoulder_lift -1.2 rad, elbow 1.0 rad,
wrist_1 -0.6 rad, shoulder_pan at 1 rad/s; t_end = 1 s. 6 DOF.

``solo12`` — the Solo-12 quadruped (``solo_description/robots/solo12.urdf``) with a free
base (Pinocchio's free-flyer root): 12 revolute leg joints + 6 base DOF, falling freely
under gravity (no ground contact) from the base at 0.3 m, legs bent (hip flexion 0.8 rad,
knee -1.6 rad), the base turning at (0.5, -0.3, 1.0) rad/s; t_end = 0.5 s. 18 DOF.

Both conserve energy (no joint friction or damping is modelled: the URDFs' <dynamics> are
listed as notes). The import and the dynamics are cross-checked against Pinocchio in
tests/test_urdf_peers.py (docs/robots.md).
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

import workbench.plugin.registry
from workbench.errors import ModelError
from workbench.model import Model
from workbench.model.importers.urdf import load_urdf
from workbench.plugin.problem import Problem

INSTALL = 'pip install "mbs-workbench[robots]"'

try:
    _ROBOTS: Path | None = Path(
        metadata.distribution("example-robot-data").locate_file(
            "cmeel.prefix/share/example-robot-data/robots"
        )
    )
except metadata.PackageNotFoundError:
    _ROBOTS = None  # the problems say so when run (unavailable), not at import


PACKAGE_ROOT = _ROBOTS.parents[1]
"""The folder holding the package ``example-robot-data`` that its URDFs' meshes name
(``package://example-robot-data/robots/...``): a package root the catalog names."""


def example_robot_file(relative: str) -> Path:
    """A URDF shipped by example-robot-data, found through the installed distribution."""
    if _ROBOTS is None:
        raise ModelError(f"example-robot-data is not installed: {INSTALL}")
    return _ROBOTS / relative


class _UrdfRobot(Problem):
    file: ClassVar[str] = ""
    import_options: ClassVar[dict[str, Any]] = {}
    n_samples = 51

    def unavailable(self) -> str | None:
        if _ROBOTS is None:
            return f"needs example-robot-data, which is not installed: {INSTALL}"
        if not example_robot_file(self.file).is_file():
            return f"example-robot-data has no {self.file}: reinstall it with {INSTALL}"
        return None

    def model(self) -> Model:
        model = load_urdf(
            example_robot_file(self.file), package_path=[PACKAGE_ROOT], **self.import_options
        ).model
        model.name = self.name
        return model


@workbench.plugin.registry.problem
class UR5(_UrdfRobot):
    name = "ur5"
    summary = "UR5 arm from example-robot-data's URDF (6 revolute joints), unforced"
    source = "example-robot-data ur5_robot.urdf; robots family (docs/robots.md)"
    file = "ur_description/urdf/ur5_robot.urdf"
    t_end = 1.0

    def initial_joint_coordinates(self) -> dict[str, Any]:
        return {"shoulder_lift_joint": -1.2, "elbow_joint": 1.0, "wrist_1_joint": -0.6}

    def initial_joint_velocities(self) -> dict[str, Any]:
        return {"shoulder_pan_joint": 1.0}


@workbench.plugin.registry.problem
class Solo12(_UrdfRobot):
    name = "solo12"
    summary = "Solo-12 quadruped from example-robot-data's URDF with a free base, falling freely"
    source = "example-robot-data solo12.urdf; robots family (docs/robots.md)"
    file = "solo_description/robots/solo12.urdf"
    import_options = {"floating_base": True}
    t_end = 0.5

    def initial_joint_coordinates(self) -> dict[str, Any]:
        legs = {}
        for leg in ("FL", "FR", "HL", "HR"):
            legs[f"{leg}_HFE"] = 0.8 if leg.startswith("F") else -0.8
            legs[f"{leg}_KFE"] = -1.6 if leg.startswith("F") else 1.6
        return {"root_joint": [0.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0], **legs}

    def initial_joint_velocities(self) -> dict[str, Any]:
        return {"root_joint": [0.0, 0.0, 0.0, 0.5, -0.3, 1.0], "FL_HAA": 1.0}
