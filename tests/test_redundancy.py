"""One rank and one assembly for all: describe, the formalisms and the initial state agree.

``workbench describe`` (mechanics.topology), absolute-dae and nonholonomic-projection all
decide redundancy with numerics.linalg.independent_rows, and topology, absolute-dae and
the initial state all assemble closed loops with numerics.linalg.gauss_newton.
"""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from workbench.equations.initial import project_joint_state
from workbench.errors import IntegrationError, ModelError
from workbench.mechanics.kinematics import TreeKinematics, quaternion_slices
from workbench.mechanics.topology import analyze, assemble
from workbench.model import Frame, Model
from workbench.plugin.registry import get_formalism
from workbench.plugins.formalisms.nonholonomic_projection import velocity_partition

from .test_absolute_dae import parallel_four_bar
from .test_topology import four_bar


def removed_rows(notes: list[str]) -> list[str]:
    prefix = "removed redundant constraint rows: "
    (line,) = [n for n in notes if n.startswith(prefix)]
    return line[len(prefix) :].split(", ")


def test_describe_and_formalisms_agree_on_the_redundant_rows_of_a_parallel_four_bar() -> None:
    model = four_bar("spatial")  # a parallelogram, assembled at its neutral configuration
    topology = analyze(model)
    assert topology.assembled
    assert topology.dof == 1
    assert len(topology.redundant_constraints) == 3
    assert topology.redundant_elements == ["closure"]

    equations = get_formalism("absolute-dae")().build(model)
    assert removed_rows(equations.notes) == topology.redundant_constraints

    kinematics = TreeKinematics(model)
    partition = velocity_partition(kinematics)
    kept = {kinematics.velocity_constraint_names[i] for i in partition.rows}
    redundant = [n for n in kinematics.velocity_constraint_names if n not in kept]
    assert redundant == topology.redundant_constraints
    assert partition.rows.size == topology.rank
    assert partition.independent.size == topology.dof

    with pytest.raises(ModelError, match="redundant closure"):
        get_formalism("minimal-ode")().build(model, {"loops": "state-space"})


def spherical_loop() -> Model:
    """A body hung from the origin by a spherical tree joint (quaternion coordinates), its
    point (0, 0, -1) held at the ground point (0, 0, -1) by a spherical cut joint: it can
    only turn about z (1 DOF)."""
    model = Model("spherical-loop", kind="spatial")
    model.add_body("body", 1.0, com=(0.0, 0.0, -0.5), inertia=(0.1, 0.1, 0.05))
    model.add_joint("hang", "spherical", "ground", "body")
    model.add_joint(
        "hold", "spherical", "body", "ground",
        parent_frame=Frame.at(0, 0, -1), child_frame=Frame.at(0, 0, -1), cut=True,
    )
    return model


def closure_residual(kinematics: TreeKinematics, q: np.ndarray) -> np.ndarray:
    g = ca.Function("g", [kinematics.t, kinematics.q], [kinematics.closure_constraints])
    return np.asarray(g(0.0, q)).ravel()


def test_assemble_moves_a_perturbed_loop_onto_its_constraints() -> None:
    model = spherical_loop()
    kinematics = TreeKinematics(model.validate())
    rng = np.random.default_rng(4)
    q0 = np.array([1.0, 0.0, 0.0, 0.0]) + rng.uniform(-0.2, 0.2, 4)
    assert np.abs(closure_residual(kinematics, q0 / np.linalg.norm(q0))).max() > 1e-2
    result = assemble(kinematics, q0)
    assert result.converged
    assert np.abs(closure_residual(kinematics, result.x)).max() <= 1e-12
    for part in quaternion_slices(kinematics):
        assert np.linalg.norm(result.x[part]) == pytest.approx(1.0, abs=1e-15)
    assert analyze(model, q=q0).assembled  # describe assembles the same way


def test_describe_assembles_a_four_bar_from_an_open_configuration() -> None:
    model = parallel_four_bar()
    kinematics = TreeKinematics(model.validate())
    q0 = np.array([0.3, -0.4, 0.2])
    topology = analyze(model, q=q0)
    assert topology.assembled
    assert np.abs(closure_residual(kinematics, topology.configuration)).max() <= 1e-12


def test_an_independent_coordinate_out_of_its_joint_is_refused() -> None:
    """("crank-joint", 1) of a revolute joint was column 1 of q: the coupler's angle was
    held instead of the crank's, and the run said ok."""
    kinematics = TreeKinematics(four_bar("planar").validate())
    problem = SimpleNamespace(name="four-bar", independent_coordinates=[("crank-joint", 1)])
    q0 = np.array([0.3, -0.3, 0.3])
    with pytest.raises(IntegrationError, match=r"\('crank-joint', 1\) is out of range: joint "
                       r"'crank-joint' has 1 coordinates; give an index from 0 to 0"):
        project_joint_state(kinematics, problem, 0.0, q0, np.zeros(3))


def test_holding_every_joint_of_a_loop_is_named_as_the_reason_it_cannot_close() -> None:
    """Three coordinates held in a one-DOF four-bar: not a matter of a better start."""
    kinematics = TreeKinematics(four_bar("planar").validate())
    every = [("crank-joint", 0), ("coupler-joint", 0), ("rocker-joint", 0)]
    q0 = np.array([0.3, 0.1, 0.0])  # the rocker should be at 0.3: the loop is open
    with pytest.raises(IntegrationError, match=r"the independent coordinates \(crank-joint\[0\], "
                       r"coupler-joint\[0\], rocker-joint\[0\]\) are held fixed, and the "
                       r"others can meet only 0 of the 2"):
        project_joint_state(kinematics, SimpleNamespace(name="four-bar",
                            independent_coordinates=every), 0.0, q0, np.zeros(3))  # fmt: skip


def test_initial_state_projection_keeps_the_independent_coordinate() -> None:
    model = parallel_four_bar()
    kinematics = TreeKinematics(model.validate())
    problem = SimpleNamespace(name="four-bar", independent_coordinates=[("j1", 0)])
    q0 = np.array([0.3, -0.4, 0.2])
    q, v = project_joint_state(kinematics, problem, 0.0, q0, np.array([1.0, 0.0, 0.0]))
    assert q[0] == q0[0]
    assert np.abs(closure_residual(kinematics, q)).max() <= 1e-12
    w = ca.Function("W", [kinematics.t, kinematics.q], [kinematics.velocity_constraint_matrix])
    assert np.abs(np.asarray(w(0.0, q)) @ v).max() <= 1e-10
    assert v[0] == 1.0
