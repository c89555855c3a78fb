# SPDX-License-Identifier: MIT
"""Inputs of pitmap-report: summary.json, scores.json, trajectory CSV and PLY products (PLY
through the project's C++ reader), and the Products base of the Report that loads them and keeps
what is missing or unusable."""

import json
import os
import subprocess

import numpy as np

from .rasters import save_figure
from .util import PROGRAM_DIR, ReportError, log, not_produced

# pitmap's one PLY reader (common/formats/ply, C++), as a program beside pitmap-report.
PLY_LAYOUT = "pitmap-ply-layout"


class PlyError(Exception):
    pass


class ForeignProductError(PlyError):
    """A product of another run than summary.json's (its pitmap_run_id differs): not drawn."""


class Ply:
    """A binary PLY file: header facts plus one numpy structured array per element.

    The PLY is parsed and checked once, by the project's C++ reader (common/formats/ply,
    DescribeFile) through the pitmap-ply-layout program beside this report: it says where each
    element's records lie and their numpy dtype, having checked that the file holds them all
    and that every list has the same length in every record (triangles). The records are then
    memory-mapped, so multi-million-point clouds cost no copy and no parsing in Python. Errors
    (not a PLY, ASCII or big-endian, truncated, lists of varying length) raise PlyError naming
    the file; a missing pitmap-ply-layout raises ReportError.
    """

    def __init__(self, path):
        self.path = path
        fname = os.path.basename(path)
        tool = os.path.join(PROGRAM_DIR, PLY_LAYOUT)
        if not os.access(tool, os.X_OK):
            raise ReportError(f"{tool}: not found (build the pitmap-report target, which "
                              "builds it)")
        r = subprocess.run([tool, path], capture_output=True, text=True, errors="replace")
        if r.returncode != 0:
            msg = r.stderr.strip() or f"{PLY_LAYOUT} exit status {r.returncode}"
            if msg.startswith(path + ": "):
                msg = fname + msg[len(path):]
            raise PlyError(msg)
        try:
            layout = json.loads(r.stdout)
        except ValueError as e:
            raise PlyError(f"{fname}: {PLY_LAYOUT} output unreadable: {e}")
        self.comments = layout["comments"]
        o = layout["origin"]
        self._origin = None if o is None else (o["latitude_deg"], o["longitude_deg"],
                                               o["height_m"])
        self.elements = {}  # name -> structured array
        self.counts = {}    # name -> count from the header
        for e in layout["elements"]:
            dtype = np.dtype([(f["name"], f["dtype"], tuple(f["shape"])) if "shape" in f
                              else (f["name"], f["dtype"]) for f in e["fields"]])
            count = e["count"]
            if dtype.itemsize != e["record_bytes"]:  # the two sides disagree: a bug
                raise PlyError(f"{fname}: element {e['name']}: record of {e['record_bytes']} "
                               f"bytes, dtype of {dtype.itemsize}")
            self.counts[e["name"]] = count
            if count == 0 or dtype.itemsize == 0:
                self.elements[e["name"]] = np.zeros(count, dtype)
            else:
                self.elements[e["name"]] = np.memmap(path, dtype=dtype, mode="r",
                                                     offset=e["offset"], shape=(count,))

    def origin(self):
        """pitmap_origin (lat, lon, h) of the header comments, None without one."""
        return self._origin

    def run_id(self):
        """The pitmap_run_id comment's id (the survey run that wrote the file), None without."""
        for c in self.comments:
            if c.startswith("pitmap_run_id "):
                return c[len("pitmap_run_id "):].strip()
        return None


def read_trajectory(path):
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


