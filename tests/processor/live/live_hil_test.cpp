// SPDX-License-Identifier: MIT
// pitmap live through real processes: the HIL rig (`pitmap-sim hil`: NovAtel on a pty and TCP,
// Delta T on UDP, in real time) feeds the real pitmap-acqd, which publishes on an isolated LCM
// multicast URL (its own port); pitmap-live subscribes there and serves its JSON. While the
// survey runs, the coverage served must grow, pings be georeferenced as they arrive, and the
// daemon's status (clocks, channels) show up. Skips when a program is not built or the machine
// has no ptys.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/process.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using pitmap::test::FreePort;
using pitmap::test::ReadText;
using pitmap::test::Spawn;
using pitmap::test::Wait;

namespace {

constexpr double kDurationS = 16.0;

// GET http://127.0.0.1:port/path; the body, or "" on any failure.
std::string HttpGet(int port, const std::string& path) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) return "";
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    std::string body;
    if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0) {
        const std::string req =
            "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
        if (::send(fd, req.data(), req.size(), 0) == static_cast<ssize_t>(req.size())) {
            std::string resp;
            char buf[65536];
            for (;;) {
                const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
                if (n <= 0) break;
                resp.append(buf, static_cast<std::size_t>(n));
            }
            const std::size_t at = resp.find("\r\n\r\n");
            if (resp.rfind("HTTP/1.1 200", 0) == 0 && at != std::string::npos)
                body = resp.substr(at + 4);
        }
    }
    ::close(fd);
    return body;
}

