# SPDX-License-Identifier: MIT
"""The client's sections of the report: the cover (survey metadata), the one-page summary
(the IHO S-44 compliance statement in words, coverage, key figures, datums and units,
caveats), the datums with the water level and the sound-speed casts applied, and the maps in
the projected CRS with grid coordinates, scale bar and north arrow. Each is a function of the
products (loaders.Products); none shows a path of the processing machine."""

import datetime
import math
import os

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.colors import LightSource, ListedColormap, Normalize  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from .maps import (MapError, add_furniture, grid_convergence_deg, raster_extent,  # noqa: E402
                   read_geotiff, utm_central_meridian_deg, world_to_grid)
from .util import esc, facts_table, num, strip_paths, table  # noqa: E402

NOT_SET = '<span class="not-set">not set</span>'
# The S-44 share of soundings within the order's limits that meets it (S-44 Ed. 6.1 Table 1:
# uncertainties at the 95 % confidence level).
S44_REQUIRED_SHARE = 0.95
METADATA_TEXT = ("project", "client", "site", "survey_id", "surveyor", "organisation", "vessel",
                 "notes")
EQUIPMENT_ROLES = {"multibeam": "Multibeam echosounder", "gnss_ins": "GNSS/INS"}


def _text(v):
    return v.strip() if isinstance(v, str) and v.strip() else None


def _number(v):
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def survey_metadata(summary):
    """The survey's metadata: summary.json "metadata" (pitmap run's), with what older
    products have instead where a field is unset (the CRS and datum records, the first and last
    ping, the vehicle's name). Every value is a string or None ("not set"); "equipment" a list
    of (role, model); "sources" says which fields came from the fallbacks."""
    md = summary.get("metadata") if isinstance(summary.get("metadata"), dict) else {}
    out = {k: _text(md.get(k)) for k in METADATA_TEXT}
    out["sources"] = {}
    out["equipment"] = []
    for e in md.get("equipment") or []:
        if isinstance(e, dict) and _text(e.get("model")):
            out["equipment"].append((str(e.get("role", "")), _text(e["model"])))
    tm = summary.get("time") if isinstance(summary.get("time"), dict) else {}
    for key, fallback in (("survey_start_utc", "first_ping_utc"),
                          ("survey_end_utc", "last_ping_utc")):
        out[key] = _text(md.get(key))
        if out[key] is None and _text(tm.get(fallback)):
            out[key] = _iso_seconds(tm[fallback])
            out["sources"][key] = "first and last ping"
    out["processed_utc"] = _text(md.get("processed_utc"))
    out["software"] = _text(md.get("software"))
    veh = summary.get("vehicle") if isinstance(summary.get("vehicle"), dict) else {}
    if out["vessel"] is None and _text(veh.get("name")):
        out["vessel"] = _text(veh["name"])
        out["sources"]["vessel"] = "vehicle.yaml name"
    h = md.get("horizontal_crs") if isinstance(md.get("horizontal_crs"), dict) else {}
    out["horizontal_crs"], out["horizontal_epsg"] = _text(h.get("name")), h.get("epsg")
    utm = summary.get("utm") if isinstance(summary.get("utm"), dict) else {}
    if out["horizontal_crs"] is None and utm.get("zone"):
        hemi = "N" if utm.get("northern", True) else "S"
        out["horizontal_crs"] = f"WGS 84 / UTM zone {utm['zone']}{hemi}"
        out["horizontal_epsg"] = utm.get("epsg")
        out["sources"]["horizontal_crs"] = "summary.json utm"
    v = md.get("vertical_crs") if isinstance(md.get("vertical_crs"), dict) else {}
    out["vertical_crs"], out["vertical_epsg"] = _text(v.get("name")), v.get("epsg")
    out["vertical_description"] = _text(v.get("description"))
    vd = summary.get("vertical_datum") if isinstance(summary.get("vertical_datum"), dict) else {}
    if out["vertical_crs"] is None and _text(vd.get("vertical_crs")):
        out["vertical_crs"] = _text(vd["vertical_crs"])
        out["vertical_epsg"] = vd.get("vertical_epsg")
        out["vertical_description"] = _text(vd.get("description"))
        out["sources"]["vertical_crs"] = "summary.json vertical_datum"
    out["s44_order_target"] = _text(md.get("s44_order_target"))
    s44 = _s44(summary)
    if out["s44_order_target"] is None and s44 and _text(s44.get("order")):
        out["s44_order_target"] = _text(s44["order"])
        out["sources"]["s44_order_target"] = "the grid stage's order"
    return out


