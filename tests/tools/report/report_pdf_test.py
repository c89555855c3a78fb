#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""pitmap-report --pdf: report.pdf printed by headless Chromium (Page.printToPDF over
tools/browser/cdp.py's pipe) from report.html of the synthetic products
(report_test.WriteProducts with report_test.METADATA).

Fails when the PDF is missing or not a PDF, when its title is not the report's (the
metadata's project, site and survey id), or when it has fewer pages than the client's
sections (the print CSS starts each section on a new page). Exit 77 (ctest skip) only when
Chromium cannot start here.

Usage: report_pdf_test.py --report BIN/pitmap-report --source SOURCE_DIR --work DIR"""

import argparse
import os
import re
import shutil
import subprocess
import sys


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def pdf_title(data):
    """The document information dictionary's /Title: a literal string, or UTF-16 in hex."""
    m = re.search(rb"/Title\s*(\((?:\\.|[^\\)])*\)|<[0-9A-Fa-f]+>)", data)
    if not m:
        return None
    raw = m.group(1)
    if raw.startswith(b"<"):
        b = bytes.fromhex(raw[1:-1].decode("ascii"))
        return b[2:].decode("utf-16-be") if b.startswith(b"\xfe\xff") else b.decode("latin-1")
    return re.sub(rb"\\(.)", rb"\1", raw[1:-1]).decode("latin-1")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--work", required=True)
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.source, "tests", "tools", "report"))
    import report_test  # noqa: E402  (writes the synthetic products)

    if shutil.which("chromium") is None and shutil.which("chromium-browser") is None:
        print("SKIP: chromium is not installed")
        sys.exit(77)
    shutil.rmtree(args.work, ignore_errors=True)
    products = os.path.join(args.work, "products")
    os.makedirs(products)
    report_test.WriteProducts(products, full=True, metadata=report_test.METADATA)
    r = subprocess.run(["/usr/bin/python3", args.report, products, "--pdf"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        if "did not answer on the DevTools pipe" in r.stderr:
            print("SKIP: " + r.stderr.strip().splitlines()[-1])
            sys.exit(77)
        fail("pitmap-report --pdf failed: " + r.stderr[-2000:])
    path = os.path.join(products, "report.pdf")
    if not os.path.isfile(path):
        fail("no report.pdf")
    with open(path, "rb") as f:
        data = f.read()
    if not data.startswith(b"%PDF-") or b"%%EOF" not in data[-64:]:
        fail("report.pdf is not a whole PDF")
    pages = len(re.findall(rb"/Type\s*/Page\b", data))
    with open(os.path.join(products, "report.html"), encoding="utf-8") as f:
        sections = re.findall(r'<section id="([^"]+)">', f.read())
    title = pdf_title(data)
    print("report.pdf: %d kB, %d pages, %d sections, title %r" % (len(data) // 1024, pages,
                                                                   len(sections), title))
    want = "Pit 7 <north> lake \u2013 Bejanca \u2013 BJ-2026-06"
    if title != want:
        fail("the PDF's title is %r, not %r" % (title, want))
    if pages < len(sections):
        fail("%d pages for %d sections: the print CSS does not start each section on a page"
             % (pages, len(sections)))
    if os.path.exists(path + ".tmp"):
        fail("report.pdf.tmp left behind")
    print("PASS")


if __name__ == "__main__":
    main()
