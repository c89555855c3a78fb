// SPDX-License-Identifier: MIT
// pitmap-sim: synthetic surveys with ground truth.
//   pitmap-sim synth --scenario NAME --out DIR [--seed N]   log files + truth, faster than real time
//   pitmap-sim scenarios                                    the built-in scenarios
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>

#include "common/progress.hpp"
#include "tools/sim/synth.hpp"

using namespace pitmap;

int main(int argc, char** argv) {
    CLI::App app{"pitmap-sim: simulated sensors, synthetic surveys with ground truth"};
    app.require_subcommand(1);
    std::string scenario_name, out_dir;
    std::uint64_t seed = 0;
    int threads = 0;
    auto* synth = app.add_subcommand("synth", "write a survey's LCM logs (as pitmap-acqd would) and its ground truth");
    synth->add_option("--scenario", scenario_name, "built-in scenario: demo, bejanca, gps-outage")->required();
    synth->add_option("--out", out_dir, "output folder: DIR/log (logs, vehicle.yaml) and DIR/truth")->required();
    synth->add_option("--seed", seed, "random seed (default: the scenario's own)");
    synth->add_option("--threads", threads, "threads for sonar ray casting (0 = all cores)");
    auto* list = app.add_subcommand("scenarios", "list the built-in scenarios");
    CLI11_PARSE(app, argc, argv);

    if (*list) {
        for (const auto& n : sim::BuiltinScenarioNames()) {
            const auto s = *sim::BuiltinScenario(n);
            std::printf("%-11s pit %.0f x %.0f m, %.0f m deep, %.0f s, %.0f pings\n", n.c_str(),
                        2 * s.pit.half_length_m, 2 * s.pit.half_width_m, s.pit.max_depth_m,
                        s.track.duration_s, s.track.duration_s * s.sonar.ping_rate_hz);
        }
        return 0;
    }
    auto scenario = sim::BuiltinScenario(scenario_name);
    if (!scenario) {
        std::fprintf(stderr, "pitmap-sim: %s\n", scenario.error().message.c_str());
        return 2;
    }
    if (seed != 0) scenario->seed = seed;
    sim::SynthOptions opt;
    opt.out_dir = out_dir;
    opt.num_threads = threads;
    const auto t0 = std::chrono::steady_clock::now();
    ProgressReporter progress("synth " + scenario_name, 1000);
    auto result = sim::RunSynth(*scenario, opt, progress.AsCallback());
    progress.Finish();
    if (!result) {
        std::fprintf(stderr, "pitmap-sim: %s\n", result.error().message.c_str());
        return 1;
    }
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("pitmap-sim: %s: %.1f s simulated (%.0f m) in %.1f s: %lld pings, %lld NovAtel frames "
                "(%lld bytes); log: %lld events, %.1f MB in %d file(s) under %s/log; truth in %s/truth\n",
                scenario_name.c_str(), result->duration_s, result->track_length_m, wall,
                static_cast<long long>(result->pings), static_cast<long long>(result->novatel_frames),
                static_cast<long long>(result->novatel_bytes), static_cast<long long>(result->log_events),
                static_cast<double>(result->log_bytes) / 1e6, result->log_files, out_dir.c_str(), out_dir.c_str());
    return 0;
}
