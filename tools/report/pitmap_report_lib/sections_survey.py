# SPDX-License-Identifier: MIT
"""The report's table sections: the survey facts, the quality gates, the sonar clock, the
boresight calibration and the scores against ground truth."""

import datetime
import json
import os

import numpy as np

from .loaders import Ply, PlyError
from .util import esc, gps_to_utc, num, not_produced, table

# What pitmap-eval's scores mean (pitmap-eval --help); unknown names are shown as they come.
SCORE_MEANINGS = {
    "trajectory_ate_rmse_m":
        "trajectory error after SLAM (RMS position error vs truth, no alignment)",
    "trajectory_ate_rmse_before_m": "trajectory error before SLAM (trajectory_initial.csv)",
    "trajectory_ate_max_m": "largest trajectory position error after SLAM",
    "trajectory_z_std_m": "std of the track height (a surface vehicle's track is planar)",
    "points_rms_m": "RMS distance of the points to the true terrain",
    "points_p95_m": "95th percentile of the point distance to the true terrain",
    "points_bias_m": "mean signed point distance to the true terrain",
    "points_scored": "points scored",
    "boresight_error_deg": "angle between the estimated and the true boresight rotation",
    "mesh_mean_abs_m": "mean |distance| of mesh vertices and centroids to the true surface",
    "mesh_rms_m": "RMS distance of the mesh to the true surface",
    "mesh_p95_m": "95th percentile of the mesh distance to the true surface",
    "mesh_completeness": "share of the insonified true surface within 0.2 m of the mesh",
}


