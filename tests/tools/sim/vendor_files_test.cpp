// SPDX-License-Identifier: MIT
// The quarry survey as the instruments' own software records it (synth --vendor-files): the
// NovAtel .gps stream and the .83P file frame with no skipped byte and hold exactly the bytes
// of the log's raw channels; the 83P headers carry the topside clock as truth/sonar_clock.json
// states it, the stale NMEA position of the GNSS antenna (at the fix epochs, not at the pings),
// speed and course, HDT heading and the head's own pitch/roll; v1.00 keeps working.
#include <gtest/gtest.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "common/frames.hpp"
#include "common/geodesy.hpp"
#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/deltat/stream_framer.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "common/vehicle.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "tools/sim/synth.hpp"
#include "tools/sim/truth_io.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {
namespace {

namespace fs = std::filesystem;
namespace dt = protocol::deltat;

std::vector<std::uint8_t> ReadAll(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Every record of a .83P file, framed as the processor frames it; counts skipped bytes.
std::vector<std::vector<std::uint8_t>> Frame83P(const std::vector<std::uint8_t>& file,
                                                std::size_t& skipped) {
    dt::StreamFramer framer;
    framer.Push(file);
    std::vector<std::vector<std::uint8_t>> records;
    skipped = 0;
    const auto drain = [&] {
        while (true) {
            auto ev = framer.Next();
            if (std::holds_alternative<protocol::NeedMore>(ev)) break;
            if (auto* s = std::get_if<protocol::Skipped>(&ev)) {
                skipped += s->bytes;
                continue;
            }
            const auto& r = std::get<dt::Record>(ev);
            records.emplace_back(r.bytes.begin(), r.bytes.end());
        }
    };
    drain();
    while (auto s = framer.Flush()) {
        skipped += s->bytes;
        drain();
    }
    return records;
}

struct SynthRun {
    fs::path dir;
    ScenarioConfig scenario;
    SynthResult result;
};

SynthRun Synthesize(const std::string& tag, const ScenarioConfig& sc) {
    SynthRun run;
    run.dir = fs::path(::testing::TempDir()) /
              ("pitmap_vendor_" + tag + "_" + std::to_string(::getpid()));
    fs::remove_all(run.dir);
    run.scenario = sc;
    SynthOptions opt;
    opt.out_dir = run.dir.string();
    opt.vendor_files = true;
    auto r = RunSynth(sc, opt);
    EXPECT_TRUE(r.ok()) << r.error().message;
    if (r.ok()) run.result = *r;
    return run;
}

class VendorFiles : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        ScenarioConfig sc = *BuiltinScenario("quarry");
        sc.track.duration_s = 40.0;  // 400 pings: along the high wall on the north side
        run_ = new SynthRun(Synthesize("quarry", sc));
        auto truth = ReadTruth((run_->dir / "truth").string());
        ASSERT_TRUE(truth.ok()) << truth.error().message;
        truth_ = new Truth(*truth);
    }
    static void TearDownTestSuite() {
        fs::remove_all(run_->dir);
        delete run_;
        delete truth_;
    }
    static fs::path Vendor(const char* ext) {
        return run_->dir / "vendor" / (run_->scenario.name + ext);
    }
    // The raw channel's payloads in log order.
    static std::vector<std::vector<std::uint8_t>> RawChannel(const std::string& channel) {
        std::vector<fs::path> logs;
        for (const auto& e : fs::directory_iterator(run_->dir / "log"))
            if (e.path().extension() == ".lcmlog") logs.push_back(e.path());
        std::sort(logs.begin(), logs.end());
        std::vector<std::vector<std::uint8_t>> out;
        for (const auto& path : logs) {
            lcm::LogFile log(path.string(), "r");
            while (const lcm::LogEvent* ev = log.readNextEvent()) {
                if (ev->channel != channel) continue;
                raw_bytes_t raw;
                if (raw.decode(ev->data, 0, ev->datalen) <= 0) continue;
                out.emplace_back(raw.data.begin(), raw.data.end());
            }
        }
        return out;
    }
    static SynthRun* run_;
    static Truth* truth_;
};
SynthRun* VendorFiles::run_ = nullptr;
Truth* VendorFiles::truth_ = nullptr;