def _iso_seconds(t):
    """'2026-06-15T09:00:00.000000Z' -> '2026-06-15T09:00:00Z'."""
    t = str(t)
    return t.split(".")[0] + "Z" if "." in t and t.endswith("Z") else t


def _s44(summary):
    g = (summary.get("stages") or {}).get("grid")
    q = g.get("s44") if isinstance(g, dict) else None
    return q if isinstance(q, dict) else None


def report_title(summary):
    """Project, site and survey id of the metadata; without any, a generic title (never the
    folder's name)."""
    md = survey_metadata(summary)
    parts = [md[k] for k in ("project", "site", "survey_id") if md[k]]
    return " \u2013 ".join(parts) if parts else "Bathymetric survey report"


def subtitle(p):
    """The line under the title: client and survey period when set."""
    md = survey_metadata(p.summary)
    parts = []
    if md["client"]:
        parts.append(f"for {esc(md['client'])}")
    if md["survey_start_utc"]:
        parts.append(f"surveyed {esc(md['survey_start_utc'][:10])}")
    return "Bathymetric survey report" + (", " + ", ".join(parts) if parts else "")


def _crs_text(name, epsg):
    if not name:
        return NOT_SET
    return esc(name) + (f" (EPSG:{esc(epsg)})" if epsg else "")


def _utc_text(t):
    if not t:
        return NOT_SET
    return esc(t.replace("T", " ").replace("Z", " UTC"))


def cover(p):
    """The cover: who, where, when, with what, in which datums."""
    md = survey_metadata(p.summary)

    def field(key):
        v = md[key]
        if v is None:
            return NOT_SET
        src = md["sources"].get(key)
        return esc(v) + (f' <span class="source">(from {esc(src)})</span>' if src else "")

    period = NOT_SET
    if md["survey_start_utc"] or md["survey_end_utc"]:
        period = f"{_utc_text(md['survey_start_utc'])} to {_utc_text(md['survey_end_utc'])}"
        if "survey_start_utc" in md["sources"]:
            period += f' <span class="source">(from the {md["sources"]["survey_start_utc"]})</span>'
    equipment = "<br>".join(f"{esc(EQUIPMENT_ROLES.get(r, r or 'equipment'))}: {esc(m)}"
                            for r, m in md["equipment"]) or NOT_SET
    rows = [("Project", field("project")), ("Client", field("client")), ("Site", field("site")),
            ("Survey ID", field("survey_id")), ("Organisation", field("organisation")),
            ("Surveyor", field("surveyor")), ("Vessel", field("vessel")),
            ("Equipment", equipment), ("Survey period", period),
            ("Processed", _utc_text(md["processed_utc"])),
            ("Software", field("software")),
            ("Horizontal CRS", _crs_text(md["horizontal_crs"], md["horizontal_epsg"])),
            ("Vertical datum", _crs_text(md["vertical_crs"], md["vertical_epsg"])),
            ("IHO S-44 order sought", field("s44_order_target")),
            ("Report written", datetime.datetime.now(datetime.timezone.utc)
             .strftime("%Y-%m-%d %H:%M:%S UTC"))]
    if md["notes"]:
        rows.append(("Notes", esc(md["notes"])))
    return '<div class="cover">' + facts_table(rows) + "</div>"


def _pct(share, digits=1):
    """A share as a percentage that never rounds a shortfall up to 100 (99.96 % -> 99.9)."""
    v = 100.0 * share
    f = 10 ** digits
    return f"{math.floor(v * f + 1e-9) / f:.{digits}f}"


