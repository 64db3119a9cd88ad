"""The 3-D viewer page (``softtrack animate ... --out x.html``) and the interactive report
(``softtrack report --html``) in a real browser: Debian's chromium driven by Selenium. The
viewer loads offline with no console error, plays (its canvas changes between two frames),
pauses, scrubs, switches controller, a toggle hides the target's path, and a screenshot shows
both arms in their colours; the report opens with its answers and a checkbox hides a curve; a
tuning study's trials are lines in parallel coordinates, the pruned ones hidden by a checkbox."""

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

from softtrack.report.interactive import AnswerTable, CurvePanel, interactive_page
from softtrack.report.tune_view import TuneAxis, TuneTrial, TuneView, tune_html_section
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


def test_report_page_answers_first_and_a_checkbox_hides_a_curve(
    browser: Any, tmp_path: Path
) -> None:
    steps = np.linspace(1e3, 1e5, 50)
    panel = CurvePanel(
        "centralized",
        "episode return",
        (
            ("TD3", "#1f77b4", steps, np.log(steps), np.full(50, 0.5)),
            ("DDPG", "#ff7f0e", steps, 0.8 * np.log(steps), np.full(50, 0.3)),
        ),
    )
    answers = [
        AnswerTable(
            "shared target: 3-D RMSE (m)",
            ("trajectory, arm", "study (TD3, 3 seeds)", "TD3"),
            (("circle, arm 1", "0.0650", "0.0402 [0.0383, 0.0432]"),),
        )
    ]
    page = tmp_path / "interactive.html"
    page.write_text(
        interactive_page(
            "report",
            "intro",
            answers,
            [panel],
            [_rollout("TD3 (seed 0)", "circle", 1.2)],
            ["run", "status"],
            [["01ABC", "completed"]],
        ),
        encoding="utf-8",
    )
    browser.get(page.as_uri())
    time.sleep(0.5)
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []
    headings = [h.text for h in browser.find_elements("tag name", "h2")]
    assert headings[0].startswith("Best controllers per task") and headings[-1] == "Runs"
    curve = browser.find_element("id", "curve-0-1")
    assert curve.is_displayed()
    browser.find_element("id", "toggle-0-1").click()
    assert not curve.is_displayed()
    assert browser.find_element("id", "curve-0-0").is_displayed()


def test_tune_study_in_parallel_coordinates(browser: Any, tmp_path: Path) -> None:
    from selenium.webdriver import ActionChains

    axes = (
        TuneAxis("algo.learning_rate", "float", True, 1e-4, 1e-2),
        TuneAxis("algo.batch_size", "categorical", False, None, None, ("8", "16")),
    )
    trials = tuple(
        TuneTrial(
            number=k,
            state="PRUNED" if k >= 4 else "COMPLETE",
            score=0.05 + 0.01 * k,
            step=200,
            values={"algo.learning_rate": 1e-4 * 2**k, "algo.batch_size": "8" if k % 2 else "16"},
            run_id=f"RUN{k}",
        )
        for k in range(6)
    )
    view = TuneView(
        "demo",
        "best validation score",
        axes,
        trials,
        (("algo.learning_rate", 0.8), ("algo.batch_size", 0.2)),
        "PED-ANOVA",
    )
    page = tmp_path / "interactive.html"
    page.write_text(
        interactive_page(
            "report", "intro", [], [], [], ["run"], [], tune_html=tune_html_section([view])
        ),
        encoding="utf-8",
    )
    browser.get(page.as_uri())
    time.sleep(0.3)
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []
    svg = browser.find_element("id", "parallel-svg-0")
    assert len(svg.find_elements("css selector", "polyline.complete")) == 4
    pruned = svg.find_elements("css selector", "polyline.pruned")
    assert len(pruned) == 2 and all(p.is_displayed() for p in pruned)
    assert len(browser.find_elements("css selector", "#importance-0 .bar")) == 2
    browser.find_element("id", "pruned-0").click()
    assert not any(p.is_displayed() for p in pruned)
    best = svg.find_element("css selector", 'polyline[data-trial="0"]')
    # a point on the line a quarter along it, as an offset from the svg's centre
    dx, dy = browser.execute_script(
        """const [svg, line] = arguments, p = line.getPointAtLength(line.getTotalLength() / 4);
        const q = p.matrixTransform(line.getScreenCTM()), r = svg.getBoundingClientRect();
        return [q.x - (r.x + r.width / 2), q.y - (r.y + r.height / 2)];""",
        svg,
        best,
    )
    ActionChains(browser).move_to_element_with_offset(svg, round(dx), round(dy)).perform()
    assert browser.find_element("id", "caption-0").text.startswith("trial 0 (complete): 0.05 m")
