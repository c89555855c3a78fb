# SPDX-License-Identifier: MIT
"""A pitmap campaign: a list of surveys (each with its logs or vendor files, vehicle file,
casts and config) run as a Snakemake workflow (tools/campaign/Snakefile, docs/campaigns.md).

This module reads and checks the campaign file, builds each survey's `pitmap run` command,
and writes the campaign's summary table from the surveys' summary.json. It is imported by the
Snakefile and by the launcher (pitmap-campaign); it never runs Snakemake itself.

Every problem of a campaign file is listed, not just the first (`load` returns them all):
unknown keys, missing or duplicate survey names, inputs, vehicle files, casts or configs that
are not there, wrong types, `tiles: true` without a config that enables tiles, and (with
check_crs, `pitmap info` on each survey without such a problem) every problem pitmap finds in a
survey's config (e.g. a tile size too small for the voxel size) and surveys of one site whose
products would be in different horizontal CRS (`pitmap info` says which UTM zone each survey's
georef will use).
"""
import csv
import io
import json
import os
import re
import subprocess

import yaml

# The keys a campaign file may hold (docs/campaigns.md "The campaign file").
TOP_KEYS = {"campaign", "site", "defaults", "surveys", "compare"}
# Per-survey settings that may also stand in `defaults:`.
OPTION_KEYS = {
    "config": str,            # pitmap YAML config (pitmap config --defaults)
    "report": bool,           # report.html (false: --no-report)
    "calibrate": bool,        # false: --no-calibrate
    "slam": bool,             # false: --no-slam
    "clean": bool,            # false: --no-clean
    "from_raw": bool,         # --from-raw
    "strict": bool,           # --strict: a tripped quality gate fails the job
    "sonar_clock_offset_s": (int, float),  # --sonar-clock-offset
    "svp": list,              # sound-velocity casts (--svp)
    "threads": int,           # cores the scheduler gives the survey's job
    "mem_mb": int,            # memory the scheduler reserves for it (Slurm --mem)
    "runtime_min": int,       # wall-time limit on a cluster (Slurm -t), minutes
    "tiles": bool,            # per-tile jobs: grid and fuse tile by tile (config tiles:)
}
SURVEY_KEYS = {"name", "site", "inputs", "vehicle"} | set(OPTION_KEYS)
DEFAULTS = {
    "report": True, "calibrate": True, "slam": True, "clean": True, "from_raw": False,
    "strict": False, "svp": [], "threads": 1, "mem_mb": 4000, "runtime_min": 240,
    "tiles": False,
}
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
CRS_RE = re.compile(r"^crs: EPSG:(\d+)", re.MULTILINE)


class CampaignError(Exception):
    """A campaign file that cannot be run; .problems lists every problem found."""

    def __init__(self, path, problems):
        self.path = path
        self.problems = list(problems)
        super().__init__(format_problems(path, self.problems))


def format_problems(path, problems):
    lines = [f"{path}: {len(problems)} problem(s):"]
    lines += [f"  - {p}" for p in problems]
    return "\n".join(lines)


def _type_name(t):
    names = {bool: "true or false", int: "an integer", str: "a path", list: "a list",
             (int, float): "a number"}
    return names.get(t, str(t))


def _check_type(value, t):
    if t is int or t == (int, float):
        # YAML's true/false are Python ints: not a number here.
        return isinstance(value, t) and not isinstance(value, bool)
    return isinstance(value, t)


