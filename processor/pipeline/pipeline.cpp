// SPDX-License-Identifier: MIT
#include "processor/pipeline/pipeline.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "common/config.hpp"
#include "common/formats/replace_file.hpp"
#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/peak_memory.hpp"
#include "common/progress.hpp"
#include "processor/calib/sonar_clock.hpp"
#include "processor/georef/mount_check.hpp"
#include "processor/io/products.hpp"
#include "processor/io/svp_files.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/result_json.hpp"
#include "processor/survey/edit_log.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// "edits: N soundings rejected and M restored by hand (P/edits.json)".
std::string EditsText(const std::vector<std::uint8_t>& manual) {
    std::size_t rejected = 0, restored = 0;
    for (const std::uint8_t m : manual) {
        rejected += m == static_cast<std::uint8_t>(survey::ManualEdit::kReject);
        restored += m == static_cast<std::uint8_t>(survey::ManualEdit::kRestore);
    }
    return "edits: " + std::to_string(rejected) + " soundings rejected and " +
           std::to_string(restored) + " restored by hand (" + survey::kEditLogFileName + ")";
}

// summary["time"]: GPS - UTC for the survey (the receiver's TIME log when it logged one, else
// common/gps_time's leap-second table) and the pings' span in both scales. The report turns GPS
// seconds into UTC with it, so the table exists once (in C++).
json TimeJson(const survey::IngestedSeries& ing) {
    const std::int64_t t0 = ing.pings.pings.front().utime_gps;
    const std::int64_t t1 = ing.pings.pings.back().utime_gps;
    const bool receiver = ing.nav.leap_seconds >= 0;
    const int leap = receiver ? ing.nav.leap_seconds : LeapSecondsAtGps(t0);
    return {{"gps_minus_utc_s", leap},
            {"gps_minus_utc_source", receiver ? "receiver TIME log" : "built-in leap-second table"},
            {"leap_second_table_valid_until", LeapSecondTableValidUntil()},
            {"first_ping_gps_s", static_cast<double>(t0) * 1e-6},
            {"last_ping_gps_s", static_cast<double>(t1) * 1e-6},
            {"first_ping_utc", FormatUnixIso8601(UnixFromGps(t0, leap))},
            {"last_ping_utc", FormatUnixIso8601(UnixFromGps(t1, leap))}};
}

// The vehicle file: products.vehicle_yaml (--vehicle), else vehicle.yaml beside the first
// input, else "" (io::VehicleFilePath, shared with pitmap live).
std::string VehicleFilePath(const std::vector<std::string>& files, const PipelineConfig& config) {
    return io::VehicleFilePath(files, config.vehicle_yaml);
}

// What the vehicle file sets for ingest where the config and command line left it unset:
// the channels and the sonar clock offset.
void ApplyVehicle(const VehicleDescription& v, io::IngestConfig& icfg) {
    if (icfg.nav_channel_id.empty()) icfg.nav_channel_id = v.navigation_channel;
    if (icfg.sonar_channel_id.empty()) icfg.sonar_channel_id = v.sonar_channel;
    if (!icfg.sonar_clock_offset_known && v.sonar_clock_offset_s) {
        icfg.sonar_clock_offset_s = *v.sonar_clock_offset_s;
        icfg.sonar_clock_offset_known = true;
    }
}

}  // namespace

namespace detail {

std::string Fixed(double v, int digits) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
}

namespace {

double ProcessCpuSeconds() {
    struct rusage u {};
    if (::getrusage(RUSAGE_SELF, &u) != 0) return 0.0;
    auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + t.tv_usec * 1e-6; };
    return s(u.ru_utime) + s(u.ru_stime);
}

}  // namespace

StageClock::StageClock()
    : start_(std::chrono::steady_clock::now()), cpu_start_s_(ProcessCpuSeconds()) {
    // The stage's own peak, not the previous stage's retained memory (where the kernel allows).
    ResetPeakRss();
}

double StageClock::cpu_seconds() const {
    return ProcessCpuSeconds() - cpu_start_s_;
}

void StageClock::ResetPeakWithinStage() {
    peak_before_reset_mb_ = peak_rss_mb();
    ResetPeakRss();
}

double StageClock::peak_rss_mb() const {
    return std::max(peak_before_reset_mb_, PeakRssMb());
}

double StageClock::seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void RecordStage(json& summary, Stage stage_id, json stage, const StageClock& clock) {
    const std::string name = ToString(stage_id);
    stage["seconds"] = clock.seconds();
    stage["cpu_seconds"] = clock.cpu_seconds();
    stage["peak_rss_mb"] = clock.peak_rss_mb();
    const double budget_mb = summary.contains("memory") && summary["memory"].is_object()
                                 ? summary["memory"].value("budget_mb", 0.0)
                                 : 0.0;
    if (budget_mb > 0 && clock.peak_rss_mb() > budget_mb) {
        // The quality gate STAGE/memory_budget (as TripGate's; ClearGates clears it when the
        // stage runs again).
        if (!summary.contains("quality_gates") || !summary["quality_gates"].is_array())
            summary["quality_gates"] = json::array();
        summary["quality_gates"].push_back(
            {{"stage", name},
             {"gate", "memory_budget"},
             {"message",
              "peak resident memory " + Fixed(clock.peak_rss_mb(), 0) +
                  " MB is over run.memory_budget_mb (" + Fixed(budget_mb, 0) + " MB)"}});
    }
    summary["stages"][name] = std::move(stage);
    json order = json::array();
    if (summary.contains("stage_order") && summary["stage_order"].is_array()) {
        for (const auto& n : summary["stage_order"]) {
            if (n.is_string() && n.get<std::string>() != name) order.push_back(n);
        }
    }
    order.push_back(name);
    summary["stage_order"] = std::move(order);
}

