// SPDX-License-Identifier: MIT
// The vehicle description, vehicle.yaml: the one schema written by the simulator, recorded by
// pitmap-acqd (its config's `vehicle` section, copied into the log folder at start) and read by
// the processor. VehicleYamlTemplate() is the documented schema (docs/reference.md "vehicle.yaml",
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
// Uncertainty: the optional `uncertainty:` section is the sensor error model (1 sigma) that the
// total propagated uncertainty of each sounding (processor/hydro/tpu.hpp) is computed from;
// absent, SensorErrorModel's defaults (an Imagenex Delta T on a NovAtel SPAN RTK INS) apply, so
// files written before the section existed read as before.
//
// Failure model: parsing lists every problem (missing required keys, wrong types, values out
// of range, unknown keys) and never throws. Values no surface vehicle has are problems too,
// each naming the likely mistake: a lever arm beyond 50 m (in cm or mm?), a transducer above
// the water line or more than 10 m below it (z is down: a flipped sign, or cm), a GNSS antenna
// under the water line. A file without the `pitmap_vehicle` key is "not a
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

// The sensor error model, 1 sigma (Hare, Godin & Mayer 1995: the terms of a multibeam sounding's
// error budget). Defaults: an Imagenex Delta T (range noise as pitmap-sim models the head:
// 0.2 % of the range plus 2 cm) on a NovAtel SPAN INS with RTK (1 cm horizontal, 1.5 cm
// vertical, roll/pitch 0.015 deg, heading 0.04 deg: SPAN's RTK specification and pitmap-sim's
// INS error model). The INS terms are fallbacks: the processor uses the INS's own standard
// deviations (INSSTDEV) where the logs carry them.
struct SensorErrorModel {
    // Sonar.
    double range_sigma_m = 0.02;                 // range noise, constant part, m
    double range_sigma_fraction = 0.002;         // range noise, share of the range
    double beam_angle_sigma_deg = 0.05;          // beam pointing (detection within the beam)
    double surface_sound_speed_sigma_mps = 0.5;  // at the transducer (beam steering), m/s
    double mean_sound_speed_sigma_mps = 1.0;     // of the water column (range scale), m/s
    // INS (fallbacks where the logs carry no INSSTDEV) and the INS's output noise.
    double position_sigma_h_m = 0.01;     // per horizontal axis
    double position_sigma_v_m = 0.015;    // vertical
    double position_noise_m = 0.005;      // white noise per output, beyond the reported sigma
    double roll_pitch_sigma_deg = 0.015;  // roll and pitch
    double heading_sigma_deg = 0.04;      // heading
    double heave_sigma_m = 0.0;           // 0: heights come from the INS (RTK), heave included
    double latency_sigma_s = 0.001;       // residual sonar-to-INS timing error
    // Mount.
    double lever_arm_sigma_m = 0.01;    // per axis, INS to transducer
    double boresight_sigma_deg = 0.02;  // per axis, after calibration

    // Every problem (a value negative or not finite, a fraction >= 0.1).
    std::vector<std::string> Validate() const;
};

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
    std::string sonar_model;    // `sonar.model`: for the products' metadata; "" = not given
    // GNSS and INS.
    std::vector<Eigen::Vector3d> gnss_antenna_lever_arms_m;  // vehicle frame, one per antenna
    std::optional<double> ins_height_above_waterline_m;      // > 0 = INS above the water
    std::string navigation_channel;                          // "" = every INS channel
    std::string ins_model;  // `ins.model`: GNSS/INS make and model (metadata); "" = not given
    // The `uncertainty:` section; nullopt = absent (SensorErrorModel's defaults apply).
    std::optional<SensorErrorModel> uncertainty;
    // The error model to use: the section's, else the defaults.
    SensorErrorModel ErrorModel() const { return uncertainty.value_or(SensorErrorModel{}); }

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
