// SPDX-License-Identifier: MIT
// The backscatter mosaic of the `grid` stage (grid_stage.hpp, hydro/mosaic.hpp): the survey's
// 83P intensities on the DEM's grid, written as P/mosaic.tif.
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "processor/io/grid_io.hpp"
#include "processor/pipeline/survey.hpp"

namespace pitmap::proc::pipeline::detail {

using nlohmann::json;

Expected<json> MosaicSurvey(const Survey& s,
                            const GridStageConfig& gc,
                            const io::GridRaster& dem,
                            georef::UtmPoints& utm,
                            const Eigen::Matrix<double, 2, 3>& utm_to_world,
                            const Log& log) {
    const georef::PingSeries& series = s.model.ingest.pings;
    if (!series.has_intensities()) {
        const std::string why =
            "the pings carry no intensities (83P v1.00, v1.10 without them, or a survey.pitmap "
            "of format 1: run `pitmap georef` again): no mosaic";
        log("grid: mosaic: " + why);
        return json{{"made", false}, {"reason", why}};
    }
    const georef::GeorefPoints& pts = s.geo.points;
    const std::size_t n = pts.size();
    // World ENU directions -> the grid's (UTM) axes: the inverse of the affine fit's linear
    // part (the grid convergence, under a degree; the scale is 1 within 1e-3).
    const Eigen::Matrix2d to_utm = utm_to_world.block<2, 2>(0, 0).inverse();
    hydro::MosaicSoundings m;
    m.x.resize(n);
    m.y.resize(n);
    m.intensity.resize(n);
    m.range_m.resize(n);
    m.beam_dir.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
        const georef::GeorefPing& p = s.geo.pings[pts.ping[j]];
        const georef::PingHeader& h = series.pings[p.header_index];
        m.x[j] = utm.easting_northing_height[j].x();
        m.y[j] = utm.easting_northing_height[j].y();
        m.intensity[j] = series.intensities[h.beam_offset + pts.beam[j]];
        m.range_m[j] = pts.range_m[j];
        // The direction the echo came from: transducer -> sounding (with refraction the chord
        // of the curved ray, within a few tenths of a degree of its arrival angle in a pit).
        const Eigen::Vector3d d = (pts.position_world[j] - p.sensor_world).normalized();
        const Eigen::Vector2d xy = to_utm * d.head<2>();
        m.beam_dir[j] = Eigen::Vector3d(xy.x(), xy.y(), d.z()).normalized().cast<float>();
    }
    const std::vector<float>* elevation = nullptr;
    for (const auto& l : dem.layers) {
        if (l.name == "elevation") elevation = &l.values;
    }
    if (elevation == nullptr) return Error{"grid: mosaic: the DEM has no elevation layer"};
    const hydro::MosaicGrid grid{dem.x0, dem.y0, dem.resolution_m, dem.nx, dem.ny, elevation};
    std::vector<Eigen::Vector3d>().swap(utm.easting_northing_height);
    const hydro::MosaicResult r = hydro::RunMosaic(std::move(m), grid, gc.mosaic_config);
    log("grid: mosaic: " + r.message);
    json rec = {{"made", r.ok},
                {"message", r.message},
                {"soundings", r.soundings_in},
                {"used", r.used},
                {"no_intensity", r.no_intensity},
                {"saturated", r.saturated},
                {"outside_grid", r.outside_grid},
                {"beyond_incidence", r.beyond_incidence},
                {"nodes_filled", r.nodes_filled},
                {"median_incidence_deg", r.median_incidence_deg},
                {"corrected_p05_db", r.corrected_p05_db},
                {"corrected_p95_db", r.corrected_p95_db},
                {"angular", hydro::ToString(gc.mosaic_config.angular)},
                {"reference_angle_deg", gc.mosaic_config.reference_angle_deg},
                {"spreading_db_per_decade", gc.mosaic_config.spreading_db_per_decade},
                {"absorption_db_per_m", gc.mosaic_config.absorption_db_per_m}};
    // The angular response applied, relative to the reference angle (the report plots it).
    const double ref = r.response.At(gc.mosaic_config.reference_angle_deg);
    json curve = json::array();
    for (std::size_t k = 0; k < r.response.level_db.size(); ++k) {
        curve.push_back({(static_cast<double>(k) + 0.5) * r.response.bin_deg,
                         r.response.level_db[k] - ref,
                         r.response.counts.empty() ? 0 : r.response.counts[k]});
    }
    rec["angular_response_deg_db_count"] = curve;
    if (!r.ok) return rec;
    io::GridRaster raster = dem;
    raster.horizontal_only = true;
    raster.vertical_wkt.clear();
    raster.layers = {{"backscatter", "dB", r.corrected_db},
                     {"uncorrected", "dB", r.uncorrected_db},
                     {"count", "", r.count}};
    char range_note[160];
    std::snprintf(range_note,
                  sizeof range_note,
                  "%.1f log10(R) + 2 x %.4f dB/m x R",
                  gc.mosaic_config.spreading_db_per_decade,
                  gc.mosaic_config.absorption_db_per_m);
    raster.metadata = {
        {"pitmap_mosaic", "relative seabed backscatter, dB (83P intensity as amplitude)"},
        {"pitmap_range_correction", range_note},
        {"pitmap_angular_correction",
         std::string(hydro::ToString(gc.mosaic_config.angular)) + ", referenced to " +
             std::to_string(gc.mosaic_config.reference_angle_deg) + " deg incidence"}};
    if (!s.model.run_id.empty()) raster.metadata.emplace_back("pitmap_run_id", s.model.run_id);
    if (auto w = io::WriteCogGeoTiff(s.out_dir + "/mosaic.tif", raster); !w) return w.error();
    rec["file"] = "mosaic.tif";
    return rec;
}

}  // namespace pitmap::proc::pipeline::detail