void SetMemoryBudget(json& summary, const RunOptions& run) {
    summary["memory"] = {{"budget_mb", run.memory_budget_mb},
                         {"block_soundings", run.block_soundings}};
}

namespace {

// WritePoints with the accepted soundings from `accepted` for points.ply and points.las and
// `read_accepted` for points_utm.ply (held, or read a block at a time from the view's file:
// decision 041); geo's pings and origin are read, not its points.
Status WritePointsOf(const std::string& dir,
                     const georef::GeorefResult& geo,
                     const io::PointBlocks& accepted,
                     const AcceptedPointsReader& read_accepted,
                     const PipelineConfig& c,
                     json& summary,
                     const std::string& run_id,
                     const georef::GeorefResult* rejected,
                     const survey::PingSeries* pings,
                     const ProductMetadata* meta) {
    io::PointExtras extras;  // the 83P intensities only: no TPU or datum before the grid stage
    extras.pings = pings;
    if (auto s = io::WritePly(dir + "/points.ply", geo, accepted, &extras, run_id, rejected); !s)
        return s;
    // The soundings are placed in UTM where the files are written (24 bytes a sounding less).
    auto utm = georef::UtmProjectionOf(geo);
    if (!utm) return Error{"UTM: " + utm.error().message};
    summary["utm"] = {{"zone", utm->zone}, {"northern", utm->northern}, {"epsg", utm->epsg}};
    if (c.write_las) {
        if (auto s = io::WriteLas(
                dir + "/points.las", geo, accepted, *utm, &extras, run_id, rejected, meta);
            !s)
            return s;
        // Heights above the ellipsoid here: the grid stage writes them again in the datum.
        if (!c.write_points_utm) return Ok{};
        if (auto s = WriteProjectedPointsOf(dir,
                                            geo.pings,
                                            accepted.count,
                                            read_accepted,
                                            *utm,
                                            rejected,
                                            hydro::DatumModel{},
                                            meta != nullptr ? *meta : ProductMetadata{},
                                            run_id,
                                            BlockWithinBudget(c.run, ResidentMb()));
            !s)
            return s;
    }
    return Ok{};
}

// The held points as points_utm.ply reads them (one block: the points themselves).
AcceptedPointsReader HeldPointsReader(const georef::GeorefPoints& points) {
    return
        [&points](
            std::size_t first, std::size_t, const georef::GeorefPoints*& out, std::size_t& offset) {
            out = &points;
            offset = first;
            return Status{Ok{}};
        };
}

}  // namespace

Status WritePoints(const std::string& dir,
                   const georef::GeorefResult& geo,
                   const PipelineConfig& c,
                   json& summary,
                   const std::string& run_id,
                   const georef::GeorefResult* rejected,
                   const survey::PingSeries* pings,
                   const ProductMetadata* meta) {
    return WritePointsOf(dir,
                         geo,
                         io::WholePoints(geo),
                         HeldPointsReader(geo.points),
                         c,
                         summary,
                         run_id,
                         rejected,
                         pings,
                         meta);
}

std::size_t ViewSize(const StageContext& s) {
    return s.spilled_view ? s.spilled_view->size() : s.geo.points.size();
}

Status ForEachViewBlock(const StageContext& s,
                        std::size_t block,
                        const std::function<Status(const georef::GeorefPoints&, std::size_t)>& fn) {
    const std::size_t n = ViewSize(s);
    block = std::max<std::size_t>(block, 1);
    georef::GeorefPoints b;
    for (std::size_t first = 0; first < n; first += block) {
        const std::size_t count = std::min(block, n - first);
        if (s.spilled_view) {
            if (auto st = s.spilled_view->ReadBlock(first, count, b); !st) return st;
        } else {
            b = georef::SliceOf(s.geo.points, first, count);
        }
        if (auto st = fn(b, first); !st) return st;
    }
    return Ok{};
}

io::PointBlocks ViewPointBlocks(StageContext& s, std::size_t block) {
    if (!s.spilled_view) return io::WholePoints(s.geo);
    io::PointBlocks blocks;
    blocks.count = ViewSize(s);
    blocks.for_each =
        [&s, block](const std::function<Status(const georef::GeorefResult&, std::size_t)>& fn) {
            return ForEachViewBlock(
                s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
                    s.geo.points = b;
                    Status w = fn(s.geo, first);
                    s.geo.points = georef::GeorefPoints();
                    return w;
                });
        };
    return blocks;
}

AcceptedPointsReader ViewPointsReader(const StageContext& s,
                                      std::shared_ptr<georef::GeorefPoints> buffer) {
    if (!s.spilled_view) return HeldPointsReader(s.geo.points);
    return [&s, buffer](std::size_t first,
                        std::size_t count,
                        const georef::GeorefPoints*& points,
                        std::size_t& offset) -> Status {
        if (auto st = s.spilled_view->ReadBlock(first, count, *buffer); !st) return st;
        points = buffer.get();
        offset = 0;
        return Ok{};
    };
}

georef::GeorefResult RejectedView(const StageContext& s, const PipelineConfig& c) {
    return georef::Georeference(s.model,
                                s.model.latest(),
                                c.georef,
                                s.refraction,
                                {},
                                nullptr,
                                survey::SoundingView::kRejected);
}

