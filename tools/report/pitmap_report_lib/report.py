# SPDX-License-Identifier: MIT
"""The Report: a products folder (loaders.Products) and its sections (the sections_* mixins)
made into one self-contained HTML page."""

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

from .loaders import Products  # noqa: E402
from .rasters import SaveFigure  # noqa: E402
from .sections_clean import CleanSections  # noqa: E402
from .sections_geometry import GeometrySections  # noqa: E402
from .sections_hydro import HydroSections  # noqa: E402
from .sections_stats import StatsSections  # noqa: E402
from .sections_survey import SurveySections  # noqa: E402
from .sections_viewer import ViewerSection  # noqa: E402
from .util import DieWithParent, Esc, Log  # noqa: E402


class Report(Products, SurveySections, GeometrySections, HydroSections, CleanSections,
             ViewerSection, StatsSections):
    def __init__(self, folder, scores_path, title):
        super().__init__(folder, scores_path)
        self.title = title
        self.fig_dir = os.path.join(folder, "report")
        os.makedirs(self.fig_dir, exist_ok=True)

    # ---- figures
    def Figure(self, fig, name, alt):
        return SaveFigure(fig, self.fig_dir, name, alt)

    def MinutesOf(self, t):
        return (np.asarray(t, dtype=np.float64) - (self.t0 or 0.0)) / 60.0

    # ---- page
    SECTIONS = (
        ("summary", "Survey", "SectionHeader"),
        ("quality", "Quality gates", "SectionQuality"),
        ("trajectory", "Trajectory before and after SLAM", "SectionTrajectory"),
        ("cross-sections", "Cross-sections of the point cloud", "SectionCrossSections"),
        ("depth", "Depth-coloured top view", "SectionDepth"),
        ("hydro", "Vertical datum and IHO S-44 quality control", "SectionHydro"),
        ("rejections", "Rejected soundings", "SectionRejections"),
        ("mosaic", "Backscatter mosaic", "SectionMosaic"),
        ("mesh", "Mesh before and after SLAM", "SectionMesh"),
        ("viewer", "Interactive 3D view", "SectionViewer"),
        ("boresight", "Boresight calibration", "SectionBoresight"),
        ("clock", "Sonar clock and latency", "SectionClock"),
        ("tsdf", "TSDF weight histogram", "SectionTsdf"),
        ("slam", "SLAM per iteration", "SectionSlam"),
        ("stages", "Stages: time and memory", "SectionStages"),
        ("scores", "Scores against ground truth", "SectionScores"),
    )
    # Drawn first when sections run in parallel: the mesh section (two meshes read and
    # rasterised, two figures) costs about as much as all the others together.
    HEAVY_FIRST = ("mesh", "viewer", "cross-sections", "depth")

    def RunSection(self, index):
        """One section drawn: (its HTML, the problems and missing products it added). What
        it added is returned and taken out of self.problems and self.missing again, so that
        sections drawn here and in other processes are merged the same way, in page order."""
        sid, heading, method = self.SECTIONS[index]
        n_problems, n_missing = len(self.problems), len(self.missing)
        Log(f"section {sid}")
        try:
            frag = getattr(self, method)()
        except Exception as e:  # a broken product must not cost the whole report
            Log(f"section {sid} failed: {type(e).__name__}: {e}")
            self.problems.append(f"{heading}: {type(e).__name__}: {e}")
            frag = f'<p class="problem">could not draw: {Esc(type(e).__name__)}: {Esc(e)}</p>'
            plt.close("all")
        added = (self.problems[n_problems:], self.missing[n_missing:])
        del self.problems[n_problems:]
        del self.missing[n_missing:]
        return (frag,) + added

    def Build(self, jobs=1):
        """The page. With jobs > 1 the sections are drawn by that many forked processes
        (the loaded trajectories and points are shared, copy-on-write); the page, its
        problems and its missing products are the same as when drawn one after the other,
        in page order."""
        self.LoadTrajectories()
        self.LoadPoints()
        self.LoadScores()
        n = len(self.SECTIONS)
        results = [None] * n
        if jobs > 1 and "fork" in multiprocessing.get_all_start_methods():
            global _REPORT
            _REPORT = self
            heavy = self.HEAVY_FIRST
            order = sorted(range(n), key=lambda i: heavy.index(self.SECTIONS[i][0])
                           if self.SECTIONS[i][0] in heavy else len(heavy) + i)
            try:
                with ProcessPoolExecutor(max_workers=jobs,
                                         mp_context=multiprocessing.get_context("fork"),
                                         initializer=DieWithParent,
                                         initargs=(os.getpid(),)) as ex:
                    futures = {i: ex.submit(_RunSectionOfReport, i) for i in order}
                    for i, fut in futures.items():
                        results[i] = fut.result()
            except BrokenProcessPool as e:
                # A worker killed (out of memory, a signal): the sections it did not return
                # are drawn here, one after the other.
                Log(f"a section process died ({e}); drawing the rest in this process")
            finally:
                _REPORT = None
        for i in range(n):
            if results[i] is None:
                results[i] = self.RunSection(i)
        body = []
        for (sid, heading, _), (frag, added_problems, added_missing) in zip(self.SECTIONS,
                                                                           results):
            self.problems.extend(added_problems)
            self.missing.extend(m for m in added_missing if m not in self.missing)
            body.append(f'<section id="{sid}"><h2>{Esc(heading)}</h2>\n{frag}\n</section>')
        toc = " &middot; ".join(f'<a href="#{sid}">{Esc(h)}</a>' for sid, h, _ in self.SECTIONS)
        notes = []
        if self.missing:
            notes.append('<p class="missing">not produced: ' +
                         ", ".join(Esc(m) for m in self.missing) + "</p>")
        for p in self.problems:
            notes.append(f'<p class="problem">{Esc(p)}</p>')
        return PAGE.format(title=Esc(self.title), toc=toc, notes="\n".join(notes),
                           body="\n".join(body), css=CSS)


# The report whose sections forked workers draw (set by Build only while they run).
_REPORT = None


def _RunSectionOfReport(index):
    return _REPORT.RunSection(index)


CSS = """
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; margin: 0 auto;
       max-width: 1400px; padding: 0 24px 48px; color: #222; background: #fff; }
h1 { margin: 24px 0 4px; font-size: 26px; }
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
img { max-width: 100%; height: auto; display: block; margin: 8px 0; }
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
"""

# The report is one self-contained file: its policy admits its own inline scripts and styles
# (the viewer with three.js inlined), images and glTF textures from data: and blob: URLs (what
# GLTFLoader makes of a .glb opened locally), and no network at all. A <meta> policy cannot
# say frame-ancestors; a file opened from disk has no headers to say it.
CSP = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
       "img-src data: blob:; connect-src data: blob:; base-uri 'none'; form-action 'none'")

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
<nav>{toc}</nav>
{notes}
{body}
<footer>pitmap-report. Local frame: East, North, Up metres at the world origin;
times in GPS seconds since 1980-01-06 unless marked UTC.</footer>
</body>
</html>
""".replace("@CSP@", CSP)
