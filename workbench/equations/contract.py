"""The equations contract: what a formalism returns for one model (docs/architecture.md).

A formalism describes its equations symbolically as a :class:`MechanicalSystem` (CasADi
SX or MX expressions in its own t, q, v) and hands it to
:func:`workbench.equations.forms.build_equations`, which derives the forms below. An
integrator consumes one form:

* ``mechanical``: M(q) v' = Q(t, q, v) - W^T lambda, g(t, q) = 0, W v + w = 0
  (holonomic rows then nonholonomic rows), q' = H(q) v;
* ``dae``: 0 = F(t, y, y') at index 3, 2 (GGL), 1 (Baumgarte) or 0 (implicit ODE);
* ``ode``: y' = f(t, y) with df/dy.

State vectors are ordered [q, v, (lambda), (mu)]; their names are ``Equations.y_names``.
Every numeric function is a :class:`~workbench.equations.evaluate.FastFunction`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from workbench.equations.evaluate import FastFunction
from workbench.equations.observables import Observables
from workbench.errors import PluginError
from workbench.model import Model

FORMS = ("ode", "dae", "mechanical")


@dataclass
class MechanicalSystem:
    """Symbolic equations of motion in a formalism's coordinates.

    t (1), q (nq), v (nv): symbols (all SX or all MX). qdot (nq): q' = H(q) v.
    mass (nv, nv), forces (nv): M and Q (applied minus gyroscopic/centrifugal terms).
    position_constraints (m): holonomic g(t, q). velocity_constraints (m + k): W v + w,
    linear in v, its first m rows the time derivative of g. ``acceleration``: an explicit
    v' when the formalism computes it without forming M (recursive); optional.
    ``rotation_blocks``: (q slice of 4 Euler parameters p, v slice of the 3 body-frame
    angular velocity components omega) pairs with p' = 1/2 p * (0, omega), one per rotating
    frame whose coordinates are Euler parameters; a Lie-group integrator updates those p
    multiplicatively, p <- p * exp(h omega), and every other coordinate additively.
    """

    t: Any
    q: Any
    v: Any
    qdot: Any
    mass: Any
    forces: Any
    q_names: list[str]
    v_names: list[str]
    position_constraints: Any = None
    velocity_constraints: Any = None
    constraint_names: list[str] = field(default_factory=list)
    acceleration: Any = None
    rotation_blocks: list[tuple[slice, slice]] = field(default_factory=list)

    def __post_init__(self) -> None:
        zero = self.q[0:0]  # empty expression of the right type
        if self.position_constraints is None:
            self.position_constraints = zero
        if self.velocity_constraints is None:
            self.velocity_constraints = zero
        self._check_shapes()

    def _check_shapes(self) -> None:
        """PluginError naming the first field whose shape does not fit q and v: a field of
        the wrong size met CasADi only later, as an assertion from its C++ source."""
        nq, nv = _column_length("q", self.q), _column_length("v", self.v)
        m = _column_length("position_constraints", self.position_constraints)
        expected = [("t", self.t, (1, 1), "a scalar"), ("qdot", self.qdot, (nq, 1), f"nq = {nq}"),
                    ("mass", self.mass, (nv, nv), f"nv x nv = {nv} x {nv}"),
                    ("forces", self.forces, (nv, 1), f"nv = {nv}")]  # fmt: skip
        if self.acceleration is not None:
            expected.append(("acceleration", self.acceleration, (nv, 1), f"nv = {nv}"))
        for name, value, shape, what in expected:
            actual = _shape(name, value)
            if actual != shape and actual[0] * actual[1] + shape[0] * shape[1] > 0:
                raise PluginError(f"MechanicalSystem.{name} {_shape_text(value)}, expected {what}")
        rows = _column_length("velocity_constraints", self.velocity_constraints)
        columns = _shape("velocity_constraints", self.velocity_constraints)[1] if rows else 1
        if rows < m or columns != 1:
            raise PluginError(
                f"MechanicalSystem.velocity_constraints {_shape_text(self.velocity_constraints)}"
                f", expected a column of at least the {m} position constraints' time derivatives"
            )
        for name, names, size in (("q_names", self.q_names, nq), ("v_names", self.v_names, nv)):
            if len(names) != size:
                raise PluginError(
                    f"MechanicalSystem.{name} has {len(names)} names, expected {size}"
                )
        if self.constraint_names and len(self.constraint_names) != rows:
            raise PluginError(
                f"MechanicalSystem.constraint_names has {len(self.constraint_names)} names, "
                f"expected one a velocity constraint ({rows})"
            )

    @property
    def n_holonomic(self) -> int:
        return int(self.position_constraints.numel())

    @property
    def n_constraints(self) -> int:
        return int(self.velocity_constraints.numel())


def _shape(name: str, value: Any) -> tuple[int, int]:
    """(rows, columns) of an expression or array (a 1-D array is a column)."""
    shape = getattr(value, "shape", None)
    if shape is None or len(shape) > 2:
        raise PluginError(
            f"MechanicalSystem.{name} is {type(value).__name__}, expected a CasADi expression"
        )
    return (tuple(shape) + (1, 1))[:2] if len(shape) < 2 else (shape[0], shape[1])


def _shape_text(value: Any) -> str:
    rows, columns = _shape("", value)
    return f"has {rows} rows" if columns == 1 else f"is {rows} x {columns}"


def _column_length(name: str, value: Any) -> int:
    """The length of a column vector (an empty expression of any shape: 0); PluginError
    for anything else."""
    rows, columns = _shape(name, value)
    if rows * columns == 0:
        return 0
    if columns != 1:
        raise PluginError(f"MechanicalSystem.{name} is {rows} x {columns}, expected a column")
    return rows


@dataclass
class OdeForm:
    """y' = rhs(t, y); jacobian(t, y) = df/dy. y = [q, v]."""

    rhs: FastFunction
    jacobian: FastFunction
    n: int


