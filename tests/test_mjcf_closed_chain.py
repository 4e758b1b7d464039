"""A closed chain from MJCF: the RSSR linkage of the catalog (problems/robot_files), whose
<connect> equality becomes a spherical loop-closing joint. Every formalism that handles
closed loops gives the same constraint-consistent body accelerations at assembled states
(to 1e-9 relative), and the imported model has the linkage's 2 degrees of freedom.

MuJoCo is not the oracle here: its equality constraints are soft (the constraint force
follows a spring-damper reference acceleration scaled by the impedance solimp < 1), so its
constrained qacc differs from the rigid one by an amount set by solref/solimp, not by
round-off (docs/robots.md gives the measured gap).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from workbench.mechanics.kinematics import TreeKinematics
from workbench.mechanics.topology import analyze
from workbench.plugin.registry import get_formalism, plugin_names
from workbench.plugin.robot_problem import RobotProblem
from workbench.testing.states import body_accelerations, formalism_state

pytest.importorskip("mujoco", reason="MuJoCo is a dependency of the workbench")

CRANK, ROCKER_PIVOT, ROCKER, COUPLER = (
    0.1,
    np.array([0.3, 0.2, 0.1]),
    0.15,
    np.array([0.2, 0.2, 0.25]),
)


@functools.cache
def problem() -> RobotProblem:
    from importlib import resources

    path = resources.files("workbench.problems").joinpath("robot_files/rssr_linkage.xml")
    return RobotProblem({"file": str(path)})


def assembled(theta: float, spin: float) -> np.ndarray:
    """Joint coordinates [crank, rocker, coupler Euler parameters] of the assembled linkage
    at crank angle theta: the rocker angle from |C - B| = |coupler|, the coupler turned
    from its rest direction onto C - B, then by ``spin`` about it."""
    b = CRANK * np.array([np.cos(theta), np.sin(theta), 0.0])

    def tip(phi: float) -> np.ndarray:
        return ROCKER_PIVOT + ROCKER * np.array([0.0, -np.sin(phi), np.cos(phi)])

    phi = brentq(lambda p: np.linalg.norm(tip(p) - b) - np.linalg.norm(COUPLER), -1.2, 1.2)
    crank = Rotation.from_rotvec([0.0, 0.0, theta])
    target = crank.inv().apply(tip(phi) - b)  # in the crank's frame
    turn, _ = Rotation.align_vectors([target], [COUPLER])
    coupler = Rotation.from_rotvec(spin * target / np.linalg.norm(target)) * turn
    x, y, z, w = coupler.as_quat()
    return np.array([theta, phi, w, x, y, z])


def states(model, n: int = 3):
    kinematics = TreeKinematics(model)
    assert [j.name for j in kinematics.order] == ["crank_joint", "rocker_joint", "coupler_joint"]
    w_matrix = kinematics.function("w", [kinematics.velocity_constraint_matrix])
    rng = np.random.default_rng(4)
    for _ in range(n):
        q = assembled(rng.uniform(-0.6, 0.6), rng.uniform(-1.0, 1.0))
        w = w_matrix(0.0, q, np.zeros(kinematics.nv))
        null = np.linalg.svd(np.atleast_2d(np.asarray(w)))[2][-2:]
        yield q, rng.uniform(-3, 3, 2) @ null


def test_rssr_linkage_imports_as_a_two_dof_closed_chain():
    model = problem().model()
    kinematics = TreeKinematics(model)
    assert [j.name for j in model.cut_joints] == ["closure"]
    assert model.joints["closure"].type == "spherical"
    closure = kinematics.function("g", [kinematics.closure_constraints])
    for q, _ in states(model):
        g = closure(0.0, q, np.zeros(kinematics.nv))
        assert np.abs(np.asarray(g)).max() < 1e-12
    assert analyze(model).dof == 2


def test_closed_loop_formalisms_agree_on_the_rssr_linkage():
    model = problem().model()
    names = [n for n in plugin_names("formalism") if not get_formalism(n).unsupported(model)]
    assert {"recursive", "minimal-ode", "absolute-dae"} <= set(names)
    built = {name: get_formalism(name)().build(model) for name in names}
    for q, v in states(model):
        reference = body_accelerations(
            built["minimal-ode"], formalism_state(built["minimal-ode"], 0.0, q, v)
        )
        scale = np.abs(reference).max()
        assert scale > 1.0
        for name, equations in built.items():
            ours = body_accelerations(equations, formalism_state(equations, 0.0, q, v))
            np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-9 * scale, err_msg=name)


def test_weld_becomes_a_fixed_cut_joint_at_the_compiled_relative_pose():
    """tests/robots/weld.xml: two bodies on ball joints welded by <weld>. The fixed cut
    joint closes at qpos0 (where MuJoCo compiled the relative pose), and at random
    configurations its position rows have the length of MuJoCo's own weld residual."""
    import mujoco

    from workbench.model.importers.mjcf import load_mjcf

    path = str(Path(__file__).parent / "robots" / "weld.xml")
    model = load_mjcf(path).model
    assert model.joints["w"].type == "fixed" and model.joints["w"].cut
    kinematics = TreeKinematics(model)
    closure = kinematics.function("g", [kinematics.closure_constraints])
    at_rest = np.array([1.0, 0, 0, 0, 1.0, 0, 0, 0])
    assert np.abs(np.asarray(closure(0.0, at_rest, np.zeros(6)))).max() < 1e-12
    theirs = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(theirs)
    rng = np.random.default_rng(2)
    for _ in range(3):
        q = rng.standard_normal(8)
        q[:4] /= np.linalg.norm(q[:4])
        q[4:] /= np.linalg.norm(q[4:])
        data.qpos[:] = q  # ball joints: the same Euler parameters in both
        mujoco.mj_forward(theirs, data)
        ours = np.asarray(closure(0.0, q, np.zeros(6))).ravel()
        assert np.linalg.norm(ours[:3]) == pytest.approx(np.linalg.norm(data.efc_pos[:3]), rel=1e-9)
