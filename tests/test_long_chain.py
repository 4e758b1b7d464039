"""Model checks scale as O(n) (issue 31, item 6): a serial chain of 10,000 links, built
in Python or read from a URDF, is validated, analysed and described in seconds. Before,
``validation._check_tree`` walked every body to the ground with a loop test on a list
(O(n^3): 0.8 s at 600 links, an hour at 10,000) and ``describe`` took the rank of the
empty constraint Jacobian through symbolic kinematics of the whole chain (superlinear).
No timing is asserted: the generous timeout is reached only by a hang."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.errors import ModelError
from workbench.mechanics.topology import analyze
from workbench.model import Frame, Model

LINKS = 10_000
pytestmark = pytest.mark.timeout(900)


def chain(n: int) -> Model:
    model = Model("chain")
    parent = "ground"
    for i in range(n):
        model.add_body(f"b{i}", 1.0, (0.05, 0.0, 0.0), (0.01, 0.01, 0.01))
        model.add_joint(f"j{i}", "revolute", parent, f"b{i}", Frame.at(0.1, 0.0, 0.0))
        parent = f"b{i}"
    return model


def chain_urdf(n: int) -> str:
    inertial = (
        '<inertial><origin xyz="0.05 0 0"/><mass value="1"/>'
        '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
    )
    parts = ['<robot name="chain">', '<link name="base"/>']
    for i in range(n):
        parent = "base" if i == 0 else f"l{i - 1}"
        parts.append(f'<link name="l{i}">{inertial}</link>')
        parts.append(
            f'<joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>'
            '<origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint>'
        )
    return "\n".join([*parts, "</robot>"])


def test_a_10000_link_chain_built_in_python_is_checked_and_analysed():
    model = chain(LINKS)
    topology = analyze(model)  # validates, then the tree and its rank
    assert topology.dof == LINKS and topology.rank == 0 and topology.n_loops == 0
    assert topology.depth[f"b{LINKS - 1}"] == LINKS
    assert len(topology.configuration) == LINKS


def test_the_linear_tree_check_still_finds_loops_and_detached_bodies():
    model = chain(50)
    model.add_body("lost", 1.0, inertia=(0.01, 0.01, 0.01))
    model.add_body("a", 1.0, inertia=(0.01, 0.01, 0.01))
    model.add_body("c", 1.0, inertia=(0.01, 0.01, 0.01))
    model.add_joint("a-c", "revolute", "a", "c")
    model.add_joint("c-a", "revolute", "c", "a")
    with pytest.raises(ModelError, match=r"body 'lost': it is not connected to 'ground'"):
        model.validate()
    del model.bodies["lost"]
    with pytest.raises(ModelError, match=r"body 'a': its tree joints form a closed loop"):
        model.validate()


def test_a_10000_link_urdf_is_described(tmp_path: Path):
    (tmp_path / "chain.urdf").write_text(chain_urdf(LINKS))
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    result = subprocess.run(
        [sys.executable, "-m", "workbench", "describe", "chain.urdf"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    dof = [line for line in result.stdout.splitlines() if "│ DOF" in line]
    assert dof and "10000" in dof[0], dof
