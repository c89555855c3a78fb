// SPDX-License-Identifier: MIT
// The mine-planning layers of the `grid` stage (grid_stage.hpp, hydro/terrain.hpp): slope,
// roughness and steps of the CUBE surface as P/terrain.tif, and where a crawler can stand and
// what it can reach from its launch point as the class map P/crawler.tif.
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "processor/io/grid_io.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {

using nlohmann::json;

namespace {

// The class map's colours (RGBA by TerrainClass code): reachable green, traversable but cut off
// blue, too steep orange, steps red, too rough purple; no data is the file's no-data value.
constexpr std::array<std::array<std::uint8_t, 4>, hydro::kTerrainClassCount> kClassColours = {{
    {0, 0, 0, 0},
    {46, 160, 67, 255},
    {66, 133, 244, 255},
    {245, 154, 35, 255},
    {214, 39, 40, 255},
    {148, 103, 189, 255},
}};

io::GridRaster TerrainRaster(const io::GridRaster& dem,
                             hydro::TerrainResult& r,
                             const hydro::TerrainConfig& c) {
    io::GridRaster raster = dem.OnSameGrid();
    io::GridLayer slope{"slope", "deg", std::move(r.slope_deg)};
    slope.metadata = {{"pitmap_definition",
                       "tilt of the least-squares plane of the DEM nodes in a " +
                           Fixed(c.window_m, 2) + " m square window, degrees from level"}};
    io::GridLayer roughness{"roughness", "metre", std::move(r.roughness_m)};
    roughness.metadata = {{"pitmap_definition", "RMS of the window's heights about that plane, m"}};
    io::GridLayer step{"step", "metre", std::move(r.step_m)};
    step.metadata = {{"pitmap_definition",
                      "height range of the nodes in a " + Fixed(c.step_window_m, 2) +
                          " m square window once the plane is removed, m: ledges, boulder "
                          "flanks, bench edges"}};
    raster.layers = {std::move(slope), std::move(roughness), std::move(step)};
    raster.metadata = {{"pitmap_product", "mine-planning terrain layers of the CUBE surface"}};
    return raster;
}

io::GridRaster CrawlerRaster(const io::GridRaster& dem,
                             hydro::TerrainResult& r,
                             const hydro::TerrainConfig& c) {
    io::GridRaster raster = dem.OnSameGrid();
    raster.sample_type = io::GridSampleType::kByte;
    // No data is the Byte raster's no-data value (NaN here, 255 in the file), not class 0.
    std::vector<float> codes = std::move(r.terrain_class);
    for (float& v : codes) {
        if (v == static_cast<float>(hydro::TerrainClass::kNoData)) {
            v = std::numeric_limits<float>::quiet_NaN();
        }
    }
    io::GridLayer cls("crawler", "", std::move(codes), io::GridBandKind::kClass);
    for (int k = 0; k < hydro::kTerrainClassCount; ++k) {
        cls.class_names.emplace_back(hydro::TerrainClassName(static_cast<hydro::TerrainClass>(k)));
        cls.class_colours.push_back(kClassColours[k]);
    }
    raster.layers = {std::move(cls)};
    std::string limits = "max slope " + Fixed(c.crawler_max_slope_deg, 1) + " deg, max step " +
                         Fixed(c.crawler_max_step_m, 2) + " m, max roughness " +
                         Fixed(c.crawler_max_roughness_m, 3) + " m, footprint " +
                         Fixed(c.window_m, 2) + " m";
    raster.metadata = {{"pitmap_product", "where a bottom crawler can stand and what it reaches"},
                       {"pitmap_crawler_limits", limits}};
    if (r.launch_given) {
        raster.metadata.emplace_back(
            "pitmap_launch_easting_northing",
            Fixed(c.launch_easting, 2) + " " + Fixed(c.launch_northing, 2));
    }
    return raster;
}

json TerrainRecord(const hydro::TerrainResult& r, const hydro::TerrainConfig& c) {
    json areas = json::object();
    for (int k = 1; k < hydro::kTerrainClassCount; ++k) {  // not "no data": the grid's rest
        areas[hydro::TerrainClassName(static_cast<hydro::TerrainClass>(k))] =
            static_cast<double>(r.nodes_by_class[k]) * r.node_area_m2;
    }
    json rec = {{"message", r.message},
                {"window_m", c.window_m},
                {"step_window_m", c.step_window_m},
                {"min_fill", c.min_fill},
                {"window_nodes", r.window_nodes},
                {"step_window_nodes", r.step_window_nodes},
                {"crawler_max_slope_deg", c.crawler_max_slope_deg},
                {"crawler_max_step_m", c.crawler_max_step_m},
                {"crawler_max_roughness_m", c.crawler_max_roughness_m},
                {"area_with_data_m2", static_cast<double>(r.nodes_with_data) * r.node_area_m2},
                {"area_by_class_m2", areas},
                {"launch_given", r.launch_given}};
    if (r.launch_given) {
        rec["launch_easting_northing"] = {c.launch_easting, c.launch_northing};
        rec["launch_found"] = r.launch_found;
        if (r.launch_found) rec["launch_snap_distance_m"] = r.launch_snap_distance_m;
    }
    return rec;
}

}  // namespace

Expected<json> TerrainSurvey(const StageContext& s,
                             const GridStageConfig& gc,
                             const io::GridRaster& dem,
                             const Log& log) {
    const std::vector<float>* elevation = dem.Values("elevation");
    if (elevation == nullptr) return Error{"grid: terrain: the DEM has no elevation layer"};
    const hydro::TerrainConfig& c = gc.terrain_config;
    const hydro::TerrainGrid grid{dem.x0, dem.y0, dem.resolution_m, dem.nx, dem.ny, elevation};
    hydro::TerrainResult r = hydro::ComputeTerrain(grid, c);
    log("grid: terrain: " + r.message);
    json rec = TerrainRecord(r, c);

    io::GridRaster terrain = TerrainRaster(dem, r, c);
    io::GridRaster crawler = CrawlerRaster(dem, r, c);
    if (!s.model.run_id.empty()) {
        terrain.metadata.emplace_back("pitmap_run_id", s.model.run_id);
        crawler.metadata.emplace_back("pitmap_run_id", s.model.run_id);
    }
    if (auto w = io::WriteCogGeoTiff(s.out_dir + "/terrain.tif", terrain); !w) return w.error();
    if (auto w = io::WriteCogGeoTiff(s.out_dir + "/crawler.tif", crawler); !w) return w.error();
    rec["files"] = {"terrain.tif", "crawler.tif"};
    return rec;
}

}  // namespace pitmap::proc::pipeline::detail
