// SPDX-License-Identifier: MIT
// The backscatter mosaic's maths (processor/hydro/mosaic.hpp): intensity to dB, the range
// terms, incidence on the DEM's slopes, the angular responses, and the whole correction on a
// synthetic seabed of known backscatter seen by a sonar with spreading, absorption and a
// non-Lambertian angular response.
#include "processor/hydro/mosaic.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>

namespace pitmap::proc::hydro {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

TEST(Mosaic, IntensityIsAnAmplitudeInDb) {
    EXPECT_DOUBLE_EQ(IntensityDb(1), 0.0);
    EXPECT_NEAR(IntensityDb(1000), 60.0, 1e-12);
    EXPECT_NEAR(IntensityDb(65534), 96.329334, 1e-5);
    EXPECT_DOUBLE_EQ(IntensityDb(0), 0.0);  // never -inf (0 is "none" and not used)
}

TEST(Mosaic, RangeLossIsTwoWaySpreadingAndAbsorption) {
    MosaicConfig c;  // 40 log10 R + 2 x 0.021 R
    EXPECT_NEAR(RangeLossDb(1.0, c), 0.042, 1e-12);
    EXPECT_NEAR(RangeLossDb(10.0, c), 40.42, 1e-12);
    EXPECT_NEAR(RangeLossDb(100.0, c), 80.0 + 4.2, 1e-12);
    c.spreading_db_per_decade = 20;
    c.absorption_db_per_m = 0;
    EXPECT_NEAR(RangeLossDb(50.0, c), 20 * std::log10(50.0), 1e-12);
}

TEST(Mosaic, IncidenceIsBetweenTheBeamAndTheSurfaceNormal) {
    const Eigen::Vector3d up(0, 0, 1);
    EXPECT_NEAR(IncidenceDeg(Eigen::Vector3d(0, 0, -1), up), 0.0, 1e-9);
    const double a = 60 * kPi / 180;
    const Eigen::Vector3d beam(std::sin(a), 0, -std::cos(a));
    EXPECT_NEAR(IncidenceDeg(beam, up), 60.0, 1e-9);
    // The same beam on a 60 deg slope facing it meets it square on; on one facing away, grazes.
    EXPECT_NEAR(IncidenceDeg(beam, Eigen::Vector3d(-std::sin(a), 0, std::cos(a))), 0.0, 1e-6);
    EXPECT_NEAR(IncidenceDeg(beam, Eigen::Vector3d(std::sin(a), 0, std::cos(a))), 90.0, 1e-6);
    // From below: 90 (never a negative or NaN angle).
    EXPECT_DOUBLE_EQ(IncidenceDeg(Eigen::Vector3d(0, 0, 1), up), 90.0);
}

TEST(Mosaic, DemNormalFollowsAPlaneEvenAtEdgesAndHoles) {
    const int nx = 6, ny = 5;
    const double res = 0.5;
    std::vector<float> z(nx * ny);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i)
            z[j * nx + i] = static_cast<float>(5.0 + 0.3 * i * res - 0.2 * j * res);
    z[2 * nx + 3] = kNaN;  // a hole: its neighbours go one-sided
    MosaicGrid g{100, 200, res, nx, ny, &z};
    const Eigen::Vector3d want = Eigen::Vector3d(-0.3, 0.2, 1.0).normalized();
    for (auto [i, j] : {std::pair{0, 0}, {2, 2}, {4, 2}, {3, 1}, {5, 4}, {3, 2}}) {
        EXPECT_NEAR((DemNormal(g, i, j) - want).norm(), 0.0, 1e-5) << i << " " << j;
    }
    std::vector<float> lone(9, kNaN);
    lone[4] = 3.0f;
    MosaicGrid one{0, 0, 1.0, 3, 3, &lone};
    EXPECT_NEAR((DemNormal(one, 1, 1) - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);
}

TEST(Mosaic, LambertResponseIsCosSquaredInDb) {
    const AngularResponse r = LambertResponse(1.0, 80.0);
    ASSERT_EQ(r.level_db.size(), 80u);
    EXPECT_NEAR(r.At(0.5), 20 * std::log10(std::cos(0.5 * kPi / 180)), 1e-9);
    EXPECT_NEAR(r.At(60.0), 20 * std::log10(0.5), 0.01);  // between bin centres: linear
    EXPECT_NEAR(r.At(45.5), 20 * std::log10(std::cos(45.5 * kPi / 180)), 1e-9);
}

TEST(Mosaic, EmpiricalResponseIsTheBinMeanWithThinBinsInterpolated) {
    MosaicConfig c;
    c.angle_bin_deg = 2.0;
    c.max_incidence_deg = 40.0;
    c.min_bin_soundings = 5;
    std::vector<float> level, inc;
    for (int k = 0; k < 20; ++k) {
        if (k == 7) continue;                           // bin 7 (14..16 deg) empty
        for (int n = 0; n < (k == 12 ? 3 : 10); ++n) {  // bin 12 thin
            const double t = 2.0 * k + 0.2 * n;
            inc.push_back(static_cast<float>(t));
            level.push_back(static_cast<float>(50.0 - 0.5 * (2.0 * k + 1.0) + (n % 2 ? 1 : -1)));
        }
    }
    const AngularResponse r = EstimateAngularResponse(level, inc, c);
    ASSERT_EQ(r.level_db.size(), 20u);
    for (int k = 0; k < 20; ++k) {
        EXPECT_NEAR(r.level_db[k], 50.0 - 0.5 * (2.0 * k + 1.0), 1e-4) << "bin " << k;
    }
    EXPECT_EQ(r.counts[7], 0);
    EXPECT_EQ(r.counts[12], 3);
}

// A seabed of 3 m squares of four materials (and a 2 m boulder), surveyed by parallel lines
// 8 m apart at 10 m depth over a DEM with a 15 deg slope on one side; the echo follows the
// sonar equation with a specular lobe that Lambert's law lacks.
struct Synthetic {
    std::vector<float> dem;
    MosaicGrid grid;
    MosaicSoundings soundings;
    std::vector<double> truth_db;  // per node
};

double TrueBs(double x, double y) {
    if (std::hypot(x - 21.0, y - 20.0) < 1.0) return -8.0;  // boulder
    static const double levels[4] = {-14, -20, -26, -32};
    const long ix = static_cast<long>(std::floor(x / 3.0)),
               iy = static_cast<long>(std::floor(y / 3.0));
    return levels[static_cast<std::size_t>(((ix * 7 + iy * 13) % 4 + 4) % 4)];
}

double Ground(double x) {
    return x < 30 ? -10.0 : -10.0 + (x - 30) * std::tan(15 * kPi / 180);
}

Synthetic MakeSurvey(double specular_db, double speckle_db) {
    Synthetic s;
    const double res = 0.5;
    const int nx = 100, ny = 80;  // 50 m x 40 m
    s.dem.resize(nx * ny);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) s.dem[j * nx + i] = static_cast<float>(Ground(i * res));
    s.grid = {0.0, 0.0, res, nx, ny, &s.dem};
    std::mt19937_64 rng(11);
    std::normal_distribution<double> noise(0.0, 1.0);
    const double sl = 110, k = 40, a = 0.021;
    for (double line_x = 6; line_x <= 44; line_x += 8) {
        for (double y = 2; y <= 38; y += 0.25) {
            const Eigen::Vector3d head(line_x, y, 0.0);
            for (int b = -60; b <= 60; ++b) {
                const double theta = b * kPi / 180;
                // March along the beam to the ground.
                const Eigen::Vector3d u(std::sin(theta), 0, -std::cos(theta));
                double t = 0;
                while (t < 80 && (head + t * u).z() > Ground((head + t * u).x())) t += 0.01;
                const Eigen::Vector3d p = head + t * u;
                if (t >= 80 || p.x() < 0 || p.x() > 49.5) continue;
                const double slope = p.x() < 30 ? 0.0 : 15 * kPi / 180;
                const Eigen::Vector3d n(-std::sin(slope), 0, std::cos(slope));
                const double inc = IncidenceDeg(u, n);
                const double ar = 20 * std::log10(std::cos(inc * kPi / 180)) +
                                  specular_db * std::exp(-std::pow(inc / 10.0, 2));
                const double level = sl - k * std::log10(t) - 2 * a * t + TrueBs(p.x(), p.y()) +
                                     ar + speckle_db * noise(rng);
                s.soundings.x.push_back(p.x());
                s.soundings.y.push_back(p.y());
                s.soundings.intensity.push_back(static_cast<std::uint16_t>(
                    std::clamp(std::round(std::pow(10.0, level / 20)), 1.0, 65535.0)));
                s.soundings.range_m.push_back(static_cast<float>(t));
                s.soundings.beam_dir.push_back(u.cast<float>());
            }
        }
    }
    s.truth_db.resize(nx * ny);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) s.truth_db[j * nx + i] = TrueBs(i * res, j * res);
    return s;
}

