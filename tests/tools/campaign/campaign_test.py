#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pitmap-campaign (tools/campaign, docs/campaigns.md) on short simulated surveys.

  campaign_test.py --bin BUILD/bin --source SRC --work DIR [CheckTest | RunTest] [-v]

CheckTest: bad campaign files are refused at start with every problem named (missing inputs,
vehicle files, casts and configs, duplicate names, unknown keys, wrong types, surveys of one
site in different CRS, a tile size too small for the voxel size and an overlap below the
truncation in a survey's config, tiles: true without tiles in its config), and nothing is run.
TilesTest: a survey by tiles (TilesTest's docstring).
RunTest: the example campaign (4 simulated demo surveys) through Snakemake with 2 workers gives
products identical to running each survey alone with the same command (product_compare.py:
everything but the run id, the processing time and the time and memory figures); a worker
killed mid-run and then the whole run killed, the restart redoes only the unfinished jobs.
"""
import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import product_compare  # noqa: E402

ARGS = None
# A bound on every wait for the workflow: a hang fails the test instead of blocking ctest.
WAIT_LIMIT_S = 600


def sh(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def lib():
    sys.path.insert(0, os.path.join(ARGS.bin, "pitmap_campaign"))
    import pitmap_campaign_lib
    return pitmap_campaign_lib


class CheckTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.work = os.path.join(ARGS.work, "check")
        shutil.rmtree(cls.work, ignore_errors=True)
        os.makedirs(cls.work)
        r = sh([os.path.join(ARGS.bin, "pitmap-sim"), "synth", "--scenario", "demo",
                "--duration", "5", "--out", os.path.join(cls.work, "s")])
        assert r.returncode == 0, r.stderr

    def write(self, name, text):
        path = os.path.join(self.work, name)
        with open(path, "w") as f:
            f.write(text)
        return path

    def check(self, path):
        return sh([os.path.join(ARGS.bin, "pitmap-campaign"), "check", path])

    def test_every_problem_is_named(self):
        self.write("zone31.yaml", "products:\n  origin:\n    latitude_deg: 40.0\n"
                   "    longitude_deg: 3.0\n    height_m: 0\n")
        path = self.write("bad.yaml", """
campaign: bad
colour: blue
defaults:
  report: yes please
surveys:
  - name: a
    inputs: [s/log]
  - name: a
    inputs: [s/log]
  - name: b
    inputs: [missing/log]
    vehicle: missing/vehicle.yaml
  - name: c
    inputs: [s/log]
    svp: [casts/none.svp]
    config: nowhere.yaml
    threads: two
    flavour: salty
  - inputs: [s/log]
""")
        r = self.check(path)
        self.assertEqual(r.returncode, 2, r.stderr)
        expected = [
            "unknown key 'colour'",
            "defaults: report must be true or false",
            "survey a: the name is also survey 1's",
            "survey b: input missing/log does not exist",
            "survey b: vehicle file missing/vehicle.yaml does not exist",
            "survey c: cast casts/none.svp does not exist",
            "survey c: config nowhere.yaml does not exist",
            "survey c: threads must be an integer",
            "survey c: unknown key 'flavour'",
            "survey 5: name: required",
        ]
        for e in expected:
            self.assertIn(e, r.stderr)
        self.assertIn(f"{len(expected)} problem(s)", r.stderr)
        # `run` refuses it before anything: no output folder.
        out = os.path.join(self.work, "bad-out")
        r = sh([os.path.join(ARGS.bin, "pitmap-campaign"), "run", path, "--out", out])
        self.assertEqual(r.returncode, 2)
        self.assertIn("survey b: input missing/log does not exist", r.stderr)
        self.assertFalse(os.path.exists(out))

    def test_surveys_of_one_site_in_different_crs(self):
        self.write("zone31.yaml", "products:\n  origin:\n    latitude_deg: 40.0\n"
                   "    longitude_deg: 3.0\n    height_m: 0\n")
        path = self.write("crs.yaml", """
campaign: crs
site: pit
surveys:
  - {name: here, inputs: [s/log]}
  - {name: there, inputs: [s/log], config: zone31.yaml}
  - {name: other-pit, site: far, inputs: [s/log], config: zone31.yaml}
""")
        r = self.check(path)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("site pit: surveys in different CRS (EPSG:32629: here; EPSG:32631: there)",
                      r.stderr)
        self.assertIn("1 problem(s)", r.stderr)  # site far alone in zone 31 is fine
        ok = self.write("crs-ok.yaml", "campaign: crs\nsite: pit\nsurveys:\n"
                        "  - {name: here, inputs: [s/log]}\n"
                        "  - {name: other-pit, site: far, inputs: [s/log], config: zone31.yaml}\n")
        r = self.check(ok)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("here: site pit, EPSG:32629", r.stdout)
        self.assertIn("other-pit: site far, EPSG:32631", r.stdout)

    def test_tile_problems_are_named_at_start(self):
        self.write("small-tiles.yaml", "tiles:\n  enabled: true\n  tile_size_m: 5\n"
                   "  overlap_m: 0.5\nfuse:\n  voxel_size_m: 0.1\n  truncation_m: 1.5\n")
        path = self.write("tiles.yaml", """
campaign: tiles
surveys:
  - {name: small, inputs: [s/log], config: small-tiles.yaml, tiles: true}
  - {name: untiled, inputs: [s/log], tiles: true}
  - {name: gone, inputs: [nowhere/log]}
""")
        r = self.check(path)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        for e in ["survey small: pitmap info failed: ",
                  "tiles.tile_size_m (5 m) is too small for fuse.voxel_size_m (0.1 m)",
                  "tiles.overlap_m (0.5 m) is below fuse.truncation_m (1.5 m)",
                  "survey untiled: tiles: true needs a config with tiles: enabled: true",
                  "survey gone: input nowhere/log does not exist"]:
            self.assertIn(e, r.stderr)
        self.assertIn("4 problem(s)", r.stderr)
        out = os.path.join(self.work, "tiles-out")
        r = sh([os.path.join(ARGS.bin, "pitmap-campaign"), "run", path, "--out", out])
        self.assertEqual(r.returncode, 2)
        self.assertIn("tiles.tile_size_m (5 m) is too small", r.stderr)
        self.assertFalse(os.path.exists(out))

    def test_not_a_campaign(self):
        r = self.check(self.write("list.yaml", "- a\n- b\n"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("not a YAML mapping", r.stderr)
        r = self.check(os.path.join(self.work, "absent.yaml"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("the campaign file does not exist", r.stderr)
        r = self.check(self.write("empty.yaml", "campaign: x\nsurveys: []\n"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("surveys: a list of at least one survey is required", r.stderr)


def survey_jobs(log_text):
    """{jobid: survey} of the survey jobs Snakemake started, and the surveys it finished."""
    started = {}
    for block in re.split(r"\n\[[^\]]+\]\n", log_text):
        m = re.search(r"^rule survey:\n", block, re.MULTILINE)
        if not m:
            continue
        jid = re.search(r"^\s+jobid: (\d+)$", block, re.MULTILINE)
        name = re.search(r"^\s+wildcards: survey=(\S+)$", block, re.MULTILINE)
        started[int(jid.group(1))] = name.group(1)
    finished = {started[int(j)] for j in re.findall(r"^Finished job (\d+)\.$", log_text,
                                                        re.MULTILINE) if int(j) in started}
    return started, finished


def read(path):
    with open(path, errors="replace") as f:
        return f.read()


def wait_for(what, predicate):
    """Polls predicate() until it is true; fails after WAIT_LIMIT_S (a hang, not a timing)."""
    deadline = time.monotonic() + WAIT_LIMIT_S
    while time.monotonic() < deadline:
        v = predicate()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"gave up waiting for {what}")


def running_survey(out):
    """(pid, survey) of a `pitmap run` working in out/surveys/, or None."""
    target = os.path.join(out, "surveys") + "/"
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            argv = read(f"/proc/{pid}/cmdline").split("\0")
        except OSError:
            continue
        if len(argv) > 3 and os.path.basename(argv[0]) == "pitmap" and argv[1] == "run":
            try:
                cwd = os.readlink(f"/proc/{pid}/cwd")  # Snakemake's: the output folder
            except OSError:
                continue
            for i, a in enumerate(argv[:-1]):
                if a == "--out" and os.path.join(cwd, argv[i + 1]).startswith(target):
                    return int(pid), os.path.basename(os.path.normpath(argv[i + 1]))
    return None


class RunTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not shutil.which("snakemake"):
            raise AssertionError("snakemake is not installed: run tools/install-deps.sh")
        cls.work = os.path.join(ARGS.work, "run")
        shutil.rmtree(cls.work, ignore_errors=True)
        os.makedirs(cls.work)
        env = dict(os.environ, BIN_DIR=ARGS.bin)
        r = sh([os.path.join(ARGS.source, "tools/campaign/example/make-example.sh"), cls.work,
                "30"], env=env)
        assert r.returncode == 0, r.stdout + r.stderr
        cls.campaign_file = os.path.join(cls.work, "campaign.yaml")
        cls.campaign = lib().load(cls.campaign_file)
        # Each survey alone: the same `pitmap run` command the workflow runs, by hand.
        cls.alone = os.path.join(cls.work, "alone")
        for sv in cls.campaign["surveys"]:
            r = sh([os.path.join(ARGS.bin, "pitmap"), "run", *lib().run_args(sv), "--out",
                    os.path.join(cls.alone, sv["name"])])
            assert r.returncode == 0, r.stderr[-2000:]

    def launcher(self, out, *extra):
        return [os.path.join(ARGS.bin, "pitmap-campaign"), "run", self.campaign_file, "--out",
                out, *extra]

    def assert_same_as_alone(self, out):
        for sv in self.campaign["surveys"]:
            diff = product_compare.differences(os.path.join(self.alone, sv["name"]),
                                               os.path.join(out, "surveys", sv["name"]))
            self.assertEqual(diff, [], sv["name"])

    def test_two_workers_give_the_products_of_each_survey_alone(self):
        out = os.path.join(self.work, "out")
        r = sh(self.launcher(out, "--cores", "2"))
        self.assertEqual(r.returncode, 0, r.stderr[-3000:])
        names = [sv["name"] for sv in self.campaign["surveys"]]
        started, finished = survey_jobs(r.stderr)
        self.assertEqual(sorted(started.values()), sorted(names))
        self.assertEqual(finished, set(names))
        # Two workers: two survey jobs started before the first one finished.
        before_first = r.stderr.split("Finished job", 1)[0]
        self.assertEqual(len(survey_jobs(before_first)[0]), 2)
        self.assert_same_as_alone(out)
        # The comparison can fail: two different surveys differ.
        self.assertNotEqual(product_compare.differences(
            os.path.join(self.alone, names[0]), os.path.join(self.alone, names[1])), [])
        # The campaign table: one row per survey, from its summary.json.
        with open(os.path.join(out, "campaign_summary.json")) as f:
            table = json.load(f)
        self.assertEqual([row["survey"] for row in table["surveys"]], names)
        for row in table["surveys"]:
            with open(os.path.join(out, "surveys", row["survey"], "summary.json")) as f:
                s = json.load(f)
            self.assertEqual(row["soundings"], s["soundings"]["total"])
            self.assertEqual(row["crs"], f"EPSG:{s['utm']['epsg']}")
        self.assertEqual(len(read(os.path.join(out, "campaign_summary.csv")).splitlines()),
                         1 + len(names))
        # Run again: nothing to do.
        r = sh(self.launcher(out, "--cores", "2"))
        self.assertEqual(r.returncode, 0, r.stderr[-3000:])
        self.assertIn("Nothing to be done", r.stderr)

    def test_restart_redoes_only_the_unfinished_jobs(self):
        out = os.path.join(self.work, "out-restart")
        log1 = os.path.join(self.work, "restart-1.log")
        # One worker, so that "mid-run" has finished, running and waiting jobs.
        with open(log1, "w") as f:
            p = subprocess.Popen(self.launcher(out, "--cores", "1"), stdout=f, stderr=f,
                                 start_new_session=True)
        try:
            # First survey done: kill the worker of the second (its job fails; the others go on).
            wait_for("a first finished survey", lambda: survey_jobs(read(log1))[1])
            first_done = survey_jobs(read(log1))[1]
            pid, killed_worker = wait_for(
                "a second survey running",
                lambda: (lambda r: r if r and r[1] not in first_done else None)(running_survey(out)))
            os.kill(pid, signal.SIGKILL)
            # Another survey done, the next one running: kill the whole run (Snakemake too).
            wait_for("a second finished survey",
                     lambda: len(survey_jobs(read(log1))[1]) >= 2)
            done = survey_jobs(read(log1))[1]
            wait_for("a last survey running",
                     lambda: (lambda r: r if r and r[1] not in done | {killed_worker} else None)(
                         running_survey(out)))
            done = survey_jobs(read(log1))[1]
            os.killpg(p.pid, signal.SIGKILL)
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        names = {sv["name"] for sv in self.campaign["surveys"]}
        self.assertNotIn(killed_worker, done)
        self.assertTrue(2 <= len(done) < len(names), done)
        self.assertIn(f"Error in rule survey", read(log1))
        mtimes = {n: os.stat(os.path.join(out, "surveys", n, "summary.json")).st_mtime_ns
                  for n in done}

        r = sh(self.launcher(out, "--cores", "2"))
        self.assertEqual(r.returncode, 0, r.stderr[-3000:])
        started, finished = survey_jobs(r.stderr)
        # Only the unfinished surveys ran again, each once: the killed worker's and the one
        # the kill interrupted (and any the kill left waiting).
        self.assertEqual(sorted(started.values()), sorted(names - done))
        self.assertIn(killed_worker, started.values())
        self.assertEqual(finished, names - done)
        for n in done:
            self.assertEqual(os.stat(os.path.join(out, "surveys", n, "summary.json")).st_mtime_ns,
                             mtimes[n], n)
        self.assertTrue(os.path.isfile(os.path.join(out, "campaign_summary.csv")))
        self.assert_same_as_alone(out)


def jobs_of(log_text):
    """The jobs Snakemake started, in order, as {jobid: (rule, wildcards)} (wildcards as
    "k=v, ..."), and the finished ones as a set of (rule, wildcards)."""
    started = {}
    for block in re.split(r"\n\[[^\]]+\]\n", log_text):
        m = re.search(r"^(?:rule|checkpoint) (\w+):\n", block, re.MULTILINE)
        jid = re.search(r"^\s+jobid: (\d+)$", block, re.MULTILINE)
        if not m or not jid:
            continue
        wc = re.search(r"^\s+wildcards: (.+)$", block, re.MULTILINE)
        started[int(jid.group(1))] = (m.group(1), wc.group(1) if wc else "")
    finished = [started[int(j)] for j in re.findall(r"^Finished job (\d+)\.$", log_text,
                                                    re.MULTILINE) if int(j) in started]
    return started, finished


TILE_RULES = ("dem_tile", "tsdf_tile")


def running_tile_job(out):
    """(pid, (rule, wildcards)) of a `pitmap grid|fuse --tile` working in out/surveys/, or None."""
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            argv = read(f"/proc/{pid}/cmdline").split("\0")
            cwd = os.readlink(f"/proc/{pid}/cwd")
        except OSError:
            continue
        if len(argv) < 3 or os.path.basename(argv[0]) != "pitmap" or \
                argv[1] not in ("grid", "fuse") or os.path.realpath(cwd) != os.path.realpath(out):
            continue
        tile = [a[len("--tile="):] for a in argv if a.startswith("--tile=")]
        folder = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == "--out"]
        if tile and folder:
            survey = os.path.basename(os.path.normpath(folder[0]))
            rule = "dem_tile" if argv[1] == "grid" else "tsdf_tile"
            return int(pid), (rule, f"tiled={survey}, tile={lib().tile_name(tile[0])}")
    return None


class TilesTest(unittest.TestCase):
    """A survey by tiles (campaign-tiles.yaml: epoch1 by tiles, epoch2 whole) with 2 workers:
    its stages, every DEM and TSDF tile and the merge each a job; a tile job's worker killed
    and then the whole run, the restart runs exactly the unfinished jobs; the merged DEM and
    TSDF equal `pitmap grid` and `pitmap fuse` of the whole survey on a copy of its folder."""

    @classmethod
    def setUpClass(cls):
        if not shutil.which("snakemake"):
            raise AssertionError("snakemake is not installed: run tools/install-deps.sh")
        cls.work = os.path.join(ARGS.work, "tiles")
        shutil.rmtree(cls.work, ignore_errors=True)
        os.makedirs(cls.work)
        env = dict(os.environ, BIN_DIR=ARGS.bin)
        r = sh([os.path.join(ARGS.source, "tools/campaign/example/make-example.sh"), cls.work,
                "30"], env=env)
        assert r.returncode == 0, r.stdout + r.stderr
        cls.campaign_file = os.path.join(cls.work, "campaign-tiles.yaml")

    def launcher(self, out, *extra):
        return [os.path.join(ARGS.bin, "pitmap-campaign"), "run", self.campaign_file, "--out",
                out, *extra]

    def test_tile_jobs_two_workers_restart_and_products(self):
        out = os.path.join(self.work, "out")
        log1 = os.path.join(self.work, "run-1.log")
        with open(log1, "w") as f:
            p = subprocess.Popen(self.launcher(out, "--cores", "2"), stdout=f, stderr=f,
                                 start_new_session=True)
        killed = None
        try:
            def tiles_done():
                return [j for j in jobs_of(read(log1))[1] if j[0] in TILE_RULES]
            # Two tile jobs done: kill the worker of a running one (its job fails, the others
            # go on), then, one more tile job done, the whole run (Snakemake too).
            wait_for("two finished tile jobs", lambda: len(tiles_done()) >= 2)
            done = set(tiles_done())
            pid, killed = wait_for("a tile job running", lambda: (
                lambda r: r if r and r[1] not in done else None)(running_tile_job(out)))
            os.kill(pid, signal.SIGKILL)
            n = len(tiles_done())
            wait_for("another finished tile job", lambda: len(tiles_done()) > n or
                     p.poll() is not None)
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        text1 = read(log1)
        started1, finished1 = jobs_of(text1)
        self.assertNotIn(killed, finished1)
        self.assertIn("Error in rule " + killed[0], text1)
        # Two workers: two tile jobs started before the first tile job finished.
        tile_ids = [j for j, (rule, _) in started1.items() if rule in TILE_RULES]
        first_finish = min(text1.find(f"Finished job {j}.") for j in tile_ids
                           if f"Finished job {j}." in text1)
        self.assertGreaterEqual(sum(1 for j in tile_ids if text1.find(f"jobid: {j}\n") <
                                    first_finish), 2)
        survey = os.path.join(out, "surveys", "epoch1-tiles")
        outputs = {}
        for rule, wc in finished1:
            if rule in TILE_RULES:
                tile = wc.split("tile=")[1]
                f = (f"tiles/dem/dem_{tile}.tif" if rule == "dem_tile"
                     else f"tiles/tsdf/tsdf_{tile}.vdb")
                outputs[f] = os.stat(os.path.join(survey, f)).st_mtime_ns

        r = sh(self.launcher(out, "--cores", "2"))
        self.assertEqual(r.returncode, 0, r.stderr[-3000:])
        started2, finished2 = jobs_of(r.stderr)
        ran2 = sorted(started2.values())
        # Exactly the unfinished jobs, each once; the killed tile among them.
        self.assertEqual(len(ran2), len(set(ran2)), ran2)
        self.assertFalse(set(ran2) & set(finished1), sorted(set(ran2) & set(finished1)))
        self.assertIn(killed, ran2)
        self.assertEqual(sorted(finished2), ran2)
        for f, mtime in outputs.items():
            self.assertEqual(os.stat(os.path.join(survey, f)).st_mtime_ns, mtime, f)
        # Every tile of the survey's lists was a job of its own; one model job, one merge.
        # (Started, not finished: a job that ended just before the kill may not have been
        # logged as finished, and its complete outputs are rightly kept.)
        every = set(started1.values()) | set(started2.values())
        L = lib()
        grid = L.read_tile_list(os.path.join(out, "tilelists/epoch1-tiles/grid.txt"))
        fuse = L.read_tile_list(os.path.join(out, "tilelists/epoch1-tiles/fuse.txt"))
        self.assertGreaterEqual(len(grid), 4)
        self.assertGreaterEqual(len(fuse), 4)
        for rule, names in (("dem_tile", grid), ("tsdf_tile", fuse)):
            self.assertEqual(sorted(wc for r_, wc in every if r_ == rule),
                             sorted(f"tiled=epoch1-tiles, tile={t}" for t in names))
        for rule in ("survey_tiles", "merge_tiles"):
            self.assertEqual([wc for r_, wc in every if r_ == rule], ["tiled=epoch1-tiles"])
        self.assertIn(("survey", "survey=epoch2"), every)
        with open(os.path.join(out, "campaign_summary.json")) as f:
            rows = json.load(f)["surveys"]
        self.assertEqual([row["survey"] for row in rows], ["epoch1-tiles", "epoch2"])

        # The merged products against the whole survey's on a copy of the folder.
        copy = os.path.join(self.work, "whole")
        shutil.rmtree(copy, ignore_errors=True)
        shutil.copytree(survey, copy, ignore=shutil.ignore_patterns("tiles", "tsdf.vdb", "mesh*"))
        config = os.path.join(self.work, "tiles.yaml")
        for stage in ("grid", "fuse"):
            r = sh([os.path.join(ARGS.bin, "pitmap"), stage, "--out", copy, "--config", config])
            self.assertEqual(r.returncode, 0, r.stderr[-2000:])
        from osgeo import gdal
        gdal.UseExceptions()
        vrt, dem = gdal.Open(os.path.join(survey, "tiles/dem.vrt")), \
            gdal.Open(os.path.join(copy, "dem.tif"))
        # (GDAL computes the VRT's resolution as its extent over its size: 1 ulp off.)
        gv, gd = vrt.GetGeoTransform(), dem.GetGeoTransform()
        self.assertEqual((gv[0], gv[3]), (gd[0], gd[3]))
        for k in (1, 5):
            self.assertAlmostEqual(gv[k], gd[k], delta=1e-9 * abs(gd[k]))
        self.assertEqual((vrt.RasterXSize, vrt.RasterYSize), (dem.RasterXSize, dem.RasterYSize))
        self.assertEqual(vrt.RasterCount, dem.RasterCount)
        for b in range(1, vrt.RasterCount + 1):
            x = vrt.GetRasterBand(b).ReadAsArray().tobytes()
            y = dem.GetRasterBand(b).ReadAsArray().tobytes()
            self.assertEqual(x, y, f"band {b}")
        rid = product_compare.run_id(survey)
        self.assertTrue(product_compare._same_file(
            "tsdf.vdb", os.path.join(survey, "tsdf.vdb"), os.path.join(copy, "tsdf.vdb"), rid,
            product_compare.run_id(copy)), "the merged tsdf.vdb is not the whole survey's")


def main():
    global ARGS
    p = argparse.ArgumentParser()
    p.add_argument("--bin", required=True)
    p.add_argument("--source", required=True)
    p.add_argument("--work", required=True)
    ARGS, rest = p.parse_known_args()
    ARGS.bin = os.path.abspath(ARGS.bin)
    ARGS.work = os.path.abspath(ARGS.work)
    os.makedirs(ARGS.work, exist_ok=True)
    unittest.main(argv=[sys.argv[0]] + rest)


if __name__ == "__main__":
    main()
