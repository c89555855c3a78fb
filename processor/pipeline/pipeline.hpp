// SPDX-License-Identifier: MIT
// Composition of the stages on a products folder P (the `pitmap` subcommands). The state the
// stages share is the survey model (processor/survey), saved as P/survey.pitmap; every other
// file in P is a product, and summary.json is a report no stage reads to decide what to do.
//   georef:    inputs -> ingest -> sonar clock -> georef -> survey.pitmap (trajectory version
//              "ins"), points.ply, points.las, trajectory_ins.csv (the INS at its own rate, with
//              velocity and status), boresight.json (the mount used), summary.json
//   calibrate: survey.pitmap from its nominal state -> boresight (and latency) calibration ->
//              survey.pitmap (version "calibrated"), boresight.json, points.ply, points.las
//   slam:      survey.pitmap (the calibrated trajectory) -> continuous-time SLAM ->
//              survey.pitmap (version "slam"), trajectory_initial.csv and points_initial.ply
//              (per ping, before), trajectory.csv, points.ply, points.las (after)
//   fuse:      the pings on the newest trajectory -> TSDF -> weight filter -> P/tsdf.vdb
//   grid:      the soundings on the newest trajectory -> per-sounding TPU -> CUBE surface ->
//              P/dem.tif (COG), dem.bag (grid_stage.hpp)
//   mesh:      P/tsdf.vdb -> P/mesh.{ply,obj,glb}, mesh_filled.{ply,obj,glb}
//   report:    P -> P/report.html (the pitmap-report program beside the pitmap executable)
//   run:       all of the above in memory (georef, calibrate, SLAM, grid, fuse, mesh, report;
//              calibrate, SLAM, grid and the report optional), plus P/mesh_initial.ply (the mesh
//              before SLAM) for the report. The survey is georeferenced once (again only where
//              the calibration changes the ping times) and each product is written once:
//              points, boresight.json and survey.pitmap by one export after the last stage
//              that changes the survey (summary.json stage "export").
// Refraction: with casts (config refraction.svp_files, `--svp FILE...`) georef ray-traces
// every beam (processor/svp/refraction.hpp); the survey model records the casts and settings,
// and the later stages trace again with them.
// Trajectory files (common/formats/trajectory_csv.hpp) each have one meaning: trajectory_ins.csv
// the INS rate, trajectory_initial.csv and trajectory.csv one pose per ping before and after
// SLAM (absent when no SLAM ran).
// summary.json: world_origin {latitude_deg, longitude_deg, height_m}, utm {zone, northern, epsg},
// time {gps_minus_utc_s, gps_minus_utc_source, leap_second_table_valid_until,
// first/last_ping_gps_s, first/last_ping_utc}, inputs, mount, sonar_clock, stages -> name ->
// {seconds, peak_rss_mb, counts...}, stage_order, quality_gates, and after `run` total_seconds.
// peak_rss_mb is the process's resident-memory high-water mark during the stage (reset at each
// stage start where the kernel allows it).
#pragma once

#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/calib/boresight.hpp"
#include "processor/clean/clean.hpp"
#include "processor/fusion/tsdf.hpp"
#include "processor/georef/georef.hpp"
#include "processor/io/ingest.hpp"
#include "processor/mesh/surface.hpp"
#include "processor/pipeline/grid_stage.hpp"
#include "processor/pipeline/metadata.hpp"
#include "processor/pipeline/tiles.hpp"
#include "processor/slam/slam.hpp"
#include "processor/svp/refraction.hpp"

namespace pitmap::proc::pipeline {

// Which optional stages `pitmap run` performs.
struct RunOptions {
    bool calibrate = true;         // boresight calibration before SLAM
    bool slam = true;              // continuous-time SLAM (else the INS trajectory is fused)
    bool mesh_before_slam = true;  // also mesh the survey before SLAM (mesh_initial.ply, report)
    // The mesh before SLAM is a picture for the report: its voxels are this many times the
    // final ones (2 = an eighth of the voxels), and it gets no hole filling.
    double initial_mesh_voxel_factor = 2.0;
    // ... and it is fused from every n-th ping: at twice the voxel size the pings (0.15 m
    // apart at 1.5 m/s and 10 Hz) are still closer than the voxels, and the gap between the
    // kept ones is bridged like the full spacing (fuse.ping_gap_fill_m times the stride).
    int initial_mesh_ping_stride = 2;
    bool report = true;  // report.html through pitmap-report
    // Equipment models for the report's 3D view (pitmap-report --equipment: a YAML list of
    // .glb files placed by UTM position and heading); "" = none.
    std::string report_equipment;
    // The memory a run may hold, MB (issue 38, docs/decisions/018-memory-budget.md): the
    // block-wise parts of the stages hold one block of block_soundings soundings at a time, and
    // each stage's peak resident memory is compared with it (summary.json "memory", quality gate
    // STAGE/memory_budget when a stage exceeds it).
    double memory_budget_mb = 4096;
    // Soundings per block of the block-wise parts (the UTM point files, ...); one block at
    // kBlockBytesPerSounding bytes a sounding must fit in the budget.
    int block_soundings = 1 << 20;

