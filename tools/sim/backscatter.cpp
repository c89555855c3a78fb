// SPDX-License-Identifier: MIT
#include "tools/sim/backscatter.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// SplitMix64 finaliser: a well-mixed hash of a tile and the seed.
std::uint64_t Mix(std::uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

}  // namespace

SeabedBackscatter::SeabedBackscatter(const BackscatterConfig& config,
                                     std::uint64_t seed,
                                     std::vector<Boulder> boulders)
    : cfg_(config), seed_(seed), boulders_(std::move(boulders)) {}

int SeabedBackscatter::PatchIndex(double x, double y) const {
    const auto ix = static_cast<std::int64_t>(std::floor(x / cfg_.patch_size_m));
    const auto iy = static_cast<std::int64_t>(std::floor(y / cfg_.patch_size_m));
    const std::uint64_t h = Mix(Mix(seed_ ^ 0x5EABEDull) ^ Mix(static_cast<std::uint64_t>(ix)) ^
                                (Mix(static_cast<std::uint64_t>(iy)) << 1));
    return static_cast<int>(h % cfg_.patch_levels_db.size());
}

double SeabedBackscatter::At(double x, double y) const {
    for (const Boulder& b : boulders_) {
        if (std::hypot(x - b.centre.x(), y - b.centre.y()) <= b.diameter_m / 2)
            return cfg_.boulder_db;
    }
    return cfg_.patch_levels_db[static_cast<std::size_t>(PatchIndex(x, y))];
}

std::vector<float> SeabedBackscatter::Sample(const TerrainGrid& g) const {
    std::vector<float> out(static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny));
    for (int iy = 0; iy < g.ny; ++iy) {
        for (int ix = 0; ix < g.nx; ++ix) {
            out[static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                static_cast<std::size_t>(ix)] =
                static_cast<float>(At(g.x0_m + ix * g.resolution_m, g.y0_m + iy * g.resolution_m));
        }
    }
    return out;
}

double SeabedBackscatter::AngularResponseDb(double incidence_deg) const {
    const double t = std::clamp(incidence_deg, 0.0, 89.0);
    const double lambert = 20.0 * std::log10(std::cos(t * kPi / 180.0));
    const double u = t / cfg_.specular_width_deg;
    return lambert + cfg_.specular_db * std::exp(-u * u);
}

double SeabedBackscatter::LevelDb(double range_m, double incidence_deg, double bs_db) const {
    const double r = std::max(range_m, 0.1);
    return cfg_.source_level_db - cfg_.spreading_db_per_decade * std::log10(r) -
           2.0 * cfg_.absorption_db_per_m * r + bs_db + AngularResponseDb(incidence_deg);
}

}  // namespace pitmap::sim
