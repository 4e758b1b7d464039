"""Regenerate the documentation's pictures from real sweeps: ``python docs/make_screenshots.py``.

1. ``docs/images/work-precision.png``: the work-precision diagram of the double pendulum
   drawn by the report of a sweep (3 formalisms x 3 integrators x 6 tolerances).
2. ``docs/images/rerun-viewer.png``: the Rerun web viewer showing the recording of a small
   sweep (double pendulum, two formalisms, a loose and a tight tolerance) in the
   workbench's blueprint: 3D view beside the drift and energy plots.
3. ``docs/images/rerun-robot.png``: the same viewer on a run of the UR5 imported from
   example-robot-data's URDF (the robots extra), drawn with its own meshes
   (``--only robot`` makes this one alone).
4. ``docs/images/report-overview.png``: the first screen (1400 x 900 px) of the report of
   the default sweep, in headless Chromium: the overview and its recommendation. The
   default sweep takes minutes, so it is not run here: give its directory with
   ``--default-sweep`` (default ``reports/latest``, where ``workbench sweep`` writes), or
   ``--only-overview`` to make this picture alone.

Needs the test extra (selenium) and Debian's chromium + chromium-driver; the viewer is
served by ``rerun --serve-web`` on 127.0.0.1 only and rendered by headless Chromium with
SwiftShader (WebGL on the CPU). The sweeps go to ``reports/screenshots/`` (git-ignored),
started afresh. Takes about two minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any
from urllib.parse import quote

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from workbench.outputs.browser import headless_chromium  # noqa: E402

TOLERANCES = "[1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]"
DIAGRAM_SPEC = f"""
jobs = 2
time_limit = 60.0
tolerances = {TOLERANCES}
atol_factor = 1e-3
problems = ["double-pendulum"]
formalisms = ["minimal-ode", "recursive", {{ name = "absolute-dae", options = {{ index = 1 }} }}]
integrators = ["scipy-dop853", "scipy-radau", "sundials-ida"]
"""
RECORDING_SPEC = """
jobs = 2
time_limit = 60.0
tolerances = [1e-3, 1e-7]
atol_factor = 1e-3
problems = ["double-pendulum"]
formalisms = ["minimal-ode", { name = "absolute-dae", options = { index = 1 } }]
integrators = ["scipy-radau"]
"""
ROBOT_SPEC = """
jobs = 2
time_limit = 120.0
tolerances = [1e-6]
atol_factor = 1e-3
problems = ["ur5"]
formalisms = ["recursive"]
integrators = ["sundials-cvode-bdf"]
"""
VIEWER_SIZE = (1600, 900)
FIRST_SCREEN = (1400, 900)
MAX_BYTES = 300_000


def sweep(spec: str, out: Path) -> Path:
    """Run ``workbench sweep`` on ``spec`` into a fresh ``out``; return ``out``."""
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    spec_file = out.with_suffix(".toml")
    spec_file.write_text(f'out = "{out.as_posix()}"\n{spec}', encoding="utf-8")
    subprocess.run([sys.executable, "-m", "workbench", "sweep", str(spec_file)], check=True)
    return out


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def wait_for_port(port: int, seconds: float = 30.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise RuntimeError(f"nothing listens on 127.0.0.1:{port} after {seconds} s")


def save_small_png(source: Path | bytes, target: Path) -> None:
    """Write ``source`` (a PNG) to ``target``, quantized to 256 colours if too large."""
    import io

    from PIL import Image

    image = Image.open(io.BytesIO(source) if isinstance(source, bytes) else source)
    image = image.convert("RGB")
    image.save(target, optimize=True)
    if target.stat().st_size > MAX_BYTES:
        image.quantize(256, dither=Image.Dither.NONE).save(target, optimize=True)
    print(f"wrote {target} ({target.stat().st_size // 1000} kB, {image.width}x{image.height})")


def screenshot(driver: Any, attempts: int = 5) -> bytes:
    """A PNG of the viewport; retried, since a busy CPU renderer can miss the deadline."""
    from selenium.common.exceptions import TimeoutException

    for attempt in range(attempts):
        try:
            return driver.get_screenshot_as_png()
        except TimeoutException:
            if attempt == attempts - 1:
                raise
            time.sleep(2)
    raise AssertionError("unreachable")


def viewer_screenshot(recording: Path, target: Path, settle: float) -> None:
    """Serve ``recording`` with the Rerun web viewer on 127.0.0.1 and screenshot it."""
    grpc_port, web_port = free_port(), free_port()
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rerun",
            "--serve-web",
            "--bind",
            "127.0.0.1",
            "--port",
            str(grpc_port),
            "--web-viewer-port",
            str(web_port),
            str(recording),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_for_port(web_port)
        source = quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
        driver = headless_chromium(*VIEWER_SIZE, webgl=True)
        try:
            driver.get(f"http://127.0.0.1:{web_port}/?url={source}")
            time.sleep(settle)  # the wasm viewer loads, receives the recording, renders
            save_small_png(screenshot(driver), target)
        finally:
            driver.quit()
    finally:
        server.terminate()
        server.wait(timeout=10)


def overview_screenshot(results: Path, target: Path) -> None:
    """The first screen of the report of the sweep in ``results`` (written afresh)."""
    if not (results / "runs").is_dir():
        raise SystemExit(
            f"no sweep results in {results}: run `workbench sweep` (the default sweep) first, "
            "or give its directory with --default-sweep"
        )
    report = results / "report"
    subprocess.run(
        [sys.executable, "-m", "workbench", "report", str(results), "-o", str(report)], check=True
    )
    driver = headless_chromium(*FIRST_SCREEN)
    try:
        driver.get((report / "index.html").resolve().as_uri())
        time.sleep(1)  # the heat map image decodes
        save_small_png(screenshot(driver), target)
    finally:
        driver.quit()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=Path, default=ROOT / "docs" / "images")
    parser.add_argument("--work", type=Path, default=ROOT / "reports" / "screenshots")
    parser.add_argument("--settle", type=float, default=20.0, help="seconds for the viewer")
    parser.add_argument("--only", choices=["all", "robot"], default="all")
    parser.add_argument("--default-sweep", type=Path, default=ROOT / "reports" / "latest")
    parser.add_argument("--only-overview", action="store_true", help="only report-overview.png")
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)

    overview_screenshot(args.default_sweep, args.images / "report-overview.png")
    if args.only_overview:
        return
    robot = sweep(ROBOT_SPEC, args.work / "robot") / "recording.rrd"
    viewer_screenshot(robot, args.images / "rerun-robot.png", args.settle)
    if args.only == "robot":
        return

    diagram = sweep(DIAGRAM_SPEC, args.work / "diagram")
    figure = diagram / "report" / "figures" / "double-pendulum-work-precision.png"
    save_small_png(figure, args.images / "work-precision.png")

    recording = sweep(RECORDING_SPEC, args.work / "recording") / "recording.rrd"
    viewer_screenshot(recording, args.images / "rerun-viewer.png", args.settle)


if __name__ == "__main__":
    main()
