// SPDX-License-Identifier: MIT
// The backscatter mosaic of the `grid` stage (grid_stage.hpp, hydro/mosaic.hpp): the survey's
// 83P intensities on the DEM's grid, written as P/mosaic.tif.
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "processor/io/grid_io.hpp"
#include "processor/pipeline/grid_cube_tiles.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {

using nlohmann::json;

namespace {

// What the mosaic's dB are relative to (docs/products-typing.md). The 83P intensity is a u16
// "normalized amplitude" with no physical scaling (Imagenex 83P v1.10, bytes 256 + 2B on;
// the head's source level, receiver gain, start gain and normalisation are not in the record).
constexpr const char* kDbReference =
    "dB re 1 unit of the 83P intensity (u16 normalized amplitude, no physical scaling): 20 log10 "
    "of the intensity plus the range loss added back (levels carried to 1 m) and the angular "
    "response referred to the reference incidence; not calibrated (the head's source level, "
    "gain and normalisation are unknown and not removed): compare values within one survey of "
    "one head and settings only";

std::vector<io::GridLayer> MosaicLayers(const hydro::MosaicResult& r,
                                        const hydro::MosaicConfig& c) {
    char range[200];
    std::snprintf(range,
                  sizeof range,
                  "20 log10(I) + %.1f log10(R / 1 m) + 2 x %.4f dB/m x R",
                  c.spreading_db_per_decade,
                  c.absorption_db_per_m);
    char angular[200];
    std::snprintf(angular,
                  sizeof angular,
                  "%s, referred to %.1f deg incidence",
                  hydro::ToString(c.angular),
                  c.reference_angle_deg);
    using K = io::GridBandKind;
    io::GridLayer corrected{"backscatter", "dB", r.corrected_db, K::kContinuous};
    corrected.metadata = {{"pitmap_reference", kDbReference},
                          {"pitmap_formula", std::string(range) + " - AR(theta) + AR(ref)"},
                          {"pitmap_angular_correction", angular}};
    io::GridLayer uncorrected{"uncorrected", "dB", r.uncorrected_db, K::kContinuous};
    uncorrected.metadata = {
        {"pitmap_reference",
         "dB re 1 unit of the 83P intensity (u16 normalized amplitude, no physical scaling), as "
         "received: no range or angular correction; not calibrated"},
        {"pitmap_formula", "20 log10(I)"}};
    io::GridLayer count{"count", "count", r.count, K::kCount};
    count.metadata = {{"pitmap_count", "soundings averaged in the node"}};
    return {std::move(corrected), std::move(uncorrected), std::move(count)};
}

std::vector<std::pair<std::string, std::string>> MosaicMetadata(const hydro::MosaicConfig& c) {
    char range_note[160];
    std::snprintf(range_note,
                  sizeof range_note,
                  "%.1f log10(R) + 2 x %.4f dB/m x R",
                  c.spreading_db_per_decade,
                  c.absorption_db_per_m);
    return {{"pitmap_mosaic", "relative seabed backscatter, dB (83P intensity as amplitude)"},
            {"pitmap_db_reference", kDbReference},
            {"pitmap_range_correction", range_note},
            {"pitmap_angular_correction",
             std::string(hydro::ToString(c.angular)) + ", referenced to " +
                 std::to_string(c.reference_angle_deg) + " deg incidence"}};
}

// The mosaic's soundings of a block of the view: UTM positions, the 83P intensity, the range
// and the beam's direction in the grid's axes.
void MosaicBlockOf(const StageContext& s,
                   const georef::GeorefPoints& pts,
                   const georef::UtmProjection& utm,
                   const Eigen::Matrix2d& to_utm,
                   hydro::MosaicSoundings& m) {
    const survey::PingSeries& series = s.model.ingest.pings;
    const std::size_t n = pts.size();
    m.x.resize(n);
    m.y.resize(n);
    m.intensity.resize(n);
    m.range_m.resize(n);
    m.beam_dir.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
        const georef::GeorefPing& p = s.geo.pings[pts.ping[j]];
        const survey::PingHeader& h = series.pings[p.header_index];
        const Eigen::Vector3d enh = utm.At(pts, s.geo.pings, j);
        m.x[j] = enh.x();
        m.y[j] = enh.y();
        m.intensity[j] = series.intensities[h.beam_offset + pts.beam[j]];
        m.range_m[j] = pts.range_m[j];
        // The direction the echo came from: transducer -> sounding (with refraction the chord
        // of the curved ray, within a few tenths of a degree of its arrival angle in a pit).
        const Eigen::Vector3d d = (pts.position_world[j] - p.sensor_world).normalized();
        const Eigen::Vector2d xy = to_utm * d.head<2>();
        m.beam_dir[j] = Eigen::Vector3d(xy.x(), xy.y(), d.z()).normalized().cast<float>();
    }
}

}  // namespace

Expected<json> MosaicSurvey(const StageContext& s,
                            const GridStageConfig& gc,
                            const io::GridRaster& dem,
                            const georef::UtmProjection& utm,
                            const Eigen::Matrix<double, 2, 3>& utm_to_world,
                            const Log& log,
                            std::size_t block) {
    const survey::PingSeries& series = s.model.ingest.pings;
    if (!series.has_intensities()) {
        const std::string why =
            "the pings carry no intensities (83P v1.00, v1.10 without them, or a survey.pitmap "
            "of format 1: run `pitmap georef` again): no mosaic";
        log("grid: mosaic: " + why);
        return json{{"made", false}, {"reason", why}};
    }
    const std::vector<float>* elevation = dem.Values("elevation");
    if (elevation == nullptr) return Error{"grid: mosaic: the DEM has no elevation layer"};
    const hydro::MosaicGrid grid{dem.x0, dem.y0, dem.resolution_m, dem.nx, dem.ny, elevation};
    // World ENU directions -> the grid's (UTM) axes: the inverse of the affine fit's linear
    // part (the grid convergence, under a degree; the scale is 1 within 1e-3).
    const Eigen::Matrix2d to_utm = utm_to_world.block<2, 2>(0, 0).inverse();
    const std::size_t n = ViewSize(s);
    hydro::MosaicByBlocks mosaic(grid, gc.mosaic_config);
    mosaic.Reserve(n);
    hydro::MosaicSoundings m;
    auto st = ForEachViewBlock(
        s, block == 0 ? n : block, [&](const georef::GeorefPoints& b, std::size_t) {
            MosaicBlockOf(s, b, utm, to_utm, m);
            mosaic.Add(m);
            return Status{Ok{}};
        });
    if (!st) return Error{"grid: mosaic: " + st.error().message};
    m = hydro::MosaicSoundings{};
    const hydro::MosaicResult r = mosaic.Finish();
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
    io::GridRaster raster = dem.OnSameGrid();
    raster.layers = MosaicLayers(r, gc.mosaic_config);
    raster.metadata = MosaicMetadata(gc.mosaic_config);
    if (!s.model.run_id.empty()) raster.metadata.emplace_back("pitmap_run_id", s.model.run_id);
    if (auto w = io::WriteCogGeoTiff(s.out_dir + "/mosaic.tif", raster); !w) return w.error();
    rec["file"] = "mosaic.tif";
    return rec;
}

}  // namespace pitmap::proc::pipeline::detail
