"""MJCF numbers that are not finite are refused as in URDF (issue 31, item 8): MuJoCo's
compiler takes ``mass="nan"`` and puts a density-derived mass in its place, so the run
would be ``ok`` on a model the file does not describe. Checked in the XML before MuJoCo
compiles, in every numeric attribute, also in included files; one line naming the
element and the attribute."""

from __future__ import annotations

from pathlib import Path

import pytest

from workbench.errors import ModelError
from workbench.model.importers import load_robot

BODY = '<body name="b"><joint name="h" axis="0 0 1"/><geom name="g" size="0.1"/></body>'


def scene(body: str = BODY, extra: str = "") -> str:
    return f'<mujoco model="m">{extra}<worldbody>\n{body}</worldbody></mujoco>'


def edited(old: str, new: str) -> str:
    return scene(BODY.replace(old, new))


CASES = {
    # name: (text, the attribute as the message shows it, element)
    "mass nan": (edited('size="0.1"', 'size="0.1" mass="nan"'), "mass='nan'", "<geom name='g'>"),
    "pos inf": (edited('"b"', '"b" pos="0 inf 0"'), "pos='0 inf 0'", "<body name='b'>"),
    "axis -Infinity": (
        edited('axis="0 0 1"', 'axis="0 0 -Infinity"'), "axis='0 0 -Infinity'", "<joint name='h'>"
    ),
    "overflow 1e999": (edited('size="0.1"', 'size="1e999"'), "size='1e999'", "<geom name='g'>"),
    "damping NaN in a default": (
        scene(extra='<default><joint damping="NaN"/></default>'), "damping='NaN'", "<joint>",
    ),
    "gravity nan": (scene(extra='<option gravity="0 0 nan"/>'), "gravity='0 0 nan'", "<option>"),
    "inertial diaginertia": (
        edited("<joint", '<inertial pos="0 0 0" mass="1" diaginertia="1 nan 1"/><joint'),
        "diaginertia='1 nan 1'", "<inertial>",
    ),
}  # fmt: skip


def test_mujoco_itself_takes_a_nan_mass(tmp_path: Path, monkeypatch) -> None:
    """Why the check exists: the compiler accepts the file (it would be an ok run)."""
    mujoco = pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)  # MuJoCo's warning goes to MUJOCO_LOG.TXT in the folder
    text, _, _ = CASES["mass nan"]
    compiled = mujoco.MjModel.from_xml_string(text)
    assert compiled.body_mass[1] > 0


@pytest.mark.parametrize("case", list(CASES))
def test_a_non_finite_mjcf_number_is_one_line_naming_element_and_attribute(case, tmp_path):
    text, attribute, element = CASES[case]
    path = tmp_path / "scene.xml"
    path.write_text(text)
    with pytest.raises(ModelError) as raised:
        load_robot(path)
    message = str(raised.value)
    assert "\n" not in message and str(path) in message, message
    assert attribute in message and "not a finite number" in message, message
    assert element.replace("'", '"') in message.replace("'", '"'), message
    assert "(line " in message


def test_an_included_file_is_checked_too_and_names_stay_names(tmp_path: Path) -> None:
    (tmp_path / "part.xml").write_text('<mujoco><option timestep="nan"/></mujoco>')
    path = tmp_path / "scene.xml"
    path.write_text(scene(extra='<include file="part.xml"/>'))
    with pytest.raises(ModelError, match=r"part\.xml: <option> \(line 1\): timestep='nan'"):
        load_robot(path)
    # a body named "inf" and a joint named "nan" are names, not numbers
    named = BODY.replace('name="b"', 'name="inf"').replace('name="h"', 'name="nan"')
    path.write_text(scene(named))
    assert "inf" in load_robot(path).model.bodies
