// SPDX-License-Identifier: MIT
#include "processor/hydro/terrain.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <deque>

namespace pitmap::proc::hydro {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// Summed-area tables of the moments a plane fit needs, over the nodes that have a height.
// Coordinates are node indices (i, j); heights are relative to their mean, which keeps the
// squared sums' rounding far below a centimetre's square over a window.
class PlaneMoments {
public:
    enum Moment { kN, kX, kY, kZ, kXX, kXY, kYY, kXZ, kYZ, kZZ, kCount };

    PlaneMoments(const TerrainGrid& dem, double z_mean)
        : nx_(dem.nx), ny_(dem.ny), sat_(static_cast<std::size_t>(nx_ + 1) * (ny_ + 1)) {
        const std::vector<float>& h = *dem.height;
        for (int j = 0; j < ny_; ++j) {
            std::array<double, kCount> row{};  // this row's running sums up to node i
            for (int i = 0; i < nx_; ++i) {
                const float z = h[static_cast<std::size_t>(j) * nx_ + i];
                if (std::isfinite(z)) {
                    const double x = i, y = j, dz = z - z_mean;
                    const std::array<double, kCount> m = {
                        1, x, y, dz, x * x, x * y, y * y, x * dz, y * dz, dz * dz};
                    for (int k = 0; k < kCount; ++k) row[k] += m[k];
                }
                const auto& below = At(i + 1, j);
                auto& here = At(i + 1, j + 1);
                for (int k = 0; k < kCount; ++k) here[k] = below[k] + row[k];
            }
        }
    }

