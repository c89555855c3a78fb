# SPDX-License-Identifier: MIT
"""The report's section on the rejected soundings (issue 35): the rejections by reason
(summary.json "soundings"), where the rejected soundings lie (points.ply's status) and the
runs of pings with the most of them."""

import math

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .rasters import limits  # noqa: E402
from .util import esc, gps_to_utc, num, table  # noqa: E402

# survey::SoundingStatus (processor/survey/sounding_status.hpp): codes are stored, never
# renumbered.
STATUS_NAMES = ("accepted", "no_detection", "range_gate", "spike", "refraction",
                "surface_filter", "free_space", "multipath", "cluster", "manual",
                "profile")

# A ping belongs to a run when at least this share of its soundings in points.ply is rejected.
RUN_MIN_REJECTED_SHARE = 0.1


def status_name(code):
    code = int(code)
    return STATUS_NAMES[code] if 0 <= code < len(STATUS_NAMES) else f"code {code}"


def ping_runs(ping, rejected, min_share=RUN_MIN_REJECTED_SHARE):
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


def sounding_counts(p):
    """The soundings kept and rejected, by reason (summary.json "soundings"); None when the
    products have no counts."""
    snd = p.summary.get("soundings")
    if not isinstance(snd, dict):
        return None
    total = snd.get("total", 0)
    reasons = snd.get("rejected") if isinstance(snd.get("rejected"), dict) else {}
    n_rej = sum(v for v in reasons.values() if isinstance(v, (int, float)))
    share = (lambda n: f"{num(100.0 * n / total, 2)} %") if total else (lambda n: "")
    rows = [["<b>accepted</b>", num(snd.get("accepted", 0)), share(snd.get("accepted", 0))]]
    for name, n in sorted(reasons.items(), key=lambda kv: -kv[1]):
        if n:
            rows.append([esc(name), num(n), share(n)])
    rows.append(["<b>rejected</b>", num(n_rej), share(n_rej)])
    rows.append(["<b>total</b>", num(total), ""])
    out = [table(rows, header=["status", "soundings", "share"]),
           "<p>Every sounding of the georeferenced pings, accepted or rejected with "
           "its reason. points.ply and points.las hold the rejected soundings that "
           "have a position (all but no detection and refraction) after the "
           "accepted ones, with their status.</p>"]
    note = pings_left_out(snd)
    if note:
        out.append(note)
    return "\n".join(out)


def pings_left_out(snd):
    """A sentence on the pings georef could not place (summary.json soundings.pings), their
    beams not among the soundings above; "" when every ping was placed or the products predate
    the counts."""
    pings = snd.get("pings")
    if not isinstance(pings, dict):
        return ""
    left = pings.get("left_out") if isinstance(pings.get("left_out"), dict) else {}
    why = {"outside_nav": "outside the navigation's time span", "nav_gap": "in a navigation gap",
           "bad_header": "with a header that cannot be used"}
    parts = [f"{num(n)} {why.get(k, esc(str(k)))}" for k, n in sorted(left.items())
             if isinstance(n, (int, float)) and n > 0]
    if not parts:
        return ""
    beams = snd.get("not_placed", 0)
    return (f"<p><b>Pings not placed:</b> {', '.join(parts)} (of {num(pings.get('in', 0))}); "
            f"their {num(beams)} beams are not in the products.</p>")


def rejections(p):
    """Engineering: the rejected soundings by reason, a plan view of where they lie and the
    ten runs of pings with the most."""
    counts = sounding_counts(p)
    rej = p.rejected.get("final")
    if counts is None and rej is None:
        return p.missing_product("soundings", "summary.json has no soundings counts and "
                                 "points.ply no rejected soundings")
    out = [counts] if counts else []
    if rej is None or len(rej) == 0:
        out.append(p.missing_product("rejected soundings in points.ply",
                                     "none rejected, or products.write_rejected is false"))
        return "\n".join(out)
    out.append(rejection_map(p, rej))
    out.append(worst_ping_runs(p, rej))
    return "\n".join(out)


def rejection_map(p, rej):
    """Plan view: the accepted soundings in grey, the rejected coloured by reason."""
    acc = p.points.get("final")
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
                  rasterized=True, label=f"{status_name(code)} ({num(int(m.sum()) * step)})")
    xl = limits([x for x, _ in xs], margin=0.02, lo_pct=0.05)
    yl = limits([y for _, y in xs], margin=0.02, lo_pct=0.05)
    a.set_xlim(xl)
    a.set_ylim(yl)
    a.set_aspect("equal")
    a.set_xlabel("east (m)")
    a.set_ylabel("north (m)")
    a.legend(loc="upper right", fontsize=8, markerscale=6)
    a.grid(alpha=0.3)
    return (p.figure(fig, "rejections_map", "where the rejected soundings lie") +
            "<p>Plan view of the rejected soundings by reason over the accepted ones "
            "(grey).</p>")


def worst_ping_runs(p, rej):
    """The ten runs of consecutive pings with the most rejected soundings."""
    acc = p.points.get("final")
    if "ping" not in rej.dtype.names or acc is None or "ping" not in acc.dtype.names:
        return p.missing_product("worst ping runs", "points.ply has no ping property")
    ping = np.concatenate([np.asarray(acc["ping"], dtype=np.int64),
                           np.asarray(rej["ping"], dtype=np.int64)])
    flag = np.concatenate([np.zeros(len(acc), bool), np.ones(len(rej), bool)])
    runs = ping_runs(ping, flag)[:10]
    if not runs:
        return "<p>No ping has 10 % or more of its soundings rejected.</p>"
    rp = np.asarray(rej["ping"], dtype=np.int64)
    rs = np.asarray(rej["status"])
    have_t = "gps_time_s" in rej.dtype.names
    rt = np.asarray(rej["gps_time_s"], dtype=np.float64) if have_t else None
    tm = p.summary.get("time") if isinstance(p.summary.get("time"), dict) else {}
    leap = tm.get("gps_minus_utc_s")
    rows = []
    for first, last, n in runs:
        m = (rp >= first) & (rp <= last)
        codes, counts = np.unique(rs[m], return_counts=True)
        main = ", ".join(f"{status_name(c)} {num(int(k))}" for c, k in
                         sorted(zip(codes, counts), key=lambda ck: -ck[1])[:3])
        when = ""
        if have_t and m.any():
            t = float(rt[m].min())
            when = f"{num(float(p.minutes_of(t)), 2)} min"
            if isinstance(leap, (int, float)) and math.isfinite(t):
                when = gps_to_utc(t, leap).strftime("%H:%M:%S UTC") + f" ({when})"
        rows.append([when, f"{first}&ndash;{last}", num(last - first + 1), num(n),
                     esc(main)])
    return (table(rows, header=["start", "pings", "pings in run", "rejected",
                                "main reasons"]) +
            f"<p>Runs of consecutive pings in which {num(100 * RUN_MIN_REJECTED_SHARE, 0)} "
            "% or more of the soundings in points.ply are rejected, the ten with the most "
            "rejected soundings (ping: the index in points.ply; time since the first "
            "ping).</p>")
