"""MJCF models imported by workbench.model.importers.mjcf: every formalism that supports
the model gives MuJoCo's ``qacc`` (``mj_forward`` on the same file, contacts, limits,
equality constraints and actuation disabled, armature zeroed) at random states under random
generalized forces, to 1e-9 relative, and its mass matrix equals ``mj_fullM``.

Coordinates: a hinge or slide angle is ours + qpos0 (MuJoCo turns by qpos - qpos0); ball
and free coordinates and every velocity are the same numbers in MuJoCo and here (Euler
parameters scalar-first; ball and free angular velocities in the body frame, the free
linear velocity in the world). The joint springs and dampers of the file are imported and
left on in MuJoCo, so they are compared too.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from tests.test_urdf_peers import in_joint_coordinates
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import JointForce
from workbench.model.importers.mjcf import load_mjcf
from workbench.plugin.registry import get_formalism, plugin_names
from workbench.testing.states import body_accelerations, formalism_state

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is a dependency of the workbench")

ROBOTS = Path(__file__).parent / "robots"
MODELS = ["arm.xml", "floating.xml", "springs.xml"]
RELATIVE = 1e-9


@functools.cache
def imported(file: str):
    result = load_mjcf(ROBOTS / file)
    rng = np.random.default_rng(3)
    kinematics = TreeKinematics(result.model)
    for joint in kinematics.free_joints:
        _, v_slice = kinematics.joint_slices[joint.name]
        value = rng.uniform(-3.0, 3.0, v_slice.stop - v_slice.start)
        function = (
            (lambda t, q, v, c=float(value[0]): c)
            if value.size == 1
            else (lambda t, q, v, c=tuple(value): np.array(c))
        )
        result.model.add_force(JointForce(f"torque {joint.name}", joint.name, function))
    return result, kinematics


@functools.cache
def built(file: str, formalism: str):
    return get_formalism(formalism)().build(imported(file)[0].model)


def mujoco_model(file: str):
    model = mujoco.MjModel.from_xml_path(str(ROBOTS / file))
    disable = mujoco.mjtDisableBit
    for bit in ("mjDSBL_CONTACT", "mjDSBL_CONSTRAINT", "mjDSBL_LIMIT", "mjDSBL_ACTUATION"):
        model.opt.disableflags |= getattr(disable, bit)
    model.dof_armature[:] = 0.0
    model.dof_frictionloss[:] = 0.0
    return model


class MujocoMap:
    """Our joint state -> MuJoCo's qpos, qvel (indices by joint name)."""

    def __init__(self, file: str) -> None:
        self.imported, self.kinematics = imported(file)
        self.model = mujoco_model(file)
        self.slices = []
        for joint in self.kinematics.free_joints:
            theirs = self.model.joint(joint.name)
            q_slice, v_slice = self.kinematics.joint_slices[joint.name]
            qa, va = int(theirs.qposadr[0]), int(theirs.dofadr[0])
            their_q = slice(qa, qa + q_slice.stop - q_slice.start)
            their_v = slice(va, va + v_slice.stop - v_slice.start)
            offset = self.model.qpos0[their_q] if joint.type in ("revolute", "prismatic") else 0.0
            self.slices.append((q_slice, v_slice, their_q, their_v, offset))

    def state(self, q, v):
        qpos, qvel = np.zeros(self.model.nq), np.zeros(self.model.nv)
        for q_slice, v_slice, their_q, their_v, offset in self.slices:
            qpos[their_q], qvel[their_v] = q[q_slice] + offset, v[v_slice]
        return qpos, qvel

    def velocities(self, v):
        out = np.zeros(self.model.nv)
        for _, v_slice, _, their_v, _ in self.slices:
            out[their_v] = v[v_slice]
        return out

    def torques(self) -> np.ndarray:
        tau = np.zeros(self.kinematics.nv)
        for force in self.imported.model.forces:
            if isinstance(force, JointForce):
                _, v_slice = self.kinematics.joint_slices[force.joint]
                tau[v_slice] = force.function(0.0, None, None)
        return self.velocities(tau)

    def random_states(self, n: int = 3):
        rng = np.random.default_rng(17)
        for _ in range(n):
            q = np.zeros(self.kinematics.nq)
            for joint in self.kinematics.free_joints:
                q_slice, _ = self.kinematics.joint_slices[joint.name]
                size = q_slice.stop - q_slice.start
                values = rng.uniform(-1.5, 1.5, size)
                if joint.type in ("spherical", "free"):
                    values[-4:] /= np.linalg.norm(values[-4:])
                q[q_slice] = values
            yield q, rng.uniform(-2.0, 2.0, self.kinematics.nv)


def supporting(file: str) -> list[str]:
    model = imported(file)[0].model
    return [n for n in plugin_names("formalism") if not get_formalism(n).unsupported(model)]


