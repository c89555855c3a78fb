// SPDX-License-Identifier: MIT
// The `grid` stage (grid_stage.hpp): its configuration and its run on a survey in memory.
#include "processor/pipeline/grid_stage.hpp"

#include <time.h>
#include <algorithm>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <optional>
#include <sstream>
#include <type_traits>
#include <utility>

#include "common/formats/replace_file.hpp"
#include "common/frames.hpp"
#include "common/geodesy.hpp"
#include "common/peak_memory.hpp"
#include "common/vehicle.hpp"
#include "processor/hydro/tpu.hpp"
#include "processor/io/geoid.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/products.hpp"
#include "processor/io/water_level.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/compare_stage.hpp"
#include "processor/pipeline/grid_cube_tiles.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/posterior.hpp"

namespace pitmap::proc::pipeline {

namespace {

using nlohmann::json;

// Wall and process CPU seconds of the parts of the stage (CPU time says what a part costs when
// other processes share the cores).
struct PartClock {
    explicit PartClock(detail::StageClock& stage) : stage_clock(&stage) {
        stage_clock->ResetPeakWithinStage();
    }
    detail::StageClock* stage_clock;
    std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
    double cpu = Cpu();
    // Each part's peak resident memory, MB (name -> MB): the stage's high-water mark is reset
    // at each lap, so a part's figure is its own where the kernel allows (StageClock).
    nlohmann::json peak_rss_mb = nlohmann::json::object();
    static double Cpu() {
        timespec ts{};
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
        return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
    }
    // Records the part that ends now as name -> [wall s, CPU s], and its peak memory.
    void Lap(nlohmann::json& out, const char* name) {
        const auto now = std::chrono::steady_clock::now();
        const double c = Cpu();
        out[name] = {std::chrono::duration<double>(now - wall).count(), c - cpu};
        peak_rss_mb[name] = PeakRssMb();
        stage_clock->ResetPeakWithinStage();
        wall = std::chrono::steady_clock::now();
        cpu = Cpu();
    }
};

// The error model: the vehicle file's `uncertainty:` (the file georef used), else defaults.
// `sv_source`: where the sonar's own sound speed comes from (vehicle.yaml).
SensorErrorModel ErrorModel(const std::string& path,
                            const Log& log,
                            std::string* source,
                            SoundVelocitySource* sv_source) {
    *sv_source = SoundVelocitySource::kUnknown;
    if (path.empty()) {
        *source = "defaults (no vehicle.yaml)";
        return SensorErrorModel{};
    }
    auto v = ReadVehicleFile(path);
    if (!v) {
        log("warning: grid: " + v.error().message + "; the default sensor error model is used");
        *source = "defaults (vehicle.yaml unreadable)";
        return SensorErrorModel{};
    }
    *source = v->uncertainty ? path + " uncertainty:" : "defaults (" + path + " has none)";
    *sv_source = v->sound_velocity_source;
    return v->ErrorModel();
}

double MedianOf(std::vector<double> v) {
    if (v.empty()) return 0;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

// The vertical datum of the products (hydro/datum.hpp) at every ping, with its record for
// summary.json. `ping_geo` are the transducers' geodetic positions.
Expected<hydro::DatumModel> ProductDatum(const detail::StageContext& s,
                                         const hydro::VerticalDatumConfig& vc,
                                         const std::string& site,
                                         const std::vector<Geodetic>& ping_geo,
                                         json* record,
                                         const Log& log) {
    hydro::DatumInputs in;
    in.site_name = site;
    in.ping_t_s.reserve(s.geo.pings.size());
    for (const auto& p : s.geo.pings)
        in.ping_t_s.push_back(static_cast<double>(p.utime_gps) * 1e-6);
    *record = {{"datum", hydro::ToString(vc.datum)}};
    if (vc.datum == hydro::VerticalDatum::kGeoid) {
        const hydro::GeoidCrs* g = hydro::FindGeoidCrs(vc.geoid_vertical_epsg);
        const std::string grid = vc.geoid_grid.empty() ? g->default_grid : vc.geoid_grid;
        auto geoid = io::GeoidGrid::Open(grid);
        if (!geoid) return Error{"grid: vertical datum: " + geoid.error().message};
        auto n = geoid->Undulations(ping_geo);
        if (!n) return Error{"grid: vertical datum: " + n.error().message};
        in.geoid_n_m = std::move(*n);
        in.source_name = grid;
        (*record)["geoid_grid"] = grid;
    }
    if (vc.datum == hydro::VerticalDatum::kWaterLevel) {
        double above = vc.ins_height_above_waterline_m;
        std::string above_source = "vertical.ins_height_above_waterline_m";
        if (std::isnan(above)) {
            above_source = "vehicle.yaml ins.height_above_waterline_m";
            const auto v = s.summary.find("vehicle");
            if (v != s.summary.end() && v->is_object() &&
                v->value("ins_height_above_waterline_m", json()).is_number()) {
                above = (*v)["ins_height_above_waterline_m"].get<double>();
            }
        }
        if (!std::isfinite(above)) {
            return Error{
                "grid: vertical datum water_level needs the INS height above the water "
                "line: vehicle.yaml ins.height_above_waterline_m or "
                "vertical.ins_height_above_waterline_m"};
        }
        std::vector<hydro::HeightSample> h;
        h.reserve(s.model.ingest.nav.samples.size());
        for (const auto& n : s.model.ingest.nav.samples) {
            h.push_back({static_cast<double>(n.utime_gps) * 1e-6, n.position.height_m});
        }
        hydro::WaterSurfaceStats ws;
        in.surface = hydro::SmoothWaterSurface(h, above, vc.smoothing_window_s, vc.step_s, &ws);
        (*record)["water_level_source"] = hydro::ToString(vc.water_level_source);
        (*record)["ins_height_above_waterline_m"] = above;
        (*record)["ins_height_above_waterline_source"] = above_source;
        (*record)["gnss_water_surface"] = {{"samples", ws.samples_used},
                                           {"rejected", ws.samples_rejected},
                                           {"median_m", ws.level_median_m},
                                           {"min_m", ws.level_min_m},
                                           {"max_m", ws.level_max_m},
                                           {"raw_sd_mad_m", ws.raw_mad_m},
                                           {"smoothing_window_s", vc.smoothing_window_s}};
        if (vc.water_level_source == hydro::WaterLevelSource::kFile) {
            auto levels = io::ReadWaterLevelFile(vc.water_level_file);
            if (!levels) return Error{"grid: vertical datum: " + levels.error().message};
            for (const auto& l : *levels) {
                in.levels.t_s.push_back(static_cast<double>(l.utime_gps) * 1e-6);
                in.levels.level_m.push_back(l.level_m);
            }
            in.source_name = std::filesystem::path(vc.water_level_file).filename().string();
            (*record)["water_level_file"] = vc.water_level_file;
            (*record)["water_levels"] = levels->size();
        }
    }
    hydro::DatumBuild b = hydro::BuildDatum(vc, in);
    if (!b.ok) return Error{"grid: " + b.message};
    (*record)["vertical_crs"] = b.model.crs_name;
    (*record)["vertical_epsg"] = b.model.vertical_epsg > 0 ? json(b.model.vertical_epsg) : json();
    (*record)["description"] = b.model.description;
    (*record)["mean_datum_height_m"] = b.model.mean_datum_height_m;
    log("grid: vertical datum: " + b.model.description);
    return std::move(b.model);
}

json OrderShares(const std::array<double, hydro::kNumS44Orders>& a) {
    json j = json::object();
    for (int o = 0; o < hydro::kNumS44Orders; ++o)
        j[hydro::ToString(static_cast<hydro::S44Order>(o))] = a[o];
    return j;
}

// UTM easting/northing -> world east/north: an affine fit over soundings spread across the
// survey (UTM is conformal: over a pit its scale and grid convergence are constant to 1e-7).
// `sample` holds the soundings j = 0, step, 2 step, ... (step = max(1, n / 2000) of the view's
// n): each one's UTM position and its world position (UtmToWorldSample).
Eigen::Matrix<double, 2, 3> UtmToWorld(
    const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& sample) {
    Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
    Eigen::Matrix<double, 3, 2> Atb = Eigen::Matrix<double, 3, 2>::Zero();
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    if (!sample.empty()) c = sample.front().first.head<2>();
    for (const auto& [enh, world] : sample) {
        const Eigen::Vector3d a(enh.x() - c.x(), enh.y() - c.y(), 1.0);
        AtA += a * a.transpose();
        Atb += a * world.head<2>().transpose();
    }
    Eigen::Matrix<double, 3, 2> X = AtA.ldlt().solve(Atb);
    // world = X^T [e - c_e, n - c_n, 1]
    Eigen::Matrix<double, 2, 3> M = X.transpose();
    M.col(2) -= M.block<2, 2>(0, 0) * c;
    return M;
}

json S44Json(const hydro::S44Result& r,
             const std::string& holiday_file,
             const Eigen::Matrix<double, 2, 3>& to_world) {
    json holidays = json::array();
    const auto world = [&](double x, double y) {
        const Eigen::Vector2d w = to_world * Eigen::Vector3d(x, y, 1.0);
        return json{w.x(), w.y()};
    };
    for (std::size_t k = 0; k < r.holidays.size() && k < 200; ++k) {
        const auto& h = r.holidays[k];
        holidays.push_back({{"x_m", h.x},
                            {"y_m", h.y},
                            {"world_m", world(h.x, h.y)},
                            {"bbox_m", {h.x_min, h.y_min, h.x_max, h.y_max}},
                            {"bbox_world_m",
                             {world(h.x_min, h.y_min),
                              world(h.x_max, h.y_min),
                              world(h.x_max, h.y_max),
                              world(h.x_min, h.y_max)}},
                            {"nodes", h.nodes},
                            {"area_m2", h.area_m2},
                            {"largest_square_m", h.largest_square_m}});
    }
    json bins = json::array();
    for (const auto& b : r.crossline_by_angle) {
        bins.push_back({{"angle_lo_deg", b.angle_lo_deg},
                        {"angle_hi_deg", b.angle_hi_deg},
                        {"count", b.count},
                        {"mean_m", b.mean_m},
                        {"sd_m", b.sd_m},
                        {"rms_m", b.rms_m},
                        {"within_tvu", b.within_tvu}});
    }
    json limits = json::object();
    for (int o = 0; o < hydro::kNumS44Orders; ++o) {
        const auto& L = hydro::LimitsOf(static_cast<hydro::S44Order>(o));
        limits[hydro::ToString(static_cast<hydro::S44Order>(o))] = {
            {"thu_m", L.thu_constant_m},
            {"thu_depth_fraction", L.thu_depth_fraction},
            {"tvu_a_m", L.tvu_a_m},
            {"tvu_b", L.tvu_b},
            {"feature_m", L.feature_size_m},
            {"coverage_percent", L.coverage_percent}};
    }
    const int met = hydro::StrictestOrderMet(r);
    return {{"standard", "IHO S-44 Edition 6.1.0"},
            {"order", hydro::ToString(r.order)},
            {"limits", limits},
            {"soundings", r.soundings},
            {"nodes", r.nodes},
            {"nodes_without_thu", r.nodes_without_thu},
            {"soundings_within_tvu", OrderShares(r.soundings_within_tvu)},
            {"soundings_within_thu", OrderShares(r.soundings_within_thu)},
            {"soundings_within_both", OrderShares(r.soundings_within_both)},
            {"nodes_within_tvu", OrderShares(r.nodes_within_tvu)},
            {"nodes_within_thu", OrderShares(r.nodes_within_thu)},
            {"strictest_order_met_95",
             met >= 0 ? json(hydro::ToString(static_cast<hydro::S44Order>(met))) : json()},
            {"coverage_share", r.coverage_share},
            {"nodes_survey_area", r.nodes_survey_area},
            {"nodes_in_gaps", r.nodes_in_gaps},
            {"gaps", r.gaps},
            {"feature_size_m", r.feature_size_m},
            {"holiday_count", r.holidays.size()},
            {"holidays", holidays},
            {"holiday_map", holiday_file},
            {"crossline",
             {{"compared", r.crossline_compared},
              {"mean_m", r.crossline_mean_m},
              {"sd_m", r.crossline_sd_m},
              {"rms_m", r.crossline_rms_m},
              {"within_tvu", r.crossline_within_tvu},
              {"by_angle", bins}}},
            {"message", r.message}};
}

// dem.tif's bands (io::GridLayer): heights and uncertainty in metres, averaged when zoomed out;
// density and hypotheses counts ("count": without a unit of their own GDAL would report the
// vertical CRS's metre), the nearest node's when zoomed out.
std::vector<io::GridLayer> DemLayers(const hydro::CubeGrid& g) {
    using K = io::GridBandKind;
    return {{"elevation", "metre", g.elevation_m, K::kContinuous},
            {"uncertainty", "metre", g.uncertainty_m, K::kContinuous},
            {"density", "count", g.density, K::kCount},
            {"hypotheses", "count", g.hypotheses, K::kCount}};
}

// s44_holidays.tif: the holiday map as an 8-bit class raster (0 covered, 1 gap, 2 holiday,
// 255 outside the survey) with category names and colours, on the DEM's grid and horizontal
// CRS (classes are not heights: no vertical CRS, no unit).
io::GridRaster HolidayRaster(const io::GridRaster& dem, const hydro::S44Result& r) {
    io::GridRaster hol = dem.OnSameGrid();
    hol.sample_type = io::GridSampleType::kByte;
    io::GridLayer l("holiday", "", r.holiday_map, io::GridBandKind::kClass);
    l.class_names = {"covered", "gap", "holiday"};
    l.class_colours = {{{190, 190, 190, 255}, {255, 190, 0, 255}, {220, 0, 0, 255}}};
    hol.layers = {std::move(l)};
    hol.metadata = {{"pitmap_holidays",
                     "IHO S-44 order " + std::string(hydro::ToString(r.order)) +
                         ": 0 covered, 1 gap, 2 holiday, 255 (nodata) outside the survey"}};
    return hol;
}

}  // namespace

std::vector<std::string> GridStageConfig::Validate() const {
    std::vector<std::string> out = cube.Validate();
    if (!(tpu_sound_speed_mps >= 1300 && tpu_sound_speed_mps <= 1700)) {
        out.push_back("grid.tpu_sound_speed_mps must be within 1300..1700");
    }
    if (!(ins_sigma_max_age_s > 0)) out.push_back("grid.ins_sigma_max_age_s must be > 0");
    if (!(surface_filter_gate > 0)) out.push_back("grid.surface_filter_gate must be > 0");
    if (!(surface_filter_min_m >= 0)) out.push_back("grid.surface_filter_min_m must be >= 0");
    if (!(surface_filter_max_slope_deg > 0 && surface_filter_max_slope_deg <= 90))
        out.push_back("grid.surface_filter_max_slope_deg must be in (0, 90]");
    for (auto& p : sound_speed.Validate()) out.push_back("grid." + p);
    for (auto& p : vertical.Validate()) out.push_back(p);
    for (auto& p : s44_config.Validate()) out.push_back(p);
    for (auto& p : mosaic_config.Validate()) out.push_back(p);
    for (auto& p : terrain_config.Validate()) out.push_back(p);
    return out;
}

namespace detail {

namespace {

// UtmToWorld over the view's soundings 0, step, 2 step, ... (step = max(1, n / 2000)), each
// read alone while the view is spilled.
Expected<Eigen::Matrix<double, 2, 3>> UtmToWorldOf(const StageContext& s,
                                                   const georef::UtmProjection& utm) {
    const std::size_t n = ViewSize(s);
    const std::size_t step = std::max<std::size_t>(1, n / 2000);
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> sample;
    georef::GeorefPoints one;
    for (std::size_t j = 0; j < n; j += step) {
        if (s.spilled_view) {
            if (auto st = s.spilled_view->ReadBlock(j, 1, one); !st)
                return Error{"grid: " + st.error().message};
            sample.emplace_back(utm.At(one, s.geo.pings, 0), one.position_world[0]);
        } else {
            sample.emplace_back(utm.At(s.geo, j), s.geo.points.position_world[j]);
        }
    }
    return UtmToWorld(sample);
}

// The column speed sigma at each ping from its cast (hydro::CastSpeedSigma: the cast's age and
// distance, and the header's disagreement with it at the transducer), the pings without a cast
// keeping the error model's.
struct CastSigmas {
    std::vector<double> column;        // per ping, m/s
    std::vector<double> disagreement;  // |header - cast at the transducer|, m/s, where measured
    std::size_t with_cast = 0;         // pings with a cast
    bool header_measured = false;      // the header's speed is a measurement at the head
};

// CastSigmas, and each cast ping's column and surface speed sigmas into `sig`.
CastSigmas CastSpeedSigmas(const StageContext& s,
                           const SensorErrorModel& m,
                           const hydro::SoundSpeedSigmaConfig& cfg,
                           bool header_measured,
                           std::vector<hydro::PingSigma>& sig) {
    CastSigmas out;
    out.header_measured = header_measured;
    out.column.assign(sig.size(), m.mean_sound_speed_sigma_mps);
    const svp::Refraction* refr = s.geo.refraction.get();
    if (refr == nullptr) return out;
    const LocalTangentFrame world(s.model.origin);
    for (std::size_t k = 0; k < sig.size(); ++k) {
        const georef::GeorefPing& ping = s.geo.pings[k];
        if (ping.cast < 0 || static_cast<std::size_t>(ping.cast) >= refr->casts().size()) continue;
        const svp::PreparedCast& c = refr->casts()[static_cast<std::size_t>(ping.cast)];
        const double age_s = c.cast.has_time()
                                 ? static_cast<double>(ping.utime_gps - c.cast.utime_gps) * 1e-6
                                 : std::nan("");
        double distance_m = std::nan("");
        if (c.cast.has_position()) {
            const Eigen::Vector3d at =
                world.ToEnu(Geodetic{c.cast.latitude_deg, c.cast.longitude_deg, 0.0});
            distance_m = (ping.sensor_world - at).head<2>().norm();
        }
        double dis = std::nan("");
        if (header_measured) {
            const double depth =
                refr->TransducerDepth(ping.T_world_vehicle.linear() * s.model.mount.lever_arm_m);
            dis = ping.assumed_sound_speed_mps - c.profile.SpeedAt(depth);
            out.disagreement.push_back(std::abs(dis));
        }
        out.column[k] =
            hydro::CastSpeedSigma(m.mean_sound_speed_sigma_mps, age_s, distance_m, dis, cfg);
        sig[k].column_speed_sigma_mps = out.column[k];
        // The steering correction used the cast's speed at the face (kProfile): off by the
        // disagreement; with the header's speed (kHeader) no correction was made.
        if (refr->surface_speed() == svp::SurfaceSpeedSource::kProfile && std::isfinite(dis)) {
            sig[k].surface_speed_sigma_mps = std::hypot(m.surface_sound_speed_sigma_mps, dis);
        }
        ++out.with_cast;
    }
    return out;
}

// The swath overlap's estimate of the column speed error (hydro::EstimateColumnSpeedError), from
// the soundings and their offsets from their transducer: only those it takes (every
// hydro::OverlapStride-th), gathered from the view a block at a time.
Expected<std::shared_ptr<const hydro::OverlapSpeedEstimate>> OverlapSpeedEstimateOf(
    const StageContext& s, const hydro::SoundSpeedSigmaConfig& cfg, std::size_t block) {
    const std::size_t stride = hydro::OverlapStride(ViewSize(s), cfg);
    std::vector<Eigen::Vector3d> points, offsets;
    const std::size_t taken = (ViewSize(s) + stride - 1) / stride;
    points.reserve(taken);
    offsets.reserve(taken);
    auto st = ForEachViewBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
        for (std::size_t j = (first + stride - 1) / stride * stride - first; j < b.size();
             j += stride) {
            points.push_back(b.position_world[j]);
            offsets.push_back(b.position_world[j] - s.geo.pings[b.ping[j]].sensor_world);
        }
        return Status{Ok{}};
    });
    if (!st) return st.error();
    return std::make_shared<const hydro::OverlapSpeedEstimate>(
        hydro::EstimateColumnSpeedError(points, offsets, cfg));
}

// What the overlap shows of stratified water in depth class `c`, for the gates' messages.
std::string StratifiedText(const hydro::OverlapDepthClass& c, double sound_speed_mps) {
    return "the swath overlap shows a column speed error of " +
           Fixed(c.relative_error * sound_speed_mps, 1) + " +- " +
           Fixed(c.relative_error_se * sound_speed_mps, 1) + " m/s at " + Fixed(c.lo_m, 0) + "-" +
           Fixed(c.hi_m, 0) +
           " m below the transducer (stratified water the profile does not describe)";
}

// Stratified water and nothing that measures it: every ping's column takes the a-priori bound
// of a fresh-water pit (the overlap sees only part of the error), and the gate
// grid/sound_speed_not_assessable says so.
void TakeAPrioriBound(StageContext& s,
                      const SensorErrorModel& m,
                      const std::string& strat_text,
                      std::vector<double>& column,
                      std::vector<hydro::PingSigma>& sig,
                      const Log& log) {
    for (std::size_t k = 0; k < sig.size(); ++k) {
        column[k] = std::hypot(m.mean_sound_speed_sigma_mps,
                               hydro::NoCastPriorSigma(s.geo.pings[k].assumed_sound_speed_mps));
        sig[k].column_speed_sigma_mps = column[k];
    }
    TripGate(s,
             Stage::kGrid,
             "sound_speed_not_assessable",
             "no sound-velocity cast, and " + strat_text +
                 ": the TPU takes the a-priori bound of the column's speed (between the "
                 "surface speed and water at 4 degC, sigma " +
                 Fixed(column.empty() ? 0.0 : column.front(), 1) +
                 " m/s), so the TVU and the S-44 order rest on that bound; give a cast "
                 "(--svp) to assess the survey",
             log);
}

// Nothing shows stratification, but too little overlap to say there is none: the TVU keeps the
// error model's column term, and the gate grid/sound_speed_not_assessable says it could not be
// assessed.
void GateTooLittleOverlap(StageContext& s,
                          const hydro::OverlapSpeedEstimate& est,
                          const SensorErrorModel& m,
                          const Log& log) {
    TripGate(s,
             Stage::kGrid,
             "sound_speed_not_assessable",
             "no sound-velocity cast, and too little swath overlap on floors to measure "
             "the water column's speed error (" +
                 est.message + "; the estimated depth classes hold " +
                 Fixed(100 * est.EstimatedShare(), 0) +
                 " % of its soundings): the TVU assumes the column the error model "
                 "states (" +
                 Fixed(m.mean_sound_speed_sigma_mps, 1) +
                 " m/s), which in stratified water it is not; give a cast (--svp) to "
                 "assess the survey",
             log);
}

// The overlap shows stratified water the cast(s) do not describe: the gate
// grid/sound_speed_cast_disagrees.
void GateCastDisagrees(StageContext& s, const std::string& strat_text, const Log& log) {
    TripGate(s,
             Stage::kGrid,
             "sound_speed_cast_disagrees",
             strat_text +
                 ": the cast(s) do not describe the water the soundings went through "
                 "(another time or place, or a wrong cast); the TPU carries the "
                 "overlap's estimate",
             log);
}

// The median, NaN when empty.
double MedianOrNan(std::vector<double> v) {
    if (v.empty()) return std::nan("");
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
}

// What the sound speed term of the TPU took and why.
struct SoundSpeedVerdict {
    std::string source;       // cast, error_model, a_priori_bound; "+overlap" when it was used
    bool stratified = false;  // the overlap shows stratified water
    bool assessable = false;  // a cast, or an overlap that stands for the column
};

// summary.json's stages.grid.sound_speed.
json SoundSpeedJson(const CastSigmas& cast,
                    const hydro::OverlapSpeedEstimate& est,
                    const SoundSpeedVerdict& verdict,
                    double sound_speed_mps) {
    json classes = json::array();
    for (const auto& c : est.classes) {
        if (c.cells == 0) continue;
        classes.push_back({{"depth_m", {c.lo_m, std::isinf(c.hi_m) ? json(nullptr) : json(c.hi_m)}},
                           {"cells", c.cells},
                           {"soundings", c.soundings},
                           {"estimated", c.estimated},
                           {"weight_m2", c.weight_m2},
                           {"relative_error", c.relative_error},
                           {"relative_error_se", c.relative_error_se},
                           {"speed_error_mps", c.relative_error * sound_speed_mps}});
    }
    json out = {{"source", verdict.source},
                {"pings_with_cast", cast.with_cast},
                {"header_speed_measured", cast.header_measured},
                {"median_column_sigma_mps", MedianOrNan(cast.column)},
                {"stratified", verdict.stratified},
                {"assessable", verdict.assessable},
                {"overlap_estimated_share", est.EstimatedShare()},
                {"overlap",
                 {{"soundings", est.soundings_used},
                  {"cells", est.cells_used},
                  {"classes", classes},
                  {"message", est.message}}}};
    if (!cast.disagreement.empty()) {
        out["median_surface_disagreement_mps"] = MedianOrNan(cast.disagreement);
    }
    return out;
}

// The TPU's sound speed sigmas from the data (hydro/sound_speed.hpp), per ping into `sig`, and
// the column speed error the swath overlap measured into tcfg; returns summary.json's
// stages.grid.sound_speed. Without a cast and without an estimate from the overlap the
// a-priori bound applies and the gate grid/sound_speed_not_assessable trips.
Expected<json> SoundSpeedSigmas(StageContext& s,
                                const GridStageConfig& gc,
                                SoundVelocitySource sv_source,
                                std::vector<hydro::PingSigma>& sig,
                                hydro::TpuConfig& tcfg,
                                std::size_t block,
                                const Log& log) {
    const SensorErrorModel& m = tcfg.model;
    const hydro::SoundSpeedSigmaConfig& cfg = gc.sound_speed;
    // The header's speed is a measurement at the head unless it was typed in.
    const bool header_measured = sv_source != SoundVelocitySource::kManual;
    CastSigmas cast = CastSpeedSigmas(s, m, cfg, header_measured, sig);
    // The swath overlap's estimate of the column speed error, cast or no cast.
    auto estimate = OverlapSpeedEstimateOf(s, cfg, block);
    if (!estimate) return Error{"grid: " + estimate.error().message};
    const auto est = std::move(*estimate);
    log("grid: sound speed from the swath overlap: " + est->message);
    const int strat = est->StratifiedClass(tcfg.sound_speed_mps, cfg.overlap_stratified_mps);
    const std::string strat_text =
        strat >= 0
            ? StratifiedText(est->classes[static_cast<std::size_t>(strat)], tcfg.sound_speed_mps)
            : std::string();
    const bool overlap_enough =
        est->estimated() && est->EstimatedShare() >= cfg.overlap_min_estimated_share;
    SoundSpeedVerdict verdict;
    verdict.source = cast.with_cast > 0 ? "cast" : "error_model";
    verdict.stratified = strat >= 0;
    // Without a cast the column is assessed only by an overlap that stands for it.
    verdict.assessable = cast.with_cast > 0 || (strat < 0 && overlap_enough);
    if (cast.with_cast == 0 && strat >= 0) {
        TakeAPrioriBound(s, m, strat_text, cast.column, sig, log);
        verdict.source = "a_priori_bound";
    } else {
        if (est->estimated()) {
            tcfg.column_relative_sigma_at = [est](double d, double prior) {
                return est->RelativeSigmaAt(d, prior);
            };
            verdict.source += "+overlap";
        }
        if (!verdict.assessable) GateTooLittleOverlap(s, *est, m, log);
        if (strat >= 0) GateCastDisagrees(s, strat_text, log);
    }
    return SoundSpeedJson(cast, *est, verdict, tcfg.sound_speed_mps);
}

// The transducers' geodetic positions, per ping.
std::vector<Geodetic> PingGeodetic(const StageContext& s) {
    const LocalTangentFrame world(s.model.origin);
    std::vector<Geodetic> ping_geo(s.geo.pings.size());
    for (std::size_t k = 0; k < ping_geo.size(); ++k) {
        ping_geo[k] = world.FromEnu(s.geo.pings[k].sensor_world);
    }
    return ping_geo;
}

}  // namespace

Expected<hydro::DatumModel> SurveyDatum(const StageContext& s,
                                        const PipelineConfig& config,
                                        json* record,
                                        const Log& log) {
    json r;
    return ProductDatum(s,
                        config.grid.vertical,
                        config.metadata.site,
                        PingGeodetic(s),
                        record != nullptr ? record : &r,
                        log);
}

// The crossline check against the stated uncertainty: two soundings of one spot differ by
// sqrt(2) sigma on average, sigma = TVU95 / 1.96. Lines that disagree far beyond it are a gate
// naming the likely input from the shape of the disagreement: growing with the beam angle is
// the across-track geometry, a constant offset the heights, neither the navigation or clock.
void CheckCrosslines(StageContext& s,
                     const hydro::S44Result& r,
                     double median_tvu_95_m,
                     const QualityConfig& q,
                     const Log& log) {
    constexpr std::int64_t kMinCompared = 200;
    if (r.crossline_compared < kMinCompared || !(median_tvu_95_m > 0)) return;
    const double expected = std::sqrt(2.0) * median_tvu_95_m / 1.96;
    if (!(r.crossline_rms_m > q.crossline_tvu_ratio * expected)) return;
    // Inner (< 20 deg) and outer (>= 45 deg) beams' RMS.
    double inner_ss = 0, outer_ss = 0;
    std::int64_t inner_n = 0, outer_n = 0;
    for (const auto& b : r.crossline_by_angle) {
        const double mid = 0.5 * (std::abs(b.angle_lo_deg) + std::abs(b.angle_hi_deg));
        if (mid < 20) {
            inner_ss += b.rms_m * b.rms_m * static_cast<double>(b.count);
            inner_n += b.count;
        } else if (mid >= 45) {
            outer_ss += b.rms_m * b.rms_m * static_cast<double>(b.count);
            outer_n += b.count;
        }
    }
    const double inner = inner_n > 0 ? std::sqrt(inner_ss / static_cast<double>(inner_n)) : 0.0;
    const double outer = outer_n > 0 ? std::sqrt(outer_ss / static_cast<double>(outer_n)) : 0.0;
    std::string cause;
    if (inner > 0 && outer > 2 * inner) {
        cause = "it grows with the beam angle (" + Fixed(inner, 3) + " m under 20 deg, " +
                Fixed(outer, 3) +
                " m beyond 45 deg): the across-track geometry: the sound speed (no cast, or the "
                "wrong one), the mount's roll or connector, the lever arm's y";
    } else if (std::abs(r.crossline_mean_m) > 0.5 * r.crossline_rms_m) {
        cause = "most of it is a constant offset (mean " + Fixed(r.crossline_mean_m, 3) +
                " m): the heights: the navigation's, the lever arm's z, the vertical datum";
    } else {
        cause =
            "it is neither a beam-angle trend nor an offset: the navigation (drift between "
            "lines), the sonar clock, or the lever arm's x";
    }
    TripGate(s,
             Stage::kGrid,
             "crossline_rms",
             "crossline RMS " + Fixed(r.crossline_rms_m, 3) + " m over " +
                 std::to_string(r.crossline_compared) + " soundings is " +
                 Fixed(r.crossline_rms_m / expected, 1) + "x what the median TVU (" +
                 Fixed(median_tvu_95_m, 3) + " m, 95 %) predicts for two soundings (" +
                 Fixed(expected, 3) + " m); " + cause,
             log);
}

// CUBE's own test, after it has chosen: a sounding whose height differs from the chosen
// hypothesis of its node by more than surface_filter_gate times the combined 1-sigma
// (sounding TVU and node uncertainty) and by more than surface_filter_min_m is rejected, on
// floors only (the surface between the neighbouring nodes no steeper than
// surface_filter_max_slope_deg: on walls a node's height says little about a sounding beside
// it, and the 3D cleaning judges there).
std::vector<std::uint8_t> SurfaceFilter(const std::vector<hydro::CubeSounding>& snd,
                                        const hydro::CubeGrid& g,
                                        const GridStageConfig& gc) {
    std::vector<std::uint8_t> verdict(snd.size(), 0);
    const double max_tan = std::tan(gc.surface_filter_max_slope_deg * M_PI / 180.0);
    auto at = [&](int i, int j) -> double {
        if (i < 0 || j < 0 || i >= g.nx || j >= g.ny) return std::nan("");
        return g.elevation_m[static_cast<std::size_t>(j) * g.nx + i];
    };
    for (std::size_t k = 0; k < snd.size(); ++k) {
        const hydro::CubeSounding& q = snd[k];
        // From the global node index (x0 = i0 res), so that a tile's grid (another x0) picks
        // the same node as the survey's.
        const int i = static_cast<int>(std::llround(q.x / g.resolution_m) - g.i0);
        const int j = static_cast<int>(std::llround(q.y / g.resolution_m) - g.j0);
        const double z = at(i, j);
        if (!std::isfinite(z)) continue;
        const double u = g.uncertainty_m[static_cast<std::size_t>(j) * g.nx + i] / 1.96;
        // The slope from the neighbouring nodes (any missing: not a floor to judge on).
        const double zx0 = at(i - 1, j), zx1 = at(i + 1, j), zy0 = at(i, j - 1), zy1 = at(i, j + 1);
        if (!std::isfinite(zx0) || !std::isfinite(zx1) || !std::isfinite(zy0) ||
            !std::isfinite(zy1))
            continue;
        const double gx = (zx1 - zx0) / (2 * g.resolution_m);
        const double gy = (zy1 - zy0) / (2 * g.resolution_m);
        if (std::hypot(gx, gy) > max_tan) continue;
        const double dz = std::abs(q.z - z);
        const double sigma = std::sqrt(u * u + double{q.sigma_v_m} * q.sigma_v_m);
        if (dz > gc.surface_filter_min_m && dz > gc.surface_filter_gate * sigma) {
            verdict[k] = static_cast<std::uint8_t>(survey::SoundingStatus::kSurfaceFilter);
        }
    }
    return verdict;
}

namespace {

// The TPU's settings for this survey, and where its sensor error model came from.
struct TpuSetup {
    hydro::TpuConfig config;
    std::string model_source;
    SoundVelocitySource sv_source = SoundVelocitySource::kUnknown;
};

// The TPU's settings: the vehicle file's error model (ErrorModel), the clock's remaining
// uncertainty and, once calibrated, the boresight's. An error when the model is invalid.
Expected<TpuSetup> SurveyTpuSetup(const StageContext& s,
                                  const GridStageConfig& gc,
                                  const Log& log) {
    TpuSetup setup;
    hydro::TpuConfig& tcfg = setup.config;
    tcfg.model = ErrorModel(s.model.vehicle_yaml, log, &setup.model_source, &setup.sv_source);
    tcfg.sound_speed_mps = gc.tpu_sound_speed_mps;
    tcfg.num_threads = gc.cube.num_threads;
    tcfg.clock_sigma_s = std::abs(s.model.clock.sigma_s());
    if (s.model.calibration == survey::CalibrationState::kCalibrated) {
        tcfg.boresight_sigma_rpy_deg = s.model.boresight_sd_deg;  // NaN where unknown
    }
    if (auto p = tcfg.Validate(); !p.empty()) {
        return Error{"grid: invalid sensor error model (" + setup.model_source + "):\n" +
                     FormatProblems(p)};
    }
    return setup;
}

// The pose sigma the TPU takes at every ping, and its record for summary.json.
struct PoseSigmas {
    std::vector<hydro::PingSigma> per_ping;
    std::size_t from_slam = 0;  // pings whose sigma is SLAM's posterior
    json record;
};

// The INS's own sigma at each ping (the error model's where the INS reports none, or too long
// ago), replaced by SLAM's posterior where grid.tpu_slam_posterior asks for it and SLAM's
// trajectory is used.
PoseSigmas TpuPoseSigmas(const StageContext& s,
                         const GridStageConfig& gc,
                         const hydro::TpuConfig& tcfg,
                         const Log& log) {
    const SensorErrorModel& model = tcfg.model;
    PoseSigma fallback;
    fallback << frames::DegToRad(model.roll_pitch_sigma_deg),
        frames::DegToRad(model.roll_pitch_sigma_deg), frames::DegToRad(model.heading_sigma_deg),
        model.position_sigma_h_m, model.position_sigma_h_m, model.position_sigma_v_m;
    PoseSigmas out;
    out.per_ping.resize(s.geo.pings.size());
    for (std::size_t k = 0; k < out.per_ping.size(); ++k) {
        PoseSigma sigma = PoseSigmaAt(
            s.model.ingest.nav, s.geo.pings[k].utime_gps, gc.ins_sigma_max_age_s, fallback);
        bool slam = false;
        if (gc.tpu_slam_posterior) sigma = ProcessingSigma(s.model, s.geo.pings[k], sigma, &slam);
        out.from_slam += slam ? 1 : 0;
        out.per_ping[k].attitude_rpy_rad = sigma.head<3>();
        out.per_ping[k].position_enu_m = sigma.tail<3>();
    }
    const auto boresight_deg = [&](std::size_t axis) {  // the boresight sigma the TPU took
        const double b = tcfg.boresight_sigma_rpy_deg[axis];
        return std::isnan(b) ? model.boresight_sigma_deg : b;
    };
    out.record = {{"source", out.from_slam > 0 ? "slam_posterior" : "ins"},
                  {"pings_slam_posterior", out.from_slam},
                  {"pings", out.per_ping.size()},
                  {"boresight_sigma_deg", {boresight_deg(0), boresight_deg(1), boresight_deg(2)}},
                  {"boresight_sigma_source",
                   std::isnan(tcfg.boresight_sigma_rpy_deg[0]) ? "error_model" : "calibration"}};
    log("grid: TPU pose sigma: " + std::to_string(out.from_slam) + " of " +
        std::to_string(out.per_ping.size()) + " pings from SLAM's posterior, the rest the INS's");
    return out;
}

// The posterior without the perturbed-start runs (slam.posterior_start_runs: 0) states less
// than the true error in a GNSS outage (docs/uncertainty.md, decisions 012 and 016): a TPU and
// an S-44 order stated from it must say so.
void GateUnvalidatedPosterior(StageContext& s, const Log& log) {
    TripGate(s,
             Stage::kGrid,
             "tpu_from_unvalidated_posterior",
             "the TPU takes SLAM's posterior pose sigma (grid.tpu_slam_posterior) computed "
             "without the perturbed-start runs (slam.posterior_start_runs: 0), which states "
             "less than the true error in a GNSS outage (docs/uncertainty.md): the THU/TVU and "
             "the S-44 order are optimistic",
             log);
}

// CUBE's input: every sounding in UTM with its height on the datum (D at its ping), its 1-sigma
// TVU and THU and its depth below the transducer (for the capture distance), handed to `sink` a
// block of the view at a time, in the survey's order (ForEachViewBlock). The TPU's pass-common
// sigmas are CUBE's alone: once in its input they are released from `tpu` (8 bytes a sounding).
Status CubeSoundingsByBlock(
    const StageContext& s,
    const georef::UtmProjection& utm,
    const std::vector<double>& datum_height_m,
    hydro::TpuResult& tpu,
    std::size_t block,
    const std::function<Status(const std::vector<hydro::CubeSounding>&)>& sink) {
    const std::vector<georef::GeorefPing>& pings = s.geo.pings;
    std::vector<hydro::CubeSounding> soundings;
    const std::int64_t t0_gps = pings.empty() ? 0 : pings.front().utime_gps;
    auto st = ForEachViewBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
        soundings.resize(b.size());
        for (std::size_t i = 0; i < b.size(); ++i) {
            const std::size_t j = first + i;
            const Eigen::Vector3d enh = utm.At(b, pings, i);
            const std::uint32_t ping = b.ping[i];
            const double depth = pings[ping].sensor_world.z() - b.position_world[i].z();
            soundings[i] = {
                enh.x(),
                enh.y(),
                enh.z() - datum_height_m[ping],
                static_cast<float>(tpu.tvu_95_m[j] / hydro::kTvu95),
                static_cast<float>(tpu.thu_95_m[j] / hydro::kThu95),
                static_cast<float>(depth),
                tpu.sigma_v_common_m[j],
                static_cast<float>(static_cast<double>(pings[ping].utime_gps - t0_gps) * 1e-6),
                tpu.sigma_h_common_m[j]};
        }
        return sink(soundings);
    });
    if (!st) return Error{"grid: " + st.error().message};
    std::vector<float>().swap(tpu.sigma_v_common_m);
    std::vector<float>().swap(tpu.sigma_h_common_m);
    return Ok{};
}

