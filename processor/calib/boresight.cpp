// SPDX-License-Identifier: MIT
#include "processor/calib/boresight.hpp"
#include "processor/calib/boresight_blocks.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <unordered_map>

#include "common/frames.hpp"
#include "processor/calib/boresight_residual.hpp"
#include "processor/calib/pass_pairs.hpp"
#include "processor/registration/correspondence.hpp"
#include "processor/registration/grid_key.hpp"
#include "processor/registration/neighbours.hpp"
#include "processor/registration/normal_equations.hpp"
#include "processor/registration/normals.hpp"
#include "processor/registration/robust.hpp"

namespace pitmap::proc::calib {

using detail::Collect;
using detail::FindPairs;
using detail::IndexOwnPasses;
using detail::Pair;
using detail::Samples;
using detail::Stats;
using detail::ViewWindows;
using georef::GeorefResult;
using survey::SonarMount;

const char* ToString(Termination t) {
    switch (t) {
        case Termination::kConverged:
            return "converged";
        case Termination::kMaxIterations:
            return "max_iterations";
        case Termination::kNoOverlap:
            return "no_overlap";
        case Termination::kCancelled:
            return "cancelled";
    }
    return "unknown";
}

std::vector<std::string> BoresightConfig::Validate() const {
    std::vector<std::string> p;
    if (!(segment_duration_s > 0)) p.push_back("calibrate.segment_duration_s must be > 0");
    if (!(part_duration_s > 0)) p.push_back("calibrate.part_duration_s must be > 0");
    if (!(min_separation_s >= part_duration_s)) {
        p.push_back("calibrate.min_separation_s must be >= part_duration_s");
    }
    if (beam_stride < 1) p.push_back("calibrate.beam_stride must be >= 1");
    if (!(min_distance_m > 0)) p.push_back("calibrate.min_distance_m must be > 0");
    if (!(max_distance_m >= min_distance_m)) {
        p.push_back("calibrate.max_distance_m must be >= min_distance_m");
    }
    if (!(normal_radius_m > 0)) p.push_back("calibrate.normal_radius_m must be > 0");
    if (!(cauchy_scale_m > 0)) p.push_back("calibrate.cauchy_scale_m must be > 0");
    if (max_iterations < 1) p.push_back("calibrate.max_iterations must be >= 1");
    if (!(convergence_deg > 0)) p.push_back("calibrate.convergence_deg must be > 0");
    if (!(max_position_stddev_m > 0)) p.push_back("calibrate.max_position_stddev_m must be > 0");
    if (!(max_heading_stddev_deg > 0)) p.push_back("calibrate.max_heading_stddev_deg must be > 0");
    if (num_verify_segments < 0) p.push_back("calibrate.num_verify_segments must be >= 0");
    if (verify_query_every < 1) p.push_back("calibrate.verify_query_every must be >= 1");
    if (!(height_offset_sigma_m > 0)) p.push_back("calibrate.height_offset_sigma_m must be > 0");
    if (!(ins_attitude_correlation_time_s >= 0)) {
        p.push_back("calibrate.ins_attitude_correlation_time_s must be >= 0");
    }
    if (!(range_noise_fraction >= 0)) p.push_back("calibrate.range_noise_fraction must be >= 0");
    if (!(range_noise_constant_m > 0)) p.push_back("calibrate.range_noise_constant_m must be > 0");
    if (!(latency_sigma_s > 0)) p.push_back("calibrate.latency_sigma_s must be > 0");
    if (!(latency_scan_step_s > 0)) p.push_back("calibrate.latency_scan_step_s must be > 0");
    if (!(latency_scan_s >= 0)) p.push_back("calibrate.latency_scan_s must be >= 0");
    return p;
}

namespace {

// Vehicle poses of the pings with the sonar clock shifted by tau: the INS interpolated at
// t + tau, clamped to its span (a ping within tau of the span's end keeps the edge pose). With
// tau = 0 these are the georeference's own poses.
class ShiftedPoses {
public:
    ShiftedPoses(const GeorefResult& geo, const survey::NavSeries& nav)
        : geo_(geo), traj_(nav, LocalTangentFrame(geo.world_origin)) {}