    // The sums over nodes i0..i1, j0..j1 (inclusive, clipped to the grid).
    std::array<double, kCount> Window(int i0, int j0, int i1, int j1) const {
        i0 = std::max(i0, 0);
        j0 = std::max(j0, 0);
        i1 = std::min(i1, nx_ - 1);
        j1 = std::min(j1, ny_ - 1);
        const auto& a = At(i1 + 1, j1 + 1);
        const auto& b = At(i0, j1 + 1);
        const auto& c = At(i1 + 1, j0);
        const auto& d = At(i0, j0);
        std::array<double, kCount> s;
        for (int k = 0; k < kCount; ++k) s[k] = a[k] - b[k] - c[k] + d[k];
        return s;
    }

private:
    const std::array<double, kCount>& At(int i, int j) const {
        return sat_[static_cast<std::size_t>(j) * (nx_ + 1) + i];
    }
    std::array<double, kCount>& At(int i, int j) {
        return sat_[static_cast<std::size_t>(j) * (nx_ + 1) + i];
    }
    int nx_, ny_;
    std::vector<std::array<double, kCount>> sat_;
};

// The least-squares plane z = z_c + gx (x - i) + gy (y - j) of a window around node (i, j), in
// node units, and the RMS of its residuals. Invalid when the window's nodes do not span a plane.
struct LocalPlane {
    bool valid = false;
    double z_c = 0, gx = 0, gy = 0;  // height at the node (relative to the mean), gradient
    double rms = 0;
};

LocalPlane FitPlane(const std::array<double, PlaneMoments::kCount>& s, int i, int j) {
    using M = PlaneMoments;
    LocalPlane p;
    const double n = s[M::kN];
    if (n < 4) return p;
    const double mx = s[M::kX] / n, my = s[M::kY] / n, mz = s[M::kZ] / n;
    const double cxx = s[M::kXX] - s[M::kX] * mx, cxy = s[M::kXY] - s[M::kX] * my,
                 cyy = s[M::kYY] - s[M::kY] * my, cxz = s[M::kXZ] - s[M::kX] * mz,
                 cyz = s[M::kYZ] - s[M::kY] * mz, czz = s[M::kZZ] - s[M::kZ] * mz;
    const double det = cxx * cyy - cxy * cxy;
    // Nodes on a line (a one-node-wide strip) leave the cross slope unknown.
    if (!(det > 1e-9 * (cxx * cyy + 1e-12))) return p;
    p.gx = (cyy * cxz - cxy * cyz) / det;
    p.gy = (cxx * cyz - cxy * cxz) / det;
    p.z_c = mz + p.gx * (i - mx) + p.gy * (j - my);
    const double rss = std::max(0.0, czz - p.gx * cxz - p.gy * cyz);
    p.rms = n > 3 ? std::sqrt(rss / (n - 3)) : 0.0;
    p.valid = true;
    return p;
}

int HalfWindow(double side_m, double resolution_m) {
    return std::max(1, static_cast<int>(std::lround(0.5 * side_m / resolution_m)));
}

// The height range of the residuals from the node's plane in the step window; NaN when too few
// nodes of it have a height.
float StepHeight(const TerrainGrid& dem,
                 double z_mean,
                 const LocalPlane& plane,
                 int i,
                 int j,
                 int half,
                 double min_fill) {
    const std::vector<float>& h = *dem.height;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    int count = 0, total = 0;
    for (int v = j - half; v <= j + half; ++v) {
        if (v < 0 || v >= dem.ny) continue;
        for (int u = i - half; u <= i + half; ++u) {
            if (u < 0 || u >= dem.nx) continue;
            ++total;
            const float z = h[static_cast<std::size_t>(v) * dem.nx + u];
            if (!std::isfinite(z)) continue;
            const double r = (z - z_mean) - (plane.z_c + plane.gx * (u - i) + plane.gy * (v - j));
            lo = std::min(lo, r);
            hi = std::max(hi, r);
            ++count;
        }
    }
    if (count < 2 || count < min_fill * total) return std::numeric_limits<float>::quiet_NaN();
    return static_cast<float>(hi - lo);
}

// Slope, roughness and step of every node with enough heights around it.
void MeasureNodes(const TerrainGrid& dem, const TerrainConfig& c, TerrainResult& r) {
    const std::vector<float>& h = *dem.height;
    const std::size_t n = h.size();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    r.slope_deg.assign(n, nan);
    r.roughness_m.assign(n, nan);
    r.step_m.assign(n, nan);
    double sum = 0;
    std::int64_t count = 0;
    for (float z : h) {
        if (std::isfinite(z)) {
            sum += z;
            ++count;
        }
    }
    if (count == 0) return;
    const double z_mean = sum / static_cast<double>(count);
    const PlaneMoments moments(dem, z_mean);
    const int half = HalfWindow(c.window_m, dem.resolution_m);
    const int step_half = std::min(half, HalfWindow(c.step_window_m, dem.resolution_m));
    r.window_nodes = 2 * half + 1;
    r.step_window_nodes = 2 * step_half + 1;
    for (int j = 0; j < dem.ny; ++j) {
        for (int i = 0; i < dem.nx; ++i) {
            const std::size_t k = static_cast<std::size_t>(j) * dem.nx + i;
            if (!std::isfinite(h[k])) continue;
            const auto s = moments.Window(i - half, j - half, i + half, j + half);
            const int cols = std::min(i + half, dem.nx - 1) - std::max(i - half, 0) + 1;
            const int rows = std::min(j + half, dem.ny - 1) - std::max(j - half, 0) + 1;
            if (s[PlaneMoments::kN] < c.min_fill * cols * rows) continue;
            const LocalPlane plane = FitPlane(s, i, j);
            if (!plane.valid) continue;
            const float step = StepHeight(dem, z_mean, plane, i, j, step_half, c.min_fill);
            if (!std::isfinite(step)) continue;
            const double grad = std::hypot(plane.gx, plane.gy) / dem.resolution_m;
            r.slope_deg[k] = static_cast<float>(std::atan(grad) * kRadToDeg);
            r.roughness_m[k] = static_cast<float>(plane.rms);
            r.step_m[k] = step;
        }
    }
}

// Per node, whether a step higher than the crawler climbs lies within its footprint (the
// window around it): the crawler standing there would have its body on it. A summed-area table
// of the step nodes, so the footprint's size costs nothing.
std::vector<char> StepInFootprint(const TerrainGrid& dem,
                                  const TerrainConfig& c,
                                  const TerrainResult& r) {
    const int nx = dem.nx, ny = dem.ny;
    std::vector<std::int32_t> sat(static_cast<std::size_t>(nx + 1) * (ny + 1), 0);
    const auto at = [&](int i, int j) -> std::int32_t& {
        return sat[static_cast<std::size_t>(j) * (nx + 1) + i];
    };
    for (int j = 0; j < ny; ++j) {
        std::int32_t row = 0;
        for (int i = 0; i < nx; ++i) {
            row += r.step_m[static_cast<std::size_t>(j) * nx + i] > c.crawler_max_step_m ? 1 : 0;
            at(i + 1, j + 1) = at(i + 1, j) + row;
        }
    }
    const int half = HalfWindow(c.window_m, dem.resolution_m);
    std::vector<char> out(static_cast<std::size_t>(nx) * ny, 0);
    for (int j = 0; j < ny; ++j) {
        const int j0 = std::max(j - half, 0), j1 = std::min(j + half, ny - 1);
        for (int i = 0; i < nx; ++i) {
            const int i0 = std::max(i - half, 0), i1 = std::min(i + half, nx - 1);
            out[static_cast<std::size_t>(j) * nx + i] =
                at(i1 + 1, j1 + 1) - at(i0, j1 + 1) - at(i1 + 1, j0) + at(i0, j0) > 0;
        }
    }
    return out;
}

TerrainClass Classify(const TerrainResult& r,
                      std::size_t k,
                      const TerrainConfig& c,
                      const std::vector<char>& step_in_footprint) {
    if (!std::isfinite(r.slope_deg[k])) return TerrainClass::kNoData;
    if (step_in_footprint[k]) return TerrainClass::kStep;
    if (r.slope_deg[k] > c.crawler_max_slope_deg) return TerrainClass::kTooSteep;
    if (r.roughness_m[k] > c.crawler_max_roughness_m) return TerrainClass::kTooRough;
    return TerrainClass::kTraversable;
}

// The traversable node nearest to the launch point, within launch_snap_m; false if none.
bool FindLaunchNode(const TerrainGrid& dem,
                    const TerrainConfig& c,
                    const std::vector<TerrainClass>& cls,
                    TerrainResult& r) {
    const double fi = (c.launch_easting - dem.x0) / dem.resolution_m;
    const double fj = (c.launch_northing - dem.y0) / dem.resolution_m;
    const int reach = static_cast<int>(std::ceil(c.launch_snap_m / dem.resolution_m));
    const int ci = static_cast<int>(std::lround(fi)), cj = static_cast<int>(std::lround(fj));
    double best = std::numeric_limits<double>::infinity();
    for (int j = std::max(0, cj - reach); j <= std::min(dem.ny - 1, cj + reach); ++j) {
        for (int i = std::max(0, ci - reach); i <= std::min(dem.nx - 1, ci + reach); ++i) {
            if (cls[static_cast<std::size_t>(j) * dem.nx + i] != TerrainClass::kTraversable) {
                continue;
            }
            const double d = std::hypot(i - fi, j - fj) * dem.resolution_m;
            if (d <= c.launch_snap_m && d < best) {
                best = d;
                r.launch_i = i;
                r.launch_j = j;
            }
        }
    }
    if (!std::isfinite(best)) return false;
    r.launch_snap_distance_m = best;
    return true;
}

// Marks the traversable nodes 8-connected to the launch node as reachable.
void FloodFromLaunch(const TerrainGrid& dem,
                     const TerrainResult& r,
                     std::vector<TerrainClass>& cls) {
    std::deque<std::pair<int, int>> queue{{r.launch_i, r.launch_j}};
    cls[static_cast<std::size_t>(r.launch_j) * dem.nx + r.launch_i] = TerrainClass::kReachable;
    while (!queue.empty()) {
        const auto [i, j] = queue.front();
        queue.pop_front();
        for (int dj = -1; dj <= 1; ++dj) {
            for (int di = -1; di <= 1; ++di) {
                const int u = i + di, v = j + dj;
                if (u < 0 || v < 0 || u >= dem.nx || v >= dem.ny) continue;
                auto& c = cls[static_cast<std::size_t>(v) * dem.nx + u];
                if (c != TerrainClass::kTraversable) continue;
                c = TerrainClass::kReachable;
                queue.emplace_back(u, v);
            }
        }
    }
}

}  // namespace

