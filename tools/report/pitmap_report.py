#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pitmap-report: the report of a products folder, as self-contained HTML pages.

Usage: pitmap-report P [--scores FILE] [--title TEXT] [--jobs N] [--pdf]
       pitmap-report --compare C [--epochs A B] [--title TEXT] [--pdf]
       pitmap-report --view-gltf FILE.glb [-o PAGE.html] [--title TEXT]

Reads what `pitmap run --out P` wrote (summary.json with the survey's metadata, dem.tif,
s44_holidays.tif, mosaic.tif, trajectory[_initial].csv or, without SLAM, trajectory_ins.csv,
points[_initial].ply, mesh[_initial].ply, boresight.json, optional scores.json from
pitmap-eval --json) and writes two pages with the plots embedded as PNG data URIs (no external
resource), and the same PNGs under P/report/:

  P/report.html              the client's report: cover (metadata), summary (the IHO S-44
                             compliance statement in words, coverage, key figures, datums and
                             units, caveats), datums with the water level and the sound-speed
                             casts applied, maps in the projected CRS (grid coordinates, scale
                             bar, north arrow), S-44 quality control, soundings kept, the
                             backscatter mosaic, the 3D view, scores only when a truth is given.
                             No path of this machine: inputs by file name.
  P/report_engineering.html  the processing details: trajectories and point-cloud sections
                             before/after SLAM (the seed paper's Figs. 3 and 4) in local metres,
                             rejections, meshes, boresight, sonar clock, TSDF weights, SLAM per
                             iteration, stage times and memory.
  P/report.pdf               with --pdf: report.html printed by headless Chromium (A4).

The title is the metadata's project, site and survey id (--title replaces it).

--compare C writes the change report of `pitmap compare A B --out C` instead: C/report.html
(and C/report/*.png; C/report.pdf with --pdf): the two surveys, a summary, the map of
significant change over A's hill-shade, the volume table with its 95 % uncertainty, two
cross-sections of both surveys through the largest change (depth grids and soundings), the
co-registration, the change along the normal, both capacity curves, B's slope and crawler maps
and the quality gates. Every figure is compare.json's; A and B are the folders compare.json
names (--epochs A B when they have moved). A compare.json that is missing or damaged, or A or
B not found or processed again since the comparison, is an error (exit 1).

--view-gltf writes a self-contained page with the report's 3D viewer and FILE.glb embedded
(base64, read by three.js's GLTFLoader): pitmap's mesh.glb or any self-contained glTF 2.0
binary. Default page: FILE.html beside it. A file that is not a glTF binary (12-byte header:
magic "glTF", version 2, length = the file's size; then a JSON chunk) is refused.

Exit 0 when the pages were written (every missing optional product is named on the
engineering page as "not produced: ..."); 1 when P is not a usable products folder (no
readable summary.json), a page cannot be written or --pdf fails, or (--view-gltf) the file is
not a usable glTF binary or the page cannot be written; 2 on bad arguments.

Runs with Debian's python3, python3-numpy, python3-matplotlib (Agg backend) and python3-gdal
(the maps); --pdf needs chromium. The work is done by the package pitmap_report_lib beside
this script (see its __init__.py); PLY products are read through pitmap-ply-layout, also
beside it (the project's C++ PLY reader, built with the pitmap-report target), so run the
copy in the build's bin folder. Large products stay cheap: PLY records are memory-mapped
through numpy structured dtypes and plots use rasters or subsamples, never every point.
"""

import argparse
import difflib
import os
import subprocess
import sys

# The package beside this script (tools/report in the source tree; build/bin when built).
sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))

# Ply, PlyError, gps_to_utc, the rasters and the glb check are also what report_test.py
# checks through this module.
from pitmap_report_lib.equipment import (  # noqa: E402
    EquipmentError, place_equipment, read_equipment)
from pitmap_report_lib.gltf import GlbError, check_glb, gltf_page  # noqa: E402,F401
from pitmap_report_lib.loaders import Ply, PlyError, Products  # noqa: E402,F401
from pitmap_report_lib.rasters import raster_max, raster_mean, rasterise_mesh  # noqa: E402,F401
from pitmap_report_lib import (  # noqa: E402,F401
    maps, report, sections_change, sections_client, util)
from pitmap_report_lib.change import CompareFolder  # noqa: E402
from pitmap_report_lib.util import (  # noqa: E402,F401
    PROG, ReportError, die_with_parent, gps_to_utc, log)


class _Parser(argparse.ArgumentParser):
    """argparse with the project's usage errors: exit 2 (docs/cli.md), and the closest option
    named for a mistyped one."""

    def error(self, message):
        options = [o for a in self._actions for o in a.option_strings if o.startswith("--")]
        if "unrecognized arguments:" in message:
            for word in message.split(":", 1)[1].split():
                close = difflib.get_close_matches(word.split("=")[0], options, n=1, cutoff=0.6)
                if close:
                    message += f" (did you mean '{close[0]}'?)"
                    break
        super().error(message)


class _Version(argparse.Action):
    """--version: the build's version and git commit, as pitmap-ply-layout (built with this
    script, beside it) states them."""

    def __call__(self, parser, namespace, values, option_string=None):
        exe = os.path.join(os.path.dirname(os.path.realpath(__file__)), "pitmap-ply-layout")
        try:
            line = subprocess.run([exe, "--version"], capture_output=True, text=True,
                                  check=True).stdout.strip()
            print(PROG + line[len("pitmap-ply-layout"):])
        except (OSError, subprocess.CalledProcessError):
            print(PROG + " unknown (no pitmap-ply-layout beside it)")
        parser.exit(0)


def main(argv=None):
    # Ends with whatever started it (pitmap run, a shell), and on SIGTERM; its section workers
    # likewise end with it (report.draw_sections).
    die_with_parent()
    ap = _Parser(prog=PROG, description="Write P/report.html (the client's "
                                 "report) and P/report_engineering.html (self-contained, PNG "
                                 "plots embedded) and P/report/*.png from a pitmap products "
                                 "folder P.")
    ap.add_argument("products", metavar="P", nargs="?",
                    help="products folder (pitmap run --out P)")
    ap.add_argument("--scores", metavar="FILE",
                    help="scores JSON from pitmap-eval --json (default: P/scores.json; the "
                    "scores section is there only when a truth is given)")
    ap.add_argument("--title", metavar="TEXT", help="report (or page) title (default: the "
                    "metadata's project, site and survey id)")
    ap.add_argument("-j", "--jobs", metavar="N", type=int, default=None,
                    help="sections drawn by N processes at once (default: the CPUs this "
                    "process may run on, at most 4; 1 draws them one after the other)")
    ap.add_argument("--pdf", action="store_true",
                    help="also P/report.pdf: report.html printed by headless Chromium (A4)")
    ap.add_argument("--view-gltf", metavar="GLB",
                    help="instead of a report: a self-contained page showing GLB (glTF 2.0 "
                    "binary, e.g. P/mesh.glb) in the report's 3D viewer")
    ap.add_argument("-o", "--output", metavar="HTML",
                    help="the page of --view-gltf (default: GLB with .html)")
    ap.add_argument("--equipment", metavar="FILE",
                    help="YAML list of equipment models (.glb: the mining vehicle, a launch "
                    "vessel) placed by UTM position and heading in the 3D view "
                    "(docs/report.md)")
    ap.add_argument("--compare", metavar="C",
                    help="instead of a survey report: the change report of the folder C of "
                    "`pitmap compare A B --out C` (C/report.html, C/report/*.png; with --pdf "
                    "C/report.pdf)")
    ap.add_argument("--epochs", metavar=("A", "B"), nargs=2,
                    help="with --compare: the two products folders compared (default: "
                    "compare.json's inputs)")
    ap.add_argument("--version", action=_Version, nargs=0,
                    help="print the version and git commit, then exit")
    args = ap.parse_args(argv)
    if args.view_gltf is not None:
        if args.products is not None or args.scores is not None or args.pdf:
            ap.error("--view-gltf takes no products folder, no --scores and no --pdf")
        return view_gltf(args.view_gltf, args.output, args.title)
    if args.compare is not None:
        if args.products is not None or args.scores is not None or args.output is not None \
                or args.equipment is not None or args.jobs is not None:
            ap.error("--compare takes no products folder, --scores, -o, --jobs or --equipment "
                     "(the surveys are compare.json's, or --epochs A B)")
        return compare_report(args.compare, args.epochs, args.title, args.pdf)
    if args.epochs is not None:
        ap.error("--epochs goes with --compare")
    if args.products is None:
        ap.error("give a products folder P (or --compare C, or --view-gltf GLB)")
    if args.output is not None:
        ap.error("-o/--output goes with --view-gltf (the report is always P/report.html)")
    if args.jobs is not None and args.jobs < 1:
        ap.error("--jobs must be at least 1")
    jobs = args.jobs if args.jobs is not None else min(4, len(os.sched_getaffinity(0)))
    folder = os.path.abspath(args.products)
    if not os.path.isdir(folder):
        print(f"{PROG}: {args.products}: not a folder", file=sys.stderr)
        return 2  # a usage error (docs/cli.md): nothing written
    scores = args.scores or os.path.join(folder, "scores.json")
    equipment = []
    if args.equipment is not None:
        try:
            equipment = read_equipment(args.equipment)
        except EquipmentError as e:
            print(f"{PROG}: {e}", file=sys.stderr)
            return 2  # a bad input named before anything is drawn
    try:
        products = Products(folder, scores)
        if equipment:
            products.equipment = place_equipment(equipment, products.summary)
        title = args.title or sections_client.report_title(products.summary)
        pages = report.build(products, title, jobs)
    except EquipmentError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 2
    except (ReportError, OSError) as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    written = []
    for name in (report.ENGINEERING_PAGE, report.CLIENT_PAGE):
        out = os.path.join(folder, name)
        try:
            write_atomically(out, pages[name])
        except OSError as e:
            print(f"{PROG}: {out}: cannot write: {e}", file=sys.stderr)
            return 1
        written.append(f"{out} ({os.path.getsize(out) // 1024} kB)")
    log("wrote " + ", ".join(written)
        + (f"; not produced: {', '.join(products.missing)}" if products.missing else "")
        + (f"; {len(products.problems)} problem(s)" if products.problems else ""))
    if args.pdf:
        from pitmap_report_lib.pdf import write_pdf
        out = os.path.join(folder, "report.pdf")
        try:
            size = write_pdf(os.path.join(folder, report.CLIENT_PAGE), out)
        except (ReportError, OSError) as e:
            print(f"{PROG}: {e}", file=sys.stderr)
            return 1
        log(f"wrote {out} ({size // 1024} kB)")
    return 0


def compare_report(folder, epochs, title, pdf):
    """C/report.html (and with pdf C/report.pdf): the change report of a compare folder."""
    if not os.path.isdir(folder):
        print(f"{PROG}: {folder}: not a folder", file=sys.stderr)
        return 2
    folder = os.path.abspath(folder)
    a_dir, b_dir = epochs if epochs else (None, None)
    try:
        c = CompareFolder(folder, a_dir, b_dir)
        page = report.build_change(c, title or sections_change.change_title(c))
    except (ReportError, OSError) as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    out = os.path.join(folder, report.CLIENT_PAGE)
    try:
        write_atomically(out, page)
    except OSError as e:
        print(f"{PROG}: {out}: cannot write: {e}", file=sys.stderr)
        return 1
    log(f"wrote {out} ({os.path.getsize(out) // 1024} kB)"
        + (f"; not produced: {', '.join(c.missing)}" if c.missing else "")
        + (f"; {len(c.problems)} problem(s)" if c.problems else ""))
    if pdf:
        from pitmap_report_lib.pdf import write_pdf
        target = os.path.join(folder, "report.pdf")
        try:
            size = write_pdf(out, target)
        except (ReportError, OSError) as e:
            print(f"{PROG}: {e}", file=sys.stderr)
            return 1
        log(f"wrote {target} ({size // 1024} kB)")
    return 0


def write_atomically(out, page):
    tmp = out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(page)
    os.replace(tmp, out)


def view_gltf(glb, output, title):
    out = output or os.path.splitext(glb)[0] + ".html"
    try:
        page = gltf_page(glb, title)
    except GlbError as e:
        print(f"{PROG}: {glb}: {e}", file=sys.stderr)
        return 1
    except OSError as e:  # unreadable file, missing viewer scripts
        print(f"{PROG}: {glb}: {e}", file=sys.stderr)
        return 1
    try:
        write_atomically(out, page)
    except OSError as e:
        print(f"{PROG}: {out}: cannot write: {e}", file=sys.stderr)
        return 1
    log(f"wrote {out} ({os.path.getsize(out) // 1024} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
