# SPDX-License-Identifier: MIT
"""The report's processing statistics: the TSDF weight histogram, SLAM per iteration, and time
and memory per stage."""

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
from matplotlib.ticker import EngFormatter, LogLocator, MaxNLocator  # noqa: E402

from .util import esc, num, table  # noqa: E402

# Stage order of `pitmap run`; summary.json may give its own in "stage_order".
PIPELINE_STAGES = ["ingest", "georef", "calibrate", "slam", "fuse", "mesh", "export", "report"]


def tsdf(p):
    fuse = p.stages.get("fuse")
    if not isinstance(fuse, dict):
        return p.missing_product("TSDF fusion statistics", "no fuse stage in summary.json")
    out = []

    def histogram_of(stage):
        h = stage.get("weight_histogram") if isinstance(stage, dict) else None
        if isinstance(h, dict) and len(h.get("counts", [])) and \
                len(h.get("edges", [])) == len(h["counts"]) + 1:
            return (np.asarray(h["edges"], dtype=np.float64),
                    np.asarray(h["counts"], dtype=np.float64), bool(h.get("before_filter")))
        return None

    h = histogram_of(fuse)
    h0 = histogram_of(p.stages.get("fuse_initial"))
    if h is not None:
        edges, counts, before_filter = h
        fig, a = plt.subplots(figsize=(12, 4.2), layout="constrained")
        a.bar(edges[:-1], np.where(counts > 0, counts, np.nan), width=np.diff(edges),
              align="edge", color="tab:blue", edgecolor="white", linewidth=0.5,
              label=f"{p.after} (fuse)")
        if h0 is not None:
            a.stairs(np.where(h0[1] > 0, h0[1], np.nan), h0[0], color="k", ls="--", lw=1.2,
                     label="before SLAM (fuse_initial)")
        a.set_yscale("log")
        a.set_ylim(bottom=0.8)  # counts are whole: no "500 m" (milli-voxel) tick below 1
        # 1-2-5 steps with k/M labels: a histogram spanning one decade still gets labels.
        a.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        a.yaxis.set_major_formatter(EngFormatter(sep=" "))
        a.set_xlabel("voxel weight (measurements: rays, or the beams of each footprint; "
                     "capped at w_max)")
        a.set_ylabel("active voxels")
        a.xaxis.set_major_locator(MaxNLocator(integer=True))
        a.grid(alpha=0.3, which="both", axis="y")
        mw = fuse.get("min_weight")
        if isinstance(mw, (int, float)):
            a.axvline(float(mw), color="tab:red", ls="--", label=f"filter min weight {mw:g}")
        a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9)
        when = " (before the weight filter)" if before_filter else ""
        a.set_title("TSDF weight histogram" + when)
        out.append(p.figure(fig, "tsdf_weights", "TSDF weight histogram"))
        out.append('<p class="caption">How often each voxel was observed. Voxels under the '
                   "filter weight are dropped before meshing (outlier surfaces); the last "
                   "bin holds the voxels at the weight cap.</p>")
    else:
        out.append(p.missing_product("TSDF weight histogram",
                                     "no stages.fuse.weight_histogram {edges, counts}"))
    facts = [(k.replace("_", " "), num(v, 4)) for k, v in fuse.items()
             if isinstance(v, (int, float, str, bool)) and k not in ("seconds", "peak_rss_mb")]
    for k, v in fuse.items():
        if isinstance(v, dict) and k != "weight_histogram":
            facts += [(f"{k} {kk}".replace("_", " "), num(vv, 4)) for kk, vv in v.items()
                      if isinstance(vv, (int, float, str, bool))]
    if facts:
        out.append(table([(f"<b>{esc(k)}</b>", v) for k, v in facts], cls="facts"))
    return "\n".join(out)