Status WritePoints(StageContext& s, const PipelineConfig& c) {
    s.summary["soundings"] = SoundingsJson(s.geo.counts);
    const ProductMetadata meta = SurveyProductMetadata(s, c, nullptr);
    // The view's soundings a block at a time from its file while it is there (decision 041).
    const io::PointBlocks accepted = ViewPointBlocks(s, BlockWithinBudget(c.run, ResidentMb()));
    const AcceptedPointsReader read_accepted =
        ViewPointsReader(s, std::make_shared<georef::GeorefPoints>());
    std::optional<georef::GeorefResult> rejected;
    if (c.write_rejected) rejected = RejectedView(s, c);
    return WritePointsOf(s.out_dir,
                         s.geo,
                         accepted,
                         read_accepted,
                         c,
                         s.summary,
                         s.model.run_id,
                         rejected ? &*rejected : nullptr,
                         &s.model.ingest.pings,
                         &meta);
}

json SoundingsJson(const georef::GeorefCounts& c) {
    std::int64_t total = 0;
    json rejected = json::object();
    for (int k = 0; k < survey::kNumSoundingStatus; ++k) {
        total += c.status[static_cast<std::size_t>(k)];
        if (k == static_cast<int>(survey::SoundingStatus::kAccepted)) continue;
        rejected[std::string(survey::ToString(static_cast<survey::SoundingStatus>(k)))] =
            c.status[static_cast<std::size_t>(k)];
    }
    return {{"total", total},
            {"accepted", c.status[static_cast<std::size_t>(survey::SoundingStatus::kAccepted)]},
            {"rejected", std::move(rejected)},
            {"pings",
             {{"in", c.pings_in},
              {"georeferenced", c.pings_georeferenced},
              {"left_out",
               {{"outside_nav", c.pings_outside_nav},
                {"nav_gap", c.pings_in_nav_gap},
                {"bad_header", c.pings_bad_header}}}}},
            {"not_placed", std::max<std::int64_t>(0, c.soundings_in - total)}};
}

std::vector<std::string> ProductsReplacedBy(Stage stage) {
    const std::vector<std::string> slam = {
        "trajectory_initial.csv", "trajectory.csv", "trajectory_sigma.csv", "points_initial.ply"};
    const std::vector<std::string> grid = {"dem.tif",
                                           "dem.bag",
                                           "soundings_tpu.ply",
                                           "s44_holidays.tif",
                                           "s44_holidays.tif.aux.xml",
                                           "mosaic.tif",
                                           "terrain.tif",
                                           "crawler.tif",
                                           "crawler.tif.aux.xml",
                                           "capacity.csv"};
    const std::vector<std::string> mesh = {"mesh.ply",
                                           "mesh.obj",
                                           "mesh.glb",
                                           "mesh_filled.ply",
                                           "mesh_filled.obj",
                                           "mesh_filled.glb",
                                           "mesh_utm.ply",
                                           "mesh_utm.glb",
                                           "mesh_utm.prj"};
    const std::vector<std::string> report = {
        "report.html", "report_engineering.html", "report.pdf", "report"};
    std::vector<std::string> out;
    const auto add = [&out](const std::vector<std::string>& names) {
        out.insert(out.end(), names.begin(), names.end());
    };
    switch (stage) {
        case Stage::kIngest:
        case Stage::kGeoref:
        case Stage::kExport:
            add({survey::kSurveyFileName,
                 "summary.json",
                 "ingest.cache",  // the survey file's predecessor
                 "points.ply",
                 "points.las",
                 "points_utm.ply",
                 "points_utm.prj",
                 "boresight.json",
                 "trajectory_ins.csv",
                 "tsdf.vdb",
                 "mesh_initial.ply"});
            add(slam);
            add(grid);
            add(mesh);
            add(report);
            break;
        case Stage::kCalibrate:
        case Stage::kSlam:
            add(slam);
            add(grid);
            add({"tsdf.vdb", "mesh_initial.ply"});
            add(mesh);
            add(report);
            break;
        case Stage::kClean:
            add({"points.ply", "points.las", "points_utm.ply", "points_utm.prj"});
            add(grid);
            add({"tsdf.vdb"});
            add(mesh);
            add(report);
            break;
        case Stage::kGrid:
            add(grid);
            add(report);
            break;
        case Stage::kFuse:
        case Stage::kFuseInitial:
            add({"tsdf.vdb"});
            add(mesh);
            add(report);
            break;
        case Stage::kMesh:
        case Stage::kMeshInitial:
            add(mesh);
            add(report);
            break;
        case Stage::kReport:
            add(report);
            break;
    }
    return out;
}

std::vector<std::string> AllProducts() {
    return ProductsReplacedBy(Stage::kGeoref);
}

Status RemoveNamedProducts(const std::string& out_dir, const std::vector<std::string>& names) {
    std::error_code ec;
    for (const std::string& name : names) {
        const fs::path p = fs::path(out_dir) / name;
        fs::remove_all(p, ec);
        if (ec) return Error{p.string() + ": cannot remove the earlier product: " + ec.message()};
    }
    return Ok{};
}

void RemoveStalePartials(const std::string& out_dir) {
    // What a killed writer left (common/formats/replace_file.hpp).
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(out_dir, ec)) {
        if (formats::IsPartialName(e.path().filename().string())) {
            std::error_code rec;
            fs::remove(e.path(), rec);
        }
    }
}

Status RemoveProducts(const std::string& out_dir, const std::vector<std::string>& names) {
    if (auto r = RemoveNamedProducts(out_dir, names); !r) return r;
    RemoveStalePartials(out_dir);
    return Ok{};
}

std::string ForeignProduct(const StageContext& s,
                           const std::string& file,
                           const std::string& product_run_id) {
    const std::string& run = s.model.run_id;
    if (run.empty() || product_run_id == run) return "";
    return s.out_dir + "/" + file + " is from another run (" +
           (product_run_id.empty() ? std::string("no run id") : "run id " + product_run_id) + "; " +
           survey::kSurveyFileName + " has run id " + run + ")";
}