def compliance_statement(s44, target=None):
    """The S-44 verdict in words, from the grid stage's S-44 record: (verdict, sentence) with
    verdict "met", "not met" or "unknown". An order is met when at least 95 % of the soundings
    are within both its TVU and THU limits and, for an order that asks for feature detection
    (full coverage), no holiday is left; `target` (the order sought, default the record's)."""
    if not isinstance(s44, dict):
        return "unknown", "No IHO S-44 assessment was made (the grid stage did not run it)."
    order = target or s44.get("order")
    within = (s44.get("soundings_within_both") or {}).get(order)
    if _number(within) is None:
        return "unknown", (f"The IHO S-44 record has no figures for order {esc(order)}; "
                           "compliance cannot be stated.")
    std = esc(s44.get("standard") or "IHO S-44 Edition 6.1")
    lim = (s44.get("limits") or {}).get(order) or {}
    n = s44.get("soundings")
    holidays = s44.get("holiday_count")
    coverage = _number(s44.get("coverage_share"))
    feature = _number(s44.get("feature_size_m")) or _number(lim.get("feature_m"))
    wants_features = bool(feature) and (_number(lim.get("coverage_percent")) or 0) >= 100
    same_order = order == s44.get("order")
    uncertainty_ok = within >= S44_REQUIRED_SHARE
    coverage_ok = (not wants_features) or (same_order and holidays == 0)
    met = uncertainty_ok and coverage_ok
    counted = f" of the {num(n)} soundings" if isinstance(n, int) else " of the soundings"
    s = (f"The survey <b>{'meets' if met else 'does not meet'}</b> {std} Order "
         f"<b>{esc(order)}</b>: {_pct(within)} %{counted} are within the order's total "
         f"vertical and horizontal uncertainty limits at 95 % confidence (at least "
         f"{S44_REQUIRED_SHARE * 100:.0f} % required)")
    if coverage is not None:
        s += f", over {_pct(coverage)} % of the survey area"
    if wants_features:
        if not same_order:
            s += (f"; the holidays were searched for order {esc(s44.get('order'))}, not "
                  f"{esc(order)}, so full coverage for order {esc(order)} is not assessed")
        elif holidays == 0:
            s += f", with no holiday that could hide a {num(feature, 1)} m feature"
        else:
            s += (f"; <b>{num(holidays)} holiday(s)</b> could hide a {num(feature, 1)} m "
                  "feature, where the order asks for full coverage")
    s += "."
    if not uncertainty_ok:
        s += (f" The uncertainty limits of order {esc(order)} are met by too few soundings "
              f"({_pct(within)} %).")
    best = s44.get("strictest_order_met_95")
    if best and best != order:
        s += f" The strictest order whose uncertainty limits are met is {esc(best)}."
    elif not best:
        s += " No order's uncertainty limits are met by 95 % of the soundings."
    if s44.get("sound_speed_not_assessable"):
        s += (" <b>Not assessable for sound speed:</b> "
              f"{esc(s44['sound_speed_not_assessable'])}.")
    return ("met" if met else "not met"), s


def caveats(p):
    """What the client must know before using the results, in words."""
    out = []
    for g in p.summary.get("quality_gates") or []:
        if isinstance(g, dict):
            out.append(f"Quality gate <i>{esc(g.get('gate', '?'))}</i> "
                       f"({esc(g.get('stage', '?'))}): {esc(strip_paths(g.get('message', '')))}")
    if "slam" not in p.stages:
        out.append("The trajectory was not refined by SLAM: the positions are the GNSS/INS "
                   "solution as recorded.")
    if not isinstance(p.summary.get("refraction"), dict):
        out.append("No sound-speed cast was applied: beams were traced as straight lines "
                   "(refraction off). In a stratified pit the outer beams carry the error.")
    md = survey_metadata(p.summary)
    if not md["vertical_crs"]:
        out.append("No vertical datum is recorded for these products.")
    vd = p.summary.get("vertical_datum")
    if isinstance(vd, dict) and vd.get("datum") == "ellipsoid":
        out.append("Heights are above the WGS 84 ellipsoid: no geoid, water level or tide was "
                   "applied.")
    snd = p.summary.get("soundings")
    if isinstance(snd, dict) and isinstance(snd.get("total"), int) and snd["total"] > 0:
        rej = sum(v for v in (snd.get("rejected") or {}).values() if isinstance(v, int))
        share = rej / snd["total"]
        if share > 0.05:
            out.append(f"{num(100 * share, 1)} % of the soundings were rejected by the "
                       "automatic cleaning (see Soundings kept and rejected).")
    if not _s44(p.summary):
        out.append("No IHO S-44 assessment was made (no grid stage): compliance is not stated.")
    return out


