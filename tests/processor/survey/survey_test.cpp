// SPDX-License-Identifier: MIT
// The survey model and its file (processor/survey): a round trip keeps every part; the state
// alone loads without the big sections; truncated, overwritten (20 seeds), crafted (right
// CRCs, wrong content) and foreign files are clear errors naming the file, in memory bounded by
// the file's size; the georeferencing view puts soundings on the trajectory version asked for;
// a calibration is undone exactly; the cleaning's flags round trip sparse, are checked, and a
// format-3 file (without them) still loads.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "common/peak_memory.hpp"
#include "common/protocol/novatel/crc32.hpp"
#include "processor/georef/survey_view.hpp"
#include "processor/survey/survey.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::survey {
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

// Where each section's payload starts in a survey file, by tag (the layout of survey_file.hpp).
struct SectionAt {
    std::size_t crc_at = 0;
    std::size_t payload_at = 0;
    std::size_t bytes = 0;
};
std::map<std::string, SectionAt> Sections(const std::vector<std::uint8_t>& b) {
    std::map<std::string, SectionAt> out;
    std::uint32_t count = 0;
    std::memcpy(&count, b.data() + 16, 4);
    std::size_t pos = 20;
    for (std::uint32_t i = 0; i < count && pos + 28 <= b.size(); ++i) {
        const std::string tag(reinterpret_cast<const char*>(b.data() + pos),
                              strnlen(reinterpret_cast<const char*>(b.data() + pos), 16));
        std::uint64_t n = 0;
        std::memcpy(&n, b.data() + pos + 16, 8);
        out[tag] = {pos + 24, pos + 28, static_cast<std::size_t>(n)};
        pos += 28 + n;
    }
    return out;
}

// Recomputes every section's CRC (a crafted file whose checksums are right, so that the
// structural checks behind them are exercised).
void FixCrcs(std::vector<std::uint8_t>& b) {
    for (const auto& [tag, s] : Sections(b)) {
        if (s.payload_at + s.bytes > b.size()) continue;
        const std::uint32_t crc = protocol::novatel::Crc32({b.data() + s.payload_at, s.bytes});
        std::memcpy(b.data() + s.crc_at, &crc, 4);
    }
}

// Offsets of the four arrays' u64 count fields in the ingest section's payload.
std::vector<std::size_t> IngestArrays(const std::vector<std::uint8_t>& b) {
    const SectionAt s = Sections(b).at("ingest");
    std::vector<std::size_t> at;
    std::size_t pos = s.payload_at + 8;  // leap seconds, ping clock
    for (int array = 0; array < 4; ++array) {
        at.push_back(pos);
        std::uint64_t count = 0, size = 0;
        std::memcpy(&count, b.data() + pos, 8);
        std::memcpy(&size, b.data() + pos + 8, 8);
        pos += 16 + count * size;
    }
    EXPECT_EQ(pos, s.payload_at + s.bytes) << "the layout walked is the file's";
    return at;
}

// The file as formats 1-4 held it: the ping records in PingHeader's old memory layout (112
// bytes: 7 bytes of padding after sound_speed_valid, 1 after aid_attitude_at_ping) instead of
// format 5's 104 bytes field by field.
std::vector<std::uint8_t> WithLegacyPings(const std::vector<std::uint8_t>& b) {
    const SectionAt s = Sections(b).at("ingest");
    const std::size_t pings_at = IngestArrays(b)[2];
    std::uint64_t count = 0, size = 0;
    std::memcpy(&count, b.data() + pings_at, 8);
    std::memcpy(&size, b.data() + pings_at + 8, 8);
    EXPECT_EQ(size, 104u);
    std::vector<std::uint8_t> out(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(pings_at));
    const std::uint64_t legacy = 112;
    out.insert(out.end(),
               b.begin() + static_cast<std::ptrdiff_t>(pings_at),
               b.begin() + static_cast<std::ptrdiff_t>(pings_at + 8));
    out.insert(out.end(),
               reinterpret_cast<const std::uint8_t*>(&legacy),
               reinterpret_cast<const std::uint8_t*>(&legacy) + 8);
    for (std::uint64_t i = 0; i < count; ++i) {
        const std::uint8_t* r = b.data() + pings_at + 16 + i * 104;
        out.insert(out.end(), r, r + 25);           // utime, ping number, speed, valid
        out.insert(out.end(), 7, std::uint8_t{0});  // padding
        out.insert(out.end(), r + 25, r + 64);      // resolution .. aid_attitude_at_ping
        out.push_back(0);                           // padding
        out.insert(out.end(), r + 64, r + 104);     // aid latitude .. heading
    }
    out.insert(
        out.end(), b.begin() + static_cast<std::ptrdiff_t>(pings_at + 16 + count * 104), b.end());
    const std::uint64_t bytes = s.bytes + count * 8;
    std::memcpy(out.data() + s.crc_at - 8, &bytes, 8);
    FixCrcs(out);
    return out;
}

std::vector<std::uint8_t> AsFormat(std::vector<std::uint8_t> b, std::uint32_t version) {
    std::memcpy(b.data() + 8, &version, 4);
    return b;
}

