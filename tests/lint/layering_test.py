#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The processor's module layering (docs/architecture.md, "Modules and what each may use").

Reads every `#include "processor/<module>/..."` of each processor module (processor/<module>/)
and the `pitmap::proc_<module>` libraries its CMakeLists.txt links, and checks them against
ALLOWED below; also that no processor file includes firmware_host/ or tools/, and that only the
modules in MAY_LINK_LCM link LCM. Prints each violation with its file and line; exit status 1
when there is any. `--self-test` plants violations in a scratch tree and fails unless each is
found. Python 3, standard library only.
"""
import argparse
import pathlib
import re
import sys
import tempfile

# Module -> the processor modules it may use (common/ and the third-party libraries are open to
# every module). Keep it in step with docs/architecture.md.
ALLOWED = {
    "svp": set(),  # sound-velocity casts and ray tracing: pure
    "survey": {"svp"},  # the survey model: its data types and file; svp for the refraction record
    "registration": set(),
    "georef": {"survey", "svp"},
    "io": {"survey", "georef", "svp"},
    "calib": {"survey", "georef", "registration"},
    "slam": {"registration"},
    "compare": {"registration"},  # pitmap compare: co-registration and change of two surveys
    "clean": {"survey", "georef"},
    "fusion": set(),
    "mesh": {"fusion"},
    "hydro": {"survey", "georef", "svp"},
    "pipeline": {"survey", "georef", "svp", "io", "calib", "slam", "clean", "fusion", "mesh",
                 "hydro", "registration", "compare"},
    "live": {"survey", "georef", "svp", "io", "hydro"},
    "edit": {"survey", "georef", "svp", "io", "hydro", "live"},
    "apps": {"survey", "georef", "svp", "io", "calib", "slam", "clean", "fusion", "mesh",
             "hydro", "registration", "compare", "pipeline", "live", "edit"},
}
# The modules that may link LCM (pitmap::lcmtypes, pitmap::lcmlog): the style guide's "no stage
# links LCM".
MAY_LINK_LCM = {"io", "live", "apps"}
FORBIDDEN_ROOTS = ("firmware_host/", "tools/")
SOURCE_SUFFIXES = {".hpp", ".cpp", ".h", ".in"}

INCLUDE_RE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
LINK_RE = re.compile(r"target_link_libraries\s*\(([^)]*)\)", re.S)
PROC_LIB_RE = re.compile(r"pitmap::proc_([a-z_]+)")
LCM_LIB_RE = re.compile(r"pitmap::(lcmtypes|lcmlog)\b")


def module_of_library(name):
    """proc_live_http -> live: the longest module name the library name starts with."""
    best = None
    for m in ALLOWED:
        if name == m or name.startswith(m + "_"):
            if best is None or len(m) > len(best):
                best = m
    return best


def check_table():
    problems = []
    for m, deps in ALLOWED.items():
        for d in sorted(deps - set(ALLOWED)):
            problems.append(f"layering table: {m} names unknown module {d}")
    # The table itself must be a DAG: a cycle would allow two modules to need each other.
    state = {}

    def visit(m, path):
        if state.get(m) == "done":
            return
        if state.get(m) == "open":
            problems.append("layering table: cycle " + " -> ".join(path + [m]))
            return
        state[m] = "open"
        for d in sorted(ALLOWED[m]):
            if d in ALLOWED:
                visit(d, path + [m])
        state[m] = "done"

    for m in sorted(ALLOWED):
        visit(m, [])
    return problems


def allowed_text(module):
    deps = sorted(ALLOWED[module])
    return ", ".join(deps + ["common"]) if deps else "common only"


def check_tree(root):
    """Returns the violations under root/processor, as strings."""
    root = pathlib.Path(root)
    proc = root / "processor"
    problems = check_table()
    modules = sorted(p.name for p in proc.iterdir() if p.is_dir())
    for module in modules:
        if module not in ALLOWED:
            problems.append(f"processor/{module}/: a module without a row in the layering table "
                            f"({pathlib.Path(__file__).name} ALLOWED, docs/architecture.md)")
            continue
        for path in sorted((proc / module).rglob("*")):
            if not path.is_file() or path.suffix not in SOURCE_SUFFIXES:
                continue
            rel = path.relative_to(root).as_posix()
            lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
            for number, line in enumerate(lines, 1):
                m = INCLUDE_RE.match(line)
                if not m:
                    continue
                target = m.group(1)
                if target.startswith(FORBIDDEN_ROOTS):
                    problems.append(f"{rel}:{number}: the processor may not include {target}")
                    continue
                parts = target.split("/")
                if len(parts) < 3 or parts[0] != "processor":
                    continue
                used = parts[1]
                if used == module:
                    continue
                if used not in ALLOWED[module]:
                    problems.append(f"{rel}:{number}: {module} may not include {target} "
                                    f"({module} may use: {allowed_text(module)})")
        cmake = proc / module / "CMakeLists.txt"
        if cmake.is_file():
            text = cmake.read_text(encoding="utf-8")
            rel = cmake.relative_to(root).as_posix()
            for call in LINK_RE.finditer(text):
                number = text.count("\n", 0, call.start()) + 1
                body = call.group(1)
                for lib in PROC_LIB_RE.findall(body):
                    used = module_of_library(lib)
                    if used is None:
                        problems.append(f"{rel}:{number}: links pitmap::proc_{lib}, "
                                        f"which belongs to no module of the layering table")
                    elif used != module and used not in ALLOWED[module]:
                        problems.append(f"{rel}:{number}: {module} may not link "
                                        f"pitmap::proc_{lib} ({module} may use: "
                                        f"{allowed_text(module)})")
                for lib in LCM_LIB_RE.findall(body):
                    if module not in MAY_LINK_LCM:
                        problems.append(f"{rel}:{number}: {module} may not link pitmap::{lib} "
                                        f"(only {', '.join(sorted(MAY_LINK_LCM))} link LCM)")
    return problems


def self_test():
    """Plants one violation of each kind in a scratch copy of a small tree; each must be found."""
    plants = {
        "processor/survey/model.hpp": '#include "processor/io/ingest.hpp"\n',
        "processor/survey/CMakeLists.txt":
            "target_link_libraries(pitmap_proc_survey\n  PUBLIC pitmap::proc_georef)\n",
        "processor/georef/georef.cpp": '#include "firmware_host/io/byte_source.hpp"\n',
        "processor/hydro/CMakeLists.txt":
            "target_link_libraries(pitmap_proc_hydro PRIVATE pitmap::lcmtypes)\n",
        "processor/newstage/stage.cpp": '#include "processor/survey/survey.hpp"\n',
        # Allowed: must not be reported.
        "processor/io/ingest.hpp": '#include "processor/survey/series.hpp"\n',
        "processor/live/CMakeLists.txt":
            "target_link_libraries(pitmap_proc_live_http PUBLIC pitmap::proc_live)\n",
    }
    expected = [
        "processor/survey/model.hpp:1: survey may not include processor/io/ingest.hpp",
        "processor/survey/CMakeLists.txt:1: survey may not link pitmap::proc_georef",
        "processor/georef/georef.cpp:1: the processor may not include firmware_host/",
        "processor/hydro/CMakeLists.txt:1: hydro may not link pitmap::lcmtypes",
        "processor/newstage/: a module without a row",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for rel, text in plants.items():
            path = pathlib.Path(tmp) / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        found = check_tree(tmp)
    failures = [e for e in expected if not any(p.startswith(e) for p in found)]
    unexpected = [p for p in found if not any(p.startswith(e) for e in expected)]
    for e in failures:
        print(f"layering self-test: not found: {e}")
    for p in unexpected:
        print(f"layering self-test: reported although allowed: {p}")
    if failures or unexpected:
        return 1
    print(f"layering self-test: all {len(expected)} planted violations found, nothing else")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default=str(pathlib.Path(__file__).resolve().parents[2]),
                        help="the repository root (default: this checkout)")
    parser.add_argument("--self-test", action="store_true",
                        help="check the checker on planted violations")
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    problems = check_tree(args.source)
    for p in problems:
        print(p)
    if problems:
        print(f"layering: {len(problems)} violation(s) of the processor's module layering "
              f"(tests/lint/layering_test.py, docs/architecture.md)")
        return 1
    print(f"layering: {len(ALLOWED)} modules, every include and link as the table allows")
    return 0


if __name__ == "__main__":
    sys.exit(main())
