# SPDX-License-Identifier: MIT
"""The sections of the change report (pitmap-report --compare C, issue 37 item 5): the two
surveys, a summary, the map of significant change, the volumes of cut and fill with their 95 %
uncertainty, cross-sections of both surveys through the largest change, the co-registration,
the change along the surface normal, the capacity curves, the mine-planning maps of the later
survey and the quality gates. Every figure in words or tables is compare.json's, as `pitmap
compare` wrote it; the pictures draw dod.tif, change_regions.geojson, the capacity CSVs and the
two surveys' dem.tif and soundings. Each section is a function of a change.CompareFolder
returning its HTML, or None to be left out."""

import json
import math
import os

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.colors import LightSource, TwoSlopeNorm  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from . import sections_planning as planning  # noqa: E402
from .capacity import draw_curves, read_csv  # noqa: E402
from .change import _is_number  # noqa: E402
from .loaders import Ply, PlyError  # noqa: E402
from .maps import add_furniture, raster_extent  # noqa: E402
from .sections_client import _dem as dem_of  # noqa: E402
from .sections_client import survey_metadata  # noqa: E402
from .util import esc, facts_table, num, strip_paths, table  # noqa: E402

COLOUR = {"a": "#1f77b4", "b": "#e4741b"}
CUT_COLOUR, FILL_COLOUR = "#b2182b", "#2166ac"
# A section runs down the slope where the ground at the change is steeper than this (a slump
# on a wall), else along the change's longest extent (a heap or a cut on the floor).
FALL_LINE_MIN_SLOPE_DEG = 15.0
# A change on ground this steep in A is on a wall: when the largest change is not, the largest
# one on a wall gets a section of its own, down the wall.
WALL_MIN_SLOPE_DEG = 30.0
# The map labels the regions of the largest volume; the others are outlined only.
MAX_LABELLED_REGIONS = 20


def _input(c, side):
    """compare.json's inputs.a or inputs.b, {} when absent or not an object."""
    inputs = c.compare.get("inputs")
    rec = inputs.get(side) if isinstance(inputs, dict) else None
    return rec if isinstance(rec, dict) else {}


def _crs(c):
    crs = c.compare.get("crs")
    return crs if isinstance(crs, dict) else {}


def _date(c, side):
    """The survey's start date (YYYY-MM-DD) from compare.json, else the folder's metadata;
    None when neither says."""
    t = _input(c, side).get("survey_start_utc")
    if not t:
        t = survey_metadata(c.epochs[side].summary).get("survey_start_utc")
    return str(t)[:10] if t else None


def _label(c, side):
    """'A (2026-06-15)', or 'A' without a date."""
    d = _date(c, side)
    return f"{side.upper()} ({d})" if d else side.upper()


def _survey_name(p):
    md = survey_metadata(p.summary)
    parts = [md.get(k) for k in ("project", "site") if md.get(k)]
    return " \u2013 ".join(parts)


def change_title(c):
    """'Change between surveys: <project - site>, <date A> to <date B>'."""
    name = _survey_name(c.a)
    da, db = _date(c, "a"), _date(c, "b")
    return ("Change between surveys" + (f": {name}" if name else "")
            + (f", {da} to {db}" if da and db else ""))


def subtitle(c):
    md = survey_metadata(c.a.summary)
    client = f"Client: {esc(md['client'])}. " if md.get("client") else ""
    return (f"{client}Survey {esc(_label(c, 'a'))} compared with survey {esc(_label(c, 'b'))}; "
            "B minus A, after co-registration on stable ground.")


# ---- surveys and summary ----

def surveys(c):
    """Who, what and when of both surveys, and the datums of the comparison."""
    rows = []
    keys = (("survey id", "survey_id"), ("site", "site"), ("surveyor", "surveyor"),
            ("organisation", "organisation"), ("vessel", "vessel"),
            ("survey start (UTC)", "survey_start_utc"), ("survey end (UTC)", "survey_end_utc"),
            ("processed (UTC)", "processed_utc"), ("software", "software"))
    mds = {s: survey_metadata(c.epochs[s].summary) for s in ("a", "b")}
    for label, key in keys:
        vals = [mds[s].get(key) for s in ("a", "b")]
        rows.append([f"<b>{esc(label)}</b>"] + [esc(v) if v else '<span class="not-set">not '
                                                 'set</span>' for v in vals])
    rows.append(["<b>run id</b>"] + [esc(_input(c, s).get("run_id") or "not recorded")
                                     for s in ("a", "b")])
    crs = _crs(c)
    datum = [("horizontal CRS", f"{esc(crs.get('horizontal') or '?')}"
              + (f" (EPSG:{esc(crs['epsg'])})" if crs.get("epsg") else "")),
             ("vertical datum", esc(crs.get("vertical") or "?")),
             ("sign", "B minus A: positive where material was added (fill, deposit), negative "
                      "where it was removed (cut, slump scar)"),
             ("units", "metres, square metres, cubic metres; uncertainties at 95 % "
                       "confidence")]
    return "\n".join([table(rows, header=["", _label(c, "a"), _label(c, "b")], cls="facts"),
                      facts_table(datum)])


def _f(d, key):
    """An optional figure of compare.json: the number at d[key], else NaN."""
    v = d.get(key) if isinstance(d, dict) else None
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan


def _text(v, digits):
    """A figure as text, "?" for NaN (an optional figure compare.json does not have)."""
    return "?" if math.isnan(v) else num(v, digits)


def _num(d, key, digits):
    """An optional figure of compare.json as text: "?" when it is not there."""
    return _text(_f(d, key), digits)


