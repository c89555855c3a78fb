// SPDX-License-Identifier: MIT
#include "processor/pipeline/pipeline.hpp"

#include <fcntl.h>
#include <malloc.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <sstream>

#include "common/config.hpp"
#include "common/frames.hpp"
#include "common/progress.hpp"
#include "processor/io/products.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/survey.hpp"

namespace pitmap::proc::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json CountsJson(const io::IngestCounts& c) {
    json j = {{"files", c.files},
              {"bytes", c.bytes},
              {"events", c.events},
              {"corrupt_events", c.corrupt_events},
              {"resync_bytes", c.resync_bytes},
              {"truncated_events", c.truncated_events},
              {"length_repairs", c.length_repairs},
              {"files_skipped", c.files_skipped},
              {"decode_failures", c.decode_failures},
              {"nav_samples", c.nav_samples},
              {"nav_without_time", c.nav_without_time},
              {"nav_not_good", c.nav_not_good},
              {"nav_duplicates", c.nav_duplicates},
              {"stddev_samples", c.stddev_samples},
              {"pings", c.pings},
              {"pings_without_time", c.pings_without_time},
              {"pings_bad", c.pings_bad},
              {"ping_duplicates", c.ping_duplicates},
              {"raw_chunks_decoded", c.raw_chunks_decoded},
              {"raw_skipped_bytes", c.raw_skipped_bytes},
              {"raw_decode_errors", c.raw_decode_errors}};
    return j;
}

json CountsJson(const georef::GeorefCounts& c) {
    return {{"pings_in", c.pings_in},
            {"pings_georeferenced", c.pings_georeferenced},
            {"pings_outside_nav", c.pings_outside_nav},
            {"pings_in_nav_gap", c.pings_in_nav_gap},
            {"pings_bad_header", c.pings_bad_header},
            {"soundings_in", c.soundings_in},
            {"no_detection", c.no_detection},
            {"range_gate", c.range_gate},
            {"spikes", c.spikes},
            {"points", c.points}};
}

}  // namespace

