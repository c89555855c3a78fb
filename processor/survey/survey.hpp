// SPDX-License-Identifier: MIT
// The survey model: the state the processing stages share, in memory and in one versioned
// binary file in the products folder (survey_file.hpp). The products folder holds outputs;
// summary.json is a report that no stage reads to decide what to do; the stages decide on this.
//
//   ingest        the navigation and the pings in GPS time, after the sonar clock correction
//                 (the ping series keeps the sonar-frame ranges; the range gate and the spike
//                 filter are the georeferencing's and are applied once per view)
//   vehicle       the vehicle file's path and the nominal mount; the current mount (calibrated)
//   origin        the world frame (local ENU at this point)
//   clock         what the sonar clock correction has applied and how sure it is
//   refraction    the sound-velocity casts and settings the georeferencing traces with
//   trajectories  one vehicle pose per ping in named versions: INS (the navigation at the
//                 nominal ping times), calibrated (the navigation at the calibrated times, with
//                 the calibrated mount), SLAM (after continuous-time SLAM)
//   flags         each sounding's status beyond georef's own filters (survey/sounding_status.hpp):
//                 what the cleaning decided (saved here) and the hand edits (the edit log,
//                 P/edits.json, read again by every stage command: edit_log.hpp)
//
// Its data types live here too: the series (series.hpp: NavSeries, PingSeries), the mount
// (mount.hpp), the sounding statuses (sounding_status.hpp). Layering: survey uses common and svp
// only; io fills the model (ingest, cast files: io::BuildRefraction), georef views it
// (georef/survey_view.hpp: Georeference, the soundings of a trajectory version with the current
// mount), the pipeline writes products from it (tests/lint/layering_test.py checks the arrows).
// Nothing here writes a product.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/progress.hpp"
#include "common/result.hpp"
#include "common/se3.hpp"
#include "processor/survey/mount.hpp"
#include "processor/survey/series.hpp"
#include "processor/survey/sounding_status.hpp"
#include "processor/svp/refraction.hpp"

