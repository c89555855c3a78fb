# SPDX-License-Identifier: MIT
"""pitmap-report on small synthetic products folders that this test writes itself.

Usage: python3 report_test.py --report PATH_TO_pitmap-report [unittest args]

Checks: the report is written and self-contained (no http(s) link, every image a data URI,
no reference to a file, a Content-Security-Policy that allows no network), holds every section, names each missing optional product
("not produced: ...") instead of failing, refuses a folder without summary.json, and the
PLY reader and raster helpers give known values.
"""

import argparse
import base64
import importlib.machinery
import importlib.util
import json
import os
import re
import signal
import struct
import subprocess
import sys
import tempfile
import time
import unittest

import numpy as np

REPORT = None  # path of the pitmap-report script, from --report
SECTIONS = ["summary", "quality", "trajectory", "cross-sections", "depth", "hydro", "rejections",
            "mosaic", "mesh", "viewer", "boresight", "clock", "tsdf", "slam", "stages", "scores"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
GPS_T0 = 1465549218.0  # 2026-06-15 09:00:00 UTC (GPS - UTC = 18 s)


def LoadModule():
    loader = importlib.machinery.SourceFileLoader("pitmap_report", REPORT)
    spec = importlib.util.spec_from_loader("pitmap_report", loader)
    mod = importlib.util.module_from_spec(spec)
    loader.exec_module(mod)
    return mod


def Bowl(x, y):
    """A pit: 8 m deep bowl of radius 15 m with a 2 m bench."""
    r = np.hypot(x, y)
    return np.where(r < 15, -8 + 6 * (r / 15) ** 2 + 2 * (r > 9), 0.5) - 2.0


def WritePly(path, header_props, arrays, faces=None, comments=(), endian="<"):
    """Binary PLY; header_props = [(name, ply type, numpy type)], arrays by name."""
    n = len(arrays[header_props[0][0]])
    fmt = "binary_little_endian" if endian == "<" else "binary_big_endian"
    head = ["ply", f"format {fmt} 1.0"] + [f"comment {c}" for c in comments]
    head.append(f"element vertex {n}")
    head += [f"property {t} {name}" for name, t, _ in header_props]
    dtype = np.dtype([(name, endian + nt) for name, _, nt in header_props])
    rec = np.zeros(n, dtype)
    for name, _, _ in header_props:
        rec[name] = arrays[name]
    body = rec.tobytes()
    if faces is not None:
        head += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
        fd = np.dtype([("n", "u1"), ("v", endian + "i4", (3,))])
        fr = np.zeros(len(faces), fd)
        fr["n"] = 3
        fr["v"] = faces
        body += fr.tobytes()
    head.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(head) + "\n").encode("ascii") + body)


POINT_PROPS = [("x", "float", "f4"), ("y", "float", "f4"), ("z", "float", "f4"),
               ("gps_time_s", "double", "f8"), ("range_m", "float", "f4"),
               ("ping", "uint", "u4"), ("beam", "ushort", "u2")]


def RejectedSoundings(arrays):
    """Rejected soundings for points.ply: a fish school (free space, 6) 3 m above the floor in
    pings 10-14, all beams; a spike (3) 4 m below on the first beam of every 7th ping."""
    ping, beam = arrays["ping"], arrays["beam"]
    fish = (ping >= 10) & (ping <= 14)
    spike = (ping % 7 == 0) & (beam == 0) & ~fish
    out = {k: np.concatenate([v[fish], v[spike]]) for k, v in arrays.items()}
    n_fish = int(fish.sum())
    out["z"] = out["z"] + np.where(np.arange(len(out["z"])) < n_fish, 3.0, -4.0)
    out["status"] = np.where(np.arange(len(out["z"])) < n_fish, 6, 3)
    return out


