"""Mirrored computations of generated C paired into vector lanes (workbench/equations/lanes.py):
the pairs are found, and the library's numbers equal the VM's bit for bit."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from workbench.equations import compiled, lanes
from workbench.model import GROUND, Frame, Model


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path / "cache"))


def _limb(x: ca.SX, constants: np.ndarray) -> ca.SX:
    """A deep chain of products and sums of the inputs and ``constants``."""
    value = x[0]
    for k, c in enumerate(constants):
        value = value * x[1] + c * ca.sin(x[k % 2]) - value / (2 + x[0] * x[0])
    return value


def mirrored_function() -> ca.Function:
    """Two outputs of the same shape with other constants and inputs (a left and a right
    limb), a third of another shape."""
    x = ca.SX.sym("x", 4)
    left = _limb(x[0:2], np.linspace(0.3, 1.2, 8))
    right = _limb(x[2:4], -np.linspace(0.3, 1.2, 8))
    other = ca.exp(x[0]) * x[3]
    return ca.Function("mirrored", [x], [ca.vertcat(left, right, other)])


def loaded_library(function: ca.Function) -> ca.Function:
    generated = compiled.generate(function)
    return compiled.load_generated(generated)


def test_mirrored_outputs_run_in_vector_lanes_with_the_vms_numbers(cache) -> None:
    function = mirrored_function()
    code = compiled.generate_c(compiled.exported(function))
    assert lanes.VECTOR_TYPE in code
    # the chain's products, sums, differences and quotients are paired; sines are not
    assert code.count(f"  {lanes.VECTOR_TYPE} w") >= 5 * 8
    assert code.count("=sin(") == 16  # each a scalar call, its value packed into a lane
    loaded = loaded_library(function)
    for x in np.random.default_rng(1).uniform(-2, 2, (20, 4)):
        assert np.array_equal(np.asarray(loaded(x)), np.asarray(function(x)))


def test_a_body_without_mirrored_outputs_is_left_as_casadi_wrote_it() -> None:
    x = ca.SX.sym("x", 3)
    function = compiled.exported(ca.Function("plain", [x], [ca.vertcat(x[0] * x[1], ca.exp(x[2]))]))
    generator = ca.CodeGenerator(function.name(), {"with_header": False, "verbose": False})
    generator.add(function)
    assert compiled.generate_c(function) == generator.dump()
    assert lanes.REGISTER_ALLOCATION not in compiled.generate(function).flags
    assert lanes.pair_lanes("int main() { return 0; }") == "int main() { return 0; }"
    zero = compiled.exported(ca.Function("zero", [x], [ca.SX.zeros(2)]))  # no operation
    assert lanes.VECTOR_TYPE not in compiled.generate_c(zero)


def mirrored_legs() -> Model:
    """A free base with two legs of three revolute links mirrored in its x-z plane (the
    numbers differ in sign, the shape of the computation is the same)."""
    model = Model("mirrored-legs", kind="spatial")
    model.add_body("base", 5.0, com=[0.01, 0.0, 0.02], inertia=np.diag([0.1, 0.2, 0.15]))
    model.add_joint("root", "free", GROUND, "base")
    inertia = np.array([[0.02, 0.001, 0.002], [0.001, 0.025, 0.003], [0.002, 0.003, 0.015]])
    flip = np.diag([1.0, -1.0, 1.0])
    for side, sign in (("left", 1.0), ("right", -1.0)):
        parent = "base"
        for k, axis in enumerate(([0, 0, 1], [1, 0, 0], [0, 1, 0])):
            body = f"{side}{k}"
            mirror = np.eye(3) if sign > 0 else flip
            model.add_body(
                body, 1.0 + k, com=[0.01, sign * 0.02, -0.1], inertia=mirror @ inertia @ mirror
            )
            offset = [0.0, sign * 0.1, 0.0] if k == 0 else [0.02, sign * 0.01, -0.3]
            model.add_joint(
                f"{side}_{k}", "revolute", parent, body, parent_frame=Frame(offset), axis=axis
            )
            parent = body
    return model.validate()


def test_mirrored_legs_articulated_body_accelerations_in_lanes_equal_the_vm(cache) -> None:
    """The recursive formalism's ode right-hand side of a model with mirrored legs: the
    legs' operations are paired (fewer statements), the library's numbers are the VM's bit
    for bit."""
    from workbench.plugins.formalisms.recursive import ode_function

    function = ode_function(mirrored_legs())
    code = compiled.generate_c(compiled.exported(function))
    paired = code.count(f"  {lanes.VECTOR_TYPE} w")
    assert paired > 0.2 * function.n_instructions()
    generated = compiled.generate(function)
    assert generated.code == code and lanes.REGISTER_ALLOCATION in generated.flags
    loaded = compiled.load_generated(generated)
    rng = np.random.default_rng(3)
    for _ in range(10):
        y = rng.uniform(-1.5, 1.5, function.nnz_in(1))
        y[3:7] /= np.linalg.norm(y[3:7])
        assert np.array_equal(np.asarray(loaded(0.1, y)), np.asarray(function(0.1, y)))
