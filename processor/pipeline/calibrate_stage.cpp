// SPDX-License-Identifier: MIT
// The sensor-model stages: the sonar clock check at georeference time (ClockSurvey) and the
// calibration of the mount and the ping latency (CalibrateSurvey, `pitmap calibrate`). Both end
// in the survey model's calibrated state and a regeoreference; the stage bodies around them
// (ingest, georef, export) are in pipeline.cpp.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/frames.hpp"
#include "common/peak_memory.hpp"
#include "common/progress.hpp"
#include "processor/calib/boresight_blocks.hpp"
#include "processor/calib/sonar_clock.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/pipeline.hpp"
#include "processor/pipeline/result_json.hpp"

namespace pitmap::proc::pipeline {

using nlohmann::json;

namespace detail {

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

// The rotation a calibration added to the nominal mount, as roll, pitch, yaw (deg) about the
// vehicle's axes: R_after = R_change * R_before.
Eigen::Vector3d MountChangeDeg(const survey::SonarMount& before, const survey::SonarMount& after) {
    const Eigen::Matrix3d R = after.R_vehicle_sonar() * before.R_vehicle_sonar().transpose();
    const frames::Rpy d = frames::RpyFromRotationNed(R);
    return {frames::RadToDeg(d.roll), frames::RadToDeg(d.pitch), frames::RadToDeg(d.yaw)};
}

// What a boresight change beyond a mount's tolerance most likely comes from, by its largest
// axis: pitch is an along-track disagreement of opposite passes, roll an across-track tilt,
// yaw a turned head.
std::string LikelyMountCause(const Eigen::Vector3d& change_deg) {
    Eigen::Index axis = 0;
    change_deg.cwiseAbs().maxCoeff(&axis);
    switch (axis) {
        case 0:
            return "an across-track tilt between passes: the connector direction "
                   "(sonar.mount.connector: a head turned by 180 deg mirrors the fan), the lever "
                   "arm's y, or the sound speed";
        case 1:
            return "an along-track disagreement between opposite passes: the lever arm's x (its "
                   "sign or its value, sonar.lever_arm_m), or the sonar clock";
        default:
            return "a turned head: the connector direction (sonar.mount.connector) or an INS "
                   "heading offset";
    }
}

// The header clock search's settings for this vehicle: the NMEA position in the headers is
// the (first) GNSS antenna's.
calib::ClockSearchConfig HeaderSearch(const StageContext& s) {
    calib::ClockSearchConfig search;
    if (s.vehicle && !s.vehicle->gnss_antenna_lever_arms_m.empty())
        search.antenna_lever_arm_m = s.vehicle->gnss_antenna_lever_arms_m.front();
    return search;
}

// A configured offset checked against the 83P headers' aids: with it, the header positions
// must lie where the INS antenna was (an error otherwise), and an estimate that disagrees trips
// sonar_clock_disagrees (the configured value is used).
Status CheckConfiguredOffset(StageContext& s,
                             const PipelineConfig& config,
                             const calib::ClockEstimate& est,
                             const calib::ClockSearchConfig& search,
                             const std::string& nav_span,
                             const Log& log) {
    const double offset = config.ingest.sonar_clock_offset_s;
    const double at_configured =
        calib::HeaderPositionMisfit(s.model.ingest.pings, s.model.ingest.nav, 0.0, search);
    if (std::isfinite(at_configured) && at_configured > search.max_position_misfit_m) {
        return Error{"sonar clock: with the configured offset (" + Num("%+.3f", offset) +
                     " s) the 83P header positions lie a median " + Num("%.1f", at_configured) +
                     " m from the INS antenna (limit " + Num("%.1f", search.max_position_misfit_m) +
                     " m); " +
                     (est.found
                          ? "the headers put the offset at " +
                                Num("%+.3f", ImpliedClockOffset(offset, est.correction_s)) + " s"
                          : "at no offset do they match the navigation (best " +
                                Num("%.1f", est.misfit) + " m): is this .83P of this survey?") +
                     ". Navigation: " + nav_span};
    }
    const double tol = std::max(3 * est.sigma_s, config.quality.clock_disagreement_s);
    if (est.found && est.method != "span" && std::abs(est.correction_s) > tol) {
        TripGate(s,
                 Stage::kGeoref,
                 "sonar_clock_disagrees",
                 "the configured sonar clock offset is " + Num("%+.3f", offset) + " s, the " +
                     est.method + " in the 83P headers implies " +
                     Num("%+.3f", ImpliedClockOffset(offset, est.correction_s)) + " s (+- " +
                     Num("%.3f", est.sigma_s) + " s); the configured value is used",
                 log);
    }
    return Ok{};
}

// The coarse clock from the 83P headers' aids (calib::EstimateSonarClock): with a configured
// offset, checked against it; without, applied to the pings (an error when not found or more
// uncertain than max_clock_scan_s). `applied` and `sigma` are the correction and what is left
// for the calibration's latency scan.
Status CoarseHeaderClock(StageContext& s,
                         const PipelineConfig& config,
                         const std::string& nav_span,
                         const Log& log,
                         json& clk,
                         double& applied,
                         double& sigma) {
    survey::PingSeries& pings = s.model.ingest.pings;
    const calib::ClockSearchConfig search = HeaderSearch(s);
    const calib::ClockEstimate est = calib::EstimateSonarClock(pings, s.model.ingest.nav, search);
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
        if (auto c = CheckConfiguredOffset(s, config, est, search, nav_span, log); !c) return c;
        sigma = 0.1;
        return Ok{};
    }
    const std::string give =
        "; give the offset (--sonar-clock-offset S, or sonar.clock_offset_s in "
        "vehicle.yaml: the sonar clock minus UTC). Navigation: " +
        nav_span + "; sonar, on its own clock: " + sonar_span;
    if (!est.found) return Error{"sonar clock: " + est.message + give};
    if (est.sigma_s > config.quality.max_clock_scan_s) {
        return Error{"sonar clock: " + est.message + ": more uncertain than the " +
                     Num("%.1f", config.quality.max_clock_scan_s) +
                     " s the data can resolve (quality.max_clock_scan_s)" + give};
    }
    survey::ShiftPingTimes(pings, est.correction_s);
    applied = est.correction_s;
    sigma = est.sigma_s;
    return Ok{};
}

// A step of the topside clock mid-survey (an NTP correction): each side on its own offset
// (calib::FindSonarClockSteps); an error when the header times run backwards.
Status HeaderClockSteps(StageContext& s, const Log& log, json& clk) {
    survey::PingSeries& pings = s.model.ingest.pings;
    calib::ClockStepConfig sc;
    sc.R_vehicle_sonar = s.model.mount.R_vehicle_sonar();
    if (s.vehicle && !s.vehicle->gnss_antenna_lever_arms_m.empty())
        sc.antenna_lever_arm_m = s.vehicle->gnss_antenna_lever_arms_m.front();
    const calib::ClockStepResult steps = calib::FindSonarClockSteps(pings, s.model.ingest.nav, sc);
    log("sonar clock: " + steps.message);
    json js = json::array();
    for (const auto& st : steps.steps) {
        js.push_back({{"ping_index", st.ping_index},
                      {"ping_number", st.ping_number},
                      {"gps_s", static_cast<double>(st.utime) * 1e-6},
                      {"jump_s", st.jump_s},
                      {"step_s", st.step_s},
                      {"sigma_s", st.sigma_s},
                      {"resolved", st.resolved}});
    }
    clk["steps"] = {{"method", steps.method},
                    {"steps", js},
                    {"pauses", steps.pauses},
                    {"backward", steps.backward},
                    {"message", steps.message}};
    if (steps.backward > 0) {
        s.summary["sonar_clock"] = clk;
        return Error{"sonar clock: " + steps.message +
                     ": pitmap cannot order them; split the .83P at the step (or give the "
                     "pings before and after it as separate surveys)"};
    }
    if (!steps.segment_shift_s.empty()) {
        calib::ApplyClockSteps(pings, steps);
        for (const auto& st : steps.steps) {
            if (!st.resolved) continue;
            log("warning: the topside clock steps " + Num("%+.3f", st.step_s) + " s at ping " +
                std::to_string(st.ping_index) + " (number " + std::to_string(st.ping_number) +
                "): the pings on each side get their own offset");
        }
    }
    for (const auto& st : steps.steps) {
        if (st.resolved) continue;
        log("warning: the 83P header times jump " + Num("%+.3f", st.jump_s) + " s at ping " +
            std::to_string(st.ping_index) + " (number " + std::to_string(st.ping_number) +
            "): a pause or a clock step the header aids cannot tell apart");
    }
    return Ok{};
}

// The topside PC's clock also runs at a rate of its own: timed by the head's attitude sensor
// along the whole survey (calib::EstimateSonarClockRate), and taken out of the ping times
// before anything looks at the soundings.
calib::ClockRateEstimate HeaderClockRate(StageContext& s, const Log& log, json& clk) {
    calib::ClockRateConfig rc;
    rc.R_vehicle_sonar = s.model.mount.R_vehicle_sonar();
    const calib::ClockRateEstimate rate =
        calib::EstimateSonarClockRate(s.model.ingest.pings, s.model.ingest.nav, rc);
    log("sonar clock: " + rate.message);
    clk["rate"] = {{"found", rate.found},
                   {"rate_ppm", rate.rate_ppm},
                   {"rate_sigma_ppm", rate.rate_sigma_ppm},
                   {"offset_s", rate.offset_s},
                   {"offset_sigma_s", rate.offset_sigma_s},
                   {"reference_gps_s", static_cast<double>(rate.reference_utime) * 1e-6},
                   {"samples", rate.samples},
                   {"residual_rms_deg", rate.residual_rms_deg},
                   {"message", rate.message}};
    if (rate.found) {
        survey::ShiftPingTimes(
            s.model.ingest.pings, 0.0, rate.rate_ppm * 1e-6, rate.reference_utime);
        clk["rate_ppm"] = rate.rate_ppm;
        clk["rate_sigma_ppm"] = rate.rate_sigma_ppm;
        clk["rate_reference_gps_s"] = static_cast<double>(rate.reference_utime) * 1e-6;
    }
    return rate;
}

// The clock as found, in the summary and in the survey model.
void RecordClock(StageContext& s,
                 const PipelineConfig& config,
                 json clk,
                 double applied,
                 double sigma,
                 const calib::ClockRateEstimate& rate) {
    clk["correction_s"] = applied;
    clk["sigma_s"] = sigma;
    s.summary["sonar_clock"] = std::move(clk);
    s.model.clock = {};
    if (rate.found) {
        s.model.clock.rate_ppm = rate.rate_ppm;
        s.model.clock.rate_sigma_ppm = rate.rate_sigma_ppm;
        s.model.clock.rate_reference_utime = rate.reference_utime;
    }
    s.model.clock.configured = config.ingest.sonar_clock_offset_known;
    s.model.clock.configured_offset_s =
        config.ingest.sonar_clock_offset_known ? config.ingest.sonar_clock_offset_s : 0.0;
    s.model.clock.coarse_correction_s = applied;
    s.model.clock.coarse_sigma_s = sigma;
}

// The calibration's settings for this survey: the pings carry the coarse clock correction
// already, so the latency scan covers what it leaves (4 sigma; none on the daemon's stamps).
calib::BoresightConfig CalibrationConfig(const StageContext& s, const PipelineConfig& config) {
    calib::BoresightConfig bc = config.calibrate;
    if (bc.estimate_latency) {
        const bool header = s.model.ingest.pings.clock == survey::PingClock::kTopsideHeader;
        bc.initial_latency_s = 0;
        bc.latency_scan_s =
            header ? std::clamp(
                         4 * s.model.clock.coarse_sigma_s, 0.25, config.quality.max_clock_scan_s)
                   : 0.0;
    }
    return bc;
}

// summary.json's "calibrate": the fit's figures and the mount before and after.
json CalibrationJson(const calib::BoresightResult& cal,
                     const calib::BoresightConfig& bc,
                     const survey::SonarMount& before) {
    return {{"termination", calib::ToString(cal.termination)},
            {"iterations", cal.iterations},
            {"message", cal.message},
            {"segment", cal.segment},
            {"residual_before_rms_m", cal.before.rms_m},
            {"residual_after_rms_m", cal.after.rms_m},
            {"residual_expected_rms_m", cal.after.expected_rms_m},
            {"pairs", cal.after.pairs},
            {"formal_sd_deg", {cal.formal_sd_deg[0], cal.formal_sd_deg[1], cal.formal_sd_deg[2]}},
            {"ins_attitude_sd_deg",
             {cal.ins_attitude_sd_deg[0], cal.ins_attitude_sd_deg[1], cal.ins_attitude_sd_deg[2]}},
            {"sd_deg", {cal.sd_deg[0], cal.sd_deg[1], cal.sd_deg[2]}},
            {"ins_attitude_sd_reported", cal.ins_attitude_reported},
            {"height_offsets_rms_m", cal.height_offsets_rms_m},
            {"latency_estimated", cal.latency_estimated},
            {"latency_s", cal.latency_s},
            {"latency_formal_sd_s", cal.latency_formal_sd_s},
            {"latency_scan_s", bc.latency_scan_s},
            {"latency_scan_best_s", cal.latency_scan_best_s},
            {"boresight_before", MountJson(before)},
            {"boresight_after", MountJson(cal.mount)}};
}

// The verification on other segments, into st["verify"] and the log: false when the
// calibrated mount fits one of them worse than the nominal one, or the calibrated latency fits
// it worse than the nominal latency by more than kLatencyVerifyMargin (pair sampling moves the
// RMS by ~1 %; a 100 ms clock step on the demo moves it by 18 %).
bool Verified(const calib::BoresightResult& cal,
              const calib::BoresightConfig& bc,
              json& st,
              const Log& log) {
    constexpr double kLatencyVerifyMargin = 0.02;
    st["verify"] = json::array();
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
        log("calibrate: not verified: no other low-drift segment of the survey with overlapping "
            "passes lies outside the calibration window (calibrate.segment_duration_s " +
            Num("%.0f", bc.segment_duration_s) + " s); the result rests on its own window alone");
    }
    return verified;
}

