// SPDX-License-Identifier: MIT
// The XTF reader (processor/io/xtf.hpp) on a real QINSy/R2Sonic 2026 line (tests/data/xtf/,
// README.md there says what it holds), on cut and corrupted copies of it, and through ingest.
#include "processor/io/xtf.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/gps_time.hpp"
#include "processor/io/ingest.hpp"

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

const std::string kLine =
    std::string(PITMAP_TEST_DATA_DIR) + "/xtf/r2sonic2026_150708_R2Testing_0001.xtf";

std::vector<std::uint8_t> ReadAll(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Offsets of the packets of one header type, by walking the sizes (byte 10, little-endian).
std::vector<std::size_t> PacketsOfType(const std::vector<std::uint8_t>& b, int type) {
    std::vector<std::size_t> out;
    for (std::size_t p = kXtfFileHeaderBytes; p + 14 <= b.size();) {
        const std::uint32_t n = b[p + 10] | (b[p + 11] << 8) | (b[p + 12] << 16) |
                                (static_cast<std::uint32_t>(b[p + 13]) << 24);
        if (b[p + 2] == type) out.push_back(p);
        if (n < 14) break;
        p += n;
    }
    return out;
}

bool Mentions(const std::vector<std::string>& warnings, const std::string& what) {
    return std::any_of(warnings.begin(), warnings.end(), [&](const std::string& w) {
        return w.find(what) != std::string::npos;
    });
}

class XtfLine : public ::testing::Test {
protected:
    void SetUp() override {
        bytes_ = ReadAll(kLine);
        ASSERT_EQ(bytes_.size(), 2163520u);
    }
    Expected<XtfFile> Decode(const std::vector<std::uint8_t>& b) {
        return DecodeXtf(ByteSpan(b.data(), b.size()), "line.xtf");
    }
    std::vector<std::uint8_t> bytes_;
};

TEST_F(XtfLine, ReadsWhatTheReadmeSays) {
    const auto f = Decode(bytes_);
    ASSERT_TRUE(f.ok()) << f.error().message;
    EXPECT_EQ(f->header.recording_program, "QINSy");
    EXPECT_EQ(f->header.nav_units, kXtfNavUnitsLatLon);
    EXPECT_EQ(f->header.sonar_channels, 0);
    EXPECT_EQ(f->header.bathymetry_channels, 1);
    EXPECT_EQ(f->counts.packets, 923 + 1203 + 1204);
    EXPECT_EQ(f->counts.packets_by_type.at(65), 923);
    EXPECT_EQ(f->counts.packets_by_type.at(3), 1203);
    EXPECT_EQ(f->counts.packets_by_type.at(107), 1204);
    EXPECT_EQ(f->counts.unknown_packets, 0);
    EXPECT_EQ(f->counts.bad_packets, 0);
    EXPECT_EQ(f->counts.skipped_bytes, 0);
    EXPECT_TRUE(f->warnings.empty());
    ASSERT_EQ(f->pings.size(), 923u);
    ASSERT_EQ(f->attitude.size(), 1203u);
    ASSERT_EQ(f->positions.size(), 1204u);

    const XtfBathyPing& first = f->pings.front();
    const XtfBathyPing& last = f->pings.back();
    EXPECT_EQ(first.ping_number, 151989u);
    EXPECT_EQ(last.ping_number, 152911u);
    EXPECT_EQ(first.model, "2026");
    EXPECT_NEAR(first.sound_speed_mps, 1514.96, 0.005);
    EXPECT_DOUBLE_EQ(first.frequency_hz, 400000.0);
    EXPECT_NEAR(first.range_setting_m, 31.9, 0.05);
    const double span_s = static_cast<double>(last.utime_unix - first.utime_unix) * 1e-6;
    EXPECT_NEAR(span_s, 48.1, 0.05);
    // 2015-07-08 23:52:15.9 UTC.
    const auto start = UnixFromUtcCalendar({2015, 7, 8, 23, 52, 15, 900000});
    ASSERT_TRUE(start);
    EXPECT_NEAR(static_cast<double>(first.utime_unix - *start) * 1e-6, 0.0, 0.05);
    for (const XtfBathyPing& p : f->pings) {
        ASSERT_EQ(p.twtt_counts.size(), 256u);
        ASSERT_EQ(p.angle_rad.size(), 256u);
        ASSERT_EQ(p.intensity.size(), 256u);
        ASSERT_EQ(p.quality.size(), 256u);
        ASSERT_GT(p.twtt_scale_s, 0);
        // Equi-distant beams: angles increase, port (negative) to starboard, closer at the
        // edges than near nadir.
        ASSERT_LT(p.angle_rad.front(), -1.0f);
        ASSERT_GT(p.angle_rad.back(), 1.0f);
        for (std::size_t i = 1; i < 256; ++i) ASSERT_GT(p.angle_rad[i], p.angle_rad[i - 1]);
    }
    const auto& a = first.angle_rad;
    EXPECT_LT(a[1] - a[0], a[128] - a[127]);
    // Every point of this line passed the head's brightness and colinearity tests and has a
    // detection (phase 0xB or magnitude 0x7).
    for (std::uint8_t q : first.quality) EXPECT_TRUE(q == 0xB || q == 0x7) << int(q);
    // Attitude and navigation: San Francisco Bay, heading about 251 deg at the start.
    EXPECT_NEAR(f->positions.front().y, 37.7568, 1e-3);
    EXPECT_NEAR(f->positions.front().x, -122.3775, 1e-3);
    EXPECT_NEAR(f->attitude.front().heading_deg, 250.88, 0.01);
    EXPECT_EQ(f->attitude.front().utime_unix, f->positions.front().utime_unix);
}

TEST_F(XtfLine, IngestGivesNavigationAndPingsInGpsTime) {
    IngestResult r;
    ASSERT_TRUE(IngestXtfFiles({kLine}, -1, r));
    EXPECT_EQ(r.pings.pings.size(), 923u);
    EXPECT_EQ(r.pings.range_counts.size(), 923u * 256u);
    ASSERT_TRUE(r.pings.has_beam_angles());
    EXPECT_EQ(r.pings.beam_angles_deg.size(), r.pings.range_counts.size());
    EXPECT_TRUE(r.pings.has_intensities());
    EXPECT_EQ(r.nav.samples.size(), 1204u);
    EXPECT_EQ(r.nav.stddevs.size(), 1204u);
    EXPECT_EQ(r.counts.events, 923 + 1203 + 1204);
    EXPECT_EQ(r.counts.events_by_channel.at("XTF_TYPE_65"), 923);
    // UTC + 17 s (GPS - UTC in July 2015).
    const auto f = ReadXtfFile(kLine);
    ASSERT_TRUE(f.ok());
    EXPECT_EQ(r.pings.pings.front().utime_gps,
              f->pings.front().utime_unix - kGpsEpochUnixSeconds * kMicrosPerSecond +
                  17 * kMicrosPerSecond);
    // Range resolution c/2 * scale; the first ping's outer beam at 8069 counts is ~23.4 m.
    const auto& h = r.pings.pings.front();
    EXPECT_NEAR(h.range_resolution_m, 0.5 * 1514.962 * f->pings.front().twtt_scale_s, 1e-9);
    EXPECT_NEAR(r.pings.range_counts[0] * h.range_resolution_m, 23.4, 0.1);
    EXPECT_NEAR(r.pings.BeamAngleDeg(h, 0), -61.54, 0.01);
    EXPECT_NEAR(r.pings.BeamAngleDeg(h, 255), 61.98, 0.01);
    // Depth below the head of the first ping's beams: a few metres to the range setting.
    for (std::size_t i = 0; i < 256; ++i) {
        const double depth = r.pings.range_counts[i] * h.range_resolution_m *
                             std::cos(r.pings.BeamAngleDeg(h, i) * M_PI / 180.0);
        EXPECT_GT(depth, 3.0);
        EXPECT_LT(depth, 31.9);
    }
    EXPECT_FALSE(r.assumed.empty());
    EXPECT_TRUE(Mentions(r.assumed, "sigmas"));
    EXPECT_TRUE(Mentions(r.assumed, "1514.96 m/s"));
    EXPECT_TRUE(Mentions(r.assumed, "not applied"));  // the header's channel offsets
}

TEST_F(XtfLine, IngestFilesSniffsXtf) {
    const auto r = IngestFiles({kLine}, IngestConfig{});
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->pings.pings.size(), 923u);
    EXPECT_EQ(r->nav.samples.size(), 1204u);
    EXPECT_TRUE(r->warnings.empty()) << r->warnings.front();
    const auto expanded = ExpandInputs({fs::path(kLine).parent_path().string()});
    ASSERT_TRUE(expanded.ok());
    EXPECT_EQ(std::count_if(expanded->begin(),
                            expanded->end(),
                            [](const std::string& p) { return p.ends_with(".xtf"); }),
              1);
}