json LoadSummaryOfRun(const std::string& out_dir,
                      const survey::SurveyModel& model,
                      const Log& log) {
    json summary = json::object();
    if (auto read = io::ReadSummaryJson(out_dir + "/summary.json"); !read) {
        log("warning: " + read.error().message + "; summary.json is written anew");
    } else if (const std::string theirs = read->value("run_id", std::string());
               !model.run_id.empty() && theirs != model.run_id) {
        // The report of another survey (a survey.pitmap copied in, a re-run killed half-way):
        // nothing of it describes this survey, so it is started again rather than mixed.
        log("warning: " + out_dir + "/summary.json is of another run (" +
            (theirs.empty() ? std::string("no run id") : "run id " + theirs) + "; " +
            survey::kSurveyFileName + " has run id " + model.run_id +
            "); summary.json is written anew");
    } else {
        summary = std::move(*read);
    }
    if (!model.run_id.empty()) summary["run_id"] = model.run_id;
    return summary;
}

Status SaveSummary(const StageContext& s) {
    return io::WriteJsonFile(s.out_dir + "/summary.json", s.summary);
}

void TripGate(StageContext& s,
              Stage stage_id,
              const std::string& gate,
              const std::string& message,
              const Log& log) {
    const std::string stage = ToString(stage_id);
    log("quality gate " + stage + "/" + gate + ": " + message);
    if (!s.summary.contains("quality_gates") || !s.summary["quality_gates"].is_array())
        s.summary["quality_gates"] = json::array();
    s.summary["quality_gates"].push_back({{"stage", stage}, {"gate", gate}, {"message", message}});
}

void ClearGates(StageContext& s, Stage stage_id) {
    const std::string stage = ToString(stage_id);
    if (!s.summary.contains("quality_gates") || !s.summary["quality_gates"].is_array()) return;
    json kept = json::array();
    for (const auto& g : s.summary["quality_gates"]) {
        if (!(g.is_object() && g.value("stage", "") == stage)) kept.push_back(g);
    }
    s.summary["quality_gates"] = std::move(kept);
}

Expected<StageContext> LoadSurvey(const std::string& out_dir,
                                  const PipelineConfig& config,
                                  StartFrom start,
                                  const Log& log,
                                  ViewIn view) {
    StageContext s;
    s.out_dir = out_dir;
    auto model = survey::LoadSurvey(out_dir + "/" + survey::kSurveyFileName);
    if (!model) return model.error();
    s.model = std::move(*model);
    // The report this stage adds to; a damaged one, or one of another run, is started again
    // (it decides nothing).
    s.summary = LoadSummaryOfRun(out_dir, s.model, log);
    SetMemoryBudget(s.summary, config.run);
    auto refraction = io::BuildRefraction(s.model.refraction);
    if (!refraction) {
        return Error{out_dir + "/" + survey::kSurveyFileName +
                     ": the sound-velocity casts georef used: " + refraction.error().message};
    }
    s.refraction = *refraction;
    if (s.refraction) {
        log("refraction: " + std::to_string(s.refraction->casts().size()) +
            " cast(s) as georef used them");
    }
    auto manual = survey::LoadEdits(out_dir, s.model.ingest.pings);
    if (!manual) return manual.error();
    s.model.flags.manual = std::move(*manual);
    if (!s.model.flags.manual.empty()) log(EditsText(s.model.flags.manual));
    if (start == StartFrom::kNominal) s.model.ResetCalibration();
    if (start == StartFrom::kBeforeSlam) s.model.DropFrom(survey::TrajectoryVersion::kSlam);
    std::size_t kept = 0;
    if (view == ViewIn::kFile) {
        // The stage reads the view from its file: written there a block of pings at a time,
        // never held (decision 041).
        const ViewMaker make = ModelViewMaker(s, config, survey::SoundingView::kAccepted, &kept);
        if (auto st = ViewToFile(s, make, log); !st) return st.error();
    } else {
        s.geo =
            georef::Georeference(s.model, s.model.latest(), config.georef, s.refraction, {}, &kept);
    }
    if (kept > 0) {
        log("warning: " + std::to_string(kept) + " pings have no pose in the survey's " +
            survey::ToString(s.model.latest()) + " trajectory and keep the navigation's");
    }
    return s;
}

ViewMaker ModelViewMaker(const StageContext& s,
                         const PipelineConfig& config,
                         survey::SoundingView which,
                         std::size_t* kept) {
    return [&s, &config, which, kept](const georef::GeorefBlockSink& sink) {
        return georef::GeoreferenceByBlocks(s.model,
                                            s.model.latest(),
                                            config.georef,
                                            s.refraction,
                                            BlockWithinBudget(config.run, ResidentMb()),
                                            sink,
                                            {},
                                            kept,
                                            which);
    };
}

Expected<StageContext> LoadSurveyReplacing(const std::string& out_dir,
                                           const PipelineConfig& config,
                                           StartFrom start,
                                           Stage stage,
                                           const Log& log) {
    RemoveStalePartials(out_dir);
    auto s = LoadSurvey(out_dir, config, start, log, ViewIn::kFile);
    if (!s) return s.error();
    if (auto r = RemoveNamedProducts(out_dir, ProductsReplacedBy(stage)); !r) return r.error();
    return s;
}

