"""URDF robots of example-robot-data, imported by workbench.model.importers.urdf: every
formalism that supports the model gives the accelerations of Pinocchio's ``aba`` built from
the same file (``pin.buildModelFromUrdf``) at random states under random joint torques, to
1e-9 relative, and its mass matrix equals ``pin.crba``.

Formalisms in joint coordinates are compared with Pinocchio directly (coordinates mapped
by tests/robot_peers.py); the others (absolute coordinates, momenta) through the time
derivative of every body's twist, against the recursive formalism's, which is itself
checked against Pinocchio here.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from tests.robot_peers import PinocchioMap, example_robot, pinocchio_model, random_state
from workbench.model import JointForce
from workbench.model.importers.urdf import load_urdf
from workbench.plugin.registry import get_formalism, plugin_names
from workbench.testing.states import body_accelerations, formalism_state

LOCAL = Path(__file__).parent / "robots"
ROBOTS = {
    # name: (file in example-robot-data, or a Path of a test file, import options)
    "ur5": ("ur_description/urdf/ur5_robot.urdf", {}),  # 4 fixed joints (world, ee_link, ...)
    "panda": ("panda_description/urdf/panda.urdf", {"mimic": "independent"}),  # prismatic
    "solo12": ("solo_description/robots/solo12.urdf", {"floating_base": True}),  # free base
    "double-pendulum": (  # continuous joints
        "double_pendulum_description/urdf/double_pendulum_continuous.urdf",
        {},
    ),
    # a planar joint (axis z of a tilted joint frame) carrying a pendulum
    "planar-carriage": (LOCAL / "planar.urdf", {}),
}
# timed against pin.aba (benchmarks/peers_pyperf.py), checked here only by the recursive ABA
HUMANOID = {"talos": ("talos_data/robots/talos_reduced.urdf", {"floating_base": True})}
STATES = 3
RELATIVE = 1e-9


@functools.cache
def imported(robot: str, torques: bool = True):
    """The imported robot, with a constant random torque on every actuated joint."""
    relative, options = {**ROBOTS, **HUMANOID}[robot]
    if isinstance(relative, Path):  # a test file: its meshes (if any) beside it
        path, where = relative, {}
    else:  # example-robot-data: the folder holding the packages its meshes name
        path = example_robot(relative)
        where = {"package_path": [path.parents[len(Path(relative).parts) + 1]]}
    result = load_urdf(path, **where, **options)
    if torques:
        rng = np.random.default_rng(5)
        for joint in result.model.tree_joints:
            if joint.type == "planar":  # a force along x, y and a torque about z
                value = tuple(rng.uniform(-5.0, 5.0, 3))
                result.model.add_force(JointForce(
                    f"torque {joint.name}", joint.name, lambda t, q, v, c=value: np.array(c)
                ))  # fmt: skip
            elif joint.type != "free":
                value = float(rng.uniform(-5.0, 5.0))
                result.model.add_force(
                    JointForce(f"torque {joint.name}", joint.name, lambda t, q, v, c=value: c)
                )
    return result


@functools.cache
def built(robot: str, formalism: str):
    return get_formalism(formalism)().build(imported(robot).model)


def supporting(robot: str) -> list[str]:
    model = imported(robot).model
    return [
        name for name in plugin_names("formalism") if not get_formalism(name).unsupported(model)
    ]


def torque_vector(robot: str, peers: PinocchioMap) -> np.ndarray:
    tau = np.zeros(peers.kinematics.nv)
    for force in imported(robot).model.forces:
        _, v_slice = peers.kinematics.joint_slices[force.joint]
        tau[v_slice] = force.function(0.0, None, None)
    return tau


def states(robot: str, peers: PinocchioMap):
    rng = np.random.default_rng(11)
    for _ in range(STATES):
        yield random_state(peers.kinematics, rng)


def in_joint_coordinates(equations, q: np.ndarray, v: np.ndarray) -> bool:
    q_f, v_f = (np.ravel(x) for x in equations.joint_space_map(0.0, q, v))
    return (
        q_f.shape == q.shape
        and v_f.shape == v.shape
        and np.allclose(q_f, q)
        and np.allclose(v_f, v)
    )


@pytest.mark.parametrize("robot, most", [("solo12", 3_450), ("talos", 10_900)])
def test_the_legged_robots_aba_graph_stays_lean_and_equals_pinocchio_aba(
    robot: str, most: int
) -> None:
    """The recursive formalism's ode right-hand side of Solo12 and Talos (free base, aligned
    revolute joints, with joint torques): at most ``most`` CasADi instructions (3,690 and
    11,258 before the bias force went through the centre of mass, unit-column joints
    skipped D^-1 D and U^T a' and sums went on one triangle: 3,385 and 10,802), and v'
    equal to pin.aba's."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    from workbench.plugins.formalisms.recursive import ode_function

    function = ode_function(imported(robot).model)
    assert function.n_instructions() <= most
    peers = PinocchioMap(imported(robot), pinocchio_model(imported(robot)))
    data, tau = peers.pin_model.createData(), torque_vector(robot, peers)
    for q, v in states(robot, peers):
        q_pin, v_pin, t_matrix = peers.state(q, v)
        expected = pin.aba(peers.pin_model, data, q_pin, v_pin, t_matrix @ tau)
        rates = np.ravel(function(0.0, np.concatenate([q, v])))
        ours = peers.accelerations(q, v, rates[q.size :])
        np.testing.assert_allclose(ours, expected, rtol=0, atol=RELATIVE * np.abs(expected).max())


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_every_formalism_equals_pinocchio_aba(robot: str) -> None:
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    peers = PinocchioMap(imported(robot), pinocchio_model(imported(robot)))
    data = peers.pin_model.createData()
    formalisms = supporting(robot)
    assert "recursive" in formalisms
    compared = []
    for q, v in states(robot, peers):
        q_pin, v_pin, t_matrix = peers.state(q, v)
        tau_pin = t_matrix @ torque_vector(robot, peers)  # T orthogonal: T^-T = T
        expected = pin.aba(peers.pin_model, data, q_pin, v_pin, tau_pin)
        scale = np.abs(expected).max()
        assert scale > 1.0
        reference = formalism_state(built(robot, "recursive"), 0.0, q, v)
        for name in formalisms:
            equations = built(robot, name)
            state = formalism_state(equations, 0.0, q, v)
            if in_joint_coordinates(equations, q, v):
                ours = peers.accelerations(q, v, state.acceleration)
                np.testing.assert_allclose(
                    ours, expected, rtol=0, atol=RELATIVE * scale, err_msg=name
                )
                if "ode" in equations.forms:  # the formalism's own algorithm (e.g. ABA)
                    (f,) = equations.forms["ode"].rhs(0.0, np.concatenate([q, v]))
                    ours = peers.accelerations(q, v, np.ravel(f)[q.size :])
                    np.testing.assert_allclose(
                        ours, expected, rtol=0, atol=RELATIVE * scale, err_msg=name
                    )
            else:
                theirs = body_accelerations(built(robot, "recursive"), reference)
                ours = body_accelerations(equations, state)
                np.testing.assert_allclose(
                    ours, theirs, rtol=0, atol=RELATIVE * np.abs(theirs).max(), err_msg=name
                )
            compared.append(name)
    assert set(compared) == set(formalisms)


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_joint_space_mass_matrices_equal_pinocchio_crba(robot: str) -> None:
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    peers = PinocchioMap(imported(robot), pinocchio_model(imported(robot)))
    data = peers.pin_model.createData()
    checked = 0
    for q, v in states(robot, peers):
        q_pin, _, t_matrix = peers.state(q, v)
        upper = pin.crba(peers.pin_model, data, q_pin)
        expected = np.triu(upper) + np.triu(upper, 1).T
        for name in supporting(robot):
            equations = built(robot, name)
            if "mechanical" not in equations.forms or not in_joint_coordinates(equations, q, v):
                continue
            (mass,) = equations.forms["mechanical"].mass(0.0, q)
            mass = np.reshape(mass, (v.size, v.size))
            np.testing.assert_allclose(
                t_matrix @ mass @ t_matrix.T, expected, rtol=0,
                atol=RELATIVE * np.abs(expected).max(), err_msg=name,
            )  # fmt: skip
            checked += 1
    assert checked >= STATES


def test_a_planar_joint_moves_along_its_frames_x_and_y_as_pinocchio():
    """URDF planar joint, axis z: q = (x, y, angle) moves the child link along the joint
    frame's x and y and turns it about z, where Pinocchio's JointModelPlanar puts it."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    from workbench.mechanics import joints as jk

    robot = imported("planar-carriage", torques=False)
    peers = PinocchioMap(robot, pinocchio_model(robot))
    data = peers.pin_model.createData()
    joint = robot.model.joints["plane"]
    index = peers.pin_model.getJointId("plane")
    for q_joint in ([0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.3, -0.2, 1.1]):
        q = np.zeros(peers.kinematics.nq)
        q[peers.kinematics.joint_slices["plane"][0]] = q_joint
        q_pin, _, _ = peers.state(q, np.zeros(peers.kinematics.nv))
        pin.forwardKinematics(peers.pin_model, data, q_pin)
        offset, rotation = jk.relative_transform(joint, np.array(q_joint))
        frame = joint.parent_frame
        position = frame.position + frame.rotation @ np.ravel(np.asarray(offset, float))
        orientation = frame.rotation @ np.asarray(rotation, float) @ joint.child_frame.rotation.T
        np.testing.assert_allclose(position, data.oMi[index].translation, atol=1e-12)
        np.testing.assert_allclose(orientation, data.oMi[index].rotation, atol=1e-12)


# example-robot-data files that Pinocchio read and the workbench once refused: pr2 (a
# Gazebo <material value="PR2/..."> read as a number), so100 (a joint and a link named
# "gripper"), icub (links with a mass and a zero inertia: point masses), human (massless
# links between the joints of its gimbals)
ONCE_REFUSED = [
    "human_description/robots/human.urdf",
    "pr2_description/urdf/pr2.urdf",
    "so_arm_description/urdf/so100.urdf",
    "icub_description/robots/icub.urdf",
    "icub_description/robots/icub_reduced.urdf",
]


@pytest.mark.parametrize("relative", ONCE_REFUSED)
def test_once_refused_robots_equal_pinocchio_aba_and_crba(relative: str) -> None:
    """Imported as Pinocchio reads them (mimic joints independent, meshes not needed), the
    recursive formalism's accelerations equal ``pin.aba`` and its mass matrix ``pin.crba``
    at three random states under random joint torques, to 1e-9 relative."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    robot = load_urdf(example_robot(relative), mimic="independent", meshes=False)
    peers = PinocchioMap(robot, pinocchio_model(robot))
    equations = get_formalism("recursive")().build(robot.model)
    data = peers.pin_model.createData()
    rng = np.random.default_rng(23)
    for _ in range(STATES):
        q, v = random_state(peers.kinematics, rng)
        q_pin, v_pin, t_matrix = peers.state(q, v)
        expected = pin.aba(peers.pin_model, data, q_pin, v_pin, np.zeros(peers.pin_model.nv))
        ours = peers.accelerations(q, v, formalism_state(equations, 0.0, q, v).acceleration)
        np.testing.assert_allclose(ours, expected, rtol=0, atol=RELATIVE * np.abs(expected).max())
        upper = pin.crba(peers.pin_model, data, q_pin)
        (mass,) = equations.forms["mechanical"].mass(0.0, q)
        mass = t_matrix @ np.reshape(mass, (v.size, v.size)) @ t_matrix.T
        full = np.triu(upper) + np.triu(upper, 1).T
        np.testing.assert_allclose(mass, full, rtol=0, atol=RELATIVE * np.abs(full).max())


# what the workbench still refuses of the URDFs Pinocchio builds, and why (docs/robots.md)
STILL_REFUSED = {
    # massless links at the end of a chain: Pinocchio builds them, but its aba is not finite
    "romeo_description/urdf/romeo.urdf": "has no mass",
    "romeo_description/urdf/romeo_laas_small.urdf": "has no mass",
    "romeo_description/urdf/romeo_small.urdf": "triangle inequality",  # impossible inertia
}


@pytest.mark.slow
def test_every_example_robot_pinocchio_builds_is_imported_or_refused_with_its_reason():
    """All URDFs of example-robot-data, read as Pinocchio reads them (the options the
    refusals advise): every file Pinocchio builds imports, except STILL_REFUSED, each
    refused in one line naming the link and its line (benchmarks/robot_import_share.py
    prints the shares and compares the dynamics)."""
    pytest.importorskip("pinocchio", reason="Pinocchio (pin) is in the test extra")
    from benchmarks.robot_import_share import as_pinocchio, pinocchio_reads, robots_folder

    root = robots_folder()
    refused = {}
    for path in sorted(root.rglob("*.urdf")):
        if not pinocchio_reads(path)[0]:
            continue
        robot, _, reason = as_pinocchio(path)
        if robot is None:
            refused[str(path.relative_to(root))] = reason
    assert set(refused) == set(STILL_REFUSED), refused
    for file, reason in refused.items():
        assert STILL_REFUSED[file] in reason and "(line " in reason and "\n" not in reason
