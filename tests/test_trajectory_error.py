"""A result row carries the error over the whole trajectory (L2 over the samples) beside
its maximum (L-infinity) and end value, and the step a fixed-step method took."""

from __future__ import annotations

import math

import numpy as np
import pytest

from workbench.execution.execute import RunSpec, execute_run


def test_l2_error_is_the_rms_of_the_series_and_fixed_step_follows_rtol(tmp_path) -> None:
    rows = {}
    for integrator, rtol in (("rk4", 1e-4), ("rk4", 1e-8), ("scipy-dop853", 1e-6)):
        result = execute_run(
            RunSpec("simple-pendulum", "minimal-ode", integrator, rtol, rtol * 1e-3)
        )
        assert result.row["status"] == "ok", result.row["message"]
        rows[(integrator, rtol)] = result
    for result in rows.values():
        row, errors = result.row, result.series["ref_err"].to_numpy()
        assert row["err_l2"] == np.sqrt(np.mean(errors**2))  # the L2 norm over the samples
        assert row["err_l2"] <= row["err_max"] and row["err_max"] == errors.max()
        assert row["err_end"] == errors[-1]
    # rk4's step from rtol, h = 1 ms (rtol / 1e-6)^(1/4), cut to divide the 0.05 s output
    # interval: the row records the step taken, 0.05 / ceil(0.05 / h)
    for rtol in (1e-4, 1e-8):
        asked = 1e-3 * (rtol / 1e-6) ** 0.25
        taken = 0.05 / math.ceil(0.05 / asked)
        assert rows[("rk4", rtol)].row["fixed_step_s"] == pytest.approx(taken, rel=1e-12)
        assert taken <= asked
    assert rows[("rk4", 1e-8)].row["err_l2"] < rows[("rk4", 1e-4)].row["err_l2"] / 10
    assert math.isnan(rows[("scipy-dop853", 1e-6)].row["fixed_step_s"])  # adaptive
