#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The 3D viewer's tools in a real browser (headless Chromium over the DevTools pipe,
tools/browser/cdp.py): report.html of the synthetic products (report_test.WriteProducts: a
pit with a bench, soundings, trajectories) and the glTF page (pitmap-report --view-gltf) of a
mesh.glb written by the pipeline's mesh code (pitmap-test-glb-fixture).

Checks, failing on any console error or uncaught exception:
- cross-section: two clicks give a profile whose mesh segments match the heights of the
  report's mesh at 200 stations along the same line, computed here from the page's own mesh
  data by a different method (a vertical ray through each triangle, barycentric heights); the
  same for a known oblique line across the bench; the corridor holds the soundings counted
  here; the profile plot is drawn;
- "enter VR": the button exists and says that VR is not available (three.js r111's
  "VR NOT FOUND", or "WEBXR NOT SUPPORTED");
- the glTF page draws a non-blank view with the file's triangle count, and its cross-section
  cuts the loaded mesh;
- equipment (pitmap-report --equipment): the .glb given at a UTM position and heading stands
  there in the report's view, centred on the position and with its lowest point on the mesh;
- "open glTF...": the same .glb loads into report.html; a truncated one and one whose header
  was patched to the truncated length give a message in the page; so does each of 300
  mutations (truncations, flipped bytes, overwritten words) of a small valid .glb, and the
  view keeps drawing.
Exit 77 (ctest skip) only when Chromium cannot start here.

Usage: viewer_browser_test.py --report BIN/pitmap-report --source SOURCE_DIR
                              --glb-fixture BIN/pitmap-test-glb-fixture --work DIR"""

import argparse
import base64
import json
import os
import re
import shutil
import struct
import subprocess
import sys

import numpy as np

STATIONS = 200
HEIGHT_TOLERANCE_M = 1e-3  # float32 coordinates of a ~30 m scene: about 4e-6 m of rounding


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def ViewerData(page_path):
    """The page's #viewer-data: ENU mesh vertices, triangles and soundings (numpy)."""
    with open(page_path, encoding="utf-8") as f:
        page = f.read()
    m = re.search(r'<script type="application/json" id="viewer-data">(.*?)</script>', page, re.S)
    data = json.loads(m.group(1).replace("<\\/", "</"))
    centre = np.array(data["centre_enu_m"])
    v = np.frombuffer(base64.b64decode(data["mesh"]["positions"]), "<f4").reshape(-1, 3)
    t = np.frombuffer(base64.b64decode(data["mesh"]["indices"]), "<u4").reshape(-1, 3)
    p = np.frombuffer(base64.b64decode(data["points"]), "<f4").reshape(-1, 3)
    return v.astype(np.float64) + centre, t.astype(np.int64), p.astype(np.float64) + centre


