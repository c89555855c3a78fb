// SPDX-License-Identifier: MIT
// The INS terms in a GNSS outage (processor/slam/terms.cpp, SlamConfig::drift_by_smoothness_only,
// docs/decisions/022): a drift that is one realisation of the integrated random walk the INS
// reports costs what the drift-smoothness term says it should (about one per node), not three
// times that from the relative-motion and absolute terms counting the same drift again.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {
namespace {

struct Outage {
    Input in;
    Param p;
    std::vector<Pose> T;  // the INS poses corrected by the true drift
    std::size_t outage_nodes = 0;
};

// One node a second for 140 s, GNSS out from 20 s: the INS drifts east by an integrated random
// walk of density q and reports sigma^2 = f^2 + (q t^1.5 / sqrt 3)^2.
Outage MakeOutage(double q) {
    Outage o;
    const std::size_t n = 141;
    const double f = 0.01, t_out = 20.0;
    std::vector<std::size_t> starts(n);
    std::mt19937 rng(36);
    std::normal_distribution<double> g(0.0, 1.0);
    double drift = 0, rate = 0;
    for (std::size_t k = 0; k < n; ++k) {
        starts[k] = k;
        const double t = static_cast<double>(k);
        if (t > t_out) {
            rate += q * g(rng);  // dt = 1 s
            drift += rate;
            ++o.outage_nodes;
        }
        const double te = std::max(0.0, t - t_out);
        const double grow = q * std::pow(te, 1.5) / std::sqrt(3.0);
        Vector6d sigma;
        sigma << 1e-4, 1e-4, 2e-4, std::hypot(f, grow), std::hypot(f, grow),
            std::hypot(1.5 * f, grow);
        const Eigen::Vector3d truth(1.5 * t, 0.0, 0.0);
        o.in.t_s.push_back(1000.0 + t);
        o.in.T_ins.push_back(
            MakePose(Eigen::Matrix3d::Identity(), truth + Eigen::Vector3d(drift, 0, 0)));
        o.in.sigma.push_back(sigma);
        o.T.push_back(MakePose(Eigen::Matrix3d::Identity(), truth));
    }
    o.in.sigma_floor << 1e-4, 1e-4, 2e-4, f, f, 1.5 * f;
    o.p = MakeParam(o.in.T_ins, starts);
    for (std::size_t k = 0; k < n; ++k) {
        o.p.k0[k] = static_cast<int>(k);
        o.p.k1[k] = static_cast<int>(k);
        o.p.pivot[k] = o.in.T_ins[k].translation();
    }
    return o;
}

double PoseTermsCost(const Outage& o, const SlamConfig& cfg) {
    Terms acc(o.p.num_nodes());
    AddPoseTerms(o.in, o.p, o.T, cfg, /*linearise=*/false, acc);
    return acc.cost;
}

TEST(SlamDriftPrior, AnOutagesDriftCostsWhatTheSmoothnessTermSays) {
    SlamConfig cfg;
    const Outage o = MakeOutage(cfg.drift_velocity_random_walk_mps_per_sqrt_s);
    const auto n = static_cast<double>(o.outage_nodes);
    ASSERT_GT(std::abs(o.in.T_ins.back().translation().x() - o.T.back().translation().x()), 0.2)
        << "the draw does not drift";
    // The true correction's smoothness residuals are N(0, q^2) per node on one axis: a
    // chi-square of about n (sd sqrt(2 n) = 15).
    cfg.drift_by_smoothness_only = true;
    const double by_smoothness = PoseTermsCost(o, cfg);
    EXPECT_GT(by_smoothness, 0.6 * n);
    EXPECT_LT(by_smoothness, 1.5 * n);
    // The relative-motion and absolute terms in full take the drift as independent errors per
    // step and per node, and charge the true correction about three times as much.
    cfg.drift_by_smoothness_only = false;
    const double counted_thrice = PoseTermsCost(o, cfg);
    RecordProperty("costs",
                   std::to_string(n) + " " + std::to_string(by_smoothness) + " " +
                       std::to_string(counted_thrice));
    EXPECT_GT(counted_thrice, 2.0 * by_smoothness);
    // Where the INS reports no drift (GNSS good throughout) the terms are the same either way.
    Outage good = o;
    for (Vector6d& sg : good.in.sigma) sg = good.in.sigma_floor;
    cfg.drift_by_smoothness_only = true;
    const double good_on = PoseTermsCost(good, cfg);
    cfg.drift_by_smoothness_only = false;
    EXPECT_GT(good_on, 0.0);
    EXPECT_DOUBLE_EQ(good_on, PoseTermsCost(good, cfg));
}

}  // namespace
}  // namespace pitmap::proc::slam::detail
