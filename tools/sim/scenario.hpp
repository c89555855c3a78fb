// SPDX-License-Identifier: MIT
// Synthetic survey scenarios: the pit, the track, the sensors and the faults to inject.
// Built-in names are stable (shared/design/mission.md): "demo", "bejanca", "gps-outage";
// "quarry" is the short non-bowl test survey (high wall, ramp, boulders, NMEA into the topside).
// "mine" is the larger pit of the scale work (issue 38): 500 m x 300 m, a four-hour survey.
// All lengths in metres, angles in degrees (configuration), times in seconds.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "common/vehicle.hpp"

namespace pitmap::sim {

// The pit: a rounded rectangle (superellipse) at the water line, benches down to a backfilled
// floor. World frame: ENU, origin at the pit centre on the water surface (z = 0).
struct PitConfig {
    double half_length_m = 62.5;         // x half-size at the water line
    double half_width_m = 45.0;          // y half-size at the water line
    double superellipse_exponent = 4.0;  // 2 = ellipse, larger = more rectangular
    double max_depth_m = 27.0;           // deepest point below the water surface
    double floor_depth_m = 22.0;         // mean depth of the backfilled floor
    int num_benches = 3;                 // terraces between the shore and the floor
    double bench_width_m = 7.0;          // horizontal width of a bench tread
    double wall_slope_deg = 60.0;        // slope of the walls between benches
    double shore_slope_deg = 35.0;       // slope from the water line to the first bench
    double backfill_amplitude_m = 3.0;   // height of the backfill mounds on the floor
    double backfill_wavelength_m = 30.0;
    double rubble_amplitude_m = 0.15;  // small-scale roughness everywhere underwater
    double rubble_wavelength_m = 3.0;
    double grid_resolution_m = 0.10;  // resolution of the exact terrain grid
    double land_height_m = 3.0;       // height of the banks above the water