TEST(LiveHil, CoverageGrowsWhileTheDaemonPublishes) {
    const fs::path bin = PITMAP_BIN_DIR;
    const fs::path acqd = bin / "pitmap-acqd", sim = bin / "pitmap-sim", live = bin / "pitmap-live";
    for (const fs::path& p : {acqd, sim, live}) {
        if (!fs::exists(p)) GTEST_SKIP() << p.filename() << " is not built: test skipped";
    }
    const fs::path dir = pitmap::test::FreshDir("pitmap_live_hil");
    const int lcm_port = FreePort(SOCK_DGRAM), http_port = FreePort(SOCK_STREAM);
    const int tcp_port = FreePort(SOCK_STREAM), udp_port = FreePort(SOCK_DGRAM);
    ASSERT_GT(lcm_port, 0);
    ASSERT_GT(http_port, 0);
    const std::string url =
        "udpm://239.255.76.67:" + std::to_string(lcm_port) + "?ttl=0&recv_buf_size=4194304";

    const pid_t live_pid = Spawn({live.string(),
                                  "--lcm-url",
                                  url,
                                  "--port",
                                  std::to_string(http_port),
                                  "--cell-size",
                                  "0.5",
                                  // The budget's sharing is checked below, from this machine.
                                  "--budget-loopback",
                                  "--out",
                                  (dir / "snapshots").string()},
                                 (dir / "live.out").string());
    // pitmap-live is up when it answers.
    json status;
    for (int k = 0; k < 100 && status.is_null(); ++k) {
        const std::string body = HttpGet(http_port, "/api/status");
        if (!body.empty()) status = json::parse(body);
        if (status.is_null()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_FALSE(status.is_null()) << ReadText(dir / "live.out");
    EXPECT_EQ(status["grid"]["filled_cells"], 0);

    const pid_t sim_pid = Spawn(
        pitmap::test::HilRigArgs(
            bin, kDurationS, dir / "run", dir / "com1", tcp_port, udp_port, {"--lcm-url", url}),
        (dir / "sim.out").string());
    // Poll while the survey runs: the filled cells seen, in order.
    std::vector<std::int64_t> cells;
    int sim_rc = -2;
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::seconds(static_cast<int>(kDurationS) + 90);
    while (std::chrono::steady_clock::now() < deadline) {
        int st = 0;
        if (::waitpid(sim_pid, &st, WNOHANG) == sim_pid) {
            sim_rc = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
            break;
        }
        const std::string body = HttpGet(http_port, "/api/status");
        if (!body.empty()) {
            status = json::parse(body);
            const std::int64_t c = status["grid"]["filled_cells"];
            if (cells.empty() || c != cells.back()) cells.push_back(c);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    if (sim_rc == -2) {
        ::kill(sim_pid, SIGTERM);
        Wait(sim_pid, 20);
    }
    const std::string sim_out = ReadText(dir / "sim.out");
    if (sim_rc != 0 && sim_out.find("no pseudo-terminal") != std::string::npos) {
        ::kill(live_pid, SIGTERM);
        Wait(live_pid, 10);
        GTEST_SKIP() << "no pty support on this machine: " << sim_out;
    }
    ASSERT_EQ(sim_rc, 0) << sim_out << "\n--- acqd.out:\n" << ReadText(dir / "run" / "acqd.out");
    // Let pitmap-live take the last messages, then read its final state.
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    status = json::parse(HttpGet(http_port, "/api/status"));
    const json tiles = json::parse(HttpGet(http_port, "/api/tiles?since=0&client=hil1"));
    const std::string bad = HttpGet(http_port, "/api/tiles?since=-1");
    const std::string bad_client = HttpGet(http_port, "/api/tiles?since=0&client=a%20b");
    const json budget = json::parse(HttpGet(http_port, "/api/status?client=hil2"))["budget"];
    ::kill(live_pid, SIGTERM);
    const int live_rc = Wait(live_pid, 10);
    EXPECT_EQ(live_rc, 0) << ReadText(dir / "live.out");

    // New coverage seen at least three times while the survey ran (not only at its end).
    ASSERT_GE(cells.size(), 3u) << status.dump(1);
    for (std::size_t k = 1; k < cells.size(); ++k) EXPECT_GT(cells[k], cells[k - 1]);
    // The daemon published about 10 pings a second; pitmap-live georeferenced nearly all of
    // them (the last ones may wait for the navigation that would bracket them).
    const std::int64_t pings = status["pings"];
    EXPECT_GT(pings, static_cast<std::int64_t>(8 * (kDurationS - 4))) << status.dump(1);
    EXPECT_GE(status["georef"]["pings_georeferenced"].get<std::int64_t>(), pings - 5);
    EXPECT_GT(status["grid"]["filled_cells"].get<std::int64_t>(), 500);
    EXPECT_FALSE(tiles["tiles"].empty());
    EXPECT_TRUE(bad.empty());         // refused (HTTP 400)
    EXPECT_TRUE(bad_client.empty());  // refused (HTTP 400)
    // Two page ids seen within the idle time: each has half the link.
    EXPECT_GE(budget["clients"].get<int>(), 2) << budget.dump();
    EXPECT_LE(budget["client_rate_bytes_per_s"].get<double>(),
              budget["rate_bytes_per_s"].get<double>() / 2 + 1e-6);
    // TVU status (the default sensor error model: no --vehicle): nearly every cell meets S-44
    // order 1a, every georeferenced ping had an INS sigma (the INS's or the model's), no alarm.
    const json& tvu = status["grid"]["tvu"];
    EXPECT_EQ(tvu["order"], "1a");
    ASSERT_TRUE(tvu["share_meeting"].is_number()) << tvu.dump();
    EXPECT_GT(tvu["share_meeting"].get<double>(), 0.9) << tvu.dump();
    EXPECT_GT(tvu["last_batch_median_tvu_m"].get<double>(), 0.01) << tvu.dump();
    EXPECT_LT(tvu["last_batch_median_tvu_m"].get<double>(), 0.5) << tvu.dump();
    EXPECT_EQ(tvu["pings_with_ins_sigma"].get<std::int64_t>() +
                  tvu["pings_with_model_sigma"].get<std::int64_t>(),
              status["georef"]["pings_georeferenced"].get<std::int64_t>());
    for (const json& a : status["alarms"]) EXPECT_NE(a["id"], "tvu_over_limit") << a.dump();
    ASSERT_FALSE(tiles["tiles"].empty());
    EXPECT_TRUE(tiles["tiles"][0]["tvu"].is_string());
    EXPECT_EQ(tiles["tvu"]["order"], "1a");
    // The daemon's own status arrived: its channels, its host clock model.
    ASSERT_TRUE(status["daemon"].is_object()) << status.dump(1);
    EXPECT_GE(status["daemon"]["channels"].size(), 2u);
    bool host_clock = false;
    for (const json& c : status["clocks"]) host_clock |= c["source"] == "host_from_novatel";
    EXPECT_TRUE(host_clock) << status["clocks"].dump();
    EXPECT_EQ(status["counts"]["decode_failures"], 0);
    fs::remove_all(dir);
}

}  // namespace