def HeightsUnder(vertices, triangles, xy):
    """Height of the mesh at each (x, y), by the barycentric coordinates of the triangle
    containing it (NaN outside the mesh); the mesh is a height field here."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    out = np.full(len(xy), np.nan)
    for i, (x, y) in enumerate(xy):
        det = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
        ok = np.abs(det) > 1e-12
        l1 = ((b[:, 1] - c[:, 1]) * (x - c[:, 0]) + (c[:, 0] - b[:, 0]) * (y - c[:, 1])) / np.where(ok, det, 1)
        l2 = ((c[:, 1] - a[:, 1]) * (x - c[:, 0]) + (a[:, 0] - c[:, 0]) * (y - c[:, 1])) / np.where(ok, det, 1)
        l3 = 1 - l1 - l2
        inside = ok & (l1 >= -1e-9) & (l2 >= -1e-9) & (l3 >= -1e-9)
        if inside.any():
            k = np.argmax(inside)
            out[i] = l1[k] * a[k, 2] + l2[k] * b[k, 2] + l3[k] * c[k, 2]
    return out


def CheckProfile(profile, vertices, triangles, points, label):
    """The page's profile against the heights computed here along the same line."""
    seg = np.array(profile["segments"], dtype=np.float64).reshape(-1, 4)
    if len(seg) == 0:
        fail("%s: the profile has no mesh segment: %s" % (label, profile))
    a, b = np.array(profile["a"][:2]), np.array(profile["b"][:2])
    length = np.hypot(*(b - a))
    if abs(length - profile["length"]) > 1e-6 * max(1, length):
        fail("%s: length %.6f, expected %.6f" % (label, profile["length"], length))
    u = (b - a) / length
    s = np.linspace(0, length, STATIONS + 2)[1:-1]
    expected = HeightsUnder(vertices, triangles, a[None, :] + s[:, None] * u[None, :])
    worst, checked = 0.0, 0
    for si, ze in zip(s, expected):
        lo, hi = np.minimum(seg[:, 0], seg[:, 2]), np.maximum(seg[:, 0], seg[:, 2])
        cover = (lo <= si + 1e-9) & (hi >= si - 1e-9) & (hi - lo > 1e-9)
        if np.isnan(ze):
            continue
        if not cover.any():
            fail("%s: no profile segment at s = %.3f m where the mesh is at z = %.3f m"
                 % (label, si, ze))
        f = (si - seg[cover, 0]) / (seg[cover, 2] - seg[cover, 0])
        zs = seg[cover, 1] + f * (seg[cover, 3] - seg[cover, 1])
        err = np.min(np.abs(zs - ze))
        worst = max(worst, err)
        checked += 1
        if err > HEIGHT_TOLERANCE_M:
            fail("%s: at s = %.3f m the profile says z = %s m, the mesh is at %.4f m"
                 % (label, si, np.round(zs, 4).tolist(), ze))
    if checked < STATIONS // 4:
        fail("%s: only %d of %d stations over the mesh" % (label, checked, STATIONS))
    d = (points[:, 0] - a[0]) * -u[1] + (points[:, 1] - a[1]) * u[0]
    sp = (points[:, 0] - a[0]) * u[0] + (points[:, 1] - a[1]) * u[1]
    n_corridor = int(np.sum((np.abs(d) <= profile["corridor"]) & (sp >= 0) & (sp <= length)))
    if abs(n_corridor - profile["points"]) > 2:  # float32 ties at the corridor's edge
        fail("%s: %d soundings in the corridor, expected %d" % (label, profile["points"],
                                                               n_corridor))
    print("%s: %.2f m, %d segments, %d stations over the mesh within %.1e m (worst %.1e m), "
          "%d soundings in the corridor" % (label, length, len(seg), checked,
                                             HEIGHT_TOLERANCE_M, worst, profile["points"]))


def WaitFor(browser, expression, what, tries=300):
    value = None
    for _ in range(tries):
        browser.pump(0.1)
        try:
            text = browser.evaluate("JSON.stringify(%s)" % expression)
        except RuntimeError:
            continue
        value = json.loads(text) if text is not None else None
        if value:
            return value
    fail("%s: %r; errors: %s" % (what, value, browser.errors()))


def Click(browser, fx, fy):
    rect = browser.evaluate("(() => { const b = document.querySelector('#viewer3d canvas')"
                            ".getBoundingClientRect(); return {x: b.x, y: b.y, "
                            "width: b.width, height: b.height}; })()")
    x, y = rect["x"] + rect["width"] * fx, rect["y"] + rect["height"] * fy
    for kind in ("mousePressed", "mouseReleased"):
        browser.call("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y,
                                                  "button": "left", "clickCount": 1})
    browser.pump(0.2)


def PressButton(browser, prefix):
    browser.evaluate("[...document.querySelectorAll('#viewer3d-bar button')]"
                     ".find(b => b.textContent.startsWith(%s)).click()" % json.dumps(prefix))