struct Score {
    double rms_db = 0;            // after the median offset
    double patch_max_abs_db = 0;  // per truth level
    double correlation = 0;
};

// Nodes whose footprint lies on one material, offset removed (the mosaic is relative).
Score ScoreAgainstTruth(const Synthetic& s, const std::vector<float>& mosaic) {
    std::vector<double> d, e, t;
    const int nx = s.grid.nx;
    for (int j = 1; j + 1 < s.grid.ny; ++j) {
        for (int i = 1; i + 1 < nx; ++i) {
            const std::size_t q = static_cast<std::size_t>(j * nx + i);
            if (!std::isfinite(mosaic[q])) continue;
            const double x = i * s.grid.resolution_m, y = j * s.grid.resolution_m;
            bool uniform = true;
            for (double dx : {-0.4, 0.4})
                for (double dy : {-0.4, 0.4}) uniform &= TrueBs(x + dx, y + dy) == s.truth_db[q];
            if (!uniform) continue;
            d.push_back(mosaic[q] - s.truth_db[q]);
            e.push_back(mosaic[q]);
            t.push_back(s.truth_db[q]);
        }
    }
    EXPECT_GT(d.size(), 3000u);
    std::vector<double> sorted = d;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double offset = sorted[sorted.size() / 2];
    Score sc;
    std::map<double, std::pair<double, int>> by_level;
    double me = 0, mt = 0;
    for (std::size_t k = 0; k < d.size(); ++k) {
        sc.rms_db += (d[k] - offset) * (d[k] - offset);
        by_level[t[k]].first += d[k] - offset;
        ++by_level[t[k]].second;
        me += e[k];
        mt += t[k];
    }
    sc.rms_db = std::sqrt(sc.rms_db / d.size());
    for (const auto& [level, v] : by_level)
        sc.patch_max_abs_db = std::max(sc.patch_max_abs_db, std::abs(v.first / v.second));
    me /= d.size();
    mt /= d.size();
    double see = 0, stt = 0, set = 0;
    for (std::size_t k = 0; k < d.size(); ++k) {
        see += (e[k] - me) * (e[k] - me);
        stt += (t[k] - mt) * (t[k] - mt);
        set += (e[k] - me) * (t[k] - mt);
    }
    sc.correlation = set / std::sqrt(see * stt);
    return sc;
}

