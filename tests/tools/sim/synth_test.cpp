// SPDX-License-Identifier: MIT
// A short synthetic survey, read back as the processor would: every ping and every NovAtel
// frame is in the log exactly once, the raw streams decode with no error, and the soundings,
// placed with the true trajectory and boresight, lie on the true terrain within the noise.
#include "tools/sim/synth.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "pitmap/ins_pva_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "tools/sim/truth_io.hpp"

namespace pitmap::sim {
namespace {

namespace fs = std::filesystem;

class Synth : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = new fs::path(fs::path(::testing::TempDir()) /
                            ("pitmap_synth_" + std::to_string(::getpid())));
        fs::remove_all(*dir_);
        scenario_ = new ScenarioConfig(*BuiltinScenario("demo"));
        scenario_->track.duration_s = 12.0;  // 120 pings
        SynthOptions opt;
        opt.out_dir = dir_->string();
        opt.rotate_bytes = 1 << 20;  // force several log segments
        auto r = RunSynth(*scenario_, opt);
        ASSERT_TRUE(r.ok()) << r.error().message;
        result_ = new SynthResult(*r);
    }
    static void TearDownTestSuite() {
        fs::remove_all(*dir_);
        delete dir_;
        delete scenario_;
        delete result_;
    }
    static std::vector<fs::path> Logs() {
        std::vector<fs::path> logs;
        for (const auto& e : fs::directory_iterator(*dir_ / "log"))
            if (e.path().extension() == ".lcmlog") logs.push_back(e.path());
        std::sort(logs.begin(), logs.end());
        return logs;
    }
    static fs::path* dir_;
    static ScenarioConfig* scenario_;
    static SynthResult* result_;
};
fs::path* Synth::dir_ = nullptr;
ScenarioConfig* Synth::scenario_ = nullptr;
SynthResult* Synth::result_ = nullptr;

TEST_F(Synth, EveryFrameAndPingIsLoggedOnceInTimeOrder) {
    ASSERT_EQ(result_->pings, 120);
    const auto logs = Logs();
    EXPECT_GE(logs.size(), 2u);  // rotated
    EXPECT_EQ(static_cast<int>(logs.size()), result_->log_files);
    std::map<std::string, int> per_channel;
    std::vector<std::uint8_t> novatel_stream;
    std::int64_t last_utime = 0, expect_seq = 0, expect_ping = 0;
    std::int64_t pva = 0;
    for (const auto& path : logs) {
        lcm::LogFile log(path.string(), "r");
        ASSERT_TRUE(log.good());
        while (const lcm::LogEvent* ev = log.readNextEvent()) {
            EXPECT_GE(ev->timestamp, last_utime);
            last_utime = ev->timestamp;
            ++per_channel[ev->channel];
            if (ev->channel == "RAW_NOVATEL_COM1") {
                raw_bytes_t raw;
                ASSERT_GT(raw.decode(ev->data, 0, ev->datalen), 0);
                EXPECT_EQ(raw.seq, expect_seq++);
                EXPECT_EQ(raw.protocol, "novatel");
                novatel_stream.insert(novatel_stream.end(), raw.data.begin(), raw.data.end());
            } else if (ev->channel == "MULTIBEAM_PING_DELTAT_UDP") {
                multibeam_ping_t ping;
                ASSERT_GT(ping.decode(ev->data, 0, ev->datalen), 0);
                EXPECT_EQ(ping.ping_number, expect_ping++);
                EXPECT_EQ(ping.num_beams, 480);
                EXPECT_EQ(ping.format_version, 10);
                EXPECT_NE(ping.utime_gps, 0);
            } else if (ev->channel == "INS_PVA_NOVATEL_COM1") {
                ins_pva_t m;
                ASSERT_GT(m.decode(ev->data, 0, ev->datalen), 0);
                ++pva;
            }
        }
    }
    EXPECT_EQ(per_channel["RAW_DELTAT_UDP"], 120);
    EXPECT_EQ(per_channel["MULTIBEAM_PING_DELTAT_UDP"], 120);
    EXPECT_EQ(pva, 12 * 50 + 12);  // INSPVAS at 50 Hz + INSPVAX at 1 Hz
    EXPECT_EQ(per_channel["IMU_NOVATEL_COM1"], 12 * 200);
    EXPECT_EQ(per_channel["GNSS_POSITION_NOVATEL_COM1"], 12);
    // The raw serial stream frames completely: every frame the receiver emitted, no skipped byte.
    EXPECT_EQ(static_cast<std::int64_t>(novatel_stream.size()), result_->novatel_bytes);
    protocol::novatel::Framer framer;
    framer.Push(novatel_stream);
    std::int64_t frames = 0;
    while (true) {
        auto ev = framer.Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        ASSERT_FALSE(std::holds_alternative<protocol::Skipped>(ev));
        ++frames;
    }
    EXPECT_FALSE(framer.Flush().has_value());
    EXPECT_EQ(frames, result_->novatel_frames);
    EXPECT_TRUE(fs::exists(*dir_ / "log" / "vehicle.yaml"));
}