def _volume(v, u=None, digits=2):
    s = f"{num(float(v), digits)} m&sup3;"
    return s + (f" &plusmn; {num(float(u), digits)}" if u is not None else "")


def _gates(c):
    gates = [g for g in c.compare.get("quality_gates") or [] if isinstance(g, dict)]
    return gates


def summary(c):
    """The change in one paragraph and the key figures."""
    ch, cap, reg = c.compare["change"], c.compare["capacity"], c.compare["registration"]
    cut, fill = ch["cut"], ch["fill"]
    n = len(ch["regions"])
    cut_text = _volume(cut["volume_m3"], cut["u95_m3"])
    fill_text = _volume(fill["volume_m3"], fill["u95_m3"])
    sentence = (f"Between survey {esc(_label(c, 'a'))} and survey {esc(_label(c, 'b'))}, "
                f"<b>{n}</b> region{'s' if n != 1 else ''} of significant change "
                f"{'were' if n != 1 else 'was'} found: <b>cut {cut_text}</b> over "
                f"{num(float(cut['area_m2']), 1)} m&sup2; in {cut['regions']} region(s) and "
                f"<b>fill {fill_text}</b> over {num(float(fill['area_m2']), 1)} m&sup2; in "
                f"{fill['regions']} region(s) (95 % uncertainty).")
    gates = _gates(c)
    # A statement of fact, grey; red when a gate of the comparison tripped (then read it with
    # the gates' messages).
    verdict = "verdict not-met" if gates else "verdict"
    net = ch["net_m3"] if _is_number(ch.get("net_m3")) else cut["volume_m3"] + fill["volume_m3"]
    rows = [("compared area", f"{_num(ch, 'compared_area_m2', 0)} m&sup2;"),
            ("net change (cut + fill)", _volume(net)),
            ("smallest detectable change (median LoD95)",
             f"{_num(ch, 'median_lod95_m', 3)} m"),
            ("stable ground: B - A", f"mean {_num(ch, 'stable_mean_m', 3)} m, RMS "
                                     f"{_num(ch, 'stable_rms_m', 3)} m"),
            ("co-registration residual (stable ground, vertical RMS)",
             f"{num(float(reg['rms_vertical_after_m']), 3)} m (before: "
             f"{num(float(reg['rms_vertical_before_m']), 3)} m)"),
            ("water volume at the water level",
             f"A {num(float(cap['a']['volume_at_water_level_m3']), 0)} m&sup3;, B "
             f"{num(float(cap['b']['volume_at_water_level_m3']), 0)} m&sup3;"),
            ("quality gates", "none tripped" if not gates else
             "; ".join(esc(strip_paths(g.get("message", g.get("gate", "?")))) for g in gates))]
    return "\n".join([f'<p class="{verdict}">{sentence}</p>', facts_table(rows)])


# ---- the map ----

def _extent_of_data(d, v):
    """The extent of a raster's finite nodes (left, right, bottom, top), padded."""
    gt = d["gt"]
    rows, cols = np.nonzero(np.isfinite(v))
    if len(rows) == 0:
        return raster_extent(gt, d["nx"], d["ny"])
    left, right = gt[0] + cols.min() * gt[1], gt[0] + (cols.max() + 1) * gt[1]
    top, bottom = gt[3] + rows.min() * gt[5], gt[3] + (rows.max() + 1) * gt[5]
    pad = max(1.0, 0.04 * max(right - left, top - bottom))
    return (left - pad, right + pad, bottom - pad, top + pad)


def _map_furniture(ax, ext, crs):
    """The survey maps' furniture, with fewer northing ticks on a map wider than high (the
    labels stand upright and would overlap)."""
    add_furniture(ax, ext, crs)
    w, h = ext[1] - ext[0], ext[3] - ext[2]
    ax.yaxis.set_major_locator(MaxNLocator(nbins=int(np.clip(6 * h / w, 2, 8))))


def _hillshade(ax, dem):
    z = dem["bands"].get("elevation")
    if z is None:
        return
    fill = np.where(np.isfinite(z), z, np.nanmean(z) if np.isfinite(z).any() else 0.0)
    shade = LightSource(azdeg=315, altdeg=45).hillshade(fill, vert_exag=2.0, dx=dem["gt"][1],
                                                         dy=-dem["gt"][5])
    rgba = np.dstack([shade, shade, shade, np.isfinite(z) * 1.0])
    ax.imshow(rgba, extent=raster_extent(dem["gt"], dem["nx"], dem["ny"]),
              interpolation="nearest", zorder=1)


def _outlines(c):
    """{region id: (kind, [rings as N x 2 arrays])} from change_regions.geojson, or None."""
    try:
        with open(c.path("change_regions.geojson")) as f:
            gj = json.load(f)
        out = {}
        for feat in gj["features"]:
            props = feat["properties"]
            geom = feat["geometry"]
            polys = geom["coordinates"] if geom["type"] == "MultiPolygon" else [
                geom["coordinates"]]
            out[int(props["id"])] = (props.get("kind"), [np.asarray(ring, dtype=np.float64)
                                                         for poly in polys for ring in poly])
        return out
    except (OSError, ValueError, KeyError, TypeError, IndexError) as e:
        c.problems.append(f"change_regions.geojson: unreadable ({strip_paths(e)}); outlines "
                          "drawn from dod.tif's region band")
        return None


