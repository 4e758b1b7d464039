"""Where a user meets imported robots: ``workbench describe FILE``, ``workbench run FILE``,
sweep entries ``{ urdf = PATH }`` / ``{ mjcf = PATH }`` relative to the specification, and
the "robot" problem's initial state (options q0 / v0, else the MJCF keyframe)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workbench.errors import ConfigError
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
from workbench.plugin.robot_problem import RobotProblem
from workbench.runs.sweep_spec import parse_spec

REPO = Path(__file__).resolve().parents[1]
ARM = REPO / "tests" / "robots" / "arm.xml"
HANG = 600  # seconds only a hung command reaches


def workbench(*args: str, cwd: Path = REPO) -> subprocess.CompletedProcess:
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    command = [sys.executable, "-m", "workbench", *args]
    return subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=HANG)


def test_describe_a_robot_file_lists_its_bodies_joints_and_dof():
    result = workbench("describe", str(ARM))
    assert result.returncode == 0, result.stderr
    fragments = ("robot (problem", "upper", "forearm", "wrist", "spherical", "DOF")
    # what the file holds beyond the model: the welded body, the limit, what is left out
    fragments += ("links welded", "sensor", "elbow -0.2 .. 0.2", "contacts are not modelled")
    for fragment in fragments:
        assert fragment in result.stdout


def test_run_a_robot_file_conserves_energy(tmp_path):
    """The free-floating MJCF body with two limbs (no dampers): a run from the file's
    folder finishes ok and its energy error is that of the integrator's tolerance."""
    shutil.copy(REPO / "tests" / "robots" / "floating.xml", tmp_path / "floating.xml")
    result = workbench(
        "run", "floating.xml", "-f", "recursive", "-i", "sundials-cvode-bdf", "--rtol", "1e-8",
        "-o", "t_end=0.3", "-o", "v0={hip1 = 2.0, root = [0, 0, 1, 0.5, 0, 0]}", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    rows = {}
    for line in result.stdout.splitlines():
        cells = [cell.strip() for cell in line.split("│") if cell.strip()]
        if len(cells) == 2:
            rows[cells[0]] = cells[1]
    assert rows["status"] == "ok", rows
    assert 0 < float(rows["energy_err_max"]) < 1e-5


def test_a_missing_robot_file_is_one_line(tmp_path):
    result = workbench("describe", "nowhere.urdf", cwd=tmp_path)
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "nowhere.urdf" in lines[0] and "not found" in lines[0]


def test_sweep_entries_resolve_paths_relative_to_the_spec(tmp_path, monkeypatch):
    (tmp_path / "robots").mkdir()
    shutil.copy(ARM, tmp_path / "robots" / "arm.xml")
    spec = tmp_path / "spec.toml"
    text = """problems = [{ mjcf = "robots/arm.xml", t_end = 0.5, q0 = { shoulder = 0.2 } }]
formalisms = ["recursive"]
integrators = ["sundials-cvode-bdf"]
tolerances = [1e-6]
"""
    spec.write_text(text)
    monkeypatch.chdir(REPO)  # not the spec's folder
    parsed = parse_spec(text, str(spec))
    (run,) = parsed.runs
    assert run.problem == "arm.xml[q0={shoulder:0.2},t_end=0.5]"
    assert run.problem_options["file"] == str((tmp_path / "robots" / "arm.xml").resolve())
    assert run.problem_options["t_end"] == 0.5
    with pytest.raises(ConfigError, match=r"problems\[0\]\.urdf.*not found"):
        parse_spec(text.replace('mjcf = "robots/arm.xml"', 'urdf = "robots/gone.urdf"'), str(spec))
    with pytest.raises(ConfigError, match="not a URDF file"):
        parse_spec(text.replace("mjcf =", "urdf ="), str(spec))
    # a file that does not read as a model, or a q0 naming no joint of it: refused before
    # any run (each run failed with it, and the sweep ended with exit code 0)
    with pytest.raises(ConfigError, match=r"line 1: problems\[0\]\.options: .*'elbw' is not a "
                       r"joint of arm.xml \(its joints: .*elbow"):  # fmt: skip
        parse_spec(text.replace("shoulder = 0.2", "elbw = 0.2"), str(spec))
    broken = tmp_path / "robots" / "broken.urdf"
    broken.write_text(
        '<robot name="r"><link name="a"/><joint name="j" type="revolute"><parent link="a"/>'
        '<child link="gone"/><axis xyz="0 0 1"/></joint></robot>'
    )
    unknown_link = r"problems\[0\]\.options: .*broken.urdf: joint 'j'.*'gone'"
    with pytest.raises(ConfigError, match=unknown_link):
        parse_spec(text.replace('mjcf = "robots/arm.xml"', 'urdf = "robots/broken.urdf"')
                   .replace(", q0 = { shoulder = 0.2 }", ""), str(spec))  # fmt: skip
    # `workbench run` alike: one line, exit 2, no run
    result = workbench("run", str(broken), "-f", "recursive", "-i", "scipy-dop853", cwd=tmp_path)
    assert result.returncode == 2 and "unknown child link 'gone'" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "run failed" not in result.stderr
    # `describe` says only that, without the robot problem's generic description first
    described = workbench("describe", str(broken), cwd=tmp_path)
    assert described.returncode == 2 and described.stdout == ""
    assert "unknown child link 'gone'" in described.stderr


def test_initial_state_from_options_or_keyframe():
    from importlib import resources

    linkage = str(resources.files("workbench.problems").joinpath("robot_files/rssr_linkage.xml"))
    problem = RobotProblem({"file": linkage})
    model = problem.model()
    kinematics = TreeKinematics(model)
    v0 = initial_joint_values(model, kinematics, problem.initial_joint_velocities(), True)
    assert v0[kinematics.joint_slices["crank_joint"][1]] == pytest.approx(3.0)  # the keyframe
    given = RobotProblem({"file": str(ARM), "q0": [0.1, 0.02, 1.0, 0.0, 0.0, 0.0, 0.3]})
    assert given.initial_joint_coordinates() == {
        "shoulder": 0.1, "elbow": 0.02, "wrist": [1.0, 0.0, 0.0, 0.0], "knuckle": 0.3,
    }  # fmt: skip
    with pytest.raises(ConfigError, match="'hip' is not a joint of arm.xml"):
        RobotProblem({"file": str(ARM), "q0": {"hip": 0.1}}).initial_joint_coordinates()
    with pytest.raises(ConfigError, match="3 values for 7"):
        RobotProblem({"file": str(ARM), "q0": [0.1, 0.2, 0.3]}).initial_joint_coordinates()
    q = initial_joint_values(model, kinematics, problem.initial_joint_coordinates(), False)
    assert np.all(np.isfinite(q))


def test_visual_meshes_reach_the_recording(tmp_path):
    """A URDF link's STL mesh becomes a mesh shape of its body (scaled, at the visual's
    origin) and an Asset3D in the Rerun recording; a COLLADA mesh goes through trimesh."""
    rr = pytest.importorskip("rerun")
    trimesh = pytest.importorskip("trimesh")
    from workbench.model.importers import load_robot
    from workbench.outputs.recording import _mesh_archetypes

    trimesh.creation.box(extents=(0.1, 0.2, 0.3)).export(tmp_path / "link.stl")
    (tmp_path / "robot.urdf").write_text(
        """<robot name="meshy"><link name="base"/>
<link name="arm"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>
<visual><origin xyz="0 0 0.5" rpy="0 0 1.5707963267948966"/>
<geometry><mesh filename="link.stl" scale="2 2 2"/></geometry></visual></link>
<joint name="j" type="continuous"><parent link="base"/><child link="arm"/></joint></robot>"""
    )
    model = load_robot(tmp_path / "robot.urdf").model
    (shape,) = model.bodies["arm"].shapes
    assert shape.kind == "mesh" and shape.size == (2.0, 2.0, 2.0)
    np.testing.assert_allclose(shape.frame.position, [0, 0, 0.5])
    np.testing.assert_allclose(shape.frame.rotation @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    (place, asset), warning = _mesh_archetypes(shape)
    assert not warning
    assert isinstance(asset, rr.Asset3D) and isinstance(place, rr.Transform3D)
    trimesh.creation.box(extents=(0.1, 0.2, 0.3)).export(tmp_path / "link.dae")
    (tmp_path / "robot.urdf").write_text(
        (tmp_path / "robot.urdf").read_text().replace(".stl", ".dae")
    )
    model = load_robot(tmp_path / "robot.urdf").model
    (_, mesh), _ = _mesh_archetypes(model.bodies["arm"].shapes[0])
    assert isinstance(mesh, rr.Mesh3D)


PLANAR_URDF = """<robot name="slider">
<link name="table"/>
<link name="puck"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>
<inertia ixx="0.1" iyy="0.2" izz="0.3" ixy="0.01"/></inertial></link>
<joint name="glide" type="{kind}"><parent link="table"/><child link="puck"/>
<origin xyz="0 0 1" rpy="0.2 0.1 0"/><axis xyz="{axis}"/></joint></robot>"""


@pytest.mark.parametrize(
    ("kind", "axis"),
    [
        ("planar", "0 0 1"),  # plane normal near z: gravity mostly normal to the plane
        ("planar", "0 1 0"),  # plane normal near y: the plane nearly holds the vertical
        ("floating", "1 0 0"),  # free fall
    ],
)
def test_planar_and_floating_urdf_joints_fall_as_they_should(tmp_path, kind, axis):
    """From rest, gravity acts at the centre of mass, so the puck does not start turning
    and its frame accelerates as gravity projected on the joint's plane (planar: the plane
    normal to the file's axis, tilted by the origin's rpy) or at g (floating)."""
    from scipy.spatial.transform import Rotation

    from workbench.model.importers import load_robot
    from workbench.plugin.registry import get_formalism
    from workbench.testing.states import body_accelerations, formalism_state

    (tmp_path / "slider.urdf").write_text(PLANAR_URDF.format(kind=kind, axis=axis))
    model = load_robot(tmp_path / "slider.urdf").model
    equations = get_formalism("recursive")().build(model)
    kinematics = TreeKinematics(model)
    q = initial_joint_values(model, kinematics, {}, False)
    state = formalism_state(equations, 0.0, q, np.zeros(kinematics.nv))
    rates = body_accelerations(equations, state).reshape(-1, 6)[0]
    gravity = np.array([0.0, 0.0, -9.81])
    want = gravity
    if kind == "planar":
        normal = Rotation.from_euler("xyz", [0.2, 0.1, 0.0]).as_matrix() @ np.array(
            [float(x) for x in axis.split()]
        )
        want = gravity - normal * (normal @ gravity)
    np.testing.assert_allclose(rates[:3], want, atol=1e-9)


def test_without_example_robot_data_the_robots_say_how_to_install_them(monkeypatch, tmp_path):
    """The URDF robots of the catalog need the robots extra; without it they stay registered
    (a sweep plans the same runs on every install) and each run is a skipped row naming
    the pip command. The missing package is simulated where the problems look for it."""
    pytest.importorskip("workbench.problems.robots", reason="example-robot-data missing")
    from workbench.errors import ModelError
    from workbench.execution.execute import RunSpec, execute_run
    from workbench.problems import robots

    assert robots.UR5().unavailable() is None  # installed: it runs
    monkeypatch.setattr(robots, "_ROBOTS", None)  # what the module keeps without the package
    for problem in (robots.UR5(), robots.Solo12()):
        assert 'pip install "mbs-workbench[robots]"' in problem.unavailable()
        with pytest.raises(ModelError, match=r"mbs-workbench\[robots\]"):
            problem.model()
    spec = RunSpec("ur5", "recursive", "scipy-dop853", 1e-4, 1e-7)
    row = execute_run(spec, reference_dir=tmp_path).row
    assert row["status"] == "skipped"
    assert 'not installed: pip install "mbs-workbench[robots]"' in row["message"]
    monkeypatch.setattr(robots, "_ROBOTS", tmp_path)  # the package without its files
    assert "has no ur_description/urdf/ur5_robot.urdf" in robots.UR5().unavailable()


def test_a_sweep_of_two_robots_gives_two_problems(tmp_path):
    """Each robot file is a problem of its own, named after the file (parent folders tell
    files of the same name apart) and the options set: in the rows, in `workbench results`
    and in the recording; a robot's name also finds the robot problem in the registry."""
    from workbench.plugin.registry import get_problem
    from workbench.runs.store import load_results

    for folder, source in (("arm", ARM), ("floating", REPO / "tests" / "robots" / "floating.xml")):
        (tmp_path / folder).mkdir()
        shutil.copy(source, tmp_path / folder / "robot.xml")
    (tmp_path / "spec.toml").write_text(
        'problems = [{ mjcf = "arm/robot.xml", t_end = 0.05 }, { mjcf = "floating/robot.xml" }]\n'
        'formalisms = ["recursive"]\nintegrators = ["sundials-cvode-bdf"]\ntolerances = [1e-4]\n'
    )
    parsed = parse_spec((tmp_path / "spec.toml").read_text(), str(tmp_path / "spec.toml"))
    names = ["arm/robot.xml[t_end=0.05]", "floating/robot.xml"]
    assert [run.problem for run in parsed.runs] == names
    assert get_problem("floating/robot.xml") is RobotProblem
    result = workbench("sweep", "spec.toml", "--out", "out", "--no-report", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    rows = load_results(tmp_path / "out")
    assert sorted(rows["problem"]) == names
    assert set(rows["status"]) == {"ok"}
    listed = workbench("results", "out", "--format", "csv", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    assert all(name in listed.stdout for name in names)


def test_meshes_false_imports_a_robot_whose_meshes_are_missing(tmp_path):
    """The advice of a missing mesh (import with meshes=False) is an option of the robot
    problem: ``-o meshes=false`` on the command line, ``meshes = false`` in a sweep entry."""
    (tmp_path / "robot.urdf").write_text(
        '<robot name="r"><link name="base"/><link name="arm"><inertial><mass value="1"/>'
        '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>'
        '<visual><geometry><mesh filename="meshes/gone.stl"/></geometry></visual></link>'
        '<joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>'
        '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/></joint></robot>'
    )
    refused = workbench("describe", "robot.urdf", cwd=tmp_path)
    assert refused.returncode != 0 and "meshes=False" in refused.stderr
    described = workbench("describe", "robot.urdf", "-o", "meshes=false", cwd=tmp_path)
    assert described.returncode == 0, described.stderr
    assert "shoulder" in described.stdout
    text = """problems = [{ urdf = "robot.urdf", meshes = false }]
formalisms = ["recursive"]
integrators = ["sundials-cvode-bdf"]
tolerances = [1e-6]
"""
    (tmp_path / "spec.toml").write_text(text)
    (run,) = parse_spec(text, str(tmp_path / "spec.toml")).runs
    assert run.problem == "robot.urdf[meshes=false]"
    assert RobotProblem(run.problem_options).model().bodies["arm"].mass == 1.0