TEST_F(VendorFiles, GpsFileIsTheReceiverStreamAndFramesWithNoSkippedByte) {
    const auto file = ReadAll(Vendor(".gps"));
    ASSERT_EQ(static_cast<std::int64_t>(file.size()), run_->result.vendor_gps_bytes);
    ASSERT_GT(file.size(), 100000u);
    std::vector<std::uint8_t> logged;
    for (const auto& chunk : RawChannel("RAW_NOVATEL_COM1"))
        logged.insert(logged.end(), chunk.begin(), chunk.end());
    EXPECT_TRUE(file == logged) << "the .gps file differs from the serial stream in the log";
    protocol::novatel::Framer framer;
    framer.Push(file);
    std::int64_t frames = 0, skipped = 0;
    while (true) {
        auto ev = framer.Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (auto* s = std::get_if<protocol::Skipped>(&ev)) {
            skipped += static_cast<std::int64_t>(s->bytes);
            continue;
        }
        ++frames;
    }
    while (auto s = framer.Flush()) skipped += static_cast<std::int64_t>(s->bytes);
    EXPECT_EQ(skipped, 0);
    EXPECT_EQ(frames, run_->result.novatel_frames);
}

// The vehicle file beside the vendor files, as beside the logs: schema 1, the scenario's lever
// arms, the sonar clock offset left unknown (the processor finds or is given it).
TEST_F(VendorFiles, VehicleFileBesideThemIsTheSchemaWithTheClockOffsetUnknown) {
    const auto v = ReadVehicleFile((run_->dir / "vendor" / "vehicle.yaml").string());
    ASSERT_TRUE(v) << v.error().message;
    const auto& arm = run_->scenario.lever_arms.sonar_m;
    EXPECT_EQ(v->sonar_lever_arm_m, Eigen::Vector3d(arm[0], arm[1], arm[2]));
    EXPECT_FALSE(v->sonar_clock_offset_s.has_value());
}

TEST_F(VendorFiles, File83PHoldsEveryDatagramAndFramesWithNoSkippedByte) {
    const auto file = ReadAll(Vendor(".83P"));
    ASSERT_EQ(static_cast<std::int64_t>(file.size()), run_->result.vendor_83p_bytes);
    std::size_t skipped = 0;
    const auto records = Frame83P(file, skipped);
    EXPECT_EQ(skipped, 0u);
    ASSERT_EQ(static_cast<std::int64_t>(records.size()), run_->result.pings);
    const auto datagrams = RawChannel("RAW_DELTAT_UDP");
    ASSERT_EQ(datagrams.size(), records.size());
    for (std::size_t i = 0; i < records.size(); ++i) ASSERT_TRUE(records[i] == datagrams[i]) << i;
}

TEST_F(VendorFiles, TruthGridHoldsTheQuarryFeaturesAndTheSonarSeesTheHighWall) {
    const PitWorld world(run_->scenario.pit, run_->scenario.seed);
    EXPECT_EQ(world.boulders().size(), 36u);
    const TerrainGrid& g = truth_->terrain;
    ASSERT_TRUE(g.height_m == world.grid().height_m);  // boulders, ramp, wall: all in truth
    // Insonified cells steeper than 60 deg over a 1 m baseline (the high wall).
    const int k = static_cast<int>(std::lround(0.5 / g.resolution_m));
    const double tan60 = std::tan(60.0 * 3.14159265358979323846 / 180.0);
    double seen_m2 = 0;
    for (int iy = k; iy + k < g.ny; ++iy) {
        for (int ix = k; ix + k < g.nx; ++ix) {
            const auto at = [&](int x, int y) {
                return g.height_m[static_cast<std::size_t>(y) * static_cast<std::size_t>(g.nx) +
                                  static_cast<std::size_t>(x)];
            };
            const double gx = (at(ix + k, iy) - at(ix - k, iy)) / (2 * k * g.resolution_m);
            const double gy = (at(ix, iy + k) - at(ix, iy - k)) / (2 * k * g.resolution_m);
            const std::size_t i = static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                                  static_cast<std::size_t>(ix);
            if (std::hypot(gx, gy) > tan60 && at(ix, iy) < -1.0 && truth_->coverage[i])
                seen_m2 += g.resolution_m * g.resolution_m;
        }
    }
    EXPECT_GT(seen_m2, 40.0);
}

// Decoded pings of a .83P file.
std::vector<dt::Ping83P> DecodeFile(const fs::path& path) {
    std::size_t skipped = 0;
    std::vector<dt::Ping83P> pings;
    dt::FloatOrderMemory memory;
    for (const auto& rec : Frame83P(ReadAll(path), skipped)) {
        auto d = dt::DecodeRecord83P(rec, memory);
        EXPECT_TRUE(std::holds_alternative<dt::Ping83P>(d));
        if (auto* p = std::get_if<dt::Ping83P>(&d)) pings.push_back(*p);
    }
    return pings;
}

// GPS time of a ping's interrogation by the convention truth/sonar_clock.json states:
// header time (as UTC, moved to the GPS epoch and time scale with GPS - UTC) - offset(t).
double GpsFromHeader(const dt::Ping83P& p, const SonarClockTruth& c, double t) {
    const std::int64_t header_gps_scale = GpsFromUnix(p.utime_sonar_header, c.gps_minus_utc_s);
    return static_cast<double>(header_gps_scale) * 1e-6 - (c.offset_s + c.drift_ppm * 1e-6 * t);
}

