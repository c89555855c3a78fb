// SPDX-License-Identifier: MIT
#include "processor/pipeline/pipeline.hpp"

#include <chrono>
#include <filesystem>
#include <sstream>

#include "common/config.hpp"
#include "common/frames.hpp"
#include "common/progress.hpp"
#include "processor/io/products.hpp"

namespace pitmap::proc::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

std::vector<std::string> PipelineConfig::Validate() const {
    std::vector<std::string> p = ingest.Validate();
    for (auto& s : georef.Validate()) p.push_back(s);
    for (auto& s : calibrate.Validate()) p.push_back(s);
    const bool any = !std::isnan(origin_latitude_deg) || !std::isnan(origin_longitude_deg) ||
                     !std::isnan(origin_height_m);
    const bool all = !std::isnan(origin_latitude_deg) && !std::isnan(origin_longitude_deg) &&
                     !std::isnan(origin_height_m);
    if (any && !all) p.push_back("products.origin needs latitude_deg, longitude_deg and height_m");
    if (all && std::abs(origin_latitude_deg) > 90)
        p.push_back("products.origin.latitude_deg out of range");
    return p;
}

Expected<PipelineConfig> LoadConfig(const std::string& path) {
    auto reader = ConfigReader::FromFile(path);
    if (!reader) return reader.error();
    PipelineConfig c;
    ConfigReader in = reader->Child("ingest");
    std::string source = io::ToString(c.ingest.source);
    in.Read("source", source);
    if (!io::ParseIngestSource(source, c.ingest.source)) {
        in.AddProblem(in.Path("source") + ": must be auto, decoded or raw");
    }
    in.Read("nav_channel_id", c.ingest.nav_channel_id);
    in.Read("sonar_channel_id", c.ingest.sonar_channel_id);
    in.Read("sonar_clock_offset_s", c.ingest.sonar_clock_offset_s);
    in.Read("require_good_ins", c.ingest.require_good_ins);
    in.RejectUnknownKeys();
    ConfigReader g = reader->Child("georef");
    auto& gc = c.georef;
    g.Read("max_nav_gap_s", gc.max_nav_gap_s);
    g.Read("min_range_m", gc.min_range_m);
    g.Read("max_range_m", gc.max_range_m);
    g.Read("sound_speed_scaling", gc.sound_speed_scaling);
    g.Read("nominal_sound_speed_mps", gc.nominal_sound_speed_mps);
    g.Read("apply_profile_tilt", gc.apply_profile_tilt);
    g.Read("spike_half_window", gc.spike_half_window);
    g.Read("spike_abs_m", gc.spike_abs_m);
    g.Read("spike_rel", gc.spike_rel);
    g.Read("num_threads", gc.num_threads);
    g.RejectUnknownKeys();
    ConfigReader b = reader->Child("calibrate");
    auto& bc = c.calibrate;
    b.Read("segment_start_s", bc.segment_start_s);
    b.Read("segment_duration_s", bc.segment_duration_s);
    b.Read("part_duration_s", bc.part_duration_s);
    b.Read("min_separation_s", bc.min_separation_s);
    b.Read("beam_stride", bc.beam_stride);
    b.Read("max_distance_m", bc.max_distance_m);
    b.Read("min_distance_m", bc.min_distance_m);
    b.Read("normal_radius_m", bc.normal_radius_m);
    b.Read("cauchy_scale_m", bc.cauchy_scale_m);
    b.Read("max_iterations", bc.max_iterations);
    b.Read("convergence_deg", bc.convergence_deg);
    b.Read("max_position_stddev_m", bc.max_position_stddev_m);
    b.Read("max_heading_stddev_deg", bc.max_heading_stddev_deg);
    b.Read("num_verify_segments", bc.num_verify_segments);
    b.Read("estimate_height_offsets", bc.estimate_height_offsets);
    b.Read("height_offset_sigma_m", bc.height_offset_sigma_m);
    b.Read("range_noise_fraction", bc.range_noise_fraction);
    b.Read("range_noise_constant_m", bc.range_noise_constant_m);
    b.RejectUnknownKeys();
    ConfigReader pr = reader->Child("products");
    pr.Read("write_las", c.write_las);
    pr.Read("vehicle_yaml", c.vehicle_yaml);
    ConfigReader o = pr.Child("origin");
    o.Read("latitude_deg", c.origin_latitude_deg);
    o.Read("longitude_deg", c.origin_longitude_deg);
    o.Read("height_m", c.origin_height_m);
    o.RejectUnknownKeys();
    pr.RejectUnknownKeys();
    reader->RejectUnknownKeys();
    std::vector<std::string> problems = reader->problems();
    for (auto& s : c.Validate()) problems.push_back(path + ": " + s);
    if (!problems.empty()) return Error{"invalid config:\n" + FormatProblems(problems)};
    return c;
}

