#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pitmap-campaign: a campaign of surveys through Snakemake (docs/campaigns.md).

  pitmap-campaign check CAMPAIGN.yaml [--no-crs]
      check the campaign file and print every problem (exit 2), else each survey and its CRS
  pitmap-campaign run CAMPAIGN.yaml --out DIR [--cores N] [--dry-run] [--stop-on-failure]
                      [--slurm --jobs N [--account A] [--partition P]] [-- SNAKEMAKE ARGS...]
      check it, then run the workflow in DIR: one `pitmap run` per survey (DIR/surveys/NAME,
      log DIR/logs/NAME.log; a survey with tiles: true as its stages, one job per DEM and
      TSDF tile, and the merge), the summary table (DIR/campaign_summary.{csv,json,md}), and the
      repeat-survey comparisons (DIR/compare/A_vs_B) when `pitmap compare` exists. Run again
      after a failure or a kill: only the unfinished jobs run (Snakemake's bookkeeping in
      DIR/.snakemake). Locally N jobs at once (default 2) within 90 % of the memory; --slurm
      submits each survey as a Slurm job (Snakemake's SLURM executor; DIR on a shared file
      system that every node sees, pitmap installed on every node).
  pitmap-campaign status CAMPAIGN.yaml --out DIR
      which outputs are there, and which job would run next (snakemake --summary)
