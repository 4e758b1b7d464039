"""The public Python API (workbench.run, sweep, describe, load_results...): what a
notebook does, including plugins defined in the notebook itself."""

from __future__ import annotations

import sys
import textwrap
import types

import matplotlib
import numpy as np
import pytest

import workbench
from workbench.api import sweeps as api_sweep
from workbench.errors import ConfigError
from workbench.plugin.registry import REGISTRY

matplotlib.use("Agg")


@pytest.fixture
def registry_restored():
    """The registry (and the API's record of what it registered) as it was, after."""
    from workbench.api import runs as api_run

    REGISTRY.discover()
    saved = {kind: dict(entries) for kind, entries in REGISTRY.entries.items()}
    here = set(api_run.REGISTERED_HERE)
    yield
    for kind, entries in saved.items():
        REGISTRY.entries[kind] = entries
    api_run.REGISTERED_HERE.clear()
    api_run.REGISTERED_HERE.update(here)


def test_import_workbench_stays_cheap() -> None:
    import subprocess

    code = "import sys, workbench; print(sorted({'pandas', 'casadi'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert {"run", "sweep", "describe", "load_results", "list_plugins"} <= set(dir(workbench))


def test_run_gives_the_row_the_named_trajectory_and_plots(fake_plugins, tmp_path) -> None:
    result = workbench.run("test-pendulum", "minimal-ode", "test-rk45", rtol=1e-8, index=1,
                           initial_angle=0.5, out=tmp_path)  # fmt: skip
    assert result.row["status"] == "ok" and result.row["formalism_options"].count('"index":1')
    assert result.row["problem_options"] == '{"initial_angle":0.5}'  # routed to the problem
    trajectory = result.trajectory
    assert list(trajectory.columns) == ["t", "pivot", "pivot.v"] and len(trajectory) == 41
    assert trajectory["pivot"].iloc[0] == pytest.approx(-0.5)  # the initial angle given
    # energy of a rigid pendulum is conserved: the series says how well
    assert result.energy["energy_err"].max() < 1e-6
    assert result.drift.columns.tolist() == ["t", "drift_pos", "drift_vel", "drift_nh"]
    # the stored run is the same run
    assert workbench.load_trajectory(tmp_path, result.run_id).equals(trajectory)
    assert workbench.load_results(tmp_path)["run_id"].tolist() == [result.run_id]
    # poses: the link's frame turns about the pivot, which stays at the origin
    poses = result.poses()
    np.testing.assert_allclose(poses[["link.x", "link.y", "link.z"]].to_numpy(), 0, atol=1e-12)
    quaternion = poses[["link.p0", "link.p1", "link.p2", "link.p3"]].to_numpy()
    np.testing.assert_allclose(np.linalg.norm(quaternion, axis=1), 1.0, atol=1e-12)
    angle = 2 * np.arctan2(quaternion[:, 3], quaternion[:, 0])
    np.testing.assert_allclose(angle, trajectory["pivot"], atol=1e-12)
    for plot in (result.plot, result.plot_drift, result.plot_energy, result.plot_error):
        assert plot().get_xlabel() == "t [s]"
    html = result._repr_html_()
    assert "test-pendulum / minimal-ode / test-rk45" in html and "<table>" in html


def test_run_refuses_bad_input_in_one_line(fake_plugins) -> None:
    with pytest.raises(ConfigError, match="no_such_option=: no option of that name"):
        workbench.run("test-pendulum", "minimal-ode", "test-rk45", no_such_option=1)
    with pytest.raises(ConfigError, match=r"indx=: no option .* \(did you mean index\?\)"):
        workbench.run("test-pendulum", "minimal-ode", "test-rk45", indx=1)
    with pytest.raises(workbench.WorkbenchError, match="did you mean"):
        workbench.run("test-pendulum", "minimal-odee", "test-rk45")


