"""The energy error's normaliser is the one the row schema states (qa3d F8): with E0 = 0
(IFToMM A01 released at rest at the pivot's height) "relative to |E0|" means nothing,
and the columns are |E - E0| / S, S = max(T0 + |V0|, max over t of T)."""

from __future__ import annotations

import math

import numpy as np

import workbench
from workbench.execution.row_schema import ENERGY_ERROR, SCHEMA
from workbench.problems.iftomm import A01_LENGTH, A01_MASS, GRAVITY


def test_the_documented_normaliser_is_the_codes_on_a_problem_with_zero_initial_energy() -> None:
    described = dict(SCHEMA)["energy_err_max"]
    assert ENERGY_ERROR in described and "S = max(T0 + |V0|, max over t of T)" in described
    result = workbench.run("iftomm-a01", "minimal-ode", "scipy-dop853", rtol=1e-6, duration=4.0)
    trajectory = result.trajectory
    theta, omega = trajectory["pivot"].to_numpy(), trajectory["pivot.v"].to_numpy()
    kinetic = A01_MASS * A01_LENGTH**2 * omega**2 / 2  # point mass on a massless link
    potential = -A01_MASS * GRAVITY * A01_LENGTH * np.cos(theta)  # zero at the pivot's height
    energy = kinetic + potential
    assert abs(energy[0]) < 1e-12  # E0 = 0: a relative error to |E0| would be infinite
    scale = max(kinetic[0] + abs(potential[0]), kinetic.max())
    # the largest kinetic energy sampled: at most m g L, reached at the bottom
    assert 0.5 < scale / (A01_MASS * GRAVITY * A01_LENGTH) < 1 + 1e-6
    by_hand = np.abs(energy - energy[0]) / scale
    series = result.energy["energy_err"].to_numpy()
    np.testing.assert_allclose(series, by_hand, rtol=1e-6, atol=1e-15)
    assert math.isclose(result.row["energy_err_max"], by_hand.max(), rel_tol=1e-6)
    assert math.isclose(result.row["energy_err_final"], by_hand[-1], rel_tol=1e-6)
