// SPDX-License-Identifier: MIT
// Ground truth written beside the simulated sensor data, and read back by the scorer.
//
// <dir>/scenario.json     the ScenarioConfig (every parameter, seed included)
// <dir>/terrain.json      grid header: x0_m, y0_m, resolution_m, nx, ny, origin (lat, lon, h)
// <dir>/terrain.f32       heights, float32 little-endian, row-major (iy * nx + ix), metres, z up
// <dir>/trajectory.csv    true vehicle pose at a fixed rate: gps_time_s (GPS seconds since
//                         1980-01-06), x_m, y_m, z_m (world ENU), roll_deg, pitch_deg, yaw_deg
// <dir>/boresight.json    true R_vehicle_sonar as roll/pitch/yaw degrees, lever arms
// <dir>/coverage.u8       optional: 1 byte per terrain cell (same grid), 1 where a true beam
//                         hit that cell (the insonified area), else 0
// <dir>/backscatter.json  optional: the seabed backscatter and the echo amplitude model of the
//                         83P intensities (BackscatterConfig, every parameter), the layout of
// <dir>/backscatter.f32   BS(x, y) at the terrain grid's nodes, dB, float32 little-endian,
//                         row-major as terrain.f32 (the truth a backscatter mosaic is scored on)
// <dir>/artifacts.json    optional (pitmap-sim synth): the echo artifact model
//                         (EchoArtifactConfig, every parameter), the survey's ping timing
//                         (first_ping_gps_s, ping_rate_hz: ping k transmits at first + k / rate),
//                         the beams per kind and the good soundings (detections not listed) per
//                         slope class of the true surface; the counts are also in
//                         scenario.json "echo_artifacts"
// <dir>/artifacts.bin     the beams listed, as runs: "PMEA", u16 version (1), u16 beams per
//                         ping, u64 number of runs, then per run (sorted by ping, beam) u32 ping
//                         number (the 83P's), u16 first beam, u16 number of beams, u8 kind
//                         (tools/sim/echo_artifacts.hpp EchoArtifactKind: 1 mid-water, 2 bubble,
//                         3 dropout, 4 multipath, 5 smile, 6 coarse outlier), little-endian,
//                         9 bytes a run (the quarry: 185 kB, 90 % of it the coarse
//                         outliers, single beams; bejanca about 1.1 MB)
// <dir>/scenario.json's "water" is read back (Truth::water) when its refraction is on: the
//                         scorer then casts the true beams along curved rays.
// <dir>/sonar_clock.json  optional: the topside PC clock of the 83P headers (SonarClockTruth)
//                         and what the topside's NMEA / attitude inputs put into the headers
// <dir>/capacity.csv      the pit's capacity on the true terrain of this epoch: level_m (world
//                         z, the survey's water surface 0), level_height_m (ellipsoidal,
//                         origin height + level_m), area_m2 (water surface), volume_m3 (water)
//                         every 0.25 m from the deepest point to 0
// Repeat surveys (epoch >= 2, tools/sim/terrain_change.hpp), the change since epoch 1:
// <dir>/changes.json      epoch; per part: name, change, shape and its parameters (world frame),
//                         sign (gain, loss), volume_m3 (exact, signed), volume_grid_m3 (the
//                         same summed over the terrain grid), max_thickness_m, outline (world
//                         x, y ring); totals gain_m3, loss_m3
// <dir>/changes.geojson   the parts' outlines as an RFC 7946 FeatureCollection (WGS 84 lon,
//                         lat), properties name, change, sign, volume_m3
// <dir>/change.f32        the height change (this epoch minus epoch 1) at the terrain grid's
//                         nodes, float32 little-endian, row-major as terrain.f32, metres
#pragma once

#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "common/se3.hpp"
#include "tools/sim/echo_artifacts.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

struct TruthPose {
    double gps_time_s = 0;  // GPS seconds since 1980-01-06
    Pose T_world_vehicle;
};

struct TruthBoresight {
    double roll_deg = 0, pitch_deg = 0, yaw_deg = 0;  // R_vehicle_sonar error about the nominal
    std::vector<double> lever_arm_sonar_m;            // vehicle frame
};

