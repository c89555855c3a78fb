# SPDX-License-Identifier: MIT
"""Inputs of the change report (pitmap-report --compare C): the folder `pitmap compare A B
--out C` wrote (compare.json, dod.tif, change_regions.geojson, capacity_a.csv, capacity_b.csv,
change_points.ply) and the two products folders it compared. compare.json is read defensively
(the comparison grows new fields): what the report shows is checked once, here, and a damaged
file is refused with every problem named; fields it does not know are left alone."""

import json
import math
import os

import numpy as np

from .loaders import Ply, PlyError, Products
from .maps import MapError, read_geotiff
from .rasters import save_figure
from .util import ReportError, log, not_produced, strip_paths

COMPARE_JSON = "compare.json"


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check(j, path, kind, problems):
    """The value at `path` (keys and list indices) of j when it is of `kind` ("number",
    "object", "list", "int", "text"), else None with the problem added."""
    v = j
    where = ""
    for k in path:
        where += f"[{k}]" if isinstance(k, int) else (f".{k}" if where else k)
        present = (k < len(v)) if isinstance(k, int) and isinstance(v, list) else (
            isinstance(v, dict) and k in v)
        v = v[k] if present else None
        if v is None:
            # nlohmann::json writes a NaN as null: a figure that was not a number.
            problems.append(f"{where} is {'null' if present else 'missing'}")
            return None
    ok = {"number": _is_number(v), "object": isinstance(v, dict), "list": isinstance(v, list),
          "int": isinstance(v, int) and not isinstance(v, bool), "text": isinstance(v, str)}[kind]
    if not ok:
        shown = json.dumps(v)[:40]
        problems.append(f"{where} is not {'an' if kind in ('object', 'int') else 'a'} "
                        f"{'integer' if kind == 'int' else kind} ({shown})")
        return None
    return v


def check_compare_json(j):
    """Every problem of a compare.json for the change report (empty: usable): the figures the
    report shows must be there and be finite numbers."""
    if not isinstance(j, dict):
        return ["not a JSON object"]
    p = []
    for side in ("cut", "fill"):
        for k in ("volume_m3", "u95_m3", "area_m2"):
            _check(j, ["change", side, k], "number", p)
        _check(j, ["change", side, "regions"], "int", p)
    regions = _check(j, ["change", "regions"], "list", p) or []
    ids = set()
    for i, r in enumerate(regions):
        if _check(j, ["change", "regions", i], "object", p) is None:
            continue
        rid = _check(j, ["change", "regions", i, "id"], "int", p)
        if rid is not None:
            if rid in ids or rid <= 0:
                p.append(f"change.regions[{i}].id {rid} is not a new positive id")
            ids.add(rid)
        kind = _check(j, ["change", "regions", i, "kind"], "text", p)
        if kind is not None and kind not in ("cut", "fill"):
            p.append(f"change.regions[{i}].kind is {kind!r}, not cut or fill")
        for k in ("area_m2", "volume_m3", "u95_m3"):
            _check(j, ["change", "regions", i, k], "number", p)
    for side in ("a", "b"):
        for k in ("water_level_m", "volume_at_water_level_m3", "area_at_water_level_m2",
                  "deepest_m", "surveyed_area_m2"):
            _check(j, ["capacity", side, k], "number", p)
    t = _check(j, ["registration", "translation_m"], "list", p)
    if t is not None and (len(t) != 3 or not all(_is_number(x) for x in t)):
        p.append("registration.translation_m is not three numbers")
    for k in ("roll", "pitch", "yaw"):
        _check(j, ["registration", "rotation_deg", k], "number", p)
    pivot = _check(j, ["registration", "pivot_m"], "list", p)
    if pivot is not None and (len(pivot) != 3 or not all(_is_number(x) for x in pivot)):
        p.append("registration.pivot_m is not three numbers")
    for k in ("rms_vertical_before_m", "rms_vertical_after_m"):
        _check(j, ["registration", k], "number", p)
    if "quality_gates" in j and not isinstance(j["quality_gates"], list):
        p.append("quality_gates is not a list")
    return list(dict.fromkeys(p))  # a missing object is named once, not once per field


def rotation_matrix(w):
    """R = exp([w]x) of a rotation vector w (rad; about east, north, up), as
    processor/compare/registration.hpp defines the correction."""
    w = np.asarray(w, dtype=np.float64)
    a = float(np.linalg.norm(w))
    if a < 1e-15:
        return np.eye(3)
    k = w / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


