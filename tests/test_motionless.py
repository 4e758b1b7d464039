"""A run whose state never leaves its initial value says so: a robot at rest in its
neutral pose hangs in equilibrium, every error is 0 and every pair scored 15 digits
with no warning but the reference's accuracy; a comparison of nothing."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import workbench as wb
from workbench.execution.audit import motionless_warning

HANGING_ARM = """<?xml version="1.0"?>
<robot name="arm2">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0 0 -0.25"/><mass value="1.0"/>
    <inertia ixx="0.021" iyy="0.021" izz="0.0005" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0 0 -0.2"/><mass value="0.8"/>
    <inertia ixx="0.0108" iyy="0.0108" izz="0.0004" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 -0.5"/><axis xyz="0 1 0"/></joint>
</robot>
"""


@pytest.fixture
def arm(tmp_path: Path) -> Path:
    path = tmp_path / "arm2.urdf"
    path.write_text(HANGING_ARM)
    return path


def test_a_robot_at_rest_hanging_down_is_flagged(arm: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        row = wb.run(str(arm), "recursive", "sundials-cvode-bdf", rtol=1e-6).row
    assert row["status"] == "ok" and row["err_max"] == 0.0  # nothing to be wrong about
    assert "nothing moved" in row["warnings"] and "q0 / v0" in row["warnings"]


def test_a_robot_that_swings_is_not(arm: Path) -> None:
    row = wb.run(str(arm), "recursive", "sundials-cvode-bdf", rtol=1e-6,
                 q0={"shoulder": 0.6, "elbow": -0.3}, t_end=1.0).row  # fmt: skip
    assert row["status"] == "ok" and row["err_max"] > 0
    assert "nothing moved" not in row["warnings"]


def test_the_rule_on_states() -> None:
    still = np.tile([0.0, 1.5, 0.0, 0.0], (50, 1))
    assert motionless_warning(still) is not None
    assert motionless_warning(still[:1]) is None  # one sample: nothing integrated
    moved = still.copy()
    moved[-1, 0] = 1e-9  # the least motion counts
    assert motionless_warning(moved) is None
    rounding = still.copy()
    rounding[:, 1] += np.linspace(0, 1e-13, 50)  # round-off of a state of size 1.5
    assert motionless_warning(rounding) is not None
    assert motionless_warning(np.full((3, 2), np.nan)) is None  # a failed run: its own note
