"""Independent formalisms agree on every catalog problem they can both run: body poses,
twists, energies and the time derivative of every body's twist at random consistent
states, computed exactly through CasADi from each formalism's own coordinates,
accelerations and kinematics (:func:`workbench.testing.check_formalism`, check group
"agreement", against minimal-ode)."""

import numpy as np
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.plugin.registry import get_formalism, list_plugins
from workbench.testing import check_formalism

OTHERS = [
    ("absolute-dae", {"index": 1}),
    ("recursive", {"index": 1}),
    ("nonholonomic-projection", {}),
    ("lagrange-ad", {"index": 1}),
    ("hamilton", {}),
]
SKIP_LARGE = {"binary-tree", "spatial-chain", "planar-chain"}  # covered by recursive tests


def problems() -> list[str]:
    return [
        info.name
        for info in list_plugins("problem")
        if info.plugin is not None and info.name not in SKIP_LARGE
    ]


@pytest.mark.parametrize("other", OTHERS, ids=[name for name, _ in OTHERS])
@pytest.mark.parametrize("name", problems())
def test_body_accelerations_agree_between_formalisms(name, other):
    formalism, options = other
    report = check_formalism(formalism, [name], options, checks=["agreement"], n_states=2)
    if any(r.check == "supported" for r in report.results):
        pytest.skip(report.results[-1].message)
    report.raise_if_failed()
    assert {r.check for r in report.results} >= {"observables", "accelerations"}


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
