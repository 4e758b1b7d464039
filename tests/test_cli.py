"""The command line: tables on stdout; bad input is one line on stderr and exit code 2."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tests.test_registry import FAKE_MODULES, write_fake_distribution
from workbench import cli
from workbench.errors import ConfigError
from workbench.plugin import registry as registry_module
from workbench.plugin.registry import Registry

REPO = Path(__file__).resolve().parents[1]
STARTER_PROBLEMS = ("simple-pendulum", "double-pendulum", "slider-crank", "heavy-top")


def run_workbench(*args: str, pythonpath: Path | None = None) -> subprocess.CompletedProcess:
    """``python -m workbench ARGS`` in a subprocess, wide enough that tables do not wrap."""
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(pythonpath), env.get("PYTHONPATH")]))
    return subprocess.run(
        [sys.executable, "-m", "workbench", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def assert_one_line_error(stderr: str, *fragments: str) -> None:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("error: ")
    assert "Traceback" not in stderr
    for fragment in fragments:
        assert fragment in lines[0]


@pytest.fixture
def fake_registry(tmp_path, monkeypatch):
    """The global registry replaced by a fresh one that sees only the fake distribution."""
    monkeypatch.syspath_prepend(str(write_fake_distribution(tmp_path)))
    monkeypatch.setattr(registry_module, "REGISTRY", Registry(builtin_packages={}))
    yield registry_module.REGISTRY
    for name in FAKE_MODULES:
        sys.modules.pop(name, None)


@pytest.fixture
def runner(monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    monkeypatch.setenv("NO_COLOR", "1")
    return CliRunner()


# -- in process (CliRunner) -------------------------------------------------------------
def test_list_prints_one_table_per_kind(fake_registry, runner):
    result = runner.invoke(cli.app, ["list"])
    assert result.exit_code == 0, result.output
    for title in ("problems", "formalisms", "integrators"):
        assert title in result.stdout
    assert "toy-formalism" in result.stdout
    assert "A formalism that exists only in tests." in result.stdout
    assert "planar, tree" in result.stdout
    assert "ode (index <= 0), dae (index <= 1)" in result.stdout
    assert "toy-pendulum" in result.stdout
    problems = runner.invoke(cli.app, ["list", "problems"]).stdout
    assert "capabilities" not in problems  # problems declare none: a column of '-' a row
    assert "toy-pendulum" in problems


def test_describe_prints_no_negative_zero(runner):
    result = runner.invoke(cli.app, ["describe", "slider-crank"])
    assert result.exit_code == 0, result.output
    assert "crank_pin = 0 rad," in result.stdout and "-0" not in result.stdout


def test_describe_gives_units_the_quaternion_order_and_the_velocity_frame(runner):
    """qa3d F4: options, initial coordinates and velocities had no units; what the four
    numbers of a spherical joint and the three of its velocity are was not said."""
    top = runner.invoke(cli.app, ["describe", "heavy-top"], env={"COLUMNS": "250"})
    assert top.exit_code == 0, top.output
    out = top.stdout
    assert re.search(r"│ spin\s+│ float\s+│ 50\.0\s+│ rad/s\s+│", out)
    assert re.search(r"│ initial_tilt\s+│ float\s+│ 0\.3\s+│ rad\s+│", out)
    assert "tip = (0, 0, 50) rad/s" in out  # an angular velocity
    assert "Euler parameters (p0, p1, p2, p3), scalar first" in out
    assert "angular velocity (wx, wy, wz) of the child in the child frame" in out
    ball = runner.invoke(cli.app, ["describe", "ball-on-rotating-plane"], env={"COLUMNS": "250"})
    assert "float = (0.5, 0, 0.1) m, (1, 0, 0, 0)" in ball.stdout  # free: position, quaternion
    assert "float = (0, 0.3, 0) m/s, (7, 0, 1) rad/s" in ball.stdout
    rsrrr = runner.invoke(cli.app, ["describe", "rsrrr"], env={"COLUMNS": "250"}).stdout
    assert "none given: neutral" in rsrrr and "neutral / at rest │" not in rsrrr
    assert "projected onto the loop-closure" in rsrrr
    pendulum = runner.invoke(cli.app, ["describe", "simple-pendulum"], env={"COLUMNS": "250"})
    assert "pivot = 0.5 rad" in pendulum.stdout and "Euler parameters" not in pendulum.stdout


def test_list_shows_a_broken_plugin_with_its_error(fake_registry, runner):
    result = runner.invoke(cli.app, ["list", "formalisms"])
    assert result.exit_code == 0, result.output
    line = next(line for line in result.stdout.splitlines() if "broken-formalism" in line)
    assert "broken: ImportError: fake_wb_broken needs libfoo" in line
    assert "toy-formalism" in result.stdout
    assert "toy-integrator" not in result.stdout


def test_describe_formalism_shows_options_and_capabilities(fake_registry, runner):
    result = runner.invoke(cli.app, ["describe", "toy-formalism"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "toy-formalism (formalism" in out
    assert "capabilities: planar, tree" in out
    assert "scheme" in out and "'index3' | 'ggl'" in out and "'index3'" in out
    assert "alpha" in out and "float" in out and "5.0" in out


def test_describe_problem_shows_source_and_model(fake_registry, runner):
    result = runner.invoke(cli.app, ["describe", "toy-pendulum"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "source: test suite, no book section" in out
    assert "options: none" in out
    for label in ("kind", "planar", "bodies", "1: bob", "joints", "1: pivot", "DOF"):
        assert label in out
    assert "invariants" in out and "energy" in out
    assert "reference" in out


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["list", "solvers"], "unknown plugin kind 'solvers'"),
        (["describe", "toy-formalsm"], "did you mean toy-formalism"),
        (["describe", "broken-formalism"], "is broken: ImportError"),
    ],
)
def test_bad_input_is_one_line_and_exit_code_2(fake_registry, runner, args, fragment):
    result = runner.invoke(cli.app, args)
    assert result.exit_code == 2
    assert result.stdout == ""
    assert_one_line_error(result.stderr, fragment)


def test_any_workbench_error_from_a_command_exits_2(fake_registry, runner, monkeypatch):
    def failing_list(kind: str):
        raise ConfigError("sweep 'x': tolerance 'rtol' must be positive\nsecond line")

    monkeypatch.setattr(fake_registry, "list", failing_list)
    result = runner.invoke(cli.app, ["list", "problems"])
    assert result.exit_code == 2
    assert_one_line_error(result.stderr, "must be positive | second line")


BROKEN_PIPE_SCRIPT = """
from workbench.cli.app import app