def Screenshot(browser, selector, background):
    import cdp  # noqa: E402
    rect = browser.evaluate("(() => { const e = document.querySelector(%s); e.scrollIntoView(); "
                            "const b = e.getBoundingClientRect(); return {x: b.x + scrollX, "
                            "y: b.y + scrollY, width: b.width, height: b.height}; })()"
                            % json.dumps(selector))
    browser.pump(0.5)
    return cdp.pixel_stats(browser.screenshot(rect), background=background)


def OpenFile(browser, path):
    """Chooses `path` in the page's "open glTF..." file input (fires its change event)."""
    root = browser.call("DOM.getDocument", {"depth": 0})["root"]["nodeId"]
    node = browser.call("DOM.querySelector", {"nodeId": root,
                                              "selector": "#viewer3d-open-gltf"})["nodeId"]
    browser.call("DOM.setFileInputFiles", {"nodeId": node, "files": [os.path.abspath(path)]})


def CheckNoErrors(browser, where):
    errs = browser.errors()
    if errs:
        fail("%s: console errors: %s" % (where, errs))


def CheckEquipment(browser, vertices, triangles, fixture):
    """The equipment model stands at its position: its box centred on it, its foot on the mesh."""
    placed = WaitFor(browser, "window.pitmapViewer.equipment.length === 1 && "
                     "window.pitmapViewer.equipment[0].status !== 'loading' && "
                     "window.pitmapViewer.equipment[0]", "the equipment model was not placed")
    print("equipment: %s" % json.dumps(placed))
    if placed["status"] != "placed":
        fail("the equipment model was not placed: %s" % placed["message"])
    want = fixture["equipment_world"]
    cx, cy, cz = placed["centre"]
    if abs(cx - want[0]) > 0.01 or abs(cy - want[1]) > 0.01:
        fail("equipment centred at (%.3f, %.3f), asked for (%.3f, %.3f)" % (cx, cy, want[0], want[1]))
    ground = HeightsUnder(vertices, triangles, np.array([[want[0], want[1]]]))[0]
    half = fixture["equipment_half_height"]
    if not np.isfinite(ground) or abs(cz - half - ground) > 0.05:
        fail("equipment's foot at %.3f m, the mesh under it at %.3f m" % (cz - half, ground))


