"""The equations contract: what a formalism returns for one model (DESIGN.md).

A formalism describes its equations symbolically as a :class:`MechanicalSystem`
(CasADi SX or MX expressions in its own t, q, v) together with the pose and twist of
every body, and calls :func:`build_equations`. The shared code here then derives

* the ``mechanical`` form M(q) v' = Q(t, q, v) - W^T lambda, g(t, q) = 0,
  W v + w = 0 (holonomic rows then nonholonomic rows), q' = H(q) v;
* the ``dae`` form 0 = F(t, y, y') at the requested index: 3 (positions), 2 (stabilized
  Gear-Gupta-Leimkuhler), 1 (accelerations with Baumgarte stabilization) or 0 (no
  constraints: implicit ODE);
* the ``ode`` form y' = f(t, y) with df/dy, when there are no constraints or at index 1
  (the augmented system [M W^T; W 0] solved inside f);
* formalism-neutral observables: body poses and twists, kinetic and potential energy,
  and residuals of every joint constraint evaluated on the body poses (so drift is
  measured the same way for all formalisms).

State vectors are ordered [q, v, (lambda), (mu)]; their names are ``Equations.y_names``.
Every numeric function is a :class:`~workbench.evaluate.FastFunction`; Jacobians are
:class:`~workbench.evaluate.LazyFunction`s, built on first use.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from workbench.compiled import Compiler
from workbench.evaluate import FastFunction, dense_function, lazy_dense_function
from workbench.mechanics import forces as fm
from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import BodyState, contact_rows
from workbench.model import GROUND, Model

FORMS = ("ode", "dae", "mechanical")


@dataclass
class MechanicalSystem:
    """Symbolic equations of motion in a formalism's coordinates.

    t (1), q (nq), v (nv): symbols (all SX or all MX). qdot (nq): q' = H(q) v.
    mass (nv, nv), forces (nv): M and Q (applied minus gyroscopic/centrifugal terms).
    position_constraints (m): holonomic g(t, q). velocity_constraints (m + k): W v + w,
    linear in v, its first m rows the time derivative of g. ``acceleration``: an explicit
    v' when the formalism computes it without forming M (recursive); optional.
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

    def __post_init__(self) -> None:
        zero = self.q[0:0]  # empty expression of the right type
        if self.position_constraints is None:
            self.position_constraints = zero
        if self.velocity_constraints is None:
            self.velocity_constraints = zero

    @property
    def n_holonomic(self) -> int:
        return int(self.position_constraints.numel())

    @property
    def n_constraints(self) -> int:
        return int(self.velocity_constraints.numel())


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
    """Numeric pieces of M v' = Q - W^T lambda, g = 0, W v + w = 0, q' = H v.

    mass(t, q) -> M; forces(t, q, v) -> Q; qdot(t, q, v) -> H v; kinematics(t, q) -> H;
    position_constraints(t, q) -> g; position_jacobian(t, q) -> dg/dq (m, nq);
    velocity_matrix(t, q) -> W; velocity_constraints(t, q, v) -> W v + w;
    acceleration_rhs(t, q, v) -> gamma with W v' = gamma;
    dynamics(t, q, v, a, lam) -> (r = M a - Q + W^T lam, dr/dq (nv, nq), dr/dv, M, W^T).
    """

    mass: FastFunction
    forces: FastFunction
    qdot: FastFunction
    kinematics: FastFunction
    position_constraints: FastFunction
    position_jacobian: FastFunction
    velocity_matrix: FastFunction
    velocity_constraints: FastFunction
    acceleration_rhs: FastFunction
    dynamics: FastFunction
    n_holonomic: int
    n_constraints: int