def _area_m2(p):
    g = p.stages.get("grid")
    q = _s44(p.summary)
    if isinstance(g, dict) and q and _number(g.get("resolution_m")):
        nodes = q.get("nodes_survey_area") or q.get("nodes")
        if isinstance(nodes, int):
            return nodes * float(g["resolution_m"]) ** 2
    return None


def _dem(p):
    """dem.tif read once (None when absent or unreadable; the reason in p.unusable)."""
    if hasattr(p, "_dem_cache"):
        return p._dem_cache
    dem = None
    if os.path.isfile(p.path("dem.tif")):
        try:
            dem = read_geotiff(p.path("dem.tif"))
            foreign = p.foreign_run("dem.tif", dem["metadata"].get("pitmap_run_id"))
            if foreign:
                p.unusable["dem.tif"] = foreign
                dem = None
        except ImportError:
            p.unusable["dem.tif"] = "python3-gdal is not installed"
        except (MapError, RuntimeError, OSError) as e:
            p.unusable["dem.tif"] = f"unreadable: {strip_paths(e)}"
    p._dem_cache = dem
    return dem


def _depth_sense(p, dem):
    """(values of the elevation band as shown, what they are, whether depths): depths below a
    water-level datum (positive down), else heights in the vertical CRS."""
    vd = p.summary.get("vertical_datum") if isinstance(p.summary.get("vertical_datum"),
                                                       dict) else {}
    z = dem["bands"].get("elevation")
    name = vd.get("vertical_crs") or dem["metadata"].get("pitmap_vertical_datum") or "the datum"
    if vd.get("datum") == "water_level":
        return -z, f"depth below {name}", True
    return z, f"height in {name}", False


