"""A Dask cluster without a shared file system (issue 35.5): the local plugin module and the
computed references travel with the work. The workers start in an empty folder, the
specification's folder is renamed away once the client has read the module, and the
module records every import: the workers import their own copy, the rows and the recording
equal the local pool's, and a reference the client already holds is read, not computed, by
the workers."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.test_local_plugins import HELPER, spec_text
from workbench.execution.counted_work import COLUMNS as WORK_COLUMNS
from workbench.execution.references import computed_reference_file
from workbench.execution.timing import TIMING_COLUMNS
from workbench.outputs.recording import RECORDING_FILE, SweepRecorder
from workbench.plugin import local_modules
from workbench.plugin.registry import REGISTRY
from workbench.runs import shipping, store
from workbench.runs.sweep import load_spec, run_sweep

distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")

RECORDING = """
import os
with open({log!r}, "a") as log:  # every import of this module: which process, which file
    log.write(f"{{os.getpid()}} {{__file__}}\\n")
"""


@pytest.fixture
def isolated(tmp_path, monkeypatch):
    """A specification with its helper in ``spec/``, run from ``client/``; the registry and
    sys.modules restored afterwards."""
    folder = tmp_path / "spec"
    folder.mkdir()
    log = tmp_path / "imports.log"
    (folder / "helper.py").write_text(RECORDING.format(log=str(log)) + HELPER)
    (tmp_path / "client").mkdir()
    monkeypatch.chdir(tmp_path / "client")
    monkeypatch.delenv(local_modules.NO_LOCAL_PLUGINS_VARIABLE, raising=False)
    REGISTRY.discover()
    for kind, entries in REGISTRY.entries.items():
        monkeypatch.setitem(REGISTRY.entries, kind, dict(entries))
    yield folder, log
    sys.modules.pop("helper", None)
    local_modules._FROM_FILES.pop("helper", None)


def sweep(folder: Path, out: Path, scheduler: str | None = None) -> None:
    spec = folder / f"{out.name}.toml"
    text = spec_text(out, tolerances="[1e-4, 1e-6]", integrators='["rk4", "scipy-rk45"]')
    spec.write_text(text)
    run_sweep(load_spec(spec), scheduler=scheduler, show_progress=False, recorder=SweepRecorder)


def recorded_runs(out: Path) -> list[str]:
    """The runs ``out``'s merged recording holds; no run's own file may be left beside it."""
    assert not list((out / "recordings").glob("*.rrd"))
    return sorted(SweepRecorder().add_recording(out / RECORDING_FILE))


def comparable(out: Path):
    frame = store.load_results(out).set_index("run_id").sort_index()
    frame["reference"] = frame["reference"].str.replace(r" \(read from .*\)$", "", regex=True)
    timings = {"equations_cached", *TIMING_COLUMNS, *WORK_COLUMNS}
    return frame[[c for c in frame.columns if not c.endswith("_s") and c not in timings]]


def computations(out: Path) -> int:
    """How many runs computed their reference: not read from a file, not taken from the
    worker's memory (``reference_s`` 0)."""
    frame = store.load_results(out)
    read = frame["reference"].str.contains(r"\(read from ")
    return int((~read & (frame["reference_s"] > 0)).sum())


