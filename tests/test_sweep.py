"""Sweeps: spec validation, worker pool reliability (hang, crash, death), resume, CLI."""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from workbench.cli import app
from workbench.errors import ConfigError
from workbench.execution import row_schema
from workbench.execution.worker_env import worker_threads
from workbench.plugin.registry import REGISTRY
from workbench.runs import store
from workbench.runs.sweep import load_spec, parse_spec, run_sweep

ROOT = Path(__file__).resolve().parents[1]


def spec_text(
    out: Path, integrators: str, problems: str = '["test-pendulum"]', extra: str = ""
) -> str:
    return f"""
out = "{out.as_posix()}"
jobs = 2
time_limit = 300.0  # only a hung run reaches it (a loaded machine is slow, not hung)
tolerances = [1e-4, 1e-6]
plugins = ["tests.fake_plugins"]
problems = {problems}
formalisms = [{{ name = "minimal-ode", options = {{ index = [1] }} }}]
integrators = {integrators}
{extra}
"""


def rows_by_integrator(out: Path) -> dict[str, set[str]]:
    frame = store.load_results(out)
    return {name: set(group["status"]) for name, group in frame.groupby("integrator")}


def test_spec_expands_grids_and_normalizes_options(fake_plugins, tmp_path) -> None:
    sweep = parse_spec(
        spec_text(
            tmp_path, '["test-rk45", {name = "test-rk4", options = {steps_per_sample = [2, 4]}}]'
        )
    )
    # 1 problem x 1 formalism x (1 + 2 rk4 grids) x 2 tolerances
    assert len(sweep.runs) == 6
    assert all(r.atol == pytest.approx(r.rtol * 1e-3) for r in sweep.runs)
    assert all(r.formalism_options["baumgarte_alpha"] == 10.0 for r in sweep.runs)
    assert len({r.run_id for r in sweep.runs}) == 6


def test_an_integrator_entry_runs_at_its_own_tolerances(fake_plugins, tmp_path) -> None:
    sweep = parse_spec(
        spec_text(
            tmp_path,
            '["test-rk45", {name = "test-rk4", options = {steps_per_sample = [2, 4]},'
            " tolerances = [1e-3]}]",
        )
    )
    # rk45 at the sweep's two tolerances, each rk4 grid point at its own one
    pairs = sorted((r.integrator, r.integrator_options.get("steps_per_sample"), r.rtol)
                   for r in sweep.runs)  # fmt: skip
    assert pairs == [
        ("test-rk4", 2, 1e-3),
        ("test-rk4", 4, 1e-3),
        ("test-rk45", None, 1e-6),
        ("test-rk45", None, 1e-4),
    ]
    assert all(r.atol == pytest.approx(r.rtol * 1e-3) for r in sweep.runs)


def test_an_all_entry_gives_its_tolerances_to_the_integrators_not_named() -> None:
    sweep = parse_spec(
        'problems = ["slider-crank"]\nformalisms = ["minimal-ode"]\n'
        'integrators = [{ name = "all", tolerances = [1e-3] }, "scipy-dop853"]\n'
        "tolerances = [1e-5, 1e-6]"
    )
    rtols: dict[str, set] = {}
    for run in sweep.runs:
        rtols.setdefault(run.integrator, set()).add(run.rtol)
    assert rtols.pop("scipy-dop853") == {1e-5, 1e-6}
    assert rtols and all(values == {1e-3} for values in rtols.values())


def test_full_spec_is_valid() -> None:
    sweep = load_spec("full")
    assert sweep.runs and str(sweep.out) == "reports/latest"
    assert {r.rtol for r in sweep.runs} == {1e-4, 1e-7, 1e-10}
    # "all": every working problem and formalism, including ones registered later
    for kind, names in (
        ("problem", {r.problem for r in sweep.runs}),
        ("formalism", {r.formalism for r in sweep.runs}),
    ):
        registered = {i.name for i in REGISTRY.list(kind) if i.plugin is not None}
        assert names == registered