std::string DefaultsYaml() {
    const PipelineConfig c;
    std::ostringstream o;
    auto b = [](bool v) { return v ? "true" : "false"; };
    o << "# pitmap processor configuration: every key with its default.\n"
      << "ingest:\n"
      << "  source: " << io::ToString(c.ingest.source)
      << "            # auto | decoded | raw (re-decode RAW_* channels)\n"
      << "  nav_channel_id: \"\"        # e.g. novatel_com1; \"\" = every INS channel\n"
      << "  sonar_channel_id: \"\"      # e.g. deltat_udp; \"\" = every sonar channel\n"
      << "  sonar_clock_offset_s: " << c.ingest.sonar_clock_offset_s
      << "   # .83P files: GPS = header clock (UTC) + leap + offset\n"
      << "  require_good_ins: " << b(c.ingest.require_good_ins)
      << "   # drop INS samples not INS_SOLUTION_GOOD\n"
      << "georef:\n"
      << "  max_nav_gap_s: " << c.georef.max_nav_gap_s
      << "          # refuse pings across longer INS gaps, s\n"
      << "  min_range_m: " << c.georef.min_range_m << "            # range gate, m\n"
      << "  max_range_m: " << c.georef.max_range_m << "            # range gate, m\n"
      << "  sound_speed_scaling: " << b(c.georef.sound_speed_scaling)
      << "  # r *= c_header / nominal\n"
      << "  nominal_sound_speed_mps: " << c.georef.nominal_sound_speed_mps << "\n"
      << "  apply_profile_tilt: " << b(c.georef.apply_profile_tilt) << "\n"
      << "  spike_half_window: " << c.georef.spike_half_window
      << "      # beams each side of the median; 0 = off\n"
      << "  spike_abs_m: " << c.georef.spike_abs_m
      << "            # spike if |r - median| > abs + rel * median\n"
      << "  spike_rel: " << c.georef.spike_rel << "\n"
      << "  num_threads: " << c.georef.num_threads << "              # 0 = all cores\n"
      << "calibrate:\n"
      << "  segment_start_s: " << c.calibrate.segment_start_s
      << "         # GPS seconds; < 0 = automatic\n"
      << "  segment_duration_s: " << c.calibrate.segment_duration_s << "\n"
      << "  part_duration_s: " << c.calibrate.part_duration_s << "\n"
      << "  min_separation_s: " << c.calibrate.min_separation_s
      << "      # pairs only between soundings this far apart\n"
      << "  beam_stride: " << c.calibrate.beam_stride << "\n"
      << "  max_distance_m: " << c.calibrate.max_distance_m
      << "        # correspondence gate, first iteration\n"
      << "  min_distance_m: " << c.calibrate.min_distance_m << "        # ... last iteration\n"
      << "  normal_radius_m: " << c.calibrate.normal_radius_m << "\n"
      << "  cauchy_scale_m: " << c.calibrate.cauchy_scale_m << "\n"
      << "  max_iterations: " << c.calibrate.max_iterations << "\n"
      << "  convergence_deg: " << c.calibrate.convergence_deg << "\n"
      << "  max_position_stddev_m: " << c.calibrate.max_position_stddev_m << " # low-drift limit\n"
      << "  max_heading_stddev_deg: " << c.calibrate.max_heading_stddev_deg << "\n"
      << "  num_verify_segments: " << c.calibrate.num_verify_segments << "\n"
      << "  estimate_height_offsets: " << b(c.calibrate.estimate_height_offsets)
      << "  # per-node INS height corrections (else parallel passes bias roll)\n"
      << "  height_offset_sigma_m: " << c.calibrate.height_offset_sigma_m << "  # their prior\n"
      << "  range_noise_fraction: " << c.calibrate.range_noise_fraction
      << "  # pair weights 1/sigma^2, sigma = fraction * range + constant\n"
      << "  range_noise_constant_m: " << c.calibrate.range_noise_constant_m << "\n"
      << "products:\n"
      << "  write_las: " << b(c.write_las) << "\n"
      << "  vehicle_yaml: \"\"          # \"\" = vehicle.yaml beside the first log\n"
      << "  origin:                    # world origin; absent = first INS position\n"
      << "    latitude_deg: null\n    longitude_deg: null\n    height_m: null\n";
    return o.str();
}