    // Optional quarry features (all off by default; the built-in pits without them are
    // unchanged). Directions are seen from the pit centre, degrees counter-clockwise from +x
    // (east).
    // High wall: in a sector of the perimeter the benches give way to one face from the banks
    // down to the floor (a quarry face cut without benches).
    double high_wall_slope_deg = 0;          // slope of the face; 0 = no high wall
    double high_wall_direction_deg = 90.0;   // centre of the sector
    double high_wall_half_angle_deg = 30.0;  // half-width of the sector
    double high_wall_blend_deg = 8.0;        // angular width of the blend into the benches
    // Ramp: a straight haul road, ramp_width_m wide, from the water line at ramp_direction_deg
    // down to the tread of bench `ramp_bench` at ramp_grade_deg, running counter-clockwise
    // along the shore (clockwise if ramp_clockwise). Cut and fill faces at wall_slope_deg.
    double ramp_width_m = 0;  // 0 = no ramp
    double ramp_direction_deg = -120.0;
    double ramp_grade_deg = 10.0;
    int ramp_bench = 1;  // 1 = the shallowest bench; needs num_benches >= ramp_bench
    bool ramp_clockwise = false;
    // Boulders: rounded blocks resting on gentle ground under water (treads, floor, ramp):
    // a squarish plan outline and a flat-topped dome, height 0.3-0.45 of the diameter, partly
    // buried. Placed at random (from the seed) where the ground slopes less than 15 deg.
    int num_boulders = 0;  // 0 = none
    double boulder_min_diameter_m = 0.5;
    double boulder_max_diameter_m = 2.0;
};

// The pattern of the vehicle's lines (`pitmap-sim synth --lines`), repeated until the survey's
// duration is reached:
//   kLaps    concentric laps inward from the shore, then tie lines across the long axis;
//   kStar    star_lines straight lines through the pit centre, evenly spread over 180 deg
//            (alternating direction, each end first_lap_offset_m from the shore, the next line
//            starting near where the last ended): every line crosses every other at the centre;
//   kZigzag  a zigzag of zigzag_legs legs between the west and east ends, touching
//            first_lap_offset_m from the north and south shores, then the same zigzag back
//            half a leg shifted, so that its legs cross the first pass's.
enum class TrackPattern { kLaps = 0, kStar, kZigzag };
const char* ToString(TrackPattern p);
// "laps", "star", "zigzag"; an unknown name is an error listing them.
Expected<TrackPattern> TrackPatternFromString(const std::string& name);

// The vehicle's track: its pattern of lines (by default concentric laps inward from the shore,
// then tie lines across) and its motion.
struct TrackConfig {
    TrackPattern pattern = TrackPattern::kLaps;
    int star_lines = 6;               // kStar: lines through the centre (>= 2)
    int zigzag_legs = 8;              // kZigzag: legs of one pass (>= 2)
    double speed_mps = 1.2;           // speed through the water
    double first_lap_offset_m = 4.0;  // distance of the outer lap from the shore line
    double lap_spacing_m = 9.0;       // distance between consecutive laps
    int num_laps = 4;                 // concentric laps
    int num_tie_lines = 1;            // straight lines across the pit after the laps
    bool clockwise = false;           // laps clockwise (a repeat survey's own track)
    double duration_s = 0;            // 0 = run the whole track; else stop (or loop) at this time
    double turn_radius_m = 3.0;       // minimum radius when joining track pieces
    double roll_amplitude_deg = 2.0;  // wave-induced motion
    double pitch_amplitude_deg = 1.0;
    double heave_amplitude_m = 0.05;
    double yaw_oscillation_deg = 1.5;
    double wave_period_s = 3.5;
};

struct LeverArms {
    std::vector<double> sonar_m = {0.80, 0.0, 0.25};    // vehicle (FRD) frame, INS -> sonar
    std::vector<double> antenna_m = {-0.5, 0.0, -1.2};  // INS -> GNSS antenna
};

// Errors of the INS solution the receiver reports (the truth is the vehicle's motion).
struct NavErrorConfig {
    // Defaults: a post-processed, tightly coupled RTK/INS solution (the paper's data went
    // through NovAtel Inertial Explorer), about 1 cm horizontal and 1.5 cm vertical.
    double position_noise_m = 0.005;    // white noise per INS output, horizontal
    double position_gm_sigma_m = 0.01;  // Gauss-Markov (RTK-quality) error, horizontal
    double height_gm_sigma_m = 0.015;   // Gauss-Markov error, vertical
    double position_gm_tau_s = 60.0;
    double attitude_gm_sigma_deg = 0.015;  // roll/pitch Gauss-Markov error
    double heading_gm_sigma_deg = 0.04;    // heading Gauss-Markov error
    double attitude_gm_tau_s = 120.0;
    // GPS outages: [start_s, end_s) pairs, seconds since the survey start.
    std::vector<double> outages_s;
    double outage_velocity_random_walk_mps_per_sqrt_s = 0.003;  // drift growth in outages
    double outage_vertical_fraction = 0.4;  // vertical drift relative to horizontal
    double recovery_time_s = 8.0;           // time to pull back after the outage
    // Fault cases (issue 34). INS status windows: [start_s, end_s, status] triples, the
    // NovAtel INS status (e.g. 1 INS_ALIGNING, 2 INS_HIGH_VARIANCE, 6 INS_SOLUTION_FREE) the
    // receiver reports inside them; the solution itself stays as good as outside.
    std::vector<double> status_windows;
    // Drifts the INS does not know of: [start_s, end_s, east_m, north_m] quadruples; the
    // position error grows linearly to (east, north) over the window, then is pulled back over
    // recovery_time_s; the status stays INS_SOLUTION_GOOD and the stddevs unchanged.
    std::vector<double> drift_windows;
};

struct SonarConfig {
    double ping_rate_hz = 10.0;
    int num_beams = 480;
    double start_angle_deg = -60.0;
    double angle_increment_deg = 0.25;
    double beam_width_deg = 1.5;
    int footprint_rays = 5;  // sub-rays per beam across the footprint
    double max_range_m = 100.0;
    double range_resolution_mm = 5.0;     // 83P range count unit
    double range_noise_fraction = 0.002;  // sigma = fraction * range + constant
    double range_noise_constant_m = 0.02;
    double dropout_probability = 0.02;  // beam reports 0 (no detection)
    // A patch that returns nothing (soft mud, a shadow): beams whose true hit lies within
    // dropout_patch_radius_m of (x, y) (world ENU) report no detection; 0 = none.
    double dropout_patch_x_m = 0, dropout_patch_y_m = 0, dropout_patch_radius_m = 0;
    double outlier_probability = 0.02;  // beam reports a coarse outlier
    double sound_speed_mps = 1480.0;
    bool intensities = true;
    int format_version = 10;  // 83P v1.10
    // Topside PC clock in the 83P header: offset from UTC (header clock - UTC, the sign of
    // vehicle.yaml sonar.clock_offset_s) and drift (not to be trusted).
    double topside_clock_offset_s = 3600.0 + 2.37;
    double topside_clock_drift_ppm = 35.0;
    // A step of the topside clock (an NTP correction, a user setting the PC's time): from
    // topside_clock_step_at_s after the survey start on, the header clock is
    // topside_clock_step_s further ahead (< 0 at: no step).
    double topside_clock_step_at_s = -1.0;
    double topside_clock_step_s = 0.0;
    double ping_latency_ms = 2.0;   // interrogation -> transmit
    double data_latency_ms = 35.0;  // interrogation -> datagram sent
    // The daemon's stamping error: decoded pings in the log are stamped this much late (a
    // residual latency the processor's calibration must find; 0 = exact).
    double daemon_stamp_error_ms = 0.0;
    // A step of that error during the survey (the daemon's clock re-locked, say): from
    // daemon_stamp_error_step_s after the survey start on, pings are stamped
    // daemon_stamp_error_after_ms late instead (< 0 = no step).
    double daemon_stamp_error_step_s = -1.0;
    double daemon_stamp_error_after_ms = 0.0;

