// SPDX-License-Identifier: MIT
// The `grid` stage (grid_stage.hpp): its configuration and its run on a survey in memory.
#include "processor/pipeline/grid_stage.hpp"

#include <time.h>
#include <algorithm>

#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <type_traits>

#include "common/frames.hpp"
#include "common/vehicle.hpp"
#include "processor/hydro/tpu.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/survey.hpp"

namespace pitmap::proc::pipeline {

namespace {

using nlohmann::json;

// Wall and process CPU seconds of the parts of the stage (CPU time says what a part costs when
// other processes share the cores).
struct PartClock {
    std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
    double cpu = Cpu();
    static double Cpu() {
        timespec ts{};
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
        return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
    }
    // Records the part that ends now as name -> [wall s, CPU s].
    void Lap(nlohmann::json& out, const char* name) {
        const auto now = std::chrono::steady_clock::now();
        const double c = Cpu();
        out[name] = {std::chrono::duration<double>(now - wall).count(), c - cpu};
        wall = now;
        cpu = c;
    }
};

std::string Fixed(double v, int digits) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
}

// The error model: the vehicle file's `uncertainty:` (the file georef used), else defaults.
SensorErrorModel ErrorModel(const std::string& path, const Log& log, std::string* source) {
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
    return v->ErrorModel();
}

}  // namespace

std::vector<std::string> GridStageConfig::Validate() const {
    std::vector<std::string> out = cube.Validate();
    if (!(tpu_sound_speed_mps >= 1300 && tpu_sound_speed_mps <= 1700)) {
        out.push_back("grid.tpu_sound_speed_mps must be within 1300..1700");
    }
    if (!(ins_sigma_max_age_s > 0)) out.push_back("grid.ins_sigma_max_age_s must be > 0");
    return out;
}

