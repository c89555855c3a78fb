# SPDX-License-Identifier: MIT
"""The two pages of a products folder: report.html for the client (cover, summary, datums,
maps, S-44, soundings, mosaic, 3D view, scores when a truth is given) and
report_engineering.html for the people who run the processing (trajectories, point-cloud
sections, SLAM, TSDF, boresight, clock, stage times). Every section is a function of the
products (loaders.Products) that returns its HTML, or None when it has nothing to say (the
section is then left out)."""

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from . import sections_clean as clean  # noqa: E402
from . import sections_client as client  # noqa: E402
from . import sections_geometry as geometry  # noqa: E402
from . import sections_hydro as hydro  # noqa: E402
from . import sections_planning as planning  # noqa: E402
from . import sections_stats as stats  # noqa: E402
from . import sections_survey as survey  # noqa: E402
from . import sections_viewer as viewer  # noqa: E402
from .util import die_with_parent, esc, log, strip_paths  # noqa: E402

CLIENT_PAGE = "report.html"
ENGINEERING_PAGE = "report_engineering.html"

# (page, section id, heading, function of the products)
SECTIONS = (
    (CLIENT_PAGE, "cover", "Survey", client.cover),
    (CLIENT_PAGE, "summary", "Summary", client.summary),
    (CLIENT_PAGE, "datums", "Datums, water level and sound speed", client.datums),
    (CLIENT_PAGE, "maps", "Maps", client.maps),
    (CLIENT_PAGE, "hydro", "IHO S-44 quality control", hydro.hydrography),
    (CLIENT_PAGE, "soundings", "Soundings kept and rejected", clean.sounding_counts),
    (CLIENT_PAGE, "mosaic", "Backscatter mosaic", hydro.mosaic),
    (CLIENT_PAGE, "terrain", "Mine planning: slopes and the crawler's reach", planning.terrain),
    (CLIENT_PAGE, "capacity", "Capacity: water volume against water level", planning.capacity),
    (CLIENT_PAGE, "viewer", "Interactive 3D view", viewer.viewer),
    (CLIENT_PAGE, "scores", "Scores against ground truth", survey.scores),
    (CLIENT_PAGE, "engineering", "Processing details", client.engineering_link),
    (ENGINEERING_PAGE, "processing", "Processing record", survey.survey_facts),
    (ENGINEERING_PAGE, "quality", "Quality gates", survey.quality_gates),
    (ENGINEERING_PAGE, "trajectory", "Trajectory before and after SLAM", geometry.trajectory),
    (ENGINEERING_PAGE, "trajectory-sigma", "How well the trajectory is known",
     geometry.trajectory_sigma),
    (ENGINEERING_PAGE, "cross-sections", "Cross-sections of the point cloud",
     geometry.cross_sections),
    (ENGINEERING_PAGE, "depth", "Depth-coloured top view (local metres)",
     geometry.depth_top_view),
    (ENGINEERING_PAGE, "tvu", "TVU of the soundings against the order's limit", hydro.tvu_map),
    (ENGINEERING_PAGE, "rejections", "Rejected soundings", clean.rejections),
    (ENGINEERING_PAGE, "mesh", "Mesh before and after SLAM", geometry.mesh),
    (ENGINEERING_PAGE, "boresight", "Boresight calibration", survey.boresight),
    (ENGINEERING_PAGE, "clock", "Sonar clock and latency", survey.sonar_clock),
    (ENGINEERING_PAGE, "tsdf", "TSDF weight histogram", stats.tsdf),
    (ENGINEERING_PAGE, "slam", "SLAM per iteration", stats.slam),
    (ENGINEERING_PAGE, "stages", "Stages: time and memory", stats.stages),
)
# Drawn first when sections run in parallel: the mesh section (two meshes read and
# rasterised, two figures) costs about as much as all the others together.
HEAVY_FIRST = ("mesh", "viewer", "cross-sections", "depth", "maps")


def run_section(p, index):
    """One section drawn: (its HTML or None, the problems and missing products it added).
    What it added is returned and taken out of p.problems and p.missing again, so that
    sections drawn here and in other processes are merged the same way, in page order."""
    _, sid, heading, function = SECTIONS[index]
    return draw_section(p, sid, heading, function)


def draw_section(p, sid, heading, function):
    """function(p) as a section: its HTML (a line saying it could not be drawn when it
    raised), and the problems and missing products it added to p, taken out again."""
    n_problems, n_missing = len(p.problems), len(p.missing)
    log(f"section {sid}")
    try:
        frag = function(p)
    except Exception as e:  # a broken product must not cost the whole report
        log(f"section {sid} failed: {type(e).__name__}: {e}")
        p.problems.append(f"{heading}: {type(e).__name__}: {e}")
        frag = (f'<p class="problem">could not draw: {esc(type(e).__name__)}: '
                f"{esc(strip_paths(e))}</p>")
        plt.close("all")
    added = (p.problems[n_problems:], p.missing[n_missing:])
    del p.problems[n_problems:]
    del p.missing[n_missing:]
    return (frag,) + added


