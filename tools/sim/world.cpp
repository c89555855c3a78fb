// SPDX-License-Identifier: MIT
#include "tools/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>
#include <utility>

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

// Start (distance from the shore) of the tread of bench k (1-based) and its end.
std::pair<double, double> Tread(const PitConfig& pit, int k) {
    const double h = pit.floor_depth_m / (pit.num_benches + 1);
    double start = 0;
    for (int i = 0; i < k; ++i) {
        const double slope =
            std::tan((i == 0 ? pit.shore_slope_deg : pit.wall_slope_deg) * kDegToRad);
        start += h / slope + pit.bench_width_m;
    }
    return {start - pit.bench_width_m, start};
}

double WrapDeg180(double a) {
    a = std::fmod(a + 180.0, 360.0);
    if (a < 0) a += 360.0;
    return a - 180.0;
}

// Weight of the high wall's profile at (x, y): 1 inside its sector, 0 outside, smooth between.
double HighWallWeight(const PitConfig& pit, double x, double y) {
    if (pit.high_wall_slope_deg == 0) return 0.0;
    const double phi = std::atan2(y, x) / kDegToRad;
    const double delta = std::abs(WrapDeg180(phi - pit.high_wall_direction_deg));
    const double half_blend = 0.5 * pit.high_wall_blend_deg;
    if (delta <= pit.high_wall_half_angle_deg - half_blend) return 1.0;
    if (delta >= pit.high_wall_half_angle_deg + half_blend) return 0.0;
    const double t = (pit.high_wall_half_angle_deg + half_blend - delta) / pit.high_wall_blend_deg;
    return t * t * (3 - 2 * t);
}

// Horizontal extent of the high wall from the water line to the floor.
double HighWallWidth(const PitConfig& pit) {
    return pit.floor_depth_m / std::tan(pit.high_wall_slope_deg * kDegToRad);
}

// Depth of the high wall at distance d from the shore: one face down to the floor.
double HighWallProfile(const PitConfig& pit, double d) {
    const double width = HighWallWidth(pit);
    return pit.floor_depth_m * SoftRamp(d / width, width / 0.4);
}

// The point at distance d from the shore on the ray from the pit centre at angle phi (rad).
Eigen::Vector2d RayPoint(const PitConfig& pit, double phi, double d) {
    const Eigen::Vector2d dir(std::cos(phi), std::sin(phi));
    const double p = pit.superellipse_exponent;
    const double r = std::pow(std::pow(std::abs(dir.x()) / pit.half_length_m, p) +
                                  std::pow(std::abs(dir.y()) / pit.half_width_m, p),
                              1.0 / p);
    return (1.0 / r - d) * dir;
}

// Depth with the ramp cut and filled into the natural depth (positive down, negative above
// the water): on the road its surface; beside and beyond it the natural ground, held within
// side faces at `tan_side` that start at the road's edges and ends. Where the road leaves the
// water line the bank beside it is cut down to the road.
double ApplyRamp(const RampGeometry& g, double tan_side, double x, double y, double natural_depth) {
    const double length = g.length_m();
    const Eigen::Vector2d axis = (g.bottom - g.top) / length;
    const Eigen::Vector2d rel = Eigen::Vector2d(x, y) - g.top;
    const double u = rel.dot(axis);
    const double lateral = std::abs(axis.x() * rel.y() - axis.y() * rel.x());
    const double tan_grade = std::tan(g.grade_deg * kDegToRad);
    const double road = std::clamp(u, 0.0, length) * tan_grade;
    const double e = std::max({lateral - 0.5 * g.width_m, -u, u - length, 0.0});
    return std::clamp(natural_depth, road - e * tan_side, road + e * tan_side);
}

}  // namespace

