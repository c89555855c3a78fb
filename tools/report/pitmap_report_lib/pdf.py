# SPDX-License-Identifier: MIT
"""report.pdf from report.html through headless Chromium's print to PDF (the DevTools
protocol's Page.printToPDF, over the pipe of tools/browser/cdp.py): A4, the page's print CSS
(each section on a new page, the interactive view left out), backgrounds printed."""

import base64
import importlib.util
import os
import shutil
import tempfile
import time

from .util import PROGRAM_DIR, ReportError

# cdp.py: beside the package when built (pitmap_report_lib/cdp.py, a copy of
# tools/browser/cdp.py), or in the source tree's tools/browser.
_CDP_PLACES = (os.path.join(PROGRAM_DIR, "pitmap_report_lib", "cdp.py"),
               os.path.join(PROGRAM_DIR, os.pardir, "browser", "cdp.py"))
LOAD_TIMEOUT_S = 60


def _cdp():
    for place in _CDP_PLACES:
        if os.path.isfile(place):
            spec = importlib.util.spec_from_file_location("pitmap_report_cdp", place)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            return mod
    raise ReportError("--pdf: the DevTools client cdp.py is not beside pitmap-report (build "
                      "the pitmap-report target)")


def write_pdf(html_path, pdf_path):
    """Prints html_path to pdf_path (written whole or not at all). Raises ReportError when
    Chromium is missing or fails."""
    cdp = _cdp()
    profile = tempfile.mkdtemp(prefix="pitmap-report-pdf-")
    try:
        try:
            browser = cdp.Browser(os.path.join(profile, "profile"))
        except cdp.BrowserUnavailable as e:
            raise ReportError(f"--pdf: {e}")
        try:
            browser.open("file://" + os.path.abspath(html_path))
            deadline = time.monotonic() + LOAD_TIMEOUT_S
            while time.monotonic() < deadline:
                state = browser.evaluate("document.readyState")
                if state == "complete":
                    break
                browser.pump(0.2)
            else:
                raise ReportError(f"--pdf: the page did not load in {LOAD_TIMEOUT_S} s")
            r = browser.call("Page.printToPDF", {
                "printBackground": True, "preferCSSPageSize": True,
                "displayHeaderFooter": True, "headerTemplate": "<span></span>",
                "footerTemplate": ('<div style="font-size:8px;width:100%;text-align:center;'
                                   'color:#777"><span class="title"></span> &middot; page '
                                   '<span class="pageNumber"></span> of '
                                   '<span class="totalPages"></span></div>'),
                "marginTop": 0.4, "marginBottom": 0.6}, timeout=180)
        except (RuntimeError, TimeoutError, EOFError) as e:
            raise ReportError(f"--pdf: Chromium could not print the page: {e}")
        finally:
            browser.close()
        data = base64.b64decode(r["data"])
        if not data.startswith(b"%PDF-"):
            raise ReportError("--pdf: Chromium's answer is not a PDF")
        tmp = pdf_path + ".tmp"
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, pdf_path)
        return len(data)
    finally:
        shutil.rmtree(profile, ignore_errors=True)
