// SPDX-License-Identifier: MIT
// pitmap-live (also `pitmap live`): live survey QC. Subscribes to the daemon's LCM channels, or
// replays LCM logs through the same path, and serves the live page (processor/live/server.hpp).
//   pitmap-live [--lcm-url URL] [--bind ADDR] [--port N] [--allow-host NAME]... [--vehicle FILE]
//               [--out DIR] ...
//   pitmap-live --replay LOG... [--speed S] [--no-serve] [--hold] [--status-json FILE]
//               [--snapshot-on-exit --out DIR]
//   pitmap-live --version
// Without --vehicle, vehicle.yaml beside the first replayed log is read, as pitmap run does
// (processor/io/products.hpp VehicleFilePath). Replayed logs (and --vehicle) are checked before
// anything is created.
// Exit (common/exit_codes.hpp, docs/cli.md): 0 done (SIGINT/SIGTERM, or the replay's end),
// 1 run failure, 2 usage (bad arguments, invalid config, a file that does not exist),
// 3 internal error.
#include <lcm/lcm-cpp.hpp>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "common/cli/parse.hpp"
#include "common/exit_codes.hpp"
#include "common/peak_memory.hpp"
#include "processor/io/products.hpp"
#include "processor/live/replay.hpp"
#include "processor/live/server.hpp"

namespace live = pitmap::proc::live;

namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) {
    g_stop.store(true);
}

