// SPDX-License-Identifier: MIT
// IHO S-44 quality control (processor/hydro/s44.hpp): the Table 1 limits; the shares of
// soundings and nodes within them; a holiday made on purpose is found where it is and sized,
// while a gap smaller than the feature, a gap open to the outside and the orders without full
// coverage give none; the crossline check finds a bias between crossing passes, by beam
// angle, and ignores passes that do not cross or are too recent; the soundings given a block
// at a time (S44ByBlocks) give the same result bit for bit.
#include "processor/hydro/s44.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <random>

namespace pitmap::proc::hydro {
namespace {

TEST(S44, LimitsAreTable1) {
    // TVU = sqrt(a^2 + (b d)^2), THU = c + k d (S-44 Ed. 6.1.0, Table 1).
    EXPECT_NEAR(LimitsOf(S44Order::kExclusive).Tvu(10), std::hypot(0.15, 0.075), 1e-12);
    EXPECT_NEAR(LimitsOf(S44Order::kSpecial).Tvu(20), std::hypot(0.25, 0.15), 1e-12);
    EXPECT_NEAR(LimitsOf(S44Order::kOrder1a).Tvu(10), std::hypot(0.5, 0.13), 1e-12);
    EXPECT_NEAR(LimitsOf(S44Order::kOrder1b).Tvu(0), 0.5, 1e-12);
    EXPECT_NEAR(LimitsOf(S44Order::kOrder2).Tvu(100), std::hypot(1.0, 2.3), 1e-12);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kExclusive).Thu(50), 0.5);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kSpecial).Thu(50), 2.0);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kOrder1a).Thu(20), 6.0);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kOrder2).Thu(20), 22.0);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kOrder1a).FeatureSize(30), 2.0);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kOrder1a).FeatureSize(60), 6.0);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kSpecial).FeatureSize(60), 1.0);
    EXPECT_DOUBLE_EQ(LimitsOf(S44Order::kOrder1b).FeatureSize(10), 0.0);
    EXPECT_EQ(std::string(ToString(S44Order::kOrder1a)), "1a");
}

// A flat bottom 10 m deep, a grid of nx x ny nodes at `res`, every node filled except `empty`.
S44Grid Flat(int nx, int ny, double res, const std::function<bool(int, int)>& empty) {
    S44Grid g;
    g.nx = nx;
    g.ny = ny;
    g.resolution_m = res;
    g.x0 = 1000;
    g.y0 = 2000;
    const std::size_t n = static_cast<std::size_t>(nx) * ny;
    g.elevation_m.assign(n, -10.0f);
    g.uncertainty_m.assign(n, 0.2f);
    g.depth_m.assign(n, 10.0f);
    for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
            if (empty(i, j)) {
                g.elevation_m[static_cast<std::size_t>(j) * nx + i] = std::nanf("");
                g.depth_m[static_cast<std::size_t>(j) * nx + i] = std::nanf("");
            }
        }
    }
    return g;
}

TEST(S44, SharesWithinTheLimits) {
    S44Soundings s;
    // 100 soundings at 10 m: TVU 0.1 .. 1.09 m, THU 0.2 m.
    for (int k = 0; k < 100; ++k) {
        s.x.push_back(1000 + 0.5 * (k % 10));
        s.y.push_back(2000 + 0.5 * (k / 10));
        s.z.push_back(-10);
        s.depth_m.push_back(10);
        s.tvu_95_m.push_back(0.1f + 0.01f * k);
        s.thu_95_m.push_back(0.2f);
        s.angle_deg.push_back(0);
        s.ping.push_back(0);
    }
    s.ping_t_s = {0};
    s.ping_yaw_rad = {0};
    S44Grid g = Flat(10, 10, 0.5, [](int, int) { return false; });
    g.uncertainty_m[0] = 0.6f;  // beyond 1a's 0.517 m
    const S44Result r = RunS44(s, g, S44Config{});
    EXPECT_EQ(r.soundings, 100);
    EXPECT_EQ(r.nodes, 100);
    // Exclusive: TVU 0.168 -> 0.10..0.16 pass (7); special 0.261 -> 0.10..0.26 (17);
    // 1a/1b 0.517 -> 0.10..0.51 (42); 2 1.026 -> 0.10..1.02 (93).
    EXPECT_DOUBLE_EQ(r.soundings_within_tvu[0], 0.07);
    EXPECT_DOUBLE_EQ(r.soundings_within_tvu[1], 0.17);
    EXPECT_DOUBLE_EQ(r.soundings_within_tvu[2], 0.42);
    EXPECT_DOUBLE_EQ(r.soundings_within_tvu[4], 0.93);
    EXPECT_DOUBLE_EQ(r.soundings_within_thu[0], 1.0);
    EXPECT_DOUBLE_EQ(r.soundings_within_both[2], 0.42);
    EXPECT_DOUBLE_EQ(r.nodes_within_tvu[2], 0.99);
    EXPECT_DOUBLE_EQ(r.nodes_within_tvu[0], 0.0);
    EXPECT_EQ(StrictestOrderMet(r), -1);
    EXPECT_EQ(StrictestOrderMet(r, 0.9), 4);
}