def summary(p):
    """The one page a client reads: verdict, coverage, key figures, datums, caveats."""
    out = []
    md = survey_metadata(p.summary)
    q = _s44(p.summary)
    verdict, sentence = compliance_statement(q, md["s44_order_target"])
    out.append(f'<p class="verdict {verdict.replace(" ", "-")}">{sentence}</p>')
    rows = []
    area = _area_m2(p)
    if q:
        cov = _number(q.get("coverage_share"))
        rows.append(("Surveyed area", (f"{num(area, 0)} m\u00b2 ({num(area / 1e4, 2)} ha)"
                                       if area else "not recorded") +
                     (f", {_pct(cov, 2)} % covered by the depth grid" if cov is not None else "")))
        hol = q.get("holiday_count")
        if q.get("feature_size_m"):
            rows.append(("Holidays", f"{num(hol)} (gaps that could hide a "
                         f"{num(q['feature_size_m'], 1)} m feature); {num(q.get('gaps', 0))} "
                         "smaller gaps"))
        else:
            rows.append(("Holidays", f"not searched for order {esc(q.get('order', '?'))}; "
                         f"{num(q.get('gaps', 0))} gaps mapped"))
    dem = _dem(p)
    if dem is not None and "elevation" in dem["bands"]:
        v, label, is_depth = _depth_sense(p, dem)
        ok = v[np.isfinite(v)]
        if len(ok):
            lo, hi = float(np.min(ok)), float(np.max(ok))
            what = "Depth" if is_depth else "Height"
            rows.append((f"{what} range", f"{num(lo, 2)} to {num(hi, 2)} m, median "
                         f"{num(float(np.median(ok)), 2)} m: {esc(label)}, of the depth grid"))
    g = p.stages.get("grid")
    if isinstance(g, dict):
        rows.append(("Depth grid", f"{num(g.get('resolution_m', float('nan')), 2)} m nodes, "
                     f"{num(g.get('nodes_filled', 0))} filled (CUBE)"))
        rows.append(("Uncertainty per sounding (95 %)",
                     f"median TVU {num(g.get('median_tvu_95_m', float('nan')), 3)} m, "
                     f"median THU {num(g.get('median_thu_95_m', float('nan')), 3)} m"))
        cl = (q or {}).get("crossline") or {}
        if cl.get("compared"):
            rows.append(("Crossline check", f"RMS {num(cl.get('rms_m', 0), 3)} m over "
                         f"{num(cl['compared'])} soundings, {_pct(cl.get('within_tvu', 0))} % "
                         "within the order's TVU"))
    snd = p.summary.get("soundings")
    if isinstance(snd, dict) and isinstance(snd.get("total"), int):
        rows.append(("Soundings", f"{num(snd.get('accepted', 0))} kept of "
                     f"{num(snd['total'])}"))
    tm = p.summary.get("time") if isinstance(p.summary.get("time"), dict) else {}
    t0, t1 = _number(tm.get("first_ping_gps_s")), _number(tm.get("last_ping_gps_s"))
    if t0 is not None and t1 is not None:
        rows.append(("Survey duration", f"{(t1 - t0) / 60:.1f} min of pings"))
    main = p.traj.get("final") or p.traj.get("initial")
    if main is not None:
        length = float(np.sum(np.hypot(np.diff(main["x"]), np.diff(main["y"]))))
        rows.append(("Track length", f"{length:.0f} m"))
    out.append("<h3>Key figures</h3>")
    out.append(facts_table(rows) if rows else "<p>No figures recorded.</p>")
    out.append("<h3>Datums and units</h3>")
    out.append(facts_table(_datum_rows(p, md)))
    cav = caveats(p)
    out.append("<h3>Caveats</h3>")
    out.append("<ul>" + "".join(f"<li>{c}</li>" for c in cav) + "</ul>" if cav else
               "<p>None: every stage explained its data within its quality limits.</p>")
    return "\n".join(out)


def _datum_rows(p, md):
    vd = p.summary.get("vertical_datum") if isinstance(p.summary.get("vertical_datum"),
                                                       dict) else {}
    rows = [("Horizontal", _crs_text(md["horizontal_crs"], md["horizontal_epsg"]) +
             "; eastings and northings in metres, maps oriented to grid north"),
            ("Vertical", _crs_text(md["vertical_crs"], md["vertical_epsg"]) +
             (f"; {esc(md['vertical_description'])}" if md["vertical_description"] else ""))]
    rows.append(("Water level", _water_level_text(vd)))
    rows.append(("Sound speed", _casts_text(p.summary.get("refraction"))))
    rows.append(("Units", "metres; depths positive down, heights positive up; times UTC"))
    return rows


def _water_level_text(vd):
    if not vd:
        return NOT_SET
    datum = vd.get("datum")
    if datum == "water_level":
        if vd.get("water_level_source") == "file":
            f = os.path.basename(str(vd.get("water_level_file", "")))
            return (f"observed levels from {esc(f)} ({num(vd.get('water_levels', 0))} "
                    "readings), interpolated to each ping")
        ws = vd.get("gnss_water_surface") or {}
        return ("the pit's water surface measured by the vessel's GNSS: median "
                f"{num(_number(ws.get('median_m')) or float('nan'), 3)} m ellipsoidal "
                f"(range {num(_number(ws.get('min_m')) or float('nan'), 3)} to "
                f"{num(_number(ws.get('max_m')) or float('nan'), 3)} m), running median over "
                f"{num(_number(ws.get('smoothing_window_s')) or 0, 0)} s")
    if datum == "geoid":
        return ("none (heights above the geoid, grid "
                f"{esc(os.path.basename(str(vd.get('geoid_grid', ''))))})")
    return "none applied (heights above the WGS 84 ellipsoid)"