std::int64_t WallUtime() {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

void OnLcm(const lcm::ReceiveBuffer* rbuf, const std::string& channel, live::LiveSession* s) {
    s->OnEvent(channel, rbuf->data, rbuf->data_size, WallUtime());
}

namespace codes = pitmap::exit_code;

int Usage(const std::vector<std::string>& problems) {
    for (const auto& p : problems) std::fprintf(stderr, "pitmap-live: %s\n", p.c_str());
    return codes::kUsage;
}

struct Options {
    std::string lcm_url = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
    std::string vehicle_path, status_json;
    std::vector<std::string> replay;
    double speed = 0;
    bool no_serve = false, hold = false, snapshot_on_exit = false;
    live::LiveConfig config;
    live::ServerConfig server_config;
    double budget_kbps = 50;
};

void DeclareOptions(CLI::App& app, Options& o) {
    live::ServerConfig& server_config = o.server_config;
    live::LiveConfig& config = o.config;
    app.add_option("--lcm-url", o.lcm_url, "LCM URL to subscribe on")->capture_default_str();
    app.add_option("--bind", server_config.bind_address, "address to serve on")
        ->capture_default_str();
    app.add_option("--port", server_config.port, "TCP port (0 = any free one, printed)")
        ->capture_default_str();
    app.add_option("--allow-host",
                   server_config.allowed_hosts,
                   "a further Host name the page may be opened by (DNS rebinding guard)");
    app.add_option("--max-connections",
                   server_config.limits.max_connections,
                   "open HTTP connections in all")
        ->capture_default_str();
    app.add_option("--max-connections-per-address",
                   server_config.limits.max_connections_per_address,
                   "open HTTP connections from one address")
        ->capture_default_str();
    app.add_option("--request-timeout",
                   server_config.limits.header_timeout_s,
                   "a request's header (and its body) must arrive within this, s")
        ->capture_default_str();
    app.add_option("--budget-kbps",
                   o.budget_kbps,
                   "bytes the pages on the radio link may pull, kB/s (pages on this machine: "
                   "none, unless --budget-loopback)")
        ->capture_default_str();
    app.add_option("--vehicle",
                   o.vehicle_path,
                   "vehicle.yaml: lever arm, mount, error model (default: vehicle.yaml beside "
                   "the first --replay log, as pitmap run; else zero)");
    app.add_option("--out", server_config.snapshot_dir, "snapshot directory (POST /api/snapshot)");
    app.add_option("--cell-size", config.grid.cell_size_m, "coverage cell size, m")
        ->capture_default_str();
    app.add_option("--holiday-cells", config.grid.holiday_search_cells, "holiday search, cells")
        ->capture_default_str();
    app.add_option("--s44-order",
                   config.grid.s44_order,
                   "TVU status: IHO S-44 order (exclusive, special, 1a, 1b, 2)")
        ->capture_default_str();
    app.add_option("--tvu-min-share",
                   config.grid.tvu_min_share,
                   "a cell meets the order with this share of soundings within its TVU limit")
        ->capture_default_str();
    app.add_option("--tvu-alarm-percent",
                   config.status.tvu_alarm_percent,
                   "alarm when more new cells than this (%) fail the order's TVU")
        ->capture_default_str();
    app.add_option("--tvu-window", config.status.tvu_window_s, "new cells: the last S s of data")
        ->capture_default_str();
    app.add_option("--max-clients", server_config.max_clients, "pages with a budget of their own")
        ->capture_default_str();
    app.add_option("--nav-channel", config.nav_channel_id, "INS channel id (default: every one)");
    app.add_option(
        "--sonar-channel", config.sonar_channel_id, "sonar channel id (default: every one)");
    app.add_option("--replay", o.replay, "LCM log files to replay instead of subscribing");
    app.add_option("--speed", o.speed, "replay speed (0 = as fast as possible)")
        ->capture_default_str();
    app.add_flag("--no-serve", o.no_serve, "replay only: no HTTP server");
    app.add_flag("--hold", o.hold, "replay only: keep serving after the end until SIGTERM");
    app.add_option("--status-json", o.status_json, "write the final status JSON here at the end");
    app.add_flag("--snapshot-on-exit", o.snapshot_on_exit, "write the grid into --out at the end");
    app.add_flag("--budget-loopback",
                 server_config.budget_loopback,
                 "apply --budget-kbps to pages on this machine too (loopback is not budgeted "
                 "by default: it is not the radio link; to see the thinning locally)");
}

// The settings that follow from the parsed options: the budget in bytes, the body timeout, the
// vehicle file (as pitmap run: --vehicle, else vehicle.yaml beside the first log). An error
// when a replayed log does not exist.
pitmap::Status ResolveOptions(Options& o) {
    o.server_config.budget_bytes_per_s = o.budget_kbps * 1000.0;
    for (const auto& f : o.replay) {
        std::error_code err;
        if (!std::filesystem::exists(f, err))
            return pitmap::Error{"--replay " + f + " does not exist"};
    }
    o.vehicle_path = pitmap::proc::io::VehicleFilePath(o.replay, o.vehicle_path);
    o.server_config.limits.body_timeout_s = o.server_config.limits.header_timeout_s;
    return pitmap::Ok{};
}

// The vehicle: mount and lever arm for the georeferencing (known only with a vehicle file).
struct Vehicle {
    pitmap::proc::survey::SonarMount mount;
    bool mount_known = false;
};

// The vehicle file's mount, and its sensor error model for the TVU into o.config; without one
// a zero mount and the default error model, with a warning.
pitmap::Expected<Vehicle> ReadVehicle(Options& o) {
    Vehicle out;
    out.mount_known = !o.vehicle_path.empty();
    if (!out.mount_known) {
        std::fprintf(stderr,
                     "pitmap-live: warning: no --vehicle (and no vehicle.yaml beside the first "
                     "replayed log): lever arm and mount are zero, TVU from the default sensor "
                     "error model\n");
        return out;
    }
    auto v = pitmap::proc::io::ReadVehicleYaml(o.vehicle_path);
    if (!v) return v.error();
    std::fprintf(stderr, "pitmap-live: vehicle: %s\n", o.vehicle_path.c_str());
    out.mount = v->mount;
    o.config.tpu.model = v->description.ErrorModel();
    if (!v->description.uncertainty) {
        std::fprintf(stderr,
                     "pitmap-live: %s has no uncertainty: section: TVU from the default "
                     "sensor error model\n",
                     o.vehicle_path.c_str());
    }
    return out;
}

// Every problem of the options, for Usage.
std::vector<std::string> Problems(const Options& o) {
    std::vector<std::string> problems = o.config.Validate();
    for (auto& p : o.server_config.Validate()) problems.push_back(p);
    if (!(o.speed >= 0)) problems.push_back("--speed must be >= 0");
    if (o.snapshot_on_exit && o.server_config.snapshot_dir.empty())
        problems.push_back("--snapshot-on-exit needs --out DIR");
    return problems;
}

// The live page's server, started, its URL printed; none for a replay with --no-serve.
pitmap::Expected<std::unique_ptr<live::LiveServer>> StartServer(live::LiveSession& session,
                                                                const Options& o) {
    std::unique_ptr<live::LiveServer> server;
    if (!o.replay.empty() && o.no_serve) return server;
    server = std::make_unique<live::LiveServer>(session, o.server_config);
    if (auto s = server->Start(); !s) return s.error();
    std::printf(
        "pitmap-live: open http://%s:%d/\n", o.server_config.bind_address.c_str(), server->port());
    std::fflush(stdout);
    return server;
}

// The replay's summary line on stdout.
void PrintReplaySummary(const live::LiveSession& session, const live::ReplayResult& r) {
    const auto c = session.GridStats();
    std::printf(
        "pitmap-live: replayed %lld events of %lld file(s): %.1f s of data in %.2f s "
        "(%.0fx real time), %lld soundings in %lld cells, %lld holidays, peak RSS %.0f "
        "MB\n",
        static_cast<long long>(r.events),
        static_cast<long long>(r.files),
        r.data_seconds,
        r.wall_seconds,
        r.wall_seconds > 0 ? r.data_seconds / r.wall_seconds : 0.0,
        static_cast<long long>(c.soundings),
        static_cast<long long>(c.filled_cells),
        static_cast<long long>(c.holidays),
        pitmap::PeakRssMb());
    std::fflush(stdout);
}

// Replays the logs into the session, then with --hold keeps serving until a signal. Returns
// the exit code.
int Replay(live::LiveSession& session, const Options& o, bool serving) {
    int code = 0;
    auto r = live::ReplayLogs(session, o.replay, o.speed, g_stop);
    if (!r) {
        std::fprintf(stderr, "pitmap-live: %s\n", r.error().message.c_str());
        code = codes::kFailure;
    } else {
        // The page says "replay finished" from here on, not a silent feed.
        session.MarkReplayFinished();
        PrintReplaySummary(session, *r);
    }
    while (o.hold && serving && !g_stop.load()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        session.Tick(WallUtime());
    }
    return code;
}

// Feeds the session from the LCM channels until a signal. Returns the exit code, or an error
// when LCM cannot be opened.
pitmap::Expected<int> Subscribe(live::LiveSession& session, const std::string& lcm_url) {
    lcm::LCM lcm(lcm_url);
    if (!lcm.good()) return pitmap::Error{"cannot open LCM " + lcm_url};
    lcm.subscribeFunction(".*", &OnLcm, &session);
    while (!g_stop.load()) {
        // A signal interrupts the wait (-1 with g_stop set): a normal stop.
        if (lcm.handleTimeout(50) < 0 && !g_stop.load()) {
            std::fprintf(stderr, "pitmap-live: LCM failed on %s\n", lcm_url.c_str());
            return codes::kFailure;
        }
        session.Tick(WallUtime());
    }
    return 0;
}

// The final status JSON (--status-json), a failure to write it makes `code` kFailure.
int WriteStatusJson(live::LiveSession& session, const std::string& path, int code) {
    std::ofstream f(path);
    f << session.StatusJson(WallUtime())
             .dump(2, ' ', false, nlohmann::json::error_handler_t::replace)
      << "\n";
    if (!f) {
        std::fprintf(stderr, "pitmap-live: cannot write %s\n", path.c_str());
        return codes::kFailure;
    }
    return code;
}

// The grid into the snapshot directory (--snapshot-on-exit); a failure is reported only.
void WriteSnapshot(live::LiveSession& session, const std::string& dir) {
    auto path = session.WriteSnapshot(dir);
    if (path) {
        std::printf("pitmap-live: wrote %s\n", path->c_str());
    } else {
        std::fprintf(stderr, "pitmap-live: no snapshot: %s\n", path.error().message.c_str());
    }
}

}  // namespace

