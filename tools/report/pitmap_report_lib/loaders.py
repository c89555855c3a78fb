# SPDX-License-Identifier: MIT
"""Inputs of pitmap-report: summary.json, scores.json, trajectory CSV and PLY products, and the
Products base of the Report that loads them and keeps what is missing or unusable."""

import json
import os

import numpy as np

from .util import Log, NotProduced, ReportError

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}



class PlyError(Exception):
    pass


class Ply:
    """A binary PLY file: header facts plus one numpy structured array per element.

    pitmap writes PLY in one place (common/formats/ply, C++); this reader stays in Python on
    purpose: PLY is a public format, not one pitmap defines, and reading it here lets the
    report memory-map multi-million-point clouds with numpy and run on a products folder with
    Debian's python3 alone (no pitmap binary, no intermediate copy). pitmap's own convention
    in it, the pitmap_origin comment, is checked against summary.json (CheckOrigin).

    Elements of fixed-size records are memory-mapped; a list property (faces) is read as a
    fixed-length array when every record has the same list length (triangles), which is
    checked. ASCII PLY and variable-length lists raise PlyError.
    """

    def __init__(self, path):
        self.path = path
        fname = os.path.basename(path)
        self.comments = []
        self.elements = {}  # name -> structured array
        self.counts = {}    # name -> count from the header
        with open(path, "rb") as f:
            head = f.read(1 << 16)
        end = head.find(b"end_header")
        if not head.startswith(b"ply") or end < 0:
            raise PlyError(f"{fname}: not a PLY file (no 'ply' magic or no end_header)")
        nl = head.find(b"\n", end)
        if nl < 0:
            raise PlyError(f"{fname}: header not terminated")
        data_offset = nl + 1
        fmt = None
        elements = []  # (name, count, [prop]) with prop = (name, type) or (name, count_t, item_t)
        for raw in head[:end].decode("ascii", "replace").splitlines()[1:]:
            words = raw.split()
            if not words:
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "comment":
                self.comments.append(raw.strip()[len("comment"):].strip())
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property":
                if not elements:
                    raise PlyError(f"{fname}: property before any element")
                if words[1] == "list":
                    elements[-1][2].append((words[4], words[2], words[3]))
                else:
                    elements[-1][2].append((words[2], words[1]))
        if fmt == "binary_little_endian":
            endian = "<"
        elif fmt == "binary_big_endian":
            endian = ">"
        else:
            raise PlyError(f"{fname}: format {fmt} not supported (binary PLY only)")

        def T(type_name):
            if type_name not in PLY_TYPES:
                raise PlyError(f"{fname}: unknown property type {type_name}")
            return endian + PLY_TYPES[type_name]

        file_size = os.path.getsize(path)
        offset = data_offset
        for name, count, props in elements:
            self.counts[name] = count
            fields = []
            lists = [p for p in props if len(p) == 3]
            list_lengths = {}
            if lists and count > 0:
                # The first record fixes every list's length; all records are checked below.
                with open(path, "rb") as f:
                    f.seek(offset)
                    first = f.read(4096)
                pos = 0
                for p in props:
                    if len(p) == 2:
                        pos += np.dtype(T(p[1])).itemsize
                    else:
                        ct = np.dtype(T(p[1]))
                        n = int(np.frombuffer(first, ct, count=1, offset=pos)[0])
                        list_lengths[p[0]] = n
                        pos += ct.itemsize + n * np.dtype(T(p[2])).itemsize
            for p in props:
                if len(p) == 2:
                    fields.append((p[0], T(p[1])))
                else:
                    fields.append((p[0] + "__count", T(p[1])))
                    fields.append((p[0], T(p[2]), (list_lengths.get(p[0], 0),)))
            dtype = np.dtype(fields)
            size = dtype.itemsize * count
            if offset + size > file_size:
                raise PlyError(f"{fname}: truncated (element {name} needs {offset + size} bytes, "
                               f"file has {file_size})")
            if count == 0:
                arr = np.zeros(0, dtype)
            else:
                arr = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=(count,))
            for p in lists:
                if count > 0 and np.any(arr[p[0] + "__count"] != list_lengths[p[0]]):
                    raise PlyError(f"{fname}: element {name}: lists of varying length "
                                   "are not supported")
            self.elements[name] = arr
            offset += size

    def origin(self):
        for c in self.comments:
            w = c.split()
            if len(w) == 4 and w[0] == "pitmap_origin":
                return tuple(float(v) for v in w[1:])
        return None


