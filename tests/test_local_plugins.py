"""Running someone's specification runs the code beside it: a stated, visible choice
(issue 31.3). A downloaded specification with a ``helper.py`` that writes a marker file when
imported: the helper is imported only once everything else in the specification is valid,
from its own file (its folder is not put on ``sys.path``), the import is said on stderr with
the path, and ``--no-local-plugins`` / ``WORKBENCH_NO_LOCAL_PLUGINS=1`` refuses it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from workbench.errors import ConfigError
from workbench.plugin import local_modules
from workbench.plugin.local_modules import NO_LOCAL_PLUGINS_VARIABLE
from workbench.plugin.registry import REGISTRY
from workbench.runs import store
from workbench.runs.sweep import load_spec

HELPER = """
from pathlib import Path

Path(__file__).with_name("imported.marker").write_text("helper.py ran")

from workbench.model import Model
from workbench.plugin.problem import Problem
from workbench.plugin.registry import problem


@problem
class DownloadedPendulum(Problem):
    name = "downloaded-pendulum"
    summary = "A pendulum shipped beside a downloaded specification (test)"
    source = "tests"
    t_end = 0.5
    n_samples = 6

    def model(self):
        model = Model("downloaded-pendulum", kind="planar", gravity=(0.0, -9.81, 0.0))
        model.add_body("link", 1.0, com=(0.5, 0, 0), inertia=0.1)
        model.add_joint("pivot", "revolute", "ground", "link")
        return model

    def initial_joint_coordinates(self):
        return {"pivot": -1.0}
