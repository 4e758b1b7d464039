"""Issue 18, input validation: every bad input is one clear line, nothing hangs.

Regression tests for each item (sweep specs, trajectory shapes, non-finite models, the
``run`` command, one-line messages) and seeded fuzz tests: >= 1,000 sweep specifications
through ``parse_spec`` and ``workbench sweep``, >= 1,000 models, >= 200 ``run`` lines.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tests import fuzz_inputs
from workbench.cli import app
from workbench.errors import ConfigError
from workbench.runs.sweep_spec import parse_spec

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()

SPEC = (
    'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
    "integrators = {integrators}\ntolerances = {tolerances}\n"
)


def spec(integrators: str = '["rk4"]', tolerances: str = "[1e-6]") -> str:
    return SPEC.format(integrators=integrators, tolerances=tolerances)


def one_line_error(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 1, text
    assert lines[0].startswith("error:"), text
    assert "Traceback" not in text
    return lines[0]


# ---- item 1: sweep specifications ----------------------------------------------------


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("problems = " + "[" * 3000 + "]" * 3000, "nested too deeply"),
        ("problems = " + "{a = " * 2000 + "1" + "}" * 2000, "nested too deeply"),
        ("problems = " + "[" * 30 + "]" * 30, "nested more than"),
        (spec(tolerances="[" + "9" * 5000 + "]"), "too many digits"),
        (spec() + "time_limit = " + "9" * 400, "time_limit: must be a finite number"),
        (spec() + "jobs = " + "9" * 400, "jobs: must be an integer from 1"),
        (spec(tolerances="[1e-6, 1e-7, 1e-6]"), "tolerances[2]: 1e-06 is listed twice"),
        (
            spec('[{name = "rk4", options = {step = [1e-3, 2e-3, 1e-3]}}]'),
            "integrators[0].options.step: the value 0.001 is listed twice",
        ),
        (spec('["rk4", "rk4"]'), "integrators[1]: integrator 'rk4'"),
        (
            spec('["rk4", {name = "rk4", options = {step = 1e-3}}]'),
            "integrators[1]: integrator 'rk4' with options {'step': 0.001} is listed twice",
        ),
        (
            spec(
                '[{name = "scipy-rk45", options = {max_step = [%s], first_step = [%s]}}]'
                % ((",".join(str(1 + i) for i in range(2000)),) * 2)
            ),
            "integrators[0].options: the option grid has more than",
        ),
    ],
)
def test_bad_specs_are_one_config_error_naming_the_key(text: str, fragment: str) -> None:
    started = time.perf_counter()
    with pytest.raises(ConfigError) as caught:
        parse_spec(text)
    assert time.perf_counter() - started < 5.0
    assert fragment in str(caught.value)
    assert "\n" not in str(caught.value)


def test_a_large_grid_validates_fast() -> None:
    # 16,000 runs took 81 s to validate; now each option value is normalized once
    values = ",".join(repr(1e-3 * (1 + i / 1e5)) for i in range(16_000))
    started = time.perf_counter()
    sweep = parse_spec(spec(f'[{{name = "rk4", options = {{step = [{values}]}}}}]'))
    assert len(sweep.runs) == 16_000
    assert time.perf_counter() - started < 15.0


def test_cli_sweep_reports_deep_nesting_in_one_line(tmp_path) -> None:
    path = tmp_path / "deep.toml"
    path.write_text("problems = " + "[" * 3000 + "]" * 3000)
    result = subprocess.run(
        [sys.executable, "-m", "workbench", "sweep", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert result.returncode == 2, result.stderr
    assert "nested too deeply" in one_line_error(result.stderr)


@pytest.mark.slow
def test_fuzzed_sweep_specs_give_one_line_or_a_sweep(monkeypatch, tmp_path) -> None:
    """1,100 seeded specifications through parse_spec and `workbench sweep`."""
    import workbench.runs.sweep as sweep_module

    def not_run(*args, **kwargs):
        raise ConfigError("not run in the fuzz test")

    monkeypatch.setattr(sweep_module, "run_sweep", not_run)
    started = time.perf_counter()
    slowest, kinds, valid = 0.0, {}, 0
    for seed in range(1100):
        text, kind = fuzz_inputs.sweep_spec(seed)
        kinds[kind] = kinds.get(kind, 0) + 1
        begin = time.perf_counter()
        try:
            parse_spec(text)
            valid += 1
        except ConfigError as error:
            assert "\n" not in str(error), (seed, kind, str(error))
        except Exception as error:  # noqa: BLE001 - the point of the test
            pytest.fail(f"spec {seed} ({kind}): {type(error).__name__}: {error}"[:500])
        elapsed = time.perf_counter() - begin
        slowest = max(slowest, elapsed)
        assert elapsed < 10.0, (seed, kind, elapsed)
        path = tmp_path / f"spec{seed}.toml"
        path.write_text(text, encoding="utf-8")
        result = runner.invoke(app, ["sweep", str(path)])
        assert result.exit_code == 2, (seed, kind, result.output, result.exception)
        one_line_error(result.output)
    assert time.perf_counter() - started < 600  # only a hang gets near this
    assert valid > 50 and len(kinds) == 10, (valid, kinds)
    print(f"\n1100 specs: {valid} valid, slowest validation {slowest:.2f} s, {kinds}")
