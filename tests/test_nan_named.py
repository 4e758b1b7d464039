"""A right-hand side that turns NaN is named in the failed row by every adaptive solver,
not only by SciPy's: CVODE and IDA said "step size underflow at t = 0.5" and CasADi's
CVODES "too much work", for a formalism whose forces are sqrt(0.5 - t). A failure with
finite equations gets no such note."""

from __future__ import annotations

from pathlib import Path

import pytest

import workbench as wb
from tests.test_report_stalled import template_formalism
from tests.test_scaffold import isolated_registry  # noqa: F401 - a fixture


@pytest.fixture
def nan_after_half_a_second(tmp_path: Path, isolated_registry: None) -> type:  # noqa: F811
    """The scaffold's formalism with M = I and Q = sqrt(0.5 - t): NaN from t = 0.5 on."""
    return template_formalism(tmp_path, "nan-late", "ca.SX.zeros(k.nv) + ca.sqrt(0.5 - k.t)")


@pytest.mark.parametrize(
    "integrator, what",
    [("sundials-cvode-bdf", "right-hand side"), ("sundials-cvode-adams", "right-hand side"),
     ("sundials-ida", "residual"), ("casadi-cvodes", "right-hand side"),
     ("scipy-dop853", "right-hand side")],  # fmt: skip
)
def test_the_nan_is_named(nan_after_half_a_second, integrator, what) -> None:
    with pytest.warns(RuntimeWarning):
        row = wb.run("simple-pendulum", nan_after_half_a_second, integrator, rtol=1e-6).row
    assert row["status"] == "failed"
    assert f"the {what} " in row["message"] and "NaN or infinite" in row["message"]
    assert "t = 0.5" in row["message"], row["message"]


def test_a_failure_with_finite_equations_names_no_nan() -> None:
    with pytest.warns(RuntimeWarning):
        row = wb.run("simple-pendulum", "minimal-ode", "casadi-cvodes", rtol=1e-10,
                     max_num_steps=2).row  # fmt: skip
    assert row["status"] == "failed" and "TOO_MUCH_WORK" in row["message"]
    assert "NaN" not in row["message"]
