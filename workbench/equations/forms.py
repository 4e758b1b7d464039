"""Deriving every form of the equations from a formalism's :class:`MechanicalSystem`.

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
* the contact form (gaps, their Jacobians, friction data) when the model has unilateral
  contacts (:mod:`workbench.equations.contacts`);
* formalism-neutral observables: body poses and twists, kinetic and potential energy,
  and residuals of every joint constraint evaluated on the body poses (so drift is
  measured the same way for all formalisms).

State vectors are ordered [q, v, (lambda), (mu)]; their names are ``Equations.y_names``.
Every numeric function is a :class:`~workbench.equations.evaluate.FastFunction`;
Jacobians are :class:`~workbench.equations.evaluate.LazyFunction`s, built on first use.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations.compiled import Compiler
from workbench.equations.contacts import build_contact_form
from workbench.equations.contract import (
    DaeForm,
    Equations,
    MechanicalForm,
    MechanicalSystem,
    OdeForm,
)
from workbench.equations.evaluate import FastFunction, dense_function, lazy_dense_function
from workbench.equations.observables import build_observables
from workbench.errors import PluginError
from workbench.mechanics.kinematics import BodyState, quaternion_slices, rotation_blocks
from workbench.mechanics.topology import independent_rows_at, rank_configurations
from workbench.model import Model
from workbench.numerics.rotations import quaternion_rate_matrix

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
a large one takes seconds; the limit comes from benchmarks/build_and_eval.py
(docs/performance.md)."""


def _equilibrated(kkt: Any, method: str) -> tuple[Any, Any]:
    """(D K, D) for the QR solve, D the inverse 2-norms of K's rows (otherwise D = 1): the
    QR of a row-equilibrated KKT matrix keeps more digits on badly scaled mechanisms
    (masses and lengths of many orders, as Andrews': 10.8 digits against 10.5 unscaled)."""
    if method != "qr":
        return kkt, ca.DM.ones(kkt.size1())
    scale = 1 / ca.sqrt(ca.sum2(kkt * kkt))
    return ca.repmat(scale, 1, kkt.size2()) * kkt, scale


def _kkt_solve_differs(system: MechanicalSystem) -> bool:
    """Whether :func:`_augmented_acceleration` solves [M W^T; W 0] numerically, so that
    its graph for C (QR) differs from the VM's (LAPACK's LU)."""
    nv, nc = system.v.numel(), system.n_constraints
    return nc > 0 and (nv + nc > SYMBOLIC_SOLVE_LIMIT or isinstance(system.q, ca.MX))


