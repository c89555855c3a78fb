// SPDX-License-Identifier: MIT
// The vehicle-to-shore contract for ping times (issue 16): a log written by the daemon's own
// SensorChannel and LogWriter (scripted byte source, manual clock, host clock model fed NovAtel
// samples) is ingested twice, from the decoded MULTIBEAM_PING_<ID> channel and by re-decoding
// RAW_<ID>; every ping must get the same GPS time, to the microsecond. The scenario walks
// every branch of the stamping rule (common/clock/ping_time.hpp): no host time yet, receive-
// time fallback while the header model converges, header model, a receiver reset (host model
// cleared), a topside clock jump (fallback while it is confirmed), unparsable header clocks;
// over UDP with kernel receive times (v1.10 latencies) and over a TCP stream cut into odd
// chunks (v1.00, records split across chunks).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <pitmap/multibeam_ping_t.hpp>
#include <pitmap/raw_bytes_t.hpp>

#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/publisher.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"
#include "lcmtypes/log/channels.hpp"
#include "processor/io/ingest.hpp"
#include "tests/firmware_host/daemon/acq_test_util.hpp"

namespace pitmap::proc::io {
namespace {

namespace dt = protocol::deltat;

constexpr std::int64_t kT0 = 1'700'000'000'000'000;    // host Unix us at the start
constexpr std::int64_t kHostBehindGpsUs = 250'000;     // host clock error against UTC
constexpr std::int64_t kTopsideOffsetUs = -3'700'000;  // topside clock error at the start
constexpr double kTopsideDriftPpm = 40.0;
constexpr std::int64_t kTopsideJumpUs = 2'500'000;  // the topside clock steps at kJumpPing
constexpr int kPings = 1500;                        // 10 Hz: 150 s
constexpr int kFirstHostTimePing = 30;              // NovAtel time from here on
constexpr int kResetFrom = 600;                     // receiver without time: pings [600, 630)
constexpr int kResetTo = 630;
constexpr int kJumpPing = 900;

std::int64_t GpsOfHost(std::int64_t host) {
    return GpsFromUnix(host) + kHostBehindGpsUs;
}

std::int64_t Topside(std::int64_t host, int ping) {
    const double drift = kTopsideDriftPpm * 1e-6 * static_cast<double>(host - kT0);
    return host + kTopsideOffsetUs + static_cast<std::int64_t>(drift) +
           (ping >= kJumpPing ? kTopsideJumpUs : 0);
}

struct Scenario {
    const char* name;
    acq::Transport transport;
    std::uint8_t format_version;
};

dt::Ping83P MakePing(const Scenario& sc, int number, std::int64_t header_host) {
    dt::Ping83P p;
    p.format_version = sc.format_version;
    dt::SetHeaderTime(p, Topside(header_host, number));
    if (number % 97 == 50) {
        // A header clock the topside garbled: the ping falls back to its receive time.
        const char bad[] = "XX-XXX-XXXX";
        std::copy(std::begin(bad), std::end(bad) - 1, p.date_text.begin());
    }
    p.sector_size_deg = 120;
    p.start_angle_cdeg = -6000;
    p.angle_increment_cdeg = 50;
    p.acoustic_range_m = 50;
    p.frequency_khz = 260;
    p.range_resolution_mm = 10;
    p.repetition_rate_ms = 100;
    p.ping_number = static_cast<std::uint32_t>(number);
    if (sc.format_version >= dt::kVersion110) {
        p.ping_latency_us = 2'000;
        p.data_latency_us = 12'000;
    }
    p.range_counts.assign(240, static_cast<std::uint16_t>(1000 + number % 500));
    return p;
}

struct LivePing {
    std::int64_t utime_gps = 0;
    std::int8_t source = 0;
};

struct Replay {
    std::string dir;
    std::map<std::int64_t, LivePing> live;  // MULTIBEAM_PING_ as logged, by ping number
    std::vector<pitmap::raw_bytes_t> raw;   // RAW_ as logged
};

// Runs the daemon's channel through the scenario; returns the log directory and its pings.
Replay RunDaemon(const Scenario& sc) {
    Replay out;
    out.dir = acq::testing::FreshDir(std::string("ping_replay_") + sc.name);
    acq::LogWriter log(
        acq::LogWriterConfig{.directory = out.dir, .prefix = "t", .min_free_bytes = 0});
    acq::LcmPublisher publisher(acq::LcmPublisherConfig{.lcm_url = ""}, &log);
    EXPECT_TRUE(log.Start().ok());
    EXPECT_TRUE(publisher.Start().ok());

    acq::testing::FakeSource src(sc.transport);
    acq::ManualClock clock(kT0);
    acq::TimeKeeper time;
    acq::SensorChannelConfig cfg;
    cfg.id = "mb";
    cfg.protocol = acq::ChannelProtocol::kDeltat83P;
    acq::SensorChannel ch(cfg, src, publisher, clock, time);
    EXPECT_TRUE(src.Open().ok());

    std::mt19937_64 rng(16);
    std::uniform_int_distribution<std::int64_t> within_ms(0, 999);
    std::uniform_int_distribution<std::int64_t> transport_delay(0, 20'000);
    std::uniform_int_distribution<std::int64_t> host_after_kernel(20, 900);
    std::uniform_int_distribution<std::int64_t> novatel_delay(0, 1'500);
    const std::vector<std::size_t> chunk_sizes = {1, 7, 13, 61, 251, 1021, 3, 500};
    std::size_t chunk_index = 0;
    std::vector<std::uint8_t> stream;  // TCP bytes not yet delivered
    std::int64_t next_novatel = kT0;

    for (int i = 0; i < kPings; ++i) {
        const std::int64_t header_host = kT0 + i * 100'000 + within_ms(rng);
        const dt::Ping83P ping = MakePing(sc, i, header_host);
        const std::int64_t sent = header_host + std::max(ping.data_latency_us, 5'000);
        const std::int64_t kernel = sent + transport_delay(rng);
        const std::int64_t host = kernel + host_after_kernel(rng);
        // 50 Hz NovAtel time up to the arrival (the reader threads interleave like this).
        for (; next_novatel <= host; next_novatel += 20'000) {
            const int at_ping = static_cast<int>((next_novatel - kT0) / 100'000);
            if (at_ping < kFirstHostTimePing) continue;
            const bool valid = at_ping < kResetFrom || at_ping >= kResetTo;
            time.AddNovatel(
                next_novatel + novatel_delay(rng), valid ? GpsOfHost(next_novatel) : 0, valid);
        }
        const std::vector<std::uint8_t> record = dt::EncodeRecord83P(ping);
        if (sc.transport == acq::Transport::kUdp) {
            src.PushData(record, host, kernel);
            ch.RunOnce();
        } else {
            stream.insert(stream.end(), record.begin(), record.end());
            std::int64_t t = host;
            while (stream.size() >= chunk_sizes[chunk_index % chunk_sizes.size()]) {
                const std::size_t n = chunk_sizes[chunk_index++ % chunk_sizes.size()];
                src.PushData(std::vector<std::uint8_t>(stream.begin(),
                                                       stream.begin() + static_cast<long>(n)),
                             t);
                stream.erase(stream.begin(), stream.begin() + static_cast<long>(n));
                t += 37;
                ch.RunOnce();
            }
        }
        clock.AdvanceUs(100'000);
    }
    if (!stream.empty()) src.PushData(stream, kT0 + kPings * 100'000);
    src.PushEnd();
    while (ch.RunOnce()) {
    }
    publisher.Stop();
    log.Stop();

    const std::string ping_channel = lcmlog::ChannelName(lcmlog::kChannelMultibeamPing, "mb");
    const std::string raw_channel = lcmlog::ChannelName(lcmlog::kChannelRaw, "mb");
    for (const auto& e : acq::testing::ReadLogDir(out.dir)) {
        if (e.channel == ping_channel) {
            const auto m = acq::testing::DecodeAs<pitmap::multibeam_ping_t>(e.data);
            out.live[m.ping_number] = {m.utime_gps, m.gps_time_source};
        } else if (e.channel == raw_channel) {
            out.raw.push_back(acq::testing::DecodeAs<pitmap::raw_bytes_t>(e.data));
        }
    }
    return out;
}

std::vector<std::string> LogFiles(const std::string& dir) {
    std::vector<std::string> files;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        if (e.path().extension() == ".lcmlog") files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    return files;
}

class PingTimeReplay : public ::testing::TestWithParam<Scenario> {};

TEST_P(PingTimeReplay, RedecodedRawGivesTheDaemonsTimes) {
    const Scenario sc = GetParam();
    const Replay rep = RunDaemon(sc);
    ASSERT_EQ(rep.live.size(), static_cast<std::size_t>(kPings));

    // The scenario reaches every branch of the rule.
    std::map<std::int8_t, int> by_source;
    for (const auto& [n, p] : rep.live) ++by_source[p.source];
    EXPECT_GE(by_source[pitmap::multibeam_ping_t::TIME_SOURCE_NONE], kFirstHostTimePing - 2);
    // Garbled header clocks (1 in 97) and the jump's confirmation samples.
    EXPECT_GE(by_source[pitmap::multibeam_ping_t::TIME_SOURCE_RECEIVE], 15);
    EXPECT_GE(by_source[pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK], kPings / 2);

    const std::vector<std::string> files = LogFiles(rep.dir);
    ASSERT_FALSE(files.empty());
    IngestConfig cfg;
    cfg.source = IngestSource::kDecoded;
    auto decoded = IngestLcmLogs(files, cfg);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    cfg.source = IngestSource::kRaw;
    auto raw = IngestLcmLogs(files, cfg);
    ASSERT_TRUE(raw.ok()) << raw.error().message;
    EXPECT_TRUE(raw->pings_from_raw);

    const auto& a = decoded->pings.pings;
    const auto& b = raw->pings.pings;
    std::size_t with_time = 0;
    for (const auto& [n, p] : rep.live) with_time += p.utime_gps != 0 ? 1 : 0;
    EXPECT_EQ(a.size(), with_time);
    ASSERT_EQ(b.size(), a.size());
    EXPECT_EQ(raw->counts.pings_without_time, decoded->counts.pings_without_time);
    EXPECT_EQ(raw->counts.pings_bad, 0);
    EXPECT_EQ(raw->pings.range_counts, decoded->pings.range_counts);
    std::int64_t max_diff_us = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        ASSERT_EQ(b[k].ping_number, a[k].ping_number) << "at " << k;
        EXPECT_EQ(b[k].utime_gps, a[k].utime_gps) << "ping " << a[k].ping_number;
        EXPECT_EQ(a[k].utime_gps, rep.live.at(a[k].ping_number).utime_gps);
        max_diff_us = std::max(max_diff_us, std::abs(b[k].utime_gps - a[k].utime_gps));
    }
    std::printf(
        "%s: %zu pings compared (header clock %d, receive time %d; %lld without time in both), "
        "max |raw - decoded| = %lld us\n",
        sc.name,
        a.size(),
        by_source[pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK],
        by_source[pitmap::multibeam_ping_t::TIME_SOURCE_RECEIVE],
        static_cast<long long>(decoded->counts.pings_without_time),
        static_cast<long long>(max_diff_us));

    if (sc.transport == acq::Transport::kUdp) {
        // The comparison can tell rules apart: the shore's former rule (receive GPS time minus
        // the header's transmit age) misses the header model's times by the transport delay.
        dt::FloatOrderMemory memory;
        dt::Ping83P p;
        std::int64_t old_rule_max_us = 0;
        for (const auto& r : rep.raw) {
            const auto d =
                dt::DecodeDatagramInto(ByteSpan(r.data.data(), r.data.size()), memory, p);
            if (!std::holds_alternative<dt::RecordKind>(d) || r.utime_gps == 0) continue;
            const LivePing& live = rep.live.at(p.ping_number);
            if (live.source != pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK) continue;
            const std::int64_t old_rule = r.utime_gps - std::max(0, p.TransmitAgeAtSendUs());
            old_rule_max_us = std::max(old_rule_max_us, std::abs(old_rule - live.utime_gps));
        }
        std::printf("%s: the former shore rule was up to %lld us off\n",
                    sc.name,
                    static_cast<long long>(old_rule_max_us));
        EXPECT_GT(old_rule_max_us, 5'000);
    }
}

INSTANTIATE_TEST_SUITE_P(Transports,
                         PingTimeReplay,
                         ::testing::Values(Scenario{"udp_v110", acq::Transport::kUdp, 10},
                                           Scenario{"tcp_v100", acq::Transport::kTcp, 0}),
                         [](const auto& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace pitmap::proc::io
