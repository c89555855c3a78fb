# SPDX-License-Identifier: MIT
"""The report's mine-planning section: the slope map of the surface and where a bottom crawler
can stand and drive from its launch point (terrain.tif and crawler.tif of the grid stage,
processor/hydro/terrain.hpp), with the areas of each class; and the pit's capacity curve
(water volume and area against water level) from dem.tif."""

import os

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from .capacity import capacity_curve, draw_curves, water_level_m, write_csv  # noqa: E402
from .maps import MapError, add_furniture, raster_extent, read_geotiff  # noqa: E402
from .sections_client import _dem as client_dem  # noqa: E402
from .sections_client import survey_metadata  # noqa: E402
from .util import not_produced, num, strip_paths, table  # noqa: E402

# crawler.tif's classes (terrain_stage.cpp): code, name, colour; 0 (no data) is never drawn.
CLASSES = (
    (1, "reachable", "#2ea043"),
    (2, "traversable, not reachable", "#4285f4"),
    (3, "too steep", "#f59a23"),
    (4, "step obstacle", "#d62728"),
    (5, "too rough", "#9467bd"),
)


def read_layers(p):
    """(terrain, crawler) GeoTIFFs, or an HTML line saying why the section cannot draw them."""
    try:
        terrain = read_geotiff(p.path("terrain.tif"))
        crawler = read_geotiff(p.path("crawler.tif"))
    except ImportError:
        return None, p.missing_product("terrain.tif", "python3-gdal is not installed")
    except (MapError, RuntimeError, OSError) as e:
        return None, not_produced("terrain.tif", f"unreadable: {strip_paths(e)}")
    for name, tif in (("terrain.tif", terrain), ("crawler.tif", crawler)):
        foreign = p.foreign_run(name, tif["metadata"].get("pitmap_run_id"))
        if foreign:
            return None, not_produced(name, foreign)
    return (terrain, crawler), None


def map_figure(p, tif, values, draw, title, fig_name):
    """A map of one band with the map furniture; `draw(axes, extent)` returns the artist."""
    ext = raster_extent(tif["gt"], tif["nx"], tif["ny"])
    crs = tif["crs"] or survey_metadata(p.summary)["horizontal_crs"] or ""
    w, h = ext[1] - ext[0], ext[3] - ext[2]
    width = 7.5
    fig, a = plt.subplots(figsize=(width, float(np.clip(width * h / w, 3, 10)) + 1.0),
                          layout="constrained")
    draw(fig, a, ext, values)
    a.set_title(title, fontsize=10)
    add_furniture(a, ext, crs)
    return p.figure(fig, fig_name, title)


def draw_slope(fig, a, ext, v):
    im = a.imshow(v, extent=ext, cmap="magma_r", vmin=0, vmax=60, interpolation="nearest")
    fig.colorbar(im, ax=a, shrink=0.8, pad=0.01).set_label("slope (deg)")


def draw_classes(fig, a, ext, v):
    cmap = ListedColormap([c for _, _, c in CLASSES])
    shown = np.where(np.isfinite(v), v, np.nan)
    a.imshow(shown, extent=ext, cmap=cmap, vmin=0.5, vmax=len(CLASSES) + 0.5,
             interpolation="nearest")
    a.legend(handles=[Patch(color=c, label=n) for _, n, c in CLASSES], loc="upper right",
             fontsize=7, framealpha=0.85)


def terrain(p):
    """Slope map, crawler map and the area table (issue 37 item 4)."""
    g = p.stages.get("grid")
    t = g.get("terrain") if isinstance(g, dict) else None
    if not isinstance(t, dict):
        return None  # terrain.enabled false, or no grid stage: no section
    layers, why = read_layers(p)
    if layers is None:
        return why
    terrain_tif, crawler_tif = layers
    figures = []
    if "slope" in terrain_tif["bands"]:
        figures.append(map_figure(p, terrain_tif, terrain_tif["bands"]["slope"], draw_slope,
                                  "Slope of the surface", "terrain_slope"))
    if "crawler" in crawler_tif["bands"]:
        figures.append(map_figure(p, crawler_tif, crawler_tif["bands"]["crawler"], draw_classes,
                                  "Where the crawler can stand and drive", "terrain_crawler"))
    areas = t.get("area_by_class_m2") or {}
    rows = [(name, f"{num(areas.get(name, 0), 0)} m&sup2;") for _, name, _ in CLASSES]
    limits = (f"slope up to {num(t.get('crawler_max_slope_deg', 0), 1)} deg, steps up to "
              f"{num(t.get('crawler_max_step_m', 0), 2)} m, roughness up to "
              f"{num(t.get('crawler_max_roughness_m', 0), 3)} m RMS over a "
              f"{num(t.get('window_m', 0), 2)} m footprint")
    if not t.get("launch_given"):
        launch = "none given (terrain.launch_easting, terrain.launch_northing): nothing is " \
                 "marked reachable"
    elif not t.get("launch_found"):
        launch = "no traversable ground near the launch point: nothing is reachable"
    else:
        e, n = t.get("launch_easting_northing", [0, 0])
        launch = (f"E {e:.1f}, N {n:.1f} (UTM; started "
                  f"{num(t.get('launch_snap_distance_m', 0), 1)} m from it)")
    facts = [("crawler", limits), ("launch point", launch),
             ("surface with data", f"{num(t.get('area_with_data_m2', 0), 0)} m&sup2;")]
    return "\n".join([table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"),
                      table(rows, header=["class", "area"]),
                      '<div class="pair">' + "".join(figures) + "</div>"])