TEST(Mosaic, CorrectionRecoversTheSeabedAndEachTermMatters) {
    const Synthetic s = MakeSurvey(/*specular_db=*/6.0, /*speckle_db=*/0.0);
    MosaicConfig c;  // empirical, 40 log R + 2 x 0.021 R: the survey's own physics
    const MosaicResult r = RunMosaic(s.soundings, s.grid, c);
    ASSERT_TRUE(r.ok) << r.message;
    EXPECT_EQ(r.no_intensity + r.saturated + r.outside_grid, 0) << r.message;
    const Score corrected = ScoreAgainstTruth(s, r.corrected_db);
    const Score raw = ScoreAgainstTruth(s, r.uncorrected_db);
    std::printf(
        "corrected: rms %.2f dB, level max %.2f dB, r %.3f; uncorrected: rms %.2f dB, "
        "level max %.2f dB, r %.3f\n",
        corrected.rms_db,
        corrected.patch_max_abs_db,
        corrected.correlation,
        raw.rms_db,
        raw.patch_max_abs_db,
        raw.correlation);
    EXPECT_LT(corrected.rms_db, 0.6);
    EXPECT_LT(corrected.patch_max_abs_db, 0.4);
    EXPECT_GT(corrected.correlation, 0.99);
    // Uncorrected, the range and angle terms stay (averaged over the lines that overlap).
    EXPECT_GT(raw.rms_db, 2.0);
    EXPECT_GT(raw.rms_db, 10 * corrected.rms_db);
    EXPECT_LT(raw.correlation, 0.95);
    // The estimated response is the true one (relative to 45 deg) within a few tenths of a dB.
    const double ref = r.response.At(45);
    for (double t : {2.0, 10.0, 20.0, 35.0, 55.0}) {
        const double truth = 20 * std::log10(std::cos(t * kPi / 180)) +
                             6.0 * std::exp(-std::pow(t / 10.0, 2)) -
                             20 * std::log10(std::cos(45 * kPi / 180));
        EXPECT_NEAR(r.response.At(t) - ref, truth, 0.5) << t << " deg";
    }

    // Lambert's law leaves the specular lobe near nadir.
    c.angular = AngularCorrection::kLambert;
    const Score lambert = ScoreAgainstTruth(s, RunMosaic(s.soundings, s.grid, c).corrected_db);
    EXPECT_GT(lambert.rms_db, corrected.rms_db + 0.5);
    // No incidence correction at all, or no range correction: clearly worse.
    c.angular = AngularCorrection::kNone;
    const Score none = ScoreAgainstTruth(s, RunMosaic(s.soundings, s.grid, c).corrected_db);
    EXPECT_GT(none.rms_db, 1.0);
    EXPECT_GT(none.rms_db, 10 * corrected.rms_db);
    c = MosaicConfig{};
    c.spreading_db_per_decade = 0;
    c.absorption_db_per_m = 0;
    c.empirical_iterations = 0;
    const Score no_range = ScoreAgainstTruth(s, RunMosaic(s.soundings, s.grid, c).corrected_db);
    EXPECT_GT(no_range.rms_db, corrected.rms_db + 0.5);
}