SurveyModel SmallSurvey() {
    SurveyModel m;
    IngestedSeries& r = m.ingest;
    r.nav.leap_seconds = 18;
    for (int i = 0; i < 40; ++i) {
        survey::NavSample s;
        s.utime_gps = 1'400'000'000'000'000 + i * 10'000;
        s.position = {40.4435 + i * 1e-6, -7.7806, 412.0};
        s.yaw_rad = 0.01 * i;
        s.ins_status = 3;
        s.position_type = 56;
        r.nav.samples.push_back(s);
        survey::NavStdDev d;
        d.utime_gps = s.utime_gps;
        d.north_m = d.east_m = d.up_m = 0.02f;
        r.nav.stddevs.push_back(d);
    }
    for (int p = 0; p < 10; ++p) {
        survey::PingHeader h;
        h.utime_gps = 1'400'000'000'010'000 + p * 30'000;
        h.ping_number = p;
        h.sound_speed_valid = p % 2 == 0;
        h.range_resolution_m = 0.01;
        h.start_angle_deg = -60;
        h.angle_increment_deg = 1.0;
        h.beam_offset = static_cast<std::uint32_t>(r.pings.range_counts.size());
        h.num_beams = 121;
        r.pings.pings.push_back(h);
        for (int b = 0; b < 121; ++b) r.pings.range_counts.push_back(1000u + b);
        // Intensities on all but the first ping (which has none: zeros).
        for (int b = 0; b < 121; ++b)
            r.pings.intensities.push_back(
                static_cast<std::uint16_t>(p == 0 ? 0 : 2000 + 7 * b + p));
        // Per-beam angles (R2Sonic-like, closer together at the edges).
        for (int b = 0; b < 121; ++b)
            r.pings.beam_angles_deg.push_back(
                static_cast<float>(-60.0 + b - 0.002 * b * (120 - b)));
    }
    m.vehicle_yaml = "vehicle.yaml";
    m.nominal_mount.boresight_roll_deg = 0.5;
    m.nominal_mount.lever_arm_m = Eigen::Vector3d(0.3, 0.0, 0.8);
    m.mount = m.nominal_mount;
    m.origin = {40.4435, -7.7806, 412.0};
    m.clock.configured = true;
    m.clock.configured_offset_s = 2.35;
    m.clock.coarse_sigma_s = 0.1;
    m.refraction.svp_files = {"cast.svp"};
    m.refraction.selection = svp::CastSelection::kNearestInTime;
    m.refraction.ins_height_above_waterline_m = 0.4;
    return m;
}

class SurveyFile : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(::testing::TempDir()) / ("pitmap_survey_" + std::to_string(::getpid()));
        fs::create_directories(dir_);
        path_ = (dir_ / kSurveyFileName).string();
        SurveyModel m = SmallSurvey();
        m.refraction = {};  // Georeference would read the cast file
        const georef::GeorefResult geo =
            georef::Georeference(m, TrajectoryVersion::kIns, {}, nullptr);
        ASSERT_GT(geo.pings.size(), 0u);
        m.trajectory(TrajectoryVersion::kIns) =
            georef::TrajectoryOf(geo, m.ingest.pings.pings.size());
        m.refraction = SmallSurvey().refraction;
        ASSERT_TRUE(SaveSurvey(path_, m));
        good_ = ReadBytes(path_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    void ExpectError(const std::vector<std::uint8_t>& bytes, const std::string& what) {
        WriteBytes(path_, bytes);
        const auto r = LoadSurvey(path_);
        ASSERT_FALSE(r.ok()) << what;
        EXPECT_NE(r.error().message.find(path_), std::string::npos)
            << what << ": " << r.error().message;
    }

    fs::path dir_;
    std::string path_;
    std::vector<std::uint8_t> good_;
};

TEST_F(SurveyFile, RoundTripsEveryPart) {
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    const SurveyModel w = SmallSurvey();
    EXPECT_EQ(r->ingest.nav.leap_seconds, 18);
    ASSERT_EQ(r->ingest.nav.samples.size(), w.ingest.nav.samples.size());
    EXPECT_EQ(r->ingest.nav.samples[7].utime_gps, w.ingest.nav.samples[7].utime_gps);
    EXPECT_DOUBLE_EQ(r->ingest.nav.samples[7].yaw_rad, w.ingest.nav.samples[7].yaw_rad);
    EXPECT_EQ(r->ingest.nav.stddevs.size(), w.ingest.nav.stddevs.size());
    ASSERT_EQ(r->ingest.pings.pings.size(), 10u);
    EXPECT_TRUE(r->ingest.pings.pings[4].sound_speed_valid);
    EXPECT_FALSE(r->ingest.pings.pings[5].sound_speed_valid);
    EXPECT_EQ(r->ingest.pings.range_counts, w.ingest.pings.range_counts);
    EXPECT_EQ(r->vehicle_yaml, "vehicle.yaml");
    EXPECT_DOUBLE_EQ(r->nominal_mount.boresight_roll_deg, 0.5);
    EXPECT_DOUBLE_EQ(r->mount.lever_arm_m.z(), 0.8);
    EXPECT_DOUBLE_EQ(r->origin.latitude_deg, 40.4435);
    EXPECT_TRUE(r->clock.configured);
    EXPECT_DOUBLE_EQ(r->clock.configured_offset_s, 2.35);
    EXPECT_DOUBLE_EQ(r->clock.sigma_s(), 0.1);
    ASSERT_EQ(r->refraction.svp_files.size(), 1u);
    EXPECT_EQ(r->refraction.selection, svp::CastSelection::kNearestInTime);
    EXPECT_DOUBLE_EQ(r->refraction.ins_height_above_waterline_m, 0.4);
    EXPECT_EQ(r->calibration, CalibrationState::kNotRun);
    EXPECT_TRUE(std::isnan(r->boresight_sd_deg[0])) << "no calibration, no stated sigma";
    ASSERT_TRUE(r->has(TrajectoryVersion::kIns));
    EXPECT_FALSE(r->has(TrajectoryVersion::kSlam));
    EXPECT_EQ(r->latest(), TrajectoryVersion::kIns);
    const PingTrajectory& t = r->trajectory(TrajectoryVersion::kIns);
    ASSERT_EQ(t.T_world_vehicle.size(), 10u);
    for (std::size_t i = 0; i < 10; ++i) EXPECT_EQ(t.valid[i], 1) << i;
    EXPECT_NEAR(t.T_world_vehicle[3].translation().y(),
                georef::TrajectoryOf(georef::Georeference(
                                         [] {
                                             SurveyModel m = SmallSurvey();
                                             m.refraction = {};
                                             return m;
                                         }(),
                                         TrajectoryVersion::kIns,
                                         {},
                                         nullptr),
                                     10)
                    .T_world_vehicle[3]
                    .translation()
                    .y(),
                1e-12);
}

