"""Bad robot files: each gives one ModelError line naming the element at fault (and, for
URDF, its line), never a traceback, a silent default or a dropped element."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.errors import ModelError
from workbench.model.importers import load_robot

pytest.importorskip("yourdfpy", reason="yourdfpy is a dependency of the workbench")

INERTIAL = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>'


def urdf(links: str = "", joints: str = "", arm: str = INERTIAL) -> str:
    return f"""<?xml version="1.0"?>
<robot name="bad">
  <link name="base"/>
  <link name="arm">{arm}</link>
  {links}
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
  </joint>
  {joints}
</robot>
"""


MJCF_BODY = '<body name="b"><joint name="h" axis="0 0 1"/><geom size="0.1"/></body>'


def mjcf(body: str = MJCF_BODY, extra: str = "") -> str:
    return f'<mujoco model="bad"><worldbody>{body}</worldbody>{extra}</mujoco>'


CASES = {
    # name: (file name, text, fragments the one line must contain)
    "missing inertia": (
        "robot.urdf",
        urdf(arm='<inertial><mass value="1"/></inertial>'),
        ["link 'arm' (line 4)", "no <inertia>"],
    ),
    "missing inertia component": (
        "robot.urdf",
        urdf(arm='<inertial><mass value="1"/><inertia ixx="1" iyy="1"/></inertial>'),
        ["link 'arm'", "<inertia> (line 4)", "no izz"],
    ),
    "zero mass": (
        "robot.urdf",
        urdf(arm='<inertial><mass value="0"/><inertia ixx="1" iyy="1" izz="1"/></inertial>'),
        ["link 'arm' (line 4)", "moves with joint 'shoulder'", "no mass", "moves nothing"],
    ),
    "no inertial on a moving link": (
        "robot.urdf",
        urdf(arm=""),
        ["link 'arm' (line 4)", "no mass"],
    ),
    "unknown joint type": (
        "robot.urdf",
        urdf(
            links=f'<link name="hand">{INERTIAL}</link>',
            joints='<joint name="wrist" type="ball"><parent link="arm"/><child link="hand"/>'
            "</joint>",
        ),
        ["joint 'wrist' (line 9)", "unknown joint type 'ball'"],
    ),
    "mimic joint": (
        "robot.urdf",
        urdf(
            links=f'<link name="hand">{INERTIAL}</link>',
            joints='<joint name="wrist" type="revolute"><parent link="arm"/><child link="hand"/>'
            '<mimic joint="shoulder" multiplier="2"/></joint>',
        ),
        ["joint 'wrist' (line 9)", "mimic", "mimic='independent'"],
    ),
    "broken XML": ("robot.urdf", urdf().replace("</robot>", "</robo>"), ["broken XML at line"]),
    "missing mesh": (
        "robot.urdf",
        urdf(
            arm=INERTIAL + '<visual><geometry><mesh filename="meshes/gone.stl"/></geometry>'
            "</visual>"
        ),
        ["link 'arm' (line 4)", "mesh 'meshes/gone.stl' not found"],
    ),  # fmt: skip
    "cycle": (
        "robot.urdf",
        urdf()
        .replace('<link name="base"/>', "")
        .replace('<parent link="base"/>', '<parent link="arm"/>')
        .replace('<child link="arm"/>', '<child link="arm2"/>')
        .replace(
            "</robot>",
            f'<link name="arm2">{INERTIAL}</link><joint name="back" '
            'type="revolute"><parent link="arm2"/><child link="arm"/></joint></robot>',
        ),
        ["cycle"],
    ),  # fmt: skip
    "unknown parent link": (
        "robot.urdf",
        urdf().replace('<parent link="base"/>', '<parent link="nowhere"/>'),
        ["joint 'shoulder' (line 6)", "unknown parent link 'nowhere'"],
    ),
    "NaN attribute": (
        "robot.urdf",
        urdf().replace('<axis xyz="0 0 1"/>', '<origin xyz="0 nan 0"/><axis xyz="0 0 1"/>'),
        ["joint 'shoulder'", "<origin> (line 7)", "xyz='0 nan 0'", "not a finite number"],
    ),
    "zero axis": (
        "robot.urdf",
        urdf().replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'),
        ["joint 'shoulder' (line 6)", "<axis> is zero"],
    ),
    "not a robot": ("robot.urdf", "<mujoco/>", ["root element is <mujoco>"]),
    "robot without a name": (
        "robot.urdf",
        urdf().replace('<robot name="bad">', "<robot>"),
        ["line 2", '<robot> has no name="..."'],
    ),
    "nothing moves": (
        "robot.urdf",
        urdf().replace('type="revolute"', 'type="fixed"'),
        ["link 'base' (line 3)", "no moving joint", "floating_base=True"],
    ),
    "impossible inertia": (
        "robot.urdf",
        urdf(arm='<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.5"/></inertial>'),
        ["link 'arm' (line 4)", "triangle inequality"],
    ),
    "unsupported MJCF element (tendon)": (
        "scene.xml",
        mjcf(
            '<body name="b"><joint name="h" axis="0 0 1"/><geom size="0.1"/>'
            '<site name="s1"/></body><site name="s0" pos="0 0 1"/>',
            '<tendon><spatial name="cable"><site site="s0"/><site site="s1"/></spatial></tendon>',
        ),
        ["tendon 'cable'", "cannot be represented"],
    ),
    "unsupported MJCF equality (joint)": (
        "scene.xml",
        mjcf(
            MJCF_BODY + '<body name="c"><joint name="k" axis="0 1 0"/><geom size="0.1"/></body>',
            '<equality><joint name="couple" joint1="h" joint2="k"/></equality>',
        ),
        ["equality 'couple' (joint)", "cannot be represented"],
    ),
    "MJCF body with two joints": (
        "scene.xml",
        mjcf(
            '<body name="b"><joint name="h1" axis="0 0 1"/><joint name="h2" axis="0 1 0"/>'
            '<geom size="0.1"/></body>'
        ),
        ["body 'b' has 2 joints (h1, h2)"],
    ),  # fmt: skip
    "unknown MJCF element": (
        "scene.xml",
        mjcf('<bodyy name="b"/>'),
        ["MuJoCo cannot compile it", "bodyy"],
    ),
    "MJCF armature": (
        "scene.xml",
        mjcf(MJCF_BODY.replace('axis="0 0 1"', 'axis="0 0 1" armature="0.01"')),
        ["joint 'h': armature 0.01", "rotor inertia", "drop=['armature']"],
    ),
    "MJCF frictionloss": (
        "scene.xml",
        mjcf(MJCF_BODY.replace('axis="0 0 1"', 'axis="0 0 1" frictionloss="0.2"')),
        ["joint 'h': frictionloss 0.2", "dry joint friction", "drop=['frictionloss']"],
    ),
    "MJCF gravity compensation": (
        "scene.xml",
        mjcf(MJCF_BODY.replace('<body name="b">', '<body name="b" gravcomp="1">')),
        ["body 'b': gravcomp 1", "drop=['gravcomp']"],
    ),
    "MJCF fluid forces": (
        "scene.xml",
        mjcf(extra='<option density="1.2"/>'),
        ["density 1.2", "fluid forces", "drop=['fluid']"],
    ),
    "massless MJCF body": (
        "scene.xml",
        mjcf('<body name="b"><joint name="h" axis="0 0 1"/></body>'),
        ["MuJoCo cannot compile it", "mass"],
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_bad_file_gives_one_line_naming_the_element(case: str, tmp_path: Path) -> None:
    name, text, fragments = CASES[case]
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ModelError) as raised:
        load_robot(path)
    message = str(raised.value)
    assert "\n" not in message, message
    assert str(path) in message, message
    for fragment in fragments:
        assert fragment in message, message


def test_the_command_line_prints_a_bad_file_as_one_line(tmp_path: Path) -> None:
    _, text, fragments = CASES["mimic joint"]
    (tmp_path / "robot.urdf").write_text(text)
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    result = subprocess.run(
        [sys.executable, "-m", "workbench", "describe", "robot.urdf"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert all(fragment in lines[0] for fragment in fragments), lines[0]


def test_mimic_joints_import_as_independent_joints_when_asked(tmp_path: Path) -> None:
    _, text, _ = CASES["mimic joint"]
    path = tmp_path / "robot.urdf"
    path.write_text(text)
    imported = load_robot(path, mimic="independent")
    assert [j.name for j in imported.model.tree_joints] == ["shoulder", "wrist"]


def test_an_mjcf_term_the_model_cannot_hold_is_left_out_only_when_asked(tmp_path: Path) -> None:
    """drop=[...] imports the file without the named terms and says so in the notes; an
    unknown name is refused with the list of names."""
    path = tmp_path / "scene.xml"
    path.write_text(
        mjcf(MJCF_BODY.replace('axis="0 0 1"', 'axis="0 0 1" armature="0.01" frictionloss="1"'))
    )
    with pytest.raises(ModelError, match="armature"):
        load_robot(path, drop=["frictionloss"])
    imported = load_robot(path, drop=["armature", "frictionloss"])
    assert any("armature 0.01: left out" in note for note in imported.notes)
    assert any("frictionloss 1: left out" in note for note in imported.notes)
    with pytest.raises(ModelError, match="'friction' is not a term.*armature, frictionloss"):
        load_robot(path, drop=["friction"])


def test_mjcf_switches_for_gravity_springs_and_dampers_are_honoured(tmp_path: Path) -> None:
    path = tmp_path / "scene.xml"
    body = MJCF_BODY.replace('axis="0 0 1"', 'axis="0 0 1" stiffness="3" damping="0.5"')
    path.write_text(mjcf(body, '<option><flag gravity="disable" spring="disable"/></option>'))
    model = load_robot(path).model
    assert not model.gravity.any()
    (spring,) = model.forces
    assert (spring.stiffness, spring.damping) == (0.0, 0.5)


def test_what_the_urdf_specification_allows_is_read(tmp_path: Path) -> None:
    """Read as Pinocchio reads them: a Gazebo extension's non-numeric ``value`` (PR2), a
    joint and a link of the same name (SO-100's "gripper"; the body takes the name
    gripper_link), a link with a mass and a zero inertia (iCub: a point mass at its
    centre of mass), a massless link between two joints (human.urdf's gimbals)."""
    text = urdf(
        links='<link name="gripper"><inertial><origin xyz="0.1 0 0"/><mass value="0.3"/>'
        '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>'
        '<gazebo reference="arm"><material value="Gazebo/Grey"/></gazebo>',
        joints='<joint name="gripper" type="revolute"><parent link="arm"/>'
        '<child link="gripper"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/></joint>',
    )
    text = text.replace(  # the arm becomes a massless link between two joints
        f'<link name="arm">{INERTIAL}</link>', '<link name="arm"/>'
    )
    path = tmp_path / "robot.urdf"
    path.write_text(text)
    imported = load_robot(path)
    model = imported.model
    assert model.bodies["arm"].point_mass and model.bodies["arm"].mass == 0.0
    assert imported.links["gripper"][0] == "gripper_link"
    assert model.joints["gripper"].child == "gripper_link"
    body = model.bodies["gripper_link"]
    assert body.point_mass and body.mass == 0.3 and list(body.com) == [0.1, 0.0, 0.0]


def test_an_mjcf_body_and_joint_may_share_a_name(tmp_path: Path) -> None:
    """MuJoCo names bodies and joints apart: the body becomes <name>_body."""
    path = tmp_path / "scene.xml"
    path.write_text(mjcf('<body name="arm"><joint name="arm" axis="0 1 0"/><geom size="0.1" '
                         'pos="0.2 0 0"/></body>'))  # fmt: skip
    imported = load_robot(path)
    assert imported.links["arm"][0] == "arm_body"
    assert imported.model.joints["arm"].child == "arm_body"
