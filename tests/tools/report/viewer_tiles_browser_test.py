#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The 3D viewer's mesh tiles loaded by view (tools/report/viewer3d_tiles.js) in headless
Chromium (tools/browser/cdp.py): report.html of the synthetic products (report_test) with
P/tiles/mesh/ holding 24 x 24 tiles of 10 m (glTF binaries written here, y-up as pitmap's), the
folder served over HTTP on 127.0.0.1 by a server in this process that logs every request.

A scripted camera: low over the south-west corner looking north-east, then over the north-east
corner looking south-west, then 300 m above the pit. After each move, once the page has no
request in flight, the tiles are checked against the rule of viewer3d_tiles.js computed here
independently (numpy, from the page's view-projection matrix: a box is outside the frustum when
its eight corners are all outside one clip plane; the distance from the eye to the box):
- every tile that is clearly wanted (its box grown by s/4 in the frustum and within the near
  distance, with 1 cm to spare) is loaded; no tile that is clearly not wanted was requested;
- every tile that the rule unloads (box grown by s out of the frustum, or beyond twice the near
  distance) is no longer loaded: the first corner's tiles after the move to the second, all of
  them from 300 m (where every tile is in the frustum but too far);
- the server saw exactly the tiles the page requested (no other), the loaded triangles
  are the index's, and the page logged no error.
Exit 77 (ctest skip) only when Chromium cannot start here.

Usage: viewer_tiles_browser_test.py --report BIN/pitmap-report --source SOURCE_DIR --work DIR"""

import argparse
import functools
import http.server
import json
import os
import shutil
import struct
import subprocess
import sys
import threading

import numpy as np

TILES = 24          # per side
TILE_M = 10.0       # tile edge, m
QUADS = 4           # quads per tile edge
X0 = -120.0         # south-west corner of the tiled area, local ENU m
SLACK_M = 0.01      # margin of the "clearly" sets against float ties


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def Surface(x, y):
    return -10.0 + 0.5 * np.sin(x / 7.0) * np.cos(y / 5.0)


def TileGlb(i, j):
    """Tile (i, j): a height field of QUADS x QUADS quads, glTF y-up (E, U, -N), no colours
    (the viewer colours it by depth). Returns the bytes, its z range and triangle count."""
    xs = X0 + TILE_M * (i + np.linspace(0, 1, QUADS + 1))
    ys = X0 + TILE_M * (j + np.linspace(0, 1, QUADS + 1))
    gx, gy = np.meshgrid(xs, ys)
    gz = Surface(gx, gy)
    pos = np.stack([gx.ravel(), gz.ravel(), -gy.ravel()], axis=1).astype("<f4")
    n = QUADS + 1
    tri = []
    for b in range(QUADS):
        for a in range(QUADS):
            k = b * n + a
            tri += [k, k + 1, k + n, k + 1, k + n + 1, k + n]
    idx = np.array(tri, dtype="<u4")
    binary = pos.tobytes() + idx.tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                       "mode": 4}]}],
           "buffers": [{"byteLength": len(binary)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
                           {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": idx.nbytes}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos),
                          "type": "VEC3", "min": pos.min(axis=0).tolist(),
                          "max": pos.max(axis=0).tolist()},
                         {"bufferView": 1, "componentType": 5125, "count": len(idx),
                          "type": "SCALAR"}]}
    text = json.dumps(doc).encode()
    text += b" " * ((4 - len(text) % 4) % 4)
    body = (struct.pack("<II", len(text), 0x4E4F534A) + text +
            struct.pack("<II", len(binary), 0x004E4942) + binary)
    glb = struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body
    return glb, (float(gz.min()), float(gz.max())), len(idx) // 3


def WriteTiles(products):
    """P/tiles/mesh/mesh_I_J.glb and index.json as pitmap's WriteMeshIndex writes them."""
    folder = os.path.join(products, "tiles", "mesh")
    os.makedirs(folder, exist_ok=True)
    entries = []
    for j in range(TILES):
        for i in range(TILES):
            glb, (z0, z1), triangles = TileGlb(i, j)
            name = "mesh_%d_%d.glb" % (i, j)
            with open(os.path.join(folder, name), "wb") as f:
                f.write(glb)
            entries.append({"i": i, "j": j, "file": name,
                            "min_m": [X0 + TILE_M * i, X0 + TILE_M * j, z0],
                            "max_m": [X0 + TILE_M * (i + 1), X0 + TILE_M * (j + 1), z1],
                            "vertices": (QUADS + 1) ** 2, "triangles": triangles})
    index = {"format": "pitmap mesh tiles 1", "frame": "local ENU at the origin, metres",
             "voxel_size_m": 0.1, "tile_size_m": TILE_M, "tiles": entries}
    with open(os.path.join(folder, "index.json"), "w") as f:
        json.dump(index, f)
    return {e["file"]: e for e in entries}


class Server:
    """The products folder over HTTP on 127.0.0.1 (a free port), every GET path logged."""

    def __init__(self, folder):
        self.paths = []
        log = self.paths

        class Handler(http.server.SimpleHTTPRequestHandler):
            def do_GET(self):
                log.append(self.path)
                super().do_GET()

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(
            ("127.0.0.1", 0), functools.partial(Handler, directory=folder))
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()
        self.url = "http://127.0.0.1:%d/" % self.httpd.server_address[1]

    def tile_requests(self):
        return [os.path.basename(p) for p in self.paths
                if p.startswith("/tiles/mesh/") and p.endswith(".glb")]

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


def Evaluate(browser, expression):
    text = browser.evaluate("JSON.stringify(%s)" % expression)
    return json.loads(text) if text is not None else None


def Settle(browser, what):
    """Waits until the page has evaluated the rule on the current camera with nothing in
    flight for a few animation frames; returns window.pitmapViewer.tiles."""
    quiet = 0
    for _ in range(600):
        browser.pump(0.05)
        st = Evaluate(browser, "window.pitmapViewer && window.pitmapViewer.tiles")
        if st and st["status"] == "ready" and st["fetching"] == 0:
            quiet += 1
            if quiet >= 6:
                return st
        else:
            quiet = 0
    fail("%s: the tiles did not settle: %s; errors: %s" % (what, st, browser.errors()))


def Rule(view, boxes, tile_m):
    """Per tile: (distance from the eye, in the frustum with margin m?) for the rule."""
    vp = np.array(view["viewProjection"]).reshape(4, 4).T  # three.js is column-major
    eye = np.array(view["eye"])
    centre = np.array(view["centre"])
    out = {}
    for name, (lo, hi) in boxes.items():
        lo, hi = lo - centre, hi - centre  # the view's coordinates
        d = float(np.linalg.norm(eye - np.clip(eye, lo, hi)))

        def inside(margin):
            a, b = lo - margin, hi + margin
            corners = np.array([[x, y, z, 1.0] for x in (a[0], b[0]) for y in (a[1], b[1])
                                for z in (a[2], b[2])])
            c = corners @ vp.T
            x, y, z, w = c[:, 0], c[:, 1], c[:, 2], c[:, 3]
            for plane in (x + w, w - x, y + w, w - y, z + w, w - z):
                if np.all(plane < 0):
                    return False
            return True
        out[name] = (d, inside)
    return out


def CheckView(browser, server, label, position, target, boxes, tile_m, before):
    """Moves the camera, waits, checks the rule; returns the page's tile state."""
    requested_before = len(before["requests"])
    browser.evaluate("window.pitmapViewer.setCamera(%s, %s)" % (json.dumps(position),
                                                               json.dumps(target)))
    st = Settle(browser, label)
    view = Evaluate(browser, "window.pitmapViewer.tiles.view()")
    near = view["near"]
    rule = Rule(view, boxes, tile_m)
    clearly = {n for n, (d, inside) in rule.items()
               if d <= near - SLACK_M and inside(tile_m / 4 - SLACK_M)}
    maybe = {n for n, (d, inside) in rule.items()
             if d <= near + SLACK_M and inside(tile_m / 4 + SLACK_M)}
    unloaded = {n for n, (d, inside) in rule.items()
                if d > 2 * near + SLACK_M or not inside(tile_m + SLACK_M)}
    loaded = set(st["loaded"])
    new_requests = st["requests"][requested_before:]
    print("%s: eye %s, near %.1f m: %d tiles clearly wanted, %d loaded, %d requested by this "
          "move, %d unloads so far" % (label, np.round(view["eye"], 1).tolist(), near,
                                       len(clearly), len(loaded), len(new_requests),
                                       st["unloads"]))
    if not clearly <= loaded:
        fail("%s: tiles in view and near not loaded: %s" % (label, sorted(clearly - loaded)))
    stray = [n for n in new_requests if n not in maybe]
    if stray:
        fail("%s: tiles requested that are out of view or too far: %s" % (label, stray))
    if loaded & unloaded:
        fail("%s: tiles the rule unloads are still loaded: %s" % (label, sorted(loaded & unloaded)))
    # (A tile loaded again after an unload may come from the browser's cache.)
    seen, asked = set(server.tile_requests()), set(st["requests"])
    if seen != asked:
        fail("%s: the server saw tiles the page did not ask for: %s, or missed some: %s"
             % (label, sorted(seen - asked), sorted(asked - seen)))
    triangles = sum(boxes_triangles[n] for n in loaded)
    if st["triangles"] != triangles:
        fail("%s: %d triangles loaded, the index says %d for %s" % (label, st["triangles"],
                                                                     triangles, sorted(loaded)))
    errors = browser.errors()
    if errors:
        fail("%s: errors in the page: %s" % (label, errors))
    return st, clearly, unloaded


boxes_triangles = {}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", required=True)
    ap.add_argument("--source", required=True)
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
    entries = WriteTiles(products)
    boxes = {n: (np.array(e["min_m"]), np.array(e["max_m"])) for n, e in entries.items()}
    boxes_triangles.update({n: e["triangles"] for n, e in entries.items()})
    r = subprocess.run(["/usr/bin/python3", args.report, products], capture_output=True,
                       text=True)
    if r.returncode != 0:
        fail("pitmap-report failed: " + r.stderr[-2000:])
    with open(os.path.join(products, "report.html"), encoding="utf-8") as f:
        if '"mesh_tiles"' not in f.read():
            fail("report.html does not name the mesh tiles")

    try:
        browser = cdp.Browser(os.path.join(args.work, "profile"))
    except cdp.BrowserUnavailable as e:
        print("SKIP: %s" % e)
        sys.exit(cdp.SKIP)
    server = Server(products)
    try:
        # From a file the page does not try to read the tiles, and says how to serve them.
        browser.open("file://" + os.path.abspath(os.path.join(products, "report.html")))
        st = None
        for _ in range(300):
            browser.pump(0.1)
            st = Evaluate(browser, "window.pitmapViewer && window.pitmapViewer.frames >= 3 && "
                          "window.pitmapViewer.tiles")
            if st:
                break
        if not st or st["status"] != "file" or st["requests"]:
            fail("report.html from a file: %s" % st)
        print("from a file: %s" % st["message"])

        browser.open(server.url + "report.html")
        st = Settle(browser, "the served page")
        if st["count"] != TILES * TILES:
            fail("the page read %d tiles from the index, expected %d" % (st["count"],
                                                                         TILES * TILES))
        print("served: %d tiles in the index; the opening view loaded %d" % (st["count"],
                                                                            len(st["loaded"])))
        sw, sw_clearly, _ = CheckView(browser, server, "south-west corner", [-126, -126, -6],
                                      [-110, -110, -10], boxes, TILE_M, st)
        if not sw_clearly or len(sw_clearly) >= TILES * TILES // 2:
            fail("the south-west view should want some tiles, not half: %d" % len(sw_clearly))
        ne, ne_clearly, ne_unloaded = CheckView(browser, server, "north-east corner",
                                                [126, 126, -6], [110, 110, -10], boxes, TILE_M, sw)
        gone = sw_clearly & ne_unloaded
        if not gone or set(ne["loaded"]) & gone:
            fail("the south-west tiles were not unloaded after the move: %s" % sorted(gone))
        if not (ne_clearly - sw_clearly):
            fail("the move to the north-east loaded no new tile")
        high, high_clearly, high_unloaded = CheckView(browser, server, "300 m above",
                                                      [0, -1, 290], [0, 0, -10], boxes, TILE_M,
                                                      ne)
        if high["loaded"] or len(high_unloaded) != TILES * TILES or \
                len(high["requests"]) != len(ne["requests"]):
            fail("from 300 m every tile is too far: loaded %s, requests %d -> %d"
                 % (high["loaded"], len(ne["requests"]), len(high["requests"])))
        print("PASS")
    finally:
        server.close()
        browser.close()


if __name__ == "__main__":
    main()