TEST_F(SurveyFile, EveryTrajectoryVersionRoundTrips) {
    auto m = LoadSurvey(path_);
    ASSERT_TRUE(m.ok()) << m.error().message;
    const PingTrajectory ins = m->trajectory(TrajectoryVersion::kIns);
    for (int v = 1; v < kNumTrajectoryVersions; ++v) {
        PingTrajectory t = ins;
        for (auto& T : t.T_world_vehicle) T.translation().z() += 0.1 * v;
        t.valid[static_cast<std::size_t>(v)] = 0;
        m->trajectories[v] = t;
    }
    m->calibration = CalibrationState::kKeptNominal;
    ASSERT_TRUE(SaveSurvey(path_, *m));
    const auto back = LoadSurvey(path_);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->calibration, CalibrationState::kKeptNominal);
    for (int v = 0; v < kNumTrajectoryVersions; ++v) {
        const PingTrajectory& t = back->trajectories[v];
        ASSERT_EQ(t.T_world_vehicle.size(), ins.T_world_vehicle.size()) << v;
        for (std::size_t i = 0; i < t.T_world_vehicle.size(); ++i) {
            EXPECT_NEAR(t.T_world_vehicle[i].translation().z(),
                        ins.T_world_vehicle[i].translation().z() + 0.1 * v,
                        1e-12);
            EXPECT_TRUE(t.T_world_vehicle[i].linear().isApprox(ins.T_world_vehicle[i].linear()));
            EXPECT_EQ(t.valid[i], v > 0 && i == static_cast<std::size_t>(v) ? 0 : 1);
        }
    }
    EXPECT_EQ(back->latest(), TrajectoryVersion::kSlam);
}

// The calibrated boresight's sigma is part of the state (boresight.json is written from it),
// and a reset of the calibration drops it.
TEST_F(SurveyFile, TheBoresightSigmaRoundTripsAndGoesWithTheCalibration) {
    SurveyModel m = SmallSurvey();
    m.calibration = CalibrationState::kCalibrated;
    m.boresight_sd_deg = {0.011, 0.012, 0.03};
    ASSERT_TRUE(SaveSurvey(path_, m));
    const auto r = LoadSurvey(path_, LoadParts::kState);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->boresight_sd_deg, m.boresight_sd_deg);
    SurveyModel again = *r;
    EXPECT_TRUE(again.ResetCalibration());
    EXPECT_TRUE(std::isnan(again.boresight_sd_deg[2]));
}

TEST_F(SurveyFile, TheStateLoadsWithoutTheBigSections) {
    // Damage the ingest payload: a state-only load never reads it.
    std::vector<std::uint8_t> bad = good_;
    bad[Sections(bad).at("ingest").payload_at + 40] ^= 0xff;
    WriteBytes(path_, bad);
    const auto state = LoadSurvey(path_, LoadParts::kState);
    ASSERT_TRUE(state.ok()) << state.error().message;
    EXPECT_DOUBLE_EQ(state->origin.longitude_deg, -7.7806);
    EXPECT_TRUE(state->ingest.pings.pings.empty());
    const auto all = LoadSurvey(path_);
    ASSERT_FALSE(all.ok());
    EXPECT_NE(all.error().message.find("checksum"), std::string::npos) << all.error().message;
}

TEST_F(SurveyFile, TruncatedFilesAreCleanErrors) {
    const std::size_t n = good_.size();
    for (std::size_t keep : {std::size_t{0},
                             std::size_t{3},
                             std::size_t{8},
                             std::size_t{19},
                             std::size_t{20},
                             std::size_t{31},
                             std::size_t{100},
                             n / 3,
                             n / 2,
                             n - 5,
                             n - 1}) {
        ExpectError({good_.begin(), good_.begin() + static_cast<long>(keep)},
                    "truncated to " + std::to_string(keep));
    }
    std::vector<std::uint8_t> longer = good_;
    longer.push_back(0);
    ExpectError(longer, "one byte appended");
}

TEST_F(SurveyFile, OverwrittenBytesAreCleanErrorsOverTwentySeeds) {
    for (unsigned seed = 1; seed <= 20; ++seed) {
        std::mt19937 rng(seed);
        std::vector<std::uint8_t> bad = good_;
        std::uniform_int_distribution<std::size_t> at(0, bad.size() - 1);
        for (int k = 0; k < 20; ++k) bad[at(rng)] ^= static_cast<std::uint8_t>(1 + rng() % 255);
        ExpectError(bad, "seed " + std::to_string(seed));
    }
}