def survey_facts(p):
    s = p.summary
    rows = []
    main = p.traj.get("final") or p.traj.get("initial")
    if main is not None:
        t_a, t_b = float(main["t"][0]), float(main["t"][-1])
        tm = s.get("time") if isinstance(s.get("time"), dict) else {}
        leap = tm.get("gps_minus_utc_s")
        if isinstance(leap, (int, float)) and not isinstance(leap, bool):
            u_a, u_b = gps_to_utc(t_a, leap), gps_to_utc(t_b, leap)
            rows.append(("Survey time (UTC)",
                         f"{u_a:%Y-%m-%d %H:%M:%S} to {u_b:%H:%M:%S} "
                         f"({(t_b - t_a) / 60:.1f} min; GPS {t_a:.1f} to {t_b:.1f} s; "
                         f"GPS - UTC = {leap:g} s, "
                         f"{esc(tm.get('gps_minus_utc_source', '?'))})"))
        else:
            rows.append(("Survey time (GPS)",
                         f"GPS {t_a:.1f} to {t_b:.1f} s ({(t_b - t_a) / 60:.1f} min); UTC "
                         "unknown: summary.json has no time.gps_minus_utc_s (an older "
                         "pitmap georef)"))
        length = float(np.sum(np.hypot(np.diff(main["x"]), np.diff(main["y"]))))
        which = p.after if "final" in p.traj else "before SLAM"
        rows.append(("Track length", f"{length:.0f} m ({which})"))
    o = s.get("world_origin") or {}
    if o:
        rows.append(("World origin (WGS84)",
                     f"lat {num(float(o.get('latitude_deg', float('nan'))), 7)}&deg;, "
                     f"lon {num(float(o.get('longitude_deg', float('nan'))), 7)}&deg;, "
                     f"h {num(float(o.get('height_m', float('nan'))), 2)} m; "
                     "frame: East, North, Up metres"))
    u = s.get("utm") or {}
    if u:
        rows.append(("Projected CRS", f"UTM zone {esc(u.get('zone'))}"
                     f"{'N' if u.get('northern', True) else 'S'}, EPSG:{esc(u.get('epsg'))}"))
    geo = p.stages.get("georef") or {}
    ing = p.stages.get("ingest") or {}
    if "pings_georeferenced" in geo:
        rows.append(("Pings", f"{num(geo['pings_georeferenced'])} georeferenced of "
                     f"{num(geo.get('pings_in', ing.get('pings', '?')))}"))
    elif "pings" in ing:
        rows.append(("Pings", num(ing["pings"])))
    for key, label in (("final", f"Points ({p.after})"),
                       ("initial", "Points (before SLAM)")):
        if key in p.points:
            rows.append((label, num(len(p.points[key]))))
    for name in ("mesh.ply", "mesh_initial.ply"):
        if os.path.isfile(p.path(name)):
            try:
                ply = Ply(p.path(name))
                foreign = p.foreign_run(name, ply.run_id())
                rows.append((f"Mesh {name}", esc(foreign) if foreign else
                             f"{num(ply.counts.get('vertex', 0))} vertices, "
                             f"{num(ply.counts.get('face', 0))} triangles"))
            except (OSError, PlyError) as e:
                rows.append((f"Mesh {name}", esc(e)))
    ate = p.score_text("trajectory_ate_rmse_before_m", "trajectory_ate_rmse_m", "")
    if ate:
        rows.append(("Trajectory error vs truth (before &rarr; after SLAM)", ate.strip()))
    if "initial" in p.traj and "final" in p.traj:
        rows.append(("Track height std (before &rarr; after SLAM)",
                     f"{np.std(p.traj['initial']['z']):.3f} &rarr; "
                     f"{np.std(p.traj['final']['z']):.3f} m"))
    rec = p.stages.get("slam")
    if isinstance(rec, dict) and "initial_consistency_m" in rec:
        rows.append(("SLAM consistency score",
                     f"{num(rec['initial_consistency_m'], 4)} &rarr; "
                     f"{num(rec.get('final_consistency_m', float('nan')), 4)} m "
                     f"({esc(rec.get('termination', '?'))})"))
    if "total_seconds" in s:
        rows.append(("Processing time", f"{float(s['total_seconds']):.1f} s"))
    inputs = s.get("inputs") or []
    if inputs:
        rows.append(("Inputs", "<br>".join(esc(i) for i in inputs)))
    m = s.get("mount") or {}
    if m:
        rows.append(("Boresight used (roll, pitch, yaw)",
                     f"{num(float(m.get('roll_deg', 0)))}&deg;, "
                     f"{num(float(m.get('pitch_deg', 0)))}&deg;, "
                     f"{num(float(m.get('yaw_deg', 0)))}&deg;"))
    rows.append(("Report written (UTC)",
                 f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M:%S}"))
    return table([(f"<b>{k}</b>", v) for k, v in rows], cls="facts")


def quality_gates(p):
    """The quality gates: where a stage said it could not explain its data."""
    gates = p.summary.get("quality_gates")
    if not isinstance(gates, list) or not gates:
        return ('<p>No quality gate tripped: every stage explained its data within the '
                'limits of the <code>quality</code> configuration.</p>')
    rows = [[esc(g.get("stage", "?")), esc(g.get("gate", "?")), esc(g.get("message", ""))]
            for g in gates if isinstance(g, dict)]
    return ('<p class="problem">' + str(len(rows)) + " quality gate(s) tripped: the "
            "products below are what the processing could make, but these stages could not "
            "explain their data. Read the reasons before using the results.</p>" +
            table(rows, header=["stage", "gate", "what was found"]))


def sonar_clock(p):
    clk = p.summary.get("sonar_clock")
    if not isinstance(clk, dict):
        return p.missing_product("sonar clock", "summary.json has no sonar_clock (older run)")
    facts = [("time source of the pings", esc(clk.get("source", "?")))]
    if clk.get("configured"):
        facts.append(("configured offset", f"{num(clk.get('configured_offset_s', 0), 4)} s"))
    co = clk.get("coarse")
    if isinstance(co, dict):
        facts.append(("coarse estimate (" + esc(co.get("method", "?")) + ")",
                      esc(co.get("message", ""))))
    rate = clk.get("rate")
    if isinstance(rate, dict) and rate.get("message"):
        facts.append(("clock rate (" + ("applied" if rate.get("found") else "not applied") +
                      ")", esc(rate["message"])))
    if "latency_s" in clk:
        facts.append(("latency from the soundings",
                      f"{num(1e3 * float(clk['latency_s']), 2)} ms (formal sd "
                      f"{num(1e3 * float(clk.get('latency_formal_sd_s', 0)), 2)} ms)"))
    correction = (f"{num(float(clk.get('correction_s', 0)), 4)} s &plusmn; "
                  f"{num(float(clk.get('sigma_s', 0)), 4)} s")
    if "rate_ppm" in clk:
        ref = float(clk.get("rate_reference_gps_s", 0))
        when = (f"{(ref - p.t0) / 60:.2f} min since start" if p.t0
                else f"{ref:.3f} GPS s")
        correction += (f" at {when}, {num(float(clk['rate_ppm']), 1)} ppm of the time "
                       "since then added")
    facts.append(("correction applied to the ping times", correction))
    if "estimated_offset_s" in clk:
        facts.append(("offset the data imply", f"{num(clk['estimated_offset_s'], 4)} s"))
    return table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts")


def boresight(p):
    out = []
    cal = p.stages.get("calibrate")
    bs_file = p.path("boresight.json")
    mount = None
    if os.path.isfile(bs_file):
        try:
            with open(bs_file) as f:
                mount = json.load(f)
            foreign = p.foreign_run("boresight.json", mount.get("run_id")
                                    if isinstance(mount, dict) else None)
            if foreign:
                out.append(not_produced("boresight.json", foreign))
                mount = None
        except (OSError, ValueError) as e:
            out.append(not_produced("boresight.json", f"unreadable: {e}"))
    else:
        out.append(p.missing_product("boresight.json"))
    if not isinstance(cal, dict):
        out.append(p.missing_product("boresight calibration",
                                     "no calibrate stage in summary.json; the mount was used "
                                     "as configured"))
        if isinstance(mount, dict):
            out.append(table([[esc(a), num(float(mount.get(f"{a}_deg", float("nan"))), 4)]
                              for a in ("roll", "pitch", "yaw")],
                             header=["axis", "boresight used (deg)"]))
        return "\n".join(out)
    b0 = cal.get("boresight_before") or {}
    b1 = cal.get("boresight_after") or mount or {}
    sd = cal.get("formal_sd_deg") or [float("nan")] * 3
    # 1 sigma with the INS's own attitude error over the window (older summaries: none).
    sd_all = cal.get("sd_deg") or [float("nan")] * 3

    def at_index(v, i):
        try:
            return float(v[i])
        except (IndexError, TypeError, ValueError):
            return float("nan")
    rows = []
    for i, axis in enumerate(("roll", "pitch", "yaw")):
        a0 = float(b0.get(f"{axis}_deg", float("nan")))
        a1 = float(b1.get(f"{axis}_deg", float("nan")))
        rows.append([axis, num(a0, 4), num(a1, 4), num(a1 - a0, 4),
                     num(at_index(sd, i), 4), num(at_index(sd_all, i), 4)])
    out.append(table(rows, header=["axis", "before (deg)", "after (deg)", "change (deg)",
                                   "formal sd (deg)", "sd with the INS attitude (deg)"]))
    facts = []
    if "residual_before_rms_m" in cal or "residual_after_rms_m" in cal:
        r0 = cal.get("residual_before_rms_m", float("nan"))
        r1 = cal.get("residual_after_rms_m", float("nan"))
        facts.append(("residual RMS", f"{num(r0, 4)} &rarr; {num(r1, 4)} m"))
    for k in ("pairs", "iterations", "termination", "height_offsets_rms_m"):
        if k in cal:
            facts.append((k.replace("_", " "), num(cal[k], 4)))
    seg = cal.get("segment")
    if isinstance(seg, dict) and "start_s" in seg:
        t0 = p.t0 or seg["start_s"]
        facts.append(("calibration segment",
                      f"{(seg['start_s'] - t0) / 60:.2f} to "
                      f"{(seg.get('end_s', 0) - t0) / 60:.2f}"
                      f" min since start ({seg.get('end_s', 0) - seg['start_s']:.0f} s)"))
    if cal.get("message"):
        facts.append(("message", esc(cal["message"])))
    out.append(table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
    ver = cal.get("verify")
    if isinstance(ver, list) and ver:
        t0 = p.t0 or 0.0
        rows = []
        for v in ver:
            rows.append([f"{(v.get('start_s', 0) - t0) / 60:.2f}&ndash;"
                         f"{(v.get('end_s', 0) - t0) / 60:.2f}",
                         num(float(v.get("rms_before_m", float("nan"))), 4),
                         num(float(v.get("rms_after_m", float("nan"))), 4),
                         num(v.get("pairs", 0))])
        out.append("<h3>Verification segments</h3>")
        out.append(table(rows, header=["segment (min since start)", "RMS before (m)",
                                       "RMS after (m)", "pairs"]))
    else:
        out.append(not_produced("verification segments", "calibrate reported none"))
    return "\n".join(out)


def scores(p):
    """The scores against a ground truth (pitmap-eval --json): a simulated survey's, or a
    reference survey's; None when no truth was given."""
    name = os.path.basename(p.scores_path)
    if not p.scores:
        return p.missing_product(name) if name in p.unusable else None
    rows = [[esc(k), num(v, 4) if isinstance(v, (int, float)) else esc(v),
             esc(SCORE_MEANINGS.get(k, ""))] for k, v in p.scores.items()]
    return table(rows, header=["score", "value", "meaning"])
