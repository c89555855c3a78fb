// SPDX-License-Identifier: MIT
// Boresight calibration on a synthetic seabed with relief, surveyed by passes with a known
// boresight; the soundings are georeferenced with the nominal (zero) boresight and the
// calibration must recover the true one. One pass alone has no overlap and must say so.
#include "processor/calib/boresight.hpp"
#include "processor/calib/boresight_blocks.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <type_traits>

#include "common/frames.hpp"
#include "processor/calib/pass_pairs.hpp"

namespace pitmap::proc::calib {
namespace {

using georef::GeorefResult;
using survey::SonarMount;

double Seabed(double x, double y) {
    return -10.0 + 1.5 * std::sin(x / 6.0) + 1.0 * std::cos(y / 5.0);
}

struct Pass {
    double t0_s;                 // start time, seconds
    Eigen::Vector2d start, dir;  // metres, unit direction
    double length_m;
};

// Pings at 10 Hz along the passes at 1 m/s; 121 beams over +-60 deg; soundings georeferenced
// with `nominal`, ranges found on the seabed with `truth`. `ins_error` (when given) is the INS's
// horizontal error at time t: the ranges come from the true pose, the georeference (and what the
// calibration sees) from the INS's.
GeorefResult Survey(const std::vector<Pass>& passes,
                    const SonarMount& truth,
                    const SonarMount& nominal,
                    const std::function<Eigen::Vector2d(double)>& ins_error = {}) {
    GeorefResult g;
    const Pose T_vs_true = truth.T_vehicle_sonar(), T_vs_nom = nominal.T_vehicle_sonar();
    for (const Pass& pass : passes) {
        const double yaw = std::atan2(pass.dir.x(), pass.dir.y());  // from north, clockwise
        for (int k = 0; k <= static_cast<int>(pass.length_m * 10); ++k) {
            const Eigen::Vector2d xy = pass.start + pass.dir * (k * 0.1);
            georef::GeorefPing ping;
            ping.utime_gps = static_cast<std::int64_t>((pass.t0_s + k * 0.1) * 1e6);
            ping.T_world_vehicle =
                MakePose(frames::RotationWorldFromRpy(0.02 * std::sin(k * 0.3), 0.0, yaw),
                         Eigen::Vector3d(xy.x(), xy.y(), 0.0));
            const Pose T_true = ping.T_world_vehicle;
            if (ins_error) {
                const Eigen::Vector2d e = ins_error(pass.t0_s + k * 0.1);
                ping.T_world_vehicle.translation() += Eigen::Vector3d(e.x(), e.y(), 0.0);
            }
            const auto pi = static_cast<std::uint32_t>(g.pings.size());
            g.pings.push_back(ping);
            for (int b = 0; b < 121; ++b) {
                const double theta = frames::DegToRad(-60.0 + b);
                // Range where the true beam meets the seabed (bisection on the height difference).
                double lo = 0.5, hi = 60.0;
                for (int it = 0; it < 60; ++it) {
                    const double r = 0.5 * (lo + hi);
                    const Eigen::Vector3d p =
                        T_true * (T_vs_true * georef::BeamVectorSonar(r, theta, 0.0));
                    (p.z() > Seabed(p.x(), p.y()) ? lo : hi) = r;
                }
                const double r = 0.5 * (lo + hi);
                g.points.position_world.push_back(
                    ping.T_world_vehicle * (T_vs_nom * georef::BeamVectorSonar(r, theta, 0.0)));
                g.points.ping.push_back(pi);
                g.points.beam.push_back(static_cast<std::uint16_t>(b));
                g.points.range_m.push_back(static_cast<float>(r));
                g.points.angle_rad.push_back(static_cast<float>(theta));
            }
        }
    }
    return g;
}

SonarMount Mount(double roll, double pitch, double yaw) {
    SonarMount m;
    m.lever_arm_m = Eigen::Vector3d(0.8, 0.0, 0.25);
    m.boresight_roll_deg = roll;
    m.boresight_pitch_deg = pitch;
    m.boresight_yaw_deg = yaw;
    return m;
}

// The INS's reported 1-sigma once a second over [0, t_end] s: horizontal 0.01 m, or 5 m from
// outage_from_s on (a GNSS outage); attitude as given (NaN = not reported).
survey::NavSeries InsSigmas(int t_end,
                            double outage_from_s,
                            float roll_deg = NAN,
                            float pitch_deg = NAN,
                            float yaw_deg = 0.02f) {
    survey::NavSeries nav;
    for (int t = 0; t <= t_end; ++t) {
        survey::NavStdDev sd;
        sd.utime_gps = static_cast<std::int64_t>(t) * 1'000'000;
        sd.east_m = sd.north_m = t >= outage_from_s ? 5.0f : 0.01f;
        sd.up_m = 0.02f;
        sd.roll_deg = roll_deg;
        sd.pitch_deg = pitch_deg;
        sd.yaw_deg = yaw_deg;
        nav.stddevs.push_back(sd);
    }
    return nav;
}

TEST(Boresight, RecoversAKnownErrorFromOppositeAndCrossingPasses) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const std::vector<Pass> passes = {
        {0.0, {0, -20}, {0, 1}, 40}, {60.0, {4, 20}, {0, -1}, 40}, {120.0, {-20, 2}, {1, 0}, 40}};
    const GeorefResult geo = Survey(passes, truth, nominal);
    const BoresightResult res = CalibrateBoresight(geo, {}, nominal, BoresightConfig{});
    EXPECT_NE(res.termination, Termination::kNoOverlap) << res.message;
    EXPECT_NEAR(res.mount.boresight_roll_deg, 1.0, 0.02) << res.message;
    EXPECT_NEAR(res.mount.boresight_pitch_deg, -0.8, 0.02) << res.message;
    EXPECT_NEAR(res.mount.boresight_yaw_deg, 1.5, 0.02) << res.message;
    EXPECT_LT(res.after.rms_m, 0.5 * res.before.rms_m);
    EXPECT_GT(res.after.pairs, 1000);
    EXPECT_EQ(res.mount.lever_arm_m, nominal.lever_arm_m);
}

double ErrorDeg(const SonarMount& a, const SonarMount& b) {
    return frames::RadToDeg(
        Eigen::AngleAxisd(a.R_vehicle_sonar().transpose() * b.R_vehicle_sonar()).angle());
}

// An INS's horizontal error wanders by 3 cm between passes (over minutes): over 10 m of water
// that is up to 0.17 deg of pitch or yaw. The per-node horizontal corrections (their prior set
// to that INS's sigma) take it: 0.021 deg left; without them the boresight carries 0.077 deg.
TEST(Boresight, HorizontalInsErrorsBetweenPassesAreNotTakenForTheMount) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const std::vector<Pass> passes = {{0.0, {0, -20}, {0, 1}, 40},
                                      {60.0, {4, 20}, {0, -1}, 40},
                                      {120.0, {-20, 2}, {1, 0}, 40},
                                      {180.0, {20, -3}, {-1, 0}, 40}};
    const auto wander = [](double t) {
        const double a = 2 * M_PI * t / 240.0;
        return Eigen::Vector2d(0.03 * std::sin(a), 0.03 * std::cos(a));
    };
    const GeorefResult geo = Survey(passes, truth, nominal, wander);
    BoresightConfig cfg;
    cfg.horizontal_offset_sigma_m = 0.03;  // this INS's error
    const BoresightResult with = CalibrateBoresight(geo, {}, nominal, cfg);
    BoresightConfig heights_only = cfg;
    heights_only.estimate_horizontal_offsets = false;
    const BoresightResult without = CalibrateBoresight(geo, {}, nominal, heights_only);
    EXPECT_LT(ErrorDeg(with.mount, truth), 0.03) << with.message;
    EXPECT_GT(ErrorDeg(without.mount, truth), 2 * ErrorDeg(with.mount, truth)) << without.message;
}

