"""minimal-ode: the state-space (coordinate partitioning) and DAE treatments of a closed
loop describe the same motion, and the state-space form stays on the constraint manifold."""

import numpy as np
from scipy.integrate import solve_ivp

from workbench.equations.initial import consistent_initial_state
from workbench.plugin.registry import get_formalism, get_problem


def integrate(equations, problem, rtol):
    state = consistent_initial_state(equations, problem)
    ode = equations.forms["ode"]
    return solve_ivp(
        lambda t, y: ode.rhs(t, y)[0],
        (0.0, 1.0),
        state.y0(equations, "ode"),
        method="DOP853",
        rtol=rtol,
        atol=rtol,
    )


def test_state_space_agrees_with_index1_dae_and_holds_the_loop():
    problem = get_problem("slider-crank")()
    minimal = get_formalism("minimal-ode")()
    partitioned = minimal.build(problem.model(), {"loops": "state-space"})
    assert partitioned.nv == 1 and partitioned.n_constraints == 0
    assert "independent velocities" in partitioned.notes[0]
    dae = minimal.build(problem.model(), {"index": 1})
    a, b = integrate(partitioned, problem, 1e-10), integrate(dae, problem, 1e-11)
    nq = partitioned.nq
    poses_a = partitioned.observables.poses(1.0, a.y[:nq, -1])
    poses_b = dae.observables.poses(1.0, b.y[:nq, -1])
    assert np.abs(poses_a - poses_b).max() < 1e-7
    for t, y in zip(a.t, a.y.T, strict=True):
        position, velocity, _ = partitioned.observables.residuals(t, y[:nq], y[nq:])
        assert np.abs(position).max() < 1e-11 and np.abs(velocity).max() < 1e-9
    energy = [
        partitioned.observables.energy(t, y[:nq], y[nq:])[0].sum()
        for t, y in zip(a.t, a.y.T, strict=True)
    ]
    assert np.ptp(energy) < 1e-7 * abs(energy[0])


def test_forms_follow_the_options():
    minimal = get_formalism("minimal-ode")
    assert minimal.forms({"loops": "state-space"}) == {"ode": 0, "dae": 0, "mechanical": 0}
    assert "ode" not in minimal.forms({"index": 3})
    assert minimal.forms({"index": 1})["ode"] == 0
