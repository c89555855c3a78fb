# SPDX-License-Identifier: MIT
"""The report's hydrographic section: vertical datum, TPU and the IHO S-44 Ed. 6.1 quality
control of the grid stage (orders, holidays, compliance map, crossline check), and its
backscatter mosaic."""

import math

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .maps import MapError, add_furniture, raster_extent, read_geotiff  # noqa: E402
from .rasters import limits, raster_max  # noqa: E402
from .sections_client import survey_metadata  # noqa: E402
from .util import esc, not_produced, num, strip_paths, table  # noqa: E402


def hydrography(p):
    """TPU and IHO S-44 Ed. 6.1 quality control (the grid stage): tables a surveyor can hand to
    a client, the holidays in grid coordinates, the crossline check by beam angle. (The
    vertical datum is in the client's datums section; the TVU map of the soundings in local
    metres is on the engineering page, tvu_map.)"""
    g = p.stages.get("grid")
    if not isinstance(g, dict):
        return None  # no grid stage: the summary says there is no S-44 assessment
    out = []
    facts = []
    facts.append(("TPU per sounding (95 %)",
                  f"median TVU {num(g.get('median_tvu_95_m', float('nan')), 3)} m, median "
                  f"THU {num(g.get('median_thu_95_m', float('nan')), 3)} m; error model "
                  f"{esc(strip_paths(str(g.get('error_model', '?'))))}"))
    facts.append(("CUBE surface", f"{num(g.get('resolution_m', float('nan')), 2)} m nodes, "
                  f"{num(g.get('nodes_filled', 0))} filled (dem.tif, dem.bag)"))
    out.append(table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
    q = g.get("s44")
    if not isinstance(q, dict):
        out.append("<p>No IHO S-44 assessment was made (s44.enabled is false).</p>")
        return "\n".join(out)
    order = q.get("order", "?")
    met = q.get("strictest_order_met_95")
    out.append(f"<h3>IHO S-44 Edition 6.1: order {esc(order)}</h3>")
    out.append(f"<p>Strictest order whose TVU and THU 95 % of the soundings meet: "
               f"<b>{esc(met) if met else 'none'}</b>. Chosen order for holidays and "
               f"the crossline check: <b>{esc(order)}</b>.</p>")
    rows = []
    lim = q.get("limits") or {}
    for o in ("exclusive", "special", "1a", "1b", "2"):
        L = lim.get(o) or {}
        thu = f"{num(L.get('thu_m', 0), 1)}"
        if L.get("thu_depth_fraction"):
            thu += f" + {num(100 * L['thu_depth_fraction'], 0)} % d"
        pct = lambda key: num(100 * float((q.get(key) or {}).get(o, float("nan"))), 1)
        name = f"<b>{esc(o)}</b>" if o == order else esc(o)
        rows.append([name, thu, f"{num(L.get('tvu_a_m', 0), 2)} / {num(L.get('tvu_b', 0), 4)}",
                     num(L.get("feature_m", 0), 1) if L.get("feature_m") else "n/a",
                     f"{num(L.get('coverage_percent', 0), 0)} %",
                     pct("soundings_within_tvu"), pct("soundings_within_thu"),
                     pct("soundings_within_both"), pct("nodes_within_tvu"),
                     pct("nodes_within_thu")])
    out.append(table(rows, header=["order", "THU (m)", "TVU a (m) / b", "feature (m)",
                                   "coverage", "soundings within TVU (%)",
                                   "within THU (%)", "within both (%)",
                                   "nodes within TVU (%)", "nodes within THU (%)"]))
    out.append(f'<p class="caption">{num(q.get("soundings", 0))} soundings, '
               f'{num(q.get("nodes", 0))} grid nodes. TVU limit sqrt(a&sup2; + (b d)&sup2;), '
               "d the depth (below the water-level datum, else below the transducer); node "
               "TVU is the CUBE uncertainty, node THU the mean THU of its soundings.</p>")
    track = trajectory_radius_figure(p, g)
    if track:
        out.append(track)
    hol = q.get("holidays") or []
    facts = [("coverage of the survey area", f"{num(100 * q.get('coverage_share', 0), 2)} % "
              f"({num(q.get('nodes_in_gaps', 0))} empty nodes in {num(q.get('gaps', 0))} "
              "gaps inside it)"),
             ("holidays", f"<b>{num(q.get('holiday_count', 0))}</b> (gaps that could hide a "
              f"{num(q.get('feature_size_m', 0), 2)} m feature; map s44_holidays.tif)"
              if q.get("feature_size_m") else
              f"not applicable to order {esc(order)} (5 % coverage); "
              f"{num(q.get('gaps', 0))} gaps mapped in s44_holidays.tif")]
    out.append(table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
    if hol:
        out.append(table([[str(i + 1), f"{float(h['x_m']):.2f}", f"{float(h['y_m']):.2f}",
                           num(h.get("area_m2", 0), 2), num(h.get("largest_square_m", 0), 2)]
                          for i, h in enumerate(hol[:20])],
                         header=["holiday", "UTM easting (m)", "UTM northing (m)",
                                 "area (m&sup2;)", "largest empty square (m)"]))
    cl = q.get("crossline") or {}
    out.append("<h3>Crossline check</h3>")
    bins = cl.get("by_angle") or []
    if not cl.get("compared"):
        out.append("<p>The track does not cross its own earlier lines (no sounding has "
                   "crossing soundings at least 30 s older in its cell).</p>")
        return "\n".join(out)
    out.append(f"<p>{num(cl['compared'])} soundings compared with the surface of the "
               f"earlier lines they cross: mean {num(cl.get('mean_m', 0), 3)} m, sd "
               f"{num(cl.get('sd_m', 0), 3)} m, RMS {num(cl.get('rms_m', 0), 3)} m; "
               f"{num(100 * cl.get('within_tvu', 0), 1)} % within the order {esc(order)} "
               "TVU limit.</p>")
    out.append(table([[f"{num(b['angle_lo_deg'], 0)}&ndash;{num(b['angle_hi_deg'], 0)}",
                       num(b["count"]), num(b["mean_m"], 3), num(b["sd_m"], 3),
                       num(b["rms_m"], 3), num(100 * b["within_tvu"], 1)] for b in bins],
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
        out.append(p.figure(fig, "s44_crossline", "crossline differences by beam angle"))
    return "\n".join(out)


def trajectory_radius_figure(p, g):
    """The trajectory's stated 95 % horizontal radius per window along the track (summary.json
    stages.slam.posterior.windows: SLAM's posterior with its perturbed-start spread), the pose
    term behind the THU above; None without it (SLAM's posterior not computed)."""
    post = (p.stages.get("slam") or {}).get("posterior") or {}
    ws = [w for w in post.get("windows") or []
          if isinstance(w, dict) and w.get("median_radius_h95_m") is not None]
    if not ws:
        return None
    t = np.array([0.5 * (float(w["start_gps_s"]) + float(w["end_gps_s"])) for w in ws])
    med = np.array([float(w["median_radius_h95_m"]) for w in ws])
    top = np.array([float(w["max_radius_h95_m"]) for w in ws])
    fig, a = plt.subplots(figsize=(8, 2.6), layout="constrained")
    minutes = p.minutes_of(t)
    a.step(minutes, top, where="mid", color="tab:red", lw=0.9, label="max")
    a.step(minutes, med, where="mid", color="tab:blue", lw=1.2, label="median")
    a.set_yscale("log")
    a.set_xlabel("time since start (min)")
    a.set_ylabel("95 % horizontal radius (m)")
    a.grid(alpha=0.3, which="both")
    a.legend(fontsize=8)
    window = num(float(post.get("window_s", 0)), 0)
    runs = post.get("start_runs") or 0
    return (p.figure(fig, "s44_trajectory_radius", "trajectory 95 % horizontal radius along "
                     "the track") +
            f'<p class="caption">How well the trajectory is known along the track: the 95 % '
            f"horizontal radius SLAM's posterior states per {window} s window (with the spread "
            f"of {num(runs)} SLAM runs from perturbed starts), the pose term of the THU and "
            "TVU above.</p>")


def tvu_map(p):
    """Engineering: the soundings coloured by TVU over the order's limit, holidays outlined,
    in local world metres (points.ply)."""
    g = p.stages.get("grid")
    q = g.get("s44") if isinstance(g, dict) else None
    if not isinstance(q, dict):
        return p.missing_product("S-44 quality control", "no grid stage with s44")
    order = q.get("order", "?")
    pts = p.points.get("final")
    if pts is None or "tvu_95_m" not in pts.dtype.names:
        return p.missing_product("points.ply tvu_95_m", "points.ply without THU/TVU "
                                 "(grid.write_point_tpu)")
    lim = (q.get("limits") or {}).get(order) or {}
    step = max(1, len(pts) // 400000)
    x = np.asarray(pts["x"][::step], dtype=np.float64)
    y = np.asarray(pts["y"][::step], dtype=np.float64)
    tvu = np.asarray(pts["tvu_95_m"][::step], dtype=np.float64)
    if "depth_m" in pts.dtype.names:
        d = np.asarray(pts["depth_m"][::step], dtype=np.float64)
    else:
        d = p.ref_z - np.asarray(pts["z"][::step], dtype=np.float64)
    a_m, b = float(lim.get("tvu_a_m", 0.5)), float(lim.get("tvu_b", 0.013))
    ratio = tvu / np.sqrt(a_m ** 2 + (b * np.maximum(d, 0)) ** 2)
    xl = limits([x], margin=0.02, lo_pct=0.05)
    yl = limits([y], margin=0.02, lo_pct=0.05)
    cell = max(0.1, max(xl[1] - xl[0], yl[1] - yl[0]) / 400.0)
    nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
    ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
    grid = raster_max(x, y, ratio, xl[0], yl[0], cell, nx, ny)
    fig, a = plt.subplots(figsize=(11, float(np.clip(9.5 * ny / nx, 3, 13)) + 0.8),
                          layout="constrained")
    im = a.imshow(grid, origin="lower", extent=(xl[0], xl[0] + nx * cell, yl[0],
                  yl[0] + ny * cell), cmap="RdYlGn_r", vmin=0, vmax=1.5,
                  interpolation="nearest")
    for i, h in enumerate((q.get("holidays") or [])[:50]):
        box = h.get("bbox_world_m")
        if not box:
            continue
        bx = [c[0] for c in box] + [box[0][0]]
        by = [c[1] for c in box] + [box[0][1]]
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
    return p.figure(fig, "s44_compliance", "S-44 TVU compliance map with holidays")


def mosaic(p):
    """The backscatter mosaic of the grid stage (mosaic.tif): corrected and uncorrected side
    by side, with the angular response the correction used (issue 17 item 6)."""
    g = p.stages.get("grid")
    m = g.get("mosaic") if isinstance(g, dict) else None
    if not isinstance(m, dict):
        return None  # no mosaic made (mosaic.enabled false, or no grid stage): no section
    if not m.get("made"):
        return not_produced("mosaic.tif", m.get("reason") or m.get("message") or "")
    try:
        tif = read_geotiff(p.path("mosaic.tif"))
    except ImportError:
        return p.missing_product("mosaic.tif", "python3-gdal is not installed")
    except (MapError, RuntimeError, OSError) as e:
        return not_produced("mosaic.tif", f"unreadable: {strip_paths(e)}")
    foreign = p.foreign_run("mosaic.tif", tif["metadata"].get("pitmap_run_id"))
    if foreign:
        return not_produced("mosaic.tif", foreign)
    ext = raster_extent(tif["gt"], tif["nx"], tif["ny"])
    crs = tif["crs"] or survey_metadata(p.summary)["horizontal_crs"] or ""
    figures = []
    for name, title, fig_name in (
            ("backscatter", "Seabed backscatter, corrected for range and incidence", "mosaic"),
            ("uncorrected", "Uncorrected: 20 log10(intensity)", "mosaic_uncorrected")):
        if name not in tif["bands"]:
            continue
        v = tif["bands"][name]
        ok = v[np.isfinite(v)]
        lo, hi = np.percentile(ok, [2, 98]) if len(ok) else (0, 1)
        w, h = ext[1] - ext[0], ext[3] - ext[2]
        big = name == "backscatter"
        width = 11.0 if big else 7.5
        fig, a = plt.subplots(figsize=(width, float(np.clip(width * h / w, 3, 12)) + 1.0),
                              layout="constrained")
        im = a.imshow(v, extent=ext, cmap="gray", vmin=lo, vmax=hi, interpolation="nearest")
        a.set_title(title, fontsize=10)
        add_furniture(a, ext, crs)
        # The reference the mosaic states in full (pitmap_db_reference, mosaic_stage.cpp), in
        # short; an older mosaic said only "relative".
        fig.colorbar(im, ax=a, shrink=0.8, pad=0.01).set_label(
            "dB re 1 unit of the 83P intensity (not calibrated)"
            if "pitmap_db_reference" in tif["metadata"] else "dB (relative)")
        figures.append(p.figure(fig, fig_name, title))
    fig, a = plt.subplots(figsize=(6, 4), layout="constrained")
    curve = np.asarray(m.get("angular_response_deg_db_count") or [[0, 0, 0]], dtype=float)
    a.plot(curve[:, 0], curve[:, 1], "o-", ms=2)
    a.set_xlabel("incidence (deg)")
    a.set_ylabel("angular response removed (dB, 0 at the reference)")
    a.set_title(f"{m.get('angular', '?')} angular response", fontsize=10)
    a.grid(alpha=0.3)
    figures.append(p.figure(fig, "mosaic_angular_response", "angular response"))
    facts = [("soundings used", f"{num(m.get('used', 0))} of {num(m.get('soundings', 0))} "
              f"(no intensity {num(m.get('no_intensity', 0))}, saturated "
              f"{num(m.get('saturated', 0))}, incidence beyond the limit "
              f"{num(m.get('beyond_incidence', 0))})"),
             ("range correction", f"{num(m.get('spreading_db_per_decade', 0), 1)} log10(R) + "
              f"2 &times; {num(m.get('absorption_db_per_m', 0), 4)} dB/m &times; R"),
             ("incidence correction", f"{esc(m.get('angular', '?'))}, referenced to "
              f"{num(m.get('reference_angle_deg', 0), 0)} deg (incidence from the DEM's "
              f"slopes; median {num(m.get('median_incidence_deg', 0), 1)} deg)"),
             ("corrected, 5-95 %", f"{num(m.get('corrected_p05_db', 0), 1)} to "
              f"{num(m.get('corrected_p95_db', 0), 1)} dB on {num(m.get('nodes_filled', 0))} "
              "nodes (mosaic.tif: backscatter, uncorrected, count)")]
    return "\n".join([table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"),
                      figures[0], '<div class="pair">' + "".join(figures[1:]) + "</div>"])
