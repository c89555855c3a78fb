# SPDX-License-Identifier: MIT
"""Gridding (mean/max rasters, hole filling, mesh rasterising, mesh decimation, subsampling)
and figure making for pitmap-report. Pure numpy except the matplotlib figure helpers."""

import base64
import io
import math
import os

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .util import esc, log  # noqa: E402

MAX_SCATTER_POINTS = 150_000  # per panel
FIG_DPI = 100


def decimate_mesh(xyz, tri, max_triangles):
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


def subsample(n, k, seed=0):
    """Sorted indices of at most k of n items (all when n <= k)."""
    if n <= k:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(n, size=k, replace=False))


def limits(arrays, margin=0.03, lo_pct=None):
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


def empty_panel(a):
    """A panel whose product does not exist: a grey note, no axes."""
    a.text(0.5, 0.5, "not produced", ha="center", va="center", transform=a.transAxes,
           color="grey", fontsize=12)
    a.set_xticks([])
    a.set_yticks([])
    for sp in a.spines.values():
        sp.set_color("0.85")


def raster_mean(x, y, v, x0, y0, cell, nx, ny):
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


def raster_max(x, y, v, x0, y0, cell, nx, ny):
    """Largest v per grid cell (the surface seen from above), NaN where empty."""
    ix = np.floor((x - x0) / cell).astype(np.int64)
    iy = np.floor((y - y0) / cell).astype(np.int64)
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny) & np.isfinite(v)
    flat = iy[ok] * nx + ix[ok]
    vv = v[ok]
    grid = np.full(nx * ny, np.nan)
    if len(flat):
        # Grouped by cell (one sort key, not two), the largest of each group by reduceat.
        order = np.argsort(flat)
        fs = flat[order]
        first = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
        grid[fs[first]] = np.maximum.reduceat(vv[order], first)
    return grid.reshape(ny, nx)


def fill_holes(grid, passes=2):
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


def rasterise_mesh(v, t, x0, y0, cell, nx, ny, chunk=300_000):
    """Top surface of a triangle mesh on a grid: each triangle is sampled on a barycentric
    lattice fine enough to hit every cell it covers, the highest sample per cell wins.
    Triangles go in chunks so that memory stays bounded for meshes of millions."""
    grid = raster_max(v[:, 0], v[:, 1], v[:, 2], x0, y0, cell, nx, ny)
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
        grid = np.fmax(grid, raster_max(np.concatenate(xs), np.concatenate(ys),
                                        np.concatenate(zs), x0, y0, cell, nx, ny))
    return grid


def save_figure(fig, fig_dir, name, alt):
    """fig as fig_dir/name.png, closed; returns an <img> with the PNG as a data URI."""
    path = os.path.join(fig_dir, name + ".png")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=FIG_DPI)
    plt.close(fig)
    data = buf.getvalue()
    with open(path, "wb") as f:
        f.write(data)
    log(f"figure {name}.png ({len(data) // 1024} kB)")
    b64 = base64.b64encode(data).decode("ascii")
    return f'<img alt="{esc(alt)}" src="data:image/png;base64,{b64}">'
