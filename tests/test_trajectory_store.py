"""Trajectories in the results store: each run's states at its output samples, named by
the equations, beside its series; ``store_trajectories = false`` leaves them out."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.errors import ConfigError
from workbench.execution import row_schema
from workbench.execution.execute import RunSpec, execute_run, normalized_spec
from workbench.execution.timing import Timing
from workbench.runs import store
from workbench.runs.sweep import run_sweep
from workbench.runs.sweep_spec import parse_spec


class Keep:
    """A sink that keeps what the integrator returned and the equations it integrated."""

    def log_run(self, spec, equations, problem, trajectory, series):
        self.equations, self.trajectory = equations, trajectory


@pytest.mark.parametrize(
    ("problem", "formalism", "integrator", "form", "multipliers"),
    [
        ("test-pendulum", {"name": "minimal-ode", "index": 1}, "test-rk45", "ode", 0),
        # a loop in absolute coordinates, integrated as an index-1 DAE: lambda stored
        ("test-slider-crank", {"name": "absolute-dae", "index": 1}, "sundials-ida", "dae", 1),
        # the mechanical form: generalized-alpha carries [q, v, lambda]
        ("test-slider-crank", {"name": "absolute-dae", "index": 3}, "generalized-alpha",
         "mechanical", 1),
    ],  # fmt: skip
)
def test_stored_trajectory_is_what_the_integrator_returned(
    fake_plugins, tmp_path, problem, formalism, integrator, form, multipliers
) -> None:
    options = {k: v for k, v in formalism.items() if k != "name"}
    spec = normalized_spec(RunSpec(problem, formalism["name"], integrator, 1e-6, 1e-9, {}, options))
    sink = Keep()
    result = execute_run(spec, sink=sink, timing=Timing(repeats=1))
    assert result.row["status"] == "ok", result.row["message"]
    assert result.row["form"] == form
    store.write_run(tmp_path, result.row, result.series)

    trajectory = store.load_trajectory(tmp_path, spec.run_id)
    returned = np.atleast_2d(sink.trajectory.y)
    equations = sink.equations
    names = list(trajectory.columns[1:])
    # named by the equations: q, v, then one multiplier per constraint row
    assert names[: equations.nq + equations.nv] == equations.q_names + equations.v_names
    lambdas = [n for n in names if n.startswith("lambda:")]
    assert len(lambdas) == multipliers * equations.n_constraints
    assert lambdas == [f"lambda:{n}" for n in equations.constraint_names][: len(lambdas)]
    # the very numbers the integrator returned, at its output times
    np.testing.assert_array_equal(trajectory["t"].to_numpy(), np.asarray(sink.trajectory.times))
    np.testing.assert_array_equal(trajectory[names].to_numpy(), returned)
    # the series without states is the one it was; with them, the trajectory's columns too
    series = store.load_series(tmp_path, spec.run_id)
    assert list(series.columns) == row_schema.SERIES_COLUMNS
    full = store.load_series(tmp_path, spec.run_id, states=True)
    assert [c.removeprefix(row_schema.STATE_PREFIX) for c in full.columns[7:]] == names
    # a multiplier keeps a loop closed: it is not zero on a moving slider-crank
    if multipliers:
        assert np.abs(trajectory[lambdas].to_numpy()).max() > 1e-3


def _spec_text(tmp_path, extra: str) -> str:
    return (
        f'out = "{tmp_path}"\njobs = 1\ntolerances = [1e-5]\nrepeats = 1\n'
        'plugins = ["tests.fake_plugins"]\nproblems = ["test-pendulum"]\n'
        'formalisms = [{ name = "minimal-ode", options = { index = 1 } }]\n'
        f'integrators = ["test-rk45"]\n{extra}'
    )


def test_a_sweep_stores_trajectories_unless_switched_off(fake_plugins, tmp_path) -> None:
    on, off = tmp_path / "on", tmp_path / "off"
    run_sweep(parse_spec(_spec_text(on, "")), show_progress=False)
    run_sweep(parse_spec(_spec_text(off, "store_trajectories = false")), show_progress=False)
    (run_id,) = store.load_results(on)["run_id"]
    trajectory = store.load_trajectory(on, run_id)
    assert list(trajectory.columns) == ["t", "pivot", "pivot.v"] and len(trajectory) == 41
    assert list(store.load_series(off, run_id, states=True).columns) == row_schema.SERIES_COLUMNS
    with pytest.raises(ConfigError, match="no stored trajectory.*store_trajectories = false"):
        store.load_trajectory(off, run_id)
    # the series of all runs never carries states (their names differ from run to run)
    assert list(store.load_series(on).columns) == row_schema.SERIES_COLUMNS
    # a resumed sweep finds both stores whole
    assert store.completed_run_ids(on) == store.completed_run_ids(off) == {run_id}


def test_store_trajectories_must_be_a_boolean(fake_plugins, tmp_path) -> None:
    with pytest.raises(ConfigError, match="store_trajectories: must be true or false"):
        parse_spec(_spec_text(tmp_path, 'store_trajectories = "no"'))