def slam(p):
    rec = p.stages.get("slam")
    if not isinstance(rec, dict):
        return p.missing_product("SLAM statistics", "no slam stage in summary.json")
    out = []
    its = [i for i in rec.get("iterations") or [] if isinstance(i, dict)]
    if its:
        stages = [str(i.get("stage", "?")) for i in its]
        xs = np.arange(1, len(its) + 1)
        fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
        keys = [("pair_rms_m", "pair RMS distance (m)", False),
                ("cost", "cost (sum of squared whitened residuals)", True),
                ("consistency_m", "consistency score (m, lower is better)", False)]
        colours = {"rigid": "tab:blue", "semi_rigid": "tab:orange"}
        for a, (k, label, logy) in zip(ax, keys):
            vals = np.array([float(i.get(k, np.nan)) for i in its])
            for st in dict.fromkeys(stages):
                m = np.array([s == st for s in stages])
                a.plot(xs[m], vals[m], "o-", ms=4, color=colours.get(st, "tab:green"),
                       label=st.replace("_", "-"))
            best = np.array([bool(i.get("best", False)) for i in its])
            if best.any():
                a.plot(xs[best], vals[best], "o", ms=9, mfc="none", mec="k",
                       label="best so far")
            if logy and np.all(vals[np.isfinite(vals)] > 0):
                a.set_yscale("log")
            a.set_xlabel("iteration (rigid, then semi-rigid)")
            a.xaxis.set_major_locator(MaxNLocator(integer=True))
            a.set_ylabel(label)
            a.grid(alpha=0.3)
        ax[0].legend(fontsize=8)
        fig.suptitle("SLAM per iteration")
        fig.tight_layout()
        out.append(p.figure(fig, "slam_iterations", "SLAM per-iteration trend"))
    else:
        out.append(p.missing_product("SLAM iterations", "no stages.slam.iterations"))
    facts = []
    if "initial_consistency_m" in rec or "final_consistency_m" in rec:
        c0 = rec.get("initial_consistency_m", float("nan"))
        c1 = rec.get("final_consistency_m", float("nan"))
        facts.append(("consistency", f"{num(c0, 4)} &rarr; {num(c1, 4)} m"))
    facts += [(k.replace("_", " "), num(v, 4)) for k, v in rec.items()
              if isinstance(v, (int, float, str, bool)) and k not in
              ("seconds", "peak_rss_mb", "initial_consistency_m", "final_consistency_m")]
    if facts:
        out.append(table([(f"<b>{esc(k)}</b>", v) for k, v in facts], cls="facts"))
    return "\n".join(out)


def stage_order(p):
    order = p.summary.get("stage_order")
    if isinstance(order, list) and order:
        names = [str(n) for n in order if n in p.stages]
    else:
        names = [n for n in PIPELINE_STAGES if n in p.stages]
    return names + [n for n in p.stages if n not in names]


def stages(p):
    names = stage_order(p)
    if not names:
        return p.missing_product("stage statistics", "summary.json has no stages")
    rows = []
    secs, mems = [], []
    for n in names:
        st = p.stages.get(n) or {}
        s = st.get("seconds")
        m = st.get("peak_rss_mb")
        secs.append(float(s) if isinstance(s, (int, float)) else 0.0)
        mems.append(float(m) if isinstance(m, (int, float)) else float("nan"))
        counts = [f"{esc(k.replace('_', ' '))} {num(v, 4)}" for k, v in st.items()
                  if isinstance(v, (int, float, bool)) and not isinstance(v, bool)
                  and k not in ("seconds", "peak_rss_mb")]
        rows.append([f"<b>{esc(n)}</b>", num(s, 2) if s is not None else "&ndash;",
                     num(m, 0) if m is not None else "&ndash;",
                     '<span class="counts">' + ", ".join(counts) + "</span>"])
    total = p.summary.get("total_seconds")
    rows.append(["<b>total</b>", num(total, 2) if total is not None else num(sum(secs), 2),
                 num(float(np.nanmax(mems)), 0) if np.isfinite(mems).any() else "&ndash;",
                 "peak memory is the largest of the stages"])
    out = [table(rows, header=["stage", "seconds", "peak RSS (MB)", "counts"], cls="stages")]
    fig, ax = plt.subplots(1, 2, figsize=(13, 0.45 * len(names) + 1.4))
    yy = np.arange(len(names))[::-1]
    ax[0].barh(yy, secs, color="tab:blue")
    ax[0].set_xlabel("seconds")
    ax[1].barh(yy, np.nan_to_num(mems), color="tab:purple")
    ax[1].set_xlabel("peak RSS (MB)")
    for a in ax:
        a.set_yticks(yy, names)
        a.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    out.append(p.figure(fig, "stages", "time and memory per stage"))
    return "\n".join(out)
