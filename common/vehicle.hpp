// SPDX-License-Identifier: MIT
// The vehicle description, vehicle.yaml: the one schema written by the simulator, recorded by
// pitmap-acqd (its config's `vehicle` section, copied into the log folder at start) and read by
// the processor. VehicleYamlTemplate() is the documented schema (README "Vehicle description",
// `pitmap config --vehicle`); docs/conventions.md defines the frames it uses.
//
// Frames and angles: lever arms in the vehicle frame (x forward, y starboard, z down) from the
// INS reference point, metres. The sonar's rotation is
//   R_vehicle_sonar = R_boresight * R_mount,
//   R_mount = Rz(connector yaw) * Rx(-tilt),  R_boresight = Rz(yaw) Ry(pitch) Rx(roll),
// connector yaw aft 0, port +90, forward 180, starboard -90 degrees (the head turned about the
// vehicle's down axis; aft = the standard mount, sonar frame = vehicle frame); tilt_deg > 0
// turns the fan's centre beam from straight down towards the sonar's +y side (starboard for
// a connector-aft head). The boresight angles are the small residual rotations about the
// vehicle's axes that `pitmap calibrate` estimates.
//
// Sonar clock offset: clock_offset_s = (the sonar's clock, i.e. the topside time stamped in
// .83P headers) - (GPS-disciplined UTC), seconds. Positive = the sonar clock runs ahead; the
// processor subtracts it from header times. Used only for .83P files (logged pings are
// stamped by the daemon's clock model).
//
// Failure model: parsing lists every problem (missing required keys, wrong types, values out
// of range, unknown keys) and never throws. A file without the `pitmap_vehicle` key is "not a
// pitmap vehicle file" and only the required keys are listed as missing.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "common/config.hpp"
#include "common/result.hpp"

namespace pitmap {

inline constexpr int kVehicleSchemaVersion = 1;

enum class SonarOrientation { kDown = 0, kTilted };
enum class ConnectorDirection { kAft = 0, kForward, kPort, kStarboard };
// Where the sound velocity the sonar uses (83P header) comes from.
enum class SoundVelocitySource { kUnknown = 0, kProbe, kManual };

const char* ToString(SonarOrientation o);
const char* ToString(ConnectorDirection c);
const char* ToString(SoundVelocitySource s);

struct VehicleDescription {
    std::string name;
    // Sonar.
    Eigen::Vector3d sonar_lever_arm_m = Eigen::Vector3d::Zero();  // required
    SonarOrientation orientation = SonarOrientation::kDown;       // required
    double tilt_deg = 0;                                          // tilted only, 0 < |t| <= 90
    ConnectorDirection connector = ConnectorDirection::kAft;      // required
    Eigen::Vector3d boresight_deg = Eigen::Vector3d::Zero();      // roll, pitch, yaw
    std::optional<double> sonar_clock_offset_s;                   // sonar clock - UTC; unknown
    SoundVelocitySource sound_velocity_source = SoundVelocitySource::kUnknown;
    std::string sonar_channel;  // LCM channel id, "" = every sonar channel
    // GNSS and INS.
    std::vector<Eigen::Vector3d> gnss_antenna_lever_arms_m;  // vehicle frame, one per antenna
    std::optional<double> ins_height_above_waterline_m;      // > 0 = INS above the water
    std::string navigation_channel;                          // "" = every INS channel

    // R_mount (orientation, connector, tilt) and R_boresight * R_mount, as above.
    Eigen::Matrix3d R_vehicle_sonar_nominal() const;
    Eigen::Matrix3d R_vehicle_sonar() const;
};

// Reads a vehicle description from a map (a file's root, or a config's `vehicle` section),
// recording every problem (required keys, types, ranges, unknown keys) in `r`.
void ReadVehicle(ConfigReader& r, VehicleDescription& v);
// Parses vehicle.yaml text; `origin` names it in messages. Every problem is listed in the
// error, one per line, each starting with `origin`.
Expected<VehicleDescription> ParseVehicleYaml(const std::string& text, const std::string& origin);
// As ParseVehicleYaml on a file's contents; a missing file is an error naming it.
Expected<VehicleDescription> ReadVehicleFile(const std::string& path);

// The description as vehicle.yaml text (schema kVehicleSchemaVersion), every key written; it
// parses back to the same values. `indent` spaces before every line (for a config section).
std::string FormatVehicleYaml(const VehicleDescription& v, int indent = 0);
// The documented schema: an example vehicle.yaml with a comment on every key.
std::string VehicleYamlTemplate();

}  // namespace pitmap
