"""The live page and track's trajectory.html in a real browser (issue 23 §2).

Headless Debian chromium (``/usr/bin/chromium``) driven by playwright; skipped with the reason when
either is missing. Map tile requests are refused (the test machine is offline; the page must draw
its metric grid without them). Screenshots stay under the test's tmp_path (the path is printed).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pandas as pd
import pytest

from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live.process import SRC, LiveServer
from wearnav.track import track

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]
WALK_S = 60.0
# saturated pixels (path colours, fix centres): max − min channel above this; the grid and the
# background are grey, accuracy circles faint
SATURATED = """(() => { const c = document.getElementById("map"), d = c.getContext("2d")
  .getImageData(0, 0, c.width, c.height).data; let n = 0;
  for (let i = 0; i < d.length; i += 4) { const m = Math.max(d[i], d[i+1], d[i+2]) - Math.min(d[i], d[i+1], d[i+2]);
    if (m > 90) n++; } return n; })()"""


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.is_file():
        pytest.skip(f"no chromium at {CHROMIUM} (Debian package chromium)")
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (python) is not installed")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=ARGS)
        yield b
        b.close()


def new_page(browser):
    page = browser.new_page(viewport={"width": 1100, "height": 700})
    page.route("**/tile.openstreetmap.org/**", lambda route: route.abort())  # offline: the grid must do
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    return page, errors


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    root = tmp_path_factory.mktemp("live_page")
    simulated_export(root / "export", seed=1, duration_s=WALK_S)
    return root


def test_trajectory_html_opens_offline_draws_and_slides(browser, walk, tmp_path):
    track(walk / "export", None, walk / "track")
    table = pd.read_csv(walk / "track" / "trajectory.csv")
    page, errors = new_page(browser)
    page.goto((walk / "track" / "trajectory.html").as_uri())
    page.wait_for_function("window.wearnavState && window.wearnavState.upto !== undefined")
    n = len(table)
    expected = len(range(0, n, 25)) + (1 if (n - 1) % 25 else 0)
    assert page.evaluate("window.wearnavState.path.length") == expected
    assert page.text_content("#points") == str(expected)
    assert page.text_content("#activity") in {a["label"] for a in page.evaluate("window.wearnavState.activity")}
    full = page.evaluate(SATURATED)
    page.screenshot(path=str(tmp_path / "trajectory.png"))
    page.evaluate("""(() => { const s = document.getElementById("slider"); s.value = 10;
                     s.dispatchEvent(new Event("input")); })()""")
    assert page.evaluate("window.wearnavState.upto") == 10 and page.text_content("#points") == "11"
    assert page.text_content("#time") == f"{page.evaluate('window.wearnavState.path[10][0]'):.1f}"
    part = page.evaluate(SATURATED)
    page.screenshot(path=str(tmp_path / "trajectory_slider.png"))
    print(
        f"\nscreenshots: {tmp_path / 'trajectory.png'}, {tmp_path / 'trajectory_slider.png'}; "
        f"saturated pixels {full} (whole path), {part} (10 s)"
    )
    assert full > part + 500 and part > 0 and not errors


def test_live_page_follows_a_replayed_walk(browser, walk, tmp_path):
    """`wearnav live` (a real process) and `wearnav replay` (one too) of the 60-s export at 10×;
    the page opened with the token shows the server's path (as many points as the offline path
    has 1-s points up to the live path's end), the activity, the three devices, and then the
    banner once they stop sending."""
    if not (walk / "track").is_dir():
        track(walk / "export", None, walk / "track")
    table = pd.read_csv(walk / "track" / "trajectory.csv")
    token, session = "page-test-token", "pagetest"
    srv = LiveServer(tmp_path / "live.db", "--token", token, token=token).start(timeout_s=60)
    try:
        out = subprocess.run(
            [
                sys.executable,
                "-m",
                "wearnav",
                "replay",
                str(walk / "export"),
                "--url",
                f"{srv.url}/push",
                "--speed",
                "10",
                "--token",
                token,
                "--session",
                session,
            ],
            capture_output=True,
            text=True,
            timeout=120,
            env={**os.environ, "PYTHONPATH": str(SRC), "OMP_NUM_THREADS": "1"},
        )
        assert out.returncode == 0, out.stderr
        sent = json.loads(out.stdout)
        assert sent["acknowledged"] == sent["messages"]
        headers = {"authorization": f"Bearer {token}"}
        deadline, state = time.monotonic() + 30, {}
        while time.monotonic() < deadline:  # the tracker catches up with the last push
            state = httpx.get(f"{srv.url}/state", params={"session": session}, headers=headers).json()
            if state.get("path") and state["path"][-1][0] > table["t"].iloc[-1] - 6 and state.get("activity"):
                break
            time.sleep(0.5)
        page, errors = new_page(browser)
        page.goto(f"{srv.url}/?token={token}&session={session}")
        page.wait_for_function("window.wearnavState && window.wearnavState.path.length > 0")
        st = page.evaluate("window.wearnavState")
        n = int(np.sum(table["t"].to_numpy() <= st["path"][-1][0] + 1e-3))
        expected = len(range(0, n, 25)) + (1 if (n - 1) % 25 else 0)
        print(
            f"\nlive page: {len(st['path'])} points (expected {expected}), activity {st['activity']}, "
            f"devices {sorted(st['devices'])}, path to {st['path'][-1][0]:.1f} s of {table['t'].iloc[-1]:.1f} s"
        )
        assert st["path"][0][0] == pytest.approx(table["t"].iloc[0], abs=2e-3)
        assert len(st["path"]) == expected and page.text_content("#points") == str(expected)
        assert st["activity"] and page.text_content("#activity") == st["activity"]["label"]
        assert sorted(st["devices"]) == ["earbuds", "phone", "watch"] and len(st["fixes"]) > 30
        assert page.locator("#devices tbody tr").count() == 3 and st["anchor"] != "none"
        page.screenshot(path=str(tmp_path / "live.png"))
        page.wait_for_selector("#banner.show", timeout=15_000)  # the server marks them stopped after 5 s
        assert "stopped sending" in page.text_content("#banner")
        page.screenshot(path=str(tmp_path / "live_stopped.png"))
        print(f"screenshots: {tmp_path / 'live.png'}, {tmp_path / 'live_stopped.png'}")
        assert not errors
    finally:
        srv.stop()
