"""The articulated-body algorithm through joint-type kernels (bounded generated code)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from tests.test_recursive import random_body, random_frame, random_state
from workbench.equations import compiled
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import AppliedForce, JointForce, JointSpringDamper, Model, SpringDamper
from workbench.plugin.registry import get_formalism
from workbench.plugins.formalisms import recursive as rec
from workbench.plugins.formalisms import recursive_kernels as rk


def kernel_tree(n: int, seed: int, forces: bool = True) -> Model:
    """A free base, then every joint type that has a kernel (fixed included) on random
    parents, rotated frames, full inertias; springs, joint and applied forces."""
    rng = np.random.default_rng(seed)
    model = Model(f"kernel-tree-{n}-{seed}", kind="spatial")
    random_body(model, "b0", rng, point_mass=False)
    model.add_joint("j0", "free", "ground", "b0", child_frame=random_frame(rng))
    kinds = ("revolute", "prismatic", "spherical", "fixed", "revolute")
    for i in range(1, n):
        random_body(model, f"b{i}", rng, point_mass=False)
        model.add_joint(f"j{i}", kinds[i % len(kinds)], f"b{rng.integers(i)}", f"b{i}",
                        parent_frame=random_frame(rng), child_frame=random_frame(rng),
                        axis=rng.standard_normal(3))  # fmt: skip
    if forces:
        model.add_force(SpringDamper("spring", "b0", np.array([0.1, 0, 0]), f"b{n - 1}",
                                     np.zeros(3), stiffness=20.0, damping=0.5,
                                     rest_length=0.2))  # fmt: skip
        model.add_force(JointSpringDamper("joint-spring", "j1", 5.0, 0.3, rest=0.1))
        model.add_force(JointForce("motor", "j1", lambda t, q, v: ca.sin(t) - 0.2 * q))
        model.add_force(AppliedForce(
            "push", "b1", np.array([0.1, 0.2, 0.0]),
            lambda t, r, rot, vel, omega: (ca.vertcat(1.0, -0.5, 0.3 * ca.cos(t)) - 0.1 * vel,
                                           ca.vertcat(0.0, 0.2, 0.0) - 0.05 * omega),
        ))  # fmt: skip
    return model.validate()


@pytest.mark.parametrize(("n", "seed", "forces"), [(3, 0, True), (9, 1, True), (14, 2, False)])
def test_kernels_give_the_unrolled_accelerations(n: int, seed: int, forces: bool) -> None:
    model = kernel_tree(n, seed, forces)
    assert rk.supports(model)
    unrolled, kernels = rec.ode_function(model), rec.ode_function(model, kernels=True)
    assert kernels.is_a("MXFunction")
    rng = np.random.default_rng(seed)
    k = TreeKinematics(model)
    for _ in range(3):
        y = random_state(k, rng)
        expected = np.asarray(unrolled(0.7, y)).ravel()
        actual = np.asarray(kernels(0.7, y)).ravel()
        assert np.max(np.abs(actual - expected)) <= 1e-12 * max(1.0, np.max(np.abs(expected)))


def test_kernel_code_grows_by_a_few_lines_a_link() -> None:
    """The generated C of the kernels' graph grows with the links by far less than the
    unrolled graph's (whose every link's instructions are written out): the point."""

    def code_bytes(n: int, kernels: bool) -> int:
        function = rec.ode_function(kernel_tree(n, 3, forces=False), kernels=kernels)
        return len(compiled.generate_c(compiled.exported(function)))

    kernel_growth = code_bytes(30, True) - code_bytes(10, True)
    unrolled_growth = code_bytes(30, False) - code_bytes(10, False)
    assert 0 < kernel_growth < 0.4 * unrolled_growth


def test_unsupported_joint_types_keep_the_unrolled_graph() -> None:
    model = Model("universal", kind="spatial")
    model.add_body("b", 1.0, inertia=(0.1, 0.2, 0.3))
    model.add_joint("j", "universal", "ground", "b", axis=(1, 0, 0), axis2=(0, 1, 0))
    assert not rk.supports(model) and not rk.use_kernels(model, 10**9)
    assert rec.ode_function(model, kernels=None).is_a("SXFunction")


@pytest.mark.skipif(compiled.c_compiler() is None, reason="no C compiler")
def test_a_compiled_build_above_the_threshold_compiles_the_kernels(monkeypatch, tmp_path) -> None:
    """The formalism compiles the kernels' graph once the unrolled one is larger than the
    threshold (here lowered to 0), the VM keeps the unrolled one, and both agree."""
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path))
    monkeypatch.setattr(rk, "KERNELS_ABOVE_INSTRUCTIONS", 0)
    model = kernel_tree(6, 4)
    equations = get_formalism("recursive")().build(model, {"compile": "jit"})
    rhs = equations.forms["ode"].rhs
    assert rhs.for_c.is_a("MXFunction") and rhs.function.is_a("SXFunction")
    vm = get_formalism("recursive")().build(model, {"compile": "none"}).forms["ode"].rhs
    rng = np.random.default_rng(4)
    for _ in range(3):
        y = random_state(TreeKinematics(model), rng)
        expected = np.array(vm(0.3, y)[0])
        actual = np.array(rhs(0.3, y)[0])
        assert rhs.evaluated is not rhs.function  # ran in C
        assert np.max(np.abs(actual - expected)) <= 1e-12 * max(1.0, np.max(np.abs(expected)))
    assert not equations.compile_warnings


def test_the_kernels_compile_at_o2_and_the_entry_at_the_flags(monkeypatch, tmp_path) -> None:
    """The kernels (the functions the graph's entry calls) carry GCC's -O2 mark under the
    default flags, the entry does not; other flags apply to all; the numbers equal the
    VM's and an -O0 build's to 1e-12."""
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path))
    model = kernel_tree(9, 1)
    kernels, unrolled = rec.ode_function(model, kernels=True), rec.ode_function(model)
    code = compiled.generate(kernels).code
    marked = [line for line in code.splitlines() if line.startswith("WB_CALLEE static")]
    assert len(marked) >= 5 and not any("casadi_f0(" in line for line in marked)
    assert "WB_CALLEE" not in compiled.generate(kernels, "-O0").code
    assert "WB_CALLEE static" not in compiled.generate(unrolled).code  # one body, no callees
    y = random_state(TreeKinematics(model), np.random.default_rng(4))
    expected = np.asarray(kernels(0.7, y)).ravel()
    for flags in (compiled.DEFAULT_FLAGS, "-O0"):
        actual = np.asarray(compiled.compile_function(kernels, flags)(0.7, y)).ravel()
        assert np.max(np.abs(actual - expected)) <= 1e-12 * max(1.0, np.max(np.abs(expected)))


def test_the_kernels_keep_their_values_in_local_variables(monkeypatch, tmp_path) -> None:
    """The kernels' SX code keeps its values in local variables (which the compiler holds
    in registers), whole, not in CasADi's work array cut into parts: random tree N = 200
    36.0 -> 24.0 µs a call. The numbers equal the VM's bit for bit; the entry stays at
    -O1."""
    import re

    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path))
    model = kernel_tree(9, 1)
    kernels = rec.ode_function(model, kernels=True)
    assert compiled.uses_locals(kernels)
    generated = compiled.generate(kernels)
    bodies = re.split(r"^(?:WB_CALLEE )?static int casadi_f(\d+)\(", generated.code, flags=re.M)
    pairs = zip(bodies[1::2], bodies[2::2], strict=True)
    callees = [body for number, body in pairs if number != "0"]
    assert len(callees) >= 5 and "_part" not in generated.code
    assert not any("w[" in body.split("\n}\n")[0] for body in callees)
    assert generated.flags.split()[0] == "-O1"
    loaded = compiled.load_generated(generated)
    rng = np.random.default_rng(8)
    for _ in range(3):
        y = random_state(TreeKinematics(model), rng)
        assert np.array_equal(np.asarray(loaded(0.7, y)), np.asarray(kernels(0.7, y)))
