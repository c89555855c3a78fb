#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The live page in a real browser (headless Chromium over the DevTools pipe).

A simulated survey's LCM log is replayed into pitmap-live at 2x (the same event path as a live
subscription) while Chromium shows the page. Fails on any console error or uncaught exception,
when the coverage the page shows does not grow while pings are sent, or when the 2D map or the
3D canvas is blank in a screenshot (pixel statistics), or when the snapshot button (a POST
with the page's token, under the page's Content-Security-Policy) does not write a file whose
name alone it shows. Then the TVU status layer: on the
simulated survey (its vehicle.yaml's error model) most cells meet IHO S-44 order 1a (green on
the map); replayed again with a deliberately bad error model (position noise 0.5 m: TVU >= 0.98
m, over the 1a limit at any depth here) most cells fail (red) and the page shows the
tvu_over_limit alarm. The page is on this machine (loopback): it is not budgeted, so it never
shows THINNED at the default budget. Once the replay ends the page says "replay finished" and,
more than the no-messages time (5 s) later, shows no no_messages alarm. Exit 77 (ctest skip)
only when Chromium cannot start here.

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


def green_red(img):
    """Pixels in the page's TVU colours: meets (40, 190, 70), fails (220, 40, 40)."""
    w, h, ch, data = img
    green = red = 0
    for p in range(0, w * h * ch, ch):
        r, g, b = data[p], data[p + 1], data[p + 2]
        if g > 150 and r < 100 and b < 120:
            green += 1
        elif r > 180 and g < 80 and b < 80:
            red += 1
    return green, red


def map_shot(browser):
    r = browser.evaluate("(() => { const b = document.getElementById('map')"
                         ".getBoundingClientRect(); return {x: b.x, y: b.y, "
                         "width: b.width, height: b.height}; })()")
    return browser.screenshot(r)


TVU_STATE = "JSON.stringify({polls: pitmapLive.polls, tvu: pitmapLive.tvuCells, " \
            "legend: document.getElementById('legend').textContent, " \
            "alarms: document.getElementById('alarms').textContent, " \
            "errors: pitmapLive.errors})"


def tvu_layer(browser, want_meeting, label):
    """Switches the map to the TVU layer; checks the share of cells meeting 1a and the colours."""
    browser.evaluate("pitmapLive.setLayer('tvu')")
    browser.pump(2.0)
    s = json.loads(browser.evaluate(TVU_STATE))
    meets, fails = s["tvu"]["meets"], s["tvu"]["fails"]
    print("%s: TVU layer %d cells meet, %d fail; legend: %s" % (label, meets, fails, s["legend"]))
    if meets + fails < 50:
        fail("%s: the TVU layer holds %d cells" % (label, meets + fails))
    share = meets / float(meets + fails)
    if (want_meeting and share < 0.9) or (not want_meeting and share > 0.1):
        fail("%s: %.1f %% of cells meet order 1a" % (label, 100 * share))
    if "order 1a" not in s["legend"] or "sqrt(0.50" not in s["legend"]:
        fail("%s: the legend does not name the order and its limit: %s" % (label, s["legend"]))
    green, red = green_red(map_shot(browser))
    print("%s: map pixels green %d, red %d" % (label, green, red))
    if want_meeting and not (green > 2000 and green > 5 * red):
        fail("%s: the map is not mostly green (green %d, red %d)" % (label, green, red))
    if not want_meeting and not (red > 2000 and red > 5 * green):
        fail("%s: the map is not mostly red (green %d, red %d)" % (label, green, red))
    return s


def start_live(bin_dir, logs, vehicle, speed, out_path, snapshots):
    live_out = open(out_path, "w+")
    live = subprocess.Popen([os.path.join(bin_dir, "pitmap-live"), "--replay"] + logs +
                            ["--speed", speed, "--hold", "--port", "0", "--cell-size", "0.5",
                             "--vehicle", vehicle, "--out", snapshots],
                            stdout=live_out, stderr=subprocess.STDOUT)
    port = None
    for _ in range(100):
        live_out.seek(0)
        m = re.search(r"open http://127\.0\.0\.1:(\d+)/", live_out.read())
        if m:
            port = int(m.group(1))
            break
        time.sleep(0.1)
    return live, live_out, port


