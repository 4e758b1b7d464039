"""Headless Chromium for looking at what the workbench writes (report pages, the Rerun web
viewer): the browser test of the report and ``docs/make_screenshots.py`` share it.

Uses the system's Chromium and chromedriver (Debian packages ``chromium`` and
``chromium-driver``) through selenium, so selenium-manager never downloads a browser; the
browser resolves no host but 127.0.0.1 / localhost, so a page cannot reach the network.
selenium is a test dependency (``pip install -e ".[test]"``), imported only here.
"""

from __future__ import annotations

import os
import shutil
from typing import Any

from workbench.errors import ConfigError

BROWSER_NAMES: tuple[str, ...] = ("chromium", "chromium-browser", "google-chrome")
DRIVER_NAMES: tuple[str, ...] = ("chromedriver",)
INSTALL_HINT = "install them with `apt-get install -y chromium chromium-driver`"
FLAGS: tuple[str, ...] = (
    "--headless=new",
    "--no-sandbox",  # runs as root in containers and CI
    "--disable-dev-shm-usage",  # small /dev/shm in containers
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-default-apps",
    "--disable-extensions",
    "--disable-sync",
    "--no-first-run",
    "--no-default-browser-check",
    "--mute-audio",
    "--hide-scrollbars",
    "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1 , EXCLUDE localhost",
)
# 2D pages need no GPU; WebGL pages (the Rerun web viewer) get SwiftShader, a CPU renderer.
NO_GPU_FLAGS: tuple[str, ...] = ("--disable-gpu",)
WEBGL_FLAGS: tuple[str, ...] = (
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
)


def find_chromium() -> tuple[str, str] | None:
    """Paths of the Chromium browser and of chromedriver, or None if either is missing.

    The environment variables CHROMIUM and CHROMEDRIVER override the search of PATH.
    """
    browser = _which(os.environ.get("CHROMIUM"), BROWSER_NAMES)
    driver = _which(os.environ.get("CHROMEDRIVER"), DRIVER_NAMES)
    return (browser, driver) if browser and driver else None


def _which(override: str | None, names: tuple[str, ...]) -> str | None:
    if override:
        return shutil.which(override)
    return next((path for name in names if (path := shutil.which(name))), None)


def headless_chromium(width: int = 1280, height: int = 1000, *, webgl: bool = False) -> Any:
    """A selenium WebDriver on headless Chromium with a ``width`` x ``height`` viewport
    whose console log (``driver.get_log("browser")``) keeps every level.

    webgl: render WebGL on the CPU (SwiftShader) instead of disabling the GPU.
    Raises ConfigError when selenium, Chromium or chromedriver is missing.
    """
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        raise ConfigError(
            'selenium is not installed: pip install -e ".[test]" (or pip install selenium)'
        ) from None
    found = find_chromium()
    if found is None:
        raise ConfigError(f"Chromium or chromedriver not found on PATH: {INSTALL_HINT}")
    browser, driver = found
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in FLAGS + (WEBGL_FLAGS if webgl else NO_GPU_FLAGS):
        options.add_argument(flag)
    options.add_argument(f"--window-size={width},{height}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    chrome = webdriver.Chrome(service=Service(driver), options=options)
    set_viewport(chrome, width, height)
    return chrome


def set_viewport(driver: Any, width: int, height: int) -> None:
    """Make the page's viewport (what a screenshot shows) exactly ``width`` x ``height``."""
    driver.execute_cdp_cmd(
        "Emulation.setDeviceMetricsOverride",
        {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
    )