// A calibration that cannot be used: the stage recorded, the survey saved, the run stopped.
Status StopCalibration(StageContext& s,
                       const json& st,
                       const StageClock& clock,
                       const std::string& why) {
    RecordStage(s.summary, Stage::kCalibrate, st, clock);
    if (s.defer_products) {
        (void)SaveSummary(s);
    } else {
        (void)SaveSurvey(s);
    }
    return Error{"calibrate: " + why};
}

// Why a boresight change beyond quality.max_boresight_change_deg is not applied (a mount
// bracket is off by a degree or two: a calibration that turns the head further is absorbing a
// wrong input, a lever arm's sign, the connector, the clock), naming the likely input.
std::string ImplausibleChange(const StageContext& s,
                              const Eigen::Vector3d& change,
                              const calib::BoresightResult& cal,
                              double max_change_deg) {
    return "the calibrated boresight turns the nominal mount by roll " + Num("%+.2f", change.x()) +
           ", pitch " + Num("%+.2f", change.y()) + ", yaw " + Num("%+.2f", change.z()) +
           " deg (sd " + Num("%.2f", cal.sd_deg[0]) + ", " + Num("%.2f", cal.sd_deg[1]) + ", " +
           Num("%.2f", cal.sd_deg[2]) + " deg), beyond the " + Num("%.1f", max_change_deg) +
           " deg a mount can be off (quality.max_boresight_change_deg): not a residual but " +
           LikelyMountCause(change) + ". Check vehicle.yaml" +
           (s.model.vehicle_yaml.empty() ? std::string() : " (" + s.model.vehicle_yaml + ")");
}

