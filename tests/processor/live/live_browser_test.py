#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The live page in a real browser (headless Chromium over the DevTools pipe).

A simulated survey's LCM log is replayed into pitmap-live at 2x (the same event path as a live
subscription) while Chromium shows the page. Fails on any console error or uncaught exception,
when the coverage the page shows does not grow while pings are sent, or when the 2D map or the
3D canvas is blank in a screenshot (pixel statistics). Exit 77 (ctest skip) only when Chromium
cannot start here.

Usage: live_browser_test.py BIN_DIR SOURCE_DIR WORK_DIR"""

import json
import os
import re
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(sys.argv[2], "tools", "browser"))
import cdp  # noqa: E402


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def main():
    bin_dir, _, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    sim = os.path.join(work, "sim")
    subprocess.run([os.path.join(bin_dir, "pitmap-sim"), "synth", "--scenario", "demo",
                    "--duration", "40", "--out", sim], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    logs = sorted(os.path.join(sim, "log", f) for f in os.listdir(os.path.join(sim, "log"))
                  if f.endswith(".lcmlog"))
    try:
        browser = cdp.Browser(os.path.join(work, "profile"))
    except cdp.BrowserUnavailable as e:
        print("SKIP: %s" % e)
        sys.exit(cdp.SKIP)

    live_out = open(os.path.join(work, "live.out"), "w+")
    live = subprocess.Popen([os.path.join(bin_dir, "pitmap-live"), "--replay"] + logs +
                            ["--speed", "2", "--hold", "--port", "0", "--cell-size", "0.5",
                             "--vehicle", os.path.join(sim, "log", "vehicle.yaml")],
                            stdout=live_out, stderr=subprocess.STDOUT)
    try:
        port = None
        for _ in range(100):
            live_out.seek(0)
            m = re.search(r"open http://127\.0\.0\.1:(\d+)/", live_out.read())
            if m:
                port = int(m.group(1))
                break
            time.sleep(0.1)
        if port is None:
            fail("pitmap-live did not start")
        browser.open("http://127.0.0.1:%d/" % port)
        state = "JSON.stringify({polls: pitmapLive.polls, cells: pitmapLive.filledCells, " \
                "errors: pitmapLive.errors, points: pitmapLive.nPoints})"
        # The first observation once the page has polled twice, the second 4 s later: the
        # replay (40 s of survey at 2x) is still sending pings in between.
        first, s = None, None
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            browser.pump(0.1)
            try:
                s = browser.evaluate(state)
            except RuntimeError:
                continue
            s = json.loads(s)
            if s["polls"] >= 2 and s["cells"] > 0:
                first = s
                break
        if first is None:
            fail("the page never showed coverage: %s; errors: %s" % (s, browser.errors()))
        browser.pump(4.0)
        second = json.loads(browser.evaluate(state))
        print("page at t1: %s, 4 s later: %s" % (first, second))
        if second["polls"] < first["polls"] + 2:
            fail("the page stopped polling: %s -> %s" % (first, second))
        if second["cells"] <= first["cells"]:
            fail("no new coverage on the page while pings were sent: %s -> %s" % (first, second))
        if second["errors"] != 0:
            fail("the page failed to fetch %d time(s)" % second["errors"])
        # Screenshots of both canvases.
        for cid, min_share in (("map", 0.02), ("view3d", 0.005)):
            r = browser.evaluate("(() => { const b = document.getElementById('%s')"
                                 ".getBoundingClientRect(); return {x: b.x, y: b.y, "
                                 "width: b.width, height: b.height}; })()" % cid)
            img = browser.screenshot(r)
            share, colours = cdp.pixel_stats(img)
            print("canvas %s: %dx%d, %.1f %% drawn, %d colours" %
                  (cid, img[0], img[1], 100 * share, colours))
            if share < min_share or colours < 8:
                fail("canvas %s is blank (%.2f %% drawn, %d colours)" % (cid, 100 * share, colours))
        errs = browser.errors()
        if errs:
            fail("console errors: %s" % errs)
        print("PASS")
    finally:
        browser.close()
        live.terminate()
        try:
            live.wait(timeout=10)
        except subprocess.TimeoutExpired:
            live.kill()
        live_out.close()


if __name__ == "__main__":
    main()
