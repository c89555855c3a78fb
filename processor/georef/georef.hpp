// SPDX-License-Identifier: MIT
// Georeferencing: INS pose at each ping time, lever arm and boresight, beams to points in the
// world frame (local ENU at an origin, GeographicLib LocalCartesian) and their UTM coordinates.
//
// Geometry (docs/conventions.md, shared/specs/imagenex_deltat.md §1.5):
//   theta_i = start + i * increment (positive to starboard; PingSeries::beam_angles_deg instead
//   when the ping has its own), r_i = count_i * range_resolution_m
//   (times c_header / nominal_sound_speed_mps when sound_speed_scaling is on),
//   p_sonar = Ry(tilt) (0, r sin theta, r cos theta),
//   p_world = t_world_vehicle(t) + R_world_vehicle(t) (lever_arm_m + R_vehicle_sonar p_sonar),
//   R_world_vehicle = frames::RotationWorldFromRpy(roll, pitch, yaw) at the ping's transmit time,
//   position interpolated linearly and attitude by slerp between the two bracketing INS samples.
// Refraction (optional, processor/svp/refraction.hpp): with a svp::Refraction each beam is ray
// traced through the ping's sound-velocity cast from the transducer depth instead of the
// straight p_sonar above; the launch angle is taken after the attitude and the mount, and the
// steering is corrected for the speed at the face. Beams whose ray turns, surfaces or cannot be
// steered are dropped and counted (refraction_failed).
// Pings whose bracketing samples are more than max_nav_gap_s apart (or outside the nav span by
// more than max_nav_extrapolation_s) are refused and counted. Filters, in order: no detection,
// range gate, spike filter (median of the valid ranges within +-spike_half_window beams;
// |r - median| > spike_abs_m + spike_rel * median is a spike).
// Thread safety: RunGeoref is reentrant; results do not depend on the thread count.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/progress.hpp"
#include "common/se3.hpp"
#include "processor/survey/mount.hpp"
#include "processor/survey/series.hpp"
#include "processor/survey/sounding_status.hpp"
#include "processor/svp/refraction.hpp"

namespace pitmap::proc::georef {

struct GeorefConfig {
    double max_nav_gap_s = 0.5;  // refuse pings between INS samples further apart
    // Place pings up to this long before the first or after the last INS sample, s, by
    // extrapolating the two end samples' motion: a latency correction can move the first ping
    // a few ms before a navigation that starts with it. 0 = only within the span.
    double max_nav_extrapolation_s = 0.02;
    double min_range_m = 0.5;               // range gate, metres
    double max_range_m = 100.0;             // range gate, metres
    bool sound_speed_scaling = false;       // r *= c_header / nominal (MB-System convention)
    double nominal_sound_speed_mps = 1500;  // the sound speed the counts were computed with
    bool apply_profile_tilt = true;         // rotate the fan by the header's profile tilt
    int spike_half_window = 3;              // beams each side for the median; 0 = no filter
    double spike_abs_m = 0.3;               // spike threshold, constant part, metres
    double spike_rel = 0.03;                // spike threshold, share of the median range
    int num_threads = 0;                    // 0 = all cores (TBB)

