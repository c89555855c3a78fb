#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""docs/benchmarks.md is what tools/bench/benchmarks_page.py makes of docs/benchmarks/, and the
renderer finds what it must: a page edited by hand, an unknown placeholder, a result that cannot
make its table, a result not measured yet, a machine path left in a result."""

import json
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "tools", "bench"))
import benchmarks_page  # noqa: E402

SCRIPT = os.path.join(ROOT, "tools", "bench", "benchmarks_page.py")

LIVE = {"speed": 1.0, "events": 10, "data_seconds": 60.0, "wall_seconds": 60.0,
        "pings_timed": 600, "page_poll_s": 0.8,
        "server_latency_s": {"mean": 0.075, "p50": 0.074, "p95": 0.078, "p99": 0.079, "max": 0.19},
        "documents_build_s": {"p50": 0.0005, "p99": 0.0009, "polls": 75},
        "ping_to_page_s": {"mean": 0.4755, "worst": 0.8799}}


class RenderTest(unittest.TestCase):
    def run_script(self, *args):
        return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True)

    def test_the_committed_page_is_current(self):
        r = self.run_script("render", "--check")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_a_page_edited_by_hand_fails_the_check(self):
        with tempfile.TemporaryDirectory() as d:
            page = os.path.join(d, "benchmarks.md")
            with open(os.path.join(ROOT, "docs", "benchmarks.md")) as f:
                text = f.read()
            with open(page, "w") as f:
                f.write(text.replace("Benchmarks", "Benchmarks (edited)", 1))
            r = self.run_script("render", "--check", "--page", page)
            self.assertEqual(r.returncode, 1)
            self.assertIn("edit those", r.stderr)

    def test_figures_come_from_the_result(self):
        page = benchmarks_page.render("{{live.context}}\n{{live.latency}}\n",
                                      {"live": dict(LIVE, context={"commit": "abc1234"})})
        self.assertIn("`abc1234`", page)
        self.assertIn("0.075 s", page)   # the server's mean latency
        self.assertIn("0.880 s", page)   # the worst ping to page
        self.assertIn("| a ping on the server", page)

    def test_a_result_not_measured_says_so_once(self):
        page = benchmarks_page.render("{{e2e.context}}\n{{e2e.stages}}\n{{e2e.scores}}\n", {})
        self.assertEqual(page.count("Not measured yet"), 1)
        self.assertIn("tools/bench/run-benchmarks.sh e2e", page)

    def test_an_unknown_placeholder_is_an_error(self):
        with self.assertRaises(SystemExit) as e:
            benchmarks_page.render("{{e2e.nonsense}}\n", {})
        self.assertIn("unknown placeholder", str(e.exception))

    def test_a_result_that_cannot_make_its_table_is_an_error(self):
        broken = dict(LIVE)
        del broken["server_latency_s"]
        with self.assertRaises(SystemExit) as e:
            benchmarks_page.render("{{live.latency}}\n", {"live": broken})
        self.assertIn("live.json cannot make", str(e.exception))

    def test_the_stored_results_name_no_machine_path(self):
        for name in os.listdir(os.path.join(ROOT, "docs", "benchmarks")):
            if name.endswith(".json"):
                with open(os.path.join(ROOT, "docs", "benchmarks", name)) as f:
                    text = f.read()
                json.loads(text)
                for needle in ('"executable"', '"host_name"', "/root/", "/home/"):
                    self.assertNotIn(needle, text, name)


if __name__ == "__main__":
    unittest.main()