// The gates of a usable calibration: the residual against the range noise, and a latency
// still moving at the end.
void GateCalibration(StageContext& s,
                     const calib::BoresightResult& cal,
                     const QualityConfig& q,
                     const Log& log) {
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
}

// The view's soundings for the calibration: read a block at a time from the view's file while
// it is there (decision 033), else the held points. A block that cannot be read is kept in
// `error` (the calibration then saw part of the view; the caller stops).
calib::ViewReader CalibrationView(const StageContext& s, std::size_t block, Status& error) {
    if (!s.spilled_view) return calib::HeldView(s.geo.points);
    calib::ViewReader r;
    r.size = s.spilled_view->size();
    const io::SpilledPoints* file = &*s.spilled_view;
    r.read = [file, block, &error](std::size_t first, std::size_t end, const calib::ViewVisit& v) {
        georef::GeorefPoints points;
        for (std::size_t b = first; b < end; b += block) {
            if (auto st = file->ReadBlock(b, std::min(block, end - b), points); !st) {
                if (error) error = st;
                return false;
            }
            v(points, b, 0, points.size());
        }
        return true;
    };
    return r;
}

// The new mount on the view's soundings (georef::Regeoreference): in place when they are
// held, else a block at a time from the view's file into a new one that replaces it.
Status RemountView(StageContext& s, const PipelineConfig& config, const survey::SonarMount& m) {
    if (!s.spilled_view) {
        georef::Regeoreference(s.geo, m);
        return Ok{};
    }
    const georef::Remount remount(s.geo, m);
    const io::SpilledPoints& old = *s.spilled_view;
    auto writer = io::SpillWriter::Open(
        io::NextViewSpillPath(s.out_dir, old.path()), old.size(), old.with_status());
    if (!writer) return writer.error();
    const std::size_t block = BlockWithinBudget(config.run, ResidentMb());
    georef::GeorefPoints points;
    for (std::size_t b = 0; b < old.size(); b += block) {
        if (auto st = old.ReadBlock(b, block, points); !st) return st;
        remount.Apply(points);
        if (auto st = writer->Append(points); !st) return st;
    }
    auto remounted = writer->Finish();
    if (!remounted) return remounted.error();
    s.spilled_view = std::move(*remounted);  // the old file removed
    return Ok{};
}

