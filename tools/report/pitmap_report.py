#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pitmap-report: a self-contained HTML report of a products folder.

Usage: pitmap-report P [--scores FILE] [--title TEXT]

Reads what `pitmap run --out P` wrote (summary.json, trajectory[_initial].csv or, without
SLAM, trajectory_ins.csv,
points[_initial].ply, mesh[_initial].ply, boresight.json, optional scores.json from
pitmap-eval --json) and writes P/report.html with the plots embedded as PNG data URIs
(no external resource), and the same PNGs under P/report/. The figures follow the seed
paper: trajectory before/after SLAM and point-cloud cross-sections (Fig. 3), a
depth-coloured top view and mesh renders before/after SLAM (Fig. 4).

Frames: products are in the local world frame (East, North, Up metres at the summary's
world_origin); gps_time_s counts seconds since 1980-01-06 on the GPS time scale.

Exit 0 when the report was written (every missing optional product is named in it as
"not produced: ..."); 1 when P is not a usable products folder (no readable
summary.json) or the report cannot be written; 2 on bad arguments.

Runs with Debian's python3, python3-numpy and python3-matplotlib (Agg backend) only.
Large products stay cheap: PLY data is memory-mapped through numpy structured dtypes and
plots use rasters or subsamples, never every point.
"""

import argparse
import base64
import datetime
import html
import io
import json
import math
import os
import re
import resource
import sys
import time

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.colors import LightSource, Normalize  # noqa: E402
from matplotlib.ticker import EngFormatter, LogLocator, MaxNLocator  # noqa: E402

PROG = "pitmap-report"
# The interactive 3D view: three.js from Debian's libjs-three, inlined into report.html with
# viewer3d.js (installed beside this script as pitmap-report-viewer3d.js).
THREE_DIR = os.environ.get("PITMAP_THREE_DIR", "/usr/share/javascript/three")
VIEWER_MAX_TRIANGLES = 250_000  # what a laptop's integrated GPU turns smoothly
VIEWER_MAX_POINTS = 150_000
VIEWER_MAX_TRAJECTORY = 5_000
START_TIME = time.monotonic()

# Stage order of `pitmap run`; summary.json may give its own in "stage_order".
PIPELINE_STAGES = ["ingest", "georef", "calibrate", "slam", "fuse", "mesh", "export", "report"]

GPS_EPOCH_UNIX_S = 315964800  # 1980-01-06 00:00:00 UTC
# GPS - UTC comes from summary.json "time" (written by `pitmap georef` from the receiver's TIME
# log or the C++ leap-second table, common/gps_time): the report keeps no table of its own.

# What pitmap-eval's scores mean (pitmap-eval --help); unknown names are shown as they come.
SCORE_MEANINGS = {
    "trajectory_ate_rmse_m":
        "trajectory error after SLAM (RMS position error vs truth, no alignment)",
    "trajectory_ate_rmse_before_m": "trajectory error before SLAM (trajectory_initial.csv)",
    "trajectory_ate_max_m": "largest trajectory position error after SLAM",
    "trajectory_z_std_m": "std of the track height (a surface vehicle's track is planar)",
    "points_rms_m": "RMS distance of the points to the true terrain",
    "points_p95_m": "95th percentile of the point distance to the true terrain",
    "points_bias_m": "mean signed point distance to the true terrain",
    "points_scored": "points scored",
    "boresight_error_deg": "angle between the estimated and the true boresight rotation",
    "mesh_mean_abs_m": "mean |distance| of mesh vertices and centroids to the true surface",
    "mesh_rms_m": "RMS distance of the mesh to the true surface",
    "mesh_p95_m": "95th percentile of the mesh distance to the true surface",
    "mesh_completeness": "share of the insonified true surface within 0.2 m of the mesh",
}

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}

MAX_SCATTER_POINTS = 150_000  # per panel
FIG_DPI = 100


def PeakRssMb():
    """VmHWM of this process. Linux carries ru_maxrss across exec, so a report started by
    `pitmap run` would show the pipeline's peak there; VmHWM starts afresh."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def Log(msg):
    print(f"{PROG}: [{time.monotonic() - START_TIME:6.1f} s, {PeakRssMb():5.0f} MB] {msg}",
          file=sys.stderr, flush=True)


class ReportError(Exception):
    """A products folder that cannot be reported on at all."""


class PlyError(Exception):
    pass


# ----------------------------------------------------------------------------------- inputs


class Ply:
    """A binary PLY file: header facts plus one numpy structured array per element.

    pitmap writes PLY in one place (common/formats/ply, C++); this reader stays in Python on
    purpose: PLY is a public format, not one pitmap defines, and reading it here lets the
    report memory-map multi-million-point clouds with numpy and run on a products folder with
    Debian's python3 alone (no pitmap binary, no intermediate copy). pitmap's own convention
    in it, the pitmap_origin comment, is checked against summary.json (CheckOrigin).

    Elements of fixed-size records are memory-mapped; a list property (faces) is read as a
    fixed-length array when every record has the same list length (triangles), which is
    checked. ASCII PLY and variable-length lists raise PlyError.
    """

    def __init__(self, path):
        self.path = path
        fname = os.path.basename(path)
        self.comments = []
        self.elements = {}  # name -> structured array
        self.counts = {}    # name -> count from the header
        with open(path, "rb") as f:
            head = f.read(1 << 16)
        end = head.find(b"end_header")
        if not head.startswith(b"ply") or end < 0:
            raise PlyError(f"{fname}: not a PLY file (no 'ply' magic or no end_header)")
        nl = head.find(b"\n", end)
        if nl < 0:
            raise PlyError(f"{fname}: header not terminated")
        data_offset = nl + 1
        fmt = None
        elements = []  # (name, count, [prop]) with prop = (name, type) or (name, count_t, item_t)
        for raw in head[:end].decode("ascii", "replace").splitlines()[1:]:
            words = raw.split()
            if not words:
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "comment":
                self.comments.append(raw.strip()[len("comment"):].strip())
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property":
                if not elements:
                    raise PlyError(f"{fname}: property before any element")
                if words[1] == "list":
                    elements[-1][2].append((words[4], words[2], words[3]))
                else:
                    elements[-1][2].append((words[2], words[1]))
        if fmt == "binary_little_endian":
            endian = "<"
        elif fmt == "binary_big_endian":
            endian = ">"
        else:
            raise PlyError(f"{fname}: format {fmt} not supported (binary PLY only)")

        def T(type_name):
            if type_name not in PLY_TYPES:
                raise PlyError(f"{fname}: unknown property type {type_name}")
            return endian + PLY_TYPES[type_name]

        file_size = os.path.getsize(path)
        offset = data_offset
        for name, count, props in elements:
            self.counts[name] = count
            fields = []
            lists = [p for p in props if len(p) == 3]
            list_lengths = {}
            if lists and count > 0:
                # The first record fixes every list's length; all records are checked below.
                with open(path, "rb") as f:
                    f.seek(offset)
                    first = f.read(4096)
                pos = 0
                for p in props:
                    if len(p) == 2:
                        pos += np.dtype(T(p[1])).itemsize
                    else:
                        ct = np.dtype(T(p[1]))
                        n = int(np.frombuffer(first, ct, count=1, offset=pos)[0])
                        list_lengths[p[0]] = n
                        pos += ct.itemsize + n * np.dtype(T(p[2])).itemsize
            for p in props:
                if len(p) == 2:
                    fields.append((p[0], T(p[1])))
                else:
                    fields.append((p[0] + "__count", T(p[1])))
                    fields.append((p[0], T(p[2]), (list_lengths.get(p[0], 0),)))
            dtype = np.dtype(fields)
            size = dtype.itemsize * count
            if offset + size > file_size:
                raise PlyError(f"{fname}: truncated (element {name} needs {offset + size} bytes, "
                               f"file has {file_size})")
            if count == 0:
                arr = np.zeros(0, dtype)
            else:
                arr = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=(count,))
            for p in lists:
                if count > 0 and np.any(arr[p[0] + "__count"] != list_lengths[p[0]]):
                    raise PlyError(f"{fname}: element {name}: lists of varying length "
                                   "are not supported")
            self.elements[name] = arr
            offset += size

    def origin(self):
        for c in self.comments:
            w = c.split()
            if len(w) == 4 and w[0] == "pitmap_origin":
                return tuple(float(v) for v in w[1:])
        return None


def DecimateMesh(xyz, tri, max_triangles):
    """Vertex clustering: vertices snapped to a cubic grid, each cluster merged into its mean,
    collapsed and duplicate triangles dropped; the cell grows by 1.25x until the triangles fit
    `max_triangles`. Returns (vertices, triangles) with only the vertices still used."""
    if len(tri) <= max_triangles:
        return xyz, tri
    lo = xyz.min(axis=0)
    edge = np.linalg.norm(xyz[tri[:, 0]] - xyz[tri[:, 1]], axis=1)
    cell = max(float(np.median(edge)), 1e-6) * math.sqrt(len(tri) / max_triangles)
    for _ in range(40):
        q = np.floor((xyz - lo) / cell).astype(np.int64)
        n = q.max(axis=0) + 1
        key = (q[:, 0] * n[1] + q[:, 1]) * n[2] + q[:, 2]
        uniq, cluster = np.unique(key, return_inverse=True)
        t = cluster[tri]
        keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
        t = t[keep]
        # The same triangle twice (any rotation of its corners) once.
        r = np.argmin(t, axis=1)
        t = np.stack([t[np.arange(len(t)), (r + k) % 3] for k in range(3)], axis=1)
        t = np.unique(t, axis=0)
        if len(t) <= max_triangles:
            counts = np.bincount(cluster, minlength=len(uniq)).astype(np.float64)
            v = np.stack([np.bincount(cluster, weights=xyz[:, c], minlength=len(uniq)) / counts
                          for c in range(3)], axis=1)
            used, t = np.unique(t, return_inverse=True)
            return v[used], t.reshape(-1, 3).astype(np.uint32)
        cell *= 1.25
    raise ValueError("mesh decimation did not reach the triangle budget")


def InlineScript(js):
    """JavaScript made safe to inline in <script>: no "</script", and no http(s) URL in the
    report (three.js has a namespace string and comments with URLs; none is fetched)."""
    js = re.sub(r"(?i)</script", r"<\\/script", js)
    js = js.replace('"http://www.w3.org/1999/xhtml"', '"htt"+"p://www.w3.org/1999/xhtml"')
    return re.sub(r"(?i)\bhttp(s?):", r"hxxp\1:", js)


