// SPDX-License-Identifier: MIT
#include "processor/compare/capacity.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pitmap::proc::compare {

CapacityResult ComputeCapacity(const SurfaceGrid& s, double water_level_m, double step_m) {
    CapacityResult r;
    r.water_level_m = water_level_m;
    const double cell = s.resolution_m * s.resolution_m;
    std::vector<double> z;
    z.reserve(s.z_m.size());
    for (float v : s.z_m) {
        if (std::isfinite(v)) z.push_back(v);
    }
    r.surveyed_area_m2 = static_cast<double>(z.size()) * cell;
    if (z.empty() || !(step_m > 0)) return r;
    std::sort(z.begin(), z.end());
    r.min_height_m = z.front();
    // Prefix sums over the sorted heights: volume(L) = cell (k L - sum of the k heights < L).
    std::vector<double> prefix(z.size() + 1, 0.0);
    for (std::size_t k = 0; k < z.size(); ++k) prefix[k + 1] = prefix[k] + z[k];
    const auto at = [&](double level) {
        const auto k =
            static_cast<std::size_t>(std::lower_bound(z.begin(), z.end(), level) - z.begin());
        return CapacityRow{level,
                           static_cast<double>(k) * cell,
                           (static_cast<double>(k) * level - prefix[k]) * cell};
    };
    for (double level = std::floor(r.min_height_m / step_m) * step_m; level < water_level_m;
         level += step_m) {
        r.rows.push_back(at(level));
    }
    const CapacityRow top = at(water_level_m);
    r.rows.push_back(top);
    r.area_at_water_level_m2 = top.area_m2;
    r.volume_at_water_level_m3 = top.volume_m3;
    return r;
}

}  // namespace pitmap::proc::compare