def _draw_outlines(c, ax, d, outlines):
    regions = {int(r["id"]): r for r in c.compare["change"]["regions"]}
    labelled = {int(r["id"]) for r in sorted(regions.values(), key=lambda r: (
        -abs(float(r["volume_m3"])), int(r["id"])))[:MAX_LABELLED_REGIONS]}
    gt = d["gt"]
    for rid, r in regions.items():
        colour = CUT_COLOUR if r["kind"] == "cut" else FILL_COLOUR
        if outlines is not None and rid in outlines:
            for ring in outlines[rid][1]:
                ax.plot(ring[:, 0], ring[:, 1], color=colour, lw=1.1, zorder=5)
        else:
            mask = (d["bands"]["region"] == rid).astype(float)
            xs = gt[0] + (np.arange(d["nx"]) + 0.5) * gt[1]
            ys = gt[3] + (np.arange(d["ny"]) + 0.5) * gt[5]
            if mask.any():
                ax.contour(xs, ys, mask, levels=[0.5], colors=colour, linewidths=1.1, zorder=5)
        if rid not in labelled:
            continue
        centre = r.get("centroid_m")
        if not (isinstance(centre, list) and len(centre) == 2
                and all(_is_number(v) for v in centre)):
            rows, cols = np.nonzero(d["bands"]["region"] == rid)
            if len(rows) == 0:
                continue
            centre = (gt[0] + (cols.mean() + 0.5) * gt[1], gt[3] + (rows.mean() + 0.5) * gt[5])
        ax.text(centre[0], centre[1], f"R{rid}", fontsize=8, weight="bold", color=colour,
                ha="center", va="center", zorder=6,
                bbox={"facecolor": "white", "edgecolor": colour, "alpha": 0.8, "pad": 1.2})


def _sym_limit(v):
    ok = np.abs(v[np.isfinite(v)])
    return max(0.1, float(np.percentile(ok, 99))) if len(ok) else 1.0


def change_map(c):
    """Significant change over A's hill-shade, cut and fill outlined; the difference everywhere
    and the level of detection beside it."""
    d = c.dod()
    if d is None:
        return c.missing_product("dod.tif")
    diff, sig, lod = (d["bands"][k] for k in ("difference", "significance", "lod95"))
    ext = _extent_of_data(d, diff)
    crs = d["crs"] or _crs(c).get("horizontal") or ""
    dem_a = dem_of(c.a)
    shown = np.where(np.isfinite(sig) & (sig != 0), diff, np.nan)
    lim = _sym_limit(shown if np.isfinite(shown).any() else diff)
    norm = TwoSlopeNorm(vcenter=0.0, vmin=-lim, vmax=lim)
    w, h = ext[1] - ext[0], ext[3] - ext[2]
    fig, a = plt.subplots(figsize=(11, float(np.clip(11 * h / w, 3.5, 12)) + 1.0),
                          layout="constrained")
    if dem_a is not None:
        _hillshade(a, dem_a)
    im = a.imshow(shown, extent=raster_extent(d["gt"], d["nx"], d["ny"]), cmap="RdBu",
                  norm=norm, interpolation="nearest", zorder=2)
    _draw_outlines(c, a, d, _outlines(c))
    lines = _section_lines(c)
    for name, p0, p1, _ in lines or []:
        a.plot([p0[0], p1[0]], [p0[1], p1[1]], "k-", lw=1.2, zorder=7)
        for (x, y), t in ((p0, name), (p1, name + "'")):
            a.text(x, y, t, fontsize=9, weight="bold", zorder=8, ha="center", va="center",
                   bbox={"facecolor": "white", "edgecolor": "black", "pad": 1.0})
    _map_furniture(a, ext, crs)
    cb = fig.colorbar(im, ax=a, shrink=0.8, pad=0.01)
    cb.set_label("significant change, B - A (m): red loss, blue gain")
    a.legend(handles=[plt.Line2D([], [], color=CUT_COLOUR, lw=1.2, label="cut (loss) region"),
                      plt.Line2D([], [], color=FILL_COLOUR, lw=1.2, label="fill (gain) region"),
                      plt.Line2D([], [], color="black", lw=1.2, label="cross-section")],
             loc="upper left", fontsize=8, framealpha=0.85)
    a.set_title("Significant change between the surveys over survey A's hill-shade")
    out = [c.figure(fig, "change_map", "map of significant change"),
           '<p class="caption">Coloured: nodes where |B - A| exceeds the level of detection at '
           "95 % (LoD95, from both surveys' node uncertainty and the co-registration's); grey: "
           "no detectable change or only one survey. Outlines: the change regions of "
           f"change_regions.geojson; the {MAX_LABELLED_REGIONS} largest by volume labelled R and "
           "their id there, as in the volume table.</p>"]
    # Side by side when the area is about as wide as high, one above the other when wide.
    if w > 1.4 * h:
        fig, axs = plt.subplots(2, 1, figsize=(11, 2 * float(np.clip(11 * h / w, 2.5, 8)) + 1.5),
                                layout="constrained")
    else:
        fig, axs = plt.subplots(1, 2, figsize=(15, float(np.clip(7.5 * h / w, 3, 10)) + 1.2),
                                layout="constrained")
    dl = _sym_limit(diff)
    im = axs[0].imshow(diff, extent=raster_extent(d["gt"], d["nx"], d["ny"]), cmap="RdBu",
                       norm=TwoSlopeNorm(vcenter=0.0, vmin=-dl, vmax=dl),
                       interpolation="nearest")
    fig.colorbar(im, ax=axs[0], shrink=0.8, pad=0.01).set_label("B - A (m)")
    axs[0].set_title("Difference B - A, every compared node", fontsize=10)
    ok = lod[np.isfinite(lod)]
    im = axs[1].imshow(lod, extent=raster_extent(d["gt"], d["nx"], d["ny"]), cmap="viridis",
                       vmin=0, vmax=float(np.percentile(ok, 95)) if len(ok) else 1.0,
                       interpolation="nearest")
    fig.colorbar(im, ax=axs[1], shrink=0.8, pad=0.01).set_label("LoD95 (m)")
    axs[1].set_title("Level of detection at 95 %", fontsize=10)
    for ax in axs:
        _map_furniture(ax, ext, crs)
    out.append(c.figure(fig, "change_difference_lod", "difference and level of detection"))
    return "\n".join(out)


