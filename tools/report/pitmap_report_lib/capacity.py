# SPDX-License-Identifier: MIT
"""The capacity curve of a pit (issue 37): for each water level L, the area of the water
surface and the volume of water over the surveyed nodes of dem.tif,
  area(L) = cell^2 #{nodes: z < L},   volume(L) = cell^2 sum over nodes of max(0, L - z),
the same figures as `pitmap compare` writes (processor/compare/capacity.hpp): the single-survey
report draws it from the products folder, the change report reads compare's CSVs. Pure numpy."""

import csv
import os

import numpy as np

from .loaders import read_trajectory

CSV_COLUMNS = ("level_m", "depth_below_water_level_m", "area_m2", "volume_m3")


def capacity_curve(z, cell_m, water_level_m, step_m=0.25):
    """{water_level_m, deepest_m, surveyed_area_m2, area_at_water_level_m2,
    volume_at_water_level_m3, rows: [(level_m, area_m2, volume_m3)]} over the finite heights z
    of nodes of cell_m x cell_m: a row every step_m from the deepest node (rounded down to a
    step) up to below the water level, and one at the water level. No heights: no rows."""
    v = np.sort(np.asarray(z, dtype=np.float64)[np.isfinite(z)].ravel())
    cell = cell_m * cell_m
    out = {"water_level_m": float(water_level_m), "deepest_m": 0.0,
           "surveyed_area_m2": len(v) * cell, "area_at_water_level_m2": 0.0,
           "volume_at_water_level_m3": 0.0, "rows": []}
    if len(v) == 0 or not step_m > 0:
        return out
    out["deepest_m"] = float(v[0])
    prefix = np.concatenate([[0.0], np.cumsum(v)])

    def at(level):
        k = int(np.searchsorted(v, level, side="left"))
        return (float(level), k * cell, (k * level - prefix[k]) * cell)

    level = np.floor(v[0] / step_m) * step_m
    while level < water_level_m:
        out["rows"].append(at(level))
        level += step_m
    top = at(water_level_m)
    out["rows"].append(top)
    out["area_at_water_level_m2"], out["volume_at_water_level_m3"] = top[1], top[2]
    return out


def water_level_m(p):
    """The survey's water level in dem.tif's vertical datum, as `pitmap compare` finds it: the
    vehicle rides on the water, so the median height of its trajectory (trajectory.csv, else
    trajectory_ins.csv; the upper median) minus the INS's height above the water line, less the
    datum's ellipsoidal height. None when the products do not say."""
    name = "trajectory.csv" if os.path.isfile(p.path("trajectory.csv")) else "trajectory_ins.csv"
    try:
        z = np.sort(read_trajectory(p.path(name))["z"])
    except (OSError, ValueError):
        return None
    s = p.summary
    origin = s.get("world_origin") if isinstance(s.get("world_origin"), dict) else {}
    h0 = origin.get("height_m", 0.0)
    vehicle = s.get("vehicle") if isinstance(s.get("vehicle"), dict) else {}
    above = vehicle.get("ins_height_above_waterline_m")
    vd = s.get("vertical_datum") if isinstance(s.get("vertical_datum"), dict) else {}
    datum_h = 0.0
    if vd.get("datum", "ellipsoid") != "ellipsoid":
        d = vd.get("mean_datum_height_m")
        datum_h = float(d) if isinstance(d, (int, float)) else 0.0
    if not isinstance(h0, (int, float)):
        return None
    above = float(above) if isinstance(above, (int, float)) else 0.0
    return float(h0) + float(z[len(z) // 2]) - above - datum_h


def write_csv(path, curve):
    """The curve as `pitmap compare`'s capacity_a.csv."""
    with open(path, "w", newline="") as f:
        f.write(",".join(CSV_COLUMNS) + "\n")
        for level, area, volume in curve["rows"]:
            f.write(f"{level:.4f},{curve['water_level_m'] - level:.4f},{area:.3f},{volume:.3f}\n")


def read_csv(path):
    """A capacity CSV (compare's capacity_a.csv or capacity_b.csv) as float arrays by column.
    Raises ValueError naming what is wrong."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or [c.strip() for c in rows[0]][:4] != list(CSV_COLUMNS):
        raise ValueError(f"{os.path.basename(path)}: not a capacity table (header "
                         f"{','.join(CSV_COLUMNS)})")
    try:
        data = np.array([[float(c) for c in r[:4]] for r in rows[1:] if r], dtype=np.float64)
    except ValueError as e:
        raise ValueError(f"{os.path.basename(path)}: {e}")
    if data.ndim != 2 or len(data) == 0:
        raise ValueError(f"{os.path.basename(path)}: no rows")
    return {c: data[:, i] for i, c in enumerate(CSV_COLUMNS)}


def draw_curves(ax_volume, ax_area, curves):
    """Volume and water-surface area against water level of each (label, colour, columns,
    water level) in curves, each survey's water level dashed."""
    for label, colour, c, level in curves:
        ax_volume.plot(c["volume_m3"], c["level_m"], "-", color=colour, lw=1.8, label=label)
        ax_area.plot(c["area_m2"], c["level_m"], "-", color=colour, lw=1.8, label=label)
        for a in (ax_volume, ax_area):
            a.axhline(level, color=colour, ls="--", lw=1.0)
    ax_volume.set_xlabel("volume of water (m\u00b3)")
    ax_area.set_xlabel("water-surface area (m\u00b2)")
    for a in (ax_volume, ax_area):
        a.grid(alpha=0.3)
        a.set_xlim(left=0)
    ax_volume.legend(fontsize=8, loc="lower right")
