"""The articulated-body algorithm with one generated kernel per joint type (bounded code).

:func:`~workbench.plugins.formalisms.recursive.articulated_body_accelerations` unrolls the
recursions into one straight-line graph, each link's constants folded into numbers: the
fewest instructions, but C that grows with the tree (1.5 MB at 200 links), and once it
outgrows a core's cache a call slows down (docs/performance.md). Here each pass of the
algorithm is one small SX Function a joint type (a *kernel*: revolute, prismatic,
spherical, free, fixed), whose link constants are an input: the joint placement
E0 = (L_R A)^T and r0, the prismatic axis and the spatial inertia's 21 unique entries.
The tree is an MX graph of calls to those kernels, so the generated C holds each kernel
once and a few lines a link: its size grows by a call a pass and link, not by the
link's instructions. The price: constants are no longer folded (products by the frames'
exact zeros and ones are made), about 1.5-2x the instructions a link.

The passes are those of the recursive formalism's module docstring, per link i:
``outward``  (q_i, v_i, V_lambda(i), k_i, f^x_i) -> V_i, c_i, p^A_i (with I^A_i = I_i),
X_i (the joint's transform E_i, r_i: the later passes take it, not recompute it: a
revolute joint's sin and cos once a call, not three times);
``inward``   (q_i, v_i, I^A_i, p^A_i, c_i, tau_i, X_i) -> X_i^T I^a_i X_i, X_i^T p^a_i,
D_i^-1 U_i^T, D_i^-1 u_i (what the parent receives, and what pass 3 needs);
``accelerate`` (q_i, v_i, a_lambda(i), c_i, D_i^-1 U_i^T, D_i^-1 u_i, X_i) -> a_i, v'_i;
a root joint's inward and accelerate are one kernel ``root`` (it hands nothing on).
Joint types other than those five (universal, planar, cylindrical, driven joints) are
not supported here: :func:`supports` says so and the caller keeps the unrolled graph.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import casadi as ca
import numpy as np

from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import GROUND, Model
from workbench.numerics.spatial import (
    articulated_update,
    congruence,
    force_cross,
    motion_cross,
    symmetric,
    transform_force_back,
    transform_motion,
)
from workbench.plugins.formalisms.recursive import (
    SpatialTree,
    _free_joint_model,
    _placement,
    _rotation_z,
    _solve_symmetric,
    _unit_columns,
    joint_frame,
)

KINDS = ("revolute", "prismatic", "spherical", "free", "fixed")
N_CONSTANTS = 9 + 3 + 3 + 21  # E0, r0, axis, the spatial inertia's unique entries
_UNIQUE = [(i, j) for i in range(6) for j in range(i, 6)]


def supports(model: Model) -> bool:
    """Whether every tree joint of ``model`` has a kernel (no drives, types of KINDS)."""
    return all(j.type in KINDS and j.drive is None for j in model.tree_joints)


def _dimensions(kind: str) -> tuple[int, int]:
    return {"revolute": (1, 1), "prismatic": (1, 1), "spherical": (4, 3), "free": (7, 6),
            "fixed": (0, 0)}[kind]  # fmt: skip


def _motion(kind: str, joint: Any, q: Any, v: Any, k: Any) -> tuple[Any, ...]:
    """(E, r, S, v_J, c_J, local) of a joint of ``kind`` at q, v with symbolic constants k,
    the formulas of :func:`~workbench.plugins.formalisms.recursive.joint_model`."""
    E0, r0, axis = ca.reshape(k[0:9], 3, 3), k[9:12], k[12:15]
    if kind == "free":
        motion = _free_joint_model(joint, q, v, E0.T, r0)
        return motion.E, motion.r, motion.S, motion.v_J, motion.c_J, motion.local
    if kind == "revolute":
        E, r, S = ca.mtimes(_rotation_z(q[0]).T, E0), r0, _unit_columns([2])
    elif kind == "prismatic":
        E, r, S = E0, r0 + axis * q[0], _unit_columns([5])
    elif kind == "spherical":
        _, R_rel = jk.relative_transform(joint, q)
        E, r, S = ca.mtimes(ca.SX(R_rel).T, E0), r0, _unit_columns([0, 1, 2])
    else:
        return E0, r0, ca.SX(6, 0), ca.SX.zeros(6), ca.SX.zeros(6), None
    return E, r, S, ca.mtimes(S, v), ca.SX.zeros(6), None


def _inertia(k: Any) -> Any:
    entries = {pair: k[15 + n] for n, pair in enumerate(_UNIQUE)}
    return symmetric(lambda i, j: entries[(min(i, j), max(i, j))], 6)


@cache
def _kernels(kind: str) -> dict[str, ca.Function]:
    """The kernels of one joint type."""
    joint = _STAND_INS[kind]
    nq, nv = _dimensions(kind)
    q, v, k = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("k", N_CONSTANTS)
    E, r, S, v_J, c_J, local = _motion(kind, joint, q, v, k)
    S_aba = local.S if local else S
    rows = tuple(int(S_aba[:, c].sparsity().row()[0]) for c in range(S_aba.size2()))
    inertia = _inertia(k)
    V_p, f = ca.SX.sym("V_parent", 6), ca.SX.sym("f_ext", 6)
    V = transform_motion(E, r, V_p) + v_J
    c = (ca.SX.zeros(6) if local else c_J) + motion_cross(V, v_J)
    p_A = force_cross(V, ca.mtimes(inertia, V)) - f
    X = ca.vertcat(ca.reshape(E, 9, 1), r)  # the joint's transform, handed to the later passes
    outward = ca.Function(f"aba_out_{kind}", [q, v, V_p, k, f], [V, c, p_A, X])
    X = ca.SX.sym("X", 12)  # the later passes take it rather than recompute it (sin, cos)
    E, r = ca.reshape(X[0:9], 3, 3), X[9:12]

    I_A, p, c_i = ca.SX.sym("I_A", 6, 6), ca.SX.sym("p_A", 6), ca.SX.sym("c", 6)
    tau, a_p = ca.SX.sym("tau", nv), ca.SX.sym("a_parent", 6)
    a_prime = transform_motion(E, r, a_p) + c_i
    kernels = {"outward": outward}
    if nv:
        U = ca.mtimes(I_A, S_aba)
        D = ca.mtimes(S_aba.T, U)
        tau_i = local.tau(tau) if local else tau
        u = tau_i - ca.mtimes(S_aba.T, p)
        D_inv = _solve_symmetric(D, ca.horzcat(U.T, u))
        D_inv_U, D_inv_u = D_inv[:, :6], D_inv[:, 6]
        I_a = articulated_update(I_A, U, D_inv_U, rows)
        p_a = p + ca.mtimes(I_a, c_i) + ca.mtimes(U, D_inv_u)
        for column, row in enumerate(rows):  # S^T p^a = tau exactly
            p_a[row] = tau_i[column]
        root_vdot = _solve_symmetric(D, u - ca.mtimes(U.T, a_prime))
        kernels["root"] = ca.Function(
            f"aba_root_{kind}", [q, v, I_A, p, c_i, tau, a_p, X],
            [a_prime + ca.mtimes(S_aba, root_vdot),
             local.rates(root_vdot) if local else root_vdot]
        )  # fmt: skip
    else:
        I_a, p_a = I_A, p + ca.mtimes(I_A, c_i)
        D_inv_U, D_inv_u = ca.SX(0, 6), ca.SX(0, 1)
    DU, Du = ca.SX.sym("D_inv_U", nv, 6), ca.SX.sym("D_inv_u", nv)
    kernels["inward"] = ca.Function(
        f"aba_in_{kind}", [q, v, I_A, p, c_i, tau, X],
        [congruence(E, r, I_a), transform_force_back(E, r, p_a), D_inv_U, D_inv_u]
    )  # fmt: skip
    vdot = Du - ca.mtimes(DU, a_prime)
    kernels["accelerate"] = ca.Function(
        f"aba_acc_{kind}", [q, v, a_p, c_i, DU, Du, X],
        [a_prime + ca.mtimes(S_aba, vdot), local.rates(vdot) if local else vdot]
    )  # fmt: skip
    return kernels


def link_constants(model: Model, kinematics: TreeKinematics, tree: SpatialTree) -> list:
    """k_i (N_CONSTANTS) of every link, in ``tree.links`` order, numeric."""
    frames: dict[str, Any] = {}
    constants = []
    for joint, link in zip(kinematics.order, tree.links, strict=True):
        parent = frames.get(joint.parent) if joint.parent != GROUND else None
        L_R, L_r, A, _ = _placement(joint, parent)
        frames[joint.child] = joint_frame(joint, parent)
        axis = L_R @ A[:, 2] if joint.type == "prismatic" else np.zeros(3)
        inertia = np.asarray(ca.evalf(link.inertia))
        unique = [inertia[i, j] for i, j in _UNIQUE]
        E0 = (L_R @ A).T
        constants.append(np.concatenate([E0.ravel(order="F"), L_r, axis, unique]))
    return constants


def articulated_body_accelerations_mx(
    model: Model, kinematics: TreeKinematics, q: ca.MX, v: ca.MX, t: ca.MX
) -> ca.MX:
    """v' (nv, MX) of the tree at ``q``, ``v``, ``t`` (MX) through the joint-type kernels
    (module docstring); the model's joint forces and applied wrenches come from one SX
    Function of (t, q, v)."""
    k = kinematics
    tree = SpatialTree(model, k)
    links = tree.links
    constants = link_constants(model, k, tree)
    f_all, tau_all = ca.vertcat(*[link.f_ext for link in links]), tree.joint_forces()
    if f_all.nnz() or tau_all.nnz():  # else (no applied forces but gravity) constant zeros
        applied = ca.Function("aba_applied", [k.t, k.q, k.v], [f_all, tau_all])
        f_all, tau_all = applied(t, q, v)
    else:
        f_all, tau_all = ca.MX(6 * len(links), 1), ca.MX(k.nv, 1)
    n = len(links)
    coordinates = []
    for joint in k.order:
        q_slice, v_slice = k.joint_slices.get(joint.name, (slice(0, 0), slice(0, 0)))
        coordinates.append((q[q_slice], v[v_slice]))
    kernels = [_kernels(_convention(j)) for j in k.order]
    V, c, I_A, p_A, X = [None] * n, [None] * n, [None] * n, [None] * n, [None] * n
    for i, link in enumerate(links):
        V_p = ca.MX.zeros(6) if link.parent < 0 else V[link.parent]
        V[i], c[i], p_A[i], X[i] = kernels[i]["outward"](
            *coordinates[i], V_p, ca.DM(constants[i]), f_all[6 * i : 6 * i + 6]
        )
        I_A[i] = ca.DM(np.asarray(ca.evalf(link.inertia)))
    D_inv_U, D_inv_u, vdot, a = [None] * n, [None] * n, [None] * n, [None] * n
    taus = [tau_all[link.v_slice] if link.nv else ca.MX(0, 1) for link in links]
    for i in reversed(range(n)):
        link = links[i]
        if link.parent < 0 and link.nv:
            continue  # its inward and outward passes are one kernel, below
        I_par, p_par, D_inv_U[i], D_inv_u[i] = kernels[i]["inward"](
            *coordinates[i], I_A[i], p_A[i], c[i], taus[i], X[i]
        )
        if link.parent >= 0:
            I_A[link.parent] = I_A[link.parent] + I_par
            p_A[link.parent] = p_A[link.parent] + p_par
    base = ca.MX(ca.DM(np.asarray(ca.evalf(tree.base_acceleration)).ravel()))
    for i, link in enumerate(links):
        a_p = base if link.parent < 0 else a[link.parent]
        if link.parent < 0 and link.nv:
            a[i], vdot[i] = kernels[i]["root"](
                *coordinates[i], I_A[i], p_A[i], c[i], taus[i], a_p, X[i]
            )
        else:
            a[i], vdot[i] = kernels[i]["accelerate"](
                *coordinates[i], a_p, c[i], D_inv_U[i], D_inv_u[i], X[i]
            )
    order = sorted((link.v_slice.start, i) for i, link in enumerate(links) if link.nv)
    return ca.vertcat(*[vdot[i] for _, i in order])


def _convention(joint: Any) -> str:
    """``joint``'s type, with a stand-in joint of that type kept for :func:`_kernels`: the
    kernels use a joint only for its type's coordinate conventions."""
    _STAND_INS.setdefault(joint.type, joint)
    return joint.type