class Products:
    """A products folder: summary.json (required), the optional products loaded on demand, and
    the names of what is missing or unusable with the reason. Every report section is a
    function of one of these (report.py); figures go to P/report/NAME.png and into the page."""

    def __init__(self, folder, scores_path):
        self.folder = folder
        self.scores_path = scores_path
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
        # The run summary.json describes (pitmap georef makes one per survey); a product that
        # names another run is left out (ForeignRun). None: a folder written before run ids.
        rid = self.summary.get("run_id")
        self.run_id = rid if isinstance(rid, str) and rid else None
        self.stages = self.summary.get("stages") or {}
        if not isinstance(self.stages, dict):
            self.stages = {}
        self.traj = {}
        self.points = {}
        # The rejected soundings of points.ply (status != 0, issue 35): "final" only; every
        # figure of self.points draws the accepted soundings alone.
        self.rejected = {}
        self.t0 = None
        self.ref_z = 0.0
        # The final products are "after SLAM" only when SLAM ran (pitmap run --no-slam).
        self.after = "after SLAM" if "slam" in self.stages else "SLAM not run"
        self.fig_dir = os.path.join(folder, "report")

    def figure(self, fig, name, alt):
        """fig saved as P/report/NAME.png and closed; its <img> (a data URI) returned."""
        os.makedirs(self.fig_dir, exist_ok=True)
        return save_figure(fig, self.fig_dir, name, alt)

    def minutes_of(self, t):
        """GPS seconds -> minutes since the first pose (or sounding)."""
        return (np.asarray(t, dtype=np.float64) - (self.t0 or 0.0)) / 60.0

    def path(self, name):
        return os.path.join(self.folder, name)

    def missing_product(self, name, why=""):
        """An optional product that is absent, or present but unusable (then its own reason,
        from self.unusable, is given)."""
        if name not in self.missing:
            self.missing.append(name)
        return not_produced(name, self.unusable.get(name, why))

    def foreign_run(self, name, product_run_id):
        """Why `name` is not drawn when it names another run than summary.json (a product left
        by an earlier survey, or a survey.pitmap copied in), else None. The line is added to
        the report's problems once."""
        if self.run_id is None or product_run_id == self.run_id:
            return None
        what = f"(id {product_run_id})" if product_run_id else "(it has no run id)"
        msg = (f"{name} is from another run {what}; not drawn (summary.json run id "
               f"{self.run_id})")
        if msg not in self.problems:
            self.problems.append(msg)
        log(msg)
        return msg

    def check_origin(self, ply, name):
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

    def load_trajectories(self):
        names = [("initial", "trajectory_initial.csv"), ("final", "trajectory.csv")]
        if not any(os.path.isfile(self.path(n)) for _, n in names):
            # No SLAM ran (georef only, or `run --no-slam`): the INS trajectory is the final one.
            names = [("final", "trajectory_ins.csv")]
        for key, name in names:
            if os.path.isfile(self.path(name)):
                try:
                    self.traj[key] = read_trajectory(self.path(name))
                    log(f"{name}: {len(self.traj[key]['t'])} poses")
                except (OSError, ValueError) as e:
                    log(f"{name}: unreadable: {e}")
                    self.unusable[name] = f"unreadable: {e}"
        ts = [tr["t"][0] for tr in self.traj.values()]
        if ts:
            self.t0 = min(ts)
        main = self.traj.get("final") or self.traj.get("initial")
        if main is not None:
            self.ref_z = float(np.median(main["z"]))

    def load_points(self):
        for key, name in (("initial", "points_initial.ply"), ("final", "points.ply")):
            if not os.path.isfile(self.path(name)):
                continue
            try:
                ply = Ply(self.path(name))
                foreign = self.foreign_run(name, ply.run_id())
                if foreign:
                    self.unusable[name] = foreign
                    continue
                v = ply.elements.get("vertex")
                if v is None or not all(c in v.dtype.names for c in ("x", "y", "z")):
                    raise PlyError(f"{name}: no vertex x, y, z")
                if len(v) == 0:
                    self.unusable[name] = "no points"
                    continue
                if "status" in v.dtype.names:
                    # Accepted first, then rejected (processor/io/products.hpp); a mask keeps
                    # any order. Copies only when there are rejected soundings.
                    status = np.asarray(v["status"])
                    bad = status != 0
                    if bad.any():
                        self.rejected[key] = v[bad]
                        v = v[~bad]
                    if len(v) == 0:
                        self.unusable[name] = "no accepted points"
                        continue
                self.points[key] = v
                self.check_origin(ply, name)
                log(f"{name}: {len(v)} accepted points, "
                    f"{len(self.rejected.get(key, ()))} rejected")
            except (OSError, PlyError) as e:
                log(f"{name}: unreadable: {e}")
                self.unusable[name] = f"unreadable: {e}"
        if self.t0 is None:
            for v in self.points.values():
                if "gps_time_s" in v.dtype.names and len(v):
                    self.t0 = float(np.min(v["gps_time_s"][::max(1, len(v) // 10000)]))

    def load_mesh(self, name):
        if not os.path.isfile(self.path(name)):
            return None
        ply = Ply(self.path(name))
        if self.run_id is not None and ply.run_id() != self.run_id:
            what = f"(id {ply.run_id()})" if ply.run_id() else "(it has no run id)"
            raise ForeignProductError(f"{name} is from another run {what}; not drawn "
                                      f"(summary.json run id {self.run_id})")
        v = ply.elements.get("vertex")
        f = ply.elements.get("face")
        if v is None or f is None:
            raise PlyError(f"{name}: no vertex or face element")
        self.check_origin(ply, name)
        lists = [n for n in f.dtype.names if not n.endswith("__count")]
        if not lists or f.dtype[lists[0]].shape != (3,) and len(f):
            raise PlyError(f"{name}: faces are not triangles")
        xyz = np.stack([np.asarray(v[c], dtype=np.float64) for c in ("x", "y", "z")], axis=1)
        tri = np.array(f[lists[0]], dtype=np.int32).reshape(-1, 3) if len(f) else \
            np.zeros((0, 3), np.int32)
        if len(tri) and (tri.min() < 0 or tri.max() >= len(xyz)):
            raise PlyError(f"{name}: face index out of range")
        return xyz, tri

    def load_scores(self):
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

    def score_text(self, before, after, label):
        """'label: 1.23 -> 0.45 m' from two scores when both exist, else ''."""
        b, a = self.scores.get(before), self.scores.get(after)
        if isinstance(b, (int, float)) and isinstance(a, (int, float)):
            return f"{label} {b:.3f} &rarr; {a:.3f} m (scores.json)"
        return ""

