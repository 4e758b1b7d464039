"""`python -m benchmarks --summary` holds each sweep's figures to the targets of that sweep:
a quick look (``--suite quick``) is listed apart and never shown as the full sweep's verdict."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

import benchmarks.__main__ as summary
from benchmarks import default_sweep

STORED = Path(summary.__file__).parent / "results"


def test_a_quick_sweep_is_not_held_to_the_full_sweeps_targets(tmp_path, monkeypatch) -> None:
    shutil.copy(STORED / "default_sweep-quick.csv", tmp_path / default_sweep.results_name("quick"))
    monkeypatch.setattr(summary, "RESULTS", tmp_path)
    rows = [row for row in summary.targets() if "sweep" in row.target]
    assert len(rows) == 2
    assert all(row.target.startswith("sweep quick (") for row in rows)
    assert all(pd.isna(row.bound) for row in rows)


def test_the_full_sweep_keeps_its_targets(tmp_path, monkeypatch) -> None:
    shutil.copy(STORED / "default_sweep.csv", tmp_path / default_sweep.results_name("full"))
    monkeypatch.setattr(summary, "RESULTS", tmp_path)
    rows = [row for row in summary.targets() if row.target.startswith("sweep full (")]
    share = [
        row
        for row in rows
        if row.target.endswith("share of the runs' time outside the integrators")
    ]
    assert len(rows) == 2 and len(share) == 1
    assert share[0].bound == pytest.approx(0.1)


def test_a_later_tiny_run_measurement_replaces_the_targets_one(tmp_path, monkeypatch) -> None:
    for name in ("footprint-targets.csv", "footprint-tiny.csv"):
        shutil.copy(STORED / name, tmp_path / name)
    monkeypatch.setattr(summary, "RESULTS", tmp_path)
    tiny = pd.read_csv(tmp_path / "footprint-tiny.csv").dropna(subset=["marginal_outside_cpu_ms"])
    rows = {row.target: row for row in summary.issue35_targets()}
    marginal = rows["time outside integration, marginal at 10,000 runs (ms)"]
    assert marginal.value == tiny[tiny["code"] == "after"].marginal_outside_cpu_ms.iloc[-1]
    assert "footprint-tiny.csv" in marginal.note
    # the same sweep under --no-recording is said beside it, not as the target's value
    (unrecorded,) = [row for target, row in rows.items() if "--no-recording" in target]
    assert unrecorded.value == tiny[tiny["code"] != "after"].marginal_outside_cpu_ms.iloc[-1]
    assert unrecorded.value < marginal.value and unrecorded.bound != unrecorded.bound  # none
