#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs the two Debian packages of tools/build-packages.sh on this machine, checks that the
# installed programs work from their installed places, then purges them and checks that nothing
# of theirs is left (docs/packages.md). Needs root (a CI container, or sudo); changes the
# machine only while it runs: it refuses to start when pitmap or pitmap-acqd is installed
# already, and it purges both packages on any exit.
#
# Usage: tools/test-packages.sh [PITMAP_ACQD_DEB PITMAP_DEB]
#   default: build-vehicle/packages/pitmap-acqd_*.deb and build/packages/pitmap_*.deb
#
# What it checks:
#   pitmap-acqd  --help; --version names the package's version; --check-config of the installed
#                example (exit 0) and of a broken copy (exit 2, the problem named); the user and
#                group pitmap, /var/log/pitmap 0750 pitmap:pitmap; the unit names the installed
#                binary (systemd-analyze verify when there); not enabled without
#                /etc/pitmap/acqd.yaml, enabled once it exists (reinstall); a replay run as user
#                pitmap writes a 0640 log into /var/log/pitmap that pitmap-inspect reads.
#   pitmap       pitmap-sim synth (a 30 s demo survey) -> pitmap run -> the products and
#                report.html with its 3D view (three.js from libjs-three inlined);
#                pitmap-eval scores them; pitmap-report from /usr/bin re-writes the report
#                with the scores (and --pdf when chromium is there); `pitmap live` finds
#                pitmap-live; `pitmap edit` serves three.js from libjs-three;
#                pitmap-campaign checks a campaign of it (and plans it with snakemake).
#   purge        both packages gone, none of their files, the enablement links and
#                deb-systemd-helper state gone, /var/log/pitmap gone; the user pitmap is
#                removed here only if this script's install created it (Debian keeps system
#                users on purge).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
start=$(date +%s)

acqd_deb=${1:-}
shore_deb=${2:-}
if [[ -z $acqd_deb ]]; then
  acqd_deb=$(find "$root/build-vehicle/packages" -maxdepth 1 -name 'pitmap-acqd_*.deb' \
    2> /dev/null | sort | tail -n 1)
  shore_deb=$(find "$root/build/packages" -maxdepth 1 -name 'pitmap_*.deb' 2> /dev/null |
    sort | tail -n 1)
fi
for f in "$acqd_deb" "$shore_deb"; do
  if [[ ! -f $f ]]; then
    echo "test-packages: package '$f' not found (tools/build-packages.sh builds them)" >&2
    exit 2
  fi
done
acqd_deb=$(realpath "$acqd_deb")
shore_deb=$(realpath "$shore_deb")

if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo > /dev/null 2>&1; then exec sudo "$0" "$acqd_deb" "$shore_deb"; fi
  echo "test-packages: needs root (dpkg -i)" >&2
  exit 2
fi
for p in pitmap pitmap-acqd; do
  if dpkg-query -W -f='${Status}' "$p" 2> /dev/null | grep -q "installed"; then
    echo "test-packages: $p is installed already; purge it first (dpkg --purge $p)" >&2
    exit 2
  fi
done
if [[ -e /etc/pitmap || -e /var/log/pitmap ]]; then
  echo "test-packages: /etc/pitmap or /var/log/pitmap exists already; not touching it" >&2
  exit 2
fi
user_existed=0
getent passwd pitmap > /dev/null && user_existed=1

tmp=$(mktemp -d)
chmod 0755 "$tmp"  # the daemon runs as user pitmap and reads its replay file from here
failures=0
fail() {
  echo "test-packages: FAIL: $*" >&2
  failures=$((failures + 1))
}
ok() { echo "test-packages: ok: $*"; }

edit_pid=
cleanup() {
  if [[ -n $edit_pid ]]; then kill "$edit_pid" 2> /dev/null || true; fi
  rm -f /etc/pitmap/acqd.yaml
  rm -rf /var/log/pitmap/pkgtest
  dpkg --purge pitmap pitmap-acqd > "$tmp/purge-on-exit.out" 2>&1 || cat "$tmp/purge-on-exit.out"
  if [[ $user_existed -eq 0 ]] && getent passwd pitmap > /dev/null; then
    userdel pitmap 2> /dev/null || true
    if getent group pitmap > /dev/null; then groupdel pitmap 2> /dev/null || true; fi
  fi
  rm -rf "$tmp"
}
trap cleanup EXIT