// An array count edited to 3 GiB must not allocate 3 GiB before the error: every count is
// checked against the bytes that remain, whether or not the CRC is right.
TEST_F(SurveyFile, HugeCountsFailWithoutAllocating) {
    const double rss_before_mb = PeakRssMb();
    const std::vector<std::size_t> offsets = IngestArrays(good_);
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
                if (fix_crc) FixCrcs(bad);
                ExpectError(bad,
                            "array " + std::to_string(array) + " count " + std::to_string(huge));
            }
        }
        std::vector<std::uint8_t> bad = good_;
        bad[at + 8] ^= 0x40;
        ExpectError(bad, "array " + std::to_string(array) + " element size");
    }
    // A section length past the end of the file.
    std::vector<std::uint8_t> bad = good_;
    const std::uint64_t huge = 3ull << 30;
    std::memcpy(bad.data() + Sections(bad).at("ingest").crc_at - 8, &huge, 8);
    ExpectError(bad, "section length");
    EXPECT_LT(PeakRssMb() - rss_before_mb, 64.0) << "memory stays bounded by the file size";
}

TEST_F(SurveyFile, CraftedContentWithRightCrcsIsCheckedToo) {
    // Beam offsets pointing past the range counts.
    std::vector<std::uint8_t> bad = good_;
    const std::size_t first = IngestArrays(good_)[2] + 16;
    const std::uint32_t offset = 1u << 30;
    constexpr std::size_t kBeamOffsetAt = 57;  // in a ping record (survey_records.hpp)
    std::memcpy(bad.data() + first + kBeamOffsetAt, &offset, 4);
    FixCrcs(bad);
    ExpectError(bad, "beam offset");
    // The second ping's beams on the first's (in range, but shared: georef would write both
    // pings' soundings into the same slots).
    bad = good_;
    std::uint64_t header_size = 0;
    std::memcpy(&header_size, good_.data() + IngestArrays(good_)[2] + 8, 8);
    const std::uint32_t zero = 0;
    std::memcpy(bad.data() + first + header_size + kBeamOffsetAt, &zero, 4);
    FixCrcs(bad);
    ExpectError(bad, "overlapping beam offsets");
    // An unknown ping clock.
    bad = good_;
    bad[Sections(bad).at("ingest").payload_at + 4] = 9;
    FixCrcs(bad);
    ExpectError(bad, "ping clock");
    // A pose that is not finite, and a rotation that is not one.
    for (std::size_t field : {std::size_t{0}, std::size_t{3}}) {
        bad = good_;
        const std::size_t pose = Sections(bad).at("traj.ins").payload_at + 16;
        const double v = field == 0 ? std::nan("") : 2.0;
        std::memcpy(bad.data() + pose + field * 8, &v, 8);
        FixCrcs(bad);
        ExpectError(bad, "pose field " + std::to_string(field));
    }
    // A state that is not JSON, or lacks a key.
    for (const char* text : {"{", "[]", "{\"vehicle_yaml\": 3}"}) {
        bad = good_;
        const SectionAt st = Sections(bad).at("state");
        std::vector<std::uint8_t> payload(text, text + std::strlen(text));
        bad.erase(bad.begin() + static_cast<long>(st.payload_at),
                  bad.begin() + static_cast<long>(st.payload_at + st.bytes));
        bad.insert(bad.begin() + static_cast<long>(st.payload_at), payload.begin(), payload.end());
        const std::uint64_t n = payload.size();
        std::memcpy(bad.data() + st.crc_at - 8, &n, 8);
        FixCrcs(bad);
        ExpectError(bad, std::string("state ") + text);
    }
    // A bool byte of 7 reads as true (no undefined bool value reaches the stages).
    bad = good_;
    constexpr std::size_t kSoundSpeedValidAt = 24;  // in a ping record (survey_records.hpp)
    ASSERT_FALSE(SmallSurvey().ingest.pings.pings[1].sound_speed_valid);
    bad[first + header_size + kSoundSpeedValidAt] = 7;
    FixCrcs(bad);
    WriteBytes(path_, bad);
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_TRUE(r->ingest.pings.pings[1].sound_speed_valid);
}

TEST_F(SurveyFile, EmptyForeignAndOtherVersionFilesAreCleanErrors) {
    ExpectError({}, "empty");
    ExpectError(std::vector<std::uint8_t>(4096, 0), "zeros");
    std::vector<std::uint8_t> other = good_;
    other[8] = 99;  // format version
    WriteBytes(path_, other);
    const auto r = LoadSurvey(path_);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("format 99"), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find("georef"), std::string::npos) << r.error().message;
    const auto missing = LoadSurvey((dir_ / "none.pitmap").string());
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.error().message.find("none.pitmap"), std::string::npos);
}

TEST_F(SurveyFile, IntensitiesRoundTripAndAreOnlyWrittenWhenThere) {
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->ingest.pings.intensities, SmallSurvey().ingest.pings.intensities);
    ASSERT_TRUE(Sections(good_).count("intensity"));
    std::uint32_t version = 0;
    std::memcpy(&version, good_.data() + 8, 4);
    EXPECT_EQ(version, kSurveyFormatVersion);

    SurveyModel none = SmallSurvey();
    none.ingest.pings.intensities.clear();
    ASSERT_TRUE(SaveSurvey(path_, none));
    EXPECT_FALSE(Sections(ReadBytes(path_)).count("intensity"));
    const auto back = LoadSurvey(path_);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_FALSE(back->ingest.pings.has_intensities());
}

// The file without one section, marked as of format `version`.
std::vector<std::uint8_t> Without(const std::vector<std::uint8_t>& b,
                                  const std::string& tag,
                                  std::uint32_t version) {
    const SectionAt s = Sections(b).at(tag);
    std::vector<std::uint8_t> out(b.begin(),
                                  b.begin() + static_cast<std::ptrdiff_t>(s.crc_at - 24));
    out.insert(out.end(), b.begin() + static_cast<std::ptrdiff_t>(s.payload_at + s.bytes), b.end());
    std::memcpy(out.data() + 8, &version, 4);
    std::uint32_t count = 0;
    std::memcpy(&count, out.data() + 16, 4);
    --count;
    std::memcpy(out.data() + 16, &count, 4);
    return out;
}

