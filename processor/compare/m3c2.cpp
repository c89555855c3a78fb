// SPDX-License-Identifier: MIT
#include "processor/compare/m3c2.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <unordered_set>

#include "processor/registration/neighbours.hpp"
#include "processor/registration/normals.hpp"

namespace pitmap::proc::compare {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

struct Cylinder {
    int n = 0;
    double mean = 0, sd = 0;
};

// The positions along n of the soundings of `index` in the cylinder about c along n, sorted.
void AlongCylinder(const reg::PointIndex<double>& index,
                   const Eigen::Vector3d& c,
                   const Eigen::Vector3d& n,
                   double radius,
                   double depth,
                   std::vector<reg::PointIndex<double>::Hit>& hits,
                   std::vector<double>& along) {
    index.WithinCylinder(c, n, radius, depth, hits, along);
    std::sort(along.begin(), along.end());
}

// One surface of a cylinder's sorted positions: they are split where two consecutive ones lie
// more than `gap` apart, and the group nearest to `target` is taken (its count, mean and
// standard deviation). A cylinder of max_depth_m along the normal can hold a second surface
// (the far face of a ridge or a boulder, the other side of a narrow cut); averaged with the
// near one it reads as a change of half their distance.
Cylinder NearestSurface(const std::vector<double>& along, double target, double gap) {
    Cylinder best;
    double best_miss = std::numeric_limits<double>::infinity();
    std::size_t begin = 0;
    for (std::size_t k = 1; k <= along.size(); ++k) {
        if (k < along.size() && along[k] - along[k - 1] <= gap) continue;
        // The group [begin, k): its distance to the target (0 inside it).
        const double miss = std::max({0.0, along[begin] - target, target - along[k - 1]});
        if (miss < best_miss) {
            best_miss = miss;
            double sum = 0, sum2 = 0;
            for (std::size_t q = begin; q < k; ++q) sum += along[q];
            best.n = static_cast<int>(k - begin);
            best.mean = sum / best.n;
            for (std::size_t q = begin; q < k; ++q)
                sum2 += (along[q] - best.mean) * (along[q] - best.mean);
            best.sd = best.n > 1 ? std::sqrt(sum2 / (best.n - 1)) : 0.0;
        }
        begin = k;
    }
    return best;
}

}  // namespace

std::vector<std::string> M3c2Config::Validate() const {
    std::vector<std::string> p;
    if (!(core_spacing_m > 0)) p.push_back("m3c2.core_spacing_m must be > 0");
    if (!(normal_radius_m > 0)) p.push_back("m3c2.normal_radius_m must be > 0");
    if (!(projection_radius_m > 0)) p.push_back("m3c2.projection_radius_m must be > 0");
    if (!(max_depth_m > 0)) p.push_back("m3c2.max_depth_m must be > 0");
    if (!(surface_gap_m > 0)) p.push_back("m3c2.surface_gap_m must be > 0");
    if (!(max_planarity_ratio > 0 && max_planarity_ratio <= 1))
        p.push_back("m3c2.max_planarity_ratio must be in (0, 1]");
    if (min_points < 2) p.push_back("m3c2.min_points must be >= 2");
    if (!(z95 > 0)) p.push_back("m3c2.z95 must be > 0");
    if (min_cluster_cores < 1) p.push_back("m3c2.min_cluster_cores must be >= 1");
    if (!(cluster_radius_m > 0)) p.push_back("m3c2.cluster_radius_m must be > 0");
    return p;
}

