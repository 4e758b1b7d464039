"""Independent formalisms agree on every catalog problem they can both run: the time
derivative of every body's twist (linear and angular acceleration of its frame) at the
consistent initial state, computed exactly through CasADi from each formalism's own
coordinates, accelerations and kinematics."""

import casadi as ca
import numpy as np
import pytest

from workbench.initial import consistent_initial_state
from workbench.registry import get_formalism, list_plugins

REFERENCE = ("minimal-ode", {"index": 1})
OTHERS = [
    ("absolute-dae", {"index": 1}),
    ("recursive", {"index": 1}),
    ("nonholonomic-projection", {}),
]
SKIP_LARGE = {"binary-tree", "spatial-chain", "planar-chain"}  # covered by recursive tests


def body_accelerations(equations, state) -> np.ndarray:
    twists = equations.observables.twists.function
    t, q, v = ca.SX.sym("t"), ca.SX.sym("q", equations.nq), ca.SX.sym("v", equations.nv)
    twist = ca.vec(twists(t, q, v))
    qdot, a = ca.SX.sym("qd", equations.nq), ca.SX.sym("a", equations.nv)
    rate = ca.jacobian(twist, q) @ qdot + ca.jacobian(twist, v) @ a + ca.jacobian(twist, t)
    function = ca.Function("rate", [t, q, v, qdot, a], [rate])
    value = function(state.t0, state.q, state.v, state.qdot, state.acceleration)
    return np.asarray(value).ravel()


def problems() -> list[str]:
    return [
        info.name
        for info in list_plugins("problem")
        if info.plugin is not None and info.name not in SKIP_LARGE
    ]


@pytest.mark.parametrize("other", OTHERS, ids=[name for name, _ in OTHERS])
@pytest.mark.parametrize("name", problems())
def test_body_accelerations_agree_between_formalisms(name, other):
    problem = next(i.plugin for i in list_plugins("problem") if i.name == name)()
    model = problem.model()
    results = []
    for formalism_name, options in (REFERENCE, other):
        formalism = get_formalism(formalism_name)
        if formalism.unsupported(model):
            pytest.skip(f"{formalism_name} does not support {formalism.unsupported(model)}")
        equations = formalism().build(model, options)
        state = consistent_initial_state(equations, problem)
        results.append(
            (body_accelerations(equations, state), equations.observables.poses(state.t0, state.q))
        )
    (acc_a, poses_a), (acc_b, poses_b) = results
    assert np.allclose(poses_a, poses_b, atol=1e-10)
    scale = max(1.0, np.abs(acc_a).max())
    assert np.abs(acc_a - acc_b).max() <= 1e-9 * scale


NONHOLONOMIC = ["ball-on-rotating-plane", "knife-edge-cart", "rolling-pendulum"]


def poses_after(formalism_name: str, options: dict, problem, t_end: float) -> np.ndarray:
    from scipy.integrate import solve_ivp

    equations = get_formalism(formalism_name)().build(problem.model(), options)
    state = consistent_initial_state(equations, problem)
    ode = equations.forms["ode"]
    solution = solve_ivp(
        lambda t, y: ode.rhs(t, y)[0],
        (state.t0, t_end),
        state.y0(equations, "ode"),
        method="DOP853",
        rtol=1e-10,
        atol=1e-10,
    )
    assert solution.status == 0
    return equations.observables.poses(t_end, solution.y[: equations.nq, -1])


@pytest.mark.parametrize("name", NONHOLONOMIC)
def test_projection_and_absolute_coordinates_follow_the_same_motion(name):
    """Over a short horizon the two nonholonomic treatments give the same body poses."""
    problem = next(i.plugin for i in list_plugins("problem") if i.name == name)()
    projected = poses_after("nonholonomic-projection", {}, problem, 0.5)
    absolute = poses_after("absolute-dae", {"index": 1}, problem, 0.5)
    assert np.abs(projected - absolute).max() < 1e-7