def _augmented_acceleration(
    system: MechanicalSystem, gamma: Any, compiled: bool = False, shared: dict | None = None
) -> tuple[Any, Any, Any, Callable[[], Any] | None]:
    """(v', lambda, y symbols, Jacobian builder) solving [M W^T; W 0] [v'; lambda] = [Q; gamma].

    Returns v' and lambda as expressions in symbols t, q, v that may be fresh MX symbols
    (returned as a triple) when the system is too large for a symbolic solve. Then the
    builder gives dv'/d[q; v] by the implicit function theorem: with K s = b,
    ds/dy = -K^-1 d(K s - b)/dy at fixed s, one Jacobian of the nv + nc residuals and a
    second solve with the same K, where CasADi's own derivative of the solve would
    differentiate every entry of K (hundreds of MB for a large absolute-coordinate model;
    docs/performance.md). None: ``casadi.jacobian`` will do. The residuals' Jacobian is
    made when the builder is first called, once for all calls that pass the same
    ``shared`` dict (the graphs for the VM and for C solve the same K s = b): made at
    build time for both, it was 1.6 of the 2.2 CPU seconds of building the absolute
    coordinates' equations of the articulated arm, the binary tree and Solo12, for an ode
    Jacobian only implicit ode integrators ask for.
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
        # M alone is symmetric positive definite: CasADi's sparse LDL^T (compiles to C). The
        # indefinite KKT matrix: LAPACK's LU with partial pivoting in the VM; compiled, CasADi's
        # sparse QR of the row-equilibrated matrix (LAPACK's LU has no C code generation; the
        # QR loses about half a digit on Andrews' badly scaled system: tests/test_ivp_testset)
        method = "ldl" if nc == 0 else ("qr" if compiled else "lapacklu")
        if isinstance(q, ca.SX):
            shared = {} if shared is None else shared

            def residual_jacobian(*args: Any) -> Any:
                if "kkt_residual_jacobian" not in shared:
                    s = ca.SX.sym("s", nv + nc)
                    residual = ca.mtimes(kkt_sx, s) - rhs_sx
                    shared["kkt_residual_jacobian"] = ca.Function(
                        "kkt_residual_jacobian", [t, q, v, s],
                        [ca.jacobian(residual, ca.vertcat(q, v))],
                    )  # fmt: skip
                return shared["kkt_residual_jacobian"](*args)

            kkt_sx, rhs_sx = kkt, rhs
            symbols = (ca.MX.sym("t"), ca.MX.sym("q", q.numel()), ca.MX.sym("v", nv))
            kkt, rhs = ca.Function("kkt", [t, q, v], [kkt, rhs])(*symbols)
            kkt, scale = _equilibrated(kkt, method)
            solution = ca.solve(kkt, scale * rhs, method)

            def jacobian() -> Any:
                d_residual = residual_jacobian(*symbols, solution)
                scaled = ca.repmat(scale, 1, d_residual.size2()) * d_residual
                return -ca.solve(kkt, scaled, method)[:nv, :]

        else:
            kkt, scale = _equilibrated(kkt, method)
            solution = ca.solve(kkt, scale * rhs, method)
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
    quaternion_slices: list[slice] | None = None,
    ode_rhs_for_c: Callable[[Any, Any], Any] | None = None,
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
    ``quaternion_slices``: the slices of q that hold Euler parameters (for the audit);
    by default the q slices of ``system.rotation_blocks``, which are checked here
    (:func:`check_rotation_blocks`) and handed on in the mechanical form.
    ``ode_rhs_for_c``: (t, y) MX -> [q'; v'] MX, another graph of an unconstrained ode
    right-hand side to compile to C (e.g. with bounded code size); the VM keeps the other.
    """
    compiler = compiler if compiler is not None else Compiler()

    def hot(name: str, inputs: list, outputs: list, for_c: Any = None) -> FastFunction:
        return dense_function(name, inputs, outputs, compiler=compiler, for_c=for_c)

    def lazy_hot(name: str, inputs: list, outputs: Any, for_c: Any = None) -> Any:
        return lazy_dense_function(name, inputs, outputs, compiler=compiler, for_c=for_c)

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
        kinematics_offset=hot("kinematics_offset", [t, q], [ca.substitute(system.qdot, v, zero_v)]),
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
        rotation_blocks=list(system.rotation_blocks),
    )
    check_rotation_blocks(formalism, system)

    # ode form: [q' ; v'] with v' from the (augmented) system
    if ode or nc == 0:
        kkt_shared: dict = {}  # the KKT residuals' Jacobian, made once for both graphs

        def ode_graphs(for_c: bool) -> tuple[list, list, Callable[[], list]]:
            """(inputs, [f], Jacobian builder) of the ode right-hand side."""
            accel, _, (t_o, q_o, v_o), accel_jacobian = _augmented_acceleration(
                system, stabilized, for_c, kkt_shared
            )
            qdot = system.qdot
            if q_o is not q:
                qdot = ca.Function("qdot", [t, q, v], [qdot])(t_o, q_o, v_o)
            y = ca.vertcat(q_o, v_o)
            f = ca.vertcat(qdot, accel)

            def ode_jacobian() -> list:
                if accel_jacobian is None:
                    return [ca.jacobian(f, y)]
                return [ca.vertcat(ca.jacobian(qdot, y), accel_jacobian())]

            return [t_o, y], [f], ode_jacobian

        inputs, outputs, jacobian = ode_graphs(compiler.mode == "jit")
        # compile=auto: the VM keeps LAPACK's LU, C gets the QR that it can generate
        both = compiler.mode == "auto" and _kkt_solve_differs(system)
        c_graphs = ode_graphs(True) if both else None
        rhs_for_c = c_graphs[:2] if c_graphs else None
        if ode_rhs_for_c is not None and compiler.active and nc == 0:
            t_c, y_c = ca.MX.sym("t"), ca.MX.sym("y", nq + nv)
            rhs_for_c = ([t_c, y_c], [ode_rhs_for_c(t_c, y_c)])
        forms["ode"] = OdeForm(
            rhs=hot("ode_rhs", inputs, outputs, rhs_for_c),
            jacobian=lazy_hot(
                "ode_jac", inputs, jacobian, (c_graphs[0], c_graphs[2]) if c_graphs else None
            ),
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
        compiler=compiler,
        quaternion_slices=list(
            quaternion_slices
            if quaternion_slices is not None
            else [q_slice for q_slice, _ in system.rotation_blocks]
        ),
        contacts=build_contact_form(model, t, q, v, system.qdot, bodies, hot),
    )


