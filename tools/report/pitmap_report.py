#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pitmap-report: a self-contained HTML report of a products folder.

Usage: pitmap-report P [--scores FILE] [--title TEXT]
       pitmap-report --view-gltf FILE.glb [-o PAGE.html] [--title TEXT]

Reads what `pitmap run --out P` wrote (summary.json, trajectory[_initial].csv or, without
SLAM, trajectory_ins.csv,
points[_initial].ply, mesh[_initial].ply, boresight.json, optional scores.json from
pitmap-eval --json) and writes P/report.html with the plots embedded as PNG data URIs
(no external resource), and the same PNGs under P/report/. The figures follow the seed
paper: trajectory before/after SLAM and point-cloud cross-sections (Fig. 3), a
depth-coloured top view and mesh renders before/after SLAM (Fig. 4).

Frames: products are in the local world frame (East, North, Up metres at the summary's
world_origin); gps_time_s counts seconds since 1980-01-06 on the GPS time scale.

--view-gltf writes a self-contained page with the report's 3D viewer and FILE.glb embedded
(base64, read by three.js's GLTFLoader): pitmap's mesh.glb or any self-contained glTF 2.0
binary. Default page: FILE.html beside it. A file that is not a glTF binary (12-byte header:
magic "glTF", version 2, length = the file's size; then a JSON chunk) is refused.

Exit 0 when the report was written (every missing optional product is named in it as
"not produced: ..."); 1 when P is not a usable products folder (no readable
summary.json) or the report cannot be written, or (--view-gltf) the file is not a usable glTF
binary or the page cannot be written; 2 on bad arguments.

Runs with Debian's python3, python3-numpy and python3-matplotlib (Agg backend). The work is
done by the package pitmap_report_lib beside this script (see its __init__.py); PLY products
are read through pitmap-ply-layout, also beside it (the project's C++ PLY reader, built with
the pitmap-report target), so run the copy in the build's bin folder. Large products stay
cheap: PLY records are memory-mapped through numpy structured dtypes and plots use rasters or
subsamples, never every point.
"""

import argparse
import os
import sys

# The package beside this script (tools/report in the source tree; build/bin when built).
sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))

# Ply, PlyError, GpsToUtc, the rasters and the glb check are also what report_test.py checks
# through this module.
from pitmap_report_lib.gltf import CheckGlb, GlbError, GltfPage  # noqa: E402,F401
from pitmap_report_lib.loaders import Ply, PlyError  # noqa: E402,F401
from pitmap_report_lib.rasters import RasteriseMesh, RasterMax, RasterMean  # noqa: E402,F401
from pitmap_report_lib.report import Report  # noqa: E402
from pitmap_report_lib.util import (  # noqa: E402,F401
    PROG, DieWithParent, GpsToUtc, Log, ReportError)


def main(argv=None):
    # Ends with whatever started it (pitmap run, a shell), and on SIGTERM; its section workers
    # likewise end with it (Report.Build).
    DieWithParent()
    ap = argparse.ArgumentParser(prog=PROG, description="Write P/report.html (self-contained, "
                                 "PNG plots embedded) and P/report/*.png from a pitmap products "
                                 "folder P.")
    ap.add_argument("products", metavar="P", nargs="?",
                    help="products folder (pitmap run --out P)")
    ap.add_argument("--scores", metavar="FILE",
                    help="scores JSON from pitmap-eval --json (default: P/scores.json)")
    ap.add_argument("--title", metavar="TEXT", help="report (or page) title")
    ap.add_argument("-j", "--jobs", metavar="N", type=int, default=None,
                    help="sections drawn by N processes at once (default: the CPUs this "
                    "process may run on, at most 4; 1 draws them one after the other)")
    ap.add_argument("--view-gltf", metavar="GLB",
                    help="instead of a report: a self-contained page showing GLB (glTF 2.0 "
                    "binary, e.g. P/mesh.glb) in the report's 3D viewer")
    ap.add_argument("-o", "--output", metavar="HTML",
                    help="the page of --view-gltf (default: GLB with .html)")
    args = ap.parse_args(argv)
    if args.view_gltf is not None:
        if args.products is not None or args.scores is not None:
            ap.error("--view-gltf takes no products folder and no --scores")
        return ViewGltf(args.view_gltf, args.output, args.title)
    if args.products is None:
        ap.error("give a products folder P (or --view-gltf GLB)")
    if args.output is not None:
        ap.error("-o/--output goes with --view-gltf (the report is always P/report.html)")
    if args.jobs is not None and args.jobs < 1:
        ap.error("--jobs must be at least 1")
    jobs = args.jobs if args.jobs is not None else min(4, len(os.sched_getaffinity(0)))
    folder = os.path.abspath(args.products)
    if not os.path.isdir(folder):
        print(f"{PROG}: {args.products}: not a folder", file=sys.stderr)
        return 1
    title = args.title or f"pitmap survey report: {os.path.basename(folder)}"
    scores = args.scores or os.path.join(folder, "scores.json")
    try:
        report = Report(folder, scores, title)
        page = report.Build(jobs)
    except ReportError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    out = os.path.join(folder, "report.html")
    try:
        WriteAtomically(out, page)
    except OSError as e:
        print(f"{PROG}: {out}: cannot write: {e}", file=sys.stderr)
        return 1
    Log(f"wrote {out} ({os.path.getsize(out) // 1024} kB)"
        + (f"; not produced: {', '.join(report.missing)}" if report.missing else "")
        + (f"; {len(report.problems)} problem(s)" if report.problems else ""))
    return 0


def WriteAtomically(out, page):
    tmp = out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(page)
    os.replace(tmp, out)


def ViewGltf(glb, output, title):
    out = output or os.path.splitext(glb)[0] + ".html"
    try:
        page = GltfPage(glb, title)
    except GlbError as e:
        print(f"{PROG}: {glb}: {e}", file=sys.stderr)
        return 1
    except OSError as e:  # unreadable file, missing viewer scripts
        print(f"{PROG}: {glb}: {e}", file=sys.stderr)
        return 1
    try:
        WriteAtomically(out, page)
    except OSError as e:
        print(f"{PROG}: {out}: cannot write: {e}", file=sys.stderr)
        return 1
    Log(f"wrote {out} ({os.path.getsize(out) // 1024} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
