"""A robot file reads only inside its box (issue 31, item 1; docs/robots.md "What a robot
file may read"): its own folder, the package roots the user names, the folders the user
allows. Each way out - ``../``, an absolute path, ``file://``, ``package://../`` and a
symbolic link inside the robot's folder pointing out - is one ModelError line naming the
element and where the reference leads, for URDF and MJCF alike; the outside file's bytes
reach neither the imported model nor a sweep's results folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.errors import ModelError
from workbench.model.importers import load_robot

pytest.importorskip("yourdfpy", reason="yourdfpy is a dependency of the workbench")
pytestmark = pytest.mark.timeout(900)  # only a hung command reaches it

SECRET = "SECRET-4f1c9d"  # in the outside file: must never reach a result
INERTIAL = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>'


def ascii_stl(name: str) -> str:
    """A one-triangle ASCII STL whose solid is named ``name`` (so its bytes are findable)."""
    return (
        f"solid {name}\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0.1 0 0\n"
        f"vertex 0 0.1 0\nendloop\nendfacet\nendsolid {name}\n"
    )


def obj_mesh() -> str:
    vertices = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\n"
    return f"# {SECRET}\n{vertices}f 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


@pytest.fixture
def box(tmp_path: Path) -> tuple[Path, Path]:
    """(the robot's folder, an outside folder holding the secret meshes)."""
    robot, outside = tmp_path / "robot", tmp_path / "outside"
    robot.mkdir()
    outside.mkdir()
    (outside / "secret.stl").write_text(ascii_stl(SECRET))
    (outside / "secret.obj").write_text(obj_mesh())
    (outside / "secret.xml").write_text(
        f'<mujoco><asset><mesh name="s" file="{outside / "secret.obj"}"/></asset></mujoco>'
    )
    (robot / "inside.stl").write_text(ascii_stl("inside"))
    (robot / "link.stl").symlink_to(outside / "secret.stl")
    (robot / "link.obj").symlink_to(outside / "secret.obj")
    return robot, outside


def urdf(mesh: str) -> str:
    return f"""<robot name="boxed"><link name="base"/>
<link name="arm">{INERTIAL}<visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
<joint name="j" type="continuous"><parent link="base"/><child link="arm"/></joint></robot>"""


def mjcf(asset: str = "", compiler: str = "", include: str = "") -> str:
    return f"""<mujoco model="boxed">{compiler}{include}<asset>{asset}</asset><worldbody>
<body name="b"><joint name="h" axis="0 0 1"/><geom size="0.1"/></body></worldbody></mujoco>"""


def urdf_attacks(outside: Path) -> dict[str, str]:
    return {
        "../": "../outside/secret.stl",
        "absolute path": str(outside / "secret.stl"),
        "file://": f"file://{outside / 'secret.stl'}",
        "package://../": "package://../outside/secret.stl",
        "package://robot/..": "package://robot/../outside/secret.stl",  # the robot folder
        "symlink inside": "link.stl",
    }


def mjcf_attacks(outside: Path) -> dict[str, str]:
    return {
        "../": mjcf('<mesh name="m" file="../outside/secret.obj"/>'),
        "absolute path": mjcf(f'<mesh name="m" file="{outside / "secret.obj"}"/>'),
        "file://": mjcf(f'<mesh name="m" file="file://{outside / "secret.obj"}"/>'),
        "meshdir outside": mjcf(
            '<mesh name="m" file="secret.obj"/>', compiler=f'<compiler meshdir="{outside}"/>'
        ),
        "include outside": mjcf(include='<include file="../outside/secret.xml"/>'),
        "symlink inside": mjcf('<mesh name="m" file="link.obj"/>'),
    }


@pytest.mark.parametrize("attack", list(urdf_attacks(Path("/x"))))
def test_a_urdf_mesh_outside_the_robot_folder_is_refused(attack, box):
    robot, outside = box
    reference = urdf_attacks(outside)[attack]
    (robot / "robot.urdf").write_text(urdf(reference))
    with pytest.raises(ModelError) as raised:
        load_robot(robot / "robot.urdf")
    message = str(raised.value)
    assert "\n" not in message and "link 'arm'" in message and repr(reference) in message
    assert ("outside" in message and "--allow-root" in message) or "package" in message
    if attack != "package://../":  # refused before it is resolved: it names no package
        assert str(outside.resolve() / "secret.stl") in message, message


@pytest.mark.parametrize("attack", list(mjcf_attacks(Path("/x"))))
def test_an_mjcf_file_reference_outside_the_robot_folder_is_refused(attack, box):
    """Checked before MuJoCo compiles: MuJoCo would read the file (and a mesh it cannot
    parse is its error, after the bytes were read)."""
    robot, outside = box
    (robot / "scene.xml").write_text(mjcf_attacks(outside)[attack])
    with pytest.raises(ModelError) as raised:
        load_robot(robot / "scene.xml")
    message = str(raised.value)
    assert "\n" not in message and "outside" in message and "--allow-root" in message, message
    assert str(robot / "scene.xml") in message and "(line " in message
    assert str(outside.resolve()) in message


def test_files_inside_and_named_roots_are_read(box, tmp_path, monkeypatch):
    """The box is not a cage: files in the robot's folder, in a package found through
    package_path or ROS_PACKAGE_PATH, or under an allowed root are read."""
    robot, outside = box
    (robot / "robot.urdf").write_text(urdf("inside.stl"))
    (shape,) = load_robot(robot / "robot.urdf").model.bodies["arm"].shapes
    assert shape.path == str((robot / "inside.stl").resolve())

    packages = tmp_path / "packages"
    (packages / "my_robot" / "meshes").mkdir(parents=True)
    (packages / "my_robot" / "meshes" / "arm.stl").write_text(ascii_stl("arm"))
    (robot / "robot.urdf").write_text(urdf("package://my_robot/meshes/arm.stl"))
    with pytest.raises(ModelError, match="package 'my_robot' looked for in"):
        load_robot(robot / "robot.urdf")
    imported = load_robot(robot / "robot.urdf", package_path=[packages])
    assert imported.meshes[0].path == (packages / "my_robot" / "meshes" / "arm.stl").resolve()
    monkeypatch.setenv("ROS_PACKAGE_PATH", f"/nonexistent{os.pathsep}{packages}")
    assert load_robot(robot / "robot.urdf").meshes[0].path == imported.meshes[0].path

    (robot / "robot.urdf").write_text(urdf(str(outside / "secret.stl")))
    allowed = load_robot(robot / "robot.urdf", allow_roots=[outside])
    assert allowed.meshes[0].path == (outside / "secret.stl").resolve()
    (robot / "scene.xml").write_text(mjcf('<mesh name="m" file="../outside/secret.obj"/>'))
    assert "b" in load_robot(robot / "scene.xml", allow_roots=[outside]).model.bodies


def test_only_regular_files_within_the_size_limit_are_read(box):
    robot, _ = box
    os.mkfifo(robot / "pipe.stl")  # opening it for reading would block forever
    (robot / "robot.urdf").write_text(urdf("pipe.stl"))
    with pytest.raises(ModelError, match="not a regular file"):
        load_robot(robot / "robot.urdf")
    (robot / "robot.urdf").write_text(urdf("inside.stl"))
    with pytest.raises(ModelError, match=r"more than the limit of 1e-05 MB.*max_file_mb"):
        load_robot(robot / "robot.urdf", max_file_mb=1e-5)  # 10 bytes
    (robot / "scene.xml").write_text(mjcf('<mesh name="m" file="inside.stl"/>'))
    with pytest.raises(ModelError, match="more than the limit"):
        load_robot(robot / "scene.xml", max_file_mb=1e-5)


def workbench(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    env.pop("ROS_PACKAGE_PATH", None)
    command = [sys.executable, "-m", "workbench", *args]
    return subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def test_a_sweep_of_an_attacking_robot_keeps_the_outside_bytes_out(box, tmp_path):
    """End to end: a sweep of a URDF whose mesh leads outside through a symbolic link is
    refused before any run, in one line naming the refusal (exit 2; it used to run and
    record every run as failed), and no file it wrote holds a byte of the outside file."""
    robot, _ = box
    (robot / "robot.urdf").write_text(urdf("link.stl"))
    spec = tmp_path / "spec.toml"
    spec.write_text(
        'problems = [{ urdf = "robot/robot.urdf", t_end = 0.05 }]\nformalisms = ["recursive"]\n'
        'integrators = ["scipy-dop853"]\ntolerances = [1e-4]\nout = "OUT"\n'
    )
    result = workbench("sweep", str(spec), cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "link.stl" in result.stderr
    assert "through a symbolic link" in result.stderr and "outside" in result.stderr
    files = [path for path in (tmp_path / "OUT").rglob("*") if path.is_file()]
    assert not [path for path in files if SECRET.encode() in path.read_bytes()]


def test_the_command_line_names_package_roots_and_allowed_folders(box, tmp_path):
    robot, outside = box
    packages = tmp_path / "packages"
    (packages / "my_robot").mkdir(parents=True)
    (packages / "my_robot" / "arm.stl").write_text(ascii_stl("arm"))
    (robot / "robot.urdf").write_text(urdf("package://my_robot/arm.stl"))
    refused = workbench("describe", "robot/robot.urdf", cwd=tmp_path)
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    assert "--package-path" in refused.stderr
    described = workbench(
        "describe", "robot/robot.urdf", "--package-path", "packages", cwd=tmp_path
    )
    assert described.returncode == 0, described.stderr
    # the model's row "meshes | 1" (the robot problem's option "meshes" is a row too)
    counts = [line.split("│")[2].strip() for line in described.stdout.splitlines()
              if line.startswith("│ meshes ")]  # fmt: skip
    assert "1" in counts


def test_a_sweep_entry_names_package_roots_relative_to_the_spec(box, tmp_path, monkeypatch):
    from workbench.runs.sweep_spec import parse_spec

    robot, _ = box
    (tmp_path / "packages" / "my_robot").mkdir(parents=True)
    (robot / "robot.urdf").write_text(urdf("inside.stl"))
    text = (
        'problems = [{ urdf = "robot/robot.urdf", package_path = ["packages", "robot"], '
        'allow_roots = ["outside"], max_file_mb = 5.0 }]\n'
        'formalisms = ["recursive"]\nintegrators = ["scipy-dop853"]\ntolerances = [1e-6]\n'
    )
    (tmp_path / "spec.toml").write_text(text)
    monkeypatch.chdir(robot)  # not the specification's folder
    (run,) = parse_spec(text, str(tmp_path / "spec.toml")).runs  # two folders, one run
    options = run.problem_options
    assert options["package_path"] == [str(tmp_path / "packages"), str(robot)]
    assert options["allow_roots"] == [str(tmp_path / "outside")]
    assert options["max_file_mb"] == 5.0
