"""Formalism ``nonholonomic-projection``: minimal velocities and Jourdain's projection.

Book 8.1.3 (minimal velocities), 8.2.2 (equations of motion in minimal form) and 8.3.2
(the ball on a rotating plane). The tree joint velocities v (nv) obey the velocity
constraints W(t, q) v + w(t, q) = 0 (closure rows of the cut joints and contact heights,
then nonholonomic rows; :class:`~workbench.mechanics.kinematics.TreeKinematics`). They are written
with minimal velocities s (nv - rank W):

    v = F(t, q) s + f(t, q),    W F = 0,    W f + w = 0,

by partitioning: the independent velocities v_i = s are a selection, computed first
where ``workbench describe`` and every formalism decide the rank (the model's initial
configuration, assembled, confirmed at random assembled ones:
:func:`workbench.mechanics.topology.rank_configurations`): the independent rows of W as
everywhere in the workbench (:func:`workbench.numerics.linalg.independent_rows`), then the dependent
velocities by pivoted QR of those rows (option ``independent`` names the independent
velocities instead); the dependent ones follow from W_d v_d = -(W_i s + w):

    F = P^T [I; -W_d^-1 W_i],    f = P^T [0; -W_d^-1 w]    (symbolic W_d^-1).

Jourdain's principle projects the equations of motion with F^T:

    (F^T M F) s' = F^T (Q - h - M (F' s + f')),    q' = H(q) (F s + f),

computed body by body with each body's twist written in s (so the bias F' s + f' is the
time derivative of the twists at s' = 0). It is an ODE in y = (q, s): no multipliers and
no velocity constraints (they hold by construction, to round-off). Holonomic closure
constraints and contact heights are *not* enforced at position level: their drift is
measured by the observables.

Re-partitioning (Wehage and Haug): a partition holds only where W_d keeps its rank (a knife
edge whose heading turns through 90 degrees: its one dependent velocity has W_d =
cos(heading)). The equations offer every partition of the same rows of W as a chart of an
``Equations.atlas`` (:class:`PartitionAtlas`: the best chart at q by pivoted QR of W(q),
its conditioning sigma_min(W_d) / sigma_max(W), the state carried from chart to chart
through v = F s + f, each chart's equations compiled when first used); the run integrates
chart by chart and restarts on the best one where the current chart degrades
(:mod:`workbench.runs.charts`; the switches are in the row's ``notes``). Measured on the
knife-edge cart turning through 10 rad: 11.5 correct digits with DOP853 at rtol 1e-12 (one
partition: 8.7; minimal-ode with multipliers: 13, the reference's cap), 10.9 with CVODE
Adams (9.4; 11.2), at about 2.3 times the right-hand sides of one partition.
``repartition = false`` (or naming ``independent``) keeps one partition for the run: the
run's audit then reports the least sigma_min(W_d) / sigma_max(W) reached
(``Equations.partition_matrices``) and warns below
:data:`workbench.runs.audit.SINGULAR_RATIO` ("singular velocity partition").
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations import Equations, MechanicalSystem, build_equations
from workbench.equations.compiled import Compiler
from workbench.errors import ConfigError, ModelError
from workbench.mechanics.kinematics import BodyState, TreeKinematics, quaternion_slices
from workbench.mechanics.newton_euler import newton_euler_forces
from workbench.mechanics.topology import independent_rows_at, rank_configurations
from workbench.model import Model
from workbench.numerics.linalg import independent_columns
from workbench.plugin.formalism import CompileOptions, Formalism
from workbench.plugin.registry import formalism


@dataclass(frozen=True)
class ProjectionOptions(CompileOptions):
    """``independent``: names of tree-joint velocities (``TreeKinematics.v_names``) to keep
    as the minimal velocities s for the whole run; empty: chosen by pivoted QR, and with
    ``repartition`` (default) chosen again along the run where the partition degrades."""

    independent: tuple[str, ...] = ()
    repartition: bool = True

    def __post_init__(self) -> None:
        if isinstance(self.independent, str) or not all(
            isinstance(name, str) for name in self.independent
        ):
            raise ConfigError("independent must be a list of velocity names")
        object.__setattr__(self, "independent", tuple(self.independent))


@dataclass
class Partition:
    """The velocity partition: ``rows`` of W kept (independent rows), ``independent`` and
    ``dependent`` columns (indices into v), and the reference configuration used."""

    rows: np.ndarray
    independent: np.ndarray
    dependent: np.ndarray
    q_reference: np.ndarray


def velocity_partition(kinematics: TreeKinematics, independent: tuple[str, ...] = ()) -> Partition:
    """Choose independent rows of W and independent velocities (see the module doc)."""
    k = kinematics
    w_function = ca.Function("W", [k.t, k.q], [ca.densify(k.velocity_constraint_matrix)])

    def w_at(q: np.ndarray) -> np.ndarray:
        return np.asarray(w_function(0.0, q), dtype=float).reshape(-1, k.nv)

    # where describe and every formalism decide the rank: the model's initial configuration
    rows_list, decided = independent_rows_at(w_at, rank_configurations(k.model, k))
    if decided is None:
        raise ModelError(
            f"model {k.model.name!r}: the velocity constraint matrix is not finite at any "
            "reference configuration tried"
        )
    q_ref, w_matrix = decided.q, w_at(decided.q)
    rows = np.array(rows_list, dtype=int)
    rank = rows.size
    w_rows = w_matrix[rows]
    if independent:
        unknown = [name for name in independent if name not in k.v_names]
        if unknown:
            raise ConfigError(
                f"nonholonomic-projection: {unknown[0]!r} is not a tree-joint velocity; use "
                f"one of {', '.join(k.v_names)}"
            )
        chosen = np.array([k.v_names.index(name) for name in independent], dtype=int)
        dependent = np.array([c for c in range(k.nv) if c not in set(chosen)], dtype=int)
        if dependent.size != rank or independent_columns(w_rows[:, dependent]).size < rank:
            raise ConfigError(
                f"nonholonomic-projection: the independent velocities {list(independent)} "
                f"leave a singular dependent block; give {k.nv - rank} velocities whose "
                "complement the constraints determine"
            )
    else:
        dependent = np.sort(independent_columns(w_rows))
        chosen = np.array([c for c in range(k.nv) if c not in set(dependent)], dtype=int)
    return Partition(rows, np.sort(chosen), dependent, q_ref)


def minimal_velocity_map(
    kinematics: TreeKinematics, partition: Partition, s: Any
) -> tuple[Any, Any, Any]:
    """(F (nv, ns), f (nv), v = F s + f) as SX expressions in (t, q) and s."""
    k = kinematics
    n_s = partition.independent.size
    rows = [int(i) for i in partition.rows]
    w_matrix = k.velocity_constraint_matrix[rows, :]
    w_bias = k.velocity_constraint_bias[rows]
    F = ca.SX.zeros(k.nv, n_s)
    f = ca.SX.zeros(k.nv)
    for column, index in enumerate(partition.independent):
        F[int(index), column] = 1.0
    if partition.dependent.size:
        dependent = [int(i) for i in partition.dependent]
        independent = [int(i) for i in partition.independent]
        solution = ca.solve(w_matrix[:, dependent], ca.horzcat(w_matrix[:, independent], w_bias))
        F[dependent, :] = -solution[:, :n_s]
        f[dependent] = -solution[:, n_s]
    return F, f, ca.mtimes(F, s) + f


def projected_system(
    model: Model, kinematics: TreeKinematics, partition: Partition
) -> tuple[MechanicalSystem, dict[str, BodyState], dict[str, Any]]:
    """The projected equations, the bodies' states in (t, q, s) and the joint coordinates."""
    k = kinematics
    names = [k.v_names[int(i)] for i in partition.independent]
    s = ca.SX.sym("s", len(names))
    _, _, v_of_s = minimal_velocity_map(k, partition, s)
    body_names = list(model.bodies)
    joints = model.tree_joints
    twists = [x for b in body_names for x in (k.bodies[b].velocity, k.bodies[b].angular_velocity)]
    joint_velocities = [k.joint_coordinates(j)[1] for j in joints]
    joint_velocities = [ca.SX(x) if not isinstance(x, ca.SX) else x for x in joint_velocities]
    substituted = ca.substitute([k.qdot, *twists, *joint_velocities], [k.v], [v_of_s])
    qdot, twists, joint_velocities = (
        substituted[0],
        substituted[1 : 1 + len(twists)],
        substituted[1 + len(twists) :],
    )
    bodies = {
        b: BodyState(k.bodies[b].position, k.bodies[b].rotation, twists[2 * i], twists[2 * i + 1])
        for i, b in enumerate(body_names)
    }
    joint_coordinates = {
        j.name: (k.joint_coordinates(j)[0], joint_velocities[i]) for i, j in enumerate(joints)
    }
    mass, forces = newton_euler_forces(model, bodies, joint_coordinates, k.t, k.q, s, qdot)
    system = MechanicalSystem(
        t=k.t,
        q=k.q,
        v=s,
        qdot=qdot,
        mass=mass,
        forces=forces,
        q_names=k.q_names,
        v_names=names,
    )
    return system, bodies, joint_coordinates