// CUBE's input held whole (CubeSoundingsByBlock), for a tile alone and the tile list.
Expected<std::vector<hydro::CubeSounding>> CubeSoundings(const StageContext& s,
                                                         const georef::UtmProjection& utm,
                                                         const std::vector<double>& datum_height_m,
                                                         hydro::TpuResult& tpu,
                                                         std::size_t block) {
    std::vector<hydro::CubeSounding> soundings;
    soundings.reserve(ViewSize(s));
    auto st = CubeSoundingsByBlock(
        s, utm, datum_height_m, tpu, block, [&](const std::vector<hydro::CubeSounding>& b) {
            soundings.insert(soundings.end(), b.begin(), b.end());
            return Status{Ok{}};
        });
    if (!st) return st.error();
    return soundings;
}

// CUBE's input on disk (CubeInputFile, decision 035): the grid stage's CUBE and surface filter
// read it by bands and blocks.
Expected<CubeInputFile> CubeInputToFile(const StageContext& s,
                                        const georef::UtmProjection& utm,
                                        const std::vector<double>& datum_height_m,
                                        hydro::TpuResult& tpu,
                                        std::size_t block) {
    auto file = CubeInputFile::Create(s.out_dir);
    if (!file) return Error{"grid: " + file.error().message};
    auto st = CubeSoundingsByBlock(
        s, utm, datum_height_m, tpu, block, [&](const std::vector<hydro::CubeSounding>& b) {
            return file->Append(b);
        });
    if (!st) return st.error();
    if (auto c = file->Close(); !c) return Error{"grid: " + c.error().message};
    return std::move(*file);
}

