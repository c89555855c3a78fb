# SPDX-License-Identifier: MIT
"""pitmap-report on small synthetic products folders that this test writes itself.

Usage: python3 report_test.py --report PATH_TO_pitmap-report [unittest args]

Checks: both pages (report.html for the client, report_engineering.html) are written and
self-contained (no http(s) link, every image a data URI, no link but to each other, a
Content-Security-Policy that allows no network) and hold their sections; the cover shows
summary.json's metadata, or what older products have and "not set"; the S-44 compliance
statement for hand-made records; no path of this machine on the client's page; scores only
with a truth; the maps' scale bar against the geotransform; the engineering page names each
missing optional product ("not produced: ...") instead of failing; a folder without
summary.json is refused; the PLY reader and raster helpers give known values.
"""

import argparse
import base64
import importlib.machinery
import importlib.util
import json
import math
import os
import re
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import unittest

import numpy as np

REPORT = None  # path of the pitmap-report script, from --report
CLIENT_SECTIONS = ["cover", "summary", "datums", "maps", "hydro", "soundings", "mosaic", "terrain",
                   "capacity", "viewer", "scores", "engineering"]
ENGINEERING_SECTIONS = ["processing", "quality", "trajectory", "cross-sections", "depth", "tvu",
                        "rejections", "mesh", "boresight", "clock", "tsdf", "slam", "stages"]
# The maps' raster (WriteDem): 80 x 60 nodes of 0.5 m, UTM 29N, north-up.
DEM_GT = (603390.0, 0.5, 0.0, 4477710.0, 0.0, -0.5)
DEM_NX, DEM_NY = 80, 60
METADATA = {
    "project": "Pit 7 <north> lake", "client": "Lusa Quarries", "site": "Bejanca",
    "survey_id": "BJ-2026-06", "surveyor": "A. Hydrographer", "organisation": "Survey Co",
    "vessel": "ASV-2", "notes": "calm water",
    "equipment": [{"role": "multibeam", "model": "Imagenex DeltaT 837B"},
                  {"role": "gnss_ins", "model": "NovAtel PwrPak7D-E1"}],
    "survey_start_utc": "2026-06-15T09:00:00Z", "survey_end_utc": "2026-06-15T09:02:00Z",
    "processed_utc": "2026-06-16T10:11:12Z", "software": "pitmap 0.9.1",
    "horizontal_crs": {"name": "WGS 84 / UTM zone 29N", "epsg": 32629},
    "vertical_crs": {"name": "pit water level", "epsg": None,
                     "description": "depths below the pit's water level"},
    "s44_order_target": "special"}
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


def WriteTerrain(folder, grid):
    """terrain.tif (slope, roughness, step) and crawler.tif (Byte classes, no data 255) on
    DEM_GT, as the grid stage writes them, and their summary record."""
    from osgeo import gdal, osr
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32629)
    gx, gy = np.meshgrid(np.arange(DEM_NX), np.arange(DEM_NY))
    slope = np.clip(np.hypot(gx - 40, gy - 30), 0, 60).astype(np.float32)
    classes = np.where(slope < 15, 1, np.where(slope < 30, 2, 3)).astype(np.uint8)
    classes[10:14, 10:14] = 4
    classes[0, :] = 255
    for name, bands, dtype in (("terrain.tif", (("slope", slope), ("roughness", slope * 0.001),
                                                ("step", slope * 0.01)), gdal.GDT_Float32),
                               ("crawler.tif", (("crawler", classes),), gdal.GDT_Byte)):
        ds = gdal.GetDriverByName("GTiff").Create(os.path.join(folder, name), DEM_NX, DEM_NY,
                                                  len(bands), dtype)
        ds.SetGeoTransform(DEM_GT)
        ds.SetProjection(srs.ExportToWkt())
        for b, (desc, v) in enumerate(bands, start=1):
            band = ds.GetRasterBand(b)
            band.SetDescription(desc)
            if dtype == gdal.GDT_Byte:
                band.SetNoDataValue(255)
            band.WriteArray(v)
        ds = None
    grid["terrain"] = {
        "files": ["terrain.tif", "crawler.tif"], "window_m": 1.0, "step_window_m": 0.4,
        "crawler_max_slope_deg": 20.0, "crawler_max_step_m": 0.3, "crawler_max_roughness_m": 0.1,
        "launch_given": True, "launch_found": True, "launch_easting_northing": [603410.0, 4477695.0],
        "launch_snap_distance_m": 0.4, "area_with_data_m2": 1185.0,
        "area_by_class_m2": {"reachable": 512.25, "traversable, not reachable": 300.0,
                             "too steep": 350.0, "step obstacle": 4.0, "too rough": 0.0}}


def BoxGlb(size=(2.0, 0.8, 1.0)):
    """A glTF 2.0 binary of one box, size (x, y, z) in glTF's y-up axes: for a crawler 2 m wide,
    0.8 m high and 1 m long."""
    sx, sy, sz = (s / 2 for s in size)
    corners = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)],
                       dtype="<f4")
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
                     dtype="<u2")
    binary = corners.tobytes() + faces.tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"byteLength": len(binary)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": corners.nbytes},
                           {"buffer": 0, "byteOffset": corners.nbytes,
                            "byteLength": faces.nbytes}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                          "min": corners.min(axis=0).tolist(), "max": corners.max(axis=0).tolist()},
                         {"bufferView": 1, "componentType": 5123, "count": faces.size,
                          "type": "SCALAR"}]}
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(text), 0x4E4F534A)
            + text + struct.pack("<II", len(binary), 0x004E4942) + binary)


