// SPDX-License-Identifier: MIT
// Refraction of multibeam soundings: which cast applies to a ping, and where a beam ends after
// ray tracing (processor/svp/ray_trace.hpp) instead of a straight line.
//
// Per beam (what hydrographic packages do, e.g. CARIS HIPS "Sound Velocity Correction"):
//  1. Beam steering: the sonar formed the beam at angle theta (sonar frame, from the head's
//     normal) assuming the speed c_assumed (83P bytes 83-84; 1500 m/s when not set). With the
//     true speed at the face c_tx the beam left at sin(theta') = sin(theta) c_tx / c_assumed.
//  2. Launch angle: the beam's direction u = R_world_sonar * Ry(tilt) (0, sin theta', cos theta')
//     after the vehicle's attitude and the mount; phi0 = acos(-u_up) from the downward vertical,
//     and its horizontal direction (u_east, u_north) / |.|.
//  3. One-way travel time T = r / c_assumed (the 83P range is c_assumed * two-way time / 2).
//  4. TraceRay from the transducer depth with p = sin(phi0) / c_tx; the sounding is the
//     transducer plus the horizontal distance along that direction and the depth difference.
// With a constant profile equal to c_assumed this is the straight beam (tests check it).
//
// The transducer depth below the water surface is taken from the static draft:
// depth = -(R_world_vehicle * lever_arm)_up - ins_height_above_waterline_m (heave rides with
// the surface; vehicle.yaml ins_height_above_waterline_m, or RefractionConfig's value).
//
// Thread safety: a Refraction is immutable after construction; its methods are reentrant.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "processor/svp/cast.hpp"
#include "processor/svp/ray_trace.hpp"

namespace pitmap::proc::svp {

enum class CastSelection {
    kNearestPreceding = 0,  // the latest cast taken at or before the ping (else the first one)
    kNearestInTime,         // the cast closest in time
    kNearestInDistance,     // the cast closest to the transducer (every cast needs a position)
};
// Where the sound speed at the transducer face (c_tx) comes from.
enum class SurfaceSpeedSource {
    kProfile = 0,  // the selected cast at the transducer depth
    kHeader,       // the 83P header's sound velocity (a probe at the head): no steering change
};
const char* ToString(CastSelection s);
const char* ToString(SurfaceSpeedSource s);
bool ParseCastSelection(const std::string& text, CastSelection& out);
bool ParseSurfaceSpeedSource(const std::string& text, SurfaceSpeedSource& out);

// Config section `refraction:` (pitmap config --defaults).
struct RefractionConfig {
    std::vector<std::string> svp_files;  // casts; empty = straight rays (no refraction)
    CastSelection selection = CastSelection::kNearestPreceding;
    SurfaceSpeedSource surface_speed = SurfaceSpeedSource::kProfile;
    // INS reference point above the water line, m; NaN = vehicle.yaml's
    // ins_height_above_waterline_m (one of the two is needed when svp_files is not empty).
    double ins_height_above_waterline_m = std::numeric_limits<double>::quiet_NaN();

    bool enabled() const { return !svp_files.empty(); }
    std::vector<std::string> Validate() const;
};

// The `refraction:` section of the processor's YAML is read and printed by the processor's one
// config key table (processor/pipeline/config.cpp, VisitRefraction).

// A cast ready for tracing.
struct PreparedCast {
    SoundSpeedCast cast;
    LayeredProfile profile;
};

// What georef needs per ping to refract its beams.
struct BeamGeometry {
    Eigen::Vector3d offset_world = Eigen::Vector3d::Zero();  // sounding - transducer, ENU
    RayStatus status = RayStatus::kInvalid;
    bool steering_failed = false;  // |sin theta'| > 1: no such beam in this water
};

class Refraction {
public:
    // Preconditions: casts non-empty, each valid (ValidateCast); with kNearestInDistance every
    // cast has a position; ins_height_above_waterline_m finite.
    Refraction(std::vector<SoundSpeedCast> casts,
               CastSelection selection,
               SurfaceSpeedSource surface_speed,
               double ins_height_above_waterline_m);
    // Problems that stop a Refraction from being built (for the caller to report).
    static std::vector<std::string> Check(const std::vector<SoundSpeedCast>& casts,
                                          CastSelection selection,
                                          double ins_height_above_waterline_m);

    // The cast for a ping at a time and place (latitude/longitude of the transducer).
    int SelectCast(std::int64_t utime_gps, double latitude_deg, double longitude_deg) const;
    // Transducer depth below the water surface from the lever arm rotated into ENU.
    double TransducerDepth(const Eigen::Vector3d& lever_arm_world) const {
        return -lever_arm_world.z() - ins_height_above_waterline_m_;
    }
    // Speed at the transducer face for a ping (kHeader: the header's speed).
    double FaceSpeed(int cast, double transducer_depth_m, double header_speed_mps) const;
    // The sounding of one beam (see the file comment). `beam_sonar_unit` is the beam's unit
    // vector in the sonar frame as formed (before the steering correction), `R_world_sonar`
    // the sonar's attitude, `range_m` the 83P range, `c_assumed` the header speed.
    BeamGeometry Beam(int cast,
                      const Eigen::Matrix3d& R_world_sonar,
                      double beam_angle_rad,
                      double tilt_rad,
                      double range_m,
                      double c_assumed_mps,
                      double transducer_depth_m,
                      double face_speed_mps) const;

    const std::vector<PreparedCast>& casts() const { return casts_; }
    CastSelection selection() const { return selection_; }
    SurfaceSpeedSource surface_speed() const { return surface_speed_; }
    double ins_height_above_waterline_m() const { return ins_height_above_waterline_m_; }

private:
    std::vector<PreparedCast> casts_;
    std::vector<int> by_time_;  // cast indices sorted by time (unknown time first)
    CastSelection selection_;
    SurfaceSpeedSource surface_speed_;
    double ins_height_above_waterline_m_;
};

}  // namespace pitmap::proc::svp
