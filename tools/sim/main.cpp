// SPDX-License-Identifier: MIT
// pitmap-sim: synthetic surveys with ground truth.
//   pitmap-sim synth --scenario NAME --out DIR [--seed N] [--vendor-files] [--epoch K]
//                    [--topside-clock-offset S]             log files + truth (+ vendor files),
//                    [--duration S] [--refraction]          faster than real time; --refraction:
//                                                           a refracting water column
//                    [--echo-artifacts LEVEL]               fish, bubbles, multipath, smile
//                    [--lines laps|star|zigzag]             the pattern of the survey lines
//   pitmap-sim hil --scenario NAME --out DIR [--acqd PATH] [--duration S] [--faults ...]
//                                                           real-time emulators (pty, TCP, UDP)
//                                                           feeding the daemon; truth + manifest
//   pitmap-sim scenarios                                    the built-in scenarios
//   pitmap-sim --version
// Exit (common/exit_codes.hpp): 0 ok, 1 run failure (or the daemon's), 2 usage (bad arguments,
// an unknown scenario, --acqd not there: checked before --out is created), 3 internal error.
#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <string>
#include <vector>

#include "common/cli/parse.hpp"
#include "common/exit_codes.hpp"
#include "common/progress.hpp"
#include "tools/sim/hil/hil_run.hpp"
#include "tools/sim/synth.hpp"
#include "tools/sim/terrain_change.hpp"

using namespace pitmap;