def WriteEquipment(work, products, world_xy, heading_deg=30.0):
    """work/crawler.glb (a 0.8 m high box) and work/equipment.yaml placing it at the UTM position
    of the products' world point world_xy: (the file, world_xy, half the model's height)."""
    from osgeo import osr
    with open(os.path.join(products, "summary.json")) as f:
        summary = json.load(f)
    o = summary["world_origin"]
    # The world point (local East, North on the origin's tangent plane) in ECEF, then in UTM
    # through GDAL: an independent path from the report's own (maps.grid_to_world).
    lat, lon, h = math.radians(o["latitude_deg"]), math.radians(o["longitude_deg"]), o["height_m"]
    a, f_ = 6378137.0, 1 / 298.257223563
    e2 = f_ * (2 - f_)
    nu = a / math.sqrt(1 - e2 * math.sin(lat) ** 2)
    x0 = (nu + h) * math.cos(lat) * math.cos(lon)
    y0 = (nu + h) * math.cos(lat) * math.sin(lon)
    z0 = (nu * (1 - e2) + h) * math.sin(lat)
    east, north = world_xy
    X = x0 - math.sin(lon) * east - math.sin(lat) * math.cos(lon) * north
    Y = y0 + math.cos(lon) * east - math.sin(lat) * math.sin(lon) * north
    Z = z0 + math.cos(lat) * north
    src, dst = osr.SpatialReference(), osr.SpatialReference()
    src.ImportFromEPSG(4978)
    dst.ImportFromEPSG(summary["utm"]["epsg"])
    for sr in (src, dst):
        sr.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    utm = osr.CoordinateTransformation(src, dst).TransformPoint(X, Y, Z)
    e, n = [utm[0]], [utm[1]]
    with open(os.path.join(work, "crawler.glb"), "wb") as f:
        f.write(BoxGlb())
    path = os.path.join(work, "equipment.yaml")
    with open(path, "w") as f:
        f.write("equipment:\n  - name: mining vehicle\n    model: crawler.glb\n"
                f"    easting: {e[0]:.4f}\n    northing: {n[0]:.4f}\n"
                f"    heading_deg: {heading_deg}\n")
    return path, list(world_xy), 0.4


def WriteDem(folder):
    """dem.tif (elevation, uncertainty) and s44_holidays.tif (one holiday of 4 x 4 nodes) on
    DEM_GT, as the grid stage writes them."""
    from osgeo import gdal, osr
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32629)
    gx, gy = np.meshgrid(np.arange(DEM_NX), np.arange(DEM_NY))
    elevation = -2.0 - 6.0 * np.exp(-((gx - 40) ** 2 + (gy - 30) ** 2) / 400.0)
    holidays = np.zeros((DEM_NY, DEM_NX))
    holidays[20:24, 30:34] = 2
    holidays[40, 10] = 1
    for name, bands in (("dem.tif", (("elevation", elevation), ("uncertainty",
                                                               0.05 + 0.01 * gx / DEM_NX))),
                        ("s44_holidays.tif", (("holiday", holidays),))):
        ds = gdal.GetDriverByName("GTiff").Create(os.path.join(folder, name), DEM_NX, DEM_NY,
                                                  len(bands), gdal.GDT_Float32)
        ds.SetGeoTransform(DEM_GT)
        ds.SetProjection(srs.ExportToWkt())
        for b, (desc, v) in enumerate(bands, start=1):
            band = ds.GetRasterBand(b)
            band.SetDescription(desc)
            band.SetNoDataValue(float("nan"))
            band.WriteArray(v.astype(np.float32))
        ds = None


def WriteProducts(folder, full=True, points_per_pose=21, metadata=None):
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
    if metadata is not None:
        summary["metadata"] = metadata
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
        WriteTerrain(folder, summary["stages"]["grid"])
        WriteDem(folder)
        summary["time"].update({"first_ping_utc": "2026-06-15T09:00:00.000000Z",
                                "last_ping_utc": "2026-06-15T09:01:59.800000Z",
                                "first_ping_gps_s": GPS_T0, "last_ping_gps_s": GPS_T0 + 119.8})
        summary["refraction"] = {
            "svp_files": ["/data/casts/pit7.svp"], "selection": "nearest_preceding",
            "surface_speed": "profile", "ins_height_above_waterline_m": 0.3,
            "casts": [{"name": "/data/casts/pit7.svp section 1", "time_utc":
                       "2026-06-15T08:50:00.000000Z", "latitude_deg": 40.4435,
                       "longitude_deg": -7.7806, "points": 4, "max_depth_m": 12.0,
                       "surface_speed_mps": 1496.0,
                       "profile": {"depth_m": [0, 2, 7, 12],
                                   "speed_mps": [1496.0, 1495.5, 1452.5, 1452.0]}}]}
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


def ReadPages(folder):
    """(report.html, report_engineering.html) of a products folder."""
    out = []
    for name in ("report.html", "report_engineering.html"):
        with open(os.path.join(folder, name), encoding="utf-8") as f:
            out.append(f.read())
    return tuple(out)


# An absolute path of a machine: "/" then at least two parts (a folder and a name), not after
# a word character, a dot, a colon or a slash.
MACHINE_PATH = re.compile(r"(?<![\w.:/])/[\w.-]+/[\w./-]*")


def VisibleText(page):
    """The page without its scripts, its images' data and its CSS: what a reader sees and
    the attributes."""
    page = re.sub(r"(?s)<script.*?</script>", "", page)
    page = re.sub(r"(?s)<style>.*?</style>", "", page)
    return re.sub(r'src="data:[^"]*"', 'src=""', page)


class ReportTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pitmap-report-test-")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def AssertSelfContained(self, page, folder, images=True):
        self.assertNotRegex(page, r"(?i)https?:")
        srcs = re.findall(r'src="([^"]*)"', page)
        if images:
            self.assertTrue(srcs, "no image at all")
        for s in srcs:
            self.assertTrue(s.startswith("data:image/png;base64,"), s[:60])
            self.assertEqual(base64.b64decode(s.split(",", 1)[1])[:8], PNG_MAGIC)
        for h in re.findall(r'href="([^"]*)"', page):
            self.assertTrue(h.startswith("#") or h in ("report.html", "report_engineering.html"),
                            h)
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
        page, eng = ReadPages(p)
        self.AssertSelfContained(page, p)
        self.AssertSelfContained(eng, p)
        self.assertIn("<title>Test pit &lt;survey&gt;</title>", page)
        sec, esec = Sections(page), Sections(eng)
        self.assertEqual(list(sec), CLIENT_SECTIONS)
        self.assertEqual(list(esec), ENGINEERING_SECTIONS)
        self.assertIn('href="report_engineering.html"', sec["engineering"])
        for text in (page, eng):
            self.assertFalse("not produced" in text, "not produced")
            self.assertNotIn("could not draw", text)
            self.assertNotIn('class="problem"', text)
        for s in ("maps", "datums", "hydro", "mosaic"):
            self.assertIn("data:image/png", sec[s], s)
        # Mine planning: both maps, the crawler's limits, the launch point, the areas.
        self.assertEqual(sec["terrain"].count("data:image/png"), 2)
        self.assertIn("slope up to 20.0 deg, steps up to 0.30 m", sec["terrain"])
        self.assertIn("E 603410.0, N 4477695.0", sec["terrain"])
        self.assertIn("<td>reachable</td><td>512 m&sup2;</td>", sec["terrain"])
        # The capacity curve: the water level as pitmap compare finds it (the vessel's median
        # height 412.0 + 0 m, no INS height above the water line, less the datum's 411.98 m),
        # the volume of water over dem.tif's nodes below it, here by hand.
        elevation = -2.0 - 6.0 * np.exp(-((np.arange(DEM_NX)[None, :] - 40) ** 2
                                          + (np.arange(DEM_NY)[:, None] - 30) ** 2) / 400.0)
        level = 412.0 - 411.98
        volume = float(np.sum(level - elevation.astype(np.float32)) * DEM_GT[1] ** 2)
        self.assertIn(f"<td>{level:.3f} m</td>", sec["capacity"])
        self.assertIn(f"<td>{volume:.0f} m&sup3;</td>", sec["capacity"])
        self.assertIn(f"<td>{DEM_NX * DEM_NY * DEM_GT[1] ** 2:.0f} m&sup2;</td>",
                      sec["capacity"])
        self.assertEqual(sec["capacity"].count("data:image/png"), 1)
        with open(os.path.join(p, "report", "capacity.csv")) as f:
            rows = f.read().splitlines()
        self.assertEqual(rows[0], "level_m,depth_below_water_level_m,area_m2,volume_m3")
        last = [float(v) for v in rows[-1].split(",")]
        self.assertAlmostEqual(last[0], level, places=4)
        self.assertAlmostEqual(last[3], volume, delta=0.002)
        self.assertAlmostEqual(last[2], DEM_NX * DEM_NY * DEM_GT[1] ** 2, places=3)
        for s in ("trajectory", "cross-sections", "depth", "tvu", "mesh", "tsdf", "slam",
                  "stages"):
            self.assertIn("data:image/png", esec[s], s)
        self.assertIn("40.0 log10(R) + 2 &times; 0.0210 dB/m", sec["mosaic"])
        self.assertIn("empirical, referenced to 45 deg", sec["mosaic"])
        self.assertIn("2026-06-15 09:00:00", esec["processing"])
        # The summary: the verdict for the grid stage's order (1a: 99.9 % of the soundings,
        # but one holiday where the order asks for full coverage), the datums, the caveats.
        self.assertIn('class="verdict not-met"', sec["summary"])
        self.assertIn("does not meet</b> IHO S-44 Edition 6.1 Order <b>1a</b>: 99.9 %",
                      sec["summary"])
        self.assertIn("<b>1 holiday(s)</b> could hide a 2.0 m feature", sec["summary"])
        self.assertIn("pit water level (GNSS, survey median)", sec["summary"])
        # Datums: the water level used, the cast applied (file name only) and its plot.
        self.assertIn("the pit's water surface measured by the vessel's GNSS: median 411.980 m",
                      sec["datums"])
        self.assertIn("<td>pit7.svp section 1</td><td>2026-06-15 08:50:00 UTC</td>",
                      sec["datums"])
        self.assertIn("grid north lies 0.79&deg; east of true north", sec["datums"])
        # The S-44 section: the orders' table, the holiday, the crossline table.
        self.assertIn("IHO S-44 Edition 6.1: order 1a", sec["hydro"])
        self.assertIn("<td><b>1a</b></td><td>5 + 5 % d</td>", sec["hydro"])
        self.assertIn("99.9", sec["hydro"])
        self.assertIn("<td>603410.20</td><td>4477697.30</td>", sec["hydro"])
        self.assertIn("100.0 % within the order 1a TVU limit", sec["hydro"])
        # The maps: in the raster's grid, scale bar from its 40 m width (DEM_GT).
        self.assertIn("north arrow: grid north; scale bar 10 m", sec["maps"])
        # Soundings: the client's table; the engineering page's map and worst ping runs
        # (the fish school, pings 10-14, first; the spikes one ping each).
        self.assertIn("<td>no_detection</td><td>40</td>", sec["soundings"])
        self.assertIn("<td>free_space</td>", esec["rejections"])
        self.assertIn("<td>no_detection</td><td>40</td>", esec["rejections"])
        self.assertNotIn("<td>multipath</td>", esec["rejections"])  # none: not listed
        self.assertIn("data:image/png", esec["rejections"])
        runs = re.findall(r"<td>(\d+)&ndash;(\d+)</td>", esec["rejections"])
        self.assertEqual(runs[0], ("10", "14"))
        self.assertIn("09:0", esec["rejections"])  # a UTC start time
        self.assertIn("free_space",
                      esec["rejections"].split("10&ndash;14")[1].split("</tr>")[0])
        self.assertIn("0.5200", esec["boresight"])      # roll after
        self.assertIn("0.0377", esec["boresight"])      # verification segment RMS after
        self.assertIn("No quality gate tripped", esec["quality"])
        self.assertIn("header position: correction -2.732 s", esec["clock"])
        self.assertIn("378.60 ms", esec["clock"])       # latency from the soundings
        self.assertIn("-2.3534 s", esec["clock"])       # total correction
        self.assertIn("1.3468", sec["scores"])
        self.assertIn("trajectory error before SLAM", sec["scores"])
        self.assertIn("1.347 &rarr; 0.031 m", esec["processing"])  # ATE before -> after
        self.assertIn("1.347 &rarr; 0.031 m", esec["trajectory"])
        # Stage table in stage_order, then the total.
        order = [m for m in re.findall(r"<td><b>([a-z]+)</b></td>", esec["stages"])]
        self.assertEqual(order, ["ingest", "georef", "calibrate", "slam", "grid", "fuse", "mesh",
                                 "total"])
        pngs = sorted(os.listdir(os.path.join(p, "report")))
        for name in ("trajectory.png", "cross_sections.png", "depth_top_view.png",
                     "mesh_renders.png", "tsdf_weights.png", "slam_iterations.png",
                     "stages.png", "s44_compliance.png", "s44_crossline.png", "mosaic.png",
                     "rejections_map.png", "map_depth.png", "map_uncertainty_coverage.png",
                     "sound_speed_casts.png", "capacity.png"):
            self.assertIn(name, pngs)
            with open(os.path.join(p, "report", name), "rb") as f:
                self.assertEqual(f.read(8), PNG_MAGIC)

    def test_trajectory_sigma_per_window(self):
        # P/trajectory_sigma.csv: 90 s at 10 Hz, the stated sigma 1 cm, 5 cm from 30 to 60 s
        # (SLAM's posterior there), the INS's 1 cm then 2 m: a figure and one row a 30 s window.
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        t = GPS_T0 + np.arange(900) * 0.1
        inside = (t >= GPS_T0 + 30) & (t < GPS_T0 + 60)
        sig = np.where(inside, 0.05, 0.01)
        ins = np.where(inside, 2.0, 0.01)
        with open(os.path.join(p, "trajectory_sigma.csv"), "w") as f:
            f.write("gps_time_s,x_m,y_m,z_m,x0_m,y0_m,z0_m,sigma_east_m,sigma_north_m,"
                    "sigma_up_m,sigma_roll_deg,sigma_pitch_deg,sigma_yaw_deg,ins_sigma_east_m,"
                    "ins_sigma_north_m,ins_sigma_up_m,slam_posterior\n")
            for k in range(len(t)):
                f.write(f"{t[k]:.6f},0,0,0,0,0,0,{sig[k]},{sig[k]},0.02,0.01,0.01,0.04,"
                        f"{ins[k]},{ins[k]},0.02,{int(inside[k])}\n")
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        _, eng = ReadPages(p)
        esec = Sections(eng)
        sec = esec["trajectory-sigma"]
        self.assertIn("data:image/png", sec)
        rows = re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td><td>([^<]*)</td><td>([^<]*)"
                          r"</td><td>([^<]*)</td></tr>", sec)
        self.assertEqual(len(rows), 3)
        self.assertEqual(rows[0][1], "0.024")  # 2.4477 x 0.01 m
        self.assertEqual(rows[1][1], "0.122")  # 2.4477 x 0.05 m
        self.assertEqual(rows[1][3], "4.895")  # the INS's own in the outage
        self.assertEqual([r[4] for r in rows], ["0 %", "100 %", "0 %"])

    def test_s44_section_shows_the_trajectory_radius_along_the_track(self):
        # summary.json stages.slam.posterior.windows (20 s): 1 cm stated with GNSS, 0.2 m in
        # the second window; the S-44 section gets the figure, a survey without them none.
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn("s44_trajectory_radius", Sections(ReadPages(p)[0])["hydro"])
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        summary["stages"]["slam"]["posterior"] = {
            "computed": True, "window_s": 20.0, "start_runs": 4,
            "windows": [{"start_gps_s": GPS_T0 + 20 * k, "end_gps_s": GPS_T0 + 20 * (k + 1),
                         "pings": 200, "median_radius_h95_m": 0.49 if k == 1 else 0.0245,
                         "max_radius_h95_m": 0.6 if k == 1 else 0.03} for k in range(3)]}
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        sec = Sections(ReadPages(p)[0])["hydro"]
        self.assertIn("trajectory 95 % horizontal radius along the track", sec)
        self.assertIn("per 20 s window (with the spread of 4 SLAM runs", sec)
        with open(os.path.join(p, "report", "s44_trajectory_radius.png"), "rb") as f:
            self.assertEqual(f.read(8), PNG_MAGIC)

    def test_cover_shows_the_metadata(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True, metadata=METADATA)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, eng = ReadPages(p)
        # Title: project, site and survey id, escaped; not the folder's name.
        title = "Pit 7 &lt;north&gt; lake \u2013 Bejanca \u2013 BJ-2026-06"
        self.assertIn(f"<title>{title}</title>", page)
        self.assertIn(f"<h1>{title}</h1>", page)
        self.assertIn(f"<title>{title} &ndash; engineering</title>", eng)
        cover = Sections(page)["cover"]
        for label, value in (("Project", "Pit 7 &lt;north&gt; lake"), ("Client", "Lusa Quarries"),
                             ("Site", "Bejanca"), ("Survey ID", "BJ-2026-06"),
                             ("Organisation", "Survey Co"), ("Surveyor", "A. Hydrographer"),
                             ("Vessel", "ASV-2"),
                             ("Equipment", "Multibeam echosounder: Imagenex DeltaT 837B<br>"
                              "GNSS/INS: NovAtel PwrPak7D-E1"),
                             ("Survey period", "2026-06-15 09:00:00 UTC to 2026-06-15 09:02:00 "
                              "UTC"),
                             ("Processed", "2026-06-16 10:11:12 UTC"),
                             ("Software", "pitmap 0.9.1"),
                             ("Horizontal CRS", "WGS 84 / UTM zone 29N (EPSG:32629)"),
                             ("Vertical datum", "pit water level"),
                             ("IHO S-44 order sought", "special"), ("Notes", "calm water")):
            self.assertIn(f"<td><b>{label}</b></td><td>{value}</td>", cover, label)
        self.assertNotIn("not set", cover)
        self.assertNotIn("(from ", cover)  # nothing from the fallbacks
        # The order sought is the metadata's: special is met by the soundings (93 % < 95 %:
        # not), and its holidays were searched for 1a.
        summary = Sections(page)["summary"]
        self.assertIn("does not meet</b> IHO S-44 Edition 6.1 Order <b>special</b>: 93.0 %",
                      summary)
        self.assertIn("the holidays were searched for order 1a, not special", summary)

    def test_cover_of_older_products_falls_back_and_says_not_set(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        summary["vehicle"] = {"name": "demo-asv"}
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, _ = ReadPages(p)
        self.assertIn("<title>Bathymetric survey report</title>", page)
        cover = Sections(page)["cover"]
        for label in ("Project", "Client", "Site", "Survey ID", "Organisation", "Surveyor",
                      "Equipment", "Processed", "Software"):
            self.assertIn(f"<td><b>{label}</b></td><td><span class=\"not-set\">not set</span>"
                          "</td>", cover, label)
        self.assertIn("<td><b>Vessel</b></td><td>demo-asv <span class=\"source\">(from "
                      "vehicle.yaml name)</span>", cover)
        self.assertIn("2026-06-15 09:00:00 UTC to 2026-06-15 09:01:59 UTC", cover)
        self.assertIn("WGS 84 / UTM zone 29N (EPSG:32629)", cover)
        self.assertIn("pit water level (GNSS, survey median)", cover)
        self.assertIn("<td><b>IHO S-44 order sought</b></td><td>1a", cover)
        self.assertNotIn("Notes", cover)
        # A summary.json with nothing to fall back on: every field "not set", no crash.
        WriteProducts(p, full=False)
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        for k in ("utm", "time", "world_origin"):
            del summary[k]
        summary["metadata"] = {"project": "", "equipment": "not a list", "horizontal_crs": 7}
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        for name in ("dem.tif", "s44_holidays.tif", "mosaic.tif", "scores.json"):
            if os.path.exists(os.path.join(p, name)):
                os.remove(os.path.join(p, name))
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, _ = ReadPages(p)
        sec = Sections(page)
        self.assertNotIn("could not draw", page)
        self.assertIn("<td><b>Horizontal CRS</b></td><td><span class=\"not-set\">", sec["cover"])
        self.assertIn("No IHO S-44 assessment was made", sec["summary"])
        self.assertNotIn("mosaic", sec)
        self.assertNotIn("scores", sec)

    def test_client_page_has_no_machine_paths(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        with open(os.path.join(p, "summary.json")) as f:
            summary = json.load(f)
        summary["inputs"] = ["/srv/surveys/2026/pit7/survey-0001.lcmlog",
                             "/srv/surveys/2026/pit7/vendor/"]
        summary["stages"]["grid"]["error_model"] = "/srv/surveys/vehicle.yaml uncertainty:"
        summary["vertical_datum"].update({"water_level_source": "file",
                                          "water_level_file": "/srv/tides/pit7-levels.csv",
                                          "water_levels": 48})
        summary["quality_gates"] = [{"stage": "grid", "gate": "crossline",
                                     "message": "see /srv/surveys/2026/pit7/P/s44_holidays.tif"}]
        with open(os.path.join(p, "summary.json"), "w") as f:
            json.dump(summary, f)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, eng = ReadPages(p)
        visible = VisibleText(page)
        self.assertEqual(MACHINE_PATH.findall(visible), [])
        self.assertNotIn(self.dir, page)
        # The inputs by file name, the water level file and the cast by name.
        self.assertIn("survey-0001.lcmlog<br>vendor", Sections(page)["engineering"])
        self.assertIn("observed levels from pit7-levels.csv (48 readings)", page)
        self.assertIn("pit7.svp section 1", page)
        self.assertIn("see s44_holidays.tif", Sections(page)["summary"])
        # The engineering page keeps the full inputs; the check finds them there.
        self.assertIn("/srv/surveys/2026/pit7/survey-0001.lcmlog",
                      MACHINE_PATH.findall(VisibleText(eng)))

    def test_scores_only_with_a_truth(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=True)
        os.remove(os.path.join(p, "scores.json"))
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, eng = ReadPages(p)
        self.assertNotIn("scores", Sections(page))
        self.assertNotIn("scores", Sections(eng))
        self.assertFalse("not produced" in page, "not produced")
        self.assertNotIn("scores.json", page + eng)
        self.assertNotIn("against ground truth", page)

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
        page, eng = ReadPages(p)
        sec = Sections(eng)
        # The client's summary lists them among the caveats, in words.
        self.assertIn("Quality gate <i>calibration_residual</i> (calibrate): residual RMS",
                      Sections(page)["summary"])
        self.assertIn("2 quality gate(s) tripped", sec["quality"])
        self.assertIn("calibration_residual", sec["quality"])
        self.assertIn("what &lt;noise&gt; leaves", sec["quality"])  # escaped
        self.assertIn("slam_beyond_ins_sigma", sec["quality"])

    def test_missing_optional_products_are_named(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=False)
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, eng = ReadPages(p)
        self.AssertSelfContained(page, p, images=False)  # no grid: no map, no cast
        self.AssertSelfContained(eng, p)
        sec, esec = Sections(page), Sections(eng)
        # The client's page leaves out what has nothing to show (no mosaic, no truth) and has
        # no "not produced" banner; the engineering page names every missing product.
        self.assertEqual(list(sec), [s for s in CLIENT_SECTIONS if s not in
                                     ("hydro", "mosaic", "terrain", "capacity", "scores",
                                      "soundings")])
        self.assertEqual(list(esec), ENGINEERING_SECTIONS)
        self.assertFalse("not produced" in page, "a 'not produced' line on the client's page")
        self.assertNotIn("could not draw", page + eng)
        expect = {"trajectory": "trajectory_initial.csv", "cross-sections": "points_initial.ply",
                  "mesh": "mesh.ply", "boresight": "boresight.json", "tsdf": "TSDF",
                  "slam": "SLAM", "tvu": "S-44", "rejections": "soundings"}
        for s, name in expect.items():
            self.assertRegex(esec[s], r"not produced: [^<]*" + re.escape(name), s)
        self.assertIn("mesh_initial.ply", esec["mesh"])
        self.assertIn('class="missing">not produced: ', eng)
        self.assertIn("No IHO S-44 assessment was made", sec["summary"])
        self.assertIn("No depth map", sec["maps"])
        # Without a slam stage nothing claims to be "after SLAM".
        self.assertIn("Points (SLAM not run)", esec["processing"])
        self.assertNotIn("after SLAM", esec["processing"])
        self.assertIn("not refined by SLAM", sec["summary"])
        # What exists is still drawn.
        for s in ("trajectory", "cross-sections", "depth", "stages"):
            self.assertIn("data:image/png", esec[s], s)

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
        page, eng = ReadPages(p)
        sec = Sections(eng)
        for text in (page, eng):
            self.assertRegex(text, r'class="problem">mesh_initial\.ply: origin 40\.4436000 '
                                   r"[^<]*differs from summary\.json world_origin 40\.4435000")
        self.assertRegex(sec["mesh"], r"not produced: mesh\.ply \([^)]*truncated")
        self.assertIn("data:image/png", sec["mesh"])  # the mesh before SLAM is still drawn
        # A truth was given but its scores cannot be read: the client's page says so.
        self.assertRegex(Sections(page)["scores"], r"not produced: scores\.json \(unreadable")

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
            pages[jobs] = re.sub(r"Report written[^<]*</b></td><td>[^<]*", "",
                                 "".join(ReadPages(p)))
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
        page = "".join(ReadPages(p))
        sec = Sections(ReadPages(p)[1])
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
        page = ReadPages(p)[1]
        sec = Sections(page)
        self.assertIn(f"points.ply is from another run (id {other}); not drawn", page)
        self.assertIn(f"points.ply is from another run (id {other}); not drawn", ReadPages(p)[0])
        self.assertIn(f"mesh.ply is from another run (it has no run id); not drawn", page)
        self.assertRegex(sec["depth"], r"not produced: points\.ply \(points\.ply is from another")
        self.assertNotIn("data:image/png", sec["depth"])
        # The same points with this run's id are drawn.
        WritePly(os.path.join(p, "points.ply"), POINT_PROPS, arrays,
                 comments=[origin, "pitmap_run_id " + run])
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        page = ReadPages(p)[1]
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

    def test_version_and_a_mistyped_option(self):
        r = Run("--version")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertRegex(r.stdout, r"^pitmap-report [0-9.]+ \(git ")
        r = Run(self.dir, "--pfd")
        self.assertEqual(r.returncode, 2)
        self.assertIn("did you mean '--pdf'", r.stderr)

    def test_unusable_folder_fails_clearly(self):
        r = Run(self.dir)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("summary.json", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "report.html")))
        r = Run(os.path.join(self.dir, "does-not-exist"))
        self.assertEqual(r.returncode, 2)  # usage (docs/cli.md)
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
        sec = Sections(ReadPages(p)[1])
        self.assertIn("Survey time (GPS)", sec["processing"])
        self.assertIn("UTC unknown", sec["processing"])
        self.assertNotIn("2026-06-15 09:00:00", sec["processing"])

    def test_ins_trajectory_is_shown_when_no_slam_ran(self):
        p = os.path.join(self.dir, "P")
        WriteProducts(p, full=False)
        os.rename(os.path.join(p, "trajectory.csv"), os.path.join(p, "trajectory_ins.csv"))
        r = Run(p)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("trajectory_ins.csv: 600 poses", r.stderr)