def test_misbehaving_plugins_give_rows_and_the_sweep_completes(fake_plugins, tmp_path) -> None:
    integrators = '["test-rk45", "test-hang", "test-raise", "test-nan", "test-die"]'
    text = spec_text(tmp_path, integrators, extra="")
    text = text.replace(
        '[{ name = "minimal-ode"',
        '[{ name = "test-broken-build", options = { index = 1 } }, { name = "minimal-ode"',
    )
    # 20 s: a limit the hung runs reach and a working run does not, even at load 16
    summary = run_sweep(parse_spec(text), time_limit=20.0, show_progress=False)
    frame = store.load_results(tmp_path)
    assert len(frame) == summary.total == 20 and frame["run_id"].is_unique
    good = frame[frame["formalism"] == "minimal-ode"]
    status = {n: set(g["status"]) for n, g in good.groupby("integrator")}
    assert status == {
        "test-rk45": {"ok"},
        "test-hang": {"timeout"},
        "test-raise": {"failed"},
        "test-nan": {"failed"},
        "test-die": {"failed"},
    }
    messages = good.set_index("integrator")["message"]
    assert "time limit of 20 s" in messages["test-hang"].iloc[0]
    assert "worker process died (exit code -11, SIGSEGV)" in messages["test-die"].iloc[0]
    assert "raised" in messages["test-raise"].iloc[0]
    broken = frame[frame["formalism"] == "test-broken-build"]
    assert set(broken["status"]) == {"failed"}
    assert all(m.startswith("build:") for m in broken["message"])
    assert (tmp_path / "results.parquet").is_file() and not list(tmp_path.rglob("*.tmp"))
    environment = json.loads((tmp_path / store.ENVIRONMENT_FILE).read_text())
    assert environment["distributions"]["mbs-workbench"] == frame["version_workbench"].iloc[0]
    assert set(frame["schema_version"]) == {row_schema.SCHEMA_VERSION}
    # the rows the parent wrote (timeout, died) name the workers' threads, not its own
    assert set(frame["threads"]) == {worker_threads()}
    # every ok row has its series
    for run_id in frame.loc[frame["status"] == "ok", "run_id"]:
        assert store.series_path(tmp_path, run_id).is_file()
    # resume: nothing left to do
    again = run_sweep(parse_spec(text), show_progress=False)
    assert again.total == 0 and again.already_done == 20


def test_killed_sweep_resumes_to_the_same_rows(tmp_path) -> None:
    """SIGKILL the whole sweep mid-way; the re-run ends with exactly the full set of rows."""
    integrators = (
        '["test-rk45", {name = "test-rk4", options = {steps_per_sample = [1, 2, 3, 4, 5]}}]'
    )
    killed_out, clean_out = tmp_path / "killed", tmp_path / "clean"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for out in (killed_out, clean_out):
        (tmp_path / f"{out.name}.toml").write_text(
            spec_text(out, integrators, problems='["test-pendulum", "test-slider-crank"]')
        )
    command = [sys.executable, "-m", "workbench", "sweep", "--jobs", "2"]
    process = subprocess.Popen(
        command + [str(tmp_path / "killed.toml")],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(store.completed_run_ids(killed_out)) < 3:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)  # the sweep and its workers
    process.wait()
    partial = store.completed_run_ids(killed_out)
    assert 3 <= len(partial) < 24
    for out in (killed_out, clean_out):
        done = subprocess.run(  # the rows are the subject: no report (2 x 8 s of CPU)
            command + ["--no-report", str(tmp_path / f"{out.name}.toml")],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=900,  # only a hung sweep reaches it
        )
        assert done.returncode == 0, done.stderr
    killed, clean = store.load_results(killed_out), store.load_results(clean_out)
    assert sorted(killed["run_id"]) == sorted(clean["run_id"]) and killed["run_id"].is_unique
    assert len(clean) == 24 and set(killed["status"]) == {"ok"}
    assert not list(killed_out.rglob("*.tmp"))


# ---- the CLI ------------------------------------------------------------------------

runner = CliRunner()


