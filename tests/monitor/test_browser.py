"""The monitor in a real (headless) browser: a realtime emulated run streams into the page, the controller's
Pause reaches the run's journal folder, and the run answers.

Needs selenium, chromium and chromedriver: skipped without them, a failure where .ci/run installed them
(RDEA_LAB_REQUIRE_BROWSER); bokeh comes with the test extra.
Set RDEA_LAB_MONITOR_SCREENSHOT=docs/img/monitor.png to keep the page's screenshot.
"""

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rdea_lab.runs.control import read_state

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM, CHROMEDRIVER = shutil.which("chromium"), shutil.which("chromedriver")  # as .ci/run finds them
PROTOCOL = """name: monitor_test
kind: custom
description: a short realtime run for the monitor's browser test
source: rdea-lab test
sample_rate: 200 Hz
measure: [force]
limits: {max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}
stretch:
  - {kind: ramp, duration: 5 s, to: 1.3}
  - {kind: sine, duration: 25 s, mean: 1.3, amplitude: 0.05, frequency: 0.5 Hz}
voltage:
  - {kind: ramp, duration: 5 s, from: 0 V, to: 1 kV}
  - {kind: sine, duration: 25 s, mean: 1 kV, amplitude: 0.5 kV, frequency: 1 Hz}
"""
POINTS = ("const s = Bokeh.documents.length ? Bokeh.documents[0].get_model_by_name('live') : null;"
          "return s ? s.data.time.length : -1")


def browser():
    """A headless chromium driven by selenium, or a skip saying what is missing."""
    def missing(what):
        if os.environ.get("RDEA_LAB_REQUIRE_BROWSER"):  # CI, where .ci/run installed the browser: a failure
            pytest.fail(what)
        pytest.skip(what)

    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        missing("selenium not installed (pip install selenium)")
    for path in (CHROMIUM, CHROMEDRIVER):
        if not path or not os.access(path, os.X_OK):
            missing("chromium or chromedriver not installed (apt-get install chromium chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,1000"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def wait_for(what, timeout, step=0.1):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = what()
        if got:
            return got
        time.sleep(step)
    return what()


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


#: The <button> of the Bokeh widget with css class ``rdea-<name>``, searched through the nested shadow roots.
FIND_BUTTON = """
const find = (root) => {
  for (const el of root.querySelectorAll("*")) {
    if (el.classList && el.classList.contains(arguments[0])) return el.shadowRoot.querySelector("button");
    if (el.shadowRoot) { const got = find(el.shadowRoot); if (got) return got; }
  }
  return null;
};
return find(document);
"""


def click(driver, name):
    """Click the Bokeh button ``name`` as a user does (the element, not its model)."""
    button = driver.execute_script(FIND_BUTTON, f"rdea-{name}")
    assert button is not None, f"no {name} button on the page"
    button.click()


@pytest.mark.slow  # 20-30 s on a loaded 2-core machine (two browsers, a realtime run, the twin beside it)
def test_a_realtime_run_in_the_browser_and_pause_from_the_controller(tmp_path, monkeypatch):
    driver = browser()
    from rdea_lab.monitor import Monitor

    runs = tmp_path / "runs"
    runs.mkdir()
    (tmp_path / "monitor_test.yaml").write_text(PROTOCOL)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.Popen([sys.executable, "-m", "rdea_lab.cli", "run", str(tmp_path / "monitor_test.yaml"),
                            "--specimen", "specimen2", "--backend", "emulator", "--realtime", "--quiet",
                            "--out", str(runs / "live.nc")], env=env, cwd=tmp_path,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    monkeypatch.chdir(tmp_path)
    mon = Monitor("runs", port=free_port(), params="paper2021_table3", model="su")
    viewer = None
    try:
        mon.start()
        viewer = browser()  # both pages open while the run starts: it appears in them when its journal does
        viewer.get(mon.urls[0])
        driver.get(mon.urls[1])
        journal = runs / "live.nc.part"
        assert wait_for(lambda: (journal / "samples.f8").exists(), 30), run.stderr.read() if run.poll() else ""
        # the engine publishes its state (state.json, with its pid) from the first block on
        assert wait_for(lambda: (read_state(journal) or {}).get("pid") == run.pid, 20), read_state(journal)

        first = wait_for(lambda: (driver.execute_script(POINTS) or 0) > 0 and driver.execute_script(POINTS), 20)
        assert first and first > 0
        later = wait_for(lambda: (driver.execute_script(POINTS) or 0) > first + 100 and driver.execute_script(POINTS),
                         10)
        assert later, "the plot's points did not grow"
        assert wait_for(lambda: (viewer.execute_script(POINTS) or 0) > 0, 10), "a second viewer sees nothing"
        assert viewer.execute_script("return Bokeh.documents[0].get_model_by_name('pause').disabled")
        assert not driver.execute_script("return Bokeh.documents[0].get_model_by_name('pause').disabled")
        viewer.quit()  # a page closed: nothing changes for the run (asserted below: it goes on)
        viewer = None

        click(driver, "pause")
        assert wait_for(lambda: (read_state(journal) or {}).get("state") in ("pausing", "paused"), 10), \
            read_state(journal)
        message = lambda: driver.execute_script(  # noqa: E731
            "return Bokeh.documents[0].get_model_by_name('message').text")
        assert wait_for(lambda: "the run is paus" in message(), 15), message()
        state = lambda: driver.execute_script(  # noqa: E731
            "return Bokeh.documents[0].get_model_by_name('state').text")
        assert wait_for(lambda: "<b>paus" in state(), 10), state()  # the run's published state, on the page
        assert run.poll() is None and journal.is_dir()  # the run goes on after its viewers left
        shot = os.environ.get("RDEA_LAB_MONITOR_SCREENSHOT")
        driver.save_screenshot(str(tmp_path / "monitor.png"))
        if shot:
            shutil.copy(tmp_path / "monitor.png", shot)
    finally:
        for d in (viewer, driver):
            if d is not None:
                d.quit()
        mon.stop()
        run.terminate()
        run.communicate(timeout=60)