// The boresight's stated uncertainty adds the INS's attitude error averaged over the window:
// the INS's reported 1-sigma times sqrt(g(T / tau)), g(x) = 2 (x - 1 + e^-x) / x^2; none when
// the error is taken as white (tau 0).
TEST(Boresight, StatedUncertaintyAddsTheInsAttitudeErrorOverTheWindow) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const std::vector<Pass> passes = {
        {0.0, {0, -20}, {0, 1}, 40}, {60.0, {4, 20}, {0, -1}, 40}, {120.0, {-20, 2}, {1, 0}, 40}};
    const GeorefResult geo = Survey(passes, truth, nominal);
    survey::NavSeries nav = InsSigmas(170, 1e9, 0.01f, 0.02f, 0.05f);
    BoresightConfig cfg;
    const BoresightResult res = CalibrateBoresight(geo, nav, nominal, cfg);
    ASSERT_NE(res.termination, Termination::kNoOverlap) << res.message;
    EXPECT_TRUE(res.ins_attitude_reported);
    const double x =
        (res.segment.end_s - res.segment.start_s) / cfg.ins_attitude_correlation_time_s;
    const double g = std::sqrt(2 * (x - 1 + std::exp(-x)) / (x * x));
    const double reported[3] = {0.01, 0.02, 0.05};
    for (int j = 0; j < 3; ++j) {
        // The mount is within 2 deg of level: the axes map nearly one to one.
        EXPECT_NEAR(res.ins_attitude_sd_deg[j], reported[j] * g, 0.04 * reported[j] * g) << j;
        EXPECT_NEAR(
            res.sd_deg[j], std::hypot(res.formal_sd_deg[j], res.ins_attitude_sd_deg[j]), 1e-12);
    }
    cfg.ins_attitude_correlation_time_s = 0;
    const BoresightResult white = CalibrateBoresight(geo, nav, nominal, cfg);
    for (int j = 0; j < 3; ++j) {
        EXPECT_EQ(white.ins_attitude_sd_deg[j], 0.0);
        EXPECT_EQ(white.sd_deg[j], white.formal_sd_deg[j]);
    }
    // No attitude sigmas from the INS: nothing to add.
    for (auto& sd : nav.stddevs) sd.roll_deg = sd.pitch_deg = sd.yaw_deg = NAN;
    const BoresightResult none = CalibrateBoresight(geo, nav, nominal, BoresightConfig{});
    EXPECT_EQ(none.sd_deg[2], none.formal_sd_deg[2]);
    EXPECT_FALSE(none.ins_attitude_reported);
}

