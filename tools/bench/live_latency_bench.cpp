// SPDX-License-Identifier: MIT
// Ping-to-page latency of `pitmap live` at a given replay speed (issue 18: < 1 s at 1x).
//
//   pitmap-bench-live_latency LOG... [--speed 1] [--seconds S] [--vehicle vehicle.yaml]
//
// The logs are fed through live::ReplayLogs, the path `pitmap live --replay` takes, paced at
// `speed` times the logged rate: each event reaches LiveSession::OnEvent at its turn and the
// session is ticked after it, as the LCM loop ticks after every handled message. A ping is
// "on the server" from the first tick after which the session's georeferenced-ping count
// covers it (pings are georeferenced in arrival order once the navigation brackets them and a
// processing interval of data time has passed); its server latency is that wall time minus the
// wall time it was fed. The page then sees it at its next poll: page.html polls every
// kPagePollS after the previous answer, so the page adds a wait uniform in [0, kPagePollS) and
// the time to build the answer (the documents the page asks for, timed here). Printed:
// percentiles of the server latency, the document build time, and the page latency's mean
// (server + poll / 2 + build) and worst case (server p99 + poll + build p99).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "lcmtypes/log/channels.hpp"
#include "processor/io/products.hpp"
#include "processor/live/replay.hpp"
#include "processor/live/session.hpp"

namespace {

using namespace pitmap::proc;

constexpr double kPagePollS = 0.8;  // page.html: setTimeout(poll, 800) after each answer

double Percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const auto i = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
    return v[std::min(i, v.size() - 1)];
}