Status ViewToFile(StageContext& s, const ViewMaker& make, const Log& log, bool with_status) {
    // One view at a time: the new one is made from the model alone.
    s.spilled_view.reset();
    s.geo = georef::GeorefResult{};
    const std::size_t beams = s.model.ingest.pings.range_counts.size();
    auto writer = io::SpillWriter::Open(io::ViewSpillPath(s.out_dir), beams, with_status);
    if (!writer) log("warning: " + writer.error().message + ": the view is held in memory");
    georef::GeorefPoints held;
    Status failed = Ok{};
    auto sink = [&](const georef::GeorefPoints& block, const georef::GeorefResult&) {
        if (!writer) {
            georef::AppendPoints(block, held);
            return true;
        }
        failed = writer->Append(block);
        return static_cast<bool>(failed);
    };
    s.geo = make(sink);
    if (!failed) return failed;
    if (!writer) {
        s.geo.points = std::move(held);
        return Ok{};
    }
    auto spilled = writer->Finish();
    if (!spilled) return spilled.error();
    s.spilled_view = std::move(*spilled);
    return Ok{};
}

Status GeoreferenceToFile(StageContext& s,
                          const PipelineConfig& config,
                          std::optional<Geodetic> origin,
                          georef::MountCheckByBlocks* check,
                          const ProgressCallback& progress,
                          const Log& log) {
    const ViewMaker make = [&](const georef::GeorefBlockSink& sink) {
        const auto checked = [&](const georef::GeorefPoints& b,
                                 const georef::GeorefResult& so_far) {
            if (check != nullptr) check->Add(so_far, b);
            return sink(b, so_far);
        };
        return georef::RunGeorefByBlocks(s.model.ingest.nav,
                                         s.model.ingest.pings,
                                         s.model.mount,
                                         config.georef,
                                         BlockWithinBudget(config.run, ResidentMb()),
                                         checked,
                                         origin,
                                         progress,
                                         s.refraction,
                                         &s.model.flags);
    };
    if (auto st = ViewToFile(s, make, log); !st) return Error{"georef: " + st.error().message};
    return Ok{};
}

Status SpillView(StageContext& s) {
    if (s.spilled_view) return Ok{};
    auto spilled = io::SpilledPoints::Spill(s.geo.points, io::ViewSpillPath(s.out_dir));
    if (!spilled) return spilled.error();
    s.spilled_view = std::move(*spilled);
    return Ok{};
}

Status RestoreView(StageContext& s) {
    if (!s.spilled_view) return Ok{};
    Status st = s.spilled_view->Restore(s.geo.points);
    s.spilled_view.reset();
    return st;
}

Status SaveSurvey(const StageContext& s) {
    if (auto w = survey::SaveSurvey(s.out_dir + "/" + survey::kSurveyFileName, s.model); !w)
        return w;
    return SaveSummary(s);
}

Status ExportSurvey(StageContext& s, const PipelineConfig& config, bool points) {
    StageClock clock;
    if (points) {
        if (auto w = WritePoints(s, config); !w) return w;
    } else {
        s.summary["soundings"] = SoundingsJson(s.geo.counts);
        if (auto utm = georef::UtmProjectionOf(s.geo); utm) {
            s.summary["utm"] = {
                {"zone", utm->zone}, {"northern", utm->northern}, {"epsg", utm->epsg}};
        }
    }
    // The mount used and what is known of it, from the model (summary.json is written, never
    // read back for a product).
    json bj = MountJson(s.model.mount);
    if (s.model.calibration == survey::CalibrationState::kCalibrated &&
        std::isfinite(s.model.boresight_sd_deg[0])) {
        // The calibrated boresight's 1-sigma uncertainty: range noise and the INS's attitude.
        bj["sd_deg"] = s.model.boresight_sd_deg;
    }
    bj["sonar_clock"] = survey::ClockJson(s.model.clock);
    if (!s.model.run_id.empty()) bj["run_id"] = s.model.run_id;
    if (auto w = io::WriteJsonFile(s.out_dir + "/boresight.json", bj); !w) return w;
    if (auto w = survey::SaveSurvey(s.out_dir + "/" + survey::kSurveyFileName, s.model); !w)
        return w;
    RecordStage(
        s.summary,
        Stage::kExport,
        {{"points", s.geo.counts.points}, {"trajectory", survey::ToString(s.model.latest())}},
        clock);
    return SaveSummary(s);
}

// The windows the INS marked not good (ingest's status rule): each with the pings it holds,
// in summary["ingest_ins_windows"]; any window with pings is a georef gate.
void InsWindowGate(StageContext& s,
                   const std::vector<io::InsStatusWindow>& windows,
                   const Log& log) {
    if (windows.empty()) return;
    const auto& P = s.model.ingest.pings.pings;
    json list = json::array();
    std::int64_t pings_total = 0;
    std::string text;
    for (const auto& w : windows) {
        const auto lo =
            std::lower_bound(P.begin(), P.end(), w.first_utime, [](const auto& p, std::int64_t t) {
                return p.utime_gps < t;
            });
        const auto hi =
            std::upper_bound(P.begin(), P.end(), w.last_utime, [](std::int64_t t, const auto& p) {
                return t < p.utime_gps;
            });
        const auto n = static_cast<std::int64_t>(hi - lo);
        pings_total += n;
        list.push_back({{"first_gps_s", static_cast<double>(w.first_utime) * 1e-6},
                        {"last_gps_s", static_cast<double>(w.last_utime) * 1e-6},
                        {"statuses", w.statuses},
                        {"navigating", w.navigating},
                        {"dropped", w.dropped},
                        {"samples", w.samples},
                        {"pings", n}});
        if (n > 0 && text.size() < 600) {
            char b[200];
            std::snprintf(b,
                          sizeof(b),
                          "%s%s for %.1f s from ping %lld (%lld pings, %s)",
                          text.empty() ? "" : "; ",
                          w.statuses.c_str(),
                          static_cast<double>(w.last_utime - w.first_utime) * 1e-6,
                          static_cast<long long>(lo - P.begin()),
                          static_cast<long long>(n),
                          !w.navigating ? "not georeferenced"
                          : w.dropped   ? "dropped by ingest.require_good_ins"
                                        : "kept, down-weighted");
            text += b;
        }
    }
    s.summary["ingest_ins_windows"] = list;
    if (pings_total > 0) {
        TripGate(s,
                 Stage::kGeoref,
                 "ins_not_good",
                 "the INS marks " + std::to_string(pings_total) +
                     " pings' navigation as not good: " + text +
                     "; the products there rest on a degraded or missing solution (navigation)",
                 log);
    }
}