TEST(Mosaic, WithoutASpecularLobeLambertIsExactAndSpeckleAverages) {
    const Synthetic s = MakeSurvey(/*specular_db=*/0.0, /*speckle_db=*/3.0);
    MosaicConfig c;
    c.angular = AngularCorrection::kLambert;
    const Score lambert = ScoreAgainstTruth(s, RunMosaic(s.soundings, s.grid, c).corrected_db);
    c.angular = AngularCorrection::kEmpirical;
    const Score empirical = ScoreAgainstTruth(s, RunMosaic(s.soundings, s.grid, c).corrected_db);
    // Several soundings a node: the 3 dB speckle averages down; the patches' means are right.
    EXPECT_LT(lambert.patch_max_abs_db, 0.4);
    EXPECT_LT(empirical.patch_max_abs_db, 0.4);
    EXPECT_GT(lambert.correlation, 0.9);
    EXPECT_GT(empirical.correlation, 0.9);
}

TEST(Mosaic, UnusableIntensitiesAreCountedNotUsed) {
    std::vector<float> dem(4, -10.0f);
    MosaicGrid g{0, 0, 1.0, 2, 2, &dem};
    MosaicSoundings s;
    const Eigen::Vector3f down(0, 0, -1);
    for (auto [x, I] : {std::pair{0.0, std::uint16_t{0}},
                        {0.0, std::uint16_t{65535}},
                        {5.0, std::uint16_t{100}},
                        {1.0, std::uint16_t{1000}}}) {
        s.x.push_back(x);
        s.y.push_back(0);
        s.intensity.push_back(I);
        s.range_m.push_back(10);
        s.beam_dir.push_back(down);
    }
    // Grazing beam: beyond max_incidence_deg.
    s.x.push_back(0);
    s.y.push_back(1);
    s.intensity.push_back(500);
    s.range_m.push_back(10);
    s.beam_dir.push_back(Eigen::Vector3f(1, 0, -0.05f).normalized());
    MosaicConfig c;
    c.angular = AngularCorrection::kNone;
    const MosaicResult r = RunMosaic(s, g, c);
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.no_intensity, 1);
    EXPECT_EQ(r.saturated, 1);
    EXPECT_EQ(r.outside_grid, 1);
    EXPECT_EQ(r.beyond_incidence, 1);
    EXPECT_EQ(r.used, 1);
    EXPECT_EQ(r.nodes_filled, 1);
    EXPECT_NEAR(r.uncorrected_db[1], 60.0, 1e-4);
    EXPECT_NEAR(r.corrected_db[1], 60.0 + 40.42, 1e-4);
    EXPECT_TRUE(std::isnan(r.corrected_db[0]));
    MosaicSoundings none = s;
    for (auto& v : none.intensity) v = 0;
    EXPECT_FALSE(RunMosaic(none, g, c).ok);
}