// The surface filter's verdicts applied to the view (RejectPoints: the model's flags, the view's
// counts; a sounding a hand edit restored stays): to the held points, or, while the view is
// spilled, a block of `block` at a time and then to its file (SpilledPoints::KeepOnly), so that
// the view is not read back whole. Returns which soundings stayed.
Expected<std::vector<char>> RejectInView(StageContext& s,
                                         const std::vector<std::uint8_t>& verdict,
                                         std::size_t block) {
    if (!s.spilled_view) return RejectPoints(s, verdict);
    survey::SoundingFlags& flags = s.model.flags;
    if (flags.cleaning.size() != s.model.ingest.pings.range_counts.size())
        flags.cleaning.assign(s.model.ingest.pings.range_counts.size(), 0);
    std::vector<char> keep(verdict.size(), 1);
    std::vector<std::uint8_t> part;
    auto st = ForEachViewBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
        const auto from = verdict.begin() + static_cast<std::ptrdiff_t>(first);
        const auto to = from + static_cast<std::ptrdiff_t>(b.size());
        if (std::all_of(from, to, [](std::uint8_t v) { return v == 0; })) return Status{Ok{}};
        part.assign(from, to);
        s.geo.points = b;  // RejectPoints reads the block as the view (its pings are the view's)
        const std::vector<char> k = RejectPoints(s, part);
        s.geo.points = georef::GeorefPoints();
        std::copy(k.begin(), k.end(), keep.begin() + static_cast<std::ptrdiff_t>(first));
        return Status{Ok{}};
    });
    if (!st) return Error{"grid: " + st.error().message};
    if (auto k = s.spilled_view->KeepOnly(keep, block); !k)
        return Error{"grid: " + k.error().message};
    // RejectPoints counted each block's points as the view's: the view's own count.
    s.geo.counts.points = static_cast<std::int64_t>(s.spilled_view->size());
    return keep;
}