namespace {

// A new georeference starts a new survey model (a new run) and a new report: every product of
// an earlier one goes first, so that a failed or killed georef leaves nothing of the earlier
// survey beside what it wrote. A damaged edit log stops here, before anything of the folder is
// removed (whether it is this survey's is known once the inputs are read).
Status ClearEarlierSurvey(const std::string& out_dir) {
    std::error_code ec;
    if (const std::string edits = out_dir + "/" + survey::kEditLogFileName; fs::exists(edits, ec)) {
        if (auto e = survey::ReadEditLog(edits); !e) return e.error();
    }
    return RemoveProducts(out_dir, AllProducts());
}

// The new run: an empty survey model with its run id, an empty summary.
void StartRun(StageContext& s, const Log& log) {
    s.model = survey::SurveyModel{};
    s.model.run_id = survey::NewRunId();
    s.summary = json::object();
    s.summary["run_id"] = s.model.run_id;
    log("run id " + s.model.run_id);
}

// The vehicle file at `path` ("" = none: a zero mount, with a warning): its mount into the model,
// its description, and what it sets for ingest (ApplyVehicle). Returns the INS's height above the
// water line when the file gives it.
Expected<std::optional<double>> ReadVehicle(StageContext& s,
                                            const std::string& path,
                                            const std::string& first_input,
                                            io::IngestConfig& icfg,
                                            const Log& log) {
    if (path.empty()) {
        log("warning: no vehicle.yaml found beside " + first_input +
            ": lever arm and boresight default to zero (give --vehicle FILE)");
        return std::optional<double>();
    }
    auto v = io::ReadVehicleYaml(path);
    if (!v) return v.error();
    s.model.mount = v->mount;
    s.model.nominal_mount = v->mount;
    s.model.vehicle_yaml = fs::absolute(path).string();
    s.vehicle = v->description;
    ApplyVehicle(v->description, icfg);
    s.summary["vehicle_yaml"] = fs::absolute(path).string();
    s.summary["vehicle"] = io::VehicleJson(v->description);
    return v->description.ins_height_above_waterline_m;
}

// A vendor file that does not say everything (ingest's `assumed`): the mount is the vehicle
// file's, and the list says so.
void NoteAssumedMount(const StageContext& s,
                      const std::string& vehicle_path,
                      std::vector<std::string>& assumed) {
    const survey::SonarMount& m = s.model.mount;
    char mount[200];
    std::snprintf(mount,
                  sizeof mount,
                  "lever arm %.3f %.3f %.3f m, boresight roll %.2f pitch %.2f yaw %.2f deg",
                  m.lever_arm_m.x(),
                  m.lever_arm_m.y(),
                  m.lever_arm_m.z(),
                  m.boresight_roll_deg,
                  m.boresight_pitch_deg,
                  m.boresight_yaw_deg);
    assumed.push_back(
        "mount: " + std::string(mount) + " from " +
        (vehicle_path.empty() ? std::string("no vehicle file (zero)") : "the vehicle file"));
}

// io::IngestFiles into the model (its navigation and pings), with a progress bar, its warnings
// and assumptions logged and its record in the summary; returns the INS status windows for the
// georef gate. An error when the inputs hold no navigation or no pings.
Expected<std::vector<io::InsStatusWindow>> IngestSurvey(StageContext& s,
                                                        const std::vector<std::string>& files,
                                                        const io::IngestConfig& icfg,
                                                        const std::string& vehicle_path,
                                                        const Log& log) {
    StageClock clock;
    ProgressReporter bar(ToString(Stage::kIngest), 1000);
    auto ing = io::IngestFiles(files, icfg, bar.AsCallback());
    bar.Finish();
    if (!ing) return ing.error();
    s.model.ingest = {std::move(ing->nav), std::move(ing->pings)};
    for (const auto& w : ing->warnings) log("warning: " + w);
    if (!ing->assumed.empty()) NoteAssumedMount(s, vehicle_path, ing->assumed);
    for (const auto& a : ing->assumed) log("assumed: " + a);
    log("ingest: " + ing->message);
    json record = ing->counts;
    record["warnings"] = ing->warnings;
    record["assumed"] = ing->assumed;
    record["nav_from_raw"] = ing->nav_from_raw;
    record["pings_from_raw"] = ing->pings_from_raw;
    RecordStage(s.summary, Stage::kIngest, record, clock);
    if (s.model.ingest.nav.samples.empty())
        return Error{"no INS navigation in the inputs (" + files.front() + " ...)"};
    if (s.model.ingest.pings.pings.empty())
        return Error{"no sonar pings in the inputs (" + files.front() + " ...)"};
    return std::move(ing->ins_windows);
}

// georef::RunGeoref of the ingested pings on the INS trajectory, with a progress bar; the world
// origin is the configured one, else the first navigation sample. The view goes to its file
// block by block (GeoreferenceToFile); `check` sees every block (the mount check).
Status GeoreferenceIngest(StageContext& s,
                          const PipelineConfig& config,
                          georef::MountCheckByBlocks& check,
                          const Log& log) {
    std::optional<Geodetic> origin;
    if (!std::isnan(config.origin_latitude_deg)) {
        origin = Geodetic{
            config.origin_latitude_deg, config.origin_longitude_deg, config.origin_height_m};
    }
    ProgressReporter bar(ToString(Stage::kGeoref), 1000);
    auto st = GeoreferenceToFile(s, config, origin, &check, bar.AsCallback(), log);
    bar.Finish();
    if (!st) return st;
    log("georef: " + s.geo.message);
    return Ok{};
}

// Pings outside the navigation's span are not georeferenced: a warning, or the georef gate
// pings_outside_navigation beyond quality.max_outside_nav_fraction of them.
void GateOutsideNavigation(StageContext& s, const QualityConfig& quality, const Log& log) {
    const std::int64_t outside = s.geo.counts.pings_outside_nav;
    if (outside <= 0) return;
    const auto& pings = s.model.ingest.pings.pings;
    const auto& nav = s.model.ingest.nav.samples;
    const std::string what =
        std::to_string(outside) + " of " + std::to_string(pings.size()) +
        " pings lie outside the navigation span and are not georeferenced: navigation " +
        calib::SpanText(nav.front().utime_gps, nav.back().utime_gps) + ", sonar " +
        calib::SpanText(pings.front().utime_gps, pings.back().utime_gps);
    if (static_cast<double>(outside) >
        quality.max_outside_nav_fraction * static_cast<double>(pings.size())) {
        TripGate(s, Stage::kGeoref, "pings_outside_navigation", what, log);
    } else {
        log("warning: " + what);
    }
}

// The mount against the attitude (georef::CheckMountAgainstAttitude), in summary["mount_check"].
// A mount that does not explain the soundings stops georef (an error), unless the sonar clock
// is in doubt (a sonar_clock gate tripped): the attitude of another time leaves the roll in
// the soundings too, so the check cannot blame the mount and trips the gate naming both.
Status CheckMount(StageContext& s, const georef::MountCheck& mc, const Log& log) {
    log("georef: " + mc.message);
    s.summary["mount_check"] = {{"checked", mc.checked},
                                {"consistent", mc.consistent},
                                {"roll_gain", mc.roll_gain},
                                {"roll_gain_sd", mc.roll_gain_sd},
                                {"pitch_gain", mc.pitch_gain},
                                {"pitch_gain_sd", mc.pitch_gain_sd},
                                {"pings", mc.pings},
                                {"message", mc.message}};
    if (mc.consistent) return Ok{};
    bool clock_in_doubt = false;
    for (const auto& g : s.summary.value("quality_gates", json::array())) {
        clock_in_doubt |= g.is_object() && g.value("stage", "") == ToString(Stage::kGeoref) &&
                          g.value("gate", "").rfind("sonar_clock", 0) == 0;
    }
    if (clock_in_doubt) {
        TripGate(s,
                 Stage::kGeoref,
                 "mount_inconsistent",
                 mc.message +
                     "; or the sonar clock, which is in doubt (a sonar_clock gate "
                     "tripped): the attitude of another time leaves the roll in "
                     "the soundings too",
                 log);
        return Ok{};
    }
    TripGate(s, Stage::kGeoref, "mount_inconsistent", mc.message, log);
    (void)SaveSummary(s);
    return Error{
        "georef: the sonar mount of " +
        (s.model.vehicle_yaml.empty() ? std::string("the vehicle file") : s.model.vehicle_yaml) +
        " does not explain the soundings: " + mc.likely_cause + " (" + mc.message +
        "; quality.check_mount: false skips this check)"};
}

// The georeference into the model (its world origin and INS trajectory) and the summary (the
// stage's counts, the origin, the survey's time, the inputs, the mount).
void RecordGeoref(StageContext& s, const std::vector<std::string>& files, const StageClock& clock) {
    s.model.origin = s.geo.world_origin;
    s.model.trajectory(survey::TrajectoryVersion::kIns) =
        georef::TrajectoryOf(s.geo, s.model.ingest.pings.pings.size());
    RecordStage(s.summary, Stage::kGeoref, s.geo.counts, clock);
    // Whether the view went to its file as it was made (decision 033), or is held.
    s.summary["stages"][ToString(Stage::kGeoref)]["view_in_file"] = s.spilled_view.has_value();
    s.summary["world_origin"] = survey::OriginJson(s.model.origin);
    s.summary["time"] = TimeJson(s.model.ingest);
    s.summary["inputs"] = json::array();
    for (const auto& f : files) s.summary["inputs"].push_back(fs::absolute(f).string());
    s.summary["mount"] = MountJson(s.model.mount);
}

}  // namespace

