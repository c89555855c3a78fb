// SPDX-License-Identifier: MIT
#include "processor/compare/design.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace pitmap::proc::compare {

std::vector<std::string> DesignConfig::Validate() const {
    std::vector<std::string> p;
    if (!(z95 > 0)) p.push_back("design.z95 must be > 0");
    return p;
}

SurfaceGrid RasterizeMesh(const TriangleMesh& mesh, const SurfaceGrid& like) {
    SurfaceGrid out = like;
    out.z_m.assign(like.z_m.size(), std::numeric_limits<float>::quiet_NaN());
    out.sigma_m.assign(like.z_m.size(), 0.0f);
    if (mesh.triangles.empty() || like.nx <= 0 || like.ny <= 0) return out;
    // Triangles by the 1 m cells of their footprint's bounding box.
    constexpr double kCell = 1.0;
    const double gx0 = like.x0, gy0 = like.y0;
    const int cx = static_cast<int>(std::ceil((like.nx - 1) * like.resolution_m / kCell)) + 1;
    const int cy = static_cast<int>(std::ceil((like.ny - 1) * like.resolution_m / kCell)) + 1;
    std::vector<std::vector<int>> cells(static_cast<std::size_t>(cx) *
                                        static_cast<std::size_t>(cy));
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
        for (int k : mesh.triangles[t]) {
            const Eigen::Vector3d& v = mesh.vertices[static_cast<std::size_t>(k)];
            x0 = std::min(x0, v.x());
            x1 = std::max(x1, v.x());
            y0 = std::min(y0, v.y());
            y1 = std::max(y1, v.y());
        }
        const int i0 = std::max(0, static_cast<int>(std::floor((x0 - gx0) / kCell)));
        const int i1 = std::min(cx - 1, static_cast<int>(std::floor((x1 - gx0) / kCell)));
        const int j0 = std::max(0, static_cast<int>(std::floor((y0 - gy0) / kCell)));
        const int j1 = std::min(cy - 1, static_cast<int>(std::floor((y1 - gy0) / kCell)));
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i)
                cells[static_cast<std::size_t>(j) * static_cast<std::size_t>(cx) +
                      static_cast<std::size_t>(i)]
                    .push_back(static_cast<int>(t));
    }
    for (int j = 0; j < like.ny; ++j) {
        for (int i = 0; i < like.nx; ++i) {
            const double x = like.x0 + i * like.resolution_m, y = like.y0 + j * like.resolution_m;
            const int ci = std::min(cx - 1, static_cast<int>((x - gx0) / kCell));
            const int cj = std::min(cy - 1, static_cast<int>((y - gy0) / kCell));
            double best = -std::numeric_limits<double>::infinity();
            for (int t : cells[static_cast<std::size_t>(cj) * static_cast<std::size_t>(cx) +
                               static_cast<std::size_t>(ci)]) {
                const auto& tri = mesh.triangles[static_cast<std::size_t>(t)];
                const Eigen::Vector3d& a = mesh.vertices[static_cast<std::size_t>(tri[0])];
                const Eigen::Vector3d& b = mesh.vertices[static_cast<std::size_t>(tri[1])];
                const Eigen::Vector3d& c = mesh.vertices[static_cast<std::size_t>(tri[2])];
                // Barycentric coordinates of (x, y) in the triangle's footprint.
                const double det =
                    (b.y() - c.y()) * (a.x() - c.x()) + (c.x() - b.x()) * (a.y() - c.y());
                if (std::abs(det) < 1e-12) continue;  // a vertical triangle
                const double l1 =
                    ((b.y() - c.y()) * (x - c.x()) + (c.x() - b.x()) * (y - c.y())) / det;
                const double l2 =
                    ((c.y() - a.y()) * (x - c.x()) + (a.x() - c.x()) * (y - c.y())) / det;
                const double l3 = 1.0 - l1 - l2;
                if (l1 < -1e-9 || l2 < -1e-9 || l3 < -1e-9) continue;
                best = std::max(best, l1 * a.z() + l2 * b.z() + l3 * c.z());
            }
            if (std::isfinite(best)) out.z_m[out.index(i, j)] = static_cast<float>(best);
        }
    }
    return out;
}

DesignResult CompareWithDesign(const SurfaceGrid& s,
                               const SurfaceGrid& d,
                               const DesignConfig& cfg) {
    DesignResult r;
    const std::size_t n = s.z_m.size();
    constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
    r.difference_m.assign(n, kNaNf);
    r.u95_m.assign(n, kNaNf);
    r.significance.assign(n, kNaNf);
    const double cell = s.resolution_m * s.resolution_m;
    double sum_sigma_above = 0, sum_sigma_below = 0, sum_diff = 0;
    for (int j = 0; j < s.ny; ++j) {
        for (int i = 0; i < s.nx; ++i) {
            const std::size_t k = s.index(i, j);
            if (!s.filled(i, j)) continue;
            const double zd = d.HeightAt(s.x0 + i * s.resolution_m, s.y0 + j * s.resolution_m);
            if (!std::isfinite(zd)) continue;
            const double diff = s.z_m[k] - zd;
            const double sigma = std::isfinite(s.sigma_m[k]) ? s.sigma_m[k] : 0.0;
            const double u = cfg.z95 * sigma;
            r.difference_m[k] = static_cast<float>(diff);
            r.u95_m[k] = static_cast<float>(u);
            const int sig = std::abs(diff) > u ? (diff > 0 ? 1 : -1) : 0;
            r.significance[k] = static_cast<float>(sig);
            ++r.compared_nodes;
            sum_diff += diff;
            if (diff > 0) {
                r.above_m3 += diff * cell;
                r.above_area_m2 += cell;
            } else if (diff < 0) {
                r.below_m3 += diff * cell;
                r.below_area_m2 += cell;
            }
            // A node within its own uncertainty of the design may lie on either side.
            if (diff > 0 || sig == 0) sum_sigma_above += sigma;
            if (diff < 0 || sig == 0) sum_sigma_below += sigma;
            if (sig > 0) {
                r.significant_above_area_m2 += cell;
                r.significant_above_m3 += diff * cell;
                r.significant_above_u95_m3 += u * cell;
            }
            if (sig < 0) {
                r.significant_below_area_m2 += cell;
                r.significant_below_m3 += diff * cell;
                r.significant_below_u95_m3 += u * cell;
            }
        }
    }
    r.compared_area_m2 = static_cast<double>(r.compared_nodes) * cell;
    r.above_u95_m3 = cfg.z95 * sum_sigma_above * cell;
    r.below_u95_m3 = cfg.z95 * sum_sigma_below * cell;
    if (r.compared_nodes > 0)
        r.mean_difference_m = sum_diff / static_cast<double>(r.compared_nodes);
    char buf[300];
    std::snprintf(buf,
                  sizeof buf,
                  "%zu nodes (%.0f m2) against the design: above %.2f +- %.2f m3 (%.0f m2), below "
                  "%.2f +- %.2f m3 (%.0f m2), mean difference %.3f m",
                  r.compared_nodes,
                  r.compared_area_m2,
                  r.above_m3,
                  r.above_u95_m3,
                  r.above_area_m2,
                  r.below_m3,
                  r.below_u95_m3,
                  r.below_area_m2,
                  r.mean_difference_m);
    r.message = buf;
    return r;
}

}  // namespace pitmap::proc::compare