TEST(Boresight, ShorterWindowsAreTriedWhenNoFullWindowIsLowDrift) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const std::vector<Pass> passes = {
        {0.0, {0, -20}, {0, 1}, 40}, {40.0, {4, 20}, {0, -1}, 40}, {120.0, {-20, 2}, {1, 0}, 40}};
    const GeorefResult geo = Survey(passes, truth, nominal);
    // The INS drifts (GNSS outage) from 100 s on: no 160 s window is low drift, 80 s ones are.
    const survey::NavSeries nav = InsSigmas(170, 100.0);
    BoresightConfig cfg;
    cfg.segment_duration_s = 160;
    const BoresightResult res = CalibrateBoresight(geo, nav, nominal, cfg);
    EXPECT_NE(res.termination, Termination::kNoOverlap) << res.message;
    EXPECT_LE(res.segment.max_position_stddev_m, cfg.max_position_stddev_m) << res.message;
    EXPECT_LE(res.segment.end_s, 100.0 + 1e-6);
    EXPECT_NEAR(res.segment.end_s - res.segment.start_s, 80.0, 1e-6);
}

// Verification only on low-drift segments: the INS drifts (GNSS outage) from 100 s on, so the
// crossing passes there say nothing about the mount (their positions are metres off) and the
// calibration on the first two passes is not verified instead of being checked against them.
TEST(Boresight, DriftingSegmentsAreNotUsedForVerification) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const std::vector<Pass> passes = {{0.0, {0, -20}, {0, 1}, 40},
                                      {40.0, {4, 20}, {0, -1}, 40},
                                      {120.0, {-20, 2}, {1, 0}, 40},
                                      {160.0, {20, -3}, {-1, 0}, 40}};
    const GeorefResult geo = Survey(passes, truth, nominal);
    const survey::NavSeries nav = InsSigmas(210, 100.0);
    BoresightConfig cfg;
    cfg.segment_duration_s = 80;
    cfg.num_verify_segments = 2;
    const BoresightResult res = CalibrateBoresight(geo, nav, nominal, cfg);
    ASSERT_NE(res.termination, Termination::kNoOverlap) << res.message;
    EXPECT_LE(res.segment.end_s, 100.0 + 1e-6);
    bool drifting_candidate = false;
    for (const auto& c : res.candidates) {
        const bool apart = c.end_s <= res.segment.start_s || c.start_s >= res.segment.end_s;
        drifting_candidate |= apart && !c.low_drift && c.overlap_cells > 0;
    }
    EXPECT_TRUE(drifting_candidate) << "the survey must offer a drifting segment with overlap";
    for (const auto& v : res.verify) EXPECT_TRUE(v.segment.low_drift) << v.segment.start_s;
    EXPECT_TRUE(res.verify.empty());
}