def test_no_report_writes_the_rows_and_says_how_to_write_the_report(fake_plugins, tmp_path) -> None:
    """--no-report: rows, series and recording, no report, and a line naming the command
    that writes it; once written, a sweep with nothing new calls it unchanged, and a sweep
    that adds rows says the one there is not current."""
    out = tmp_path / "out"
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(out, '["test-rk45"]'))
    result = runner.invoke(app, ["sweep", str(spec), "--no-report"])
    assert result.exit_code == 0, result.output
    assert f"report: not written (--no-report); `workbench report {out}` writes it" in (
        result.output
    )
    assert len(store.load_results(out)) == 2 and not (out / "report").exists()
    assert (out / "recording.rrd").is_file()
    assert runner.invoke(app, ["report", str(out)]).exit_code == 0
    result = runner.invoke(app, ["sweep", str(spec), "--no-report"])
    assert f"report: {out / 'report' / 'index.html'} (unchanged" in result.output
    spec.write_text(spec_text(out, '["test-rk45", "test-rk4"]'))
    result = runner.invoke(app, ["sweep", str(spec), "--no-report"])
    assert result.exit_code == 0, result.output
    older = out / "report" / "index.html"
    assert f"{older} is not current: other rows or code made it" in result.output
    assert len(store.load_results(out)) == 4
    assert "why runs failed" not in result.output  # none did
    # a sweep with failed runs names the command that lists them with their reasons
    spec.write_text(spec_text(tmp_path / "failing", '["test-raise"]'))
    result = runner.invoke(app, ["sweep", str(spec), "--no-report", "--no-recording"])
    assert "(0 ok, 2 failed" in result.output, result.output
    line = next(x for x in result.output.splitlines() if x.startswith("why runs failed"))
    command = shlex.split(line.split(": ", 1)[1])
    assert command[:2] == ["workbench", "results"]
    listed = runner.invoke(app, command[1:])
    assert listed.exit_code == 0, listed.output
    assert listed.output.count("raised") == 2 and "The 2 runs in" in listed.output