TEST_F(VendorFiles, HeaderTimeIsTheTopsideClockAsTruthStatesIt) {
    ASSERT_TRUE(truth_->sonar_clock.has_value());
    const SonarClockTruth& c = *truth_->sonar_clock;
    EXPECT_DOUBLE_EQ(c.offset_s, 2.350);
    EXPECT_DOUBLE_EQ(c.header_resolution_s, 0.001);
    const auto pings = DecodeFile(Vendor(".83P"));
    ASSERT_EQ(pings.size(), 400u);
    for (const auto& p : pings) {
        const double t_int = static_cast<double>(p.ping_number) / 10.0 - c.ping_latency_s;
        const double late = c.survey_start_gps_s + t_int - GpsFromHeader(p, c, t_int);
        EXPECT_GE(late, -1e-6) << p.ping_number;  // truncated to the millisecond
        EXPECT_LT(late, c.header_resolution_s + 1e-6) << p.ping_number;
    }
}

TEST_F(VendorFiles, HeaderPositionIsTheStaleAntennaFixNotThePingPosition) {
    const SonarClockTruth& c = *truth_->sonar_clock;
    const SonarConfig& so = run_->scenario.sonar;
    ASSERT_TRUE(c.nmea_position);
    const LocalTangentFrame enu(truth_->origin);
    const auto& la = run_->scenario.lever_arms.antenna_m;
    const Eigen::Vector3d lever(la[0], la[1], la[2]);
    const auto antenna_at = [&](double t) {
        auto T = InterpolateTruth(truth_->trajectory, c.survey_start_gps_s + t);
        EXPECT_TRUE(T.ok());
        return Eigen::Vector3d(*T * lever);
    };
    int blank = 0, checked = 0;
    double sum2_fix = 0, sum_ping = 0;
    for (const auto& p : DecodeFile(Vendor(".83P"))) {
        const double t_int =
            static_cast<double>(p.ping_number) / so.ping_rate_hz - c.ping_latency_s;
        const double since = t_int - c.nmea_latency_s;
        if (since < 0) {  // no fix received yet: blank position, zero speed
            EXPECT_TRUE(std::isnan(p.latitude_deg)) << p.ping_number;
            EXPECT_TRUE(std::isnan(p.longitude_deg)) << p.ping_number;
            ++blank;
            continue;
        }
        ASSERT_TRUE(std::isfinite(p.latitude_deg)) << p.ping_number;
        const double t_fix =
            std::floor(since * c.nmea_position_rate_hz + 1e-9) / c.nmea_position_rate_hz;
        const Eigen::Vector3d fix = antenna_at(t_fix);
        const Eigen::Vector3d header =
            enu.ToEnu({p.latitude_deg, p.longitude_deg, truth_->origin.height_m + fix.z()});
        const double err_fix = (header - fix).head<2>().norm();
        EXPECT_LT(err_fix, 0.12) << p.ping_number;  // 0.02 m noise + 1e-5 min quantisation
        sum2_fix += err_fix * err_fix;
        sum_ping += (header - antenna_at(t_int)).head<2>().norm();
        // VTG: the antenna's speed and course at the same epoch.
        const Eigen::Vector3d v =
            (antenna_at(t_fix + 0.05) - antenna_at(std::max(0.0, t_fix - 0.05))) /
            (t_fix + 0.05 - std::max(0.0, t_fix - 0.05));
        EXPECT_NEAR(p.speed_over_ground_knots, v.head<2>().norm() / (1852.0 / 3600.0), 0.25)
            << p.ping_number;
        const double course = std::atan2(v.x(), v.y()) * 180 / 3.14159265358979323846;
        const double dc = std::remainder(p.course_over_ground_deg - course, 360.0);
        EXPECT_LT(std::abs(dc), 4.0) << p.ping_number;
        ++checked;
    }
    EXPECT_EQ(blank, 2);  // pings 0 and 1 go out before the first fix (0.15 s) arrives
    ASSERT_GT(checked, 390);
    EXPECT_LT(std::sqrt(sum2_fix / checked), 0.05);
    // Stale: at 1.5 m/s and 0.15-1.15 s of age, about a metre from the antenna at the ping.
    EXPECT_GT(sum_ping / checked, 0.5);
}

