// SPDX-License-Identifier: MIT
#include "tools/sim/world.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::sim {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// Integer hash -> uniform value in [-1, 1] (splitmix64 finaliser).
double LatticeValue(std::int64_t ix, std::int64_t iy, std::uint64_t seed) {
    std::uint64_t z = seed ^ (static_cast<std::uint64_t>(ix) * 0x9E3779B97F4A7C15ull) ^
                      (static_cast<std::uint64_t>(iy) * 0xC2B2AE3D27D4EB4Full);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

double Fade(double t) {
    return t * t * t * (t * (t * 6 - 15) + 10);
}

// Smooth value noise with unit lattice spacing, range about [-1, 1].
double ValueNoise(double x, double y, std::uint64_t seed) {
    const double fx = std::floor(x), fy = std::floor(y);
    const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
    const double u = Fade(x - fx), v = Fade(y - fy);
    const double a = LatticeValue(ix, iy, seed), b = LatticeValue(ix + 1, iy, seed);
    const double c = LatticeValue(ix, iy + 1, seed), d = LatticeValue(ix + 1, iy + 1, seed);
    return (a * (1 - u) + b * u) * (1 - v) + (c * (1 - u) + d * u) * v;
}

// Three octaves of value noise at the given wavelength, range about [-1, 1].
double Fbm(double x, double y, double wavelength, std::uint64_t seed) {
    double sum = 0, amp = 1, norm = 0, f = 1.0 / wavelength;
    for (int o = 0; o < 3; ++o) {
        sum += amp * ValueNoise(x * f, y * f, seed + static_cast<std::uint64_t>(o) * 7919u);
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    return sum / norm;
}

// A ramp from 0 (t <= 0) to 1 (t >= 1), linear in between, with corners rounded over about
// 1/k in t (difference of two softplus functions).
double SoftRamp(double t, double k) {
    auto softplus = [](double z) { return z > 30 ? z : std::log1p(std::exp(z)); };
    return (softplus(k * t) - softplus(k * (t - 1.0))) / k;
}

// Depth below the water line (m, positive down) at distance d (m) from the shore, without noise.
double BenchProfile(const PitConfig& pit, double d) {
    const int risers = pit.num_benches + 1;
    const double h = pit.floor_depth_m / risers;
    const double corner_m = 0.4;
    double depth = 0, start = 0;
    for (int i = 0; i < risers; ++i) {
        const double slope =
            std::tan((i == 0 ? pit.shore_slope_deg : pit.wall_slope_deg) * kDegToRad);
        const double width = h / slope;
        depth += h * SoftRamp((d - start) / width, width / corner_m);
        start += width + pit.bench_width_m;
    }
    return depth;
}

// Distance from the shore at which the floor starts.
double FloorStart(const PitConfig& pit) {
    const int risers = pit.num_benches + 1;
    const double h = pit.floor_depth_m / risers;
    double start = 0;
    for (int i = 0; i < risers; ++i) {
        const double slope =
            std::tan((i == 0 ? pit.shore_slope_deg : pit.wall_slope_deg) * kDegToRad);
        start += h / slope + (i + 1 < risers ? pit.bench_width_m : 0.0);
    }
    return start;
}

}  // namespace

double DistanceFromShore(const PitConfig& pit, double x, double y) {
    const double p = pit.superellipse_exponent;
    const double r = std::pow(
        std::pow(std::abs(x) / pit.half_length_m, p) + std::pow(std::abs(y) / pit.half_width_m, p),
        1.0 / p);
    const double rho = std::hypot(x, y);
    if (r < 1e-9) return std::min(pit.half_length_m, pit.half_width_m);
    // The shore point on the ray from the centre is at rho / r.
    return rho / r - rho;
}

PitWorld::PitWorld(const PitConfig& pit, std::uint64_t seed) {
    const double margin = 8.0;
    grid_.resolution_m = pit.grid_resolution_m;
    grid_.x0_m = -(pit.half_length_m + margin);
    grid_.y0_m = -(pit.half_width_m + margin);
    grid_.nx =
        static_cast<int>(std::ceil(2 * (pit.half_length_m + margin) / grid_.resolution_m)) + 1;
    grid_.ny =
        static_cast<int>(std::ceil(2 * (pit.half_width_m + margin) / grid_.resolution_m)) + 1;
    grid_.height_m.resize(static_cast<std::size_t>(grid_.nx) * static_cast<std::size_t>(grid_.ny));
    const double floor_start = FloorStart(pit);
    const double land_slope = std::tan(pit.shore_slope_deg * kDegToRad);
    for (int iy = 0; iy < grid_.ny; ++iy) {
        const double y = grid_.y0_m + iy * grid_.resolution_m;
        for (int ix = 0; ix < grid_.nx; ++ix) {
            const double x = grid_.x0_m + ix * grid_.resolution_m;
            const double d = DistanceFromShore(pit, x, y);
            double z;
            if (d <= 0) {
                z = std::min(pit.land_height_m, -d * land_slope);  // banks above the water
            } else {
                double depth = BenchProfile(pit, d);
                // Backfill mounds on the floor, faded in over 6 m past the last wall.
                const double w_floor = std::clamp((d - floor_start) / 6.0, 0.0, 1.0);
                depth -= w_floor * pit.backfill_amplitude_m *
                         Fbm(x, y, pit.backfill_wavelength_m, seed ^ 0xB4CF111ull);
                // A sump: the deepest hole of the pit, off centre on the floor.
                const double sump_sigma = 0.15 * std::min(pit.half_length_m, pit.half_width_m);
                const double sx = x - 0.25 * pit.half_length_m, sy = y + 0.2 * pit.half_width_m;
                depth += w_floor * (pit.max_depth_m - pit.floor_depth_m + 0.5) *
                         std::exp(-(sx * sx + sy * sy) / (2 * sump_sigma * sump_sigma));
                // Rubble everywhere under water, faded in over the first metre.
                const double w_wet = std::clamp(d / 1.0, 0.0, 1.0);
                depth += w_wet * pit.rubble_amplitude_m *
                         Fbm(x, y, pit.rubble_wavelength_m, seed ^ 0x5EB1Eull);
                z = -std::clamp(depth, 0.0, pit.max_depth_m);
            }
            grid_.height_m[static_cast<std::size_t>(iy) * static_cast<std::size_t>(grid_.nx) +
                           static_cast<std::size_t>(ix)] = static_cast<float>(z);
        }
    }
    ComputeMaxSlope();
}

PitWorld::PitWorld(TerrainGrid grid) : grid_(std::move(grid)) {
    ComputeMaxSlope();
}

void PitWorld::ComputeMaxSlope() {
    double m = 0;
    for (int iy = 0; iy + 1 < grid_.ny; ++iy) {
        for (int ix = 0; ix + 1 < grid_.nx; ++ix) {
            const double gx = std::abs(At(ix + 1, iy) - At(ix, iy));
            const double gy = std::abs(At(ix, iy + 1) - At(ix, iy));
            m = std::max(m, std::hypot(gx, gy) / grid_.resolution_m);
        }
    }
    max_slope_ = std::max(m, 0.1);
}

double PitWorld::At(int ix, int iy) const {
    ix = std::clamp(ix, 0, grid_.nx - 1);
    iy = std::clamp(iy, 0, grid_.ny - 1);
    return grid_.height_m[static_cast<std::size_t>(iy) * static_cast<std::size_t>(grid_.nx) +
                          static_cast<std::size_t>(ix)];
}

double PitWorld::Height(double x, double y) const {
    // One clamp, then the four corners straight from the row-major array (hot path of the
    // ray marcher: no per-corner bounds checks).
    const double gx = std::clamp((x - grid_.x0_m) / grid_.resolution_m, 0.0, grid_.nx - 1.0);
    const double gy = std::clamp((y - grid_.y0_m) / grid_.resolution_m, 0.0, grid_.ny - 1.0);
    const int ix = std::min(static_cast<int>(gx), grid_.nx - 2);
    const int iy = std::min(static_cast<int>(gy), grid_.ny - 2);
    const double u = gx - ix, v = gy - iy;
    const float* row0 = grid_.height_m.data() +
                        static_cast<std::size_t>(iy) * static_cast<std::size_t>(grid_.nx) +
                        static_cast<std::size_t>(ix);
    const float* row1 = row0 + grid_.nx;
    return (row0[0] * (1 - u) + row0[1] * u) * (1 - v) + (row1[0] * (1 - u) + row1[1] * u) * v;
}

Eigen::Vector2d PitWorld::Gradient(double x, double y) const {
    const double gx = std::clamp((x - grid_.x0_m) / grid_.resolution_m, 0.0, grid_.nx - 1.0);
    const double gy = std::clamp((y - grid_.y0_m) / grid_.resolution_m, 0.0, grid_.ny - 1.0);
    const int ix = std::min(static_cast<int>(gx), grid_.nx - 2);
    const int iy = std::min(static_cast<int>(gy), grid_.ny - 2);
    const double u = gx - ix, v = gy - iy;
    const double dhdu =
        (At(ix + 1, iy) - At(ix, iy)) * (1 - v) + (At(ix + 1, iy + 1) - At(ix, iy + 1)) * v;
    const double dhdv =
        (At(ix, iy + 1) - At(ix, iy)) * (1 - u) + (At(ix + 1, iy + 1) - At(ix + 1, iy)) * u;
    return Eigen::Vector2d(dhdu, dhdv) / grid_.resolution_m;
}

Eigen::Vector3d PitWorld::Normal(double x, double y) const {
    const Eigen::Vector2d g = Gradient(x, y);
    return Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
}

double PitWorld::SignedDistance(const Eigen::Vector3d& p) const {
    Eigen::Vector3d n = Normal(p.x(), p.y());
    double d = (p.z() - Height(p.x(), p.y())) * n.z();  // vertical gap * cos(slope)
    // Re-project onto the surface near the foot point (handles bench edges and walls).
    for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d foot = p - d * n;
        const Eigen::Vector3d s(foot.x(), foot.y(), Height(foot.x(), foot.y()));
        n = Normal(foot.x(), foot.y());
        d = n.dot(p - s);
    }
    return d;
}

