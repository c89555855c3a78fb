// SPDX-License-Identifier: MIT
// The points each pass contributes to SLAM, bounded per cell (issue 38, decision 036): a pit
// surveyed K times is seen K times over each cell, and every pass's soundings at the sonar's
// density (about 80 a square metre on bejanca) were held in SLAM's points, world points and
// k-d trees. Per section (a pass over a cell: section_length_s of pings) and per cube of
// pass_cell_m, only the first pass_cell_points points enter; what is left of a pass is its
// surface sampled at the cube's size, which is what its pairs and normals see of it.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

namespace {

// A cube's key: 21 bits per axis (cube indices wrap every 2^21 cubes, 524 km at 0.25 m: the
// points of one section never lie that far apart).
std::uint64_t CubeKey(const Eigen::Vector3d& p, double cell_m) {
    constexpr std::uint64_t kMask = (std::uint64_t{1} << 21) - 1;
    const auto index = [&](double x) {
        return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(x / cell_m))) &
               kMask;
    };
    return (index(p.x()) << 42) | (index(p.y()) << 21) | index(p.z());
}

}  // namespace

std::vector<std::uint8_t> BoundPointsPerCell(
    const std::vector<const std::vector<Eigen::Vector3f>*>& points,
    const std::vector<Pose>& T,
    const std::vector<std::size_t>& section_start,
    double cell_m,
    int per_cell,
    const std::vector<char>& every_point) {
    // First finite point of each slice among the finite points.
    std::vector<std::size_t> first(points.size() + 1, 0);
    for (std::size_t s = 0; s < points.size(); ++s) {
        std::size_t n = 0;
        for (const auto& x : *points[s]) n += x.allFinite() ? 1 : 0;
        first[s + 1] = first[s] + n;
    }
    std::vector<std::uint8_t> keep(first.back(), 1);
    if (!(cell_m > 0) || section_start.size() < 2) return keep;
    const auto bound = static_cast<std::uint32_t>(std::max(per_cell, 0));
    tbb::parallel_for(std::size_t{0}, section_start.size() - 1, [&](std::size_t i) {
        if (i < every_point.size() && every_point[i] != 0) return;
        std::unordered_map<std::uint64_t, std::uint32_t> count;
        for (std::size_t s = section_start[i]; s < section_start[i + 1]; ++s) {
            std::size_t k = first[s];
            for (const auto& x : *points[s]) {
                if (!x.allFinite()) continue;
                std::uint32_t& c = count[CubeKey(T[s] * x.cast<double>(), cell_m)];
                keep[k++] = c < bound ? 1 : 0;
                if (c < bound) ++c;
            }
        }
    });
    return keep;
}

std::vector<char> SectionsKeepingEveryPoint(const Input& in,
                                            const std::vector<std::size_t>& section_start,
                                            double max_sigma_m) {
    const std::size_t sections = section_start.empty() ? 0 : section_start.size() - 1;
    std::vector<char> every(sections, 0);
    if (!(max_sigma_m > 0)) return every;
    for (std::size_t i = 0; i < sections; ++i) {
        for (std::size_t s = section_start[i]; s < section_start[i + 1] && !every[i]; ++s)
            every[i] = std::max(in.sigma[s](3), in.sigma[s](4)) > max_sigma_m ? 1 : 0;
    }
    return every;
}

}  // namespace pitmap::proc::slam::detail