    std::vector<std::string> Validate() const;
};
// The most a block-wise part holds per sounding of its block, bytes (a point of points_utm.ply
// as it is made: 32 bytes; the rest is margin for the parts to come).
inline constexpr double kBlockBytesPerSounding = 64;
// The smallest block a block-wise part works in (a ping of the widest sonar).
inline constexpr std::size_t kMinBlockSoundings = 1024;
// The block a block-wise part uses when the process holds `resident_mb` already: the
// configured run.block_soundings, or fewer soundings when one block at kBlockBytesPerSounding
// would take the process over run.memory_budget_mb (the budget enforced: the part works in
// smaller blocks instead), never under kMinBlockSoundings (a process over its budget already
// works in those, and the stage's gate says so).
std::size_t BlockWithinBudget(const RunOptions& run, double resident_mb);

// Quality gates: where a stage says that it cannot explain its data (summary.json
// "quality_gates", the terminal and the report; `pitmap ... --strict` exits non-zero on any).
struct QualityConfig {
    double calibration_residual_ratio = 1.5;  // residual RMS after calibration / range noise's
    double max_clock_scan_s = 5.0;            // widest sonar-clock uncertainty the data may resolve
    double clock_disagreement_s = 0.05;       // configured vs found clock offset, beyond 3 sigma
    double slam_sigma_multiple = 3.0;         // SLAM may move a ping this many INS sigmas ...
    double slam_min_allowance_m = 0.05;       // ... or this far, whichever is larger
    double slam_good_ins_sigma_m = 0.10;      // pings whose INS horizontal sigma is below: "good"
    double slam_max_fraction = 0.05;          // more good pings moved further trips the gate
    double slam_drift_window_s = 30.0;        // ... and per window: most moved = drift gate
    // The passes' plane-fit consistency after SLAM / what the range noise leaves (calibrate's
    // range noise model over the soundings): above, the soundings disagree in a way SLAM did
    // not explain (the demo: 1.4; the demo with its sonar clock 1.5 s off: 15.7).
    double slam_consistency_ratio = 3.0;
    double max_outside_nav_fraction = 0.01;  // pings outside the navigation span
    // A calibration that turns the nominal mount further than this (deg, any axis) is absorbing
    // a wrong input (lever arm sign, connector, clock): an error naming it, not a result.
    double max_boresight_change_deg = 5.0;
    // The cleaning rejecting more than this share of the soundings is not cleaning echoes but
    // absorbing a disagreement of the swaths (a gate naming the likely inputs).
    double max_cleaned_share = 0.05;
    // Crossline RMS / what the soundings' median TVU predicts for a difference of two
    // soundings (sqrt(2) TVU95 / 1.96): above, the lines disagree beyond their stated
    // uncertainty (grid gate naming the likely input).
    double crossline_tvu_ratio = 3.0;
    // Georef checks the mount against the data (georef/mount_check.hpp): soundings that follow
    // the vehicle's roll or pitch are an error naming sonar.mount.
    bool check_mount = true;

    std::vector<std::string> Validate() const;
};

// SLAM stage settings beyond slam::SlamConfig.
struct SlamStageConfig {
    int point_stride = 1;          // every n-th kept sounding of a ping goes into its slice
    double sigma_max_age_s = 5.0;  // INS stddev records further from a ping are not used
    // INS 1-sigma used where the logs carry none: roll, pitch, yaw (deg), east, north, up (m).
    double fallback_attitude_deg[3] = {0.02, 0.02, 0.05};
    double fallback_position_m[3] = {0.02, 0.02, 0.03};
    // The posterior's reference takes the INS's slow horizontal error as the GNSS fixes in the
    // ping headers state it, where larger than the INS reports (calib::EstimateInsSlowError,
    // docs/decisions/027); false = the INS's own steady sigma.
    bool ins_slow_error_from_fixes = false;
};

struct PipelineConfig {
    io::IngestConfig ingest;
    georef::GeorefConfig georef;
    svp::RefractionConfig refraction;  // sound-velocity casts; none = straight rays
    calib::BoresightConfig calibrate;
    slam::SlamConfig slam;
    SlamStageConfig slam_stage;
    clean::CleanConfig clean;
    fusion::TsdfConfig tsdf;
    fusion::WeightFilterConfig weight_filter;
    mesh::MeshConfig mesh;
    RunOptions run;
    QualityConfig quality;
    GridStageConfig grid;  // the `grid:` section (grid_stage.hpp)
    TilesConfig tiles;     // the `tiles:` section (tiles.hpp): grid and fuse by tiles
    // The report program (pitmap-report); set by the command line, "" = no report.
    std::string report_program;
    // World origin; NaN = the first INS position.
    double origin_latitude_deg = std::numeric_limits<double>::quiet_NaN();
    double origin_longitude_deg = std::numeric_limits<double>::quiet_NaN();
    double origin_height_m = std::numeric_limits<double>::quiet_NaN();
    bool write_las = true;  // points.las (UTM) beside points.ply
    // points_utm.ply (+ .prj) beside points.las: the soundings as absolute UTM doubles for PLY
    // readers (docs/georeferencing.md); about 33 bytes a sounding.
    bool write_points_utm = true;
    // points.ply/las also hold the rejected soundings (after the accepted ones, with their
    // status; io/products.hpp); false = the accepted soundings only.
    bool write_rejected = true;
    std::string vehicle_yaml;       // "" = vehicle.yaml beside the first log
    SurveyMetadataConfig metadata;  // the `metadata:` section (metadata.hpp)