TEST(S44, NodeThuFromTheSoundingsWithinTheCaptureDistance) {
    // Issue 39: a node's THU is the mean THU of the soundings within their capture distance of
    // it (CUBE's rule), not of the soundings nearest it. One row of 6 nodes, 1 m apart, at
    // x = 1000 .. 1005, 10 m deep: capture distance clamp(0.05 x 10, 0.71, 1.5) = 0.71 m.
    // Node 4 is empty; node 5 is filled but no sounding reaches it.
    S44Grid g = Flat(6, 1, 1.0, [](int i, int) { return i == 4; });
    S44Soundings s;
    // Sounding (x - 1000, THU): A (0.0, 0.1), B (0.4, 0.7), C (2.0, 2.8), D (2.6, 1.0). Within
    // 0.71 m: node 0 <- A (0), B (0.4); node 1 <- B (0.6); node 2 <- C (0), D (0.6);
    // node 3 <- D (0.4) (A, C are 1.0 m from node 1, C 1.0 m from node 3).
    const double xs[] = {0.0, 0.4, 2.0, 2.6};
    const float thu[] = {0.1f, 0.7f, 2.8f, 1.0f};
    for (int k = 0; k < 4; ++k) {
        s.x.push_back(1000 + xs[k]);
        s.y.push_back(2000);
        s.z.push_back(-10);
        s.depth_m.push_back(10);
        s.tvu_95_m.push_back(0.1f);
        s.thu_95_m.push_back(thu[k]);
        s.angle_deg.push_back(0);
        s.ping.push_back(0);
    }
    s.ping_t_s = {0};
    s.ping_yaw_rad = {0};
    const S44Result r = RunS44(s, g, S44Config{});
    // Node THU: 0 (0.1 + 0.7) / 2 = 0.4, 1 0.7, 2 (2.8 + 1.0) / 2 = 1.9, 3 1.0; node 5 none.
    // Limits at 10 m: exclusive 0.5 (node 0 only: 1 of 4), special 2.0 (all 4), 1a, 1b
    // 5.5 and 2 21 (all 4). The nearest-node rule gave node 1 no THU, node 2 C's 2.8 alone:
    // exclusive 1/5, special 2/5, 1a 3/5.
    EXPECT_EQ(r.nodes, 5);
    EXPECT_EQ(r.nodes_without_thu, 1);
    EXPECT_DOUBLE_EQ(r.nodes_within_thu[0], 0.25);
    EXPECT_DOUBLE_EQ(r.nodes_within_thu[1], 1.0);
    EXPECT_DOUBLE_EQ(r.nodes_within_thu[2], 1.0);
    EXPECT_DOUBLE_EQ(r.nodes_within_thu[4], 1.0);
    // Soundings: THU <= 0.5: A only (1 of 4); <= 2.0: A, B, D (3 of 4); <= 5.5: all.
    EXPECT_DOUBLE_EQ(r.soundings_within_thu[0], 0.25);
    EXPECT_DOUBLE_EQ(r.soundings_within_thu[1], 0.75);
    EXPECT_DOUBLE_EQ(r.soundings_within_thu[2], 1.0);

    // A capture distance of at most 0.45 resolutions: node 1 (B 0.6 m away) and node 2 (C
    // 0 m, D 0.6 m: C alone, 2.8) change. Nodes with a THU: 0 (A, B: 0.4), 2 (C: 2.8),
    // 3 (D: 1.0); nodes 1 and 5 have none. Exclusive 1/3, special 2/3.
    g.capture_min_res = 0.1;
    g.capture_max_res = 0.45;
    const S44Result t = RunS44(s, g, S44Config{});
    EXPECT_EQ(t.nodes_without_thu, 2);
    EXPECT_DOUBLE_EQ(t.nodes_within_thu[0], 1.0 / 3.0);
    EXPECT_DOUBLE_EQ(t.nodes_within_thu[1], 2.0 / 3.0);
    EXPECT_DOUBLE_EQ(t.nodes_within_thu[2], 1.0);
}