@pytest.mark.parametrize(
    "body, fragment",
    [
        (
            'problems = "x"\nformalisms = ["minimal-ode"]\nintegrators = ["test-rk45"]\n'
            'tolerances = [1e-6]\njobs = "two"',
            "jobs",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = ["minimal-odee"]\n'
            'integrators = ["test-rk45"]\ntolerances = [1e-6]',
            "did you mean minimal-ode",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = [{name = "minimal-ode", options = '
            '{indx = 1}}]\nintegrators = ["test-rk45"]\ntolerances = [1e-6]',
            "unknown option",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = ["minimal-ode"]\n'
            'integrators = ["test-rk45"]\ntolerances = [-1e-6]',
            "line 6: tolerances[0]",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = [{name = "all", options = '
            '{indx = 1}}]\nintegrators = ["test-rk45"]\ntolerances = [1e-6]',
            "line 4: formalisms[0].options.indx: no registered formalism has this option",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = [{name = "minimal-ode", options = '
            '{index = []}}]\nintegrators = ["test-rk45"]\ntolerances = [1e-6]',
            "empty grid",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = ["minimal-ode"]\n'
            'integrators = ["test-rk45"]\ntolerances = []',
            "tolerances",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = ["minimal-ode"]\n'
            'integrators = ["test-rk45"]\ntolerances = [1e-6]\nspeed = 3',
            "speed: unknown key",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = ["minimal-ode"]\n'
            'integrators = [{name = "test-rk45", tolerances = [1e-6, 0.0]}]\ntolerances = [1e-6]',
            "line 5: integrators[0].tolerances[1]",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = ["minimal-ode"]\n'
            'integrators = [{name = "test-rk45", tolerances = [1e-6, 1e-6]}]\n'
            "tolerances = [1e-6]",
            "integrators[0].tolerances[1]: 1e-06 is listed twice",
        ),
        (
            'problems = ["test-pendulum"]\nformalisms = [{name = "minimal-ode", '
            'tolerances = [1e-6]}]\nintegrators = ["test-rk45"]\ntolerances = [1e-6]',
            "formalisms[0].tolerances: unknown key; a table has name and options; only "
            "integrator entries take their own tolerances",
        ),
        ('problems = ["test-pendulum"\nformalisms = 1', "line 4"),
    ],
)
def test_malformed_specs_give_one_line_and_exit_2(tmp_path, body, fragment) -> None:
    out = tmp_path / "out"
    spec = tmp_path / "spec.toml"
    spec.write_text(f'out = "{out.as_posix()}"\nplugins = ["tests.fake_plugins"]\n{body}\n')
    REGISTRY.discover()  # saved discovered: a restore must not leave an empty registry
    saved = {kind: dict(entries) for kind, entries in REGISTRY.entries.items()}
    try:
        result = runner.invoke(app, ["sweep", str(spec)])
    finally:
        for kind, entries in saved.items():
            REGISTRY.entries[kind] = entries
        sys.modules.pop("tests.fake_plugins", None)
    assert result.exit_code == 2, result.output
    # the error is one line; a plugin module imported from the current directory is said
    # on a line of its own before it (tests/test_local_plugins.py)
    lines = [
        line for line in result.output.splitlines() if line.strip() and not line.startswith(
            "plugins: imported local module tests.fake_plugins from "
        )
    ]  # fmt: skip
    assert len(lines) == 1 and lines[0].startswith("error:"), result.output
    assert fragment in lines[0]
    assert "Traceback" not in result.output
    assert not out.exists()


def test_all_table_gives_its_options_to_the_plugins_that_have_them() -> None:
    sweep = parse_spec(
        'problems = ["slider-crank"]\nformalisms = [{ name = "all", options = { index = [1, 2] } },'
        ' "minimal-ode"]\nintegrators = ["sundials-ida"]\ntolerances = [1e-6]'
    )
    indices: dict[str, set] = {}
    for run in sweep.runs:
        indices.setdefault(run.formalism, set()).add(run.formalism_options.get("index"))
    assert indices["minimal-ode"] == {3}  # named explicitly: its own (default) options
    assert indices["absolute-dae"] == indices["recursive"] == {1, 2}
    assert indices["nonholonomic-projection"] == {None}  # no index option: defaults


def test_missing_spec_file_and_bad_cli_values(tmp_path) -> None:
    result = runner.invoke(app, ["sweep", str(tmp_path / "none.toml")])
    assert result.exit_code == 2 and "cannot read" in result.output
    result = runner.invoke(app, ["sweep", "--jobs", "0"])
    assert result.exit_code == 2 and "--jobs" in result.output
    result = runner.invoke(app, ["results", str(tmp_path)])
    assert result.exit_code == 2 and "no results" in result.output


def test_run_and_results_commands(fake_plugins, tmp_path) -> None:
    result = runner.invoke(
        app,
        [
            "run",
            "test-pendulum",
            "-f",
            "minimal-ode",
            "-i",
            "test-rk4",
            "--rtol",
            "1e-6",
            "-o",
            "index=1",
            "-o",
            "integrator.steps_per_sample=3",
            "--out",
            str(tmp_path),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "energy_err_max" in result.output and "ok" in result.output
    result = runner.invoke(
        app, ["run", "test-pendulum", "-f", "minimal-ode", "-i", "test-rk4", "-o", "nonsense=1"]
    )
    assert result.exit_code == 2 and "nonsense" in result.output
    result = runner.invoke(
        app, ["run", "test-pendulum", "-f", "minimal-ode", "-i", "test-rk4", "-o", "indx=1"]
    )
    assert result.exit_code == 2 and "-o indx: no option" in result.output
    assert "(did you mean index?)" in result.output
    result = runner.invoke(app, ["results", str(tmp_path)])
    assert result.exit_code == 0 and "test-pendulum" in result.output


TOML_VALUES = st.recursive(
    st.one_of(
        st.integers(-3, 3),
        st.floats(allow_nan=False, width=32),
        st.booleans(),
        st.sampled_from(["test-pendulum", "minimal-ode", "test-rk45", "all", "", "x"]),
    ),
    lambda children: (
        st.lists(children, max_size=3)
        | st.dictionaries(
            st.sampled_from(["name", "options", "index", "bad"]), children, max_size=2
        )
    ),
    max_leaves=6,
)


def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, float):
        return repr(value) if value == value and abs(value) != float("inf") else "1.0"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    return str(value)


@settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    values=st.dictionaries(
        st.sampled_from(
            [
                "problems",
                "formalisms",
                "integrators",
                "tolerances",
                "jobs",
                "time_limit",
                "atol_factor",
                "missing_plugins",
                "out",
                "bogus",
            ]
        ),
        TOML_VALUES,
        max_size=6,
    )
)
def test_generated_specs_never_give_a_traceback(tmp_path_factory, values) -> None:
    directory = tmp_path_factory.mktemp("spec")
    values.pop("out", None)
    spec = directory / "spec.toml"
    spec.write_text(
        f'out = "{(directory / "out").as_posix()}"\njobs = 1\ntime_limit = 20\n'
        + "\n".join(
            f"{k} = {_toml(v)}" for k, v in values.items() if k != "jobs" and k != "time_limit"
        )
    )
    try:
        sweep = parse_spec(spec.read_text())
    except ConfigError:
        sweep = None
    if sweep is not None and len(sweep.runs) > 4:
        return  # a valid, large sweep: not run here
    result = runner.invoke(app, ["sweep", str(spec)])
    assert result.exit_code in (0, 2), result.output
    assert "Traceback" not in result.output
    if result.exit_code == 2:
        assert result.output.startswith("error:")
        assert not (directory / "out").exists()


@pytest.mark.slow
def test_dask_scheduler_runs_and_kills_hung_runs(fake_plugins, tmp_path) -> None:
    distributed = pytest.importorskip("distributed")
    text = spec_text(tmp_path, '["test-rk45", "test-hang", "test-die"]')
    # a Dask task's limit covers its child's interpreter start-up (seconds at load 15):
    # 30 s is a limit only the hung runs reach; two workers wait for them side by side
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        summary = run_sweep(
            parse_spec(text),
            time_limit=30.0,
            scheduler=cluster.scheduler_address,
            show_progress=False,
        )
    assert summary.total == 6
    assert rows_by_integrator(tmp_path) == {
        "test-rk45": {"ok"},
        "test-hang": {"timeout"},
        "test-die": {"failed"},
    }
    ok = store.load_results(tmp_path).query("status == 'ok'")
    assert all(store.series_path(tmp_path, r).is_file() for r in ok["run_id"])


def test_workers_take_runs_of_the_equations_they_built() -> None:
    """Dispatch order: a worker's own (problem, formalism) first, then equations no other
    worker is on, so each model is built by about one worker; nothing lost or repeated."""
    from collections import deque

    from workbench.execution.execute import RunSpec, equations_key
    from workbench.runs.local_pool import _take_next

    runs = [
        RunSpec(problem, "minimal-ode", integrator, rtol, rtol * 1e-3)
        for problem in ("a", "b", "c")
        for integrator in ("i", "j")
        for rtol in (1e-4, 1e-8)
    ]
    queue = deque((equations_key(run), run) for run in runs)
    pairs: dict[str, tuple | None] = {"w1": None, "w2": None}
    taken: dict[str, list[str]] = {"w1": [], "w2": []}
    while queue:
        for worker in ("w1", "w2"):
            if not queue:
                break
            others = {p for w, p in pairs.items() if w != worker}
            pairs[worker], spec = _take_next(queue, pairs[worker], others)
            assert pairs[worker] == equations_key(spec)
            taken[worker].append(spec.problem)
    assert sorted(taken["w1"] + taken["w2"]) == sorted(r.problem for r in runs)
    assert taken["w1"] == ["a"] * 4 + ["c"] * 2 and taken["w2"] == ["b"] * 4 + ["c"] * 2