def CheckReport(browser, page, fixture):
    browser.open("file://" + os.path.abspath(page))
    state = WaitFor(browser, "window.pitmapViewer && window.pitmapViewer.frames >= 3 && "
                    "window.pitmapViewer", "the report's 3D view did not render")
    print("report 3D view: %d triangles, %d soundings" % (state["triangles"], state["points"]))
    vertices, triangles, points = ViewerData(page)
    CheckEquipment(browser, vertices, triangles, fixture)

    # "Enter VR": r111's VRButton says so when the browser has no immersive VR.
    vr = WaitFor(browser, "(() => { const b = document.getElementById('viewer3d-vr'); "
                 "return b && b.style.display !== 'none' && b.textContent; })()",
                 "no VR button, or it never settled")
    print("VR button: %r" % vr)
    if vr not in ("VR NOT FOUND", "WEBXR NOT SUPPORTED"):
        fail("headless Chromium has no VR headset, but the VR button says %r" % vr)

    # The cross-section tool by two clicks on the pit.
    browser.evaluate("document.getElementById('viewer3d').scrollIntoView()")
    PressButton(browser, "cross-section")
    for fx in (0.42, 0.58):
        Click(browser, fx, 0.5)
    text = browser.evaluate("document.getElementById('viewer3d-info').textContent")
    print("cross-section tool: %r" % text)
    if not text.startswith("cross-section "):
        fail("the cross-section tool made no profile: %r" % text)
    profile = json.loads(browser.evaluate("JSON.stringify(window.pitmapViewer.profile)"))
    CheckProfile(profile, vertices, triangles, points, "clicked profile")
    share, colours = Screenshot(browser, "#viewer3d-profile-canvas", (255, 255, 255))
    print("profile plot: %.1f %% drawn, %d colours" % (100 * share, colours))
    if share < 0.01 or colours < 4:
        fail("the profile plot is blank (%.2f %% drawn, %d colours)" % (100 * share, colours))
    # A wider corridor (the input's change event) redraws the same profile.
    browser.evaluate("(() => { const c = document.getElementById('viewer3d-corridor'); "
                     "c.value = '1.0'; c.dispatchEvent(new Event('change')); })()")
    wider = json.loads(browser.evaluate("JSON.stringify(window.pitmapViewer.profile)"))
    if wider["corridor"] != 1.0 or wider["a"] != profile["a"] or wider["points"] <= profile["points"]:
        fail("the corridor input did not redraw the profile: %s" % {
            k: wider[k] for k in ("a", "corridor", "points")})
    CheckProfile(wider, vertices, triangles, points, "clicked profile, corridor 1 m")
    # A known oblique line across the bowl and its bench, with a wider corridor.
    browser.evaluate("document.getElementById('viewer3d-corridor').value = '1.5'")
    known = json.loads(browser.evaluate(
        "JSON.stringify(window.pitmapViewer.crossSection([-14, -3], [13, 5]))"))
    if known["corridor"] != 1.5:
        fail("the corridor input was not used: %s" % known["corridor"])
    CheckProfile(known, vertices, triangles, points, "known line (-14, -3) -> (13, 5)")
    CheckNoErrors(browser, "report.html")

    # "open glTF...": the pipeline's .glb, then broken ones.
    OpenFile(browser, fixture["glb"])
    g = WaitFor(browser, "window.pitmapViewer.gltf && window.pitmapViewer.gltf.status !== "
                "'loading' && window.pitmapViewer.gltf", "open glTF did not finish")
    print("open glTF (report.html): %s" % g)
    if g["status"] != "loaded" or g["triangles"] != fixture["triangles"]:
        fail("mesh.glb did not load into report.html with %d triangles: %s"
             % (fixture["triangles"], g))
    for path, words in ((fixture["truncated"], "truncated"), (fixture["damaged"], "cannot read")):
        OpenFile(browser, path)
        g = WaitFor(browser, "window.pitmapViewer.gltf && window.pitmapViewer.gltf.name === %s "
                    "&& window.pitmapViewer.gltf.status !== 'loading' && window.pitmapViewer.gltf"
                    % json.dumps(os.path.basename(path)), "open glTF did not finish")
        shown = browser.evaluate("(() => { const p = document.getElementById('viewer3d-problem');"
                                 " return p.hidden ? '' : p.textContent; })()")
        print("open glTF %s: %r" % (os.path.basename(path), shown))
        if g["status"] != "error" or words not in shown:
            fail("%s: expected a message with %r in the page, got %r (%s)"
                 % (path, words, shown, g))
    CheckGltfMutations(browser)
    # Drawn on demand: the animation loop still turns after the broken files, the view is not
    # redrawn while nothing happens, and an input draws it again.
    def Viewer():
        return json.loads(browser.evaluate("JSON.stringify(window.pitmapViewer)"))
    browser.pump(0.6)  # past the 300 ms an input keeps drawing
    state = Viewer()
    browser.pump(0.5)
    idle = Viewer()
    if idle["ticks"] <= state["ticks"]:
        fail("the view's animation loop stopped after the broken files")
    if idle["frames"] != state["frames"]:
        fail("the view was redrawn %d times in 0.5 s with nothing happening"
             % (idle["frames"] - state["frames"]))
    browser.evaluate("window.dispatchEvent(new Event('resize'))")
    browser.pump(0.3)
    if Viewer()["frames"] <= idle["frames"]:
        fail("the view was not redrawn after an input (resize)")
    print("drawn on demand: %d loop turns and no redraw in 0.5 s idle, redrawn after a resize"
          % (idle["ticks"] - state["ticks"]))
    CheckNoErrors(browser, "report.html with glTF files")