# ---- the volume table ----

def volumes(c):
    """Per region and in total: area, volume and its 95 % uncertainty with the terms it is
    made of."""
    ch = c.compare["change"]
    regions = sorted(ch["regions"], key=lambda r: (-abs(float(r["volume_m3"])), int(r["id"])))
    rows = []
    for r in regions:
        def term(k):
            v = r.get(k)
            return num(float(v), 2) if isinstance(v, (int, float)) else "?"
        rows.append([f"R{r['id']}", esc(r["kind"]), num(float(r["area_m2"]), 2),
                     num(float(r["volume_m3"]), 2), num(float(r["u95_m3"]), 2),
                     term("sigma_random_m3"), term("sigma_registration_m3"), term("rim_m3"),
                     term("max_abs_difference_m"), term("mean_lod95_m")])
    header = ["region", "kind", "area (m\u00b2)", "volume (m\u00b3)", "U95 (m\u00b3)",
              "random, 1\u03c3 (m\u00b3)", "registration, 1\u03c3 (m\u00b3)", "rim (m\u00b3)",
              "largest |B - A| (m)", "mean LoD95 (m)"]
    totals = []
    for side in ("cut", "fill"):
        t = ch[side]
        totals.append([f"<b>all {side}</b>", str(t["regions"]), num(float(t["area_m2"]), 2),
                       f"<b>{num(float(t['volume_m3']), 2)}</b>",
                       f"<b>{num(float(t['u95_m3']), 2)}</b>"])
    net = (ch["net_m3"] if _is_number(ch.get("net_m3"))
           else ch["cut"]["volume_m3"] + ch["fill"]["volume_m3"])
    totals.append(["<b>net</b>", str(len(regions)), num(float(ch["cut"]["area_m2"])
                                                        + float(ch["fill"]["area_m2"]), 2),
                   f"<b>{num(float(net), 2)}</b>", "not stated"])
    out = ['<h3>Change regions</h3>', table(rows, header=header, cls="volumes") if rows else
           "<p>No region of significant change.</p>",
           '<h3>Totals</h3>', table(totals, header=["", "regions", "area (m\u00b2)",
                                                     "volume (m\u00b3)", "U95 (m\u00b3)"],
                                    cls="totals"),
           '<p class="caption">Volume: the sum of B - A over a region\'s nodes times the node '
           "area (negative: material removed). U95, its uncertainty at 95 % confidence: "
           "1.96 &radic;(random&sup2; + registration&sup2;) + rim, where random is the nodes' own "
           "error (correlated over 1 m patches), registration the co-registration's, and rim "
           "what the outline may leave below detection along its edge. Totals add the random "
           "terms in quadrature and the registration and rim terms linearly; the net change "
           "mixes both signs and its uncertainty is not stated.</p>"]
    return "\n".join(out)


# ---- cross-sections ----

def _sample(band, gt, x, y):
    """Nearest-node values of a north-up raster band at points (NaN outside)."""
    col = np.floor((np.asarray(x) - gt[0]) / gt[1]).astype(np.int64)
    row = np.floor((np.asarray(y) - gt[3]) / gt[5]).astype(np.int64)
    ok = (col >= 0) & (col < band.shape[1]) & (row >= 0) & (row < band.shape[0])
    out = np.full(len(col), np.nan)
    out[ok] = band[row[ok], col[ok]]
    return out


def largest_region(c):
    """compare.json's region of the largest |volume| (ties: the lower id), or None."""
    regions = c.compare["change"]["regions"]
    if not regions:
        return None
    return sorted(regions, key=lambda r: (-abs(float(r["volume_m3"])), int(r["id"])))[0]


def _region_geometry(c, d, r):
    """(x, y of its nodes, centre: the node of the largest |B - A|, mean slope of A over it in
    deg or None, downhill unit vector or None) of region r in dod.tif; None without nodes."""
    gt = d["gt"]
    rows, cols = np.nonzero(d["bands"]["region"] == int(r["id"]))
    if len(rows) == 0:
        return None
    x = gt[0] + (cols + 0.5) * gt[1]
    y = gt[3] + (rows + 0.5) * gt[5]
    diff = np.abs(d["bands"]["difference"][rows, cols])
    k = int(np.nanargmax(diff)) if np.isfinite(diff).any() else 0
    slope, downhill = None, None
    dem_a = dem_of(c.a)
    if dem_a is not None and "elevation" in dem_a["bands"]:
        if not hasattr(c, "_gradient_a"):
            c._gradient_a = np.gradient(dem_a["bands"]["elevation"], dem_a["gt"][5],
                                        dem_a["gt"][1])
        gy, gx = c._gradient_a
        sx, sy = _sample(gx, dem_a["gt"], x, y), _sample(gy, dem_a["gt"], x, y)
        if np.isfinite(sx).any():
            g = np.array([np.nanmean(sx), np.nanmean(sy)])
            if np.all(np.isfinite(g)) and np.hypot(*g) > 0:
                slope = math.degrees(math.atan(float(np.hypot(*g))))
                downhill = -g / np.hypot(*g)
    return x, y, np.array([x[k], y[k]]), slope, downhill


