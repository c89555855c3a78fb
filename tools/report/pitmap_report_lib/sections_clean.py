# SPDX-License-Identifier: MIT
"""The report's section on the rejected soundings (issue 35): the rejections by reason
(summary.json "soundings"), where the rejected soundings lie (points.ply's status) and the
runs of pings with the most of them."""

import math

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .rasters import Limits  # noqa: E402
from .util import Esc, GpsToUtc, Num, Table  # noqa: E402

# georef::SoundingStatus (processor/georef/sounding_status.hpp): codes are stored, never
# renumbered.
STATUS_NAMES = ("accepted", "no_detection", "range_gate", "spike", "refraction",
                "surface_filter", "free_space", "multipath", "cluster", "manual",
                "profile")

# A ping belongs to a run when at least this share of its soundings in points.ply is rejected.
RUN_MIN_REJECTED_SHARE = 0.1


def StatusName(code):
    code = int(code)
    return STATUS_NAMES[code] if 0 <= code < len(STATUS_NAMES) else f"code {code}"


def PingRuns(ping, rejected, min_share=RUN_MIN_REJECTED_SHARE):
    """Runs of consecutive pings (by points.ply's ping index) in which at least `min_share` of
    the soundings are rejected. `ping`: the ping index of every sounding; `rejected`: whether it
    is. Returns [(first_ping, last_ping, rejected_count)], most rejected first (ties: earlier
    first)."""
    ping = np.asarray(ping, dtype=np.int64)
    rejected = np.asarray(rejected, dtype=bool)
    if ping.size == 0:
        return []
    pings, inverse = np.unique(ping, return_inverse=True)
    total = np.bincount(inverse, minlength=len(pings))
    bad = np.bincount(inverse, weights=rejected, minlength=len(pings)).astype(np.int64)
    hot = (bad > 0) & (bad >= min_share * total)
    runs = []
    i = 0
    while i < len(pings):
        if not hot[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(pings) and hot[j + 1] and pings[j + 1] == pings[j] + 1:
            j += 1
        runs.append((int(pings[i]), int(pings[j]), int(bad[i:j + 1].sum())))
        i = j + 1
    runs.sort(key=lambda r: (-r[2], r[0]))
    return runs


class CleanSections:
    """Mixin of report.Report (needs the loaded products of loaders.Products)."""

    def SectionRejections(self):
        """Rejected soundings: a table by reason, a plan view of where they lie and the ten
        runs of pings with the most."""
        snd = self.summary.get("soundings")
        rej = self.rejected.get("final")
        if not isinstance(snd, dict) and rej is None:
            return self.Missing("soundings", "summary.json has no soundings counts and "
                                "points.ply no rejected soundings")
        out = []
        if isinstance(snd, dict):
            total = snd.get("total", 0)
            reasons = snd.get("rejected") if isinstance(snd.get("rejected"), dict) else {}
            n_rej = sum(v for v in reasons.values() if isinstance(v, (int, float)))
            share = (lambda n: f"{Num(100.0 * n / total, 2)} %") if total else (lambda n: "")
            rows = [["<b>accepted</b>", Num(snd.get("accepted", 0)),
                     share(snd.get("accepted", 0))]]
            for name, n in sorted(reasons.items(), key=lambda kv: -kv[1]):
                if n:
                    rows.append([Esc(name), Num(n), share(n)])
            rows.append(["<b>rejected</b>", Num(n_rej), share(n_rej)])
            rows.append(["<b>total</b>", Num(total), ""])
            out.append(Table(rows, header=["status", "soundings", "share"]))
            out.append("<p>Every sounding of the georeferenced pings, accepted or rejected with "
                       "its reason (summary.json <code>soundings</code>). points.ply and "
                       "points.las hold the rejected soundings that have a position (all but "
                       "no detection and refraction) after the accepted ones.</p>")
        if rej is None or len(rej) == 0:
            out.append(self.Missing("rejected soundings in points.ply",
                                    "none rejected, or products.write_rejected is false"))
            return "\n".join(out)
        out.append(self.RejectionMap(rej))
        out.append(self.WorstPingRuns(rej))
        return "\n".join(out)

    def RejectionMap(self, rej):
        """Plan view: the accepted soundings in grey, the rejected coloured by reason."""
        acc = self.points.get("final")
        fig, a = plt.subplots(figsize=(11, 8), layout="constrained")
        xs = []
        if acc is not None and len(acc):
            step = max(1, len(acc) // 200000)
            ax = np.asarray(acc["x"][::step], dtype=np.float64)
            ay = np.asarray(acc["y"][::step], dtype=np.float64)
            a.scatter(ax, ay, s=0.2, c="0.8", linewidths=0, rasterized=True, label="accepted")
            xs.append((ax, ay))
        status = np.asarray(rej["status"])
        step = max(1, len(rej) // 200000)
        rx = np.asarray(rej["x"][::step], dtype=np.float64)
        ry = np.asarray(rej["y"][::step], dtype=np.float64)
        rs = status[::step]
        xs.append((rx, ry))
        cmap = plt.get_cmap("tab10")
        for code in np.unique(rs):
            m = rs == code
            a.scatter(rx[m], ry[m], s=1.5, color=cmap(int(code) % 10), linewidths=0,
                      rasterized=True, label=f"{StatusName(code)} ({Num(int(m.sum()) * step)})")
        xl = Limits([x for x, _ in xs], margin=0.02, lo_pct=0.05)
        yl = Limits([y for _, y in xs], margin=0.02, lo_pct=0.05)
        a.set_xlim(xl)
        a.set_ylim(yl)
        a.set_aspect("equal")
        a.set_xlabel("east (m)")
        a.set_ylabel("north (m)")
        a.legend(loc="upper right", fontsize=8, markerscale=6)
        a.grid(alpha=0.3)
        return (self.Figure(fig, "rejections_map", "where the rejected soundings lie") +
                "<p>Plan view of the rejected soundings by reason over the accepted ones "
                "(grey).</p>")

    def WorstPingRuns(self, rej):
        """The ten runs of consecutive pings with the most rejected soundings."""
        acc = self.points.get("final")
        if "ping" not in rej.dtype.names or acc is None or "ping" not in acc.dtype.names:
            return self.Missing("worst ping runs", "points.ply has no ping property")
        ping = np.concatenate([np.asarray(acc["ping"], dtype=np.int64),
                               np.asarray(rej["ping"], dtype=np.int64)])
        flag = np.concatenate([np.zeros(len(acc), bool), np.ones(len(rej), bool)])
        runs = PingRuns(ping, flag)[:10]
        if not runs:
            return "<p>No ping has 10 % or more of its soundings rejected.</p>"
        rp = np.asarray(rej["ping"], dtype=np.int64)
        rs = np.asarray(rej["status"])
        have_t = "gps_time_s" in rej.dtype.names
        rt = np.asarray(rej["gps_time_s"], dtype=np.float64) if have_t else None
        tm = self.summary.get("time") if isinstance(self.summary.get("time"), dict) else {}
        leap = tm.get("gps_minus_utc_s")
        rows = []
        for first, last, n in runs:
            m = (rp >= first) & (rp <= last)
            codes, counts = np.unique(rs[m], return_counts=True)
            main = ", ".join(f"{StatusName(c)} {Num(int(k))}" for c, k in
                             sorted(zip(codes, counts), key=lambda ck: -ck[1])[:3])
            when = ""
            if have_t and m.any():
                t = float(rt[m].min())
                when = f"{Num(float(self.MinutesOf(t)), 2)} min"
                if isinstance(leap, (int, float)) and math.isfinite(t):
                    when = GpsToUtc(t, leap).strftime("%H:%M:%S UTC") + f" ({when})"
            rows.append([when, f"{first}&ndash;{last}", Num(last - first + 1), Num(n),
                         Esc(main)])
        return (Table(rows, header=["start", "pings", "pings in run", "rejected",
                                    "main reasons"]) +
                f"<p>Runs of consecutive pings in which {Num(100 * RUN_MIN_REJECTED_SHARE, 0)} "
                "% or more of the soundings in points.ply are rejected, the ten with the most "
                "rejected soundings (ping: the index in points.ply; time since the first "
                "ping).</p>")
