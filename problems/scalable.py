"""Scalable families (book 10.5, 10.6): chains and trees of any size, for cost-vs-size plots.

All links are pendulums under gravity with revolute joints, moving freely from an initial
pose; energy is conserved. None has an analytic reference. Keep sizes small for tests;
the recursive O(n) formalism should overtake the O(n^3) one as they grow.

``planar-chain`` — planar; gravity (0, -9.81, 0) m/s^2. Option ``n_links`` (default 5):
identical uniform bars of length 1/n_links m and mass 1/n_links kg (the whole chain is a
1 m, 1 kg rope of bars; Izz = m L^2 / 12), each body frame at its upper joint, the bar
along body -y; revolute ``joint1`` from the ground at the origin, ``joint{i}`` at the end
of link i-1. n_links DOF. Initial state: joint1 at 1.0 rad, the others at 0.2 (-1)^i
rad; at rest. t_end = 2 s.

``spatial-chain`` — spatial; z up; gravity (0, 0, -9.81) m/s^2. Option ``n_links``
(default 5). Link i (solid rod of radius 0.02 m, mass 0.5 kg) runs from its joint to
(0.05, 0.03, -0.3) m in its body frame (skewed, so its inertia tensor about the centre of
mass is full), its centre of mass moved off the rod by (0.01, -0.02, 0) m; joint i sits
at the end of link i-1 (the origin for i = 1), with axes cycling z, y, x. n_links DOF.
Initial state: all angles 0.4 rad; joint1 at 2 rad/s, the rest at rest. t_end = 2 s.
Invariant: the angular momentum about the vertical through the origin
(``vertical_angular_momentum``, kg m^2/s; joint1 turns about that axis).

``binary-tree`` — spatial; gravity (0, 0, -9.81) m/s^2. Option ``depth`` (default 3):
2^depth - 1 bodies. The root ``b1`` hangs from the origin by a revolute about z; body
bk has the children b(2k) and b(2k+1) at its tip, on revolutes about its body x and y
axes respectively. A body at level l (root: l = 0) is a solid rod of radius 0.02 m,
length 0.4 (0.7^l) m and mass 1.0 (0.5^l) kg from its frame's origin to
(0.25 s, 0, -1) times its length, with s = 1 for the root and first children, -1 for
second children (the branches splay). 2^depth - 1 DOF. Initial state: every angle
0.3 (-1)^k rad (k the body number), the root at 1 rad/s. t_end = 2 s. Invariant:
``vertical_angular_momentum`` as above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import workbench.plugin.registry
from workbench.errors import ConfigError
from workbench.model import Frame, Model, Shape
from workbench.plugin.problem import Invariant, Problem
from workbench.problems._parts import angular_momentum, planar_rod
from workbench.problems.ch10_open_trees import add_link

GRAVITY = 9.81  # m/s^2


def vertical_angular_momentum(
    model: Model, t: float, poses: np.ndarray, twists: np.ndarray
) -> np.ndarray:
    """Angular momentum (kg m^2/s) about the vertical axis through the origin (vectorized)."""
    return angular_momentum(model, poses, twists)[..., 2]


@dataclass(frozen=True)
class ChainOptions:
    n_links: int = 5

    def __post_init__(self) -> None:
        if self.n_links < 1:
            raise ConfigError(f"n_links must be >= 1, not {self.n_links}")


@dataclass(frozen=True)
class TreeOptions:
    depth: int = 3

    def __post_init__(self) -> None:
        if self.depth < 1:
            raise ConfigError(f"depth must be >= 1, not {self.depth}")


@workbench.plugin.registry.problem
class PlanarChain(Problem):
    name = "planar-chain"
    summary = "Planar chain of n uniform bars (n-link pendulum), option n_links"
    source = "book 10.5, 10.6 (scalable)"
    Options = ChainOptions
    t_end = 2.0
    n_samples = 201
    conservative = True

    def model(self) -> Model:
        n = self.options.n_links
        length, mass = 1.0 / n, 1.0 / n
        model = Model(f"{self.name}-{n}", kind="planar", gravity=(0.0, -GRAVITY, 0.0))
        parent, at = "ground", Frame()
        for i in range(1, n + 1):
            com, izz = planar_rod(mass, (0, 0, 0), (0, -length, 0))
            model.add_body(
                f"link{i}",
                mass,
                com=com,
                inertia=izz,
                shapes=[Shape("box", (0.02, length, 0.02), Frame.at(0, -length / 2, 0))],
            )
            model.add_joint(f"joint{i}", "revolute", parent, f"link{i}", parent_frame=at)
            parent, at = f"link{i}", Frame.at(0, -length, 0)
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        angles = {"joint1": 1.0}
        angles.update({f"joint{i}": 0.2 * (-1) ** i for i in range(2, self.options.n_links + 1)})
        return angles


SPATIAL_LINK = np.array([0.05, 0.03, -0.3])  # m, rod end in the body frame
SPATIAL_COM_OFFSET = np.array([0.01, -0.02, 0.0])  # m
SPATIAL_MASS = 0.5  # kg
ROD_RADIUS = 0.02  # m
AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0))  # z, y, x


@workbench.plugin.registry.problem
class SpatialChain(Problem):
    name = "spatial-chain"
    summary = "Spatial chain of n skewed rods, axes cycling z y x, option n_links"
    source = "book 10.5, 10.6 (scalable)"
    Options = ChainOptions
    t_end = 2.0
    n_samples = 201
    conservative = True

    def model(self) -> Model:
        n = self.options.n_links
        model = Model(f"{self.name}-{n}", kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        parent, at = "ground", np.zeros(3)
        for i in range(1, n + 1):
            add_link(model, f"link{i}", SPATIAL_MASS, SPATIAL_LINK, ROD_RADIUS, SPATIAL_COM_OFFSET)
            model.add_joint(
                f"joint{i}",
                "revolute",
                parent,
                f"link{i}",
                parent_frame=Frame(at),
                axis=AXES[(i - 1) % 3],
            )
            parent, at = f"link{i}", SPATIAL_LINK
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {f"joint{i}": 0.4 for i in range(1, self.options.n_links + 1)}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"joint1": 2.0}

    def invariants(self) -> list[Invariant]:
        return [Invariant("vertical_angular_momentum", vertical_angular_momentum, vectorized=True)]


TREE_LENGTH = 0.4  # m, root
TREE_MASS = 1.0  # kg, root
TREE_LENGTH_RATIO = 0.7
TREE_MASS_RATIO = 0.5


def tree_link_end(k: int, level: int) -> np.ndarray:
    """Rod end (3,) of body bk at ``level`` in its body frame (m)."""
    splay = -1.0 if k > 1 and k % 2 == 1 else 1.0
    return TREE_LENGTH * TREE_LENGTH_RATIO**level * np.array([0.25 * splay, 0.0, -1.0])


@workbench.plugin.registry.problem
class BinaryTree(Problem):
    name = "binary-tree"
    summary = "Spatial binary tree of 2^depth - 1 rods on revolute joints, option depth"
    source = "book 10.2.4, 10.6.2 (scalable)"
    Options = TreeOptions
    t_end = 2.0
    n_samples = 201
    conservative = True

    @property
    def n_bodies(self) -> int:
        return 2**self.options.depth - 1

    def model(self) -> Model:
        model = Model(
            f"{self.name}-{self.options.depth}", kind="spatial", gravity=(0.0, 0.0, -GRAVITY)
        )
        for k in range(1, self.n_bodies + 1):
            level = k.bit_length() - 1
            end = tree_link_end(k, level)
            add_link(model, f"b{k}", TREE_MASS * TREE_MASS_RATIO**level, end, ROD_RADIUS)
            if k == 1:
                parent, at, axis = "ground", np.zeros(3), AXES[0]
            else:
                parent = f"b{k // 2}"
                at = tree_link_end(k // 2, level - 1)
                axis = AXES[2] if k % 2 == 0 else AXES[1]
            model.add_joint(f"j{k}", "revolute", parent, f"b{k}", parent_frame=Frame(at), axis=axis)
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {f"j{k}": 0.3 * (-1) ** k for k in range(1, self.n_bodies + 1)}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"j1": 1.0}

    def invariants(self) -> list[Invariant]:
        return [Invariant("vertical_angular_momentum", vertical_angular_momentum, vectorized=True)]