def stop_live(live, live_out):
    live.terminate()
    try:
        live.wait(timeout=10)
    except subprocess.TimeoutExpired:
        live.kill()
    live_out.close()


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

    snapshots = os.path.join(work, "snapshots")
    live, live_out, port = start_live(bin_dir, logs, os.path.join(sim, "log", "vehicle.yaml"), "2",
                                      os.path.join(work, "live.out"), snapshots)
    try:
        try:
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
            # Loopback: no budget, no thinning (a 2x replay at the default 50 kB/s thinned).
            budget = json.loads(browser.evaluate(
                "JSON.stringify({text: document.getElementById('budget').textContent, "
                "thinned: document.body.dataset.thinned})"))
            print("budget: %s" % budget)
            if budget["thinned"] != "0" or "THINNED" in budget["text"]:
                fail("the page on loopback was thinned: %s" % budget)
            if "no link budget" not in budget["text"]:
                fail("the page does not say it is not budgeted: %s" % budget)
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
            # The snapshot button: the page's POST carries its token past the server's check
            # (under its Content-Security-Policy: a violation is a console error), the answer
            # names the file only, and the file is there.
            browser.evaluate("document.getElementById('snapshot').click()")
            msg = ""
            for _ in range(50):
                browser.pump(0.2)
                msg = browser.evaluate("document.getElementById('snapmsg').textContent")
                if msg:
                    break
            print("snapshot: %s" % msg)
            m = re.fullmatch(r"written: (live_grid_[0-9A-Za-z_.-]+\.tif)", msg or "")
            if not m:
                fail("the snapshot button did not write a file (or named a path): %r" % msg)
            if not os.path.exists(os.path.join(snapshots, m.group(1))):
                fail("the snapshot %s is not in %s" % (m.group(1), snapshots))
            # The TVU status layer on the simulated survey: most cells meet 1a, no TVU alarm.
            s = tvu_layer(browser, True, "good model")
            if "tvu_over_limit" in s["alarms"]:
                fail("tvu_over_limit raised on the good survey: %s" % s["alarms"])
            errs = browser.errors()
            if errs:
                fail("console errors: %s" % errs)
            # This page stops polling before its server goes (its failed fetches would be
            # console errors of the next part); its events are checked and dropped.
            browser.call("Page.navigate", {"url": "about:blank"})
            browser.pump(0.5)
            browser.events.clear()
        finally:
            stop_live(live, live_out)

        # The same survey with a deliberately bad error model: most cells fail, the alarm fires.
        with open(os.path.join(sim, "log", "vehicle.yaml")) as f:
            text = f.read()
        bad_text, n = re.subn(r"position_noise_m: [0-9.eE+-]+", "position_noise_m: 0.5", text)
        if n != 1:
            fail("the simulated vehicle.yaml has no uncertainty: position_noise_m")
        bad = os.path.join(work, "vehicle_bad.yaml")
        with open(bad, "w") as f:
            f.write(bad_text)
        live, live_out, port = start_live(bin_dir, logs, bad, "8", os.path.join(work, "live_bad.out"),
                                          snapshots)
        try:
            if port is None:
                fail("pitmap-live (bad model) did not start")
            browser.open("http://127.0.0.1:%d/" % port)
            s = None
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                browser.pump(0.5)
                try:
                    s = json.loads(browser.evaluate(TVU_STATE))
                except RuntimeError:
                    continue
                if s["polls"] >= 2 and "tvu_over_limit" in s["alarms"]:
                    break
            if s is None or "tvu_over_limit" not in s["alarms"]:
                fail("the page never showed the tvu_over_limit alarm: %s" % s)
            m = re.search(r"TVU over the order 1a limit in (\d+) % of new cells", s["alarms"])
            if not m or int(m.group(1)) < 90:
                fail("the alarm's reason does not say most new cells fail: %s" % s["alarms"])
            print("bad model: alarm: %s" % s["alarms"])
            tvu_layer(browser, False, "bad model")
            # The replay (40 s at 8x) ends: the page says so, and 7 s of silence later (more
            # than no_messages_s = 5 s) it still raises no no_messages alarm.
            feed = None
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                browser.pump(0.5)
                feed = json.loads(browser.evaluate(
                    "JSON.stringify({source: document.body.dataset.source, "
                    "feed: document.getElementById('feed').textContent})"))
                if feed["source"] == "replay-finished":
                    break
            if feed is None or feed["source"] != "replay-finished" or \
                    feed["feed"] != "replay finished":
                fail("the page does not say the replay finished: %s" % feed)
            browser.pump(7.0)
            s = json.loads(browser.evaluate(TVU_STATE))
            print("replay finished, 7 s later: alarms: %s" % s["alarms"])
            if "no_messages" in s["alarms"]:
                fail("an ended replay raised the no_messages alarm: %s" % s["alarms"])
            errs = browser.errors()
            if errs:
                fail("console errors: %s" % errs)
            print("PASS")
        finally:
            stop_live(live, live_out)
    finally:
        browser.close()


if __name__ == "__main__":
    main()
