// SPDX-License-Identifier: MIT
// PPS through the RFC 2783 path, without a PPS device (none exists here): the config
// (`pps_device` must exist and be a character device, checked at start-up, also by the real
// binary's --check-config), PpsChannel feeding a scripted PpsSource into the TimeKeeper
// (pulses labelled by the NovAtel model remove its delay floor; far pulses are rejected;
// device errors are counted and the device reopened), and the Daemon running the PPS thread.
// Rfc2783PpsSource itself is only checked on its error path (a non-PPS character device).
#include <gtest/gtest.h>

#include <atomic>
#include <deque>
#include <filesystem>
#include <mutex>

#include "common/gps_time.hpp"
#include "firmware_host/daemon/daemon.hpp"
#include "firmware_host/daemon/daemon_config.hpp"
#include "firmware_host/daemon/pps_channel.hpp"
#include "firmware_host/io/pps_source.hpp"
#include "tests/firmware_host/daemon/acqd_process_util.hpp"

namespace pitmap::acq {
namespace {

constexpr std::int64_t kT0 = 1'700'000'000'000'000;
// Truth: GPS time of host instant h (host clock 123.456 ms behind).
std::int64_t Gps(std::int64_t h) {
    return GpsFromUnix(h, 18) + 123'456;
}
// Host instant at which GPS time is `gps`.
std::int64_t HostAt(std::int64_t gps) {
    return UnixFromGps(gps - 123'456, 18);
}

// A scripted PPS device: pulses, timeouts and failures in order; then timeouts.
class FakePps final : public PpsSource {
public:
    struct Step {
        enum class Kind { kPulse, kTimeout, kError } kind;
        std::int64_t utime = 0;
    };
    void Push(Step s) {
        std::lock_guard<std::mutex> lock(mu_);
        steps_.push_back(s);
    }
    Status Open() override {
        ++opens;
        return Ok{};
    }
    Expected<PpsOutcome> Fetch(PpsPulse& pulse, int timeout_ms) override {
        Step s{Step::Kind::kTimeout};
        {
            std::lock_guard<std::mutex> lock(mu_);
            if (!steps_.empty()) {
                s = steps_.front();
                steps_.pop_front();
                ++consumed;
            }
        }
        switch (s.kind) {
            case Step::Kind::kPulse:
                pulse.utime_assert = s.utime;
                pulse.sequence = static_cast<std::uint64_t>(++sequence_);
                return PpsOutcome::kPulse;
            case Step::Kind::kError:
                return Error{"fake pps: device went away"};
            case Step::Kind::kTimeout:
                std::this_thread::sleep_for(std::chrono::milliseconds(std::min(timeout_ms, 5)));
                return PpsOutcome::kTimeout;
        }
        return PpsOutcome::kTimeout;
    }
    void Close() override { ++closes; }
    std::string description() const override { return "fake pps"; }

    std::atomic<int> opens{0};
    std::atomic<int> closes{0};
    std::atomic<int> consumed{0};

private:
    std::mutex mu_;
    std::deque<Step> steps_;
    std::int64_t sequence_ = 0;
};

std::string BaseYaml(const std::string& dir) {
    return "lcm_url: \"memq://\"\nlog:\n  directory: " + dir +
           "/logs\n  min_free_bytes: 0\nchannels:\n  - id: mb\n    protocol: deltat_83p\n"
           "    udp: {bind_address: 127.0.0.1, allowed_senders: [127.0.0.1], port: 0}\n";
}

TEST(PpsConfigTest, DeviceMustExistAndBeACharacterDevice) {
    const std::string dir = testing::FreshDir("pps_config");
    const auto none = LoadDaemonConfigFromString(BaseYaml(dir), "none");
    EXPECT_TRUE(none.problems.empty());
    EXPECT_TRUE(none.config.pps.device.empty());

    const auto missing =
        LoadDaemonConfigFromString(BaseYaml(dir) + "pps_device: /nonexistent/pps9\n", "missing");
    ASSERT_EQ(missing.problems.size(), 1u);
    EXPECT_NE(missing.problems[0].find("pps_device"), std::string::npos) << missing.problems[0];
    EXPECT_NE(missing.problems[0].find("/nonexistent/pps9"), std::string::npos);

    testing::WriteText(dir + "/plain", "not a device");
    const auto plain = LoadDaemonConfigFromString(
        BaseYaml(dir) + "pps_device: " + dir + "/plain\npps_fetch_timeout_ms: 0\n", "plain");
    ASSERT_EQ(plain.problems.size(), 2u);
    EXPECT_NE(plain.problems[0].find("not a character device"), std::string::npos);
    EXPECT_NE(plain.problems[1].find("fetch_timeout_ms"), std::string::npos);

    const auto ok = LoadDaemonConfigFromString(BaseYaml(dir) + "pps_device: /dev/null\n", "ok");
    EXPECT_TRUE(ok.problems.empty());
    EXPECT_EQ(ok.config.pps.device, "/dev/null");
}

TEST(PpsConfigTest, BinaryRejectsAMissingDeviceAtStartUp) {
    const std::string dir = testing::FreshDir("pps_binary");
    testing::WriteText(dir + "/c.yaml", BaseYaml(dir) + "pps_device: /nonexistent/pps9\n");
    for (const bool check_only : {true, false}) {
        std::vector<std::string> args = {"--config", dir + "/c.yaml"};
        if (check_only) args.push_back("--check-config");
        const pid_t pid = testing::SpawnAcqd(args, dir + "/err.txt");
        EXPECT_EQ(testing::WaitExit(pid), 2);
        EXPECT_NE(testing::ReadText(dir + "/err.txt").find("/nonexistent/pps9"), std::string::npos);
    }
    EXPECT_FALSE(std::filesystem::exists(dir + "/logs"));  // nothing was started
}

TEST(PpsSourceTest, Rfc2783SourceFailsCleanlyOnANonPpsDevice) {
    Rfc2783PpsSource src("/dev/null");
    const Status s = src.Open();
    ASSERT_FALSE(s.ok());
    if (Rfc2783Available()) {
        EXPECT_NE(s.error().message.find("time_pps_create"), std::string::npos)
            << s.error().message;
    } else {
        EXPECT_NE(s.error().message.find("pps-tools"), std::string::npos) << s.error().message;
    }
    PpsPulse p;
    EXPECT_FALSE(src.Fetch(p, 1).ok());
    src.Close();
}

TEST(PpsChannelTest, PulsesRemoveTheDelayFloorOfTheMessageModel) {
    TimeKeeper time;
    // NovAtel messages every 50 ms for 30 s, each 3..8 ms late: the lower envelope sits on
    // the 3 ms floor, which no message-only model can see.
    const std::int64_t end = kT0 + 30'000'000;
    for (std::int64_t h = kT0, i = 0; h < end; h += 50'000, ++i) {
        const std::int64_t delay = 3'000 + (i * 7919) % 5'000;
        time.AddNovatel(h, Gps(h - delay), true);
    }
    const std::int64_t query = end - 200'000;
    const std::int64_t envelope_error = time.HostToGps(query).utime_gps - Gps(query);
    EXPECT_NEAR(static_cast<double>(envelope_error), -3'000.0, 200.0);
    EXPECT_FALSE(time.HostQuality(query).from_pps);

    FakePps pps;
    const std::int64_t first_second = Gps(end - 6'000'000) / 1'000'000 + 1;
    for (std::int64_t k = 0; k < 5; ++k) {
        if (k == 2) {
            pps.Push({FakePps::Step::Kind::kError});
            // A pulse 400 ms off a whole second (a glitch): rejected.
            pps.Push(
                {FakePps::Step::Kind::kPulse, HostAt((first_second + k) * 1'000'000) - 400'000});
        }
        pps.Push({FakePps::Step::Kind::kPulse, HostAt((first_second + k) * 1'000'000)});
        pps.Push({FakePps::Step::Kind::kTimeout});
    }
    PpsChannel channel(pps, time, 100, nullptr, BackoffConfig{.initial_ms = 1, .max_ms = 2});
    for (int i = 0; i < 1000 && pps.consumed.load() < 12; ++i) channel.RunOnce();
    ASSERT_EQ(pps.consumed.load(), 12);

    const PpsCounters c = channel.counters();
    EXPECT_EQ(c.pulses, 6);
    EXPECT_EQ(c.used, 5);
    EXPECT_EQ(c.rejected, 1);
    EXPECT_EQ(c.errors, 1);
    EXPECT_EQ(c.opens, 2);  // reopened after the failure
    EXPECT_EQ(c.timeouts, 5);
    EXPECT_NE(c.last_error.find("went away"), std::string::npos);

    // With the pulses in use the model has no floor left.
    const std::int64_t last_pulse = HostAt((first_second + 4) * 1'000'000);
    for (const std::int64_t h : {last_pulse - 1'500'000, last_pulse, last_pulse + 500'000}) {
        const GpsEstimate e = time.HostToGps(h);
        EXPECT_EQ(e.state, ClockState::kLocked);
        EXPECT_NEAR(static_cast<double>(e.utime_gps - Gps(h)), 0.0, 5.0) << h;
    }
    const ClockQuality q = time.HostQuality(last_pulse + 500'000);
    EXPECT_TRUE(q.from_pps);
    EXPECT_EQ(time.HostClockSync(last_pulse + 500'000).source,
              pitmap::clock_sync_t::SOURCE_HOST_FROM_PPS);
}

TEST(PpsChannelTest, DaemonRunsThePpsThreadWhenADeviceIsConfigured) {
    const std::string dir = testing::FreshDir("pps_daemon");
    auto loaded = LoadDaemonConfigFromString(BaseYaml(dir) + "pps_device: /dev/null\n", "t");
    ASSERT_TRUE(loaded.problems.empty());
    auto fake = std::make_unique<FakePps>();
    FakePps& pps = *fake;
    // No NovAtel channel, so no model: every pulse is fetched and rejected (not invented).
    for (int k = 0; k < 3; ++k) pps.Push({FakePps::Step::Kind::kPulse, kT0 + k * 1'000'000});
    SystemClock clock;
    Daemon daemon(std::move(loaded.config), clock, std::move(fake));
    ASSERT_TRUE(daemon.Start().ok());
    EXPECT_TRUE(testing::WaitFor([&] { return pps.consumed.load() == 3; }));
    EXPECT_TRUE(testing::WaitFor([&] { return daemon.pps_counters().pulses == 3; }));
    daemon.Stop();
    const PpsCounters c = daemon.pps_counters();
    EXPECT_EQ(c.pulses, 3);
    EXPECT_EQ(c.rejected, 3);
    EXPECT_EQ(c.used, 0);
    EXPECT_EQ(c.opens, 1);
    EXPECT_GE(pps.closes.load(), 1);
    EXPECT_EQ(daemon.Snapshot().host_clock.source, pitmap::clock_sync_t::SOURCE_HOST_FROM_NOVATEL);
}

}  // namespace
}  // namespace pitmap::acq