"""

# a sibling module the specification does not name: it must not become importable
SIBLING = "VALUE = 'the sibling was importable'\n"


def spec_text(out: Path, **changes: str | None) -> str:
    """The specification; a change to None leaves its key out."""
    keys = {
        "out": f'"{out.as_posix()}"',
        "jobs": "1",
        "time_limit": "300.0",
        "plugins": '["helper"]',
        "problems": '["downloaded-pendulum"]',
        "formalisms": '["minimal-ode"]',
        "integrators": '["rk4"]',
        "tolerances": "[1e-6]",
    } | changes
    return "".join(f"{key} = {value}\n" for key, value in keys.items() if value is not None)


@pytest.fixture
def downloaded(tmp_path, monkeypatch):
    """A downloaded folder (specification beside helper.py and sibling.py), run from
    another directory; the registry, sys.modules and the environment restored afterwards."""
    folder = tmp_path / "downloaded"
    folder.mkdir()
    (folder / "helper.py").write_text(HELPER)
    (folder / "sibling.py").write_text(SIBLING)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.delenv(NO_LOCAL_PLUGINS_VARIABLE, raising=False)
    REGISTRY.discover()
    for kind, entries in REGISTRY.entries.items():
        monkeypatch.setitem(REGISTRY.entries, kind, dict(entries))
    yield folder
    for name in ("helper", "sibling"):
        sys.modules.pop(name, None)
        local_modules._FROM_FILES.pop(name, None)


INVALID_ELSEWHERE = {
    "a problem entry of the wrong type": {"problems": '["downloaded-pendulum", 42]'},
    "an unknown key in a formalism table": {
        "formalisms": '[{ name = "minimal-ode", optons = {} }]'
    },
    "a value twice in an option grid": {
        "integrators": '[{ name = "rk4", options = { steps_per_sample = [2, 2] } }]'
    },
    "an integrator's own bad tolerance": {"integrators": '[{ name = "rk4", tolerances = [-1] }]'},
    "an unknown top-level key": {"tolerance": "[1e-6]"},
    "a missing key": {"integrators": None},
    "a table where a list goes": {"tolerances": "[1e-6]\n[extra]\nx = 1"},
}


@pytest.mark.parametrize("changes", INVALID_ELSEWHERE.values(), ids=INVALID_ELSEWHERE.keys())
def test_a_specification_invalid_elsewhere_does_not_import_its_helper(downloaded, changes):
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(downloaded / "out", **changes))
    with pytest.raises(ConfigError):
        load_spec(spec)
    assert not (downloaded / "imported.marker").exists()
    assert "helper" not in sys.modules


def test_the_helper_is_imported_from_its_file_and_said_on_stderr(downloaded, capsys):
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(downloaded / "out"))
    path_before = list(sys.path)
    sweep = load_spec(spec)
    assert (downloaded / "imported.marker").read_text() == "helper.py ran"
    assert [run.problem for run in sweep.runs] == ["downloaded-pendulum"]
    helper = str((downloaded / "helper.py").resolve())
    assert sweep.plugins == [f"helper={helper}"]  # what workers import: the same file
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"plugins: imported local module helper from {helper}"]
    # only the module named: its folder is not on the path, its sibling not importable
    assert sys.path == path_before
    with pytest.raises(ModuleNotFoundError):
        __import__("sibling")


@pytest.mark.parametrize("value", ["1", "yes"])
def test_the_environment_switch_refuses_a_local_module(downloaded, monkeypatch, value):
    monkeypatch.setenv(NO_LOCAL_PLUGINS_VARIABLE, value)
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(downloaded / "out"))
    with pytest.raises(ConfigError) as caught:
        load_spec(spec)
    message = str(caught.value)
    assert "\n" not in message
    assert "'helper' is a local plugin module" in message
    assert str((downloaded / "helper.py").resolve()) in message
    assert NO_LOCAL_PLUGINS_VARIABLE in message and "run without the switch" in message
    assert not (downloaded / "imported.marker").exists()
    # installed modules still load under the switch (an installed package is not local)
    assert load_spec(spec, allow_local=True).runs  # and the switch is per call too


def test_a_plugin_path_is_relative_to_the_specification(downloaded, capsys):
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(downloaded / "out", plugins='["helper.py"]'))
    sweep = load_spec(spec)
    assert sweep.plugins == [f"helper={(downloaded / 'helper.py').resolve()}"]
    assert "imported local module helper from" in capsys.readouterr().err


CONSOLE_SCRIPT = Path(sys.executable).parent / "workbench"


def test_the_command_line_switch_and_a_sweep_that_imports_it_once(downloaded, tmp_path):
    """The end to end form: the switch refuses (one line, exit 2, nothing imported); without
    it the sweep runs in a worker process that imports the same file (row ok), and the
    parent says the import once, with the path."""
    if not CONSOLE_SCRIPT.exists():
        pytest.skip(f"no console script at {CONSOLE_SCRIPT}")
    out = tmp_path / "out"
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(out))
    command = [str(CONSOLE_SCRIPT), "sweep", str(spec)]
    refused = subprocess.run(
        [*command, "--no-local-plugins"], capture_output=True, text=True, timeout=600
    )
    assert refused.returncode == 2
    lines = refused.stderr.strip().splitlines()
    assert len(lines) == 1 and "local plugin modules are off" in lines[0], refused.stderr
    assert not (downloaded / "imported.marker").exists() and not out.exists()

    ran = subprocess.run([*command, "--no-report"], capture_output=True, text=True, timeout=600)
    assert ran.returncode == 0, ran.stderr
    helper = (downloaded / "helper.py").resolve()
    said = [line for line in ran.stderr.splitlines() if line.startswith("plugins:")]
    assert said == [f"plugins: imported local module helper from {helper}"]
    frame = store.load_results(out)
    assert list(frame["status"]) == ["ok"], frame["message"].tolist()


def test_plugins_given_on_the_command_line_join_a_specification(downloaded, capsys):
    """`workbench sweep spec --plugins FILE`: a specification that names no plugin module,
    the module given beside it (a path from the current directory), the same rules."""
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(downloaded / "out", plugins=None))
    with pytest.raises(ConfigError, match="unknown problem 'downloaded-pendulum'"):
        load_spec(spec)
    assert not (downloaded / "imported.marker").exists()
    given = str(downloaded / "helper.py")
    with pytest.raises(ConfigError, match=r"--plugins\[0\]: 'helper' is a local plugin module"):
        load_spec(spec, plugins=[given], allow_local=False)
    sweep = load_spec(spec, plugins=[given])
    assert sweep.plugins == [f"helper={Path(given).resolve()}"]
    assert "plugins: imported local module helper from" in capsys.readouterr().err


def test_a_worker_imports_the_file_it_is_given_not_a_name_it_searches(downloaded, tmp_path):
    """What every worker (local pool spawned or forkserver, Dask child, `workbench run`'s
    child) does with the parent's list: a fresh interpreter elsewhere, with nothing on its
    path, gets the very file; a file that is not there is one ConfigError naming it."""
    helper = (downloaded / "helper.py").resolve()
    code = (
        "import sys\n"
        "from workbench.plugin.local_modules import import_plugin_modules\n"
        "from workbench.plugin.registry import get_problem\n"
        "before = list(sys.path)\n"
        "import_plugin_modules(sys.argv[1:])\n"
        "assert sys.path == before\n"
        "print(get_problem('downloaded-pendulum').__module__, sys.modules['helper'].__file__)\n"
    )
    elsewhere = tmp_path / "worker"
    elsewhere.mkdir()
    done = subprocess.run(
        [sys.executable, "-c", code, f"helper={helper}"],
        cwd=elsewhere, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["helper", str(helper)]
    with pytest.raises(ConfigError, match="cannot import plugin module 'gone'"):
        local_modules.import_plugin_modules([f"gone={tmp_path / 'gone.py'}"])


@pytest.mark.parametrize(
    "module",
    [
        local_modules.PluginModule("helper"),
        local_modules.PluginModule("helper", "/a b/c=d/helper.py"),
        local_modules.PluginModule("my_pkg.plugins", "/x/my_pkg/__init__.py", "MyProblem"),
        local_modules.PluginModule("pkg.mod", "", "Klass"),
    ],
)
def test_what_workers_receive_reads_back(module):
    assert local_modules.PluginModule.from_text(module.text()) == module


def test_a_dotted_module_of_a_local_package(downloaded, capsys):
    """``plugins = ["my_pkg.plugins"]`` beside the specification: the package is imported
    from its ``__init__.py``, the submodule from the package's folder, nothing else."""
    package = downloaded / "my_pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "plugins.py").write_text(HELPER.replace("with_name(", "parent.with_name("))
    (downloaded / "helper.py").unlink()
    spec = downloaded / "sweep.toml"
    spec.write_text(spec_text(downloaded / "out", plugins='["my_pkg.plugins"]'))
    try:
        sweep = load_spec(spec)
        assert sweep.plugins == [f"my_pkg.plugins={(package / '__init__.py').resolve()}"]
        assert (downloaded / "imported.marker").exists()
        said = capsys.readouterr().err.strip().splitlines()
        assert said == [
            f"plugins: imported local module my_pkg.plugins from {package.resolve() / 'plugins.py'}"
        ]
    finally:
        for name in ("my_pkg", "my_pkg.plugins"):
            sys.modules.pop(name, None)
        local_modules._FROM_FILES.pop("my_pkg", None)


def test_a_plugin_importing_its_sibling_is_told_how(downloaded) -> None:
    """The folder stays off sys.path, and the error says so and how to name the sibling
    (it was a bare ModuleNotFoundError)."""
    (downloaded / "helper.py").write_text("import sibling\n" + HELPER)
    text = spec_text(downloaded / "out", plugins='["helper"]')
    (downloaded / "spec.toml").write_text(text)
    with pytest.raises(ConfigError) as caught:
        load_spec(str(downloaded / "spec.toml"))
    message = str(caught.value)
    assert "No module named 'sibling' (sibling.py beside it is not importable" in message
    assert "name it with --plugins too, before helper.py" in message
    sys.modules.pop("helper", None)
    local_modules._FROM_FILES.pop("helper", None)
    (downloaded / "spec.toml").write_text(spec_text(downloaded / "out",
                                                    plugins='["sibling", "helper"]'))  # fmt: skip
    assert load_spec(str(downloaded / "spec.toml")).plugins  # named first, it imports