std::optional<RampGeometry> PlanRamp(const PitConfig& pit) {
    if (!(pit.ramp_width_m > 0) || pit.ramp_bench < 1 || pit.ramp_bench > pit.num_benches)
        return std::nullopt;
    RampGeometry g;
    g.width_m = pit.ramp_width_m;
    g.grade_deg = pit.ramp_grade_deg;
    g.bottom_depth_m = pit.floor_depth_m / (pit.num_benches + 1) * pit.ramp_bench;
    const double length = g.bottom_depth_m / std::tan(pit.ramp_grade_deg * kDegToRad);
    const double phi_top = pit.ramp_direction_deg * kDegToRad;
    const double sign = pit.ramp_clockwise ? -1.0 : 1.0;
    const auto [tread0, tread1] = Tread(pit, pit.ramp_bench);
    const double d_bottom = 0.5 * (tread0 + tread1);
    g.top = RayPoint(pit, phi_top, 0.0);
    const auto bottom_at = [&](double delta) {
        return RayPoint(pit, phi_top + sign * delta, d_bottom);
    };
    // Walk along the tread until the chord is as long as the road, then bisect.
    const double step = 0.5 * kDegToRad;
    double lo = 0, hi = step;
    while (hi < 3.0 && (bottom_at(hi) - g.top).norm() < length) {
        lo = hi;
        hi += step;
    }
    for (int i = 0; i < 50; ++i) {
        const double mid = 0.5 * (lo + hi);
        ((bottom_at(mid) - g.top).norm() < length ? lo : hi) = mid;
    }
    g.bottom = bottom_at(hi);
    return g;
}

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
    const double bench_floor_start = FloorStart(pit);
    const double bench_land_slope = std::tan(pit.shore_slope_deg * kDegToRad);
    const bool high_wall = pit.high_wall_slope_deg != 0;
    const double high_wall_land_slope =
        high_wall ? std::tan(pit.high_wall_slope_deg * kDegToRad) : 0.0;
    const std::optional<RampGeometry> ramp = PlanRamp(pit);
    const double ramp_side_slope = std::tan(pit.wall_slope_deg * kDegToRad);
    for (int iy = 0; iy < grid_.ny; ++iy) {
        const double y = grid_.y0_m + iy * grid_.resolution_m;
        for (int ix = 0; ix < grid_.nx; ++ix) {
            const double x = grid_.x0_m + ix * grid_.resolution_m;
            const double d = DistanceFromShore(pit, x, y);
            // Inside the high wall's sector its single face replaces the benches.
            const double w_wall = high_wall ? HighWallWeight(pit, x, y) : 0.0;
            // Backfill and sump fade in past the benches' last wall everywhere (blending the
            // high wall's shorter reach would draw seams along its sector to the pit centre).
            const double floor_start = bench_floor_start;
            const double land_slope =
                w_wall > 0 ? (1 - w_wall) * bench_land_slope + w_wall * high_wall_land_slope
                           : bench_land_slope;
            double z;
            if (d <= 0) {
                z = std::min(pit.land_height_m, -d * land_slope);  // banks above the water
                if (ramp) z = -ApplyRamp(*ramp, ramp_side_slope, x, y, -z);
            } else {
                double depth = BenchProfile(pit, d);
                if (w_wall > 0) depth = (1 - w_wall) * depth + w_wall * HighWallProfile(pit, d);
                if (ramp) depth = ApplyRamp(*ramp, ramp_side_slope, x, y, depth);
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
    if (pit.num_boulders > 0) PlaceBoulders(pit, seed);
    ComputeMaxSlope();
}

void PitWorld::PlaceBoulders(const PitConfig& pit, std::uint64_t seed) {
    std::mt19937_64 rng(seed ^ 0xB0A1DE25ull);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const double max_ground_slope = std::tan(15.0 * kDegToRad);
    const int max_attempts = 400 * pit.num_boulders;
    for (int attempt = 0;
         attempt < max_attempts && static_cast<int>(boulders_.size()) < pit.num_boulders;
         ++attempt) {
        // Draw every number of the attempt first, so the sequence does not depend on where
        // the attempts fail.
        const double x = (2 * uni(rng) - 1) * pit.half_length_m;
        const double y = (2 * uni(rng) - 1) * pit.half_width_m;
        const double diameter =
            pit.boulder_min_diameter_m +
            uni(rng) * (pit.boulder_max_diameter_m - pit.boulder_min_diameter_m);
        const double aspect = 0.7 + 0.3 * uni(rng);
        const double theta = uni(rng) * 3.14159265358979323846;
        const double height = (0.25 + 0.15 * uni(rng)) * diameter;
        if (DistanceFromShore(pit, x, y) < 2.0) continue;
        const double ground = Height(x, y);
        if (ground > -2.0) continue;  // under water only
        const double r = std::max(1.0, 0.5 * diameter);
        const double gx = (Height(x + r, y) - Height(x - r, y)) / (2 * r);
        const double gy = (Height(x, y + r) - Height(x, y - r)) / (2 * r);
        if (std::hypot(gx, gy) > max_ground_slope) continue;
        const Eigen::Vector2d c(x, y);
        bool clear = true;
        for (const Boulder& b : boulders_) {
            if ((b.centre - c).norm() < 0.5 * (b.diameter_m + diameter) + 0.5) clear = false;
        }
        if (!clear) continue;
        // Flat-topped dome over a squarish outline, sunk by 15 % of its height.
        const double a = 0.5 * diameter, b = aspect * a;
        const double bury = 0.15 * height, base = ground - bury;
        const double ct = std::cos(theta), st = std::sin(theta);
        const int i0 = static_cast<int>(std::floor((x - a - grid_.x0_m) / grid_.resolution_m));
        const int i1 = static_cast<int>(std::ceil((x + a - grid_.x0_m) / grid_.resolution_m));
        const int j0 = static_cast<int>(std::floor((y - a - grid_.y0_m) / grid_.resolution_m));
        const int j1 = static_cast<int>(std::ceil((y + a - grid_.y0_m) / grid_.resolution_m));
        for (int iy = std::max(j0, 0); iy <= std::min(j1, grid_.ny - 1); ++iy) {
            for (int ix = std::max(i0, 0); ix <= std::min(i1, grid_.nx - 1); ++ix) {
                const double px = grid_.x0_m + ix * grid_.resolution_m - x;
                const double py = grid_.y0_m + iy * grid_.resolution_m - y;
                const double u = (ct * px + st * py) / a, v = (-st * px + ct * py) / b;
                const double rho = std::cbrt(std::pow(std::abs(u), 3) + std::pow(std::abs(v), 3));
                if (rho >= 1.0) continue;
                const double top = base + (height + bury) * (1 - rho * rho * rho);
                float& cell = grid_.height_m[static_cast<std::size_t>(iy) *
                                                 static_cast<std::size_t>(grid_.nx) +
                                             static_cast<std::size_t>(ix)];
                cell = std::max(cell, static_cast<float>(top));
            }
        }
        boulders_.push_back({c, diameter, height});
    }
}

PitWorld::PitWorld(TerrainGrid grid) : grid_(std::move(grid)) {
    ComputeMaxSlope();
}

void PitWorld::AddHeights(const std::vector<float>& delta_m) {
    if (delta_m.size() != grid_.height_m.size()) std::abort();  // a bug: another grid's layout
    for (std::size_t i = 0; i < delta_m.size(); ++i) grid_.height_m[i] += delta_m[i];
    ComputeMaxSlope();
}

Eigen::Vector2d PointFromShore(const PitConfig& pit, double direction_deg, double d_m) {
    return RayPoint(pit, direction_deg * kDegToRad, d_m);
}

FaceSpan DeepestFace(const PitConfig& pit, double direction_deg) {
    const double rad = direction_deg * kDegToRad;
    const Eigen::Vector2d probe = RayPoint(pit, rad, 1.0);
    if (HighWallWeight(pit, probe.x(), probe.y()) >= 1.0) return {0.0, HighWallWidth(pit)};
    const double h = pit.floor_depth_m / (pit.num_benches + 1);
    const double riser =
        h / std::tan((pit.num_benches == 0 ? pit.shore_slope_deg : pit.wall_slope_deg) * kDegToRad);
    const double foot = FloorStart(pit);
    return {foot - riser, foot};
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