// The surface filter (SurfaceFilter, its verdicts from CUBE's input a block at a time):
// soundings that do not support their node's chosen hypothesis are rejected in the survey
// (RejectInView), taken out of the TPU and CUBE's input, and CUBE runs again by bands without
// them. Returns how many.
Expected<std::int64_t> RejectOffSurface(StageContext& s,
                                        const GridStageConfig& gc,
                                        const TilesConfig& tiles,
                                        CubeInputFile& input,
                                        hydro::CubeResult& cube,
                                        hydro::TpuResult& tpu,
                                        std::size_t block,
                                        std::size_t* bands) {
    auto verdict = SurfaceVerdicts(input, cube.grid, gc, block);
    if (!verdict) return Error{"grid: " + verdict.error().message};
    auto kept_view = RejectInView(s, *verdict, block);
    if (!kept_view) return kept_view.error();
    std::vector<std::uint8_t>().swap(*verdict);
    const std::vector<char>& keep = *kept_view;
    std::int64_t rejected = 0;
    std::size_t kept = 0;
    for (std::size_t j = 0; j < keep.size(); ++j) {
        if (!keep[j]) {
            ++rejected;
            continue;
        }
        tpu.thu_95_m[kept] = tpu.thu_95_m[j];
        tpu.tvu_95_m[kept] = tpu.tvu_95_m[j];
        ++kept;
    }
    tpu.thu_95_m.resize(kept);
    tpu.tvu_95_m.resize(kept);
    if (rejected > 0) {
        // CUBE again without them: a node whose chosen hypothesis they made (an echo held
        // long enough over one node to outvote the seabed) is decided on the rest.
        auto left = input.KeepOnly(keep, block);
        if (!left) return Error{"grid: " + left.error().message};
        input = std::move(*left);
        auto again = CubeByBands(input, gc, tiles, block, bands);
        if (!again) return Error{"grid: " + again.error().message};
        cube = std::move(*again);
        if (!cube.ok) return Error{cube.message};
    }
    return rejected;
}

