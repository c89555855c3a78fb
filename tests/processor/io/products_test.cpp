// SPDX-License-Identifier: MIT
// Product readers on corrupted input (issue 14, case 5): summary.json with wrong types and
// empty files (the survey file's own tests are in tests/processor/survey). Every failure is a clear
// error naming the file, in memory bounded by the file's size; nothing crashes. vehicle.yaml: each
// sonar mount georeferences its beams where that mount looks; a foreign file is an error.
// points.las: its CRS VLR is a compound WKT with the vertical datum. Issue 35: points.ply and
// points.las carry the rejected soundings after the accepted ones, with their status (PLY) and
// as withheld low or high noise (LAS), the accepted ones as bathymetry.
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

#include "common/formats/ply.hpp"
#include "common/frames.hpp"
#include "processor/io/products.hpp"
#include "processor/io/projected_points.hpp"
#include "processor/io/view_spill.hpp"

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> ReadBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class ProductReaders : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(::testing::TempDir()) / ("pitmap_products_" + std::to_string(::getpid()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    fs::path dir_;
};

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
    survey::NavSeries nav;
    for (int i = 0; i < 3; ++i) {
        survey::NavSample s;
        s.utime_gps = 1'400'000'000'000'000 + i * 100'000;
        s.position = {40.4435, -7.7806, 412.0};
        nav.samples.push_back(s);
    }
    survey::PingSeries pings;
    survey::PingHeader h;
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

// A floor at z = -10 around x, y in [0, 4): two accepted soundings per 2 m cell.
georef::GeorefResult FloorSoundings(survey::SoundingView view) {
    georef::GeorefResult r;
    r.world_origin = {40.4435, -7.7806, 412.0};
    georef::GeorefPing ping;
    ping.utime_gps = 1'400'000'000'000'000;
    r.pings = {ping, ping};
    r.pings[1].utime_gps += 100'000;
    const auto add = [&](Eigen::Vector3d p, std::uint32_t k, std::uint16_t beam, int status) {
        r.points.position_world.push_back(p);
        r.points.ping.push_back(k);
        r.points.beam.push_back(beam);
        r.points.range_m.push_back(static_cast<float>(-p.z()));
        r.points.angle_rad.push_back(0.0f);
        if (view != survey::SoundingView::kAccepted) {
            r.points.status.push_back(static_cast<std::uint8_t>(status));
        }
    };
    using S = survey::SoundingStatus;
    if (view == survey::SoundingView::kAccepted) {
        std::uint16_t b = 0;
        for (const double x : {0.5, 1.5, 2.5, 3.5}) {
            for (const double y : {0.5, 1.5, 2.5, 3.5}) {
                add({x, y, -10.0 + 0.01 * b}, b % 2, b, 0);
                ++b;
            }
        }
    } else {
        add({0.7, 0.7, -6.0}, 0, 40, static_cast<int>(S::kFreeSpace));  // fish above the floor
        add({1.2, 3.1, -14.0}, 1, 41, static_cast<int>(S::kSpike));     // below the floor
        add({5.0, 1.0, -15.0}, 1, 42, static_cast<int>(S::kManual));    // a cell beside the floor
        add({40, 40, -20.0}, 0, 43, static_cast<int>(S::kMultipath));   // no floor near: reason
        add({40, 44, -20.0}, 0, 44, static_cast<int>(S::kCluster));     // no floor near: reason
    }
    return r;
}

TEST(LasNoise, BelowTheLocalAcceptedMedianIsLowNoiseAboveIsHighNoise) {
    const auto a = FloorSoundings(survey::SoundingView::kAccepted);
    const auto r = FloorSoundings(survey::SoundingView::kRejected);
    const std::vector<std::uint8_t> c = LasNoiseClasses(a.points, r.points);
    ASSERT_EQ(c.size(), 5u);
    EXPECT_EQ(c[0], kLasClassHighNoise) << "above its cell's floor";
    EXPECT_EQ(c[1], kLasClassLowNoise) << "below its cell's floor";
    EXPECT_EQ(c[2], kLasClassLowNoise) << "below the neighbouring cells' floor";
    EXPECT_EQ(c[3], kLasClassLowNoise) << "no floor near: multipath lies behind a surface";
    EXPECT_EQ(c[4], kLasClassHighNoise) << "no floor near: any other reason";
    // Relative to the local surface, not an absolute height: a floor at -20 makes -14 high.
    auto deep = a;
    for (auto& p : deep.points.position_world) p.z() = -20;
    EXPECT_EQ(LasNoiseClasses(deep.points, r.points)[1], kLasClassHighNoise);
}

TEST_F(ProductReaders, PointFilesCarryTheRejectedSoundingsWithTheirStatus) {
    const auto a = FloorSoundings(survey::SoundingView::kAccepted);
    const auto r = FloorSoundings(survey::SoundingView::kRejected);
    const std::size_t na = a.points.size(), nr = r.points.size();
    // PLY: the accepted soundings first (status 0), then the rejected with their codes; THU and
    // TVU NaN for the rejected.
    PointExtras x;
    x.thu_95_m.assign(na, 0.1f);
    x.tvu_95_m.assign(na, 0.2f);
    const std::string ply = (dir_ / "points.ply").string();
    ASSERT_TRUE(WritePly(ply, a, &x, "", &r));
    const auto m = formats::ply::ReadMesh(ply, {"status", "thu_95_m", "gps_time_s", "beam"});
    ASSERT_TRUE(m) << m.error().message;
    ASSERT_EQ(m->vertices.size(), na + nr);
    for (std::size_t j = 0; j < na + nr; ++j) {
        const bool accepted = j < na;
        const double status = m->vertex_properties[0][j];
        EXPECT_EQ(status, accepted ? 0.0 : static_cast<double>(r.points.status[j - na])) << j;
        EXPECT_EQ(std::isnan(m->vertex_properties[1][j]), !accepted) << j;
        const auto& src = accepted ? a : r;
        const std::size_t i = accepted ? j : j - na;
        EXPECT_NEAR((m->vertices[j] - src.points.position_world[i]).norm(), 0, 1e-5) << j;
        EXPECT_EQ(m->vertex_beam[j], src.points.beam[i]) << j;
        EXPECT_DOUBLE_EQ(m->vertex_properties[2][j],
                         static_cast<double>(src.pings[src.points.ping[i]].utime_gps) * 1e-6);
    }
    bool names = false;
    for (const auto& c : m->comments) {
        names = names || (c.find("3 spike") != std::string::npos &&
                          c.find("6 free_space") != std::string::npos &&
                          c.find("9 manual") != std::string::npos);
    }
    EXPECT_TRUE(names) << "a comment names the codes";
    // Without the rejected view: the accepted soundings only, all status 0.
    ASSERT_TRUE(WritePly(ply, a));
    const auto only = formats::ply::ReadMesh(ply, {"status"});
    ASSERT_TRUE(only) << only.error().message;
    ASSERT_EQ(only->vertices.size(), na);
    for (double s : only->vertex_properties[0]) EXPECT_EQ(s, 0.0);

    // LAS: class 40 for the accepted, 7 or 18 withheld for the rejected, in the same order.
    const auto utm = georef::ToUtm(a);
    ASSERT_TRUE(utm) << utm.error().message;
    const std::string las = (dir_ / "points.las").string();
    ASSERT_TRUE(WriteLas(las, a, *utm, &x, "", &r));
    const std::vector<std::uint8_t> b = ReadBytes(las);
    auto u16 = [&](std::size_t at) { return static_cast<unsigned>(b[at] | (b[at + 1] << 8)); };
    auto u32 = [&](std::size_t at) {
        return static_cast<std::uint32_t>(u16(at) | (u16(at + 2) << 16));
    };
    std::uint64_t count = 0;
    std::memcpy(&count, &b[247], 8);
    ASSERT_EQ(count, na + nr) << "number of point records";
    const std::size_t rec_len = u16(105), first = u32(96);
    ASSERT_EQ(rec_len, 38u);
    ASSERT_EQ(b.size(), first + rec_len * (na + nr));
    const std::vector<std::uint8_t> noise = LasNoiseClasses(a.points, r.points);
    const double sz = [&] {
        double v;
        std::memcpy(&v, &b[131 + 16], 8);
        return v;
    }();
    const double oz = [&] {
        double v;
        std::memcpy(&v, &b[131 + 40], 8);
        return v;
    }();
    double min_z = 0;
    std::memcpy(&min_z, &b[131 + 88], 8);
    EXPECT_LT(min_z, -15.0 + 412.0 + 0.01) << "the bounds hold the rejected soundings";
    for (std::size_t j = 0; j < na + nr; ++j) {
        const std::size_t at = first + rec_len * j;
        const bool accepted = j < na;
        EXPECT_EQ(b[at + 15] & kLasFlagWithheld, accepted ? 0 : kLasFlagWithheld) << j;
        EXPECT_EQ(b[at + 16], accepted ? kLasClassBathymetry : noise[j - na]) << j;
        float thu;
        std::memcpy(&thu, &b[at + 30], 4);
        EXPECT_EQ(std::isnan(thu), !accepted) << j;
        std::int32_t z;
        std::memcpy(&z, &b[at + 8], 4);
        const double h = accepted ? utm->easting_northing_height[j].z()
                                  : 412.0 + r.points.position_world[j - na].z();
        EXPECT_NEAR(z * sz + oz, h, accepted ? 1e-3 : 0.01) << j;
    }
}

// Issue 38: the soundings placed in UTM one at a time (georef::UtmProjection) are ToUtm's points
// bit for bit, and points.las written from the projection is the file written from the held
// points, byte for byte; a projection of other pings is refused.
TEST_F(ProductReaders, LasFromTheUtmProjectionIsTheFileOfTheHeldPoints) {
    const auto a = FloorSoundings(survey::SoundingView::kAccepted);
    const auto r = FloorSoundings(survey::SoundingView::kRejected);
    const auto held = georef::ToUtm(a);
    ASSERT_TRUE(held) << held.error().message;
    const auto projection = georef::UtmProjectionOf(a);
    ASSERT_TRUE(projection) << projection.error().message;
    EXPECT_EQ(projection->zone, held->zone);
    EXPECT_EQ(projection->epsg, held->epsg);
    EXPECT_EQ(projection->sensor_utm.size(), a.pings.size());
    for (std::size_t j = 0; j < a.points.size(); ++j) {
        const Eigen::Vector3d p = projection->At(a, j);
        for (int k = 0; k < 3; ++k) EXPECT_EQ(p[k], held->easting_northing_height[j][k]) << j;
    }
    PointExtras x;
    x.thu_95_m.assign(a.points.size(), 0.1f);
    x.tvu_95_m.assign(a.points.size(), 0.2f);
    const std::string from_held = (dir_ / "held.las").string();
    const std::string from_projection = (dir_ / "projected.las").string();
    ASSERT_TRUE(WriteLas(from_held, a, *held, &x, "", &r));
    ASSERT_TRUE(WriteLas(from_projection, a, *projection, &x, "", &r));
    const auto bytes = ReadBytes(from_projection);
    ASSERT_GT(bytes.size(), 375u);
    EXPECT_EQ(bytes, ReadBytes(from_held));
    auto fewer = *projection;
    fewer.sensor_utm.pop_back();
    const auto refused = WriteLas(from_projection, a, fewer);
    ASSERT_FALSE(refused);
    EXPECT_NE(refused.error().message.find("not of these soundings"), std::string::npos)
        << refused.error().message;
}

// points_utm.ply made a block at a time is the file of the held points whatever the block size
// (1, one short of the points, the points, more than the points); the points are asked for in
// order, each once, in blocks no larger than asked; blocks of 0 points are refused.
TEST_F(ProductReaders, ProjectedPointsInBlocksAreTheFileOfTheHeldPoints) {
    ProjectedPoints held;
    held.crs_name = "WGS 84 / UTM zone 29N + EGM96 height";
    held.horizontal_epsg = 32629;
    held.vertical_epsg = 5773;
    std::mt19937 rng(38);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const std::size_t n = 1001;
    for (std::size_t j = 0; j < n; ++j) {
        held.positions.emplace_back(
            600000.0 + 300 * u(rng), 4470000.0 + 300 * u(rng), 380.0 + 30 * u(rng));
        held.gps_time_s.push_back(1.4e9 + 0.1 * static_cast<double>(j));
        held.status.push_back(static_cast<std::uint8_t>(j % 11));
    }
    const std::string whole = (dir_ / "whole.ply").string();
    ASSERT_TRUE(WriteProjectedPointsPly(whole, held, nullptr, "run"));
    const auto expected = ReadBytes(whole);
    ASSERT_GT(expected.size(), n * 33);
    for (const std::size_t block : {std::size_t{1}, n - 1, n, n + 7}) {
        std::size_t next = 0;
        bool ordered = true;
        const auto fill = [&](std::size_t first, std::span<ProjectedPoint> out) {
            ordered = ordered && first == next && out.size() <= block && !out.empty();
            next = first + out.size();
            for (std::size_t k = 0; k < out.size(); ++k) {
                out[k] = {
                    held.positions[first + k], held.gps_time_s[first + k], held.status[first + k]};
            }
        };
        const std::string path = (dir_ / "blocks.ply").string();
        ASSERT_TRUE(WriteProjectedPointsPly(path, held, n, block, fill, nullptr, "run"));
        EXPECT_TRUE(ordered) << "block " << block;
        EXPECT_EQ(next, n) << "block " << block;
        EXPECT_EQ(ReadBytes(path), expected) << "block " << block;
    }
    const auto none = [](std::size_t, std::span<ProjectedPoint>) {};
    const auto zero = WriteProjectedPointsPly((dir_ / "zero.ply").string(), held, n, 0, none);
    ASSERT_FALSE(zero);
    EXPECT_NE(zero.error().message.find("blocks of 0 points"), std::string::npos);
}

// 40 pings of 121 beams over a sloping floor, with 83P intensities: the accepted view, its
// pings (`series`) and, beside it, FloorSoundings' rejected soundings on the same two first
// pings' times.
georef::GeorefResult ManySoundings(survey::PingSeries& series) {
    georef::GeorefResult r;
    r.world_origin = {40.4435, -7.7806, 412.0};
    for (std::uint32_t k = 0; k < 40; ++k) {
        survey::PingHeader h;
        h.utime_gps = 1'400'000'000'000'000 + k * 100'000;
        h.beam_offset = static_cast<std::uint32_t>(series.range_counts.size());
        h.num_beams = 121;
        series.pings.push_back(h);
        georef::GeorefPing ping;
        ping.utime_gps = h.utime_gps;
        ping.header_index = k;
        ping.sensor_world = Eigen::Vector3d(0.3 * k, 0.0, -0.5);
        r.pings.push_back(ping);
        for (std::uint16_t b = 0; b < 121; ++b) {
            series.range_counts.push_back(1000u + b);
            series.intensities.push_back(static_cast<std::uint16_t>(7 * k + b));
            if ((k + b) % 13 == 0) continue;  // a beam georef dropped
            const double a = frames::DegToRad(-60.0 + b);
            r.points.position_world.emplace_back(
                0.3 * k + 0.01 * b, 10.0 * std::tan(a), -10.0 - 0.02 * b + 1e-3 * std::sin(k));
            r.points.ping.push_back(k);
            r.points.beam.push_back(b);
            r.points.range_m.push_back(static_cast<float>(10.0 / std::cos(a)));
            r.points.angle_rad.push_back(static_cast<float>(a));
        }
    }
    return r;
}

// Decisions 035, 041: points.ply and points.las written from the view's file a block at a
// time (PointBlocks over SpilledPoints::ReadBlock) are the files of the held view, byte for byte,
// whatever the block; a file that cannot be read is an error and leaves no product.
TEST_F(ProductReaders, PointFilesFromBlocksOfTheViewsFileAreTheHeldViewsFiles) {
    survey::PingSeries series;
    const georef::GeorefResult a = ManySoundings(series);
    ASSERT_TRUE(series.has_intensities());
    const auto r = FloorSoundings(survey::SoundingView::kRejected);
    const auto utm = georef::UtmProjectionOf(a);
    ASSERT_TRUE(utm);
    PointExtras x;
    x.pings = &series;
    const std::string held_ply = (dir_ / "held.ply").string();
    const std::string held_las = (dir_ / "held.las").string();
    ASSERT_TRUE(WritePly(held_ply, a, &x, "0123456789abcdef0123456789abcdef", &r));
    ASSERT_TRUE(WriteLas(held_las, a, *utm, &x, "0123456789abcdef0123456789abcdef", &r));
    georef::GeorefPoints points = a.points;
    auto spilled = SpilledPoints::Spill(points, (dir_ / ".partial-view_points").string());
    ASSERT_TRUE(spilled) << spilled.error().message;
    georef::GeorefResult pings_only = a;
    pings_only.points = georef::GeorefPoints{};
    const std::size_t n = a.points.size();
    // The blocks as the pipeline lends them (ViewPointBlocks): each read from the file into the
    // survey's points while a writer reads it.
    const auto from_file = [&](std::size_t block, std::size_t& asked) {
        PointBlocks blocks;
        blocks.count = n;
        blocks.for_each =
            [&, block](const std::function<Status(const georef::GeorefResult&, std::size_t)>& fn) {
                georef::GeorefResult lent = pings_only;
                for (std::size_t first = 0; first < n; first += block) {
                    const std::size_t count = std::min(block, n - first);
                    asked += count;
                    if (auto st = spilled->ReadBlock(first, count, lent.points); !st) return st;
                    if (auto st = fn(lent, first); !st) return st;
                }
                return Status{Ok{}};
            };
        return blocks;
    };
    for (const std::size_t block : {std::size_t{1}, std::size_t{977}, n + 3}) {
        std::size_t asked = 0;
        const PointBlocks blocks = from_file(block, asked);
        const std::string ply = (dir_ / "blocks.ply").string();
        const std::string las = (dir_ / "blocks.las").string();
        ASSERT_TRUE(WritePly(ply, pings_only, blocks, &x, "0123456789abcdef0123456789abcdef", &r));
        ASSERT_TRUE(WriteLas(
            las, pings_only, blocks, *utm, &x, "0123456789abcdef0123456789abcdef", &r, nullptr));
        EXPECT_GE(asked, 2 * n) << "PLY once, LAS at least once more";
        EXPECT_EQ(ReadBytes(ply), ReadBytes(held_ply)) << block;
        EXPECT_EQ(ReadBytes(las), ReadBytes(held_las)) << block;
    }
    PointBlocks gone;
    gone.count = n;
    gone.for_each = [](const std::function<Status(const georef::GeorefResult&, std::size_t)>&) {
        return Status{Error{"P/.partial-view_points: cannot read a block of the view's points"}};
    };
    const std::string ply = (dir_ / "failed.ply").string();
    const std::string las = (dir_ / "failed.las").string();
    const Status p = WritePly(ply, pings_only, gone, &x, "", nullptr);
    ASSERT_FALSE(p);
    EXPECT_NE(p.error().message.find(".partial-view_points"), std::string::npos);
    EXPECT_FALSE(WriteLas(las, pings_only, gone, *utm, &x, "", &r, nullptr));
    EXPECT_FALSE(fs::exists(ply));
    EXPECT_FALSE(fs::exists(las));
}

}  // namespace
}  // namespace pitmap::proc::io
