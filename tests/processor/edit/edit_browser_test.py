#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""pitmap edit's page in a real browser (headless Chromium over the DevTools pipe).

On a simulated survey (pitmap-sim synth demo, 20 s, with echo artifacts; pitmap georef) the
page is opened from the URL `pitmap edit P --no-open --port 0` prints. Fails on any console
error or uncaught exception, a blank 3D or cross-section canvas, and when:
  - a lasso drawn with the mouse on the 3D view (DevTools mouse events) does not reject exactly
    the accepted soundings inside it: counted here independently, in Python, by projecting
    every sounding of /api/points (the whole survey: the display stride is 1 here) with the
    matrix the page sent and testing the polygon it sent (even-odd, half-open edges);
  - the edit is not in P/edits.json (one edit, that many soundings), or the statuses the page
    is sent differ from the expected ones;
  - the undo button does not bring the statuses and the file back;
  - a box drawn on the cross-section does not stay inside its slab (every rejected sounding lies
    within half the slab of the section plane);
  - the saved log does not reproduce the flags: the survey georeferenced again into a new
    folder with edits.json copied in (pitmap georef), opened by a second pitmap edit (which
    applies it through survey::LoadEdits), must give the same statuses;
  - the re-run button does not start the program (a stub given with --rerun-program, which
    records its arguments: `rerun P`) and show its output and exit status;
  - an error answer of the server (no route, a body it cannot read, a bad selection) has no
    JSON {"error": ...} body.
Exit 77 (ctest skip) only when Chromium cannot start here.

Usage: edit_browser_test.py BIN_DIR SOURCE_DIR WORK_DIR"""

import json
import os
import shutil
import stat
import struct
import subprocess
import sys
import time
import urllib.error
import urllib.request

sys.path.insert(0, os.path.join(sys.argv[2], "tools", "browser"))
import cdp  # noqa: E402


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def get(url):
    with urllib.request.urlopen(url, timeout=30) as r:
        return r.read()


def error_body(url, method="GET", body=None, headers=None):
    """The status and parsed JSON body of a request that must fail (4xx/5xx)."""
    req = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            fail("%s %s answered %d, not an error" % (method, url, r.status))
    except urllib.error.HTTPError as e:
        text = e.read()
        try:
            j = json.loads(text)
        except ValueError:
            fail("%s %s: %d with a body that is not JSON: %r" % (method, url, e.code, text))
        if not isinstance(j, dict) or not j.get("error"):
            fail("%s %s: %d without an error text: %r" % (method, url, e.code, text))
        return e.code, j


def start_editor(bin_dir, folder, log_path, extra=()):
    out = open(log_path, "w")
    p = subprocess.Popen([os.path.join(bin_dir, "pitmap"), "edit", folder, "--no-open",
                          "--port", "0"] + list(extra), stdout=subprocess.PIPE, stderr=out,
                         text=True)
    line = p.stdout.readline().strip()
    if not line.startswith("http://127.0.0.1:"):
        p.kill()
        fail("pitmap edit printed no URL (%r); see %s" % (line, log_path))
    return p, line


def project(m, x, y, z):
    """The page's column-major view-projection matrix applied as the server does."""
    cx = m[0] * x + m[4] * y + m[8] * z + m[12]
    cy = m[1] * x + m[5] * y + m[9] * z + m[13]
    cz = m[2] * x + m[6] * y + m[10] * z + m[14]
    cw = m[3] * x + m[7] * y + m[11] * z + m[15]
    if not cw > 0:
        return None
    nz = cz / cw
    if nz < -1 or nz > 1:
        return None
    return cx / cw, cy / cw


def inside(poly, x, y):
    c = False
    n = len(poly)
    k = n - 1
    for i in range(n):
        ax, ay = poly[i]
        bx, by = poly[k]
        if (ay > y) != (by > y):
            if x < ax + (y - ay) * (bx - ax) / (by - ay):
                c = not c
        k = i
    return c


def drag(browser, points):
    """A mouse drag through `points` (page pixels)."""
    x, y = points[0]
    browser.call("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": x, "y": y})
    browser.call("Input.dispatchMouseEvent", {"type": "mousePressed", "x": x, "y": y,
                                              "button": "left", "buttons": 1, "clickCount": 1})
    for x, y in points[1:]:
        browser.call("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": x, "y": y,
                                                  "button": "left", "buttons": 1})
    browser.call("Input.dispatchMouseEvent", {"type": "mouseReleased", "x": x, "y": y,
                                              "button": "left", "buttons": 0, "clickCount": 1})


def wait_for(browser, expr, what, seconds=60):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if browser.evaluate(expr):
            return
        time.sleep(0.2)
    fail("timed out waiting for " + what + "; page errors: " +
         json.dumps(browser.evaluate("pitmapEdit.errors")))