// dem.tif's and dem.bag's raster: the CUBE grid's bands in UTM, on the products' vertical datum,
// with the surface's provenance in its metadata.
io::GridRaster DemRaster(const StageContext& s,
                         const GridStageConfig& gc,
                         const hydro::CubeGrid& grid,
                         const georef::UtmProjection& utm,
                         const hydro::DatumModel& datum,
                         const ProductMetadata& meta) {
    io::GridRaster raster;
    raster.product = meta;
    raster.x0 = grid.x0;
    raster.y0 = grid.y0;
    raster.resolution_m = grid.resolution_m;
    raster.nx = grid.nx;
    raster.ny = grid.ny;
    raster.utm_zone = utm.zone;
    raster.northern = utm.northern;
    raster.vertical_wkt = datum.VerticalWkt();
    raster.layers = DemLayers(grid);
    raster.metadata = {
        {"pitmap_surface", "CUBE (Calder & Mayer 2003)"},
        {"pitmap_disambiguation", hydro::ToString(gc.cube.disambiguation)},
        {"pitmap_vertical_datum", datum.crs_name},
        {"pitmap_vertical_datum_description", datum.description},
        {"pitmap_uncertainty", "95 %: 1.96 x max(posterior sd, sd of the hypothesis' soundings)"},
        {"pitmap_density", "soundings in the chosen hypothesis"}};
    // The run the grid belongs to: a GeoTIFF metadata item (for the BAG, GDAL's driver keeps
    // only its own XML).
    if (!s.model.run_id.empty()) raster.metadata.emplace_back("pitmap_run_id", s.model.run_id);
    return raster;
}

// P/tiles/dem/dem_I_J.tif, the DEM's tiles (the grid tiles' cores that hold a node), and
// P/tiles/dem.vrt over them; the files go into `files`. The folder is emptied first (a coarser
// run's tiles would be left over otherwise).
Status WriteDemTiles(const std::string& dir,
                     const TilesConfig& tiles,
                     const io::GridRaster& dem,
                     const hydro::CubeGrid& grid,
                     json& files,
                     json& record) {
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::remove_all(dir + "/tiles/dem", ec);
    fs::remove(dir + "/tiles/dem.vrt", ec);
    fs::create_directories(dir + "/tiles/dem", ec);
    if (ec) return Error{dir + "/tiles/dem: " + ec.message()};
    const hydro::CubeNodeRange survey{grid.i0, grid.j0, grid.i0 + grid.nx, grid.j0 + grid.ny};
    const std::int64_t n = NodesPerTile(tiles, grid.resolution_m);
    std::vector<std::string> written;
    json list = json::array();
    for (const GridTile& tile : GridTiles(survey, n)) {
        io::GridRaster r = dem;
        r.nx = static_cast<int>(tile.core.nx());
        r.ny = static_cast<int>(tile.core.ny());
        r.x0 = static_cast<double>(tile.core.i0) * grid.resolution_m;
        r.y0 = static_cast<double>(tile.core.j0) * grid.resolution_m;
        std::int64_t filled = 0;
        for (std::size_t l = 0; l < dem.layers.size(); ++l) {
            std::vector<float>& v = r.layers[l].values;
            v.assign(static_cast<std::size_t>(r.nx) * static_cast<std::size_t>(r.ny), 0.0f);
            for (int j = 0; j < r.ny; ++j) {
                for (int i = 0; i < r.nx; ++i) {
                    const std::size_t from =
                        static_cast<std::size_t>(tile.core.j0 + j - grid.j0) * grid.nx +
                        static_cast<std::size_t>(tile.core.i0 + i - grid.i0);
                    const float x = dem.layers[l].values[from];
                    v[static_cast<std::size_t>(j) * r.nx + i] = x;
                    if (l == 0 && std::isfinite(x)) ++filled;
                }
            }
        }
        if (filled == 0) continue;
        const std::string name = "dem/dem_" + TileName(tile.index) + ".tif";
        if (auto w = io::WriteCogGeoTiff(dir + "/tiles/" + name, r); !w) return w;
        written.push_back(name);
        files.push_back("tiles/" + name);
        list.push_back({{"i", tile.index.i},
                        {"j", tile.index.j},
                        {"file", "tiles/" + name},
                        {"nodes", {r.nx, r.ny}},
                        {"nodes_filled", filled}});
    }
    if (!written.empty()) {
        if (auto w = io::WriteVrt(dir + "/tiles/dem.vrt", written); !w) return w;
        files.push_back("tiles/dem.vrt");
    }
    record["dem_tiles"] = list;
    return Ok{};
}

// dem.tif and dem.bag, as configured; each file written is added to `files`.
Status WriteDem(const std::string& dir,
                const GridStageConfig& gc,
                const io::GridRaster& raster,
                json& files) {
    if (gc.write_geotiff) {
        if (auto w = io::WriteCogGeoTiff(dir + "/dem.tif", raster); !w) return w;
        files.push_back("dem.tif");
    }
    if (gc.write_bag) {
        if (auto w = io::WriteBag(dir + "/dem.bag", raster); !w) return w;
        files.push_back("dem.bag");
    }
    return Ok{};
}

// The pit's capacity curve (issue 37 item 3), as pitmap compare finds it from dem.tif, a row
// every 0.25 m (compare's --capacity-step default): summary.json's "capacity" and the stage's
// capacity.csv, or why there is none.
void RecordCapacity(StageContext& s, json& stage, const Log& log) {
    if (auto cap = SurveyCapacity(s.out_dir, s.summary, 0.25); cap) {
        char buf[200];
        std::snprintf(buf,
                      sizeof buf,
                      "grid: capacity: %.0f m3 of water at the water level %.3f m over %.0f m2 "
                      "surveyed (capacity.csv)",
                      (*cap)["volume_at_water_level_m3"].get<double>(),
                      (*cap)["water_level_m"].get<double>(),
                      (*cap)["surveyed_area_m2"].get<double>());
        log(buf);
        stage["files"].push_back("capacity.csv");
        s.summary["capacity"] = std::move(*cap);
    } else {
        log("grid: no capacity curve: " + cap.error().message);
        s.summary["capacity"] = {{"computed", false}, {"message", cap.error().message}};
    }
}

// dem.tif and dem.bag (WriteDem) and, with tiles.enabled, the tiles' record and (with
// tiles.write_products) the DEM's tiles.
Status WriteDemProducts(const std::string& dir,
                        const PipelineConfig& config,
                        const io::GridRaster& dem,
                        const hydro::CubeGrid& grid,
                        json& files,
                        json& tiles_record) {
    if (auto w = WriteDem(dir, config.grid, dem, files); !w) return w;
    if (!config.tiles.enabled) return Ok{};
    tiles_record = {{"tile_size_m", config.tiles.tile_size_m},
                    {"overlap_m", config.tiles.overlap_m},
                    {"nodes_per_tile", NodesPerTile(config.tiles, grid.resolution_m)}};
    if (!config.tiles.write_products) return Ok{};
    return WriteDemTiles(dir, config.tiles, dem, grid, files, tiles_record);
}