def check_rotation_blocks(formalism: str, system: MechanicalSystem) -> None:
    """PluginError unless every (q slice, v slice) of ``system.rotation_blocks`` is 4
    Euler parameters p and 3 body-frame angular velocities omega with p' = 1/2 p * (0, omega),
    checked at a random state (a wrong block would make a Lie-group update silently wrong).
    Evaluated in CasADi's VM, so a compiled formalism compiles nothing more for it."""
    if not system.rotation_blocks:
        return
    nq, nv = system.q.numel(), system.v.numel()
    rng = np.random.default_rng(7)
    q, v = rng.uniform(-1.0, 1.0, nq), rng.uniform(-1.0, 1.0, nv)
    for q_slice, _ in system.rotation_blocks:
        q[q_slice] /= np.linalg.norm(q[q_slice])
    qdot = ca.Function("qdot_check", [system.t, system.q, system.v], [system.qdot])
    rates = np.ravel(np.asarray(qdot(0.3, q, v), dtype=float))
    for q_slice, v_slice in system.rotation_blocks:
        sizes = (len(range(nq)[q_slice]), len(range(nv)[v_slice]))
        expected = None
        if sizes == (4, 3):
            expected = np.asarray(quaternion_rate_matrix(q[q_slice], "body")) @ v[v_slice]
        if expected is None or not np.allclose(rates[q_slice], expected, rtol=1e-9, atol=1e-12):
            raise PluginError(
                f"formalism {formalism!r}: rotation block (q[{q_slice.start}:{q_slice.stop}], "
                f"v[{v_slice.start}:{v_slice.stop}]) is not 4 Euler parameters driven by "
                "the body-frame angular velocity (p' = 1/2 p * (0, omega)); fix "
                "MechanicalSystem.rotation_blocks"
            )


def joint_space_system(
    kinematics: Any, mass: Any, forces: Any, acceleration: Any = None
) -> MechanicalSystem:
    """M v' = forces - W^T lambda in the tree's free joint coordinates.

    ``kinematics`` a TreeKinematics: its t, q, v, q' = H v and names, and as constraints
    its closure rows g(t, q) (cut joints, contact heights) and velocity rows W v + w
    (their derivatives, then nonholonomic rows). ``mass`` (nv, nv) and ``forces`` (nv, Q
    minus the velocity-product terms) are the formalism's; ``acceleration`` an explicit v'
    (nv) of the unconstrained tree when the formalism has one.
    """
    k = kinematics
    return MechanicalSystem(
        t=k.t,
        q=k.q,
        v=k.v,
        qdot=k.qdot,
        mass=mass,
        forces=forces,
        q_names=k.q_names,
        v_names=k.v_names,
        position_constraints=k.closure_constraints,
        velocity_constraints=k.velocity_constraints,
        constraint_names=k.velocity_constraint_names,
        acceleration=acceleration,
        rotation_blocks=rotation_blocks(k),
    )


