// SPDX-License-Identifier: MIT
// pitmap-acqd: the onboard acquisition daemon (issue 4). Arguments -> YAML -> DaemonConfig ->
// every problem listed -> Daemon -> run until SIGTERM/SIGINT (flush, exit 0); SIGHUP starts a
// new log file. With file sources only, it exits once every file is replayed.
//
//   pitmap-acqd --config FILE [--check-config]
//   pitmap-acqd --version | --help
//
// Exit codes (common/exit_codes.hpp, docs/cli.md): 0 ok, 1 start-up failure (the host checks
// of startup_check.hpp, the log directory, LCM), 2 usage or invalid config (with
// --check-config: any problem, host checks included; an unknown argument names the closest
// known one), 3 internal error. Warnings (a serial device not there yet, a UDP port in use) do
// not stop it.
// Signals are blocked in every thread and taken synchronously here (sigtimedwait), so only
// main handles them.
#include <signal.h>

#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "common/cli/suggest.hpp"
#include "common/exit_codes.hpp"
#include "common/version.hpp"
#include "firmware_host/daemon/clock.hpp"
#include "firmware_host/daemon/daemon.hpp"
#include "firmware_host/daemon/daemon_config.hpp"
#include "firmware_host/daemon/startup_check.hpp"

namespace {

namespace codes = pitmap::exit_code;

void Usage(std::FILE* to) {
    std::fprintf(to,
                 "usage: pitmap-acqd --config FILE [--check-config]\n"
                 "  --config FILE     daemon configuration (YAML)\n"
                 "  --check-config    validate FILE, list every problem, exit\n"
                 "  --version         print the version and git commit\n"
                 "  -h, --help        print this help\n");
}

int Run(int argc, char** argv) {
    std::string config_path;
    bool check_only = false;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--config" && i + 1 < argc) {
            config_path = argv[++i];
        } else if (a.rfind("--config=", 0) == 0) {
            config_path = a.substr(9);
        } else if (a == "--check-config") {
            check_only = true;
        } else if (a == "--help" || a == "-h") {
            Usage(stdout);
            return codes::kOk;
        } else if (a == "--version") {
            std::printf("%s\n", pitmap::VersionLine("pitmap-acqd").c_str());
            return codes::kOk;
        } else if (a == "--config") {
            std::fprintf(stderr, "pitmap-acqd: --config needs a FILE\n");
            Usage(stderr);
            return codes::kUsage;
        } else {
            const std::string name = a.substr(0, a.find('='));
            std::fprintf(
                stderr,
                "pitmap-acqd: unknown argument '%s'%s\n",
                a.c_str(),
                pitmap::cli::DidYouMean(name, {"--config", "--check-config", "--version", "--help"})
                    .c_str());
            Usage(stderr);
            return codes::kUsage;
        }
    }
    if (config_path.empty()) {
        Usage(stderr);
        return codes::kUsage;
    }
    pitmap::acq::LoadedConfig loaded = pitmap::acq::LoadDaemonConfig(config_path);
    // What the host must offer (log directory, devices, ports): checked here too, before any
    // thread starts, so a start-up fails with the whole list rather than the first problem.
    const pitmap::acq::HostCheck host = pitmap::acq::CheckHost(loaded.config);
    for (const auto& w : host.warnings) {
        std::fprintf(stderr, "pitmap-acqd: warning: %s\n", w.c_str());
    }
    std::vector<std::string> problems = loaded.problems;
    problems.insert(problems.end(), host.errors.begin(), host.errors.end());
    if (!problems.empty()) {
        std::fprintf(
            stderr, "pitmap-acqd: %s: %zu problem(s):\n", config_path.c_str(), problems.size());
        for (const auto& p : problems) std::fprintf(stderr, "  - %s\n", p.c_str());
        return check_only || !loaded.problems.empty() ? codes::kUsage : codes::kFailure;
    }
    if (check_only) {
        std::printf("%s: ok (%zu channels%s)\n",
                    config_path.c_str(),
                    loaded.config.channels.size(),
                    host.warnings.empty() ? "" : ", warnings");
        return 0;
    }

    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGTERM);
    sigaddset(&signals, SIGINT);
    sigaddset(&signals, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);  // before any thread starts
    signal(SIGPIPE, SIG_IGN);

    pitmap::acq::SystemClock clock;
    pitmap::acq::Daemon daemon(std::move(loaded.config), clock);
    if (auto s = daemon.Start(); !s) {
        std::fprintf(stderr, "pitmap-acqd: %s\n", s.error().message.c_str());
        return codes::kFailure;
    }
    std::fprintf(stderr,
                 "pitmap-acqd: running with %zu channels, logging to %s\n",
                 daemon.config().channels.size(),
                 daemon.config().log.directory.c_str());
    const int period_ms = daemon.config().status_period_ms;
    std::int64_t next_status = clock.MonotonicUs();
    while (true) {
        const std::int64_t wait_us = std::max<std::int64_t>(0, next_status - clock.MonotonicUs());
        timespec timeout{static_cast<time_t>(wait_us / 1'000'000),
                         static_cast<long>((wait_us % 1'000'000) * 1000)};
        const int sig = sigtimedwait(&signals, nullptr, &timeout);
        if (sig == SIGTERM || sig == SIGINT) {
            std::fprintf(stderr, "pitmap-acqd: %s, flushing and exiting\n", strsignal(sig));
            break;
        }
        if (sig == SIGHUP) {
            std::fprintf(stderr, "pitmap-acqd: SIGHUP, rotating the log\n");
            daemon.Rotate();
            continue;
        }
        if (clock.MonotonicUs() >= next_status) {
            daemon.PublishStatus();
            next_status += std::int64_t{period_ms} * 1000;
            if (daemon.AllFinished()) {
                std::fprintf(stderr, "pitmap-acqd: every source reached its end\n");
                break;
            }
        }
    }
    daemon.Stop();
    return codes::kOk;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return Run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "pitmap-acqd: internal error: %s\n", e.what());
        return codes::kInternal;
    }
}