// The point files with each sounding's THU and TVU (and its datum height when the datum is not
// the ellipsoid): soundings_tpu.ply, points.ply, points.las and points_utm.ply, as configured;
// each file written is added to `files`. The THU/TVU are borrowed from `tpu` and handed back.
// While the view is spilled, points.ply, points.las and points_utm.ply read it a block at a time
// (decision 035); soundings_tpu.ply (off by default) takes it back whole first.
Status WriteSoundingProducts(StageContext& s,
                             const PipelineConfig& config,
                             const georef::UtmProjection& utm,
                             const hydro::DatumModel& datum,
                             const ProductMetadata& meta,
                             hydro::TpuResult& tpu,
                             std::size_t block,
                             json& files) {
    const GridStageConfig& gc = config.grid;
    const std::string& dir = s.out_dir;
    if (gc.write_sounding_tpu) {
        if (auto st = RestoreView(s); !st) return Error{"grid: " + st.error().message};
        if (auto w = io::WriteSoundingTpuPly(
                dir + "/soundings_tpu.ply", s.geo, tpu.thu_95_m, tpu.tvu_95_m, s.model.run_id);
            !w) {
            return w;
        }
        files.push_back("soundings_tpu.ply");
    }
    if (!gc.write_point_tpu) return Ok{};
    io::PointExtras extras;  // borrows the THU/TVU (moved in, moved back after the writes)
    extras.thu_95_m = std::move(tpu.thu_95_m);
    extras.tvu_95_m = std::move(tpu.tvu_95_m);
    if (gc.vertical.datum != hydro::VerticalDatum::kEllipsoid)
        extras.datum_height_m = datum.datum_height_m;
    extras.vertical_wkt = datum.VerticalWkt();
    extras.vertical_name = datum.crs_name;
    extras.pings = &s.model.ingest.pings;
    // The rejected soundings after the accepted ones (THU/TVU NaN: not computed for them).
    std::optional<georef::GeorefResult> rejected;
    if (config.write_rejected) rejected = RejectedView(s, config);
    const georef::GeorefResult* rej = rejected ? &*rejected : nullptr;
    s.summary["soundings"] = SoundingsJson(s.geo.counts);
    const io::PointBlocks blocks = ViewPointBlocks(s, block);
    if (auto w = io::WritePly(dir + "/points.ply", s.geo, blocks, &extras, s.model.run_id, rej); !w)
        return w;
    files.push_back("points.ply");
    if (config.write_las) {
        if (auto w = io::WriteLas(
                dir + "/points.las", s.geo, blocks, utm, &extras, s.model.run_id, rej, &meta);
            !w)
            return w;
        files.push_back("points.las");
        if (config.write_points_utm) {
            if (auto w = WriteProjectedPointsOf(
                    dir,
                    s.geo.pings,
                    ViewSize(s),
                    ViewPointsReader(s, std::make_shared<georef::GeorefPoints>()),
                    utm,
                    rej,
                    datum,
                    meta,
                    s.model.run_id,
                    BlockWithinBudget(config.run, ResidentMb()));
                !w)
                return w;
            files.push_back("points_utm.ply");
        }
    }
    tpu.thu_95_m = std::move(extras.thu_95_m);
    tpu.tvu_95_m = std::move(extras.tvu_95_m);
    return Ok{};
}

// S-44's soundings of a block of the view (its first sounding the view's `first`): UTM
// positions with heights on the datum, the depth its limits take (below the water-level datum,
// else below the transducer), the beam angle, the THU/TVU and the ping indices.
void S44BlockOf(const StageContext& s,
                const georef::GeorefPoints& b,
                std::size_t first,
                const georef::UtmProjection& utm,
                const std::vector<double>& datum_height_m,
                bool water_level_datum,
                const hydro::TpuResult& tpu,
                hydro::S44Soundings& out) {
    const std::vector<georef::GeorefPing>& pings = s.geo.pings;
    const std::size_t n = b.size();
    out.x.resize(n);
    out.y.resize(n);
    out.z.resize(n);
    out.depth_m.resize(n);
    out.angle_deg.resize(n);
    out.ping.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d enh = utm.At(b, pings, i);
        const std::uint32_t ping = b.ping[i];
        out.x[i] = enh.x();
        out.y[i] = enh.y();
        out.z[i] = enh.z() - datum_height_m[ping];
        out.depth_m[i] =
            water_level_datum
                ? static_cast<float>(-out.z[i])
                : static_cast<float>(pings[ping].sensor_world.z() - b.position_world[i].z());
        out.angle_deg[i] = static_cast<float>(frames::RadToDeg(b.angle_rad[i]));
        out.ping[i] = ping;
    }
    const auto from = static_cast<std::ptrdiff_t>(first);
    const auto to = static_cast<std::ptrdiff_t>(first + n);
    out.thu_95_m.assign(tpu.thu_95_m.begin() + from, tpu.thu_95_m.begin() + to);
    out.tvu_95_m.assign(tpu.tvu_95_m.begin() + from, tpu.tvu_95_m.begin() + to);
}

// hydro::RunS44 of the view's soundings, by blocks (hydro::S44ByBlocks: two passes over the
// view, the same result bit for bit; decision 035): S-44's soundings are never whole.
Expected<hydro::S44Result> S44OfView(const StageContext& s,
                                     const hydro::S44Grid& nodes,
                                     const GridStageConfig& gc,
                                     const georef::UtmProjection& utm,
                                     const std::vector<double>& datum_height_m,
                                     const hydro::TpuResult& tpu,
                                     std::size_t block) {
    const bool water_level_datum = gc.vertical.datum == hydro::VerticalDatum::kWaterLevel;
    std::vector<double> ping_t_s, ping_yaw_rad;
    for (const auto& p : s.geo.pings) {
        ping_t_s.push_back(static_cast<double>(p.utime_gps) * 1e-6);
        const Eigen::Vector3d forward = p.T_world_vehicle.rotation() * Eigen::Vector3d::UnitX();
        ping_yaw_rad.push_back(std::atan2(forward.x(), forward.y()));
    }
    hydro::S44ByBlocks s44(nodes, gc.s44_config, std::move(ping_t_s), std::move(ping_yaw_rad));
    hydro::S44Soundings part;
    for (const bool first_pass : {true, false}) {
        auto st = ForEachViewBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
            S44BlockOf(s, b, first, utm, datum_height_m, water_level_datum, tpu, part);
            if (first_pass) {
                s44.AddFirst(part);
            } else {
                s44.AddSecond(part);
            }
            return Status{Ok{}};
        });
        if (!st) return Error{"grid: " + st.error().message};
    }
    return s44.Finish();
}

// S-44's nodes: the CUBE grid, the nodes' depth (below the datum for a water level, else below
// the transducers' median height) and CUBE's capture distance rule, from which S-44 finds the
// soundings each node was offered (its THU).
hydro::S44Grid S44NodesOf(const StageContext& s,
                          const GridStageConfig& gc,
                          const hydro::CubeGrid& grid,
                          const std::vector<double>& datum_height_m,
                          bool water_level_datum) {
    hydro::S44Grid nodes{.x0 = grid.x0,
                         .y0 = grid.y0,
                         .resolution_m = grid.resolution_m,
                         .nx = grid.nx,
                         .ny = grid.ny,
                         .elevation_m = grid.elevation_m,
                         .uncertainty_m = grid.uncertainty_m,
                         .depth_m = {},
                         .capture_depth_fraction = gc.cube.capture_distance_scale,
                         .capture_min_res = gc.cube.min_capture_distance_res,
                         .capture_max_res = gc.cube.max_capture_distance_res};
    double reference_m = 0.0;
    if (!water_level_datum) {
        const std::vector<Geodetic> ping_geo = PingGeodetic(s);
        std::vector<double> transducer_m(ping_geo.size());
        for (std::size_t k = 0; k < ping_geo.size(); ++k)
            transducer_m[k] = ping_geo[k].height_m - datum_height_m[k];
        reference_m = MedianOf(std::move(transducer_m));
    }
    nodes.depth_m.resize(grid.elevation_m.size());
    for (std::size_t q = 0; q < nodes.depth_m.size(); ++q) {
        nodes.depth_m[q] = static_cast<float>(reference_m - grid.elevation_m[q]);
    }
    return nodes;
}

// The IHO S-44 assessment (hydro::RunS44) of the soundings and the DEM: s44_holidays.tif (added
// to `files`), the crossline gate and the stage's "s44" record. The view is read a block at a
// time, twice (it stays on disk while spilled; S44OfView).
Expected<json> RunS44Survey(StageContext& s,
                            const PipelineConfig& config,
                            const io::GridRaster& dem,
                            const hydro::CubeGrid& grid,
                            const georef::UtmProjection& utm,
                            const hydro::DatumModel& datum,
                            hydro::TpuResult& tpu,
                            const json& pose_sigma,
                            const json& sound_speed,
                            const Eigen::Matrix<double, 2, 3>& utm_to_world,
                            std::size_t block,
                            json& files,
                            const Log& log) {
    const GridStageConfig& gc = config.grid;
    const bool water_level_datum = gc.vertical.datum == hydro::VerticalDatum::kWaterLevel;
    const double median_tvu_95_m = tpu.median_tvu_95_m;
    const hydro::S44Grid nodes = S44NodesOf(s, gc, grid, datum.datum_height_m, water_level_datum);
    auto s44 = S44OfView(s, nodes, gc, utm, datum.datum_height_m, tpu, block);
    if (!s44) return s44.error();
    const hydro::S44Result& r44 = *s44;
    log("grid: S-44: " + r44.message);
    io::GridRaster holidays = HolidayRaster(dem, r44);
    if (!s.model.run_id.empty()) holidays.metadata.emplace_back("pitmap_run_id", s.model.run_id);
    std::string holiday_file;
    if (gc.write_geotiff) {
        if (auto w = io::WriteCogGeoTiff(s.out_dir + "/s44_holidays.tif", holidays); !w)
            return w.error();
        holiday_file = "s44_holidays.tif";
        files.push_back(holiday_file);
    }
    json record = S44Json(r44, holiday_file, utm_to_world);
    // What the TPU behind the order took as the pose sigma (SLAM's posterior or the INS's).
    record["pose_sigma_source"] = pose_sigma["source"];
    // And where its sound speed term came from: an a-priori bound is no assessment.
    record["sound_speed_source"] = sound_speed["source"];
    if (!sound_speed.value("assessable", true)) {
        record["sound_speed_not_assessable"] =
            sound_speed["source"] == "a_priori_bound"
                ? "no sound-velocity cast in stratified water (quality gate "
                  "grid/sound_speed_not_assessable): the TVU takes the a-priori bound of a "
                  "fresh-water pit's sound speed, and the order stated rests on that bound"
                : "no sound-velocity cast and too little overlap to measure the water "
                  "column (quality gate grid/sound_speed_not_assessable): the TVU assumes "
                  "the error model's sound speed, which stratified water would exceed";
    }
    CheckCrosslines(s, r44, median_tvu_95_m, config.quality, log);
    return record;
}