// The calibration (or the nominal mount, kept) into the survey model, and the soundings
// georeferenced again: from the ingested series when the ping times change, else with the new
// mount; the view a block at a time through its file (decision 033) when it is there.
Status ApplyCalibration(StageContext& s,
                        const PipelineConfig& config,
                        const calib::BoresightResult& cal,
                        bool keep_nominal,
                        const Log& log) {
    s.model.mount = cal.mount;
    s.model.calibration = keep_nominal ? survey::CalibrationState::kKeptNominal
                                       : survey::CalibrationState::kCalibrated;
    s.model.boresight_sd_deg =
        keep_nominal ? survey::kNoBoresightSd
                     : std::array<double, 3>{cal.sd_deg[0], cal.sd_deg[1], cal.sd_deg[2]};
    survey::SonarClockState& mc = s.model.clock;
    if (cal.latency_estimated && !keep_nominal) {
        mc.latency_applied = true;
        mc.latency_s = cal.latency_s;
        mc.latency_formal_sd_s = cal.latency_formal_sd_s;
    }
    if (mc.latency_applied && cal.latency_s != 0.0) {
        survey::ShiftPingTimes(s.model.ingest.pings, cal.latency_s);
        // The old view is dropped first: the new one is made from the model alone (decision
        // 020), and written to its file as it is made (decision 033).
        if (auto st = GeoreferenceToFile(s, config, s.model.origin, nullptr, {}, log); !st)
            return st;
    } else if (auto st = RemountView(s, config, cal.mount); !st) {
        return Error{"calibrate: " + st.error().message};
    }
    if (!keep_nominal) {
        s.model.trajectory(survey::TrajectoryVersion::kCalibrated) =
            georef::TrajectoryOf(s.geo, s.model.ingest.pings.pings.size());
    }
    return Ok{};
}