@formalism
class NonholonomicProjection(Formalism):
    name = "nonholonomic-projection"
    summary = "Minimal velocities v = F s + f, Jourdain projection F^T, an ODE in (q, s) (8.2.2)"
    Options = ProjectionOptions
    capabilities = frozenset(
        {"planar", "spatial", "nonholonomic", "closed-loops", "point-masses", "rheonomic"}
    )

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        cls.parse_options(options)
        return {"ode": 0, "dae": 0, "mechanical": 0}

    def build(self, model: Model, options: Any = None) -> Equations:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        kinematics = TreeKinematics(model)
        partition = velocity_partition(kinematics, options.independent)
        equations = self.equations_for(model, options, kinematics, partition)
        if partition.dependent.size and options.repartition and not options.independent:
            equations.atlas = PartitionAtlas(self, model, options, kinematics, partition,
                                             equations)  # fmt: skip
        return equations

    def equations_for(self, model: Model, options: Any, kinematics: TreeKinematics,
                      partition: Partition) -> Equations:  # fmt: skip
        """The projected equations with one velocity partition (one chart)."""
        system, bodies, joint_coordinates = projected_system(model, kinematics, partition)
        independent = [int(i) for i in partition.independent]
        notes = [
            "minimal velocities: " + (", ".join(system.v_names) or "none"),
            "holonomic constraints are not enforced at position level; see their drift",
        ]
        if partition.dependent.size:
            dependent = ", ".join(kinematics.v_names[int(i)] for i in partition.dependent)
            if options.repartition and not options.independent:
                notes.append(
                    f"velocity partition: dependent velocities {dependent} at the start, "
                    "solved from their block W_d of W; the run changes partition where W_d "
                    "degrades (see the message for the partitions used)"
                )
            else:
                notes.append(
                    f"fixed velocity partition: dependent velocities {dependent}, solved "
                    "from their block W_d of W for the whole run; where W_d turns singular "
                    "along the motion (a knife edge turned 90 degrees) digits are lost and "
                    "the run warns"
                )
        equations = build_equations(
            self.name,
            model,
            system,
            bodies,
            ([kinematics.t, kinematics.q, kinematics.v], [kinematics.q, kinematics.v[independent]]),
            ode=True,
            joint_coordinates={name: qv[0] for name, qv in joint_coordinates.items()},
            notes=notes,
            compiler=Compiler.from_options(options),
            quaternion_slices=quaternion_slices(kinematics),
        )
        if partition.dependent.size:
            equations.partition_matrices = partition_matrices(kinematics, partition)
        return equations


