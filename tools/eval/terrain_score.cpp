// SPDX-License-Identifier: MIT
#include "tools/eval/terrain_score.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "processor/io/grid_io.hpp"

namespace pitmap::eval {

namespace {

using proc::hydro::TerrainClass;

bool CanStand(float code) {
    const auto c = static_cast<TerrainClass>(static_cast<int>(code));
    return c == TerrainClass::kReachable || c == TerrainClass::kTraversable;
}

}  // namespace

std::optional<TerrainScore> ScoreTerrain(const TerrainLayers& product,
                                         const sim::PitWorld& world,
                                         const proc::hydro::TerrainConfig& config) {
    const std::size_t n = static_cast<std::size_t>(product.nx) * product.ny;
    if (product.slope_deg.size() != n || product.step_m.size() != n ||
        product.terrain_class.size() != n || product.node_world_xy.size() != n) {
        return std::nullopt;
    }
    // The true heights at the DEM's nodes, and the layers a perfect survey would give. No launch
    // point: reachability depends on it, standing does not.
    std::vector<float> true_height(n);
    for (std::size_t k = 0; k < n; ++k) {
        const Eigen::Vector2d& p = product.node_world_xy[k];
        true_height[k] = p.allFinite() ? static_cast<float>(world.Height(p.x(), p.y()))
                                       : std::numeric_limits<float>::quiet_NaN();
    }
    proc::hydro::TerrainConfig c = config;
    c.launch_easting = c.launch_northing = std::numeric_limits<double>::quiet_NaN();
    const proc::hydro::TerrainGrid grid{
        0, 0, product.resolution_m, product.nx, product.ny, &true_height};
    const proc::hydro::TerrainResult truth = proc::hydro::ComputeTerrain(grid, c);

    TerrainScore s;
    double slope_sum = 0, step_sum = 0;
    std::size_t agree = 0, true_blocked = 0, found_blocked = 0, said_blocked = 0, false_blocked = 0;
    for (std::size_t k = 0; k < n; ++k) {
        if (!std::isfinite(product.slope_deg[k]) || !std::isfinite(truth.slope_deg[k])) continue;
        if (!std::isfinite(product.terrain_class[k])) continue;
        ++s.nodes;
        slope_sum += std::abs(product.slope_deg[k] - truth.slope_deg[k]);
        step_sum += std::abs(product.step_m[k] - truth.step_m[k]);
        const bool stand = CanStand(product.terrain_class[k]);
        const bool true_stand = CanStand(truth.terrain_class[k]);
        agree += stand == true_stand;
        if (!true_stand) {
            ++true_blocked;
            found_blocked += !stand;
        }
        if (!stand) {
            ++said_blocked;
            false_blocked += true_stand;
        }
    }
    if (s.nodes == 0) return std::nullopt;
    const auto share = [](std::size_t a, std::size_t b) {
        return b > 0 ? static_cast<double>(a) / static_cast<double>(b) : 0.0;
    };
    s.slope_mean_abs_deg = slope_sum / static_cast<double>(s.nodes);
    s.step_mean_abs_m = step_sum / static_cast<double>(s.nodes);
    s.class_agreement = share(agree, s.nodes);
    s.blocked_recall = true_blocked > 0 ? share(found_blocked, true_blocked) : 1.0;
    s.blocked_false_share = share(false_blocked, said_blocked);
    return s;
}

namespace {

// The settings the grid stage made the layers with (summary.json stages.grid.terrain).
Expected<proc::hydro::TerrainConfig> TerrainSettings(const std::filesystem::path& summary_path) {
    std::ifstream in(summary_path);
    const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
    if (j.is_discarded()) return Error{summary_path.string() + ": not JSON"};
    const auto* stage = &j;
    for (const char* key : {"stages", "grid", "terrain"}) {
        if (!stage->is_object() || !stage->contains(key)) {
            return Error{summary_path.string() + ": no stages.grid.terrain record"};
        }
        stage = &(*stage)[key];
    }
    proc::hydro::TerrainConfig c;
    c.window_m = stage->value("window_m", c.window_m);
    c.step_window_m = stage->value("step_window_m", c.step_window_m);
    c.min_fill = stage->value("min_fill", c.min_fill);
    c.crawler_max_slope_deg = stage->value("crawler_max_slope_deg", c.crawler_max_slope_deg);
    c.crawler_max_step_m = stage->value("crawler_max_step_m", c.crawler_max_step_m);
    c.crawler_max_roughness_m = stage->value("crawler_max_roughness_m", c.crawler_max_roughness_m);
    return c;
}

}  // namespace

Expected<std::optional<TerrainScore>> ScoreTerrainProducts(const std::string& products_dir,
                                                           const sim::PitWorld& world,
                                                           const Geodetic& origin) {
    namespace fs = std::filesystem;
    const fs::path P(products_dir);
    if (!fs::exists(P / "terrain.tif") || !fs::exists(P / "crawler.tif")) {
        return std::optional<TerrainScore>{};
    }
    auto settings = TerrainSettings(P / "summary.json");
    if (!settings) return settings.error();
    auto terrain = proc::io::ReadGrid((P / "terrain.tif").string());
    if (!terrain) return terrain.error();
    auto crawler = proc::io::ReadGrid((P / "crawler.tif").string());
    if (!crawler) return crawler.error();
    const proc::io::GridRaster& g = terrain->grid;
    const int epsg = terrain->horizontal_epsg;
    const std::vector<float>* slope = g.Values("slope");
    const std::vector<float>* step = g.Values("step");
    const std::vector<float>* cls = crawler->grid.Values("crawler");
    if (slope == nullptr || step == nullptr || cls == nullptr || crawler->grid.nx != g.nx ||
        crawler->grid.ny != g.ny ||
        !((epsg > 32600 && epsg <= 32660) || (epsg > 32700 && epsg <= 32760))) {
        return Error{products_dir +
                     "/terrain.tif, crawler.tif: not the slope/step and crawler "
                     "layers of one WGS 84 / UTM grid"};
    }
    TerrainLayers layers;
    layers.nx = g.nx;
    layers.ny = g.ny;
    layers.resolution_m = g.resolution_m;
    layers.slope_deg = *slope;
    layers.step_m = *step;
    layers.terrain_class = *cls;
    layers.node_world_xy.resize(
        static_cast<std::size_t>(g.nx) * g.ny,
        Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
    const LocalTangentFrame tf(origin);
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            UtmCoordinate u;
            u.zone = epsg % 100;
            u.northern = epsg < 32700;
            u.easting_m = g.x0 + i * g.resolution_m;
            u.northing_m = g.y0 + j * g.resolution_m;
            u.height_m = origin.height_m;
            if (auto geo = GeodeticFromUtm(u)) {
                layers.node_world_xy[static_cast<std::size_t>(j) * g.nx + i] =
                    tf.ToEnu(*geo).head<2>();
            }
        }
    }
    return ScoreTerrain(layers, world, *settings);
}

}  // namespace pitmap::eval
