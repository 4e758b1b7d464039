"""``python -m workbench.testing ... | head -1`` ends quietly, as ``workbench ... | head``
does: the reader left with what it wanted, nothing to report (it printed a
BrokenPipeError traceback)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


@pytest.mark.parametrize("buffered", [True, False])
def test_a_reader_that_leaves_early_gets_no_traceback(buffered: bool) -> None:
    environment = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    if not buffered:
        environment["PYTHONUNBUFFERED"] = "1"
    command = [sys.executable, "-m", "workbench.testing", "formalism", "minimal-ode"]
    child = subprocess.Popen(
        [*command, "--structural"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )
    child.stdout.close()  # before the child writes: its stdout's reader is gone
    _, err = child.communicate(timeout=600)
    assert err == ""
    assert child.returncode == 1