TEST_F(VendorFiles, HeaderAttitudeIsTheHeadsOwnAndHeadingTheStaleHdt) {
    const SonarClockTruth& c = *truth_->sonar_clock;
    const SonarConfig& so = run_->scenario.sonar;
    const auto& b = truth_->boresight;
    const Eigen::Matrix3d R_vehicle_sonar = frames::RotationNedFromRpy(
        frames::DegToRad(b.roll_deg), frames::DegToRad(b.pitch_deg), frames::DegToRad(b.yaw_deg));
    double sum_roll = 0, sum_pitch = 0, sum_heading = 0;
    int n = 0, headings = 0;
    for (const auto& p : DecodeFile(Vendor(".83P"))) {
        const double t_int =
            static_cast<double>(p.ping_number) / so.ping_rate_hz - c.ping_latency_s;
        ASSERT_TRUE(p.internal_pitch_valid && p.internal_roll_valid) << p.ping_number;
        EXPECT_FALSE(p.internal_heading_valid);
        auto T = InterpolateTruth(truth_->trajectory, c.survey_start_gps_s + std::max(0.0, t_int));
        ASSERT_TRUE(T.ok());
        const frames::Rpy head = frames::RpyFromRotationWorld(T->linear() * R_vehicle_sonar);
        const double droll = p.internal_roll_deg - frames::RadToDeg(head.roll);
        const double dpitch = p.internal_pitch_deg - frames::RadToDeg(head.pitch);
        EXPECT_LT(std::abs(droll), 0.3) << p.ping_number;
        EXPECT_LT(std::abs(dpitch), 0.3) << p.ping_number;
        sum_roll += droll;
        sum_pitch += dpitch;
        ++n;
        // HDT at 5 Hz, as stale as the position.
        const double since = t_int - c.nmea_latency_s;
        if (since < 0) {
            EXPECT_FALSE(p.external_valid(dt::kExternalHeadingValid)) << p.ping_number;
            continue;
        }
        ASSERT_TRUE(p.external_valid(dt::kExternalHeadingValid)) << p.ping_number;
        const double t_hdt =
            std::floor(since * c.nmea_heading_rate_hz + 1e-9) / c.nmea_heading_rate_hz;
        auto Th = InterpolateTruth(truth_->trajectory, c.survey_start_gps_s + t_hdt);
        ASSERT_TRUE(Th.ok());
        const double yaw = frames::RadToDeg(frames::RpyFromRotationWorld(Th->linear()).yaw);
        const double dh = std::remainder(p.external_heading_deg - yaw, 360.0);
        EXPECT_LT(std::abs(dh), 0.3) << p.ping_number;
        sum_heading += dh;
        ++headings;
    }
    ASSERT_EQ(n, 400);
    // The head's attitude includes the mount (0.6 deg roll, -0.4 deg pitch boresight).
    EXPECT_LT(std::abs(sum_roll / n), 0.05);
    EXPECT_LT(std::abs(sum_pitch / n), 0.05);
    EXPECT_GT(headings, 390);
    EXPECT_LT(std::abs(sum_heading / headings), 0.05);
}

TEST(VendorFilesV100, HeaderFieldsAndAClockOffsetOverrideInTheV100Layout) {
    ScenarioConfig sc = *BuiltinScenario("quarry");
    sc.track.duration_s = 3.0;
    sc.sonar.format_version = 0;
    sc.sonar.topside_clock_offset_s = -3600.25;  // a PC an hour behind, as synth's option sets
    const SynthRun run = Synthesize("v100", sc);
    auto truth = ReadTruth((run.dir / "truth").string());
    ASSERT_TRUE(truth.ok()) << truth.error().message;
    ASSERT_TRUE(truth->sonar_clock.has_value());
    const SonarClockTruth& c = *truth->sonar_clock;
    EXPECT_DOUBLE_EQ(c.offset_s, -3600.25);
    EXPECT_DOUBLE_EQ(c.header_resolution_s, 0.01);
    const auto pings = DecodeFile(run.dir / "vendor" / "quarry.83P");
    ASSERT_EQ(pings.size(), 30u);
    for (const auto& p : pings) {
        EXPECT_EQ(p.format_version, 0);
        const double t_int = static_cast<double>(p.ping_number) / 10.0 - c.ping_latency_s;
        const double late = c.survey_start_gps_s + t_int - GpsFromHeader(p, c, t_int);
        EXPECT_GE(late, -1e-6) << p.ping_number;
        EXPECT_LT(late, 0.01 + 1e-6) << p.ping_number;
        EXPECT_TRUE(p.internal_pitch_valid && p.internal_roll_valid);
        EXPECT_EQ(p.external_sensor_flags, 0);  // v1.00 has no external sensor fields
        if (p.ping_number >= 2) {
            EXPECT_TRUE(std::isfinite(p.latitude_deg)) << p.ping_number;
        }
    }
    fs::remove_all(run.dir);
}

}  // namespace
}  // namespace pitmap::sim
