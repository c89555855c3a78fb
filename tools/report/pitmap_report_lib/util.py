# SPDX-License-Identifier: MIT
"""Logging, errors and HTML helpers shared by every part of pitmap-report."""

import base64
import ctypes
import datetime
import html
import math
import os
import re
import resource
import signal
import sys
import time

import numpy as np

PROG = "pitmap-report"
# The folder of the pitmap-report program (build/bin, or tools/report in the source tree).
PROGRAM_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
START_TIME = time.monotonic()

GPS_EPOCH_UNIX_S = 315964800  # 1980-01-06 00:00:00 UTC
# GPS - UTC comes from summary.json "time" (written by `pitmap georef` from the receiver's TIME
# log or the C++ leap-second table, common/gps_time): the report keeps no table of its own.


PR_SET_PDEATHSIG = 1  # <sys/prctl.h>


def die_with_parent(parent_pid=None):
    """SIGTERM unblocked and at its default action (an inherited blocked or ignored SIGTERM
    passes through fork and exec: such a process is deaf to `kill`), and SIGTERM from the kernel
    when the parent dies (prctl PR_SET_PDEATHSIG), so that a report whose pitmap was killed, or
    a section worker whose report was, does not run on alone. With `parent_pid`, a parent that
    died before the prctl (the process was re-parented already) ends this process at once.
    Linux only; elsewhere a no-op."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):
        return
    if parent_pid is not None and os.getppid() != parent_pid:
        os.kill(os.getpid(), signal.SIGTERM)


def peak_rss_mb():
    """VmHWM of this process. Linux carries ru_maxrss across exec, so a report started by
    `pitmap run` would show the pipeline's peak there; VmHWM starts afresh."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def log(msg):
    print(f"{PROG}: [{time.monotonic() - START_TIME:6.1f} s, {peak_rss_mb():5.0f} MB] {msg}",
          file=sys.stderr, flush=True)


class ReportError(Exception):
    """A products folder that cannot be reported on at all."""


def inline_script(js):
    """JavaScript made safe to inline in <script>: no "</script", and no http(s) URL in the
    report (three.js has a namespace string and comments with URLs; none is fetched)."""
    js = re.sub(r"(?i)</script", r"<\\/script", js)
    js = js.replace('"http://www.w3.org/1999/xhtml"', '"htt"+"p://www.w3.org/1999/xhtml"')
    return re.sub(r"(?i)\bhttp(s?):", r"hxxp\1:", js)


def b64(a):
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def gps_to_utc(gps_s, gps_minus_utc_s):
    """GPS seconds since 1980-01-06 -> UTC datetime, with GPS - UTC as summary.json gives it."""
    return datetime.datetime.fromtimestamp(gps_s + GPS_EPOCH_UNIX_S - gps_minus_utc_s,
                                           datetime.timezone.utc)


def esc(v):
    return html.escape(str(v))


def num(v, digits=3):
    """Number formatting for tables: integers with thin grouping, floats to `digits`."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}".replace(",", "\u2009")
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        if v != 0 and (abs(v) >= 1e6 or abs(v) < 10 ** (-digits)):
            return f"{v:.{digits}g}"
        return f"{v:.{digits}f}"
    return esc(v)


def not_produced(what, why=""):
    because = f" ({esc(why)})" if why else ""
    return f'<p class="missing">not produced: {esc(what)}{because}</p>'


def table(rows, header=None, cls=""):
    out = [f'<table class="{cls}">' if cls else "<table>"]
    if header:
        out.append("<tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>")
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def facts_table(rows):
    """A two-column table of (label, HTML value) rows, the label in bold."""
    return table([(f"<b>{esc(k)}</b>", v) for k, v in rows], cls="facts")


# An absolute path of this machine: "/" then folders, not after a word character, a dot, a
# colon or a slash (URLs, fractions, "km/h"), up to its last part.
_ABSOLUTE_PATH = re.compile(r"(?<![\w.:/])/(?:[^\s/<>\"'(),;]+/)+([^\s/<>\"'(),;]+)")


def strip_paths(text):
    """Text with every absolute path cut to its file name (the client's report names inputs by
    file name only)."""
    return _ABSOLUTE_PATH.sub(r"\1", str(text))
