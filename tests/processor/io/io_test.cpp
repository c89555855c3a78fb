// SPDX-License-Identifier: MIT
// Ingest of LCM logs (the reader itself: tests/lcmtypes/lcm_log_reader_test.cpp); empty
// segments; LAS 1.4 writer: read back field by field.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <pitmap/multibeam_ping_t.hpp>
#include <pitmap/raw_bytes_t.hpp>

#include "common/byte_io.hpp"
#include "lcmtypes/log/lcm_log_reader.hpp"
#include "processor/io/ingest.hpp"
#include "processor/io/products.hpp"

namespace pitmap::proc::io {
namespace {

void PutBe(std::vector<std::uint8_t>& b, std::uint64_t v, int n) {
    for (int i = n - 1; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

std::vector<std::uint8_t> Event(std::int64_t num, const std::string& ch, std::size_t len) {
    std::vector<std::uint8_t> b;
    PutBe(b, lcmlog::kLcmSyncWord, 4);
    PutBe(b, static_cast<std::uint64_t>(num), 8);
    PutBe(b, 1'700'000'000'000'000ull + static_cast<std::uint64_t>(num), 8);
    PutBe(b, ch.size(), 4);
    PutBe(b, len, 4);
    b.insert(b.end(), ch.begin(), ch.end());
    for (std::size_t i = 0; i < len; ++i) b.push_back(static_cast<std::uint8_t>(i));
    return b;
}

std::string WriteFile(const std::string& name, const std::vector<std::uint8_t>& b) {
    const std::string path = ::testing::TempDir() + "/" + name;
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    return path;
}

std::vector<std::uint8_t> EventWith(std::int64_t num,
                                    const std::string& ch,
                                    const std::vector<std::uint8_t>& data) {
    std::vector<std::uint8_t> b;
    PutBe(b, lcmlog::kLcmSyncWord, 4);
    PutBe(b, static_cast<std::uint64_t>(num), 8);
    PutBe(b, 1'700'000'000'000'000ull + static_cast<std::uint64_t>(num), 8);
    PutBe(b, ch.size(), 4);
    PutBe(b, data.size(), 4);
    b.insert(b.end(), ch.begin(), ch.end());
    b.insert(b.end(), data.begin(), data.end());
    return b;
}

template <class T>
std::vector<std::uint8_t> Encode(const T& msg) {
    std::vector<std::uint8_t> b(static_cast<std::size_t>(msg.getEncodedSize()));
    msg.encode(b.data(), 0, static_cast<int>(b.size()));
    return b;
}

std::vector<std::uint8_t> PingBytes(std::int64_t i, int beams) {
    pitmap::multibeam_ping_t m{};
    m.utime = 1'700'000'000'000'000 + i * 100'000;
    m.utime_gps = 1'400'000'000'000'000 + i * 100'000;
    m.ping_number = i;
    m.sound_speed_mps = 1500;
    m.sound_speed_valid = 1;
    m.range_resolution_m = 0.01f;
    m.start_angle_deg = -60;
    m.angle_increment_deg = 1;
    m.num_beams = static_cast<std::int16_t>(beams);
    m.range_counts.assign(static_cast<std::size_t>(beams), 1000);
    return Encode(m);
}

// One MULTIBEAM_PING with num_beams = -1 among 1 200 used to abort `pitmap info` and `pitmap
// run` with "internal error: vector::_M_default_append"; raw events with num_bytes = -5 or
// 0x7fffffff likewise (or allocated 2 GiB). Each is one counted decode failure now.
TEST(Ingest, UndecodableEventsAreCountedAndSkipped) {
    std::vector<std::uint8_t> log;
    for (int i = 0; i < 1200; ++i) {
        auto ping = PingBytes(i, 32);
        if (i == 600) {
            const std::size_t at = ping.size() - 2 - 4 * 32 - 2;  // num_beams
            ping[at] = 0xFF;
            ping[at + 1] = 0xFF;
        }
        const auto e = EventWith(i, "MULTIBEAM_PING_DELTAT_UDP", ping);
        log.insert(log.end(), e.begin(), e.end());
    }
    for (const std::uint32_t bad : {0xFFFFFFFBu, 0x7FFFFFFFu}) {
        pitmap::raw_bytes_t raw{};
        raw.source = "novatel_com1";
        raw.protocol = "novatel";
        raw.transport = pitmap::raw_bytes_t::TRANSPORT_SERIAL;
        raw.num_bytes = 64;
        raw.data.assign(64, 0x20);
        auto bytes = Encode(raw);
        const std::size_t at = bytes.size() - 64 - 4;
        for (int k = 0; k < 4; ++k) bytes[at + k] = static_cast<std::uint8_t>(bad >> (24 - 8 * k));
        const auto e = EventWith(2000, "RAW_NOVATEL_COM1", bytes);
        log.insert(log.end(), e.begin(), e.end());
    }
    IngestConfig cfg;
    auto r = IngestLcmLogs({WriteFile("badcounts.lcmlog", log)}, cfg);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->counts.events, 1202);
    EXPECT_EQ(r->counts.decode_failures, 3);
    EXPECT_EQ(r->pings.pings.size(), 1199u);
    cfg.source = IngestSource::kRaw;
    r = IngestLcmLogs({WriteFile("badcounts.lcmlog", log)}, cfg);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->counts.decode_failures, 2);
}

// The daemon's retry on a full disk once left a 0-byte segment; `pitmap info LOGDIR` then
// refused the whole folder. Empty and too-short files are skipped with a warning.
TEST(Ingest, EmptySegmentsAreSkippedWithAWarning) {
    std::vector<std::uint8_t> log;
    for (int i = 0; i < 10; ++i) {
        const auto e = EventWith(i, "MULTIBEAM_PING_DELTAT_UDP", PingBytes(i, 8));
        log.insert(log.end(), e.begin(), e.end());
    }
    const std::string good = WriteFile("seg-000.lcmlog", log);
    const std::string empty = WriteFile("seg-001.lcmlog", {});
    const std::string tiny = WriteFile("seg-002.lcmlog", {0xED, 0xA1});
    auto r = IngestFiles({good, empty, tiny}, IngestConfig{});
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->counts.files_skipped, 2);
    ASSERT_EQ(r->warnings.size(), 2u);
    EXPECT_NE(r->warnings[0].find("seg-001.lcmlog"), std::string::npos);
    EXPECT_EQ(r->counts.pings, 10);
    // Nothing readable at all is still an error, naming the file.
    // A clean log says nothing more; a damaged one says so.
    auto damaged_log = log;
    damaged_log[30] ^= 0x5A;  // inside the first event's channel name
    auto damaged = IngestFiles({WriteFile("seg-damaged.lcmlog", damaged_log)}, IngestConfig{});
    ASSERT_TRUE(damaged.ok()) << damaged.error().message;
    ASSERT_FALSE(damaged->warnings.empty());
    EXPECT_NE(damaged->warnings.back().find("damaged input"), std::string::npos);
    auto none = IngestFiles({empty}, IngestConfig{});
    ASSERT_FALSE(none.ok());
    EXPECT_NE(none.error().message.find("seg-001.lcmlog"), std::string::npos);
}

// IngestFiles used to copy 4 of the vendor files' counters and drop the others: the same
// capture given twice reported 0 duplicate INS samples. Every count now reaches the result.
TEST(Ingest, VendorFileCountsAreAllKept) {
    const std::string capture = std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins1.gps";
    std::ifstream in(capture, std::ios::binary);
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    const std::string copy = WriteFile("ins1-copy.gps", bytes);
    IngestConfig cfg;
    auto direct = IngestNovatelFiles({capture, copy}, cfg);
    ASSERT_TRUE(direct.ok()) << direct.error().message;
    ASSERT_GT(direct->counts.nav_duplicates, 0);
    auto merged = IngestFiles({capture, copy}, cfg);
    ASSERT_TRUE(merged.ok()) << merged.error().message;
    EXPECT_EQ(merged->counts.nav_duplicates, direct->counts.nav_duplicates);
    EXPECT_EQ(merged->counts.nav_samples, direct->counts.nav_samples);
    EXPECT_EQ(merged->counts.nav_not_good, direct->counts.nav_not_good);
    EXPECT_EQ(merged->counts.nav_without_time, direct->counts.nav_without_time);
    EXPECT_EQ(merged->counts.files, 2);
    EXPECT_EQ(merged->counts.bytes, 2 * static_cast<std::int64_t>(bytes.size()));
}

TEST(Ingest, LogWithoutSensorChannelsGivesEmptySeries) {
    auto e = Event(0, "OTHER", 3);
    auto r = IngestLcmLogs({WriteFile("other.lcmlog", e)}, IngestConfig{});
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->counts.events, 1);
    EXPECT_TRUE(r->nav.samples.empty());
    EXPECT_TRUE(r->pings.pings.empty());
    EXPECT_FALSE(IngestLcmLogs({}, IngestConfig{}).ok());
}

TEST(Las, ReadsBackFieldByField) {
    georef::GeorefResult g;
    g.world_origin = {40.4435, -7.7806, 412.0};
    georef::GeorefPing ping;
    ping.utime_gps = 1'465'500'000'123'456;
    g.pings.push_back(ping);
    for (int i = 0; i < 2; ++i) {
        g.points.position_world.emplace_back(i * 1.0, 2.0, -10.0);
        g.points.ping.push_back(0);
        g.points.beam.push_back(static_cast<std::uint16_t>(i));
        g.points.range_m.push_back(10.0f);
        g.points.angle_rad.push_back(i == 0 ? -0.5f : 0.5f);
    }
    auto utm = georef::ToUtm(g);
    ASSERT_TRUE(utm.ok());
    EXPECT_EQ(utm->zone, 29);
    EXPECT_EQ(utm->epsg, 32629);
    const std::string path = ::testing::TempDir() + "/p.las";
    ASSERT_TRUE(WriteLas(path, g, *utm).ok());
    std::ifstream in(path, std::ios::binary);
    std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(in)), {});
    ByteReader r(b);
    EXPECT_EQ(r.FixedString(4), "LASF");
    r.Seek(6);
    EXPECT_EQ(r.U16Le(), 0x11);  // adjusted GPS time + WKT
    r.Seek(24);
    EXPECT_EQ(r.U8(), 1);
    EXPECT_EQ(r.U8(), 4);
    r.Seek(94);
    EXPECT_EQ(r.U16Le(), 375);
    const std::uint32_t point_offset = r.U32Le();
    EXPECT_EQ(r.U32Le(), 1u);  // one VLR
    EXPECT_EQ(r.U8(), 6);
    EXPECT_EQ(r.U16Le(), 30);
    EXPECT_EQ(r.U32Le(), 0u);  // legacy count
    r.Seek(131);
    const double sx = r.F64Le();
    r.Seek(155);
    const double ox = r.F64Le(), oy = r.F64Le(), oz = r.F64Le();
    EXPECT_DOUBLE_EQ(sx, 0.001);
    r.Seek(247);
    EXPECT_EQ(r.U64Le(), 2u);
    // VLR
    r.Seek(375 + 2);
    EXPECT_EQ(r.FixedString(16).substr(0, 15), "LASF_Projection");
    EXPECT_EQ(r.U16Le(), 2112);
    const std::uint16_t wkt_len = r.U16Le();
    r.Skip(32);
    const std::string wkt = r.FixedString(wkt_len);
    EXPECT_NE(wkt.find("UTM zone 29N"), std::string::npos);
    EXPECT_EQ(point_offset, 375u + 54u + wkt_len);
    // Points.
    r.Seek(point_offset);
    for (int i = 0; i < 2; ++i) {
        const double x = r.I32Le() * 0.001 + ox;
        const double y = r.I32Le() * 0.001 + oy;
        const double z = r.I32Le() * 0.001 + oz;
        EXPECT_NEAR(x, utm->easting_northing_height[i].x(), 0.001);
        EXPECT_NEAR(y, utm->easting_northing_height[i].y(), 0.001);
        EXPECT_NEAR(z, utm->easting_northing_height[i].z(), 0.001);
        r.Skip(2);
        EXPECT_EQ(r.U8(), 0x11);
        r.Skip(3);
        EXPECT_NEAR(r.I16Le() * 0.006, i == 0 ? -28.65 : 28.65, 0.01);
        r.Skip(2);
        EXPECT_NEAR(r.F64Le(), 1'465'500'000.123456 - 1e9, 1e-6);
    }
    EXPECT_EQ(r.position(), b.size());
    EXPECT_TRUE(r.ok());
}

}  // namespace
}  // namespace pitmap::proc::io
