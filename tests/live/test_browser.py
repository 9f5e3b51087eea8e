"""End to end in a real headless Chromium (Debian's package): the page follows an emulated
board, shows its health, and cannot write anything.

Skips when /usr/bin/chromium is absent, except in CI (CI=true), where .ci/run installs it
and a missing browser is a failure.
"""

from __future__ import annotations

import json
import os
import shutil
import threading
import time

import pytest
from tests.support.headless import CHROMIUM, Chromium

from imuhal.core.samples import GyroSample, PressureSample
from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.live import LiveView

EXECUTABLE = CHROMIUM if os.path.exists(CHROMIUM) else shutil.which("chromium")
if EXECUTABLE is None:
    if os.environ.get("CI") == "true":
        raise RuntimeError(f"CI needs {CHROMIUM} for the live view's browser test; .ci/run "
                           f"installs it (apt-get install chromium)")
    pytest.skip(f"{CHROMIUM} is not installed (apt-get install chromium); the live view's "
                f"browser test needs it", allow_module_level=True)

ROLL_DEG = 20.0
START_HOLD_S = 8.0      # the AHRS converges from level to the 20 deg roll in this time
LIFT_SPEED_M_S = 2.0
SPEED = 2.0             # the emulated run is paced at twice the wall clock once watched
END_S = 12.0

STATE = "JSON.stringify(window.imuhalState)"


@pytest.fixture(scope="module")
def browser():
    with Chromium(EXECUTABLE) as chromium:
        yield chromium


def _run(pipeline, sink, go: threading.Event, *, paced_from_s: float = START_HOLD_S - 1.0,
         end_s: float = END_S) -> None:
    """Free-running up to ``paced_from_s`` (the AHRS converges), then paced at SPEED x the
    wall clock once the page is ready (go), as an embedding program would feed the view."""
    wall0 = None
    for event in pipeline.events(end_s):
        sink.handle(event)
        if event.t_ns < paced_from_s * 1e9:
            continue
        if wall0 is None:
            go.wait(30)
            wall0 = time.monotonic() - event.t_ns / 1e9 / SPEED
        ahead = event.t_ns / 1e9 / SPEED - (time.monotonic() - wall0)
        if ahead > 0:
            time.sleep(ahead)
    sink.close()


def test_the_page_follows_an_emulated_board_and_issues_no_write(plugins, seed_board,
                                                                browser, tmp_path):
    params = {"roll_deg": ROLL_DEG, "start_hold_s": START_HOLD_S, "ramp_s": 0.5,
              "speed_m_s": LIFT_SPEED_M_S, "floors": 10}
    go = threading.Event()
    with open_emulated(seed_board, plugins, scenario="elevator", scenario_params=params,
                       seed=4) as pipeline, \
            LiveView(pipeline, truth=EmulatedBoard.of(pipeline)) as live:
        runner = threading.Thread(target=_run, args=(pipeline, live.sink, go), daemon=True)
        runner.start()
        browser.events.clear()
        browser.navigate(live.url)
        browser.wait_for("window.imuhalState && window.imuhalState.messages > 0")
        go.set()
        # Still on the ground floor, banked 20 deg: the horizon shows the roll, the vario 0.
        still = browser.wait_for(f"imuhalState.t_s > {START_HOLD_S - 0.8} && {STATE}")
        # Riding up at 2 m/s: the vario follows.
        riding = browser.wait_for(f"imuhalState.truth && imuhalState.truth.climb_m_s > "
                                  f"{LIFT_SPEED_M_S - 0.05} && imuhalState.t_s > "
                                  f"{START_HOLD_S + 1.5} && {STATE}")
        shot = browser.screenshot()
        dom = browser.evaluate(
            "JSON.stringify({roll: document.getElementById('horizon').dataset.rollDeg,"
            " climb: document.getElementById('vario-bar').dataset.climbMS,"
            " bad: document.querySelectorAll('#health-table tr.bad').length,"
            " rows: document.querySelectorAll('#health-table tbody tr').length,"
            " forms: document.querySelectorAll('form, input, textarea, [formaction]').length,"
            " buttons: Array.from(document.querySelectorAll('button')).map(b => b.type),"
            " status: document.body.dataset.status})")
        # The drawing itself: banked right, the horizon is low on the left and high on the
        # right, so left of centre just below the centre line is still sky, right of centre
        # just above it is already ground.
        sky_left, ground_right = browser.evaluate(
            "(() => { const c = document.getElementById('horizon'), g = c.getContext('2d');"
            " const cx = c.width / 2, cy = (c.height - 40) / 2, r = Math.min(cx, cy) - 4;"
            " const px = (x, y) => Array.from(g.getImageData(x, y, 1, 1).data);"
            " return [px(cx - 0.7 * r, cy + 0.12 * r), px(cx + 0.7 * r, cy - 0.12 * r)]; })()")
        requests = browser.requests()
        problems = browser.problems()
        runner.join(timeout=30)
    still, riding, dom = json.loads(still), json.loads(riding), json.loads(dom)
    assert still["status"] == "live"
    assert abs(still["roll_deg"] - ROLL_DEG) < 3.0, still["roll_deg"]
    assert abs(still["climb_m_s"]) < 0.3
    assert abs(riding["roll_deg"] - ROLL_DEG) < 3.0
    assert abs(riding["climb_m_s"] - riding["truth"]["climb_m_s"]) < 0.5, riding["climb_m_s"]
    assert riding["errors"]["climb_m_s"] == pytest.approx(
        riding["climb_m_s"] - riding["truth"]["climb_m_s"])
    # What is drawn is what is exposed.
    assert float(dom["roll"]) == pytest.approx(riding["roll_deg"], abs=5.0)
    assert sky_left[2] > sky_left[0], sky_left            # blue: sky
    assert ground_right[0] > ground_right[2], ground_right  # brown: ground
    assert dom["rows"] == 3 and dom["bad"] == 0  # imu, mag, baro: healthy
    # Nothing on the page can write: no form or input, only plain buttons, and every
    # request it made was a GET to this server.
    assert dom["forms"] == 0 and set(dom["buttons"]) == {"button"}
    assert requests and {r["method"] for r in requests} == {"GET"}
    assert all(r["url"].startswith(live.url) for r in requests)
    assert problems == []  # no script error, no CSP violation, no failed load
    assert shot.startswith(b"\x89PNG")
    (tmp_path / "live-view.png").write_bytes(shot)