    Pose At(std::uint32_t ping, double tau) const {
        const auto& g = geo_.pings[ping];
        if (tau == 0.0 || traj_.times().size() < 2) return g.T_world_vehicle;
        std::int64_t t = g.utime_gps + static_cast<std::int64_t>(std::llround(tau * 1e6));
        t = std::clamp(t, traj_.times().front(), traj_.times().back());
        auto T = traj_.PoseAt(t, kMaxGapS);
        return T ? *T : g.T_world_vehicle;
    }
    // d(T_world_vehicle(t + tau) x)/dtau by central differences over +-0.1 s: several INS
    // samples, so that their white position noise (mm at 50 Hz would be dm/s within one
    // sample interval) does not enter the Jacobian; wave motion (periods of seconds) bends
    // the difference by well under 1 %.
    // As an affine map of the sonar point x in the vehicle frame: Rate = A x + b.
    struct RateMap {
        Eigen::Matrix3d A;
        Eigen::Vector3d b;
        Eigen::Vector3d operator()(const Eigen::Vector3d& x) const { return A * x + b; }
    };
    RateMap Rate(std::uint32_t ping, double tau) const {
        constexpr double h = 0.1;
        const Pose plus = At(ping, tau + h), minus = At(ping, tau - h);
        return {(plus.linear() - minus.linear()) / (2 * h),
                (plus.translation() - minus.translation()) / (2 * h)};
    }

private:
    static constexpr double kMaxGapS = 0.5;
    const GeorefResult& geo_;
    georef::Trajectory traj_;
};

// The vehicle poses of the pings of S (which come in ping order) at one latency, each
// interpolated once: the positions and the pair Jacobians of an iteration both read them.
class PingPoses {
public:
    PingPoses(const ShiftedPoses& poses, const Samples& S, double tau) {
        if (S.ping.empty()) return;
        const auto [lo, hi] = std::minmax_element(S.ping.begin(), S.ping.end());
        first_ = *lo;
        T_.resize(static_cast<std::size_t>(*hi - *lo) + 1);
        tbb::parallel_for(std::size_t{0}, T_.size(), [&](std::size_t i) {
            T_[i] = poses.At(first_ + static_cast<std::uint32_t>(i), tau);
        });
    }
    const Pose& operator[](std::uint32_t ping) const { return T_[ping - first_]; }

private:
    std::uint32_t first_ = 0;
    std::vector<Pose> T_;
};

void Positions(const PingPoses& T,
               const Samples& S,
               const SonarMount& m,
               std::vector<Eigen::Vector3d>& p) {
    const Pose T_vs = m.T_vehicle_sonar();
    p.resize(S.ping.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, p.size(), 1024), [&](const auto& b) {
        for (std::size_t k = b.begin(); k != b.end(); ++k)
            p[k] = T[S.ping[k]] * (T_vs * S.s_sonar[k]);
    });
}

// The soundings of [t0, t1) with their own passes indexed at the given mount and latency;
// every query_every-th of them seeks pairs.
Samples CollectIndexed(const ViewWindows& view,
                       const ShiftedPoses& poses,
                       const SonarMount& m,
                       double tau,
                       double t0,
                       double t1,
                       int query_every,
                       const BoresightConfig& cfg) {
    Samples S = Collect(view, t0, t1, cfg.beam_stride);
    S.query_every = query_every;
    std::vector<Eigen::Vector3d> p;
    Positions(PingPoses(poses, S, tau), S, m, p);
    IndexOwnPasses(p, S, cfg);
    return S;
}

// Residuals of the pairs within `d_max` (default: the last iteration's gate) at a latency.
ResidualStats Evaluate(const ShiftedPoses& poses,
                       const Samples& S,
                       const SonarMount& m,
                       double tau,
                       const BoresightConfig& cfg,
                       double d_max = 0) {
    std::vector<Eigen::Vector3d> p;
    Positions(PingPoses(poses, S, tau), S, m, p);
    return Stats(FindPairs(p, S, cfg, d_max > 0 ? d_max : cfg.min_distance_m));
}

// The latency scan's cost: the median |residual| over the pairs within max_distance_m
// (insensitive to the pair count, which itself changes with tau), and the pair count.
std::pair<double, std::int64_t> ScanCost(const ShiftedPoses& poses,
                                         const Samples& S,
                                         const SonarMount& m,
                                         double tau,
                                         const BoresightConfig& cfg) {
    const ResidualStats st = Evaluate(poses, S, m, tau, cfg, cfg.max_distance_m);
    return {st.pairs > 0 ? st.median_abs_m : std::numeric_limits<double>::infinity(), st.pairs};
}

SegmentScore ScoreSegment(const ViewWindows& view,
                          const survey::NavSeries& nav,
                          double t0,
                          double t1,
                          const BoresightConfig& cfg) {
    SegmentScore s;
    s.start_s = t0;
    s.end_s = t1;
    struct Span {
        double lo = 1e300, hi = -1e300;
    };
    std::unordered_map<std::uint64_t, Span> cells;
    const GeorefResult& geo = view.geo();
    // Every 7th sounding of the view (by its index in the whole view).
    view.ForEach(
        t0,
        t1,
        [&](const georef::GeorefPoints& P, std::size_t first, std::size_t lo, std::size_t hi) {
            for (std::size_t j = lo + (7 - (first + lo) % 7) % 7; j < hi; j += 7) {
                const double t = static_cast<double>(geo.pings[P.ping[j]].utime_gps) * 1e-6;
                if (t < t0 || t >= t1) continue;
                const auto& x = P.position_world[j];
                const std::uint64_t key = reg::CellKeyOf(x.x(), x.y(), 1.0);
                Span& sp = cells[key];
                sp.lo = std::min(sp.lo, t);
                sp.hi = std::max(sp.hi, t);
            }
        });
    for (const auto& [k, sp] : cells) s.overlap_cells += (sp.hi - sp.lo >= cfg.min_separation_s);
    for (const auto& sd : nav.stddevs) {
        const double t = static_cast<double>(sd.utime_gps) * 1e-6;
        if (t < t0 || t >= t1) continue;
        const double h =
            std::hypot(static_cast<double>(sd.north_m), static_cast<double>(sd.east_m));
        if (std::isfinite(h)) s.max_position_stddev_m = std::max(s.max_position_stddev_m, h);
        if (std::isfinite(sd.yaw_deg)) {
            s.max_heading_stddev_deg =
                std::max(s.max_heading_stddev_deg, static_cast<double>(sd.yaw_deg));
        }
    }
    s.low_drift = s.max_position_stddev_m <= cfg.max_position_stddev_m &&
                  s.max_heading_stddev_deg <= cfg.max_heading_stddev_deg;
    return s;
}

// The part of the boresight's uncertainty that comes from the INS: a vehicle-frame attitude
// error delta (roll, pitch, heading; Gauss-Markov, the INS's reported 1-sigma averaged over
// [t0, t1), correlation time tau) averaged over the window, as the data see it. Its variance is
// sigma^2 g(T / tau), g(x) = 2 (x - 1 + e^-x) / x^2 (1 for a window much shorter than tau,
// tau / T for a much longer one). R_wv Exp(delta) R_vs moves the boresight's Euler angles
// (R_vs = Rz(yaw) Ry(pitch) Rx(roll)) by M^-1 delta, M = [Rz Ry x, Rz y, z].
// Returns false when the INS reported no attitude sigma (of some axis) in the window: that
// axis then has none added.
bool InsAttitudeSd(const survey::NavSeries& nav,
                   double t0,
                   double t1,
                   const SonarMount& m,
                   double tau,
                   double out_deg[3]) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Vector3i n = Eigen::Vector3i::Zero();
    for (const auto& sd : nav.stddevs) {
        const double t = static_cast<double>(sd.utime_gps) * 1e-6;
        if (t < t0 || t >= t1) continue;
        const float v[3] = {sd.roll_deg, sd.pitch_deg, sd.yaw_deg};
        for (int j = 0; j < 3; ++j) {
            if (!std::isfinite(v[j])) continue;
            sum[j] += v[j];
            ++n[j];
        }
    }
    const double T = t1 - t0;
    const double x = tau > 0 ? T / tau : std::numeric_limits<double>::infinity();
    const double g = x < 1e-6 ? 1.0 : std::isinf(x) ? 0.0 : 2 * (x - 1 + std::exp(-x)) / (x * x);
    Eigen::Vector3d sigma;
    for (int j = 0; j < 3; ++j) sigma[j] = n[j] > 0 ? sum[j] / n[j] * std::sqrt(g) : 0.0;
    const double yaw = frames::DegToRad(m.boresight_yaw_deg);
    const double pitch = frames::DegToRad(m.boresight_pitch_deg);
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d Ry =
        Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix();
    Eigen::Matrix3d M;
    M.col(0) = Rz * Ry * Eigen::Vector3d::UnitX();
    M.col(1) = Rz * Eigen::Vector3d::UnitY();
    M.col(2) = Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d Minv = M.inverse();
    const Eigen::Matrix3d C = Minv * sigma.cwiseAbs2().asDiagonal() * Minv.transpose();
    for (int j = 0; j < 3; ++j) out_deg[j] = std::sqrt(std::max(0.0, C(j, j)));
    return n.minCoeff() > 0;
}