const char* TerrainClassName(TerrainClass c) {
    switch (c) {
        case TerrainClass::kNoData:
            return "no data";
        case TerrainClass::kReachable:
            return "reachable";
        case TerrainClass::kTraversable:
            return "traversable, not reachable";
        case TerrainClass::kTooSteep:
            return "too steep";
        case TerrainClass::kStep:
            return "step obstacle";
        case TerrainClass::kTooRough:
            return "too rough";
    }
    return "?";
}

std::vector<std::string> TerrainConfig::Validate() const {
    std::vector<std::string> out;
    if (!(window_m > 0)) out.push_back("terrain.window_m must be > 0");
    if (!(step_window_m > 0 && step_window_m <= window_m)) {
        out.push_back("terrain.step_window_m must be > 0 and at most terrain.window_m");
    }
    if (!(min_fill > 0 && min_fill <= 1)) out.push_back("terrain.min_fill must be in (0, 1]");
    if (!(crawler_max_slope_deg > 0 && crawler_max_slope_deg < 90)) {
        out.push_back("terrain.crawler_max_slope_deg must be in (0, 90)");
    }
    if (!(crawler_max_step_m > 0)) out.push_back("terrain.crawler_max_step_m must be > 0");
    if (!(crawler_max_roughness_m > 0)) {
        out.push_back("terrain.crawler_max_roughness_m must be > 0");
    }
    if (std::isnan(launch_easting) != std::isnan(launch_northing)) {
        out.push_back(
            "terrain.launch_easting and terrain.launch_northing go together: give both "
            "or neither");
    }
    if (!(launch_snap_m >= 0)) out.push_back("terrain.launch_snap_m must be >= 0");
    return out;
}

