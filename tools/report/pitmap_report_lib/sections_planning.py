# SPDX-License-Identifier: MIT
"""The report's mine-planning section: the slope map of the surface and where a bottom crawler
can stand and drive from its launch point (terrain.tif and crawler.tif of the grid stage,
processor/hydro/terrain.hpp), with the areas of each class."""

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from .maps import MapError, add_furniture, raster_extent, read_geotiff  # noqa: E402
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