TEST(S44, HolidayMadeOnPurposeIsFoundWhereItIs) {
    // 0.1 m nodes, 200 x 150; the survey area is a disc of radius 7 m; a 1.5 m square gap in
    // it at nodes 120..134 x 60..74 (centre 1012.7, 2006.7), a 0.5 m gap at 40..44 x 40..44,
    // and a notch from the disc's edge.
    const auto outside = [](int i, int j) { return std::hypot(i - 100, j - 75) > 70; };
    const auto big = [](int i, int j) { return i >= 120 && i < 135 && j >= 60 && j < 75; };
    const auto small = [](int i, int j) { return i >= 60 && i < 65 && j >= 70 && j < 75; };
    const auto notch = [](int i, int j) { return i >= 95 && i < 105 && j < 40; };
    S44Grid g = Flat(200, 150, 0.1, [&](int i, int j) {
        return outside(i, j) || big(i, j) || small(i, j) || notch(i, j);
    });
    S44Soundings s;
    s.z = {-10};
    s.x = {1010};
    s.y = {2007};
    s.depth_m = {10};
    s.tvu_95_m = {0.1f};
    s.thu_95_m = {0.1f};
    s.angle_deg = {0};
    s.ping = {0};
    s.ping_t_s = {0};
    s.ping_yaw_rad = {0};
    S44Config c;
    c.order = S44Order::kSpecial;  // feature 1 m: the 1.5 m gap is a holiday, the 0.5 m one not
    S44Result r = RunS44(s, g, c);
    ASSERT_EQ(r.holidays.size(), 1u) << r.message;
    const S44Holiday& h = r.holidays[0];
    EXPECT_EQ(h.nodes, 225);
    EXPECT_NEAR(h.area_m2, 2.25, 1e-9);
    EXPECT_NEAR(h.largest_square_m, 1.5, 1e-9);
    EXPECT_NEAR(h.x, 1000 + 12.7, 1e-9);
    EXPECT_NEAR(h.y, 2000 + 6.7, 1e-9);
    EXPECT_NEAR(h.x_min, 1011.95, 1e-9);
    EXPECT_NEAR(h.y_max, 2007.45, 1e-9);
    EXPECT_EQ(r.gaps, 2);  // the notch is outside
    EXPECT_EQ(r.nodes_in_gaps, 225 + 25);
    EXPECT_FLOAT_EQ(r.holiday_map[70 * 200 + 125], 2.0f);
    EXPECT_FLOAT_EQ(r.holiday_map[72 * 200 + 62], 1.0f);
    EXPECT_FLOAT_EQ(r.holiday_map[75 * 200 + 100], 0.0f);
    EXPECT_TRUE(std::isnan(r.holiday_map[10 * 200 + 100]));  // in the notch: outside
    EXPECT_DOUBLE_EQ(r.feature_size_m, 1.0);
    EXPECT_NEAR(r.coverage_share, 1.0 - 250.0 / r.nodes_survey_area, 1e-12);
    // Order 1a (2 m features): no holiday; order 1b (5 % coverage): none either.
    c.order = S44Order::kOrder1a;
    EXPECT_TRUE(RunS44(s, g, c).holidays.empty());
    c.order = S44Order::kOrder1b;
    r = RunS44(s, g, c);
    EXPECT_TRUE(r.holidays.empty());
    EXPECT_EQ(r.gaps, 2);
    // Exclusive (0.5 m features): both gaps.
    c.order = S44Order::kExclusive;
    EXPECT_EQ(RunS44(s, g, c).holidays.size(), 2u);
}

