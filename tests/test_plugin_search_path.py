"""``plugins = ["my_module"]`` finds a module in the current directory and beside the
specification, with the ``workbench`` console script as with ``python -m workbench`` (issue
18.9: the console script's ``sys.path[0]`` is its ``bin/`` directory, not the current one)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from workbench.runs import store

CONSOLE_SCRIPT = Path(sys.executable).parent / "workbench"

LOCAL_PLUGIN = """
from workbench.model import Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import problem


@problem
class LocalPendulum(Problem):
    name = "local-pendulum"
    summary = "A pendulum defined beside the sweep (test)"
    source = "tests"
    t_end = 1.0
    n_samples = 11

    def model(self):
        model = Model("local-pendulum", kind="planar", gravity=(0.0, -9.81, 0.0))
        model.add_body("link", 1.0, com=(0.5, 0, 0), inertia=0.1)
        model.add_joint("pivot", "revolute", "ground", "link")
        return model

    def initial_joint_coordinates(self):
        return {"pivot": -1.0}
"""


def spec_text(out: Path) -> str:
    return f"""
out = "{out.as_posix()}"
jobs = 1
time_limit = 300.0
plugins = ["local_pendulum_plugin"]
problems = ["local-pendulum"]
formalisms = ["minimal-ode"]
integrators = ["rk4"]
tolerances = [1e-6]
"""


def sweep(command: list[str], cwd: Path, spec: Path) -> subprocess.CompletedProcess:
    return subprocess.run(  # the module being found is the subject: no report
        [*command, "sweep", "--no-report", str(spec)],
        cwd=cwd, capture_output=True, text=True, timeout=600,
    )  # fmt: skip


@pytest.mark.parametrize(
    "command",
    [[str(CONSOLE_SCRIPT)], [sys.executable, "-m", "workbench"]],
    ids=["console-script", "python-m"],
)
@pytest.mark.parametrize("where", ["current-directory", "spec-directory"])
def test_local_plugin_module_is_found(tmp_path, command, where) -> None:
    if not CONSOLE_SCRIPT.exists():
        pytest.skip(f"no console script at {CONSOLE_SCRIPT}")
    home = tmp_path / "project"
    home.mkdir()
    (home / "local_pendulum_plugin.py").write_text(LOCAL_PLUGIN)
    out = tmp_path / "out"
    spec = home / "sweep.toml"
    spec.write_text(spec_text(out))
    # run in the project, or elsewhere naming the spec beside the module
    cwd = home if where == "current-directory" else tmp_path
    result = sweep(command, cwd, spec)
    assert result.returncode == 0, result.stderr
    frame = store.load_results(out)
    assert list(frame["problem"]) == ["local-pendulum"]
    assert list(frame["status"]) == ["ok"], frame["message"].tolist()


def test_a_module_found_nowhere_is_one_line(tmp_path) -> None:
    if not CONSOLE_SCRIPT.exists():
        pytest.skip(f"no console script at {CONSOLE_SCRIPT}")
    spec = tmp_path / "sweep.toml"
    spec.write_text(spec_text(tmp_path / "out"))
    result = sweep([str(CONSOLE_SCRIPT)], tmp_path, spec)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "No module named 'local_pendulum_plugin'" in lines[0]
