# SPDX-License-Identifier: MIT
"""The report's hydrographic section: vertical datum, TPU and the IHO S-44 Ed. 6.1 quality
control of the grid stage (orders, holidays, compliance map, crossline check), and its
backscatter mosaic."""

import math

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .rasters import Limits, RasterMax  # noqa: E402
from .util import Esc, NotProduced, Num, Table  # noqa: E402


class HydroSections:
    """Mixin of report.Report (needs the loaded products of loaders.Products)."""

    def SectionHydro(self):
        """Vertical datum, TPU and IHO S-44 Ed. 6.1 quality control (the grid stage): tables a
        surveyor can hand to a client, a compliance map with the holidays, the crossline check
        by beam angle."""
        g = self.stages.get("grid")
        if not isinstance(g, dict):
            return self.Missing("grid stage", "no grid stage in summary.json (pitmap grid)")
        out = []
        vd = self.summary.get("vertical_datum")
        facts = []
        if isinstance(vd, dict):
            crs = Esc(vd.get("vertical_crs", "?"))
            if vd.get("vertical_epsg"):
                crs += f" (EPSG:{Esc(vd['vertical_epsg'])})"
            facts.append(("vertical datum", crs))
            facts.append(("reduction", Esc(vd.get("description", ""))))
            ws = vd.get("gnss_water_surface")
            if isinstance(ws, dict):
                facts.append(("water surface from GNSS (ellipsoidal)",
                              f"median {Num(ws.get('median_m', float('nan')), 3)} m, range "
                              f"{Num(ws.get('min_m', float('nan')), 3)} to "
                              f"{Num(ws.get('max_m', float('nan')), 3)} m, heave/noise sd "
                              f"{Num(ws.get('raw_sd_mad_m', float('nan')), 3)} m "
                              f"({Num(ws.get('samples', 0))} INS samples)"))
        else:
            facts.append(("vertical datum", "WGS 84 ellipsoidal height"))
        facts.append(("TPU per sounding (95 %)",
                      f"median TVU {Num(g.get('median_tvu_95_m', float('nan')), 3)} m, median "
                      f"THU {Num(g.get('median_thu_95_m', float('nan')), 3)} m; error model "
                      f"{Esc(g.get('error_model', '?'))}"))
        facts.append(("CUBE surface", f"{Num(g.get('resolution_m', float('nan')), 2)} m nodes, "
                      f"{Num(g.get('nodes_filled', 0))} filled (dem.tif, dem.bag)"))
        out.append(Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
        q = g.get("s44")
        if not isinstance(q, dict):
            out.append(self.Missing("S-44 quality control", "s44.enabled is false"))
            return "\n".join(out)
        order = q.get("order", "?")
        met = q.get("strictest_order_met_95")
        out.append(f"<h3>IHO S-44 Edition 6.1: order {Esc(order)}</h3>")
        out.append(f"<p>Strictest order whose TVU and THU 95 % of the soundings meet: "
                   f"<b>{Esc(met) if met else 'none'}</b>. Chosen order for holidays and "
                   f"the crossline check: <b>{Esc(order)}</b>.</p>")
        rows = []
        lim = q.get("limits") or {}
        for o in ("exclusive", "special", "1a", "1b", "2"):
            L = lim.get(o) or {}
            thu = f"{Num(L.get('thu_m', 0), 1)}"
            if L.get("thu_depth_fraction"):
                thu += f" + {Num(100 * L['thu_depth_fraction'], 0)} % d"
            pct = lambda key: Num(100 * float((q.get(key) or {}).get(o, float("nan"))), 1)
            name = f"<b>{Esc(o)}</b>" if o == order else Esc(o)
            rows.append([name, thu, f"{Num(L.get('tvu_a_m', 0), 2)} / {Num(L.get('tvu_b', 0), 4)}",
                         Num(L.get("feature_m", 0), 1) if L.get("feature_m") else "n/a",
                         f"{Num(L.get('coverage_percent', 0), 0)} %",
                         pct("soundings_within_tvu"), pct("soundings_within_thu"),
                         pct("soundings_within_both"), pct("nodes_within_tvu"),
                         pct("nodes_within_thu")])
        out.append(Table(rows, header=["order", "THU (m)", "TVU a (m) / b", "feature (m)",
                                       "coverage", "soundings within TVU (%)",
                                       "within THU (%)", "within both (%)",
                                       "nodes within TVU (%)", "nodes within THU (%)"]))
        out.append(f'<p class="caption">{Num(q.get("soundings", 0))} soundings, '
                   f'{Num(q.get("nodes", 0))} grid nodes. TVU limit sqrt(a&sup2; + (b d)&sup2;), '
                   "d the depth (below the water-level datum, else below the transducer); node "
                   "TVU is the CUBE uncertainty, node THU the mean THU of its soundings.</p>")
        hol = q.get("holidays") or []
        facts = [("coverage of the survey area", f"{Num(100 * q.get('coverage_share', 0), 2)} % "
                  f"({Num(q.get('nodes_in_gaps', 0))} empty nodes in {Num(q.get('gaps', 0))} "
                  "gaps inside it)"),
                 ("holidays", f"<b>{Num(q.get('holiday_count', 0))}</b> (gaps that could hide a "
                  f"{Num(q.get('feature_size_m', 0), 2)} m feature; map s44_holidays.tif)"
                  if q.get("feature_size_m") else
                  f"not applicable to order {Esc(order)} (5 % coverage); "
                  f"{Num(q.get('gaps', 0))} gaps mapped in s44_holidays.tif")]
        out.append(Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"))
        if hol:
            out.append(Table([[str(i + 1), f"{float(h['x_m']):.2f}", f"{float(h['y_m']):.2f}",
                               Num(h.get("area_m2", 0), 2), Num(h.get("largest_square_m", 0), 2)]
                              for i, h in enumerate(hol[:20])],
                             header=["holiday", "UTM easting (m)", "UTM northing (m)",
                                     "area (m&sup2;)", "largest empty square (m)"]))
        out.append(self.HydroMap(q, order))
        cl = q.get("crossline") or {}
        out.append("<h3>Crossline check</h3>")
        bins = cl.get("by_angle") or []
        if not cl.get("compared"):
            out.append("<p>The track does not cross its own earlier lines (no sounding has "
                       "crossing soundings at least 30 s older in its cell).</p>")
            return "\n".join(out)
        out.append(f"<p>{Num(cl['compared'])} soundings compared with the surface of the "
                   f"earlier lines they cross: mean {Num(cl.get('mean_m', 0), 3)} m, sd "
                   f"{Num(cl.get('sd_m', 0), 3)} m, RMS {Num(cl.get('rms_m', 0), 3)} m; "
                   f"{Num(100 * cl.get('within_tvu', 0), 1)} % within the order {Esc(order)} "
                   "TVU limit.</p>")
        out.append(Table([[f"{Num(b['angle_lo_deg'], 0)}&ndash;{Num(b['angle_hi_deg'], 0)}",
                           Num(b["count"]), Num(b["mean_m"], 3), Num(b["sd_m"], 3),
                           Num(b["rms_m"], 3), Num(100 * b["within_tvu"], 1)] for b in bins],
                         header=["|beam angle| (deg)", "soundings", "mean (m)", "sd (m)",
                                 "RMS (m)", "within TVU (%)"]))
        if bins:
            fig, a = plt.subplots(figsize=(8, 3.4), layout="constrained")
            c = [0.5 * (b["angle_lo_deg"] + b["angle_hi_deg"]) for b in bins]
            a.errorbar(c, [b["mean_m"] for b in bins], yerr=[b["sd_m"] for b in bins],
                       fmt="o-", capsize=3, label="mean +- sd")
            a.axhline(0, color="k", lw=0.6)
            a.set_xlabel("|beam angle| (deg)")
            a.set_ylabel("sounding - crossing surface (m)")
            a.grid(alpha=0.3)
            a.legend(fontsize=8)
            out.append(self.Figure(fig, "s44_crossline", "crossline differences by beam angle"))
        return "\n".join(out)

    def HydroMap(self, q, order):
        """Soundings coloured by TVU over the order's limit, holidays outlined."""
        pts = self.points.get("final")
        if pts is None or "tvu_95_m" not in pts.dtype.names:
            return self.Missing("points.ply tvu_95_m", "points.ply without THU/TVU "
                                "(grid.write_point_tpu)")
        lim = (q.get("limits") or {}).get(order) or {}
        step = max(1, len(pts) // 400000)
        x = np.asarray(pts["x"][::step], dtype=np.float64)
        y = np.asarray(pts["y"][::step], dtype=np.float64)
        tvu = np.asarray(pts["tvu_95_m"][::step], dtype=np.float64)
        if "depth_m" in pts.dtype.names:
            d = np.asarray(pts["depth_m"][::step], dtype=np.float64)
        else:
            d = self.ref_z - np.asarray(pts["z"][::step], dtype=np.float64)
        a_m, b = float(lim.get("tvu_a_m", 0.5)), float(lim.get("tvu_b", 0.013))
        ratio = tvu / np.sqrt(a_m ** 2 + (b * np.maximum(d, 0)) ** 2)
        xl = Limits([x], margin=0.02, lo_pct=0.05)
        yl = Limits([y], margin=0.02, lo_pct=0.05)
        cell = max(0.1, max(xl[1] - xl[0], yl[1] - yl[0]) / 400.0)
        nx = max(1, int(math.ceil((xl[1] - xl[0]) / cell)))
        ny = max(1, int(math.ceil((yl[1] - yl[0]) / cell)))
        grid = RasterMax(x, y, ratio, xl[0], yl[0], cell, nx, ny)
        fig, a = plt.subplots(figsize=(11, float(np.clip(9.5 * ny / nx, 3, 13)) + 0.8),
                              layout="constrained")
        im = a.imshow(grid, origin="lower", extent=(xl[0], xl[0] + nx * cell, yl[0],
                      yl[0] + ny * cell), cmap="RdYlGn_r", vmin=0, vmax=1.5,
                      interpolation="nearest")
        for i, h in enumerate((q.get("holidays") or [])[:50]):
            box = h.get("bbox_world_m")
            if not box:
                continue
            bx = [p[0] for p in box] + [box[0][0]]
            by = [p[1] for p in box] + [box[0][1]]
            a.plot(bx, by, color="m", lw=1.5, label="holiday" if i == 0 else None)
            a.annotate(str(i + 1), (h["world_m"][0], h["world_m"][1]), color="m", fontsize=9,
                       ha="center", va="center", weight="bold")
        if q.get("holidays"):
            a.legend(loc="upper right", fontsize=8)
        a.set_xlim(xl)
        a.set_ylim(yl)
        a.set_aspect("equal")
        a.set_xlabel("East x (m, world)")
        a.set_ylabel("North y (m, world)")
        a.set_title(f"largest TVU / order {order} TVU limit per {cell:.2f} m cell "
                    "(> 1: the order is not met)")
        a.grid(alpha=0.25)
        cb = fig.colorbar(im, ax=a, shrink=0.9, pad=0.01)
        cb.set_label("TVU (95 %) / limit")
        return self.Figure(fig, "s44_compliance", "S-44 TVU compliance map with holidays")

    def SectionMosaic(self):
        """The backscatter mosaic of the grid stage (mosaic.tif): corrected and uncorrected side
        by side, with the angular response the correction used (issue 17 item 6)."""
        g = self.stages.get("grid")
        m = g.get("mosaic") if isinstance(g, dict) else None
        if not isinstance(m, dict):
            return self.Missing("mosaic.tif", "no mosaic in the grid stage (mosaic.enabled)")
        if not m.get("made"):
            return NotProduced("mosaic.tif", m.get("reason") or m.get("message") or "")
        try:
            from osgeo import gdal  # python3-gdal: read only here, so the rest needs no GDAL
        except ImportError:
            return self.Missing("mosaic.tif", "python3-gdal is not installed")
        gdal.UseExceptions()
        ds = gdal.Open(self.P("mosaic.tif"))
        foreign = self.ForeignRun("mosaic.tif", ds.GetMetadataItem("pitmap_run_id"))
        if foreign:
            return NotProduced("mosaic.tif", foreign)
        gt = ds.GetGeoTransform()
        bands = {ds.GetRasterBand(b).GetDescription(): ds.GetRasterBand(b).ReadAsArray()
                 for b in range(1, ds.RasterCount + 1)}
        ext = (gt[0], gt[0] + gt[1] * ds.RasterXSize, gt[3] + gt[5] * ds.RasterYSize, gt[3])
        fig, axes = plt.subplots(1, 3, figsize=(15, 5.2), layout="constrained",
                                 gridspec_kw={"width_ratios": [1, 1, 0.8]})
        for a, name, title in ((axes[0], "backscatter", "corrected (range, incidence)"),
                               (axes[1], "uncorrected", "uncorrected: 20 log10(intensity)")):
            v = np.asarray(bands.get(name), dtype=np.float64)
            ok = v[np.isfinite(v)]
            lo, hi = np.percentile(ok, [2, 98]) if len(ok) else (0, 1)
            im = a.imshow(v, extent=ext, cmap="gray", vmin=lo, vmax=hi, interpolation="nearest")
            a.set_title(title, fontsize=10)
            a.set_xlabel("UTM easting (m)")
            a.set_aspect("equal")
            a.ticklabel_format(useOffset=False, style="plain")
            a.tick_params(labelsize=7)
            fig.colorbar(im, ax=a, shrink=0.8, pad=0.01).set_label("dB (relative)")
        axes[0].set_ylabel("UTM northing (m)")
        curve = np.asarray(m.get("angular_response_deg_db_count") or [[0, 0, 0]], dtype=float)
        axes[2].plot(curve[:, 0], curve[:, 1], "o-", ms=2)
        axes[2].set_xlabel("incidence (deg)")
        axes[2].set_ylabel("angular response removed (dB, 0 at the reference)")
        axes[2].set_title(f"{m.get('angular', '?')} angular response", fontsize=10)
        axes[2].grid(alpha=0.3)
        facts = [("soundings used", f"{Num(m.get('used', 0))} of {Num(m.get('soundings', 0))} "
                  f"(no intensity {Num(m.get('no_intensity', 0))}, saturated "
                  f"{Num(m.get('saturated', 0))}, incidence beyond the limit "
                  f"{Num(m.get('beyond_incidence', 0))})"),
                 ("range correction", f"{Num(m.get('spreading_db_per_decade', 0), 1)} log10(R) + "
                  f"2 &times; {Num(m.get('absorption_db_per_m', 0), 4)} dB/m &times; R"),
                 ("incidence correction", f"{Esc(m.get('angular', '?'))}, referenced to "
                  f"{Num(m.get('reference_angle_deg', 0), 0)} deg (incidence from the DEM's "
                  f"slopes; median {Num(m.get('median_incidence_deg', 0), 1)} deg)"),
                 ("corrected, 5-95 %", f"{Num(m.get('corrected_p05_db', 0), 1)} to "
                  f"{Num(m.get('corrected_p95_db', 0), 1)} dB on {Num(m.get('nodes_filled', 0))} "
                  "nodes (mosaic.tif: backscatter, uncorrected, count)")]
        return "\n".join([Table([(f"<b>{k}</b>", v) for k, v in facts], cls="facts"),
                          self.Figure(fig, "mosaic", "backscatter mosaic")])