    std::vector<std::string> Validate() const;
};

// Interpolated INS poses in the world frame.
class Trajectory {
public:
    Trajectory(const survey::NavSeries& nav, const LocalTangentFrame& world);
    // T_world_vehicle at a time; nullopt across a gap > max_gap_s or outside the span by more
    // than max_extrapolation_s (within it: the two end samples' motion extrapolated, when they
    // are no further apart than max_gap_s).
    std::optional<Pose> PoseAt(std::int64_t utime_gps,
                               double max_gap_s,
                               double max_extrapolation_s = 0.0) const;
    const std::vector<std::int64_t>& times() const { return utime_gps_; }
    const std::vector<Pose>& poses() const { return T_world_vehicle_; }

private:
    std::vector<std::int64_t> utime_gps_;
    std::vector<Pose> T_world_vehicle_;
};

// Georeferenced soundings (struct of arrays, one entry per kept sounding).
struct GeorefPoints {
    std::vector<Eigen::Vector3d> position_world;  // ENU metres at the world origin
    std::vector<std::uint32_t> ping;              // index into GeorefResult::pings
    std::vector<std::uint16_t> beam;              // beam number in its ping
    std::vector<float> range_m;                   // slant range used
    std::vector<float> angle_rad;                 // beam angle theta (sonar frame)
    // SoundingStatus per point in the views kRejected and kCandidates (the latter: accepted or
    // the cleaning's earlier verdict); empty in the accepted view.
    std::vector<std::uint8_t> status;
    std::size_t size() const { return position_world.size(); }
};
// Points first .. first + count - 1 of `p` (every array `p` fills; first + count <= p.size()).
GeorefPoints SliceOf(const GeorefPoints& p, std::size_t first, std::size_t count);
// Appends `from`'s points to `to` (every array, in order).
void AppendPoints(const GeorefPoints& from, GeorefPoints& to);

// One georeferenced ping.
struct GeorefPing {
    std::int64_t utime_gps = 0;
    std::int64_t ping_number = 0;
    std::uint32_t header_index = 0;  // index into the input survey::PingSeries
    Pose T_world_vehicle;
    Eigen::Vector3d sensor_world = Eigen::Vector3d::Zero();  // transducer position
    double profile_tilt_rad = 0;                             // applied tilt
    // Refraction inputs (used when GeorefResult::refraction is set).
    double assumed_sound_speed_mps = 1500;  // the header's (the sonar's) sound speed
    int cast = -1;                          // index into refraction->casts(); -1 = none
};

struct GeorefCounts {
    std::int64_t pings_in = 0;
    std::int64_t pings_georeferenced = 0;
    std::int64_t pings_outside_nav = 0;  // off the INS span by > max_nav_extrapolation_s
    std::int64_t pings_in_nav_gap = 0;   // bracketing samples further apart than max_nav_gap_s
    std::int64_t pings_bad_header = 0;   // zero resolution, NaN angles
    std::int64_t soundings_in = 0;
    std::int64_t no_detection = 0;
    std::int64_t range_gate = 0;
    std::int64_t spikes = 0;
    std::int64_t refraction_failed = 0;  // ray turned, surfaced or beam not steerable
    std::int64_t cleaned = 0;  // rejected by the cleaning (survey::SoundingFlags::cleaning)
    std::int64_t manual = 0;   // rejected by hand (survey::SoundingFlags::manual)
    std::int64_t points = 0;   // soundings in the view
    // Soundings of the georeferenced pings per status (index = SoundingStatus code).
    survey::StatusCounts status{};
};

struct GeorefResult {
    Geodetic world_origin;
    GeorefPoints points;
    std::vector<GeorefPing> pings;
    GeorefCounts counts;
    survey::SonarMount mount;  // the mount the points were computed with
    // The refraction applied (null = straight rays); Regeoreference traces again with it.
    std::shared_ptr<const svp::Refraction> refraction;
    bool cancelled = false;
    std::string message;
};

// Sonar-frame vector of a beam: Ry(tilt) (0, r sin theta, r cos theta).
Eigen::Vector3d BeamVectorSonar(double range_m, double angle_rad, double tilt_rad);

// The sonar-frame vector from the transducer to sounding j as georeferenced (with refraction,
// the ray-traced sounding seen from the head; else BeamVectorSonar).
Eigen::Vector3d SoundingVectorSonar(const GeorefResult& result, std::size_t j);

// Median spike filter over one ping's ranges (metres, <= 0 = invalid). Sets keep[i] = false for
// spikes; returns their number.
int SpikeFilter(const std::vector<double>& range_m,
                int half_window,
                double abs_m,
                double rel,
                std::vector<char>& keep);

// Georeferences every ping. `origin`: world frame origin; nullopt = the first INS position.
// `flags` (optional): the statuses decided outside georef (the cleaning, hand edits); `view`:
// which soundings to return.
// Preconditions: config.Validate() is empty.
GeorefResult RunGeoref(const survey::NavSeries& nav,
                       const survey::PingSeries& pings,
                       const survey::SonarMount& mount,
                       const GeorefConfig& config,
                       std::optional<Geodetic> origin = std::nullopt,
                       const ProgressCallback& progress = {},
                       std::shared_ptr<const svp::Refraction> refraction = nullptr,
                       const survey::SoundingFlags* flags = nullptr,
                       survey::SoundingView view = survey::SoundingView::kAccepted);

// Re-applies a mount (boresight) to already georeferenced soundings, in place; the pings keep
// their poses (with refraction, each beam is traced again). Used after calibration.
void Regeoreference(GeorefResult& result, const survey::SonarMount& mount);

// UTM coordinates of the points, all in the zone of the world origin. Exact (GeographicLib) at
// each ping's sensor position; a point adds its offset from the sensor through the ENU -> UTM
// Jacobian at the origin (error below 1 mm for offsets under 100 m).
struct UtmPoints {
    int zone = 0;
    bool northern = true;
    int epsg = 0;
    std::vector<Eigen::Vector3d> easting_northing_height;  // metres, ellipsoidal height
};
Expected<UtmPoints> ToUtm(const GeorefResult& result);

// ToUtm's projection without its array: the Jacobian at the origin and each ping's sensor
// position in UTM (24 bytes a ping instead of 24 bytes a sounding), so that a stage places the
// soundings one at a time where it reads them. At(result, j) is ToUtm(result)'s point j bit for
// bit (ToUtm is this loop). `result` must be the one the projection was made of (its pings).
struct UtmProjection {
    int zone = 0;
    bool northern = true;
    int epsg = 0;
    Eigen::Matrix2d en_per_world = Eigen::Matrix2d::Identity();  // d(E, N) / d(east, north)
    std::vector<Eigen::Vector3d> sensor_utm;                     // per ping of the result

    Eigen::Vector3d At(const GeorefResult& result, std::size_t j) const {
        return At(result.points, result.pings, j);
    }
    // Point j of `points`, a block of the result's view (its ping indices into `pings`, the
    // result's pings).
    Eigen::Vector3d At(const GeorefPoints& points,
                       const std::vector<GeorefPing>& pings,
                       std::size_t j) const {
        const std::uint32_t k = points.ping[j];
        const Eigen::Vector3d d = points.position_world[j] - pings[k].sensor_world;
        const Eigen::Vector2d en = en_per_world * d.head<2>();
        return sensor_utm[k] + Eigen::Vector3d(en.x(), en.y(), d.z());
    }
};
Expected<UtmProjection> UtmProjectionOf(const GeorefResult& result);

}  // namespace pitmap::proc::georef