// Which window is the better one to calibrate on: low drift first, then more overlap.
bool BetterSegment(const SegmentScore& a, const SegmentScore& b) {
    if (a.low_drift != b.low_drift) return a.low_drift;
    return a.overlap_cells > b.overlap_cells;
}

// Candidate windows, overlapping by 3/4. When no window of the configured length is low drift (a
// GNSS outage longer than the survey's quiet stretches), shorter ones are tried, down to a
// quarter of it, before settling for the best drifting one.
std::vector<SegmentScore> CandidateSegments(const ViewWindows& view,
                                            const survey::NavSeries& nav,
                                            const BoresightConfig& cfg) {
    const GeorefResult& geo = view.geo();
    const double t_first = static_cast<double>(geo.pings.front().utime_gps) * 1e-6;
    const double t_last = static_cast<double>(geo.pings.back().utime_gps) * 1e-6 + 1e-6;
    std::vector<SegmentScore> candidates;
    const double full = std::min(cfg.segment_duration_s, t_last - t_first);
    for (double dur = full; dur >= full / 4 - 1e-9; dur /= 2) {
        const double step = dur / 4;
        for (double t0 = t_first; t0 + dur <= t_last + 1e-9; t0 += step) {
            candidates.push_back(ScoreSegment(view, nav, t0, t0 + dur, cfg));
            if (step <= 0) break;
        }
        if (std::any_of(candidates.begin(),
                        candidates.end(),
                        [](const SegmentScore& c) { return c.low_drift; }) ||
            step <= 0) {
            break;
        }
    }
    if (candidates.empty()) candidates.push_back(ScoreSegment(view, nav, t_first, t_last, cfg));
    return candidates;
}