M3c2Result RunM3c2(const std::vector<Eigen::Vector3d>& a,
                   const std::vector<Eigen::Vector3d>& b,
                   const Eigen::Vector3d& inside,
                   const RigidCorrection& T,
                   const Eigen::Matrix<double, 6, 6>& C,
                   const M3c2Config& cfg,
                   const std::function<double(const Eigen::Vector3d&)>& sigma_common) {
    M3c2Result r;
    if (a.empty() || b.empty()) {
        r.message = "no soundings to compare";
        return r;
    }
    const reg::PointIndex<double> ia(a.data(), a.size());
    const reg::PointIndex<double> ib(b.data(), b.size());
    // Core points: the first sounding of A in each voxel.
    std::unordered_set<std::int64_t> seen;
    std::vector<Eigen::Vector3d> cores;
    const Eigen::Vector3d origin = a.front();
    for (const Eigen::Vector3d& p : a) {
        const Eigen::Vector3d q = (p - origin) / cfg.core_spacing_m;
        const auto ix = static_cast<std::int64_t>(std::floor(q.x())) & 0x1FFFFF;
        const auto iy = static_cast<std::int64_t>(std::floor(q.y())) & 0x1FFFFF;
        const auto iz = static_cast<std::int64_t>(std::floor(q.z())) & 0x1FFFFF;
        if (seen.insert((ix << 42) | (iy << 21) | iz).second) cores.push_back(p);
    }
    r.cores.resize(cores.size());
    std::vector<reg::PointIndex<double>::Hit> hits;
    std::vector<double> along;
    for (std::size_t k = 0; k < cores.size(); ++k) {
        M3c2Core& core = r.cores[k];
        core.position = cores[k];
        core.distance_m = std::numeric_limits<float>::quiet_NaN();
        core.lod95_m = std::numeric_limits<float>::quiet_NaN();
        // The normal from both surveys' soundings: A's alone may be one swath's edge, a strip
        // a few pings wide whose plane tilts with the surface's curvature across it (on the
        // quarry's 150 s pair, 12 deg where the face is 28 deg: B's soundings then spread
        // along the normal and their mean reads as a loss of 0.1 m). Each survey's own
        // neighbourhood must be a plane, their union need not be: a change offsets them.
        reg::MomentAccumulator m, m_own[2];
        for (int e = 0; e < 2; ++e) {
            const reg::PointIndex<double>& index = e == 0 ? ia : ib;
            index.WithinRadius(cores[k], cfg.normal_radius_m * cfg.normal_radius_m, hits);
            for (const auto& [i, d2] : hits) {
                m.Add(index.point(i));
                m_own[e].Add(index.point(i));
            }
        }
        if (m_own[0].count() < 3 || m_own[1].count() < 3) continue;
        const reg::PlaneFit fit = reg::FitPlane(m);
        if (!fit.valid) continue;
        if (!reg::FitPlane(m_own[0]).Planar(cfg.max_planarity_ratio) ||
            !reg::FitPlane(m_own[1]).Planar(cfg.max_planarity_ratio)) {
            // No plane at the normal's scale (a ridge's crest, a boulder, a corner): a normal
            // and a distance along it are not defined (Lague et al. 2013, sec. 3.2: the normal
            // scale must exceed the roughness many times).
            ++r.not_planar;
            continue;
        }
        Eigen::Vector3d n = fit.normal;
        if (std::abs(n.z()) < std::sin(25.0 / kRadToDeg)) {
            // A wall: the normal points into the pit, where the water (and the sonar) is.
            Eigen::Vector3d towards = inside - cores[k];
            towards.z() = 0;
            if (n.dot(towards) < 0) n = -n;
        } else if (n.z() < 0) {
            n = -n;
        }
        core.normal = n;
        core.slope_deg = static_cast<float>(std::acos(std::min(1.0, std::abs(n.z()))) * kRadToDeg);
        // A's surface is the one through the core (one of A's soundings, at 0 along n); B's
        // the one nearest to A's.
        AlongCylinder(ia, cores[k], n, cfg.projection_radius_m, cfg.max_depth_m, hits, along);
        const Cylinder ca = NearestSurface(along, 0.0, cfg.surface_gap_m);
        AlongCylinder(ib, cores[k], n, cfg.projection_radius_m, cfg.max_depth_m, hits, along);
        const Cylinder cb = NearestSurface(along, ca.mean, cfg.surface_gap_m);
        core.n_a = ca.n;
        core.n_b = cb.n;
        if (ca.n < cfg.min_points || cb.n < cfg.min_points) continue;
        Eigen::Matrix<double, 1, 6> J;
        J.head<3>() = ((cores[k] - T.pivot).cross(n)).transpose();
        J.tail<3>() = n.transpose();
        const double var_reg = std::max(0.0, (J * C * J.transpose())(0, 0));
        const double d = cb.mean - ca.mean;
        double common = sigma_common ? sigma_common(cores[k]) : 0.0;
        if (!std::isfinite(common)) common = 0.0;
        const double lod = cfg.z95 * std::sqrt(ca.sd * ca.sd / ca.n + cb.sd * cb.sd / cb.n +
                                               common * common + var_reg);
        core.distance_m = static_cast<float>(d);
        core.lod95_m = static_cast<float>(lod);
        core.significance = std::abs(d) > lod ? (d > 0 ? 1 : -1) : 0;
        ++r.measured;
        r.significant += core.significance != 0;
    }
    // Clusters: a significant core needs min_cluster_cores of its sign around it.
    if (cfg.min_cluster_cores > 1) {
        for (const int sign : {-1, 1}) {
            std::vector<Eigen::Vector3d> pts;
            std::vector<std::size_t> which;
            for (std::size_t k = 0; k < r.cores.size(); ++k) {
                if (r.cores[k].significance == sign) {
                    pts.push_back(r.cores[k].position);
                    which.push_back(k);
                }
            }
            if (pts.empty()) continue;
            const reg::PointIndex<double> index(pts.data(), pts.size());
            std::vector<std::size_t> drop;
            for (std::size_t q = 0; q < pts.size(); ++q) {
                index.WithinRadius(pts[q], cfg.cluster_radius_m * cfg.cluster_radius_m, hits);
                if (static_cast<int>(hits.size()) < cfg.min_cluster_cores) drop.push_back(which[q]);
            }
            for (std::size_t k : drop) r.cores[k].significance = 0;
            r.isolated += drop.size();
            r.significant -= drop.size();
        }
    }
    char buf[240];
    std::snprintf(buf,
                  sizeof buf,
                  "%zu core points (%zu on no plane), %zu measured along their normal, %zu "
                  "significant (%zu isolated ones dropped)",
                  r.cores.size(),
                  r.not_planar,
                  r.measured,
                  r.significant,
                  r.isolated);
    r.message = buf;
    return r;
}

}  // namespace pitmap::proc::compare
