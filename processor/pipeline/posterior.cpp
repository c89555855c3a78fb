// SPDX-License-Identifier: MIT
#include "processor/pipeline/posterior.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>

namespace pitmap::proc::pipeline::detail {

namespace {

using json = nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::array<double, 6> kUnknown = {kNaN, kNaN, kNaN, kNaN, kNaN, kNaN};

// Horizontal: the RMS of east and north (the TPU's THU convention); vertical: up.
double Horizontal(const std::array<double, 6>& s) {
    return std::sqrt(0.5 * (s[3] * s[3] + s[4] * s[4]));
}

// The q-quantile (nearest rank) of v, which it sorts; NaN when empty.
double Quantile(std::vector<double>& v, double q) {
    if (v.empty()) return kNaN;
    std::sort(v.begin(), v.end());
    const auto i = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size()))) - 1;
    return v[std::min(i, v.size() - 1)];
}

json Number(double v) {
    return std::isfinite(v) ? json(v) : json(nullptr);
}

}  // namespace

std::vector<std::array<double, 6>> SlamPingSigma(const georef::GeorefResult& geo,
                                                 const SliceSet& set,
                                                 const slam::SlamResult& r,
                                                 std::size_t num_pings) {
    const slam::SlamPosterior& post = r.posterior;
    if (!post.computed || post.slice_sigma.size() != r.trajectory.size()) return {};
    std::vector<std::array<double, 6>> out(num_pings, kUnknown);
    // Slices in time order (r.trajectory is): geo ping index and sigma, if SLAM's pose was kept.
    std::vector<std::pair<std::int64_t, std::array<double, 6>>> kept;
    kept.reserve(r.trajectory.size());
    std::vector<char> is_slice(geo.pings.size(), 0);
    for (std::size_t s = 0; s < r.trajectory.size(); ++s) {
        const slam::SlamPose& sp = r.trajectory[s];
        if (sp.input_index >= set.ping.size()) continue;
        const std::size_t k = set.ping[sp.input_index];
        if (k >= geo.pings.size()) continue;
        const georef::GeorefPing& ping = geo.pings[k];
        is_slice[k] = 1;
        const double moved =
            (ping.T_world_vehicle.translation() - sp.T_world_vehicle.translation()).norm();
        if (!(moved <= 1e-3)) continue;  // not SLAM's pose: the INS's sigma applies
        std::array<double, 6> sig;
        for (int c = 0; c < 6; ++c) sig[static_cast<std::size_t>(c)] = post.slice_sigma[s](c);
        if (ping.header_index < num_pings) out[ping.header_index] = sig;
        kept.emplace_back(ping.utime_gps, sig);
    }
    if (kept.empty()) return out;
    std::sort(
        kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (std::size_t k = 0; k < geo.pings.size(); ++k) {
        const georef::GeorefPing& ping = geo.pings[k];
        if (is_slice[k] != 0 || ping.header_index >= num_pings) continue;
        auto it = std::lower_bound(
            kept.begin(), kept.end(), ping.utime_gps, [](const auto& a, std::int64_t t) {
                return a.first < t;
            });
        if (it == kept.end() ||
            (it != kept.begin() && ping.utime_gps - (it - 1)->first < it->first - ping.utime_gps)) {
            --it;
        }
        out[ping.header_index] = it->second;
    }
    return out;
}

json PosteriorJson(const georef::GeorefResult& geo,
                   const std::vector<std::array<double, 6>>& ping_sigma,
                   const slam::SlamResult& r,
                   double window_s) {
    const slam::SlamPosterior& p = r.posterior;
    json out = {{"computed", p.computed}};
    if (!p.computed) {
        out["message"] = p.message.empty() ? "not computed (slam.posterior is off)" : p.message;
        return out;
    }
    const double slam_s = r.timings.total_s;
    out.update({{"variance_factor", p.variance_factor},
                {"residual_correlation", p.residual_correlation},
                {"observations", p.observations},
                {"unknowns", p.unknowns},
                {"pairs", p.num_pairs},
                {"nodes_solved", p.nodes_solved},
                {"solve_windows", p.windows},
                {"factor_nonzeros", p.largest_factor_nonzeros},
                {"model", p.clusters > 0 ? "cluster_robust" : "formal"},
                {"clusters", p.clusters},
                {"formal_horizontal_median_m", p.formal_horizontal_median_m},
                {"ins_white_noise_m",
                 {p.ins_white_noise_m.x(), p.ins_white_noise_m.y(), p.ins_white_noise_m.z()}},
                {"reference_horizontal_sigma_m", p.reference_horizontal_sigma_m},
                {"steady_model", p.steady_model},
                {"steady_up_median_m", p.steady_up_median_m},
                {"seconds_steady", p.steady_s},
                {"seconds", p.total_s},
                {"seconds_search", p.search_s},
                {"seconds_build", p.build_s},
                {"seconds_factor", p.factor_s},
                {"seconds_marginals", p.marginals_s},
                {"start_runs", p.start_runs},
                {"seconds_start_runs", p.start_runs_s},
                {"start_runs_note", p.start_runs_note},
                {"share_of_slam", slam_s > 0 ? p.total_s / slam_s : 0.0}});
    if (!p.start_spread.empty()) {
        std::vector<double> spread;
        for (const Eigen::Vector3d& d : p.start_spread) {
            spread.push_back(std::sqrt(0.5 * (d.x() * d.x() + d.y() * d.y())));
        }
        const double largest = *std::max_element(spread.begin(), spread.end());
        out["start_spread_horizontal_m"] = {{"median", Number(Quantile(spread, 0.5))},
                                            {"p95", Number(Quantile(spread, 0.95))},
                                            {"max", Number(largest)}};
    }
    std::vector<double> h, v;
    struct Window {
        double h = 0, v = 0;
        std::vector<double> hs;
    };
    std::map<std::int64_t, Window> windows;
    const auto window_us = static_cast<std::int64_t>(window_s * 1e6);
    const std::int64_t t0 = geo.pings.empty() ? 0 : geo.pings.front().utime_gps;
    for (const georef::GeorefPing& ping : geo.pings) {
        if (ping.header_index >= ping_sigma.size()) continue;
        const std::array<double, 6>& s = ping_sigma[ping.header_index];
        const double sh = Horizontal(s);
        if (!std::isfinite(sh) || !std::isfinite(s[5])) continue;
        h.push_back(sh);
        v.push_back(s[5]);
        if (window_us <= 0) continue;
        Window& w = windows[(ping.utime_gps - t0) / window_us];
        w.h = std::max(w.h, sh);
        w.v = std::max(w.v, s[5]);
        w.hs.push_back(sh);
    }
    out["pings"] = h.size();
    out["horizontal_sigma_m"] = {{"median", Number(Quantile(h, 0.5))},
                                 {"p95", Number(Quantile(h, 0.95))}};
    out["vertical_sigma_m"] = {{"median", Number(Quantile(v, 0.5))},
                               {"p95", Number(Quantile(v, 0.95))}};
    json ws = json::array();
    for (auto& [index, w] : windows) {
        const double a = static_cast<double>(t0 + index * window_us) * 1e-6;
        ws.push_back({{"start_gps_s", a},
                      {"end_gps_s", a + window_s},
                      {"pings", w.hs.size()},
                      {"max_horizontal_sigma_m", w.h},
                      {"max_vertical_sigma_m", w.v},
                      {"median_radius_h95_m", Number(kCircular95 * Quantile(w.hs, 0.5))},
                      {"max_radius_h95_m", kCircular95 * w.h}});
    }
    out["window_s"] = window_s;
    out["windows"] = ws;
    return out;
}

PoseSigma ProcessingSigma(const survey::SurveyModel& m,
                          const georef::GeorefPing& ping,
                          const PoseSigma& ins,
                          bool* from_slam) {
    if (from_slam != nullptr) *from_slam = false;
    if (m.latest() != survey::TrajectoryVersion::kSlam) return ins;
    const survey::PingTrajectory& t = m.trajectory(survey::TrajectoryVersion::kSlam);
    if (ping.header_index >= t.sigma.size()) return ins;
    PoseSigma out = ins;
    bool any = false;
    for (int c = 0; c < 6; ++c) {
        const double v = t.sigma[ping.header_index][static_cast<std::size_t>(c)];
        if (std::isfinite(v)) {
            out(c) = v;
            any = true;
        }
    }
    if (from_slam != nullptr) *from_slam = any;
    return out;
}

Status WriteTrajectorySigmaCsv(const std::string& path,
                               const georef::GeorefResult& geo,
                               const std::vector<Pose>& before,
                               const survey::SurveyModel& m,
                               double max_age_s,
                               const PoseSigma& fallback) {
    if (before.size() != geo.pings.size()) {
        return Error{"internal: " + std::to_string(before.size()) + " initial poses for " +
                     std::to_string(geo.pings.size()) + " pings"};
    }
    const std::string partial = path + ".partial";
    std::FILE* f = std::fopen(partial.c_str(), "w");
    if (f == nullptr) return Error{"cannot create " + partial + ": " + std::strerror(errno)};
    std::fprintf(f,
                 "gps_time_s,x_m,y_m,z_m,x0_m,y0_m,z0_m,sigma_east_m,sigma_north_m,sigma_up_m,"
                 "sigma_roll_deg,sigma_pitch_deg,sigma_yaw_deg,ins_sigma_east_m,"
                 "ins_sigma_north_m,ins_sigma_up_m,slam_posterior\n");
    constexpr double kDeg = 180.0 / 3.14159265358979323846;
    for (std::size_t k = 0; k < geo.pings.size(); ++k) {
        const georef::GeorefPing& ping = geo.pings[k];
        const PoseSigma ins = PoseSigmaAt(m.ingest.nav, ping.utime_gps, max_age_s, fallback);
        bool slam = false;
        const PoseSigma s = ProcessingSigma(m, ping, ins, &slam);
        const Eigen::Vector3d x = ping.T_world_vehicle.translation();
        const Eigen::Vector3d x0 = before[k].translation();
        std::fprintf(f,
                     "%.6f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.5g,%.5g,%.5g,%.5g,%.5g,%.5g,%.5g,%.5g,"
                     "%.5g,%d\n",
                     static_cast<double>(ping.utime_gps) * 1e-6,
                     x.x(),
                     x.y(),
                     x.z(),
                     x0.x(),
                     x0.y(),
                     x0.z(),
                     s(3),
                     s(4),
                     s(5),
                     s(0) * kDeg,
                     s(1) * kDeg,
                     s(2) * kDeg,
                     ins(3),
                     ins(4),
                     ins(5),
                     slam ? 1 : 0);
    }
    const bool ok = std::ferror(f) == 0;
    if (std::fclose(f) != 0 || !ok) {
        std::remove(partial.c_str());
        return Error{"write failed: " + partial};
    }
    if (std::rename(partial.c_str(), path.c_str()) != 0) {
        return Error{"cannot rename " + partial + " to " + path + ": " + std::strerror(errno)};
    }
    return Ok{};
}

}  // namespace pitmap::proc::pipeline::detail