def _casts_text(ref):
    if not isinstance(ref, dict):
        return "no cast applied (straight rays)"
    casts = ref.get("casts") or []
    return (f"{len(casts)} cast(s) applied, chosen per ping by "
            f"{esc(str(ref.get('selection', '?')).replace('_', ' '))}")


def datums(p):
    """Horizontal and vertical datums, the water level used, the sound-speed casts applied
    (time, place, a speed-against-depth plot)."""
    md = survey_metadata(p.summary)
    out = [facts_table(_datum_rows(p, md))]
    o = p.summary.get("world_origin") or {}
    utm = p.summary.get("utm") if isinstance(p.summary.get("utm"), dict) else {}
    lat, lon = _number(o.get("latitude_deg")), _number(o.get("longitude_deg"))
    if lat is not None and lon is not None and utm.get("zone"):
        gamma = grid_convergence_deg(lat, lon, utm_central_meridian_deg(int(utm["zone"])))
        side = "east" if gamma >= 0 else "west"
        out.append(f"<p>Maps are drawn to grid north. At the site ({num(lat, 5)}&deg;, "
                   f"{num(lon, 5)}&deg;) grid north lies {num(abs(gamma), 2)}&deg; {side} of "
                   "true north (grid convergence).</p>")
    out.append("<h3>Sound-speed casts applied</h3>")
    ref = p.summary.get("refraction")
    if not isinstance(ref, dict):
        out.append("<p>No sound-speed cast was applied: each beam was traced as a straight "
                   "line at the speed measured at the transducer.</p>")
        return "\n".join(out)
    casts = [c for c in ref.get("casts") or [] if isinstance(c, dict)]
    rows = []
    for i, c in enumerate(casts):
        lat_c, lon_c = _number(c.get("latitude_deg")), _number(c.get("longitude_deg"))
        where = (f"{num(lat_c, 5)}&deg;, {num(lon_c, 5)}&deg;"
                 if lat_c is not None and lon_c is not None else "not recorded")
        rows.append([str(i + 1), esc(strip_paths(c.get("name", "?"))),
                     _utc_text(_iso_seconds(c["time_utc"])) if c.get("time_utc")
                     else "not recorded", where, num(c.get("points", 0)),
                     num(_number(c.get("max_depth_m")) or float("nan"), 1),
                     num(_number(c.get("surface_speed_mps")) or float("nan"), 1)])
    out.append(table(rows, header=["cast", "file", "time", "position (WGS 84)", "points",
                                   "deepest (m)", "speed at the surface (m/s)"]))
    out.append(f"<p>Chosen per ping: {esc(str(ref.get('selection', '?')).replace('_', ' '))}; "
               "speed at the transducer face from the "
               f"{esc(str(ref.get('surface_speed', '?')).replace('_', ' '))}.</p>")
    profiles = [(i, c["profile"]) for i, c in enumerate(casts)
                if isinstance(c.get("profile"), dict) and c["profile"].get("depth_m")]
    if profiles:
        fig, a = plt.subplots(figsize=(5.5, 5.0), layout="constrained")
        for i, pr in profiles:
            a.plot(pr["speed_mps"], pr["depth_m"], "-", lw=1.5, label=f"cast {i + 1}")
        a.invert_yaxis()
        a.set_xlabel("sound speed (m/s)")
        a.set_ylabel("depth below the water surface (m)")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
        a.set_title("Sound speed against depth")
        out.append(p.figure(fig, "sound_speed_casts", "sound speed against depth of the casts"))
    else:
        out.append("<p>The casts' profiles are not in summary.json (products of an older "
                   "pitmap).</p>")
    return "\n".join(out)


