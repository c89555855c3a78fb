# SPDX-License-Identifier: MIT
"""The report's interactive 3D view: a decimated mesh, the trajectories and a subset of the
soundings for viewer3d.js, with three.js from Debian's libjs-three inlined (no network)."""

import json
import os

import numpy as np

from .loaders import PlyError
from .rasters import decimate_mesh, subsample
from .util import b64, esc, inline_script, num, PROGRAM_DIR

# The interactive 3D view: three.js from Debian's libjs-three, inlined into report.html with
# viewer3d.js and viewer3d_profile.js (installed beside this script as pitmap-report-viewer3d.js
# and pitmap-report-viewer3d-profile.js).
THREE_DIR = os.environ.get("PITMAP_THREE_DIR", "/usr/share/javascript/three")
VIEWER_MAX_TRIANGLES = 250_000  # what a laptop's integrated GPU turns smoothly
VIEWER_MAX_POINTS = 150_000
VIEWER_MAX_TRAJECTORY = 5_000


def viewer_script_files():
    """The JavaScript files of the viewer, in page order: three.js r111 and its OrbitControls,
    VRButton and GLTFLoader (libjs-three), then the profile maths and the viewer (ours)."""
    ours = []
    for installed, source in (("pitmap-report-viewer3d-profile.js", "viewer3d_profile.js"),
                              ("pitmap-report-viewer3d-tiles.js", "viewer3d_tiles.js"),
                              ("pitmap-report-viewer3d.js", "viewer3d.js")):
        path = os.path.join(PROGRAM_DIR, installed)
        ours.append(path if os.path.isfile(path) else os.path.join(PROGRAM_DIR, source))
    examples = os.path.join(THREE_DIR, "examples", "js")
    return [os.path.join(THREE_DIR, "three.min.js"),
            os.path.join(examples, "controls", "OrbitControls.js"),
            os.path.join(examples, "webxr", "VRButton.js"),
            os.path.join(examples, "loaders", "GLTFLoader.js")] + ours


def missing_viewer_files():
    return [f for f in viewer_script_files() if not os.path.isfile(f)]


def viewer_html(data, caption):
    """The viewer's HTML: caption, WebGL view, control bar, messages, the cross-section panel,
    the data as JSON and every script inlined. data: what viewer3d.js reads (#viewer-data)."""
    scripts = []
    for f in viewer_script_files():
        with open(f, encoding="utf-8") as fh:
            scripts.append(f"<script>{inline_script(fh.read())}</script>")
    blob = json.dumps(data).replace("</", "<\\/")
    return (f'<p class="caption">{caption}</p>\n'
            '<div id="viewer3d"></div><div id="viewer3d-bar"></div>'
            '<div id="viewer3d-info" class="caption"></div>\n'
            '<p id="viewer3d-problem" class="viewer-problem" hidden></p>\n'
            '<div id="viewer3d-profile" hidden>'
            '<div id="viewer3d-profile-caption" class="caption"></div>'
            '<label>corridor &plusmn; <input type="number" id="viewer3d-corridor" value="0.5" '
            'min="0" step="0.1"> m</label> '
            '<label><input type="checkbox" id="viewer3d-truescale"> true scale (1:1)</label>'
            '<canvas id="viewer3d-profile-canvas"></canvas>'
            '<div id="viewer3d-profile-readout" class="caption"></div></div>\n'
            f'<script type="application/json" id="viewer-data">{blob}</script>\n'
            + "\n".join(scripts))


MESH_TILE_INDEX = "tiles/mesh/index.json"  # relative to the products folder (report.html)


def mesh_tiles(folder):
    """How many tiles P/tiles/mesh/index.json lists (0: none, or not a tile index)."""
    try:
        with open(os.path.join(folder, MESH_TILE_INDEX), encoding="utf-8") as f:
            index = json.load(f)
    except (OSError, ValueError):
        return 0
    tiles = index.get("tiles") if isinstance(index, dict) else None
    return len(tiles) if isinstance(tiles, list) else 0