@dataclass
class DaeForm:
    """0 = residual(t, y, y'); jacobian(t, y, y', c) = dF/dy + c dF/dy'.

    ``algebraic``: True for components whose derivative does not appear (lambda, mu).
    ``index``: differentiation index of the formulation (0 = implicit ODE).
    """

    residual: FastFunction
    jacobian: FastFunction
    algebraic: np.ndarray
    index: int
    n: int


@dataclass
class MechanicalForm:
    """Numeric pieces of M v' = Q - W^T lambda, g = 0, W v + w = 0, q' = H v + f.

    mass(t, q) -> M; forces(t, q, v) -> Q; qdot(t, q, v) -> H v + f; kinematics(t, q) -> H;
    kinematics_offset(t, q) -> f, the part of q' that does not move with v (zero unless
    the coordinates are rheonomic, e.g. minimal velocities on a moving plane: an
    integrator that advances q by H v alone drops it);
    position_constraints(t, q) -> g; position_jacobian(t, q) -> dg/dq (m, nq);
    velocity_matrix(t, q) -> W; velocity_constraints(t, q, v) -> W v + w;
    acceleration_rhs(t, q, v) -> gamma with W v' = gamma;
    dynamics(t, q, v, a, lam) -> (r = M a - Q + W^T lam, dr/dq (nv, nq), dr/dv, M, W^T).
    ``rotation_blocks``: (q slice of Euler parameters, v slice of the body-frame angular
    velocity) pairs, as :attr:`MechanicalSystem.rotation_blocks` (checked at build).
    """

    mass: FastFunction
    forces: FastFunction
    qdot: FastFunction
    kinematics: FastFunction
    kinematics_offset: FastFunction
    position_constraints: FastFunction
    position_jacobian: FastFunction
    velocity_matrix: FastFunction
    velocity_constraints: FastFunction
    acceleration_rhs: FastFunction
    dynamics: FastFunction
    n_holonomic: int
    n_constraints: int
    rotation_blocks: list[tuple[slice, slice]] = field(default_factory=list)


@dataclass
class ContactForm:
    """Numeric data of the unilateral contacts (:mod:`workbench.equations.contacts`).

    gaps(t, q) -> g_N (nc); normal_jacobian(t, q) -> W_N (nc, nv) with U_N = W_N v;
    tangent_jacobian(t, q) -> W_T (nc * n_tangent, nv), contact-major; normal_bias(t, q,
    v) and tangent_bias(t, q, v) -> wdot with U' = W v' + wdot. ``restitution`` e and
    ``friction`` mu: one a contact. Contact forces enter as W_N^T lambda_N + W_T^T lambda_T.
    """

    names: list[str]
    restitution: np.ndarray
    friction: np.ndarray
    n_tangent: int
    gaps: FastFunction
    normal_jacobian: FastFunction
    tangent_jacobian: FastFunction
    normal_bias: FastFunction
    tangent_bias: FastFunction
    # Coulomb friction in joints (Model.add_joint_friction): the joint rates U_F = W_F v,
    # joint_rate_jacobian(t, q) -> W_F (nf, nv), joint_rate_bias(t, q, v) -> wdot_F with
    # U_F' = W_F v' + wdot_F, and each |lambda_F| <= bound (forces W_F^T lambda_F)
    joint_friction_names: list[str] = field(default_factory=list)
    joint_friction_bound: np.ndarray = field(default_factory=lambda: np.zeros(0))
    joint_rate_jacobian: FastFunction | None = None
    joint_rate_bias: FastFunction | None = None

    @property
    def n_contacts(self) -> int:
        return len(self.names)

    @property
    def n_joint_frictions(self) -> int:
        return len(self.joint_friction_names)