def independent_joint_space_rows(model: Model, kinematics: Any) -> list[int]:
    """Rows of the tree's velocity constraints W v + w that are independent (kept).

    Decided where ``workbench describe`` and every formalism decide it
    (:func:`~workbench.mechanics.topology.rank_configurations`: the problem's initial
    configuration, assembled, confirmed at random assembled ones) by
    :func:`~workbench.numerics.linalg.independent_rows`. A row can be dependent for good:
    a rolling sphere carried by a joint that keeps it at its height and lets it turn about
    one horizontal axis only has a contact-height row and a sideways rolling row that
    vanish identically in joint coordinates.
    """
    k = kinematics
    n_rows = int(k.velocity_constraints.numel())
    if n_rows == 0:
        return []
    w_function = k.function("W", [k.velocity_constraint_matrix], with_v=False)

    def w_at(q: np.ndarray) -> np.ndarray:
        return np.asarray(w_function(0.0, q), dtype=float).reshape(n_rows, k.nv)

    rows, where = independent_rows_at(w_at, rank_configurations(model, k))
    return list(range(n_rows)) if where is None else rows


def without_redundant_rows(
    model: Model, kinematics: Any, system: MechanicalSystem
) -> tuple[MechanicalSystem, list[str]]:
    """``system`` without its dependent constraint rows, and the names of those removed.

    A dependent row makes [M W^T; W 0] and every iteration matrix singular (the ode form
    returns inf, an implicit integrator cannot start); removing it leaves the motion as
    it was, since the remaining rows impose the same constraints.
    """
    names = list(system.constraint_names)
    kept = independent_joint_space_rows(model, kinematics)
    if len(kept) == system.n_constraints:
        return system, []
    n_h = system.n_holonomic
    kept_h = [i for i in kept if i < n_h]
    g, c = system.position_constraints, system.velocity_constraints
    reduced = MechanicalSystem(
        t=system.t,
        q=system.q,
        v=system.v,
        qdot=system.qdot,
        mass=system.mass,
        forces=system.forces,
        q_names=system.q_names,
        v_names=system.v_names,
        position_constraints=g[kept_h] if kept_h else None,
        velocity_constraints=c[kept] if kept else None,
        constraint_names=[names[i] for i in kept] if names else [],
        acceleration=system.acceleration,
        rotation_blocks=list(system.rotation_blocks),
    )
    removed = [names[i] if names else f"c[{i}]" for i in range(system.n_constraints)]
    return reduced, [removed[i] for i in range(len(removed)) if i not in kept]


def build_joint_space_equations(
    formalism: str,
    model: Model,
    kinematics: Any,
    system: MechanicalSystem,
    options: Any,
    ode: bool,
    notes: list[str] | None = None,
    ode_rhs_for_c: Callable[[Any, Any], Any] | None = None,
) -> Equations:
    """:func:`build_equations` for formalisms whose coordinates are the tree's free joint
    coordinates (``kinematics`` a TreeKinematics): the joint-space map is the identity.
    ``options`` carries ``index``, ``baumgarte_alpha`` and ``baumgarte_beta``. Dependent
    constraint rows are removed (:func:`without_redundant_rows`) and named in the notes."""
    k = kinematics
    system, removed = without_redundant_rows(model, k, system)
    if removed:
        notes = [*(notes or []), f"removed redundant constraint rows: {', '.join(removed)}"]
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
        quaternion_slices=quaternion_slices(k),
        ode_rhs_for_c=ode_rhs_for_c,
    )