// The file of the format before intensities: without the intensity and beam_angle sections.
std::vector<std::uint8_t> AsFormat1(const std::vector<std::uint8_t>& b) {
    return Without(Without(WithLegacyPings(b), "beam_angle", 2), "intensity", 1);
}

TEST_F(SurveyFile, BeamAnglesRoundTripAndAreOnlyWrittenWhenThere) {
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->ingest.pings.beam_angles_deg, SmallSurvey().ingest.pings.beam_angles_deg);
    ASSERT_TRUE(Sections(good_).count("beam_angle"));

    SurveyModel none = SmallSurvey();
    none.ingest.pings.beam_angles_deg.clear();
    ASSERT_TRUE(SaveSurvey(path_, none));
    EXPECT_FALSE(Sections(ReadBytes(path_)).count("beam_angle"));
    const auto back = LoadSurvey(path_);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_FALSE(back->ingest.pings.has_beam_angles());
}

TEST_F(SurveyFile, AFormat2FileIsReadWithoutBeamAnglesAndCannotHoldThem) {
    WriteBytes(path_, Without(WithLegacyPings(good_), "beam_angle", 2));
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_FALSE(r->ingest.pings.has_beam_angles());
    EXPECT_TRUE(r->ingest.pings.has_intensities());
    WriteBytes(path_, AsFormat(WithLegacyPings(good_), 2));
    const auto c = LoadSurvey(path_);
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.error().message.find("unknown section \"beam_angle\""), std::string::npos)
        << c.error().message;
}

TEST_F(SurveyFile, BeamAnglesThatDoNotMatchTheRangeCountsAreAnError) {
    std::vector<std::uint8_t> bad = good_;
    const SectionAt s = Sections(bad).at("beam_angle");
    std::uint64_t count = 0;
    std::memcpy(&count, bad.data() + s.payload_at, 8);
    --count;
    std::memcpy(bad.data() + s.payload_at, &count, 8);
    bad.erase(bad.begin() + static_cast<std::ptrdiff_t>(s.payload_at + s.bytes - 4),
              bad.begin() + static_cast<std::ptrdiff_t>(s.payload_at + s.bytes));
    const std::uint64_t bytes = s.bytes - 4;
    std::memcpy(bad.data() + s.crc_at - 8, &bytes, 8);
    FixCrcs(bad);
    WriteBytes(path_, bad);
    const auto r = LoadSurvey(path_);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("angles for"), std::string::npos) << r.error().message;
}

TEST_F(SurveyFile, AFormat1FileIsReadWithoutIntensities) {
    WriteBytes(path_, AsFormat1(good_));
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_FALSE(r->ingest.pings.has_intensities());
    EXPECT_EQ(r->ingest.pings.range_counts, SmallSurvey().ingest.pings.range_counts);
    EXPECT_TRUE(r->has(TrajectoryVersion::kIns));
    // A format 1 file cannot hold the section (a crafted one is an error, not a guess).
    WriteBytes(path_, AsFormat(WithLegacyPings(good_), 1));
    const auto c = LoadSurvey(path_);
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.error().message.find("unknown section \"intensity\""), std::string::npos)
        << c.error().message;
}

TEST_F(SurveyFile, IntensitiesThatDoNotMatchTheRangeCountsAreAnError) {
    // One intensity fewer, with the right CRCs: the count field says n - 1 and the payload
    // ends two bytes early.
    std::vector<std::uint8_t> bad = good_;
    const SectionAt s = Sections(bad).at("intensity");
    std::uint64_t count = 0;
    std::memcpy(&count, bad.data() + s.payload_at, 8);
    --count;
    std::memcpy(bad.data() + s.payload_at, &count, 8);
    bad.erase(bad.begin() + static_cast<std::ptrdiff_t>(s.payload_at + s.bytes - 2),
              bad.begin() + static_cast<std::ptrdiff_t>(s.payload_at + s.bytes));
    const std::uint64_t bytes = s.bytes - 2;
    std::memcpy(bad.data() + s.crc_at - 8, &bytes, 8);
    FixCrcs(bad);
    WriteBytes(path_, bad);
    const auto r = LoadSurvey(path_);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("intensities for"), std::string::npos) << r.error().message;
}

TEST_F(SurveyFile, AFailedSaveKeepsThePreviousFile) {
    // A folder in the way of the temporary file: the save fails, the old file stays whole.
    fs::create_directories(path_ + ".partial");
    const Status st = SaveSurvey(path_, SmallSurvey());
    EXPECT_FALSE(st.ok());
    EXPECT_EQ(ReadBytes(path_), good_);
}

// ---- the cleaning's flags (issue 35: format 4's optional cleaning section) ----

// Cleaning statuses on some soundings of SmallSurvey (1210 of them), hand edits on others.
SurveyModel CleanedSurvey() {
    SurveyModel m = SmallSurvey();
    const std::size_t n = m.ingest.pings.range_counts.size();
    m.flags.cleaning.assign(n, 0);
    m.flags.cleaning[0] = static_cast<std::uint8_t>(survey::SoundingStatus::kFreeSpace);
    m.flags.cleaning[17] = static_cast<std::uint8_t>(survey::SoundingStatus::kMultipath);
    m.flags.cleaning[121 * 4 + 60] = static_cast<std::uint8_t>(survey::SoundingStatus::kCluster);
    m.flags.cleaning[n - 1] = static_cast<std::uint8_t>(survey::SoundingStatus::kProfile);
    m.flags.cleaning[n - 2] = static_cast<std::uint8_t>(survey::SoundingStatus::kSurfaceFilter);
    m.flags.manual.assign(n, 0);
    m.flags.manual[5] = static_cast<std::uint8_t>(survey::ManualEdit::kReject);
    return m;
}