def SmallGlb():
    """A valid glTF 2.0 binary of a tetrahedron: positions, colours, uint32 indices."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype="<f4")
    col = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], dtype="<f4")
    idx = np.array([0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3], dtype="<u4")
    binary = pos.tobytes() + col.tobytes() + idx.tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1},
                                       "indices": 2, "mode": 4}]}],
           "buffers": [{"byteLength": len(binary)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                           {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                           {"buffer": 0, "byteOffset": 96, "byteLength": 48}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 1]},
                         {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                         {"bufferView": 2, "componentType": 5125, "count": 12,
                          "type": "SCALAR"}]}
    text = json.dumps(doc).encode()
    text += b" " * ((4 - len(text) % 4) % 4)
    body = (struct.pack("<II", len(text), 0x4E4F534A) + text +
            struct.pack("<II", len(binary), 0x004E4942) + binary)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


# In the page: 300 mutations of a .glb (seeded), each opened as "open glTF..." opens a file,
# with 5 s to finish; returns how many loaded, failed with a message, or never finished.
MUTATE_JS = """(async () => {
  const src = Uint8Array.from(atob(%s), c => c.charCodeAt(0));
  let seed = 12345;
  const rand = (n) => { seed = (seed * 1103515245 + 12345) %% 2147483648; return seed %% n; };
  const tally = { loaded: 0, error: 0, hung: 0, silent: 0, original: "" };
  tally.original = (await window.pitmapViewer.openGltf(src.slice().buffer, "original.glb")).status;
  for (let i = 0; i < 300; ++i) {
    let b = src.slice();
    const kind = i %% 3;
    if (kind === 0) b = b.slice(0, rand(b.length));
    else if (kind === 1) for (let k = 0; k <= rand(4); ++k) b[rand(b.length)] ^= 1 + rand(255);
    else new DataView(b.buffer).setUint32(4 * rand(b.length >> 2), rand(2147483647) * 2, true);
    const timeout = new Promise(r => setTimeout(() => r(null), 5000));
    const g = await Promise.race([window.pitmapViewer.openGltf(b.buffer, "m" + i + ".glb"), timeout]);
    if (g === null) tally.hung += 1;
    else if (g.status === "loaded") tally.loaded += 1;
    else if (g.status === "error" && !document.getElementById("viewer3d-problem").hidden &&
             g.message) tally.error += 1;
    else tally.silent += 1;
  }
  return tally;
})()"""


def CheckGltfMutations(browser):
    glb = SmallGlb()
    tally = browser.call("Runtime.evaluate", {
        "expression": MUTATE_JS % json.dumps(base64.b64encode(glb).decode()),
        "returnByValue": True, "awaitPromise": True}, timeout=120)["result"]["value"]
    print("300 mutated .glb files: %s" % tally)
    if tally["original"] != "loaded":
        fail("the small valid .glb did not load: %s" % tally)
    if tally["hung"] or tally["silent"] or tally["error"] < 150:
        fail("mutated .glb files: some never finished or failed without a message: %s" % tally)


def CheckGltfPage(browser, page, fixture):
    browser.open("file://" + os.path.abspath(page))
    g = WaitFor(browser, "window.pitmapViewer && window.pitmapViewer.frames >= 3 && "
                "window.pitmapViewer.gltf && window.pitmapViewer.gltf.status !== 'loading' && "
                "window.pitmapViewer.gltf", "the glTF page did not render")
    print("glTF page: %s" % g)
    if g["status"] != "loaded" or g["triangles"] != fixture["triangles"]:
        fail("the glTF page did not show %d triangles: %s" % (fixture["triangles"], g))
    browser.pump(0.5)
    share, colours = Screenshot(browser, "#viewer3d", (0x15, 0x19, 0x1d))
    print("glTF page canvas: %.1f %% drawn, %d colours" % (100 * share, colours))
    if share < 0.03 or colours < 16:
        fail("the glTF page is blank (%.2f %% drawn, %d colours)" % (100 * share, colours))
    # The mound of the fixture (a sphere of radius 2.5 m at (0, 0, -11) on a floor at -12 m):
    # a profile across its top rises above the floor.
    p = json.loads(browser.evaluate(
        "JSON.stringify(window.pitmapViewer.crossSection([-5, 0], [5, 0]))"))
    z = np.array(p["segments"]).reshape(-1, 4)[:, [1, 3]] if p["segments"] else np.zeros((0, 2))
    print("glTF page profile: %d segments, z %.2f .. %.2f m" % (len(z), z.min(), z.max())
          if len(z) else "glTF page profile: empty")
    if len(z) == 0 or not (-12.3 < z.min() < -11.7) or not (-9.0 < z.max() < -8.0):
        fail("the profile across the glTF mound does not show a floor at -12 m and a top at "
             "-8.5 m: %s" % p)
    CheckNoErrors(browser, "the glTF page")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--glb-fixture", required=True)
    ap.add_argument("--work", required=True)
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.source, "tools", "browser"))
    sys.path.insert(0, os.path.join(args.source, "tests", "tools", "report"))
    import cdp  # noqa: E402
    import report_test  # noqa: E402  (writes the synthetic products)

    shutil.rmtree(args.work, ignore_errors=True)
    products = os.path.join(args.work, "products")
    os.makedirs(products)
    report_test.WriteProducts(products, full=True)
    glb_dir = os.path.join(args.work, "glb")
    os.makedirs(glb_dir)
    r = subprocess.run([args.glb_fixture, glb_dir], capture_output=True, text=True)
    if r.returncode != 0:
        fail("pitmap-test-glb-fixture failed: " + r.stderr)
    fixture = json.loads(r.stdout)
    fixture["glb"] = os.path.join(glb_dir, "mesh.glb")
    with open(fixture["glb"], "rb") as f:
        glb = f.read()
    fixture["truncated"] = os.path.join(glb_dir, "truncated.glb")
    with open(fixture["truncated"], "wb") as f:
        f.write(glb[:len(glb) * 6 // 10])
    # The same truncation with the header's length patched to match: only GLTFLoader notices.
    fixture["damaged"] = os.path.join(glb_dir, "damaged.glb")
    cut = bytearray(glb[:len(glb) * 6 // 10 // 4 * 4])
    struct.pack_into("<I", cut, 8, len(cut))
    with open(fixture["damaged"], "wb") as f:
        f.write(cut)
    print("mesh.glb: %d bytes, %d vertices, %d triangles" % (len(glb), fixture["vertices"],
                                                             fixture["triangles"]))
    # The report, with the fixture's mesh as an equipment model at a UTM position on the pit.
    equipment, fixture["equipment_world"], fixture["equipment_half_height"] = \
        report_test.WriteEquipment(args.work, products, world_xy=(3.0, -2.0))
    r = subprocess.run(["/usr/bin/python3", args.report, products, "--equipment", equipment],
                       capture_output=True, text=True)
    if r.returncode != 0:
        fail("pitmap-report failed: " + r.stderr[-2000:])
    view = os.path.join(args.work, "view.html")
    r = subprocess.run(["/usr/bin/python3", args.report, "--view-gltf", fixture["glb"], "-o", view],
                       capture_output=True, text=True)
    if r.returncode != 0:
        fail("pitmap-report --view-gltf failed: " + r.stderr[-2000:])
    print("view.html: %.1f MB" % (os.path.getsize(view) / 1e6))

    try:
        browser = cdp.Browser(os.path.join(args.work, "profile"))
    except cdp.BrowserUnavailable as e:
        print("SKIP: %s" % e)
        sys.exit(cdp.SKIP)
    try:
        CheckReport(browser, os.path.join(products, "report.html"), fixture)
        CheckGltfPage(browser, view, fixture)
        print("PASS")
    finally:
        browser.close()


if __name__ == "__main__":
    main()
