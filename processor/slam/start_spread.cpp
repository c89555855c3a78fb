// SPDX-License-Identifier: MIT
// The spread of SLAM's result over runs from perturbed starts (SlamConfig::posterior_start_runs,
// docs/decisions/016): a posterior about the optimum states how well the data pin the result
// down there, not where SLAM stopped. In a GNSS outage SLAM can stop in a flat valley of its
// cost along the track (0.1-0.25 m off, decision 012) with a Gauss-Newton step of a cm; from a
// different start it stops elsewhere in the same valley. The runs' spread about the result
// states that part of the error.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <unordered_map>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam {

namespace {

constexpr double kMinDriftSigmaM = 1e-3;  // below, a slice is not in a drifting stretch

// Per slice (time order `order`), the drift 1-sigma of position component c (3 + c of the pose
// sigma): the part above the survey's smallest, held against falling faster than the recovery.
std::vector<double> DriftSigma(const std::vector<Slice>& slices,
                               const std::vector<std::size_t>& order,
                               int c,
                               double recovery_time_s) {
    double floor = std::numeric_limits<double>::infinity();
    for (const Slice& s : slices) floor = std::min(floor, s.pose_sigma(3 + c));
    std::vector<double> g(order.size(), 0.0);
    for (std::size_t k = 0; k < order.size(); ++k) {
        const double sigma = slices[order[k]].pose_sigma(3 + c);
        g[k] = std::sqrt(std::max(0.0, sigma * sigma - floor * floor));
        if (k > 0 && recovery_time_s > 0) {
            const double dt = slices[order[k]].gps_time_s - slices[order[k - 1]].gps_time_s;
            g[k] = std::max(g[k], g[k - 1] * std::exp(-std::max(0.0, dt) / recovery_time_s));
        }
    }
    return g;
}

}  // namespace

std::vector<Slice> PerturbedStart(const std::vector<Slice>& slices,
                                  double recovery_time_s,
                                  std::uint64_t seed) {
    std::vector<Slice> out = slices;
    std::vector<std::size_t> order(slices.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return slices[a].gps_time_s < slices[b].gps_time_s;
    });
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (int c = 0; c < 3; ++c) {
        const std::vector<double> g = DriftSigma(slices, order, c, recovery_time_s);
        // Unit-density velocity random walk v and its integral x, with their exact variances
        // for the discrete steps: var_v += dt; cov_xv += dt var_v (after the step);
        // var_x += 2 dt cov_xv(before) + dt^2 var_v(after).
        double v = 0, x = 0, var_v = 0, var_x = 0, cov_xv = 0;
        bool in_stretch = false;
        for (std::size_t k = 0; k < order.size(); ++k) {
            if (!(g[k] > kMinDriftSigmaM)) {
                in_stretch = false;
                continue;
            }
            double dt = 0;
            if (in_stretch) {
                dt = std::max(0.0, slices[order[k]].gps_time_s - slices[order[k - 1]].gps_time_s);
            } else {
                in_stretch = true;
                v = x = var_v = var_x = cov_xv = 0;
                dt = k > 0 ? std::max(0.0,
                                      slices[order[k]].gps_time_s - slices[order[k - 1]].gps_time_s)
                           : 0.0;
                if (!(dt > 0)) dt = 0.1;  // the first slice of the survey: one ping's step
            }
            const double cov_before = cov_xv;
            v += std::sqrt(dt) * normal(rng);
            var_v += dt;
            x += v * dt;
            var_x += 2.0 * dt * cov_before + dt * dt * var_v;
            cov_xv = cov_before + dt * var_v;
            if (!(var_x > 0)) continue;
            out[order[k]].T_world_vehicle.translation()(c) += g[k] * x / std::sqrt(var_x);
        }
    }
    return out;
}

std::vector<Eigen::Vector3d> StartSpread(const std::vector<SlamPose>& main,
                                         const std::vector<std::vector<SlamPose>>& runs) {
    std::vector<Eigen::Vector3d> sum(main.size(), Eigen::Vector3d::Zero());
    std::vector<int> count(main.size(), 0);
    std::unordered_map<std::size_t, std::size_t> at;  // input index -> pose of `main`
    for (std::size_t s = 0; s < main.size(); ++s) at.emplace(main[s].input_index, s);
    for (const std::vector<SlamPose>& run : runs) {
        for (const SlamPose& pose : run) {
            const auto it = at.find(pose.input_index);
            if (it == at.end()) continue;
            const Eigen::Vector3d d =
                pose.T_world_vehicle.translation() - main[it->second].T_world_vehicle.translation();
            if (!d.allFinite()) continue;
            sum[it->second] += d.cwiseAbs2();
            ++count[it->second];
        }
    }
    std::vector<Eigen::Vector3d> out(main.size(), Eigen::Vector3d::Zero());
    for (std::size_t s = 0; s < main.size(); ++s) {
        if (count[s] > 0) out[s] = (sum[s] / static_cast<double>(count[s])).cwiseSqrt();
    }
    return out;
}

namespace detail {

bool AddStartSpread(const std::vector<Slice>& slices,
                    const SlamConfig& cfg,
                    const SlamProgress& progress,
                    SlamResult& res) {
    const auto t0 = Clock::now();
    SlamPosterior& post = res.posterior;
    // Where the INS reports no horizontal drift beyond a point's sigma the perturbed starts
    // lie within the pairs' noise of this one and end where it did (a GNSS-good survey): the
    // runs would cost posterior_start_runs SLAM runs for nothing.
    std::vector<std::size_t> order(slices.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return slices[a].gps_time_s < slices[b].gps_time_s;
    });
    double largest = 0;
    for (int c = 0; c < 2; ++c) {
        for (double g : DriftSigma(slices, order, c, cfg.ins_sigma_recovery_time_s)) {
            largest = std::max(largest, g);
        }
    }
    if (!(largest > cfg.point_sigma_m)) {
        post.start_runs_note =
            "not run: the INS reports no horizontal drift beyond the point "
            "sigma (largest " +
            std::to_string(largest) + " m)";
        return true;
    }
    SlamConfig run_cfg = cfg;
    run_cfg.posterior = false;
    run_cfg.posterior_start_runs = 0;
    std::vector<std::vector<SlamPose>> runs;
    for (int k = 0; k < cfg.posterior_start_runs; ++k) {
        // The perturbed copy's points move into the run (one copy of them at a time).
        SlamResult run =
            RunSlam(PerturbedStart(slices,
                                   cfg.ins_sigma_recovery_time_s,
                                   cfg.posterior_start_seed + static_cast<std::uint64_t>(k)),
                    run_cfg,
                    progress);
        if (run.termination == SlamTermination::kCancelled) return false;
        if (run.trajectory.empty()) continue;  // invalid input: nothing to compare
        runs.push_back(std::move(run.trajectory));
    }
    post.start_spread = StartSpread(res.trajectory, runs);
    post.start_runs = runs.size();
    for (std::size_t s = 0; s < post.slice_sigma.size() && s < post.start_spread.size(); ++s) {
        for (int c = 0; c < 3; ++c) {
            post.slice_sigma[s](3 + c) =
                std::hypot(post.slice_sigma[s](3 + c), post.start_spread[s](c));
        }
    }
    post.start_runs_s = Seconds(t0);
    post.total_s += post.start_runs_s;
    return true;
}

}  // namespace detail

}  // namespace pitmap::proc::slam