def partition_matrices(kinematics: TreeKinematics, partition: Partition) -> ca.Function:
    """(t, q) -> (W_d (m, m), W (m, nv)): the dependent block and the rows kept."""
    k = kinematics
    w_rows = ca.densify(k.velocity_constraint_matrix[[int(i) for i in partition.rows], :])
    w_d = w_rows[:, [int(i) for i in partition.dependent]]
    return ca.Function("partition", [k.t, k.q], [w_d, w_rows])


class PartitionAtlas:
    """The velocity partitions of one model as charts (:class:`workbench.equations.Atlas`).

    A chart is the tuple of dependent velocities (indices into v); the rows of W are those
    of the build. The best chart at q is the one pivoted QR of W(q) picks (as at the
    build); its conditioning is sigma_min(W_d) / sigma_max(W). A chart's equations are
    built the first time the run asks for them (only the charts used are compiled).
    """

    def __init__(self, formalism: NonholonomicProjection, model: Model, options: Any,
                 kinematics: TreeKinematics, partition: Partition,
                 equations: Equations) -> None:  # fmt: skip
        self._formalism, self._model, self._options = formalism, model, options
        self._kinematics, self._rows, self._q_reference = (
            kinematics, partition.rows, partition.q_reference,
        )  # fmt: skip
        self.home = self.key(partition)
        self._equations: dict[tuple[int, ...], Equations] = {self.home: equations}
        k = kinematics
        w_rows = ca.densify(k.velocity_constraint_matrix[[int(i) for i in partition.rows], :])
        self._w_rows = ca.Function("W_rows", [k.t, k.q], [w_rows])
        self._velocity: dict[tuple[int, ...], ca.Function] = {}

    @staticmethod
    def key(partition: Partition) -> tuple[int, ...]:
        return tuple(int(i) for i in partition.dependent)

    def _w(self, t: float, q: np.ndarray) -> np.ndarray:
        return np.asarray(self._w_rows(t, q), dtype=float).reshape(self._rows.size, -1)

    def name(self, chart: tuple[int, ...]) -> str:
        """The chart's dependent velocities, e.g. "plane.v[1]"."""
        return ", ".join(self._kinematics.v_names[i] for i in chart)

    def best(self, t: float, q: np.ndarray) -> tuple[int, ...]:
        """The chart pivoted QR of W(t, q) picks."""
        return tuple(int(i) for i in np.sort(independent_columns(self._w(t, q))))

    def conditioning(self, chart: tuple[int, ...], t: float, q: np.ndarray) -> float:
        """sigma_min(W_d) / sigma_max(W) of ``chart`` at (t, q): 0 where it is singular."""
        w = self._w(t, q)
        scale = np.linalg.norm(w, 2)
        if not scale > 0 or len(chart) != self._rows.size:
            return 0.0
        return float(np.linalg.svd(w[:, list(chart)], compute_uv=False)[-1] / scale)

    def _partition(self, chart: tuple[int, ...]) -> Partition:
        independent = [c for c in range(self._kinematics.nv) if c not in set(chart)]
        return Partition(self._rows, np.array(independent, dtype=int),
                         np.array(chart, dtype=int), self._q_reference)  # fmt: skip

    def equations(self, chart: tuple[int, ...]) -> Equations:
        """The projected equations in ``chart`` (built once)."""
        if chart not in self._equations:
            options = replace(self._options, independent=(), repartition=False)
            built = self._formalism.equations_for(self._model, options, self._kinematics,
                                                  self._partition(chart))  # fmt: skip
            built.atlas = self
            self._equations[chart] = built
        return self._equations[chart]

    def transfer(self, source: tuple[int, ...], target: tuple[int, ...], t: float,
                 y: np.ndarray) -> np.ndarray:  # fmt: skip
        """y = (q, s) in ``source`` -> (q, s) in ``target``, through v = F s + f."""
        k = self._kinematics
        if source not in self._velocity:
            s = ca.SX.sym("s", k.nv - len(source))
            _, _, v = minimal_velocity_map(k, self._partition(source), s)
            self._velocity[source] = ca.Function("v_of_s", [k.t, k.q, s], [v])
        q, s = y[: k.nq], y[k.nq :]
        v = np.ravel(np.asarray(self._velocity[source](t, q, s), dtype=float))
        independent = self._partition(target).independent
        return np.concatenate([q, v[independent]])
