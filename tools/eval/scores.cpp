// SPDX-License-Identifier: MIT
#include "tools/eval/scores.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "common/frames.hpp"
#include "common/se3.hpp"

namespace pitmap::eval {

std::vector<ProductPose> ProductPoses(const formats::TrajectoryCsv& trajectory) {
    std::vector<ProductPose> out;
    out.reserve(trajectory.rows.size());
    for (const formats::TrajectoryRow& r : trajectory.rows) {
        out.push_back({r.gps_time_s, r.position_world_m});
    }
    return out;
}

Pose ProductToTruthFrame(const Geodetic& product_origin, const Geodetic& truth_origin) {
    const LocalTangentFrame prod(product_origin), truth(truth_origin);
    // Images of the product frame's origin and axes in the truth frame.
    const Eigen::Vector3d o = truth.ToEnu(prod.FromEnu(Eigen::Vector3d::Zero()));
    Eigen::Matrix3d R;
    for (int i = 0; i < 3; ++i) {
        R.col(i) = (truth.ToEnu(prod.FromEnu(100.0 * Eigen::Vector3d::Unit(i))) - o) / 100.0;
    }
    // Re-orthonormalise (removes the tiny error of the 100 m finite differences).
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    return MakePose(svd.matrixU() * svd.matrixV().transpose(), o);
}

DistanceStats SummariseDistances(std::vector<double> d) {
    DistanceStats s;
    s.count = d.size();
    if (d.empty()) return s;
    double sum = 0, sum2 = 0, sum_abs = 0;
    for (double& v : d) {
        sum += v;
        sum2 += v * v;
        v = std::abs(v);
        sum_abs += v;
    }
    const auto n = static_cast<double>(d.size());
    s.bias_m = sum / n;
    s.rms_m = std::sqrt(sum2 / n);
    s.mean_abs_m = sum_abs / n;
    const auto k = static_cast<std::size_t>(std::ceil(0.95 * n)) - 1;
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
    s.p95_m = d[k];
    s.max_abs_m = *std::max_element(d.begin(), d.end());
    return s;
}

TrajectoryScore ScoreTrajectory(const std::vector<ProductPose>& est,
                                const Pose& T,
                                const std::vector<sim::TruthPose>& truth) {
    TrajectoryScore s;
    double sum2 = 0, zsum = 0, zsum2 = 0;
    for (const ProductPose& p : est) {
        auto t = sim::InterpolateTruth(truth, p.gps_time_s);
        if (!t) continue;
        const Eigen::Vector3d pt = T * p.position;
        const double e = (pt - t->translation()).norm();
        sum2 += e * e;
        s.ate_max_m = std::max(s.ate_max_m, e);
        zsum += pt.z();
        zsum2 += pt.z() * pt.z();
        ++s.poses;
    }
    if (s.poses > 0) {
        const auto n = static_cast<double>(s.poses);
        s.ate_rmse_m = std::sqrt(sum2 / n);
        s.z_std_m = std::sqrt(std::max(0.0, zsum2 / n - (zsum / n) * (zsum / n)));
    }
    return s;
}

std::vector<AteWindow> ScoreTrajectoryWindows(const std::vector<ProductPose>& after,
                                              const std::vector<ProductPose>& before,
                                              const Pose& T,
                                              const std::vector<sim::TruthPose>& truth,
                                              double window_s) {
    std::vector<AteWindow> out;
    if (!(window_s > 0) || truth.empty()) return out;
    const double t0 = truth.front().gps_time_s;
    const double t_end = truth.back().gps_time_s;
    auto slice = [](const std::vector<ProductPose>& v, double a, double b) {
        std::vector<ProductPose> s;
        for (const ProductPose& p : v) {
            if (p.gps_time_s >= a && p.gps_time_s < b) s.push_back(p);
        }
        return s;
    };
    const auto n = static_cast<std::size_t>(std::ceil((t_end - t0) / window_s));
    for (std::size_t k = 0; k < n; ++k) {
        const double a = t0 + static_cast<double>(k) * window_s;
        const double b = a + window_s;
        const TrajectoryScore sa = ScoreTrajectory(slice(after, a, b), T, truth);
        const TrajectoryScore sb = ScoreTrajectory(slice(before, a, b), T, truth);
        if (sa.poses == 0 || sb.poses == 0) continue;
        out.push_back({a - t0, b - t0, sa.poses, sb.ate_rmse_m, sa.ate_rmse_m});
    }
    return out;
}

Expected<std::vector<StatedPose>> ReadTrajectorySigmaCsv(const std::string& path) {
    std::ifstream in(path);
    if (!in) return Error{path + ": cannot open"};
    std::string line;
    if (!std::getline(in, line) || line.rfind("gps_time_s,", 0) != 0)
        return Error{path + ": not a trajectory_sigma.csv (no header)"};
    std::vector<StatedPose> out;
    std::size_t row = 1;
    while (std::getline(in, line)) {
        ++row;
        if (line.empty()) continue;
        std::array<double, 17> v{};
        std::stringstream ss(line);
        std::string cell;
        std::size_t n = 0;
        while (n < v.size() && std::getline(ss, cell, ',')) {
            char* end = nullptr;
            v[n] = std::strtod(cell.c_str(), &end);
            if (end == cell.c_str()) break;
            ++n;
        }
        if (n != v.size()) {
            return Error{path + ": row " + std::to_string(row) + " has " + std::to_string(n) +
                         " numbers, expected 17"};
        }
        StatedPose p;
        p.gps_time_s = v[0];
        p.position = {v[1], v[2], v[3]};
        p.initial = {v[4], v[5], v[6]};
        p.sigma_enu_m = {v[7], v[8], v[9]};
        p.ins_sigma_enu_m = {v[13], v[14], v[15]};
        p.slam_posterior = v[16] != 0;
        out.push_back(p);
    }
    return out;
}

namespace {

struct Containment {
    std::vector<double> error_h, radius_h;
    std::size_t within_h = 0, within_v = 0;
    void Add(const Eigen::Vector3d& err, const Eigen::Vector3d& sigma) {
        const double r = 2.4477 * std::sqrt(0.5 * (sigma.x() * sigma.x() + sigma.y() * sigma.y()));
        const double eh = err.head<2>().norm();
        error_h.push_back(eh);
        radius_h.push_back(r);
        within_h += eh <= r ? 1 : 0;
        within_v += std::abs(err.z()) <= 1.96 * sigma.z() ? 1 : 0;
    }
    ContainmentScore Score() {
        ContainmentScore s;
        s.poses = error_h.size();
        if (s.poses == 0) return s;
        const auto n = static_cast<double>(s.poses);
        s.share_within_h95 = static_cast<double>(within_h) / n;
        s.share_within_v95 = static_cast<double>(within_v) / n;
        const auto median = [](std::vector<double>& v) {
            std::nth_element(
                v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
            return v[v.size() / 2];
        };
        s.median_error_h_m = median(error_h);
        s.median_radius_h95_m = median(radius_h);
        return s;
    }
};

}  // namespace

UncertaintyScore ScoreUncertainty(const std::vector<StatedPose>& poses,
                                  const Pose& T,
                                  const std::vector<sim::TruthPose>& truth,
                                  double outage_sigma_m) {
    Containment after_all, after_outage, before_all, before_outage;
    for (const StatedPose& p : poses) {
        auto t = sim::InterpolateTruth(truth, p.gps_time_s);
        if (!t) continue;
        const Eigen::Vector3d e_after = T * p.position - t->translation();
        const Eigen::Vector3d e_before = T * p.initial - t->translation();
        const bool outage = p.ins_sigma_enu_m.head<2>().norm() / std::sqrt(2.0) > outage_sigma_m;
        after_all.Add(e_after, p.sigma_enu_m);
        before_all.Add(e_before, p.ins_sigma_enu_m);
        if (outage) {
            after_outage.Add(e_after, p.sigma_enu_m);
            before_outage.Add(e_before, p.ins_sigma_enu_m);
        }
    }
    return {after_all.Score(), after_outage.Score(), before_all.Score(), before_outage.Score()};
}

DistanceStats ScorePoints(const std::vector<Eigen::Vector3d>& pts,
                          const Pose& T,
                          const sim::PitWorld& world,
                          std::size_t max_points) {
    const std::size_t stride = std::max<std::size_t>(
        1, (pts.size() + max_points - 1) / std::max<std::size_t>(max_points, 1));
    std::vector<double> d;
    d.reserve(pts.size() / stride + 1);
    for (std::size_t i = 0; i < pts.size(); i += stride)
        d.push_back(world.SignedDistance(T * pts[i]));
    return SummariseDistances(std::move(d));
}

double SlopeDeg(const sim::PitWorld& world, double x, double y) {
    const double nz = std::clamp(std::abs(world.Normal(x, y).z()), 0.0, 1.0);
    return frames::RadToDeg(std::acos(nz));
}

namespace {

// Points hashed by cells of the search radius: a query looks at its 27 neighbouring cells,
// which hold every point within the radius.
class RadiusGrid {
public:
    RadiusGrid(const std::vector<Eigen::Vector3d>& points, double radius_m)
        : points_(points), radius_(radius_m) {
        keyed_.reserve(points.size());
        for (std::size_t i = 0; i < points.size(); ++i) {
            const Eigen::Vector3d& p = points[i];
            keyed_.emplace_back(Key(Cell(p.x()), Cell(p.y()), Cell(p.z())),
                                static_cast<std::uint32_t>(i));
        }
        std::sort(keyed_.begin(), keyed_.end());
    }
    bool AnyWithin(const Eigen::Vector3d& q) const {
        const std::int64_t cx = Cell(q.x()), cy = Cell(q.y()), cz = Cell(q.z());
        for (std::int64_t dx = -1; dx <= 1; ++dx)
            for (std::int64_t dy = -1; dy <= 1; ++dy)
                for (std::int64_t dz = -1; dz <= 1; ++dz) {
                    const std::int64_t k = Key(cx + dx, cy + dy, cz + dz);
                    auto it = std::lower_bound(
                        keyed_.begin(), keyed_.end(), std::make_pair(k, std::uint32_t{0}));
                    for (; it != keyed_.end() && it->first == k; ++it) {
                        if ((points_[it->second] - q).norm() <= radius_) return true;
                    }
                }
        return false;
    }

private:
    std::int64_t Cell(double v) const { return static_cast<std::int64_t>(std::floor(v / radius_)); }
    static std::int64_t Key(std::int64_t x, std::int64_t y, std::int64_t z) {
        return ((x & 0x1FFFFF) << 42) | ((y & 0x1FFFFF) << 21) | (z & 0x1FFFFF);
    }
    const std::vector<Eigen::Vector3d>& points_;
    double radius_;
    std::vector<std::pair<std::int64_t, std::uint32_t>> keyed_;
};

}  // namespace

std::vector<Eigen::Vector3d> SamplesInSharedCells(const std::vector<Eigen::Vector3d>& samples,
                                                  const std::vector<Eigen::Vector3d>& others,
                                                  double cell_m) {
    auto key = [cell_m](const Eigen::Vector3d& p) {
        return std::array<std::int64_t, 3>{static_cast<std::int64_t>(std::floor(p.x() / cell_m)),
                                           static_cast<std::int64_t>(std::floor(p.y() / cell_m)),
                                           static_cast<std::int64_t>(std::floor(p.z() / cell_m))};
    };
    std::vector<std::array<std::int64_t, 3>> cells;
    cells.reserve(others.size());
    for (const auto& q : others) cells.push_back(key(q));
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    std::vector<Eigen::Vector3d> shared;
    for (const auto& p : samples) {
        if (std::binary_search(cells.begin(), cells.end(), key(p))) shared.push_back(p);
    }
    return shared;
}

std::optional<double> MeshCompleteness(const std::vector<Eigen::Vector3d>& samples,
                                       const sim::Truth& truth,
                                       double radius_m,
                                       double min_slope_deg,
                                       double max_slope_deg,
                                       double min_depth_m,
                                       double max_depth_m) {
    if (truth.coverage.empty()) return std::nullopt;
    const RadiusGrid grid(samples, radius_m);
    const sim::TerrainGrid& g = truth.terrain;
    const sim::PitWorld world(g);
    std::size_t covered = 0, found = 0;
    for (int iy = 0; iy < g.ny; ++iy) {
        for (int ix = 0; ix < g.nx; ++ix) {
            if (truth.coverage[static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                               static_cast<std::size_t>(ix)] == 0)
                continue;
            const double sx = g.x0_m + ix * g.resolution_m, sy = g.y0_m + iy * g.resolution_m;
            if (min_slope_deg > 0 || max_slope_deg <= 90) {
                const double slope = SlopeDeg(world, sx, sy);
                if (slope < min_slope_deg || slope >= max_slope_deg) continue;
            }
            if (min_depth_m > 0 || max_depth_m < std::numeric_limits<double>::infinity()) {
                const double depth = world.Depth(sx, sy);
                if (depth < min_depth_m || depth >= max_depth_m) continue;
            }
            ++covered;
            if (grid.AnyWithin(Eigen::Vector3d(sx, sy, world.Height(sx, sy)))) ++found;
        }
    }
    if (covered == 0) return std::nullopt;
    return static_cast<double>(found) / static_cast<double>(covered);
}

double BoresightErrorDeg(double re, double pe, double ye, double rt, double pt, double yt) {
    using frames::DegToRad;
    const Eigen::Matrix3d a = frames::RotationNedFromRpy(DegToRad(re), DegToRad(pe), DegToRad(ye));
    const Eigen::Matrix3d b = frames::RotationNedFromRpy(DegToRad(rt), DegToRad(pt), DegToRad(yt));
    return frames::RadToDeg(RotationAngleBetween(a, b));
}

DemScore ScoreDem(const std::vector<Eigen::Vector3d>& nodes, const sim::Truth& truth) {
    DemScore out;
    const sim::TerrainGrid& g = truth.terrain;
    const sim::PitWorld world(g);
    const bool have_cov = !truth.coverage.empty();
    std::vector<double> all, inson;
    std::size_t filled_inson = 0;
    for (const Eigen::Vector3d& p : nodes) {
        const double fx = (p.x() - g.x0_m) / g.resolution_m, fy = (p.y() - g.y0_m) / g.resolution_m;
        const long ix = std::lround(fx), iy = std::lround(fy);
        if (ix < 0 || iy < 0 || ix >= g.nx || iy >= g.ny) continue;
        const bool covered =
            have_cov &&
            truth.coverage[static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                           static_cast<std::size_t>(ix)] != 0;
        out.insonified_nodes += covered;
        if (!std::isfinite(p.z())) continue;
        const double d = p.z() - world.Height(p.x(), p.y());
        all.push_back(d);
        if (covered) {
            inson.push_back(d);
            ++filled_inson;
        }
    }
    out.all = SummariseDistances(std::move(all));
    out.insonified = SummariseDistances(std::move(inson));
    if (have_cov && out.insonified_nodes > 0) {
        out.fill_insonified =
            static_cast<double>(filled_inson) / static_cast<double>(out.insonified_nodes);
    }
    return out;
}

std::optional<MosaicScore> ScoreMosaic(const std::vector<Eigen::Vector3d>& nodes,
                                       double resolution_m,
                                       const sim::Truth& truth,
                                       std::size_t min_patch_nodes) {
    if (truth.backscatter_db.empty()) return std::nullopt;
    const sim::TerrainGrid& g = truth.terrain;
    const auto truth_at = [&](double x, double y) -> double {
        const long ix = std::lround((x - g.x0_m) / g.resolution_m);
        const long iy = std::lround((y - g.y0_m) / g.resolution_m);
        if (ix < 0 || iy < 0 || ix >= g.nx || iy >= g.ny) return std::nan("");
        return truth.backscatter_db[static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                                    static_cast<std::size_t>(ix)];
    };
    const double h = 0.75 * resolution_m;
    const double patch = truth.backscatter.patch_size_m;
    struct Node {
        double est, tru;
        long px, py;
    };
    std::vector<Node> kept;
    for (const Eigen::Vector3d& p : nodes) {
        if (!std::isfinite(p.z())) continue;
        const double t = truth_at(p.x(), p.y());
        if (!std::isfinite(t)) continue;
        bool uniform = true;
        for (const auto& [dx, dy] : {std::pair{-h, -h}, {h, -h}, {-h, h}, {h, h}, {0.0, 0.0}}) {
            if (truth_at(p.x() + dx, p.y() + dy) != t) uniform = false;
        }
        if (!uniform) continue;
        kept.push_back({p.z(),
                        t,
                        static_cast<long>(std::floor(p.x() / patch)),
                        static_cast<long>(std::floor(p.y() / patch))});
    }
    MosaicScore out;
    out.nodes = kept.size();
    if (kept.size() < 2) return out;
    std::vector<double> diff(kept.size());
    double me = 0, mt = 0;
    for (std::size_t k = 0; k < kept.size(); ++k) {
        diff[k] = kept[k].est - kept[k].tru;
        me += kept[k].est;
        mt += kept[k].tru;
    }
    me /= static_cast<double>(kept.size());
    mt /= static_cast<double>(kept.size());
    double see = 0, stt = 0, set = 0;
    for (const Node& n : kept) {
        see += (n.est - me) * (n.est - me);
        stt += (n.tru - mt) * (n.tru - mt);
        set += (n.est - me) * (n.tru - mt);
    }
    out.correlation = see > 0 && stt > 0 ? set / std::sqrt(see * stt) : 0.0;
    std::vector<double> sorted = diff;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    out.offset_db = sorted[sorted.size() / 2];
    double ss = 0;
    // Patches keyed by square and truth level (boulders in a square are their own patch).
    std::map<std::tuple<long, long, double>, std::pair<double, std::size_t>> patches;
    std::map<double, std::pair<double, std::size_t>> levels;
    for (std::size_t k = 0; k < kept.size(); ++k) {
        const double e = diff[k] - out.offset_db;
        ss += e * e;
        auto& pa = patches[{kept[k].px, kept[k].py, kept[k].tru}];
        pa.first += e;
        ++pa.second;
        auto& le = levels[kept[k].tru];
        le.first += e;
        ++le.second;
    }
    out.rms_db = std::sqrt(ss / static_cast<double>(kept.size()));
    double sum_abs = 0;
    for (const auto& [key, v] : patches) {
        if (v.second < min_patch_nodes) continue;
        const double m = std::abs(v.first / static_cast<double>(v.second));
        sum_abs += m;
        out.patch_max_abs_db = std::max(out.patch_max_abs_db, m);
        ++out.patches;
    }
    if (out.patches > 0) out.patch_mean_abs_db = sum_abs / static_cast<double>(out.patches);
    for (const auto& [level, v] : levels) {
        out.by_level.emplace_back(level, v.first / static_cast<double>(v.second), v.second);
    }
    return out;
}

namespace {

// Sums of one TPU class.
struct TpuAccumulator {
    std::size_t n = 0, in_tvu = 0, in_thu = 0;
    double ss_err = 0, sum_err = 0, ss_tvu = 0;
    void Add(const Eigen::Vector3d& e, double tvu_95_m, double thu_95_m) {
        ++n;
        in_tvu += std::abs(e.z()) <= tvu_95_m;
        in_thu += e.head<2>().norm() <= thu_95_m;
        ss_err += e.z() * e.z();
        sum_err += e.z();
        ss_tvu += (tvu_95_m / 1.96) * (tvu_95_m / 1.96);
    }
    TpuBin Bin(double lo, double hi) const {
        TpuBin t;
        t.lo = lo;
        t.hi = hi;
        t.count = n;
        if (n == 0) return t;
        const auto c = static_cast<double>(n);
        t.within_tvu = static_cast<double>(in_tvu) / c;
        t.within_thu = static_cast<double>(in_thu) / c;
        t.vertical_rms_m = std::sqrt(ss_err / c);
        t.tvu_rms_m = std::sqrt(ss_tvu / c);
        t.vertical_bias_m = sum_err / c;
        return t;
    }
};

// The class of v among edges[0..n-1] ([edge i, edge i + 1)), or -1 outside them.
template <std::size_t N>
int ClassOf(const double (&edges)[N], double v) {
    for (std::size_t i = 0; i + 1 < N; ++i) {
        if (v >= edges[i] && v < edges[i + 1]) return static_cast<int>(i);
    }
    return -1;
}

template <std::size_t N>
std::vector<TpuBin> TpuBins(const double (&edges)[N], const std::vector<TpuAccumulator>& acc) {
    std::vector<TpuBin> out;
    for (std::size_t i = 0; i + 1 < N; ++i) out.push_back(acc[i].Bin(edges[i], edges[i + 1]));
    return out;
}

}  // namespace

TpuScore ScoreTpu(const std::vector<TpuSounding>& snd,
                  const sim::Truth& truth,
                  const sim::PitWorld& world,
                  std::size_t max_soundings,
                  const sim::WaterColumn* water) {
    TpuScore out;
    const auto& b = truth.boresight;
    const double deg = M_PI / 180.0;
    Eigen::Vector3d arm = Eigen::Vector3d::Zero();
    if (b.lever_arm_sonar_m.size() == 3) {
        arm =
            Eigen::Vector3d(b.lever_arm_sonar_m[0], b.lever_arm_sonar_m[1], b.lever_arm_sonar_m[2]);
    }
    const Pose T_vehicle_sonar = MakePose(
        frames::RotationNedFromRpy(b.roll_deg * deg, b.pitch_deg * deg, b.yaw_deg * deg), arm);
    constexpr int kBins = 7;  // 0..70 deg
    constexpr std::size_t kAngleClasses = std::size(kTpuAngleClassEdgesDeg) - 1;
    constexpr std::size_t kDepthClasses = std::size(kTpuDepthClassEdgesM) - 1;
    constexpr std::size_t kSlopeClasses = std::size(kSlopeClassEdgesDeg) - 1;
    std::vector<TpuAccumulator> bins(kBins), angle_class(kAngleClasses), depth(kDepthClasses),
        slope(kSlopeClasses);
    TpuAccumulator all;
    const std::size_t stride = std::max<std::size_t>(
        1, (snd.size() + max_soundings - 1) / std::max<std::size_t>(max_soundings, 1));
    for (std::size_t i = 0; i < snd.size(); i += stride) {
        const TpuSounding& s = snd[i];
        auto pose = sim::InterpolateTruth(truth.trajectory, s.gps_time_s);
        if (!pose) {
            ++out.no_truth;
            continue;
        }
        const Pose T_world_sonar = *pose * T_vehicle_sonar;
        const double th = s.angle_deg * deg;
        const Eigen::Vector3d dir =
            T_world_sonar.linear() * Eigen::Vector3d(0, std::sin(th), std::cos(th));
        std::optional<Eigen::Vector3d> hit;
        if (water != nullptr) {
            // A one-way time long enough for any beam of the pit (500 m at 1400 m/s).
            if (auto h = water->Cast(world, T_world_sonar.translation(), dir, 0.36)) {
                hit = h->point;
            }
        } else if (auto r = world.RayCast(T_world_sonar.translation(), dir, 500.0)) {
            hit = T_world_sonar.translation() + *r * dir;
        }
        if (!hit) {
            ++out.no_truth;
            continue;
        }
        const Eigen::Vector3d e = s.position - *hit;
        const double abs_angle = std::abs(s.angle_deg);
        all.Add(e, s.tvu_95_m, s.thu_95_m);
        bins[std::min(kBins - 1, static_cast<int>(abs_angle / 10.0))].Add(
            e, s.tvu_95_m, s.thu_95_m);
        if (int k = ClassOf(kTpuAngleClassEdgesDeg, abs_angle); k >= 0) {
            angle_class[k].Add(e, s.tvu_95_m, s.thu_95_m);
        }
        if (int k = ClassOf(kTpuDepthClassEdgesM, std::max(0.0, -hit->z())); k >= 0) {
            depth[k].Add(e, s.tvu_95_m, s.thu_95_m);
        }
        if (int k = ClassOf(kSlopeClassEdgesDeg, SlopeDeg(world, hit->x(), hit->y())); k >= 0) {
            slope[k].Add(e, s.tvu_95_m, s.thu_95_m);
        }
    }
    for (int k = 0; k < kBins; ++k) out.by_angle.push_back(bins[k].Bin(10.0 * k, 10.0 * (k + 1)));
    out.all = all.Bin(0, 90);
    out.by_angle_class = TpuBins(kTpuAngleClassEdgesDeg, angle_class);
    out.by_depth = TpuBins(kTpuDepthClassEdgesM, depth);
    out.by_slope = TpuBins(kSlopeClassEdgesDeg, slope);
    return out;
}

DemUncertaintyScore ScoreDemUncertainty(const std::vector<Eigen::Vector3d>& nodes,
                                        const std::vector<double>& uncertainty_95_m,
                                        const sim::Truth& truth) {
    const sim::TerrainGrid& g = truth.terrain;
    const sim::PitWorld world(g);
    struct Acc {
        std::size_t n = 0, in = 0;
        double ss_err = 0, ss_stated = 0;
        void Add(double e, double u) {
            ++n;
            in += std::abs(e) <= u;
            ss_err += e * e;
            ss_stated += (u / 1.96) * (u / 1.96);
        }
        DemUncertaintyBin Bin(double lo, double hi) const {
            DemUncertaintyBin b;
            b.lo = lo;
            b.hi = hi;
            b.count = n;
            if (n == 0) return b;
            const auto c = static_cast<double>(n);
            b.within = static_cast<double>(in) / c;
            b.error_rms_m = std::sqrt(ss_err / c);
            b.stated_rms_m = std::sqrt(ss_stated / c);
            return b;
        }
    };
    constexpr std::size_t kSlopes = std::size(kSlopeClassEdgesDeg) - 1;
    constexpr std::size_t kDepths = std::size(kTpuDepthClassEdgesM) - 1;
    Acc all;
    std::vector<Acc> slope(kSlopes), depth(kDepths);
    for (std::size_t i = 0; i < nodes.size() && i < uncertainty_95_m.size(); ++i) {
        const Eigen::Vector3d& p = nodes[i];
        const double u = uncertainty_95_m[i];
        if (!std::isfinite(p.z()) || !std::isfinite(u)) continue;
        const double fx = (p.x() - g.x0_m) / g.resolution_m, fy = (p.y() - g.y0_m) / g.resolution_m;
        if (fx < 0 || fy < 0 || fx > g.nx - 1 || fy > g.ny - 1) continue;
        const double e = p.z() - world.Height(p.x(), p.y());
        all.Add(e, u);
        if (int k = ClassOf(kSlopeClassEdgesDeg, SlopeDeg(world, p.x(), p.y())); k >= 0) {
            slope[k].Add(e, u);
        }
        if (int k = ClassOf(kTpuDepthClassEdgesM, world.Depth(p.x(), p.y())); k >= 0) {
            depth[k].Add(e, u);
        }
    }
    DemUncertaintyScore out;
    out.all = all.Bin(0, 0);
    for (std::size_t k = 0; k < kSlopes; ++k) {
        out.by_slope.push_back(slope[k].Bin(kSlopeClassEdgesDeg[k], kSlopeClassEdgesDeg[k + 1]));
    }
    for (std::size_t k = 0; k < kDepths; ++k) {
        out.by_depth.push_back(depth[k].Bin(kTpuDepthClassEdgesM[k], kTpuDepthClassEdgesM[k + 1]));
    }
    return out;
}

ArtifactScore ScoreArtifacts(const std::vector<Eigen::Vector3d>& points,
                             const std::vector<double>& gps_time_s,
                             const std::vector<int>& beam,
                             const sim::ArtifactTruth& truth,
                             const sim::PitWorld& world) {
    ArtifactScore out;
    out.points = points.size();
    std::vector<double> good;
    good.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        const double k_real = (gps_time_s[i] - truth.first_ping_gps_s) * truth.ping_rate_hz;
        const double k = std::round(k_real);
        if (std::abs(k_real - k) > 0.25 || k < 0 || beam[i] < 0) {
            ++out.unmatched;
            continue;
        }
        const sim::EchoArtifactKind kind = truth.KindOf(static_cast<std::int64_t>(k), beam[i]);
        if (kind != sim::EchoArtifactKind::kNone) {
            ++out.in_points[static_cast<int>(kind)];
            continue;
        }
        ++out.good_in_points;
        const double slope = SlopeDeg(world, points[i].x(), points[i].y());
        for (int c = 0; c < sim::kNumArtifactSlopeClasses; ++c) {
            if (slope >= sim::kArtifactSlopeEdgesDeg[c] &&
                slope < sim::kArtifactSlopeEdgesDeg[c + 1])
                ++out.good_in_points_by_slope[c];
        }
        good.push_back(world.SignedDistance(points[i]));
    }
    out.good = SummariseDistances(std::move(good));
    return out;
}

std::size_t KeepAccepted(formats::ply::Mesh& cloud, std::size_t status_index) {
    auto& props = cloud.vertex_properties;
    if (status_index >= props.size()) return 0;
    const std::vector<double> status = std::move(props[status_index]);
    props.erase(props.begin() + static_cast<std::ptrdiff_t>(status_index));
    const bool beams = cloud.vertex_beam.size() == cloud.vertices.size();
    std::size_t out = 0;
    for (std::size_t i = 0; i < cloud.vertices.size(); ++i) {
        if (!(i < status.size() && status[i] == 0.0)) continue;
        cloud.vertices[out] = cloud.vertices[i];
        if (beams) cloud.vertex_beam[out] = cloud.vertex_beam[i];
        for (auto& p : props) {
            if (i < p.size()) p[out] = p[i];
        }
        ++out;
    }
    const std::size_t dropped = cloud.vertices.size() - out;
    cloud.vertices.resize(out);
    if (beams) cloud.vertex_beam.resize(out);
    for (auto& p : props) p.resize(std::min(p.size(), out));
    return dropped;
}

Expected<std::vector<std::string>> PlyVertexProperties(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open"};
    std::string head(formats::ply::kMaxHeaderBytes, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(in.gcount()));
    in.clear();
    in.seekg(0, std::ios::end);
    const auto size = static_cast<std::uint64_t>(std::max<std::streamoff>(in.tellg(), 0));
    std::size_t header_bytes = 0;
    auto h = formats::ply::ParseHeader(head, size, &header_bytes);
    if (!h) return Error{path + ": " + h.error().message};
    std::vector<std::string> names;
    for (const auto& e : h->elements) {
        if (e.name != "vertex") continue;
        for (const auto& p : e.properties) names.push_back(p.name);
    }
    return names;
}

}  // namespace pitmap::eval