TEST_F(XtfLine, ACutFileLosesOnlyTheCutPacketWithAWarning) {
    // Cut in the middle of the last bathymetry packet.
    const std::size_t at = PacketsOfType(bytes_, 65).back();
    std::vector<std::uint8_t> cut(bytes_.begin(), bytes_.begin() + at + 1000);
    const auto f = Decode(cut);
    ASSERT_TRUE(f.ok()) << f.error().message;
    EXPECT_EQ(f->pings.size(), 922u);
    EXPECT_EQ(f->counts.truncated_packets, 1);
    EXPECT_EQ(f->counts.skipped_bytes, 1000);
    ASSERT_EQ(f->warnings.size(), 1u);
    EXPECT_NE(f->warnings[0].find("line.xtf"), std::string::npos);
    EXPECT_NE(f->warnings[0].find("cut short"), std::string::npos);
    EXPECT_NE(f->warnings[0].find("byte offset " + std::to_string(at)), std::string::npos)
        << f->warnings[0];
    // A cut inside a packet header.
    std::vector<std::uint8_t> cut2(bytes_.begin(), bytes_.begin() + at + 5);
    const auto g = Decode(cut2);
    ASSERT_TRUE(g.ok());
    EXPECT_EQ(g->counts.truncated_packets, 1);
    EXPECT_EQ(g->pings.size(), 922u);
    // Cut inside the file header: not XTF any more, an error naming the file.
    std::vector<std::uint8_t> cut3(bytes_.begin(), bytes_.begin() + 700);
    const auto h = Decode(cut3);
    ASSERT_FALSE(h.ok());
    EXPECT_NE(h.error().message.find("line.xtf"), std::string::npos);
}