int main(int argc, char** argv) try {
    CLI::App app{"pitmap-live: live coverage, status and alarms from the daemon's LCM channels"};
    Options o;
    DeclareOptions(app, o);
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap-live")) return *code;
    if (auto r = ResolveOptions(o); !r) return Usage({r.error().message});
    auto vehicle = ReadVehicle(o);
    if (!vehicle) return Usage({vehicle.error().message});
    if (auto problems = Problems(o); !problems.empty()) return Usage(problems);

    live::LiveSession session(o.config, vehicle->mount, vehicle->mount_known);
    if (!o.replay.empty()) session.MarkReplay();
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    auto server = StartServer(session, o);
    if (!server) {
        std::fprintf(stderr, "pitmap-live: %s\n", server.error().message.c_str());
        return codes::kFailure;
    }

    int code = 0;
    if (o.replay.empty()) {
        auto subscribed = Subscribe(session, o.lcm_url);
        if (!subscribed) {
            std::fprintf(stderr, "pitmap-live: %s\n", subscribed.error().message.c_str());
            return codes::kFailure;
        }
        code = *subscribed;
    } else {
        code = Replay(session, o, *server != nullptr);
    }
    if (!o.status_json.empty()) code = WriteStatusJson(session, o.status_json, code);
    if (*server) (*server)->Stop();
    if (o.snapshot_on_exit) WriteSnapshot(session, o.server_config.snapshot_dir);
    return code;
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap-live: internal error: %s\n", e.what());
    return codes::kInternal;
}