def viewer(p):
    """The interactive WebGL view: decimated mesh, trajectories before and after SLAM, a
    subset of the soundings, coloured by depth; three.js inlined (no network)."""
    absent = missing_viewer_files()
    if absent:
        return p.missing_product("3D view", "not found: " + ", ".join(absent) +
                                 " (Debian's libjs-three: tools/install-deps.sh)")
    mesh = None
    for name in ("mesh_filled.ply", "mesh.ply"):
        try:
            m = p.load_mesh(name)
        except (OSError, PlyError) as e:
            p.problems.append(f"3D view: {e}")
            continue
        if m is not None and len(m[1]):
            mesh = m
            break
    pts = p.points.get("final") if "final" in p.points else p.points.get("initial")
    if mesh is None and pts is None:
        return p.missing_product("3D view", "no mesh and no soundings")
    parts = []
    if mesh is not None:
        parts.append(mesh[0])
    if pts is not None:
        idx = subsample(len(pts), min(len(pts), 20000))
        parts.append(np.stack([np.asarray(pts[c][idx], dtype=np.float64)
                               for c in ("x", "y", "z")], axis=1))
    allp = np.concatenate(parts)
    lo, hi = np.percentile(allp, 0.5, axis=0), np.percentile(allp, 99.5, axis=0)
    centre = (lo + hi) / 2.0
    radius = float(max(1.0, np.max(hi - lo) / 2.0))
    zlim = [float(lo[2] - centre[2]), float(hi[2] - centre[2])]
    data = {"centre_enu_m": centre.tolist(), "radius": radius, "zlim": zlim}
    facts = []
    if mesh is not None:
        v, t = decimate_mesh(mesh[0], mesh[1], VIEWER_MAX_TRIANGLES)
        data["mesh"] = {"positions": b64((v - centre).astype("<f4")),
                        "indices": b64(np.asarray(t, dtype="<u4"))}
        facts.append(f"mesh {num(len(t))} of {num(len(mesh[1]))} triangles")
    if pts is not None:
        idx = subsample(len(pts), min(len(pts), VIEWER_MAX_POINTS))
        xyz = np.stack([np.asarray(pts[c][idx], dtype=np.float64) for c in ("x", "y", "z")],
                       axis=1)
        data["points"] = b64((xyz - centre).astype("<f4"))
        facts.append(f"{num(len(idx))} of {num(len(pts))} soundings")
    for key, name in (("final", "trajectory_after"), ("initial", "trajectory_before")):
        tr = p.traj.get(key)
        if tr is None:
            continue
        step = max(1, len(tr["x"]) // VIEWER_MAX_TRAJECTORY)
        xyz = np.stack([tr[c][::step] for c in ("x", "y", "z")], axis=1)
        data[name] = b64((xyz - centre).astype("<f4"))
    if "initial" in p.traj:
        facts.append("trajectory before SLAM (orange) and after (white)")
    # The mesh tiles (pitmap run with tiles.enabled): viewer3d_tiles.js reads their index and
    # loads the tiles in view when the page is served over HTTP (not from file://).
    tiles = mesh_tiles(p.folder)
    if tiles:
        data["mesh_tiles"] = {"index": MESH_TILE_INDEX, "tiles": tiles}
        facts.append(f"{num(tiles)} mesh tiles loaded by view when served over HTTP")
    placed = getattr(p, "equipment", None) or []
    if placed:
        data["equipment"] = [{"name": e["name"], "glb": b64(np.frombuffer(e["glb"], np.uint8)),
                              "heading_deg": e["heading_deg"], "position_m": e["position_m"]}
                             for e in placed]
        facts.append("equipment: " + ", ".join(e["name"] for e in placed))
    return '<p class="print-only">The interactive 3D view is in report.html.</p>' + viewer_html(
        data, "Drag to turn, wheel to zoom, right-drag to pan; "
                      f'{esc(", ".join(facts))}; coloured by depth. Local ENU metres about '
                      f"({centre[0]:.1f}, {centre[1]:.1f}, {centre[2]:.1f}). "
                      "Cross-section: two clicks give the profile of the mesh and the "
                      "soundings along the vertical plane through them. Enter VR shows the "
                      "pit at real size from its south edge; open glTF... shows a .glb "
                      "(mesh.glb) in this view.")