TEST_F(XtfLine, CorruptedPacketHeadersAreSkippedToTheNextPacket) {
    std::vector<std::uint8_t> bad = bytes_;
    const auto bathy = PacketsOfType(bytes_, 65);
    const auto nav = PacketsOfType(bytes_, 107);
    // A flipped magic, a size that overruns the file, a size that lands mid-packet.
    bad[bathy[10]] ^= 0xFF;
    bad[nav[20] + 13] = 0x7F;
    bad[bathy[30] + 10] ^= 0x10;
    const auto f = Decode(bad);
    ASSERT_TRUE(f.ok()) << f.error().message;
    EXPECT_EQ(f->pings.size(), 921u);
    EXPECT_EQ(f->positions.size(), 1203u);
    EXPECT_EQ(f->attitude.size(), 1203u);
    EXPECT_EQ(f->counts.resyncs, 3);
    EXPECT_EQ(f->counts.skipped_bytes, 2176 + 64 + 2176);
    EXPECT_EQ(f->warnings.size(), 3u);
    EXPECT_TRUE(Mentions(f->warnings, "byte offset " + std::to_string(bathy[10])));
    EXPECT_TRUE(Mentions(f->warnings, "byte offset " + std::to_string(nav[20])));
    EXPECT_TRUE(Mentions(f->warnings, "byte offset " + std::to_string(bathy[30])));
}

TEST_F(XtfLine, DamageBeyondTheFirstFewPlacesIsSaidAsATotal) {
    std::vector<std::uint8_t> bad = bytes_;
    const auto bathy = PacketsOfType(bytes_, 65);
    // Eight flipped magics: the first five places are warnings of their own, the other three
    // one total.
    for (int k = 0; k < 8; ++k) bad[bathy[10 + 20 * k]] ^= 0xFF;
    const auto f = Decode(bad);
    ASSERT_TRUE(f.ok()) << f.error().message;
    EXPECT_EQ(f->counts.resyncs, 8);
    ASSERT_EQ(f->warnings.size(), 6u);
    for (int k = 0; k < 5; ++k) {
        EXPECT_TRUE(Mentions(f->warnings, "byte offset " + std::to_string(bathy[10 + 20 * k])));
    }
    EXPECT_NE(f->warnings.back().find("line.xtf: 3 more damaged places"), std::string::npos)
        << f->warnings.back();
}