namespace pitmap::proc::survey {

// The named versions of the per-ping trajectory, in the order the stages make them.
enum class TrajectoryVersion : std::uint8_t { kIns = 0, kCalibrated = 1, kSlam = 2 };
inline constexpr int kNumTrajectoryVersions = 3;
const char* ToString(TrajectoryVersion v);

// One vehicle pose per ping of the survey's PingSeries (index = the ping's index in it);
// valid[i] == 0 where the georeferencing refused ping i (outside the navigation, in a gap).
// sigma (SLAM's trajectory only, else empty): the pose's 1-sigma as the processing knows it
// (slam::SlamPosterior, docs/uncertainty.md): roll, pitch, yaw (rad), east, north, up (m) per
// ping; NaN where it does not know it (the INS's own sigma applies there).
struct PingTrajectory {
    std::vector<Pose> T_world_vehicle;
    std::vector<std::uint8_t> valid;
    std::vector<std::array<double, 6>> sigma;
    bool empty() const { return T_world_vehicle.empty(); }
};

// What has been done to the sonar's clock. The coarse correction (found from the 83P headers at
// georef) and, once applied, the latency the calibration found are in the ping times already.
struct SonarClockState {
    bool configured = false;         // an offset was given (command line, config, vehicle file)
    double configured_offset_s = 0;  // that offset (sonar clock minus UTC)
    double coarse_correction_s = 0;  // applied at georef
    double coarse_sigma_s = 0;       // its 1-sigma (what the calibration's latency scan covers)
    bool latency_applied = false;    // the calibration's latency is in the ping times
    double latency_s = 0;
    double latency_formal_sd_s = 0;
    // The topside clock's rate error (from the head's attitude sensor), applied at georef with
    // the coarse correction: a ping at t gained rate_ppm * 1e-6 * (t - rate_reference_utime).
    double rate_ppm = 0;
    double rate_sigma_ppm = 0;
    std::int64_t rate_reference_utime = 0;
    // Everything applied to the ping times (at the rate's reference time), and the 1-sigma of
    // what remains.
    double correction_s() const { return coarse_correction_s + (latency_applied ? latency_s : 0); }
    double sigma_s() const { return latency_applied ? latency_formal_sd_s : coarse_sigma_s; }
};

// The sound-velocity casts the georeferencing traces through (svp/refraction.hpp); no files =
// straight rays. The casts are read again from the files on load.
struct RefractionRecord {
    std::vector<std::string> svp_files;
    svp::CastSelection selection = svp::CastSelection::kNearestPreceding;
    svp::SurfaceSpeedSource surface_speed = svp::SurfaceSpeedSource::kProfile;
    double ins_height_above_waterline_m = 0;
    bool enabled() const { return !svp_files.empty(); }
};

// How the boresight calibration ended; `run` goes on without it after kNoOverlap.
enum class CalibrationState : std::uint8_t {
    kNotRun = 0,
    kCalibrated = 1,   // the mount (and latency) found were applied
    kKeptNominal = 2,  // a quality gate rejected them; the nominal mount was kept
    kNoOverlap = 3,    // no overlapping passes to calibrate on
};
const char* ToString(CalibrationState s);

inline constexpr std::array<double, 3> kNoBoresightSd = {std::numeric_limits<double>::quiet_NaN(),
                                                         std::numeric_limits<double>::quiet_NaN(),
                                                         std::numeric_limits<double>::quiet_NaN()};

struct SurveyModel {
    // The run: a random 128-bit id (32 lower-case hex digits, NewRunId) made when georef starts
    // a new model; every product and summary.json of this survey carries it, so a stage or the
    // report can tell a product of another run. "" = a survey written before run ids.
    std::string run_id;
    IngestedSeries ingest;
    std::string vehicle_yaml;  // the vehicle file used, "" = none (lever arm and mount zero)
    survey::SonarMount nominal_mount;
    survey::SonarMount mount;  // the current one
    // The calibrated boresight's 1-sigma (roll, pitch, yaw; deg): the fit's range noise and the
    // INS's attitude error (calib::BoresightResult::sd_deg); NaN unless calibration ==
    // kCalibrated.
    std::array<double, 3> boresight_sd_deg = kNoBoresightSd;
    Geodetic origin;
    SonarClockState clock;
    RefractionRecord refraction;
    CalibrationState calibration = CalibrationState::kNotRun;
    std::array<PingTrajectory, kNumTrajectoryVersions> trajectories;
    // cleaning: the cleaning's verdict per sounding of ingest.pings (empty = none yet);
    // manual: the edit log applied (not saved in survey.pitmap: the edit log is the record).
    survey::SoundingFlags flags;

    const PingTrajectory& trajectory(TrajectoryVersion v) const {
        return trajectories[static_cast<int>(v)];
    }
    PingTrajectory& trajectory(TrajectoryVersion v) { return trajectories[static_cast<int>(v)]; }
    bool has(TrajectoryVersion v) const { return !trajectory(v).empty(); }
    // The newest version present (kIns when none is).
    TrajectoryVersion latest() const;
    // Drops `v` and every later version (a new georeference or calibration makes them stale).
    void DropFrom(TrajectoryVersion v);
    // Back to the state before any calibration: the nominal mount, the ping times without the
    // calibration's latency, no calibrated or SLAM trajectory. Returns whether anything changed
    // (then any view of the survey must be made again).
    bool ResetCalibration();
};

// A new run id: 128 random bits (std::random_device) as 32 lower-case hex digits.
std::string NewRunId();
// Whether `id` is a run id as NewRunId makes them.
bool IsRunId(const std::string& id);

// The sonar clock state as survey.pitmap and boresight.json write it.
nlohmann::json ClockJson(const SonarClockState& c);

// The mount as summary.json and boresight.json write it, and back (an error names what is
// wrong); the world origin likewise.
nlohmann::json MountJson(const survey::SonarMount& m);
Expected<survey::SonarMount> MountFromJson(const nlohmann::json& m);
nlohmann::json OriginJson(const Geodetic& g);
Expected<Geodetic> OriginFromJson(const nlohmann::json& o);

}  // namespace pitmap::proc::survey
