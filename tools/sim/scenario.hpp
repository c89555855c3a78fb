// SPDX-License-Identifier: MIT
// Synthetic survey scenarios: the pit, the track, the sensors and the faults to inject.
// Built-in names are stable (shared/design/mission.md): "demo", "bejanca", "gps-outage".
// All lengths in metres, angles in degrees (configuration), times in seconds.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"

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
};

// The vehicle's track: concentric laps inward from the shore, then tie lines across.
struct TrackConfig {
    double speed_mps = 1.2;           // speed through the water
    double first_lap_offset_m = 4.0;  // distance of the outer lap from the shore line
    double lap_spacing_m = 9.0;       // distance between consecutive laps
    int num_laps = 4;                 // concentric laps
    int num_tie_lines = 1;            // straight lines across the pit after the laps
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
    double outlier_probability = 0.02;  // beam reports a coarse outlier
    double sound_speed_mps = 1480.0;
    bool intensities = true;
    int format_version = 10;  // 83P v1.10
    // Topside PC clock in the 83P header: offset from UTC and drift (not to be trusted).
    double topside_clock_offset_s = 3600.0 + 2.37;
    double topside_clock_drift_ppm = 35.0;
    double ping_latency_ms = 2.0;   // interrogation -> transmit
    double data_latency_ms = 35.0;  // interrogation -> datagram sent
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
    double ins_rate_hz = 50.0;   // INSPVAS
    double imu_rate_hz = 200.0;  // RAWIMUSX
    double gnss_rate_hz = 1.0;   // BESTPOS, INSPVAX, INSSTDEV, TIME

    // Every problem with the configuration (empty when valid).
    std::vector<std::string> Validate() const;
};

// The names of the built-in scenarios, in a stable order.
const std::vector<std::string>& BuiltinScenarioNames();
// A built-in scenario by name; an unknown name is an error that lists the valid ones.
Expected<ScenarioConfig> BuiltinScenario(const std::string& name);

}  // namespace pitmap::sim