// Two passes over a 20 m slope: pass A (t 0..60 s) heading north, pass B (t 100..160 s)
// heading east with a +5 cm bias on its outer beams (|angle| >= 40 deg) only.
S44Soundings Passes(double heading_b_rad, double t_b) {
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(0, 20);
    std::normal_distribution<double> n(0, 0.01);
    S44Soundings s;
    const auto truth = [](double x, double y) { return -10.0 + 0.2 * x - 0.1 * y; };
    for (int p = 0; p < 2; ++p) {
        s.ping_t_s.push_back(p == 0 ? 30.0 : t_b);
        s.ping_yaw_rad.push_back(p == 0 ? 0.0 : heading_b_rad);
    }
    for (int k = 0; k < 200000; ++k) {
        const int p = k % 2;
        const double x = 1000 + u(rng), y = 2000 + u(rng);
        const float angle = static_cast<float>(-60 + 120 * u(rng) / 20);
        double z = truth(x - 1000, y - 2000) + n(rng);
        if (p == 1 && std::abs(angle) >= 40) z += 0.05;
        s.x.push_back(x);
        s.y.push_back(y);
        s.z.push_back(z);
        s.depth_m.push_back(static_cast<float>(-z));
        s.tvu_95_m.push_back(0.05f);
        s.thu_95_m.push_back(0.05f);
        s.angle_deg.push_back(angle);
        s.ping.push_back(static_cast<std::uint32_t>(p));
    }
    return s;
}

TEST(S44, CrosslineFindsTheBiasOfTheCrossingPassByBeamAngle) {
    S44Grid g;
    g.nx = g.ny = 46;
    g.resolution_m = 0.5;
    g.x0 = 999;
    g.y0 = 1999;
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            g.elevation_m.push_back(
                static_cast<float>(-10.0 + 0.2 * (0.5 * i - 1) - 0.1 * (0.5 * j - 1)));
            g.uncertainty_m.push_back(0.05f);
            g.depth_m.push_back(10.0f);
        }
    }
    S44Config c;
    c.crossline_cell_m = 1.0;
    const S44Result r = RunS44(Passes(M_PI / 2, 130.0), g, c);
    // Only pass B's soundings are compared (with pass A, 100 s earlier, crossing at 90 deg).
    EXPECT_NEAR(static_cast<double>(r.crossline_compared), 100000, 2000);
    ASSERT_EQ(r.crossline_by_angle.size(), 6u);
    for (const S44AngleBin& b : r.crossline_by_angle) {
        const double expected = b.angle_lo_deg >= 40 ? 0.05 : 0.0;
        EXPECT_NEAR(b.mean_m, expected, 0.005) << b.angle_lo_deg;
        EXPECT_NEAR(b.sd_m, 0.0105, 0.004) << b.angle_lo_deg;  // sqrt(0.01^2 + 0.01^2 / n)
        EXPECT_GT(b.within_tvu, 0.99);
    }
    EXPECT_NEAR(r.crossline_mean_m, 0.05 / 3, 0.005);
    // A pass along the same heading does not cross; one 10 s later is too recent.
    EXPECT_EQ(RunS44(Passes(M_PI, 130.0), g, c).crossline_compared, 0);
    EXPECT_EQ(RunS44(Passes(M_PI / 2, 40.0), g, c).crossline_compared, 0);
}

// Soundings first .. first + count - 1 of `s` (the pings' arrays left out, as a block).
S44Soundings Slice(const S44Soundings& s, std::size_t first, std::size_t count) {
    S44Soundings b;
    const auto take = [&](const auto& from, auto& to) {
        to.assign(from.begin() + static_cast<std::ptrdiff_t>(first),
                  from.begin() + static_cast<std::ptrdiff_t>(first + count));
    };
    take(s.x, b.x);
    take(s.y, b.y);
    take(s.z, b.z);
    take(s.depth_m, b.depth_m);
    take(s.thu_95_m, b.thu_95_m);
    take(s.tvu_95_m, b.tvu_95_m);
    take(s.angle_deg, b.angle_deg);
    take(s.ping, b.ping);
    return b;
}

bool SameBits(double a, double b) {
    return std::memcmp(&a, &b, sizeof a) == 0;
}