TEST(Boresight, OnePassHasNoOverlapAndSaysSo) {
    const SonarMount truth = Mount(1.0, 0, 0), nominal = Mount(0, 0, 0);
    const GeorefResult geo = Survey({{0.0, {0, -20}, {0, 1}, 15}}, truth, nominal);
    const BoresightResult res = CalibrateBoresight(geo, {}, nominal, BoresightConfig{});
    EXPECT_EQ(res.termination, Termination::kNoOverlap);
    EXPECT_STREQ(ToString(res.termination), "no_overlap");
    EXPECT_NE(res.message.find("no overlap"), std::string::npos) << res.message;
    EXPECT_EQ(res.mount.boresight_roll_deg, 0.0);  // unchanged
}

// Verification seeks pairs from every other sample only (verify_query_every): those it finds
// are the very pairs the full search finds for the same samples, against all the samples.
TEST(PassPairs, QueryingEveryOtherSampleGivesTheSamePairsForThoseSamples) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const GeorefResult geo =
        Survey({{0.0, {0, -20}, {0, 1}, 40}, {60.0, {4, 20}, {0, -1}, 40}}, truth, nominal);
    const BoresightConfig cfg;
    detail::Samples all = detail::Collect(geo, 0.0, 1e9, cfg.beam_stride);
    const Pose T_vs = nominal.T_vehicle_sonar();
    std::vector<Eigen::Vector3d> p(all.ping.size());
    for (std::size_t k = 0; k < p.size(); ++k)
        p[k] = geo.pings[all.ping[k]].T_world_vehicle * (T_vs * all.s_sonar[k]);
    detail::Samples half = all;
    half.query_every = 2;
    detail::IndexOwnPasses(p, all, cfg);
    detail::IndexOwnPasses(p, half, cfg);
    const auto a = detail::FindPairs(p, all, cfg, 0.5);
    const auto h = detail::FindPairs(p, half, cfg, 0.5);
    ASSERT_EQ(a.size(), h.size());
    std::size_t found = 0, odd_targets = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        if (k % 2 == 1) {
            EXPECT_FALSE(h[k].ok) << k;
            EXPECT_EQ(half.own_begin[k + 1], half.own_begin[k]) << "not indexed: " << k;
            continue;
        }
        ASSERT_EQ(h[k].ok, a[k].ok) << k;
        if (!h[k].ok) continue;
        ++found;
        odd_targets += h[k].c.target % 2;
        EXPECT_EQ(h[k].c.target, a[k].c.target) << k;
        EXPECT_DOUBLE_EQ(h[k].r, a[k].r) << k;
    }
    EXPECT_GT(found, 1000u);
    EXPECT_GT(odd_targets, found / 4) << "the samples that seek no pair are still paired with";
}

TEST(Boresight, ConfigValidationListsEveryProblem) {
    BoresightConfig c;
    c.segment_duration_s = 0;
    c.beam_stride = 0;
    c.height_offset_sigma_m = -1;
    c.verify_query_every = 0;
    const auto p = c.Validate();
    EXPECT_EQ(p.size(), 4u);
    EXPECT_TRUE(BoresightConfig{}.Validate().empty());
}

