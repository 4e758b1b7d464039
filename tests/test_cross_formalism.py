"""absolute-dae and minimal-ode describe the same physics: same body accelerations and
the same motion from the same random consistent joint-space state.

The overconstrained parallel four-bar is left out: minimal-ode keeps its redundant
closure rows, so its augmented matrix is singular (absolute-dae removes them).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.test_absolute_dae import MODELS, accelerations, build, consistent_state

COMPARED = [name for name in MODELS if name != "parallel-four-bar"]


def twist_rates(eq, t: float, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """d/dt of every body's twist (6, n_bodies): d(twist)/dt + d(twist)/dq q' + d(twist)/dv v'."""
    function = eq.observables.twists.function
    t_sym, q_sym, v_sym = ca.MX.sym("t"), ca.MX.sym("q", q.size), ca.MX.sym("v", v.size)
    twists = ca.vec(function(t_sym, q_sym, v_sym))
    qdot = eq.forms["mechanical"].qdot(t, q, v)[0]
    rate = (
        ca.jtimes(twists, t_sym, ca.DM(1.0))
        + ca.jtimes(twists, q_sym, ca.DM(qdot))
        + ca.jtimes(twists, v_sym, ca.DM(a))
    )
    evaluate = ca.Function("twist_rate", [t_sym, q_sym, v_sym], [rate])
    return np.asarray(evaluate(t, q, v)).reshape(-1, 6).T


def states(name: str, seed: int, t: float):
    """Equations of both formalisms and one consistent state in each one's coordinates."""
    minimal = build(name, "minimal-ode", index=1)
    absolute = build(name, "absolute-dae", index=1)
    q_joint, v_joint = consistent_state(minimal.model, seed, t)
    q_abs, v_abs = absolute.joint_space_map(t, q_joint, v_joint)
    return (minimal, q_joint, v_joint), (absolute, q_abs, v_abs)


@pytest.mark.parametrize("seed", [11, 12, 13])
@pytest.mark.parametrize("name", COMPARED)
def test_same_body_accelerations(name: str, seed: int) -> None:
    t = 0.25
    rates = []
    for eq, q, v in states(name, seed, t):
        a, _ = accelerations(eq.forms["mechanical"], t, q, v)
        rates.append(twist_rates(eq, t, q, v, a))
    scale = max(1.0, np.abs(rates[0]).max())
    np.testing.assert_allclose(rates[1], rates[0], rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize("name", COMPARED)
def test_minimal_mass_matrix_symmetric_positive_definite(name: str) -> None:
    (minimal, q, v), _ = states(name, 21, 0.0)
    mass = minimal.forms["mechanical"].mass(0.0, q)[0].reshape(v.size, v.size)
    np.testing.assert_allclose(mass, mass.T, atol=1e-14)
    assert np.linalg.eigvalsh(mass).min() > 0.0


@pytest.mark.parametrize("name", COMPARED)
def test_same_motion_after_short_integration(name: str) -> None:
    t_end = 0.3
    end_frames = []
    for eq, q, v in states(name, 31, 0.0):
        ode = eq.forms["ode"]
        solution = solve_ivp(
            lambda t, y, ode=ode: ode.rhs(t, y)[0],
            (0.0, t_end),
            np.concatenate([q, v]),
            method="Radau",
            rtol=1e-10,
            atol=1e-12,
            jac=lambda t, y, ode=ode: ode.jacobian(t, y)[0],
        )
        assert solution.success, solution.message
        end_frames.append(eq.observables.frames(t_end, solution.y[: q.size, -1]))
    for a, b in zip(*end_frames, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-7)


@pytest.mark.parametrize("name", COMPARED)
def test_same_number_of_free_velocities(name: str) -> None:
    """nv - (constraint rows) agrees: no row lost or invented; only the four-bar had removals."""
    (minimal, _, _), (absolute, _, _) = states(name, 41, 0.0)
    assert absolute.nv - absolute.n_constraints == minimal.nv - minimal.n_constraints
    assert not any(note.startswith("removed") for note in absolute.notes)