// inputs -> ingest -> georef -> products; the survey stays in memory for later stages.
Status GeorefSurvey(StageContext& s,
                    const std::vector<std::string>& inputs,
                    const PipelineConfig& config,
                    const Log& log) {
    const std::string& out_dir = s.out_dir;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) return Error{out_dir + ": cannot create: " + ec.message()};
    auto files = io::ExpandInputs(inputs);
    if (!files) return files.error();
    if (files->empty()) return Error{"no input files"};
    const std::string vpath = VehicleFilePath(*files, config);
    if (auto r = ClearEarlierSurvey(out_dir); !r) return r;
    StartRun(s, log);
    SetMemoryBudget(s.summary, config.run);
    io::IngestConfig icfg = config.ingest;
    auto ins_height_m = ReadVehicle(s, vpath, files->front(), icfg, log);
    if (!ins_height_m) return ins_height_m.error();
    if (auto r = SetUpRefraction(s, config, *ins_height_m, log); !r) return r;
    // The configured offset (sonar clock minus UTC), null when the clock is to be found.
    s.summary["sonar_clock_offset_s"] =
        icfg.sonar_clock_offset_known ? json(icfg.sonar_clock_offset_s) : json(nullptr);
    auto ins_windows = IngestSurvey(s, *files, icfg, vpath, log);
    if (!ins_windows) return ins_windows.error();

    // The hand edits (P/edits.json) survive a new georeference: applied on top of georef's and
    // the cleaning's verdicts. One of another survey, or a damaged one, stops here.
    auto manual = survey::LoadEdits(out_dir, s.model.ingest.pings);
    if (!manual) return manual.error();
    s.model.flags.manual = std::move(*manual);
    if (!s.model.flags.manual.empty()) log(EditsText(s.model.flags.manual));

    PipelineConfig resolved = config;  // with what the vehicle file gave
    resolved.ingest = icfg;
    if (auto c = ClockSurvey(s, resolved, log); !c) {
        (void)SaveSummary(s);
        return c;
    }

    StageClock georef_clock;
    georef::MountCheckByBlocks mount_check;
    if (auto g = GeoreferenceIngest(s, config, mount_check, log); !g) return g;
    GateOutsideNavigation(s, config.quality, log);
    InsWindowGate(s, *ins_windows, log);
    if (config.quality.check_mount) {
        if (auto m = CheckMount(s, mount_check.Check(s.geo), log); !m) return m;
    }
    RecordGeoref(s, *files, georef_clock);
    if (auto st = io::WriteInsTrajectoryCsv(
            out_dir + "/trajectory_ins.csv", s.model.ingest.nav, s.model.origin);
        !st)
        return st;
    return s.defer_products ? SaveSummary(s) : ExportSurvey(s, config);
}

}  // namespace detail

