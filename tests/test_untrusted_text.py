"""What other people's names and files may not do to a reader (issue 31, item 9): raw
HTML in plugin names and options stays text in Markdown tables (as in the HTML report),
``workbench view --web`` listens on 127.0.0.1 unless told otherwise, and a missing mesh
is one line on stderr."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import psutil
import pytest

from workbench.outputs.report.tables import markdown_table, write_table
from workbench.outputs.results_table import render

ATTACK = '<img src=x onerror="alert(1)">'


def test_markdown_tables_escape_raw_html(tmp_path: Path) -> None:
    table = pd.DataFrame(
        {"formalism": [f"evil{ATTACK}"], "integrator": ["rk4[step=<b>1</b>]"], "rtol": [1e-6]}
    )
    for text in (
        markdown_table(table),  # workbench results --format markdown, report tables
        render(table, "markdown", "results"),
        write_table(table, tmp_path, "pairs")[1].read_text(),  # tables/*.md
    ):
        assert "<img" not in text and "<b>" not in text, text
        assert '&lt;img src=x onerror="alert(1)">' in text and "&lt;b>1&lt;/b>" in text
    # a comparison reads as one ("&gt; 1000 rtol" did)
    said = "error 0.3 (> 1000 rtol)"
    assert said in markdown_table(pd.DataFrame({"warnings": [said]}))


def workbench(*args: str, cwd: Path, **kwargs) -> subprocess.CompletedProcess:
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    command = [sys.executable, "-m", "workbench", *args]
    return subprocess.run(
        command, cwd=cwd, env=env, capture_output=True, text=True, timeout=600, **kwargs
    )


def listening(pid: int) -> set[str]:
    """The addresses the process ``pid`` and its children listen on."""
    try:
        processes = [psutil.Process(pid), *psutil.Process(pid).children(recursive=True)]
    except psutil.NoSuchProcess:
        return set()
    found = set()
    for process in processes:
        try:
            connections = process.net_connections(kind="inet")
        except psutil.Error:
            continue
        found |= {c.laddr.ip for c in connections if c.status == psutil.CONN_LISTEN}
    return found


@pytest.mark.timeout(600)
def test_view_serves_to_this_machine_only(tmp_path: Path) -> None:
    """Rerun's --serve-web listens on 0.0.0.0 by default; workbench view --web on
    127.0.0.1 (its gRPC and HTTP servers both)."""
    from workbench.outputs.recording import RerunSink

    recording = RerunSink().save(tmp_path / "recording.rrd")
    env = dict(os.environ, NO_COLOR="1")
    command = [sys.executable, "-m", "workbench", "view", "--web", str(recording),
               "--web-port", "0", "--grpc-port", "0"]  # fmt: skip
    process = subprocess.Popen(
        command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True,
    )  # fmt: skip
    try:
        addresses: set[str] = set()
        deadline = time.monotonic() + 300  # only a hung viewer takes this long
        while len(addresses) < 1 and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.5)
            addresses = listening(process.pid)
        time.sleep(2)  # the second server
        addresses = listening(process.pid)
        assert addresses == {"127.0.0.1"}, addresses
    finally:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=60)


def test_view_without_display_advises_the_local_address(tmp_path: Path) -> None:
    from workbench.outputs.recording import RerunSink

    recording = RerunSink().save(tmp_path / "recording.rrd")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run(
        [sys.executable, "-m", "workbench", "view", str(recording)],
        env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "--bind 127.0.0.1" in result.stdout and "workbench view --web" in result.stdout


def test_a_missing_mesh_is_one_line_on_stderr(tmp_path: Path) -> None:
    (tmp_path / "robot.urdf").write_text(
        """<robot name="r"><link name="base"/>
<link name="arm"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/>
</inertial><visual><geometry><mesh filename="meshes/gone.stl"/></geometry></visual></link>
<joint name="j" type="continuous"><parent link="base"/><child link="arm"/></joint></robot>"""
    )
    result = workbench("describe", "robot.urdf", cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr  # yourdfpy's "Unable to resolve filename" was a 2nd
    assert "meshes/gone.stl" in lines[0] and "not found" in lines[0]