// The pings the soundings georeferenced again leave out (a latency correction can move a ping
// out of the navigation's span), into the stage's record and the log; summary.json's
// "soundings" says it again at the end (SoundingsJson).
void RecordPingsLeftOut(const StageContext& s, json& st, const Log& log) {
    const georef::GeorefCounts& c = s.geo.counts;
    st["pings_georeferenced"] = c.pings_georeferenced;
    if (c.pings_georeferenced >= c.pings_in) return;
    log("calibrate: " + std::to_string(c.pings_in - c.pings_georeferenced) + " of " +
        std::to_string(c.pings_in) +
        " pings left out of the georeferenced soundings: " + std::to_string(c.pings_outside_nav) +
        " outside the navigation's span, " + std::to_string(c.pings_in_nav_gap) + " in its gaps, " +
        std::to_string(c.pings_bad_header) + " with a bad header");
}

// The sonar clock after the calibration, in summary.json's "sonar_clock"; with a configured
// offset on header time, in its own terms too (the offset that would have needed no
// correction), and a gate when the soundings' latency disagrees with it.
void RecordCalibratedClock(StageContext& s,
                           const calib::BoresightResult& cal,
                           const QualityConfig& q,
                           const Log& log) {
    const bool header = s.model.ingest.pings.clock == survey::PingClock::kTopsideHeader;
    const survey::SonarClockState& mc = s.model.clock;
    json& clk = s.summary["sonar_clock"];
    clk["latency_s"] = mc.latency_applied ? mc.latency_s : 0.0;
    clk["latency_formal_sd_s"] = cal.latency_formal_sd_s;
    clk["correction_s"] = mc.correction_s();
    clk["sigma_s"] = mc.sigma_s();
    if (!mc.configured || !header) return;
    const double implied = ImpliedClockOffset(mc.configured_offset_s, mc.correction_s());
    clk["estimated_offset_s"] = implied;
    if (mc.latency_applied &&
        std::abs(cal.latency_s) > std::max(q.clock_disagreement_s, 3 * cal.latency_formal_sd_s)) {
        TripGate(s,
                 Stage::kCalibrate,
                 "sonar_clock_disagrees",
                 "the configured sonar clock offset is " + Num("%+.4f", mc.configured_offset_s) +
                     " s, the soundings put it at " + Num("%+.4f", implied) +
                     " s; the soundings' value is applied",
                 log);
    }
}

}  // namespace