def _line_through(name, x, y, centre, u, what):
    """A section along u through centre, past the region's nodes (x, y) by half their extent
    along u, at least 2 m, on each side."""
    s = (x - centre[0]) * u[0] + (y - centre[1]) * u[1]
    margin = max(2.0, 0.5 * float(s.max() - s.min()))
    return (name, centre + (float(s.min()) - margin) * u, centre + (float(s.max()) + margin) * u,
            what)


def _section_lines(c):
    """[(name, start, end, how)] of the cross-sections: two through the largest change, the
    first down the slope of A's surface there when it is 15 deg or steeper (a slumped wall),
    else along the region's longest extent, the second across it; and when the largest change
    lies on gentler ground, a third down the slope through the largest change on a wall (mean
    slope 30 deg or more). Each through its region's node of the largest |B - A|. Also sets
    c.section_regions: [(section names, centre, region)]. None without a region or dod.tif."""
    if hasattr(c, "section_lines"):
        return c.section_lines
    c.section_lines, c.section_regions = None, []
    r = largest_region(c)
    d = c.dod()
    if r is None or d is None:
        return None
    geo = _region_geometry(c, d, r)
    if geo is None:
        c.problems.append(f"dod.tif has no node of region {r['id']} of compare.json")
        return None
    x, y, centre, slope, downhill = geo
    if slope is not None and slope >= FALL_LINE_MIN_SLOPE_DEG:
        u, how = downhill, f"down the slope ({slope:.0f} deg on average over the region in A)"
    elif len(x) >= 2:
        w, v = np.linalg.eigh(np.cov(np.stack([x, y])))
        u, how = v[:, int(np.argmax(w))], "along the change's longest extent"
    else:
        u, how = np.array([1.0, 0.0]), "west to east"
    lines = [_line_through("1", x, y, centre, u, how),
             _line_through("2", x, y, centre, np.array([-u[1], u[0]]), "across section 1")]
    c.section_regions.append(("1 and 2", centre, r, "the largest by volume"))
    if slope is None or slope < WALL_MIN_SLOPE_DEG:
        by_volume = sorted(c.compare["change"]["regions"],
                           key=lambda q: (-abs(float(q["volume_m3"])), int(q["id"])))
        for q in by_volume:
            if q is r:
                continue
            geo = _region_geometry(c, d, q)
            if geo is not None and geo[3] is not None and geo[3] >= WALL_MIN_SLOPE_DEG:
                qx, qy, qc, qs, qu = geo
                lines.append(_line_through("3", qx, qy, qc, qu, f"down the wall ({qs:.0f} deg "
                                           "on average over the region in A)"))
                c.section_regions.append(("3", qc, q, "the largest by volume on a wall"))
                break
    c.section_lines = lines
    return lines


def _exaggeration(length, z_range):
    """1 when the section's heights span at least a fifth of its length, else the 2, 5, 10 or
    20 that brings them nearest a third of it."""
    if not z_range > 0 or z_range >= 0.2 * length:
        return 1.0
    want = length / (3.0 * z_range)
    return min((2.0, 5.0, 10.0, 20.0), key=lambda e: abs(math.log(e / want)))


def _profile_figure(c, name, p0, p1, what, d, dem_a, pts):
    gt = d["gt"]
    length = float(np.hypot(*(p1 - p0)))
    u = (p1 - p0) / length
    step = abs(gt[1])
    s = np.arange(0.0, length + 0.5 * step, step)
    px, py = p0[0] + s * u[0], p0[1] + s * u[1]
    za = _sample(dem_a["bands"]["elevation"], dem_a["gt"], px, py)
    diff = _sample(d["bands"]["difference"], gt, px, py)
    sig = _sample(d["bands"]["significance"], gt, px, py)
    zb = za + diff
    half_width = max(0.25, 1.5 * step)
    zs = [za[np.isfinite(za)], zb[np.isfinite(zb)]]
    near_points = {}
    for side in ("a", "b"):
        q = pts.get(side)
        if q is None or len(q) == 0:
            continue
        along = (q[:, 0] - p0[0]) * u[0] + (q[:, 1] - p0[1]) * u[1]
        across = -(q[:, 0] - p0[0]) * u[1] + (q[:, 1] - p0[1]) * u[0]
        idx = np.nonzero((np.abs(across) <= half_width) & (along >= 0) & (along <= length))[0]
        if len(idx) > 20000:
            idx = idx[np.linspace(0, len(idx) - 1, 20000).astype(np.int64)]
        if len(idx):
            near_points[side] = (along[idx], q[idx, 2])
            zs.append(q[idx, 2])
    allz = np.concatenate(zs)
    z_lo, z_hi = (float(allz.min()), float(allz.max())) if len(allz) else (0.0, 1.0)
    ve = _exaggeration(length, z_hi - z_lo)
    # The axes keep the section's length and heights at the stated scale: the figure's height
    # follows (a wall at true scale is tall, a floor is flat and exaggerated).
    pad = 0.1 * max(z_hi - z_lo, 0.5)
    height_in = float(np.clip(9.5 * ve * (z_hi - z_lo + 2 * pad) / length, 1.8, 8.5))
    fig, a = plt.subplots(figsize=(11, height_in + 1.4), layout="constrained")
    for side, (along, z) in near_points.items():
        a.plot(along, z, ".", ms=1.5, color=COLOUR[side], alpha=0.35, zorder=2)
    a.plot(s, za, "-", color=COLOUR["a"], lw=1.8, label=f"{_label(c, 'a')}: depth grid",
           zorder=4)
    a.plot(s, zb, "-", color=COLOUR["b"], lw=1.8,
           label=f"{_label(c, 'b')}: depth grid, co-registered", zorder=4)
    a.fill_between(s, za, zb, where=sig < 0, color=CUT_COLOUR, alpha=0.35, lw=0,
                   label="significant loss", zorder=3)
    a.fill_between(s, za, zb, where=sig > 0, color=FILL_COLOUR, alpha=0.35, lw=0,
                   label="significant gain", zorder=3)
    for side in near_points:
        a.plot([], [], ".", ms=6, color=COLOUR[side], alpha=0.6,
               label=f"{_label(c, side)}: soundings within {half_width:g} m")
    a.set_xlim(0, length)
    a.set_ylim(z_lo - pad, z_hi + pad)
    a.set_aspect(ve, adjustable="box")
    bearing = math.degrees(math.atan2(u[0], u[1])) % 360.0
    a.set_xlabel(f"distance from {name} (m), towards grid bearing {bearing:.0f} deg")
    a.set_ylabel("height (m)")
    a.set_title(f"Section {name}-{name}' {what}"
                + (f"; vertical exaggeration {ve:g}x" if ve != 1 else "; true scale"),
                fontsize=10)
    a.grid(alpha=0.3)
    a.legend(fontsize=7, loc="best", framealpha=0.85)
    return c.figure(fig, f"change_section_{name}", f"cross-section {name} of both surveys")


