"""The demo's recording in Foxglove Studio 1.48, in a real browser: Debian's
chromium and chromium-driver, driven by selenium, open `run.mcap` in Foxglove Studio
(`@foxglove/studio-base@1.48.0`'s prebuilt bundle with React 17, tests/browser/host) with the
patrol layout, and find no problem listed, data in the three motivation plots (their legends
show values), the supervisor table filled, every allocation row visible and the alarm in the
Log panel. A tier of its own (`pytest -m browser`; .ci/run installs what it needs): skipped,
saying why, where chromium or the host page's packages are not installed."""

from __future__ import annotations

import re
import shutil
import tempfile
import time
from pathlib import Path

import pytest

from tests.browser.hostserver import MODULES, HostServer

pytestmark = [pytest.mark.browser, pytest.mark.multiprocess]

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / "configs/applications/patrol/foxglove_layout.json"
CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")
BUNDLE = MODULES / "@foxglove/studio-base/assets/index.js"
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync")
LOAD = 300  # wall seconds for the 56 MB bundle and the file (≈ 45 s on an idle machine)


def needs() -> str | None:
    if CHROMIUM is None or DRIVER is None:
        return "chromium and chromium-driver are not installed (apt-get install chromium " \
               "chromium-driver; .ci/run does)"
    if not BUNDLE.is_file():
        return "Foxglove Studio's packages are not installed (npm ci --prefix tests/browser/host)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    return None


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """The demo's run.mcap, 20 simulated seconds (robot2 fails at 10 s: the communication_lost
    alarm)."""
    from tests.harness.helpers import Children
    why = needs()
    if why:
        pytest.skip(why)
    children = Children()
    out = tmp_path_factory.mktemp("browser") / "run"
    try:
        demo = children.mrta("demo", "--duration", "20", "--speed", "0", "--no-live",
                             "--output", out, name="demo")
        assert demo.wait(240) == 0, demo.stderr[-10:]
    finally:
        children.stop_all()
    return out / "run.mcap"


@pytest.fixture
def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    profile = tempfile.mkdtemp(prefix="mrta-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (*FLAGS, f"--user-data-dir={profile}", "--window-size=1600,1000"):
        options.add_argument(flag)
    driver = webdriver.Chrome(options=options, service=Service(DRIVER))
    try:
        # the page's own size, what a user's 1600×1000 window shows (window size counts the
        # browser's frame too)
        driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
            "width": 1600, "height": 1000, "deviceScaleFactor": 1, "mobile": False})
        # the page's one thread is busy for tens of seconds at a time while the bundle starts
        driver.set_script_timeout(LOAD)
        driver.set_page_load_timeout(LOAD)
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def motivation_values(text: str) -> dict[str, list[float]]:
    """Each motivation plot's legend values (shown once the plot has data at that time)."""
    out = {}
    for robot in ("robot1", "robot2", "robot3"):
        m = re.search(rf"{robot}: motivation \(rqt_alliance\)\nwander\n([-\d.]+)\n"
                      r"border_protection\n([-\d.]+)\nreport\n([-\d.]+)", text)
        if m:
            out[robot] = [float(v) for v in m.groups()]
    return out


ROWS_VISIBLE = """
const panel = [...document.querySelectorAll('*')].find(
    e => e.childElementCount === 0 && e.textContent === arguments[0]);
if (!panel) return null;
let root = panel;
while (root && !(root.getBoundingClientRect().height > 100)) root = root.parentElement;
const box = root.getBoundingClientRect();
return arguments[1].map(name => [...root.querySelectorAll('*')].some(e =>
    e.childElementCount === 0 && e.textContent === name &&
    e.getBoundingClientRect().bottom <= box.bottom && e.getBoundingClientRect().top >= box.top));
"""


@pytest.mark.timeout(900)
def test_the_demo_recording_fills_every_panel_with_no_problem(recording, browser, tmp_path):
    from selenium.webdriver.common.by import By
    with HostServer(LAYOUT, recording) as url:
        # at 19.5 s of the 20 s run: the supervisor's latest state, the alarm after 10 s
        browser.get(f"{url}/?ds=remote-file&ds.url={url}/run.mcap&layoutId=patrol"
                    "&time=1970-01-01T00:00:19.500000000Z")
        deadline = time.monotonic() + LOAD
        text = ""
        while time.monotonic() < deadline:
            error = browser.execute_script("return window.mrtaHostError")
            assert error is None, error
            text = browser.find_element(By.TAG_NAME, "body").text
            if len(motivation_values(text)) == 3 and "communication_lost robot2" in text \
                    and "ALLIANCE" in text:
                break
            time.sleep(2)
        browser.save_screenshot(str(tmp_path / "foxglove.png"))
        assert len(motivation_values(text)) == 3, (text[-2000:], tmp_path / "foxglove.png")
        assert "ALARM communication_lost robot2" in text
        assert re.search(r"\n19\.5 Patrol ALLIANCE ", text), text[-2000:]  # the table, filled
        assert "This panel encountered an unexpected error" not in text
        assert browser.execute_script(ROWS_VISIBLE, "who does what (allocation timeline)",
                                      ["robot1", "robot2", "robot3"]) == [True, True, True]
        values = motivation_values(text)
        assert max(values["robot1"]) > 0 and max(values["robot3"]) > 0, values
        # the Problems tab: no schema refused, no message that failed to decode
        tab = next(e for e in browser.find_elements(By.CSS_SELECTOR, "button[role=tab]")
                   if e.text.startswith("Problems"))
        assert tab.text.strip() == "Problems", tab.text  # a count would follow the name
        tab.click()
        time.sleep(1)
        shown = browser.find_element(By.TAG_NAME, "body").text
        browser.save_screenshot(str(tmp_path / "problems.png"))
        assert "No problems found" in shown, shown[:1500]
