"""Spanning tree, loops and degrees of freedom (workbench.mechanics.topology)."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.errors import ModelError
from workbench.mechanics.topology import analyze
from workbench.model import Drive, Frame, KnifeEdge, Model, RollingSphere

CUBE = np.diag([0.1, 0.1, 0.1])


def four_bar(kind: str) -> Model:
    """A unit-square parallelogram four-bar, closed at the neutral coordinates.

    crank (ground pivot (0, 0)) and rocker (ground pivot (1, 0)) point along their body y
    axes, the coupler along its x axis; the cut revolute joins coupler end and rocker end.
    """
    model = Model(f"four-bar-{kind}", kind=kind)
    inertia = 0.1 if kind == "planar" else CUBE
    for name in ("crank", "coupler", "rocker"):
        model.add_body(name, 1.0, inertia=inertia)
    model.add_joint("crank-joint", "revolute", "ground", "crank")
    model.add_joint("coupler-joint", "revolute", "crank", "coupler", parent_frame=Frame.at(0, 1, 0))
    model.add_joint("rocker-joint", "revolute", "ground", "rocker", parent_frame=Frame.at(1, 0, 0))
    model.add_joint(
        "closure",
        "revolute",
        "coupler",
        "rocker",
        cut=True,
        parent_frame=Frame.at(1, 0, 0),
        child_frame=Frame.at(0, 1, 0),
    )
    return model


def chain(kind: str, types: list[str]) -> Model:
    model = Model("chain", kind=kind)
    parent = "ground"
    for i, joint_type in enumerate(types):
        model.add_body(f"b{i}", 1.0, com=(0, -0.5, 0), inertia=0.1 if kind == "planar" else CUBE)
        frame = Frame() if parent == "ground" else Frame.at(0, -1, 0)
        model.add_joint(
            f"j{i}",
            joint_type,
            parent,
            f"b{i}",
            parent_frame=frame,
            axis=(1, 0, 0) if joint_type == "prismatic" else (0, 0, 1),
        )
        parent = f"b{i}"
    return model


def test_spanning_tree_of_a_branched_model() -> None:
    model = chain("spatial", ["revolute", "revolute"])
    model.add_body("side", 1.0, inertia=CUBE)
    model.add_joint("side-joint", "spherical", "b0", "side")
    model.add_body("top", 1.0, inertia=CUBE)
    model.add_joint("top-joint", "free", "ground", "top")
    topology = analyze(model)
    assert topology.tree_joints == ["j0", "j1", "side-joint", "top-joint"]
    assert topology.cut_joints == [] and topology.loops == [] and topology.n_loops == 0
    assert topology.parent_of == {"b0": "ground", "b1": "b0", "side": "b0", "top": "ground"}
    assert topology.parent_joint["side"] == "side-joint"
    assert topology.depth == {"b0": 1, "top": 1, "b1": 2, "side": 2}
    order = topology.body_order
    assert sorted(order) == sorted(model.bodies)
    for body, parent in topology.parent_of.items():
        assert parent == "ground" or order.index(parent) < order.index(body)
    assert topology.dof_gruebler == 1 + 1 + 3 + 6 == topology.dof
    assert topology.redundant_constraints == []


@pytest.mark.parametrize(
    ("kind", "types", "dof"),
    [
        ("planar", ["revolute"], 1),
        ("planar", ["revolute", "revolute", "revolute"], 3),
        ("planar", ["prismatic", "revolute", "planar"], 5),
        ("spatial", ["spherical", "universal", "prismatic"], 6),
        ("spatial", ["cylindrical", "fixed", "free"], 8),
    ],
)
def test_gruebler_count_of_chains(kind: str, types: list[str], dof: int) -> None:
    topology = analyze(chain(kind, types))
    assert topology.dof_gruebler == dof
    assert topology.dof == dof
    assert topology.n_holonomic == 0 and topology.n_nonholonomic == 0


def test_driven_joint_contributes_no_dof() -> None:
    model = chain("planar", ["revolute", "revolute"])
    model.add_body("arm", 1.0, inertia=0.1)
    drive = Drive(lambda t: 0.5 * t, lambda t: 0.5, lambda t: 0.0)
    model.add_joint("motor", "revolute", "b1", "arm", drive=drive)
    topology = analyze(model)
    assert topology.dof_gruebler == 2 == topology.dof


def test_planar_four_bar() -> None:
    topology = analyze(four_bar("planar"))
    assert topology.cut_joints == ["closure"]
    assert topology.n_loops == 1
    assert topology.loops == [["closure", "coupler-joint", "crank-joint", "rocker-joint"]]
    assert topology.dof_gruebler == 3 - 2 == 1
    assert topology.dof == 1
    assert topology.rank == 2
    assert topology.assembled is True
    assert topology.redundant_constraints == []


def test_spatial_four_bar_with_parallel_axes_is_overconstrained() -> None:
    topology = analyze(four_bar("spatial"))
    assert topology.dof_gruebler == 3 - 5 == -2
    assert topology.dof == 1
    assert topology.overconstrained
    assert len(topology.redundant_constraints) == 3
    assert all(name.startswith("closure[") for name in topology.redundant_constraints)
    assert topology.redundant_elements == ["closure"]
    assert "redundant" in topology.describe()


def test_four_bar_assembled_from_an_open_configuration() -> None:
    model = four_bar("planar")
    topology = analyze(model, q=np.array([0.3, -0.2, 0.1]))
    assert topology.assembled is True
    assert topology.dof == 1
    assert not np.allclose(topology.configuration, 0.0)


def test_wrong_number_of_coordinates() -> None:
    with pytest.raises(ModelError, match=r"got 2 coordinates, the tree has 3"):
        analyze(four_bar("planar"), q=np.zeros(2))


def test_loop_through_a_common_ancestor() -> None:
    model = chain("planar", ["revolute", "revolute", "revolute"])
    model.add_body("branch", 1.0, inertia=0.1)
    model.add_joint("branch-joint", "revolute", "b0", "branch", parent_frame=Frame.at(0, -1, 0))
    model.add_joint(
        "tie",
        "revolute",
        "b2",
        "branch",
        cut=True,
        parent_frame=Frame.at(0, -1, 0),
        child_frame=Frame.at(0, 2, 0),
    )
    topology = analyze(model, rank=False)
    assert topology.loops == [["tie", "j2", "j1", "branch-joint"]]
    assert topology.dof_gruebler == 4 - 2
    assert topology.dof is None


def test_cut_joint_to_ground() -> None:
    model = chain("planar", ["revolute", "revolute"])
    model.add_joint(
        "pin",
        "revolute",
        "b1",
        "ground",
        cut=True,
        parent_frame=Frame.at(0, -1, 0),
        child_frame=Frame.at(1, -1, 0),
    )
    topology = analyze(model)
    assert topology.assembled is True
    assert topology.loops == [["pin", "j1", "j0"]]
    assert topology.dof_gruebler == 0
    assert topology.dof == 0


def test_rolling_sphere_counts() -> None:
    model = Model("ball")
    model.add_body("ball", 1.0, inertia=(0.004, 0.004, 0.004))
    model.add_joint("float", "free", "ground", "ball")
    model.add_nonholonomic(RollingSphere("roll", "ball", 0.1))
    topology = analyze(model)
    assert topology.dof_gruebler == 6 - 1
    assert topology.n_holonomic == 1
    assert topology.n_nonholonomic == 2
    assert topology.assembled is True
    assert topology.dof == 6 - 3


def test_knife_edge_counts() -> None:
    model = Model("sled", kind="planar")
    model.add_body("sled", 1.0, inertia=0.1)
    model.add_joint("glide", "planar", "ground", "sled")
    model.add_nonholonomic(KnifeEdge("blade", "sled", np.zeros(3), np.array([0.0, 1.0, 0.0])))
    topology = analyze(model)
    assert topology.dof_gruebler == 3
    assert topology.n_nonholonomic == 1
    assert topology.dof == 2


def test_unconnected_body() -> None:
    model = four_bar("planar")
    model.add_body("lost", 1.0, inertia=0.1)
    with pytest.raises(ModelError, match=r"body 'lost'.*not connected to 'ground'"):
        analyze(model)


def test_body_with_two_parents() -> None:
    model = four_bar("planar")
    model.add_joint("second-parent", "revolute", "coupler", "rocker")
    with pytest.raises(ModelError, match=r"body 'rocker'.*child of two tree joints"):
        analyze(model)