// A cleaning payload as survey_file.cpp lays it out: the sounding count, then the indices
// (u32) and the statuses (u8), each as a count, an element size and the elements.
std::vector<std::uint8_t> CleaningBytes(std::uint64_t soundings,
                                        const std::vector<std::uint32_t>& index,
                                        const std::vector<std::uint8_t>& code) {
    std::vector<std::uint8_t> b;
    const auto put = [&b](const void* p, std::size_t n) {
        const auto* c = static_cast<const std::uint8_t*>(p);
        b.insert(b.end(), c, c + n);
    };
    const auto put_u64 = [&put](std::uint64_t v) { put(&v, 8); };
    put_u64(soundings);
    put_u64(index.size());
    put_u64(4);
    put(index.data(), index.size() * 4);
    put_u64(code.size());
    put_u64(1);
    put(code.data(), code.size());
    return b;
}

// The file with its cleaning section's payload replaced (length and CRC right).
std::vector<std::uint8_t> WithCleaning(const std::vector<std::uint8_t>& file,
                                       const std::vector<std::uint8_t>& payload) {
    const SectionAt s = Sections(file).at("cleaning");
    std::vector<std::uint8_t> out(file.begin(),
                                  file.begin() + static_cast<std::ptrdiff_t>(s.payload_at));
    out.insert(out.end(), payload.begin(), payload.end());
    out.insert(
        out.end(), file.begin() + static_cast<std::ptrdiff_t>(s.payload_at + s.bytes), file.end());
    const std::uint64_t n = payload.size();
    std::memcpy(out.data() + s.crc_at - 8, &n, 8);
    FixCrcs(out);
    return out;
}

TEST_F(SurveyFile, TheCleaningRoundTripsWithoutTheHandEdits) {
    const SurveyModel m = CleanedSurvey();
    ASSERT_TRUE(SaveSurvey(path_, m));
    const std::vector<std::uint8_t> bytes = ReadBytes(path_);
    ASSERT_TRUE(Sections(bytes).count("cleaning"));
    // Sparse: five soundings, not one byte per sounding.
    EXPECT_EQ(Sections(bytes).at("cleaning").bytes, 8 + 16 + 5 * 4 + 16 + 5);
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->flags.cleaning, m.flags.cleaning);
    // The hand edits live in P/edits.json (edit_log.hpp), never in the survey file.
    EXPECT_TRUE(r->flags.manual.empty());
    // A state-only load reads no flags.
    const auto state = LoadSurvey(path_, LoadParts::kState);
    ASSERT_TRUE(state.ok()) << state.error().message;
    EXPECT_TRUE(state->flags.cleaning.empty());
    // Saved again, the same bytes.
    ASSERT_TRUE(SaveSurvey(path_, *r));
    EXPECT_EQ(ReadBytes(path_), bytes);
}

TEST_F(SurveyFile, AModelWithoutCleaningWritesNoSection) {
    EXPECT_FALSE(Sections(good_).count("cleaning"));
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_TRUE(r->flags.cleaning.empty());
    // A cleaning that rejected nothing is kept as such (the stage ran): every sounding 0.
    SurveyModel none = SmallSurvey();
    none.flags.cleaning.assign(none.ingest.pings.range_counts.size(), 0);
    ASSERT_TRUE(SaveSurvey(path_, none));
    const auto back = LoadSurvey(path_);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->flags.cleaning, none.flags.cleaning);
}

TEST_F(SurveyFile, ACorruptCleaningSectionIsAnErrorNamingTheFile) {
    ASSERT_TRUE(SaveSurvey(path_, CleanedSurvey()));
    const std::vector<std::uint8_t> cleaned = ReadBytes(path_);
    const std::uint64_t n = SmallSurvey().ingest.pings.range_counts.size();
    const auto n32 = static_cast<std::uint32_t>(n);
    const std::uint8_t free_space = 6, spike = 3, manual = 9;
    // The crafting itself is right: a well-formed payload loads.
    WriteBytes(path_, WithCleaning(cleaned, CleaningBytes(n, {3, 9}, {free_space, 7})));
    const auto ok = LoadSurvey(path_);
    ASSERT_TRUE(ok.ok()) << ok.error().message;
    EXPECT_EQ(ok->flags.cleaning[9], 7);

    const struct {
        const char* what;
        std::vector<std::uint8_t> payload;
        const char* says;
    } cases[] = {
        {"indices out of order",
         CleaningBytes(n, {9, 3}, {free_space, free_space}),
         "out of order"},
        {"an index twice", CleaningBytes(n, {9, 9}, {free_space, free_space}), "out of order"},
        {"an index beyond the soundings",
         CleaningBytes(n, {3, n32}, {free_space, free_space}),
         "beyond"},
        {"a spike (georef's own status)", CleaningBytes(n, {3}, {spike}), "not a cleaning"},
        {"a manual status", CleaningBytes(n, {3}, {manual}), "not a cleaning"},
        {"accepted, listed", CleaningBytes(n, {3}, {0}), "not a cleaning"},
        {"an unknown status", CleaningBytes(n, {3}, {200}), "not a cleaning"},
        {"more indices than statuses", CleaningBytes(n, {3, 4}, {free_space}), "indices for"},
        {"fewer soundings than the range counts",
         CleaningBytes(n - 1, {3}, {free_space}),
         "range counts"},
        {"more soundings than the range counts",
         CleaningBytes(n + 1, {3}, {free_space}),
         "range counts"},
        {"a truncated payload",
         [&] {
             std::vector<std::uint8_t> b = CleaningBytes(n, {3}, {free_space});
             b.pop_back();
             return b;
         }(),
         "remain"},
    };
    for (const auto& c : cases) {
        const std::vector<std::uint8_t> bad = WithCleaning(cleaned, c.payload);
        ExpectError(bad, c.what);
        const auto r = LoadSurvey(path_);
        ASSERT_FALSE(r.ok());
        EXPECT_NE(r.error().message.find("cleaning"), std::string::npos)
            << c.what << ": " << r.error().message;
        EXPECT_NE(r.error().message.find(c.says), std::string::npos)
            << c.what << ": " << r.error().message;
    }
}

