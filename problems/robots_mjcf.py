"""Robots family, MJCF: a closed chain read from MJCF through MuJoCo's compiler.

``rssr-linkage`` — the spatial RSSR linkage of ``robot_files/rssr_linkage.xml`` (shipped
with the catalog): a crank (aluminium rod, 0.1 m) turning about z at the origin, a coupler
(0.38 m, with a 0.1 m square plate across its middle) on a ball joint at the crank's tip,
and a rocker (0.15 m) turning about x at (0.3, 0.2, 0.1) m; the MJCF <connect> equality
closing the loop becomes a spherical loop-closing joint.
5 joint coordinates - 3 closure rows = 2 DOF. Gravity (0, 0, -9.81) m/s^2. Initial state:
the file's keyframe (the assembled rest pose; crank 3 rad/s, rocker -2 rad/s, the
coupler's angular velocity normal to its axis); t_end = 1 s. Energy is conserved.
"""

from __future__ import annotations

from importlib import resources
from typing import Any

import workbench.plugin.registry
from workbench.model import Model
from workbench.model.importers.mjcf import load_mjcf
from workbench.plugin.problem import Problem


def linkage_file() -> str:
    return str(resources.files("workbench.problems").joinpath("robot_files/rssr_linkage.xml"))


@workbench.plugin.registry.problem
class RSSRLinkage(Problem):
    name = "rssr-linkage"
    summary = "Spatial RSSR linkage from MJCF (ball joint, <connect> closing the loop)"
    source = "robots family (docs/robots.md); MJCF robot_files/rssr_linkage.xml"
    t_end = 1.0
    n_samples = 51
    independent_coordinates = (("crank_joint", 0),)

    def _imported(self) -> Any:
        return load_mjcf(linkage_file())

    def model(self) -> Model:
        model = self._imported().model
        model.name = self.name
        return model

    def initial_joint_coordinates(self) -> dict[str, Any]:
        return dict(self._imported().initial_coordinates)

    def initial_joint_velocities(self) -> dict[str, Any]:
        return dict(self._imported().initial_velocities)