def ReadTrajectory(path):
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
    the names of what is missing or unusable with the reason."""

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
        self.stages = self.summary.get("stages") or {}
        if not isinstance(self.stages, dict):
            self.stages = {}
        self.traj = {}
        self.points = {}
        self.t0 = None
        self.ref_z = 0.0
        # The final products are "after SLAM" only when SLAM ran (pitmap run --no-slam).
        self.after = "after SLAM" if "slam" in self.stages else "SLAM not run"

    def P(self, name):
        return os.path.join(self.folder, name)

    def Missing(self, name, why=""):
        """An optional product that is absent, or present but unusable (then its own reason,
        from self.unusable, is given)."""
        if name not in self.missing:
            self.missing.append(name)
        return NotProduced(name, self.unusable.get(name, why))

    def CheckOrigin(self, ply, name):
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

    def LoadTrajectories(self):
        names = [("initial", "trajectory_initial.csv"), ("final", "trajectory.csv")]
        if not any(os.path.isfile(self.P(n)) for _, n in names):
            # No SLAM ran (georef only, or `run --no-slam`): the INS trajectory is the final one.
            names = [("final", "trajectory_ins.csv")]
        for key, name in names:
            if os.path.isfile(self.P(name)):
                try:
                    self.traj[key] = ReadTrajectory(self.P(name))
                    Log(f"{name}: {len(self.traj[key]['t'])} poses")
                except (OSError, ValueError) as e:
                    Log(f"{name}: unreadable: {e}")
                    self.unusable[name] = f"unreadable: {e}"
        ts = [tr["t"][0] for tr in self.traj.values()]
        if ts:
            self.t0 = min(ts)
        main = self.traj.get("final") or self.traj.get("initial")
        if main is not None:
            self.ref_z = float(np.median(main["z"]))

    def LoadPoints(self):
        for key, name in (("initial", "points_initial.ply"), ("final", "points.ply")):
            if not os.path.isfile(self.P(name)):
                continue
            try:
                ply = Ply(self.P(name))
                v = ply.elements.get("vertex")
                if v is None or not all(c in v.dtype.names for c in ("x", "y", "z")):
                    raise PlyError(f"{name}: no vertex x, y, z")
                if len(v) == 0:
                    self.unusable[name] = "no points"
                    continue
                self.points[key] = v
                self.CheckOrigin(ply, name)
                Log(f"{name}: {len(v)} points")
            except (OSError, PlyError) as e:
                Log(f"{name}: unreadable: {e}")
                self.unusable[name] = f"unreadable: {e}"
        if self.t0 is None:
            for v in self.points.values():
                if "gps_time_s" in v.dtype.names and len(v):
                    self.t0 = float(np.min(v["gps_time_s"][::max(1, len(v) // 10000)]))

    def LoadMesh(self, name):
        if not os.path.isfile(self.P(name)):
            return None
        ply = Ply(self.P(name))
        v = ply.elements.get("vertex")
        f = ply.elements.get("face")
        if v is None or f is None:
            raise PlyError(f"{name}: no vertex or face element")
        self.CheckOrigin(ply, name)
        lists = [n for n in f.dtype.names if not n.endswith("__count")]
        if not lists or f.dtype[lists[0]].shape != (3,) and len(f):
            raise PlyError(f"{name}: faces are not triangles")
        xyz = np.stack([np.asarray(v[c], dtype=np.float64) for c in ("x", "y", "z")], axis=1)
        tri = np.array(f[lists[0]], dtype=np.int32).reshape(-1, 3) if len(f) else \
            np.zeros((0, 3), np.int32)
        if len(tri) and (tri.min() < 0 or tri.max() >= len(xyz)):
            raise PlyError(f"{name}: face index out of range")
        return xyz, tri

    def LoadScores(self):
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

    def ScoreText(self, before, after, label):
        """'label: 1.23 -> 0.45 m' from two scores when both exist, else ''."""
        b, a = self.scores.get(before), self.scores.get(after)
        if isinstance(b, (int, float)) and isinstance(a, (int, float)):
            return f"{label} {b:.3f} &rarr; {a:.3f} m (scores.json)"
        return ""