namespace detail {

StageClock::StageClock() : start_(std::chrono::steady_clock::now()) {
    // Hand the heap's free pages back first, so the stage's peak is not the previous stage's
    // retained memory.
    ::malloc_trim(0);
    // "5" resets the peak resident set size (Linux >= 4.0); without it the peak is cumulative.
    const int fd = ::open("/proc/self/clear_refs", O_WRONLY | O_CLOEXEC);
    if (fd >= 0) {
        const ssize_t n = ::write(fd, "5", 1);
        (void)n;
        ::close(fd);
    }
}

double StageClock::seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

double StageClock::PeakRssMb() {
    if (std::FILE* f = std::fopen("/proc/self/status", "r")) {
        char line[256];
        long kb = -1;
        while (std::fgets(line, sizeof(line), f) != nullptr) {
            if (std::sscanf(line, "VmHWM: %ld kB", &kb) == 1) break;
        }
        std::fclose(f);
        if (kb >= 0) return static_cast<double>(kb) / 1024.0;
    }
    return io::PeakRssMb();
}

void RecordStage(json& summary, const std::string& name, json stage, const StageClock& clock) {
    stage["seconds"] = clock.seconds();
    stage["peak_rss_mb"] = StageClock::PeakRssMb();
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

json MountJson(const georef::SonarMount& m) {
    return {{"roll_deg", m.boresight_roll_deg},
            {"pitch_deg", m.boresight_pitch_deg},
            {"yaw_deg", m.boresight_yaw_deg},
            {"lever_arm_sonar_m", {m.lever_arm_m.x(), m.lever_arm_m.y(), m.lever_arm_m.z()}},
            {"convention", "R_vehicle_sonar = Rz(yaw) Ry(pitch) Rx(roll), vehicle FRD"}};
}

Expected<georef::SonarMount> MountFromJson(const json& m) {
    georef::SonarMount mount;
    try {
        mount.boresight_roll_deg = m.at("roll_deg").get<double>();
        mount.boresight_pitch_deg = m.at("pitch_deg").get<double>();
        mount.boresight_yaw_deg = m.at("yaw_deg").get<double>();
        const auto arm = m.at("lever_arm_sonar_m").get<std::vector<double>>();
        if (arm.size() != 3) return Error{"lever_arm_sonar_m needs 3 values"};
        mount.lever_arm_m = Eigen::Vector3d(arm[0], arm[1], arm[2]);
    } catch (const std::exception& e) {
        return Error{std::string("malformed mount: ") + e.what()};
    }
    return mount;
}

Expected<Geodetic> OriginFromJson(const json& summary) {
    if (!summary.is_object() || !summary.contains("world_origin")) {
        return Error{"no world_origin"};
    }
    try {
        const json& o = summary.at("world_origin");
        return Geodetic{o.at("latitude_deg").get<double>(),
                        o.at("longitude_deg").get<double>(),
                        o.at("height_m").get<double>()};
    } catch (const std::exception& e) {
        return Error{std::string("malformed world_origin: ") + e.what()};
    }
}

Status WritePoints(const std::string& dir,
                   const georef::GeorefResult& geo,
                   const PipelineConfig& c,
                   json& summary) {
    if (auto s = io::WritePly(dir + "/points.ply", geo); !s) return s;
    auto utm = georef::ToUtm(geo);
    if (!utm) return Error{"UTM: " + utm.error().message};
    summary["utm"] = {{"zone", utm->zone}, {"northern", utm->northern}, {"epsg", utm->epsg}};
    if (c.write_las) {
        if (auto s = io::WriteLas(dir + "/points.las", geo, *utm); !s) return s;
    }
    return Ok{};
}

Status SaveSummary(const Survey& s) {
    return io::WriteJsonFile(s.out_dir + "/summary.json", s.summary);
}

Expected<Survey> LoadSurvey(const std::string& out_dir,
                            const PipelineConfig& config,
                            bool apply_trajectory,
                            const Log& log) {
    Survey s;
    s.out_dir = out_dir;
    auto summary = io::ReadSummaryJson(out_dir + "/summary.json");
    if (!summary) return Error{summary.error().message + " (run `pitmap georef` first)"};
    s.summary = std::move(*summary);
    if (!s.summary.is_object() || !s.summary.contains("world_origin") ||
        !s.summary.contains("mount")) {
        return Error{out_dir + "/summary.json: no world_origin/mount (run `pitmap georef` first)"};
    }
    auto mount = MountFromJson(s.summary["mount"]);
    if (!mount) return Error{out_dir + "/summary.json: " + mount.error().message};
    s.mount = *mount;
    auto origin = OriginFromJson(s.summary);
    if (!origin) return Error{out_dir + "/summary.json: " + origin.error().message};
    s.origin = *origin;
    auto ing = io::ReadIngestCache(out_dir + "/ingest.cache");
    if (!ing) return ing.error();
    s.ingest = std::move(*ing);
    s.geo = georef::RunGeoref(s.ingest.nav, s.ingest.pings, s.mount, config.georef, s.origin);
    if (apply_trajectory && s.summary.contains("stages") && s.summary["stages"].contains("slam")) {
        auto traj = ReadTrajectoryCsv(out_dir + "/trajectory.csv");
        if (!traj) return traj.error();
        PoseLookup poses = PosesAtPings(s.geo, traj->gps_time_s, traj->T_world_vehicle);
        if (poses.outside_span > 0) {
            log("warning: " + std::to_string(poses.outside_span) +
                " pings outside trajectory.csv keep their INS pose");
        }
        ApplyVehiclePoses(s.geo, poses.T_world_vehicle, s.mount);
    }
    return s;
}

Status CalibrateSurvey(Survey& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    const georef::SonarMount before = s.mount;
    ProgressReporter bar("calibrate", 1000);
    calib::BoresightResult cal =
        calib::CalibrateBoresight(s.geo, s.ingest.nav, s.mount, config.calibrate, bar.AsCallback());
    bar.Finish();
    log("calibrate: " + cal.message);
    json st = {
        {"termination", calib::ToString(cal.termination)},
        {"iterations", cal.iterations},
        {"message", cal.message},
        {"segment",
         {{"start_s", cal.segment.start_s},
          {"end_s", cal.segment.end_s},
          {"overlap_cells", cal.segment.overlap_cells},
          {"max_position_stddev_m", cal.segment.max_position_stddev_m},
          {"max_heading_stddev_deg", cal.segment.max_heading_stddev_deg}}},
        {"residual_before_rms_m", cal.before.rms_m},
        {"residual_after_rms_m", cal.after.rms_m},
        {"pairs", cal.after.pairs},
        {"formal_sd_deg", {cal.formal_sd_deg[0], cal.formal_sd_deg[1], cal.formal_sd_deg[2]}},
        {"height_offsets_rms_m", cal.height_offsets_rms_m},
        {"boresight_before", MountJson(before)},
        {"boresight_after", MountJson(cal.mount)}};
    st["verify"] = json::array();
    for (const auto& v : cal.verify) {
        st["verify"].push_back({{"start_s", v.segment.start_s},
                                {"end_s", v.segment.end_s},
                                {"rms_before_m", v.before.rms_m},
                                {"rms_after_m", v.after.rms_m},
                                {"pairs", v.after.pairs}});
        char buf[160];
        std::snprintf(buf,
                      sizeof(buf),
                      "verify %.1f..%.1f s: residual RMS %.4f -> %.4f m (%lld pairs)",
                      v.segment.start_s,
                      v.segment.end_s,
                      v.before.rms_m,
                      v.after.rms_m,
                      static_cast<long long>(v.after.pairs));
        log(buf);
    }
    if (cal.termination == calib::Termination::kNoOverlap) {
        RecordStage(s.summary, "calibrate", st, clock);
        (void)SaveSummary(s);
        return Error{"calibrate: " + cal.message};
    }
    georef::Regeoreference(s.geo, cal.mount);
    s.mount = cal.mount;
    s.summary["mount"] = MountJson(cal.mount);
    if (auto w = WritePoints(s.out_dir, s.geo, config, s.summary); !w) return w;
    if (auto w = io::WriteJsonFile(s.out_dir + "/boresight.json", MountJson(cal.mount)); !w) {
        return w;
    }
    RecordStage(s.summary, "calibrate", st, clock);
    return SaveSummary(s);
}

// inputs -> ingest -> georef -> products; the survey stays in memory for later stages.
Status GeorefSurvey(Survey& s,
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
    // Vehicle config: given, or beside the first input.
    std::string vpath = config.vehicle_yaml;
    if (vpath.empty()) {
        const fs::path first = fs::path(files->front()).parent_path() / "vehicle.yaml";
        if (fs::exists(first)) vpath = first.string();
    }
    io::IngestConfig icfg = config.ingest;
    if (auto old = io::ReadSummaryJson(out_dir + "/summary.json"); old && old->is_object()) {
        s.summary = *old;
    } else {
        s.summary = json::object();
    }
    // A new georeference invalidates whatever later stages recorded.
    s.summary.erase("stages");
    s.summary.erase("stage_order");
    s.summary.erase("total_seconds");
    if (vpath.empty()) {
        log("warning: no vehicle.yaml found beside " + files->front() +
            ": lever arm and boresight default to zero (give products.vehicle_yaml)");
    } else {
        auto v = io::ReadVehicleYaml(vpath);
        if (!v) return v.error();
        for (const auto& m : v->missing) log("warning: " + vpath + ": missing " + m + " (using 0)");
        s.mount = v->mount;
        if (icfg.nav_channel_id.empty()) icfg.nav_channel_id = v->navigation_channel;
        if (icfg.sonar_channel_id.empty()) icfg.sonar_channel_id = v->sonar_channel;
        s.summary["vehicle_yaml"] = fs::absolute(vpath).string();
    }

    StageClock ingest_clock;
    ProgressReporter bar("ingest", 1000);
    auto ing = io::IngestFiles(*files, icfg, bar.AsCallback());
    bar.Finish();
    if (!ing) return ing.error();
    s.ingest = std::move(*ing);
    for (const auto& w : s.ingest.warnings) log("warning: " + w);
    log("ingest: " + s.ingest.message);
    json ist = CountsJson(s.ingest.counts);
    ist["warnings"] = s.ingest.warnings;
    ist["nav_from_raw"] = s.ingest.nav_from_raw;
    ist["pings_from_raw"] = s.ingest.pings_from_raw;
    RecordStage(s.summary, "ingest", ist, ingest_clock);
    if (s.ingest.nav.samples.empty())
        return Error{"no INS navigation in the inputs (" + files->front() + " ...)"};
    if (s.ingest.pings.pings.empty())
        return Error{"no sonar pings in the inputs (" + files->front() + " ...)"};

    StageClock georef_clock;
    std::optional<Geodetic> origin;
    if (!std::isnan(config.origin_latitude_deg)) {
        origin = Geodetic{
            config.origin_latitude_deg, config.origin_longitude_deg, config.origin_height_m};
    }
    ProgressReporter gbar("georef", 1000);
    s.geo = georef::RunGeoref(
        s.ingest.nav, s.ingest.pings, s.mount, config.georef, origin, gbar.AsCallback());
    gbar.Finish();
    log("georef: " + s.geo.message);
    s.origin = s.geo.world_origin;
    RecordStage(s.summary, "georef", CountsJson(s.geo.counts), georef_clock);
    s.summary["world_origin"] = {{"latitude_deg", s.origin.latitude_deg},
                                 {"longitude_deg", s.origin.longitude_deg},
                                 {"height_m", s.origin.height_m}};
    s.summary["inputs"] = json::array();
    for (const auto& f : *files) s.summary["inputs"].push_back(fs::absolute(f).string());
    s.summary["mount"] = MountJson(s.mount);

    StageClock export_clock;
    if (auto st = WritePoints(out_dir, s.geo, config, s.summary); !st) return st;
    if (auto st = io::WriteTrajectoryCsv(out_dir + "/trajectory.csv", s.ingest.nav, s.origin); !st)
        return st;
    if (auto st = io::WriteJsonFile(out_dir + "/boresight.json", MountJson(s.mount)); !st)
        return st;
    if (auto st = io::WriteIngestCache(out_dir + "/ingest.cache", s.ingest); !st) return st;
    // Products of later stages made from an earlier georeference would now be stale.
    for (const char* stale : {"trajectory_initial.csv",
                              "trajectory_ins.csv",
                              "points_initial.ply",
                              "tsdf.vdb",
                              "mesh.ply",
                              "mesh.obj",
                              "mesh.glb",
                              "mesh_filled.ply",
                              "mesh_filled.obj",
                              "mesh_filled.glb",
                              "mesh_initial.ply",
                              "report.html"}) {
        fs::remove(fs::path(out_dir) / stale, ec);
    }
    RecordStage(s.summary, "export", {{"points", s.geo.counts.points}}, export_clock);
    return SaveSummary(s);
}

}  // namespace detail

Expected<std::string> Info(const std::vector<std::string>& inputs, const PipelineConfig& config) {
    auto files = io::ExpandInputs(inputs);
    if (!files) return files.error();
    auto r = io::IngestFiles(*files, config.ingest);
    if (!r) return r.error();
    std::ostringstream o;
    for (const auto& f : *files) o << "file " << f << "\n";
    for (const auto& w : r->warnings) o << "warning: " << w << "\n";
    for (const auto& [ch, n] : r->counts.events_by_channel) o << "  " << ch << ": " << n << "\n";
    o << CountsJson(r->counts).dump(2) << "\n";
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
    o << r->message << "\n";
    return o.str();
}

Status RunGeorefStage(const std::vector<std::string>& inputs,
                      const std::string& out_dir,
                      const PipelineConfig& config,
                      const Log& log) {
    detail::Survey s;
    s.out_dir = out_dir;
    return detail::GeorefSurvey(s, inputs, config, log);
}

Status RunCalibrateStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, /*apply_trajectory=*/false, log);
    if (!s) return s.error();
    return detail::CalibrateSurvey(*s, config, log);
}

}  // namespace pitmap::proc::pipeline