def load(path, pitmap=None, check_crs=False):
    """The campaign of `path` as a dict (absolute paths, every option resolved):
    {"path", "name", "surveys": [{"name", "site", "inputs", "vehicle", "config", "svp",
    "report", ..., "crs"}], "sites": {site: [names in file order]}, "compare"}.
    Raises CampaignError listing every problem. check_crs runs `pitmap info` (the program
    `pitmap`) on each survey to find the CRS its products will be in: slow on long surveys
    (it reads the logs), so the launcher does it once before the workflow starts."""
    problems = []
    if not os.path.isfile(path):
        raise CampaignError(path, ["the campaign file does not exist"])
    try:
        with open(path) as f:
            doc = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise CampaignError(path, [f"not valid YAML: {e}"])
    if not isinstance(doc, dict):
        raise CampaignError(path, ["not a YAML mapping (campaign:, surveys: ...)"])
    base = os.path.dirname(os.path.abspath(path))

    def resolve(p):
        return os.path.normpath(os.path.join(base, os.path.expanduser(p)))

    for k in sorted(set(doc) - TOP_KEYS):
        problems.append(f"unknown key '{k}' (known: {', '.join(sorted(TOP_KEYS))})")
    name = doc.get("campaign")
    if not isinstance(name, str) or not NAME_RE.match(name):
        problems.append("campaign: a name is required (letters, digits, '.', '_', '-')")
        name = "campaign"
    site_default = doc.get("site", name)
    if not isinstance(site_default, str) or not NAME_RE.match(site_default):
        problems.append("site: letters, digits, '.', '_', '-'")
        site_default = name
    compare = doc.get("compare", "auto")
    if compare not in ("auto", True, False):
        problems.append("compare: auto, true or false")
    defaults = dict(DEFAULTS)
    d = doc.get("defaults", {}) or {}
    if not isinstance(d, dict):
        problems.append("defaults: a mapping of survey settings")
        d = {}
    for k, v in d.items():
        if k not in OPTION_KEYS:
            problems.append(f"defaults: unknown key '{k}' (known: {', '.join(sorted(OPTION_KEYS))})")
        elif not _check_type(v, OPTION_KEYS[k]):
            problems.append(f"defaults: {k} must be {_type_name(OPTION_KEYS[k])}")
        else:
            defaults[k] = v

    raw_surveys = doc.get("surveys")
    if not isinstance(raw_surveys, list) or not raw_surveys:
        problems.append("surveys: a list of at least one survey is required")
        raw_surveys = []
    surveys, seen = [], {}
    for i, s in enumerate(raw_surveys, 1):
        where = f"survey {i}"
        if not isinstance(s, dict):
            problems.append(f"{where}: a mapping (name:, inputs:, ...) is required")
            continue
        sname = s.get("name")
        if not isinstance(sname, str) or not NAME_RE.match(sname):
            problems.append(f"{where}: name: required, letters, digits, '.', '_', '-'")
        else:
            where = f"survey {sname}"
            if sname in seen:
                problems.append(f"{where}: the name is also survey {seen[sname]}'s")
            seen[sname] = i
        for k in sorted(set(s) - SURVEY_KEYS):
            problems.append(f"{where}: unknown key '{k}' (known: {', '.join(sorted(SURVEY_KEYS))})")
        before = len(problems)
        sv = dict(defaults)
        for k, t in OPTION_KEYS.items():
            if k in s:
                if _check_type(s[k], t):
                    sv[k] = s[k]
                else:
                    problems.append(f"{where}: {k} must be {_type_name(t)}")
        sv["name"] = sname if isinstance(sname, str) else f"survey{i}"
        site = s.get("site", site_default)
        if not isinstance(site, str) or not NAME_RE.match(site):
            problems.append(f"{where}: site: letters, digits, '.', '_', '-'")
            site = site_default
        sv["site"] = site
        if sv["threads"] < 1:
            problems.append(f"{where}: threads must be >= 1")
        if sv["mem_mb"] < 1:
            problems.append(f"{where}: mem_mb must be >= 1")
        if sv["runtime_min"] < 1:
            problems.append(f"{where}: runtime_min must be >= 1")

        inputs = s.get("inputs")
        if isinstance(inputs, str):
            inputs = [inputs]
        if not isinstance(inputs, list) or not inputs or not all(isinstance(x, str) for x in inputs):
            problems.append(f"{where}: inputs: the survey's logs, vendor files or folders (a list)")
            inputs = []
        sv["inputs"] = [resolve(x) for x in inputs]
        for raw, p in zip(inputs, sv["inputs"]):
            if not os.path.exists(p):
                problems.append(f"{where}: input {raw} does not exist ({p})")
            elif os.path.isdir(p) and not any(os.scandir(p)):
                problems.append(f"{where}: input folder {raw} is empty")

        vehicle = s.get("vehicle")
        if vehicle is not None and not isinstance(vehicle, str):
            problems.append(f"{where}: vehicle must be a path")
            vehicle = None
        if vehicle is not None:
            sv["vehicle"] = resolve(vehicle)
            if not os.path.isfile(sv["vehicle"]):
                problems.append(f"{where}: vehicle file {vehicle} does not exist")
        else:
            # pitmap's own default: vehicle.yaml beside the first input (inside it if a folder).
            sv["vehicle"] = None
            if sv["inputs"] and os.path.exists(sv["inputs"][0]):
                first = sv["inputs"][0]
                folder = first if os.path.isdir(first) else os.path.dirname(first)
                if not os.path.isfile(os.path.join(folder, "vehicle.yaml")):
                    problems.append(f"{where}: no vehicle file: give vehicle: or put vehicle.yaml "
                                    f"beside the first input ({folder})")

        if sv.get("config") is not None:
            raw = sv["config"]
            sv["config"] = resolve(raw)
            if not os.path.isfile(sv["config"]):
                problems.append(f"{where}: config {raw} does not exist")
        else:
            sv["config"] = None
        svp = []
        for c in sv["svp"]:
            if not isinstance(c, str):
                problems.append(f"{where}: svp: a list of cast files")
                continue
            svp.append(resolve(c))
            if not os.path.isfile(svp[-1]):
                problems.append(f"{where}: cast {c} does not exist")
        sv["svp"] = svp
        if sv["tiles"] and not _tiles_enabled(sv["config"]):
            problems.append(f"{where}: tiles: true needs a config with tiles: enabled: true "
                            "(the tile size and overlap of its per-tile jobs)")
        sv["crs"] = None
        sv["quick_problems"] = len(problems) > before
        surveys.append(sv)

    if check_crs:
        # pitmap's own checks (its config, every problem listed; the CRS) on the surveys that
        # passed the quick ones, so that one file names every problem at once.
        problems += _check_crs([sv for sv in surveys if not sv["quick_problems"]],
                               pitmap or "pitmap")
    for sv in surveys:
        del sv["quick_problems"]
    if problems:
        raise CampaignError(path, problems)
    sites = {}
    for sv in surveys:
        sites.setdefault(sv["site"], []).append(sv["name"])
    return {"path": os.path.abspath(path), "name": name, "surveys": surveys, "sites": sites,
            "compare": compare}