namespace {

json CountsJson(const io::IngestCounts& c) {
    json j = {{"files", c.files},
              {"bytes", c.bytes},
              {"events", c.events},
              {"corrupt_events", c.corrupt_events},
              {"resync_bytes", c.resync_bytes},
              {"truncated_events", c.truncated_events},
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

json MountJson(const georef::SonarMount& m) {
    return {{"roll_deg", m.boresight_roll_deg},
            {"pitch_deg", m.boresight_pitch_deg},
            {"yaw_deg", m.boresight_yaw_deg},
            {"lever_arm_sonar_m", {m.lever_arm_m.x(), m.lever_arm_m.y(), m.lever_arm_m.z()}},
            {"convention", "R_vehicle_sonar = Rz(yaw) Ry(pitch) Rx(roll), vehicle FRD"}};
}

double Since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
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

}  // namespace

Expected<std::string> Info(const std::vector<std::string>& inputs, const PipelineConfig& config) {
    auto files = io::ExpandInputs(inputs);
    if (!files) return files.error();
    auto r = io::IngestFiles(*files, config.ingest);
    if (!r) return r.error();
    std::ostringstream o;
    for (const auto& f : *files) o << "file " << f << "\n";
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
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) return Error{out_dir + ": cannot create: " + ec.message()};
    auto files = io::ExpandInputs(inputs);
    if (!files) return files.error();
    // Vehicle config: given, or beside the first input.
    std::string vpath = config.vehicle_yaml;
    if (vpath.empty()) {
        const fs::path first = fs::path(files->front()).parent_path() / "vehicle.yaml";
        if (fs::exists(first)) vpath = first.string();
    }
    georef::SonarMount mount;
    io::IngestConfig icfg = config.ingest;
    json summary;
    if (auto old = io::ReadJsonFile(out_dir + "/summary.json")) summary = *old;
    if (vpath.empty()) {
        log("warning: no vehicle.yaml found beside " + files->front() +
            ": lever arm and boresight default to zero (give products.vehicle_yaml)");
    } else {
        auto v = io::ReadVehicleYaml(vpath);
        if (!v) return v.error();
        for (const auto& m : v->missing) log("warning: " + vpath + ": missing " + m + " (using 0)");
        mount = v->mount;
        if (icfg.nav_channel_id.empty()) icfg.nav_channel_id = v->navigation_channel;
        if (icfg.sonar_channel_id.empty()) icfg.sonar_channel_id = v->sonar_channel;
        summary["vehicle_yaml"] = fs::absolute(vpath).string();
    }

    auto t0 = std::chrono::steady_clock::now();
    ProgressReporter bar("ingest", 1000);
    auto ing = io::IngestFiles(*files, icfg, bar.AsCallback());
    bar.Finish();
    if (!ing) return ing.error();
    const double ingest_s = Since(t0);
    log("ingest: " + ing->message);
    summary["stages"]["ingest"] = CountsJson(ing->counts);
    summary["stages"]["ingest"]["seconds"] = ingest_s;
    summary["stages"]["ingest"]["peak_rss_mb"] = io::PeakRssMb();
    summary["stages"]["ingest"]["nav_from_raw"] = ing->nav_from_raw;
    summary["stages"]["ingest"]["pings_from_raw"] = ing->pings_from_raw;
    if (ing->nav.samples.empty())
        return Error{"no INS navigation in the inputs (" + files->front() + " ...)"};
    if (ing->pings.pings.empty())
        return Error{"no sonar pings in the inputs (" + files->front() + " ...)"};

    t0 = std::chrono::steady_clock::now();
    std::optional<Geodetic> origin;
    if (!std::isnan(config.origin_latitude_deg)) {
        origin = Geodetic{
            config.origin_latitude_deg, config.origin_longitude_deg, config.origin_height_m};
    }
    ProgressReporter gbar("georef", 1000);
    georef::GeorefResult geo =
        georef::RunGeoref(ing->nav, ing->pings, mount, config.georef, origin, gbar.AsCallback());
    gbar.Finish();
    const double georef_s = Since(t0);
    log("georef: " + geo.message);
    summary["stages"]["georef"] = CountsJson(geo.counts);
    summary["stages"]["georef"]["seconds"] = georef_s;
    summary["stages"]["georef"]["peak_rss_mb"] = io::PeakRssMb();
    summary["world_origin"] = {{"latitude_deg", geo.world_origin.latitude_deg},
                               {"longitude_deg", geo.world_origin.longitude_deg},
                               {"height_m", geo.world_origin.height_m}};
    summary["inputs"] = json::array();
    for (const auto& f : *files) summary["inputs"].push_back(fs::absolute(f).string());
    summary["mount"] = MountJson(mount);

    t0 = std::chrono::steady_clock::now();
    if (auto s = WritePoints(out_dir, geo, config, summary); !s) return s;
    if (auto s = io::WriteTrajectoryCsv(out_dir + "/trajectory.csv", ing->nav, geo.world_origin);
        !s)
        return s;
    if (auto s = io::WriteJsonFile(out_dir + "/boresight.json", MountJson(mount)); !s) return s;
    if (auto s = io::WriteIngestCache(out_dir + "/ingest.cache", *ing); !s) return s;
    summary["stages"]["export"] = {
        {"seconds", Since(t0)}, {"peak_rss_mb", io::PeakRssMb()}, {"points", geo.counts.points}};
    return io::WriteJsonFile(out_dir + "/summary.json", summary);
}

Status RunCalibrateStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto summary = io::ReadJsonFile(out_dir + "/summary.json");
    if (!summary) return Error{summary.error().message + " (run `pitmap georef` first)"};
    json& s = *summary;
    if (!s.contains("world_origin") || !s.contains("mount")) {
        return Error{out_dir + "/summary.json: no world_origin/mount (run `pitmap georef` first)"};
    }
    auto ing = io::ReadIngestCache(out_dir + "/ingest.cache");
    if (!ing) return ing.error();
    georef::SonarMount mount;
    try {
        const json& m = s["mount"];
        mount.boresight_roll_deg = m.at("roll_deg").get<double>();
        mount.boresight_pitch_deg = m.at("pitch_deg").get<double>();
        mount.boresight_yaw_deg = m.at("yaw_deg").get<double>();
        const auto arm = m.at("lever_arm_sonar_m").get<std::vector<double>>();
        if (arm.size() != 3) throw std::runtime_error("lever arm");
        mount.lever_arm_m = Eigen::Vector3d(arm[0], arm[1], arm[2]);
    } catch (const std::exception&) {
        return Error{out_dir + "/summary.json: malformed mount"};
    }
    const json& o = s["world_origin"];
    const Geodetic origin{
        o.value("latitude_deg", 0.0), o.value("longitude_deg", 0.0), o.value("height_m", 0.0)};
    auto t0 = std::chrono::steady_clock::now();
    georef::GeorefResult geo =
        georef::RunGeoref(ing->nav, ing->pings, mount, config.georef, origin);
    ProgressReporter bar("calibrate", 1000);
    calib::BoresightResult cal =
        calib::CalibrateBoresight(geo, ing->nav, mount, config.calibrate, bar.AsCallback());
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
        {"boresight_before", MountJson(mount)},
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
        st["seconds"] = Since(t0);
        s["stages"]["calibrate"] = st;
        (void)io::WriteJsonFile(out_dir + "/summary.json", s);
        return Error{"calibrate: " + cal.message};
    }
    georef::Regeoreference(geo, cal.mount);
    st["seconds"] = Since(t0);
    st["peak_rss_mb"] = io::PeakRssMb();
    s["stages"]["calibrate"] = st;
    s["mount"] = MountJson(cal.mount);
    if (auto w = WritePoints(out_dir, geo, config, s); !w) return w;
    if (auto w = io::WriteJsonFile(out_dir + "/boresight.json", MountJson(cal.mount)); !w) return w;
    return io::WriteJsonFile(out_dir + "/summary.json", s);
}

}  // namespace pitmap::proc::pipeline
