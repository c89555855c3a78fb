// SPDX-License-Identifier: MIT
// SensorChannel with a scripted ByteSource, a manual clock, memq:// LCM and the real
// LogWriter: real NovAtel captures replayed in odd-sized chunks (per-kind counts equal the
// golden files, RAW_ reproduces the input byte for byte), garbage bursts, set-up commands
// with answers, refusals, silence and reconnects, 83P datagrams with and without GPS time,
// EC steering.
#include "firmware_host/daemon/sensor_channel.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <map>
#include <random>

#include "common/protocol/deltat/ec_frame.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "firmware_host/daemon/daemon_config.hpp"
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/io/udp_source.hpp"
#include "pitmap/channel_status_t.hpp"
#include "tests/firmware_host/daemon/acq_test_util.hpp"
#include "tests/protocol/novatel/test_util.hpp"

namespace pitmap::acq {
namespace {

using testing::DecodeAs;
using testing::FakeSource;
using testing::LogEvent;

constexpr std::int64_t kT0 = 1'700'000'000'000'000;

// Daemon back end of one test: log writer into a fresh directory + memq publisher.
struct Backend {
    explicit Backend(const std::string& name)
        : dir(testing::FreshDir(name)),
          log(LogWriterConfig{.directory = dir, .prefix = "t", .min_free_bytes = 0}),
          publisher(LcmPublisherConfig{.lcm_url = "memq://"}, &log) {
        EXPECT_TRUE(log.Start().ok());
        EXPECT_TRUE(publisher.Start().ok());
    }
    std::vector<LogEvent> Finish() {
        publisher.Stop();
        log.Stop();
        return testing::ReadLogDir(dir);
    }
    std::string dir;
    LogWriter log;
    LcmPublisher publisher;
};

std::vector<std::size_t> OddChunks() {
    return {1, 7, 13, 61, 251, 1021, 4093, 3};
}

// Queues `data` into the source in the cycled chunk sizes, 1 ms apart.
void Feed(FakeSource& src, const std::vector<std::uint8_t>& data, std::int64_t t0) {
    const auto sizes = OddChunks();
    std::size_t pos = 0;
    for (std::size_t i = 0; pos < data.size(); ++i) {
        const std::size_t n = std::min(sizes[i % sizes.size()], data.size() - pos);
        src.PushData(std::vector<std::uint8_t>(data.begin() + static_cast<long>(pos),
                                               data.begin() + static_cast<long>(pos + n)),
                     t0 + static_cast<std::int64_t>(i) * 1000);
        pos += n;
    }
}

void RunToEnd(SensorChannel& ch) {
    while (ch.RunOnce()) {
    }
}

std::vector<std::uint8_t> RawConcat(const std::vector<LogEvent>& events, const std::string& ch) {
    std::vector<std::uint8_t> out;
    std::int64_t expected_seq = 0;
    for (const auto& e : events) {
        if (e.channel != ch) continue;
        const auto raw = DecodeAs<pitmap::raw_bytes_t>(e.data);
        EXPECT_EQ(raw.seq, expected_seq++);
        EXPECT_EQ(raw.utime, e.timestamp);
        EXPECT_EQ(raw.num_bytes, static_cast<std::int32_t>(raw.data.size()));
        out.insert(out.end(), raw.data.begin(), raw.data.end());
    }
    return out;
}

std::map<std::string, std::int64_t> ChannelCounts(const std::vector<LogEvent>& events) {
    std::map<std::string, std::int64_t> n;
    for (const auto& e : events) ++n[e.channel];
    return n;
}

SensorChannelConfig NovatelConfig(const std::string& id) {
    SensorChannelConfig c;
    c.id = id;
    c.protocol = ChannelProtocol::kNovatel;
    return c;
}

class GoldenReplay : public ::testing::TestWithParam<const char*> {};

// Every raw NovAtel capture with a golden file: counts per kind as pitmap-inspect found them,
// CRC failures, bytes; the RAW_ channel in the log is the input, byte for byte.
TEST_P(GoldenReplay, CountsMatchGoldenAndRawIsTheInput) {
    const std::string name = GetParam();
    const auto data = testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/" + name);
    ASSERT_FALSE(data.empty());
    std::ifstream gin(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/golden/" + name + ".json");
    const nlohmann::json golden = nlohmann::json::parse(gin);

    Backend be("golden_" + name);
    FakeSource src;
    ManualClock clock(kT0);
    TimeKeeper time;
    SensorChannel ch(NovatelConfig("nov"), src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    Feed(src, data, kT0);
    src.PushEnd();
    RunToEnd(ch);
    const ChannelCounters c = ch.counters();
    const auto events = be.Finish();

    EXPECT_EQ(c.bytes, golden["input_bytes"].get<std::int64_t>());
    EXPECT_EQ(c.frames, golden["frames_total"].get<std::int64_t>());
    EXPECT_EQ(c.crc_failures, golden["crc_failures"].get<std::int64_t>());
    std::map<std::string, std::int64_t> expected;
    for (const auto& [k, v] : golden["frames_by_id"].items()) expected[k] = v.get<std::int64_t>();
    EXPECT_EQ(c.frame_kinds, expected);
    EXPECT_EQ(c.decode_errors, 0);
    EXPECT_EQ(c.queue_drops, 0);

    EXPECT_EQ(RawConcat(events, "RAW_NOV"), data);
    // Every published message is in the log exactly once.
    EXPECT_EQ(static_cast<std::int64_t>(events.size()), c.published);
    // The status snapshot carries the same counters.
    const auto st = ch.Status();
    EXPECT_EQ(st.bytes, c.bytes);
    EXPECT_EQ(st.frames, c.frames);
    EXPECT_EQ(st.num_frame_kinds, static_cast<std::int32_t>(expected.size()));
    EXPECT_EQ(st.state, pitmap::channel_status_t::STATE_STOPPED);
}

INSTANTIATE_TEST_SUITE_P(NovatelCaptures,
                         GoldenReplay,
                         ::testing::Values("gavlab_OneEach.ASC",
                                           "gavlab_OneEach.GPS",
                                           "gavlab_ParsingData.GPS",
                                           "gavlab_test2_rcvr1.dat",
                                           "oem7drv_align.gps",
                                           "oem7drv_bestpos.gps",
                                           "oem7drv_ins1.gps",
                                           "oem7drv_ins2.gps",
                                           "oem7drv_ins2_humble.gps",
                                           "oem7drv_rxstatus.gps",
                                           "oem7drv_time.gps",
                                           "rtklib_oemv_200911218.gps"),
                         [](const auto& param_info) {
                             std::string n = param_info.param;
                             for (char& ch : n) {
                                 if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                             }
                             return n;
                         });

TEST(SensorChannelTest, InsCapturePublishesDecodedChannelsAndLocksTheHostClock) {
    const auto data =
        testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins2.gps");
    Backend be("ins2");
    FakeSource src;
    ManualClock clock(kT0);
    TimeKeeper time;
    auto cfg = NovatelConfig("nov");
    cfg.imu.imu_rate_hz = 100.0;
    SensorChannel ch(cfg, src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    Feed(src, data, kT0);
    src.PushEnd();
    RunToEnd(ch);
    // memq: the publisher's own LCM object delivers to subscribers on it.
    be.publisher.Drain(5000);
    const auto events = be.Finish();
    const auto n = ChannelCounts(events);
    EXPECT_EQ(n.at("IMU_NOV"), 766);
    EXPECT_EQ(n.at("INS_PVA_NOV"), 62 + 6);
    EXPECT_EQ(n.count("RESPONSE_NOV"), 0u);
    for (const auto& e : events) {
        if (e.channel != "IMU_NOV") continue;
        const auto imu = DecodeAs<pitmap::imu_t>(e.data);
        EXPECT_EQ(imu.header.message_id, 1362);
        EXPECT_EQ(imu.corrected, 1);
        EXPECT_DOUBLE_EQ(imu.dt_s, 0.01);
        EXPECT_GT(imu.utime_gps, 0);
        break;
    }
    // The capture's INS times fed the host model: raw chunks got GPS times once it had samples.
    EXPECT_NE(time.HostQuality(kT0 + 10'000'000).state, ClockState::kNoTime);
    const auto last_raw = [&] {
        for (auto it = events.rbegin(); it != events.rend(); ++it) {
            if (it->channel == "RAW_NOV") return DecodeAs<pitmap::raw_bytes_t>(it->data);
        }
        return pitmap::raw_bytes_t{};
    }();
    EXPECT_GT(last_raw.utime_gps, 0);
    EXPECT_EQ(be.publisher.stats().queue_drops, 0);
    EXPECT_EQ(be.publisher.stats().published, static_cast<std::int64_t>(events.size()));
}

TEST(SensorChannelTest, GarbageBurstsAreCountedAndFramesSurvive) {
    const auto clean =
        testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins1.gps");
    // Insert bursts of printable-free garbage (no 0xAA, '#', '%', '<', '[', '$') every ~997 bytes.
    std::mt19937 rng(42);
    std::vector<std::uint8_t> dirty;
    std::int64_t inserted = 0;
    for (std::size_t i = 0; i < clean.size(); ++i) {
        dirty.push_back(clean[i]);
        if (i % 997 == 996) {
            const int burst = 1 + static_cast<int>(rng() % 300);
            for (int k = 0; k < burst; ++k) {
                dirty.push_back(static_cast<std::uint8_t>(0x01 + rng() % 0x1F));  // control bytes
            }
            inserted += burst;
        }
    }
    Backend be("garbage");
    FakeSource src;
    ManualClock clock(kT0);
    TimeKeeper time;
    SensorChannel ch(NovatelConfig("nov"), src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    Feed(src, dirty, kT0);
    src.PushEnd();
    RunToEnd(ch);
    const auto c = ch.counters();
    const auto events = be.Finish();
    EXPECT_EQ(RawConcat(events, "RAW_NOV"), dirty);
    EXPECT_EQ(c.bytes, static_cast<std::int64_t>(dirty.size()));
    std::int64_t skipped = 0;
    for (auto b : c.skipped_bytes) skipped += b;
    // Every byte is in a frame or counted as skipped. A burst inside a frame breaks that frame
    // (its bytes are skipped too), so frames can only be lost, never invented.
    EXPECT_GE(skipped, inserted);
    EXPECT_LE(c.frames, 284);
    EXPECT_GT(c.frames, 200);
    EXPECT_EQ(c.decode_errors, 0);
}

// Frame offsets of a clean NovAtel stream (frame boundaries to insert at).
std::vector<std::size_t> FrameOffsets(const std::vector<std::uint8_t>& data) {
    protocol::novatel::Framer f;
    f.Push(ByteSpan(data.data(), data.size()));
    std::vector<std::size_t> out;
    for (;;) {
        auto ev = f.Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (const auto* fr = std::get_if<protocol::novatel::Frame>(&ev)) {
            out.push_back(static_cast<std::size_t>(fr->offset));
        }
    }
    return out;
}

// A false long header before a pause in the input and another before the end of the stream:
// the daemon used to drop everything buffered behind each (137 of 284 frames decoded); now the
// stale wait and the end give up only the false sync and every real frame is decoded.
TEST(SensorChannelTest, FalseLongHeadersBeforeAPauseAndTheEndLoseNoFrame) {
    const auto clean =
        testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins1.gps");
    const auto offsets = FrameOffsets(clean);
    ASSERT_EQ(offsets.size(), 284u);
    const auto fake = protocol::novatel::testing::FalseLongHeader();
    std::vector<std::uint8_t> dirty(clean.begin(), clean.begin() + static_cast<long>(offsets[100]));
    dirty.insert(dirty.end(), fake.begin(), fake.end());
    const std::size_t pause = dirty.size() + (offsets[140] - offsets[100]);
    dirty.insert(dirty.end(),
                 clean.begin() + static_cast<long>(offsets[100]),
                 clean.begin() + static_cast<long>(offsets[250]));
    dirty.insert(dirty.end(), fake.begin(), fake.end());
    dirty.insert(dirty.end(), clean.begin() + static_cast<long>(offsets[250]), clean.end());

    Backend be("falsehdr");
    FakeSource src;
    ManualClock clock(kT0);
    TimeKeeper time;
    auto cfg = NovatelConfig("nov");
    SensorChannel ch(cfg, src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    // Up to the pause, then silence longer than stale_partial_ms, then the rest and the end.
    const std::vector<std::uint8_t> first(dirty.begin(), dirty.begin() + static_cast<long>(pause));
    const std::vector<std::uint8_t> rest(dirty.begin() + static_cast<long>(pause), dirty.end());
    src.PushData(first, kT0);
    ASSERT_TRUE(ch.RunOnce());
    const std::int64_t frames_before_pause = ch.counters().frames;
    clock.AdvanceUs(std::int64_t{cfg.stale_partial_ms} * 1000 + 500'000);
    src.PushTimeout();
    ASSERT_TRUE(ch.RunOnce());
    // The 40 frames behind the false header came out at the pause, not at the end.
    EXPECT_EQ(ch.counters().frames, frames_before_pause + 40);
    src.PushData(rest, kT0 + 3'000'000);
    src.PushEnd();
    RunToEnd(ch);
    const auto c = ch.counters();
    be.Finish();
    EXPECT_EQ(c.frames, 284);
    EXPECT_EQ(c.decode_errors, 0);
    std::int64_t skipped = 0;
    for (auto b : c.skipped_bytes) skipped += b;
    EXPECT_EQ(skipped, 2 * 28);
}

TEST(SensorChannelTest, SetupCommandsAnsweredRefusedAndResentOnReconnect) {
    Backend be("commands");
    FakeSource src(Transport::kTcp);
    ManualClock clock(kT0);
    TimeKeeper time;
    auto cfg = NovatelConfig("icom1");
    cfg.setup_commands = {"LOG ICOM1 INSPVAXB ONTIME 0.05", "LOG ICOM1 BOGUSB ONTIME 1"};
    SensorChannel ch(cfg, src, be.publisher, clock, time);
    int answered = 0;
    src.on_write = [&](const std::string& line) {
        // A receiver: OK to the first, ERROR to the second command.
        src.PushFrontData(line.find("BOGUS") == std::string::npos
                              ? "\r\n<OK\r\n[ICOM1]"
                              : "\r\n<ERROR:Invalid Message\r\n[ICOM1]",
                          clock.NowUtime());
        ++answered;
    };
    ASSERT_TRUE(src.Open().ok());
    for (int i = 0; i < 6; ++i) ch.RunOnce();
    ASSERT_EQ(src.writes.size(), 2u);
    EXPECT_EQ(src.writes[0], "LOG ICOM1 INSPVAXB ONTIME 0.05\r\n");
    auto c = ch.counters();
    EXPECT_EQ(c.commands_sent, 2);
    EXPECT_EQ(c.commands_ok, 1);
    EXPECT_EQ(c.commands_refused, 1);
    EXPECT_EQ(c.FrameCount("OK"), 1);
    EXPECT_EQ(c.FrameCount("ERROR"), 1);
    EXPECT_EQ(c.FrameCount("PROMPT"), 2);

    // The TCP server restarts: the channel reconnects and sends everything again.
    src.PushDisconnect();
    for (int i = 0; i < 8; ++i) ch.RunOnce();
    EXPECT_EQ(src.writes.size(), 4u);
    c = ch.counters();
    EXPECT_EQ(c.commands_ok, 2);
    EXPECT_EQ(c.commands_refused, 2);
    EXPECT_EQ(c.reconnects, 1);
    EXPECT_NE(c.last_error.find("Invalid Message"), std::string::npos);

    const auto events = be.Finish();
    std::vector<pitmap::receiver_response_t> responses;
    for (const auto& e : events) {
        if (e.channel == "RESPONSE_ICOM1")
            responses.push_back(DecodeAs<pitmap::receiver_response_t>(e.data));
    }
    ASSERT_EQ(responses.size(), 4u);
    EXPECT_EQ(responses[0].ok, 1);
    EXPECT_EQ(responses[0].command, "LOG ICOM1 INSPVAXB ONTIME 0.05");
    EXPECT_EQ(responses[1].ok, 0);
    EXPECT_EQ(responses[1].text, "ERROR:Invalid Message");
    EXPECT_EQ(responses[1].command, "LOG ICOM1 BOGUSB ONTIME 1");
    EXPECT_EQ(responses[1].source, "icom1");
    // What the receiver said is in the raw log too.
    std::string raw;
    for (auto b : RawConcat(events, "RAW_ICOM1")) raw.push_back(static_cast<char>(b));
    EXPECT_EQ(raw,
              "\r\n<OK\r\n[ICOM1]\r\n<ERROR:Invalid Message\r\n[ICOM1]"
              "\r\n<OK\r\n[ICOM1]\r\n<ERROR:Invalid Message\r\n[ICOM1]");
}

TEST(SensorChannelTest, SilentReceiverGetsOneRetryThenTheNextCommand) {
    Backend be("silent");
    FakeSource src(Transport::kTcp);
    ManualClock clock(kT0);
    TimeKeeper time;
    auto cfg = NovatelConfig("nov");
    cfg.setup_commands = {"LOG BESTPOSB ONTIME 1", "LOG TIMEB ONTIME 1"};
    SensorChannel ch(cfg, src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    ch.RunOnce();
    EXPECT_EQ(src.writes.size(), 1u);
    clock.AdvanceUs(500'000);
    ch.RunOnce();
    EXPECT_EQ(src.writes.size(), 1u);  // still waiting
    clock.AdvanceUs(600'000);
    ch.RunOnce();
    ASSERT_EQ(src.writes.size(), 2u);  // the retry
    EXPECT_EQ(src.writes[1], src.writes[0]);
    clock.AdvanceUs(1'100'000);
    ch.RunOnce();
    ASSERT_EQ(src.writes.size(), 3u);  // gave up: the next command
    EXPECT_EQ(src.writes[2], "LOG TIMEB ONTIME 1\r\n");
    EXPECT_EQ(ch.counters().commands_unanswered, 1);
    EXPECT_EQ(ch.Status().state, pitmap::channel_status_t::STATE_SILENT);
    be.Finish();
}

TEST(SensorChannelTest, UnplugReplugKeepsCountingAndReportsState) {
    const auto data =
        testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_bestpos.gps");
    Backend be("replug");
    FakeSource src;
    ManualClock clock(kT0);
    TimeKeeper time;
    SensorChannel ch(NovatelConfig("nov"), src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    const std::size_t half = data.size() / 2;
    src.PushData(std::vector<std::uint8_t>(data.begin(), data.begin() + static_cast<long>(half)),
                 kT0);
    src.PushDisconnect();
    ch.RunOnce();
    ch.RunOnce();
    EXPECT_EQ(ch.Status().state, pitmap::channel_status_t::STATE_DISCONNECTED);
    EXPECT_EQ(ch.counters().last_error, "fake device unplugged");
    src.PushData(std::vector<std::uint8_t>(data.begin() + static_cast<long>(half), data.end()),
                 kT0 + 1000);
    src.PushEnd();
    RunToEnd(ch);
    EXPECT_EQ(ch.counters().reconnects, 1);
    EXPECT_EQ(ch.counters().bytes, static_cast<std::int64_t>(data.size()));
    const auto events = be.Finish();
    EXPECT_EQ(RawConcat(events, "RAW_NOV"), data);
}

protocol::deltat::Ping83P MakePing(std::uint32_t number, std::int64_t header_utime) {
    protocol::deltat::Ping83P p;
    p.format_version = protocol::deltat::kVersion110;
    protocol::deltat::SetHeaderTime(p, header_utime);
    p.sector_size_deg = 120;
    p.start_angle_cdeg = -6000;
    p.angle_increment_cdeg = 50;
    p.acoustic_range_m = 50;
    p.frequency_khz = 260;
    p.range_resolution_mm = 10;
    p.repetition_rate_ms = 100;
    p.ping_number = number;
    p.ping_latency_us = 1000;
    p.data_latency_us = 20'000;
    p.range_counts.assign(240, 0);
    for (std::size_t i = 0; i < p.range_counts.size(); ++i) {
        p.range_counts[i] = static_cast<std::uint16_t>(1000 + i + number);
    }
    return p;
}

TEST(SensorChannelTest, DeltatDatagramsStampedOnlyOnceTheHostClockHasTime) {
    Backend be("deltat");
    FakeSource src(Transport::kUdp);
    ManualClock clock(kT0);
    TimeKeeper time;
    SensorChannelConfig cfg;
    cfg.id = "mb";
    cfg.protocol = ChannelProtocol::kDeltat83P;
    cfg.ec.enabled = true;
    cfg.ec.frame.range_m = 30;
    cfg.ec.frame.start_gain_db = 12;
    SensorChannel ch(cfg, src, be.publisher, clock, time);
    ASSERT_TRUE(src.Open().ok());
    const std::int64_t header_offset = -3'000'000;  // topside clock 3 s behind the host
    std::vector<std::vector<std::uint8_t>> sent;
    // 3 pings before any NovAtel time, then the host model learns GPS = host + 18 s, 50 pings.
    const std::int64_t gps_minus_host = 18'000'000 - 315'964'800'000'000;
    for (int i = 0; i < 53; ++i) {
        const std::int64_t tx_host = kT0 + i * 100'000;
        if (i == 3) {
            for (int k = 0; k < 100; ++k) {
                const std::int64_t h = kT0 - 10'000'000 + k * 200'000;
                time.AddNovatel(h + 2000 + (k % 7) * 500, h + gps_minus_host, true);
            }
        }
        if (i >= 3) {
            time.AddNovatel(tx_host + 2000, tx_host + gps_minus_host, true);
        }
        sent.push_back(protocol::deltat::EncodeRecord83P(
            MakePing(static_cast<std::uint32_t>(i), tx_host - 1000 + header_offset)));
        src.PushData(sent.back(), tx_host + 19'000 + (i % 5) * 300);
        ch.RunOnce();
        clock.AdvanceUs(100'000);
    }
    src.PushData({'n', 'o', 't', ' ', '8', '3', 'P'}, kT0 + 6'000'000);
    src.PushEnd();
    while (ch.RunOnce()) clock.AdvanceUs(100'000);
    const auto c = ch.counters();
    EXPECT_EQ(c.FrameCount("83P"), 53);
    EXPECT_EQ(c.decode_errors, 1);
    EXPECT_GE(c.ec_frames_sent, 1);
    ASSERT_FALSE(src.writes.empty());
    const auto ec = protocol::deltat::DecodeEcFrame(ByteSpan(
        reinterpret_cast<const std::uint8_t*>(src.writes[0].data()), src.writes[0].size()));
    ASSERT_TRUE(std::holds_alternative<protocol::deltat::EcFrame>(ec));
    EXPECT_EQ(std::get<protocol::deltat::EcFrame>(ec).range_m, 30);
    EXPECT_EQ(std::get<protocol::deltat::EcFrame>(ec).start_gain_db, 12);

    const auto events = be.Finish();
    std::vector<pitmap::multibeam_ping_t> pings;
    std::vector<std::vector<std::uint8_t>> raws;
    for (const auto& e : events) {
        if (e.channel == "MULTIBEAM_PING_MB")
            pings.push_back(DecodeAs<pitmap::multibeam_ping_t>(e.data));
        if (e.channel == "RAW_MB") raws.push_back(DecodeAs<pitmap::raw_bytes_t>(e.data).data);
    }
    ASSERT_EQ(pings.size(), 53u);
    ASSERT_EQ(raws.size(), 54u);
    for (std::size_t i = 0; i < sent.size(); ++i) EXPECT_EQ(raws[i], sent[i]);
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(pings[i].utime_gps, 0);
        EXPECT_EQ(pings[i].gps_time_source, pitmap::multibeam_ping_t::TIME_SOURCE_NONE);
        EXPECT_TRUE(std::isnan(pings[i].gps_time_stddev_s));
    }
    for (int i = 3; i < 53; ++i) {
        EXPECT_EQ(pings[i].ping_number, i);
        EXPECT_EQ(pings[i].num_beams, 240);
        EXPECT_EQ(pings[i].range_counts[5], 1005 + i);
        EXPECT_NE(pings[i].gps_time_source, pitmap::multibeam_ping_t::TIME_SOURCE_NONE);
        // Truth: transmit at tx_host (host) = tx_host + gps_minus_host (GPS).
        const std::int64_t truth = kT0 + i * 100'000 + gps_minus_host;
        EXPECT_NEAR(static_cast<double>(pings[i].utime_gps), static_cast<double>(truth), 5000.0)
            << "ping " << i;
    }
    EXPECT_EQ(pings.back().gps_time_source, pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK);
}

// ---- Issue 14: UDP hardening through the real UdpSource on loopback ----

sockaddr_in Ipv4(const char* ip, int port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    ::inet_pton(AF_INET, ip, &a.sin_addr);
    return a;
}

// A UDP socket on ip:0: the sonar topside, or a forger.
struct UdpPeer {
    int fd = -1;
    int port = 0;
    explicit UdpPeer(const char* ip) {
        fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
        sockaddr_in a = Ipv4(ip, 0);
        EXPECT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0) << ip;
        socklen_t len = sizeof(a);
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
        port = ntohs(a.sin_port);
    }
    ~UdpPeer() { ::close(fd); }
    UdpPeer(const UdpPeer&) = delete;
    UdpPeer& operator=(const UdpPeer&) = delete;
    void Send(int to_port, const std::vector<std::uint8_t>& d) const {
        const sockaddr_in to = Ipv4("127.0.0.1", to_port);
        EXPECT_EQ(
            ::sendto(fd, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to)),
            static_cast<long>(d.size()));
    }
    // The datagrams waiting now (loopback delivery is synchronous).
    std::vector<std::vector<std::uint8_t>> Drain() const {
        std::vector<std::vector<std::uint8_t>> out;
        std::vector<std::uint8_t> buf(65536);
        long n;
        while ((n = ::recv(fd, buf.data(), buf.size(), MSG_DONTWAIT)) >= 0) {
            out.emplace_back(buf.begin(), buf.begin() + n);
        }
        return out;
    }
};

SensorChannelConfig DeltatUdpConfig() {
    SensorChannelConfig cfg;
    cfg.id = "mb";
    cfg.protocol = ChannelProtocol::kDeltat83P;
    cfg.read_timeout_ms = 20;
    cfg.ec.enabled = true;
    cfg.ec.frame.range_m = 30;
    cfg.ec.interval_ms = 5000;
    return cfg;
}

// Issue 14 case 10: the head on 127.0.0.1 is allowed, a forger on 127.0.0.2 sends valid 83P
// pings. The forger's datagrams are logged raw as "deltat_83p_foreign" and counted, never
// decoded; EC frames go to the head only. (Before: the forger's pings were published as
// sonar data and every EC frame after a forged datagram went to the forger.)
TEST(SensorChannelUdpTest, ForgerLoggedRawAsForeignNeverDecodedAndGetsNoEc) {
    Backend be("udp_forger");
    UdpConfig uc;
    uc.bind_address = "127.0.0.1";
    uc.port = 0;
    uc.allowed_senders = {"127.0.0.1"};
    UdpSource src(uc);
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    ManualClock clock(kT0);
    TimeKeeper time;
    SensorChannel ch(DeltatUdpConfig(), src, be.publisher, clock, time);
    UdpPeer head("127.0.0.1");
    UdpPeer forger("127.0.0.2");

    constexpr int kRounds = 7;
    std::vector<std::vector<std::uint8_t>> forged;
    for (int i = 0; i < kRounds; ++i) {
        // The forger first, then the head; each datagram read separately, 6 s apart so every
        // datagram would be due an EC frame.
        forged.push_back(protocol::deltat::EncodeRecord83P(
            MakePing(static_cast<std::uint32_t>(1000 + i), kT0 + i * 100'000)));
        forger.Send(src.bound_port(), forged.back());
        ch.RunOnce();
        clock.AdvanceUs(6'000'000);
        head.Send(src.bound_port(),
                  protocol::deltat::EncodeRecord83P(
                      MakePing(static_cast<std::uint32_t>(i), kT0 + i * 100'000)));
        ch.RunOnce();
        clock.AdvanceUs(6'000'000);
    }
    const auto at_head = head.Drain();
    const auto at_forger = forger.Drain();
    std::printf(
        "EC frames: %zu to the head, %zu to the forger\n", at_head.size(), at_forger.size());
    EXPECT_EQ(at_head.size(), static_cast<std::size_t>(kRounds));
    EXPECT_TRUE(at_forger.empty());
    for (const auto& f : at_head) {
        EXPECT_TRUE(std::holds_alternative<protocol::deltat::EcFrame>(
            protocol::deltat::DecodeEcFrame(ByteSpan(f.data(), f.size()))));
    }
    const pitmap::channel_status_t status = ch.Status();
    EXPECT_EQ(status.foreign_datagrams, kRounds);
    EXPECT_EQ(status.chunks, kRounds);  // sensor chunks only
    EXPECT_EQ(ch.counters().FrameCount("83P"), kRounds);
    EXPECT_EQ(ch.counters().ec_frames_sent, kRounds);

    const auto events = be.Finish();
    int pings = 0;
    std::vector<pitmap::raw_bytes_t> foreign;
    std::int64_t seq = 0;
    for (const auto& e : events) {
        if (e.channel == "MULTIBEAM_PING_MB") {
            ++pings;
            EXPECT_LT(DecodeAs<pitmap::multibeam_ping_t>(e.data).ping_number, 1000);
        } else if (e.channel == "RAW_MB") {
            const auto raw = DecodeAs<pitmap::raw_bytes_t>(e.data);
            EXPECT_EQ(raw.seq, seq++);  // one sequence: no false gaps
            if (raw.protocol == "deltat_83p_foreign") {
                foreign.push_back(raw);
            } else {
                EXPECT_EQ(raw.protocol, "deltat_83p");
                EXPECT_EQ(raw.peer, "127.0.0.1:" + std::to_string(head.port));
            }
        }
    }
    std::printf("forged pings decoded: %d of %d published pings\n", pings - kRounds, pings);
    EXPECT_EQ(pings, kRounds);
    ASSERT_EQ(foreign.size(), static_cast<std::size_t>(kRounds));
    for (int i = 0; i < kRounds; ++i) {
        EXPECT_EQ(foreign[i].data, forged[i]);
        EXPECT_EQ(foreign[i].peer, "127.0.0.2:" + std::to_string(forger.port));
        EXPECT_EQ(foreign[i].transport, pitmap::raw_bytes_t::TRANSPORT_UDP);
    }
}

// Issue 14 case 8: datagrams the kernel dropped show in channel_status_t.kernel_drops, exactly,
// and a note goes to the log.
TEST(SensorChannelUdpTest, KernelDropsReachTheStatusAndTheLog) {
    Backend be("udp_drops");
    UdpConfig uc;
    uc.bind_address = "127.0.0.1";
    uc.port = 0;
    uc.allowed_senders = {"127.0.0.1"};
    uc.receive_buffer_bytes = 16384;
    UdpSource src(uc);
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    ManualClock clock(kT0);
    TimeKeeper time;
    std::FILE* sink = std::tmpfile();
    ASSERT_NE(sink, nullptr);
    RateLimitedLog log(sink);
    SensorChannelConfig cfg = DeltatUdpConfig();
    cfg.ec.enabled = false;
    SensorChannel ch(cfg, src, be.publisher, clock, time, &log);
    UdpPeer head("127.0.0.1");
    constexpr int kSent = 300;
    for (int i = 0; i < kSent; ++i) {
        head.Send(src.bound_port(),
                  protocol::deltat::EncodeRecord83P(
                      MakePing(static_cast<std::uint32_t>(i), kT0 + i * 100'000)));
    }
    // Drain (bounded: loopback has delivered everything when sendto() returned).
    for (int i = 0; i < 2 * kSent && ch.Status().chunks + ch.Status().kernel_drops < kSent; ++i) {
        ch.RunOnce();
        clock.AdvanceUs(10'000);
    }
    const pitmap::channel_status_t status = ch.Status();
    std::printf("sent %d, read %lld, kernel drops in channel_status_t %lld\n",
                kSent,
                static_cast<long long>(status.chunks),
                static_cast<long long>(status.kernel_drops));
    EXPECT_GT(status.kernel_drops, 0);
    EXPECT_EQ(status.chunks + status.kernel_drops, kSent);
    EXPECT_EQ(ch.counters().kernel_drops, status.kernel_drops);

    // A second burst within the log's one-second rate limit: its note is held back, then
    // given with the final total once the second has passed, although nothing new dropped.
    for (int i = 0; i < kSent; ++i) {
        head.Send(src.bound_port(),
                  protocol::deltat::EncodeRecord83P(
                      MakePing(static_cast<std::uint32_t>(i), kT0 + i * 100'000)));
    }
    for (int i = 0; i < 2 * kSent && ch.Status().chunks + ch.Status().kernel_drops < 2 * kSent;
         ++i) {
        ch.RunOnce();
    }
    const std::int64_t total = ch.Status().kernel_drops;
    EXPECT_GT(total, status.kernel_drops);
    EXPECT_EQ(ch.Status().chunks + total, 2 * kSent);
    clock.AdvanceUs(1'100'000);
    ch.RunOnce();
    std::fflush(sink);
    std::rewind(sink);
    std::string text(4096, '\0');
    text.resize(std::fread(text.data(), 1, text.size(), sink));
    std::fclose(sink);
    EXPECT_NE(text.find("mb: the kernel dropped"), std::string::npos) << text;
    EXPECT_NE(text.find(", " + std::to_string(total) + " in total"), std::string::npos) << text;
    be.Finish();
}

// The daemon config: a UDP channel must name its senders; EC needs to know which is the head.
TEST(SensorChannelUdpTest, ConfigRequiresAllowedSenders) {
    const auto yaml = [](const std::string& udp, const std::string& ec) {
        return "lcm_url: \"memq://\"\nlog:\n  directory: logs\n  min_free_bytes: 0\n"
               "channels:\n  - id: mb\n    protocol: deltat_83p\n    udp: {port: 4040" +
               udp + "}\n" + ec;
    };
    const auto has = [](const LoadedConfig& c, const std::string& what) {
        for (const auto& p : c.problems) {
            if (p.find(what) != std::string::npos) return true;
        }
        return false;
    };
    EXPECT_TRUE(has(LoadDaemonConfigFromString(yaml("", ""), "t"), "allowed_senders"));
    EXPECT_TRUE(
        has(LoadDaemonConfigFromString(yaml(", allowed_senders: []", ""), "t"), "allowed_senders"));
    EXPECT_TRUE(
        has(LoadDaemonConfigFromString(yaml(", allowed_senders: [sonar]", ""), "t"), "sonar"));
    const auto ok = LoadDaemonConfigFromString(yaml(", allowed_senders: [192.168.0.4]", ""), "t");
    EXPECT_TRUE(ok.problems.empty()) << ok.problems.front();
    ASSERT_EQ(ok.config.channels.size(), 1u);
    EXPECT_EQ(ok.config.channels[0].udp.bind_address, "");  // the interface facing the head
    const std::string ec = "    ec: {enabled: true, range_m: 30}\n";
    EXPECT_TRUE(has(
        LoadDaemonConfigFromString(yaml(", allowed_senders: [192.168.0.4, 192.168.0.5]", ec), "t"),
        "reply_to"));
    EXPECT_TRUE(LoadDaemonConfigFromString(yaml(", allowed_senders: [192.168.0.4, 192.168.0.5], "
                                                "reply_to: 192.168.0.5",
                                                ec),
                                           "t")
                    .problems.empty());
}

// The `vehicle` section is checked against the vehicle schema (common/vehicle.hpp) at start:
// the old free-form layout and a section without the sonar lever arm are config problems
// with their line; a schema-1 section passes and is kept for the log folder.
TEST(DaemonConfigVehicleTest, VehicleSectionIsCheckedAgainstTheSchema) {
    const std::string base =
        "lcm_url: \"memq://\"\nlog:\n  directory: logs\n  min_free_bytes: 0\n"
        "channels:\n  - id: nov\n    protocol: novatel\n    file: {path: x.gps}\n";
    const auto problems = [&](const std::string& vehicle) {
        std::string all;
        for (const auto& p : LoadDaemonConfigFromString(base + vehicle, "c.yaml").problems) {
            all += p + "\n";
        }
        return all;
    };
    const std::string old =
        problems("vehicle:\n  name: ROAZ\n  lever_arms_m: {imu_to_sonar: [1, 0, 0.5]}\n");
    EXPECT_NE(old.find("vehicle.pitmap_vehicle: required"), std::string::npos) << old;
    EXPECT_NE(old.find("vehicle.sonar.lever_arm_m: required"), std::string::npos) << old;
    EXPECT_NE(old.find("c.yaml:11: vehicle.lever_arms_m is not a known setting"), std::string::npos)
        << old;
    const std::string no_arm = problems(
        "vehicle:\n  pitmap_vehicle: 1\n  sonar:\n    mount: {orientation: down, connector: "
        "aft}\n");
    EXPECT_NE(no_arm.find("vehicle.sonar.lever_arm_m: required"), std::string::npos) << no_arm;
    const std::string vehicle =
        "vehicle:\n  pitmap_vehicle: 1\n  sonar:\n    lever_arm_m: [1, 0, 0.5]\n"
        "    mount: {orientation: tilted, tilt_deg: 30, connector: aft}\n";
    EXPECT_EQ(problems(vehicle), "");
    const auto ok = LoadDaemonConfigFromString(base + vehicle, "c.yaml");
    EXPECT_NE(ok.config.vehicle_yaml.find("tilt_deg: 30"), std::string::npos)
        << ok.config.vehicle_yaml;
}

}  // namespace
}  // namespace pitmap::acq