// The stage's record of the TPU: where its error model came from, its medians and what makes
// up the vertical variance, the clock and pose sigmas it took.
json TpuJson(const TpuSetup& setup, const PoseSigmas& pose, const hydro::TpuResult& tpu) {
    json shares = json::object();
    for (int t = 0; t < hydro::kNumTpuTerms; ++t) {
        shares[hydro::ToString(static_cast<hydro::TpuTerm>(t))] = tpu.tvu_variance_share[t];
    }
    return {{"error_model", setup.model_source},
            {"median_tvu_95_m", tpu.median_tvu_95_m},
            {"median_thu_95_m", tpu.median_thu_95_m},
            {"tvu_variance_share", shares},
            {"clock_sigma_s", setup.config.clock_sigma_s},
            {"pose_sigma", pose.record}};
}

// The stage's record of the CUBE surface: its grid and what CUBE did.
json CubeJson(const hydro::CubeResult& cube, const GridStageConfig& gc) {
    const hydro::CubeGrid& g = cube.grid;
    return {{"resolution_m", g.resolution_m},
            {"median_depth_m", cube.median_depth_m},
            {"capture_distance_m", cube.capture_distance_m},
            {"nx", g.nx},
            {"ny", g.ny},
            {"x0_m", g.x0},
            {"y0_m", g.y0},
            {"disambiguation", hydro::ToString(gc.cube.disambiguation)},
            {"nodes_filled", cube.nodes_filled},
            {"nodes_multiple_hypotheses", cube.nodes_multiple},
            {"hypotheses", cube.hypotheses_total},
            {"node_updates", cube.node_updates},
            {"soundings_rejected", cube.soundings_rejected},
            {"message", cube.message}};
}

// What CUBE reads, computed over the whole survey as the grid stage does before CUBE: the TPU
// (its setup, the pose sigmas, the sound speed term), the UTM positions, the datum, and the CUBE
// soundings in the survey's order.
struct CubeInputs {
    std::optional<TpuSetup> setup;
    PoseSigmas pose;
    json sound_speed;
    hydro::TpuResult tpu;
    std::optional<georef::UtmProjection> utm;
    std::optional<hydro::DatumModel> datum;
    json datum_record;
    std::vector<hydro::CubeSounding> soundings;
    std::size_t block = 0;  // soundings a block of the view (BlockWithinBudget)
};

// The view is read a block at a time (ForEachViewBlock): while it is spilled, only CUBE's input
// and the TPU are held whole.
// `whole_input` false: CUBE's input is left to the caller (the grid stage writes it to a file,
// CubeInputToFile), in.soundings empty.
Expected<CubeInputs> PrepareCube(StageContext& s,
                                 const PipelineConfig& config,
                                 PartClock& part,
                                 json& timings,
                                 const Log& log,
                                 bool whole_input = true) {
    const GridStageConfig& gc = config.grid;
    CubeInputs in;
    auto tpu_setup = SurveyTpuSetup(s, gc, log);
    if (!tpu_setup) return tpu_setup.error();
    in.setup = *tpu_setup;
    if (ViewSize(s) == 0) return Error{"grid: no soundings to grid"};
    in.block = BlockWithinBudget(config.run, ResidentMb());
    in.pose = TpuPoseSigmas(s, gc, tpu_setup->config, log);
    if (in.pose.from_slam > 0 && config.slam.posterior_start_runs == 0) {
        GateUnvalidatedPosterior(s, log);
    }
    in.sound_speed = {{"source", "error_model"}};
    if (gc.tpu_sound_speed_from_data) {
        auto sound_speed = SoundSpeedSigmas(
            s, gc, tpu_setup->sv_source, in.pose.per_ping, tpu_setup->config, in.block, log);
        if (!sound_speed) return sound_speed.error();
        in.sound_speed = std::move(*sound_speed);
        part.Lap(timings, "sound_speed");
    }
    hydro::TpuByBlocks tpu(
        s.geo.pings, s.model.mount, in.pose.per_ping, tpu_setup->config, ViewSize(s));
    auto read =
        ForEachViewBlock(s, in.block, [&](const georef::GeorefPoints& b, std::size_t first) {
            tpu.Add(b, first);
            return Status{Ok{}};
        });
    if (!read) return Error{"grid: " + read.error().message};
    in.tpu = tpu.Finish();
    log("grid: TPU (" + tpu_setup->model_source + "): " + in.tpu.message);
    part.Lap(timings, "tpu");
    // The soundings' UTM positions are not held (24 bytes a sounding): each part places those
    // it reads (georef::UtmProjection, the same figures bit for bit).
    auto utm = georef::UtmProjectionOf(s.geo);
    if (!utm) return Error{"grid: UTM: " + utm.error().message};
    in.utm = std::move(*utm);
    auto datum = SurveyDatum(s, config, &in.datum_record, log);
    if (!datum) return datum.error();
    in.datum = *datum;
    if (!whole_input) return in;
    auto soundings = CubeSoundings(s, *in.utm, in.datum->datum_height_m, in.tpu, in.block);
    if (!soundings) return soundings.error();
    in.soundings = std::move(*soundings);
    part.Lap(timings, "utm_datum");
    return in;
}

// The grid stage's CUBE surface and its surface filter.
struct SurfaceOutcome {
    hydro::CubeResult cube;
    std::int64_t rejected = 0;  // soundings the surface filter rejected
    std::size_t bands = 0;      // CUBE's bands of node rows (the last pass)
};

// CUBE's input written to its scratch file from the view's blocks (the part "utm_datum"), CUBE
// by bands of node rows (CubeByBands: node for node RunCube's), then the surface filter
// (RejectOffSurface) and CUBE again without what it rejected (decision 035). The file is
// removed before this returns.
Expected<SurfaceOutcome> CubeAndSurfaceFilter(StageContext& s,
                                              const PipelineConfig& config,
                                              CubeInputs& in,
                                              PartClock& part,
                                              json& timings,
                                              const Log& log) {
    const GridStageConfig& gc = config.grid;
    auto input = CubeInputToFile(s, *in.utm, in.datum->datum_height_m, in.tpu, in.block);
    if (!input) return input.error();
    part.Lap(timings, "utm_datum");
    SurfaceOutcome out;
    auto cube = CubeByBands(*input, gc, config.tiles, in.block, &out.bands);
    if (!cube) return Error{"grid: " + cube.error().message};
    if (!cube->ok) return Error{cube->message};
    out.cube = std::move(*cube);
    part.Lap(timings, "cube");
    // The surface filter: soundings that do not support the node's chosen hypothesis are
    // rejected, for the point files, S-44, the mosaic and the TSDF after this stage.
    if (gc.surface_filter) {
        auto rejected =
            RejectOffSurface(s, gc, config.tiles, *input, out.cube, in.tpu, in.block, &out.bands);
        if (!rejected) return rejected.error();
        out.rejected = *rejected;
        log("grid: surface filter: " + std::to_string(out.rejected) +
            " soundings off the CUBE surface rejected");
        part.Lap(timings, "surface_filter");
    }
    log("grid: CUBE " + std::string(hydro::ToString(gc.cube.disambiguation)) + ": " +
        out.cube.message + " (" + std::to_string(out.bands) + " bands of node rows)");
    return out;
}

}  // namespace

Expected<SurveyCubeInput> CubeInputOf(StageContext& s,
                                      const PipelineConfig& config,
                                      const Log& log) {
    StageClock clock;
    PartClock part(clock);
    json timings = json::object();
    auto in = PrepareCube(s, config, part, timings, log);
    if (!in) return in.error();
    return SurveyCubeInput{std::move(in->soundings), std::move(in->datum_record), in->utm->epsg};
}

// The soundings' TPU, then the CUBE surface on the products' datum (with the surface filter's
// second pass), the DEM and point files, S-44 and the backscatter mosaic. Each part's wall and
// CPU time go into the record (PartClock).
Status GridSurvey(StageContext& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    ClearGates(s, Stage::kGrid);
    const GridStageConfig& gc = config.grid;
    PartClock part(clock);
    json timings = json::object();
    // The view's points wait on disk (decisions 020, 031) while the TPU, CUBE's input and the
    // surface filter's verdicts read them a block at a time, and CUBE and the filter read CUBE's
    // input alone; they come back for the point files, S-44 and the mosaic.
    if (auto st = SpillView(s); !st) return Error{"grid: " + st.error().message};
    auto in = PrepareCube(s, config, part, timings, log, /*whole_input=*/false);
    if (!in) return in.error();
    const std::optional<TpuSetup>& tpu_setup = in->setup;
    const PoseSigmas& pose = in->pose;
    const json& sound_speed = in->sound_speed;
    hydro::TpuResult& tpu = in->tpu;
    std::optional<georef::UtmProjection>& utm = in->utm;
    std::optional<hydro::DatumModel>& datum = in->datum;
    const json& datum_record = in->datum_record;
    auto surface = CubeAndSurfaceFilter(s, config, *in, part, timings, log);
    if (!surface) {
        if (auto st = RestoreView(s); !st) return Error{"grid: " + st.error().message};
        return surface.error();
    }
    const hydro::CubeResult& cube = surface->cube;
    const std::int64_t surface_rejected = surface->rejected;

    const ProductMetadata meta = SurveyProductMetadata(s, config, &*datum);
    s.datum = *datum;
    const io::GridRaster dem = DemRaster(s, gc, cube.grid, *utm, *datum, meta);
    // S-44 reads the view a block at a time while it is still on disk (decision 031).
    auto utm_to_world = UtmToWorldOf(s, *utm);
    if (!utm_to_world) return utm_to_world.error();
    json s44_record, s44_files = json::array();
    if (gc.s44) {
        auto s44 = RunS44Survey(s,
                                config,
                                dem,
                                cube.grid,
                                *utm,
                                *datum,
                                tpu,
                                pose.record,
                                sound_speed,
                                *utm_to_world,
                                in->block,
                                s44_files,
                                log);
        if (!s44) return s44.error();
        s44_record = std::move(*s44);
        part.Lap(timings, "s44");
    }
    // The mosaic and the point files read the view a block at a time too (decision 035).
    json mosaic_record;
    if (gc.mosaic) {
        auto mosaic = detail::MosaicSurvey(s, gc, dem, *utm, *utm_to_world, log, in->block);
        if (!mosaic) return mosaic.error();
        mosaic_record = std::move(*mosaic);
        part.Lap(timings, "mosaic");
    }
    json files = json::array();
    json tiles_record = json::object();
    if (auto w = WriteDemProducts(s.out_dir, config, dem, cube.grid, files, tiles_record); !w)
        return w;
    if (auto w = WriteSoundingProducts(s, config, *utm, *datum, meta, tpu, in->block, files); !w)
        return w;
    part.Lap(timings, "write");
    for (const auto& f : s44_files) files.push_back(f);

    // The stage's record: the TPU's, S-44's, the mosaic's and the terrain's, then the surface's.
    json stage = TpuJson(*tpu_setup, pose, tpu);
    std::vector<float>().swap(tpu.thu_95_m);  // their last reader was the point files
    std::vector<float>().swap(tpu.tvu_95_m);
    stage["sound_speed"] = sound_speed;
    if (gc.s44) stage["s44"] = std::move(s44_record);
    if (gc.mosaic) {
        if (mosaic_record.contains("file")) files.push_back(mosaic_record["file"]);
        stage["mosaic"] = std::move(mosaic_record);
    }
    if (gc.terrain) {
        auto terrain = detail::TerrainSurvey(s, gc, dem, log);
        if (!terrain) return terrain.error();
        for (const auto& f : (*terrain)["files"]) files.push_back(f);
        stage["terrain"] = std::move(*terrain);
        part.Lap(timings, "terrain");
    }
    stage.update(CubeJson(cube, gc));
    stage["soundings"] = ViewSize(s);
    stage["utm_epsg"] = utm->epsg;
    stage["vertical_crs"] = datum->crs_name;
    stage["surface_filter_rejected"] = surface_rejected;
    stage["cube_bands"] = surface->bands;
    if (config.tiles.enabled) stage["tiles"] = tiles_record;
    stage["files"] = files;
    stage["timings_wall_cpu_s"] = timings;
    stage["peak_rss_mb_by_part"] = part.peak_rss_mb;
    s.summary["vertical_datum"] = datum_record;
    RecordCapacity(s, stage, log);
    // The view stays in its file: the stages after this one read it there by blocks (the TSDF,
    // decision 034; the point writers, 041). Restored here it was held whole only to be spilled
    // again (bejanca 4x: the stage's peak, 1 322 MB; decision 047).
    log("grid: " + Fixed(cube.grid.resolution_m, 2) + " m, " + std::to_string(cube.nodes_filled) +
        " nodes; " + files.dump());
    RecordStage(s.summary, Stage::kGrid, stage, clock);
    return SaveSummary(s);
}

