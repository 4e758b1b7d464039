"""The Lagrangian of a model in tree-joint coordinates, for energy-based formalisms.

Public plugin API (used by the energy-based formalisms): :func:`joint_space_lagrangian`
gives the kinetic energy T(t, q, v), the potential energy V(t, q) and the non-conservative
generalized forces Q_nc(t, q, v) as CasADi SX expressions in the symbols of a
:class:`~workbench.mechanics.kinematics.TreeKinematics`, from the same formalism-neutral
kinematics and force elements every formalism uses. Q_nc is the workbench's generalized
force minus its conservative part -dV/dq, so it is valid only where q' = v, i.e. without
spherical or free joints (:func:`quaternion_joints`). """

from __future__ import annotations

from typing import Any

import casadi as ca

from workbench.mechanics.forces import generalized_forces, kinetic_energy, potential_energy
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import AppliedForce, JointForce, JointSpringDamper, Model, SpringDamper

QUATERNION_JOINTS = ("spherical", "free")
QUATERNION_FEATURE = "spherical or free joints (quaternion coordinates, q' != v)"
"""A feature name for :meth:`~workbench.plugin.formalism.Formalism.unsupported` overrides."""


def quaternion_joints(model: Model) -> set[str]:
    """{QUATERNION_FEATURE} if a free tree joint of ``model`` has quaternion coordinates."""
    if any(j.type in QUATERNION_JOINTS and j.drive is None for j in model.tree_joints):
        return {QUATERNION_FEATURE}
    return set()


def has_nonconservative_forces(model: Model) -> bool:
    """Damping, joint forces or applied forces: forces that V does not describe."""
    for element in model.forces:
        if isinstance(element, JointForce | AppliedForce):
            return True
        if isinstance(element, SpringDamper | JointSpringDamper) and element.damping:
            return True
    return False


def joint_space_lagrangian(model: Model, kinematics: TreeKinematics) -> tuple[Any, Any, Any]:
    """(T, V, Q_nc): scalar, scalar, (nv,) SX expressions in (t, q, v) of ``kinematics``.

    V covers gravity and springs; Q_nc damping, joint and applied forces (zero vector if
    there are none). Requires q' = v (see the module docstring).
    """
    k = kinematics
    joints = {j.name: k.joint_coordinates(j) for j in model.tree_joints}
    kinetic = kinetic_energy(model, k.bodies)
    potential = potential_energy(model, k.bodies, {name: qv[0] for name, qv in joints.items()})
    nonconservative = ca.SX.zeros(k.nv)
    if has_nonconservative_forces(model):
        applied = generalized_forces(model, k.t, k.v, k.bodies, joints)
        nonconservative = applied + ca.gradient(potential, k.q)
    return kinetic, potential, nonconservative