    std::vector<std::string> Validate() const;
};

// Reads a YAML config (sections ingest, georef, calibrate, slam, fuse, mesh, run, quality,
// products, metadata; the key table in config.cpp); every problem listed: unknown keys, wrong
// types, invalid values.
Expected<PipelineConfig> LoadConfig(const std::string& path);
// The YAML of every default, with a comment per key (`pitmap config --defaults`).
std::string DefaultsYaml();
// `config` as YAML that LoadConfig reads back to the same values (DefaultsYaml's body).
std::string ConfigYaml(const PipelineConfig& config);

// The YAML spellings of the stages' enums.
const char* ToString(slam::CorrespondenceType t);
const char* ToString(slam::RobustKernel k);
const char* ToString(fusion::SensorModel m);

// The stages, as summary.json names them (ToString: stages.<name>, stage_order,
// quality_gates[].stage); `run` performs them in this order.
enum class Stage {
    kIngest,
    kGeoref,
    kExport,
    kCalibrate,
    kSlam,
    kClean,
    kGrid,
    kFuseInitial,
    kMeshInitial,
    kFuse,
    kMesh,
    kReport,
};
const char* ToString(Stage s);

using Log = std::function<void(const std::string&)>;

// `info`: a text report of the inputs (files, channels, counts, time spans).
Expected<std::string> Info(const std::vector<std::string>& inputs, const PipelineConfig& config);
Status RunGeorefStage(const std::vector<std::string>& inputs,
                      const std::string& out_dir,
                      const PipelineConfig& config,
                      const Log& log);
Status RunCalibrateStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
Status RunSlamStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
// `clean`: the automatic cleaning (processor/clean) on the newest trajectory; points.ply/las
// again, the later products removed.
Status RunCleanStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
// `rerun`: the stages after georef again on P/survey.pitmap (after hand edits or a new config):
// calibrate, SLAM, clean, grid, fuse, mesh, report as `run` does them, without reading the
// inputs again.
Status RunFromSurvey(const std::string& out_dir, const PipelineConfig& config, const Log& log);
Status RunGridStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
// `pitmap grid --tile I,J`: one DEM tile alone on P's survey (tiles.hpp, docs/tiles.md):
// P/tiles/dem/dem_I_J.tif (node for node the whole run's) and its record dem_I_J.json; a
// campaign's per-tile job. Fails naming a tile the survey does not have.
Status RunGridTile(const std::string& out_dir,
                   const PipelineConfig& config,
                   TileIndex tile,
                   const Log& log);
// `pitmap grid --merge-tiles`: P/tiles/dem.vrt over the DEM tiles of grid --tile.
Status RunMergeGridTiles(const std::string& out_dir, const PipelineConfig& config, const Log& log);
// `pitmap grid --list-tiles` (stage kGrid) and `pitmap fuse --list-tiles` (kFuse): every tile
// of the survey's DEM or TSDF lattice, for a campaign's per-tile jobs (some may be empty).
Expected<std::vector<TileIndex>> ListTiles(const std::string& out_dir,
                                           const PipelineConfig& config,
                                           Stage stage,
                                           const Log& log);
Status RunFuseStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
// `pitmap fuse --tile I,J`: one TSDF tile alone on P's survey (tiles.hpp): P/tiles/tsdf/
// tsdf_I_J.vdb (the core's voxels before the weight filter), P/tiles/mesh/mesh_I_J.glb and its
// index entry mesh_I_J.json; a campaign's per-tile job. Fails naming a tile the survey does not
// have.
Status RunFuseTile(const std::string& out_dir,
                   const PipelineConfig& config,
                   TileIndex tile,
                   const Log& log);
// `pitmap fuse --merge-tiles`: the tiles' cores as the survey's volume, filtered and written as
// P/tsdf.vdb (the fuse stage's record), and P/tiles/mesh/index.json from the tiles' entries.
Status RunMergeFuseTiles(const std::string& out_dir, const PipelineConfig& config, const Log& log);
Status RunMeshStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
Status RunReportStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);
// Every stage from the logs to the report, in memory; products and summary.json are written
// after each stage, so a failure leaves what was done.
Status RunAll(const std::vector<std::string>& inputs,
              const std::string& out_dir,
              const PipelineConfig& config,
              const Log& log);

}  // namespace pitmap::proc::pipeline
