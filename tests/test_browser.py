"""The 3-D viewer page (``softtrack animate ... --out x.html``) in a real browser: Debian's
chromium driven by Selenium. It loads offline with no console error, plays (its canvas changes
between two frames), pauses, scrubs, switches controller, a toggle hides the target's path,
and a screenshot shows both arms in their colours."""

from __future__ import annotations

import io
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from softtrack.report.viewer import Rollout, viewer_page
from softtrack.viz.scene import ARM_COLORS

CHROMEDRIVER = shutil.which("chromedriver")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")

pytestmark = pytest.mark.skipif(
    CHROMEDRIVER is None or CHROMIUM is None,
    reason="no chromium/chromedriver: `apt-get install chromium chromium-driver` (.ci/run does)",
)


def _rollout(controller: str, trajectory: str, bend: float) -> Rollout:
    frames, nodes = 60, 21
    s = np.linspace(0.0, 1.0, nodes)
    phase = np.linspace(0.0, 2.0 * np.pi, frames)[:, None]
    rods = np.zeros((frames, 2, 3, nodes))
    for arm, (x0, sign) in enumerate(((-0.1, 1.0), (0.1, -1.0))):
        angle = sign * bend * s[None, :] * (1.0 + 0.5 * np.sin(phase))
        rods[:, arm, 0] = x0 + np.cumsum(np.sin(angle), axis=1) / nodes
        rods[:, arm, 1] = np.cumsum(np.cos(angle), axis=1) / nodes
        rods[:, arm, 2] = 0.2 * s[None, :] * np.cos(phase)
    target = np.stack(
        [0.3 * np.cos(phase[:, 0]), np.full(frames, 0.6), 0.3 * np.sin(phase[:, 0])], axis=1
    )
    return Rollout(
        controller=controller,
        trajectory=trajectory,
        times=np.arange(1, frames + 1) / 30.0,
        nodes=rods,
        target=target,
        sphere=None,
        errors=np.full((frames, 2), 0.05),
        radius=0.05,
        target_radius=0.05,
        sphere_radius=0.05,
        bases=np.array([[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]]),
    )


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1000,900"):
        options.add_argument(argument)
    options.binary_location = str(CHROMIUM)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    yield driver
    driver.quit()


def _canvas(driver: Any) -> str:
    return str(driver.execute_script("return document.getElementById('view').toDataURL()"))


def test_viewer_plays_pauses_scrubs_and_switches(browser: Any, tmp_path: Path) -> None:
    rollouts = [
        _rollout("controller A", "circle", 1.2),
        _rollout("controller A", "rectangle", 0.6),
        _rollout("controller B", "circle", 2.0),
    ]
    page = tmp_path / "viewer.html"
    page.write_text(viewer_page(rollouts, "A vs B", fps=30.0), encoding="utf-8")
    assert "http://" not in page.read_text() and "https://" not in page.read_text()
    started = time.monotonic()
    browser.get(page.as_uri())
    time.sleep(0.6)
    first = _canvas(browser)
    time.sleep(0.4)
    assert _canvas(browser) != first  # playing
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == []

    browser.find_element("id", "play").click()
    assert "paused" in browser.find_element("id", "status").text
    paused = _canvas(browser)
    time.sleep(0.3)
    assert _canvas(browser) == paused

    browser.execute_script(
        "const s = document.getElementById('scrub'); s.value = 5; s.dispatchEvent(new Event('input'));"
    )
    assert browser.find_element("id", "status").text.startswith("frame 6 of 60")

    with_path = _canvas(browser)
    browser.find_element("id", "path").click()  # the toggle hides the target's path
    assert _canvas(browser) != with_path

    Select = pytest.importorskip("selenium.webdriver.support.select").Select
    Select(browser.find_element("id", "controller")).select_by_visible_text("controller B")
    switched = _canvas(browser)
    assert switched != with_path

    shot = Image.open(io.BytesIO(browser.get_screenshot_as_png())).convert("RGB")
    pixels = np.asarray(shot).reshape(-1, 3).astype(float)
    for colour in ARM_COLORS:
        close = np.abs(pixels - np.asarray(colour, float)).max(axis=1) < 40
        assert close.sum() > 300, f"arm colour {colour} not on screen"
    print(f"browser test: {time.monotonic() - started:.1f} s")