class EquipmentTest(unittest.TestCase):
    """pitmap-report --equipment: the file's problems all named (exit 2, nothing written), the
    UTM position taken to the products' world frame and back, the model in the view's data."""

    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="pitmap_report_equipment_")
        self.products = os.path.join(self.dir, "P")
        WriteProducts(self.products, full=True)

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def test_the_model_is_placed_in_the_view(self):
        path, world, _ = WriteEquipment(self.dir, self.products, (3.0, -2.0))
        r = Run(self.products, "--equipment", path)
        self.assertEqual(r.returncode, 0, r.stderr)
        page, _ = ReadPages(self.products)
        m = re.search(r'<script type="application/json" id="viewer-data">(.*?)</script>', page,
                      re.S)
        data = json.loads(m.group(1).replace("<\\/", "</"))
        self.assertEqual(len(data["equipment"]), 1)
        item = data["equipment"][0]
        self.assertEqual(item["name"], "mining vehicle")
        self.assertEqual(item["heading_deg"], 30.0)
        # The UTM position written to 4 decimals comes back to the world point within 1 mm;
        # no height given: the page stands it on the mesh.
        self.assertAlmostEqual(item["position_m"][0], world[0], delta=1e-3)
        self.assertAlmostEqual(item["position_m"][1], world[1], delta=1e-3)
        self.assertIsNone(item["position_m"][2])
        self.assertEqual(base64.b64decode(item["glb"]), BoxGlb())
        self.assertIn("equipment: mining vehicle", Sections(page)["viewer"])

    def test_every_problem_of_the_file_is_named(self):
        with open(os.path.join(self.dir, "broken.glb"), "wb") as f:
            f.write(BoxGlb()[:100])
        path = os.path.join(self.dir, "bad.yaml")
        with open(path, "w") as f:
            f.write("equipment:\n"
                    "  - name: crawler\n    model: missing.glb\n    easting: 1\n"
                    "  - model: broken.glb\n    easting: x\n    northing: 2\n    colour: red\n")
        r = Run(self.products, "--equipment", path)
        self.assertEqual(r.returncode, 2, r.stderr)
        for text in ("equipment[0]: northing is missing", "equipment[0]: model missing.glb",
                     "equipment[1]: name is missing", "equipment[1]: easting must be a number",
                     "equipment[1]: unknown key 'colour'", "equipment[1]: model broken.glb: "
                     "truncated"):
            self.assertIn(text, r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.products, "report.html")))

    def test_a_position_in_another_zone_is_refused(self):
        path, _, _ = WriteEquipment(self.dir, self.products, (3.0, -2.0))
        with open(path) as f:
            text = f.read()
        with open(path, "w") as f:
            f.write(re.sub(r"easting: [0-9.]+", "easting: 103412.0", text))
        r = Run(self.products, "--equipment", path)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("km from the survey (EPSG:32629)", r.stderr)

    def test_grid_to_world_inverts_world_to_grid(self):
        maps = LoadModule().maps
        origin = (40.4435, -7.7804, 412.0)
        x, y, z = np.array([0.0, 120.5, -300.0]), np.array([0.0, -80.25, 410.0]), np.zeros(3)
        e, n = maps.world_to_grid(origin, 32629, x, y, z)
        h = 412.0 + (x ** 2 + y ** 2) / (2 * 6378137.0)  # the tangent plane's height there
        x2, y2, _ = maps.grid_to_world(origin, 32629, e, n, h)
        np.testing.assert_allclose(x2, x, atol=1e-3)
        np.testing.assert_allclose(y2, y, atol=1e-3)


class HelperTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.m = LoadModule()

    def test_pings_left_out_are_said(self):
        from pitmap_report_lib.sections_clean import pings_left_out
        snd = {"pings": {"in": 1200, "georeferenced": 1197,
                         "left_out": {"outside_nav": 2, "nav_gap": 1, "bad_header": 0}},
               "not_placed": 1440}
        text = pings_left_out(snd)
        self.assertIn("2 outside the navigation", text)
        self.assertIn("1 in a navigation gap", text)
        self.assertNotIn("header", text)
        self.assertIn("1\u2009440 beams", text)
        # Every ping placed, or products from before the counts: nothing said.
        snd["pings"]["left_out"] = {"outside_nav": 0, "nav_gap": 0, "bad_header": 0}
        self.assertEqual(pings_left_out(snd), "")
        self.assertEqual(pings_left_out({"total": 5}), "")

    def test_capacity_curve_by_hand(self):
        from pitmap_report_lib.capacity import capacity_curve
        # Nodes of 2 m at heights 0, 1, 2 and an empty one; water at 1.5 m: two nodes under
        # water, 1.5 + 0.5 m deep, times 4 m^2.
        c = capacity_curve(np.array([[0.0, 1.0], [2.0, np.nan]]), 2.0, 1.5, step_m=0.5)
        self.assertEqual(c["surveyed_area_m2"], 12.0)
        self.assertEqual(c["deepest_m"], 0.0)
        self.assertEqual(c["area_at_water_level_m2"], 8.0)
        self.assertAlmostEqual(c["volume_at_water_level_m3"], 8.0)
        # Rows every 0.5 m from the deepest node, then the water level; a level equal to a
        # node's height does not count that node (z < L).
        self.assertEqual([r[0] for r in c["rows"]], [0.0, 0.5, 1.0, 1.5])
        self.assertEqual([r[1] for r in c["rows"]], [0.0, 4.0, 4.0, 8.0])
        self.assertEqual([r[2] for r in c["rows"]], [0.0, 2.0, 4.0, 8.0])
        self.assertEqual(capacity_curve(np.full(4, np.nan), 1.0, 1.0)["rows"], [])

    def test_compare_json_check_names_every_problem(self):
        from pitmap_report_lib.change import check_compare_json
        good = {
            "change": {"cut": {"volume_m3": -3.0, "u95_m3": 0.5, "area_m2": 4.0, "regions": 1},
                       "fill": {"volume_m3": 0.0, "u95_m3": 0.0, "area_m2": 0.0, "regions": 0},
                       "regions": [{"id": 1, "kind": "cut", "area_m2": 4.0, "volume_m3": -3.0,
                                    "u95_m3": 0.5}]},
            "capacity": {s: {"water_level_m": 10.0, "volume_at_water_level_m3": 100.0,
                             "area_at_water_level_m2": 20.0, "deepest_m": 2.0,
                             "surveyed_area_m2": 25.0} for s in ("a", "b")},
            "registration": {"translation_m": [0.0, 0.0, 0.01], "pivot_m": [1.0, 2.0, 3.0],
                             "rotation_deg": {"roll": 0.0, "pitch": 0.0, "yaw": 0.1},
                             "rms_vertical_before_m": 0.03, "rms_vertical_after_m": 0.02},
            "something_new": {"any": "thing"}}
        self.assertEqual(check_compare_json(good), [])
        bad = json.loads(json.dumps(good))
        bad["change"]["regions"].append({"id": 1, "kind": "cut", "area_m2": 1.0,
                                         "volume_m3": float("inf"), "u95_m3": 0.1})
        bad["change"]["fill"]["regions"] = 0.5
        del bad["capacity"]["a"]
        bad["registration"]["rotation_deg"]["yaw"] = "0.1"
        self.assertEqual(check_compare_json(bad), [
            "change.fill.regions is not an integer (0.5)",
            "change.regions[1].id 1 is not a new positive id",
            "change.regions[1].volume_m3 is not a number (Infinity)",
            "capacity.a is missing",
            'registration.rotation_deg.yaw is not a number ("0.1")'])

    def test_rotation_of_the_co_registration(self):
        from pitmap_report_lib.change import rotation_matrix
        # A yaw of 90 deg (about up) takes east to north; a rotation vector's angle is its norm.
        np.testing.assert_allclose(rotation_matrix([0, 0, math.pi / 2]) @ [1, 0, 0], [0, 1, 0],
                                   atol=1e-12)
        w = np.array([0.01, -0.02, 0.03])
        R = rotation_matrix(w)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(R @ w, w, atol=1e-15)  # the axis stays
        np.testing.assert_array_equal(rotation_matrix([0, 0, 0]), np.eye(3))

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
        self.assertEqual(str(self.m.gps_to_utc(GPS_T0, 18)), "2026-06-15 09:00:00+00:00")
        # 2000-01-01 00:00:00 UTC, GPS - UTC = 13 s then.
        self.assertEqual(str(self.m.gps_to_utc(630720013.0, 13)), "2000-01-01 00:00:00+00:00")


    def test_rasters(self):
        x = np.array([0.1, 0.2, 1.5, 5.0])
        y = np.array([0.1, 0.3, 0.5, 5.0])  # the last one is outside the grid
        v = np.array([1.0, 3.0, 7.0, 9.0])
        mean = self.m.raster_mean(x, y, v, 0.0, 0.0, 1.0, 2, 1)
        self.assertEqual(mean.tolist(), [[2.0, 7.0]])
        top = self.m.raster_max(x, y, v, 0.0, 0.0, 1.0, 3, 1)
        self.assertEqual(top[0, :2].tolist(), [3.0, 7.0])
        self.assertTrue(np.isnan(top[0, 2]))

    def S44(self, **kw):
        """A hand-made S-44 record of the grid stage (order 1a, feature detection)."""
        orders = ["exclusive", "special", "1a", "1b", "2"]
        rec = {"standard": "IHO S-44 Edition 6.1.0", "order": "1a", "soundings": 5000,
               "strictest_order_met_95": "1a", "coverage_share": 0.992, "holiday_count": 0,
               "feature_size_m": 2.0, "gaps": 3,
               "soundings_within_both": dict(zip(orders, [0.40, 0.90, 0.992, 0.992, 1.0])),
               "limits": {o: {"coverage_percent": c, "feature_m": fm} for o, c, fm in zip(
                   orders, [200, 100, 100, 5, 5], [0.5, 1, 2, 0, 0])}}
        rec.update(kw)
        return rec

    def test_compliance_statement(self):
        c = self.m.sections_client.compliance_statement
        verdict, text = c(self.S44())
        self.assertEqual(verdict, "met")
        self.assertEqual(text, "The survey <b>meets</b> IHO S-44 Edition 6.1.0 Order <b>1a</b>: "
                         "99.2 % of the 5\u2009000 soundings are within the order's total "
                         "vertical and horizontal uncertainty limits at 95 % confidence (at "
                         "least 95 % required), over 99.2 % of the survey area, with no holiday "
                         "that could hide a 2.0 m feature.")
        # A holiday fails an order that asks for full coverage ...
        verdict, text = c(self.S44(holiday_count=2))
        self.assertEqual(verdict, "not met")
        self.assertIn("<b>does not meet</b>", text)
        self.assertIn("<b>2 holiday(s)</b> could hide a 2.0 m feature", text)
        # ... not one that asks for 5 % (1b: no feature detection).
        self.assertEqual(c(self.S44(holiday_count=2, order="1b"))[0], "met")
        # Too few soundings within the limits of the order sought; the strictest met named.
        verdict, text = c(self.S44(), "special")
        self.assertEqual(verdict, "not met")
        self.assertIn("Order <b>special</b>: 90.0 %", text)
        self.assertIn("the holidays were searched for order 1a, not special", text)
        self.assertIn("The strictest order whose uncertainty limits are met is 1a.", text)
        # 94.96 % is not rounded up to a pass.
        verdict, text = c(self.S44(soundings_within_both={"1a": 0.9496}))
        self.assertEqual(verdict, "not met")
        self.assertIn(": 94.9 %", text)
        self.assertEqual(c(None)[0], "unknown")
        self.assertEqual(c(self.S44(), "2b")[0], "unknown")
        # A TVU on the a-priori sound speed bound (no cast, issue 36) says so.
        self.assertNotIn("Not assessable", c(self.S44())[1])
        verdict, text = c(self.S44(sound_speed_not_assessable="no sound-velocity cast"))
        self.assertEqual(verdict, "met")
        self.assertIn("<b>Not assessable for sound speed:</b> no sound-velocity cast.", text)

    def test_scale_bar_matches_the_geotransform(self):
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        maps = self.m.maps
        # 400 x 200 nodes of 0.5 m from (1000, 2000): 200 m wide, 100 m high.
        gt = (1000.0, 0.5, 0.0, 2000.0, 0.0, -0.5)
        extent = maps.raster_extent(gt, 400, 200)
        self.assertEqual(extent, (1000.0, 1200.0, 1900.0, 2000.0))
        self.assertEqual(maps.nice_length(200.0), 50.0)   # 1-2-5 steps, <= a quarter
        self.assertEqual(maps.nice_length(39.0), 5.0)
        self.assertEqual(maps.nice_length(0.9), 0.2)
        fig, a = plt.subplots()
        x0, x1, length = maps.add_furniture(a, extent, "WGS 84 / UTM zone 29N")
        self.assertEqual(length, 50.0)
        self.assertAlmostEqual(x1 - x0, 50.0, places=9)
        self.assertTrue(extent[0] < x0 < x1 < extent[1])
        # The bar's drawn segments (data units) add up to its length: 100 nodes of 0.5 m.
        segments = [r for r in a.patches if r.get_zorder() == 10]
        self.assertEqual(len(segments), 5)  # of 10 m
        self.assertAlmostEqual(sum(r.get_width() for r in segments), 100 * gt[1], places=9)
        self.assertEqual(min(r.get_x() for r in segments), x0)
        fig.canvas.draw()
        labels = [t.get_text() for t in a.get_xticklabels() if t.get_text()]
        self.assertIn("1\u2009100", labels)  # eastings in whole metres, no offset
        self.assertEqual(a.get_xlabel(), "Easting (m), WGS 84 / UTM zone 29N")
        self.assertIn("N", [t.get_text() for t in a.texts])
        self.assertIn("grid north", [t.get_text() for t in a.texts])
        plt.close(fig)

    def test_world_points_on_the_grid(self):
        from osgeo import osr
        maps = self.m.maps
        origin = (40.4435, -7.7804, 412.0)
        src, dst = osr.SpatialReference(), osr.SpatialReference()
        src.ImportFromEPSG(4326)
        dst.ImportFromEPSG(32629)
        for sr in (src, dst):
            sr.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
        e0, n0, _ = osr.CoordinateTransformation(src, dst).TransformPoint(origin[1], origin[0])
        e, n = maps.world_to_grid(origin, 32629, [0.0, 100.0], [0.0, 0.0], [0.0, 0.0])
        self.assertAlmostEqual(e[0], e0, places=3)   # the origin is the origin
        self.assertAlmostEqual(n[0], n0, places=3)
        # 100 m due east: 100 m times the UTM scale factor (0.9996 to 1.0004 near zone edges),
        # turned by the grid convergence: grid north lies east of true north here, so true
        # east points that much above grid east.
        d = math.hypot(e[1] - e[0], n[1] - n[0])
        self.assertAlmostEqual(d, 100.0, delta=0.05)
        gamma = maps.grid_convergence_deg(origin[0], origin[1], maps.utm_central_meridian_deg(29))
        self.assertAlmostEqual(gamma, 0.79, delta=0.005)
        self.assertAlmostEqual(math.degrees(math.atan2(n[1] - n[0], e[1] - e[0])), gamma,
                               delta=0.005)
        self.assertEqual(maps.grid_convergence_deg(0.0, 10.0, 9.0), 0.0)
        self.assertLess(maps.grid_convergence_deg(40.0, 8.0, 9.0), 0.0)

    def test_strip_paths(self):
        sp = self.m.util.strip_paths
        self.assertEqual(sp("/home/a/b/survey.lcmlog"), "survey.lcmlog")
        self.assertEqual(sp("error model /etc/pitmap/vehicle.yaml uncertainty:"),
                         "error model vehicle.yaml uncertainty:")
        self.assertEqual(sp("0.5 m/s and 10 km/h, 1/2"), "0.5 m/s and 10 km/h, 1/2")
        self.assertEqual(sp("see hxxps://example.org/a/b"), "see hxxps://example.org/a/b")

    def test_mesh_raster_covers_large_triangles(self):
        # One 10 m triangle on 0.5 m cells: every cell whose centre is inside gets a value.
        v = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0]])
        t = np.array([[0, 1, 2]])
        g = self.m.rasterise_mesh(v, t, 0.0, 0.0, 0.5, 20, 20)
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
            self.m.check_glb(data)
        self.assertIn(words, str(c.exception))

    def test_a_valid_file_passes(self):
        doc = self.m.check_glb(Glb())
        self.assertEqual(doc["asset"]["version"], "2.0")
        self.m.check_glb(Glb(binary=b""))  # a JSON chunk alone is a valid file

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
                self.assertIsInstance(self.m.check_glb(data), dict)
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