namespace detail {

Status GridSurvey(Survey& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    const GridStageConfig& gc = config.grid;
    std::string model_source;
    hydro::TpuConfig tcfg;
    tcfg.model = ErrorModel(s.model.vehicle_yaml, log, &model_source);
    tcfg.sound_speed_mps = gc.tpu_sound_speed_mps;
    tcfg.num_threads = gc.cube.num_threads;
    tcfg.clock_sigma_s = std::abs(s.model.clock.sigma_s());
    if (auto p = tcfg.Validate(); !p.empty()) {
        return Error{"grid: invalid sensor error model (" + model_source + "):\n" +
                     FormatProblems(p)};
    }
    if (s.geo.points.size() == 0) return Error{"grid: no soundings to grid"};

    PartClock part;
    json timings = json::object();
    const SensorErrorModel& m = tcfg.model;
    PoseSigma fallback;
    fallback << frames::DegToRad(m.roll_pitch_sigma_deg), frames::DegToRad(m.roll_pitch_sigma_deg),
        frames::DegToRad(m.heading_sigma_deg), m.position_sigma_h_m, m.position_sigma_h_m,
        m.position_sigma_v_m;
    std::vector<hydro::PingSigma> sig(s.geo.pings.size());
    for (std::size_t k = 0; k < sig.size(); ++k) {
        const PoseSigma p = PoseSigmaAt(
            s.model.ingest.nav, s.geo.pings[k].utime_gps, gc.ins_sigma_max_age_s, fallback);
        sig[k].attitude_rpy_rad = p.head<3>();
        sig[k].position_enu_m = p.tail<3>();
    }
    const hydro::TpuResult tpu = hydro::ComputeTpu(s.geo, s.model.mount, sig, tcfg);
    log("grid: TPU (" + model_source + "): " + tpu.message);
    part.Lap(timings, "tpu");

    auto utm = georef::ToUtm(s.geo);
    if (!utm) return Error{"grid: UTM: " + utm.error().message};
    std::vector<hydro::CubeSounding> snd(s.geo.points.size());
    for (std::size_t j = 0; j < snd.size(); ++j) {
        const Eigen::Vector3d& e = utm->easting_northing_height[j];
        const double depth =
            s.geo.pings[s.geo.points.ping[j]].sensor_world.z() - s.geo.points.position_world[j].z();
        snd[j] = {e.x(),
                  e.y(),
                  e.z(),
                  static_cast<float>(tpu.tvu_95_m[j] / hydro::kTvu95),
                  static_cast<float>(tpu.thu_95_m[j] / hydro::kThu95),
                  static_cast<float>(depth)};
    }
    part.Lap(timings, "utm");
    const hydro::CubeResult cube = hydro::RunCube(snd, gc.cube);
    part.Lap(timings, "cube");
    if (!cube.ok) return Error{cube.message};
    log("grid: CUBE " + std::string(hydro::ToString(gc.cube.disambiguation)) + ": " + cube.message);

    const hydro::CubeGrid& g = cube.grid;
    io::GridRaster raster;
    raster.x0 = g.x0;
    raster.y0 = g.y0;
    raster.resolution_m = g.resolution_m;
    raster.nx = g.nx;
    raster.ny = g.ny;
    raster.utm_zone = utm->zone;
    raster.northern = utm->northern;
    raster.layers = {{"elevation", "metre", g.elevation_m},
                     {"uncertainty", "metre", g.uncertainty_m},
                     {"density", "", g.density},
                     {"hypotheses", "", g.hypotheses}};
    raster.metadata = {
        {"pitmap_surface", "CUBE (Calder & Mayer 2003)"},
        {"pitmap_disambiguation", hydro::ToString(gc.cube.disambiguation)},
        {"pitmap_vertical_datum", "WGS 84 ellipsoidal height"},
        {"pitmap_uncertainty", "95 %: 1.96 x max(posterior sd, sd of the hypothesis' soundings)"},
        {"pitmap_density", "soundings in the chosen hypothesis"}};
    const std::string& P = s.out_dir;
    json files = json::array();
    if (gc.write_geotiff) {
        if (auto w = io::WriteCogGeoTiff(P + "/dem.tif", raster); !w) return w;
        files.push_back("dem.tif");
    }
    if (gc.write_bag) {
        if (auto w = io::WriteBag(P + "/dem.bag", raster); !w) return w;
        files.push_back("dem.bag");
    }
    if (gc.write_sounding_tpu) {
        if (auto w = io::WriteSoundingTpuPly(
                P + "/soundings_tpu.ply", s.geo, tpu.thu_95_m, tpu.tvu_95_m);
            !w) {
            return w;
        }
        files.push_back("soundings_tpu.ply");
    }
    part.Lap(timings, "write");
    json shares = json::object();
    for (int t = 0; t < hydro::kNumTpuTerms; ++t) {
        shares[hydro::ToString(static_cast<hydro::TpuTerm>(t))] = tpu.tvu_variance_share[t];
    }
    const json st = {{"error_model", model_source},
                     {"soundings", s.geo.points.size()},
                     {"median_tvu_95_m", tpu.median_tvu_95_m},
                     {"median_thu_95_m", tpu.median_thu_95_m},
                     {"tvu_variance_share", shares},
                     {"clock_sigma_s", tcfg.clock_sigma_s},
                     {"resolution_m", g.resolution_m},
                     {"median_depth_m", cube.median_depth_m},
                     {"capture_distance_m", cube.capture_distance_m},
                     {"nx", g.nx},
                     {"ny", g.ny},
                     {"x0_m", g.x0},
                     {"y0_m", g.y0},
                     {"utm_epsg", utm->epsg},
                     {"vertical_crs", "WGS 84 ellipsoidal height"},
                     {"disambiguation", hydro::ToString(gc.cube.disambiguation)},
                     {"nodes_filled", cube.nodes_filled},
                     {"nodes_multiple_hypotheses", cube.nodes_multiple},
                     {"hypotheses", cube.hypotheses_total},
                     {"node_updates", cube.node_updates},
                     {"soundings_rejected", cube.soundings_rejected},
                     {"files", files},
                     {"timings_wall_cpu_s", timings},
                     {"message", cube.message}};
    log("grid: " + Fixed(g.resolution_m, 2) + " m, " + std::to_string(cube.nodes_filled) +
        " nodes; " + files.dump());
    RecordStage(s.summary, Stage::kGrid, st, clock);
    return SaveSummary(s);
}

}  // namespace detail

Status RunGridStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kLatest, log);
    if (!s) return s.error();
    return detail::GridSurvey(*s, config, log);
}

}  // namespace pitmap::proc::pipeline