TEST_F(Synth, SoundingsLieOnTheTrueTerrainWithTheTruePoses) {
    auto truth = ReadTruth((*dir_ / "truth").string());
    ASSERT_TRUE(truth.ok()) << truth.error().message;
    // The insonified area is recorded for the mesh completeness score.
    ASSERT_EQ(truth->coverage.size(), truth->terrain.height_m.size());
    EXPECT_GT(std::count(truth->coverage.begin(), truth->coverage.end(), 1), 10000);
    const PitWorld world(truth->terrain);
    const auto& b = truth->boresight;
    const Pose T_vehicle_sonar = MakePose(
        frames::RotationNedFromRpy(frames::DegToRad(b.roll_deg),
                                   frames::DegToRad(b.pitch_deg),
                                   frames::DegToRad(b.yaw_deg)),
        Eigen::Vector3d(b.lever_arm_sonar_m[0], b.lever_arm_sonar_m[1], b.lever_arm_sonar_m[2]));
    std::vector<double> residuals;
    for (const auto& path : Logs()) {
        lcm::LogFile log(path.string(), "r");
        while (const lcm::LogEvent* ev = log.readNextEvent()) {
            if (ev->channel != "MULTIBEAM_PING_DELTAT_UDP") continue;
            multibeam_ping_t ping;
            ASSERT_GT(ping.decode(ev->data, 0, ev->datalen), 0);
            auto T_wv =
                InterpolateTruth(truth->trajectory, static_cast<double>(ping.utime_gps) * 1e-6);
            ASSERT_TRUE(T_wv.ok());
            const Pose T_ws = *T_wv * T_vehicle_sonar;
            for (int i = 0; i < ping.num_beams; ++i) {
                const int c = ping.range_counts[static_cast<std::size_t>(i)];
                if (c == 0) continue;
                const double r = c * ping.range_resolution_m;
                const double th =
                    frames::DegToRad(ping.start_angle_deg + i * ping.angle_increment_deg);
                const Eigen::Vector3d p =
                    T_ws * Eigen::Vector3d(0, r * std::sin(th), r * std::cos(th));
                residuals.push_back(std::abs(world.SignedDistance(p)));
            }
        }
    }
    ASSERT_GT(residuals.size(), 120u * 300u);
    std::sort(residuals.begin(), residuals.end());
    const double median = residuals[residuals.size() / 2];
    const double p90 = residuals[residuals.size() * 9 / 10];
    // Range noise at 5-15 m: sigma = 0.2 % r + 2 cm, about 3 cm; median |N(0, s)| = 0.67 s.
    EXPECT_LT(median, 0.04);
    EXPECT_GT(median, 0.005);  // the noise is really there
    EXPECT_LT(p90, 0.12);      // outliers (2 %) stay above p90
}

}  // namespace
}  // namespace pitmap::sim