echo "=== install: $(basename "$acqd_deb") $(basename "$shore_deb")"
if ! dpkg -i "$acqd_deb" "$shore_deb" > "$tmp/dpkg.out" 2>&1; then
  # Dependencies not installed yet: apt completes them (Debian's registry), then configures.
  echo "test-packages: dpkg -i left dependencies open; apt-get install -f"
  DEBIAN_FRONTEND=noninteractive apt-get install -f -y -qq --no-install-recommends \
    >> "$tmp/dpkg.out" 2>&1 || { cat "$tmp/dpkg.out"; fail "apt-get install -f"; exit 1; }
fi
cat "$tmp/dpkg.out"
for p in pitmap pitmap-acqd; do
  dpkg-query -W -f='${Status}' "$p" | grep -q "install ok installed" || fail "$p not installed"
  dpkg -L "$p" > "$tmp/$p.files"
done

echo "=== pitmap-acqd"
[[ $(command -v pitmap-acqd) == /usr/bin/pitmap-acqd ]] ||
  fail "pitmap-acqd is not /usr/bin/pitmap-acqd"
if pitmap-acqd --help > "$tmp/help.out" 2>&1 && grep -q -- "--check-config" "$tmp/help.out"; then
  ok "pitmap-acqd --help"
else
  fail "pitmap-acqd --help: $(cat "$tmp/help.out")"
fi
# --version names the package's upstream version (its Debian version less any -revision).
upstream=$(dpkg-query -W -f='${Version}' pitmap-acqd)
upstream=${upstream%-*}
if pitmap-acqd --version > "$tmp/version.out" 2>&1 &&
  [[ $(head -n 1 "$tmp/version.out") == "pitmap-acqd $upstream"* ]]; then
  ok "pitmap-acqd --version: $(head -n 1 "$tmp/version.out")"
else
  fail "pitmap-acqd --version (want pitmap-acqd $upstream): $(cat "$tmp/version.out")"
fi
example=/etc/pitmap/acqd.yaml.example
if pitmap-acqd --config "$example" --check-config > "$tmp/check.out" 2>&1; then
  ok "pitmap-acqd --config $example --check-config: $(tail -n 1 "$tmp/check.out")"
else
  fail "check of $example: $(cat "$tmp/check.out")"
fi
sed 's/^status_period_ms: .*/status_period_ms: -5/' "$example" > "$tmp/broken.yaml"
rc=0
pitmap-acqd --config "$tmp/broken.yaml" --check-config > "$tmp/broken.out" 2>&1 || rc=$?
if [[ $rc -eq 2 ]] && grep -q status_period_ms "$tmp/broken.out"; then
  ok "a broken config: exit 2, names status_period_ms"
else
  fail "a broken config: exit $rc (want 2): $(cat "$tmp/broken.out")"
fi
getent passwd pitmap > /dev/null || fail "no user pitmap"
id -nG pitmap 2> /dev/null | grep -qw dialout || fail "user pitmap is not in group dialout"
if [[ $(stat -c '%a %U %G' /var/log/pitmap 2> /dev/null) == "750 pitmap pitmap" ]]; then
  ok "user pitmap, /var/log/pitmap 0750 pitmap:pitmap"
else
  fail "/var/log/pitmap: $(stat -c '%a %U %G' /var/log/pitmap 2>&1)"
fi
unit=$(grep "/pitmap-acqd.service$" "$tmp/pitmap-acqd.files" || true)
grep -q '^ExecStart=/usr/bin/pitmap-acqd --config /etc/pitmap/acqd.yaml$' "$unit" ||
  fail "$unit does not start /usr/bin/pitmap-acqd"
if command -v systemd-analyze > /dev/null 2>&1; then
  # Offline: loads the unit and checks its directives and that its programs exist.
  if systemd-analyze verify "$unit" > "$tmp/verify.out" 2>&1; then
    ok "systemd-analyze verify $unit"
  else
    fail "systemd-analyze verify: $(cat "$tmp/verify.out")"
  fi
fi
wants=/etc/systemd/system/multi-user.target.wants/pitmap-acqd.service
[[ ! -e $wants ]] || fail "enabled without /etc/pitmap/acqd.yaml"
# The operator writes the configuration; the next configure (here: a reinstall) enables it.
install -m 0640 -g pitmap "$example" /etc/pitmap/acqd.yaml
dpkg -i "$acqd_deb" > "$tmp/reinstall.out" 2>&1 || { cat "$tmp/reinstall.out"; fail "reinstall"; }
if [[ -L $wants ]]; then
  ok "enabled once /etc/pitmap/acqd.yaml exists"