// The configured window, else the best candidate.
SegmentScore ChooseSegment(const ViewWindows& view,
                           const survey::NavSeries& nav,
                           const std::vector<SegmentScore>& candidates,
                           const BoresightConfig& cfg) {
    if (cfg.segment_start_s >= 0) {
        return ScoreSegment(
            view, nav, cfg.segment_start_s, cfg.segment_start_s + cfg.segment_duration_s, cfg);
    }
    return *std::min_element(candidates.begin(), candidates.end(), BetterSegment);
}

// Beyond the linear range: the latency within tau0 +- latency_scan_s whose pairs fit best at the
// nominal mount.
double ScanLatency(const ShiftedPoses& poses,
                   const Samples& S,
                   const SonarMount& mount,
                   double tau0,
                   const BoresightConfig& cfg) {
    double tau = tau0;
    double best = std::numeric_limits<double>::infinity();
    std::int64_t most_pairs = 0;
    std::vector<std::pair<double, std::pair<double, std::int64_t>>> costs;
    const int n = static_cast<int>(std::floor(cfg.latency_scan_s / cfg.latency_scan_step_s));
    for (int i = -n; i <= n; ++i) {
        const double t = tau0 + i * cfg.latency_scan_step_s;
        costs.push_back({t, ScanCost(poses, S, mount, t, cfg)});
        most_pairs = std::max(most_pairs, costs.back().second.second);
    }
    for (const auto& [t, c] : costs) {
        // Too few pairs means the passes were pushed apart, not that they fit.
        if (2 * c.second >= most_pairs && c.first < best) {
            best = c.first;
            tau = t;
        }
    }
    return tau;
}

// Nuisance: a height correction per node (every part_duration_s, linear in between) absorbs the
// INS height error, which differs from pass to pass. Without it a height difference between two
// parallel passes d apart reads as a roll of dz / d (1.5 cm over 3 m = 0.3 deg). With
// estimate_horizontal_offsets each node also has a north and an east correction.
class NodeOffsets {
public:
    NodeOffsets(const BoresightConfig& cfg, double seg_len)
        : cfg_(cfg),
          dims_(cfg.estimate_horizontal_offsets ? 3
                : cfg.estimate_height_offsets   ? 1
                                                : 0),
          nodes_(dims_ > 0 ? static_cast<int>(std::ceil(seg_len / cfg.part_duration_s)) + 1 : 0),
          phi_(cfg.offset_correlation_time_s > 0
                   ? std::exp(-cfg.part_duration_s / cfg.offset_correlation_time_s)
                   : 0.0),
          off_(Eigen::VectorXd::Zero(nodes_ * dims_)) {}

    int size() const { return nodes_ * dims_; }
    bool empty() const { return nodes_ == 0; }

    // The node before t (seconds into the segment) and the fraction of the way to the next.
    void Locate(double t, int& i, double& f) const {
        const double u =
            std::clamp(t / cfg_.part_duration_s, 0.0, static_cast<double>(nodes_ - 1) - 1e-9);
        i = static_cast<int>(u);
        f = u - i;
    }
    // The world axis that unknown d of a node corrects.
    int Axis(int d) const { return dims_ == 1 ? 2 : d; }

    Eigen::Vector3d At(double t) const {
        Eigen::Vector3d o = Eigen::Vector3d::Zero();
        if (nodes_ == 0) return o;
        int i;
        double f;
        Locate(t, i, f);
        for (int d = 0; d < dims_; ++d)
            o[Axis(d)] = (1 - f) * off_[i * dims_ + d] + f * off_[(i + 1) * dims_ + d];
        return o;
    }

    // The rows of the offsets in d r / d x for sample time t on one side (sgn = +1 query,
    // -1 target) of a pair with normal nrm; the offsets' unknowns start at block `base`.
    template <class Push>
    void Rows(double t, double sgn, const Eigen::Vector3d& nrm, int base, Push push) const {
        int i;
        double f;
        Locate(t, i, f);
        for (int d = 0; d < dims_; ++d) {
            push(base + i * dims_ + d, sgn * (1 - f) * nrm[Axis(d)]);
            push(base + (i + 1) * dims_ + d, sgn * f * nrm[Axis(d)]);
        }
    }

