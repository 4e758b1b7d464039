"""benchmarks.peers_paired's statistic: a process's ratio is of timings made in turn in
that process, so a slow-down of the whole process (the machine's, both sides alike)
leaves it as it is, where the slowest process of one side over the fastest of the other
(pyperf's upper end) takes it in twice."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyperf")

from benchmarks.peers_paired import summarize  # noqa: E402
from benchmarks.peers_pyperf import BUFFER, PYTHON  # noqa: E402

PREPARED = {"kind": "random", "name": "7", "nv": 14, "graph": "unrolled",
            "python_call": "direct", "instructions": 1, "code_bytes": 1}  # fmt: skip


def test_a_slow_process_slows_both_sides_and_leaves_its_ratio() -> None:
    rng = np.random.default_rng(1)
    results = []
    for slow in (1.0, 1.0, 2.5, 1.0, 1.8):  # a process's speed: the machine's state
        rounds = rng.uniform(0.98, 1.02, size=(4, 20))  # the rounds' own noise
        results.append({
            PYTHON[0]: list(1e-6 * slow * rounds[0]), PYTHON[1]: list(4e-6 * slow * rounds[1]),
            BUFFER[0]: list(1e-6 * slow * rounds[2]), BUFFER[1]: list(5e-6 * slow * rounds[3]),
        })  # fmt: skip
    row = summarize(PREPARED, results, (0.0, 0.0))
    assert row["paired_median"] == pytest.approx(0.25, rel=0.02)
    assert row["paired_max"] == pytest.approx(0.25, rel=0.04)
    assert row["buffer_paired_max"] == pytest.approx(0.2, rel=0.04)
    assert row["crossed_max"] == pytest.approx(0.25 * 2.5, rel=0.04)  # 2.5x slow, 1x fast
    assert row["ours_spread"] == pytest.approx(2.5, rel=0.04)
    assert row["processes"] == 5 and row["rounds"] == 20