def test_workers_that_cannot_see_the_clients_folders(isolated, tmp_path, monkeypatch) -> None:
    folder, log = isolated
    sweep(folder, tmp_path / "local")  # the local pool's rows, as before
    away = tmp_path / "away"
    packed = shipping.pack_modules

    def pack_then_hide(plugins):  # read by the client, then gone for everybody
        result = packed(plugins)
        folder.rename(away)
        return result

    before = len(log.read_text().splitlines())  # the local pool's imports
    for name in ("workers", "workers-tmp"):
        (tmp_path / name).mkdir()
    monkeypatch.chdir(tmp_path / "workers")  # the workers start in an empty folder
    monkeypatch.setenv("TMPDIR", str(tmp_path / "workers-tmp"))  # their copies go there
    scratch = dask.config.set({"temporary-directory": str(tmp_path / "workers-tmp")})
    with (
        scratch,
        distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
        ) as cluster,
    ):
        monkeypatch.chdir(tmp_path / "client")
        monkeypatch.setattr(shipping, "pack_modules", pack_then_hide)
        monkeypatch.setattr("workbench.runs.dask_pool.pack_modules", pack_then_hide)
        sweep(folder, tmp_path / "dask", cluster.scheduler_address)
        # computed by one worker (its first run went alone), read by the other; both
        # computed it before
        assert computations(tmp_path / "dask") == 1
        # the reference a worker computed came back to the client
        returned = sorted(p.name for p in (tmp_path / "dask" / "references").iterdir())
        assert [Path(name).suffix for name in returned] == [".json", ".parquet"]
        # a second sweep whose OUT holds that reference already (another OUT: the workers'
        # own copies of the first sweep's references are not used)
        away.rename(folder)
        shutil.copytree(tmp_path / "dask" / "references", tmp_path / "known" / "references")
        sweep(folder, tmp_path / "known", cluster.scheduler_address)
    local = comparable(tmp_path / "local")
    assert len(local) == 4 and set(local["status"]) == {"ok"}
    # each run's recording came back with its row (the workers wrote theirs elsewhere)
    assert len(recorded_runs(tmp_path / "local")) == 4
    assert recorded_runs(tmp_path / "dask") == recorded_runs(tmp_path / "local")
    assert set(local["reference"].str.split(":").str[0]) == {"computed"}
    for name in ("dask", "known"):
        other = comparable(tmp_path / name)
        assert list(other.index) == list(local.index)
        different = [
            c
            for c in local.columns
            if not ((local[c] == other[c]) | (local[c].isna() & other[c].isna())).all()
        ]
        assert different == [], local[different].compare(other[different]).to_string()
    known = store.load_results(tmp_path / "known")
    assert known["reference"].str.contains(r"\(read from ").all(), known["reference"].tolist()
    # the workers imported their own copy of the module, never the client's file
    imports = [line.split(" ", 1) for line in log.read_text().splitlines()[before:]]
    copies = str(tmp_path / "workers-tmp")  # in the Dask workers' scratch folders
    assert imports, "the workers imported no helper"
    assert all(f.startswith(copies) and "/workbench-plugins-" in f for _, f in imports), imports


