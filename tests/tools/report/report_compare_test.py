#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""pitmap-report --compare C: the change report of a repeat survey (issue 37 item 5), on a
compare folder this test makes: the quarry's first 60 s surveyed twice (`pitmap-sim synth
--scenario quarry --duration 60`, epoch 1 and --epoch 2), each through `pitmap run`, then
`pitmap compare`.

Checks: the page is written, self-contained, names no path of this machine and holds its
sections; every figure of the volume table (per region and the totals), the capacity table, the
co-registration and the summary is compare.json's; the cross-section runs through the region of
the largest volume, at its node of the largest |B - A| (compare.json's max_abs_difference_m);
the change along the normal by slope class is compare.json's change3d; the pictures exist as
non-empty PNG files and in the page; the survey report of A has the capacity curve pitmap
compare found for A (the same CSV rows); a damaged compare.json, survey folders that moved or
were processed again are refused with a message naming the problem and no page; a compare.json
with fields the report does not know, or without optional ones, is still drawn; a tripped gate
leads the summary; no change is said in words; with Chromium, report.pdf has a page per
section.

Usage: report_compare_test.py --bin BUILD/bin --work DIR [unittest args]"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import unittest

BIN = None
WORK = None
COMPARE_WROTE_REPORT = False  # setUpModule: did pitmap compare write C/report.html
NO_REPORT_FILES = []  # setUpModule: the files of a comparison with --no-report
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SECTIONS = ["surveys", "summary", "change-map", "volumes", "sections", "registration",
            "change3d", "capacity", "terrain", "quality"]
FIGURES = ["change_map", "change_difference_lod", "change_section_1", "change_section_2",
           "change_normal_map", "change_capacity", "terrain_slope", "terrain_crawler"]


def Run(*args, check=True):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, args))}: exit {r.returncode}\n{r.stderr[-3000:]}")
    return r


def Report(*args):
    return Run("/usr/bin/python3", os.path.join(BIN, "pitmap-report"), *args, check=False)


def Sections(page):
    return dict(re.findall(r'<section id="([^"]+)">(.*?)</section>', page, re.S))


def Two(v):
    """A figure as the report prints it to two decimals (util.num)."""
    return f"{float(v):.2f}"


def setUpModule():
    """The compare folder, made once: C (and A, B) under WORK."""
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)
    for k in (1, 2):
        sim = os.path.join(WORK, f"S{k}")
        Run(os.path.join(BIN, "pitmap-sim"), "synth", "--scenario", "quarry", "--duration", "60",
            "--epoch", k, "--out", sim)
        Run(os.path.join(BIN, "pitmap"), "run", os.path.join(sim, "log"), "--out",
            os.path.join(WORK, "AB"[k - 1]), "--no-report")
    # pitmap compare writes the change report itself (pitmap-report --compare C), as pitmap
    # run writes the survey report; --no-report leaves it out.
    global COMPARE_WROTE_REPORT, NO_REPORT_FILES
    Run(os.path.join(BIN, "pitmap"), "compare", os.path.join(WORK, "A"),
        os.path.join(WORK, "B"), "--out", os.path.join(WORK, "C"))
    COMPARE_WROTE_REPORT = os.path.isfile(os.path.join(WORK, "C", "report.html"))
    Run(os.path.join(BIN, "pitmap"), "compare", os.path.join(WORK, "A"),
        os.path.join(WORK, "B"), "--out", os.path.join(WORK, "C_no_report"), "--no-report")
    NO_REPORT_FILES = sorted(os.listdir(os.path.join(WORK, "C_no_report")))


class ChangeReportTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.C = os.path.join(WORK, "C")
        for name in ("report.html", "report.pdf"):
            if os.path.exists(os.path.join(cls.C, name)):
                os.remove(os.path.join(cls.C, name))
        shutil.rmtree(os.path.join(cls.C, "report"), ignore_errors=True)
        cls.report_run = Report("--compare", cls.C)
        with open(os.path.join(cls.C, "compare.json")) as f:
            cls.j = json.load(f)
        cls.page = ""
        if cls.report_run.returncode == 0:
            with open(os.path.join(cls.C, "report.html"), encoding="utf-8") as f:
                cls.page = f.read()
        cls.sec = Sections(cls.page)

    def test_compare_writes_the_change_report_unless_told_not_to(self):
        self.assertTrue(COMPARE_WROTE_REPORT, "pitmap compare wrote no report.html")
        self.assertIn("compare.json", NO_REPORT_FILES)
        self.assertNotIn("report.html", NO_REPORT_FILES)
        self.assertNotIn("report", NO_REPORT_FILES)

    def test_page_is_written_with_its_sections(self):
        self.assertEqual(self.report_run.returncode, 0, self.report_run.stderr)
        self.assertEqual(list(self.sec), SECTIONS)
        self.assertNotIn("could not draw", self.page)
        self.assertNotIn('class="problem"', self.page)
        self.assertNotIn("not produced", self.page)
        self.assertNotRegex(self.page, r"(?i)https?:")
        self.assertNotIn("<link", self.page)
        self.assertIn("Content-Security-Policy", self.page)
        # No path of this machine: the work folder is named nowhere in the visible text.
        text = re.sub(r'src="data:[^"]*"', "", self.page)
        self.assertNotIn(os.path.abspath(WORK), text)
        self.assertIn("<title>Change between surveys, 2026-06-15 to 2026-09-14</title>",
                      self.page)

    def test_volume_table_is_compare_json(self):
        ch = self.j["change"]
        self.assertTrue(ch["regions"], "the quarry's first minute has changes in view")
        rows = re.findall(r"<tr><td>R(\d+)</td><td>(cut|fill)</td><td>([^<]*)</td><td>([^<]*)"
                          r"</td><td>([^<]*)</td>", self.sec["volumes"])
        self.assertEqual(len(rows), len(ch["regions"]))
        by_id = {r["id"]: r for r in ch["regions"]}
        for rid, kind, area, volume, u95 in rows:
            r = by_id[int(rid)]
            self.assertEqual((kind, area, volume, u95),
                             (r["kind"], Two(r["area_m2"]), Two(r["volume_m3"]),
                              Two(r["u95_m3"])))
        # Largest |volume| first.
        vols = [abs(by_id[int(r[0])]["volume_m3"]) for r in rows]
        self.assertEqual(vols, sorted(vols, reverse=True))
        for side in ("cut", "fill"):
            t = ch[side]
            self.assertIn(f"<tr><td><b>all {side}</b></td><td>{t['regions']}</td><td>"
                          f"{Two(t['area_m2'])}</td><td><b>{Two(t['volume_m3'])}</b></td><td><b>"
                          f"{Two(t['u95_m3'])}</b></td></tr>", self.sec["volumes"])
            self.assertIn(f"{side} {Two(t['volume_m3'])} m&sup3; &plusmn; {Two(t['u95_m3'])}",
                          self.sec["summary"])
        self.assertIn(f"<b>{Two(ch['net_m3'])}</b>", self.sec["volumes"])

    def test_capacity_and_registration_are_compare_json(self):
        cap = self.j["capacity"]
        for key, digits in (("volume_at_water_level_m3", 0), ("water_level_m", 3),
                            ("area_at_water_level_m2", 0)):
            a, b = cap["a"][key], cap["b"][key]
            unit = {"volume_at_water_level_m3": "m&sup3;", "water_level_m": "m",
                    "area_at_water_level_m2": "m&sup2;"}[key]

            def f(v):
                return f"{v:.{digits}f}"
            self.assertIn(f"<td>{f(a)} {unit}</td><td>{f(b)} {unit}</td><td>{f(b - a)} {unit}"
                          "</td>", self.sec["capacity"])
        self.assertIn("data:image/png", self.sec["capacity"])
        reg = self.j["registration"]
        self.assertIn(f"{reg['rms_vertical_after_m']:.3f} m after, "
                      f"{reg['rms_vertical_before_m']:.3f} m before", self.sec["registration"])
        self.assertIn(f"{reg['translation_m'][2] * 100:.1f} cm &plusmn; "
                      f"{reg['sigma']['up_m'] * 100:.1f}", self.sec["registration"])
        gate = reg["navigation_gate"]
        self.assertIn("tripped" if gate["tripped"] else "passed", self.sec["registration"])

    def test_cross_sections_run_through_the_largest_change(self):
        regions = self.j["change"]["regions"]
        largest = max(regions, key=lambda r: abs(r["volume_m3"]))
        self.assertIn(f"<td>R{largest['id']} ({largest['kind']}, {Two(largest['volume_m3'])} "
                      f"m&sup3; &plusmn; {Two(largest['u95_m3'])})", self.sec["sections"])
        m = re.search(r"<td><b>B - A there</b></td><td>(-?[0-9.]+) m \(LoD95 ([0-9.]+) m\)",
                      self.sec["sections"])
        self.assertTrue(m, "no difference at the section's centre")
        self.assertAlmostEqual(abs(float(m.group(1))), largest["max_abs_difference_m"],
                               delta=0.0006)
        self.assertGreater(abs(float(m.group(1))), float(m.group(2)))  # significant there
        # The quarry's first minute has no change on a wall: sections 1 and 2 only.
        self.assertEqual(self.sec["sections"].count("data:image/png"), 2)
        self.assertIn("data:image/png", self.sec["change3d"])
        by = self.j["change3d"]["by_slope"]

        def count(v):
            return f"{v:,}".replace(",", "\u2009")
        for key, label in (("floor_0_20_deg", "floors and benches (&lt; 20 deg)"),
                           ("wall_45_90_deg", "walls (&gt;= 45 deg)")):
            self.assertIn(f"<td>{label}</td><td>{count(by[key]['measured'])}</td><td>"
                          f"{count(by[key]['significant'])}</td><td>"
                          f"{by[key]['median_lod95_m']:.3f}</td>", self.sec["change3d"])

    def test_pictures_exist_and_are_in_the_page(self):
        for name in FIGURES:
            path = os.path.join(self.C, "report", name + ".png")
            self.assertTrue(os.path.isfile(path), name)
            with open(path, "rb") as f:
                data = f.read()
            self.assertEqual(data[:8], PNG_MAGIC, name)
            self.assertGreater(len(data), 10_000, name)  # a drawn picture, not an empty one
        self.assertEqual(len(re.findall(r'src="data:image/png;base64,', self.page)),
                         len(FIGURES))

    def test_survey_report_has_the_capacity_curve_compare_found(self):
        a = os.path.join(WORK, "A")
        r = Report(a, "--jobs", "1")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(a, "report", "capacity.csv")) as f:
            mine = f.read().splitlines()
        with open(os.path.join(self.C, "capacity_a.csv")) as f:
            theirs = f.read().splitlines()
        self.assertEqual(mine, theirs)
        with open(os.path.join(a, "report.html"), encoding="utf-8") as f:
            sec = Sections(f.read())
        v = self.j["capacity"]["a"]["volume_at_water_level_m3"]
        self.assertIn(f"<td>{v:.0f} m&sup3;</td>", sec["capacity"])
        self.assertIn("data:image/png", sec["terrain"])

    def Damaged(self, name, edit):
        """A copy of C whose compare.json `edit` damages; (exit, stderr, page written?)."""
        d = os.path.join(WORK, "damaged", name)
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(self.C, d, ignore=shutil.ignore_patterns("report*"))
        path = os.path.join(d, "compare.json")
        with open(path) as f:
            text = f.read()
        with open(path, "w") as f:
            f.write(edit(text))
        r = Report("--compare", d)
        return r.returncode, r.stderr, os.path.exists(os.path.join(d, "report.html"))

    def test_damaged_compare_json_is_refused_clearly(self):
        def set_value(path, value):
            def edit(text):
                j = json.loads(text)
                v = j
                for k in path[:-1]:
                    v = v[k]
                if value is KeyError:
                    del v[path[-1]]
                else:
                    v[path[-1]] = value
                return json.dumps(j)
            return edit
        cases = [
            ("truncated", lambda t: t[:len(t) // 2], "compare.json: cannot read"),
            ("not an object", lambda t: "[1, 2]", "not a JSON object"),
            ("volume as text", set_value(["change", "regions", 0, "volume_m3"], "12 m3"),
             'change.regions[0].volume_m3 is not a number ("12 m3")'),
            ("no capacity of B", set_value(["capacity", "b"], KeyError),
             "capacity.b is missing"),
            ("u95 null", set_value(["change", "cut", "u95_m3"], None),
             "change.cut.u95_m3 is null"),
            ("kind", set_value(["change", "regions", 0, "kind"], "slump"),
             "change.regions[0].kind is 'slump', not cut or fill"),
            ("translation", set_value(["registration", "translation_m"], [0.1, 0.2]),
             "registration.translation_m is not three numbers"),
        ]
        for name, edit, message in cases:
            with self.subTest(name):
                code, err, written = self.Damaged(name.replace(" ", "_"), edit)
                self.assertEqual(code, 1, err)
                self.assertIn(message, err)
                self.assertIn("damaged, not reported on" if "cannot read" not in message
                              and "object" not in message else "compare.json", err)
                self.assertFalse(written, "a page from a damaged compare.json")

    def test_fields_it_does_not_know_or_need_are_left_alone(self):
        # compare.json grows (a LoD model, a change mesh, a design surface) and older ones lack
        # what came later: the page is still drawn, from what it needs.
        def edit(text):
            j = json.loads(text)
            j["change"].pop("median_lod95_by_slope_m", None)
            j["change"].pop("stable_rms_m", None)
            for r in j["change"]["regions"]:
                for k in ("centroid_m", "sigma_random_m3", "rim_m3"):
                    r.pop(k, None)
            for k in ("sigma", "navigation_gate", "termination"):
                j["registration"].pop(k, None)
            j.pop("change3d", None)
            j["lod_model"] = {"kind": "spatially variable", "terms": [1, 2]}
            j["change"]["mesh"] = {"file": "change_mesh.ply", "vertices": 12}
            j["design"] = None
            return json.dumps(j)
        code, err, written = self.Damaged("grown", edit)
        self.assertEqual(code, 0, err)
        with open(os.path.join(WORK, "damaged", "grown", "report.html"), encoding="utf-8") as f:
            page = f.read()
        self.assertEqual(list(Sections(page)), [s for s in SECTIONS if s != "change3d"])
        self.assertFalse(os.path.exists(os.path.join(WORK, "damaged", "grown", "report",
                                                     "change_normal_map.png")))
        self.assertNotIn("could not draw", page)
        self.assertNotIn('class="problem"', page)
        # Without change_regions.geojson the outlines come from dod.tif, and the page says so.
        d = os.path.join(WORK, "damaged", "grown")
        os.remove(os.path.join(d, "change_regions.geojson"))
        r = Report("--compare", d)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(d, "report.html"), encoding="utf-8") as f:
            page = f.read()
        self.assertTrue(re.search(r'class="problem">change_regions.geojson: unreadable \(.*\); '
                                  "outlines drawn from dod.tif&#x27;s region band", page),
                        "no line saying the outlines come from dod.tif")
        self.assertIn("data:image/png", Sections(page)["change-map"])

    def test_a_tripped_gate_leads_the_summary(self):
        gate = {"stage": "compare", "gate": "correction_beyond_navigation",
                "message": "the correction (0.50 m east) is beyond what the navigation of "
                           "/data/surveys/A and B allows"}

        def edit(text):
            j = json.loads(text)
            j["quality_gates"] = [gate]
            return json.dumps(j)
        code, err, _ = self.Damaged("gate", edit)
        self.assertEqual(code, 0, err)
        with open(os.path.join(WORK, "damaged", "gate", "report.html"), encoding="utf-8") as f:
            sec = Sections(f.read())
        self.assertIn('<p class="verdict not-met">', sec["summary"])
        # Paths in a gate's message are cut to their last part on the client's page.
        message = "the correction (0.50 m east) is beyond what the navigation of A and B allows"
        self.assertIn(message, sec["summary"])
        self.assertIn(f"<td>compare</td><td>correction_beyond_navigation</td><td>{message}</td>",
                      sec["quality"])
        self.assertIn('<p class="verdict">', self.sec["summary"])  # none tripped: grey
        self.assertIn("No quality gate of the comparison tripped", self.sec["quality"])

    def test_no_change_is_said_in_words(self):
        def edit(text):
            j = json.loads(text)
            j["change"]["regions"] = []
            for side in ("cut", "fill"):
                j["change"][side].update({"volume_m3": 0.0, "u95_m3": 0.0, "area_m2": 0.0,
                                          "regions": 0})
            j["change"]["net_m3"] = 0.0
            return json.dumps(j)
        code, err, _ = self.Damaged("unchanged", edit)
        self.assertEqual(code, 0, err)
        with open(os.path.join(WORK, "damaged", "unchanged", "report.html"),
                  encoding="utf-8") as f:
            page = f.read()
        sec = Sections(page)
        self.assertIn("<b>0</b> regions of significant change were found", sec["summary"])
        self.assertIn("No region of significant change.", sec["volumes"])
        self.assertIn("No region of significant change: no cross-section.", sec["sections"])
        self.assertIn("data:image/png", sec["change-map"])
        self.assertNotIn("could not draw", page)

    def test_moved_or_reprocessed_surveys_are_refused(self):
        code, err, written = self.Damaged("moved", lambda t: t.replace(
            json.dumps(os.path.join(WORK, "A"))[1:-1], "/nonexistent/A"))
        self.assertEqual(code, 1, err)
        self.assertIn("survey A: /nonexistent/A: not found", err)
        self.assertIn("--epochs A B", err)
        self.assertFalse(written)
        # The folders given: the page is written.
        d = os.path.join(WORK, "damaged", "moved")
        r = Report("--compare", d, "--epochs", os.path.join(WORK, "A"), os.path.join(WORK, "B"))
        self.assertEqual(r.returncode, 0, r.stderr)
        # Swapped: each folder is another run than the one compared.
        r = Report("--compare", d, "--epochs", os.path.join(WORK, "B"), os.path.join(WORK, "A"))
        self.assertEqual(r.returncode, 1)
        self.assertRegex(r.stderr, r"survey A: .* is run [0-9a-f]+, but compare.json compared "
                                   r"run [0-9a-f]+")

    def test_usage_errors(self):
        r = Report("--compare", os.path.join(WORK, "nothing-here"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("not a folder", r.stderr)
        r = Report("--compare", self.C, os.path.join(WORK, "A"))
        self.assertEqual(r.returncode, 2)
        r = Report(os.path.join(WORK, "A"), "--epochs", "x", "y")
        self.assertEqual(r.returncode, 2)
        self.assertIn("--epochs goes with --compare", r.stderr)
        r = Report("--compare", os.path.join(WORK, "A"))
        self.assertEqual(r.returncode, 1)
        self.assertIn("no compare.json", r.stderr)

    def test_pdf(self):
        if shutil.which("chromium") is None and shutil.which("chromium-browser") is None:
            self.skipTest("chromium is not installed")
        d = os.path.join(WORK, "pdf")
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(self.C, d, ignore=shutil.ignore_patterns("report*"))
        r = Report("--compare", d, "--pdf")
        if r.returncode != 0 and "did not answer on the DevTools pipe" in r.stderr:
            self.skipTest(r.stderr.strip().splitlines()[-1])
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(d, "report.pdf"), "rb") as f:
            data = f.read()
        self.assertTrue(data.startswith(b"%PDF-") and b"%%EOF" in data[-64:])
        pages = len(re.findall(rb"/Type\s*/Page\b", data))
        self.assertGreaterEqual(pages, len(SECTIONS))  # each section from a new page


def main():
    global BIN, WORK
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True, help="the build's bin folder")
    ap.add_argument("--work", required=True, help="a scratch folder (made afresh)")
    args, rest = ap.parse_known_args()
    BIN, WORK = os.path.abspath(args.bin), os.path.abspath(args.work)
    unittest.main(argv=[sys.argv[0]] + rest)


if __name__ == "__main__":
    main()