class Atlas(Protocol):
    """Charts of a formalism whose coordinates (q, v) hold only near part of the motion,
    e.g. minimal velocities v_i of a velocity partition, singular where the block W_d
    solved for the dependent ones loses rank. Every chart has the same q, the same number
    of v and the same observables; a chart is any hashable key.

    1. ``home``: the chart of the Equations that offer the atlas;
    2. ``best(t, q)``: the best-conditioned chart at (t, q);
    3. ``conditioning(chart, t, q)``: a measure in [0, 1] of how well ``chart`` holds at
       (t, q), 0 where it is singular (the audit's ratio, e.g. sigma_min(W_d)/sigma_max(W));
    4. ``equations(chart)``: the chart's Equations (built on first use);
    5. ``transfer(source, target, t, y)``: a state y = (q, v) of ``source`` in ``target``;
    6. ``name(chart)``: a short text naming the chart (for the row's notes).
    """

    home: Any

    def best(self, t: float, q: np.ndarray) -> Any: ...

    def conditioning(self, chart: Any, t: float, q: np.ndarray) -> float: ...

    def equations(self, chart: Any) -> Equations: ...

    def transfer(self, source: Any, target: Any, t: float, y: np.ndarray) -> np.ndarray: ...

    def name(self, chart: Any) -> str: ...


@dataclass
class Equations:
    """What a formalism built for one model. ``forms`` maps form name -> form object."""

    formalism: str
    model: Model
    q_names: list[str]
    v_names: list[str]
    constraint_names: list[str]
    n_holonomic: int
    forms: dict[str, Any]
    observables: Observables
    joint_space_map: FastFunction  # (t, q_joint, v_joint) -> (q, v) in these coordinates
    notes: list[str] = field(default_factory=list)
    stiffness_hint: str = ""
    compile_warnings: list[str] = field(default_factory=list)  # see workbench.equations.compiled
    compiler: Any = None  # the Compiler of its functions (compile=auto: Compiler.expect)
    # (t, q) -> (W_d, W): a formalism that solves a fixed block W_d (m, m) of its velocity
    # constraints W (m, nv) for dependent velocities (a velocity partition) offers it, so
    # the run's audit reports where sigma_min(W_d) / sigma_max(W) falls (digits are lost)
    partition_matrices: Any = None
    # an :class:`Atlas` when these coordinates hold only near part of the motion (a velocity
    # partition): the run then integrates chart by chart (workbench.execution.charts)
    atlas: Any = None
    # slices of q holding Euler parameters (4 each): they stay on the unit sphere only as
    # well as the integrator keeps them there; the rotations built from them are
    # normalized, so the run's audit reads their norm here
    quaternion_slices: list[slice] = field(default_factory=list)
    # the unilateral contacts' gaps, Jacobians and friction data; None without contacts.
    # Only integrators that declare ``contacts = True`` may integrate such equations.
    contacts: ContactForm | None = None

    @property
    def nq(self) -> int:
        return len(self.q_names)

    @property
    def nv(self) -> int:
        return len(self.v_names)

    @property
    def n_constraints(self) -> int:
        return len(self.constraint_names)

    def form(self, name: str) -> Any:
        if name not in self.forms:
            raise PluginError(
                f"formalism {self.formalism!r} did not provide the {name!r} form "
                f"(it provides {', '.join(self.forms) or 'none'})"
            )
        return self.forms[name]

    def y_names(self, form: str) -> list[str]:
        """Names of the state components of ``form`` ("ode" or "dae")."""
        names = list(self.q_names) + list(self.v_names)
        if form == "dae":
            dae = self.forms["dae"]
            extra = dae.n - len(names)
            lam = [f"lambda:{n}" for n in self.constraint_names][:extra]
            mu = [f"mu:{n}" for n in self.constraint_names[: self.n_holonomic]]
            names += (lam + mu)[:extra]
        return names