def cross_sections(c):
    """Both surveys along two lines through the largest change: their depth grids (B's carried
    by the co-registration, as in dod.tif) and their soundings near the line, which show the
    wall where the grid, one height per node, cannot."""
    d = c.dod()
    if d is None:
        return c.missing_product("dod.tif")
    lines = _section_lines(c)
    if not lines:
        return "<p>No region of significant change: no cross-section.</p>"
    dem_a = dem_of(c.a)
    if dem_a is None or "elevation" not in dem_a["bands"]:
        return c.missing_product("A's dem.tif", c.a.unusable.get("dem.tif", ""))
    xs = [p[0] for _, p0, p1, _ in lines for p in (p0, p1)]
    ys = [p[1] for _, p0, p1, _ in lines for p in (p0, p1)]
    box = (min(xs) - 1, max(xs) + 1, min(ys) - 1, max(ys) + 1)
    pts = {side: c.soundings(side, box) for side in ("a", "b")}
    figures = [_profile_figure(c, name, p0, p1, what, d, dem_a, pts)
               for name, p0, p1, what in lines]
    tables = []
    for names, centre, r, which in c.section_regions:
        za = float(_sample(dem_a["bands"]["elevation"], dem_a["gt"], [centre[0]],
                           [centre[1]])[0])
        dv = float(_sample(d["bands"]["difference"], d["gt"], [centre[0]], [centre[1]])[0])
        lv = float(_sample(d["bands"]["lod95"], d["gt"], [centre[0]], [centre[1]])[0])
        tables.append(facts_table([
            (f"section {names} through region",
             f"R{r['id']} ({esc(r['kind'])}, {_volume(r['volume_m3'], r['u95_m3'])}), {which}"),
            ("at its largest change", f"E {num(float(centre[0]), 2)}, N "
                                      f"{num(float(centre[1]), 2)}"),
            ("height there", f"A {num(za, 3)} m, B {num(za + dv, 3)} m"),
            ("B - A there", f"{num(dv, 3)} m (LoD95 {num(lv, 3)} m)")]))
    missing = [side.upper() for side in ("a", "b") if pts[side] is None]
    note = (f" No soundings of {' and '.join(missing)} (points_utm.ply absent or unusable)."
            if missing else "")
    return "\n".join(tables + figures + [
        '<p class="caption">Lines: the depth grids (CUBE surfaces) of both surveys along the '
        "section, B's as carried onto A by the co-registration (the heights dod.tif compares). "
        "Dots: each survey's accepted soundings near the line (B's co-registered too): on a "
        "steep wall they show the face that a grid of one height per node smooths. Shaded: "
        "where the difference is significant. Heights in "
        f"{esc(_crs(c).get('vertical') or 'the vertical datum')}." + note + "</p>"])


# ---- co-registration, 3D change, capacity, gates ----

def registration(c):
    reg = c.compare["registration"]
    sig = reg.get("sigma") if isinstance(reg.get("sigma"), dict) else {}
    t, rot = reg["translation_m"], reg["rotation_deg"]

    def pm(v, s, scale, digits, unit):
        out = f"{num(float(v) * scale, digits)} {unit}"
        return out + (f" &plusmn; {num(float(s) * scale, digits)}"
                      if isinstance(s, (int, float)) else "")
    rows = [("east", pm(t[0], sig.get("east_m"), 100, 1, "cm")),
            ("north", pm(t[1], sig.get("north_m"), 100, 1, "cm")),
            ("up", pm(t[2], sig.get("up_m"), 100, 1, "cm")),
            ("roll", pm(rot["roll"], sig.get("roll_deg"), 1, 4, "deg")),
            ("pitch", pm(rot["pitch"], sig.get("pitch_deg"), 1, 4, "deg")),
            ("yaw", pm(rot["yaw"], sig.get("yaw_deg"), 1, 4, "deg"))]
    facts = [("correction of B onto A (1-sigma)", table(rows, cls="facts")),
             ("degrees of freedom", esc(reg.get("dof", "?"))),
             ("residual on stable ground, vertical RMS",
              f"{num(float(reg['rms_vertical_after_m']), 3)} m after, "
              f"{num(float(reg['rms_vertical_before_m']), 3)} m before")]
    used, stable = reg.get("nodes_used"), reg.get("nodes_stable")
    if isinstance(used, int) and isinstance(stable, int) and used > 0:
        facts.append(("stable ground", f"{num(stable)} of {num(used)} nodes "
                                       f"({num(100.0 * stable / used, 1)} %)"))
    if reg.get("termination"):
        facts.append(("solver", f"{esc(reg['termination'])}, {esc(reg.get('iterations', '?'))}"
                                " iterations"))
    gate = reg.get("navigation_gate") if isinstance(reg.get("navigation_gate"), dict) else {}
    if gate.get("evaluated"):
        allowed = (f"{_text(_f(gate, 'allowed_horizontal_m') * 100, 1)} cm horizontal, "
                   f"{_text(_f(gate, 'allowed_vertical_m') * 100, 1)} cm vertical, "
                   f"{_num(gate, 'allowed_yaw_deg', 3)} deg yaw")
        facts.append(("the two surveys' navigation allows (95 %)", allowed))
        facts.append(("navigation gate", "<b>tripped</b>: " + esc(gate.get("beyond", ""))
                      if gate.get("tripped") else "passed: the correction is within what the "
                      "navigation allows"))
    elif gate:
        facts.append(("navigation gate", "not evaluated: " + esc(gate.get("message", ""))))
    return "\n".join([facts_table(facts), '<p class="caption">B is carried onto A by a rigid '
                      "correction estimated on ground that did not change (changes are "
                      "outliers and never pull it); every figure of this report is after it."
                      "</p>"])