// A sounding count of 4 Gi in a small file must not allocate 4 GiB before the error (the
// count cannot exceed what the file's range counts could hold).
TEST_F(SurveyFile, AHugeCleaningCountFailsWithoutAllocating) {
    ASSERT_TRUE(SaveSurvey(path_, CleanedSurvey()));
    const std::vector<std::uint8_t> cleaned = ReadBytes(path_);
    const double rss_before_mb = PeakRssMb();
    for (std::uint64_t huge : {std::uint64_t{1} << 32,
                               (std::uint64_t{1} << 32) - 1,
                               std::uint64_t{1} << 31,
                               ~std::uint64_t{0}}) {
        ExpectError(WithCleaning(cleaned, CleaningBytes(huge, {3}, {6})),
                    "sounding count " + std::to_string(huge));
    }
    EXPECT_LT(PeakRssMb() - rss_before_mb, 64.0) << "memory stays bounded by the file size";
}

// Formats 1-4 wrote the ping records as PingHeader lay in memory; format 5 field by field. A
// format 4 file reads the same pings, and its record size is checked (a format 4 file with
// format 5 records is an error, not a misread).
TEST_F(SurveyFile, AFormat4FileReadsItsPingRecordsInTheOldLayout) {
    WriteBytes(path_, AsFormat(WithLegacyPings(good_), 4));
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    const auto& want = SmallSurvey().ingest.pings.pings;
    const auto& got = r->ingest.pings.pings;
    ASSERT_EQ(got.size(), want.size());
    for (std::size_t i = 0; i < want.size(); ++i) {
        EXPECT_EQ(got[i].utime_gps, want[i].utime_gps);
        EXPECT_EQ(got[i].ping_number, want[i].ping_number);
        EXPECT_EQ(got[i].sound_speed_valid, want[i].sound_speed_valid);
        EXPECT_EQ(got[i].range_resolution_m, want[i].range_resolution_m);
        EXPECT_EQ(got[i].start_angle_deg, want[i].start_angle_deg);
        EXPECT_EQ(got[i].beam_offset, want[i].beam_offset);
        EXPECT_EQ(got[i].num_beams, want[i].num_beams);
        EXPECT_TRUE(std::isnan(got[i].aid_heading_deg));
    }
    ExpectError(AsFormat(good_, 4), "pings: record size 104, expected 112");
}

TEST_F(SurveyFile, AFormat3FileIsReadWithoutCleaningAndCannotHoldIt) {
    WriteBytes(path_, AsFormat(WithLegacyPings(good_), 3));
    const auto r = LoadSurvey(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_TRUE(r->flags.cleaning.empty());
    EXPECT_TRUE(r->ingest.pings.has_beam_angles());
    EXPECT_EQ(r->ingest.pings.range_counts, SmallSurvey().ingest.pings.range_counts);
    // A format 3 file with the section is an error, not a guess.
    ASSERT_TRUE(SaveSurvey(path_, CleanedSurvey()));
    ExpectError(AsFormat(WithLegacyPings(ReadBytes(path_)), 3), "format 3 with a cleaning section");
    const auto c = LoadSurvey(path_);
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.error().message.find("unknown section \"cleaning\""), std::string::npos)
        << c.error().message;
}

