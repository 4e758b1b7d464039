"""The three mechanisms of the whole-simulation benchmark, each with its peers.

* ``chain``: the ``spatial-chain`` problem, 7 links (axes z, y, x, ...), from its initial
  state over 2 s (over 5 s, as measured before, the chain's chaos makes the end error
  0.05 at rtol 1e-8 and not monotonic in the tolerance, so "the same accuracy" meant
  little);
* ``tree``: a random tree of 30 bodies on revolute joints (:func:`random_revolute_tree`:
  random parents, rotated joint frames, unaligned axes, full inertia tensors) from a random
  state over 2 s;
* ``ur5``: the ``ur5`` problem (example-robot-data's URDF through our importer) from its
  initial state over 1 s; its Pinocchio model is built from the same URDF
  (``pin.buildModelFromUrdf``), not from ours.

The MuJoCo models are :func:`benchmarks.peer_models.mujoco_model` of ours (hinges, explicit
inertials, contacts and constraints off; MJCF's armature, damping and frictionloss default
to zero and are left so). :func:`accelerations` gives ours, Pinocchio's and MuJoCo's q''
at a state (in our coordinates), checked equal by :func:`check_equal` before any timing.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from benchmarks.peer_models import mujoco_model, pinocchio_model
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import Frame, Model
from workbench.plugin.registry import get_problem

CASES = ("chain", "tree", "ur5")
TOLERANCE = 1e-9  # largest relative difference of the accelerations ours / peers


def random_revolute_tree(n: int = 30, seed: int = 0) -> Model:
    """n bodies on revolute joints: each hangs from a random earlier body (or the ground
    for the first) at a rotated frame, about a random axis; boxes' full inertia tensors
    rotated at random, centres of mass off the frame origin."""
    rng = np.random.default_rng(seed)
    model = Model(f"random-revolute-tree-{n}-{seed}", kind="spatial", gravity=(0.0, 0.0, -9.81))

    def frame() -> Frame:
        return Frame(rng.uniform(-0.3, 0.3, 3), Rotation.random(random_state=rng).as_matrix())

    for i in range(n):
        mass = rng.uniform(0.5, 2.0)
        a, b, c = rng.uniform(0.1, 0.6, 3)
        moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        rotation = Rotation.random(random_state=rng).as_matrix()
        model.add_body(
            f"b{i}",
            mass,
            com=rng.uniform(-0.2, 0.2, 3),
            inertia=rotation @ np.diag(moments) @ rotation.T,
        )
        parent = "ground" if i == 0 else f"b{rng.integers(i)}"
        model.add_joint(
            f"j{i}",
            "revolute",
            parent,
            f"b{i}",
            parent_frame=frame(),
            child_frame=frame(),
            axis=rng.standard_normal(3),
        )
    return model


@dataclass
class Case:
    """A mechanism, its span and peers, and its initial state y0 = [q, v] (ours): the
    problem's consistent initial state, or ``start`` where there is no problem.

    ``pin`` and ``mujoco`` are (model, order): order[i] is our velocity index of the peer's
    coordinate i (all joints are revolute, so q and v share it)."""

    name: str
    model: Model
    t_end: float
    pin: tuple[Any, np.ndarray]
    mujoco: tuple[Any, np.ndarray]
    problem: Any = None
    start: np.ndarray | None = None

    @functools.cached_property
    def y0(self) -> np.ndarray:
        return self.start if self.problem is None else _problem_y0(self.problem)


def _problem_y0(problem: Any) -> np.ndarray:
    from workbench.equations.initial import consistent_initial_state
    from workbench.plugin.registry import get_formalism

    equations = get_formalism("recursive")().build(problem.model(), {"compile": "none"})
    return consistent_initial_state(equations, problem).y0(equations, "ode")


def _urdf_pinocchio(model: Model, urdf: str) -> tuple[Any, np.ndarray]:
    import pinocchio as pin

    built = pin.buildModelFromUrdf(urdf)
    kinematics = TreeKinematics(model)
    if built.nv != kinematics.nv or built.nq != built.nv:
        raise ValueError(
            f"{urdf}: Pinocchio's model has nq={built.nq}, nv={built.nv}; ours nv={kinematics.nv}"
        )
    order = np.zeros(built.nv, dtype=int)
    for joint in kinematics.order:
        order[built.joints[built.getJointId(joint.name)].idx_v] = kinematics.joint_slices[
            joint.name
        ][1].start
    return built, order


@functools.cache
def case(name: str) -> Case:
    """The benchmark case ``name`` (one of CASES), its peers built."""
    if name == "chain":
        problem = get_problem("spatial-chain")({"n_links": 7})
        model = problem.model()
        return Case(name, model, 2.0, pinocchio_model(model), mujoco_model(model), problem)
    if name == "tree":
        model = random_revolute_tree(30, seed=0)
        rng = np.random.default_rng(1)
        start = np.concatenate([rng.uniform(-1.0, 1.0, 30), rng.uniform(-1.0, 1.0, 30)])
        return Case(name, model, 2.0, pinocchio_model(model), mujoco_model(model), start=start)
    if name == "ur5":
        from workbench.problems.robots import example_robot_file

        problem = get_problem("ur5")({})
        model = problem.model()
        urdf = str(example_robot_file(problem.file))
        return Case(name, model, 1.0, _urdf_pinocchio(model, urdf), mujoco_model(model), problem)
    raise ValueError(f"unknown case {name!r}: use one of {', '.join(CASES)}")


class Peers:
    """q''(q, v) of Pinocchio's ``aba`` and MuJoCo's ``mj_forward``, in our coordinates."""

    def __init__(self, case: Case) -> None:
        import mujoco
        import pinocchio as pin

        self._pin, self._mujoco = pin, mujoco
        self.pin_model, self.pin_order = case.pin
        self.pin_data, self.pin_back = self.pin_model.createData(), np.argsort(self.pin_order)
        self.mj_model, self.mj_order = case.mujoco
        self.mj_data, self.mj_back = mujoco.MjData(self.mj_model), np.argsort(self.mj_order)
        self.tau = np.zeros(self.pin_model.nv)
        # the peer's right-hand side as a user would write it: no reordering when the
        # coordinates are in the same order (chain, UR5), where it cost ~1 us a call
        self.pin_same_order = np.array_equal(self.pin_order, np.arange(self.pin_order.size))

    def aba(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        if self.pin_same_order:
            return self._pin.aba(self.pin_model, self.pin_data, q, v, self.tau)
        o = self.pin_order
        return self._pin.aba(self.pin_model, self.pin_data, q[o], v[o], self.tau)[self.pin_back]

    def forward(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        self.mj_data.qpos[:], self.mj_data.qvel[:] = q[self.mj_order], v[self.mj_order]
        self._mujoco.mj_forward(self.mj_model, self.mj_data)
        return self.mj_data.qacc[self.mj_back]


def check_equal(ours: Any, peers: Peers, n: int, states: int = 3, seed: int = 7) -> float:
    """Largest relative difference of q'' (peers against ``ours(q, v)``) at random states;
    raises AssertionError above TOLERANCE."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(states):
        q, v = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
        reference = ours(q, v)
        scale = max(1.0, float(np.abs(reference).max()))
        for label, value in (("pin.aba", peers.aba(q, v)), ("mj_forward", peers.forward(q, v))):
            difference = float(np.abs(value - reference).max()) / scale
            if not difference <= TOLERANCE:
                raise AssertionError(f"{label} differs from ours by {difference:.2e} (relative)")
            worst = max(worst, difference)
    return worst