    // The priors: the first node (or every node when white) ~ N(0, sigma^2); after it
    // Gauss-Markov, o_k - phi o_(k-1) ~ N(0, sigma^2 (1 - phi^2)).
    void AddPriors(int base, reg::BlockSystem<1>& sys) const {
        using Scalar1 = Eigen::Matrix<double, 1, 1>;
        for (int j = 0; j < size(); ++j) {
            const double sig_o = Sigma(j % dims_);
            if (phi_ == 0.0 || j < dims_) {
                sys.AddPrior(static_cast<std::size_t>(base + j),
                             Scalar1::Constant(1.0 / (sig_o * sig_o)),
                             Scalar1::Constant(off_[j]));
                continue;
            }
            const int ids[2] = {base + j - dims_, base + j};
            const Scalar1 Jc[2] = {Scalar1::Constant(-phi_), Scalar1::Constant(1.0)};
            sys.Add<1>(ids,
                       Jc,
                       2,
                       Scalar1::Constant(1.0 / (sig_o * sig_o * (1 - phi_ * phi_))),
                       Scalar1::Constant(off_[j] - phi_ * off_[j - dims_]));
        }
    }

    void Update(const Eigen::VectorXd& step) { off_ += step; }
    double Rms() const {
        return off_.size() ? std::sqrt(off_.squaredNorm() / static_cast<double>(off_.size())) : 0.0;
    }

private:
    double Sigma(int d) const {
        return dims_ == 3 && d < 2 ? cfg_.horizontal_offset_sigma_m : cfg_.height_offset_sigma_m;
    }

    const BoresightConfig& cfg_;
    const int dims_;   // unknowns per node: 3 (north, east, down), 1 (down) or 0
    const int nodes_;  // nodes over the segment (0 without offsets)
    const double phi_;
    Eigen::VectorXd off_;
};

// The correspondence gate of iteration it: from max_distance_m down to min_distance_m by the
// last iteration.
double CorrespondenceGate(int it, const BoresightConfig& cfg) {
    const double a =
        cfg.max_iterations > 1 ? static_cast<double>(it) / (cfg.max_iterations - 1) : 1.0;
    return std::max(cfg.min_distance_m, cfg.max_distance_m * (1 - a) + cfg.min_distance_m * a);
}

// dp/dtau of every sample that takes part in a pair (zero for the others).
std::vector<Eigen::Vector3d> LatencyRates(const ShiftedPoses& poses,
                                          const Samples& S,
                                          const std::vector<Pair>& pairs,
                                          const SonarMount& m,
                                          double tau) {
    std::vector<Eigen::Vector3d> rate(pairs.size(), Eigen::Vector3d::Zero());
    std::vector<char> need(pairs.size(), 0);
    for (std::size_t k = 0; k < pairs.size(); ++k) {
        if (pairs[k].ok) need[k] = need[pairs[k].c.target] = 1;
    }
    const Pose T_vs = m.T_vehicle_sonar();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rate.size(), 512), [&](const auto& b) {
        // One rate map per ping (the samples are in ping order).
        std::uint32_t last = std::numeric_limits<std::uint32_t>::max();
        ShiftedPoses::RateMap R{Eigen::Matrix3d::Zero(), Eigen::Vector3d::Zero()};
        for (std::size_t k = b.begin(); k != b.end(); ++k) {
            if (!need[k]) continue;
            if (S.ping[k] != last) {
                last = S.ping[k];
                R = poses.Rate(last, tau);
            }
            rate[k] = R(T_vs * S.s_sonar[k]);
        }
    });
    return rate;
}

// The pairs' rows of the normal equations in scalar blocks: [roll, pitch, yaw, (tau), offsets...]
// (the offsets from block `base` on; tau when `rate` is not empty). Returns the pair count.
std::int64_t AddPairRows(const PingPoses& T,
                         const Samples& S,
                         const std::vector<Pair>& pairs,
                         const std::vector<Eigen::Vector3d>& rate,
                         const Pose& T_vs,
                         const NodeOffsets& offsets,
                         int base,
                         const BoresightConfig& cfg,
                         reg::BlockSystem<1>& sys) {
    std::int64_t n = 0;
    std::vector<int> idx;
    std::vector<Eigen::Matrix<double, 1, 1>> J;
    auto push = [&](int i, double v) {
        idx.push_back(i);
        J.push_back(Eigen::Matrix<double, 1, 1>::Constant(v));
    };
    for (std::size_t k = 0; k < pairs.size(); ++k) {
        const Pair& pr = pairs[k];
        if (!pr.ok) continue;
        const std::size_t q = pr.c.target;
        const Eigen::Vector3d& nrm = pr.c.query_normal;
        Eigen::RowVector3d Jr;
        BoresightPairResidual(
            T[S.ping[k]], T[S.ping[q]], T_vs, S.s_sonar[k], S.s_sonar[q], nrm, &Jr);
        idx.clear();
        J.clear();
        for (int j = 0; j < 3; ++j) push(j, Jr[j]);
        if (!rate.empty()) push(3, nrm.dot(rate[k] - rate[q]));
        if (!offsets.empty()) {
            offsets.Rows(S.t_s[k], 1.0, nrm, base, push);
            offsets.Rows(S.t_s[q], -1.0, nrm, base, push);
        }
        const Eigen::Matrix<double, 1, 1> W = Eigen::Matrix<double, 1, 1>::Constant(
            pr.w *
            reg::RobustWeight(reg::RobustKernel::kCauchy, std::abs(pr.r), cfg.cauchy_scale_m));
        sys.Add<1>(idx.data(),
                   J.data(),
                   static_cast<int>(idx.size()),
                   W,
                   Eigen::Matrix<double, 1, 1>::Constant(pr.r));
        ++n;
    }
    return n;
}