# The products whose sections forked workers draw (set by build only while they run).
_PRODUCTS = None


def _run_section_of_products(index):
    return run_section(_PRODUCTS, index)


def draw_sections(p, jobs=1):
    """Every section's result in SECTIONS order; with jobs > 1 drawn by that many forked
    processes (the loaded trajectories and points are shared, copy-on-write), with the same
    results as when drawn one after the other."""
    global _PRODUCTS
    n = len(SECTIONS)
    results = [None] * n
    if jobs > 1 and "fork" in multiprocessing.get_all_start_methods():
        _PRODUCTS = p
        order = sorted(range(n), key=lambda i: HEAVY_FIRST.index(SECTIONS[i][1])
                       if SECTIONS[i][1] in HEAVY_FIRST else len(HEAVY_FIRST) + i)
        try:
            with ProcessPoolExecutor(max_workers=jobs,
                                     mp_context=multiprocessing.get_context("fork"),
                                     initializer=die_with_parent,
                                     initargs=(os.getpid(),)) as ex:
                futures = {i: ex.submit(_run_section_of_products, i) for i in order}
                for i, fut in futures.items():
                    results[i] = fut.result()
        except BrokenProcessPool as e:
            # A worker killed (out of memory, a signal): the sections it did not return are
            # drawn here, one after the other.
            log(f"a section process died ({e}); drawing the rest in this process")
        finally:
            _PRODUCTS = None
    for i in range(n):
        if results[i] is None:
            results[i] = run_section(p, i)
    return results


def build(p, title, jobs=1):
    """{page file name: HTML} for the products p: the client's report and the engineering
    page."""
    p.load_trajectories()
    p.load_points()
    p.load_scores()
    results = draw_sections(p, jobs)
    bodies = {CLIENT_PAGE: [], ENGINEERING_PAGE: []}
    tocs = {CLIENT_PAGE: [], ENGINEERING_PAGE: []}
    for (page, sid, heading, _), (frag, added_problems, added_missing) in zip(SECTIONS, results):
        p.problems.extend(added_problems)
        p.missing.extend(m for m in added_missing if m not in p.missing)
        if frag is None:
            continue
        bodies[page].append(f'<section id="{sid}"><h2>{esc(heading)}</h2>\n{frag}\n</section>')
        tocs[page].append(f'<a href="#{sid}">{esc(heading)}</a>')
    problems = "\n".join(f'<p class="problem">{esc(strip_paths(x))}</p>' for x in p.problems)
    missing = ""
    if p.missing:
        missing = ('<p class="missing">not produced: ' +
                   ", ".join(esc(m) for m in p.missing) + "</p>")
    pages = {}
    pages[CLIENT_PAGE] = PAGE.format(
        title=esc(title), subtitle=client.subtitle(p), toc=" &middot; ".join(
            tocs[CLIENT_PAGE]), notes=problems, body="\n".join(bodies[CLIENT_PAGE]), css=CSS,
        footer=CLIENT_FOOTER)
    if viewer.mesh_tiles(p.folder):
        pages[CLIENT_PAGE] = pages[CLIENT_PAGE].replace(CSP, CSP_TILES, 1)
    pages[ENGINEERING_PAGE] = PAGE.format(
        title=esc(title) + " &ndash; engineering", subtitle="Processing details for the "
        f'survey of <a href="{CLIENT_PAGE}">{CLIENT_PAGE}</a>',
        toc=" &middot; ".join(tocs[ENGINEERING_PAGE]), notes=missing + "\n" + problems,
        body="\n".join(bodies[ENGINEERING_PAGE]), css=CSS, footer=ENGINEERING_FOOTER)
    return pages


def build_change(c, title):
    """The change report (report.html of a compare folder) of a change.CompareFolder c: its
    sections (sections_change.SECTIONS) drawn one after the other on one page."""
    from . import sections_change as change
    body, toc = [], []
    for sid, heading, function in change.SECTIONS:
        frag, added_problems, added_missing = draw_section(c, sid, heading, function)
        c.problems.extend(added_problems)
        c.missing.extend(m for m in added_missing if m not in c.missing)
        if frag is None:
            continue
        body.append(f'<section id="{sid}"><h2>{esc(heading)}</h2>\n{frag}\n</section>')
        toc.append(f'<a href="#{sid}">{esc(heading)}</a>')
    notes = "\n".join(f'<p class="problem">{esc(strip_paths(x))}</p>' for x in c.problems)
    if c.missing:
        notes = ('<p class="missing">not produced: ' + ", ".join(esc(m) for m in c.missing)
                 + "</p>\n" + notes)
    return PAGE.format(title=esc(title), subtitle=change.subtitle(c),
                       toc=" &middot; ".join(toc), notes=notes, body="\n".join(body), css=CSS,
                       footer=CHANGE_FOOTER)


