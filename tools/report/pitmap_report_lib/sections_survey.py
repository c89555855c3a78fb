# SPDX-License-Identifier: MIT
"""The report's table sections: the survey facts, the quality gates, the sonar clock, the
boresight calibration and the scores against ground truth."""

import datetime
import json
import os

import numpy as np

from .loaders import Ply, PlyError
from .util import Esc, GpsToUtc, Num, NotProduced, Table

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



class SurveySections:
    """Mixin of report.Report (needs the loaded products of loaders.Products)."""

    def SectionHeader(self):
        s = self.summary
        rows = []
        main = self.traj.get("final") or self.traj.get("initial")
        if main is not None:
            t_a, t_b = float(main["t"][0]), float(main["t"][-1])
            tm = s.get("time") if isinstance(s.get("time"), dict) else {}
            leap = tm.get("gps_minus_utc_s")
            if isinstance(leap, (int, float)) and not isinstance(leap, bool):
                u_a, u_b = GpsToUtc(t_a, leap), GpsToUtc(t_b, leap)
                rows.append(("Survey time (UTC)",
                             f"{u_a:%Y-%m-%d %H:%M:%S} to {u_b:%H:%M:%S} "
                             f"({(t_b - t_a) / 60:.1f} min; GPS {t_a:.1f} to {t_b:.1f} s; "
                             f"GPS - UTC = {leap:g} s, "
                             f"{Esc(tm.get('gps_minus_utc_source', '?'))})"))
            else:
                rows.append(("Survey time (GPS)",
                             f"GPS {t_a:.1f} to {t_b:.1f} s ({(t_b - t_a) / 60:.1f} min); UTC "
                             "unknown: summary.json has no time.gps_minus_utc_s (an older "
                             "pitmap georef)"))
            length = float(np.sum(np.hypot(np.diff(main["x"]), np.diff(main["y"]))))
            which = self.after if "final" in self.traj else "before SLAM"
            rows.append(("Track length", f"{length:.0f} m ({which})"))
        o = s.get("world_origin") or {}
        if o:
            rows.append(("World origin (WGS84)",
                         f"lat {Num(float(o.get('latitude_deg', float('nan'))), 7)}&deg;, "
                         f"lon {Num(float(o.get('longitude_deg', float('nan'))), 7)}&deg;, "
                         f"h {Num(float(o.get('height_m', float('nan'))), 2)} m; "
                         "frame: East, North, Up metres"))
        u = s.get("utm") or {}
        if u:
            rows.append(("Projected CRS", f"UTM zone {Esc(u.get('zone'))}"
                         f"{'N' if u.get('northern', True) else 'S'}, EPSG:{Esc(u.get('epsg'))}"))
        geo = self.stages.get("georef") or {}
        ing = self.stages.get("ingest") or {}
        if "pings_georeferenced" in geo:
            rows.append(("Pings", f"{Num(geo['pings_georeferenced'])} georeferenced of "
                         f"{Num(geo.get('pings_in', ing.get('pings', '?')))}"))
        elif "pings" in ing:
            rows.append(("Pings", Num(ing["pings"])))
        for key, label in (("final", f"Points ({self.after})"),
                           ("initial", "Points (before SLAM)")):
            if key in self.points:
                rows.append((label, Num(len(self.points[key]))))
        for name in ("mesh.ply", "mesh_initial.ply"):
            if os.path.isfile(self.P(name)):
                try:
                    ply = Ply(self.P(name))
                    foreign = self.ForeignRun(name, ply.run_id())
                    rows.append((f"Mesh {name}", Esc(foreign) if foreign else
                                 f"{Num(ply.counts.get('vertex', 0))} vertices, "
                                 f"{Num(ply.counts.get('face', 0))} triangles"))
                except (OSError, PlyError) as e:
                    rows.append((f"Mesh {name}", Esc(e)))
        ate = self.ScoreText("trajectory_ate_rmse_before_m", "trajectory_ate_rmse_m", "")
        if ate:
            rows.append(("Trajectory error vs truth (before &rarr; after SLAM)", ate.strip()))
        if "initial" in self.traj and "final" in self.traj:
            rows.append(("Track height std (before &rarr; after SLAM)",
                         f"{np.std(self.traj['initial']['z']):.3f} &rarr; "
                         f"{np.std(self.traj['final']['z']):.3f} m"))
        slam = self.stages.get("slam")
        if isinstance(slam, dict) and "initial_consistency_m" in slam:
            rows.append(("SLAM consistency score",
                         f"{Num(slam['initial_consistency_m'], 4)} &rarr; "
                         f"{Num(slam.get('final_consistency_m', float('nan')), 4)} m "
                         f"({Esc(slam.get('termination', '?'))})"))
        if "total_seconds" in s:
            rows.append(("Processing time", f"{float(s['total_seconds']):.1f} s"))
        inputs = s.get("inputs") or []
        if inputs:
            rows.append(("Inputs", "<br>".join(Esc(i) for i in inputs)))
        m = s.get("mount") or {}
        if m:
            rows.append(("Boresight used (roll, pitch, yaw)",
                         f"{Num(float(m.get('roll_deg', 0)))}&deg;, "
                         f"{Num(float(m.get('pitch_deg', 0)))}&deg;, "
                         f"{Num(float(m.get('yaw_deg', 0)))}&deg;"))
        rows.append(("Report written (UTC)",
                     f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M:%S}"))
        return Table([(f"<b>{k}</b>", v) for k, v in rows], cls="facts")

    def SectionQuality(self):
        """The quality gates: where a stage said it could not explain its data."""
        gates = self.summary.get("quality_gates")
        if not isinstance(gates, list) or not gates:
            return ('<p>No quality gate tripped: every stage explained its data within the '
                    'limits of the <code>quality</code> configuration.</p>')
        rows = [[Esc(g.get("stage", "?")), Esc(g.get("gate", "?")), Esc(g.get("message", ""))]
                for g in gates if isinstance(g, dict)]
        return ('<p class="problem">' + str(len(rows)) + " quality gate(s) tripped: the "
                "products below are what the processing could make, but these stages could not "
                "explain their data. Read the reasons before using the results.</p>" +
                Table(rows, header=["stage", "gate", "what was found"]))

    def SectionClock(self):
        clk = self.summary.get("sonar_clock")
        if not isinstance(clk, dict):
            return self.Missing("sonar clock", "summary.json has no sonar_clock (older run)")
        facts = [("time source of the pings", Esc(clk.get("source", "?")))]
        if clk.get("configured"):
            facts.append(("configured offset", f"{Num(clk.get('configured_offset_s', 0), 4)} s"))
        co = clk.get("coarse")
        if isinstance(co, dict):
            facts.append(("coarse estimate (" + Esc(co.get("method", "?")) + ")",
                          Esc(co.get("message", ""))))
        rate = clk.get("rate")
        if isinstance(rate, dict) and rate.get("message"):
            facts.append(("clock rate (" + ("applied" if rate.get("found") else "not applied") +
                          ")", Esc(rate["message"])))
        if "latency_s" in clk:
            facts.append(("latency from the soundings",
                          f"{Num(1e3 * float(clk['latency_s']), 2)} ms (formal sd "
                          f"{Num(1e3 * float(clk.get('latency_formal_sd_s', 0)), 2)} ms)"))
        correction = (f"{Num(float(clk.get('correction_s', 0)), 4)} s &plusmn; "
                      f"{Num(float(clk.get('sigma_s', 0)), 4)} s")
        if "rate_ppm" in clk:
            ref = float(clk.get("rate_reference_gps_s", 0))
            when = (f"{(ref - self.t0) / 60:.2f} min since start" if self.t0
                    else f"{ref:.3f} GPS s")
            correction += (f" at {when}, {Num(float(clk['rate_ppm']), 1)} ppm of the time "
                           "since then added")
        facts.append(("correction applied to the ping times", correction))
        if "estimated_offset_s" in clk:
            facts.append(("offset the data imply", f"{Num(clk['estimated_offset_s'], 4)} s"))
        return Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts")

    def SectionBoresight(self):
        out = []
        cal = self.stages.get("calibrate")
        bs_file = self.P("boresight.json")
        mount = None
        if os.path.isfile(bs_file):
            try:
                with open(bs_file) as f:
                    mount = json.load(f)
                foreign = self.ForeignRun("boresight.json", mount.get("run_id")
                                          if isinstance(mount, dict) else None)
                if foreign:
                    out.append(NotProduced("boresight.json", foreign))
                    mount = None
            except (OSError, ValueError) as e:
                out.append(NotProduced("boresight.json", f"unreadable: {e}"))
        else:
            out.append(self.Missing("boresight.json"))
        if not isinstance(cal, dict):
            out.append(self.Missing("boresight calibration",
                                    "no calibrate stage in summary.json; the mount was used "
                                    "as configured"))
            if isinstance(mount, dict):
                out.append(Table([[Esc(a), Num(float(mount.get(f"{a}_deg", float("nan"))), 4)]
                                  for a in ("roll", "pitch", "yaw")],
                                 header=["axis", "boresight used (deg)"]))
            return "\n".join(out)
        b0 = cal.get("boresight_before") or {}
        b1 = cal.get("boresight_after") or mount or {}
        sd = cal.get("formal_sd_deg") or [float("nan")] * 3
        # 1 sigma with the INS's own attitude error over the window (older summaries: none).
        sd_all = cal.get("sd_deg") or [float("nan")] * 3

        def At(v, i):
            try:
                return float(v[i])
            except (IndexError, TypeError, ValueError):
                return float("nan")
        rows = []
        for i, axis in enumerate(("roll", "pitch", "yaw")):
            a0 = float(b0.get(f"{axis}_deg", float("nan")))
            a1 = float(b1.get(f"{axis}_deg", float("nan")))
            rows.append([axis, Num(a0, 4), Num(a1, 4), Num(a1 - a0, 4),
                         Num(At(sd, i), 4), Num(At(sd_all, i), 4)])
        out.append(Table(rows, header=["axis", "before (deg)", "after (deg)", "change (deg)",
                                       "formal sd (deg)", "sd with the INS attitude (deg)"]))
        facts = []
        if "residual_before_rms_m" in cal or "residual_after_rms_m" in cal:
            r0 = cal.get("residual_before_rms_m", float("nan"))
            r1 = cal.get("residual_after_rms_m", float("nan"))
            facts.append(("residual RMS", f"{Num(r0, 4)} &rarr; {Num(r1, 4)} m"))
        for k in ("pairs", "iterations", "termination", "height_offsets_rms_m"):
            if k in cal:
                facts.append((k.replace("_", " "), Num(cal[k], 4)))
        seg = cal.get("segment")
        if isinstance(seg, dict) and "start_s" in seg:
            t0 = self.t0 or seg["start_s"]
            facts.append(("calibration segment",
                          f"{(seg['start_s'] - t0) / 60:.2f} to "
                          f"{(seg.get('end_s', 0) - t0) / 60:.2f}"
                          f" min since start ({seg.get('end_s', 0) - seg['start_s']:.0f} s)"))
        if cal.get("message"):
            facts.append(("message", Esc(cal["message"])))
        out.append(Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
        ver = cal.get("verify")
        if isinstance(ver, list) and ver:
            t0 = self.t0 or 0.0
            rows = []
            for v in ver:
                rows.append([f"{(v.get('start_s', 0) - t0) / 60:.2f}&ndash;"
                             f"{(v.get('end_s', 0) - t0) / 60:.2f}",
                             Num(float(v.get("rms_before_m", float("nan"))), 4),
                             Num(float(v.get("rms_after_m", float("nan"))), 4),
                             Num(v.get("pairs", 0))])
            out.append("<h3>Verification segments</h3>")
            out.append(Table(rows, header=["segment (min since start)", "RMS before (m)",
                                           "RMS after (m)", "pairs"]))
        else:
            out.append(NotProduced("verification segments", "calibrate reported none"))
        return "\n".join(out)

    def SectionScores(self):
        if not self.scores:
            return self.Missing(os.path.basename(self.scores_path),
                                "no ground truth given (pitmap-eval --json)")
        rows = [[Esc(k), Num(v, 4) if isinstance(v, (int, float)) else Esc(v),
                 Esc(SCORE_MEANINGS.get(k, ""))] for k, v in self.scores.items()]
        return Table(rows, header=["score", "value", "meaning"])
