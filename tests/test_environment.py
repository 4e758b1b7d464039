"""What produced a result: the row's columns, the sweep's environment.json, one reader."""

from __future__ import annotations

import json
import platform
import sys
import types

import numpy as np

from workbench.execution import environment as env


def test_distribution_versions_for_a_report() -> None:
    versions = env.distribution_versions(["numpy", "no-such-distribution-wb"])
    assert list(versions) == ["numpy", "no-such-distribution-wb"]
    assert versions == {"numpy": np.__version__, "no-such-distribution-wb": "not installed"}
    assert env.distribution_versions(["no-such-distribution-wb"], missing="") == {
        "no-such-distribution-wb": ""
    }


def test_row_columns_are_unchanged() -> None:
    row = env.environment()
    assert list(row) == [
        "version_python",
        "version_numpy",
        "version_scipy",
        "version_casadi",
        "version_sksundae",
        "version_workbench",
        "machine",
        "cpu_count",
    ]
    assert row["version_numpy"] == np.__version__
    assert row["version_python"] == platform.python_version()


def test_cpu_model_from_cpuinfo_else_the_platform(tmp_path) -> None:
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: X\nmodel name\t: Example CPU @ 3 GHz\n")
    assert env.cpu_model(str(cpuinfo)) == "Example CPU @ 3 GHz"
    # a virtual machine's name covers several generations: family and model tell them apart
    epyc = "processor\t: 0\ncpu family\t: {}\nmodel\t\t: {}\nmodel name\t: AMD EPYC\n\n"
    cpuinfo.write_text(epyc.format(25, 1) + epyc.format(99, 9))
    assert env.cpu_model(str(cpuinfo)) == "AMD EPYC (family 25, model 1)"
    cpuinfo.write_text(epyc.format(26, 2))
    assert env.cpu_model(str(cpuinfo)) == "AMD EPYC (family 26, model 2)"
    cpuinfo.write_text("processor\t: 0\nCPU part\t: 0xd0c\n")  # ARM: no model name
    expected = platform.processor() or platform.machine()
    assert env.cpu_model(str(cpuinfo)) == expected
    assert env.cpu_model(str(tmp_path / "missing")) == expected


def test_thread_settings_with_and_without_threadpoolctl(monkeypatch) -> None:
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    monkeypatch.setitem(sys.modules, "threadpoolctl", None)  # not installed
    without = env.thread_settings()
    assert without["environment"]["OMP_NUM_THREADS"] == "3"
    assert without["environment"]["MKL_NUM_THREADS"] is None
    assert "threadpools" not in without and "Build Dependencies" in without["numpy_config"]
    pools = [{"user_api": "blas", "internal_api": "openblas", "num_threads": 3}]
    fake = types.SimpleNamespace(threadpool_info=lambda: pools)
    monkeypatch.setitem(sys.modules, "threadpoolctl", fake)
    with_it = env.thread_settings()
    assert with_it["threadpools"] == pools and "numpy_config" not in with_it


def test_sweep_environment_is_json_and_lists_every_distribution() -> None:
    data = json.loads(json.dumps(env.sweep_environment()))
    assert list(data) == [
        "recorded_at",
        "python",
        "platform",
        "cpu_model",
        "cpu_count",
        "threads",
        "distributions",
    ]
    assert data["python"]["version"] == platform.python_version()
    assert data["cpu_count"] >= 1 and data["cpu_model"]
    distributions = data["distributions"]
    assert distributions["numpy"] == np.__version__
    assert distributions["mbs-workbench"] == env.environment()["version_workbench"]
    assert list(distributions) == sorted(distributions, key=str.lower)
