"""Plugins from anywhere, the same way everywhere (issue 34.3): ``--plugins MODULE_OR_FILE``
on ``workbench run``, ``describe``, ``list`` and ``python -m workbench.testing``, a plugin class
named as ``FILE.py:Class`` where a name goes, and the module-only plugin ``workbench new``
writes without ``--package`` checked by the kit and run, end to end, as written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.test_scaffold import PHYSICS

BIN = Path(sys.executable).parent
WORKBENCH = BIN / "workbench"

# a problem class in a file of its own, not decorated: `file.py:Class` registers it
MY_PROBLEM = """
from workbench.model import Model
from workbench.plugin.problem import Problem


class MyProblem(Problem):
    name = "my-swing"
    summary = "A pendulum written in a file of its own (test)"
    source = "tests"
    t_end = 0.5
    n_samples = 6

    def model(self):
        model = Model("my-swing", kind="planar", gravity=(0.0, -9.81, 0.0))
        model.add_body("link", 1.0, com=(0.5, 0, 0), inertia=0.1)
        model.add_joint("pivot", "revolute", "ground", "link")
        return model

    def initial_joint_coordinates(self):
        return {"pivot": -1.0}
"""


def run(*args: object, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(a) for a in args], capture_output=True, text=True, cwd=cwd, timeout=600, env=env
    )


UNSUPPORTED = """    @classmethod
    def unsupported(cls, model: Model) -> set[str]:
        \"\"\"Lagrange's equations in this form need q' = v: no quaternion joints.\"\"\"
        from workbench.mechanics.lagrangian import quaternion_joints

        return super().unsupported(model) | quaternion_joints(model)

"""


@pytest.fixture
def console_script():
    if not WORKBENCH.exists():
        pytest.skip(f"no console script at {WORKBENCH}")


def test_run_and_describe_a_class_of_a_file(tmp_path, console_script):
    (tmp_path / "my_problem.py").write_text(MY_PROBLEM)
    ran = run(WORKBENCH, "run", "my_problem.py:MyProblem", "-f", "minimal-ode", "-i", "rk4",
              cwd=tmp_path)  # fmt: skip
    assert ran.returncode == 0, ran.stderr
    assert "│ status" in ran.stdout and " ok " in ran.stdout.split("│ status", 1)[1][:40]
    said = f"plugins: imported local module my_problem from {tmp_path / 'my_problem.py'}"
    assert said in ran.stderr.splitlines()
    described = run(WORKBENCH, "describe", "my_problem.py:MyProblem", cwd=tmp_path)
    assert described.returncode == 0, described.stderr
    assert described.stdout.startswith("my-swing (problem, my_problem)")
    refused = run(WORKBENCH, "run", "my_problem.py:MyProblem", "-f", "minimal-ode", "-i", "rk4",
                  "--no-local-plugins", cwd=tmp_path)  # fmt: skip
    assert refused.returncode == 2
    (line,) = refused.stderr.strip().splitlines()
    assert "local plugin modules are off" in line and "my_problem.py" in line
    not_a_plugin = run(WORKBENCH, "describe", "my_problem.py:Model", cwd=tmp_path)
    assert not_a_plugin.returncode == 2
    assert "is not a problem, formalism or integrator class" in not_a_plugin.stderr


def test_the_module_only_scaffold_passes_the_kit_as_written(tmp_path, console_script):
    """`workbench new formalism` without --package, the physics written as docs/plugins.md
    says (steps 3 and 5: T - V, quaternion joints declared unsupported): the kit finds it
    with --plugins (and says how when it is not given), passes it on its default problems,
    its generated test passes, and `workbench run --plugins` runs it."""
    assert run(WORKBENCH, "new", "formalism", "my-lagrange", cwd=tmp_path).returncode == 0
    plugin = tmp_path / "my_lagrange.py"
    text = plugin.read_text()
    start = text.index("        # TODO: write the mass matrix")
    end = text.index("        return MechanicalSystem(")
    written = text[:start] + PHYSICS.lstrip("\n") + text[end:]
    build = written.index("    def build(self")
    written = written[:build] + UNSUPPORTED + written[build:]
    plugin.write_text(written.replace("TODO: ", "").replace("TODO ", ""))

    kit = [sys.executable, "-m", "workbench.testing", "formalism", "my-lagrange"]
    unnamed = run(*kit, "--structural", cwd=tmp_path)
    assert unnamed.returncode == 2
    assert "--plugins my_lagrange.py" in unnamed.stderr  # how to name it
    checked = run(*kit, "--plugins", "my_lagrange.py", cwd=tmp_path)  # the default problems
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert " 0 failed" in checked.stdout.splitlines()[0]
    by_module = run(*kit, "--plugins", "my_lagrange", "--structural", cwd=tmp_path)
    assert by_module.returncode == 0, by_module.stdout + by_module.stderr

    tested = run(sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                 "test_my_lagrange.py", cwd=tmp_path)  # fmt: skip
    assert tested.returncode == 0, tested.stdout[-2000:]
    listed = run(WORKBENCH, "list", "formalisms", "--plugins", "my_lagrange.py", cwd=tmp_path)
    assert "my-lagrange" in listed.stdout and "broken" not in listed.stdout
    ran = run(WORKBENCH, "run", "double-pendulum", "-f", "my-lagrange", "-i", "scipy-dop853",
              "--plugins", "my_lagrange.py", cwd=tmp_path)  # fmt: skip
    assert ran.returncode == 0, ran.stderr