namespace {

namespace codes = pitmap::exit_code;

std::atomic<bool> g_interrupted{false};

void OnSignal(int) {
    g_interrupted = true;
}

// `pitmap-sim hil`: exit 0 ok, 1 run failure or daemon failure, 2 bad arguments.
int RunHilCommand(const std::string& scenario_name,
                  std::uint64_t seed,
                  sim::hil::HilOptions opt,
                  const std::string& faults) {
    auto scenario = sim::BuiltinScenario(scenario_name);
    if (!scenario) {
        std::fprintf(stderr, "pitmap-sim: %s\n", scenario.error().message.c_str());
        return codes::kUsage;
    }
    if (seed != 0) scenario->seed = seed;
    auto plan = sim::hil::ParseFaults(faults);
    if (!plan) {
        std::fprintf(stderr, "pitmap-sim: %s\n", plan.error().message.c_str());
        return codes::kUsage;
    }
    opt.faults = *plan;
    if (auto p = opt.Validate(); !p.empty()) {
        for (const auto& s : p) std::fprintf(stderr, "pitmap-sim: %s\n", s.c_str());
        return codes::kUsage;
    }
    struct sigaction sa {};
    sa.sa_handler = OnSignal;
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    std::signal(SIGPIPE, SIG_IGN);
    std::fprintf(stderr,
                 "pitmap-sim: hil %s: starting the emulators%s\n",
                 scenario_name.c_str(),
                 opt.acqd_path.empty() ? "" : " and pitmap-acqd");
    auto r = sim::hil::RunHil(*scenario, opt, [] { return !g_interrupted.load(); });
    if (!r) {
        std::fprintf(stderr, "pitmap-sim: hil: %s\n", r.error().message.c_str());
        return codes::kFailure;
    }
    std::printf(
        "pitmap-sim: hil %s: %.1f s: %lld COM1 frames, %lld ICOM1 frames, %lld pings, "
        "%lld commands (%lld refused), %lld EC frames; faults: %lld garbage, %lld crc, "
        "%lld unplug, %lld tcp drop; truth and manifest in %s/truth\n",
        scenario_name.c_str(),
        r->duration_s,
        static_cast<long long>(r->com_frames),
        static_cast<long long>(r->icom_frames),
        static_cast<long long>(r->pings),
        static_cast<long long>(r->commands),
        static_cast<long long>(r->commands_refused),
        static_cast<long long>(r->ec_frames),
        static_cast<long long>(r->garbage_bursts),
        static_cast<long long>(r->crc_errors),
        static_cast<long long>(r->unplugs),
        static_cast<long long>(r->tcp_drops),
        opt.out_dir.c_str());
    if (!r->daemon_problem.empty()) {
        std::fprintf(stderr, "pitmap-sim: hil: %s\n", r->daemon_problem.c_str());
        return codes::kFailure;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) try {
    CLI::App app{"pitmap-sim: simulated sensors, synthetic surveys with ground truth"};
    app.require_subcommand(1);
    std::string scenario_name, out_dir;
    std::uint64_t seed = 0;
    int threads = 0;
    auto* synth = app.add_subcommand(
        "synth", "write a survey's LCM logs (as pitmap-acqd would) and its ground truth");
    synth
        ->add_option("--scenario",
                     scenario_name,
                     "built-in scenario: demo, bejanca, gps-outage, quarry, mine")
        ->required();
    synth->add_option("--out", out_dir, "output folder: DIR/log (logs, vehicle.yaml) and DIR/truth")
        ->required();
    synth->add_option("--seed",
                      seed,
                      "random seed (default: the scenario's own); with --epoch the first "
                      "epoch's (the pit's terrain), epoch K surveys with seed + 7919 (K - 1)");
    int epoch = 1;
    synth
        ->add_option("--epoch",
                     epoch,
                     "repeat survey K (2..9) of the scenario: the same pit with known change "
                     "since epoch 1 (a slumped wall section, a backfill heap, a thin spill, a "
                     "mined cut; truth in DIR/truth/changes.json, changes.geojson, change.f32), "
                     "surveyed again with its own track (laps clockwise, 1.5 m further out), "
                     "noise, navigation errors, mount, topside clock and date (K - 1) x 91 days "
                     "later; 1 = the scenario as it is (default)")
        ->check(CLI::Range(1, 9));
    synth->add_option("--threads", threads, "threads for sonar ray casting (0 = all cores)");
    bool vendor_files = false;
    double clock_offset_s = 0;
    double stamp_error_ms = 0;
    synth->add_flag("--vendor-files",
                    vendor_files,
                    "also write DIR/vendor/<scenario>.gps (NovAtel binary stream) and "
                    "DIR/vendor/<scenario>.83P (83P records as the topside program records them)");
    auto* clock_offset_opt =
        synth->add_option("--topside-clock-offset",
                          clock_offset_s,
                          "seconds: sonar header time minus UTC at the survey start (default: "
                          "the scenario's); GPS = header + (GPS-UTC) - offset");
    double clock_drift_ppm = 0;
    auto* clock_drift_opt = synth->add_option(
        "--topside-clock-drift",
        clock_drift_ppm,
        "ppm: how fast the topside PC clock runs against UTC (default: the scenario's; a PC "
        "crystal is good to some tens of ppm)");
    auto* stamp_error_opt =
        synth->add_option("--sonar-stamp-error-ms",
                          stamp_error_ms,
                          "the decoded pings in the log are stamped this many ms late (a "
                          "daemon's residual latency; default 0)");
    std::vector<double> stamp_step;
    synth
        ->add_option("--sonar-stamp-error-step",
                     stamp_step,
                     "AT_S MS: from AT_S seconds after the survey start on, the decoded pings are "
                     "stamped MS ms late instead (a daemon clock that stepped mid-survey)")
        ->expected(2);
    std::vector<double> dropout_patch;
    synth
        ->add_option("--dropout-patch",
                     dropout_patch,
                     "X Y R: beams hitting within R m of world (X, Y) return nothing (a holiday)")
        ->expected(3);
    std::string sonar_format;
    synth
        ->add_option("--sonar-format",
                     sonar_format,
                     "83P format of the pings: 1.10 (default, with intensities) or 1.00 (no field "
                     "for intensities)")
        ->check(CLI::IsMember({"1.00", "1.10"}));
    double duration_s = 0;
    auto* duration_opt = synth->add_option(
        "--duration", duration_s, "seconds of the survey to simulate (default: the scenario's)");
    bool refraction = false;
    double water_surface_speed = 0, water_deep_speed = 0;
    std::vector<double> thermocline;
    synth->add_flag("--refraction",
                    refraction,
                    "a refracting water column: warm mixed layer over a thermocline; the pings "
                    "are ray traced through it and the true cast is written to "
                    "DIR/truth/water_column.svp (and DIR/vendor/<scenario>.svp)");
    auto* surface_speed_opt = synth->add_option(
        "--water-surface-speed", water_surface_speed, "mixed layer sound speed, m/s (1496)");
    auto* deep_speed_opt = synth->add_option(
        "--water-deep-speed", water_deep_speed, "speed below the thermocline, m/s (1452)");
    auto* thermocline_opt =
        synth->add_option("--thermocline", thermocline, "its top and bottom depth, m (2 7)")
            ->expected(2);
    std::string echo_level;
    synth
        ->add_option("--echo-artifacts",
                     echo_level,
                     "correlated echo artifacts (fish schools, bubble sweep-down, multipath "
                     "ghosts, the nadir smile): none (default), light (~0.3 % of the beams), "
                     "typical (~1 %), heavy (~3 %); truth per beam in DIR/truth/artifacts.*")
        ->check(CLI::IsMember({"none", "light", "typical", "heavy"}));
    // Fault cases (issue 34): what real surveys break.
    std::string start_utc;
    synth->add_option("--start-utc",
                      start_utc,
                      "survey start, UTC ISO 8601 (default: the scenario's, 2026-06-15T09:00:00Z)");
    std::vector<double> origin;
    synth
        ->add_option("--origin",
                     origin,
                     "LAT LON: the pit's position, degrees WGS 84 (default: the scenario's)")
        ->expected(2);
    std::vector<double> clock_step;
    synth
        ->add_option("--topside-clock-step",
                     clock_step,
                     "AT_S S: from AT_S seconds after the survey start on, the topside clock in "
                     "the .83P headers is S seconds further ahead (an NTP correction)")
        ->expected(2);
    std::vector<std::string> ins_status_windows;
    synth
        ->add_option("--ins-status-window",
                     ins_status_windows,
                     "START END STATUS: the INS reports STATUS (aligning, high_variance, "
                     "solution_free, inactive, or a NovAtel number) from START to END s; the "
                     "solution itself stays good (repeatable)")
        ->expected(3)
        ->allow_extra_args(false);
    std::vector<double> ins_drift;
    synth
        ->add_option("--ins-drift",
                     ins_drift,
                     "START END EAST NORTH: the INS position drifts to (EAST, NORTH) m over START "
                     "to END s with its status good and its stddevs unchanged, then recovers")
        ->expected(4);
    std::string lines;
    synth
        ->add_option("--lines",
                     lines,
                     "the pattern of the survey lines, repeated for the duration: laps (the "
                     "scenario's laps and tie lines, default), star (6 lines through the pit "
                     "centre, 30 deg apart) or zigzag (8 legs across the pit from west to east, "
                     "then back half a leg shifted, crossing them)")
        ->check(CLI::IsMember({"laps", "star", "zigzag"}));
    std::vector<double> gps_outage;
    synth
        ->add_option("--gps-outage",
                     gps_outage,
                     "START END: no GNSS from START to END s (in addition to the scenario's "
                     "outages): the INS dead-reckons, its position drifts and its stddevs grow, "
                     "then it recovers (repeatable, sorted)")
        ->expected(2)
        ->allow_extra_args(false);
    bool header_gga = false;
    synth->add_flag("--header-gga",
                    header_gga,
                    "the topside's 83P headers carry the GNSS antenna's NMEA fix (GGA, 2 cm white "
                    "noise, independent of the INS's error), as the quarry's do; bejanca's and "
                    "gps-outage's topside had no NMEA input");
    auto* list = app.add_subcommand("scenarios", "list the built-in scenarios");
    sim::hil::HilOptions hil_opt;
    std::string faults;
    auto* hil = app.add_subcommand("hil", "run a scenario in real time behind a pty, TCP and UDP");
    hil->add_option("--scenario",
                    scenario_name,
                    "built-in scenario: demo, bejanca, gps-outage, quarry, mine")
        ->required();
    hil->add_option("--out", hil_opt.out_dir, "output folder: DIR/truth, DIR/log (the daemon's)")
        ->required();
    hil->add_option("--acqd", hil_opt.acqd_path, "pitmap-acqd to run against the emulators");
    hil->add_option("--duration", hil_opt.duration_s, "seconds to run (default: the scenario's)");
    hil->add_option(
        "--faults", faults, "e.g. garbage=3,crc=3,unplug=1,tcp-drop=1,jitter-ms=2,outage=10:20");
    hil->add_option(
        "--pty", hil_opt.pty_link, "symlink to the emulated COM1 (default DIR/novatel-com1)");
    hil->add_option("--baud", hil_opt.baud, "COM1 line rate the pty is paced at (460800)");
    hil->add_option("--tcp-port", hil_opt.tcp_port, "ICOM1 TCP port on 127.0.0.1 (3001)");
    hil->add_option(
        "--udp-port", hil_opt.udp_port, "the daemon's 83P UDP port on 127.0.0.1 (4040)");
    hil->add_option("--lcm-url", hil_opt.lcm_url, "the daemon's LCM URL (memq://)");
    hil->add_option("--seed", seed, "random seed (default: the scenario's own)");
    hil->add_option("--default-log",
                    hil_opt.default_logs,
                    "a COM1 log active before any command, e.g. \"LOG INSPVASB ONTIME 0.02\" "
                    "(repeatable; default: none, as after UNLOGALL)");
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap-sim")) return *code;

    if (*hil) return RunHilCommand(scenario_name, seed, hil_opt, faults);

    if (*list) {
        for (const auto& n : sim::BuiltinScenarioNames()) {
            std::printf(
                "%-11s %s\n", n.c_str(), sim::DescribeScenario(*sim::BuiltinScenario(n)).c_str());
        }
        return 0;
    }
    auto scenario = sim::BuiltinScenario(scenario_name);
    if (!scenario) {
        std::fprintf(stderr, "pitmap-sim: %s\n", scenario.error().message.c_str());
        return codes::kUsage;
    }
    if (seed != 0) scenario->seed = seed;
    if (auto repeat = sim::RepeatEpoch(*scenario, epoch); repeat) {
        scenario = std::move(*repeat);
    } else {
        std::fprintf(stderr, "pitmap-sim: %s\n", repeat.error().message.c_str());
        return codes::kUsage;
    }
    if (clock_offset_opt->count() > 0) scenario->sonar.topside_clock_offset_s = clock_offset_s;
    if (clock_drift_opt->count() > 0) scenario->sonar.topside_clock_drift_ppm = clock_drift_ppm;
    if (stamp_error_opt->count() > 0) scenario->sonar.daemon_stamp_error_ms = stamp_error_ms;
    if (stamp_step.size() == 2) {
        scenario->sonar.daemon_stamp_error_step_s = stamp_step[0];
        scenario->sonar.daemon_stamp_error_after_ms = stamp_step[1];
    }
    if (duration_opt->count() > 0) scenario->track.duration_s = duration_s;
    if (!lines.empty()) {
        auto pattern = sim::TrackPatternFromString(lines);
        if (!pattern) {
            std::fprintf(stderr, "pitmap-sim: %s\n", pattern.error().message.c_str());
            return codes::kUsage;
        }
        scenario->track.pattern = *pattern;
    }
    if (!start_utc.empty()) scenario->start_utc = start_utc;
    if (origin.size() == 2) {
        scenario->origin_latitude_deg = origin[0];
        scenario->origin_longitude_deg = origin[1];
    }
    if (clock_step.size() == 2) {
        scenario->sonar.topside_clock_step_at_s = clock_step[0];
        scenario->sonar.topside_clock_step_s = clock_step[1];
    }
    for (std::size_t i = 0; i + 2 < ins_status_windows.size(); i += 3) {
        const std::string& name = ins_status_windows[i + 2];
        const std::map<std::string, double> statuses = {
            {"inactive", 0}, {"aligning", 1}, {"high_variance", 2}, {"solution_free", 6}};
        double status = -1;
        if (auto it = statuses.find(name); it != statuses.end()) {
            status = it->second;
        } else {
            char* end = nullptr;
            status = std::strtod(name.c_str(), &end);
            if (end == name.c_str() || *end != '\0') status = -1;
        }
        char* e0 = nullptr;
        char* e1 = nullptr;
        const double a = std::strtod(ins_status_windows[i].c_str(), &e0);
        const double b = std::strtod(ins_status_windows[i + 1].c_str(), &e1);
        if (status < 0 || *e0 != '\0' || *e1 != '\0') {
            std::fprintf(stderr,
                         "pitmap-sim: --ins-status-window %s %s %s: START END in seconds, STATUS "
                         "aligning | high_variance | solution_free | inactive | a number\n",
                         ins_status_windows[i].c_str(),
                         ins_status_windows[i + 1].c_str(),
                         name.c_str());
            return codes::kUsage;
        }
        scenario->nav.status_windows.insert(scenario->nav.status_windows.end(), {a, b, status});
    }
    for (std::size_t i = 0; i + 1 < gps_outage.size(); i += 2) {
        scenario->nav.outages_s.insert(scenario->nav.outages_s.end(),
                                       {gps_outage[i], gps_outage[i + 1]});
    }
    if (header_gga) scenario->sonar.nmea_position = true;
    if (ins_drift.size() == 4) {
        scenario->nav.drift_windows.insert(
            scenario->nav.drift_windows.end(), ins_drift.begin(), ins_drift.end());
    }
    if (!sonar_format.empty()) scenario->sonar.format_version = sonar_format == "1.00" ? 0 : 10;
    if (dropout_patch.size() == 3) {
        scenario->sonar.dropout_patch_x_m = dropout_patch[0];
        scenario->sonar.dropout_patch_y_m = dropout_patch[1];
        scenario->sonar.dropout_patch_radius_m = dropout_patch[2];
    }
    if (refraction) scenario->water.refraction = true;
    if (!echo_level.empty()) {
        auto a = sim::EchoArtifactsAt(echo_level);
        if (!a) {
            std::fprintf(stderr, "pitmap-sim: %s\n", a.error().message.c_str());
            return codes::kUsage;
        }
        scenario->echo_artifacts = *a;
    }
    if (surface_speed_opt->count() > 0) scenario->water.surface_speed_mps = water_surface_speed;
    if (deep_speed_opt->count() > 0) scenario->water.deep_speed_mps = water_deep_speed;
    if (thermocline_opt->count() > 0) {
        scenario->water.mixed_layer_depth_m = thermocline[0];
        scenario->water.thermocline_depth_m = thermocline[1];
    }
    sim::SynthOptions opt;
    opt.out_dir = out_dir;
    opt.num_threads = threads;
    opt.vendor_files = vendor_files;
    const auto t0 = std::chrono::steady_clock::now();
    ProgressReporter progress("synth " + scenario_name, 1000);
    auto result = sim::RunSynth(*scenario, opt, progress.AsCallback());
    progress.Finish();
    if (!result) {
        std::fprintf(stderr, "pitmap-sim: %s\n", result.error().message.c_str());
        return codes::kFailure;
    }
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf(
        "pitmap-sim: %s: %.1f s simulated (%.0f m) in %.1f s: %lld pings, %lld NovAtel frames "
        "(%lld bytes); log: %lld events, %.1f MB in %d file(s) under %s/log; truth in %s/truth"
        "%s; echo artifacts (%s): %lld beams (%.2f %%)\n",
        scenario_name.c_str(),
        result->duration_s,
        result->track_length_m,
        wall,
        static_cast<long long>(result->pings),
        static_cast<long long>(result->novatel_frames),
        static_cast<long long>(result->novatel_bytes),
        static_cast<long long>(result->log_events),
        static_cast<double>(result->log_bytes) / 1e6,
        result->log_files,
        out_dir.c_str(),
        out_dir.c_str(),
        vendor_files ? ("; vendor files in " + out_dir + "/vendor").c_str() : "",
        scenario->echo_artifacts.level.c_str(),
        static_cast<long long>(result->artifact_soundings),
        100.0 * result->artifact_share);
    return codes::kOk;
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap-sim: internal error: %s\n", e.what());
    return codes::kInternal;
}