std::int64_t Georeferenced(live::LiveSession& s, std::int64_t wall) {
    const auto j = s.StatusJson(wall);
    const auto& g = j["georef"];
    // Every ping the georeferencing is done with, in arrival order: georeferenced or refused.
    return g.value("pings_georeferenced", 0LL) + g.value("pings_outside_nav", 0LL) +
           g.value("pings_in_nav_gap", 0LL) + g.value("pings_refused", 0LL) +
           g.value("pings_dropped_waiting", 0LL);
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"pitmap-bench-live_latency: ping-to-page latency of pitmap live"};
    std::vector<std::string> logs;
    double speed = 1.0, seconds = 0;
    std::string vehicle, json_path;
    app.add_option("logs", logs, "LCM logs (pitmap-sim synth writes DIR/log)")->required();
    app.add_option("--speed", speed, "replay speed")->capture_default_str();
    app.add_option("--seconds", seconds, "stop after this much wall time (0 = the whole log)");
    app.add_option("--vehicle", vehicle, "vehicle.yaml (default: zero mount)");
    app.add_option("--json", json_path, "also write the figures to this JSON file");
    CLI11_PARSE(app, argc, argv);
    if (!(speed > 0)) {
        std::fprintf(stderr, "pitmap-bench-live_latency: --speed must be > 0\n");
        return 2;
    }

    survey::SonarMount mount;
    live::LiveConfig config;
    if (!vehicle.empty()) {
        auto v = io::ReadVehicleYaml(vehicle);
        if (!v) {
            std::fprintf(stderr, "pitmap-bench-live_latency: %s\n", v.error().message.c_str());
            return 2;
        }
        mount = v->mount;
        config.tpu.model = v->description.ErrorModel();  // TVU as pitmap-live computes it
    }
    live::LiveSession session(config, mount, !vehicle.empty());

    std::deque<std::int64_t> fed;  // wall times of the pings not yet georeferenced
    std::int64_t done = 0;         // pings the georeferencing is done with
    std::vector<double> server_s, build_s;
    std::atomic<bool> stop{false};
    const auto t0 = std::chrono::steady_clock::now();
    std::int64_t last_build = 0;
    std::uint64_t tiles_since = 0, soundings_since = 0;
    const auto observer = [&](const std::string& channel, std::int64_t wall) {
        if (channel.rfind(pitmap::lcmlog::kChannelMultibeamPing, 0) == 0) fed.push_back(wall);
        const std::int64_t n = Georeferenced(session, wall);
        for (; done < n && !fed.empty(); ++done) {
            server_s.push_back(static_cast<double>(wall - fed.front()) * 1e-6);
            fed.pop_front();
        }
        // What the page asks for once per poll: status, alarms, new tiles, new soundings.
        if (wall - last_build >= static_cast<std::int64_t>(kPagePollS * 1e6)) {
            last_build = wall;
            const auto b0 = std::chrono::steady_clock::now();
            (void)session.StatusJson(wall);
            (void)session.AlarmsJson();
            const auto tiles = session.TilesJson(tiles_since, 50'000);
            const auto snd = session.SoundingsJson(soundings_since, 50'000);
            tiles_since = tiles.value("next_since", tiles_since);
            soundings_since = snd.value("seq", soundings_since);
            build_s.push_back(
                std::chrono::duration<double>(std::chrono::steady_clock::now() - b0).count());
        }
        if (seconds > 0 &&
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() >
                seconds) {
            stop = true;
        }
    };
    auto r = live::ReplayLogs(session, logs, speed, stop, observer);
    if (!r) {
        std::fprintf(stderr, "pitmap-bench-live_latency: %s\n", r.error().message.c_str());
        return 1;
    }
    if (server_s.empty()) {
        std::fprintf(stderr,
                     "pitmap-bench-live_latency: no ping was georeferenced (%lld events)\n",
                     static_cast<long long>(r->events));
        return 1;
    }
    const double p50 = Percentile(server_s, 0.5), p95 = Percentile(server_s, 0.95),
                 p99 = Percentile(server_s, 0.99), mx = Percentile(server_s, 1.0);
    double mean = 0;
    for (double v : server_s) mean += v;
    mean /= static_cast<double>(server_s.size());
    const double b50 = Percentile(build_s, 0.5), b99 = Percentile(build_s, 0.99);
    std::printf("replay at %.1fx: %lld events, %.1f s of data in %.1f s, %zu pings timed\n",
                speed,
                static_cast<long long>(r->events),
                r->data_seconds,
                r->wall_seconds,
                server_s.size());
    std::printf(
        "ping on the server (fed -> georeferenced into the grid): mean %.3f s, p50 %.3f "
        "s, p95 %.3f s, p99 %.3f s, max %.3f s\n",
        mean,
        p50,
        p95,
        p99,
        mx);
    std::printf(
        "page documents (status, alarms, tiles, soundings) built in p50 %.4f s, p99 "
        "%.4f s (%zu polls)\n",
        b50,
        b99,
        build_s.size());
    std::printf("ping to page with a %.1f s poll: mean %.3f s, worst %.3f s\n",
                kPagePollS,
                mean + kPagePollS / 2 + b50,
                p99 + kPagePollS + b99);
    if (!json_path.empty()) {
        const nlohmann::json j = {
            {"speed", speed},
            {"events", r->events},
            {"data_seconds", r->data_seconds},
            {"wall_seconds", r->wall_seconds},
            {"pings_timed", server_s.size()},
            {"server_latency_s",
             {{"mean", mean}, {"p50", p50}, {"p95", p95}, {"p99", p99}, {"max", mx}}},
            {"documents_build_s", {{"p50", b50}, {"p99", b99}, {"polls", build_s.size()}}},
            {"page_poll_s", kPagePollS},
            {"ping_to_page_s",
             {{"mean", mean + kPagePollS / 2 + b50}, {"worst", p99 + kPagePollS + b99}}}};
        std::ofstream out(json_path);
        out << j.dump(1) << "\n";
        if (!out) {
            std::fprintf(stderr, "pitmap-bench-live_latency: cannot write %s\n", json_path.c_str());
            return 1;
        }
    }
    return 0;
}