def WriteMosaic(folder, grid):
    """mosaic.tif (3 bands as the grid stage writes them, UTM 29N) and its summary record."""
    from osgeo import gdal, osr
    nx, ny = 40, 30
    ds = gdal.GetDriverByName("GTiff").Create(os.path.join(folder, "mosaic.tif"), nx, ny, 3,
                                              gdal.GDT_Float32)
    ds.SetGeoTransform((603390.0, 0.5, 0, 4477710.0, 0, -0.5))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32629)
    ds.SetProjection(srs.ExportToWkt())
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny))
    level = np.where((gx // 10 + gy // 10) % 2 == 0, -14.0, -26.0) + 100
    for b, (name, v) in enumerate((("backscatter", level), ("uncorrected", level - 40 - gx * 0.3),
                                   ("count", np.full((ny, nx), 4.0))), start=1):
        band = ds.GetRasterBand(b)
        band.SetDescription(name)
        band.WriteArray(v.astype(np.float32))
    ds = None
    grid["mosaic"] = {
        "made": True, "file": "mosaic.tif", "soundings": 50000, "used": 49000,
        "no_intensity": 0, "saturated": 12, "beyond_incidence": 988, "nodes_filled": nx * ny,
        "angular": "empirical", "reference_angle_deg": 45.0, "spreading_db_per_decade": 40.0,
        "absorption_db_per_m": 0.021, "median_incidence_deg": 30.1, "corrected_p05_db": 74.0,
        "corrected_p95_db": 86.0,
        "angular_response_deg_db_count": [[k + 0.5, 6.0 - 0.2 * k, 100] for k in range(80)]}


def WriteProducts(folder, full=True, points_per_pose=21):
    """A tiny survey: two laps around a bowl; before SLAM the track drifts in height."""
    os.makedirs(folder, exist_ok=True)
    t = GPS_T0 + np.arange(0, 120, 0.2)
    ang = 2 * np.pi * (t - GPS_T0) / 60
    x, y = 12 * np.cos(ang), 8 * np.sin(ang)
    drift = 0.6 * np.sin(np.pi * (t - GPS_T0) / 120)

    def Traj(path, dz):
        with open(path, "w") as f:
            f.write("gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg\n")
            for i in range(len(t)):
                f.write(f"{t[i]:.3f},{x[i]:.4f},{y[i] + dz[i] * 0.5:.4f},{dz[i]:.4f},0,0,0\n")

    Traj(os.path.join(folder, "trajectory.csv"), np.zeros_like(t))
    # Points: a fan of beams across the track at every pose.
    beams = np.linspace(-10, 10, points_per_pose)
    px = (x[:, None] + beams[None, :] * np.cos(ang)[:, None]).ravel()
    py = (y[:, None] + beams[None, :] * np.sin(ang)[:, None]).ravel()
    pt = np.repeat(t, len(beams))
    pz = Bowl(px, py)
    arrays = {"x": px, "y": py, "z": pz, "gps_time_s": pt, "range_m": -pz,
              "ping": np.repeat(np.arange(len(t)), len(beams)),
              "beam": np.tile(np.arange(len(beams)), len(t))}
    origin = "pitmap_origin 40.4435 -7.7804 412.0"
    WritePly(os.path.join(folder, "points.ply"), POINT_PROPS, arrays, comments=[origin])
    summary = {
        "world_origin": {"latitude_deg": 40.4435, "longitude_deg": -7.7804, "height_m": 412.0},
        "utm": {"zone": 29, "northern": True, "epsg": 32629},
        "inputs": ["survey.lcmlog"],
        "time": {"gps_minus_utc_s": 18, "gps_minus_utc_source": "built-in leap-second table"},
        "mount": {"roll_deg": 0.5, "pitch_deg": 0.0, "yaw_deg": 1.0},
        "stages": {
            "ingest": {"seconds": 0.5, "peak_rss_mb": 30.0, "pings": len(t)},
            "georef": {"seconds": 0.7, "peak_rss_mb": 40.0, "points": len(px),
                       "pings_in": len(t), "pings_georeferenced": len(t)},
        },
        "total_seconds": 9.5,
    }
    if full:
        Traj(os.path.join(folder, "trajectory_initial.csv"), drift)
        pd = np.repeat(drift, len(beams))
        arrays_i = dict(arrays, y=py + 0.5 * pd, z=pz + pd)
        WritePly(os.path.join(folder, "points_initial.ply"), POINT_PROPS, arrays_i,
                 comments=[origin])
        gx, gy = np.meshgrid(np.linspace(-16, 16, 33), np.linspace(-12, 12, 25))
        vx, vy = gx.ravel(), gy.ravel()
        nx = gx.shape[1]
        faces = []
        for r in range(gx.shape[0] - 1):
            for c in range(nx - 1):
                i = r * nx + c
                faces += [(i, i + 1, i + nx + 1), (i, i + nx + 1, i + nx)]
        mesh_props = [("x", "float", "f4"), ("y", "float", "f4"), ("z", "float", "f4"),
                      ("red", "uchar", "u1"), ("green", "uchar", "u1"), ("blue", "uchar", "u1")]
        col = np.full(len(vx), 128)
        for name, noise in (("mesh.ply", 0.0), ("mesh_initial.ply", 0.2)):
            z = Bowl(vx, vy) + noise * np.sin(3 * vx) * np.cos(2 * vy)
            WritePly(os.path.join(folder, name), mesh_props,
                     {"x": vx, "y": vy, "z": z, "red": col, "green": col, "blue": col},
                     faces=np.array(faces), comments=[origin])
        mount = {"roll_deg": 0.52, "pitch_deg": -0.01, "yaw_deg": 1.02,
                 "lever_arm_sonar_m": [0.8, 0, 0.25]}
        with open(os.path.join(folder, "boresight.json"), "w") as f:
            json.dump(mount, f)
        summary["stages"]["calibrate"] = {
            "seconds": 3.0, "peak_rss_mb": 60.0, "pairs": 1234, "iterations": 7,
            "termination": "converged",
            "boresight_before": {"roll_deg": 0.0, "pitch_deg": 0.0, "yaw_deg": 0.0},
            "boresight_after": mount, "formal_sd_deg": [0.005, 0.012, 0.011],
            "residual_before_rms_m": 0.0425, "residual_after_rms_m": 0.0344,
            "segment": {"start_s": GPS_T0, "end_s": GPS_T0 + 60},
            "verify": [{"start_s": GPS_T0 + 60, "end_s": GPS_T0 + 120, "rms_before_m": 0.051,
                        "rms_after_m": 0.0377, "pairs": 999}]}
        summary["sonar_clock"] = {
            "source": "83P header: the topside PC clock (offset unknown)", "configured": False,
            "coarse": {"method": "header position", "found": True, "correction_s": -2.732,
                       "sigma_s": 0.106, "message": "header position: correction -2.732 s"},
            "latency_s": 0.3786, "latency_formal_sd_s": 0.0003, "correction_s": -2.3534,
            "sigma_s": 0.0003}
        summary["stages"]["slam"] = {
            "seconds": 4.0, "peak_rss_mb": 120.0, "termination": "converged",
            "initial_consistency_m": 0.31, "final_consistency_m": 0.048,
            "iterations": [{"stage": st, "iteration": i + 1, "num_pairs": 100,
                            "cost": 50.0 / (i + 1), "pair_rms_m": 0.3 / (i + 1),
                            "consistency_m": 0.2 / (i + 1), "best": True}
                           for st in ("rigid", "semi_rigid") for i in range(3)]}
        summary["stages"]["fuse"] = {
            "seconds": 1.0, "peak_rss_mb": 200.0, "active_voxels": 4321, "sensor_model": "beam",
            "weight_histogram": {"edges": list(range(0, 22)),
                                 "counts": [0] + [1000 // k for k in range(1, 21)]}}
        summary["stages"]["mesh"] = {"seconds": 0.2, "peak_rss_mb": 210.0,
                                     "triangles": len(faces)}
        # The grid stage: points.ply again with THU/TVU, the vertical datum and S-44, and the
        # rejected soundings after the accepted ones (issue 35): a fish school over pings 10-14
        # (free space, 6), spikes on every 7th ping's outer beam (3).
        rej = RejectedSoundings(arrays)
        both = {k: np.concatenate([arrays[k], rej[k]]) for k in arrays}
        n_acc, n_rej = len(px), len(rej["x"])
        both["thu_95_m"] = np.concatenate([np.full(n_acc, 0.05), np.full(n_rej, np.nan)])
        both["tvu_95_m"] = np.concatenate([0.04 + 0.002 * np.abs(px), np.full(n_rej, np.nan)])
        both["status"] = np.concatenate([np.zeros(n_acc), rej["status"]])
        WritePly(os.path.join(folder, "points.ply"),
                 POINT_PROPS + [("thu_95_m", "float", "f4"), ("tvu_95_m", "float", "f4"),
                                ("status", "uchar", "u1")], both, comments=[origin])
        summary["soundings"] = {
            "total": n_acc + n_rej + 40, "accepted": n_acc,
            "rejected": {"no_detection": 40, "range_gate": 0,
                         "spike": int(np.sum(rej["status"] == 3)), "refraction": 0,
                         "surface_filter": 0,
                         "free_space": int(np.sum(rej["status"] == 6)), "multipath": 0,
                         "cluster": 0, "manual": 0}}
        summary["vertical_datum"] = {
            "datum": "water_level", "vertical_crs": "pit water level (GNSS, survey median)",
            "vertical_epsg": None, "description": "depths below the pit's water level",
            "mean_datum_height_m": 411.98,
            "gnss_water_surface": {"samples": 5000, "median_m": 411.98, "min_m": 411.95,
                                   "max_m": 412.01, "raw_sd_mad_m": 0.04}}
        orders = ["exclusive", "special", "1a", "1b", "2"]
        share = {o: v for o, v in zip(orders, [0.61, 0.93, 0.999, 0.999, 1.0])}
        summary["stages"]["grid"] = {
            "seconds": 2.0, "peak_rss_mb": 90.0, "median_tvu_95_m": 0.061,
            "median_thu_95_m": 0.038, "error_model": "defaults", "resolution_m": 0.1,
            "nodes_filled": 80000,
            "s44": {"order": "1a", "strictest_order_met_95": "1a",
                    "limits": {o: {"thu_m": t, "thu_depth_fraction": k, "tvu_a_m": a,
                                   "tvu_b": b, "feature_m": f, "coverage_percent": c}
                               for o, t, k, a, b, f, c in zip(
                                   orders, [0.5, 2, 5, 5, 20], [0, 0, 0.05, 0.05, 0.1],
                                   [0.15, 0.25, 0.5, 0.5, 1.0],
                                   [0.0075, 0.0075, 0.013, 0.013, 0.023], [0.5, 1, 2, 0, 0],
                                   [200, 100, 100, 5, 5])},
                    "soundings": len(px), "nodes": 80000,
                    "soundings_within_tvu": share, "soundings_within_thu": share,
                    "soundings_within_both": share, "nodes_within_tvu": share,
                    "nodes_within_thu": share, "coverage_share": 0.987,
                    "nodes_in_gaps": 900, "gaps": 12, "feature_size_m": 2.0,
                    "holiday_count": 1,
                    "holidays": [{"x_m": 603410.2, "y_m": 4477697.3, "world_m": [-3.0, 1.0],
                                  "bbox_world_m": [[-4, 0], [-2, 0], [-2, 2], [-4, 2]],
                                  "area_m2": 8.73, "largest_square_m": 2.3, "nodes": 873}],
                    "crossline": {"compared": 20062, "mean_m": -0.0169, "sd_m": 0.05,
                                  "rms_m": 0.053, "within_tvu": 1.0,
                                  "by_angle": [{"angle_lo_deg": 10 * i, "angle_hi_deg": 10 * i + 10,
                                                "count": 1000, "mean_m": 0.01 * i, "sd_m": 0.02,
                                                "rms_m": 0.03, "within_tvu": 0.99}
                                               for i in range(6)]}}}
        WriteMosaic(folder, summary["stages"]["grid"])
        summary["stage_order"] = ["ingest", "georef", "calibrate", "slam", "grid", "fuse", "mesh"]
        with open(os.path.join(folder, "scores.json"), "w") as f:
            json.dump({"trajectory_ate_rmse_m": 0.0306, "trajectory_ate_rmse_before_m": 1.3468,
                       "points_rms_m": 0.0391, "boresight_error_deg": 0.0316}, f)
    with open(os.path.join(folder, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)


def Run(*args):
    return subprocess.run([REPORT, *args], capture_output=True, text=True, timeout=300)


def Sections(page):
    """section id -> its HTML."""
    return dict(re.findall(r'<section id="([^"]+)">(.*?)</section>', page, flags=re.S))


class ReportTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pitmap-report-test-")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def AssertSelfContained(self, page, folder):
        self.assertNotRegex(page, r"(?i)https?:")
        srcs = re.findall(r'src="([^"]*)"', page)
        self.assertTrue(srcs, "no image at all")
        for s in srcs:
            self.assertTrue(s.startswith("data:image/png;base64,"), s[:60])
            self.assertEqual(base64.b64decode(s.split(",", 1)[1])[:8], PNG_MAGIC)
        for h in re.findall(r'href="([^"]*)"', page):
            self.assertTrue(h.startswith("#"), h)
        self.assertNotIn("<link", page)
        # Its policy, first in <head>: no network, nothing beyond its own inline code.
        m = re.search(r'<head>\s*<meta charset="utf-8">\s*<meta http-equiv="Content-Security-'
                      r'Policy" content="([^"]*)">', page)
        self.assertTrue(m, "no Content-Security-Policy <meta> at the top of <head>")
        csp = m.group(1)
        self.assertIn("default-src 'none'", csp)
        self.assertNotIn("'self'", csp)
        self.assertNotIn("unsafe-eval", csp)
        self.assertNotIn("url(", page)

    def test_full_folder(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        r = Run(p, "--title", "Test pit <survey>")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("section trajectory", r.stderr)  # progress lines on stderr
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            page = f.read()
        self.AssertSelfContained(page, p)
        self.assertIn("<title>Test pit &lt;survey&gt;</title>", page)
        sec = Sections(page)
        self.assertEqual(list(sec), SECTIONS)
        self.assertNotIn("not produced", page)
        self.assertNotIn("could not draw", page)
        self.assertNotIn('class="problem"', page)
        for s in ("trajectory", "cross-sections", "depth", "hydro", "mosaic", "mesh", "tsdf",
                  "slam", "stages"):
            self.assertIn("data:image/png", sec[s], s)
        self.assertIn("40.0 log10(R) + 2 &times; 0.0210 dB/m", sec["mosaic"])
        self.assertIn("empirical, referenced to 45 deg", sec["mosaic"])
        self.assertIn("2026-06-15 09:00:00", sec["summary"])
        # The S-44 section: datum, the orders' table, the holiday, the crossline table.
        self.assertIn("pit water level (GNSS, survey median)", sec["hydro"])
        self.assertIn("IHO S-44 Edition 6.1: order 1a", sec["hydro"])
        self.assertIn("<td><b>1a</b></td><td>5 + 5 % d</td>", sec["hydro"])
        self.assertIn("99.9", sec["hydro"])
        self.assertIn("<td>603410.20</td><td>4477697.30</td>", sec["hydro"])
        self.assertIn("100.0 % within the order 1a TVU limit", sec["hydro"])
        # Rejected soundings: the table by reason, the map, the worst ping runs (the fish
        # school, pings 10-14, first; the spikes one ping each).
        self.assertIn("<td>free_space</td>", sec["rejections"])
        self.assertIn("<td>no_detection</td><td>40</td>", sec["rejections"])
        self.assertNotIn("<td>multipath</td>", sec["rejections"])  # none: not listed
        self.assertIn("data:image/png", sec["rejections"])
        runs = re.findall(r"<td>(\d+)&ndash;(\d+)</td>", sec["rejections"])
        self.assertEqual(runs[0], ("10", "14"))
        self.assertIn("09:0", sec["rejections"])  # a UTC start time
        self.assertIn("free_space", sec["rejections"].split("10&ndash;14")[1].split("</tr>")[0])
        self.assertIn("0.5200", sec["boresight"])      # roll after
        self.assertIn("0.0377", sec["boresight"])      # verification segment RMS after
        self.assertIn("No quality gate tripped", sec["quality"])
        self.assertIn("header position: correction -2.732 s", sec["clock"])
        self.assertIn("378.60 ms", sec["clock"])       # latency from the soundings
        self.assertIn("-2.3534 s", sec["clock"])       # total correction
        self.assertIn("1.3468", sec["scores"])
        self.assertIn("trajectory error before SLAM", sec["scores"])
        self.assertIn("1.347 &rarr; 0.031 m", sec["summary"])  # ATE before -> after
        self.assertIn("1.347 &rarr; 0.031 m", sec["trajectory"])
        # Stage table in stage_order, then the total.
        order = [m for m in re.findall(r"<td><b>([a-z]+)</b></td>", sec["stages"])]
        self.assertEqual(order, ["ingest", "georef", "calibrate", "slam", "grid", "fuse", "mesh",
                                 "total"])
        pngs = sorted(os.listdir(os.path.join(p, "report")))
        for name in ("trajectory.png", "cross_sections.png", "depth_top_view.png",
                     "mesh_renders.png", "tsdf_weights.png", "slam_iterations.png",
                     "stages.png", "s44_compliance.png", "s44_crossline.png", "mosaic.png",
                     "rejections_map.png"):
            self.assertIn(name, pngs)
            with open(os.path.join(p, "report", name), "rb") as f:
                self.assertEqual(f.read(8), PNG_MAGIC)

    def test_tripped_quality_gates_lead_the_report(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        summary["quality_gates"] = [
            {"stage": "calibrate", "gate": "calibration_residual",
             "message": "residual RMS 0.1229 m after calibration is 2.1x what <noise> leaves"},
            {"stage": "slam", "gate": "slam_beyond_ins_sigma", "message": "SLAM moved 282 pings"}]
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            sec = Sections(f.read())
        self.assertIn("2 quality gate(s) tripped", sec["quality"])
        self.assertIn("calibration_residual", sec["quality"])
        self.assertIn("what &lt;noise&gt; leaves", sec["quality"])  # escaped
        self.assertIn("slam_beyond_ins_sigma", sec["quality"])

    def test_missing_optional_products_are_named(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=False)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            page = f.read()
        self.AssertSelfContained(page, p)
        sec = Sections(page)
        self.assertEqual(list(sec), SECTIONS)
        self.assertNotIn("could not draw", page)
        expect = {"trajectory": "trajectory_initial.csv", "cross-sections": "points_initial.ply",
                  "mesh": "mesh.ply", "boresight": "boresight.json", "tsdf": "TSDF",
                  "slam": "SLAM", "scores": "scores.json", "hydro": "grid stage",
                  "mosaic": "mosaic.tif", "rejections": "soundings"}
        for s, name in expect.items():
            self.assertRegex(sec[s], r"not produced: [^<]*" + re.escape(name), s)
        self.assertIn("mesh_initial.ply", sec["mesh"])
        # Without a slam stage nothing claims to be "after SLAM".
        self.assertIn("Points (SLAM not run)", sec["summary"])
        self.assertNotIn("after SLAM", sec["summary"])
        # What exists is still drawn.
        for s in ("trajectory", "cross-sections", "depth", "stages"):
            self.assertIn("data:image/png", sec[s], s)

    def test_broken_products_are_named_not_fatal(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        with open(os.path.join(p, "mesh.ply"), "r+b") as f:
            f.truncate(os.path.getsize(os.path.join(p, "mesh.ply")) // 2)
        with open(os.path.join(p, "scores.json"), "w") as f:
            f.write("{not json")
        with open(os.path.join(p, "mesh_initial.ply"), "r+b") as f:
            data = f.read()
            f.seek(0)
            f.write(data.replace(b"pitmap_origin 40.4435 ", b"pitmap_origin 40.4436 ", 1))
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            page = f.read()
        sec = Sections(page)
        self.assertRegex(page, r'class="problem">mesh_initial\.ply: origin 40\.4436000 '
                               r"[^<]*differs from summary\.json world_origin 40\.4435000")
        self.assertRegex(sec["mesh"], r"not produced: mesh\.ply \([^)]*truncated")
        self.assertIn("data:image/png", sec["mesh"])  # the mesh before SLAM is still drawn
        self.assertRegex(sec["scores"], r"not produced: scores\.json \(unreadable")

    def test_sections_drawn_in_parallel_give_the_same_page(self):
        # Problems and missing products from sections drawn by other processes are merged in
        # page order: a folder with both gives the page of the sequential run.
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        with open(os.path.join(p, "mesh.ply"), "r+b") as f:
            f.truncate(os.path.getsize(os.path.join(p, "mesh.ply")) // 2)
        os.remove(os.path.join(p, "trajectory_initial.csv"))
        os.remove(os.path.join(p, "boresight.json"))
        pages = {}
        for jobs in ("1", "3"):
            r = Run(p, "--jobs", jobs)
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
                pages[jobs] = re.sub(r"Report written \(UTC\)</b></td><td>[^<]*", "", f.read())
        self.assertIn('class="problem">mesh.ply', pages["1"])
        self.assertRegex(pages["1"], r'class="missing">not produced: [^<]*trajectory_initial')
        self.assertEqual(pages["1"], pages["3"])
        self.assertNotEqual(Run(p, "--jobs", "0").returncode, 0)

    def test_unusable_points_and_trajectory_are_named_with_the_reason(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        WritePly(os.path.join(p, "points.ply"), POINT_PROPS,
                 {name: np.zeros(0) for name, _, _ in POINT_PROPS})
        with open(os.path.join(p, "trajectory_initial.csv"), "w") as f:
            f.write("time,east,north\n1,2,3\n")
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            page = f.read()
        sec = Sections(page)
        self.assertNotIn("could not draw", page)
        self.assertRegex(sec["depth"], r"not produced: points\.ply \(no points\)")
        self.assertRegex(sec["cross-sections"], r"not produced: points\.ply \(no points\)")
        self.assertRegex(sec["trajectory"],
                         r"not produced: trajectory_initial\.csv \(unreadable: [^<]*gps_time_s")
        # The before-SLAM cloud is still cut.
        self.assertIn("data:image/png", sec["cross-sections"])

    def test_products_of_another_run_are_left_out_with_a_line(self):
        # Issue 34: summary.json names its run; points.ply and mesh.ply of another run (a
        # re-run killed half-way, a survey.pitmap copied in) are not drawn, and the page says so.
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        run, other = "a" * 32, "b" * 32
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        summary["run_id"] = run
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        pts = LoadModule().Ply(os.path.join(p, "points.ply")).elements["vertex"]
        arrays = {name: np.array(pts[name]) for name, _, _ in POINT_PROPS}
        origin = "pitmap_origin 40.4435 -7.7804 412.0"
        WritePly(os.path.join(p, "points.ply"), POINT_PROPS, arrays,
                 comments=[origin, "pitmap_run_id " + other])
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            page = f.read()
        sec = Sections(page)
        self.assertIn(f"points.ply is from another run (id {other}); not drawn", page)
        self.assertIn(f"mesh.ply is from another run (it has no run id); not drawn", page)
        self.assertRegex(sec["depth"], r"not produced: points\.ply \(points\.ply is from another")
        self.assertNotIn("data:image/png", sec["depth"])
        # The same points with this run's id are drawn.
        WritePly(os.path.join(p, "points.ply"), POINT_PROPS, arrays,
                 comments=[origin, "pitmap_run_id " + run])
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            page = f.read()
        self.assertNotIn("points.ply is from another run", page)
        self.assertIn("data:image/png", Sections(page)["depth"])

    def test_report_and_its_workers_end_when_their_parent_is_killed(self):
        # Issue 34: `pitmap run` killed with -9 during the report left two section workers
        # running for hours. Here a parent starts pitmap-report with two workers and is killed
        # while they draw; within a few seconds neither the report nor a worker is left.
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True, points_per_pose=400)
        parent = subprocess.Popen(
            [sys.executable, "-c",
             "import subprocess, sys\n"
             "c = subprocess.Popen([sys.argv[1], sys.argv[2], '--jobs', '2'],\n"
             "                     stderr=subprocess.DEVNULL)\n"
             "print(c.pid, flush=True)\n"
             "c.wait()\n", REPORT, p],
            stdout=subprocess.PIPE, text=True)
        report_pid = int(parent.stdout.readline())

        def Children(pid):
            out = []
            for d in os.listdir("/proc"):
                if d.isdigit():
                    try:
                        with open(f"/proc/{d}/stat") as f:
                            fields = f.read().rsplit(")", 1)[1].split()
                    except OSError:
                        continue
                    if int(fields[1]) == pid and fields[0] != "Z":
                        out.append(int(d))
            return out

        def Alive(pid):
            try:
                with open(f"/proc/{pid}/stat") as f:
                    return f.read().rsplit(")", 1)[1].split()[0] != "Z"
            except OSError:
                return False

        def Command(pid):
            try:
                with open(f"/proc/{pid}/cmdline") as f:
                    return f.read()
            except OSError:
                return ""

        deadline = time.monotonic() + 120
        workers = []
        while time.monotonic() < deadline and len(workers) < 2 and Alive(report_pid):
            workers = [w for w in Children(report_pid)
                       if "pitmap-ply-layout" not in Command(w)]
            time.sleep(0.02)
        self.assertEqual(len(workers), 2, "the report started no two section workers")
        parent.kill()
        parent.wait()
        parent.stdout.close()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(Alive(q) for q in [report_pid] + workers):
            time.sleep(0.05)
        left = [q for q in [report_pid] + workers if Alive(q)]
        for q in left:
            os.kill(q, signal.SIGKILL)
        self.assertEqual(left, [], "still running 5 s after their parent was killed")
        self.assertFalse(os.path.exists(os.path.join(p, "report.html")),
                         "the report finished before the kill: the test proved nothing")

    def test_scores_option(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=False)
        other = os.path.join(self.dir, "elsewhere.json")
        with open(other, "w") as f:
            json.dump({"mesh_completeness": 0.8765}, f)
        r = Run(p, "--scores", other)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            sec = Sections(f.read())
        self.assertIn("0.8765", sec["scores"])
        self.assertNotIn("not produced", sec["scores"])

    def test_unusable_folder_fails_clearly(self):
        r = Run(self.dir)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("summary.json", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "report.html")))
        r = Run(os.path.join(self.dir, "does-not-exist"))
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("not a folder", r.stderr)
        with open(os.path.join(self.dir, "summary.json"), "w") as f:
            f.write("[1, 2")
        r = Run(self.dir)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("summary.json", r.stderr)

    def test_survey_time_without_gps_minus_utc_is_gps_time(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=False)
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        del summary["time"]
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(p, "report.html"), encoding="utf-8") as f:
            sec = Sections(f.read())
        self.assertIn("Survey time (GPS)", sec["summary"])
        self.assertIn("UTC unknown", sec["summary"])
        self.assertNotIn("2026-06-15 09:00:00", sec["summary"])

    def test_ins_trajectory_is_shown_when_no_slam_ran(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=False)
        os.rename(os.path.join(p, "trajectory.csv"), os.path.join(p, "trajectory_ins.csv"))
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("trajectory_ins.csv: 600 poses", r.stderr)


class HelperTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.m = LoadModule()

    def test_ply_reader_follows_the_header(self):
        # Read through the project's C++ PLY reader (pitmap-ply-layout), then memory-mapped.
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "p.ply")
            props = [("beam", "ushort", "u2"), ("z", "double", "f8"), ("x", "float", "f4"),
                     ("y", "int", "i4")]
            values = {"beam": [7, 8], "z": [-1.5, 2.25], "x": [3.0, 4.0], "y": [-5, 6]}
            WritePly(path, props, values, faces=np.array([[0, 1, 0]]),
                     comments=["pitmap_origin 1.5 -2.5 3.25"])
            ply = self.m.Ply(path)
            v = ply.elements["vertex"]
            self.assertIsInstance(v, np.memmap)
            self.assertEqual(list(v["beam"]), [7, 8])
            self.assertEqual(list(v["z"]), [-1.5, 2.25])
            self.assertEqual(list(v["x"]), [3.0, 4.0])
            self.assertEqual(list(v["y"]), [-5, 6])
            self.assertEqual(ply.elements["face"]["vertex_indices"].tolist(), [[0, 1, 0]])
            self.assertEqual(ply.counts, {"vertex": 2, "face": 1})
            self.assertEqual(ply.origin(), (1.5, -2.5, 3.25))
            # pitmap writes little-endian only; big-endian is refused with a clear error.
            WritePly(path, props, values, endian=">")
            with self.assertRaisesRegex(self.m.PlyError, r"^p\.ply: .*binary_big_endian"):
                self.m.Ply(path)

    def test_ply_reader_rejects_bad_files(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "a.ply")
            with open(path, "w") as f:
                f.write("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                        "end_header\n1\n")
            with self.assertRaisesRegex(self.m.PlyError, "ascii"):
                self.m.Ply(path)
            WritePly(path, [("x", "float", "f4")], {"x": np.arange(10.0)})
            with open(path, "r+b") as f:
                f.truncate(os.path.getsize(path) - 4)
            with self.assertRaisesRegex(self.m.PlyError, r"^a\.ply: truncated \(element vertex"):
                self.m.Ply(path)
            # Faces: a quad after a triangle, and the faces cut short.
            WritePly(path, [("x", "float", "f4")], {"x": np.arange(4.0)},
                     faces=np.array([[0, 1, 2], [1, 2, 3]]))
            with open(path, "rb") as f:
                data = f.read()
            body = data.index(b"end_header\n") + len(b"end_header\n") + 4 * 4
            with open(path, "wb") as f:
                f.write(data[:body + 13] + b"\x04" + data[body + 14:])
            with self.assertRaisesRegex(self.m.PlyError, r"^a\.ply: element face: record 1: "
                                        "list vertex_indices has 4 entries.*varying length"):
                self.m.Ply(path)
            with open(path, "wb") as f:
                f.write(data[:-3])
            with self.assertRaisesRegex(self.m.PlyError, r"^a\.ply: truncated \(element face"):
                self.m.Ply(path)
            with open(path, "wb") as f:
                f.write(b"not a ply at all\n")
            with self.assertRaisesRegex(self.m.PlyError, r"^a\.ply: not a PLY file"):
                self.m.Ply(path)

    def test_ply_reader_missing_is_a_clear_error(self):
        loaders = sys.modules["pitmap_report_lib.loaders"]
        saved = loaders.PROGRAM_DIR
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "p.ply")
            WritePly(path, [("x", "float", "f4")], {"x": np.arange(3.0)})
            loaders.PROGRAM_DIR = d
            try:
                with self.assertRaisesRegex(self.m.ReportError, "pitmap-ply-layout: not found"):
                    self.m.Ply(path)
            finally:
                loaders.PROGRAM_DIR = saved

    def test_gps_to_utc(self):
        # GPS - UTC comes from summary.json (the C++ side's table or the receiver), not a copy.
        self.assertFalse(hasattr(self.m, "LEAP_SECONDS"))
        self.assertEqual(str(self.m.GpsToUtc(GPS_T0, 18)), "2026-06-15 09:00:00+00:00")
        # 2000-01-01 00:00:00 UTC, GPS - UTC = 13 s then.
        self.assertEqual(str(self.m.GpsToUtc(630720013.0, 13)), "2000-01-01 00:00:00+00:00")


    def test_rasters(self):
        x = np.array([0.1, 0.2, 1.5, 5.0])
        y = np.array([0.1, 0.3, 0.5, 5.0])  # the last one is outside the grid
        v = np.array([1.0, 3.0, 7.0, 9.0])
        mean = self.m.RasterMean(x, y, v, 0.0, 0.0, 1.0, 2, 1)
        self.assertEqual(mean.tolist(), [[2.0, 7.0]])
        top = self.m.RasterMax(x, y, v, 0.0, 0.0, 1.0, 3, 1)
        self.assertEqual(top[0, :2].tolist(), [3.0, 7.0])
        self.assertTrue(np.isnan(top[0, 2]))

    def test_mesh_raster_covers_large_triangles(self):
        # One 10 m triangle on 0.5 m cells: every cell whose centre is inside gets a value.
        v = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0]])
        t = np.array([[0, 1, 2]])
        g = self.m.RasteriseMesh(v, t, 0.0, 0.0, 0.5, 20, 20)
        cx = (np.arange(20) + 0.5) * 0.5
        inside = (cx[None, :] + cx[:, None]) < 9.5
        self.assertTrue(np.all(g[inside] == 1.0))
        self.assertTrue(np.all(np.isnan(g[(cx[None, :] + cx[:, None]) > 10.5])))



def Glb(doc=None, binary=b"\0" * 12):
    """A glTF 2.0 binary: header, JSON chunk (padded with blanks), BIN chunk (padded)."""
    if doc is None:
        doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": len(binary)}],
               "bufferViews": [{"buffer": 0, "byteLength": len(binary)}],
               "accessors": [{"bufferView": 0, "componentType": 5126, "count": 1,
                              "type": "VEC3"}],
               "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}],
               "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0}
    text = json.dumps(doc).encode()
    text += b" " * ((4 - len(text) % 4) % 4)
    binary += b"\0" * ((4 - len(binary) % 4) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary:
        body += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


class GlbCheckTest(unittest.TestCase):
    """The .glb container check of --view-gltf (pitmap_report_lib/gltf.py) on crafted bytes."""

    @classmethod
    def setUpClass(cls):
        cls.m = LoadModule()

    def AssertRefused(self, data, words):
        with self.assertRaises(self.m.GlbError) as c:
            self.m.CheckGlb(data)
        self.assertIn(words, str(c.exception))

    def test_a_valid_file_passes(self):
        doc = self.m.CheckGlb(Glb())
        self.assertEqual(doc["asset"]["version"], "2.0")
        self.m.CheckGlb(Glb(binary=b""))  # a JSON chunk alone is a valid file

    def test_header_faults(self):
        good = Glb()
        self.AssertRefused(b"", "too short")
        self.AssertRefused(good[:11], "too short")
        self.AssertRefused(b"PK\x03\x04" + good[4:], "not a glTF binary")
        self.AssertRefused(good[:4] + struct.pack("<I", 1) + good[8:], "version 1")
        self.AssertRefused(good[:4] + struct.pack("<I", 3) + good[8:], "version 3")
        self.AssertRefused(good[:-8], "truncated: its header says")
        self.AssertRefused(good + b"\0" * 4, "bytes after the end")
        self.AssertRefused(good[:8] + struct.pack("<I", 12) + good[12:], "bytes after the end")

    def test_chunk_faults(self):
        good = Glb()
        n = len(good)
        self.AssertRefused(good[:8] + struct.pack("<I", 12) + good[12:12], "no JSON chunk")
        bad_type = bytearray(good)
        struct.pack_into("<I", bad_type, 16, 0x004E4942)
        self.AssertRefused(bytes(bad_type), "not JSON")
        long_json = bytearray(good)
        struct.pack_into("<I", long_json, 12, n)
        self.AssertRefused(bytes(long_json), "the JSON chunk says")
        # The BIN chunk cut short, with the header's length made to match.
        cut = bytearray(good[:-4])
        struct.pack_into("<I", cut, 8, len(cut))
        self.AssertRefused(bytes(cut), "the BIN chunk says")
        self.AssertRefused(Glb(doc=[1, 2]), "not a JSON object")
        self.AssertRefused(Glb(doc={"asset": {"version": "1.0"}}), "asset.version 2")
        not_json = bytearray(Glb(doc={"asset": {"version": "2.0"}}))
        not_json[20] = ord("?")
        self.AssertRefused(bytes(not_json), "not JSON")
        self.AssertRefused(Glb(doc={"asset": {"version": "2.0"},
                                    "buffers": [{"uri": "mesh.bin", "byteLength": 4}]}),
                           "refers to a file outside it")

    def test_mutations_are_refused_or_accepted_never_a_crash(self):
        # Every byte of a valid file changed, and every truncation: GlbError or a document.
        good = Glb()
        rng = np.random.default_rng(3)
        cases = [good[:k] for k in range(len(good))]
        for i in range(len(good)):
            b = bytearray(good)
            b[i] = (b[i] + 1 + int(rng.integers(255))) % 256
            cases.append(bytes(b))
        for data in cases:
            try:
                self.assertIsInstance(self.m.CheckGlb(data), dict)
            except self.m.GlbError:
                pass

    def test_view_gltf_command(self):
        with tempfile.TemporaryDirectory() as d:
            glb = os.path.join(d, "mesh.glb")
            with open(glb, "wb") as f:
                f.write(Glb())
            r = Run("--view-gltf", glb)
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(d, "mesh.html"), encoding="utf-8") as f:
                page = f.read()
            self.assertNotRegex(page, r"(?i)https?:")
            self.assertIn("GLTFLoader", page)
            self.assertIn("VRButton", page)
            self.assertIn(base64.b64encode(Glb()).decode(), page)
            out = os.path.join(d, "view.html")
            self.assertEqual(Run("--view-gltf", glb, "-o", out).returncode, 0)
            self.assertTrue(os.path.isfile(out))
            for name, data, words in (("points.ply", b"ply\nformat ascii 1.0\n", "not a glTF"),
                                      ("cut.glb", Glb()[:30], "truncated"),
                                      ("empty.glb", b"", "too short")):
                path = os.path.join(d, name)
                with open(path, "wb") as f:
                    f.write(data)
                r = Run("--view-gltf", path, "-o", os.path.join(d, "bad.html"))
                self.assertEqual(r.returncode, 1, name)
                self.assertIn(f"{path}: ", r.stderr)
                self.assertIn(words, r.stderr)
                self.assertFalse(os.path.exists(os.path.join(d, "bad.html")))
            r = Run("--view-gltf", os.path.join(d, "absent.glb"))
            self.assertEqual(r.returncode, 1)
            self.assertIn("absent.glb", r.stderr)
            self.assertEqual(Run("--view-gltf", glb, d).returncode, 2)  # and a products folder
            self.assertEqual(Run(d, "-o", out).returncode, 2)
            self.assertEqual(Run().returncode, 2)

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", required=True)
    args, rest = ap.parse_known_args()
    REPORT = os.path.abspath(args.report)
    unittest.main(argv=[sys.argv[0]] + rest)