// The latency's step from the solution's x_tau.
struct LatencyStep {
    double dtau = 0;          // the Gauss-Newton step, capped at the scan step
    double tau_step = 0;      // what is added to tau (dtau, extrapolated)
    bool unresolved = false;  // the uncapped step was at least the scan step
};
LatencyStep StepLatency(double x_tau, double prev_dtau, const BoresightConfig& cfg) {
    LatencyStep s;
    // A Gauss-Newton step is linear in the rotation rates: cap it at the scan step so that an
    // early step from far away cannot jump into another wave period.
    s.dtau = std::clamp(x_tau, -cfg.latency_scan_step_s, cfg.latency_scan_step_s);
    s.unresolved = std::abs(x_tau) >= cfg.latency_scan_step_s;
    // The latency converges linearly as well: the same extrapolation as the rotation's
    // (RotationStep), its total step capped like the step itself.
    s.tau_step = s.dtau;
    if (cfg.accelerate && prev_dtau * s.dtau > 0 && std::abs(s.dtau) < std::abs(prev_dtau)) {
        const double r = s.dtau / prev_dtau;
        s.tau_step = std::clamp(s.dtau * (1.0 + std::min(r / (1.0 - r), 5.0)),
                                -cfg.latency_scan_step_s,
                                cfg.latency_scan_step_s);
    }
    return s;
}

// Accelerated ICP (Besl & McKay 1992, section IV): with correspondences found again every
// iteration the rotation converges linearly, its steps shrinking by a steady ratio r along one
// direction (bejanca: r ~ 0.7, still 0.0035 deg at the 12th iteration). When two steps agree in
// direction within 10 deg, the rest of that series, delta r / (1 - r) (at most 5 delta), is taken
// at once.
Eigen::Vector3d RotationStep(const Eigen::Vector3d& delta,
                             const Eigen::Vector3d& prev_delta,
                             const BoresightConfig& cfg) {
    Eigen::Vector3d step = delta;
    const double np = prev_delta.norm(), nd = delta.norm();
    if (cfg.accelerate && np > 0 && nd > 0 && nd < np &&
        delta.dot(prev_delta) > std::cos(frames::DegToRad(10.0)) * nd * np) {
        const double r = nd / np;
        step += delta * std::min(r / (1.0 - r), 5.0);
    }
    return step;
}

// What the iterations found.
struct MountFit {
    SonarMount mount;  // with the fitted boresight angles
    double tau = 0;    // the fitted latency (the start value without latency estimation)
    Termination termination = Termination::kMaxIterations;
    int iterations = 0;
    bool solve_failed = false;  // non-finite data: the previous iterate is kept
    bool latency_unresolved = false;
    double formal_sd_deg[3] = {0, 0, 0};
    double latency_formal_sd_s = 0;
    double height_offsets_rms_m = 0;
};