def change3d(c):
    """The change along the local normal at A's core points (walls), by slope class."""
    r = c.compare.get("change3d")
    if not isinstance(r, dict):
        return None
    if not r.get("computed"):
        return f"<p>Not computed: {esc(strip_paths(r.get('message', '')))}</p>"
    by = r.get("by_slope") if isinstance(r.get("by_slope"), dict) else {}
    lod25 = c.compare["change"].get("median_lod95_by_slope_m") or {}
    names = (("floor_0_20_deg", "floors and benches (< 20 deg)"),
             ("face_20_45_deg", "faces (20-45 deg)"), ("wall_45_90_deg", "walls (>= 45 deg)"))
    rows = []
    for key, label in names:
        b = by.get(key) if isinstance(by.get(key), dict) else {}
        l2 = lod25.get(key)
        rows.append([esc(label), num(b.get("measured", 0)), num(b.get("significant", 0)),
                     num(float(b["median_lod95_m"]), 3) if isinstance(
                         b.get("median_lod95_m"), (int, float)) else "?",
                     num(float(l2), 3) if isinstance(l2, (int, float)) else "?"])
    return "\n".join([
        f"<p>{esc(strip_paths(r.get('message', '')))}</p>",
        table(rows, header=["ground", "core points measured", "significant",
                            "smallest detectable along the normal (median LoD95, m)",
                            "smallest detectable vertically (median LoD95, m)"]),
        _change_points_map(c),
        '<p class="caption">Along the normal (M3C2-like, change_points.ply): on walls a change '
        "is measured across the face, where the vertical difference of the grids sees it as a "
        "horizontal shift.</p>",
        _regions3d_table(c)])


def _regions3d_table(c):
    """The change mesh's regions (compare.json change_mesh.regions): on the surface, walls
    included, each with its volume along its mean normal and U95; "" without them."""
    m = c.compare.get("change_mesh")
    regions = m.get("regions") if isinstance(m, dict) else None
    if not isinstance(regions, list) or not regions:
        return ""
    rows = []
    for r in sorted(regions, key=lambda r: -abs(float(r.get("volume_m3", 0.0)))):
        rows.append([esc(r.get("id", "?")), esc(r.get("kind", "?")),
                     num(float(r.get("area_m2", 0.0)), 1),
                     num(float(r.get("mean_slope_deg", 0.0)), 0),
                     num(float(r.get("mean_distance_m", 0.0)), 3),
                     f"{num(float(r.get('volume_m3', 0.0)), 2)} &plusmn; "
                     f"{num(float(r.get('u95_m3', 0.0)), 2)}"])
    for kind in ("cut", "fill"):
        t = m.get(kind) if isinstance(m.get(kind), dict) else None
        if t is not None:
            rows.append([f"<b>{kind}</b>", f"{num(int(t.get('regions', 0)))} regions",
                         num(float(t.get("area_m2", 0.0)), 1), "", "",
                         f"<b>{num(float(t.get('volume_m3', 0.0)), 2)} &plusmn; "
                         f"{num(float(t.get('u95_m3', 0.0)), 2)}</b>"])
    return "\n".join([
        "<h3>Change regions on the surface (walls included)</h3>",
        table(rows, header=["region", "kind", "area on the surface (m\u00b2)", "slope (deg)",
                            "mean distance along its axis (m)", "volume (m\u00b3, U95)"]),
        '<p class="caption">The change mesh\'s regions (change_regions_3d.geojson, the '
        "region of each vertex in change_mesh.ply): significant vertices of one sign joined by "
        "the mesh's edges, each volume measured along the region's mean normal (on a wall, "
        "across the face) against the unchanged ground 1-3 m around it, its U95 from both "
        "surveys' uncertainty, the co-registration, that ground's offset and the rim left "
        "below detection.</p>"])


