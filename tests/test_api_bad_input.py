"""The public Python API given wrong input, as a notebook gives it: each mistake raises the
workbench's own error naming what is wrong, before anything runs, not a TypeError,
KeyError or OSError from inside."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

import workbench
from workbench.errors import ConfigError, PluginError

matplotlib.use("Agg")

RUN = ("test-pendulum", "minimal-ode", "test-rk45")


@pytest.mark.parametrize("rtol", ["1e-6", None, [1e-6]])
def test_run_refuses_a_tolerance_that_is_not_a_number(fake_plugins, rtol) -> None:
    with pytest.raises(ConfigError, match="rtol: must be a number"):
        workbench.run(*RUN, rtol=rtol)


@pytest.mark.parametrize("options", ["initial_angle=0.3", [("initial_angle", 0.3)]])
def test_run_refuses_options_that_are_not_a_dict(fake_plugins, options) -> None:
    with pytest.raises(ConfigError, match="problem_options: expected a dict"):
        workbench.run(*RUN, problem_options=options)


def test_run_and_sweep_refuse_an_out_that_is_no_folder(fake_plugins, tmp_path) -> None:
    file = tmp_path / "notes.txt"
    file.write_text("not a results directory")
    with pytest.raises(ConfigError, match="is a file, not a directory"):
        workbench.run(*RUN, index=1, out=file)
    with pytest.raises(ConfigError, match="expected the path of a results directory"):
        workbench.run(*RUN, index=1, out=5)
    keys = {
        "problems": ["test-pendulum"],
        "formalisms": [{"name": "minimal-ode", "options": {"index": 1}}],
        "integrators": ["test-rk45"],
        "tolerances": [1e-4],
    }
    with pytest.raises(ConfigError, match="is a file, not a directory"):
        workbench.sweep(out=file, in_process=True, **keys)
    with pytest.raises(ConfigError, match="cannot create the results directory"):
        workbench.sweep(out=file / "below", in_process=True, **keys)
    assert file.read_text() == "not a results directory"


def test_sweep_refuses_a_spec_or_progress_of_the_wrong_kind(fake_plugins, tmp_path) -> None:
    with pytest.raises(ConfigError, match="expected a suite name, the path"):
        workbench.sweep(["test-pendulum"], out=tmp_path)
    with pytest.raises(ConfigError, match="progress: expected a function"):
        workbench.sweep(problems=["test-pendulum"], formalisms=["minimal-ode"],
                        integrators=["test-rk45"], tolerances=[1e-4], out=tmp_path,
                        in_process=True, progress=5)  # fmt: skip
    # a misspelled keyword: named as given, without the line of a text the user never saw
    with pytest.raises(ConfigError) as refused:
        workbench.sweep(problems=["test-pendulum"], formalisms=["minimal-ode"],
                        integrators=["test-rk45"], tolerance=[1e-4], out=tmp_path)  # fmt: skip
    assert str(refused.value) == (
        "workbench.sweep: tolerance: unknown key; did you mean tolerances?"
    )
    assert not (tmp_path / "runs").exists()  # refused before any run


def test_sweep_takes_numpy_tolerances(fake_plugins, tmp_path) -> None:
    tolerances = np.logspace(-4, -6, 2)  # what a notebook writes
    frame = workbench.sweep(
        problems=["test-pendulum"],
        formalisms=[{"name": "minimal-ode", "options": {"index": np.int64(1)}}],
        integrators=["test-rk45"],
        tolerances=tolerances,
        out=tmp_path,
        in_process=True,
        repeats=1,
    )
    assert sorted(frame["rtol"]) == sorted(tolerances.tolist())
    assert set(frame["status"]) == {"ok"}, frame["message"].tolist()


def test_the_load_functions_name_a_wrong_folder_or_run_id(fake_plugins, tmp_path) -> None:
    result = workbench.run(*RUN, index=1, out=tmp_path)
    row = workbench.load_results(tmp_path).iloc[0]
    with pytest.raises(ConfigError, match="run_id: expected a run id"):
        workbench.load_trajectory(tmp_path, row)  # the row, not its run_id
    with pytest.raises(ConfigError, match="run_id: expected a run id"):
        workbench.load_trajectory(tmp_path, None)
    with pytest.raises(ConfigError, match="no results in"):
        workbench.load_series(tmp_path / "elsewhere")
    with pytest.raises(ConfigError, match="elsewhere: no such file or folder"):
        workbench.load_trajectory(tmp_path / "elsewhere", row["run_id"])  # (no time series)
    with pytest.raises(ConfigError, match="expected the path of a results directory"):
        workbench.load_results(None)
    assert workbench.load_trajectory(tmp_path, row["run_id"]).equals(result.trajectory)


def test_plots_name_a_missing_problem_or_column(fake_plugins, tmp_path) -> None:
    result = workbench.run(*RUN, index=1, out=tmp_path)
    assert result.plot("pivot").get_lines()[0].get_label() == "pivot"  # one name
    with pytest.raises(ConfigError, match="no trajectory column 'pivot.x'.*pivot, pivot.v"):
        result.plot(["pivot.x"])
    results = workbench.load_results(tmp_path)
    with pytest.raises(ConfigError, match="no runs of problem 'test-pendulm'"):
        workbench.plot_work_precision(results, problem="test-pendulm")
    with pytest.raises(ConfigError, match="no column 'n_rhss'; cost measures: integrate_cpu, "
                       "integrate_wall, n_rhs, work; cost columns: .*n_rhs"):  # fmt: skip
        workbench.plot_work_precision(results, cost="n_rhss")
    axes = workbench.plot_work_precision(results, cost="n_rhs", by="formalism")
    assert [line.get_label() for line in axes.get_lines()] == ["minimal-ode"]
    # a measure by the name workbench.report takes, or its column: the same curve
    measured = workbench.plot_work_precision(results, cost="integrate_cpu")
    column = workbench.plot_work_precision(results, cost="integrate_cpu_s")
    assert measured.get_xlabel() == "integration CPU time [s]"
    assert (measured.get_lines()[0].get_xdata() == column.get_lines()[0].get_xdata()).all()
    with pytest.raises(ConfigError, match="expected the results frame"):
        workbench.plot_work_precision(str(tmp_path))


def test_list_and_describe_refuse_what_is_no_name(fake_plugins) -> None:
    with pytest.raises(PluginError, match="kind is problems, formalisms or integrators"):
        workbench.list_plugins(["problems"])
    with pytest.raises(PluginError, match="expected the name of a problem"):
        workbench.describe(["test-pendulum"])
    with pytest.raises(PluginError, match="int is not a Problem, Formalism or Integrator"):
        workbench.describe(int)


def test_a_skipped_result_says_why_in_its_repr(fake_plugins) -> None:
    with pytest.warns(RuntimeWarning, match="skipped"):
        skipped = workbench.run("test-slider-crank", "test-trees-only", "test-rk45", index=1)
    assert skipped.row["status"] == "skipped"
    assert f"message={skipped.row['message']}" in repr(skipped)
    assert "=," not in repr(skipped)  # no empty values


def test_describe_shows_the_option_values_its_model_was_built_with() -> None:
    description = workbench.describe("planar-chain", n_links=3)
    assert description.facts["bodies"].startswith("3:")  # the model has the links given
    assert description.options.loc["n_links", "value"] == 3
    assert description.options.loc["n_links", "default"] == 5
    assert "option n_links (int) = 3 (default 5)" in repr(description)
    assert "option n_links (int) = 5\n" in repr(workbench.describe("planar-chain")) + "\n"


def test_run_and_sweep_hold_the_output_folders_lock_as_the_commands_do(
    fake_plugins, tmp_path
) -> None:
    """Another process writing into OUT: ``wb.run(out=)`` and ``wb.sweep`` (in this process
    too) refuse before running, naming it; with ``wait=True`` they run once it has gone."""
    import subprocess
    import sys
    import threading

    from workbench.runs import store
    from workbench.runs.out_lock import OutputBusyError

    out = tmp_path / "out"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys; from workbench.runs.out_lock import out_lock\n"
         f"with out_lock({str(out)!r}, command='the holder'):\n"
         "    print('held', flush=True); sys.stdin.read()"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputBusyError, match="the holder.*wait=True"):
            workbench.run(*RUN, out=out)
        for in_process in (True, False):
            with pytest.raises(OutputBusyError, match="the holder"):
                workbench.sweep(out=out, problems=["test-pendulum"], formalisms=["minimal-ode"],
                                integrators=["test-rk45"], tolerances=[1e-4],
                                in_process=in_process)  # fmt: skip
        assert not list((out / store.RUNS_DIR).glob("*.json"))  # nothing ran
        threading.Timer(1.0, holder.stdin.close).start()  # the holder ends in a second
        result = workbench.run(*RUN, out=out, wait=True)
    finally:
        holder.kill()
        holder.wait()
    assert result.ok and (out / store.RUNS_DIR / f"{result.run_id}.json").is_file()


def test_a_row_written_by_run_has_the_log_column_the_schema_gives(fake_plugins, tmp_path) -> None:
    """``log`` is '' when nothing was captured (the CLI's value), not missing (NaN)."""
    from workbench.runs import store

    result = workbench.run(*RUN, out=tmp_path / "out")
    assert store.load_results(tmp_path / "out").set_index("run_id").loc[result.run_id, "log"] == ""


def test_describe_gives_each_option_its_unit() -> None:
    """``workbench describe`` printed units and ``wb.describe`` did not (qa3d, left then):
    the heavy top's spin of 50 is an angular velocity about its body axis, in rad/s."""
    description = workbench.describe("heavy-top")
    assert description.options.loc["spin", "unit"] == "rad/s"
    assert description.options.loc["initial_tilt", "unit"] == "rad"
    assert "option spin (float) = 50.0 rad/s" in repr(description)
    assert "unit" in description._repr_html_()
    integrator = workbench.describe("scipy-dop853").options
    assert "unit" in integrator.columns  # the same table for every kind of plugin


def test_every_built_in_option_of_a_physical_quantity_carries_its_unit() -> None:
    """Step sizes, speeds, stiffnesses, end times and Baumgarte gains were printed as bare
    numbers ('baumgarte_alpha (float) = 10.0'; their units only in source comments):
    each now states its unit where `describe` shows it."""
    import re

    from workbench.plugin import registry
    from workbench.plugin.options import option_units

    registry.REGISTRY.discover()
    physical = re.compile(r"(^|_)(step|speed|stiffness|t_end|baumgarte_alpha|baumgarte_beta)$")
    bare = []
    for kind in ("problem", "formalism", "integrator"):
        for name in registry.REGISTRY.entries[kind]:
            if name.startswith("test-"):
                continue
            options = getattr(registry.REGISTRY.get(kind, name), "Options", None)
            for field, unit in option_units(options).items() if options else ():
                if physical.search(field) and not unit:
                    bare.append(f"{kind} {name}: {field}")
    assert not bare, bare
    assert workbench.describe("absolute-dae").options.loc["baumgarte_beta", "unit"] == "1/s"
    assert workbench.describe("compliant-contact").options.loc["stiffness", "unit"] == "N/m"