// S44ByBlocks (decision 035): the soundings given a block at a time, twice, give RunS44's
// result bit for bit: the shares, the node THU, the holidays, the crossline sums.
TEST(S44, BlocksGiveTheWholeSurveysResultBitForBit) {
    S44Grid g = Flat(46, 46, 0.5, [](int i, int j) {
        return (i > 20 && i < 29 && j > 20 && j < 29) || i + j < 4;
    });
    g.x0 = 999;
    g.y0 = 1999;
    for (std::size_t q = 0; q < g.elevation_m.size(); ++q) {
        if (std::isfinite(g.elevation_m[q])) g.elevation_m[q] += 0.01f * static_cast<float>(q % 7);
    }
    S44Soundings s = Passes(M_PI / 2, 130.0);
    for (std::size_t j = 0; j < s.z.size(); j += 101) s.depth_m[j] = std::nanf("");
    for (std::size_t j = 0; j < s.z.size(); j += 307) s.thu_95_m[j] = 0.9f;
    S44Config c;
    c.crossline_cell_m = 1.0;
    c.order = S44Order::kSpecial;
    const S44Result whole = RunS44(s, g, c);
    ASSERT_GT(whole.crossline_compared, 1000);
    ASSERT_FALSE(whole.holidays.empty());
    for (std::size_t block : {std::size_t{1}, std::size_t{977}, s.z.size(), 3 * s.z.size()}) {
        SCOPED_TRACE(block);
        S44ByBlocks blocks(g, c, s.ping_t_s, s.ping_yaw_rad);
        for (std::size_t f = 0; f < s.z.size(); f += block)
            blocks.AddFirst(Slice(s, f, std::min(block, s.z.size() - f)));
        for (std::size_t f = 0; f < s.z.size(); f += block)
            blocks.AddSecond(Slice(s, f, std::min(block, s.z.size() - f)));
        const S44Result r = blocks.Finish();
        EXPECT_EQ(r.message, whole.message);
        EXPECT_EQ(r.soundings, whole.soundings);
        EXPECT_EQ(r.nodes, whole.nodes);
        EXPECT_EQ(r.nodes_without_thu, whole.nodes_without_thu);
        for (int o = 0; o < kNumS44Orders; ++o) {
            EXPECT_TRUE(SameBits(r.soundings_within_both[o], whole.soundings_within_both[o]));
            EXPECT_TRUE(SameBits(r.nodes_within_thu[o], whole.nodes_within_thu[o]));
            EXPECT_TRUE(SameBits(r.nodes_within_tvu[o], whole.nodes_within_tvu[o]));
        }
        EXPECT_EQ(r.holidays.size(), whole.holidays.size());
        EXPECT_TRUE(SameBits(r.feature_size_m, whole.feature_size_m));
        EXPECT_EQ(r.holiday_map.size(), whole.holiday_map.size());
        EXPECT_EQ(0,
                  std::memcmp(r.holiday_map.data(),
                              whole.holiday_map.data(),
                              whole.holiday_map.size() * sizeof(float)));
        EXPECT_EQ(r.crossline_compared, whole.crossline_compared);
        EXPECT_TRUE(SameBits(r.crossline_mean_m, whole.crossline_mean_m));
        EXPECT_TRUE(SameBits(r.crossline_rms_m, whole.crossline_rms_m));
        EXPECT_TRUE(SameBits(r.crossline_sd_m, whole.crossline_sd_m));
        ASSERT_EQ(r.crossline_by_angle.size(), whole.crossline_by_angle.size());
        for (std::size_t b = 0; b < r.crossline_by_angle.size(); ++b) {
            EXPECT_TRUE(SameBits(r.crossline_by_angle[b].rms_m, whole.crossline_by_angle[b].rms_m));
            EXPECT_EQ(r.crossline_by_angle[b].count, whole.crossline_by_angle[b].count);
        }
    }
}

TEST(S44, ValidateListsEveryProblem) {
    S44Config c;
    EXPECT_TRUE(c.Validate().empty());
    c.min_holiday_nodes = 0;
    c.crossing_angle_deg = 100;
    c.min_time_separation_s = -1;
    c.crossline_cell_m = -1;
    c.min_reference_soundings = 0;
    EXPECT_EQ(c.Validate().size(), 5u);
}

TEST(S44, OrderNamesRoundTrip) {
    for (int k = 0; k < kNumS44Orders; ++k) {
        S44Order o = S44Order::kOrder2;
        ASSERT_TRUE(S44OrderFromString(ToString(static_cast<S44Order>(k)), &o));
        EXPECT_EQ(static_cast<int>(o), k);
    }
    S44Order o = S44Order::kSpecial;
    EXPECT_FALSE(S44OrderFromString("1A", &o));
    EXPECT_FALSE(S44OrderFromString("", &o));
    EXPECT_FALSE(S44OrderFromString("3", &o));
    EXPECT_EQ(o, S44Order::kSpecial);
}

}  // namespace
}  // namespace pitmap::proc::hydro