// MosaicByBlocks (decision 035): the soundings given a block at a time give RunMosaic's result
// bit for bit (the nodes' means, the angular response, the counts), for every correction.
TEST(Mosaic, BlocksGiveTheWholeSurveysMosaicBitForBit) {
    Synthetic s = MakeSurvey(/*specular_db=*/6.0, /*speckle_db=*/2.0);
    for (std::size_t j = 0; j < s.soundings.size(); j += 53) s.soundings.intensity[j] = 0;
    for (std::size_t j = 7; j < s.soundings.size(); j += 211) s.soundings.intensity[j] = 65535;
    const std::size_t n = s.soundings.size();
    const auto same = [](const std::vector<float>& a, const std::vector<float>& b) {
        return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * 4) == 0;
    };
    for (AngularCorrection a :
         {AngularCorrection::kEmpirical, AngularCorrection::kLambert, AngularCorrection::kNone}) {
        SCOPED_TRACE(ToString(a));
        MosaicConfig c;
        c.angular = a;
        const MosaicResult whole = RunMosaic(s.soundings, s.grid, c);
        ASSERT_TRUE(whole.ok);
        for (std::size_t block : {std::size_t{1}, std::size_t{4099}, n}) {
            SCOPED_TRACE(block);
            MosaicByBlocks blocks(s.grid, c);
            blocks.Reserve(n);
            for (std::size_t f = 0; f < n; f += block) {
                const std::size_t e = std::min(n, f + block);
                const auto d = [&](std::size_t k) { return static_cast<std::ptrdiff_t>(k); };
                MosaicSoundings b;
                b.x.assign(s.soundings.x.begin() + d(f), s.soundings.x.begin() + d(e));
                b.y.assign(s.soundings.y.begin() + d(f), s.soundings.y.begin() + d(e));
                b.intensity.assign(s.soundings.intensity.begin() + d(f),
                                   s.soundings.intensity.begin() + d(e));
                b.range_m.assign(s.soundings.range_m.begin() + d(f),
                                 s.soundings.range_m.begin() + d(e));
                b.beam_dir.assign(s.soundings.beam_dir.begin() + d(f),
                                  s.soundings.beam_dir.begin() + d(e));
                blocks.Add(b);
            }
            const MosaicResult r = blocks.Finish();
            EXPECT_EQ(r.message, whole.message);
            EXPECT_TRUE(same(r.corrected_db, whole.corrected_db));
            EXPECT_TRUE(same(r.uncorrected_db, whole.uncorrected_db));
            EXPECT_TRUE(same(r.count, whole.count));
            EXPECT_EQ(r.response.level_db, whole.response.level_db);
            EXPECT_EQ(r.response.counts, whole.response.counts);
            EXPECT_EQ(r.soundings_in, whole.soundings_in);
            EXPECT_EQ(r.no_intensity, whole.no_intensity);
            EXPECT_EQ(r.saturated, whole.saturated);
            EXPECT_EQ(r.used, whole.used);
            EXPECT_EQ(r.median_incidence_deg, whole.median_incidence_deg);
        }
    }
}

TEST(Mosaic, ConfigValidationListsEveryProblem) {
    EXPECT_TRUE(MosaicConfig{}.Validate().empty());
    MosaicConfig c;
    c.spreading_db_per_decade = -1;
    c.absorption_db_per_m = 2;
    c.reference_angle_deg = 85;
    c.angle_bin_deg = 0;
    c.min_bin_soundings = 0;
    c.empirical_iterations = -1;
    EXPECT_EQ(c.Validate().size(), 6u);
}

}  // namespace
}  // namespace pitmap::proc::hydro