@app.command("pipe-test")
def pipe_test() -> None:
    raise BrokenPipeError(32, "Broken pipe")

app(["pipe-test"])
"""


@pytest.mark.parametrize("reader_gone", [True, False])
def test_a_broken_pipe_is_quiet_only_when_the_reader_of_stdout_left(reader_gone):
    """`workbench ... | head`: the reader left with what it wanted, nothing to report (exit
    1, Click's way); a broken pipe elsewhere (stdout still read) is an error said in one
    line (exit 2)."""
    child = subprocess.Popen(
        [sys.executable, "-c", BROKEN_PIPE_SCRIPT],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    if reader_gone:
        child.stdout.close()  # before the child writes: its stdout's reader is gone
    _, err = child.communicate(timeout=600)
    assert "Traceback" not in err
    if reader_gone:
        assert child.returncode == 1 and err == ""
    else:
        assert child.returncode == 2 and err.startswith("error: Broken pipe"), err


def test_every_commands_help_reaches_the_terminal_as_paragraphs_to_wrap():
    """Typer's rich help keeps a docstring's line breaks after its first paragraph (a
    70-column terminal broke `record --help` mid-sentence): each command's paragraphs
    come to it as single lines."""
    import click
    import typer

    group = typer.main.get_command(cli.app)
    context = click.Context(group)
    names = group.list_commands(context)
    assert {"sweep", "run", "record", "view"} <= set(names)
    for name in names:
        for paragraph in (group.get_command(context, name).help or "").split("\n\n"):
            assert "\n" not in paragraph or paragraph.startswith("\b"), (name, paragraph)


def test_usage_errors_exit_2(runner):
    assert runner.invoke(cli.app, ["no-such-command"]).exit_code == 2
    assert runner.invoke(cli.app, ["describe"]).exit_code == 2
    assert runner.invoke(cli.app, ["list", "problems", "extra"]).exit_code == 2


def test_version(runner):
    result = runner.invoke(cli.app, ["--version"])
    assert result.exit_code == 0 and "mbs-workbench" in result.stdout


def test_capabilities_text():
    class Both:
        capabilities = frozenset({"spatial", "loops"})
        accepts = {"mechanical": 3}

    assert cli.plugins.capabilities_text(Both) == "loops, spatial; mechanical (index <= 3)"
    assert cli.plugins.capabilities_text(object) == "-"
    assert cli.plugins.capabilities_text(None) == "-"


# -- as a subprocess --------------------------------------------------------------------
def test_subprocess_list(tmp_path):
    result = run_workbench("list", pythonpath=write_fake_distribution(tmp_path))
    assert result.returncode == 0, result.stderr
    assert "toy-formalism" in result.stdout and "toy-integrator" in result.stdout
    line = next(line for line in result.stdout.splitlines() if "broken-formalism" in line)
    assert "broken: ImportError" in line
    assert "Traceback" not in result.stdout + result.stderr


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["list", "formalsms"], "did you mean formalisms?"),
        (["describe", "no-such-plugin-anywhere"], "is called 'no-such-plugin-anywhere'"),
        (["describe", "rk4", "-o", "step=1"], "-o sets a problem's options; rk4 is an integrator"),
    ],
)
def test_subprocess_bad_input(args, fragment):
    result = run_workbench(*args)
    assert result.returncode == 2
    assert_one_line_error(result.stderr, fragment)


def test_subprocess_usage_error_exits_2():
    result = run_workbench("no-such-command")
    assert result.returncode == 2
    assert "Traceback" not in result.stderr


def test_starter_problems_are_described():
    registered = set(registry_module.plugin_names("problem"))
    missing = [name for name in STARTER_PROBLEMS if name not in registered]
    if missing:
        pytest.skip(f"starter problems not registered yet: {', '.join(missing)}")
    for name in STARTER_PROBLEMS:
        result = run_workbench("describe", name)
        assert result.returncode == 0, result.stderr
        assert "source:" in result.stdout and "DOF" in result.stdout


# -- one meaning for -o -------------------------------------------------------------------


@pytest.mark.parametrize("command", ["sweep", "report"])
def test_dash_o_is_option_everywhere_and_the_old_output_directory_is_refused(
    runner, tmp_path, command
):
    """``-o`` is ``--option NAME=VALUE`` (run, describe); in sweep and report, where it was
    the output directory, it is refused before anything runs, naming ``--out``."""
    target = tmp_path / "out"
    first = "quick" if command == "sweep" else str(tmp_path)
    result = runner.invoke(cli.app, [command, first, "-o", str(target)])
    assert result.exit_code == 2
    assert_one_line_error(result.stderr, "-o is --option NAME=VALUE", f"--out {target}")
    assert not target.exists()  # nothing was run or written
    for name in ("run", "describe"):
        shown = runner.invoke(cli.app, [name, "--help"]).stdout
        assert re.search(r"--option\s+-o\s", shown), name
    for name in ("sweep", "report"):
        shown = runner.invoke(cli.app, [name, "--help"]).stdout
        assert "--out" in shown and not re.search(r"\s-o\s", shown), name


def test_all_names_the_broken_plugin_it_leaves_out(runner, tmp_path, monkeypatch):
    from workbench.plugin.registry import REGISTRY, PluginInfo
    from workbench.runs.sweep_spec import parse_spec

    REGISTRY.discover()
    broken = PluginInfo("formalism", "half-done", None, "half_done", "...", "ImportError: libfoo")
    monkeypatch.setitem(REGISTRY.entries["formalism"], "half-done", broken)
    text = 'problems = ["simple-pendulum"]\nformalisms = "all"\ntolerances = [1e-6]\n'
    with pytest.warns(UserWarning, match=r"formalisms = \"all\" leaves out the broken "
                      r"formalism plugin half-done \(ImportError: libfoo\)"):  # fmt: skip
        spec = parse_spec(text + f'integrators = ["scipy-dop853"]\nout = "{tmp_path}"\n')
    assert "minimal-ode" in {run.formalism for run in spec.runs}
    # the CLI says it on one line of stderr, also when the sweep is then refused
    (tmp_path / "bad.toml").write_text(text + 'integrators = ["no-such-integrator"]\n')
    result = runner.invoke(cli.app, ["sweep", str(tmp_path / "bad.toml")])
    assert result.exit_code == 2, result.output
    assert 'warning: formalisms = "all" leaves out the broken formalism plugin ' in result.stderr
    assert "no-such-integrator" in result.stderr and "Traceback" not in result.output


def test_another_tool_s_word_for_a_command_names_ours(runner):
    result = runner.invoke(cli.app, ["plugins"])
    assert result.exit_code == 2
    assert "No such command 'plugins'; did you mean `workbench list`?" in result.output
    close = runner.invoke(cli.app, ["lst"])  # click's own hint for a misspelling stays
    assert close.exit_code == 2 and "Did you mean 'list'?" in close.output