// SLAM's posterior sigma goes with the SLAM trajectory (format 6): round trip, NaN kept, gone
// with a DropFrom; a format 5 file reads without it and cannot hold it; a bad one is an error.
TEST_F(SurveyFile, TheSlamSigmaRoundTripsAndIsChecked) {
    auto m = LoadSurvey(path_);
    ASSERT_TRUE(m.ok()) << m.error().message;
    EXPECT_TRUE(m->trajectory(TrajectoryVersion::kIns).sigma.empty());
    PingTrajectory slam = m->trajectory(TrajectoryVersion::kIns);
    const std::size_t n = slam.T_world_vehicle.size();
    ASSERT_GE(n, 2u);
    for (std::size_t i = 0; i < n; ++i) {
        const double f = 1.0 + static_cast<double>(i);
        slam.sigma.push_back({1e-4 * f, 2e-4 * f, 3e-4 * f, 0.01 * f, 0.02 * f, 0.03 * f});
    }
    slam.sigma[1][3] = std::numeric_limits<double>::quiet_NaN();
    m->trajectory(TrajectoryVersion::kSlam) = slam;
    ASSERT_TRUE(SaveSurvey(path_, *m));
    const std::vector<std::uint8_t> with = ReadBytes(path_);
    ASSERT_EQ(Sections(with).count("traj.slam.sigma"), 1u);
    const auto back = LoadSurvey(path_);
    ASSERT_TRUE(back.ok()) << back.error().message;
    const auto& got = back->trajectory(TrajectoryVersion::kSlam).sigma;
    ASSERT_EQ(got.size(), n);
    for (std::size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 6; ++c) {
            if (i == 1 && c == 3) {
                EXPECT_TRUE(std::isnan(got[i][c]));
            } else {
                EXPECT_EQ(got[i][c], slam.sigma[i][c]) << i << " " << c;
            }
        }
    }
    SurveyModel dropped = *back;
    dropped.DropFrom(TrajectoryVersion::kSlam);
    EXPECT_TRUE(dropped.trajectory(TrajectoryVersion::kSlam).sigma.empty());
    // Format 5: without the section it reads (the good file), with it it is an error.
    WriteBytes(path_, AsFormat(good_, 5));
    const auto old = LoadSurvey(path_);
    ASSERT_TRUE(old.ok()) << old.error().message;
    EXPECT_FALSE(old->has(TrajectoryVersion::kSlam));
    ExpectError(AsFormat(with, 5), "format 5 with a traj.slam.sigma section");
    // A negative sigma, with the right CRC.
    std::vector<std::uint8_t> bad = with;
    const double negative = -0.5;
    std::memcpy(bad.data() + Sections(bad).at("traj.slam.sigma").payload_at + 16, &negative, 8);
    FixCrcs(bad);
    ExpectError(bad, "negative sigma");
    WriteBytes(path_, bad);
    const auto neg = LoadSurvey(path_);
    ASSERT_FALSE(neg.ok());
    EXPECT_NE(neg.error().message.find("negative"), std::string::npos) << neg.error().message;
    // Fewer sigmas than poses.
    m->trajectory(TrajectoryVersion::kSlam).sigma.pop_back();
    ASSERT_TRUE(SaveSurvey(path_, *m));
    const auto short_one = LoadSurvey(path_);
    ASSERT_FALSE(short_one.ok());
    EXPECT_NE(short_one.error().message.find("sigmas for"), std::string::npos)
        << short_one.error().message;
}

TEST(SurveyModel, TheViewPutsSoundingsOnTheVersionAskedFor) {
    SurveyModel m = SmallSurvey();
    m.refraction = {};
    georef::GeorefResult ins = georef::Georeference(m, TrajectoryVersion::kIns, {}, nullptr);
    ASSERT_EQ(ins.pings.size(), 10u);
    const std::size_t n = m.ingest.pings.pings.size();
    m.trajectory(TrajectoryVersion::kIns) = georef::TrajectoryOf(ins, n);
    // A SLAM version 0.5 m east of the INS for every ping but ping 2 (no valid pose).
    PingTrajectory slam = m.trajectory(TrajectoryVersion::kIns);
    for (auto& T : slam.T_world_vehicle) T.translation().x() += 0.5;
    slam.valid[2] = 0;
    m.trajectory(TrajectoryVersion::kSlam) = slam;
    EXPECT_EQ(m.latest(), TrajectoryVersion::kSlam);
    const georef::GeorefResult moved =
        georef::Georeference(m, TrajectoryVersion::kSlam, {}, nullptr);
    const georef::GeorefResult still =
        georef::Georeference(m, TrajectoryVersion::kCalibrated, {}, nullptr);
    ASSERT_EQ(moved.points.size(), ins.points.size());
    for (std::size_t j = 0; j < ins.points.size(); ++j) {
        const double want = moved.pings[moved.points.ping[j]].header_index == 2 ? 0.0 : 0.5;
        EXPECT_NEAR(
            moved.points.position_world[j].x() - ins.points.position_world[j].x(), want, 1e-9);
        EXPECT_NEAR(still.points.position_world[j].x(), ins.points.position_world[j].x(), 1e-12);
    }
    m.DropFrom(TrajectoryVersion::kCalibrated);
    EXPECT_FALSE(m.has(TrajectoryVersion::kSlam));
    EXPECT_TRUE(m.has(TrajectoryVersion::kIns));
}

TEST(SurveyModel, ResetCalibrationUndoesTheLatencyAndTheMountExactly) {
    SurveyModel m = SmallSurvey();
    const std::vector<survey::PingHeader> nominal = m.ingest.pings.pings;
    EXPECT_FALSE(m.ResetCalibration()) << "nothing to undo";
    m.mount.boresight_yaw_deg = 1.5;
    m.clock.latency_applied = true;
    m.clock.latency_s = 0.0123456;
    m.clock.latency_formal_sd_s = 0.001;
    survey::ShiftPingTimes(m.ingest.pings, m.clock.latency_s);
    m.calibration = CalibrationState::kCalibrated;
    m.trajectory(TrajectoryVersion::kCalibrated).T_world_vehicle.assign(10, Pose::Identity());
    m.trajectory(TrajectoryVersion::kCalibrated).valid.assign(10, 1);
    EXPECT_DOUBLE_EQ(m.clock.correction_s(), 0.0123456);
    EXPECT_DOUBLE_EQ(m.clock.sigma_s(), 0.001);
    EXPECT_TRUE(m.ResetCalibration());
    for (std::size_t i = 0; i < nominal.size(); ++i)
        EXPECT_EQ(m.ingest.pings.pings[i].utime_gps, nominal[i].utime_gps) << i;
    EXPECT_DOUBLE_EQ(m.mount.boresight_yaw_deg, 0.0);
    EXPECT_DOUBLE_EQ(m.mount.boresight_roll_deg, 0.5);
    EXPECT_EQ(m.calibration, CalibrationState::kNotRun);
    EXPECT_FALSE(m.has(TrajectoryVersion::kCalibrated));
    EXPECT_DOUBLE_EQ(m.clock.sigma_s(), 0.1);
}

}  // namespace
}  // namespace pitmap::proc::survey
