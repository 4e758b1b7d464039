"""The HTML report in a real browser (headless Chromium): it renders, every image loads,
every local link resolves, the console stays clean; a broken page fails the same checks.

Skipped, with the reason, only where Chromium / chromedriver / selenium are missing and the
environment variable CI is unset; under CI a missing browser fails the test.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

import pytest

from tests.test_report import synthetic_results, synthetic_series
from workbench.outputs.browser import INSTALL_HINT, find_chromium, headless_chromium, set_viewport
from workbench.outputs.report import write_report

WIDTH = 1280
MAX_HEIGHT = 12000


def browser_missing() -> str | None:
    """Why the browser test cannot run here, or None."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return 'selenium is not installed (pip install -e ".[test]")'
    if find_chromium() is None:
        return f"Chromium or chromedriver is not installed ({INSTALL_HINT})"
    return None


@pytest.fixture(scope="module")
def browser() -> Any:
    reason = browser_missing()
    if reason is not None:
        if os.environ.get("CI"):
            pytest.fail(f"{reason}; CI is set, so the browser test must run")
        pytest.skip(f"browser test: {reason}")
    driver = headless_chromium(WIDTH, 900)
    yield driver
    driver.quit()


def render(driver: Any, page: Path, screenshot: Path) -> dict[str, Any]:
    """Load ``page`` with a viewport as tall as the page (so lazy images load and the
    screenshot shows everything); return what the checks need."""
    driver.get_log("browser")  # drop entries of earlier pages
    driver.get(page.as_uri())
    height = driver.execute_script("return document.documentElement.scrollHeight")
    set_viewport(driver, WIDTH, min(int(height), MAX_HEIGHT))
    driver.set_script_timeout(20)
    images = driver.execute_async_script(
        """
        const done = arguments[arguments.length - 1];
        const settled = img => img.complete ? Promise.resolve() : new Promise(
            r => { img.addEventListener('load', r); img.addEventListener('error', r); });
        Promise.all(Array.from(document.images, settled)).then(() => done(
            Array.from(document.images, img => [img.src, img.naturalWidth])));
        """
    )
    links = driver.execute_script(
        """
        const linking = 'a[href], link[href], object[data], embed[src]';
        return Array.from(document.querySelectorAll(linking), e => e.href || e.data || e.src);
        """
    )
    driver.save_screenshot(str(screenshot))
    return {"images": images, "links": links, "console": driver.get_log("browser")}


def problems(driver: Any, rendered: dict[str, Any]) -> list[str]:
    """Every broken image, dangling local link or anchor, and console error."""
    found = [f"image not loaded: {src}" for src, width in rendered["images"] if not width > 0]
    for link in rendered["links"]:
        parts = urlsplit(link)
        if parts.scheme != "file":
            continue
        if not Path(unquote(parts.path)).is_file():
            found.append(f"link to a missing file: {link}")
        elif parts.fragment and not driver.execute_script(
            "return document.getElementById(arguments[0]) !== null", unquote(parts.fragment)
        ):
            found.append(f"link to a missing anchor: {link}")
    found += [
        f"console: {entry['message']}"
        for entry in rendered["console"]
        if entry["level"] == "SEVERE"
    ]
    return found


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    return struct.unpack(">II", data[16:24])


def test_report_renders_in_chromium(browser: Any, tmp_path: Path) -> None:
    results = synthetic_results(problems=("heavy-top",))  # one problem keeps the test quick
    index = write_report(results, synthetic_series, tmp_path / "report", "cmd")
    screenshot = tmp_path / "report.png"
    rendered = render(browser, index, screenshot)

    assert problems(browser, rendered) == []
    # the picture in the decision table and its section, heat map, work-precision, error, drift
    assert len(rendered["images"]) == 6
    assert all(width >= 600 for src, width in rendered["images"] if "-picture" not in src)
    assert any(link.endswith(".svg") for link in rendered["links"])
    assert any(link.endswith("#heavy-top") for link in rendered["links"])
    width, height = png_size(screenshot)
    assert width == WIDTH and height > 1500  # the whole page, figures included
    assert screenshot.stat().st_size > 100_000  # text, tables and plots, not a blank page
    # The figures fit the page: nothing wider than the viewport.
    assert browser.execute_script("return document.documentElement.scrollWidth") <= WIDTH