def B64(a):
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def ReadTrajectory(path):
    """gps_time_s, x_m, y_m, z_m columns of a trajectory CSV as a dict of float arrays."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    need = ["gps_time_s", "x_m", "y_m", "z_m"]
    missing = [c for c in need if c not in header]
    if missing:
        raise ValueError(f"no column(s) {', '.join(missing)}")
    cols = [header.index(c) for c in need]
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=cols, ndmin=2)
    if data.shape[0] == 0:
        raise ValueError("no rows")
    order = np.argsort(data[:, 0], kind="stable")
    data = data[order]
    return {c: data[:, i] for i, c in enumerate(["t", "x", "y", "z"])}


def GpsToUtc(gps_s, gps_minus_utc_s):
    """GPS seconds since 1980-01-06 -> UTC datetime, with GPS - UTC as summary.json gives it."""
    return datetime.datetime.fromtimestamp(gps_s + GPS_EPOCH_UNIX_S - gps_minus_utc_s,
                                           datetime.timezone.utc)


# ---------------------------------------------------------------------------------- helpers


def Esc(v):
    return html.escape(str(v))


def Num(v, digits=3):
    """Number formatting for tables: integers with thin grouping, floats to `digits`."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}".replace(",", "\u2009")
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        if v != 0 and (abs(v) >= 1e6 or abs(v) < 10 ** (-digits)):
            return f"{v:.{digits}g}"
        return f"{v:.{digits}f}"
    return Esc(v)


def NotProduced(what, why=""):
    because = f" ({Esc(why)})" if why else ""
    return f'<p class="missing">not produced: {Esc(what)}{because}</p>'


def Table(rows, header=None, cls=""):
    out = [f'<table class="{cls}">' if cls else "<table>"]
    if header:
        out.append("<tr>" + "".join(f"<th>{Esc(h)}</th>" for h in header) + "</tr>")
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def Subsample(n, k, seed=0):
    """Sorted indices of at most k of n items (all when n <= k)."""
    if n <= k:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(n, size=k, replace=False))


def Limits(arrays, margin=0.03, lo_pct=None):
    vals = [a for a in arrays if a is not None and len(a)]
    if not vals:
        return (0.0, 1.0)
    if lo_pct is None:
        lo = min(float(np.nanmin(a)) for a in vals)
        hi = max(float(np.nanmax(a)) for a in vals)
    else:
        lo = min(float(np.nanpercentile(a, lo_pct)) for a in vals)
        hi = max(float(np.nanpercentile(a, 100 - lo_pct)) for a in vals)
    span = max(hi - lo, 1e-6)
    return (lo - margin * span, hi + margin * span)


def EmptyPanel(a):
    """A panel whose product does not exist: a grey note, no axes."""
    a.text(0.5, 0.5, "not produced", ha="center", va="center", transform=a.transAxes,
           color="grey", fontsize=12)
    a.set_xticks([])
    a.set_yticks([])
    for sp in a.spines.values():
        sp.set_color("0.85")


def RasterMean(x, y, v, x0, y0, cell, nx, ny):
    """Mean of v per grid cell (NaN where empty); rows are y, columns x."""
    ix = np.floor((x - x0) / cell).astype(np.int64)
    iy = np.floor((y - y0) / cell).astype(np.int64)
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny) & np.isfinite(v)
    flat = iy[ok] * nx + ix[ok]
    s = np.bincount(flat, weights=v[ok], minlength=nx * ny)
    n = np.bincount(flat, minlength=nx * ny)
    with np.errstate(invalid="ignore", divide="ignore"):
        grid = s / n
    grid[n == 0] = np.nan
    return grid.reshape(ny, nx)


def RasterMax(x, y, v, x0, y0, cell, nx, ny):
    """Largest v per grid cell (the surface seen from above), NaN where empty."""
    ix = np.floor((x - x0) / cell).astype(np.int64)
    iy = np.floor((y - y0) / cell).astype(np.int64)
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny) & np.isfinite(v)
    flat = iy[ok] * nx + ix[ok]
    vv = v[ok]
    grid = np.full(nx * ny, np.nan)
    if len(flat):
        order = np.lexsort((vv, flat))
        fs = flat[order]
        last = np.r_[fs[1:] != fs[:-1], True]
        grid[fs[last]] = vv[order][last]
    return grid.reshape(ny, nx)


def FillHoles(grid, passes=2):
    """NaN cells next to data take the mean of their valid 8-neighbours (`passes` rings),
    so that the hill-shade gradient has no artificial cliff at a hole's edge."""
    g = grid.copy()
    for _ in range(passes):
        nan = np.isnan(g)
        if not nan.any():
            break
        p = np.pad(g, 1, constant_values=np.nan)
        stack = np.stack([p[1 + dy:p.shape[0] - 1 + dy, 1 + dx:p.shape[1] - 1 + dx]
                          for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx])
        cnt = np.sum(np.isfinite(stack), axis=0)
        with np.errstate(invalid="ignore"):
            mean = np.nansum(stack, axis=0) / np.maximum(cnt, 1)
        fill = nan & (cnt > 0)
        g[fill] = mean[fill]
    return g


def RasteriseMesh(v, t, x0, y0, cell, nx, ny, chunk=300_000):
    """Top surface of a triangle mesh on a grid: each triangle is sampled on a barycentric
    lattice fine enough to hit every cell it covers, the highest sample per cell wins.
    Triangles go in chunks so that memory stays bounded for meshes of millions."""
    grid = RasterMax(v[:, 0], v[:, 1], v[:, 2], x0, y0, cell, nx, ny)
    for start in range(0, len(t), chunk):
        tt = t[start:start + chunk]
        a, b, c = v[tt[:, 0]], v[tt[:, 1]], v[tt[:, 2]]
        edge = np.maximum(np.maximum(np.hypot(*(a - b)[:, :2].T), np.hypot(*(b - c)[:, :2].T)),
                          np.hypot(*(c - a)[:, :2].T))
        n = np.clip(np.ceil(edge / (0.7 * cell)), 1, 64).astype(np.int64)
        xs, ys, zs = [], [], []
        for k in np.unique(n):
            sel = n == k
            if k == 1:  # vertices are already in; add the centroid
                wa = np.array([1 / 3])
                wb = np.array([1 / 3])
            else:
                i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
                keep = (i + j <= k) & ~(((i == k) & (j == 0)) | ((i == 0) & (j == k)) |
                                        ((i == 0) & (j == 0)))
                wa = (i[keep] / k).astype(np.float64)
                wb = (j[keep] / k).astype(np.float64)
            wc = 1.0 - wa - wb
            p = (a[sel][:, None, :] * wa[None, :, None] + b[sel][:, None, :] * wb[None, :, None]
                 + c[sel][:, None, :] * wc[None, :, None]).reshape(-1, 3)
            xs.append(p[:, 0])
            ys.append(p[:, 1])
            zs.append(p[:, 2])
        grid = np.fmax(grid, RasterMax(np.concatenate(xs), np.concatenate(ys),
                                       np.concatenate(zs), x0, y0, cell, nx, ny))
    return grid


# ------------------------------------------------------------------------------ the report