def _change_points_map(c):
    """The significant core points of change_points.ply over A's hill-shade, coloured by the
    distance along the normal, those on walls (>= 45 deg) ringed; "" without the file."""
    if not os.path.isfile(c.path("change_points.ply")):
        return ""
    try:
        v = Ply(c.path("change_points.ply")).elements.get("vertex")
    except PlyError as e:
        c.problems.append(f"change_points.ply: {strip_paths(e)}")
        return ""
    need = ("x", "y", "distance_m", "significance", "slope_deg")
    if v is None or not all(k in (v.dtype.names or ()) for k in need):
        c.problems.append("change_points.ply: no " + ", ".join(need) + " per vertex")
        return ""
    sig = np.asarray(v["significance"]) != 0
    dist = np.asarray(v["distance_m"], dtype=np.float64)
    sig &= np.isfinite(dist)
    x, y = np.asarray(v["x"], dtype=np.float64), np.asarray(v["y"], dtype=np.float64)
    measured = np.isfinite(dist)
    if not measured.any():
        return ""
    dem_a = dem_of(c.a)
    if dem_a is not None:
        ext = _extent_of_data(dem_a, dem_a["bands"].get("elevation", np.zeros((1, 1))))
    else:
        pad = 1.0
        ext = (x.min() - pad, x.max() + pad, y.min() - pad, y.max() + pad)
    w, h = ext[1] - ext[0], ext[3] - ext[2]
    fig, a = plt.subplots(figsize=(11, float(np.clip(11 * h / w, 3.5, 12)) + 1.0),
                          layout="constrained")
    if dem_a is not None:
        _hillshade(a, dem_a)
    lim = _sym_limit(dist[sig]) if sig.any() else 0.5
    im = a.scatter(x[sig], y[sig], c=dist[sig], s=9, cmap="RdBu",
                   norm=TwoSlopeNorm(vcenter=0.0, vmin=-lim, vmax=lim), zorder=3,
                   linewidths=0)
    wall = sig & (np.asarray(v["slope_deg"], dtype=np.float64) >= 45.0)
    if wall.any():
        a.scatter(x[wall], y[wall], s=16, facecolors="none", edgecolors="0.15",
                  linewidths=0.4, zorder=4, label=f"on walls (>= 45 deg): {int(wall.sum())}")
        a.legend(loc="upper left", fontsize=8, framealpha=0.85)
    _map_furniture(a, ext, _crs(c).get("horizontal") or "")
    fig.colorbar(im, ax=a, shrink=0.8, pad=0.01).set_label(
        "B - A along the normal (m): red loss, blue gain")
    a.set_title(f"Significant change along the surface normal: {int(sig.sum())} of "
                f"{int(measured.sum())} core points measured", fontsize=10)
    return c.figure(fig, "change_normal_map", "significant change along the normal")


def capacity(c):
    """Both surveys' capacity curves (compare's CSVs), each water level dashed, and the
    figures at the water level."""
    cap = c.compare["capacity"]
    curves = []
    for side, name in (("a", "capacity_a.csv"), ("b", "capacity_b.csv")):
        try:
            curves.append((_label(c, side), COLOUR[side], read_csv(c.path(name)),
                           float(cap[side]["water_level_m"])))
        except (OSError, ValueError) as e:
            c.unusable[name] = strip_paths(e)
            c.missing_product(name)
    out = []
    if curves:
        fig, (av, aa) = plt.subplots(1, 2, figsize=(11, 4.6), sharey=True, layout="constrained")
        draw_curves(av, aa, curves)
        vertical = _crs(c).get("vertical") or "datum"
        av.set_ylabel(f"water level (m, {vertical})", fontsize=8)
        fig.suptitle("Capacity of both surveys: volume and water-surface area against water "
                     "level", fontsize=11)
        out.append(c.figure(fig, "change_capacity", "capacity curves of both surveys"))
    rows = []
    for key, label, digits, unit in (("water_level_m", "water level", 3, "m"),
                                     ("deepest_m", "deepest node", 3, "m"),
                                     ("volume_at_water_level_m3", "volume at the water level",
                                      0, "m&sup3;"),
                                     ("area_at_water_level_m2", "water-surface area at the "
                                      "water level", 0, "m&sup2;"),
                                     ("surveyed_area_m2", "surveyed area", 0, "m&sup2;")):
        va, vb = float(cap["a"][key]), float(cap["b"][key])
        rows.append([esc(label), f"{num(va, digits)} {unit}", f"{num(vb, digits)} {unit}",
                     f"{num(vb - va, digits)} {unit}"])
    out.insert(0, table(rows, header=["", _label(c, "a"), _label(c, "b"), "B - A"],
                        cls="capacity"))
    out.append('<p class="caption">Over each survey\'s surveyed nodes only (ground a survey did '
               "not reach is not filled in: compare the surveyed areas before the volumes). The "
               "tables, a row every 0.25 m: capacity_a.csv and capacity_b.csv.</p>")
    return "\n".join(out)


def terrain_b(c):
    """The slope and crawler maps of the later survey (the single-survey report's section)."""
    n_problems, n_missing = len(c.b.problems), len(c.b.missing)
    html = planning.terrain(c.b)
    c.problems.extend(f"survey B: {x}" for x in c.b.problems[n_problems:])
    c.missing.extend(f"B's {x}" for x in c.b.missing[n_missing:])
    return html


def quality(c):
    gates = _gates(c)
    if not gates:
        return "<p>No quality gate of the comparison tripped.</p>"
    rows = [[esc(g.get("stage", "?")), esc(g.get("gate", "?")),
             esc(strip_paths(g.get("message", "")))] for g in gates]
    return table(rows, header=["stage", "gate", "message"])


SECTIONS = (
    ("surveys", "Surveys compared", surveys),
    ("summary", "Summary", summary),
    ("change-map", "Map of significant change", change_map),
    ("volumes", "Volumes of cut and fill", volumes),
    ("sections", "Cross-sections at the largest change", cross_sections),
    ("registration", "Co-registration of the surveys", registration),
    ("change3d", "Change along the surface normal", change3d),
    ("capacity", "Capacity curves", capacity),
    ("terrain", "Mine planning at survey B: slopes and the crawler's reach", terrain_b),
    ("quality", "Quality gates", quality),
)