def _summary_capacity(summary):
    """The capacity curve pitmap's grid stage put in summary.json (capacity), as
    capacity_curve returns it; None when summary.json has none (or not a whole one)."""
    cap = summary.get("capacity") if isinstance(summary, dict) else None
    if not isinstance(cap, dict) or not isinstance(cap.get("rows_level_area_volume"), list):
        return None
    keys = ("water_level_m", "deepest_m", "surveyed_area_m2", "area_at_water_level_m2",
            "volume_at_water_level_m3")
    if not all(isinstance(cap.get(k), (int, float)) for k in keys):
        return None
    rows = []
    for r in cap["rows_level_area_volume"]:
        if not (isinstance(r, list) and len(r) == 3
                and all(isinstance(x, (int, float)) for x in r)):
            return None
        rows.append(tuple(float(x) for x in r))
    if not rows:
        return None
    out = {k: float(cap[k]) for k in keys}
    out["rows"] = rows
    return out


def capacity(p):
    """The pit's capacity curve (issue 37 item 3): water volume and water-surface area against
    water level over the surveyed nodes, up to the survey's water level, as pitmap's grid stage
    put it in summary.json (capacity; else from dem.tif and the trajectory, as pitmap compare
    finds it); the table also as P/report/capacity.csv (the columns of capacity_a.csv)."""
    dem = client_dem(p)
    if dem is None or "elevation" not in dem["bands"]:
        return None  # the maps section says why there is no depth grid
    curve = _summary_capacity(p.summary)
    if curve is not None:
        level = curve["water_level_m"]
    else:  # products of a pitmap before summary.json held the curve
        level = water_level_m(p)
        if level is None:
            return ("<p>No capacity curve: the water level is not known (no readable "
                    "trajectory or world origin).</p>")
        curve = capacity_curve(dem["bands"]["elevation"], dem["gt"][1], level)
    if not curve["rows"]:
        return "<p>No capacity curve: dem.tif holds no heights.</p>"
    os.makedirs(p.fig_dir, exist_ok=True)
    write_csv(os.path.join(p.fig_dir, "capacity.csv"), curve)
    rows = np.array(curve["rows"])
    columns = {"level_m": rows[:, 0], "area_m2": rows[:, 1], "volume_m3": rows[:, 2]}
    fig, (av, aa) = plt.subplots(1, 2, figsize=(11, 4.6), sharey=True, layout="constrained")
    draw_curves(av, aa, [("this survey", "#1f77b4", columns, level)])
    av.set_ylabel(f"water level (m, {survey_metadata(p.summary)['vertical_crs'] or 'datum'})")
    fig.suptitle("Capacity: volume and water-surface area against water level", fontsize=11)
    img = p.figure(fig, "capacity", "capacity curve: volume and area against water level")
    facts = [("water level (the survey's)", f"{num(level, 3)} m"),
             ("deepest node", f"{num(curve['deepest_m'], 3)} m "
              f"({num(level - curve['deepest_m'], 2)} m below the water level)"),
             ("volume of water at the water level",
              f"{num(curve['volume_at_water_level_m3'], 0)} m&sup3;"),
             ("water-surface area at the water level",
              f"{num(curve['area_at_water_level_m2'], 0)} m&sup2;"),
             ("surveyed area", f"{num(curve['surveyed_area_m2'], 0)} m&sup2;")]
    return "\n".join([
        table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"), img,
        '<p class="caption">Over the surveyed nodes of the depth grid only: ground the survey '
        "did not reach is not filled in, so the figures are those of the surveyed area. The "
        "water level is the median height of the vessel on the water (dashed). The table, a "
        "row every 0.25 m: report/capacity.csv.</p>"])