def test_a_local_package_and_its_stored_reference_are_shipped(tmp_path, monkeypatch) -> None:
    """A package beside the specification goes whole (its submodules, a stored reference
    beside them; not its caches); a host without the client's folder imports the copy in
    a fresh interpreter, under the same names, and finds the stored reference beside it."""
    package = tmp_path / "spec" / "my_pkg"
    (package / "references").mkdir(parents=True)
    (package / "__pycache__").mkdir()
    (package / "__init__.py").write_text("")
    (package / "plugins.py").write_text(HELPER.replace("with_name(", "parent.with_name("))
    (package / "references" / "downloaded-pendulum.npz").write_bytes(b"stored poses")
    (package / "__pycache__" / "plugins.cpython.pyc").write_bytes(b"cache")
    text = f"my_pkg.plugins={package / '__init__.py'}"
    packed = shipping.pack_modules([text, "workbench.plugins"])
    (relative, _digest, files) = packed[text]  # an installed module is not shipped
    assert list(packed) == [text] and relative == "my_pkg/__init__.py"
    names = ["my_pkg/__init__.py", "my_pkg/plugins.py", "my_pkg/references/downloaded-pendulum.npz"]
    assert sorted(files) == names
    assert shipping.unpack_modules([text], packed) == [text]  # the same files here: kept
    (tmp_path / "spec").rename(tmp_path / "away")
    monkeypatch.setattr(shipping.tempfile, "tempdir", str(tmp_path / "worker"))
    shipping._RESOLVED.clear()
    (copy,) = shipping.unpack_modules([text], packed)
    assert copy.startswith("my_pkg.plugins=" + str(tmp_path / "worker" / "workbench-plugins-"))
    code = (
        "import sys\n"
        "from workbench.plugin.local_modules import import_plugin_modules\n"
        "from workbench.plugin.registry import get_problem\n"
        "import_plugin_modules(sys.argv[1:])\n"
        "from pathlib import Path\n"
        "module = sys.modules[get_problem('downloaded-pendulum').__module__]\n"
        "print(module.__name__, (Path(module.__file__).parent / 'references').is_dir())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, copy],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["my_pkg.plugins", "True"]


def test_a_problems_first_run_goes_alone_while_its_reference_is_computed(isolated, tmp_path):
    """The client holds back the other runs of a problem whose reference it has not (the
    helper's computes one), not those of a problem with its own (simple-pendulum's is
    stored); a skipped first run hands its place on, a row or a run given up lets them go."""
    from collections import deque

    from workbench.execution.execute import RunSpec

    def runs(problem: str) -> list[RunSpec]:
        return [
            RunSpec(problem, "minimal-ode", integrator, rtol, rtol)
            for integrator in ("rk4", "scipy-rk45")
            for rtol in (1e-6, 1e-4)
        ]

    local_modules.import_plugin_modules([f"helper={isolated[0] / 'helper.py'}"])
    mine, stored = runs("downloaded-pendulum"), runs("simple-pendulum")
    queue = deque((None, spec) for spec in mine + stored)
    gate = shipping.ReferenceGate(queue, tmp_path / "references")
    assert [spec for _key, spec in queue] == [mine[1], *stored]  # the loosest goes first
    gate.returned(mine[1], {"status": "skipped"})  # said at once: the next goes alone
    assert [spec for _key, spec in queue] == [mine[0], mine[1], *stored]
    queue.clear()
    gate.returned(mine[0], {"status": "ok", "reference": "computed: ..."})
    assert [spec for _key, spec in queue] == [mine[2], mine[3]]
    queue = deque((None, spec) for spec in mine)
    gate = shipping.ReferenceGate(queue, tmp_path / "references")
    gate.returned(mine[1], None)  # given up: the others try themselves
    assert sorted(spec.run_id for _key, spec in queue) == sorted(s.run_id for s in mine)
    # a reference already in OUT/references (a resume): nothing held
    (tmp_path / "references").mkdir()
    problem = REGISTRY.get("problem", "downloaded-pendulum")({})
    name = computed_reference_file(problem, "downloaded-pendulum", {}, problem.sample_times())
    for suffix in (".parquet", ".json"):
        (tmp_path / "references" / name).with_suffix(suffix).write_text("")
    queue = deque((None, spec) for spec in mine)
    shipping.ReferenceGate(queue, tmp_path / "references")
    assert len(queue) == 4


def test_another_option_sets_reference_holds_nothing_back_of_this_one(tmp_path) -> None:
    """The gate asked for any reference of the problem's name: once one option set's
    reference was in OUT/references, another set's runs were not held, and every worker
    starting one computed that set's reference again."""
    from collections import deque

    from workbench.execution.execute import RunSpec

    def runs(n_links: int) -> list[RunSpec]:
        return [RunSpec("planar-chain", "minimal-ode", "scipy-rk45", rtol, rtol,
                        problem_options={"n_links": n_links}) for rtol in (1e-6, 1e-4)]  # fmt: skip

    three, four = runs(3), runs(4)
    folder = tmp_path / "references"
    folder.mkdir()
    problem = REGISTRY.get("problem", "planar-chain")({"n_links": 3})
    name = computed_reference_file(problem, "planar-chain", {"n_links": 3}, problem.sample_times())
    (folder / name).write_text("")
    queue = deque((None, spec) for spec in three + four)
    shipping.ReferenceGate(queue, folder)
    assert [spec for _key, spec in queue] == [*three, four[1]]  # n_links 4: its pilot alone
