// SPDX-License-Identifier: MIT
// Product readers on corrupted input (issue 14, case 5): ingest.cache and summary.json,
// truncated at several points, with overwritten bytes over several seeds, with huge counts,
// wrong types and empty files. Every failure is a clear error naming the file, in memory
// bounded by the file's size; nothing crashes.
// vehicle.yaml: each sonar mount georeferences its beams where that mount looks; a foreign
// file is an error. points.las: its CRS VLR is a compound WKT with the vertical datum.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "common/frames.hpp"
#include "common/peak_memory.hpp"
#include "common/protocol/novatel/crc32.hpp"
#include "processor/io/products.hpp"

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> ReadBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteBytes(const std::string& path, const std::vector<std::uint8_t>& b) {
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// Replaces the trailing CRC-32 by the one of the bytes before it (a crafted file whose
// checksum is right, so that the structural checks behind it are exercised).
void FixCrc(std::vector<std::uint8_t>& b) {
    const std::uint32_t crc = protocol::novatel::Crc32({b.data(), b.size() - 4});
    std::memcpy(b.data() + b.size() - 4, &crc, 4);
}

// Offsets of the four arrays' u64 count fields (each followed by the u64 element size and
// the elements), after the 20-byte header.
std::vector<std::size_t> ArrayOffsets(const std::vector<std::uint8_t>& b) {
    std::vector<std::size_t> at;
    std::size_t pos = 20;  // magic, version, byte order, leap seconds, ping clock
    for (int array = 0; array < 4; ++array) {
        at.push_back(pos);
        std::uint64_t count = 0, size = 0;
        std::memcpy(&count, b.data() + pos, 8);
        std::memcpy(&size, b.data() + pos + 8, 8);
        pos += 16 + count * size;
    }
    EXPECT_EQ(pos + 4, b.size()) << "the layout walked is the file's";
    return at;
}

IngestResult SmallIngest() {
    IngestResult r;
    r.nav.leap_seconds = 18;
    for (int i = 0; i < 20; ++i) {
        georef::NavSample s;
        s.utime_gps = 1'400'000'000'000'000 + i * 10'000;
        s.position = {40.4435 + i * 1e-6, -7.7806, 412.0};
        s.yaw_rad = 0.1 * i;
        s.ins_status = 3;
        s.position_type = 56;
        r.nav.samples.push_back(s);
        georef::NavStdDev d;
        d.utime_gps = s.utime_gps;
        d.north_m = d.east_m = d.up_m = 0.02f;
        r.nav.stddevs.push_back(d);
    }
    for (int p = 0; p < 10; ++p) {
        georef::PingHeader h;
        h.utime_gps = 1'400'000'000'000'000 + p * 20'000;
        h.ping_number = p;
        h.sound_speed_valid = p % 2 == 0;
        h.range_resolution_m = 0.01;
        h.start_angle_deg = -60;
        h.angle_increment_deg = 1.0;
        h.beam_offset = static_cast<std::uint32_t>(r.pings.range_counts.size());
        h.num_beams = 121;
        r.pings.pings.push_back(h);
        for (int b = 0; b < 121; ++b) r.pings.range_counts.push_back(1000u + b);
    }
    return r;
}

class ProductReaders : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(::testing::TempDir()) / ("pitmap_products_" + std::to_string(::getpid()));
        fs::create_directories(dir_);
        cache_ = (dir_ / "ingest.cache").string();
        ASSERT_TRUE(WriteIngestCache(cache_, SmallIngest()));
        good_ = ReadBytes(cache_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    void ExpectCacheError(const std::vector<std::uint8_t>& bytes, const std::string& what) {
        WriteBytes(cache_, bytes);
        const auto r = ReadIngestCache(cache_);
        ASSERT_FALSE(r.ok()) << what;
        EXPECT_NE(r.error().message.find(cache_), std::string::npos)
            << what << ": " << r.error().message;
    }

    fs::path dir_;
    std::string cache_;
    std::vector<std::uint8_t> good_;
};

TEST_F(ProductReaders, IngestCacheRoundTrips) {
    const auto r = ReadIngestCache(cache_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    const IngestResult w = SmallIngest();
    EXPECT_EQ(r->nav.leap_seconds, 18);
    ASSERT_EQ(r->nav.samples.size(), w.nav.samples.size());
    EXPECT_EQ(r->nav.samples[7].utime_gps, w.nav.samples[7].utime_gps);
    EXPECT_DOUBLE_EQ(r->nav.samples[7].yaw_rad, w.nav.samples[7].yaw_rad);
    EXPECT_EQ(r->nav.stddevs.size(), w.nav.stddevs.size());
    ASSERT_EQ(r->pings.pings.size(), 10u);
    EXPECT_TRUE(r->pings.pings[4].sound_speed_valid);
    EXPECT_FALSE(r->pings.pings[5].sound_speed_valid);
    EXPECT_EQ(r->pings.range_counts, w.pings.range_counts);
}

TEST_F(ProductReaders, TruncatedIngestCachesAreCleanErrors) {
    const std::size_t n = good_.size();
    for (std::size_t keep : {std::size_t{0},
                             std::size_t{3},
                             std::size_t{12},
                             std::size_t{16},
                             std::size_t{20},
                             std::size_t{31},
                             std::size_t{100},
                             n / 3,
                             n / 2,
                             n - 5,
                             n - 4,
                             n - 1}) {
        ExpectCacheError({good_.begin(), good_.begin() + static_cast<long>(keep)},
                         "truncated to " + std::to_string(keep));
    }
    std::vector<std::uint8_t> longer = good_;
    longer.push_back(0);
    ExpectCacheError(longer, "one byte appended");
}

TEST_F(ProductReaders, OverwrittenIngestCacheBytesAreCleanErrorsOverTwentySeeds) {
    for (unsigned seed = 1; seed <= 20; ++seed) {
        std::mt19937 rng(seed);
        std::vector<std::uint8_t> bad = good_;
        std::uniform_int_distribution<std::size_t> at(0, bad.size() - 1);
        for (int k = 0; k < 20; ++k) bad[at(rng)] ^= static_cast<std::uint8_t>(1 + rng() % 255);
        ExpectCacheError(bad, "seed " + std::to_string(seed));
    }
}

// Case 5: an array count edited to 3 GiB allocated 3.2 GB before the error. Every count is now
// checked against the bytes that remain, before allocating, whether or not the CRC is right.
TEST_F(ProductReaders, IngestCacheKeepsThePingClockAndRefusesAnUnknownOne) {
    IngestResult r = SmallIngest();
    r.pings.clock = georef::PingClock::kTopsideHeader;
    r.pings.pings[0].aid_latitude_deg = 40.5;
    const std::string path = (dir_ / "clock.cache").string();
    ASSERT_TRUE(WriteIngestCache(path, r));
    auto back = ReadIngestCache(path);
    ASSERT_TRUE(back) << back.error().message;
    EXPECT_EQ(back->pings.clock, georef::PingClock::kTopsideHeader);
    EXPECT_EQ(back->pings.pings[0].aid_latitude_deg, 40.5);
    std::vector<std::uint8_t> bad = good_;
    bad[16] = 9;  // ping clock field
    ExpectCacheError(bad, "ping clock");
}

TEST_F(ProductReaders, HugeIngestCacheCountsFailWithoutAllocating) {
    const double rss_before_mb = PeakRssMb();
    const std::vector<std::size_t> offsets = ArrayOffsets(good_);
    for (std::size_t array = 0; array < 4; ++array) {
        const std::size_t at = offsets[array];
        std::uint64_t count = 0, size = 0;
        std::memcpy(&count, good_.data() + at, 8);
        std::memcpy(&size, good_.data() + at + 8, 8);
        for (std::uint64_t huge : std::vector<std::uint64_t>{
                 3ull << 30, (3ull << 30) / size, ~0ull, ~0ull / size, count + 1}) {
            for (bool fix_crc : {false, true}) {
                std::vector<std::uint8_t> bad = good_;
                std::memcpy(bad.data() + at, &huge, 8);
                if (fix_crc) FixCrc(bad);
                ExpectCacheError(
                    bad, "array " + std::to_string(array) + " count " + std::to_string(huge));
            }
        }
        // A wrong element size too.
        std::vector<std::uint8_t> bad = good_;
        bad[at + 8] ^= 0x40;
        ExpectCacheError(bad, "array " + std::to_string(array) + " element size");
    }
    EXPECT_LT(PeakRssMb() - rss_before_mb, 64.0) << "memory stays bounded by the file size";
}

TEST_F(ProductReaders, CraftedIngestCacheWithRightCrcIsCheckedToo) {
    // Beam offsets pointing past the range counts: the CRC is right, the content is not.
    std::vector<std::uint8_t> bad = good_;
    const std::size_t pings_at = ArrayOffsets(good_)[2];
    std::uint64_t ping_size = 0;
    std::memcpy(&ping_size, bad.data() + pings_at + 8, 8);
    ASSERT_EQ(ping_size, sizeof(georef::PingHeader));
    const std::size_t first = pings_at + 16;
    const std::uint32_t offset = 1u << 30;
    std::memcpy(bad.data() + first + offsetof(georef::PingHeader, beam_offset), &offset, 4);
    FixCrc(bad);
    ExpectCacheError(bad, "beam offset");
    // A bool byte of 7 reads as true (no undefined bool value reaches the stages).
    bad = good_;
    bad[first + offsetof(georef::PingHeader, sound_speed_valid)] = 7;
    FixCrc(bad);
    WriteBytes(cache_, bad);
    const auto r = ReadIngestCache(cache_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_TRUE(r->pings.pings[0].sound_speed_valid);
}

TEST_F(ProductReaders, EmptyAndForeignIngestCachesAreCleanErrors) {
    ExpectCacheError({}, "empty");
    ExpectCacheError(std::vector<std::uint8_t>(4096, 0), "zeros");
    std::vector<std::uint8_t> v1 = good_;
    v1[4] = 1;  // version 1 (no checksum)
    ExpectCacheError(v1, "version 1");
    EXPECT_NE(ReadIngestCache(cache_).error().message.find("version"), std::string::npos);
    const auto missing = ReadIngestCache((dir_ / "none.cache").string());
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.error().message.find("none.cache"), std::string::npos);
}

TEST_F(ProductReaders, BrokenSummaryJsonIsAnErrorNamingTheFileAndKey) {
    const std::string path = (dir_ / "summary.json").string();
    const std::string good =
        R"({"world_origin": {"latitude_deg": 40.4, "longitude_deg": -7.8, "height_m": 412},)"
        R"( "mount": {"roll_deg": 0, "pitch_deg": 0, "yaw_deg": 1,)"
        R"( "lever_arm_sonar_m": [0, 0, 0.5]}, "utm": {"zone": 29},)"
        R"( "stages": {"georef": {"seconds": 1}}, "stage_order": ["georef"]})";
    std::ofstream(path, std::ios::trunc) << good;
    ASSERT_TRUE(ReadSummaryJson(path).ok());
    struct Case {
        std::string text, expect;
    };
    const std::vector<Case> cases = {
        {"", "not valid JSON"},
        {good.substr(0, good.size() / 2), "not valid JSON"},
        {"{\"a\": 1,}", "line 1"},
        {"[1, 2]", "must be a JSON object"},
        {R"({"world_origin": 5})", "world_origin must be an object"},
        {R"({"world_origin": {"latitude_deg": "x", "longitude_deg": 0, "height_m": 0}})",
         "world_origin.latitude_deg must be a number"},
        {R"({"world_origin": {"latitude_deg": 1e300, "longitude_deg": 0, "height_m": 0}})",
         "latitude_deg beyond"},
        {R"({"world_origin": {"longitude_deg": 0, "height_m": 0}})", "latitude_deg missing"},
        {R"({"mount": {"roll_deg": 0, "pitch_deg": 0, "yaw_deg": null,)"
         R"( "lever_arm_sonar_m": [0, 0, 0]}})",
         "mount.yaw_deg"},
        {R"({"mount": {"roll_deg": 0, "pitch_deg": 0, "yaw_deg": 0,)"
         R"( "lever_arm_sonar_m": [0, 0]}})",
         "lever_arm_sonar_m"},
        {R"({"stages": []})", "stages must be an object"},
        {R"({"stages": {"fuse": 3}})", "stages.fuse must be an object"},
        {R"({"stage_order": "georef"})", "stage_order must be an array"},
        {R"({"utm": "29N"})", "utm must be an object"},
        {R"({"sonar_clock": 2})", "sonar_clock must be an object"},
        {R"({"sonar_clock": {"sigma_s": "x"}})", "sonar_clock.sigma_s must be a number"},
        {R"({"quality_gates": {}})", "quality_gates must be an array"},
        {R"({"quality_gates": [{"stage": 3, "gate": "g", "message": "m"}]})",
         "quality_gates[].stage must be a string"},
    };
    for (const Case& c : cases) {
        std::ofstream(path, std::ios::trunc) << c.text;
        const auto r = ReadSummaryJson(path);
        ASSERT_FALSE(r.ok()) << c.text;
        EXPECT_NE(r.error().message.find(path), std::string::npos) << r.error().message;
        EXPECT_NE(r.error().message.find(c.expect), std::string::npos)
            << c.text << " -> " << r.error().message;
    }
    // Overwritten bytes over several seeds: an error or a summary of the right types.
    for (unsigned seed = 1; seed <= 20; ++seed) {
        std::mt19937 rng(seed);
        std::string bad = good;
        for (int k = 0; k < 5; ++k) bad[rng() % bad.size()] = static_cast<char>(rng() & 0xff);
        std::ofstream(path, std::ios::trunc) << bad;
        const auto r = ReadSummaryJson(path);
        if (!r.ok()) {
            EXPECT_NE(r.error().message.find(path), std::string::npos);
        }
    }
    const auto missing = ReadSummaryJson((dir_ / "none.json").string());
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.error().message.find("none.json"), std::string::npos);
}

// A level vehicle heading north at the world origin, one ping with beams at -30, 0 and +30
// degrees, 10 m each, through the mount that `vehicle` (vehicle.yaml text) describes; returns
// the soundings in world ENU metres relative to the sonar, in beam order.
std::vector<Eigen::Vector3d> BeamsThrough(const fs::path& dir, const std::string& vehicle) {
    const std::string path = (dir / "vehicle.yaml").string();
    std::ofstream(path, std::ios::trunc) << vehicle;
    const auto v = ReadVehicleYaml(path);
    EXPECT_TRUE(v) << v.error().message;
    if (!v) return {};
    georef::NavSeries nav;
    for (int i = 0; i < 3; ++i) {
        georef::NavSample s;
        s.utime_gps = 1'400'000'000'000'000 + i * 100'000;
        s.position = {40.4435, -7.7806, 412.0};
        nav.samples.push_back(s);
    }
    georef::PingSeries pings;
    georef::PingHeader h;
    h.utime_gps = 1'400'000'000'100'000;
    h.range_resolution_m = 0.001;
    h.start_angle_deg = -30;
    h.angle_increment_deg = 30;
    h.num_beams = 3;
    pings.pings.push_back(h);
    pings.range_counts = {10'000, 10'000, 10'000};
    georef::GeorefConfig cfg;
    cfg.spike_half_window = 0;
    const georef::GeorefResult r = georef::RunGeoref(nav, pings, v->mount, cfg);
    EXPECT_EQ(r.points.size(), 3u);
    std::vector<Eigen::Vector3d> out;
    for (const auto& p : r.points.position_world) out.push_back(p - r.pings[0].sensor_world);
    return out;
}

std::string Vehicle(const std::string& mount) {
    return "pitmap_vehicle: 1\nsonar:\n  lever_arm_m: [0.8, 0.1, 0.25]\n  mount: {" + mount + "}\n";
}

TEST_F(ProductReaders, EachSonarMountGeoreferencesWhereItLooks) {
    // World ENU, vehicle heading north: starboard = east, forward = north, down = -z.
    const double s30 = 10 * std::sin(frames::DegToRad(30));
    const double c30 = 10 * std::cos(frames::DegToRad(30));
    const double s60 = 10 * std::sin(frames::DegToRad(60));
    const double c60 = 10 * std::cos(frames::DegToRad(60));
    struct Case {
        const char* mount;
        Eigen::Vector3d minus30, nadir, plus30;
    };
    const Case cases[] = {
        // The standard mount: positive angles to starboard.
        {"orientation: down, connector: aft", {-s30, 0, -c30}, {0, 0, -10}, {s30, 0, -c30}},
        // Head turned round: positive angles to port.
        {"orientation: down, connector: forward", {s30, 0, -c30}, {0, 0, -10}, {-s30, 0, -c30}},
        // Fan along the track: positive angles aft (connector port) or forward (starboard).
        {"orientation: down, connector: port", {0, s30, -c30}, {0, 0, -10}, {0, -s30, -c30}},
        {"orientation: down, connector: starboard", {0, -s30, -c30}, {0, 0, -10}, {0, s30, -c30}},
        // Tilted 30 degrees to starboard: the centre beam looks 30 degrees off nadir.
        {"orientation: tilted, tilt_deg: 30, connector: aft",
         {0, 0, -10},
         {s30, 0, -c30},
         {s60, 0, -c60}},
        // Connector forward, tilted towards its -y side, which is the vehicle's starboard.
        {"orientation: tilted, tilt_deg: -30, connector: forward",
         {s60, 0, -c60},
         {s30, 0, -c30},
         {0, 0, -10}},
    };
    for (const Case& c : cases) {
        const auto b = BeamsThrough(dir_, Vehicle(c.mount));
        ASSERT_EQ(b.size(), 3u) << c.mount;
        EXPECT_LT((b[0] - c.minus30).norm(), 1e-3) << c.mount << ": -30 at " << b[0].transpose();
        EXPECT_LT((b[1] - c.nadir).norm(), 1e-3) << c.mount << ": 0 at " << b[1].transpose();
        EXPECT_LT((b[2] - c.plus30).norm(), 1e-3) << c.mount << ": +30 at " << b[2].transpose();
    }
}

TEST_F(ProductReaders, ForeignOrIncompleteVehicleFilesAreErrors) {
    const std::string path = (dir_ / "vehicle.yaml").string();
    // What the processor read as a zero lever arm with two warnings before schema 1.
    std::ofstream(path, std::ios::trunc) << "vehicle: survey-boat\noperator: acme\n";
    auto v = ReadVehicleYaml(path);
    ASSERT_FALSE(v);
    EXPECT_NE(v.error().message.find(path + ": not a pitmap vehicle file; missing: "
                                            "pitmap_vehicle sonar.lever_arm_m"),
              std::string::npos)
        << v.error().message;
    std::ofstream(path, std::ios::trunc)
        << "pitmap_vehicle: 1\nsonar:\n  mount: {orientation: down, connector: aft}\n";
    v = ReadVehicleYaml(path);
    ASSERT_FALSE(v);
    EXPECT_NE(v.error().message.find("sonar.lever_arm_m: required but missing"), std::string::npos)
        << v.error().message;
}

// The LAS CRS VLR (LASF_Projection / 2112): COMPD_CS of the UTM PROJCS and a VERT_CS of WGS 84
// ellipsoidal heights (OGC 01-009 vertical datum type 2002).
TEST_F(ProductReaders, LasDeclaresItsVerticalDatum) {
    georef::GeorefResult r;
    r.world_origin = {40.4435, -7.7806, 412.0};
    georef::GeorefPing ping;
    ping.utime_gps = 1'400'000'000'000'000;
    r.pings.push_back(ping);
    r.points.position_world = {Eigen::Vector3d(1, 2, -10)};
    r.points.ping = {0};
    r.points.beam = {0};
    r.points.range_m = {10.0f};
    r.points.angle_rad = {0.0f};
    const auto utm = georef::ToUtm(r);
    ASSERT_TRUE(utm) << utm.error().message;
    const std::string las = (dir_ / "points.las").string();
    ASSERT_TRUE(WriteLas(las, r, *utm));
    const std::vector<std::uint8_t> b = ReadBytes(las);
    ASSERT_GT(b.size(), 375u + 54u);
    auto u16 = [&](std::size_t at) { return static_cast<unsigned>(b[at] | (b[at + 1] << 8)); };
    auto u32 = [&](std::size_t at) {
        return static_cast<std::uint32_t>(u16(at) | (u16(at + 2) << 16));
    };
    EXPECT_EQ(u16(6) & (1u << 4), 1u << 4) << "global encoding: WKT";
    ASSERT_EQ(u32(100), 1u) << "one VLR";
    const std::size_t vlr = u16(94);  // header size
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(&b[vlr + 2])), "LASF_Projection");
    EXPECT_EQ(u16(vlr + 18), 2112u);
    const std::size_t n = u16(vlr + 20);
    ASSERT_LE(vlr + 54 + n, b.size());
    EXPECT_EQ(u32(96), vlr + 54 + n) << "offset to point data";
    std::string wkt(reinterpret_cast<const char*>(&b[vlr + 54]), n);
    ASSERT_FALSE(wkt.empty());
    EXPECT_EQ(wkt.back(), '\0');
    wkt.pop_back();
    const std::string zone = "WGS 84 / UTM zone 29N";  // 7.78 W
    EXPECT_EQ(
        wkt.rfind("COMPD_CS[\"" + zone + " + WGS 84 ellipsoidal height\",PROJCS[\"" + zone, 0), 0u)
        << wkt;
    const auto projcs = wkt.find("PROJCS[");
    const auto vert = wkt.find(",VERT_CS[\"WGS 84 ellipsoidal height\",VERT_DATUM[");
    ASSERT_NE(vert, std::string::npos) << wkt;
    EXPECT_EQ(wkt.substr(projcs, vert - projcs), UtmWkt(29, true));
    EXPECT_NE(wkt.find("AUTHORITY[\"EPSG\",\"32629\"]]", projcs), std::string::npos) << wkt;
    EXPECT_NE(wkt.find("VERT_DATUM[\"World Geodetic System 1984\",2002]", vert), std::string::npos)
        << wkt;
    EXPECT_NE(wkt.find("AXIS[\"Ellipsoidal height\",UP]", vert), std::string::npos) << wkt;
    // Brackets balance and the compound closes last.
    int depth = 0, min_depth_before_end = 1;
    for (std::size_t i = 0; i < wkt.size(); ++i) {
        depth += wkt[i] == '[' ? 1 : wkt[i] == ']' ? -1 : 0;
        if (i > 9 && i + 1 < wkt.size())
            min_depth_before_end = std::min(min_depth_before_end, depth);
    }
    EXPECT_EQ(depth, 0);
    EXPECT_EQ(min_depth_before_end, 1) << "one COMPD_CS holds everything";
}

}  // namespace
}  // namespace pitmap::proc::io