class CompareFolder:
    """A compare folder C with its two products folders A (earlier) and B (later) as
    loaders.Products, and what is missing or unusable. Figures go to C/report/NAME.png and
    into the page, as the survey report's. Raises ReportError when compare.json is missing or
    damaged, when A or B cannot be found, or when they are not the runs compare.json compared."""

    def __init__(self, folder, a_dir=None, b_dir=None):
        self.folder = folder
        self.problems = []
        self.missing = []
        self.unusable = {}
        self.fig_dir = os.path.join(folder, "report")
        path = os.path.join(folder, COMPARE_JSON)
        if not os.path.isfile(path):
            raise ReportError(f"{folder}: no {COMPARE_JSON} (not a folder of pitmap compare?)")
        try:
            with open(path) as f:
                self.compare = json.load(f)
        except (OSError, ValueError) as e:
            raise ReportError(f"{path}: cannot read: {e}")
        problems = check_compare_json(self.compare)
        if problems:
            raise ReportError(f"{path}: damaged, not reported on: " + "; ".join(problems))
        self.epochs = {}
        for side, given in (("a", a_dir), ("b", b_dir)):
            inp = self.compare.get("inputs") if isinstance(self.compare.get("inputs"),
                                                           dict) else {}
            rec = inp.get(side) if isinstance(inp.get(side), dict) else {}
            d = given or rec.get("folder")
            name = side.upper()
            if not isinstance(d, str) or not d:
                raise ReportError(f"{path}: inputs.{side}.folder is not set: give the products "
                                  "folders with --epochs A B")
            if not os.path.isdir(d):
                raise ReportError(f"survey {name}: {d}: not found (compare.json's inputs.{side}"
                                  ".folder; give the products folders with --epochs A B)")
            p = Products(os.path.abspath(d), os.path.join(d, "scores.json"))
            want = rec.get("run_id")
            if isinstance(want, str) and want and p.run_id and p.run_id != want:
                raise ReportError(f"survey {name}: {d} is run {p.run_id}, but {COMPARE_JSON} "
                                  f"compared run {want} (the folder was processed again "
                                  "since: run pitmap compare again, or give --epochs with the "
                                  "folders it compared)")
            p.fig_dir = self.fig_dir
            self.epochs[side] = p
        self.a, self.b = self.epochs["a"], self.epochs["b"]
        reg = self.compare["registration"]
        rot = reg["rotation_deg"]
        self.R = rotation_matrix(np.radians([rot["roll"], rot["pitch"], rot["yaw"]]))
        self.pivot = np.asarray(reg["pivot_m"], dtype=np.float64)
        self.t = np.asarray(reg["translation_m"], dtype=np.float64)
        self._dod = None

    def path(self, name):
        return os.path.join(self.folder, name)

    def figure(self, fig, name, alt):
        os.makedirs(self.fig_dir, exist_ok=True)
        return save_figure(fig, self.fig_dir, name, alt)

    def missing_product(self, name, why=""):
        if name not in self.missing:
            self.missing.append(name)
        return not_produced(name, self.unusable.get(name, why))

    def correct(self, xyz):
        """B's points (N x 3, A's CRS) carried onto A by the co-registration:
        T(p) = R (p - pivot) + pivot + t."""
        return (np.asarray(xyz, dtype=np.float64) - self.pivot) @ self.R.T + self.pivot + self.t

    def dod(self):
        """dod.tif read once: read_geotiff's dict, or None (why in self.unusable)."""
        if self._dod is None and "dod.tif" not in self.unusable:
            if not os.path.isfile(self.path("dod.tif")):
                self.unusable["dod.tif"] = "not in the compare folder"
            else:
                try:
                    d = read_geotiff(self.path("dod.tif"))
                    need = [b for b in ("difference", "lod95", "significance", "region")
                            if b not in d["bands"]]
                    if need:
                        self.unusable["dod.tif"] = f"no band(s) {', '.join(need)}"
                    else:
                        self._dod = d
                except ImportError:
                    self.unusable["dod.tif"] = "python3-gdal is not installed"
                except (MapError, RuntimeError, OSError) as e:
                    self.unusable["dod.tif"] = f"unreadable: {strip_paths(e)}"
        return self._dod

    def soundings(self, side, box=None):
        """The accepted soundings (status 0) of survey A or B's points_utm.ply as N x 3 in A's
        CRS (B's carried by the co-registration), within box (xmin, xmax, ymin, ymax) when
        given; None when the file is absent or unusable (logged)."""
        p = self.epochs[side]
        name = "points_utm.ply"
        if not os.path.isfile(p.path(name)):
            return None
        try:
            ply = Ply(p.path(name))
        except PlyError as e:
            log(f"{side.upper()} {name}: {e}")
            return None
        if p.run_id and ply.run_id() and ply.run_id() != p.run_id:
            return None
        v = ply.elements.get("vertex")
        if v is None or not all(k in v.dtype.names for k in ("x", "y", "z")):
            return None
        x, y = np.asarray(v["x"], dtype=np.float64), np.asarray(v["y"], dtype=np.float64)
        keep = np.ones(len(x), bool)
        if "status" in v.dtype.names:
            keep &= np.asarray(v["status"]) == 0
        if box is not None:
            # B's points move by centimetres under the correction: the box is widened by 1 m.
            pad = 1.0 if side == "b" else 0.0
            keep &= ((x >= box[0] - pad) & (x <= box[1] + pad) & (y >= box[2] - pad)
                     & (y <= box[3] + pad))
        xyz = np.stack([x[keep], y[keep], np.asarray(v["z"], dtype=np.float64)[keep]], axis=1)
        return self.correct(xyz) if side == "b" else xyz