def test_broken_page_fails_the_checks(browser: Any, tmp_path: Path) -> None:
    page = tmp_path / "broken.html"
    page.write_text(
        '<!DOCTYPE html><html><head><meta charset="utf-8"><title>x</title></head><body>'
        '<img src="figures/missing.png" alt="gone"><a href="tables/missing.csv">CSV</a>'
        '<a href="#nowhere">here</a><script>console.error("boom")</script></body></html>',
        encoding="utf-8",
    )
    found = problems(browser, render(browser, page, tmp_path / "broken.png"))
    assert any(p.startswith("image not loaded") for p in found), found
    assert any("missing.csv" in p for p in found), found
    assert any("#nowhere" in p for p in found), found
    assert any("boom" in p for p in found), found


FIRST_SCREEN = (1400, 900)  # px: the README's screenshot


def test_first_screen_answers_per_mechanism_and_every_axis_is_labelled(
    browser: Any, tmp_path: Path
) -> None:
    """At 1400 x 900 px the decision table starts on the first screen with its first
    problem's row (picture, cheapest pair, cost), every text in it at 10 px or more; the
    heat map shows its labels at their size (not scaled down); every axis of every
    figure showing numbers has a label with a unit in brackets, every axis showing names
    a label."""
    import json
    import re

    index = write_report(synthetic_results(), synthetic_series, tmp_path / "report", "cmd")
    set_viewport(browser, *FIRST_SCREEN)
    browser.get(index.as_uri())
    screen = browser.execute_script(
        """
        const table = document.querySelector('#decision table.decision');
        if (!table) return null;
        const row = table.querySelector('tbody tr[id^="decision-"]');
        const thumb = row ? row.querySelector('img.thumb') : null;
        const sizes = Array.from(table.querySelectorAll('th, td, a, strong, span'),
            e => parseFloat(getComputedStyle(e).fontSize));
        const heat = document.querySelector('#overview figure img');
        return {top: table.getBoundingClientRect().top,
                row: row ? [row.getBoundingClientRect().bottom, row.innerText] : null,
                thumb: thumb ? [thumb.naturalWidth, thumb.getBoundingClientRect().height] : null,
                smallest: Math.min(...sizes),
                heat: heat ? [heat.naturalWidth, heat.getBoundingClientRect().width] : null};
        """
    )
    assert screen is not None, "no decision table"
    assert screen["top"] < FIRST_SCREEN[1] / 2, "the decision table starts below mid-screen"
    bottom, text = screen["row"]
    assert bottom <= FIRST_SCREEN[1], "the first problem's row is below the first screen"
    assert " / " in text and re.search(r"\d (s|ms|\u00b5s)", text), text  # pair and cost
    assert screen["thumb"] and screen["thumb"][0] > 0 and screen["thumb"][1] >= 48
    assert screen["smallest"] >= 10, f"text of {screen['smallest']} px in the decision table"
    natural, shown = screen["heat"]
    assert shown >= 0.95 * natural  # 9 pt labels at 90 dpi: 11 px, if not scaled down
    figures = browser.execute_script(
        "return Array.from(document.querySelectorAll('figure[data-axes]'),"
        " f => [f.querySelector('img').getAttribute('src'), f.dataset.axes]);"
    )
    assert len(figures) >= 7  # the heat map; per problem work-precision, error, drift
    for source, axes in figures:
        axes = json.loads(axes)
        assert axes, f"{source}: no axis recorded"
        for axis in axes:
            assert axis["label"].strip(), f"{source}: an axis without a label"
            if axis["numeric"]:
                assert re.search(r"\[[^\]]+\]", axis["label"]), f"{source}: {axis['label']!r}"