const char* ToString(Stage s) {
    switch (s) {
        case Stage::kIngest:
            return "ingest";
        case Stage::kGeoref:
            return "georef";
        case Stage::kExport:
            return "export";
        case Stage::kCalibrate:
            return "calibrate";
        case Stage::kSlam:
            return "slam";
        case Stage::kClean:
            return "clean";
        case Stage::kGrid:
            return "grid";
        case Stage::kFuseInitial:
            return "fuse_initial";
        case Stage::kMeshInitial:
            return "mesh_initial";
        case Stage::kFuse:
            return "fuse";
        case Stage::kMesh:
            return "mesh";
        case Stage::kReport:
            return "report";
    }
    return "?";
}

Expected<std::string> Info(const std::vector<std::string>& inputs, const PipelineConfig& config) {
    auto files = io::ExpandInputs(inputs);
    if (!files) return files.error();
    io::IngestConfig icfg = config.ingest;
    if (const std::string vpath = VehicleFilePath(*files, config); !vpath.empty()) {
        auto v = io::ReadVehicleYaml(vpath);
        if (!v) return v.error();
        ApplyVehicle(v->description, icfg);
    }
    auto r = io::IngestFiles(*files, icfg);
    if (!r) return r.error();
    std::ostringstream o;
    for (const auto& f : *files) o << "file " << f << "\n";
    for (const auto& w : r->warnings) o << "warning: " << w << "\n";
    for (const auto& [ch, n] : r->counts.events_by_channel) o << "  " << ch << ": " << n << "\n";
    o << json(r->counts).dump(2) << "\n";
    auto span = [](std::int64_t a, std::int64_t b) {
        char s[96];
        std::snprintf(
            s, sizeof(s), "%.3f .. %.3f GPS s (%.1f s)", a * 1e-6, b * 1e-6, (b - a) * 1e-6);
        return std::string(s);
    };
    if (!r->nav.samples.empty()) {
        o << "nav: " << span(r->nav.samples.front().utime_gps, r->nav.samples.back().utime_gps)
          << "\n";
    }
    if (!r->pings.pings.empty()) {
        o << "pings: " << span(r->pings.pings.front().utime_gps, r->pings.pings.back().utime_gps)
          << ", " << r->pings.num_soundings() << " soundings\n";
    }
    // The products' horizontal CRS as georef will choose it (the UTM zone of the world origin:
    // the configured one, else the first INS fix): a campaign checks its surveys share one.
    std::optional<Geodetic> origin;
    const char* origin_source = "configured origin";
    if (!std::isnan(config.origin_latitude_deg)) {
        origin = Geodetic{
            config.origin_latitude_deg, config.origin_longitude_deg, config.origin_height_m};
    } else if (!r->nav.samples.empty()) {
        origin = r->nav.samples.front().position;
        origin_source = "first INS fix";
    }
    if (origin) {
        if (auto u = UtmFromGeodetic(*origin); u && u->zone >= 1) {
            char line[160];
            std::snprintf(line,
                          sizeof line,
                          "crs: EPSG:%d (WGS 84 / UTM zone %d%c) from the %s %.6f %.6f\n",
                          UtmEpsgCode(u->zone, u->northern),
                          u->zone,
                          u->northern ? 'N' : 'S',
                          origin_source,
                          origin->latitude_deg,
                          origin->longitude_deg);
            o << line;
        }
    }
    o << r->message << "\n";
    return o.str();
}

Status RunGeorefStage(const std::vector<std::string>& inputs,
                      const std::string& out_dir,
                      const PipelineConfig& config,
                      const Log& log) {
    detail::StageContext s;
    s.out_dir = out_dir;
    return detail::GeorefSurvey(s, inputs, config, log);
}

}  // namespace pitmap::proc::pipeline