TerrainResult ComputeTerrain(const TerrainGrid& dem, const TerrainConfig& c) {
    TerrainResult r;
    r.node_area_m2 = dem.resolution_m * dem.resolution_m;
    MeasureNodes(dem, c, r);

    std::vector<TerrainClass> cls(dem.height->size(), TerrainClass::kNoData);
    const std::vector<char> step_in_footprint = StepInFootprint(dem, c, r);
    for (std::size_t k = 0; k < cls.size(); ++k) cls[k] = Classify(r, k, c, step_in_footprint);
    r.launch_given = std::isfinite(c.launch_easting) && std::isfinite(c.launch_northing);
    if (r.launch_given) {
        r.launch_found = FindLaunchNode(dem, c, cls, r);
        if (r.launch_found) FloodFromLaunch(dem, r, cls);
    }
    r.terrain_class.resize(cls.size());
    for (std::size_t k = 0; k < cls.size(); ++k) {
        r.terrain_class[k] = static_cast<float>(cls[k]);
        ++r.nodes_by_class[static_cast<int>(cls[k])];
        if (cls[k] != TerrainClass::kNoData) ++r.nodes_with_data;
    }

    char line[320];
    const auto area = [&](TerrainClass k) {
        return static_cast<double>(r.nodes_by_class[static_cast<int>(k)]) * r.node_area_m2;
    };
    const double traversable = area(TerrainClass::kReachable) + area(TerrainClass::kTraversable);
    if (!r.launch_given) {
        std::snprintf(line,
                      sizeof line,
                      "%.0f m2 traversable of %.0f m2 with data (no launch point: terrain.launch_* "
                      "not set)",
                      traversable,
                      static_cast<double>(r.nodes_with_data) * r.node_area_m2);
    } else if (!r.launch_found) {
        std::snprintf(line,
                      sizeof line,
                      "no traversable node within %.1f m of the launch point (%.2f, %.2f): nothing "
                      "reachable; %.0f m2 traversable elsewhere",
                      c.launch_snap_m,
                      c.launch_easting,
                      c.launch_northing,
                      traversable);
    } else {
        std::snprintf(line,
                      sizeof line,
                      "%.0f m2 reachable from the launch point (node %.2f m from it), %.0f m2 "
                      "traversable in all, of %.0f m2 with data",
                      area(TerrainClass::kReachable),
                      r.launch_snap_distance_m,
                      traversable,
                      static_cast<double>(r.nodes_with_data) * r.node_area_m2);
    }
    r.message = line;
    return r;
}

}  // namespace pitmap::proc::hydro