// The topside PC clock that stamps the 83P headers, stated so an estimator's sign can be
// checked: at t seconds after the survey start,
//   offset(t) = sonar header time - UTC = offset_s + drift_ppm * 1e-6 * t,
//   GPS time of the interrogation = header time (read as UTC) + (GPS - UTC) - offset(t),
//   GPS time of the transmit = that + ping_latency_s.
// The header time marks the interrogation and is truncated to header_resolution_s.
struct SonarClockTruth {
    double offset_s = 0;             // sonar header time - UTC at the survey start (t = 0)
    double drift_ppm = 0;            // rate of change of the offset, 1e-6 s/s
    double survey_start_gps_s = 0;   // GPS seconds since 1980-01-06 at t = 0
    int gps_minus_utc_s = 0;         // leap seconds at the survey start
    double ping_latency_s = 0;       // interrogation -> transmit
    double header_resolution_s = 0;  // 0.001 (v1.10 milliseconds) or 0.01 (v1.00 hundredths)
    double first_ping_offset_s = 0;  // offset(t) at the first and last pings' interrogation
    double last_ping_offset_s = 0;
    // Value of pitmap's sonar clock offset (--sonar-clock-offset, vehicle.yaml
    // sonar.clock_offset_s: the sonar clock minus UTC, subtracted from the header time read as
    // UTC, after GPS - UTC) that yields the transmit time of the first ping:
    // first_ping_offset_s - ping_latency_s.
    double ingest_sonar_clock_offset_s = 0;
    // The headers' auxiliary fields (SonarConfig): position feed, heading feed, attitude.
    bool nmea_position = false;
    double nmea_position_rate_hz = 0;
    double nmea_latency_s = 0;
    double nmea_position_noise_m = 0;
    bool nmea_heading = false;
    double nmea_heading_rate_hz = 0;
    bool internal_attitude_sensor = false;
};

// The sonar clock truth of a scenario whose survey starts at start_utime_gps and lasts
// duration_s (pings at k / ping_rate_hz for k < floor(duration_s * ping_rate_hz)).
SonarClockTruth MakeSonarClockTruth(const ScenarioConfig& sc,
                                    std::int64_t start_utime_gps,
                                    double duration_s);

struct Truth {
    Geodetic origin;  // world frame origin
    TerrainGrid terrain;
    std::vector<TruthPose> trajectory;
    // WriteTruth leaves <dir>/trajectory.csv alone when set: its writer wrote it row by row
    // (pitmap-sim synth, formats::TrajectoryCsvWriter: an hours-long survey's truth is not held).
    bool trajectory_written = false;
    TruthBoresight boresight;
    std::vector<std::uint8_t> coverage;  // empty, or one byte per terrain cell (insonified = 1)
    std::optional<SonarClockTruth> sonar_clock;  // written when set; read when present
    std::vector<float> backscatter_db;           // empty, or BS per terrain cell, dB
    BackscatterConfig backscatter;               // its parameters (with backscatter_db)
    std::optional<ArtifactTruth> artifacts;      // written when set; read when present
    int epoch = 1;                               // repeat surveys: this survey's epoch
    std::vector<ChangePart> changes;             // since epoch 1 (changes.json), may be empty
    std::vector<float> change_m;                 // empty, or per terrain cell (change.f32)
    // The water column the pings were ray traced through (scenario.json "water" with
    // refraction true); nullopt = straight rays at the sonar's sound speed. Read only.
    std::optional<WaterColumnConfig> water;
};

Status WriteScenarioJson(const std::string& path, const ScenarioConfig& sc);
Status WriteTruth(const std::string& dir, const ScenarioConfig& sc, const Truth& truth);
// capacity.csv, and for a repeat survey changes.json, changes.geojson and change.f32 (above);
// WriteTruth calls it.
Status WriteChangeTruth(const std::string& dir, const Truth& truth);
// Reads what WriteTruth wrote; every missing or malformed file is an error naming it.
Expected<Truth> ReadTruth(const std::string& dir);

// Interpolated true pose at a GPS time (linear position, slerp attitude); fails outside the
// trajectory's time span.
Expected<Pose> InterpolateTruth(const std::vector<TruthPose>& trajectory, double gps_time_s);

}  // namespace pitmap::sim