CSS = """
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; margin: 0 auto;
       max-width: 1400px; padding: 0 24px 48px; color: #222; background: #fff; }
h1 { margin: 24px 0 4px; font-size: 26px; }
.subtitle { margin: 0 0 8px; color: #555; }
h2 { margin-top: 36px; border-bottom: 2px solid #2a6f97; padding-bottom: 4px; color: #1d4e6b; }
h3 { margin-bottom: 6px; }
nav { font-size: 14px; margin: 8px 0 16px; line-height: 1.7; }
nav a { color: #2a6f97; text-decoration: none; }
table { border-collapse: collapse; margin: 8px 0; font-size: 14px; }
th, td { border: 1px solid #ccc; padding: 4px 10px; text-align: left; vertical-align: top; }
th { background: #eef3f7; }
td:nth-child(n+2) { font-variant-numeric: tabular-nums; }
table.facts td:first-child { white-space: nowrap; background: #f7f9fb; }
table.stages .counts { font-size: 12px; color: #444; }
.cover table.facts { font-size: 16px; min-width: 60%; }
.not-set { color: #999; font-style: italic; }
.source { color: #777; font-size: 12px; }
.verdict { font-size: 17px; padding: 10px 14px; border-left: 6px solid #999;
           background: #f4f4f4; max-width: 1100px; }
.verdict.met { border-color: #2e8b57; background: #eaf6ee; }
.verdict.not-met { border-color: #c0392b; background: #fbeaea; }
img { max-width: 100%; height: auto; display: block; margin: 8px 0; }
.pair { display: flex; flex-wrap: wrap; gap: 12px; align-items: flex-start; }
.pair img { max-width: 49%; }
.caption { font-size: 13px; color: #555; max-width: 1100px; }
.missing { color: #8a5a00; background: #fff6e0; padding: 4px 8px; border-left: 4px solid #e0a000; }
.problem, .viewer-problem { color: #900; background: #fde8e8; padding: 4px 8px;
                           border-left: 4px solid #c00; }
footer { margin-top: 40px; font-size: 12px; color: #777; }
#viewer3d { position: relative; width: 100%; height: 620px; background: #15191d; }
#viewer3d-bar { margin: 6px 0; font-size: 14px; }
#viewer3d-bar button { margin-right: 8px; }
#viewer3d-profile { margin: 8px 0; font-size: 14px; }
#viewer3d-profile-canvas { display: block; width: 100%; height: 340px; margin: 6px 0;
                           border: 1px solid #ccc; cursor: crosshair; }
.print-only { display: none; }
@page { size: A4; margin: 14mm 12mm; }
@media print {
  body { max-width: none; padding: 0; font-size: 11px; }
  nav { display: none; }
  section { break-before: page; }
  section#cover, section#surveys { break-before: auto; }
  h2 { margin-top: 0; }
  img { break-inside: avoid; max-height: 240mm; object-fit: contain; }
  table { break-inside: auto; font-size: 11px; }
  tr { break-inside: avoid; }
  #viewer3d, #viewer3d-bar, #viewer3d-info, #viewer3d-profile, #viewer3d-problem { display: none; }
  .print-only { display: block; }
}
"""

# The report is one self-contained file: its policy admits its own inline scripts and styles
# (the viewer with three.js inlined), images and glTF textures from data: and blob: URLs (what
# GLTFLoader makes of a .glb opened locally), and no network at all. A <meta> policy cannot
# say frame-ancestors; a file opened from disk has no headers to say it.
CSP = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
       "img-src data: blob:; connect-src data: blob:; base-uri 'none'; form-action 'none'")
# With mesh tiles (P/tiles/mesh) the viewer reads them from the page's own origin when the
# folder is served over HTTP (viewer3d_tiles.js): that origin only, still no other network.
CSP_TILES = CSP.replace("connect-src data: blob:", "connect-src 'self' data: blob:")

CLIENT_FOOTER = ("pitmap-report. Coordinates in the horizontal CRS of the cover, maps to grid "
                 "north; depths and heights in metres in its vertical datum; times UTC.")
CHANGE_FOOTER = ("pitmap-report, change between two surveys (pitmap compare). Coordinates in "
                 "survey A's horizontal CRS, maps to grid north; heights, differences and "
                 "volumes in metres in its vertical datum; B minus A after co-registration; "
                 "uncertainties at 95 % confidence.")
ENGINEERING_FOOTER = ("pitmap-report, engineering page. Local frame: East, North, Up metres "
                      "at the world origin; times in GPS seconds since 1980-01-06 unless "
                      "marked UTC.")

PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="@CSP@">
<title>{title}</title>
<style>{css}</style>
</head>
<body>
<h1>{title}</h1>
<p class="subtitle">{subtitle}</p>
<nav>{toc}</nav>
{notes}
{body}
<footer>{footer}</footer>
</body>
</html>
""".replace("@CSP@", CSP)