def test_a_failed_run_is_returned_with_its_reason(fake_plugins) -> None:
    with pytest.warns(RuntimeWarning, match="test-raise: failed: .*raised") as said:
        result = workbench.run("test-pendulum", "minimal-ode", "test-raise", index=1)
    assert said[0].filename == __file__  # the caller's line, not contextlib's
    assert result.row["status"] == "failed" and not result.ok
    assert "raised" in result.row["message"]
    with pytest.warns(RuntimeWarning, match="test-rk45: skipped: .*does not support"):
        skipped = workbench.run("test-slider-crank", "test-trees-only", "test-rk45", index=1)
    assert skipped.row["status"] == "skipped" and "does not support" in skipped.row["message"]
    assert skipped.trajectory.empty
    with pytest.raises(workbench.WorkbenchError, match="no equations"):
        skipped.poses()


def test_describe_and_the_lists(fake_plugins) -> None:
    problems = workbench.list_plugins("problems")
    assert "test-pendulum" in set(problems["name"]) and set(problems["kind"]) == {"problem"}
    everything = workbench.list_plugins()
    assert {"minimal-ode", "test-rk45"} <= set(everything["name"])
    assert set(everything["kind"]) == {"problem", "formalism", "integrator"}
    description = workbench.describe("test-slider-crank")
    assert description.kind == "problem" and description.facts["loops"] == "1"
    assert description.facts["DOF"] == "1"  # a slider-crank has one degree of freedom
    html = description._repr_html_()
    assert "test-slider-crank" in html and "rod &rarr; slider" in html  # the model's joints
    assert "<td>j4</td><td>revolute</td>" in description.model._repr_html_()
    options = workbench.describe("minimal-ode").options
    assert options.loc["index", "default"] == 3 or "index" in options.index


# A problem as a notebook defines it: a class in the kernel's __main__, registered with the
# decorator as the cell runs. Workers cannot import __main__'s cells: the sweep runs here.
NOTEBOOK_CELL = textwrap.dedent(
    """
    from workbench.model import Model
    from workbench.plugin.problem import Problem
    from workbench.plugin.registry import problem

    @problem
    class NotebookPendulum(Problem):
        name = "notebook-pendulum"
        summary = "A rigid pendulum defined in a notebook"
        t_end = 1.0
        n_samples = 21

        def model(self):
            model = Model("notebook-pendulum", kind="planar", gravity=(0.0, -9.81, 0.0))
            model.add_body("link", 2.0, com=(0.3, 0, 0), inertia=0.05)
            model.add_joint("pivot", "revolute", "ground", "link")
            return model

        def initial_joint_coordinates(self):
            return {"pivot": 0.8}
    """
)


def test_a_problem_defined_in_a_notebook_is_swept_across_three_formalisms(
    registry_restored, tmp_path
) -> None:
    main = types.ModuleType("__main__")  # exec'd as a kernel runs a cell
    exec(compile(NOTEBOOK_CELL, "<notebook cell>", "exec"), main.__dict__)
    assert REGISTRY.entries["problem"]["notebook-pendulum"].module == "__main__"
    calls = []
    frame = workbench.sweep(
        problems=["notebook-pendulum"],
        formalisms=[{"name": f, "options": {"index": 1}}
                    for f in ("minimal-ode", "recursive", "absolute-dae")],
        integrators=["scipy-dop853"],
        tolerances=[1e-8],
        out=tmp_path,
        progress=lambda done, total: calls.append((done, total)),
    )  # fmt: skip
    assert calls == [(1, 3), (2, 3), (3, 3)]
    assert sorted(frame["formalism"]) == ["absolute-dae", "minimal-ode", "recursive"]
    assert set(frame["status"]) == {"ok"}, frame["message"].tolist()
    # three formalisms, one pendulum: each conserves its energy and meets the reference
    assert (frame["energy_err_max"] < 1e-6).all()
    assert (frame["err_end"] < 1e-5).all()
    for run_id in frame["run_id"]:
        trajectory = workbench.load_trajectory(tmp_path, run_id)
        assert len(trajectory) == 21 and trajectory["t"].iloc[-1] == pytest.approx(1.0)