def _map_figure(extent, panels=1):
    w = extent[1] - extent[0]
    h = extent[3] - extent[2]
    width = 11.0 if panels == 1 else 15.0
    panel_w = width / panels
    height = float(np.clip(panel_w * h / w, 3.0, 12.0)) + 1.2
    return plt.subplots(1, panels, figsize=(width, height), layout="constrained", squeeze=False)


def _track_on_grid(p, epsg):
    tr = p.traj.get("final") or p.traj.get("initial")
    o = p.summary.get("world_origin") or {}
    ref = (_number(o.get("latitude_deg")), _number(o.get("longitude_deg")),
           _number(o.get("height_m")))
    if tr is None or epsg is None or None in ref:
        return None
    step = max(1, len(tr["x"]) // 5000)
    try:
        return world_to_grid(ref, epsg, tr["x"][::step], tr["y"][::step], tr["z"][::step])
    except (ImportError, RuntimeError):
        return None


def maps(p):
    """The depth chart and the uncertainty and coverage maps from dem.tif and
    s44_holidays.tif, in the projected CRS: easting/northing ticks, a scale bar and a north
    arrow (grid north), with their legends."""
    dem = _dem(p)
    if dem is None:
        why = p.unusable.get("dem.tif", "no depth grid (the grid stage did not run)")
        return f"<p>No depth map: {esc(why)}.</p>"
    md = survey_metadata(p.summary)
    crs = dem["crs"] or md["horizontal_crs"] or ""
    epsg = dem["epsg"] or md["horizontal_epsg"]
    extent = raster_extent(dem["gt"], dem["nx"], dem["ny"])
    v, label, is_depth = _depth_sense(p, dem)
    out = []
    fig, ax = _map_figure(extent)
    a = ax[0][0]
    ok = v[np.isfinite(v)]
    lo, hi = (np.percentile(ok, [0.5, 99.5]) if len(ok) else (0.0, 1.0))
    cmap = plt.get_cmap("viridis_r" if is_depth else "viridis")
    norm = Normalize(lo, hi)
    rgb = cmap(norm(np.where(np.isfinite(v), v, lo)))[..., :3]
    z = np.where(np.isfinite(v), v, np.nanmean(v) if len(ok) else 0.0)
    shade = LightSource(azdeg=315, altdeg=45).shade_rgb(
        rgb, -z if is_depth else z, fraction=0.6, blend_mode="soft", vert_exag=2.0,
        dx=dem["gt"][1], dy=-dem["gt"][5])
    a.imshow(np.dstack([shade, np.isfinite(v).astype(float)]), extent=extent,
             interpolation="nearest", zorder=1)
    legend = []
    if len(ok) and hi > lo:
        step = _contour_step(hi - lo)
        levels = np.arange(math.ceil(lo / step) * step, hi, step)
        if 1 < len(levels) <= 40:
            ny, nx = v.shape
            xs = extent[0] + (np.arange(nx) + 0.5) * dem["gt"][1]
            ys = extent[3] + (np.arange(ny) + 0.5) * dem["gt"][5]
            cs = a.contour(xs, ys, v, levels=levels, colors="k", linewidths=0.4, alpha=0.6,
                           zorder=2)
            a.clabel(cs, levels[::2], fontsize=6, fmt="%g")
            legend.append(plt.Line2D([], [], color="k", lw=0.6,
                                     label=f"contours every {step:g} m"))
    track = _track_on_grid(p, epsg)
    if track is not None:
        a.plot(track[0], track[1], color="white", lw=0.5, alpha=0.8, zorder=3)
        legend.append(plt.Line2D([], [], color="0.6", lw=1.0, label="vessel track"))
    hol = _holiday_raster(p)
    if hol is not None and np.any(hol == 2):
        xs = extent[0] + (np.arange(hol.shape[1]) + 0.5) * dem["gt"][1]
        ys = extent[3] + (np.arange(hol.shape[0]) + 0.5) * dem["gt"][5]
        a.contour(xs, ys, (hol == 2).astype(float), levels=[0.5], colors="magenta",
                  linewidths=1.2, zorder=4)
        legend.append(plt.Line2D([], [], color="magenta", lw=1.2, label="holiday"))
    bar = add_furniture(a, extent, crs)
    if legend:
        a.legend(handles=legend, loc="upper left", fontsize=8, framealpha=0.85)
    cb = fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=a, shrink=0.85, pad=0.01)
    cb.set_label(f"{label} (m)")
    if is_depth:
        cb.ax.invert_yaxis()
    a.set_title(f"{'Depths' if is_depth else 'Heights'} of the CUBE surface "
                f"({dem['gt'][1]:g} m grid), hill-shaded")
    out.append(p.figure(fig, "map_depth", "depth map in grid coordinates"))
    out.append(f'<p class="caption">Grid: {esc(crs or "not recorded")}; north arrow: grid '
               f"north; scale bar {bar[2]:g} m. Colours: {esc(label)} in metres; white: no "
               "data.</p>")
    out.append(_uncertainty_coverage_map(p, dem, extent, crs, hol))
    return "\n".join(out)


