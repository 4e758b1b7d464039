"""Topology and degrees of freedom of a model (book 9.2, 9.3, 11.1).

:func:`analyze` validates the model and returns a :class:`Topology`: the spanning tree
(tree joints, parent of every body, bodies parents-first), the cut (loop-closing) joints
and one independent loop per cut joint, the Gruebler-Kutzbach count of degrees of
freedom, and the true count from the rank of the velocity constraint matrix W(t, q)
(book 9.3.2): f = nv - rank W. Rows of W that depend linearly on earlier rows are
reported as redundant (an overconstrained mechanism, such as a spatial four-link loop with
parallel axes, has Gruebler count -2 but one degree of freedom), by
:func:`workbench.numerics.linalg.independent_rows`, the test every formalism uses, so
``describe`` and a formalism name the same rows, at the configurations every formalism
uses (:func:`rank_configurations`: the model's initial configuration, assembled, then a
few random assembled ones; the highest rank wins).

Counting (planar models: 3 instead of 6):

- a free tree joint contributes its number of velocities, a driven one none;
- a cut joint removes 6 - (its number of velocities) rows (a driven cut joint is held
  fixed relative to its driven pose and removes 6);
- a rolling sphere or disk removes one holonomic row (its contact height);
- nonholonomic rows (rolling sphere 2, rolling disk 2 (planar model 1), knife edge 1)
  restrict velocities, not positions: they are counted in ``n_nonholonomic`` and in the
  rank-based ``dof`` (which counts independent velocities), not in ``dof_gruebler``.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from workbench.errors import ModelError
from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import (
    JointLayout,
    TreeKinematics,
    initial_joint_values,
    normalize_quaternions,
    tree_order,
)
from workbench.model import GROUND, Joint, KnifeEdge, Model, RollingDisk, RollingSphere
from workbench.model.validation import validate_model
from workbench.numerics.linalg import (
    RANK_TOLERANCE,
    GaussNewtonResult,
    gauss_newton,
    independent_rows,
)


@dataclass
class Topology:
    """The structure and degrees of freedom of a model (see the module docstring).

    ``loops[i]`` belongs to ``cut_joints[i]``: the cut joint, then the tree joints from
    its parent body up to the common ancestor, then down to its child body.
    ``dof``, ``rank`` and the redundancy fields are None when the rank was not computed
    (``analyze(model, rank=False)``). ``configuration`` is the tree-joint coordinate
    vector (``TreeKinematics.q`` order) at which W was evaluated, ``assembled`` whether
    the closure constraints hold there (to 1e-9).
    """

    tree_joints: list[str]
    cut_joints: list[str]
    loops: list[list[str]]
    n_loops: int
    parent_of: dict[str, str]
    parent_joint: dict[str, str]
    depth: dict[str, int]
    body_order: list[str]
    dof_gruebler: int
    n_holonomic: int
    n_nonholonomic: int
    dof: int | None = None
    rank: int | None = None
    constraint_names: list[str] = field(default_factory=list)
    redundant_constraints: list[str] = field(default_factory=list)
    redundant_elements: list[str] = field(default_factory=list)
    configuration: np.ndarray | None = None
    assembled: bool | None = None

    @property
    def overconstrained(self) -> bool:
        """True when some constraint rows are redundant."""
        return bool(self.redundant_constraints)

    def describe(self) -> str:
        """A few human-readable lines (for the CLI and logs)."""
        lines = [
            f"{len(self.body_order)} bodies, {len(self.tree_joints)} tree joints, "
            f"{self.n_loops} loops, {self.n_nonholonomic} nonholonomic rows",
            f"DOF (Gruebler count): {self.dof_gruebler}",
        ]
        if self.dof is not None:
            lines.append(f"DOF (rank of the constraint Jacobian): {self.dof}")
        for loop in self.loops:
            lines.append(f"loop: {' - '.join(loop)}")
        if self.redundant_constraints:
            lines.append(
                f"redundant constraint rows: {', '.join(self.redundant_constraints)} "
                f"(of {', '.join(self.redundant_elements)})"
            )
        return "\n".join(lines)


def analyze(
    model: Model,
    q: np.ndarray | None = None,
    t: float = 0.0,
    rank: bool = True,
    tolerance: float = RANK_TOLERANCE,
) -> Topology:
    """Validate ``model`` and return its :class:`Topology`.

    q: free tree-joint coordinates (``TreeKinematics(model).q_names`` order, nq) at which
    the constraint Jacobian is evaluated; default: the model's ``initial_configuration``
    (the problem's initial joint coordinates; neutral where not given). Either is first
    moved onto the closure constraints g(t, q) = 0 by Gauss-Newton steps when that
    converges, so the rank is that of the assembled mechanism, and confirmed at a few
    random assembled configurations (:func:`rank_configurations`, the configurations
    every formalism uses). t: time (s) for driven joints. rank=False skips the symbolic
    kinematics (dof stays None).
    """
    validate_model(model)
    tree = tree_order(model)
    parent_of = {j.child: j.parent for j in tree}
    parent_joint = {j.child: j.name for j in tree}
    depth: dict[str, int] = {}
    for joint in tree:
        depth[joint.child] = 1 + depth.get(joint.parent, 0) if joint.parent != GROUND else 1
    body_order = [j.child for j in tree]
    loops = [_loop(joint, parent_of, parent_joint) for joint in model.cut_joints]
    n_holonomic_contacts = sum(
        isinstance(c, RollingSphere | RollingDisk) for c in model.nonholonomic
    )
    topology = Topology(
        tree_joints=[j.name for j in model.tree_joints],
        cut_joints=[j.name for j in model.cut_joints],
        loops=loops,
        n_loops=len(loops),
        parent_of=parent_of,
        parent_joint=parent_joint,
        depth=depth,
        body_order=body_order,
        dof_gruebler=_gruebler(model) - n_holonomic_contacts,
        n_holonomic=sum(_cut_rows(model, j) for j in model.cut_joints) + n_holonomic_contacts,
        n_nonholonomic=sum(_nonholonomic_rows(model, c) for c in model.nonholonomic),
    )
    if rank:
        _rank(model, topology, q, t, tolerance)
    return topology


def _loop(cut: Joint, parent_of: dict[str, str], parent_joint: dict[str, str]) -> list[str]:
    """The cut joint, then the tree path from its parent body to its child body."""

    def to_root(body: str) -> list[str]:
        path = [body]
        while body != GROUND:
            body = parent_of[body]
            path.append(body)
        return path

    up, down = to_root(cut.parent), to_root(cut.child)
    common = next(body for body in up if body in down)
    up_joints = [parent_joint[b] for b in up[: up.index(common)]]
    down_joints = [parent_joint[b] for b in down[: down.index(common)]]
    return [cut.name, *up_joints, *reversed(down_joints)]


def _joint_dof(joint: Joint) -> int:
    return 0 if joint.drive is not None else jk.DIMENSIONS[joint.type][1]


def _cut_rows(model: Model, joint: Joint) -> int:
    return (3 if model.kind == "planar" else 6) - _joint_dof(joint)


def _gruebler(model: Model) -> int:
    free = sum(_joint_dof(j) for j in model.tree_joints)
    return free - sum(_cut_rows(model, j) for j in model.cut_joints)


def _nonholonomic_rows(model: Model, constraint: object) -> int:
    if isinstance(constraint, KnifeEdge):
        return 1
    if isinstance(constraint, RollingDisk) and model.kind == "planar":
        return 1
    return 2


def _element_of(row_name: str) -> str:
    """The joint or constraint a row belongs to: "loop[2]" -> "loop", "roll.height" -> "roll"."""
    return re.sub(r"(\[\d+\]|\.height)$", "", row_name)


RANK_SAMPLES = 3
"""Random assembled configurations that confirm the rank found at the initial one."""

RANK_PERTURBATION = 0.1
"""Standard deviation of the random steps (rad or m) from the initial configuration to
those confirming configurations, before they are assembled."""


@dataclass
class RankConfiguration:
    """A tree configuration q (nq) where a rank is evaluated, ``assembled`` whether the
    closure constraints hold there (to 1e-9)."""

    q: np.ndarray
    assembled: bool


def reference_configuration(
    model: Model, kinematics: TreeKinematics | JointLayout
) -> np.ndarray:
    """The model's ``initial_configuration`` as tree coordinates (nq), neutral where a
    joint is not given, unit quaternions."""
    q = initial_joint_values(model, kinematics, model.initial_configuration, velocities=False)
    normalize_quaternions(kinematics, q)
    return q


def rank_configurations(
    model: Model,
    kinematics: TreeKinematics | None = None,
    q: np.ndarray | None = None,
    t: float = 0.0,
    samples: int = RANK_SAMPLES,
) -> list[RankConfiguration]:
    """Where the rank of a constraint Jacobian is decided, first the one that decides.

    First q (tree coordinates, nq), by default the model's initial configuration
    (:func:`reference_configuration`), assembled onto the closure constraints when that
    converges (else as it is); then up to ``samples`` random admissible configurations:
    seeded random steps from it, assembled (those that do not assemble are left out).
    The rank can only drop at a singular configuration, so the highest rank among them
    is the mechanism's (:func:`independent_rows_at`): an initial configuration that
    happens to be singular is outvoted, a regular one decides.
    """
    kinematics = kinematics or TreeKinematics(model)
    if q is None:
        q0 = reference_configuration(model, kinematics)
    else:
        q0 = np.asarray(q, dtype=float).reshape(-1)
        if q0.shape != (kinematics.nq,):
            raise ModelError(
                f"model {model.name!r}: got {q0.size} coordinates, the tree has "
                f"{kinematics.nq} ({', '.join(kinematics.q_names)})"
            )
    assembly = assemble(kinematics, q0, t)
    first = assembly.x if assembly.converged else q0
    configurations = [RankConfiguration(first, assembly.converged)]
    rng = np.random.default_rng(0)
    for _ in range(samples):
        trial = first + RANK_PERTURBATION * rng.standard_normal(first.size)
        assembly = assemble(kinematics, trial, t)
        if assembly.converged:
            configurations.append(RankConfiguration(assembly.x, True))
    return configurations


def independent_rows_at(
    matrix_at: Callable[[np.ndarray], np.ndarray],
    configurations: list[RankConfiguration],
    tolerance: float = RANK_TOLERANCE,
) -> tuple[list[int], RankConfiguration | None]:
    """Independent rows (:func:`independent_rows`) of ``matrix_at(q)``, a constraint
    Jacobian at tree configuration q, at the first of ``configurations`` where it has its
    highest rank, and that configuration; ([], None) when it is nowhere finite."""
    best: tuple[list[int], RankConfiguration] | None = None
    for configuration in configurations:
        matrix = np.asarray(matrix_at(configuration.q), dtype=float)
        if not np.all(np.isfinite(matrix)):
            continue  # a rolling disk lying flat has no contact point
        rows = independent_rows(matrix, tolerance)
        if best is None or len(rows) > len(best[0]):
            best = (rows, configuration)
    return best if best is not None else ([], None)


def _rank(
    model: Model, topology: Topology, q: np.ndarray | None, t: float, tolerance: float
) -> None:
    if q is None and not model.cut_joints and not model.nonholonomic:
        # a tree without constraint rows: W is empty (rank 0) wherever it is taken, so
        # no symbolic kinematics is needed (they cost minutes on a 10,000-link chain)
        topology.rank, topology.dof = 0, topology.dof_gruebler
        topology.constraint_names, topology.redundant_constraints = [], []
        topology.redundant_elements = []
        topology.configuration = reference_configuration(model, JointLayout(model))
        topology.assembled = True
        return
    kinematics = TreeKinematics(model)
    w_function = kinematics.function("W", [kinematics.velocity_constraint_matrix], with_v=False)

    def w_at(q_at: np.ndarray) -> np.ndarray:
        return np.asarray(w_function(t, q_at), dtype=float).reshape(-1, kinematics.nv)

    configurations = rank_configurations(model, kinematics, q, t)
    independent, decided = independent_rows_at(w_at, configurations, tolerance)
    if decided is None:
        raise ModelError(
            f"model {model.name!r}: the constraint Jacobian is not finite near the given "
            "configuration; pass a configuration where every contact is defined"
        )
    names = list(kinematics.velocity_constraint_names)
    redundant = [names[i] for i in range(len(names)) if i not in independent]
    topology.rank = len(independent)
    topology.dof = kinematics.nv - topology.rank
    topology.constraint_names = names
    topology.redundant_constraints = redundant
    topology.redundant_elements = list(dict.fromkeys(_element_of(n) for n in redundant))
    topology.configuration = decided.q
    topology.assembled = decided.assembled


def assemble(kinematics: TreeKinematics, q0: np.ndarray, t: float = 0.0) -> GaussNewtonResult:
    """Move tree coordinates q0 (nq) onto the closure constraints g(t, q) = 0.

    Minimum-norm Gauss-Newton steps in the velocities (:func:`gauss_newton` on the
    holonomic rows of W), mapped through q' = H(q) v with unit quaternions renormalized,
    so the result is a valid configuration. A model without closure constraints is
    assembled as it is (quaternions normalized). ``converged`` False when the residual
    stays above 1e-9 or is not finite (a rolling disk lying flat has no contact point).
    """
    n_h = kinematics.n_holonomic
    residual = kinematics.function(
        "closure",
        [kinematics.closure_constraints, kinematics.velocity_constraint_matrix[:n_h, :]],
        with_v=False,
    )
    # q' = H(q) v
    rate_matrix = kinematics.function(
        "H", [ca.jacobian(kinematics.qdot, kinematics.v)], with_v=False
    )

    def evaluate(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, w_h = (np.asarray(x, dtype=float) for x in residual(t, q))
        return g.reshape(-1), w_h.reshape(n_h, kinematics.nv)

    def update(q: np.ndarray, step: np.ndarray) -> np.ndarray:
        h = np.asarray(rate_matrix(t, q), dtype=float).reshape(kinematics.nq, kinematics.nv)
        q = q + h @ step
        normalize_quaternions(kinematics, q)
        return q

    q = np.array(q0, dtype=float)
    normalize_quaternions(kinematics, q)
    return gauss_newton(evaluate, q, update)