def main():
    bin_dir, _, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    sim, P, P2 = (os.path.join(work, d) for d in ("sim", "P", "P2"))
    subprocess.run([os.path.join(bin_dir, "pitmap-sim"), "synth", "--scenario", "demo",
                    "--duration", "20", "--echo-artifacts", "typical", "--out", sim], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    subprocess.run([os.path.join(bin_dir, "pitmap"), "georef", os.path.join(sim, "log"),
                    "--out", P], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    stub = os.path.join(work, "rerun_stub.sh")
    with open(stub, "w") as f:
        f.write("#!/bin/sh\necho \"$@\" > '%s'\necho 'calibrate 100 %%'\necho 'stub done'\n"
                "exit 0\n" % os.path.join(work, "rerun_args.txt"))
    os.chmod(stub, os.stat(stub).st_mode | stat.S_IEXEC)

    editor, url = start_editor(bin_dir, P, os.path.join(work, "edit.log"),
                               ["--rerun-program", stub])
    base = url.split("/?")[0]
    editors = [editor]
    try:
        browser = cdp.Browser(os.path.join(work, "profile"))
    except cdp.BrowserUnavailable as e:
        editor.kill()
        print("SKIP: %s" % e)
        sys.exit(cdp.SKIP)
    try:
        browser.open(url)
        wait_for(browser, "window.pitmapEdit && pitmapEdit.ready", "the page to load")
        meta = json.loads(get(base + "/api/meta"))
        # Error answers are JSON, httplib's own (no route, an unreadable body) included.
        token = url.split("token=")[1].split("&")[0]
        write = {"X-Pitmap-Token": token, "Origin": base}
        for args in ((base + "/api/nothing",),
                     (base + "/api/select", "POST", b"",
                      dict(write, **{"Content-Type": "multipart/form-data"})),
                     (base + "/api/select", "POST", b"{not json",
                      dict(write, **{"Content-Type": "application/json"}))):
            code, j = error_body(*args)
            print("error answer %s: %d %s" % (args[0].replace(base, ""), code, j["error"]))
        if meta["stride"] != 1:
            fail("the small survey should be shown whole (stride %d)" % meta["stride"])
        raw = get(base + "/api/points")
        n = len(raw) // 12
        xyz = struct.unpack("<%df" % (3 * n), raw)
        status0 = get(base + "/api/status")
        if len(status0) != n or n != meta["soundings"]:
            fail("sizes: %d points, %d statuses, %d soundings" % (n, len(status0),
                                                                  meta["soundings"]))
        browser.pump(1.0)
        for canvas in ("c3d", "csec"):
            r = browser.evaluate("(() => { const b = document.getElementById('%s')"
                                 ".getBoundingClientRect(); return {x: b.x, y: b.y, "
                                 "width: b.width, height: b.height}; })()" % canvas)
            share, colours = cdp.pixel_stats(browser.screenshot(r), background=(16, 20, 24))
            print("%s: %.1f %% drawn, %d colours" % (canvas, 100 * share, colours))
            if share < 0.002 or colours < 3:
                fail("the %s canvas is blank" % canvas)

        # A lasso with the mouse on the 3D view: an irregular pentagon around the middle.
        browser.evaluate("document.querySelector('input[name=tool][value=lasso]').click()")
        r = browser.evaluate("(() => { const b = document.getElementById('o3d')"
                             ".getBoundingClientRect(); return [b.x, b.y, b.width, b.height]; })()")
        cx, cy, w, h = r[0] + r[2] / 2, r[1] + r[3] / 2, r[2], r[3]
        corners = [(-0.25, -0.2), (0.2, -0.25), (0.05, 0.0), (0.25, 0.2), (-0.2, 0.15)]
        path = []
        for i in range(len(corners)):
            a, b = corners[i], corners[(i + 1) % len(corners)]
            for t in range(10):
                path.append((cx + w * (a[0] + (b[0] - a[0]) * t / 10),
                             cy + h * (a[1] + (b[1] - a[1]) * t / 10)))
        drag(browser, path)
        wait_for(browser, "pitmapEdit.selects === 1", "the lasso's answer")
        res = browser.evaluate("JSON.stringify({r: pitmapEdit.lastResult, "
                               "poly: pitmapEdit.lastPolygon, m: pitmapEdit.lastMatrix})")
        res = json.loads(res)
        poly, m, answer = res["poly"], res["m"], res["r"]
        inside_all, expect_changed = 0, []
        for i in range(n):
            p = project(m, xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2])
            if p is not None and inside(poly, p[0], p[1]):
                inside_all += 1
                if status0[i] == 0:
                    expect_changed.append(i)
        print("lasso: %d soundings inside (%d accepted); the server: %d inside, %d changed, "
              "%.0f ms in the page" % (inside_all, len(expect_changed), answer["selected"],
                                       answer["changed"], answer["ms"]))
        if len(expect_changed) < 500:
            fail("the lasso holds too few soundings to mean anything (%d)" % len(expect_changed))
        if answer["selected"] != inside_all or answer["changed"] != len(expect_changed):
            fail("the server's selection differs from the independent count")
        status1 = get(base + "/api/status")
        changed = set(expect_changed)
        for i in range(n):
            want = 9 if i in changed else status0[i]
            if status1[i] != want:
                fail("sounding %d: status %d, expected %d" % (i, status1[i], want))
        with open(os.path.join(P, "edits.json")) as f:
            log = json.load(f)
        if len(log["edits"]) != 1 or log["edits"][0]["action"] != "reject":
            fail("edits.json: %s" % json.dumps(log)[:300])
        if sum(r[2] for r in log["edits"][0]["runs"]) != len(expect_changed):
            fail("edits.json holds another number of soundings than the lasso changed")

        # Undo (the button): statuses and file back.
        browser.evaluate("document.getElementById('undo').click()")
        wait_for(browser, "pitmapEdit.meta && pitmapEdit.meta.edits === 0", "the undo")
        if get(base + "/api/status") != status0:
            fail("undo did not bring the statuses back")
        with open(os.path.join(P, "edits.json")) as f:
            if json.load(f)["edits"]:
                fail("undo left the edit in edits.json")

        # A box on the cross-section: only soundings within the slab.
        browser.evaluate("document.getElementById('slab').value = '1';"
                         "document.getElementById('slab').dispatchEvent(new Event('input'))")
        browser.evaluate("document.querySelector('input[name=tool][value=box]').click()")
        r = browser.evaluate("(() => { const b = document.getElementById('osec')"
                             ".getBoundingClientRect(); return [b.x, b.y, b.width, b.height]; })()")
        drag(browser, [(r[0] + 0.1 * r[2], r[1] + 0.1 * r[3]), (r[0] + 0.5 * r[2], r[1] + 0.5 * r[3]),
                       (r[0] + 0.9 * r[2], r[1] + 0.9 * r[3])])
        wait_for(browser, "pitmapEdit.selects === 2", "the box's answer")
        sec = json.loads(browser.evaluate("JSON.stringify({r: pitmapEdit.lastResult, "
                                          "m: pitmapEdit.lastMatrix})"))
        status2 = get(base + "/api/status")
        # Depth along the view (NDC z) of the rejected ones: inside [-1, 1] = the slab.
        m = sec["m"]
        rejected = [i for i in range(n) if status2[i] == 9]
        if len(rejected) != sec["r"]["changed"] or not rejected:
            fail("the section box changed %d soundings, the statuses show %d" %
                 (sec["r"]["changed"], len(rejected)))
        for i in rejected:
            if project(m, xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]) is None:
                fail("sounding %d rejected outside the section's slab" % i)
        print("section box: %d soundings rejected, all within the 1 m slab" % len(rejected))

        # The saved log reproduces the flags on a new georeference of the same inputs.
        os.makedirs(P2)
        shutil.copy(os.path.join(P, "edits.json"), os.path.join(P2, "edits.json"))
        subprocess.run([os.path.join(bin_dir, "pitmap"), "georef", os.path.join(sim, "log"),
                        "--out", P2], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        if not os.path.exists(os.path.join(P2, "edits.json")):
            fail("pitmap georef removed the edit log it was given")
        editor2, url2 = start_editor(bin_dir, P2, os.path.join(work, "edit2.log"))
        editors.append(editor2)
        base2 = url2.split("/?")[0]
        if get(base2 + "/api/status") != status2:
            fail("the edit log applied to a new georeference gives other statuses")
        summary = json.load(open(os.path.join(P2, "summary.json")))
        print("new georef with the edit log: statuses equal; its summary's manual count: %s" %
              json.dumps(summary.get("georef", {}).get("status", "not recorded"))[:200])

        # Re-run (the stub): started with `rerun P`, its output and exit shown.
        browser.evaluate("document.getElementById('rerun').click()")
        wait_for(browser, "pitmapEdit.rerun && pitmapEdit.rerun.state === 'exited'", "the re-run")
        text = browser.evaluate("document.getElementById('rerunlog').textContent")
        if "stub done" not in text or "exit 0" not in text:
            fail("the re-run's output is not shown: %r" % text)
        with open(os.path.join(work, "rerun_args.txt")) as f:
            args = f.read().split()
        if args != ["rerun", P]:
            fail("the re-run was started with %r" % args)

        errors = browser.errors() + browser.evaluate("pitmapEdit.errors")
        if errors:
            fail("page errors: " + "; ".join(map(str, errors)))
        print("OK")
    finally:
        browser.close()
        for e in editors:
            e.terminate()
            try:
                e.wait(timeout=10)
            except subprocess.TimeoutExpired:
                e.kill()


if __name__ == "__main__":
    main()