std::optional<double> PitWorld::RayCast(const Eigen::Vector3d& o,
                                        const Eigen::Vector3d& dir,
                                        double max_range_m) const {
    auto gap = [&](double t) {
        const Eigen::Vector3d q = o + t * dir;
        return q.z() - Height(q.x(), q.y());
    };
    double g0 = gap(0.0);
    if (g0 <= 0) return std::nullopt;
    // Conservative step: the gap cannot close faster than |dz| + max_slope * |dxy| per metre.
    const double closing = std::abs(dir.z()) + max_slope_ * std::hypot(dir.x(), dir.y());
    double t0 = 0.0;
    while (t0 < max_range_m) {
        const double step = std::max(g0 / closing, 0.02);
        const double t1 = std::min(t0 + step, max_range_m);
        const double g1 = gap(t1);
        if (g1 <= 0) {
            double lo = t0, hi = t1;  // gap(lo) > 0 >= gap(hi)
            for (int i = 0; i < 30 && hi - lo > 1e-5; ++i) {
                const double mid = 0.5 * (lo + hi);
                (gap(mid) > 0 ? lo : hi) = mid;
            }
            return 0.5 * (lo + hi);
        }
        if (t1 >= max_range_m) break;
        t0 = t1;
        g0 = g1;
    }
    return std::nullopt;
}

}  // namespace pitmap::sim
