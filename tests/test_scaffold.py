"""``workbench new``: the scaffold writes plugins that register, list, pass the structural
checks, and (slow test) install as a separate package in a fresh virtual environment
and run in a sweep, before and after the author writes the physics."""

import importlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

from workbench.cli import app
from workbench.errors import ConfigError
from workbench.plugin.registry import REGISTRY
from workbench.plugin.scaffold import scaffold
from workbench.testing import check_formalism, check_integrator, check_problem

REPO = Path(__file__).resolve().parents[1]
CHECKERS = {"formalism": check_formalism, "integrator": check_integrator, "problem": check_problem}


@pytest.fixture
def isolated_registry(monkeypatch):
    """Plugins registered during the test are removed afterwards."""
    REGISTRY.discover()
    for kind, entries in REGISTRY.entries.items():
        monkeypatch.setitem(REGISTRY.entries, kind, dict(entries))


@pytest.mark.parametrize("kind", ["formalism", "integrator", "problem"])
def test_a_module_scaffold_registers_and_passes_the_structural_checks(
    kind, tmp_path, monkeypatch, isolated_registry
):
    written = scaffold(kind, f"my-new-{kind}", where=tmp_path)
    module = f"my_new_{kind}"
    assert [p.name for p in written.files] == [f"{module}.py", f"test_{module}.py"]
    lint = subprocess.run(
        [
            sys.executable,
            "-m",
            "ruff",
            "check",
            "--select",
            "E,F,W,B,UP",
            "--line-length",
            "100",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
    )
    assert lint.returncode == 0, lint.stdout
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module(module)
    try:
        report = CHECKERS[kind](f"my-new-{kind}", checks="structural")
        assert {"registered", "metadata", "options"} <= {r.check for r in report.results}
        # all pass but metadata (and a problem's source), which name the placeholders
        failures = {r.check: r.message for r in report.failures}
        assert set(failures) == {"metadata"} | ({"declarations"} if kind == "problem" else set())
        assert "placeholder" in failures["metadata"]
    finally:
        sys.modules.pop(module, None)


def test_the_spatial_problem_placeholder_is_a_working_quaternion_problem(
    tmp_path, monkeypatch, isolated_registry
):
    """The spatial placeholder (a body on a spherical joint) passes every physics check of
    the kit as generated: only its TODO summary and source are left to write."""
    scaffold("problem", "my-top", where=tmp_path, spatial=True)
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("my_top")
    try:
        from workbench.plugin.registry import get_problem

        model = get_problem("my-top")().model()
        assert model.kind == "spatial" and [j.type for j in model.joints.values()] == ["spherical"]
        report = check_problem("my-top")
    finally:
        sys.modules.pop("my_top", None)
    failed = {r.check for r in report.failures}
    assert failed <= {"metadata", "declarations"}, report
    assert any(r.status == "pass" for r in report.results if r.check not in failed)
    with pytest.raises(ConfigError, match="--spatial is for problems only"):
        scaffold("formalism", "flat", where=tmp_path, spatial=True)


def test_the_physics_is_the_only_thing_left_to_write(tmp_path, monkeypatch, isolated_registry):
    scaffold("formalism", "unwritten", where=tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("unwritten")
    try:
        report = check_formalism("unwritten", ["simple-pendulum"])
    finally:
        sys.modules.pop("unwritten", None)
    failures = {r.check: r.message for r in report.failures}
    assert set(failures) == {"metadata", "build"}  # the TODO summary, and the physics
    assert "write the mass matrix and forces" in failures["build"]


def test_inside_a_source_tree_it_writes_a_builtin_plugin(tmp_path):
    for directory in ("plugins/formalisms", "plugins/integrators", "problems", "tests"):
        (tmp_path / directory).mkdir(parents=True)
    written = scaffold("integrator", "leapfrog", where=tmp_path)
    assert [p.relative_to(tmp_path).as_posix() for p in written.files] == [
        "plugins/integrators/leapfrog.py",
        "tests/test_leapfrog.py",
    ]


def test_a_package_scaffold_declares_its_entry_point(tmp_path):
    scaffold("problem", "my-rig", package="rig", where=tmp_path)
    text = (tmp_path / "rig" / "pyproject.toml").read_text()
    assert '[project.entry-points."workbench.problems"]' in text
    assert 'my-rig = "my_rig.plugin:MyRig"' in text
    assert (tmp_path / "rig" / "my_rig" / "plugin.py").is_file()
    assert (tmp_path / "rig" / "tests" / "test_my_rig.py").is_file()
    # the stored reference ships in the wheel, and the tests' pytest comes with [test]
    assert "[tool.setuptools.package-data]" in text
    assert 'my_rig = ["references/*.npz", "references/*.json"]' in text
    assert 'test = ["pytest>=7"]' in text
    assert (tmp_path / "rig" / "my_rig" / "references" / "README.md").is_file()


@pytest.mark.parametrize("name", ["My Formalism", "9lives", "class", "under__score", "-x", ""])
def test_bad_names_are_refused(name, tmp_path):
    with pytest.raises(ConfigError, match="is not valid"):
        scaffold("formalism", name, where=tmp_path)


def test_existing_files_are_not_overwritten_without_force(tmp_path):
    scaffold("formalism", "twice", where=tmp_path)
    (tmp_path / "twice.py").write_text("# my work\n")
    with pytest.raises(ConfigError, match="twice.py already exists.*--force"):
        scaffold("formalism", "twice", where=tmp_path)
    assert (tmp_path / "twice.py").read_text() == "# my work\n"
    scaffold("formalism", "twice", where=tmp_path, force=True)
    assert "class Twice(Formalism)" in (tmp_path / "twice.py").read_text()


def test_command_line_errors_are_one_line_with_exit_code_2(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    for args, fragment in [
        (["new", "formalism", "Bad Name"], "is not valid"),
        (["new", "solver", "x"], "unknown plugin kind"),
        (["new", "formalism", "minimal-ode"], "already registered"),
    ]:
        result = runner.invoke(app, args)
        assert result.exit_code == 2 and fragment in result.output, result.output
        assert "Traceback" not in result.output
    result = runner.invoke(app, ["new", "problem", "my-rig", "--package", "rig"])
    assert result.exit_code == 0 and "wrote rig/pyproject.toml" in result.output
    assert 'pip install -e "rig[test]"' in result.output


# -- the "done when" test: a separate package in a fresh virtual environment -------------

PHYSICS = """
        from workbench.mechanics.lagrangian import joint_space_lagrangian

        kinetic, potential, nonconservative = joint_space_lagrangian(model, k)
        momentum = ca.gradient(kinetic, k.v)
        mass = ca.jacobian(momentum, k.v)
        forces = (
            ca.gradient(kinetic - potential, k.q)
            - ca.mtimes(ca.jacobian(momentum, k.q), k.v)
            - ca.jacobian(momentum, k.t)
            + nonconservative
        )
"""


def fresh_environment(root: Path) -> Path:
    """A new virtual environment with its own pip and site-packages, the workbench
    installed into it from a copy of this source tree (a normal, non-editable install:
    package data must ship), and the third-party dependencies made importable from the
    test interpreter's site-packages (no network); returns its bin directory.

    The dependencies come through a .pth file naming a directory of symbolic links to
    the test environment's packages, leaving out mbs-workbench itself (its metadata,
    entry points and editable finder), so that everything about the workbench and the
    plugin in the fresh environment comes from real installs. pip and setuptools (>= 70.1,
    which builds wheels by itself) come from the test environment too.
    """
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root / "venv")], check=True)
    bin_dir = root / "venv" / "bin"
    purelib = subprocess.run(
        [bin_dir / "python", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    deps = root / "deps"
    deps.mkdir()
    excluded = ("mbs_workbench", "__editable__", "workbench", "plugins", "problems")
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.startswith(excluded) and not entry.name.endswith(".pth"):
            os.symlink(entry, deps / entry.name)
    (Path(purelib) / "test_dependencies.pth").write_text(f"{deps}\n")
    source = root / "source"
    shutil.copytree(
        REPO,
        source,
        ignore=shutil.ignore_patterns(
            ".git",
            "reports",
            "build",
            "*.egg-info",
            "__pycache__",
            ".pytest_cache",
            "results",
            ".ruff_cache",
            "docs",
        ),
    )
    pip = [
        bin_dir / "python",
        "-m",
        "pip",
        "install",
        "-q",
        "--no-deps",
        "--no-index",
        "--no-build-isolation",
    ]
    subprocess.run([*pip, str(source)], check=True, cwd=root)
    return bin_dir


@pytest.mark.slow
def test_scaffolded_package_in_a_fresh_environment(tmp_path):
    bin_dir = fresh_environment(tmp_path)

    def run(*args: str, check: bool = True) -> subprocess.CompletedProcess:
        result = subprocess.run(
            [str(a) for a in args], capture_output=True, text=True, cwd=tmp_path, timeout=300
        )
        assert not check or result.returncode == 0, result.stdout + result.stderr
        return result

    where = run(bin_dir / "python", "-c", "import workbench; print(workbench.__file__)")
    assert where.stdout.startswith(str(tmp_path / "venv"))  # not this source tree

    run(bin_dir / "workbench", "new", "formalism", "my-lagrange", "--package", "pkg")
    pip = [
        bin_dir / "python",
        "-m",
        "pip",
        "install",
        "-q",
        "--no-deps",
        "--no-index",
        "--no-build-isolation",
    ]
    run(*pip, "-e", tmp_path / "pkg")

    listed = run(bin_dir / "workbench", "list", "formalisms").stdout
    assert "my-lagrange" in listed and "broken" not in listed
    checked = run(
        bin_dir / "python",
        "-m",
        "workbench.testing",
        "formalism",
        "my-lagrange",
        "--structural",
        check=False,
    )
    structural = checked.stdout
    assert checked.returncode != 0  # the TODO summary fails metadata until written
    assert "1 failed" in structural and "PASS  registered" in structural
    assert "FAIL  metadata" in structural and "placeholder" in structural  # TODO summary

    spec = tmp_path / "sweep.toml"

    def sweep(out: str) -> dict:
        spec.write_text(
            textwrap.dedent(f"""
            out = "{tmp_path / out}"
            jobs = 1
            tolerances = [1e-6]
            problems = ["double-pendulum"]
            formalisms = ["my-lagrange"]
            integrators = ["scipy-dop853"]
        """)
        )
        run(bin_dir / "workbench", "sweep", spec)
        rows = run(
            bin_dir / "python",
            "-c",
            textwrap.dedent(f"""
            import json, workbench
            row = workbench.load_results("{tmp_path / out}").iloc[0]
            print(json.dumps({{k: row[k] for k in ("status", "err_max", "message")}}))
        """),
        ).stdout
        return json.loads(rows)

    before = sweep("before")  # no physics yet: the run fails at build, saying what to write
    assert before["status"] == "failed"
    assert "build: NotImplementedError" in before["message"]
    assert "write the mass matrix and forces" in before["message"]

    plugin = tmp_path / "pkg" / "my_lagrange" / "plugin.py"
    text = plugin.read_text()
    start = text.index("        # TODO: write the mass matrix")
    end = text.index("        return MechanicalSystem(")
    written = text[:start] + PHYSICS.lstrip("\n") + text[end:]
    plugin.write_text(written.replace("TODO: ", "").replace("TODO ", ""))  # and the summary

    after = sweep("after")
    assert after["status"] == "ok" and after["err_max"] < 1e-3, after
    conformance = run(
        bin_dir / "python",
        "-m",
        "workbench.testing",
        "formalism",
        "my-lagrange",
        "--problems",
        "simple-pendulum,double-pendulum",
    )
    assert " 0 failed" in conformance.stdout