@pytest.mark.parametrize("file", MODELS)
def test_every_formalism_equals_mujoco_qacc(file: str) -> None:
    peers = MujocoMap(file)
    data = mujoco.MjData(peers.model)
    compared = set()
    for q, v in peers.random_states():
        data.qpos[:], data.qvel[:] = peers.state(q, v)
        data.qfrc_applied[:] = peers.torques()
        mujoco.mj_forward(peers.model, data)
        expected = data.qacc.copy()
        scale = np.abs(expected).max()
        assert scale > 1.0
        reference = formalism_state(built(file, "recursive"), 0.0, q, v)
        for name in supporting(file):
            equations = built(file, name)
            state = formalism_state(equations, 0.0, q, v)
            if in_joint_coordinates(equations, q, v):
                ours = peers.velocities(state.acceleration)
                np.testing.assert_allclose(ours, expected, rtol=0, atol=RELATIVE * scale,
                                           err_msg=name)  # fmt: skip
            else:
                theirs = body_accelerations(built(file, "recursive"), reference)
                np.testing.assert_allclose(
                    body_accelerations(equations, state), theirs, rtol=0,
                    atol=RELATIVE * np.abs(theirs).max(), err_msg=name,
                )  # fmt: skip
            compared.add(name)
    assert "recursive" in compared and len(compared) == len(supporting(file))


@pytest.mark.parametrize("file", MODELS)
def test_mass_matrix_equals_mj_full_m(file: str) -> None:
    peers = MujocoMap(file)
    data = mujoco.MjData(peers.model)
    full = np.zeros((peers.model.nv, peers.model.nv))
    # their velocity index of each of ours
    index = peers.velocities(np.arange(peers.kinematics.nv, dtype=float)).astype(int)
    for q, v in peers.random_states():
        data.qpos[:], data.qvel[:] = peers.state(q, v)
        mujoco.mj_forward(peers.model, data)
        try:
            mujoco.mj_fullM(peers.model, data, full)  # MuJoCo 4: (m, d, dst)
        except TypeError:
            mujoco.mj_fullM(peers.model, full, data.qM)  # MuJoCo 3: (m, dst, qM)
        for name in supporting(file):
            equations = built(file, name)
            if "mechanical" not in equations.forms or not in_joint_coordinates(equations, q, v):
                continue
            (mass,) = equations.forms["mechanical"].mass(0.0, q)
            mass = np.reshape(mass, (v.size, v.size))
            np.testing.assert_allclose(
                mass[np.ix_(index, index)], full, rtol=0, atol=RELATIVE * np.abs(full).max(),
                err_msg=name,
            )  # fmt: skip


def test_quaternion_joint_springs_equal_mujoco_passive_forces_and_energy():
    """tests/robots/springs.xml: a free base and a ball joint with springs (about the
    compiled pose) and dampers, a hinge with springref. At random states the imported
    spring-dampers give MuJoCo's ``qfrc_passive`` (the rotation vector of the quaternion
    difference, ``mju_subQuat``; damping on every velocity), and the potential and kinetic
    energies of every formalism equal MuJoCo's (``mjENBL_ENERGY``: gravity and springs)."""
    import casadi as ca

    from workbench.mechanics.forces import joint_generalized_forces

    file = "springs.xml"
    peers = MujocoMap(file)
    model = peers.model
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    ours = load_mjcf(ROBOTS / file).model  # springs and dampers only, no random torques
    assert {force.joint for force in ours.forces} == {"root", "shoulder", "wrist"}
    for q, v in peers.random_states(5):
        data.qpos[:], data.qvel[:] = peers.state(q, v)
        mujoco.mj_forward(model, data)
        passive = np.zeros(peers.kinematics.nv)
        coordinates = {
            joint: (ca.DM(q[q_slice]), ca.DM(v[v_slice]))
            for joint, (q_slice, v_slice) in peers.kinematics.joint_slices.items()
        }
        for joint, force in joint_generalized_forces(ours, 0.0, coordinates).items():
            passive[peers.kinematics.joint_slices[joint][1]] = np.ravel(force)
        assert np.abs(data.qfrc_passive).max() > 1.0
        np.testing.assert_allclose(peers.velocities(passive), data.qfrc_passive, rtol=0,
                                   atol=1e-12 * np.abs(data.qfrc_passive).max())  # fmt: skip
        for name in supporting(file):
            equations = built(file, name)
            state = formalism_state(equations, 0.0, q, v)
            kinetic, potential = np.ravel(equations.observables.energy(0.0, state.q, state.v)[0])
            np.testing.assert_allclose([potential, kinetic], data.energy, rtol=1e-10,
                                       atol=1e-10, err_msg=name)  # fmt: skip