def test_the_bring_up_check_on_the_page_finds_a_wrong_mount(plugins, seed_board, browser):
    """The user presses "tilt nose up" and tilts the board (the bringup scenario does, from
    2 s); the MAX21100 really sits otherwise than the profile says, the HMC5883L does not."""
    go = threading.Event()
    with open_emulated(seed_board, plugins, scenario="bringup", seed=4,
                       physical_mounts={"imu": "-X+Y-Z"}) as pipeline, \
            LiveView(pipeline, truth=EmulatedBoard.of(pipeline)) as live:
        runner = threading.Thread(target=_run, args=(pipeline, live.sink, go), daemon=True,
                                  kwargs={"paced_from_s": 1.6, "end_s": 5.5})
        runner.start()
        browser.navigate(live.url)
        browser.wait_for("window.imuhalState && imuhalState.t_s > 1.5 && "
                         "document.querySelector('button[data-motion=nose-up]') !== null")
        browser.evaluate("document.querySelector('button[data-motion=nose-up]').click()")
        go.set()
        results = json.loads(browser.wait_for(
            "imuhalState.t_s > 5.0 && imuhalState.bringup.results['imu/gyro'] && "
            "JSON.stringify(imuhalState.bringup.results)", timeout=20))
        shown = browser.evaluate("document.getElementById('bringup-results').innerText")
        runner.join(timeout=30)
    assert results["imu/gyro"]["ok"] is False and "roll left" in results["imu/gyro"]["seen"]
    assert results["imu/accel"]["ok"] is False
    assert results["mag/mag"]["ok"] is True
    assert "check the mount of 'imu'" in shown


def test_a_device_that_goes_stale_turns_red_on_the_page(browser):
    """Fed by an embedding program (no pipeline): the barometer stops, the gyro goes on."""
    with LiveView(rate_hz=30.0) as live:
        browser.navigate(live.url)

        def feed(t0_s: float, t1_s: float, baro: bool) -> None:
            for i in range(round(t0_s * 100), round(t1_s * 100)):
                t_ns = i * 10_000_000
                live.sink.handle(GyroSample(t_ns=t_ns, device="imu",
                                            gyro_rad_s=(0.0, 0.0, 0.0)))
                if baro and i % 2 == 0:
                    live.sink.handle(PressureSample(t_ns=t_ns, device="baro",
                                                    pressure_pa=90000.0))

        feed(0.0, 1.0, baro=True)
        browser.wait_for("document.querySelectorAll('#health-table tr.good').length == 2")
        feed(1.0, 2.0, baro=False)
        red = browser.wait_for("Array.from(document.querySelectorAll('#health-table tr.bad'))"
                               ".map(r => r.dataset.device + ': ' + r.innerText).join('|')")
    assert red.startswith("baro: ") and "STALE" in red and "imu" not in red