def _tiles_enabled(config):
    """Whether the pitmap config file `config` (None: pitmap's defaults) enables tiles."""
    if not config or not os.path.isfile(config):
        return False
    try:
        with open(config) as f:
            doc = yaml.safe_load(f)
    except (OSError, yaml.YAMLError):
        return False  # pitmap's own check (pitmap info) names what is wrong with it
    tiles = doc.get("tiles") if isinstance(doc, dict) else None
    return isinstance(tiles, dict) and tiles.get("enabled") is True


def _check_crs(surveys, pitmap):
    """`pitmap info` on each survey: its CRS (EPSG code) into sv["crs"]; the problems: a survey
    pitmap cannot read, and a site whose surveys are in different CRS."""
    problems = []
    for sv in surveys:
        cmd = [pitmap, "info", *sv["inputs"]]
        if sv["vehicle"]:
            cmd += ["--vehicle", sv["vehicle"]]
        if sv["config"]:
            cmd += ["--config", sv["config"]]
        if "sonar_clock_offset_s" in sv:
            cmd += ["--sonar-clock-offset", repr(float(sv["sonar_clock_offset_s"]))]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as e:
            return [f"cannot run {pitmap} info: {e}"]
        m = CRS_RE.search(r.stdout)
        if r.returncode != 0:
            # Every problem pitmap lists ("  - ..." lines: an invalid config, e.g. a tile size
            # too small for the voxel size), else its last line.
            lines = r.stderr.strip().splitlines() or ["(no message)"]
            listed = [ln.strip()[2:] for ln in lines if ln.startswith("  - ")]
            for err in listed or [lines[-1]]:
                problems.append(f"survey {sv['name']}: pitmap info failed: {err}")
        elif not m:
            problems.append(f"survey {sv['name']}: no navigation to place it (pitmap info "
                            "printed no crs: line)")
        else:
            sv["crs"] = f"EPSG:{m.group(1)}"
    by_site = {}
    for sv in surveys:
        if sv["crs"]:
            by_site.setdefault(sv["site"], {}).setdefault(sv["crs"], []).append(sv["name"])
    for site, crs in sorted(by_site.items()):
        if len(crs) > 1:
            parts = "; ".join(f"{c}: {', '.join(n)}" for c, n in sorted(crs.items()))
            problems.append(f"site {site}: surveys in different CRS ({parts}): the products of "
                            "one site must share a CRS (set products.origin in their configs)")
    return problems


def _input_args(sv):
    """What `pitmap run` and `pitmap georef` read for survey `sv`: its logs or vendor files, the
    vehicle file, the config, the casts and a known sonar clock offset."""
    args = list(sv["inputs"])
    if sv["vehicle"]:
        args += ["--vehicle", sv["vehicle"]]
    if sv["config"]:
        args += ["--config", sv["config"]]
    if sv["svp"]:
        args += ["--svp", *sv["svp"]]
    if "sonar_clock_offset_s" in sv:
        args += ["--sonar-clock-offset", repr(float(sv["sonar_clock_offset_s"]))]
    return args


def run_args(sv):
    """The arguments of `pitmap run` for survey `sv` after `run` (without --out)."""
    args = _input_args(sv)
    for key, flag in (("report", "--no-report"), ("calibrate", "--no-calibrate"),
                      ("slam", "--no-slam"), ("clean", "--no-clean")):
        if not sv[key]:
            args.append(flag)
    if sv["from_raw"]:
        args.append("--from-raw")
    if sv["strict"]:
        args.append("--strict")
    return args


def georef_args(sv):
    """The arguments of `pitmap georef` for survey `sv` (without --out): run's inputs."""
    args = _input_args(sv)
    if sv["from_raw"]:
        args.append("--from-raw")
    return args


