# SPDX-License-Identifier: MIT
"""The report's hydrographic section: vertical datum, TPU and the IHO S-44 Ed. 6.1 quality
control of the grid stage (orders, holidays, compliance map, crossline check)."""

import math

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .rasters import Limits, RasterMax  # noqa: E402
from .util import Esc, Num, Table  # noqa: E402


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
