"""The default-sweep benchmark's shares of time: what a killed run counts as."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from benchmarks.default_sweep import shares_of


def test_a_run_killed_at_the_time_limit_is_not_counted_as_pairing() -> None:
    """A timed-out row carries only the wall time until it was killed (its progress file):
    the benchmark counted all of it as "pairing" (wall_s less the stages), 395 s of the
    full sweep's 2026-11-27 measurement. It is counted apart."""
    ok = {"status": "ok", "formalism": "recursive", "wall_s": 1.0, "cpu_s": 0.8}
    ok |= {"build_s": 0.2, "compile_s": 0.0, "init_s": 0.05, "integrate_s": 0.5}
    ok |= {"integrate_cpu_s": 0.45, "metrics_s": 0.2, "reference_s": 0.0, "log_s": 0.01}
    ok |= {"repeats": 1, "integrate_s_min": 0.5, "integrate_s_max": 0.5, "load_avg": 1.0}
    timeout = {"status": "timeout", "formalism": "absolute-dae", "wall_s": 30.0,
               "stage": "integrate"}  # fmt: skip
    skipped = {"status": "skipped", "formalism": "recursive"}
    shares, per_formalism = shares_of(pd.DataFrame([ok, timeout, skipped]), 1, 40.0)
    assert shares["total_pairing_s"] == pytest.approx(0.05)  # 1.0 - (0.2 + 0.05 + 0.5 + 0.2)
    assert shares["runs_killed"] == 1 and shares["killed_s"] == 30.0
    assert shares["ran"] == 2 and shares["median_integrate_s"] == 0.5
    assert shares["outside_share_of_stages"] == pytest.approx(1 - 0.5 / 1.01)
    assert per_formalism.loc["absolute-dae", "killed_s"] == 30.0
    assert per_formalism.loc["absolute-dae", "pairing_s"] == 0.0
    assert not math.isnan(shares["outside_share_of_cpu"])


def test_a_retimed_row_counts_its_own_integration_not_the_later_samples() -> None:
    """A close call timed again after the runs keeps its ``wall_s`` (its own integration,
    0.5 s) but gets the later samples' median as ``integrate_s`` (here 0.8 s): wall less
    stages made -0.25 s of "pairing". Its pairing is a typical run's, its integration
    the rest of its own wall time."""
    ok = {"status": "ok", "formalism": "recursive", "wall_s": 1.0, "cpu_s": 0.8}
    ok |= {"build_s": 0.2, "compile_s": 0.0, "init_s": 0.05, "integrate_s": 0.5}
    ok |= {"integrate_cpu_s": 0.45, "metrics_s": 0.2, "reference_s": 0.0, "log_s": 0.0}
    ok |= {"repeats": 3, "integrate_s_min": 0.5, "integrate_s_max": 0.5, "load_avg": 1.0}
    retimed = ok | {"integrate_s": 0.8, "integrate_cpu_s": 0.75, "integrate_s_max": 0.9,
                    "repeats": 8, "retimed": 5}  # fmt: skip
    shares, _ = shares_of(pd.DataFrame([ok, retimed]), 1, 10.0)
    assert shares["total_pairing_s"] == pytest.approx(0.1)
    assert shares["integrate_s"] == pytest.approx(1.0)
    assert shares["outside_share_of_stages"] == pytest.approx(1 - 1.0 / 2.0)
    assert shares["outside_share_of_cpu"] == pytest.approx(1 - (0.45 + 0.3) / 1.6)  # own: 0.3
    assert shares["repeat_s"] == pytest.approx(2.0)  # two more samples of 0.5 s each run
    assert shares["runs_repeated"] == 2