// Gauss-Newton over the boresight angles, the latency (estimate_latency; prior around tau0,
// starting at tau_start) and the node offsets, the pairs found again every iteration.
MountFit FitMount(const ShiftedPoses& poses,
                  const Samples& S,
                  const SonarMount& mount,
                  double tau0,
                  double tau_start,
                  double seg_len,
                  const BoresightConfig& cfg,
                  const ProgressCallback& progress) {
    MountFit fit;
    fit.mount = mount;
    fit.tau = tau_start;
    Eigen::Matrix3d R_vs = mount.R_vehicle_sonar();
    NodeOffsets offsets(cfg, seg_len);
    const int ldim = cfg.estimate_latency ? 1 : 0;
    const int base = 3 + ldim;  // [roll, pitch, yaw, (tau), offsets...]
    const int dim = base + offsets.size();
    using Scalar1 = Eigen::Matrix<double, 1, 1>;
    std::vector<Eigen::Vector3d> p;
    Eigen::Vector3d prev_delta = Eigen::Vector3d::Zero();
    double prev_dtau = 0;
    for (int it = 0; it < cfg.max_iterations; ++it) {
        if (progress && !progress(static_cast<double>(it) / cfg.max_iterations)) {
            fit.termination = Termination::kCancelled;
            break;
        }
        const double d_max = CorrespondenceGate(it, cfg);
        const PingPoses T(poses, S, fit.tau);
        Positions(T, S, fit.mount, p);
        for (std::size_t k = 0; k < p.size(); ++k) p[k] += offsets.At(S.t_s[k]);
        const std::vector<Pair> pairs = FindPairs(p, S, cfg, d_max);
        const std::vector<Eigen::Vector3d> rate =
            ldim > 0 ? LatencyRates(poses, S, pairs, fit.mount, fit.tau)
                     : std::vector<Eigen::Vector3d>{};
        reg::BlockSystem<1> sys(static_cast<std::size_t>(dim));
        const Pose T_vs_now = MakePose(R_vs, fit.mount.T_vehicle_sonar().translation());
        if (AddPairRows(T, S, pairs, rate, T_vs_now, offsets, base, cfg, sys) < 50) {
            fit.termination = Termination::kNoOverlap;
            break;
        }
        offsets.AddPriors(base, sys);
        if (ldim > 0) {
            const double sl = cfg.latency_sigma_s;
            sys.AddPrior(3, Scalar1::Constant(1.0 / (sl * sl)), Scalar1::Constant(fit.tau - tau0));
        }
        const double rot_trace = sys.diag()[0](0) + sys.diag()[1](0) + sys.diag()[2](0);
        for (std::size_t j = 0; j < 3; ++j)
            sys.AddPrior(j, Scalar1::Constant(1e-9 * rot_trace), Scalar1::Zero());
        // Gauss-Newton (no damping): the step is capped below where it matters (latency).
        reg::DampedSolver<1> solver(sys);
        Eigen::VectorXd x;
        if (!solver.Solve(0.0, &x)) {
            fit.solve_failed = true;
            break;
        }
        const Eigen::Vector3d delta = x.head<3>();
        double dtau = 0;
        if (ldim > 0) {
            const LatencyStep ls = StepLatency(x[3], prev_dtau, cfg);
            dtau = ls.dtau;
            fit.latency_unresolved = ls.unresolved;
            prev_dtau = dtau;
            fit.tau += ls.tau_step;
        }
        offsets.Update(x.tail(offsets.size()));
        const Eigen::MatrixXd C = solver.InverseLeadingBlock(base);
        for (int j = 0; j < 3; ++j)
            fit.formal_sd_deg[j] = frames::RadToDeg(std::sqrt(std::max(0.0, C(j, j))));
        if (ldim > 0) fit.latency_formal_sd_s = std::sqrt(std::max(0.0, C(3, 3)));
        fit.height_offsets_rms_m = offsets.Rms();
        R_vs = R_vs * ExpSO3(RotationStep(delta, prev_delta, cfg));
        prev_delta = delta;
        const frames::Rpy rpy = frames::RpyFromRotationNed(R_vs);
        fit.mount.boresight_roll_deg = frames::RadToDeg(rpy.roll);
        fit.mount.boresight_pitch_deg = frames::RadToDeg(rpy.pitch);
        fit.mount.boresight_yaw_deg = frames::RadToDeg(rpy.yaw);
        fit.iterations = it + 1;
        if (frames::RadToDeg(delta.norm()) < cfg.convergence_deg && std::abs(dtau) < 1e-4 &&
            d_max <= cfg.min_distance_m + 1e-9) {
            fit.termination = Termination::kConverged;
            break;
        }
    }
    return fit;
}

// Verification on up to num_verify_segments other low-drift candidates with overlap, apart from
// the segment and from each other. A drifting segment verifies nothing: its INS error moves the
// passes by more than any boresight, and on gps-outage (seeds 1, 3, 4) a window inside the GNSS
// outage rejected good calibrations.
std::vector<SegmentScore> VerifySegments(const std::vector<SegmentScore>& candidates,
                                         const SegmentScore& segment,
                                         const BoresightConfig& cfg) {
    std::vector<SegmentScore> others;
    for (const auto& c : candidates) {
        if (c.end_s <= segment.start_s || c.start_s >= segment.end_s) others.push_back(c);
    }
    std::sort(others.begin(), others.end(), BetterSegment);
    std::vector<SegmentScore> chosen;
    for (const auto& c : others) {
        if (static_cast<int>(chosen.size()) >= cfg.num_verify_segments) break;
        bool clash = false;
        for (const auto& o : chosen) clash |= !(c.end_s <= o.start_s || c.start_s >= o.end_s);
        if (!clash && c.overlap_cells > 0 && c.low_drift) chosen.push_back(c);
    }
    return chosen;
}

// The residuals on segment c before (nominal mount and latency) and after the calibration.
VerifyResult VerifyOn(const ViewWindows& view,
                      const ShiftedPoses& poses,
                      const SegmentScore& c,
                      const SonarMount& mount,
                      double tau0,
                      const BoresightResult& res,
                      const BoresightConfig& cfg) {
    const Samples V =
        CollectIndexed(view, poses, mount, tau0, c.start_s, c.end_s, cfg.verify_query_every, cfg);
    VerifyResult v{c,
                   Evaluate(poses, V, mount, tau0, cfg),
                   Evaluate(poses, V, res.mount, res.latency_s, cfg),
                   {}};
    if (res.latency_estimated) v.after_nominal_latency = Evaluate(poses, V, res.mount, tau0, cfg);
    return v;
}

