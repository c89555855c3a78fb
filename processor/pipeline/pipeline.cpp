// SPDX-License-Identifier: MIT
#include "processor/pipeline/pipeline.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <sstream>

#include "common/config.hpp"
#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/peak_memory.hpp"
#include "common/progress.hpp"
#include "processor/calib/sonar_clock.hpp"
#include "processor/io/products.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/result_json.hpp"
#include "processor/pipeline/survey.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// summary["time"]: GPS - UTC for the survey (the receiver's TIME log when it logged one, else
// common/gps_time's leap-second table) and the pings' span in both scales. The report turns GPS
// seconds into UTC with it, so the table exists once (in C++).
json TimeJson(const io::IngestResult& ing) {
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
// input, else "".
std::string VehicleFilePath(const std::vector<std::string>& files, const PipelineConfig& config) {
    if (!config.vehicle_yaml.empty() || files.empty()) return config.vehicle_yaml;
    const fs::path beside = fs::path(files.front()).parent_path() / "vehicle.yaml";
    return fs::exists(beside) ? beside.string() : "";
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

double StageClock::seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void RecordStage(json& summary, Stage stage_id, json stage, const StageClock& clock) {
    const std::string name = ToString(stage_id);
    stage["seconds"] = clock.seconds();
    stage["cpu_seconds"] = clock.cpu_seconds();
    stage["peak_rss_mb"] = PeakRssMb();
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

void TripGate(Survey& s,
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

void ClearGates(Survey& s, Stage stage_id) {
    const std::string stage = ToString(stage_id);
    if (!s.summary.contains("quality_gates") || !s.summary["quality_gates"].is_array()) return;
    json kept = json::array();
    for (const auto& g : s.summary["quality_gates"]) {
        if (!(g.is_object() && g.value("stage", "") == stage)) kept.push_back(g);
    }
    s.summary["quality_gates"] = std::move(kept);
}

namespace {

std::string Num(const char* fmt, double v) {
    char b[64];
    std::snprintf(b, sizeof(b), fmt, v);
    return b;
}

// The offset (sonar clock minus UTC, as configured) that would have needed no further
// correction: ingest subtracts the offset from the header time, the correction is added.
double ImpliedClockOffset(double configured_offset_s, double correction_s) {
    return configured_offset_s - correction_s;
}

}  // namespace

Status ClockSurvey(Survey& s, const PipelineConfig& config, const Log& log) {
    georef::PingSeries& pings = s.model.ingest.pings;
    const georef::NavSeries& nav = s.model.ingest.nav;
    const QualityConfig& q = config.quality;
    const bool header = pings.clock == georef::PingClock::kTopsideHeader;
    json clk = {{"source",
                 header ? "83P header: the topside PC clock (offset unknown)"
                        : "pitmap-acqd: GPS-disciplined receive stamps"},
                {"configured", config.ingest.sonar_clock_offset_known}};
    if (config.ingest.sonar_clock_offset_known)
        clk["configured_offset_s"] = config.ingest.sonar_clock_offset_s;
    double applied = 0;
    // What is left for the calibration's latency scan: the coarse estimate's uncertainty, or
    // half a second around a configured offset or the daemon's stamps.
    double sigma = 0.0;
    const std::string nav_span =
        calib::SpanText(nav.samples.front().utime_gps, nav.samples.back().utime_gps);
    if (header) {
        calib::ClockSearchConfig search;
        // The NMEA position in the headers is the (first) GNSS antenna's.
        if (s.vehicle && !s.vehicle->gnss_antenna_lever_arms_m.empty())
            search.antenna_lever_arm_m = s.vehicle->gnss_antenna_lever_arms_m.front();
        const calib::ClockEstimate est = calib::EstimateSonarClock(pings, nav, search);
        log("sonar clock: " + est.message);
        clk["coarse"] = {{"method", est.method},
                         {"found", est.found},
                         {"correction_s", est.correction_s},
                         {"sigma_s", est.sigma_s},
                         {"misfit", est.misfit},
                         {"samples", est.samples},
                         {"message", est.message}};
        const std::string sonar_span =
            calib::SpanText(pings.pings.front().utime_gps, pings.pings.back().utime_gps);
        if (config.ingest.sonar_clock_offset_known) {
            const double tol = std::max(3 * est.sigma_s, q.clock_disagreement_s);
            if (est.found && est.method != "span" && std::abs(est.correction_s) > tol) {
                TripGate(s,
                         Stage::kGeoref,
                         "sonar_clock_disagrees",
                         "the configured sonar clock offset is " +
                             Num("%+.3f", config.ingest.sonar_clock_offset_s) + " s, the " +
                             est.method + " in the 83P headers implies " +
                             Num("%+.3f",
                                 ImpliedClockOffset(config.ingest.sonar_clock_offset_s,
                                                    est.correction_s)) +
                             " s (+- " + Num("%.3f", est.sigma_s) +
                             " s); the configured value is used",
                         log);
            }
            sigma = 0.1;
        } else {
            const std::string give =
                "; give the offset (--sonar-clock-offset S, or sonar.clock_offset_s in "
                "vehicle.yaml: the sonar clock minus UTC). Navigation: " +
                nav_span + "; sonar, on its own clock: " + sonar_span;
            if (!est.found) return Error{"sonar clock: " + est.message + give};
            if (est.sigma_s > q.max_clock_scan_s) {
                return Error{"sonar clock: " + est.message + ": more uncertain than the " +
                             Num("%.1f", q.max_clock_scan_s) +
                             " s the data can resolve (quality.max_clock_scan_s)" + give};
            }
            georef::ShiftPingTimes(pings, est.correction_s);
            applied = est.correction_s;
            sigma = est.sigma_s;
        }
    } else {
        sigma = 0.0;  // ms: the calibration's linear range covers it
    }
    clk["correction_s"] = applied;
    clk["sigma_s"] = sigma;
    s.summary["sonar_clock"] = clk;
    s.model.clock = {};
    s.model.clock.configured = config.ingest.sonar_clock_offset_known;
    s.model.clock.configured_offset_s =
        config.ingest.sonar_clock_offset_known ? config.ingest.sonar_clock_offset_s : 0.0;
    s.model.clock.coarse_correction_s = applied;
    s.model.clock.coarse_sigma_s = sigma;
    // The two recordings must overlap in time.
    const std::int64_t p0 = pings.pings.front().utime_gps, p1 = pings.pings.back().utime_gps;
    const std::int64_t n0 = nav.samples.front().utime_gps, n1 = nav.samples.back().utime_gps;
    if (p1 < n0 || p0 > n1) {
        return Error{"navigation and sonar do not overlap in time: navigation " + nav_span +
                     ", sonar " + calib::SpanText(p0, p1) +
                     (header ? " (sonar clock corrected by " + Num("%+.3f", applied) + " s)"
                             : std::string())};
    }
    return Ok{};
}

Expected<Survey> LoadSurvey(const std::string& out_dir,
                            const PipelineConfig& config,
                            StartFrom start,
                            const Log& log) {
    Survey s;
    s.out_dir = out_dir;
    auto model = survey::LoadSurvey(out_dir + "/" + survey::kSurveyFileName);
    if (!model) return model.error();
    s.model = std::move(*model);
    // The report this stage adds to; a damaged one is started again (it decides nothing).
    if (auto summary = io::ReadSummaryJson(out_dir + "/summary.json"); summary) {
        s.summary = std::move(*summary);
    } else {
        log("warning: " + summary.error().message + "; summary.json is written anew");
        s.summary = json::object();
    }
    auto refraction = survey::BuildRefraction(s.model.refraction);
    if (!refraction) {
        return Error{out_dir + "/" + survey::kSurveyFileName +
                     ": the sound-velocity casts georef used: " + refraction.error().message};
    }
    s.refraction = *refraction;
    if (s.refraction) {
        log("refraction: " + std::to_string(s.refraction->casts().size()) +
            " cast(s) as georef used them");
    }
    if (start == StartFrom::kNominal) s.model.ResetCalibration();
    if (start == StartFrom::kBeforeSlam) s.model.DropFrom(survey::TrajectoryVersion::kSlam);
    std::size_t kept = 0;
    s.geo = survey::Georeference(s.model, s.model.latest(), config.georef, s.refraction, {}, &kept);
    if (kept > 0) {
        log("warning: " + std::to_string(kept) + " pings have no pose in the survey's " +
            survey::ToString(s.model.latest()) + " trajectory and keep the navigation's");
    }
    return s;
}

Status SaveSurvey(const Survey& s) {
    if (auto w = survey::SaveSurvey(s.out_dir + "/" + survey::kSurveyFileName, s.model); !w)
        return w;
    return SaveSummary(s);
}

Status ExportSurvey(Survey& s, const PipelineConfig& config, bool points) {
    StageClock clock;
    if (points) {
        if (auto w = WritePoints(s.out_dir, s.geo, config, s.summary); !w) return w;
    } else if (auto utm = georef::ToUtm(s.geo); utm) {
        s.summary["utm"] = {{"zone", utm->zone}, {"northern", utm->northern}, {"epsg", utm->epsg}};
    }
    json bj = MountJson(s.model.mount);
    bj["sonar_clock"] = s.summary.value("sonar_clock", json::object());
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

Status CalibrateSurvey(Survey& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    ClearGates(s, Stage::kCalibrate);
    // Calibrate from the nominal state: an earlier calibration's mount and latency are undone.
    if (s.model.ResetCalibration()) {
        log("calibrate: starting again from the nominal mount and sonar clock");
        s.geo = survey::Georeference(
            s.model, survey::TrajectoryVersion::kIns, config.georef, s.refraction);
    }
    const georef::SonarMount before = s.model.mount;
    const QualityConfig& q = config.quality;
    calib::BoresightConfig bc = config.calibrate;
    const bool header = s.model.ingest.pings.clock == georef::PingClock::kTopsideHeader;
    json& clk = s.summary["sonar_clock"];
    if (!clk.is_object()) clk = json::object();
    const double clock_sigma = s.model.clock.coarse_sigma_s;
    if (bc.estimate_latency) {
        // The pings carry the coarse correction already; scan what it leaves (4 sigma).
        bc.initial_latency_s = 0;
        bc.latency_scan_s = header ? std::clamp(4 * clock_sigma, 0.25, q.max_clock_scan_s) : 0.0;
    }
    ProgressReporter bar(ToString(Stage::kCalibrate), 1000);
    calib::BoresightResult cal =
        calib::CalibrateBoresight(s.geo, s.model.ingest.nav, s.model.mount, bc, bar.AsCallback());
    bar.Finish();
    log("calibrate: " + cal.message);
    json st = {
        {"termination", calib::ToString(cal.termination)},
        {"iterations", cal.iterations},
        {"message", cal.message},
        {"segment", cal.segment},
        {"residual_before_rms_m", cal.before.rms_m},
        {"residual_after_rms_m", cal.after.rms_m},
        {"residual_expected_rms_m", cal.after.expected_rms_m},
        {"pairs", cal.after.pairs},
        {"formal_sd_deg", {cal.formal_sd_deg[0], cal.formal_sd_deg[1], cal.formal_sd_deg[2]}},
        {"height_offsets_rms_m", cal.height_offsets_rms_m},
        {"latency_estimated", cal.latency_estimated},
        {"latency_s", cal.latency_s},
        {"latency_formal_sd_s", cal.latency_formal_sd_s},
        {"latency_scan_s", bc.latency_scan_s},
        {"latency_scan_best_s", cal.latency_scan_best_s},
        {"boresight_before", MountJson(before)},
        {"boresight_after", MountJson(cal.mount)}};
    st["verify"] = json::array();
    // The calibrated latency must not fit another segment worse than the nominal one by more
    // than this fraction (pair sampling moves the RMS by ~1 %; a 100 ms clock step on the demo
    // moves it by 18 %).
    constexpr double kLatencyVerifyMargin = 0.02;
    bool verified = true;
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
        if (v.after.pairs > 0 && v.before.pairs > 0 && v.after.rms_m > v.before.rms_m)
            verified = false;
        if (v.after.pairs > 0 && v.after_nominal_latency.pairs > 0 &&
            v.after.rms_m > (1.0 + kLatencyVerifyMargin) * v.after_nominal_latency.rms_m) {
            st["verify"].back()["rms_nominal_latency_m"] = v.after_nominal_latency.rms_m;
            log("verify: the calibrated latency fits this segment worse than the nominal one (" +
                Num("%.4f", v.after.rms_m) + " m against " +
                Num("%.4f", v.after_nominal_latency.rms_m) +
                " m): the sonar clock is not the same across the survey");
            verified = false;
        }
    }
    const bool checked = std::any_of(cal.verify.begin(), cal.verify.end(), [](const auto& v) {
        return v.after.pairs > 0 && v.before.pairs > 0;
    });
    st["verified_on_other_segments"] = checked;
    if (!checked && cal.termination != calib::Termination::kNoOverlap) {
        log("calibrate: not verified: no other segment of the survey with overlapping passes "
            "lies outside the calibration window (calibrate.segment_duration_s " +
            Num("%.0f", bc.segment_duration_s) + " s); the result rests on its own window alone");
    }
    if (cal.termination == calib::Termination::kNoOverlap) {
        s.model.calibration = survey::CalibrationState::kNoOverlap;
        RecordStage(s.summary, Stage::kCalibrate, st, clock);
        if (s.defer_products) {
            (void)SaveSummary(s);
        } else {
            (void)SaveSurvey(s);
        }
        return Error{"calibrate: " + cal.message};
    }
    if (cal.after.pairs > 0 &&
        cal.after.rms_m > q.calibration_residual_ratio * cal.after.expected_rms_m) {
        TripGate(s,
                 Stage::kCalibrate,
                 "calibration_residual",
                 "residual RMS " + Num("%.4f", cal.after.rms_m) + " m after calibration is " +
                     Num("%.1f", cal.after.rms_m / cal.after.expected_rms_m) +
                     "x what the range noise leaves (" + Num("%.4f", cal.after.expected_rms_m) +
                     " m): the overlapping passes disagree in a way the boresight and latency "
                     "do not explain (sonar clock, lever arm, sound speed or navigation)",
                 log);
    }
    if (cal.latency_unresolved) {
        TripGate(s,
                 Stage::kCalibrate,
                 "sonar_clock_unresolved",
                 "the sonar latency was still moving when the calibration ended (at " +
                     Num("%+.3f", cal.latency_s) +
                     " s): the sonar clock is off by more than the soundings can resolve; the "
                     "nominal mount and clock are kept (give --sonar-clock-offset)",
                 log);
    }
    const bool keep_nominal = !verified || cal.latency_unresolved;
    if (!verified) {
        TripGate(s,
                 Stage::kCalibrate,
                 "calibration_not_verified",
                 "the calibrated mount or latency fits other segments worse than the nominal "
                 "one: the nominal mount and sonar clock are kept",
                 log);
    }
    if (keep_nominal) {
        cal.mount = before;
        cal.latency_s = 0;
    }
    st["kept_nominal"] = keep_nominal;
    s.model.mount = cal.mount;
    s.model.calibration = keep_nominal ? survey::CalibrationState::kKeptNominal
                                       : survey::CalibrationState::kCalibrated;
    survey::SonarClockState& mc = s.model.clock;
    if (cal.latency_estimated && !keep_nominal) {
        mc.latency_applied = true;
        mc.latency_s = cal.latency_s;
        mc.latency_formal_sd_s = cal.latency_formal_sd_s;
    }
    if (mc.latency_applied && cal.latency_s != 0.0) {
        // The ping times themselves change: georeference again from the ingested series.
        georef::ShiftPingTimes(s.model.ingest.pings, cal.latency_s);
        s.geo = georef::RunGeoref(s.model.ingest.nav,
                                  s.model.ingest.pings,
                                  s.model.mount,
                                  config.georef,
                                  s.model.origin,
                                  {},
                                  s.refraction);
    } else {
        georef::Regeoreference(s.geo, cal.mount);
    }
    if (!keep_nominal) {
        s.model.trajectory(survey::TrajectoryVersion::kCalibrated) =
            survey::TrajectoryOf(s.geo, s.model.ingest.pings.pings.size());
    }
    clk["latency_s"] = mc.latency_applied ? mc.latency_s : 0.0;
    clk["latency_formal_sd_s"] = cal.latency_formal_sd_s;
    clk["correction_s"] = mc.correction_s();
    clk["sigma_s"] = mc.sigma_s();
    if (mc.configured && header) {
        // In the configured offset's own terms: the offset that would have needed no correction.
        const double implied = ImpliedClockOffset(mc.configured_offset_s, mc.correction_s());
        clk["estimated_offset_s"] = implied;
        if (mc.latency_applied && std::abs(cal.latency_s) > std::max(q.clock_disagreement_s,
                                                                     3 * cal.latency_formal_sd_s)) {
            TripGate(s,
                     Stage::kCalibrate,
                     "sonar_clock_disagrees",
                     "the configured sonar clock offset is " +
                         Num("%+.4f", mc.configured_offset_s) + " s, the soundings put it at " +
                         Num("%+.4f", implied) + " s; the soundings' value is applied",
                     log);
        }
    }
    s.summary["mount"] = MountJson(cal.mount);
    RecordStage(s.summary, Stage::kCalibrate, st, clock);
    return s.defer_products ? SaveSummary(s) : ExportSurvey(s, config);
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
    const std::string vpath = VehicleFilePath(*files, config);
    io::IngestConfig icfg = config.ingest;
    // A new georeference starts a new survey model and a new report.
    s.model = survey::SurveyModel{};
    s.summary = json::object();
    std::optional<double> ins_height_m;
    if (vpath.empty()) {
        log("warning: no vehicle.yaml found beside " + files->front() +
            ": lever arm and boresight default to zero (give --vehicle FILE)");
    } else {
        auto v = io::ReadVehicleYaml(vpath);
        if (!v) return v.error();
        s.model.mount = v->mount;
        s.model.nominal_mount = v->mount;
        s.model.vehicle_yaml = fs::absolute(vpath).string();
        s.vehicle = v->description;
        ins_height_m = v->description.ins_height_above_waterline_m;
        ApplyVehicle(v->description, icfg);
        s.summary["vehicle_yaml"] = fs::absolute(vpath).string();
        s.summary["vehicle"] = io::VehicleJson(v->description);
    }
    if (auto r = SetUpRefraction(s, config, ins_height_m, log); !r) return r;
    // The configured offset (sonar clock minus UTC), null when the clock is to be found.
    s.summary["sonar_clock_offset_s"] =
        icfg.sonar_clock_offset_known ? json(icfg.sonar_clock_offset_s) : json(nullptr);

    StageClock ingest_clock;
    ProgressReporter bar(ToString(Stage::kIngest), 1000);
    auto ing = io::IngestFiles(*files, icfg, bar.AsCallback());
    bar.Finish();
    if (!ing) return ing.error();
    s.model.ingest = std::move(*ing);
    for (const auto& w : s.model.ingest.warnings) log("warning: " + w);
    log("ingest: " + s.model.ingest.message);
    json ist = s.model.ingest.counts;
    ist["warnings"] = s.model.ingest.warnings;
    ist["nav_from_raw"] = s.model.ingest.nav_from_raw;
    ist["pings_from_raw"] = s.model.ingest.pings_from_raw;
    RecordStage(s.summary, Stage::kIngest, ist, ingest_clock);
    if (s.model.ingest.nav.samples.empty())
        return Error{"no INS navigation in the inputs (" + files->front() + " ...)"};
    if (s.model.ingest.pings.pings.empty())
        return Error{"no sonar pings in the inputs (" + files->front() + " ...)"};

    PipelineConfig resolved = config;  // with what the vehicle file gave
    resolved.ingest = icfg;
    if (auto c = ClockSurvey(s, resolved, log); !c) {
        (void)SaveSummary(s);
        return c;
    }

    StageClock georef_clock;
    std::optional<Geodetic> origin;
    if (!std::isnan(config.origin_latitude_deg)) {
        origin = Geodetic{
            config.origin_latitude_deg, config.origin_longitude_deg, config.origin_height_m};
    }
    ProgressReporter gbar(ToString(Stage::kGeoref), 1000);
    s.geo = georef::RunGeoref(s.model.ingest.nav,
                              s.model.ingest.pings,
                              s.model.mount,
                              config.georef,
                              origin,
                              gbar.AsCallback(),
                              s.refraction);
    gbar.Finish();
    log("georef: " + s.geo.message);
    if (const std::int64_t out = s.geo.counts.pings_outside_nav; out > 0) {
        const auto& P = s.model.ingest.pings.pings;
        const auto& N = s.model.ingest.nav.samples;
        const std::string what =
            std::to_string(out) + " of " + std::to_string(P.size()) +
            " pings lie outside the navigation span and are not georeferenced: navigation " +
            calib::SpanText(N.front().utime_gps, N.back().utime_gps) + ", sonar " +
            calib::SpanText(P.front().utime_gps, P.back().utime_gps);
        if (static_cast<double>(out) >
            config.quality.max_outside_nav_fraction * static_cast<double>(P.size())) {
            TripGate(s, Stage::kGeoref, "pings_outside_navigation", what, log);
        } else {
            log("warning: " + what);
        }
    }
    s.model.origin = s.geo.world_origin;
    s.model.trajectory(survey::TrajectoryVersion::kIns) =
        survey::TrajectoryOf(s.geo, s.model.ingest.pings.pings.size());
    RecordStage(s.summary, Stage::kGeoref, s.geo.counts, georef_clock);
    s.summary["world_origin"] = survey::OriginJson(s.model.origin);
    s.summary["time"] = TimeJson(s.model.ingest);
    s.summary["inputs"] = json::array();
    for (const auto& f : *files) s.summary["inputs"].push_back(fs::absolute(f).string());
    s.summary["mount"] = MountJson(s.model.mount);

    // Products of an earlier georeference, now stale (the survey file is replaced below).
    for (const char* stale : {"ingest.cache",  // the survey file's predecessor
                              "trajectory.csv",
                              "trajectory_initial.csv",
                              "points_initial.ply",
                              "tsdf.vdb",
                              "mesh.ply",
                              "mesh.obj",
                              "mesh.glb",
                              "mesh_filled.ply",
                              "mesh_filled.obj",
                              "mesh_filled.glb",
                              "mesh_initial.ply",
                              "dem.tif",
                              "dem.bag",
                              "soundings_tpu.ply",
                              "report.html"}) {
        fs::remove(fs::path(out_dir) / stale, ec);
    }
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
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kNominal, log);
    if (!s) return s.error();
    return detail::CalibrateSurvey(*s, config, log);
}

}  // namespace pitmap::proc::pipeline
