"""SciPy's solve_ivp raises an rtol below 100 machine epsilons to that floor and says so
only in a UserWarning, which a run (in its worker or ``workbench run``'s child) never
showed: rows at rtol 1e-15 and 1e-16 looked like two tolerances of a work-precision
curve and were the same integration. The row now warns that the accuracy asked was not
attempted, as the fixed-step methods do when the output interval overrides rtol."""

from __future__ import annotations

import warnings

from workbench.execution.execute import RunSpec, execute_run


def dop853(rtol: float) -> dict:
    spec = RunSpec("simple-pendulum", "minimal-ode", "scipy-dop853", rtol, 1e-18)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # SciPy's own, checked by the rows
        return execute_run(spec).row


def test_an_rtol_below_scipys_floor_is_the_floors_integration_and_is_warned() -> None:
    floor, below, tighter = dop853(2.3e-14), dop853(1e-15), dop853(1e-16)
    for row in (floor, below, tighter):
        assert row["status"] == "ok", row["message"]
    # the same integration: SciPy ran the two below its floor at the floor
    assert below["n_rhs"] == tighter["n_rhs"] and below["n_steps"] == tighter["n_steps"]
    assert below["err_end"] == tighter["err_end"]
    for row in (below, tighter):
        assert "the accuracy asked was not attempted: SciPy raises rtol" in row["warnings"]
        assert "to its least, 2.22e-14" in row["warnings"]
    assert "not attempted" not in floor["warnings"]


def test_scipy_dae_radau_below_its_floor_is_warned_too() -> None:
    spec = RunSpec("simple-pendulum", "minimal-ode", "scipy-dae-radau", 1e-16, 1e-18, {},
                   {"index": 1})  # fmt: skip
    row = execute_run(spec).row
    assert row["status"] == "ok", row["message"]
    assert "not attempted: scipy-dae raises rtol 1e-16 to its least, 2.22e-14" in row["warnings"]


def test_every_integrator_notes_an_rtol_below_100_machine_epsilons() -> None:
    """CVODE takes rtol 1e-14 as asked, where float64 rounding keeps any integrator from
    honouring it, and its row said nothing (qa3d F7); it now notes it, the same note as
    any other integrator's, and the run stays unwarned (recommendable)."""
    spec = RunSpec("simple-pendulum", "minimal-ode", "sundials-cvode-bdf", 1e-14, 1e-17)
    cvode = execute_run(spec).row
    assert cvode["status"] == "ok", cvode["message"]
    assert "rtol 1e-14 is below 100 machine epsilons (2.2e-14)" in cvode["notes"]
    assert "machine epsilons" not in cvode["warnings"]  # still recommendable
    for row in (dop853(1e-15), dop853(1e-16)):
        assert "is below 100 machine epsilons (2.2e-14)" in row["notes"]
    assert "machine epsilons" not in dop853(2.3e-14)["notes"]