    // What the topside program puts into the 83P header from its auxiliary inputs (spec
    // §1.2, §1.4). Every value it writes is the last one it had received when the ping was
    // interrogated: a fix taken at t_fix reaches it at t_fix + nmea_latency_s, so the header
    // position is stale by up to 1/rate + latency. Before the first fix arrives the fields
    // stay blank (latitude/longitude) or zero (speed/course).
    // GGA + VTG feed from a GNSS receiver whose antenna is at lever_arms.antenna_m: header
    // latitude/longitude (bytes 33-60), speed and course over ground (61-63).
    bool nmea_position = true;
    double nmea_position_rate_hz = 1.0;   // fixes per second, taken at whole multiples of 1/rate
    double nmea_latency_s = 0.15;         // fix epoch -> received by the topside (serial, parse)
    double nmea_position_noise_m = 0.02;  // white horizontal noise per fix, per axis (1 sigma);
                                          // 0.02 = RTK, about 1-2 = autonomous GNSS
    double nmea_speed_noise_mps = 0.02;   // white noise on each velocity axis of the VTG
    // HDT feed (e.g. a dual-antenna GNSS compass): external heading, bytes 137 bit 0 and
    // 146-149 (v1.10 only; v1.00 has no field for it). Heading of the vehicle's x axis.
    bool nmea_heading = false;
    double nmea_heading_rate_hz = 5.0;     // 1..10 Hz; same latency as the position feed
    double nmea_heading_noise_deg = 0.05;  // white noise per HDT sentence
    // The head's internal pitch/roll sensor (bytes 64-67, 0.1 deg resolution, bit 15 = valid):
    // the attitude of the head itself, i.e. the vehicle's attitude composed with the mount
    // (boresight), sampled at the interrogation. Aerospace convention on the sonar frame
    // (x fwd, y stbd, z down): roll positive starboard down, pitch positive bow up. No
    // internal heading (bytes 68-69 stay "not valid").
    bool internal_attitude_sensor = true;
    double internal_attitude_noise_deg = 0.05;  // white noise per ping, before quantisation
};

// The water column's sound speed (a flooded pit in summer): a warm mixed layer, a thermocline
// where the speed falls along a half cosine, cold water below (pressure adds
// deep_gradient_per_s per metre). With `refraction` the pings are ray traced through it
// (tools/sim/water_column.hpp) and the 83P header's sound speed is the speed at the transducer;
// without, rays are straight at sonar.sound_speed_mps.
struct WaterColumnConfig {
    bool refraction = false;
    double surface_speed_mps = 1496.0;   // mixed layer
    double mixed_layer_depth_m = 2.0;    // top of the thermocline
    double thermocline_depth_m = 7.0;    // bottom of the thermocline
    double deep_speed_mps = 1452.0;      // at the bottom of the thermocline
    double deep_gradient_per_s = 0.017;  // below it, m/s per m
    double cast_spacing_m = 0.5;         // depth step of the cast written to the truth
    double SpeedAt(double depth_m) const;
};

// The seabed's backscatter and the sonar's echo amplitude (the 83P intensities). The seabed
// is tiled in squares of patch_size_m (world x, y), each of one material drawn from the seed
// among patch_levels_db; boulders are boulder_db. BS(x, y) is the backscatter strength
// without the angular response. The echo level of a beam, dB re one intensity count:
//   L = source_level_db - spreading_db_per_decade log10(R) - 2 absorption_db_per_m R
//       + BS(x, y) + AR(theta) + speckle_db N(0, 1)
//   AR(theta) = 10 log10(cos^2 theta) + specular_db exp(-(theta / specular_width_deg)^2)
// (R slant range, theta incidence on the true terrain), and the 83P intensity is the
// amplitude round(10^(L / 20)) in 1..65535 (65535 = saturated). The truth writes BS on the
// terrain grid (truth_io.hpp backscatter.f32) and these parameters (backscatter.json).
struct BackscatterConfig {
    std::vector<double> patch_levels_db = {-14.0, -20.0, -26.0, -32.0};
    double patch_size_m = 5.0;
    double boulder_db = -8.0;  // rock: harder than any sediment patch
    double source_level_db = 110.0;
    double spreading_db_per_decade = 40.0;  // two-way spherical spreading
    double absorption_db_per_m = 0.021;     // one way (fresh water, 260 kHz, 10 degC)
    double specular_db = 6.0;               // specular lobe at normal incidence
    double specular_width_deg = 10.0;
    double speckle_db = 2.0;  // per-beam fluctuation (1 sigma, dB)
};

// Correlated echo artifacts of a real multibeam in a flooded pit (issue 35), on top of the
// uncorrelated dropouts and coarse outliers of SonarConfig: what a per-ping median filter
// cannot see. tools/sim/echo_artifacts.hpp describes each kind; EchoArtifactsAt(level) gives
// the presets (`pitmap-sim synth --echo-artifacts none|light|typical|heavy`). Probabilities
// are per ping (10 Hz) unless stated; every draw comes from the seed.
struct EchoArtifactConfig {
    std::string level = "none";  // the preset's name (none, light, typical, heavy, custom)
    // Mid-water targets (fish schools, vegetation): blobs alive at any time, each living
    // school_lifetime_s then reborn elsewhere, drifting at up to school_drift_mps.
    int num_schools = 0;
    double school_min_radius_m = 0.35;
    double school_max_radius_m = 0.9;
    double school_lifetime_s = 45.0;
    double school_drift_mps = 0.08;
    double school_fill = 0.5;         // share of the beams crossing a school that return from it
    double school_min_depth_m = 1.5;  // shallowest centre below the water surface
    // Bubble sweep-down / aeration: episodes of consecutive pings in which a sector of beams
    // returns near-field echoes or nothing.
    double bubble_episodes_per_min = 0;     // at random, steady running
    double bubble_turn_rate_deg_s = 6.0;    // |yaw rate| above which the vehicle "turns"
    double bubble_pitch_rate_deg_s = 1.5;   // |pitch rate| above which it "pitches hard"
    double bubble_manoeuvre_factor = 15.0;  // episode rate multiplier while turning/pitching
    int bubble_min_pings = 3;
    int bubble_max_pings = 12;
    double bubble_sector_min = 0.1;  // share of the fan the episode's sector spans, min..max
    double bubble_sector_max = 0.4;
    double bubble_return_share = 0.35;   // of the sector's beams: a near-field return
    double bubble_dropout_share = 0.35;  // of the sector's beams: no detection
    double bubble_min_range_m = 0.4;     // near-field returns, uniform in min..max
    double bubble_max_range_m = 4.0;
    // Multipath / side-lobe ghosts: beams at grazing incidence or on steep walls start an
    // episode (probability per candidate beam and ping); it holds a few neighbouring beams for
    // tens of pings, returning the true range times (1 + excess), behind the surface.
    double multipath_probability = 0;
    double multipath_grazing_deg = 70.0;     // incidence from the surface normal above which
    double multipath_wall_slope_deg = 50.0;  // or true slope above which a beam is a candidate
    int multipath_min_beams = 4;
    int multipath_max_beams = 12;
    int multipath_min_pings = 10;
    int multipath_max_pings = 40;
    double multipath_min_excess = 0.08;  // fraction of the true range, uniform in min..max
    double multipath_max_excess = 0.45;
    // Nadir side-lobe "smile": at short nadir range, episodes in which the beams within
    // smile_min..max_angle_deg of nadir whose true range exceeds the nadir range by more
    // than 5 % return the nadir range instead.
    double smile_probability = 0;  // per ping, at short range
    double smile_max_nadir_range_m = 9.0;
    double smile_min_angle_deg = 3.0;
    double smile_max_angle_deg = 25.0;
    int smile_min_pings = 2;
    int smile_max_pings = 8;
    bool enabled() const {
        return num_schools > 0 || bubble_episodes_per_min > 0 || multipath_probability > 0 ||
               smile_probability > 0;
    }
};
// The presets: "none", "light" (about 0.3 % of the beams), "typical" (about 1 %), "heavy"
// (about 3 %); an unknown name is an error listing the valid ones.
Expected<EchoArtifactConfig> EchoArtifactsAt(const std::string& level);

// A part of a repeat survey's change (tools/sim/terrain_change.hpp: shapes, volumes).
enum class ChangeShape { kParaboloid = 0, kFrustum, kBox };
const char* ToString(ChangeShape s);

struct ChangePart {
    std::string name;    // unique in the epoch, e.g. "slump_scar"
    std::string change;  // the change it belongs to: "slump", "deposit", "cut", ...
    ChangeShape shape = ChangeShape::kParaboloid;
    double x_m = 0, y_m = 0;  // centre, world ENU
    double heading_deg = 0;   // direction of the local u axis, ccw from +x
    double a_m = 1, b_m = 1;  // see the shapes above
    double ramp_m = 0;        // kBox only
    double thickness_m = 0;   // > 0 gain (terrain raised), < 0 loss (lowered)