else
  fail "not enabled: no $wants"
fi

# A replay run as the service's user: the sim's NovAtel stream as a file source, logged into
# the package's log folder.
pitmap-sim synth --scenario demo --out "$tmp/sim" --duration 30 --threads 2 --vendor-files \
  > "$tmp/sim.out" 2>&1 || { cat "$tmp/sim.out"; fail "pitmap-sim synth"; }
cat > "$tmp/replay.yaml" << EOF
lcm_url: "memq://"
status_period_ms: 200
log: {directory: /var/log/pitmap/pkgtest, prefix: pkgtest, min_free_bytes: 0}
channels:
  - id: novatel
    protocol: novatel
    file: {path: $tmp/sim/vendor/demo.gps}
vehicle:
  pitmap_vehicle: 1
  name: PKGTEST
  sonar:
    lever_arm_m: [0.0, 0.0, 0.5]
    mount: {orientation: down, connector: aft}
EOF
chmod 0644 "$tmp/replay.yaml"
if runuser -u pitmap -- pitmap-acqd --config "$tmp/replay.yaml" > "$tmp/acqd.out" 2>&1; then
  logfile=$(find /var/log/pitmap/pkgtest -maxdepth 1 -name 'pkgtest*' -type f | head -n 1)
  if [[ -n $logfile && $(stat -c '%a %U' "$logfile") == "640 pitmap" ]] &&
    pitmap-inspect "$logfile" > "$tmp/inspect.out" 2>&1; then
    ok "pitmap-acqd as user pitmap logged $(stat -c %s "$logfile") bytes (0640)," \
      "pitmap-inspect reads it"
  else
    fail "the replay's log: '${logfile}' $(stat -c '%a %U' "$logfile" 2>&1);" \
      "$(cat "$tmp/inspect.out" 2>&1)"
  fi
else
  fail "pitmap-acqd replay as user pitmap: $(cat "$tmp/acqd.out")"
fi

echo "=== pitmap"
[[ $(readlink -f "$(command -v pitmap)") == /usr/lib/pitmap/pitmap ]] ||
  fail "pitmap is not a link to /usr/lib/pitmap/pitmap"
pitmap --help > /dev/null || fail "pitmap --help"
# `pitmap live` runs pitmap-live from pitmap's own folder (through the /usr/bin link).
if pitmap live --help 2>&1 | grep -q "^pitmap-live:"; then
  ok "pitmap live runs /usr/lib/pitmap/pitmap-live"
else
  fail "pitmap live --help: $(pitmap live --help 2>&1 | head -n 3)"
fi
run_start=$(date +%s)
if (cd "$tmp" && pitmap run sim/log --out P > run.out 2>&1); then
  ok "pitmap run on the 30 s demo in $(($(date +%s) - run_start)) s"
else
  fail "pitmap run: $(tail -n 20 "$tmp/run.out")"
fi
for f in summary.json points.ply mesh.ply dem.tif trajectory.csv report.html; do
  [[ -s $tmp/P/$f ]] || fail "product $f missing"
done
# pitmap-campaign (/usr/bin link): the campaign file checked with the installed pitmap (the
# CRS through pitmap info), and Snakemake's plan of the workflow (snakemake is a Recommends).
printf 'campaign: pkg\nsurveys:\n  - {name: demo, inputs: [sim/log]}\n' > "$tmp/campaign.yaml"
if (cd "$tmp" && pitmap-campaign check campaign.yaml > campaign.out 2>&1) &&
  grep -q "demo: site pkg, EPSG:" "$tmp/campaign.out"; then
  ok "pitmap-campaign check"
else
  fail "pitmap-campaign check: $(tail -n 5 "$tmp/campaign.out")"
fi
if command -v snakemake > /dev/null 2>&1; then
  if (cd "$tmp" && pitmap-campaign run campaign.yaml --out C --dry-run > campaign.out 2>&1) &&
    grep -q "rule survey:" "$tmp/campaign.out"; then
    ok "pitmap-campaign run --dry-run"
  else
    fail "pitmap-campaign run --dry-run: $(tail -n 5 "$tmp/campaign.out")"
  fi
