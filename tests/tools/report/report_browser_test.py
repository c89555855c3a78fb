#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""report.html's interactive 3D view in a real browser (headless Chromium over the DevTools
pipe, tools/browser/cdp.py), on a synthetic products folder (report_test.WriteProducts: a pit
with a mesh, soundings and trajectories before and after SLAM) or on a folder given.

Fails on any console error or uncaught exception, when the WebGL view does not start or is
blank in a screenshot (pixel statistics), or when the distance tool does not measure between
two clicks. Exit 77 (ctest skip) only when Chromium cannot start here.

Usage: report_browser_test.py --report BIN/pitmap-report --source SOURCE_DIR --work DIR
                              [--products P]   (P: an existing products folder to check)"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--products")
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.source, "tools", "browser"))
    sys.path.insert(0, os.path.join(args.source, "tests", "tools", "report"))
    import cdp  # noqa: E402

    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    products = args.products
    if products is None:
        import report_test  # noqa: E402  (writes the synthetic products)
        products = os.path.join(args.work, "products")
        os.makedirs(products)
        report_test.WriteProducts(products, full=True)
    r = subprocess.run(["/usr/bin/python3", args.report, products], capture_output=True, text=True)
    if r.returncode != 0:
        fail("pitmap-report failed: " + r.stderr[-2000:])
    page = os.path.join(products, "report.html")
    print("report.html: %.1f MB" % (os.path.getsize(page) / 1e6))
    try:
        browser = cdp.Browser(os.path.join(args.work, "profile"))
    except cdp.BrowserUnavailable as e:
        print("SKIP: %s" % e)
        sys.exit(cdp.SKIP)
    try:
        t0 = time.monotonic()
        browser.open("file://" + os.path.abspath(page))
        state = None
        for _ in range(300):
            browser.pump(0.1)
            try:
                state = json.loads(browser.evaluate(
                    "JSON.stringify(window.pitmapViewer || null)"))
            except RuntimeError:
                continue
            if state and state.get("frames", 0) >= 3:
                break
        print("3D view: %s, first frames after %.1f s" % (state, time.monotonic() - t0))
        if not state or state.get("frames", 0) < 3:
            fail("the 3D view did not render: %s; errors: %s" % (state, browser.errors()))
        if state["triangles"] <= 0 or state["points"] <= 0:
            fail("the 3D view has no mesh or no soundings: %s" % state)
        rect = browser.evaluate("(() => { const e = document.getElementById('viewer3d'); "
                                "e.scrollIntoView(); const b = e.getBoundingClientRect(); "
                                "return {x: b.x + scrollX, y: b.y + scrollY, width: b.width, "
                                "height: b.height}; })()")
        browser.pump(0.5)
        img = browser.screenshot(rect)
        share, colours = cdp.pixel_stats(img, background=(0x15, 0x19, 0x1d))
        print("viewer canvas: %dx%d, %.1f %% drawn, %d colours" % (img[0], img[1], 100 * share,
                                                                   colours))
        if share < 0.03 or colours < 16:
            fail("the 3D view is blank (%.2f %% drawn, %d colours)" % (100 * share, colours))
        # The distance tool: two clicks on the surface near the middle of the view.
        browser.evaluate("[...document.querySelectorAll('#viewer3d-bar button')]"
                         ".find(b => b.textContent.startsWith('measure')).click()")
        rect = browser.evaluate("(() => { const b = document.querySelector('#viewer3d canvas')"
                                ".getBoundingClientRect(); return {x: b.x, y: b.y, "
                                "width: b.width, height: b.height}; })()")
        for dx in (-0.08, 0.08):
            x = rect["x"] + rect["width"] * (0.5 + dx)
            y = rect["y"] + rect["height"] * 0.5
            for kind in ("mousePressed", "mouseReleased"):
                browser.call("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y,
                                                          "button": "left", "clickCount": 1})
            browser.pump(0.2)
        text = browser.evaluate("document.getElementById('viewer3d-info').textContent")
        print("distance tool: %r" % text)
        if not text.startswith("distance ") or " m (horizontal " not in text:
            fail("the distance tool did not measure: %r" % text)
        errs = browser.errors()
        if errs:
            fail("console errors: %s" % errs)
        print("PASS")
    finally:
        browser.close()


if __name__ == "__main__":
    main()