@dataclass
class Observables:
    """Formalism-neutral quantities of a state (t, q, v).

    frames(t, q) -> (3, n_bodies) positions and (3, 3 n_bodies) rotations;
    twists(t, q, v) -> (6, n_bodies) [velocity of frame origin; angular velocity];
    energy(t, q, v) -> (2,) [T, V];
    residuals(t, q, v) -> position, velocity and nonholonomic residual vectors.
    :meth:`along` gives them all at many states in one call each.
    """

    frames: FastFunction
    twists: FastFunction
    energy: FastFunction
    residuals: FastFunction
    body_names: list[str]
    _mapped: dict = field(default_factory=dict, repr=False)  # (name, n) -> Function.map(n)

    def poses(self, t: float, q: np.ndarray) -> np.ndarray:
        """(n_bodies, 7): position and unit quaternion (scalar first) of every body."""
        positions, rotations = self.frames(t, q)
        return _poses(positions[None], rotations[None], len(self.body_names))[0]

    def poses_along(self, times: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(n, n_bodies, 7) poses at n configurations in one mapped call (see :meth:`along`)."""
        times = np.asarray(times, dtype=float).reshape(-1)
        if times.size == 0:
            return np.zeros((0, len(self.body_names), 7))
        positions, rotations = self._map("frames", times.size, times[None], np.atleast_2d(q).T)
        return _poses(positions, rotations, len(self.body_names))

    def along(self, times: np.ndarray, q: np.ndarray, v: np.ndarray) -> SampledObservables:
        """Every quantity at n states: ``times`` (n,), ``q`` (n, nq), ``v`` (n, nv).

        One evaluation of each function mapped over the n states (``Function.map``):
        metrics of a run with 500 output times called the functions 2,000 times one state
        at a time, which cost more than many integrations.
        """
        times = np.asarray(times, dtype=float).reshape(-1)
        n = times.size
        q, v = np.atleast_2d(q), np.atleast_2d(v)
        if n == 0:
            return SampledObservables.empty(len(self.body_names))
        row = times.reshape(1, n)
        positions, rotations = self._map("frames", n, row, q.T)
        (twists,) = self._map("twists", n, row, q.T, v.T)
        (energy,) = self._map("energy", n, row, q.T, v.T)
        residuals = self._map("residuals", n, row, q.T, v.T)
        n_bodies = len(self.body_names)
        return SampledObservables(
            poses=_poses(positions, rotations, n_bodies),
            twists=twists.reshape(n, 6, -1).transpose(0, 2, 1),  # as reshape(6, -1).T
            energy=energy.reshape(n, -1)[:, :2],
            residuals=[r.reshape(n, -1) for r in residuals],
        )

    def _map(self, name: str, n: int, *args: np.ndarray) -> list[np.ndarray]:
        """Outputs of observable ``name`` at n states, each stacked as (n, rows, cols)."""
        function = getattr(self, name).function
        key = (name, n)
        if key not in self._mapped:
            self._mapped[key] = function.map(n)
        outputs = self._mapped[key].call(list(args))
        stacked = []
        for i, value in enumerate(outputs):
            rows, cols = function.sparsity_out(i).shape
            stacked.append(np.asarray(value).reshape(rows, n, cols).transpose(1, 0, 2))
        return stacked


@dataclass
class SampledObservables:
    """Observables at n states: ``poses`` (n, n_bodies, 7) [position, Euler parameters];
    ``twists`` (n, n_bodies, 6) [velocity of the frame origin, angular velocity];
    ``energy`` (n, 2) [T, V]; ``residuals``: position, velocity and nonholonomic
    residuals, each (n, rows)."""

    poses: np.ndarray
    twists: np.ndarray
    energy: np.ndarray
    residuals: list[np.ndarray]

    @classmethod
    def empty(cls, n_bodies: int) -> SampledObservables:
        return cls(np.zeros((0, n_bodies, 7)), np.zeros((0, n_bodies, 6)), np.zeros((0, 2)), [])


def _poses(positions: np.ndarray, rotations: np.ndarray, n_bodies: int) -> np.ndarray:
    """(m, n_bodies, 7) poses from m stacked frames outputs: positions (m, 3, n_bodies) and
    rotations (m, 3, 3 n_bodies); quaternions scalar first with p0 >= 0."""
    m = positions.shape[0]
    matrices = rotations.reshape(m, 3, n_bodies, 3).transpose(0, 2, 1, 3)  # (m, nb, 3, 3)
    quats = Rotation.from_matrix(matrices.reshape(-1, 3, 3)).as_quat()[:, [3, 0, 1, 2]]
    quats *= np.where(quats[:, :1] < 0, -1.0, 1.0)
    origins = positions.reshape(m, 3, n_bodies).transpose(0, 2, 1)
    return np.concatenate([origins, quats.reshape(m, n_bodies, 4)], axis=2)


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
    compile_warnings: list[str] = field(default_factory=list)  # see workbench.compiled

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
        from workbench.errors import PluginError

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


# ---- building -------------------------------------------------------------------------


def _sym_like(x: Any, name: str, n: int) -> Any:
    return (ca.MX if isinstance(x, ca.MX) else ca.SX).sym(name, n)


def constraint_acceleration_rhs(system: MechanicalSystem) -> Any:
    """gamma(t, q, v) with W v' = gamma: minus the derivative of W v + w at fixed v'."""
    c = system.velocity_constraints
    return -(ca.mtimes(ca.jacobian(c, system.q), system.qdot) + ca.jacobian(c, system.t))


SYMBOLIC_SOLVE_LIMIT = 8
"""Linear systems larger than this are solved numerically inside an MX graph (M alone:
CasADi's sparse LDL^T, which compiles to C; with constraints: LAPACK LU of [M W^T; W 0]);
smaller ones symbolically (M: LDL^T, a third of the instructions of the QR used for the
indefinite [M W^T; W 0]). A symbolic factorization grows as n^3 instructions, so building
takes seconds at 6 spatial bodies. The crossover was not re-measured for LDL^T.
Measured with benchmarks/build_and_eval.py; see the README's Performance section."""


def _augmented_acceleration(
    system: MechanicalSystem, gamma: Any
) -> tuple[Any, Any, Any, Callable[[], Any] | None]:
    """(v', lambda, y symbols, Jacobian builder) solving [M W^T; W 0] [v'; lambda] = [Q; gamma].

    Returns v' and lambda as expressions in symbols t, q, v that may be fresh MX symbols
    (returned as a triple) when the system is too large for a symbolic solve. Then the
    builder gives dv'/d[q; v] by the implicit function theorem: with K s = b,
    ds/dy = -K^-1 d(K s - b)/dy at fixed s, one Jacobian of the nv + nc residuals and a
    second solve with the same K. CasADi's own derivative of the solve differentiates
    every entry of K: for the binary tree in absolute coordinates (77 unknowns, 91
    states) that took 270 MB and 1.2 s to build. None: ``casadi.jacobian`` will do.
    """
    t, q, v = system.t, system.q, system.v
    nv, nc = v.numel(), system.n_constraints
    if nc == 0 and system.acceleration is not None:
        return system.acceleration, q[0:0], (t, q, v), None
    w_matrix = ca.jacobian(system.velocity_constraints, v)
    zeros = (ca.MX if isinstance(q, ca.MX) else ca.SX).zeros(nc, nc)
    kkt = ca.vertcat(ca.horzcat(system.mass, w_matrix.T), ca.horzcat(w_matrix, zeros))
    rhs = ca.vertcat(system.forces, gamma) if nc else system.forces
    symbols = (t, q, v)
    jacobian = None
    if nv + nc > SYMBOLIC_SOLVE_LIMIT or isinstance(q, ca.MX):
        # M alone is symmetric positive definite: CasADi's sparse LDL^T, which (unlike
        # LAPACK's LU) can be compiled to C (compile=jit)
        method = "ldl" if nc == 0 else "lapacklu"
        if isinstance(q, ca.SX):
            s = ca.SX.sym("s", nv + nc)
            residual = ca.mtimes(kkt, s) - rhs
            residual_jacobian = ca.Function(
                "kkt_residual_jacobian", [t, q, v, s], [ca.jacobian(residual, ca.vertcat(q, v))]
            )
            symbols = (ca.MX.sym("t"), ca.MX.sym("q", q.numel()), ca.MX.sym("v", nv))
            kkt, rhs = ca.Function("kkt", [t, q, v], [kkt, rhs])(*symbols)
            solution = ca.solve(kkt, rhs, method)

            def jacobian() -> Any:
                d_residual = residual_jacobian(*symbols, solution)
                return -ca.solve(kkt, d_residual, method)[:nv, :]

        else:
            solution = ca.solve(kkt, rhs, method)
    elif nc == 0:  # symbolic LDL^T of M: a third of the instructions of a symbolic QR
        d, lt, p = ca.ldl(kkt)
        solution = ca.ldl_solve(rhs, d, lt, p)
    else:
        solution = ca.solve(kkt, rhs)  # symbolic QR of the indefinite [M W^T; W 0]
    return solution[:nv], solution[nv:], symbols, jacobian


def build_equations(
    formalism: str,
    model: Model,
    system: MechanicalSystem,
    bodies: dict[str, BodyState],
    joint_space_map: tuple[list[Any], list[Any]],
    dae_index: int = 3,
    baumgarte: tuple[float, float] = (0.0, 0.0),
    ode: bool = True,
    joint_coordinates: dict[str, Any] | None = None,
    notes: list[str] | None = None,
    compiler: Compiler | None = None,
) -> Equations:
    """Derive all forms and observables from a formalism's symbolic description.

    ``bodies``: symbolic pose and twist of every model body in (t, q, v).
    ``joint_space_map``: ([t, q_joint, v_joint] symbols, [q, v] expressions) mapping the
    free tree-joint coordinates (see :class:`~workbench.mechanics.kinematics.TreeKinematics`) to
    this formalism's q and v. ``dae_index``: 3, 2 or 1 for the dae form (0 is used
    automatically when there are no constraints). ``baumgarte``: (alpha, beta) for index 1
    and for the ode form of a constrained system. ``ode``: offer the ode form (for a
    constrained system it is the index-1 system, which drifts without stabilization).
    ``joint_coordinates``: q of each joint with a spring (for the potential energy);
    recovered from the poses when not given. ``compiler``: how the functions of the forms
    (evaluated in integrators' hot loops) run; observables stay in the CasADi VM.
    """
    compiler = compiler if compiler is not None else Compiler()

    def hot(name: str, inputs: list, outputs: list) -> FastFunction:
        return dense_function(name, inputs, outputs, compiler=compiler)

    def lazy_hot(name: str, inputs: list, outputs: Any) -> Any:
        return lazy_dense_function(name, inputs, outputs, compiler=compiler)

    t, q, v = system.t, system.q, system.v
    nq, nv, nc, m = q.numel(), v.numel(), system.n_constraints, system.n_holonomic
    c = system.velocity_constraints
    g = system.position_constraints
    gamma = constraint_acceleration_rhs(system) if nc else q[0:0]
    alpha, beta = baumgarte
    stabilized = gamma
    if nc and (alpha or beta):
        position_term = ca.vertcat(g, ca.DM.zeros(nc - m)) if nc > m else g
        stabilized = gamma - 2 * alpha * c - beta**2 * position_term
    forms: dict[str, Any] = {}

    # mechanical form; H and W do not depend on v, but MX Jacobians of call nodes keep v
    # as a structural input: substitute it away so they are functions of (t, q)
    zero_v = ca.DM.zeros(nv)
    w_matrix = ca.substitute(ca.jacobian(c, v), v, zero_v) if nc else ca.DM.zeros(0, nv)
    h_matrix = ca.substitute(ca.jacobian(system.qdot, v), v, zero_v)
    a = _sym_like(q, "a", nv)
    lam = _sym_like(q, "lam", nc)
    dyn = ca.mtimes(system.mass, a) - system.forces
    if nc:
        dyn = dyn + ca.mtimes(w_matrix.T, lam)
    forms["mechanical"] = MechanicalForm(
        mass=hot("mass", [t, q], [system.mass]),
        forces=hot("forces", [t, q, v], [system.forces]),
        qdot=hot("qdot", [t, q, v], [system.qdot]),
        kinematics=hot("kinematics", [t, q], [h_matrix]),
        position_constraints=hot("g", [t, q], [g]),
        position_jacobian=hot("g_q", [t, q], [ca.jacobian(g, q)]),
        velocity_matrix=hot("W", [t, q], [w_matrix]),
        velocity_constraints=hot("c", [t, q, v], [c]),
        acceleration_rhs=hot("gamma", [t, q, v], [gamma]),
        dynamics=lazy_hot(
            "dynamics",
            [t, q, v, a, lam],
            lambda: [dyn, ca.jacobian(dyn, q), ca.jacobian(dyn, v), system.mass, w_matrix.T],
        ),
        n_holonomic=m,
        n_constraints=nc,
    )

    # ode form: [q' ; v'] with v' from the (augmented) system
    if ode or nc == 0:
        accel, _, (t_o, q_o, v_o), accel_jacobian = _augmented_acceleration(system, stabilized)
        qdot = system.qdot
        if q_o is not q:
            qdot = ca.Function("qdot", [t, q, v], [qdot])(t_o, q_o, v_o)
        y = ca.vertcat(q_o, v_o)
        f = ca.vertcat(qdot, accel)

        def ode_jacobian() -> list:
            if accel_jacobian is None:
                return [ca.jacobian(f, y)]
            return [ca.vertcat(ca.jacobian(qdot, y), accel_jacobian())]

        forms["ode"] = OdeForm(
            rhs=hot("ode_rhs", [t_o, y], [f]),
            jacobian=lazy_hot("ode_jac", [t_o, y], ode_jacobian),
            n=nq + nv,
        )

    # dae form
    index = dae_index if nc else 0
    qp, vp = _sym_like(q, "qp", nq), _sym_like(q, "vp", nv)
    kinematic = qp - system.qdot
    dynamic = ca.mtimes(system.mass, vp) - system.forces
    if nc:
        dynamic = dynamic + ca.mtimes(w_matrix.T, lam)
    parts, y_parts, yp_parts, algebraic = (
        [kinematic, dynamic],
        [q, v],
        [qp, vp],
        [False] * (nq + nv),
    )
    if index == 3:
        nonholonomic = c[m:] if nc > m else q[0:0]
        parts += [g, nonholonomic]
        y_parts.append(lam)
        yp_parts.append(_sym_like(q, "lamp", nc))
        algebraic += [True] * nc
    elif index == 2:
        mu = _sym_like(q, "mu", m)
        parts[0] = kinematic + ca.mtimes(ca.jacobian(g, q).T, mu)
        parts += [c, g]
        y_parts += [lam, mu]
        yp_parts += [_sym_like(q, "lamp", nc), _sym_like(q, "mup", m)]
        algebraic += [True] * (nc + m)
    elif index == 1:
        parts.append(ca.mtimes(w_matrix, vp) - stabilized)
        y_parts.append(lam)
        yp_parts.append(_sym_like(q, "lamp", nc))
        algebraic += [True] * nc
    elif index != 0:
        raise ValueError(f"dae index must be 0, 1, 2 or 3, not {index}")
    residual = ca.vertcat(*parts)
    y_all, yp_all = ca.vertcat(*y_parts), ca.vertcat(*yp_parts)
    coefficient = _sym_like(q, "c", 1)

    def dae_jacobian() -> list:
        return [ca.jacobian(residual, y_all) + coefficient * ca.jacobian(residual, yp_all)]

    forms["dae"] = DaeForm(
        residual=hot("dae_residual", [t, y_all, yp_all], [residual]),
        jacobian=lazy_hot("dae_jacobian", [t, y_all, yp_all, coefficient], dae_jacobian),
        algebraic=np.array(algebraic, dtype=bool),
        index=index,
        n=int(y_all.numel()),
    )

    observables = build_observables(model, t, q, v, system.qdot, bodies, joint_coordinates)
    constraint_names = list(system.constraint_names) or [f"c[{i}]" for i in range(nc)]
    map_inputs, map_outputs = joint_space_map
    return Equations(
        formalism=formalism,
        model=model,
        q_names=list(system.q_names),
        v_names=list(system.v_names),
        constraint_names=constraint_names,
        n_holonomic=m,
        forms=forms,
        observables=observables,
        joint_space_map=dense_function("joint_space_map", map_inputs, map_outputs),
        notes=list(notes or []),
        compile_warnings=compiler.warnings,
    )


def build_observables(
    model: Model,
    t: Any,
    q: Any,
    v: Any,
    qdot: Any,
    bodies: dict[str, BodyState],
    joint_coordinates: dict[str, Any] | None = None,
) -> Observables:
    """Poses, twists, energies and constraint residuals from symbolic body states."""
    names = list(model.bodies)
    zero_v = ca.DM.zeros(v.numel())  # poses depend on (t, q) only; see build_equations
    positions = ca.substitute(ca.horzcat(*[bodies[b].position for b in names]), v, zero_v)
    rotations = ca.substitute(ca.horzcat(*[bodies[b].rotation for b in names]), v, zero_v)
    twists = ca.horzcat(
        *[ca.vertcat(bodies[b].velocity, bodies[b].angular_velocity) for b in names]
    )
    spring_joints = {f.joint for f in model.forces if isinstance(f, fm.JointSpringDamper)}
    coordinates = dict(joint_coordinates or {})
    for joint in spring_joints - set(coordinates):
        coordinates[joint] = fm.relative_joint_coordinates(model, bodies, joint)
    energy = ca.vertcat(
        fm.kinetic_energy(model, bodies), fm.potential_energy(model, bodies, coordinates)
    )
    position_residual = ca.substitute(joint_residuals(model, t, bodies), v, zero_v)
    velocity_residual = ca.mtimes(ca.jacobian(position_residual, q), qdot) + ca.jacobian(
        position_residual, t
    )
    nonholonomic = [
        contact_rows(model.kind == "planar", bodies[c.body], c)[1] for c in model.nonholonomic
    ]
    nh_residual = ca.vertcat(*nonholonomic) if nonholonomic else ca.DM.zeros(0, 1)
    return Observables(
        frames=dense_function("frames", [t, q], [positions, rotations]),
        twists=dense_function("twists", [t, q, v], [twists]),
        energy=dense_function("energy", [t, q, v], [energy]),
        residuals=dense_function(
            "residuals", [t, q, v], [position_residual, velocity_residual, nh_residual]
        ),
        body_names=names,
    )


def joint_residuals(model: Model, t: Any, bodies: dict[str, BodyState]) -> Any:
    """Implicit constraints of every joint (tree and cut) and contact height, on body poses."""
    rows = []
    planar = model.kind == "planar"
    ground = BodyState(ca.DM.zeros(3), ca.DM.eye(3), ca.DM.zeros(3), ca.DM.zeros(3))
    for joint in model.joints.values():
        parent = ground if joint.parent == GROUND else bodies[joint.parent]
        r_p, rot_p = parent.frame(joint.parent_frame)
        if joint.drive is not None:
            q_d, _, _ = jk.drive_values(joint, t)
            r_rel, rot_rel = jk.relative_transform(joint, q_d)
            r_p, rot_p = r_p + ca.mtimes(rot_p, r_rel), ca.mtimes(rot_p, rot_rel)
        child = ground if joint.child == GROUND else bodies[joint.child]
        r_c, rot_c = child.frame(joint.child_frame)
        residual = jk.implicit_constraints(joint, planar, r_p, rot_p, r_c, rot_c)
        if np.size(residual) if not isinstance(residual, ca.SX | ca.MX) else residual.numel():
            rows.append(residual)
    for constraint in model.nonholonomic:
        height, _ = contact_rows(planar, bodies[constraint.body], constraint)
        if height is not None:
            rows.append(height)
    return ca.vertcat(*rows) if rows else ca.DM.zeros(0, 1)


def build_joint_space_equations(
    formalism: str,
    model: Model,
    kinematics: Any,
    system: MechanicalSystem,
    options: Any,
    ode: bool,
    notes: list[str] | None = None,
) -> Equations:
    """:func:`build_equations` for formalisms whose coordinates are the tree's free joint
    coordinates (``kinematics`` a TreeKinematics): the joint-space map is the identity.
    ``options`` carries ``index``, ``baumgarte_alpha`` and ``baumgarte_beta``."""
    k = kinematics
    return build_equations(
        formalism,
        model,
        system,
        k.bodies,
        ([k.t, k.q, k.v], [k.q, k.v]),
        dae_index=options.index,
        baumgarte=(options.baumgarte_alpha, options.baumgarte_beta),
        ode=ode,
        joint_coordinates={j.name: k.joint_coordinates(j)[0] for j in model.tree_joints},
        notes=notes,
        compiler=Compiler.from_options(options),
    )
