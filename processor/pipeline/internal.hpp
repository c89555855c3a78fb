// SPDX-License-Identifier: MIT
// Internal to processor/pipeline: the stage context (the survey being processed, as the stages
// pass it along) and what the stage implementations share (summary bookkeeping, per-stage time
// and memory).
#pragma once

#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "common/vehicle.hpp"

#include "processor/fusion/tsdf.hpp"
#include "processor/georef/georef.hpp"
#include "processor/georef/georef_blocks.hpp"
#include "processor/georef/mount_check.hpp"
#include "processor/georef/survey_view.hpp"
#include "processor/hydro/datum.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/ingest.hpp"
#include "processor/io/products.hpp"
#include "processor/io/view_spill.hpp"
#include "processor/mesh/export.hpp"
#include "processor/pipeline/pipeline.hpp"
#include "processor/survey/survey.hpp"

namespace pitmap::proc::pipeline::detail {

// The stage context, one survey being processed: the model the stages share (processor/survey:
// saved as P/survey.pitmap, the only state a stage command loads), the georeferenced view the
// stages work on, and summary.json, the report each stage adds its record to (never read to
// decide).
struct StageContext {
    std::string out_dir;
    survey::SurveyModel model;
    georef::GeorefResult geo;  // the model's soundings on its newest trajectory
    nlohmann::json summary;
    std::shared_ptr<const svp::Refraction> refraction;  // the model's casts; null = straight rays
    // The vehicle file as read by georef (the coarse sonar clock search needs its antennas).
    std::optional<VehicleDescription> vehicle;
    // `run`: the stages leave points.ply/las, boresight.json and survey.pitmap to one export at
    // the end (ExportSurvey), so that each product is written once. Stage commands write their
    // products themselves.
    bool defer_products = false;
    // The products' vertical datum, once the grid stage (or the mesh stage) built it.
    std::optional<hydro::DatumModel> datum;
    // geo.points while a stage that does not read them runs (SpillView, RestoreView; decision
    // 020): on disk in P, geo.points empty meanwhile.
    std::optional<io::SpilledPoints> spilled_view;
};

// Moves the view's points (s.geo.points) to a scratch file in P until RestoreView: a stage that
// reads only what it built from them (SLAM's slices, the TSDF's scans) then runs without their
// 38 bytes a sounding. An error (P not writable, the disk full) leaves the view held.
Status SpillView(StageContext& s);
// Reads the spilled points back (bit for bit) into s.geo.points; nothing when none are spilled.
Status RestoreView(StageContext& s);
// Makes a view with `sink` (georef::RunGeorefByBlocks or GeoreferenceByBlocks handing it its
// blocks) and returns its result without points.
using ViewMaker = std::function<georef::GeorefResult(const georef::GeorefBlockSink& sink)>;
// A ViewMaker of the model's soundings of status `which` on its newest trajectory
// (georef::GeoreferenceByBlocks in blocks within the run's memory budget; `kept` as there). `s`
// and `config` must outlive it.
ViewMaker ModelViewMaker(const StageContext& s,
                         const PipelineConfig& config,
                         survey::SoundingView which,
                         std::size_t* kept = nullptr);
// s.geo made by `make` with its points written to the view's file a block at a time: the view
// is never held, s.spilled_view holds it at the end (an earlier view is dropped first). A
// folder where the file cannot be made holds the view (a warning); a write that fails midway
// (the disk full) is an error naming the file. `with_status`: the blocks carry each sounding's
// status (a view of other soundings than the accepted ones), kept in the file.
Status ViewToFile(StageContext& s, const ViewMaker& make, const Log& log, bool with_status = false);
// ViewToFile of georef::RunGeorefByBlocks: the model's ingested pings on their current times,
// its mount, flags and s.refraction (`origin` nullopt = the first navigation sample; decision
// 033). `check` (optional) sees every block.
Status GeoreferenceToFile(StageContext& s,
                          const PipelineConfig& config,
                          std::optional<Geodetic> origin,
                          georef::MountCheckByBlocks* check,
                          const ProgressCallback& progress,
                          const Log& log);

// Refraction for a new georeference: the config's casts (none: straight rays) with the INS
// height above the water line from the config, else from the vehicle file; sets the model's
// record and summary["refraction"]. An unreadable or bad cast file, or no INS height, is an
// error.
Status SetUpRefraction(StageContext& s,
                       const PipelineConfig& config,
                       std::optional<double> vehicle_ins_height_m,
                       const Log& log);

// The products (file names in P) a stage command replaces: removed before it runs, with those
// of the stages that depend on its output (calibrate and slam: every later product; fuse: the
// meshes) and report.html, so that a stage that fails or is killed half-way leaves no product
// of the previous state beside the new one. kGeoref: every product of the folder, the survey
// file and summary.json included (AllProducts). kReport: the report only.
std::vector<std::string> ProductsReplacedBy(Stage stage);
// Every product a pitmap command writes in P (not P/.pitmap.lock, not scores.json).
std::vector<std::string> AllProducts();
// Removes `names` (files or folders) from P and any *.partial file a killed writer left; an
// error names what could not be removed and why.
Status RemoveProducts(const std::string& out_dir, const std::vector<std::string>& names);
// RemoveProducts's two halves, for a stage that makes scratch files of its own in P while it
// loads (the view in its file, decision 041): what a killed writer left goes before the load,
// the products it replaces only once the load has succeeded (a survey that cannot be loaded
// keeps its products).
void RemoveStalePartials(const std::string& out_dir);
Status RemoveNamedProducts(const std::string& out_dir, const std::vector<std::string>& names);

// The run id check of a product: "" when `product_run_id` is this survey's run id (or the
// survey has none, written before run ids), else why it does not belong
// ("P/tsdf.vdb is from another run (id X; survey.pitmap has Y)").
std::string ForeignProduct(const StageContext& s,
                           const std::string& file,
                           const std::string& product_run_id);

// What a stage command starts from.
enum class StartFrom {
    kLatest,      // the newest trajectory (fuse, grid)
    kNominal,     // the state before any calibration (calibrate)
    kBeforeSlam,  // the calibrated trajectory, an earlier SLAM's dropped (slam)
};
// Where a stage command's view is made: held (s.geo.points), or written to its scratch file a
// block of pings at a time for a stage that reads it there (s.spilled_view; decision 041).
enum class ViewIn { kMemory, kFile };
// Loads P/survey.pitmap (and P/summary.json, to add to the report; a missing or unreadable one,
// or one of another run than survey.pitmap (its run_id differs), starts a new report with a
// warning), moves the model to `start` and georeferences it once (the view `view`: a folder
// where the file cannot be made holds it, a warning).
Expected<StageContext> LoadSurvey(const std::string& out_dir,
                                  const PipelineConfig& config,
                                  StartFrom start,
                                  const Log& log,
                                  ViewIn view = ViewIn::kMemory);
// A stage command's survey (calibrate, slam, clean, grid, fuse, rerun): what a killed writer
// left is removed first (the view's file is such a scratch file, decision 041), the survey is
// loaded from `start` with its view made in its file by blocks of pings (ViewIn::kFile, never
// held whole), and only then are the products `stage` replaces removed: a survey that cannot
// be loaded keeps them.
Expected<StageContext> LoadSurveyReplacing(const std::string& out_dir,
                                           const PipelineConfig& config,
                                           StartFrom start,
                                           Stage stage,
                                           const Log& log);
// Saves the model (P/survey.pitmap) and summary.json.
Status SaveSurvey(const StageContext& s);
// points.ply, points.las (unless `points` is false: the grid stage writes them with THU/TVU)
// and boresight.json of the current view, then SaveSurvey.
Status ExportSurvey(StageContext& s, const PipelineConfig& config, bool points = true);

// Wall time of one stage. Construction resets the resident-memory high-water mark
// (common/peak_memory.hpp ResetPeakRss), so RecordStage's peak_rss_mb (PeakRssMb) is the
// stage's own peak where the kernel allows it and the process's peak so far otherwise.
// cpu_seconds() is the process's user + system CPU time since construction (all threads): on a
// machine shared with other work it stays near what the stage costs, where wall time does not.
class StageClock {
public:
    StageClock();
    double seconds() const;
    double cpu_seconds() const;
    // Resets the resident high-water mark inside the stage (to measure one part of it) and
    // keeps the stage's peak so far, so that peak_rss_mb is still the whole stage's.
    void ResetPeakWithinStage();
    // The stage's peak resident memory so far, MB.
    double peak_rss_mb() const;

private:
    std::chrono::steady_clock::time_point start_;
    double cpu_start_s_;
    double peak_before_reset_mb_ = 0;
};

// Records a stage in summary["stages"][name] (adding seconds, cpu_seconds and peak_rss_mb) and
// in summary["stage_order"].
void RecordStage(nlohmann::json& summary,
                 Stage name,
                 nlohmann::json stage,
                 const StageClock& clock);

// summary["memory"]: the run's memory budget and block size (RunOptions), which RecordStage
// compares each stage's peak with (over it: the quality gate STAGE/memory_budget).
void SetMemoryBudget(nlohmann::json& summary, const RunOptions& run);

using survey::MountJson;

// points.ply, points.las (when configured, both with the run id) and summary["utm"] for the
// current soundings; `rejected` (optional): the rejected soundings of the same view
// (RejectedView), written after them; `pings` (optional): the pings they came from, for their
// 83P intensities (io::PointExtras::pings).
Status WritePoints(const std::string& dir,
                   const georef::GeorefResult& geo,
                   const PipelineConfig& c,
                   nlohmann::json& summary,
                   const std::string& run_id,
                   const georef::GeorefResult* rejected = nullptr,
                   const survey::PingSeries* pings = nullptr,
                   const ProductMetadata* meta = nullptr);
// The same for the survey: its soundings (s.geo) and, with products.write_rejected, the
// rejected ones of the model's newest trajectory; sets summary["soundings"] (SoundingsJson) and
// summary["metadata"] (ellipsoidal heights: the grid stage writes the points again in the
// vertical datum).
Status WritePoints(StageContext& s, const PipelineConfig& c);

// The rejected soundings of the survey's current view (survey::SoundingView::kRejected on the
// model's newest trajectory, with s.refraction): what the point files carry beside s.geo.
georef::GeorefResult RejectedView(const StageContext& s, const PipelineConfig& c);

// summary.json's "soundings": {total, accepted, rejected: {reason: count}, pings, not_placed}
// from georef's counts: per status (every status's name, 0 included; total: the soundings of
// the georeferenced pings, no detection included); pings: {in, georeferenced, left_out:
// {outside_nav, nav_gap, bad_header}}, the pings georef could not place and why; not_placed:
// the beams of those pings (in no total, no product).
nlohmann::json SoundingsJson(const georef::GeorefCounts& counts);

// summary.json of P for the survey `model`: the file when it is readable and of the same run,
// else a new report {run_id} with a warning saying why.
nlohmann::json LoadSummaryOfRun(const std::string& out_dir,
                                const survey::SurveyModel& model,
                                const Log& log);

Status SaveSummary(const StageContext& s);

// Quality gates (QualityConfig): a stage that cannot explain its data says so in the terminal
// ("quality gate STAGE/GATE: ...") and in summary["quality_gates"] [{stage, gate, message}];
// the report lists them. A stage clears its own before it runs again.
void TripGate(StageContext& s,
              Stage stage,
              const std::string& gate,
              const std::string& message,
              const Log& log);
void ClearGates(StageContext& s, Stage stage);

// The sonar clock after ingest: for .83P pings (topside clock) the coarse offset from the
// header aids is found and applied, or a configured offset is checked against it; then the
// navigation and sonar spans must overlap. summary["sonar_clock"] records what was done.
Status ClockSurvey(StageContext& s, const PipelineConfig& config, const Log& log);

// The stages on a survey in memory (bodies of the Run*Stage functions and of RunAll).
Status GeorefSurvey(StageContext& s,
                    const std::vector<std::string>& inputs,
                    const PipelineConfig& config,
                    const Log& log);
Status CalibrateSurvey(StageContext& s, const PipelineConfig& config, const Log& log);
Status SlamSurvey(StageContext& s, const PipelineConfig& config, const Log& log);
// The automatic cleaning (clean_stage.cpp): flags in the model, the view keeps the accepted.
// With max_ins_sigma_h_m finite, the pings whose INS horizontal 1-sigma exceeds it (a GNSS
// outage's drift) are neither judged nor evidence against the others: their soundings keep
// being accepted (run's first pass, before SLAM has put the drifted passes back).
Status CleanSurvey(StageContext& s,
                   const PipelineConfig& config,
                   const Log& log,
                   double max_ins_sigma_h_m = std::numeric_limits<double>::infinity());
// The index of point j of `geo` in the survey's range counts.
std::size_t FlatIndex(const georef::GeorefResult& geo,
                      const survey::PingSeries& pings,
                      std::size_t j);
// Keeps the points with keep[j] != 0 (in order); the pings stay.
void KeepPoints(georef::GeorefPoints& P, const std::vector<char>& keep);
// The points of s.geo with status[j] != 0 (a cleaning status) are rejected: recorded in the
// model's flags.cleaning and taken out of the view (its counts follow), except those a hand
// edit restored. Returns which points stayed (index = the point before).
std::vector<char> RejectPoints(StageContext& s, const std::vector<std::uint8_t>& status);
// The products' vertical datum (config.grid.vertical, hydro/datum.hpp) at every ping of s.geo
// (the grid stage's; the mesh stage's georeferenced files use it too). Fails as the grid stage
// would (no geoid grid, no INS height above the water line, a water-level file that does not
// cover the survey).
Expected<hydro::DatumModel> SurveyDatum(const StageContext& s,
                                        const PipelineConfig& config,
                                        nlohmann::json* record,
                                        const Log& log);
// The products' metadata (metadata.hpp) of this survey: the config's section, the vehicle file's
// equipment, the first and last ping, the UTM zone of the world origin and `datum` (nullptr =
// ellipsoidal heights); also sets summary["metadata"] to it.
ProductMetadata SurveyProductMetadata(StageContext& s,
                                      const PipelineConfig& config,
                                      const hydro::DatumModel* datum);
// points_utm.ply and points_utm.prj (projected_products.cpp): the soundings (and the rejected
// ones after them) in the products' CRS, heights h - D of `datum` at their ping; `utm` places
// the soundings of `geo` (georef::UtmProjectionOf) a block of `block_soundings` at a time.
Status WriteProjectedPoints(const std::string& dir,
                            const georef::GeorefResult& geo,
                            const georef::UtmProjection& utm,
                            const georef::GeorefResult* rejected,
                            const hydro::DatumModel& datum,
                            const ProductMetadata& meta,
                            const std::string& run_id,
                            std::size_t block_soundings);
// Where the accepted soundings first .. first + count - 1 are for points_utm.ply: `points` and
// the index `offset` of the first in them (the held view itself, or a block read from its
// scratch file into a buffer the reader keeps).
using AcceptedPointsReader = std::function<Status(std::size_t first,
                                                  std::size_t count,
                                                  const georef::GeorefPoints*& points,
                                                  std::size_t& offset)>;
// WriteProjectedPoints with the accepted soundings read a block at a time (`num_accepted` of
// them, of `pings`): the same files byte for byte (decision 035).
Status WriteProjectedPointsOf(const std::string& dir,
                              const std::vector<georef::GeorefPing>& pings,
                              std::size_t num_accepted,
                              const AcceptedPointsReader& read_accepted,
                              const georef::UtmProjection& utm,
                              const georef::GeorefResult* rejected,
                              const hydro::DatumModel& datum,
                              const ProductMetadata& meta,
                              const std::string& run_id,
                              std::size_t block_soundings);
// The view's soundings: on disk while spilled (SpillView), else held.
std::size_t ViewSize(const StageContext& s);
// Calls fn(block, first) on the view's soundings a block of `block` at a time, in order: read
// from the scratch file while the view is spilled (decisions 031, 041: the view is then never
// whole in memory), else copied from the held points. Stops at the first error.
Status ForEachViewBlock(const StageContext& s,
                        std::size_t block,
                        const std::function<Status(const georef::GeorefPoints&, std::size_t)>& fn);
// The view's accepted soundings for the point writers (io::PointBlocks), a block of `block` at
// a time: each block lent to s.geo.points while a writer reads it (s.geo then is the survey
// with the block's soundings), or the held view in one block.
io::PointBlocks ViewPointBlocks(StageContext& s, std::size_t block);
// points_utm.ply's accepted soundings: the held view, or its blocks read from the scratch file
// into `buffer`.
AcceptedPointsReader ViewPointsReader(const StageContext& s,
                                      std::shared_ptr<georef::GeorefPoints> buffer);
// A mesh's vertices (world ENU at `origin`) in the products' CRS: UTM in the origin's zone
// (exact, GeographicLib, per vertex), heights in `datum`'s vertical CRS (the geoid at each
// vertex; a water level's mean over the survey).
Expected<mesh::ProjectedMesh> ProjectMesh(const mesh::ColouredMesh& m,
                                          const Geodetic& origin,
                                          const hydro::DatumModel& datum,
                                          const PipelineConfig& config);
// Per-sounding TPU and the CUBE surface (grid_stage.hpp).
Status GridSurvey(StageContext& s, const PipelineConfig& config, const Log& log);
// One DEM tile alone, the survey's DEM tiles, the VRT over the tiles written (grid_stage.cpp;
// RunGridTile, ListTiles, RunMergeGridTiles).
Status GridTileAlone(StageContext& s,
                     const PipelineConfig& config,
                     TileIndex index,
                     const Log& log);
Expected<std::vector<TileIndex>> ListGridTiles(StageContext& s,
                                               const PipelineConfig& config,
                                               const Log& log);
Status MergeGridTiles(const std::string& out_dir, const Log& log);
// CUBE's input as the grid stage makes it from the survey's current soundings (the TPU with its
// pose and sound speed sigmas, UTM, the products' vertical datum), and the datum's record as
// summary.json's vertical_datum: `pitmap compare` grids a survey again at another resolution
// from it (compare_stage.cpp). The model and summary are not saved.
struct SurveyCubeInput {
    std::vector<hydro::CubeSounding> soundings;
    nlohmann::json datum_record;
    int utm_epsg = 0;  // the soundings' UTM zone
};
Expected<SurveyCubeInput> CubeInputOf(StageContext& s,
                                      const PipelineConfig& config,
                                      const Log& log);
// The grid stage's backscatter mosaic (mosaic_stage.cpp): P/mosaic.tif on the DEM's grid and
// its summary record; {"made": false, "reason"} when the pings carry no intensities. `utm`
// places the soundings of s.geo in UTM (georef::UtmProjectionOf), `utm_to_world` is the affine
// map of UTM into the world frame. The view is read `block` soundings at a time (0: at once),
// from its scratch file while spilled (decision 035).
Expected<nlohmann::json> MosaicSurvey(const StageContext& s,
                                      const GridStageConfig& gc,
                                      const io::GridRaster& dem,
                                      const georef::UtmProjection& utm,
                                      const Eigen::Matrix<double, 2, 3>& utm_to_world,
                                      const Log& log,
                                      std::size_t block = 0);
// v with `digits` decimals ("%.*f"), for log lines and product metadata.
std::string Fixed(double v, int digits);
// The grid stage's mine-planning layers (terrain_stage.cpp, hydro/terrain.hpp): P/terrain.tif
// and P/crawler.tif on the DEM's grid, and their summary record (areas by class, the launch).
Expected<nlohmann::json> TerrainSurvey(const StageContext& s,
                                       const GridStageConfig& gc,
                                       const io::GridRaster& dem,
                                       const Log& log);
// Integrates the pings on the current trajectory, applies the weight filter; `stage` is kFuse,
// or kFuseInitial for the mesh before SLAM.
// One TSDF tile alone and the merge of the tiles (stages3d.cpp; RunFuseTile, RunMergeFuseTiles).
Status FuseTile(StageContext& s, const PipelineConfig& config, TileIndex tile, const Log& log);
Status MergeFuseTiles(StageContext& s, const PipelineConfig& config, const Log& log);
Expected<std::vector<TileIndex>> ListFuseTiles(StageContext& s, const PipelineConfig& config);
// What FuseSurvey does with the view's points once its scans are built (the integration reads
// the scans alone): kSpilled, SpillView (a later stage calls RestoreView); kReleased, freed (the
// caller reads them no more).
enum class ViewAfterScans { kSpilled, kReleased };
Expected<fusion::TsdfVolume> FuseSurvey(StageContext& s,
                                        const PipelineConfig& config,
                                        Stage stage,
                                        ViewAfterScans view,
                                        const Log& log);
// Meshes a volume; kMesh writes mesh.* and mesh_filled.*, kMeshInitial only mesh_initial.ply.
Status MeshSurvey(StageContext& s,
                  const fusion::TsdfVolume& volume,
                  const PipelineConfig& config,
                  Stage stage,
                  const Log& log);
Status ReportSurvey(StageContext& s, const PipelineConfig& config, const Log& log);

}  // namespace pitmap::proc::pipeline::detail