def test_a_class_registered_through_the_api_runs_in_process(registry_restored, tmp_path) -> None:
    main = types.ModuleType("cell")
    exec(compile(NOTEBOOK_CELL.replace("@problem\n", ""), "<cell>", "exec"), main.__dict__)
    cls = main.__dict__["NotebookPendulum"]
    cls.__module__ = __name__  # as if defined in this (importable) test module
    assert "notebook-pendulum" not in REGISTRY.entries["problem"]
    result = workbench.run(cls, "recursive", "scipy-dop853", rtol=1e-6, index=1)
    assert result.row["status"] == "ok"
    # importable module, but a worker importing it would not register the class
    spec = api_sweep.parse_spec(
        api_sweep.toml_text({"out": str(tmp_path), "problems": [cls.name],
                             "formalisms": ["recursive"], "integrators": ["scipy-dop853"],
                             "tolerances": [1e-6]}),  # fmt: skip
    )
    assert api_sweep.local_plugins(spec) == ["notebook-pendulum"]


def test_a_sweep_of_importable_plugins_uses_worker_processes(fake_plugins, tmp_path) -> None:
    class Bar:  # a tqdm-like bar: its total is set and it advances one a run
        total, n = None, 0

        def update(self, k):
            self.n += k

    bar = Bar()
    frame = workbench.sweep(
        {"plugins": ["tests.fake_plugins"], "jobs": 2, "repeats": 1},
        problems=["test-pendulum"],
        formalisms=[{"name": "minimal-ode", "options": {"index": 1}}],
        integrators=["test-rk45"],
        tolerances=[1e-4, 1e-6],
        out=tmp_path,
        progress=bar,
    )
    assert (bar.total, bar.n) == (2, 2)
    assert len(frame) == 2 and set(frame["status"]) == {"ok"}
    spec = api_sweep.parse_spec((tmp_path / "sweep.toml").read_text())
    assert api_sweep.local_plugins(spec) == []
    # the pool of two workers ran them (a run in this process says workers 1)
    assert set(frame["workers"]) == {2}
    # a second sweep into the same folder returns its own run only, not the first's two
    second = workbench.sweep(
        {"plugins": ["tests.fake_plugins"], "jobs": 2, "repeats": 1},
        problems=["test-pendulum"],
        formalisms=[{"name": "minimal-ode", "options": {"index": 1}}],
        integrators=["test-rk45"],
        tolerances=[1e-5],
        out=tmp_path,
    )
    assert second["rtol"].tolist() == [1e-5]
    assert len(workbench.load_results(tmp_path)) == 3
    in_process = workbench.sweep(
        {"plugins": ["tests.fake_plugins"], "repeats": 1},
        problems=["test-pendulum"],
        formalisms=[{"name": "minimal-ode", "options": {"index": 1}}],
        integrators=["test-rk45"],
        tolerances=[1e-4, 1e-7],
        out=tmp_path,
        in_process=True,
    )
    assert sorted(in_process["rtol"]) == [1e-7, 1e-4]  # the 1e-4 run done before, kept
    # its report and paper folder from Python, as `workbench report` / `paper` make them
    index = workbench.report(tmp_path, cost="n_rhs")
    assert index == tmp_path / "report" / "index.html"
    assert "test-pendulum" in index.read_text()
    main = workbench.paper(tmp_path, tmp_path / "my-paper", compile=False)
    assert main == tmp_path / "my-paper" / "main.tex"
    assert "\\begin{document}" in main.read_text()
    # in the measure the report was made in: the two documents agree
    assert "cost measure: rhs evaluations." in main.read_text()
    with pytest.raises(ConfigError, match="unknown cost measure 'cpu'"):
        workbench.report(tmp_path, cost="cpu")
    with pytest.raises(ConfigError, match="no results folder or file"):
        workbench.report(tmp_path / "missing")