    // The profile in [0, 1] at a world point (0 outside the outline).
    double Profile(double x, double y) const;
    // Height change at a world point: thickness_m * Profile.
    double Delta(double x, double y) const { return thickness_m * Profile(x, y); }
    // The exact volume from the shape's formula, m^3, signed as thickness_m.
    double AnalyticVolume() const;
    // The outline (where the profile becomes 0) as a closed ring of world (x, y), counter-
    // clockwise, first point repeated last; `vertices` points on curved outlines.
    std::vector<Eigen::Vector2d> Outline(int vertices = 96) const;
    // Every problem with the part (empty when valid).
    std::vector<std::string> Validate() const;
};

struct ScenarioConfig {
    std::string name = "custom";
    std::uint64_t seed = 1;
    std::string start_utc = "2026-06-15T09:00:00Z";  // survey start
    // Geodetic position of the world origin (pit centre on the water surface), WGS84.
    double origin_latitude_deg = 40.4435;  // Bejanca, Portugal
    double origin_longitude_deg = -7.7806;
    double origin_height_m = 412.0;    // ellipsoidal height of the water surface
    double geoid_undulation_m = 55.2;  // geoid - ellipsoid (NovAtel's "undulation")
    PitConfig pit;
    TrackConfig track;
    LeverArms lever_arms;
    // True INS -> sonar rotation error the calibration must find (roll, pitch, yaw in degrees).
    std::vector<double> boresight_deg = {0.5, 0.0, 1.0};
    NavErrorConfig nav;
    SonarConfig sonar;
    WaterColumnConfig water;
    BackscatterConfig backscatter;
    EchoArtifactConfig echo_artifacts;  // none by default
    double ins_rate_hz = 50.0;          // INSPVAS
    double imu_rate_hz = 200.0;         // RAWIMUSX
    double gnss_rate_hz = 1.0;          // BESTPOS, INSPVAX, INSSTDEV, TIME
    // Repeat surveys (issue 37, tools/sim/terrain_change.hpp RepeatEpoch): the survey's epoch
    // (1 = the first), the seed of the pit's terrain and seabed (0 = seed; a repeat survey keeps
    // the first epoch's) and the changes since the first epoch (empty for epoch 1).
    int epoch = 1;
    std::uint64_t terrain_seed = 0;
    std::vector<ChangePart> changes;
    std::uint64_t TerrainSeed() const { return terrain_seed != 0 ? terrain_seed : seed; }

    // Every problem with the configuration (empty when valid).
    std::vector<std::string> Validate() const;
};

// The vehicle.yaml a survey team would write for the scenario: the true lever arms, the
// nominal mount (down, connector aft) with boresight 0 (the true boresight_deg is what
// `pitmap calibrate` must find) and the sonar clock offset unknown. Channels are left "".
// Its `uncertainty:` section states the errors the simulator injects (range noise, INS errors,
// exact angles, sound speed and lever arms; SensorErrorModel's default boresight sigma).
VehicleDescription NominalVehicle(const ScenarioConfig& sc);

// The names of the built-in scenarios, in a stable order.
const std::vector<std::string>& BuiltinScenarioNames();
// A built-in scenario by name; an unknown name is an error that lists the valid ones.
Expected<ScenarioConfig> BuiltinScenario(const std::string& name);
// One line on what a scenario holds: pit size and depth, duration and pings, terrain features,
// GNSS outages, the topside clock and the 83P header inputs (`pitmap-sim scenarios`).
std::string DescribeScenario(const ScenarioConfig& scenario);

}  // namespace pitmap::sim
