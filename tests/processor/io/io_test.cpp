// SPDX-License-Identifier: MIT
// LCM log reader: rotated files, a truncated last event and corrupt bytes are counted, never
// fatal. LAS 1.4 writer: read back field by field.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "common/byte_io.hpp"
#include "processor/io/ingest.hpp"
#include "processor/io/lcm_log_reader.hpp"
#include "processor/io/products.hpp"

namespace pitmap::proc::io {
namespace {

void PutBe(std::vector<std::uint8_t>& b, std::uint64_t v, int n) {
    for (int i = n - 1; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

std::vector<std::uint8_t> Event(std::int64_t num, const std::string& ch, std::size_t len) {
    std::vector<std::uint8_t> b;
    PutBe(b, kLcmSyncWord, 4);
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
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(b.data()),
                                                 static_cast<std::streamsize>(b.size()));
    return path;
}

TEST(LcmLogReader, CountsCorruptAndTruncatedEvents) {
    std::vector<std::uint8_t> b;
    for (int i = 0; i < 3; ++i) {
        auto e = Event(i, "CH_A", 10);
        b.insert(b.end(), e.begin(), e.end());
    }
    b.insert(b.end(), {1, 2, 3, 4, 5});  // garbage between events
    auto bad = Event(3, "CH_B", 4);
    bad[20] = 0x7F;  // channel length 2 GB: corrupt header
    b.insert(b.end(), bad.begin(), bad.end());
    auto ok = Event(4, "CH_A", 10);
    b.insert(b.end(), ok.begin(), ok.end());
    auto cut = Event(5, "CH_A", 100);
    cut.resize(60);  // power cut
    b.insert(b.end(), cut.begin(), cut.end());
    auto reader = LcmLogReader::Open(WriteFile("corrupt.lcmlog", b));
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    LcmEvent ev;
    int n = 0;
    while ((*reader)->Next(ev)) {
        EXPECT_EQ(ev.channel, "CH_A");
        EXPECT_EQ(ev.data.size(), 10u);
        ++n;
    }
    EXPECT_EQ(n, 4);
    EXPECT_EQ((*reader)->counts().corrupt_headers, 1);
    EXPECT_EQ((*reader)->counts().truncated_events, 1);
    EXPECT_GT((*reader)->counts().resync_bytes, 0);
}

TEST(LcmLogReader, MissingFileIsAnErrorNamingIt) {
    auto r = LcmLogReader::Open(::testing::TempDir() + "/nope.lcmlog");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("nope.lcmlog"), std::string::npos);
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
