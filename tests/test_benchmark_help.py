"""Every benchmark answers ``--help`` with how to run it, and runs nothing: a benchmark
that reads its arguments by hand once failed on ``--help`` with a traceback
(``benchmarks.footprint``) or took it for a problem's name (``benchmarks.nonsmooth_peers``)."""

from __future__ import annotations

import ast
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
BENCHMARKS = sorted(
    path.stem
    for path in (Path(__file__).parents[1] / "benchmarks").glob("*.py")
    if 'if __name__ == "__main__":' in path.read_text()
)


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("name", BENCHMARKS)
def test_a_benchmark_answers_help(name: str) -> None:
    outputs = [*(ROOT / "benchmarks" / "results").iterdir(), *(ROOT / "docs" / "images").iterdir()]
    before = {path: path.stat().st_mtime_ns for path in outputs}
    done = subprocess.run(
        [sys.executable, "-m", f"benchmarks.{name}", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    missing = re.search(r"ModuleNotFoundError: No module named '([\w.]+)'", done.stderr)
    if missing and importlib.util.find_spec(missing[1].split(".")[0]) is None:
        pytest.skip(f"needs {missing[1]}, not installed (pip install -e '.[bench]')")
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    module = ast.parse((ROOT / "benchmarks" / f"{name}.py").read_text())
    first_line = (ast.get_docstring(module) or "").splitlines()[0]
    said = done.stdout.strip()
    assert said.startswith("usage:") or said.startswith(first_line), said[:300]
    # it ran nothing: no result or figure written
    assert {path: path.stat().st_mtime_ns for path in outputs} == before