// `pitmap grid --tile I,J`: one DEM tile alone (docs/tiles.md). What CUBE reads is computed
// over the whole survey as the grid stage does (PrepareCube: linear in the soundings); CUBE runs
// on the tile only. With the surface filter, its first pass covers the core grown by every node
// whose verdict a sounding of the tile's second pass needs (the overlap, a predicted-surface
// cell, the node nearest the sounding and its four neighbours), each node as the whole run's
// (RunCubeTile); the soundings it rejects are left out of the second pass, which grids the core.
// The tile's lattice and resolution are the first pass's layout (the soundings before the
// filter). Writes P/tiles/dem/dem_I_J.tif and its record dem_I_J.json; the survey model and
// summary.json are not written (tile jobs run side by side on P).
Status GridTileAlone(StageContext& s,
                     const PipelineConfig& config,
                     TileIndex index,
                     const Log& log) {
    const GridStageConfig& gc = config.grid;
    const TilesConfig& tiles = config.tiles;
    StageClock clock;
    PartClock part(clock);
    json timings = json::object();
    auto in = PrepareCube(s, config, part, timings, log);
    if (!in) return in.error();
    std::vector<hydro::CubeSounding>& snd = in->soundings;
    const hydro::CubeResult layout = hydro::LayOutCube(snd, gc.cube);
    if (!layout.ok) return Error{layout.message};
    const hydro::CubeGrid& g = layout.grid;
    const double res = g.resolution_m;
    if (const auto problems = ValidateGridTiles(tiles, res, gc.cube); !problems.empty()) {
        std::string text = "grid: " + problems.front();
        for (std::size_t k = 1; k < problems.size(); ++k) text += "; " + problems[k];
        return Error{text};
    }
    const hydro::CubeNodeRange survey{g.i0, g.j0, g.i0 + g.nx, g.j0 + g.ny};
    const std::int64_t n = NodesPerTile(tiles, res);
    const std::vector<GridTile> all = GridTiles(survey, n);
    const auto it =
        std::find_if(all.begin(), all.end(), [&](const GridTile& t) { return t.index == index; });
    if (it == all.end()) {
        return Error{"grid --tile " + TileName(index) + ": the survey has no such tile (" +
                     std::to_string(all.size()) + " tiles of " + std::to_string(n) +
                     " nodes; from " + TileName(all.front().index) + " to " +
                     TileName(all.back().index) + ")"};
    }
    const hydro::CubeNodeRange core = it->core;
    hydro::CubeConfig cube = gc.cube;
    cube.resolution_m = res;
    std::int64_t rejected = 0;
    if (gc.surface_filter) {
        const std::int64_t grow = static_cast<std::int64_t>(std::ceil(tiles.overlap_m / res)) +
                                  2 * static_cast<std::int64_t>(cube.predicted_surface_cells) + 2;
        const hydro::CubeNodeRange reach{std::max(survey.i0, core.i0 - grow),
                                         std::max(survey.j0, core.j0 - grow),
                                         std::min(survey.i1, core.i1 + grow),
                                         std::min(survey.j1, core.j1 + grow)};
        const hydro::CubeResult first =
            hydro::RunCubeTile(snd, cube, reach, survey, tiles.overlap_m);
        if (!first.ok) return Error{"grid: tile " + TileName(index) + ": " + first.message};
        const std::vector<char> keep = RejectPoints(s, SurfaceFilter(snd, first.grid, gc));
        std::size_t k = 0;
        for (std::size_t j = 0; j < keep.size(); ++j) {
            if (keep[j]) snd[k++] = snd[j];
        }
        rejected = static_cast<std::int64_t>(snd.size() - k);
        snd.resize(k);
        part.Lap(timings, "surface_filter");
    }
    const hydro::CubeResult t = hydro::RunCubeTile(snd, cube, core, survey, tiles.overlap_m);
    if (!t.ok) return Error{"grid: tile " + TileName(index) + ": " + t.message};
    part.Lap(timings, "cube");

    const ProductMetadata meta = SurveyProductMetadata(s, config, &*in->datum);
    const io::GridRaster raster = DemRaster(s, gc, t.grid, *in->utm, *in->datum, meta);
    std::error_code ec;
    std::filesystem::create_directories(s.out_dir + "/tiles/dem", ec);
    if (ec) return Error{s.out_dir + "/tiles/dem: " + ec.message()};
    const std::string name = "tiles/dem/dem_" + TileName(index);
    if (auto w = io::WriteCogGeoTiff(s.out_dir + "/" + name + ".tif", raster); !w) return w;
    part.Lap(timings, "write");
    const json record = {{"i", index.i},
                         {"j", index.j},
                         {"file", name + ".tif"},
                         {"resolution_m", res},
                         {"nodes_per_tile", n},
                         {"overlap_m", tiles.overlap_m},
                         {"nx", t.grid.nx},
                         {"ny", t.grid.ny},
                         {"x0_m", t.grid.x0},
                         {"y0_m", t.grid.y0},
                         {"nodes_filled", t.nodes_filled},
                         {"soundings_used", t.soundings_used},
                         {"surface_filter_rejected", rejected},
                         {"utm_epsg", in->utm->epsg},
                         {"wall_s", clock.seconds()},
                         {"cpu_s", clock.cpu_seconds()},
                         {"peak_rss_mb", clock.peak_rss_mb()},
                         {"timings_wall_cpu_s", timings}};
    const std::string json_path = s.out_dir + "/" + name + ".json";
    if (auto w = formats::WriteReplacing(json_path,
                                         [&](const std::string& partial) -> Status {
                                             std::ofstream f(partial);
                                             f << record.dump(1) << "\n";
                                             if (!f) return Error{partial + ": cannot write"};
                                             return Ok{};
                                         });
        !w)
        return w;
    log("grid: tile " + TileName(index) + ": " + std::to_string(t.nodes_filled) + " of " +
        std::to_string(t.grid.nx * t.grid.ny) + " nodes filled, " + std::to_string(rejected) +
        " soundings off the surface; " + name + ".tif");
    return Ok{};
}

// `pitmap grid --list-tiles`: the survey's DEM tiles (the lattice over CUBE's layout of the
// soundings before the surface filter, as GridTileAlone lays it out).
Expected<std::vector<TileIndex>> ListGridTiles(StageContext& s,
                                               const PipelineConfig& config,
                                               const Log& log) {
    StageClock clock;
    PartClock part(clock);
    json timings = json::object();
    auto in = PrepareCube(s, config, part, timings, log);
    if (!in) return in.error();
    const hydro::CubeResult layout = hydro::LayOutCube(in->soundings, config.grid.cube);
    if (!layout.ok) return Error{layout.message};
    const hydro::CubeGrid& g = layout.grid;
    std::vector<TileIndex> out;
    for (const GridTile& t : GridTiles({g.i0, g.j0, g.i0 + g.nx, g.j0 + g.ny},
                                       NodesPerTile(config.tiles, g.resolution_m))) {
        out.push_back(t.index);
    }
    return out;
}

// `pitmap grid --merge-tiles`: P/tiles/dem.vrt over the DEM tiles in P/tiles/dem (those of
// grid --tile), in name order, named relative to the VRT.
Status MergeGridTiles(const std::string& out_dir, const Log& log) {
    std::vector<std::string> files;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(out_dir + "/tiles/dem", ec)) {
        if (e.path().extension() == ".tif") files.push_back("dem/" + e.path().filename().string());
    }
    if (ec || files.empty()) {
        return Error{"grid --merge-tiles: no DEM tiles in " + out_dir +
                     "/tiles/dem (run grid --tile I,J first)"};
    }
    std::sort(files.begin(), files.end());
    if (auto w = io::WriteVrt(out_dir + "/tiles/dem.vrt", files); !w) return w;
    log("grid: tiles/dem.vrt over " + std::to_string(files.size()) + " DEM tiles");
    return Ok{};
}

}  // namespace detail

Status RunMergeGridTiles(const std::string& out_dir, const PipelineConfig&, const Log& log) {
    return detail::MergeGridTiles(out_dir, log);
}

Status RunGridTile(const std::string& out_dir,
                   const PipelineConfig& config,
                   TileIndex tile,
                   const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kLatest, log);
    if (!s) return s.error();
    return detail::GridTileAlone(*s, config, tile, log);
}

Status RunGridStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    // Every part of the grid stage reads the view by blocks from its file (decisions 031, 035).
    auto s =
        detail::LoadSurveyReplacing(out_dir, config, detail::StartFrom::kLatest, Stage::kGrid, log);
    if (!s) return s.error();
    return detail::GridSurvey(*s, config, log);
}

}  // namespace pitmap::proc::pipeline
