// SPDX-License-Identifier: MIT
#include "processor/compare/design.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

namespace pitmap::proc::compare {

std::vector<std::string> DesignConfig::Validate() const {
    std::vector<std::string> p;
    if (!(z95 > 0)) p.push_back("design.z95 must be > 0");
    return p;
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