def stage_commands(sv, pitmap, out):
    """A tiled survey's stages before the tiles, as commands on its folder `out`: georef, then
    calibrate, slam and clean unless turned off (docs/campaigns.md)."""
    config = ["--config", sv["config"]] if sv["config"] else []
    cmds = [[pitmap, "georef", *georef_args(sv), "--out", out]]
    for stage in ("calibrate", "slam", "clean"):
        if sv[stage]:
            cmds.append([pitmap, stage, "--out", out, *config])
    return cmds


def tile_name(ij):
    """pitmap's file name of tile "I,J" (tiles.cpp TileName: negative as m3): "m3_12"."""
    i, j = (int(v) for v in ij.split(","))
    return "_".join(("m%d" % -v) if v < 0 else str(v) for v in (i, j))


def tile_index(name):
    """The inverse of tile_name: "m3_12" -> "-3,12"."""
    return ",".join(("-" + v[1:]) if v.startswith("m") else v for v in name.split("_"))


def read_tile_list(path):
    """The tile names of a `pitmap grid|fuse --list-tiles` output file."""
    with open(path) as f:
        return [tile_name(line.strip()) for line in f if line.strip()]


def compare_pairs(campaign):
    """The repeat-survey comparisons: each survey of a site against the one before it in the
    campaign file, as {pair name: (earlier, later)}."""
    pairs = {}
    tiled = {sv["name"] for sv in campaign["surveys"] if sv["tiles"]}
    for site, names in campaign["sites"].items():
        # A survey by tiles has its DEM as tiles and a VRT, not the dem.tif compare reads.
        names = [n for n in names if n not in tiled]
        for a, b in zip(names, names[1:]):
            pairs[f"{a}_vs_{b}"] = (a, b)
    return pairs


# The campaign summary table's columns: (header, function of (survey, summary.json)).
def _g(d, *keys):
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def _peak_rss(s):
    vals = [st.get("peak_rss_mb") for st in (s.get("stages") or {}).values()
            if isinstance(st, dict) and isinstance(st.get("peak_rss_mb"), (int, float))]
    return round(max(vals), 1) if vals else None


COLUMNS = [
    ("survey", lambda sv, s: sv["name"]),
    ("site", lambda sv, s: sv["site"]),
    ("crs", lambda sv, s: (f"EPSG:{_g(s, 'utm', 'epsg')}" if _g(s, "utm", "epsg") else None)),
    ("first_ping_utc", lambda sv, s: _g(s, "time", "first_ping_utc")),
    ("last_ping_utc", lambda sv, s: _g(s, "time", "last_ping_utc")),
    ("pings", lambda sv, s: _g(s, "stages", "georef", "pings_in")),
    ("soundings", lambda sv, s: _g(s, "soundings", "total")),
    ("accepted", lambda sv, s: _g(s, "soundings", "accepted")),
    ("roll_deg", lambda sv, s: _g(s, "mount", "roll_deg")),
    ("pitch_deg", lambda sv, s: _g(s, "mount", "pitch_deg")),
    ("yaw_deg", lambda sv, s: _g(s, "mount", "yaw_deg")),
    ("slam", lambda sv, s: _g(s, "stages", "slam", "termination")),
    ("quality_gates", lambda sv, s: " ".join(g.get("gate", "?") for g in (s.get("quality_gates") or []))),
    ("seconds", lambda sv, s: (round(s["total_seconds"], 1)
                               if isinstance(s.get("total_seconds"), (int, float)) else None)),
    ("peak_rss_mb", lambda sv, s: _peak_rss(s)),
]


def summary_rows(campaign, surveys_dir):
    rows = []
    for sv in campaign["surveys"]:
        path = os.path.join(surveys_dir, sv["name"], "summary.json")
        with open(path) as f:
            s = json.load(f)
        rows.append({h: fn(sv, s) for h, fn in COLUMNS})
    return rows


def write_summary(campaign, surveys_dir, csv_path, json_path, md_path):
    """The campaign's table, one row per survey, from each products folder's summary.json."""
    rows = summary_rows(campaign, surveys_dir)
    headers = [h for h, _ in COLUMNS]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=headers, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if v is None else v) for k, v in r.items()})
    _write(csv_path, buf.getvalue())
    _write(json_path, json.dumps({"campaign": campaign["name"], "surveys": rows}, indent=2) + "\n")

    def cell(v):
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3f}" if abs(v) < 100 else f"{v:.1f}"
        return str(v).replace("|", "/")
    md = [f"# Campaign {campaign['name']}", "",
          "| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    md += ["| " + " | ".join(cell(r[h]) for h in headers) + " |" for r in rows]
    _write(md_path, "\n".join(md) + "\n")


def _write(path, text):
    """Written beside and renamed: a killed job leaves no half table under the final name."""
    tmp = path + ".partial"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)