Exit: 0 ok, 1 a job failed (Snakemake's message names it and its log), 2 usage or a bad
campaign file, 3 internal error.
"""
import argparse
import fcntl
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.realpath(__file__))
# Installed: the library and the Snakefile in pitmap_campaign/ beside this program (and pitmap);
# in the source tree, beside it.
for _d in (os.path.join(HERE, "pitmap_campaign"), HERE):
    if os.path.isfile(os.path.join(_d, "Snakefile")):
        LIB_DIR = _d
        break
else:
    sys.exit("pitmap-campaign: internal error: no Snakefile beside " + HERE)
# No __pycache__ in the installed folder (the package does not own it).
sys.dont_write_bytecode = True
sys.path.insert(0, LIB_DIR)
import pitmap_campaign_lib as pc  # noqa: E402

USAGE, FAILURE = 2, 1


def find_pitmap():
    sibling = os.path.join(HERE, "pitmap")
    if os.access(sibling, os.X_OK):
        return sibling
    return shutil.which("pitmap")


def mem_total_mb():
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) // 1024
    except OSError:
        pass
    return None


def check(path, pitmap, crs=True):
    """The campaign, or None after printing every problem."""
    try:
        return pc.load(path, pitmap=pitmap, check_crs=crs)
    except pc.CampaignError as e:
        print("pitmap-campaign: " + str(e), file=sys.stderr)
        return None


def snakemake_command(args, pitmap):
    snakemake = shutil.which("snakemake")
    if not snakemake:
        print("pitmap-campaign: snakemake is not installed (apt-get install snakemake)",
              file=sys.stderr)
        return None
    cmd = [snakemake, "-s", os.path.join(LIB_DIR, "Snakefile"), "-d", os.path.abspath(args.out),
           "--config", f"campaign={os.path.abspath(args.campaign)}", f"pitmap={pitmap}",
           "--rerun-incomplete"]
    return cmd


def main(argv):
    p = argparse.ArgumentParser(prog="pitmap-campaign", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("check", help="check a campaign file, every problem")
    c.add_argument("campaign")
    c.add_argument("--no-crs", action="store_true",
                   help="skip the CRS check (it reads every survey's logs with pitmap info)")
    r = sub.add_parser("run", help="run (or resume) a campaign")
    r.add_argument("campaign")
    r.add_argument("--out", required=True, help="the campaign's output folder")
    r.add_argument("--cores", type=int, default=2,
                   help="local: cores Snakemake schedules on (a survey job takes `threads`, "
                        "default 1: this many surveys at once); default 2")
    r.add_argument("--dry-run", action="store_true", help="print the jobs that would run")
    r.add_argument("--stop-on-failure", action="store_true",
                   help="stop at the first failed job (default: finish the other surveys)")
    r.add_argument("--slurm", action="store_true",
                   help="submit every survey as a Slurm job (snakemake --slurm)")
    r.add_argument("--jobs", type=int, default=20, help="--slurm: jobs queued at once")
    r.add_argument("--account", help="--slurm: the Slurm account")
    r.add_argument("--partition", help="--slurm: the Slurm partition")
    r.add_argument("extra", nargs="*", help="after --: more snakemake arguments")
    s = sub.add_parser("status", help="what is done and what would run")
    s.add_argument("campaign")
    s.add_argument("--out", required=True)
    args = p.parse_args(argv)

    pitmap = find_pitmap()
    if not pitmap:
        print("pitmap-campaign: pitmap not found beside this program or on PATH", file=sys.stderr)
        return USAGE
    if args.command == "check":
        campaign = check(args.campaign, pitmap, crs=not args.no_crs)
        if campaign is None:
            return USAGE
        for sv in campaign["surveys"]:
            print(f"{sv['name']}: site {sv['site']}, {sv['crs'] or 'CRS not checked'}, "
                  f"{len(sv['inputs'])} input(s)")
        print(f"pitmap-campaign: {campaign['name']}: {len(campaign['surveys'])} survey(s), "
              f"{len(campaign['sites'])} site(s): ok")
        return 0

    if os.path.exists(args.out) and not os.path.isdir(args.out):
        print(f"pitmap-campaign: --out {args.out} is not a folder", file=sys.stderr)
        return USAGE
    if args.command == "status":
        if check(args.campaign, pitmap, crs=False) is None:
            return USAGE
        cmd = snakemake_command(args, pitmap)
        if cmd is None:
            return USAGE
        os.execv(cmd[0], cmd + ["--summary", "--cores", "1"])

    # run: every problem before any work.
    if check(args.campaign, pitmap, crs=True) is None:
        return USAGE
    if args.cores < 1 or args.jobs < 1:
        print("pitmap-campaign: --cores and --jobs must be >= 1", file=sys.stderr)
        return USAGE
    cmd = snakemake_command(args, pitmap)
    if cmd is None:
        return USAGE
    os.makedirs(args.out, exist_ok=True)
    # One campaign run per output folder: an exclusive lock held through the exec by Snakemake
    # (the descriptor is inherited) until it exits, however it exits. Holding it, no other run
    # is alive there, so Snakemake's own locks left by a killed run are stale: released first,
    # or the restart would refuse to start.
    lock_fd = os.open(os.path.join(args.out, ".pitmap-campaign.lock"), os.O_RDWR | os.O_CREAT,
                      0o644)
    try:
        fcntl.flock(lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        print(f"pitmap-campaign: another pitmap-campaign runs in {args.out}", file=sys.stderr)
        return USAGE
    os.set_inheritable(lock_fd, True)
    locks = os.path.join(args.out, ".snakemake", "locks")
    if os.path.isdir(locks) and os.listdir(locks):
        print("pitmap-campaign: releasing the locks of an earlier run that did not finish",
              file=sys.stderr)
        subprocess.run(cmd + ["--unlock", "--cores", "1"], stdout=subprocess.DEVNULL, check=True)
    if not args.stop_on_failure:
        cmd.append("--keep-going")
    if args.dry_run:
        cmd.append("--dry-run")
    if args.slurm:
        cmd += ["--slurm", "--jobs", str(args.jobs), "--latency-wait", "60"]
        defaults = []
        if args.account:
            defaults.append(f"slurm_account={args.account}")
        if args.partition:
            defaults.append(f"slurm_partition={args.partition}")
        if defaults:
            cmd += ["--default-resources", *defaults]
    else:
        cmd += ["--cores", str(args.cores)]
        total = mem_total_mb()
        if total:
            cmd += ["--resources", f"mem_mb={int(total * 0.9)}"]
    cmd += args.extra
    sys.stdout.flush()
    os.execv(cmd[0], cmd)


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except KeyboardInterrupt:
        sys.exit(130)
    except Exception as e:  # a bug: say so, exit 3
        print(f"pitmap-campaign: internal error: {e!r}", file=sys.stderr)
        sys.exit(3)
