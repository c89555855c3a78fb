// SPDX-License-Identifier: MIT
// The 83P intensities in the point files (processor/io/products.hpp, issue 39 item 5): each
// LAS record's intensity and the PLY's ushort intensity are the recorded intensity of the
// sounding's beam, found through its ping's header index, for accepted and rejected soundings
// alike; pings without intensities give none (PLY: no property, LAS: 0); the THU/TVU extra
// bytes carry names PDAL keeps.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "processor/io/products.hpp"
#include "processor/survey/sounding_status.hpp"

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

class PointIntensity : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("pitmap_point_intensity_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

std::vector<std::uint8_t> ReadBytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

unsigned U16(const std::vector<std::uint8_t>& b, std::size_t at) {
    return static_cast<unsigned>(b[at] | (b[at + 1] << 8));
}
std::uint32_t U32(const std::vector<std::uint8_t>& b, std::size_t at) {
    return static_cast<std::uint32_t>(U16(b, at) | (U16(b, at + 2) << 16));
}

// Two pings of four beams; intensities 100 200 300 400 | 5000 6000 7000 65535.
survey::PingSeries Pings() {
    survey::PingSeries s;
    s.pings.resize(2);
    s.pings[0].beam_offset = 0;
    s.pings[0].num_beams = 4;
    s.pings[1].beam_offset = 4;
    s.pings[1].num_beams = 4;
    s.range_counts.assign(8, 1000);
    s.intensities = {100, 200, 300, 400, 5000, 6000, 7000, 65535};
    return s;
}

// Georeferenced ping 0 is header 1 and ping 1 header 0 (the index is followed, not assumed).
// Accepted: (ping 0, beam 0) -> 5000, (ping 1, beam 2) -> 300, (ping 0, beam 3) -> 65535.
georef::GeorefResult Accepted() {
    georef::GeorefResult r;
    r.world_origin = {40.4435, -7.7806, 412.0};
    georef::GeorefPing p;
    p.utime_gps = 1'400'000'000'000'000;
    p.header_index = 1;
    r.pings.push_back(p);
    p.header_index = 0;
    r.pings.push_back(p);
    r.points.position_world = {
        Eigen::Vector3d(1, 2, -10), Eigen::Vector3d(3, 4, -12), Eigen::Vector3d(5, 1, -11)};
    r.points.ping = {0, 1, 0};
    r.points.beam = {0, 2, 3};
    r.points.range_m = {10.0f, 12.0f, 11.0f};
    r.points.angle_rad = {0.0f, 0.1f, 0.2f};
    return r;
}
const std::vector<unsigned> kAcceptedIntensity = {5000, 300, 65535};

// Rejected: (ping 1, beam 1) -> 200, a spike far below the others.
georef::GeorefResult Rejected() {
    georef::GeorefResult r = Accepted();
    r.points.position_world = {Eigen::Vector3d(2, 2, -30)};
    r.points.ping = {1};
    r.points.beam = {1};
    r.points.range_m = {30.0f};
    r.points.angle_rad = {0.05f};
    r.points.status = {static_cast<std::uint8_t>(survey::SoundingStatus::kSpike)};
    return r;
}

TEST_F(PointIntensity, SoundingIntensityFollowsThePingsHeaderIndex) {
    const survey::PingSeries s = Pings();
    const georef::GeorefResult r = Accepted();
    for (std::size_t i = 0; i < 3; ++i)
        EXPECT_EQ(SoundingIntensity(r, i, s), kAcceptedIntensity[i]);
    EXPECT_EQ(SoundingIntensity(r, 3, s), 0u);  // no such sounding
    georef::GeorefResult bad = r;
    bad.points.beam[0] = 4;  // beyond the ping's four beams
    EXPECT_EQ(SoundingIntensity(bad, 0, s), 0u);
    bad.pings[0].header_index = 7;  // no such header
    EXPECT_EQ(SoundingIntensity(bad, 0, s), 0u);
    survey::PingSeries none = s;
    none.intensities.clear();
    EXPECT_EQ(SoundingIntensity(r, 0, none), 0u);
}

TEST_F(PointIntensity, LasRecordsCarryTheIntensityAndPdalNames) {
    const survey::PingSeries s = Pings();
    const georef::GeorefResult a = Accepted(), rej = Rejected();
    const auto utm = georef::ToUtm(a);
    ASSERT_TRUE(utm) << utm.error().message;
    PointExtras x;
    x.thu_95_m = {0.1f, 0.2f, 0.3f};
    x.tvu_95_m = {0.4f, 0.5f, 0.6f};
    x.pings = &s;
    const fs::path las = dir_ / "points.las";
    ASSERT_TRUE(WriteLas(las.string(), a, *utm, &x, "", &rej));
    const std::vector<std::uint8_t> b = ReadBytes(las);
    ASSERT_EQ(b[104], 6u);
    const unsigned len = U16(b, 105);
    ASSERT_EQ(len, 38u);
    const std::size_t points = U32(b, 96);
    ASSERT_EQ(b.size(), points + 4 * len);
    // Format 6: X, Y, Z int32, then the intensity.
    const std::vector<unsigned> want = {5000, 300, 65535, 200};
    for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(U16(b, points + k * len + 12), want[k]) << k;
    // The extra bytes' names: a letter, then letters, digits or '_' (PDAL's Dimension rule).
    std::size_t vlr = U16(b, 94);
    vlr += 54 + U16(b, vlr + 20);  // past the WKT VLR
    ASSERT_EQ(std::string(reinterpret_cast<const char*>(&b[vlr + 2])), "LASF_Spec");
    for (std::size_t d = 0; d < 2; ++d) {
        const std::string name(reinterpret_cast<const char*>(&b[vlr + 54 + 192 * d + 4]));
        EXPECT_EQ(name, d == 0 ? kLasThuName : kLasTvuName);
        ASSERT_FALSE(name.empty());
        EXPECT_TRUE(std::isalpha(static_cast<unsigned char>(name[0]))) << name;
        for (char c : name) {
            EXPECT_TRUE(std::isalnum(static_cast<unsigned char>(c)) || c == '_') << name;
        }
    }
    // Without intensities in the pings: 0.
    survey::PingSeries none = s;
    none.intensities.clear();
    x.pings = &none;
    ASSERT_TRUE(WriteLas(las.string(), a, *utm, &x));
    const std::vector<std::uint8_t> c = ReadBytes(las);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(U16(c, U32(c, 96) + k * len + 12), 0u) << k;
}

TEST_F(PointIntensity, PlyHasAnIntensityPropertyOnlyWithIntensities) {
    const survey::PingSeries s = Pings();
    const georef::GeorefResult a = Accepted(), rej = Rejected();
    PointExtras x;
    x.pings = &s;
    const fs::path ply = dir_ / "points.ply";
    ASSERT_TRUE(WritePly(ply.string(), a, &x, "", &rej));
    std::vector<std::uint8_t> b = ReadBytes(ply);
    std::string text(b.begin(), b.end());
    std::size_t end = text.find("end_header\n");
    ASSERT_NE(end, std::string::npos);
    EXPECT_NE(text.substr(0, end).find(
                  "property ushort beam\nproperty ushort intensity\nproperty uchar status\n"),
              std::string::npos)
        << text.substr(0, end);
    // x y z float, gps_time_s double, range_m float, ping uint, beam ushort, intensity ushort,
    // status uchar.
    const std::size_t rec = 4 * 3 + 8 + 4 + 4 + 2 + 2 + 1;
    ASSERT_EQ(b.size(), end + 11 + 4 * rec);
    const std::vector<unsigned> want = {5000, 300, 65535, 200};
    for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(U16(b, end + 11 + k * rec + 30), want[k]) << k;
    // No intensities: no property.
    survey::PingSeries none = s;
    none.intensities.clear();
    x.pings = &none;
    ASSERT_TRUE(WritePly(ply.string(), a, &x));
    b = ReadBytes(ply);
    text.assign(b.begin(), b.end());
    end = text.find("end_header\n");
    EXPECT_EQ(text.substr(0, end).find("intensity"), std::string::npos);
}

}  // namespace
}  // namespace pitmap::proc::io