TEST_F(XtfLine, ACorruptedBth0SectionCountsThePingBad) {
    std::vector<std::uint8_t> bad = bytes_;
    const auto bathy = PacketsOfType(bytes_, 65);
    // R0's section size (BTH0 at +256, H0 12 bytes in and 116 long, R0 after it) made huge.
    const std::size_t r0 = bathy[5] + 256 + 12 + 116;
    ASSERT_EQ(bad[r0], 'R');
    bad[r0 + 2] = 0xFF;
    // Another ping's H0 point count made 0xFFFF.
    const std::size_t h0 = bathy[6] + 256 + 12;
    ASSERT_EQ(bad[h0], 'H');
    bad[h0 + 114] = 0xFF;
    bad[h0 + 115] = 0xFF;
    // A third one's BTH0 name flipped.
    bad[bathy[7] + 256] ^= 0x20;
    const auto f = Decode(bad);
    ASSERT_TRUE(f.ok()) << f.error().message;
    EXPECT_EQ(f->pings.size(), 920u);
    EXPECT_EQ(f->counts.bad_packets, 3);
    EXPECT_EQ(f->warnings.size(), 3u);
    EXPECT_TRUE(Mentions(f->warnings, "byte offset " + std::to_string(bathy[5])));
    // Through ingest, the damage is counted and said.
    const fs::path tmp = fs::temp_directory_path() / "pitmap_xtf_test_bad.xtf";
    {
        std::ofstream out(tmp, std::ios::binary);
        out.write(reinterpret_cast<const char*>(bad.data()),
                  static_cast<std::streamsize>(bad.size()));
    }
    const auto r = IngestFiles({tmp.string()}, IngestConfig{});
    fs::remove(tmp);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->pings.pings.size(), 920u);
    EXPECT_EQ(r->counts.decode_failures, 3);
    EXPECT_TRUE(Mentions(r->warnings, "damaged input"));
}

TEST(Xtf, NotXtfAndProjectedNavigationAreErrorsNamingTheFile) {
    std::vector<std::uint8_t> zeros(4096, 0);
    const auto f = DecodeXtf(ByteSpan(zeros.data(), zeros.size()), "zeros.xtf");
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.error().message.find("zeros.xtf"), std::string::npos);

    std::vector<std::uint8_t> b = ReadAll(kLine);
    b[164] = 0;  // nav units: metres
    const auto g = DecodeXtf(ByteSpan(b.data(), b.size()), "metres.xtf");
    ASSERT_TRUE(g.ok());
    IngestResult r;
    const auto c = AddXtfToIngest(*g, "metres.xtf", XtfAssumptions{}, -1, r);
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.error().message.find("metres.xtf"), std::string::npos);
    EXPECT_NE(c.error().message.find("nav units 0"), std::string::npos);
}

TEST(Xtf, EveryPrefixAndEveryFlippedByteIsSafe) {
    // The first 40 KB: every cut on a coarse grid and a flipped byte every 97 bytes, decoded
    // without a crash (ASan/UBSan builds check the bounds); counts stay consistent.
    const std::vector<std::uint8_t> all = ReadAll(kLine);
    const std::vector<std::uint8_t> head(all.begin(), all.begin() + 40000);
    for (std::size_t n = 0; n <= head.size(); n += 37) {
        const auto f = DecodeXtf(ByteSpan(head.data(), n), "prefix.xtf");
        if (n < kXtfFileHeaderBytes) {
            EXPECT_FALSE(f.ok());
            continue;
        }
        ASSERT_TRUE(f.ok());
        EXPECT_LE(f->pings.size() + f->attitude.size() + f->positions.size(),
                  static_cast<std::size_t>(f->counts.packets));
    }
    for (std::size_t at = 0; at < head.size(); at += 97) {
        std::vector<std::uint8_t> b = head;
        b[at] ^= 0xA5;
        const auto f = DecodeXtf(ByteSpan(b.data(), b.size()), "flip.xtf");
        if (!f.ok()) continue;
        IngestResult r;
        (void)AddXtfToIngest(*f, "flip.xtf", XtfAssumptions{}, -1, r);
    }
}

}  // namespace
}  // namespace pitmap::proc::io