def _contour_step(span):
    """A 1-2-5 contour interval giving about 8-20 contours over `span` metres."""
    target = span / 12.0
    k = math.floor(math.log10(target))
    for m in (1, 2, 5, 10):
        if m * 10.0 ** k >= target:
            return m * 10.0 ** k
    return 10.0 ** (k + 1)


def _holiday_raster(p):
    if not os.path.isfile(p.path("s44_holidays.tif")):
        return None
    try:
        h = read_geotiff(p.path("s44_holidays.tif"))
    except (ImportError, MapError, RuntimeError, OSError):
        return None
    if p.foreign_run("s44_holidays.tif", h["metadata"].get("pitmap_run_id")):
        return None
    return next(iter(h["bands"].values()), None)


def _uncertainty_coverage_map(p, dem, extent, crs, hol):
    unc = dem["bands"].get("uncertainty")
    if unc is None and hol is None:
        return ""
    panels = [k for k, v in (("uncertainty", unc), ("coverage", hol)) if v is not None]
    fig, ax = _map_figure(extent, panels=len(panels))
    for a, kind in zip(ax[0], panels):
        if kind == "uncertainty":
            ok = unc[np.isfinite(unc)]
            hi = float(np.percentile(ok, 99)) if len(ok) else 1.0
            im = a.imshow(unc, extent=extent, cmap="magma_r", vmin=0, vmax=max(hi, 1e-3),
                          interpolation="nearest")
            fig.colorbar(im, ax=a, shrink=0.8, pad=0.01).set_label(
                "node uncertainty, 95 % (m)")
            a.set_title("Uncertainty of the depth grid")
        else:
            cm = ListedColormap(["#cfe8cf", "#f2c14e", "#d7263d"])
            a.imshow(np.where(np.isfinite(hol), hol, np.nan), extent=extent, cmap=cm, vmin=-0.5,
                     vmax=2.5, interpolation="nearest")
            a.legend(handles=[Patch(color="#cfe8cf", label="covered"),
                              Patch(color="#f2c14e", label="gap (smaller than the feature)"),
                              Patch(color="#d7263d", label="holiday")],
                     loc="upper left", fontsize=8, framealpha=0.85)
            q = _s44(p.summary) or {}
            a.set_title(f"Coverage for IHO S-44 order {q.get('order', '?')}")
        add_furniture(a, extent, crs)
    return p.figure(fig, "map_uncertainty_coverage",
                    "uncertainty and coverage maps in grid coordinates")


def engineering_link(p):
    """Where the engineering details are, and the inputs by file name."""
    inputs = [os.path.basename(str(i).rstrip("/")) for i in p.summary.get("inputs") or []]
    out = ['<p>The processing details (trajectory before and after SLAM, point-cloud '
           "sections, TSDF weights, SLAM per iteration, boresight, sonar clock, stage times "
           'and memory) are in <a href="report_engineering.html">report_engineering.html</a> '
           "beside this report.</p>"]
    if inputs:
        out.append(facts_table([("Inputs", "<br>".join(esc(i) for i in inputs))]))
    return "\n".join(out)