_STAND_INS: dict[str, Any] = {}


KERNELS_ABOVE_INSTRUCTIONS = 80_000
"""Compile the kernels rather than the unrolled graph above this many instructions of the
unrolled ode right-hand side: per call in C, unrolled / kernels 1.20 / 1.85 us at 3,872
instructions (random tree N = 7), 5.9 / 10.8 at 29,829 (N = 50), 14.0 / 20.9 at 62,384
(N = 100), 33.2 / 33.9 at 91,475 (N = 150), 50.2 / 42.4 at 121,617 (N = 200), where
the unrolled library (1.2-1.6 MB) no longer stays in cache (docs/performance.md). With
the kernels' values in local variables (``compiled.uses_locals``) they cost the unrolled
code's time from N = 50 on (5.74 / 5.81 us, N = 100 11.9 / 12.0, N = 200 24.0) and 1.5x
below (N = 7, 20): the threshold was left where it was."""


def use_kernels(model: Model, instructions: int) -> bool:
    """Whether the ode right-hand side of ``model`` compiles better as kernels, from the
    unrolled graph's ``instructions`` (:data:`KERNELS_ABOVE_INSTRUCTIONS`)."""
    return instructions > KERNELS_ABOVE_INSTRUCTIONS and supports(model)


def ode_rhs_kernels(model: Model, kinematics: TreeKinematics, t: ca.MX, y: ca.MX) -> ca.MX:
    """[q'; v'] (MX) at (t, y = [q; v]) through the joint-type kernels."""
    k = kinematics
    q, v = y[: k.nq], y[k.nq :]
    rates = ca.Function("aba_rates", [k.t, k.q, k.v], [k.qdot])(t, q, v)
    vdot = articulated_body_accelerations_mx(model, k, q, v, t)
    return ca.densify(ca.vertcat(rates, vdot))


def ode_function_kernels(model: Model) -> ca.Function:
    """f(t, y) = [q'; v'] as :func:`~workbench.plugins.formalisms.recursive.ode_function`
    builds it, through the joint-type kernels (an MX Function)."""
    k = TreeKinematics(model.validate())
    t, y = ca.MX.sym("t"), ca.MX.sym("y", k.nq + k.nv)
    return ca.Function("ode_rhs", [t, y], [ode_rhs_kernels(model, k, t, y)])