Status ClockSurvey(StageContext& s, const PipelineConfig& config, const Log& log) {
    const survey::PingSeries& pings = s.model.ingest.pings;
    const survey::NavSeries& nav = s.model.ingest.nav;
    const bool header = pings.clock == survey::PingClock::kTopsideHeader;
    json clk = {{"source",
                 header ? "83P header: the topside PC clock (offset unknown)"
                        : "pitmap-acqd: GPS-disciplined receive stamps"},
                {"configured", config.ingest.sonar_clock_offset_known}};
    if (config.ingest.sonar_clock_offset_known)
        clk["configured_offset_s"] = config.ingest.sonar_clock_offset_s;
    double applied = 0;
    // What is left for the calibration's latency scan: the coarse estimate's uncertainty, or
    // half a second around a configured offset; 0 for the daemon's stamps (ms: the
    // calibration's linear range covers it).
    double sigma = 0.0;
    const std::string nav_span =
        calib::SpanText(nav.samples.front().utime_gps, nav.samples.back().utime_gps);
    calib::ClockRateEstimate rate;
    if (header) {
        if (auto c = CoarseHeaderClock(s, config, nav_span, log, clk, applied, sigma); !c) return c;
        if (auto c = HeaderClockSteps(s, log, clk); !c) return c;
        rate = HeaderClockRate(s, log, clk);
    }
    RecordClock(s, config, std::move(clk), applied, sigma, rate);
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

Status CalibrateSurvey(StageContext& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    ClearGates(s, Stage::kCalibrate);
    // Calibrate from the nominal state: an earlier calibration's mount and latency are undone.
    if (s.model.ResetCalibration()) {
        log("calibrate: starting again from the nominal mount and sonar clock");
        // The INS trajectory is the current one once the calibration is undone: a new view of
        // the model, written to its file as it is made (decision 033).
        if (auto st = GeoreferenceToFile(s, config, s.model.origin, nullptr, {}, log); !st)
            return st;
    }
    // The calibration reads the view a block at a time from its file (decision 033); a view
    // held (a stage command's) goes there first. Where it cannot, it is read held.
    if (auto sp = SpillView(s); !sp) log("warning: " + sp.error().message + ": the view is held");
    const survey::SonarMount before = s.model.mount;
    const QualityConfig& q = config.quality;
    json& clk = s.summary["sonar_clock"];
    if (!clk.is_object()) clk = json::object();
    const calib::BoresightConfig bc = CalibrationConfig(s, config);
    ProgressReporter bar(ToString(Stage::kCalibrate), 1000);
    Status read_error = Ok{};
    const calib::ViewReader view =
        CalibrationView(s, BlockWithinBudget(config.run, ResidentMb()), read_error);
    calib::BoresightResult cal = calib::CalibrateBoresight(
        s.geo, view, s.model.ingest.nav, s.model.mount, bc, bar.AsCallback());
    bar.Finish();
    if (!read_error) return Error{"calibrate: " + read_error.error().message};
    log("calibrate: " + cal.message);
    json st = CalibrationJson(cal, bc, before);
    if (!cal.ins_attitude_reported && cal.termination != calib::Termination::kNoOverlap) {
        log("calibrate: the navigation reports no roll, pitch or heading sigma in the calibration "
            "window: the boresight's stated sd (sd_deg) is the fit's alone and optimistic (it "
            "leaves out the INS's own attitude error)");
    }
    const bool verified = Verified(cal, bc, st, log);

    if (cal.termination == calib::Termination::kNoOverlap) {
        s.model.calibration = survey::CalibrationState::kNoOverlap;
        TripGate(s,
                 Stage::kCalibrate,
                 "calibration_no_overlap",
                 cal.message +
                     ": the boresight cannot be calibrated on this survey; the nominal "
                     "mount of vehicle.yaml is kept",
                 log);
        return StopCalibration(s, st, clock, cal.message);
    }
    const Eigen::Vector3d change = MountChangeDeg(before, cal.mount);
    st["change_from_nominal_deg"] = {change.x(), change.y(), change.z()};
    if (change.cwiseAbs().maxCoeff() > q.max_boresight_change_deg) {
        s.model.calibration = survey::CalibrationState::kKeptNominal;
        const std::string what = ImplausibleChange(s, change, cal, q.max_boresight_change_deg);
        TripGate(s, Stage::kCalibrate, "boresight_implausible", what, log);
        st["kept_nominal"] = true;
        return StopCalibration(s, st, clock, what);
    }
    GateCalibration(s, cal, q, log);
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
    if (auto a = ApplyCalibration(s, config, cal, keep_nominal, log); !a) return a;
    RecordPingsLeftOut(s, st, log);
    RecordCalibratedClock(s, cal, q, log);
    s.summary["mount"] = MountJson(cal.mount);
    RecordStage(s.summary, Stage::kCalibrate, st, clock);
    return s.defer_products ? SaveSummary(s) : ExportSurvey(s, config);
}

}  // namespace detail

Status RunCalibrateStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    // The calibration reads the view from its file: made there, never held (decision 041).
    auto s = detail::LoadSurveyReplacing(
        out_dir, config, detail::StartFrom::kNominal, Stage::kCalibrate, log);
    if (!s) return s.error();
    return detail::CalibrateSurvey(*s, config, log);
}

}  // namespace pitmap::proc::pipeline