std::string Summary(const BoresightResult& res, bool solve_failed) {
    char buf[256];
    std::snprintf(buf,
                  sizeof(buf),
                  "boresight roll %.3f pitch %.3f yaw %.3f deg (%s after %d iterations); "
                  "residual RMS %.4f -> %.4f m over %lld pairs",
                  res.mount.boresight_roll_deg,
                  res.mount.boresight_pitch_deg,
                  res.mount.boresight_yaw_deg,
                  ToString(res.termination),
                  res.iterations,
                  res.before.rms_m,
                  res.after.rms_m,
                  static_cast<long long>(res.after.pairs));
    std::string message = buf;
    if (solve_failed) message += "; stopped: the normal equations could not be solved";
    if (res.latency_estimated) {
        std::snprintf(buf,
                      sizeof(buf),
                      "; latency %+.4f s (formal sd %.4f s)",
                      res.latency_s,
                      res.latency_formal_sd_s);
        message += buf;
    }
    return message;
}

}  // namespace

ViewReader HeldView(const georef::GeorefPoints& points) {
    ViewReader r;
    r.size = points.size();
    r.read = [&points](std::size_t first, std::size_t end, const ViewVisit& visit) {
        end = std::min(end, points.size());
        if (first < end) visit(points, 0, first, end);
        return true;
    };
    return r;
}

BoresightResult CalibrateBoresight(const GeorefResult& geo,
                                   const survey::NavSeries& nav,
                                   const SonarMount& mount,
                                   const BoresightConfig& cfg,
                                   const ProgressCallback& progress) {
    return CalibrateBoresight(geo, HeldView(geo.points), nav, mount, cfg, progress);
}

BoresightResult CalibrateBoresight(const GeorefResult& geo,
                                   const ViewReader& reader,
                                   const survey::NavSeries& nav,
                                   const SonarMount& mount,
                                   const BoresightConfig& cfg,
                                   const ProgressCallback& progress) {
    BoresightResult res;
    res.mount = mount;
    if (geo.pings.size() < 2) {
        res.message = "too few georeferenced pings";
        return res;
    }
    const ViewWindows view(geo, reader);
    res.candidates = CandidateSegments(view, nav, cfg);
    res.segment = ChooseSegment(view, nav, res.candidates, cfg);

    const ShiftedPoses poses(geo, nav);
    const double tau0 = cfg.estimate_latency ? cfg.initial_latency_s : 0.0;
    const Samples S =
        CollectIndexed(view, poses, mount, tau0, res.segment.start_s, res.segment.end_s, 1, cfg);
    res.before = Evaluate(poses, S, mount, tau0, cfg);
    double tau = tau0;
    if (cfg.estimate_latency && cfg.latency_scan_s > 0) {
        tau = ScanLatency(poses, S, mount, tau0, cfg);
        res.latency_scan_best_s = tau;
    }

    const MountFit fit = FitMount(
        poses, S, mount, tau0, tau, res.segment.end_s - res.segment.start_s, cfg, progress);
    res.termination = fit.termination;
    res.iterations = fit.iterations;
    res.latency_unresolved = fit.latency_unresolved;
    std::copy_n(fit.formal_sd_deg, 3, res.formal_sd_deg);
    res.latency_formal_sd_s = fit.latency_formal_sd_s;
    res.height_offsets_rms_m = fit.height_offsets_rms_m;
    res.latency_estimated = cfg.estimate_latency && res.termination != Termination::kNoOverlap;
    res.latency_s = res.latency_estimated ? fit.tau : tau0;
    if (res.termination == Termination::kNoOverlap) {
        res.message = "no overlap between passes in the segment: boresight unchanged";
        return res;
    }
    res.mount = fit.mount;

    res.ins_attitude_reported = InsAttitudeSd(nav,
                                              res.segment.start_s,
                                              res.segment.end_s,
                                              res.mount,
                                              cfg.ins_attitude_correlation_time_s,
                                              res.ins_attitude_sd_deg);
    for (int j = 0; j < 3; ++j)
        res.sd_deg[j] = std::hypot(res.formal_sd_deg[j], res.ins_attitude_sd_deg[j]);
    res.after = Evaluate(poses, S, res.mount, res.latency_s, cfg);

    for (const auto& c : VerifySegments(res.candidates, res.segment, cfg))
        res.verify.push_back(VerifyOn(view, poses, c, mount, tau0, res, cfg));
    res.message = Summary(res, fit.solve_failed);
    return res;
}

}  // namespace pitmap::proc::calib
