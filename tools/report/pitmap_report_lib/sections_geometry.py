# SPDX-License-Identifier: MIT
"""The report's geometry sections: the trajectory before/after SLAM, the point-cloud
cross-sections, the depth-coloured top view and the mesh renders (paper Figs. 3 and 4)."""

import math

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.colors import LightSource, Normalize  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from .loaders import PlyError  # noqa: E402
from .rasters import (MAX_SCATTER_POINTS, empty_panel, fill_holes, limits,  # noqa: E402
                      rasterise_mesh, raster_mean, subsample)
from .util import log, num, not_produced, table  # noqa: E402


def trajectory(p):
    if not p.traj:
        return "\n".join(p.missing_product(n, "no trajectory")
                         for n in ("trajectory_initial.csv", "trajectory.csv"))
    out = []
    if "initial" not in p.traj:
        out.append(p.missing_product("trajectory_initial.csv", "no before-SLAM trajectory"))
    if "final" not in p.traj:
        out.append(p.missing_product("trajectory.csv", "no after-SLAM trajectory"))
    trs = p.traj
    dec = {k: slice(None, None, max(1, len(v["t"]) // 20000)) for k, v in trs.items()}
    xl = limits([v["x"] for v in trs.values()])
    yl = limits([v["y"] for v in trs.values()])
    zl = limits([v["z"] for v in trs.values()], margin=0.08)
    tl = limits([p.minutes_of(v["t"]) for v in trs.values()], margin=0.01)
    top_h = float(np.clip(6.0 * (yl[1] - yl[0]) / (xl[1] - xl[0]), 2.5, 9.0))
    fig, ax = plt.subplots(2, 2, figsize=(13, top_h + 4.6), height_ratios=[top_h, 3.0],
                           layout="constrained")
    panels = [("initial", "(a) before SLAM (GPS/INS)", "k", "--"),
              ("final", f"(b) {p.after}", "tab:red", "-")]
    for col, (key, title, colour, ls) in enumerate(panels):
        a_top, a_z = ax[0][col], ax[1][col]
        if key not in trs:
            for a in (a_top, a_z):
                empty_panel(a)
            a_top.set_title(title)
            continue
        tr, d = trs[key], dec[key]
        if key == "final" and "initial" in trs:
            ti, di = trs["initial"], dec["initial"]
            a_top.plot(ti["x"][di], ti["y"][di], color="0.7", ls="--", lw=0.7,
                       label="before SLAM")
            a_z.plot(p.minutes_of(ti["t"][di]), ti["z"][di], color="0.7", ls="--", lw=0.7,
                     label="before SLAM")
        a_top.plot(tr["x"][d], tr["y"][d], color=colour, ls=ls, lw=0.9,
                   label=title.split(") ")[1])
        a_top.plot(tr["x"][0], tr["y"][0], "o", color=colour, ms=5, label="start")
        a_z.plot(p.minutes_of(tr["t"][d]), tr["z"][d], color=colour, ls=ls, lw=0.9,
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
    out.append(p.figure(fig, "trajectory", "trajectory before and after SLAM"))
    ate = p.score_text("trajectory_ate_rmse_before_m", "trajectory_ate_rmse_m",
                       " Trajectory error (RMS vs truth):")
    out.append('<p class="caption">Top: the track seen from above; bottom: its height over '
               "time. A surface vehicle moves on a plane: after SLAM the height should be "
               f"flat. Both columns share their axis limits.{ate}</p>")
    return "\n".join(out)


def cross_sections(p):
    if not p.points:
        return "\n".join(p.missing_product(n, "no point cloud")
                         for n in ("points_initial.ply", "points.ply"))
    out = []
    if "initial" not in p.points:
        out.append(p.missing_product("points_initial.ply", "no before-SLAM point cloud"))
    if "final" not in p.points:
        out.append(p.missing_product("points.ply", "no after-SLAM point cloud"))
    ref = p.points.get("final", p.points.get("initial"))
    step = max(1, len(ref) // 200_000)
    xs = np.asarray(ref["x"][::step], dtype=np.float64)
    ys = np.asarray(ref["y"][::step], dtype=np.float64)
    xc = 0.5 * sum(np.percentile(xs, [1, 99])) if len(xs) else 0.0
    yc = 0.5 * sum(np.percentile(ys, [1, 99])) if len(ys) else 0.0
    half = 0.5
    cuts = {}  # (axis, key) -> (u, z, minutes)
    for key, pts in p.points.items():
        x = np.asarray(pts["x"], dtype=np.float64)
        y = np.asarray(pts["y"], dtype=np.float64)
        has_t = "gps_time_s" in pts.dtype.names
        for axis, sel, u in (("x", np.abs(y - yc) < half, x), ("y", np.abs(x - xc) < half, y)):
            idx = np.nonzero(sel)[0]
            idx = idx[subsample(len(idx), MAX_SCATTER_POINTS, seed=1)]
            # Drawn in random order: in time order the last pass would hide the others.
            np.random.default_rng(2).shuffle(idx)
            z = np.asarray(pts["z"][idx], dtype=np.float64)
            m = p.minutes_of(pts["gps_time_s"][idx]) if has_t else np.zeros(len(idx))
            cuts[(axis, key)] = (u[idx], z, m)
        del x, y
    all_m = [c[2] for c in cuts.values() if len(c[2])]
    tnorm = Normalize(min(float(m.min()) for m in all_m) if all_m else 0,
                      max(float(m.max()) for m in all_m) if all_m else 1)
    geom = {}
    for axis in ("x", "y"):
        ul = limits([cuts[(axis, k)][0] for k in p.points], margin=0.02, lo_pct=0.2)
        zl = limits([cuts[(axis, k)][1] for k in p.points], margin=0.05, lo_pct=0.2)
        # Vertical exaggeration so that a panel is about 2.8 times as wide as high.
        ve = max(1.0, round(2 * (ul[1] - ul[0]) / (2.8 * (zl[1] - zl[0]))) / 2)
        geom[axis] = (ul, zl, ve, 5.6 * ve * (zl[1] - zl[0]) / (ul[1] - ul[0]))
    fig, ax = plt.subplots(2, 2, figsize=(13, geom["x"][3] + geom["y"][3] + 1.8),
                           height_ratios=[geom["x"][3], geom["y"][3]], layout="constrained")
    sc = None
    for row, axis in enumerate(("x", "y")):
        ul, zl, ve, _ = geom[axis]
        for col, (key, title) in enumerate((("initial", "(c) before SLAM"),
                                            ("final", f"(d) {p.after}"))):
            a = ax[row][col]
            where = (f"slab y = {round(yc, 1) + 0.0:.1f} \u00b1 {half} m" if axis == "x"
                     else f"slab x = {round(xc, 1) + 0.0:.1f} \u00b1 {half} m")
            a.set_title(f"{title}: along {axis}, {where}", fontsize=10)
            if (axis, key) not in cuts:
                empty_panel(a)
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
    out.append(p.figure(fig, "cross_sections", "point cloud cross-sections before/after"))
    out.append('<p class="caption">Points within 0.5 m of a vertical plane through the middle '
               "of the survey, coloured by the time they were measured. Passes that disagree "
               "show as doubled walls or floors in different colours (paper Fig. 3 c/d).</p>")
    return "\n".join(out)


def depth_top_view(p):
    if "final" not in p.points:
        return p.missing_product("points.ply", "no after-SLAM point cloud")
    pts = p.points["final"]
    x = np.asarray(pts["x"], dtype=np.float64)
    y = np.asarray(pts["y"], dtype=np.float64)
    z = np.asarray(pts["z"], dtype=np.float64)
    xl = limits([x], margin=0.02, lo_pct=0.05)
    yl = limits([y], margin=0.02, lo_pct=0.05)
    cell = max(0.1, max(xl[1] - xl[0], yl[1] - yl[0]) / 500.0)
    nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
    ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
    grid = fill_holes(raster_mean(x, y, p.ref_z - z, xl[0], yl[0], cell, nx, ny), passes=1)
    del x, y, z
    valid = grid[np.isfinite(grid)]
    vmin, vmax = (np.percentile(valid, [0.5, 99.5]) if len(valid) else (0, 1))
    fig, a = plt.subplots(figsize=(12, float(np.clip(10.5 * ny / nx, 3, 14)) + 0.8),
                          layout="constrained")
    im = a.imshow(grid, origin="lower", extent=(xl[0], xl[0] + nx * cell, yl[0],
                  yl[0] + ny * cell), cmap="turbo_r", vmin=vmin, vmax=vmax,
                  interpolation="nearest")
    tr = p.traj.get("final")
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
    cb.set_label(f"depth below the track (m; track median z = {p.ref_z:.2f} m)")
    return "\n".join([p.figure(fig, "depth_top_view", "depth-coloured top view"),
                      f'<p class="caption">{num(len(pts))} points rasterised; white cells '
                      "hold no point (single empty cells are filled from their "
                      "neighbours).</p>"])


def mesh(p):
    meshes = {}
    out = []
    for key, name in (("initial", "mesh_initial.ply"), ("final", "mesh.ply")):
        try:
            m = p.load_mesh(name)
        except (OSError, PlyError) as e:
            out.append(not_produced(name, str(e)))
            if str(e) not in p.problems:
                p.problems.append(str(e))
            continue
        if m is None:
            out.append(p.missing_product(name, "no mesh before SLAM" if key == "initial"
                                         else "no mesh after SLAM"))
        elif len(m[1]) == 0:
            out.append(not_produced(name, "empty mesh"))
        else:
            meshes[key] = m
            log(f"{name}: {len(m[0])} vertices, {len(m[1])} triangles")
    if not meshes:
        return "\n".join(out)
    xl = limits([m[0][:, 0] for m in meshes.values()], margin=0.02)
    yl = limits([m[0][:, 1] for m in meshes.values()], margin=0.02)
    cell = max(0.05, max(xl[1] - xl[0], yl[1] - yl[0]) / 700.0)
    nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
    ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
    grids = {k: rasterise_mesh(v, t, xl[0], yl[0], cell, nx, ny)
             for k, (v, t) in meshes.items()}
    valid = np.concatenate([g[np.isfinite(g)] for g in grids.values()])
    depth_lim = (np.percentile(p.ref_z - valid, [0.5, 99.5]) if len(valid) else (0, 1))
    norm = Normalize(*depth_lim)
    cmap = plt.get_cmap("turbo_r")
    ls = LightSource(azdeg=315, altdeg=40)
    fig, ax = plt.subplots(1, 2, figsize=(14, float(np.clip(6.0 * ny / nx, 2.5, 9)) + 1.3),
                           squeeze=False, layout="constrained")
    for col, (key, title) in enumerate((("initial", "(c) mesh (before SLAM)"),
                                        ("final", f"(d) mesh ({p.after})"))):
        a = ax[0][col]
        a.set_title(title)
        if key not in grids:
            empty_panel(a)
            continue
        g = grids[key]
        filled = fill_holes(g)
        filled_any = np.where(np.isfinite(filled), filled, np.nanmean(g))
        rgb = cmap(norm(p.ref_z - filled_any))[..., :3]
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
    out.append(p.figure(fig, "mesh_renders", "mesh renders before and after SLAM"))
    out.append('<p class="caption">Each mesh rasterised from above (highest surface per '
               f"{cell:.2f} m cell), hill-shaded with light from the north-west (vertical "
               "exaggeration 2) and coloured by depth; the same colours and axes in both "
               "panels (paper Fig. 4 c/d). A rough floor or doubled benches before SLAM "
               "show passes that disagree.</p>")
    out.append(oblique_view(p, grids, meshes, xl, yl, cell, norm, cmap, ls))
    return "\n".join(out)


def oblique_view(p, grids, meshes, xl, yl, cell, norm, cmap, ls):
    """An oblique 3-D view of the rasterised meshes (coarse, lit), as a surveyor would
    look into the pit from its rim."""
    step = max(1, int(math.ceil(max(next(iter(grids.values())).shape) / 160)))
    fig = plt.figure(figsize=(14, 6.2))
    for col, (key, title) in enumerate((("initial", "before SLAM"), ("final", p.after))):
        a = fig.add_subplot(1, 2, col + 1, projection="3d")
        a.set_title(f"oblique view, {title}")
        if key not in grids:
            a.text2D(0.5, 0.5, "not produced", ha="center", transform=a.transAxes,
                     color="grey", fontsize=12)
            a.set_axis_off()
            continue
        g = fill_holes(grids[key])[::step, ::step]
        ny, nx = g.shape
        X, Y = np.meshgrid(xl[0] + (np.arange(nx) + 0.5) * cell * step,
                           yl[0] + (np.arange(ny) + 0.5) * cell * step)
        finite = np.isfinite(g)
        gz = np.where(finite, g, np.nanmean(g))
        rgb = ls.shade_rgb(cmap(norm(p.ref_z - gz))[..., :3], gz, fraction=1.0,
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
    return p.figure(fig, "mesh_oblique", "oblique 3-D view of the meshes")


# 95 % radius over the horizontal 1-sigma sqrt((sE^2 + sN^2) / 2) (IHO S-44's THU factor).
_CIRCULAR95 = 2.4477


def trajectory_sigma(p, window_s=30.0):
    """How well the trajectory is known along the track: P/trajectory_sigma.csv's stated 95 %
    horizontal radius per ping (SLAM's posterior where it was used, else the INS's), against
    the INS's own, over time and per window_s window. None when the product is absent (a
    survey processed without it)."""
    path = p.path("trajectory_sigma.csv")
    try:
        d = np.genfromtxt(path, delimiter=",", names=True)
    except (OSError, ValueError):
        return None
    need = ("gps_time_s", "sigma_east_m", "sigma_north_m", "ins_sigma_east_m",
            "ins_sigma_north_m", "slam_posterior")
    if d.size < 2 or any(n not in d.dtype.names for n in need):
        return None
    t = d["gps_time_s"]
    stated = _CIRCULAR95 * np.sqrt(0.5 * (d["sigma_east_m"] ** 2 + d["sigma_north_m"] ** 2))
    ins = _CIRCULAR95 * np.sqrt(0.5 * (d["ins_sigma_east_m"] ** 2 + d["ins_sigma_north_m"] ** 2))
    slam = d["slam_posterior"] != 0
    minutes = p.minutes_of(t)
    fig, ax = plt.subplots(figsize=(13, 3.6), layout="constrained")
    ax.semilogy(minutes, ins, color="0.6", ls="--", lw=0.8, label="INS's own")
    ax.semilogy(minutes, stated, color="tab:blue", lw=0.9,
                label="stated (SLAM's posterior)" if slam.any() else "stated (the INS's)")
    ax.set_xlabel("time since start (min)")
    ax.set_ylabel("95 % horizontal radius (m)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8)
    out = [p.figure(fig, "trajectory_sigma", "95 % horizontal radius of the trajectory")]
    rows = []
    t0 = float(t[0])
    n = int(math.ceil((float(t[-1]) - t0) / window_s)) or 1
    for k in range(n):
        m = (t >= t0 + k * window_s) & (t < t0 + (k + 1) * window_s)
        if k == n - 1:
            m |= t == t[-1]
        if not m.any():
            continue
        rows.append((f"{num(float(minutes[m][0]), 1)}&ndash;{num(float(minutes[m][-1]), 1)}",
                     num(float(np.median(stated[m])), 3), num(float(np.max(stated[m])), 3),
                     num(float(np.median(ins[m])), 3),
                     f"{100.0 * float(np.mean(slam[m])):.0f} %"))
    out.append(table(rows, header=("minutes", "stated 95 % radius, median (m)", "max (m)",
                                   "INS's own, median (m)", "pings with SLAM's posterior")))
    out.append('<p class="caption">The horizontal position of each ping as the processing '
               "knows it: the 95 % radius it states (SLAM's posterior where the TPU took it, "
               f"else the INS's sigma), per {window_s:.0f} s window along the track; the INS's "
               "own radius for comparison (metres in a GNSS outage).</p>")
    return "\n".join(out)