class Report:
    def __init__(self, folder, scores_path, title):
        self.folder = folder
        self.fig_dir = os.path.join(folder, "report")
        self.scores_path = scores_path
        self.title = title
        self.missing = []   # names of optional products not found
        self.problems = []  # sections that failed to draw, inconsistent products
        self.unusable = {}  # product name -> why it is present but not used
        self.scores = {}
        path = os.path.join(folder, "summary.json")
        if not os.path.isfile(path):
            raise ReportError(f"{folder}: no summary.json (not a pitmap products folder?)")
        try:
            with open(path) as f:
                self.summary = json.load(f)
        except (OSError, ValueError) as e:
            raise ReportError(f"{path}: cannot read: {e}")
        if not isinstance(self.summary, dict):
            raise ReportError(f"{path}: not a JSON object")
        self.stages = self.summary.get("stages") or {}
        if not isinstance(self.stages, dict):
            self.stages = {}
        os.makedirs(self.fig_dir, exist_ok=True)
        self.traj = {}
        self.points = {}
        self.t0 = None
        self.ref_z = 0.0
        # The final products are "after SLAM" only when SLAM ran (pitmap run --no-slam).
        self.after = "after SLAM" if "slam" in self.stages else "SLAM not run"

    # ---- loading
    def P(self, name):
        return os.path.join(self.folder, name)

    def Missing(self, name, why=""):
        """An optional product that is absent, or present but unusable (then its own reason,
        from self.unusable, is given)."""
        if name not in self.missing:
            self.missing.append(name)
        return NotProduced(name, self.unusable.get(name, why))

    def CheckOrigin(self, ply, name):
        """A product whose pitmap_origin differs from summary.json's world_origin would be
        drawn offset: say so (1e-6 deg is about 0.1 m)."""
        o, w = ply.origin(), self.summary.get("world_origin")
        if o is None or not isinstance(w, dict):
            return
        ref = (w.get("latitude_deg"), w.get("longitude_deg"), w.get("height_m"))
        if not all(isinstance(v, (int, float)) for v in ref):
            return
        if abs(o[0] - ref[0]) > 1e-6 or abs(o[1] - ref[1]) > 1e-6 or abs(o[2] - ref[2]) > 0.1:
            self.problems.append(f"{name}: origin {o[0]:.7f} {o[1]:.7f} {o[2]:.2f} differs from "
                                 f"summary.json world_origin {ref[0]:.7f} {ref[1]:.7f} "
                                 f"{ref[2]:.2f}; its figures are offset")

    def LoadTrajectories(self):
        names = [("initial", "trajectory_initial.csv"), ("final", "trajectory.csv")]
        if not any(os.path.isfile(self.P(n)) for _, n in names):
            # No SLAM ran (georef only, or `run --no-slam`): the INS trajectory is the final one.
            names = [("final", "trajectory_ins.csv")]
        for key, name in names:
            if os.path.isfile(self.P(name)):
                try:
                    self.traj[key] = ReadTrajectory(self.P(name))
                    Log(f"{name}: {len(self.traj[key]['t'])} poses")
                except (OSError, ValueError) as e:
                    Log(f"{name}: unreadable: {e}")
                    self.unusable[name] = f"unreadable: {e}"
        ts = [tr["t"][0] for tr in self.traj.values()]
        if ts:
            self.t0 = min(ts)
        main = self.traj.get("final") or self.traj.get("initial")
        if main is not None:
            self.ref_z = float(np.median(main["z"]))

    def LoadPoints(self):
        for key, name in (("initial", "points_initial.ply"), ("final", "points.ply")):
            if not os.path.isfile(self.P(name)):
                continue
            try:
                ply = Ply(self.P(name))
                v = ply.elements.get("vertex")
                if v is None or not all(c in v.dtype.names for c in ("x", "y", "z")):
                    raise PlyError(f"{name}: no vertex x, y, z")
                if len(v) == 0:
                    self.unusable[name] = "no points"
                    continue
                self.points[key] = v
                self.CheckOrigin(ply, name)
                Log(f"{name}: {len(v)} points")
            except (OSError, PlyError) as e:
                Log(f"{name}: unreadable: {e}")
                self.unusable[name] = f"unreadable: {e}"
        if self.t0 is None:
            for v in self.points.values():
                if "gps_time_s" in v.dtype.names and len(v):
                    self.t0 = float(np.min(v["gps_time_s"][::max(1, len(v) // 10000)]))

    def LoadMesh(self, name):
        if not os.path.isfile(self.P(name)):
            return None
        ply = Ply(self.P(name))
        v = ply.elements.get("vertex")
        f = ply.elements.get("face")
        if v is None or f is None:
            raise PlyError(f"{name}: no vertex or face element")
        self.CheckOrigin(ply, name)
        lists = [n for n in f.dtype.names if not n.endswith("__count")]
        if not lists or f.dtype[lists[0]].shape != (3,) and len(f):
            raise PlyError(f"{name}: faces are not triangles")
        xyz = np.stack([np.asarray(v[c], dtype=np.float64) for c in ("x", "y", "z")], axis=1)
        tri = np.array(f[lists[0]], dtype=np.int32).reshape(-1, 3) if len(f) else \
            np.zeros((0, 3), np.int32)
        if len(tri) and (tri.min() < 0 or tri.max() >= len(xyz)):
            raise PlyError(f"{name}: face index out of range")
        return xyz, tri

    # ---- figures
    def Figure(self, fig, name, alt):
        path = os.path.join(self.fig_dir, name + ".png")
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=FIG_DPI)
        plt.close(fig)
        data = buf.getvalue()
        with open(path, "wb") as f:
            f.write(data)
        Log(f"figure {name}.png ({len(data) // 1024} kB)")
        b64 = base64.b64encode(data).decode("ascii")
        return f'<img alt="{Esc(alt)}" src="data:image/png;base64,{b64}">'

    def MinutesOf(self, t):
        return (np.asarray(t, dtype=np.float64) - (self.t0 or 0.0)) / 60.0

    # ---- sections; each returns an HTML fragment
    def SectionHeader(self):
        s = self.summary
        rows = []
        main = self.traj.get("final") or self.traj.get("initial")
        if main is not None:
            t_a, t_b = float(main["t"][0]), float(main["t"][-1])
            tm = s.get("time") if isinstance(s.get("time"), dict) else {}
            leap = tm.get("gps_minus_utc_s")
            if isinstance(leap, (int, float)) and not isinstance(leap, bool):
                u_a, u_b = GpsToUtc(t_a, leap), GpsToUtc(t_b, leap)
                rows.append(("Survey time (UTC)",
                             f"{u_a:%Y-%m-%d %H:%M:%S} to {u_b:%H:%M:%S} "
                             f"({(t_b - t_a) / 60:.1f} min; GPS {t_a:.1f} to {t_b:.1f} s; "
                             f"GPS - UTC = {leap:g} s, "
                             f"{Esc(tm.get('gps_minus_utc_source', '?'))})"))
            else:
                rows.append(("Survey time (GPS)",
                             f"GPS {t_a:.1f} to {t_b:.1f} s ({(t_b - t_a) / 60:.1f} min); UTC "
                             "unknown: summary.json has no time.gps_minus_utc_s (an older "
                             "pitmap georef)"))
            length = float(np.sum(np.hypot(np.diff(main["x"]), np.diff(main["y"]))))
            which = self.after if "final" in self.traj else "before SLAM"
            rows.append(("Track length", f"{length:.0f} m ({which})"))
        o = s.get("world_origin") or {}
        if o:
            rows.append(("World origin (WGS84)",
                         f"lat {Num(float(o.get('latitude_deg', float('nan'))), 7)}&deg;, "
                         f"lon {Num(float(o.get('longitude_deg', float('nan'))), 7)}&deg;, "
                         f"h {Num(float(o.get('height_m', float('nan'))), 2)} m; "
                         "frame: East, North, Up metres"))
        u = s.get("utm") or {}
        if u:
            rows.append(("Projected CRS", f"UTM zone {Esc(u.get('zone'))}"
                         f"{'N' if u.get('northern', True) else 'S'}, EPSG:{Esc(u.get('epsg'))}"))
        geo = self.stages.get("georef") or {}
        ing = self.stages.get("ingest") or {}
        if "pings_georeferenced" in geo:
            rows.append(("Pings", f"{Num(geo['pings_georeferenced'])} georeferenced of "
                         f"{Num(geo.get('pings_in', ing.get('pings', '?')))}"))
        elif "pings" in ing:
            rows.append(("Pings", Num(ing["pings"])))
        for key, label in (("final", f"Points ({self.after})"),
                           ("initial", "Points (before SLAM)")):
            if key in self.points:
                rows.append((label, Num(len(self.points[key]))))
        for name in ("mesh.ply", "mesh_initial.ply"):
            if os.path.isfile(self.P(name)):
                try:
                    ply = Ply(self.P(name))
                    rows.append((f"Mesh {name}", f"{Num(ply.counts.get('vertex', 0))} vertices, "
                                 f"{Num(ply.counts.get('face', 0))} triangles"))
                except (OSError, PlyError) as e:
                    rows.append((f"Mesh {name}", Esc(e)))
        ate = self.ScoreText("trajectory_ate_rmse_before_m", "trajectory_ate_rmse_m", "")
        if ate:
            rows.append(("Trajectory error vs truth (before &rarr; after SLAM)", ate.strip()))
        if "initial" in self.traj and "final" in self.traj:
            rows.append(("Track height std (before &rarr; after SLAM)",
                         f"{np.std(self.traj['initial']['z']):.3f} &rarr; "
                         f"{np.std(self.traj['final']['z']):.3f} m"))
        slam = self.stages.get("slam")
        if isinstance(slam, dict) and "initial_consistency_m" in slam:
            rows.append(("SLAM consistency score",
                         f"{Num(slam['initial_consistency_m'], 4)} &rarr; "
                         f"{Num(slam.get('final_consistency_m', float('nan')), 4)} m "
                         f"({Esc(slam.get('termination', '?'))})"))
        if "total_seconds" in s:
            rows.append(("Processing time", f"{float(s['total_seconds']):.1f} s"))
        inputs = s.get("inputs") or []
        if inputs:
            rows.append(("Inputs", "<br>".join(Esc(i) for i in inputs)))
        m = s.get("mount") or {}
        if m:
            rows.append(("Boresight used (roll, pitch, yaw)",
                         f"{Num(float(m.get('roll_deg', 0)))}&deg;, "
                         f"{Num(float(m.get('pitch_deg', 0)))}&deg;, "
                         f"{Num(float(m.get('yaw_deg', 0)))}&deg;"))
        rows.append(("Report written (UTC)",
                     f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M:%S}"))
        return Table([(f"<b>{k}</b>", v) for k, v in rows], cls="facts")

    def SectionTrajectory(self):
        if not self.traj:
            return "\n".join(self.Missing(n, "no trajectory")
                             for n in ("trajectory_initial.csv", "trajectory.csv"))
        out = []
        if "initial" not in self.traj:
            out.append(self.Missing("trajectory_initial.csv", "no before-SLAM trajectory"))
        if "final" not in self.traj:
            out.append(self.Missing("trajectory.csv", "no after-SLAM trajectory"))
        trs = self.traj
        dec = {k: slice(None, None, max(1, len(v["t"]) // 20000)) for k, v in trs.items()}
        xl = Limits([v["x"] for v in trs.values()])
        yl = Limits([v["y"] for v in trs.values()])
        zl = Limits([v["z"] for v in trs.values()], margin=0.08)
        tl = Limits([self.MinutesOf(v["t"]) for v in trs.values()], margin=0.01)
        top_h = float(np.clip(6.0 * (yl[1] - yl[0]) / (xl[1] - xl[0]), 2.5, 9.0))
        fig, ax = plt.subplots(2, 2, figsize=(13, top_h + 4.6), height_ratios=[top_h, 3.0],
                               layout="constrained")
        panels = [("initial", "(a) before SLAM (GPS/INS)", "k", "--"),
                  ("final", f"(b) {self.after}", "tab:red", "-")]
        for col, (key, title, colour, ls) in enumerate(panels):
            a_top, a_z = ax[0][col], ax[1][col]
            if key not in trs:
                for a in (a_top, a_z):
                    EmptyPanel(a)
                a_top.set_title(title)
                continue
            tr, d = trs[key], dec[key]
            if key == "final" and "initial" in trs:
                ti, di = trs["initial"], dec["initial"]
                a_top.plot(ti["x"][di], ti["y"][di], color="0.7", ls="--", lw=0.7,
                           label="before SLAM")
                a_z.plot(self.MinutesOf(ti["t"][di]), ti["z"][di], color="0.7", ls="--", lw=0.7,
                         label="before SLAM")
            a_top.plot(tr["x"][d], tr["y"][d], color=colour, ls=ls, lw=0.9,
                       label=title.split(") ")[1])
            a_top.plot(tr["x"][0], tr["y"][0], "o", color=colour, ms=5, label="start")
            a_z.plot(self.MinutesOf(tr["t"][d]), tr["z"][d], color=colour, ls=ls, lw=0.9,
                     label=title.split(") ")[1])
            a_top.set_title(title)
            a_top.set_xlim(xl)
            a_top.set_ylim(yl)
            a_top.set_aspect("equal", adjustable="box")
            a_top.set_xlabel("East x (m)")
            a_top.set_ylabel("North y (m)")
            a_top.grid(alpha=0.3)
            a_top.legend(loc="best", fontsize=8)
            a_z.set_xlim(tl)
            a_z.set_ylim(zl)
            a_z.set_xlabel("time since start (min)")
            a_z.set_ylabel("height z (m)")
            a_z.set_title(f"track height, std {np.std(tr['z']):.3f} m, "
                          f"range {np.ptp(tr['z']):.3f} m")
            a_z.grid(alpha=0.3)
            a_z.legend(loc="best", fontsize=8)
        out.append(self.Figure(fig, "trajectory", "trajectory before and after SLAM"))
        ate = self.ScoreText("trajectory_ate_rmse_before_m", "trajectory_ate_rmse_m",
                             " Trajectory error (RMS vs truth):")
        out.append('<p class="caption">Top: the track seen from above; bottom: its height over '
                   "time. A surface vehicle moves on a plane: after SLAM the height should be "
                   f"flat. Both columns share their axis limits.{ate}</p>")
        return "\n".join(out)

    def SectionCrossSections(self):
        if not self.points:
            return "\n".join(self.Missing(n, "no point cloud")
                             for n in ("points_initial.ply", "points.ply"))
        out = []
        if "initial" not in self.points:
            out.append(self.Missing("points_initial.ply", "no before-SLAM point cloud"))
        if "final" not in self.points:
            out.append(self.Missing("points.ply", "no after-SLAM point cloud"))
        ref = self.points.get("final", self.points.get("initial"))
        step = max(1, len(ref) // 200_000)
        xs = np.asarray(ref["x"][::step], dtype=np.float64)
        ys = np.asarray(ref["y"][::step], dtype=np.float64)
        xc = 0.5 * sum(np.percentile(xs, [1, 99])) if len(xs) else 0.0
        yc = 0.5 * sum(np.percentile(ys, [1, 99])) if len(ys) else 0.0
        half = 0.5
        cuts = {}  # (axis, key) -> (u, z, minutes)
        for key, pts in self.points.items():
            x = np.asarray(pts["x"], dtype=np.float64)
            y = np.asarray(pts["y"], dtype=np.float64)
            has_t = "gps_time_s" in pts.dtype.names
            for axis, sel, u in (("x", np.abs(y - yc) < half, x), ("y", np.abs(x - xc) < half, y)):
                idx = np.nonzero(sel)[0]
                idx = idx[Subsample(len(idx), MAX_SCATTER_POINTS, seed=1)]
                # Drawn in random order: in time order the last pass would hide the others.
                np.random.default_rng(2).shuffle(idx)
                z = np.asarray(pts["z"][idx], dtype=np.float64)
                m = self.MinutesOf(pts["gps_time_s"][idx]) if has_t else np.zeros(len(idx))
                cuts[(axis, key)] = (u[idx], z, m)
            del x, y
        all_m = [c[2] for c in cuts.values() if len(c[2])]
        tnorm = Normalize(min(float(m.min()) for m in all_m) if all_m else 0,
                          max(float(m.max()) for m in all_m) if all_m else 1)
        geom = {}
        for axis in ("x", "y"):
            ul = Limits([cuts[(axis, k)][0] for k in self.points], margin=0.02, lo_pct=0.2)
            zl = Limits([cuts[(axis, k)][1] for k in self.points], margin=0.05, lo_pct=0.2)
            # Vertical exaggeration so that a panel is about 2.8 times as wide as high.
            ve = max(1.0, round(2 * (ul[1] - ul[0]) / (2.8 * (zl[1] - zl[0]))) / 2)
            geom[axis] = (ul, zl, ve, 5.6 * ve * (zl[1] - zl[0]) / (ul[1] - ul[0]))
        fig, ax = plt.subplots(2, 2, figsize=(13, geom["x"][3] + geom["y"][3] + 1.8),
                               height_ratios=[geom["x"][3], geom["y"][3]], layout="constrained")
        sc = None
        for row, axis in enumerate(("x", "y")):
            ul, zl, ve, _ = geom[axis]
            for col, (key, title) in enumerate((("initial", "(c) before SLAM"),
                                                ("final", f"(d) {self.after}"))):
                a = ax[row][col]
                where = (f"slab y = {round(yc, 1) + 0.0:.1f} \u00b1 {half} m" if axis == "x"
                         else f"slab x = {round(xc, 1) + 0.0:.1f} \u00b1 {half} m")
                a.set_title(f"{title}: along {axis}, {where}", fontsize=10)
                if (axis, key) not in cuts:
                    EmptyPanel(a)
                    continue
                u, z, m = cuts[(axis, key)]
                sc = a.scatter(u, z, c=m, s=1.0, cmap="turbo", norm=tnorm, linewidths=0,
                               rasterized=True)
                a.set_xlim(ul)
                a.set_ylim(zl)
                a.set_aspect(ve, adjustable="box")
                a.set_xlabel(f"{'East x' if axis == 'x' else 'North y'} (m)")
                a.set_ylabel(f"height z (m), vert. exag. {ve:g}x")
                a.grid(alpha=0.3)
                a.text(0.01, 0.02, f"{len(u)} points", transform=a.transAxes, fontsize=8)
        if sc is not None:
            cb = fig.colorbar(sc, ax=ax, shrink=0.8, pad=0.01, aspect=30)
            cb.set_label("pass time (min since start)")
        out.append(self.Figure(fig, "cross_sections", "point cloud cross-sections before/after"))
        out.append('<p class="caption">Points within 0.5 m of a vertical plane through the middle '
                   "of the survey, coloured by the time they were measured. Passes that disagree "
                   "show as doubled walls or floors in different colours (paper Fig. 3 c/d).</p>")
        return "\n".join(out)

    def SectionDepth(self):
        if "final" not in self.points:
            return self.Missing("points.ply", "no after-SLAM point cloud")
        pts = self.points["final"]
        x = np.asarray(pts["x"], dtype=np.float64)
        y = np.asarray(pts["y"], dtype=np.float64)
        z = np.asarray(pts["z"], dtype=np.float64)
        xl = Limits([x], margin=0.02, lo_pct=0.05)
        yl = Limits([y], margin=0.02, lo_pct=0.05)
        cell = max(0.1, max(xl[1] - xl[0], yl[1] - yl[0]) / 500.0)
        nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
        ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
        grid = FillHoles(RasterMean(x, y, self.ref_z - z, xl[0], yl[0], cell, nx, ny), passes=1)
        del x, y, z
        valid = grid[np.isfinite(grid)]
        vmin, vmax = (np.percentile(valid, [0.5, 99.5]) if len(valid) else (0, 1))
        fig, a = plt.subplots(figsize=(12, float(np.clip(10.5 * ny / nx, 3, 14)) + 0.8),
                              layout="constrained")
        im = a.imshow(grid, origin="lower", extent=(xl[0], xl[0] + nx * cell, yl[0],
                      yl[0] + ny * cell), cmap="turbo_r", vmin=vmin, vmax=vmax,
                      interpolation="nearest")
        tr = self.traj.get("final")
        if tr is not None:
            d = slice(None, None, max(1, len(tr["t"]) // 20000))
            a.plot(tr["x"][d], tr["y"][d], color="k", lw=0.4, alpha=0.6, label="track")
            a.legend(loc="upper right", fontsize=8)
        a.set_xlim(xl)
        a.set_ylim(yl)
        a.set_aspect("equal")
        a.set_xlabel("East x (m)")
        a.set_ylabel("North y (m)")
        a.set_title(f"points after SLAM: mean depth per {cell:.2f} m cell")
        a.grid(alpha=0.25)
        cb = fig.colorbar(im, ax=a, shrink=0.9, pad=0.01)
        cb.set_label(f"depth below the track (m; track median z = {self.ref_z:.2f} m)")
        return "\n".join([self.Figure(fig, "depth_top_view", "depth-coloured top view"),
                          f'<p class="caption">{Num(len(pts))} points rasterised; white cells '
                          "hold no point (single empty cells are filled from their "
                          "neighbours).</p>"])

    def SectionHydro(self):
        """Vertical datum, TPU and IHO S-44 Ed. 6.1 quality control (the grid stage): tables a
        surveyor can hand to a client, a compliance map with the holidays, the crossline check
        by beam angle."""
        g = self.stages.get("grid")
        if not isinstance(g, dict):
            return self.Missing("grid stage", "no grid stage in summary.json (pitmap grid)")
        out = []
        vd = self.summary.get("vertical_datum")
        facts = []
        if isinstance(vd, dict):
            crs = Esc(vd.get("vertical_crs", "?"))
            if vd.get("vertical_epsg"):
                crs += f" (EPSG:{Esc(vd['vertical_epsg'])})"
            facts.append(("vertical datum", crs))
            facts.append(("reduction", Esc(vd.get("description", ""))))
            ws = vd.get("gnss_water_surface")
            if isinstance(ws, dict):
                facts.append(("water surface from GNSS (ellipsoidal)",
                              f"median {Num(ws.get('median_m', float('nan')), 3)} m, range "
                              f"{Num(ws.get('min_m', float('nan')), 3)} to "
                              f"{Num(ws.get('max_m', float('nan')), 3)} m, heave/noise sd "
                              f"{Num(ws.get('raw_sd_mad_m', float('nan')), 3)} m "
                              f"({Num(ws.get('samples', 0))} INS samples)"))
        else:
            facts.append(("vertical datum", "WGS 84 ellipsoidal height"))
        facts.append(("TPU per sounding (95 %)",
                      f"median TVU {Num(g.get('median_tvu_95_m', float('nan')), 3)} m, median "
                      f"THU {Num(g.get('median_thu_95_m', float('nan')), 3)} m; error model "
                      f"{Esc(g.get('error_model', '?'))}"))
        facts.append(("CUBE surface", f"{Num(g.get('resolution_m', float('nan')), 2)} m nodes, "
                      f"{Num(g.get('nodes_filled', 0))} filled (dem.tif, dem.bag)"))
        out.append(Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
        q = g.get("s44")
        if not isinstance(q, dict):
            out.append(self.Missing("S-44 quality control", "s44.enabled is false"))
            return "\n".join(out)
        order = q.get("order", "?")
        met = q.get("strictest_order_met_95")
        out.append(f"<h3>IHO S-44 Edition 6.1: order {Esc(order)}</h3>")
        out.append(f"<p>Strictest order whose TVU and THU 95 % of the soundings meet: "
                   f"<b>{Esc(met) if met else 'none'}</b>. Chosen order for holidays and "
                   f"the crossline check: <b>{Esc(order)}</b>.</p>")
        rows = []
        lim = q.get("limits") or {}
        for o in ("exclusive", "special", "1a", "1b", "2"):
            L = lim.get(o) or {}
            thu = f"{Num(L.get('thu_m', 0), 1)}"
            if L.get("thu_depth_fraction"):
                thu += f" + {Num(100 * L['thu_depth_fraction'], 0)} % d"
            pct = lambda key: Num(100 * float((q.get(key) or {}).get(o, float("nan"))), 1)
            name = f"<b>{Esc(o)}</b>" if o == order else Esc(o)
            rows.append([name, thu, f"{Num(L.get('tvu_a_m', 0), 2)} / {Num(L.get('tvu_b', 0), 4)}",
                         Num(L.get("feature_m", 0), 1) if L.get("feature_m") else "n/a",
                         f"{Num(L.get('coverage_percent', 0), 0)} %",
                         pct("soundings_within_tvu"), pct("soundings_within_thu"),
                         pct("soundings_within_both"), pct("nodes_within_tvu"),
                         pct("nodes_within_thu")])
        out.append(Table(rows, header=["order", "THU (m)", "TVU a (m) / b", "feature (m)",
                                       "coverage", "soundings within TVU (%)",
                                       "within THU (%)", "within both (%)",
                                       "nodes within TVU (%)", "nodes within THU (%)"]))
        out.append(f'<p class="caption">{Num(q.get("soundings", 0))} soundings, '
                   f'{Num(q.get("nodes", 0))} grid nodes. TVU limit sqrt(a&sup2; + (b d)&sup2;), '
                   "d the depth (below the water-level datum, else below the transducer); node "
                   "TVU is the CUBE uncertainty, node THU the mean THU of its soundings.</p>")
        hol = q.get("holidays") or []
        facts = [("coverage of the survey area", f"{Num(100 * q.get('coverage_share', 0), 2)} % "
                  f"({Num(q.get('nodes_in_gaps', 0))} empty nodes in {Num(q.get('gaps', 0))} "
                  "gaps inside it)"),
                 ("holidays", f"<b>{Num(q.get('holiday_count', 0))}</b> (gaps that could hide a "
                  f"{Num(q.get('feature_size_m', 0), 2)} m feature; map s44_holidays.tif)"
                  if q.get("feature_size_m") else
                  f"not applicable to order {Esc(order)} (5 % coverage); "
                  f"{Num(q.get('gaps', 0))} gaps mapped in s44_holidays.tif")]
        out.append(Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
        if hol:
            out.append(Table([[str(i + 1), f"{float(h['x_m']):.2f}", f"{float(h['y_m']):.2f}",
                               Num(h.get("area_m2", 0), 2), Num(h.get("largest_square_m", 0), 2)]
                              for i, h in enumerate(hol[:20])],
                             header=["holiday", "UTM easting (m)", "UTM northing (m)",
                                     "area (m&sup2;)", "largest empty square (m)"]))
        out.append(self.HydroMap(q, order))
        cl = q.get("crossline") or {}
        out.append("<h3>Crossline check</h3>")
        bins = cl.get("by_angle") or []
        if not cl.get("compared"):
            out.append("<p>The track does not cross its own earlier lines (no sounding has "
                       "crossing soundings at least 30 s older in its cell).</p>")
            return "\n".join(out)
        out.append(f"<p>{Num(cl['compared'])} soundings compared with the surface of the "
                   f"earlier lines they cross: mean {Num(cl.get('mean_m', 0), 3)} m, sd "
                   f"{Num(cl.get('sd_m', 0), 3)} m, RMS {Num(cl.get('rms_m', 0), 3)} m; "
                   f"{Num(100 * cl.get('within_tvu', 0), 1)} % within the order {Esc(order)} "
                   "TVU limit.</p>")
        out.append(Table([[f"{Num(b['angle_lo_deg'], 0)}&ndash;{Num(b['angle_hi_deg'], 0)}",
                           Num(b["count"]), Num(b["mean_m"], 3), Num(b["sd_m"], 3),
                           Num(b["rms_m"], 3), Num(100 * b["within_tvu"], 1)] for b in bins],
                         header=["|beam angle| (deg)", "soundings", "mean (m)", "sd (m)",
                                 "RMS (m)", "within TVU (%)"]))
        if bins:
            fig, a = plt.subplots(figsize=(8, 3.4), layout="constrained")
            c = [0.5 * (b["angle_lo_deg"] + b["angle_hi_deg"]) for b in bins]
            a.errorbar(c, [b["mean_m"] for b in bins], yerr=[b["sd_m"] for b in bins],
                       fmt="o-", capsize=3, label="mean +- sd")
            a.axhline(0, color="k", lw=0.6)
            a.set_xlabel("|beam angle| (deg)")
            a.set_ylabel("sounding - crossing surface (m)")
            a.grid(alpha=0.3)
            a.legend(fontsize=8)
            out.append(self.Figure(fig, "s44_crossline", "crossline differences by beam angle"))
        return "\n".join(out)

    def HydroMap(self, q, order):
        """Soundings coloured by TVU over the order's limit, holidays outlined."""
        pts = self.points.get("final")
        if pts is None or "tvu_95_m" not in pts.dtype.names:
            return self.Missing("points.ply tvu_95_m", "points.ply without THU/TVU "
                                "(grid.write_point_tpu)")
        lim = (q.get("limits") or {}).get(order) or {}
        step = max(1, len(pts) // 400000)
        x = np.asarray(pts["x"][::step], dtype=np.float64)
        y = np.asarray(pts["y"][::step], dtype=np.float64)
        tvu = np.asarray(pts["tvu_95_m"][::step], dtype=np.float64)
        if "depth_m" in pts.dtype.names:
            d = np.asarray(pts["depth_m"][::step], dtype=np.float64)
        else:
            d = self.ref_z - np.asarray(pts["z"][::step], dtype=np.float64)
        a_m, b = float(lim.get("tvu_a_m", 0.5)), float(lim.get("tvu_b", 0.013))
        ratio = tvu / np.sqrt(a_m ** 2 + (b * np.maximum(d, 0)) ** 2)
        xl = Limits([x], margin=0.02, lo_pct=0.05)
        yl = Limits([y], margin=0.02, lo_pct=0.05)
        cell = max(0.1, max(xl[1] - xl[0], yl[1] - yl[0]) / 400.0)
        nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
        ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
        grid = RasterMax(x, y, ratio, xl[0], yl[0], cell, nx, ny)
        fig, a = plt.subplots(figsize=(11, float(np.clip(9.5 * ny / nx, 3, 13)) + 0.8),
                              layout="constrained")
        im = a.imshow(grid, origin="lower", extent=(xl[0], xl[0] + nx * cell, yl[0],
                      yl[0] + ny * cell), cmap="RdYlGn_r", vmin=0, vmax=1.5,
                      interpolation="nearest")
        for i, h in enumerate((q.get("holidays") or [])[:50]):
            box = h.get("bbox_world_m")
            if not box:
                continue
            bx = [p[0] for p in box] + [box[0][0]]
            by = [p[1] for p in box] + [box[0][1]]
            a.plot(bx, by, color="m", lw=1.5, label="holiday" if i == 0 else None)
            a.annotate(str(i + 1), (h["world_m"][0], h["world_m"][1]), color="m", fontsize=9,
                       ha="center", va="center", weight="bold")
        if q.get("holidays"):
            a.legend(loc="upper right", fontsize=8)
        a.set_xlim(xl)
        a.set_ylim(yl)
        a.set_aspect("equal")
        a.set_xlabel("East x (m, world)")
        a.set_ylabel("North y (m, world)")
        a.set_title(f"largest TVU / order {order} TVU limit per {cell:.2f} m cell "
                    "(> 1: the order is not met)")
        a.grid(alpha=0.25)
        cb = fig.colorbar(im, ax=a, shrink=0.9, pad=0.01)
        cb.set_label("TVU (95 %) / limit")
        return self.Figure(fig, "s44_compliance", "S-44 TVU compliance map with holidays")

    def SectionMosaic(self):
        """The backscatter mosaic of the grid stage (mosaic.tif): corrected and uncorrected side
        by side, with the angular response the correction used (issue 17 item 6)."""
        g = self.stages.get("grid")
        m = g.get("mosaic") if isinstance(g, dict) else None
        if not isinstance(m, dict):
            return self.Missing("mosaic.tif", "no mosaic in the grid stage (mosaic.enabled)")
        if not m.get("made"):
            return NotProduced("mosaic.tif", m.get("reason") or m.get("message") or "")
        try:
            from osgeo import gdal  # python3-gdal: read only here, so the rest needs no GDAL
        except ImportError:
            return self.Missing("mosaic.tif", "python3-gdal is not installed")
        gdal.UseExceptions()
        ds = gdal.Open(self.P("mosaic.tif"))
        gt = ds.GetGeoTransform()
        bands = {ds.GetRasterBand(b).GetDescription(): ds.GetRasterBand(b).ReadAsArray()
                 for b in range(1, ds.RasterCount + 1)}
        ext = (gt[0], gt[0] + gt[1] * ds.RasterXSize, gt[3] + gt[5] * ds.RasterYSize, gt[3])
        fig, axes = plt.subplots(1, 3, figsize=(15, 5.2), layout="constrained",
                                 gridspec_kw={"width_ratios": [1, 1, 0.8]})
        for a, name, title in ((axes[0], "backscatter", "corrected (range, incidence)"),
                               (axes[1], "uncorrected", "uncorrected: 20 log10(intensity)")):
            v = np.asarray(bands.get(name), dtype=np.float64)
            ok = v[np.isfinite(v)]
            lo, hi = np.percentile(ok, [2, 98]) if len(ok) else (0, 1)
            im = a.imshow(v, extent=ext, cmap="gray", vmin=lo, vmax=hi, interpolation="nearest")
            a.set_title(title, fontsize=10)
            a.set_xlabel("UTM easting (m)")
            a.set_aspect("equal")
            a.ticklabel_format(useOffset=False, style="plain")
            a.tick_params(labelsize=7)
            fig.colorbar(im, ax=a, shrink=0.8, pad=0.01).set_label("dB (relative)")
        axes[0].set_ylabel("UTM northing (m)")
        curve = np.asarray(m.get("angular_response_deg_db_count") or [[0, 0, 0]], dtype=float)
        axes[2].plot(curve[:, 0], curve[:, 1], "o-", ms=2)
        axes[2].set_xlabel("incidence (deg)")
        axes[2].set_ylabel("angular response removed (dB, 0 at the reference)")
        axes[2].set_title(f"{m.get('angular', '?')} angular response", fontsize=10)
        axes[2].grid(alpha=0.3)
        facts = [("soundings used", f"{Num(m.get('used', 0))} of {Num(m.get('soundings', 0))} "
                  f"(no intensity {Num(m.get('no_intensity', 0))}, saturated "
                  f"{Num(m.get('saturated', 0))}, incidence beyond the limit "
                  f"{Num(m.get('beyond_incidence', 0))})"),
                 ("range correction", f"{Num(m.get('spreading_db_per_decade', 0), 1)} log10(R) + "
                  f"2 &times; {Num(m.get('absorption_db_per_m', 0), 4)} dB/m &times; R"),
                 ("incidence correction", f"{Esc(m.get('angular', '?'))}, referenced to "
                  f"{Num(m.get('reference_angle_deg', 0), 0)} deg (incidence from the DEM's "
                  f"slopes; median {Num(m.get('median_incidence_deg', 0), 1)} deg)"),
                 ("corrected, 5-95 %", f"{Num(m.get('corrected_p05_db', 0), 1)} to "
                  f"{Num(m.get('corrected_p95_db', 0), 1)} dB on {Num(m.get('nodes_filled', 0))} "
                  "nodes (mosaic.tif: backscatter, uncorrected, count)")]
        return "\n".join([Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"),
                          self.Figure(fig, "mosaic", "backscatter mosaic")])

    def SectionViewer(self):
        """The interactive WebGL view: decimated mesh, trajectories before and after SLAM, a
        subset of the soundings, coloured by depth; three.js inlined (no network)."""
        libs = [os.path.join(THREE_DIR, "three.min.js"),
                os.path.join(THREE_DIR, "examples", "js", "controls", "OrbitControls.js"),
                os.path.join(os.path.dirname(os.path.abspath(__file__)),
                             "pitmap-report-viewer3d.js")]
        if not os.path.isfile(libs[2]):  # run from the source tree
            libs[2] = os.path.join(os.path.dirname(os.path.abspath(__file__)), "viewer3d.js")
        absent = [f for f in libs if not os.path.isfile(f)]
        if absent:
            return self.Missing("3D view", "not found: " + ", ".join(absent) +
                                " (Debian's libjs-three: tools/install-deps.sh)")
        mesh = None
        for name in ("mesh_filled.ply", "mesh.ply"):
            try:
                m = self.LoadMesh(name)
            except (OSError, PlyError) as e:
                self.problems.append(f"3D view: {e}")
                continue
            if m is not None and len(m[1]):
                mesh = m
                break
        pts = self.points.get("final") if "final" in self.points else self.points.get("initial")
        if mesh is None and pts is None:
            return self.Missing("3D view", "no mesh and no soundings")
        parts = []
        if mesh is not None:
            parts.append(mesh[0])
        if pts is not None:
            idx = Subsample(len(pts), min(len(pts), 20000))
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
            v, t = DecimateMesh(mesh[0], mesh[1], VIEWER_MAX_TRIANGLES)
            data["mesh"] = {"positions": B64((v - centre).astype("<f4")),
                            "indices": B64(np.asarray(t, dtype="<u4"))}
            facts.append(f"mesh {Num(len(t))} of {Num(len(mesh[1]))} triangles")
        if pts is not None:
            idx = Subsample(len(pts), min(len(pts), VIEWER_MAX_POINTS))
            xyz = np.stack([np.asarray(pts[c][idx], dtype=np.float64) for c in ("x", "y", "z")],
                           axis=1)
            data["points"] = B64((xyz - centre).astype("<f4"))
            facts.append(f"{Num(len(idx))} of {Num(len(pts))} soundings")
        for key, name in (("final", "trajectory_after"), ("initial", "trajectory_before")):
            tr = self.traj.get(key)
            if tr is None:
                continue
            step = max(1, len(tr["x"]) // VIEWER_MAX_TRAJECTORY)
            xyz = np.stack([tr[c][::step] for c in ("x", "y", "z")], axis=1)
            data[name] = B64((xyz - centre).astype("<f4"))
        if "initial" in self.traj:
            facts.append("trajectory before SLAM (orange) and after (white)")
        scripts = []
        for f in libs:
            with open(f, encoding="utf-8") as fh:
                scripts.append(f"<script>{InlineScript(fh.read())}</script>")
        blob = json.dumps(data).replace("</", "<\\/")
        return (f'<p class="caption">Drag to turn, wheel to zoom, right-drag to pan; '
                f'{Esc(", ".join(facts))}; coloured by depth. Local ENU metres about '
                f'({centre[0]:.1f}, {centre[1]:.1f}, {centre[2]:.1f}).</p>\n'
                f'<div id="viewer3d"></div><div id="viewer3d-bar"></div>'
                f'<div id="viewer3d-info" class="caption"></div>\n'
                f'<script type="application/json" id="viewer-data">{blob}</script>\n'
                + "\n".join(scripts))

    def SectionMesh(self):
        meshes = {}
        out = []
        for key, name in (("initial", "mesh_initial.ply"), ("final", "mesh.ply")):
            try:
                m = self.LoadMesh(name)
            except (OSError, PlyError) as e:
                out.append(NotProduced(name, str(e)))
                self.problems.append(str(e))
                continue
            if m is None:
                out.append(self.Missing(name, "no mesh before SLAM" if key == "initial"
                                        else "no mesh after SLAM"))
            elif len(m[1]) == 0:
                out.append(NotProduced(name, "empty mesh"))
            else:
                meshes[key] = m
                Log(f"{name}: {len(m[0])} vertices, {len(m[1])} triangles")
        if not meshes:
            return "\n".join(out)
        xl = Limits([m[0][:, 0] for m in meshes.values()], margin=0.02)
        yl = Limits([m[0][:, 1] for m in meshes.values()], margin=0.02)
        cell = max(0.05, max(xl[1] - xl[0], yl[1] - yl[0]) / 700.0)
        nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
        ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
        grids = {k: RasteriseMesh(v, t, xl[0], yl[0], cell, nx, ny)
                 for k, (v, t) in meshes.items()}
        valid = np.concatenate([g[np.isfinite(g)] for g in grids.values()])
        depth_lim = (np.percentile(self.ref_z - valid, [0.5, 99.5]) if len(valid) else (0, 1))
        norm = Normalize(*depth_lim)
        cmap = plt.get_cmap("turbo_r")
        ls = LightSource(azdeg=315, altdeg=40)
        fig, ax = plt.subplots(1, 2, figsize=(14, float(np.clip(6.0 * ny / nx, 2.5, 9)) + 1.3),
                               squeeze=False, layout="constrained")
        for col, (key, title) in enumerate((("initial", "(c) mesh (before SLAM)"),
                                            ("final", f"(d) mesh ({self.after})"))):
            a = ax[0][col]
            a.set_title(title)
            if key not in grids:
                EmptyPanel(a)
                continue
            g = grids[key]
            filled = FillHoles(g)
            filled_any = np.where(np.isfinite(filled), filled, np.nanmean(g))
            rgb = cmap(norm(self.ref_z - filled_any))[..., :3]
            shaded = ls.shade_rgb(rgb, filled_any, fraction=1.0, blend_mode="soft",
                                  vert_exag=2.0, dx=cell, dy=cell)
            rgba = np.dstack([shaded, np.isfinite(g).astype(float)])
            a.imshow(rgba, origin="lower", extent=(xl[0], xl[0] + nx * cell, yl[0],
                     yl[0] + ny * cell), interpolation="bilinear")
            a.set_xlim(xl)
            a.set_ylim(yl)
            a.set_aspect("equal")
            a.set_xlabel("East x (m)")
            a.set_ylabel("North y (m)")
            v, t = meshes[key]
            a.text(0.01, 0.01, f"{len(v)} vertices, {len(t)} triangles", fontsize=8,
                   transform=a.transAxes)
        sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
        cb = fig.colorbar(sm, ax=ax, shrink=0.9, pad=0.01)
        cb.set_label("depth below the track (m)")
        out.append(self.Figure(fig, "mesh_renders", "mesh renders before and after SLAM"))
        out.append('<p class="caption">Each mesh rasterised from above (highest surface per '
                   f"{cell:.2f} m cell), hill-shaded with light from the north-west (vertical "
                   "exaggeration 2) and coloured by depth; the same colours and axes in both "
                   "panels (paper Fig. 4 c/d). A rough floor or doubled benches before SLAM "
                   "show passes that disagree.</p>")
        out.append(self.Oblique(grids, meshes, xl, yl, cell, norm, cmap, ls))
        return "\n".join(out)

    def Oblique(self, grids, meshes, xl, yl, cell, norm, cmap, ls):
        """An oblique 3-D view of the rasterised meshes (coarse, lit), as a surveyor would
        look into the pit from its rim."""
        step = max(1, int(math.ceil(max(next(iter(grids.values())).shape) / 160)))
        fig = plt.figure(figsize=(14, 6.2))
        for col, (key, title) in enumerate((("initial", "before SLAM"), ("final", self.after))):
            a = fig.add_subplot(1, 2, col + 1, projection="3d")
            a.set_title(f"oblique view, {title}")
            if key not in grids:
                a.text2D(0.5, 0.5, "not produced", ha="center", transform=a.transAxes,
                         color="grey", fontsize=12)
                a.set_axis_off()
                continue
            g = FillHoles(grids[key])[::step, ::step]
            ny, nx = g.shape
            X, Y = np.meshgrid(xl[0] + (np.arange(nx) + 0.5) * cell * step,
                               yl[0] + (np.arange(ny) + 0.5) * cell * step)
            finite = np.isfinite(g)
            gz = np.where(finite, g, np.nanmean(g))
            rgb = ls.shade_rgb(cmap(norm(self.ref_z - gz))[..., :3], gz, fraction=1.0,
                               blend_mode="soft", vert_exag=1.0, dx=cell * step, dy=cell * step)
            rgba = np.dstack([rgb, finite.astype(float)])
            Z = np.where(finite, g, np.nan)
            a.plot_surface(X, Y, Z, facecolors=rgba, rstride=1, cstride=1, linewidth=0,
                           antialiased=False, shade=False)
            a.view_init(elev=35, azim=-60)
            a.set_xlabel("East x (m)")
            a.set_ylabel("North y (m)")
            a.set_zlabel("z (m)")
            # True scale, but never flatter than 0.15 of the width.
            a.set_box_aspect((xl[1] - xl[0], yl[1] - yl[0],
                              max(0.15 * max(xl[1] - xl[0], yl[1] - yl[0]),
                                  float(np.nanmax(g) - np.nanmin(g)))), zoom=1.05)
            a.zaxis.set_major_locator(MaxNLocator(4))
        fig.subplots_adjust(left=0.02, right=0.98, bottom=0.04, top=0.94, wspace=0.05)
        return self.Figure(fig, "mesh_oblique", "oblique 3-D view of the meshes")

    def SectionQuality(self):
        """The quality gates: where a stage said it could not explain its data."""
        gates = self.summary.get("quality_gates")
        if not isinstance(gates, list) or not gates:
            return ('<p>No quality gate tripped: every stage explained its data within the '
                    'limits of the <code>quality</code> configuration.</p>')
        rows = [[Esc(g.get("stage", "?")), Esc(g.get("gate", "?")), Esc(g.get("message", ""))]
                for g in gates if isinstance(g, dict)]
        return ('<p class="problem">' + str(len(rows)) + " quality gate(s) tripped: the "
                "products below are what the processing could make, but these stages could not "
                "explain their data. Read the reasons before using the results.</p>" +
                Table(rows, header=["stage", "gate", "what was found"]))

    def SectionClock(self):
        clk = self.summary.get("sonar_clock")
        if not isinstance(clk, dict):
            return self.Missing("sonar clock", "summary.json has no sonar_clock (older run)")
        facts = [("time source of the pings", Esc(clk.get("source", "?")))]
        if clk.get("configured"):
            facts.append(("configured offset", f"{Num(clk.get('configured_offset_s', 0), 4)} s"))
        co = clk.get("coarse")
        if isinstance(co, dict):
            facts.append(("coarse estimate (" + Esc(co.get("method", "?")) + ")",
                          Esc(co.get("message", ""))))
        if "latency_s" in clk:
            facts.append(("latency from the soundings",
                          f"{Num(1e3 * float(clk['latency_s']), 2)} ms (formal sd "
                          f"{Num(1e3 * float(clk.get('latency_formal_sd_s', 0)), 2)} ms)"))
        facts.append(("correction applied to the ping times",
                      f"{Num(float(clk.get('correction_s', 0)), 4)} s &plusmn; "
                      f"{Num(float(clk.get('sigma_s', 0)), 4)} s"))
        if "estimated_offset_s" in clk:
            facts.append(("offset the data imply", f"{Num(clk['estimated_offset_s'], 4)} s"))
        return Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts")

    def SectionBoresight(self):
        out = []
        cal = self.stages.get("calibrate")
        bs_file = self.P("boresight.json")
        mount = None
        if os.path.isfile(bs_file):
            try:
                with open(bs_file) as f:
                    mount = json.load(f)
            except (OSError, ValueError) as e:
                out.append(NotProduced("boresight.json", f"unreadable: {e}"))
        else:
            out.append(self.Missing("boresight.json"))
        if not isinstance(cal, dict):
            out.append(self.Missing("boresight calibration",
                                    "no calibrate stage in summary.json; the mount was used "
                                    "as configured"))
            if isinstance(mount, dict):
                out.append(Table([[Esc(a), Num(float(mount.get(f"{a}_deg", float("nan"))), 4)]
                                  for a in ("roll", "pitch", "yaw")],
                                 header=["axis", "boresight used (deg)"]))
            return "\n".join(out)
        b0 = cal.get("boresight_before") or {}
        b1 = cal.get("boresight_after") or mount or {}
        sd = cal.get("formal_sd_deg") or [float("nan")] * 3
        rows = []
        for i, axis in enumerate(("roll", "pitch", "yaw")):
            a0 = float(b0.get(f"{axis}_deg", float("nan")))
            a1 = float(b1.get(f"{axis}_deg", float("nan")))
            rows.append([axis, Num(a0, 4), Num(a1, 4), Num(a1 - a0, 4),
                         Num(float(sd[i]) if i < len(sd) else float("nan"), 4)])
        out.append(Table(rows, header=["axis", "before (deg)", "after (deg)", "change (deg)",
                                       "formal sd (deg)"]))
        facts = []
        if "residual_before_rms_m" in cal or "residual_after_rms_m" in cal:
            r0 = cal.get("residual_before_rms_m", float("nan"))
            r1 = cal.get("residual_after_rms_m", float("nan"))
            facts.append(("residual RMS", f"{Num(r0, 4)} &rarr; {Num(r1, 4)} m"))
        for k in ("pairs", "iterations", "termination", "height_offsets_rms_m"):
            if k in cal:
                facts.append((k.replace("_", " "), Num(cal[k], 4)))
        seg = cal.get("segment")
        if isinstance(seg, dict) and "start_s" in seg:
            t0 = self.t0 or seg["start_s"]
            facts.append(("calibration segment",
                          f"{(seg['start_s'] - t0) / 60:.2f} to "
                          f"{(seg.get('end_s', 0) - t0) / 60:.2f}"
                          f" min since start ({seg.get('end_s', 0) - seg['start_s']:.0f} s)"))
        if cal.get("message"):
            facts.append(("message", Esc(cal["message"])))
        out.append(Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
        ver = cal.get("verify")
        if isinstance(ver, list) and ver:
            t0 = self.t0 or 0.0
            rows = []
            for v in ver:
                rows.append([f"{(v.get('start_s', 0) - t0) / 60:.2f}&ndash;"
                             f"{(v.get('end_s', 0) - t0) / 60:.2f}",
                             Num(float(v.get("rms_before_m", float("nan"))), 4),
                             Num(float(v.get("rms_after_m", float("nan"))), 4),
                             Num(v.get("pairs", 0))])
            out.append("<h3>Verification segments</h3>")
            out.append(Table(rows, header=["segment (min since start)", "RMS before (m)",
                                           "RMS after (m)", "pairs"]))
        else:
            out.append(NotProduced("verification segments", "calibrate reported none"))
        return "\n".join(out)

    def SectionTsdf(self):
        fuse = self.stages.get("fuse")
        if not isinstance(fuse, dict):
            return self.Missing("TSDF fusion statistics", "no fuse stage in summary.json")
        out = []

        def Hist(stage):
            h = stage.get("weight_histogram") if isinstance(stage, dict) else None
            if isinstance(h, dict) and len(h.get("counts", [])) and \
                    len(h.get("edges", [])) == len(h["counts"]) + 1:
                return (np.asarray(h["edges"], dtype=np.float64),
                        np.asarray(h["counts"], dtype=np.float64), bool(h.get("before_filter")))
            return None

        h = Hist(fuse)
        h0 = Hist(self.stages.get("fuse_initial"))
        if h is not None:
            edges, counts, before_filter = h
            fig, a = plt.subplots(figsize=(12, 4.2), layout="constrained")
            a.bar(edges[:-1], np.where(counts > 0, counts, np.nan), width=np.diff(edges),
                  align="edge", color="tab:blue", edgecolor="white", linewidth=0.5,
                  label=f"{self.after} (fuse)")
            if h0 is not None:
                a.stairs(np.where(h0[1] > 0, h0[1], np.nan), h0[0], color="k", ls="--", lw=1.2,
                         label="before SLAM (fuse_initial)")
            a.set_yscale("log")
            # 1-2-5 steps with k/M labels: a histogram spanning one decade still gets labels.
            a.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            a.yaxis.set_major_formatter(EngFormatter(sep=" "))
            a.set_xlabel("voxel weight (number of updates, capped at w_max)")
            a.set_ylabel("active voxels")
            a.xaxis.set_major_locator(MaxNLocator(integer=True))
            a.grid(alpha=0.3, which="both", axis="y")
            mw = fuse.get("min_weight")
            if isinstance(mw, (int, float)):
                a.axvline(float(mw), color="tab:red", ls="--", label=f"filter min weight {mw:g}")
            a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9)
            when = " (before the weight filter)" if before_filter else ""
            a.set_title("TSDF weight histogram" + when)
            out.append(self.Figure(fig, "tsdf_weights", "TSDF weight histogram"))
            out.append('<p class="caption">How often each voxel was observed. Voxels under the '
                       "filter weight are dropped before meshing (outlier surfaces); the last "
                       "bin holds the voxels at the weight cap.</p>")
        else:
            out.append(self.Missing("TSDF weight histogram",
                                    "no stages.fuse.weight_histogram {edges, counts}"))
        facts = [(k.replace("_", " "), Num(v, 4)) for k, v in fuse.items()
                 if isinstance(v, (int, float, str, bool)) and k not in ("seconds", "peak_rss_mb")]
        for k, v in fuse.items():
            if isinstance(v, dict) and k != "weight_histogram":
                facts += [(f"{k} {kk}".replace("_", " "), Num(vv, 4)) for kk, vv in v.items()
                          if isinstance(vv, (int, float, str, bool))]
        if facts:
            out.append(Table([(f"<b>{Esc(k)}</b>", v) for k, v in facts], cls="facts"))
        return "\n".join(out)

    def SectionSlam(self):
        slam = self.stages.get("slam")
        if not isinstance(slam, dict):
            return self.Missing("SLAM statistics", "no slam stage in summary.json")
        out = []
        its = [i for i in slam.get("iterations") or [] if isinstance(i, dict)]
        if its:
            stages = [str(i.get("stage", "?")) for i in its]
            xs = np.arange(1, len(its) + 1)
            fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
            keys = [("pair_rms_m", "pair RMS distance (m)", False),
                    ("cost", "cost (sum of squared whitened residuals)", True),
                    ("consistency_m", "consistency score (m, lower is better)", False)]
            colours = {"rigid": "tab:blue", "semi_rigid": "tab:orange"}
            for a, (k, label, logy) in zip(ax, keys):
                vals = np.array([float(i.get(k, np.nan)) for i in its])
                for st in dict.fromkeys(stages):
                    m = np.array([s == st for s in stages])
                    a.plot(xs[m], vals[m], "o-", ms=4, color=colours.get(st, "tab:green"),
                           label=st.replace("_", "-"))
                best = np.array([bool(i.get("best", False)) for i in its])
                if best.any():
                    a.plot(xs[best], vals[best], "o", ms=9, mfc="none", mec="k",
                           label="best so far")
                if logy and np.all(vals[np.isfinite(vals)] > 0):
                    a.set_yscale("log")
                a.set_xlabel("iteration (rigid, then semi-rigid)")
                a.xaxis.set_major_locator(MaxNLocator(integer=True))
                a.set_ylabel(label)
                a.grid(alpha=0.3)
            ax[0].legend(fontsize=8)
            fig.suptitle("SLAM per iteration")
            fig.tight_layout()
            out.append(self.Figure(fig, "slam_iterations", "SLAM per-iteration trend"))
        else:
            out.append(self.Missing("SLAM iterations", "no stages.slam.iterations"))
        facts = []
        if "initial_consistency_m" in slam or "final_consistency_m" in slam:
            c0 = slam.get("initial_consistency_m", float("nan"))
            c1 = slam.get("final_consistency_m", float("nan"))
            facts.append(("consistency", f"{Num(c0, 4)} &rarr; {Num(c1, 4)} m"))
        facts += [(k.replace("_", " "), Num(v, 4)) for k, v in slam.items()
                  if isinstance(v, (int, float, str, bool)) and k not in
                  ("seconds", "peak_rss_mb", "initial_consistency_m", "final_consistency_m")]
        if facts:
            out.append(Table([(f"<b>{Esc(k)}</b>", v) for k, v in facts], cls="facts"))
        return "\n".join(out)

    def StageOrder(self):
        order = self.summary.get("stage_order")
        if isinstance(order, list) and order:
            names = [str(n) for n in order if n in self.stages]
        else:
            names = [n for n in PIPELINE_STAGES if n in self.stages]
        return names + [n for n in self.stages if n not in names]

    def SectionStages(self):
        names = self.StageOrder()
        if not names:
            return self.Missing("stage statistics", "summary.json has no stages")
        rows = []
        secs, mems = [], []
        for n in names:
            st = self.stages.get(n) or {}
            s = st.get("seconds")
            m = st.get("peak_rss_mb")
            secs.append(float(s) if isinstance(s, (int, float)) else 0.0)
            mems.append(float(m) if isinstance(m, (int, float)) else float("nan"))
            counts = [f"{Esc(k.replace('_', ' '))} {Num(v, 4)}" for k, v in st.items()
                      if isinstance(v, (int, float, bool)) and not isinstance(v, bool)
                      and k not in ("seconds", "peak_rss_mb")]
            rows.append([f"<b>{Esc(n)}</b>", Num(s, 2) if s is not None else "&ndash;",
                         Num(m, 0) if m is not None else "&ndash;",
                         '<span class="counts">' + ", ".join(counts) + "</span>"])
        total = self.summary.get("total_seconds")
        rows.append(["<b>total</b>", Num(total, 2) if total is not None else Num(sum(secs), 2),
                     Num(float(np.nanmax(mems)), 0) if np.isfinite(mems).any() else "&ndash;",
                     "peak memory is the largest of the stages"])
        out = [Table(rows, header=["stage", "seconds", "peak RSS (MB)", "counts"], cls="stages")]
        fig, ax = plt.subplots(1, 2, figsize=(13, 0.45 * len(names) + 1.4))
        yy = np.arange(len(names))[::-1]
        ax[0].barh(yy, secs, color="tab:blue")
        ax[0].set_xlabel("seconds")
        ax[1].barh(yy, np.nan_to_num(mems), color="tab:purple")
        ax[1].set_xlabel("peak RSS (MB)")
        for a in ax:
            a.set_yticks(yy, names)
            a.grid(alpha=0.3, axis="x")
        fig.tight_layout()
        out.append(self.Figure(fig, "stages", "time and memory per stage"))
        return "\n".join(out)

    def LoadScores(self):
        """Scores from pitmap-eval --json (optional); the reason is kept when unusable."""
        path = self.scores_path
        name = os.path.basename(path)
        if not os.path.isfile(path):
            return
        try:
            with open(path) as f:
                scores = json.load(f)
        except (OSError, ValueError) as e:
            self.unusable[name] = f"unreadable: {e}"
            return
        if not isinstance(scores, dict):
            self.unusable[name] = "not a JSON object"
            return
        self.scores = scores

    def ScoreText(self, before, after, label):
        """'label: 1.23 -> 0.45 m' from two scores when both exist, else ''."""
        b, a = self.scores.get(before), self.scores.get(after)
        if isinstance(b, (int, float)) and isinstance(a, (int, float)):
            return f"{label} {b:.3f} &rarr; {a:.3f} m (scores.json)"
        return ""

    def SectionScores(self):
        if not self.scores:
            return self.Missing(os.path.basename(self.scores_path),
                                "no ground truth given (pitmap-eval --json)")
        rows = [[Esc(k), Num(v, 4) if isinstance(v, (int, float)) else Esc(v),
                 Esc(SCORE_MEANINGS.get(k, ""))] for k, v in self.scores.items()]
        return Table(rows, header=["score", "value", "meaning"])

    # ---- page
    def Build(self):
        self.LoadTrajectories()
        self.LoadPoints()
        self.LoadScores()
        sections = [
            ("summary", "Survey", self.SectionHeader),
            ("quality", "Quality gates", self.SectionQuality),
            ("trajectory", "Trajectory before and after SLAM", self.SectionTrajectory),
            ("cross-sections", "Cross-sections of the point cloud", self.SectionCrossSections),
            ("depth", "Depth-coloured top view", self.SectionDepth),
            ("hydro", "Vertical datum and IHO S-44 quality control", self.SectionHydro),
            ("mosaic", "Backscatter mosaic", self.SectionMosaic),
            ("mesh", "Mesh before and after SLAM", self.SectionMesh),
            ("viewer", "Interactive 3D view", self.SectionViewer),
            ("boresight", "Boresight calibration", self.SectionBoresight),
            ("clock", "Sonar clock and latency", self.SectionClock),
            ("tsdf", "TSDF weight histogram", self.SectionTsdf),
            ("slam", "SLAM per iteration", self.SectionSlam),
            ("stages", "Stages: time and memory", self.SectionStages),
            ("scores", "Scores against ground truth", self.SectionScores),
        ]
        body = []
        for sid, heading, fn in sections:
            Log(f"section {sid}")
            try:
                frag = fn()
            except Exception as e:  # a broken product must not cost the whole report
                Log(f"section {sid} failed: {type(e).__name__}: {e}")
                self.problems.append(f"{heading}: {type(e).__name__}: {e}")
                frag = f'<p class="problem">could not draw: {Esc(type(e).__name__)}: {Esc(e)}</p>'
                plt.close("all")
            body.append(f'<section id="{sid}"><h2>{Esc(heading)}</h2>\n{frag}\n</section>')
        toc = " &middot; ".join(f'<a href="#{sid}">{Esc(h)}</a>' for sid, h, _ in sections)
        notes = []
        if self.missing:
            notes.append('<p class="missing">not produced: ' +
                         ", ".join(Esc(m) for m in self.missing) + "</p>")
        for p in self.problems:
            notes.append(f'<p class="problem">{Esc(p)}</p>')
        return PAGE.format(title=Esc(self.title), toc=toc, notes="\n".join(notes),
                           body="\n".join(body), css=CSS)


CSS = """
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; margin: 0 auto;
       max-width: 1400px; padding: 0 24px 48px; color: #222; background: #fff; }
h1 { margin: 24px 0 4px; font-size: 26px; }
h2 { margin-top: 36px; border-bottom: 2px solid #2a6f97; padding-bottom: 4px; color: #1d4e6b; }
h3 { margin-bottom: 6px; }
nav { font-size: 14px; margin: 8px 0 16px; line-height: 1.7; }
nav a { color: #2a6f97; text-decoration: none; }
table { border-collapse: collapse; margin: 8px 0; font-size: 14px; }
th, td { border: 1px solid #ccc; padding: 4px 10px; text-align: left; vertical-align: top; }
th { background: #eef3f7; }
td:nth-child(n+2) { font-variant-numeric: tabular-nums; }
table.facts td:first-child { white-space: nowrap; background: #f7f9fb; }
table.stages .counts { font-size: 12px; color: #444; }
img { max-width: 100%; height: auto; display: block; margin: 8px 0; }
.caption { font-size: 13px; color: #555; max-width: 1100px; }
.missing { color: #8a5a00; background: #fff6e0; padding: 4px 8px; border-left: 4px solid #e0a000; }
.problem { color: #900; background: #fde8e8; padding: 4px 8px; border-left: 4px solid #c00; }
footer { margin-top: 40px; font-size: 12px; color: #777; }
#viewer3d { width: 100%; height: 620px; background: #15191d; }
#viewer3d-bar { margin: 6px 0; font-size: 14px; }
#viewer3d-bar button { margin-right: 8px; }
"""

PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>{css}</style>
</head>
<body>
<h1>{title}</h1>
<nav>{toc}</nav>
{notes}
{body}
<footer>pitmap-report. Local frame: East, North, Up metres at the world origin;
times in GPS seconds since 1980-01-06 unless marked UTC.</footer>
</body>
</html>
"""


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description="Write P/report.html (self-contained, "
                                 "PNG plots embedded) and P/report/*.png from a pitmap products "
                                 "folder P.")
    ap.add_argument("products", metavar="P", help="products folder (pitmap run --out P)")
    ap.add_argument("--scores", metavar="FILE",
                    help="scores JSON from pitmap-eval --json (default: P/scores.json)")
    ap.add_argument("--title", metavar="TEXT", help="report title")
    args = ap.parse_args(argv)
    folder = os.path.abspath(args.products)
    if not os.path.isdir(folder):
        print(f"{PROG}: {args.products}: not a folder", file=sys.stderr)
        return 1
    title = args.title or f"pitmap survey report: {os.path.basename(folder)}"
    scores = args.scores or os.path.join(folder, "scores.json")
    try:
        report = Report(folder, scores, title)
        page = report.Build()
    except ReportError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    out = os.path.join(folder, "report.html")
    tmp = out + ".tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(page)
        os.replace(tmp, out)
    except OSError as e:
        print(f"{PROG}: {out}: cannot write: {e}", file=sys.stderr)
        return 1
    Log(f"wrote {out} ({os.path.getsize(out) // 1024} kB)"
        + (f"; not produced: {', '.join(report.missing)}" if report.missing else "")
        + (f"; {len(report.problems)} problem(s)" if report.problems else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