// Decision 033: the calibration reading the view a block at a time (a ViewReader, as the
// pipeline reads its file) gives the calibration of the view held, to the bit: the same
// candidate windows and their overlap, the same samples, the same mount, latency and residuals.
TEST(Boresight, AViewReadByBlocksGivesTheHeldViewsCalibration) {
    const SonarMount truth = Mount(1.0, -0.8, 1.5), nominal = Mount(0, 0, 0);
    const std::vector<Pass> passes = {{0.0, {0, -20}, {0, 1}, 40},
                                      {60.0, {4, 20}, {0, -1}, 40},
                                      {120.0, {-20, 2}, {1, 0}, 40},
                                      {180.0, {20, -3}, {-1, 0}, 40}};
    const GeorefResult geo = Survey(passes, truth, nominal);
    const survey::NavSeries nav = InsSigmas(230, 1e9);
    BoresightConfig cfg;
    cfg.segment_duration_s = 130;  // several candidates, and segments to verify on
    cfg.estimate_latency = true;
    const BoresightResult held = CalibrateBoresight(geo, nav, nominal, cfg);
    ASSERT_NE(held.termination, Termination::kNoOverlap) << held.message;
    ASSERT_GT(held.candidates.size(), 2u);
    GeorefResult pings_only = geo;
    pings_only.points = georef::GeorefPoints{};
    for (const std::size_t block : {std::size_t{1000}, std::size_t{4999}, std::size_t{1} << 30}) {
        std::size_t reads = 0;
        ViewReader reader;
        reader.size = geo.points.size();
        reader.read = [&](std::size_t first, std::size_t end, const ViewVisit& visit) {
            for (std::size_t b = first; b < end; b += block) {
                const std::size_t e = std::min(end, b + block);
                georef::GeorefPoints P;
                const auto cut = [&](const auto& v) {
                    return std::decay_t<decltype(v)>(v.begin() + static_cast<std::ptrdiff_t>(b),
                                                     v.begin() + static_cast<std::ptrdiff_t>(e));
                };
                P.position_world = cut(geo.points.position_world);
                P.ping = cut(geo.points.ping);
                P.beam = cut(geo.points.beam);
                P.range_m = cut(geo.points.range_m);
                P.angle_rad = cut(geo.points.angle_rad);
                visit(P, b, 0, P.size());
                reads += P.size();
            }
            return true;
        };
        const BoresightResult by = CalibrateBoresight(pings_only, reader, nav, nominal, cfg);
        SCOPED_TRACE(block);
        EXPECT_GT(reads, geo.points.size()) << "the view is read by windows";
        EXPECT_EQ(by.message, held.message);
        EXPECT_EQ(by.mount.boresight_roll_deg, held.mount.boresight_roll_deg);
        EXPECT_EQ(by.mount.boresight_pitch_deg, held.mount.boresight_pitch_deg);
        EXPECT_EQ(by.mount.boresight_yaw_deg, held.mount.boresight_yaw_deg);
        EXPECT_EQ(by.latency_s, held.latency_s);
        EXPECT_EQ(by.before.rms_m, held.before.rms_m);
        EXPECT_EQ(by.after.rms_m, held.after.rms_m);
        EXPECT_EQ(by.after.pairs, held.after.pairs);
        EXPECT_EQ(by.segment.start_s, held.segment.start_s);
        ASSERT_EQ(by.candidates.size(), held.candidates.size());
        for (std::size_t c = 0; c < by.candidates.size(); ++c) {
            EXPECT_EQ(by.candidates[c].overlap_cells, held.candidates[c].overlap_cells) << c;
        }
        ASSERT_EQ(by.verify.size(), held.verify.size());
        for (std::size_t v = 0; v < by.verify.size(); ++v) {
            EXPECT_EQ(by.verify[v].after.rms_m, held.verify[v].after.rms_m) << v;
            EXPECT_EQ(by.verify[v].before.pairs, held.verify[v].before.pairs) << v;
        }
    }
}

}  // namespace
}  // namespace pitmap::proc::calib