fi
# The 3D view: three.js from libjs-three and the viewer's own scripts from /usr/lib/pitmap.
if grep -q "OrbitControls" "$tmp/P/report.html" 2> /dev/null &&
  ! grep -q "3D view.*not found" "$tmp/P/report.html"; then
  ok "report.html with its 3D view"
else
  fail "report.html has no 3D view"
fi
if pitmap-eval --truth "$tmp/sim/truth" --products "$tmp/P" --json "$tmp/scores.json" \
  > "$tmp/eval.out" 2>&1; then
  ok "pitmap-eval"
else
  fail "pitmap-eval: $(tail -n 5 "$tmp/eval.out")"
fi
rm -f "$tmp/P/report.html"
# --pdf prints through chromium (a Suggests of the package; tools/install-deps.sh installs it)
# with the DevTools client installed in pitmap_report_lib.
pdf=()
if command -v chromium > /dev/null 2>&1; then pdf=(--pdf); fi
if pitmap-report "$tmp/P" --scores "$tmp/scores.json" "${pdf[@]}" > "$tmp/report.out" 2>&1 &&
  [[ -s $tmp/P/report.html ]]; then
  ok "pitmap-report (/usr/bin link) with the scores"
else
  fail "pitmap-report: $(tail -n 5 "$tmp/report.out")"
fi
if [[ ${#pdf[@]} -gt 0 ]]; then
  if [[ $(head -c 4 "$tmp/P/report.pdf" 2> /dev/null) == "%PDF" ]]; then
    ok "pitmap-report --pdf: report.pdf ($(stat -c %s "$tmp/P/report.pdf") bytes)"
  else
    fail "pitmap-report --pdf wrote no PDF: $(tail -n 5 "$tmp/report.out")"
  fi
fi

# The edit page serves three.js from libjs-three (the installed path the program reads).
pitmap edit "$tmp/P" --port 0 --no-open > "$tmp/edit.out" 2>&1 &
edit_pid=$!
url=
for _ in $(seq 60); do  # up to 30 s for the URL (it loads the survey first)
  url=$(grep -o 'http://127\.0\.0\.1:[0-9]*' "$tmp/edit.out" | head -n 1 || true)
  [[ -n $url ]] && break
  kill -0 "$edit_pid" 2> /dev/null || break
  sleep 0.5
done
three=/usr/share/javascript/three/three.min.js
got=$(python3 -c 'import sys, urllib.request
print(len(urllib.request.urlopen(sys.argv[1] + "/three.min.js", timeout=30).read()))' \
  "$url" 2> /dev/null || true)
if [[ -n $url && $got == "$(stat -c %s "$three")" ]]; then
  ok "pitmap edit serves $three ($got bytes)"
else
  fail "pitmap edit: url '$url', three.min.js '$got' bytes: $(tail -n 5 "$tmp/edit.out")"
fi
kill "$edit_pid" 2> /dev/null || true
wait "$edit_pid" 2> /dev/null || true
edit_pid=

echo "=== purge"
rm -f /etc/pitmap/acqd.yaml
rm -rf /var/log/pitmap/pkgtest
if ! dpkg --purge pitmap pitmap-acqd > "$tmp/purge.out" 2>&1; then
  cat "$tmp/purge.out"
  fail "dpkg --purge"
fi
for p in pitmap pitmap-acqd; do
  if dpkg-query -W -f='${Status}' "$p" 2> /dev/null | grep -q "installed"; then
    fail "$p still installed"
  fi
  # Every file and link of the package, and its own folders; shared ones (/usr/bin) stay.
  while read -r path; do
    [[ -e $path || -L $path ]] || continue
    if [[ -d $path && ! -L $path ]]; then
      case $path in
        /usr/lib/pitmap | /etc/pitmap | /usr/share/doc/pitmap*) ;;
        *) continue ;;
      esac
    fi
    fail "$p left $path"
  done < "$tmp/$p.files"
done
for path in /var/log/pitmap /etc/pitmap /usr/lib/pitmap "$wants" \
  /var/lib/systemd/deb-systemd-helper-enabled/pitmap-acqd.service.dsh-also \
  /var/lib/systemd/deb-systemd-helper-enabled/multi-user.target.wants/pitmap-acqd.service; do
  [[ ! -e $path && ! -L $path ]] || fail "left after purge: $path"
done
[[ $failures -eq 0 ]] && ok "purged, nothing left"

echo "=== test-packages: $failures failure(s) in $(($(date +%s) - start)) s"
[[ $failures -eq 0 ]]
