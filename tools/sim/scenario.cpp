// SPDX-License-Identifier: MIT
#include "tools/sim/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pitmap::sim {
namespace {

ScenarioConfig Demo() {
    ScenarioConfig s;
    s.name = "demo";
    s.seed = 7;
    s.pit.half_length_m = 20.0;
    s.pit.half_width_m = 15.0;
    s.pit.max_depth_m = 12.0;
    s.pit.floor_depth_m = 10.0;
    s.pit.num_benches = 1;
    s.pit.bench_width_m = 3.0;
    s.pit.backfill_amplitude_m = 1.2;
    s.pit.backfill_wavelength_m = 12.0;
    s.track.speed_mps = 1.5;
    s.track.first_lap_offset_m = 4.5;
    s.track.lap_spacing_m = 3.0;
    s.track.num_laps = 3;
    s.track.num_tie_lines = 1;
    s.track.duration_s = 120.0;  // 1 200 pings at 10 Hz
    s.boresight_deg = {0.5, 0.0, 1.0};
    return s;
}

ScenarioConfig Bejanca() {
    ScenarioConfig s;
    s.name = "bejanca";
    s.seed = 1919;
    // Defaults describe the Bejanca pit: 125 m x 90 m, up to 27 m deep, benches, backfill.
    s.track.speed_mps = 1.225;  // 1 567 m in 22 min
    s.track.first_lap_offset_m = 5.0;
    s.track.lap_spacing_m = 9.0;
    s.track.num_laps = 4;
    s.track.num_tie_lines = 3;
    s.track.duration_s = 1278.6;  // 12 786 pings at 10 Hz
    s.boresight_deg = {0.4, -0.3, 1.2};
    // The paper's topside program had no NMEA input and the head no attitude sensor: the 83P
    // headers stay as they were (blank position, no attitude).
    s.sonar.nmea_position = false;
    s.sonar.internal_attitude_sensor = false;
    return s;
}

ScenarioConfig GpsOutage() {
    ScenarioConfig s = Bejanca();
    s.name = "gps-outage";
    s.seed = 1942;
    s.track.speed_mps = 1.04;  // 757 m in 13 min
    s.track.first_lap_offset_m = 6.0;
    s.track.lap_spacing_m = 11.0;
    s.track.num_laps = 3;
    s.track.num_tie_lines = 1;
    s.track.duration_s = 729.1;  // 7 291 pings at 10 Hz
    s.nav.outages_s = {180.0, 420.0};
    return s;
}

// A short survey of a flooded quarry that is not a smooth bowl: two benches, a 65 deg high
// wall on the north side, a haul road down to the first bench on the south side, three dozen
// boulders, RTK-grade navigation without outage, and a topside PC fed with NMEA whose clock
// is 2.35 s ahead of UTC. About 3.5 minutes at 10 Hz: a test fixture for the processor.
ScenarioConfig Quarry() {
    ScenarioConfig s;
    s.name = "quarry";
    s.seed = 2718;
    s.pit.half_length_m = 35.0;
    s.pit.half_width_m = 25.0;
    s.pit.max_depth_m = 17.0;
    s.pit.floor_depth_m = 14.0;
    s.pit.num_benches = 2;
    s.pit.bench_width_m = 3.5;
    s.pit.wall_slope_deg = 55.0;
    s.pit.shore_slope_deg = 40.0;
    s.pit.backfill_amplitude_m = 0.8;
    s.pit.backfill_wavelength_m = 10.0;
    s.pit.rubble_amplitude_m = 0.15;
    s.pit.rubble_wavelength_m = 3.0;
    s.pit.land_height_m = 4.0;
    s.pit.high_wall_slope_deg = 65.0;
    s.pit.high_wall_direction_deg = 90.0;  // north side
    s.pit.high_wall_half_angle_deg = 35.0;
    s.pit.high_wall_blend_deg = 8.0;
    s.pit.ramp_width_m = 5.0;
    s.pit.ramp_direction_deg = -125.0;  // from the south-west corner, eastwards along the shore
    s.pit.ramp_grade_deg = 10.0;
    s.pit.ramp_bench = 1;
    s.pit.num_boulders = 36;
    s.pit.boulder_min_diameter_m = 0.5;
    s.pit.boulder_max_diameter_m = 2.0;
    s.track.speed_mps = 1.5;
    s.track.first_lap_offset_m = 4.0;
    s.track.lap_spacing_m = 7.0;
    s.track.num_laps = 2;
    s.track.num_tie_lines = 1;
    s.track.duration_s = 210.0;  // 2 100 pings at 10 Hz
    s.boresight_deg = {0.6, -0.4, 0.9};
    s.nav.outages_s.clear();  // RTK-grade throughout
    s.sonar.topside_clock_offset_s = 2.350;
    s.sonar.nmea_position = true;
    s.sonar.nmea_heading = true;
    s.sonar.internal_attitude_sensor = true;
    return s;
}

// A larger mine for the scale work (issue 38): a pit of 500 m x 300 m, 45 m deep, four
// benches, surveyed for four hours at the usual 10 Hz (144 000 pings) along five concentric
// laps and four tie lines, repeated. The terrain grid is 0.25 m (2 001 x 1 201 nodes) instead
// of 0.10 m: the same sonar footprint sampling, 6x less memory for the simulator's world.
ScenarioConfig Mine() {
    ScenarioConfig s;
    s.name = "mine";
    s.seed = 500300;
    s.pit.half_length_m = 250.0;
    s.pit.half_width_m = 150.0;
    s.pit.max_depth_m = 45.0;
    s.pit.floor_depth_m = 38.0;
    s.pit.num_benches = 4;
    s.pit.bench_width_m = 10.0;
    s.pit.backfill_amplitude_m = 4.0;
    s.pit.backfill_wavelength_m = 60.0;
    s.pit.grid_resolution_m = 0.25;
    s.pit.num_boulders = 60;
    s.pit.boulder_min_diameter_m = 0.8;
    s.pit.boulder_max_diameter_m = 3.0;
    s.track.speed_mps = 1.5;
    s.track.first_lap_offset_m = 8.0;
    s.track.lap_spacing_m = 24.0;
    s.track.num_laps = 5;
    s.track.num_tie_lines = 4;
    s.track.duration_s = 14400.0;  // 144 000 pings at 10 Hz
    s.boresight_deg = {0.3, -0.5, 0.8};
    return s;
}

void CheckPositive(std::vector<std::string>& p, double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) p.push_back(std::string(name) + " must be > 0");
}

}  // namespace

const char* ToString(TrackPattern p) {
    switch (p) {
        case TrackPattern::kLaps:
            return "laps";
        case TrackPattern::kStar:
            return "star";
        case TrackPattern::kZigzag:
            return "zigzag";
    }
    return "?";
}

Expected<TrackPattern> TrackPatternFromString(const std::string& name) {
    for (const TrackPattern p : {TrackPattern::kLaps, TrackPattern::kStar, TrackPattern::kZigzag}) {
        if (name == ToString(p)) return p;
    }
    return Error{"unknown track pattern '" + name + "' (valid: laps, star, zigzag)"};
}

std::vector<std::string> ScenarioConfig::Validate() const {
    std::vector<std::string> p;
    CheckPositive(p, pit.half_length_m, "pit.half_length_m");
    CheckPositive(p, pit.half_width_m, "pit.half_width_m");
    CheckPositive(p, pit.max_depth_m, "pit.max_depth_m");
    CheckPositive(p, pit.grid_resolution_m, "pit.grid_resolution_m");
    if (pit.superellipse_exponent < 2.0) p.push_back("pit.superellipse_exponent must be >= 2");
    if (pit.floor_depth_m > pit.max_depth_m)
        p.push_back("pit.floor_depth_m must be <= pit.max_depth_m");
    if (pit.num_benches < 0 || pit.num_benches > 10) p.push_back("pit.num_benches must be 0..10");
    if (!(pit.wall_slope_deg > 5 && pit.wall_slope_deg < 89))
        p.push_back("pit.wall_slope_deg must be in (5, 89)");
    if (!(pit.shore_slope_deg > 5 && pit.shore_slope_deg < 89))
        p.push_back("pit.shore_slope_deg must be in (5, 89)");
    if (pit.high_wall_slope_deg != 0) {
        if (!(pit.high_wall_slope_deg > 5 && pit.high_wall_slope_deg < 89))
            p.push_back("pit.high_wall_slope_deg must be 0 (none) or in (5, 89)");
        if (!(pit.high_wall_half_angle_deg > 0 && pit.high_wall_half_angle_deg <= 180))
            p.push_back("pit.high_wall_half_angle_deg must be in (0, 180]");
        if (!(pit.high_wall_blend_deg >= 0 && pit.high_wall_blend_deg < 90))
            p.push_back("pit.high_wall_blend_deg must be in [0, 90)");
        if (!std::isfinite(pit.high_wall_direction_deg))
            p.push_back("pit.high_wall_direction_deg must be finite");
    }
    if (!(pit.ramp_width_m >= 0) || !std::isfinite(pit.ramp_width_m))
        p.push_back("pit.ramp_width_m must be >= 0 (0 = no ramp)");
    if (pit.ramp_width_m > 0) {
        if (!(pit.ramp_grade_deg >= 1 && pit.ramp_grade_deg <= 30))
            p.push_back("pit.ramp_grade_deg must be in [1, 30]");
        if (pit.ramp_bench < 1 || pit.ramp_bench > pit.num_benches)
            p.push_back("pit.ramp_bench must be 1..num_benches");
        if (!std::isfinite(pit.ramp_direction_deg))
            p.push_back("pit.ramp_direction_deg must be finite");
    }
    if (pit.num_boulders < 0 || pit.num_boulders > 10000)
        p.push_back("pit.num_boulders must be 0..10000");
    if (pit.num_boulders > 0 && !(pit.boulder_min_diameter_m > 0 &&
                                  pit.boulder_max_diameter_m >= pit.boulder_min_diameter_m &&
                                  pit.boulder_max_diameter_m <= 20)) {
        p.push_back("pit: boulder diameters must satisfy 0 < min <= max <= 20 m");
    }
    CheckPositive(p, track.speed_mps, "track.speed_mps");
    CheckPositive(p, track.lap_spacing_m, "track.lap_spacing_m");
    if (track.num_laps < 1) p.push_back("track.num_laps must be >= 1");
    if (track.num_tie_lines < 0) p.push_back("track.num_tie_lines must be >= 0");
    if (track.duration_s < 0) p.push_back("track.duration_s must be >= 0 (0 = whole track)");
    if (track.star_lines < 2 || track.star_lines > 90)
        p.push_back("track.star_lines must be 2..90");
    if (track.zigzag_legs < 2 || track.zigzag_legs > 200)
        p.push_back("track.zigzag_legs must be 2..200");
    if (track.first_lap_offset_m + (track.num_laps - 1) * track.lap_spacing_m >=
        std::min(pit.half_length_m, pit.half_width_m)) {
        p.push_back(
            "track: the inner lap lies beyond the pit centre (fewer laps or smaller spacing)");
    }
    if (lever_arms.sonar_m.size() != 3) p.push_back("lever_arms.sonar_m must have 3 elements");
    if (lever_arms.antenna_m.size() != 3) p.push_back("lever_arms.antenna_m must have 3 elements");
    if (boresight_deg.size() != 3)
        p.push_back("boresight_deg must have 3 elements (roll, pitch, yaw)");
    if (nav.outages_s.size() % 2 != 0) p.push_back("nav.outages_s must hold [start, end) pairs");
    if (nav.status_windows.size() % 3 != 0)
        p.push_back("nav.status_windows must hold [start, end, status] triples");
    for (std::size_t i = 0; i + 2 < nav.status_windows.size(); i += 3) {
        if (!(nav.status_windows[i] < nav.status_windows[i + 1]))
            p.push_back("nav.status_windows: start must be < end");
        const double st = nav.status_windows[i + 2];
        if (!(st >= 0 && st <= 14 && st == std::floor(st)))
            p.push_back("nav.status_windows: the status must be a NovAtel INS status (0-14)");
    }
    if (nav.drift_windows.size() % 4 != 0)
        p.push_back("nav.drift_windows must hold [start, end, east, north] quadruples");
    for (std::size_t i = 0; i + 3 < nav.drift_windows.size(); i += 4) {
        if (!(nav.drift_windows[i] < nav.drift_windows[i + 1]))
            p.push_back("nav.drift_windows: start must be < end");
        if (!std::isfinite(nav.drift_windows[i + 2]) || !std::isfinite(nav.drift_windows[i + 3]))
            p.push_back("nav.drift_windows: the drift must be finite");
    }
    if (!std::isfinite(sonar.topside_clock_step_s) || std::abs(sonar.topside_clock_step_s) > 3600)
        p.push_back("sonar.topside_clock_step_s must be finite and within +-3600");
    for (std::size_t i = 0; i + 1 < nav.outages_s.size(); i += 2) {
        if (!(nav.outages_s[i] < nav.outages_s[i + 1]))
            p.push_back("nav.outages_s: start must be < end");
        if (i >= 2 && nav.outages_s[i] < nav.outages_s[i - 1])
            p.push_back("nav.outages_s must be sorted");
    }
    if (water.refraction) {
        for (double v : {water.surface_speed_mps, water.deep_speed_mps}) {
            if (!(v >= 1300 && v <= 1800))
                p.push_back("water: surface_speed_mps and deep_speed_mps must be in [1300, 1800]");
        }
        if (!(water.mixed_layer_depth_m >= 0 &&
              water.thermocline_depth_m > water.mixed_layer_depth_m)) {
            p.push_back("water: need 0 <= mixed_layer_depth_m < thermocline_depth_m");
        }
        if (!(std::abs(water.deep_gradient_per_s) <= 1.0))
            p.push_back("water.deep_gradient_per_s must be within +-1");
        if (!(water.cast_spacing_m >= 0.01 && water.cast_spacing_m <= 10))
            p.push_back("water.cast_spacing_m must be in [0.01, 10]");
    }
    CheckPositive(p, sonar.ping_rate_hz, "sonar.ping_rate_hz");
    if (sonar.num_beams < 1 || sonar.num_beams > 480) p.push_back("sonar.num_beams must be 1..480");
    if (sonar.footprint_rays < 1 || sonar.footprint_rays > 9)
        p.push_back("sonar.footprint_rays must be 1..9");
    CheckPositive(p, sonar.max_range_m, "sonar.max_range_m");
    CheckPositive(p, sonar.range_resolution_mm, "sonar.range_resolution_mm");
    if (sonar.max_range_m * 1000.0 / sonar.range_resolution_mm > 65535.0) {
        p.push_back(
            "sonar: max_range_m / range_resolution does not fit the 83P 16-bit range count");
    }
    if (std::abs(sonar.start_angle_deg) > 90 ||
        std::abs(sonar.start_angle_deg + (sonar.num_beams - 1) * sonar.angle_increment_deg) > 90) {
        p.push_back("sonar: the fan must stay within +-90 deg of nadir");
    }
    if (!(std::abs(sonar.daemon_stamp_error_ms) <= 1000.0))
        p.push_back("sonar.daemon_stamp_error_ms must be within +-1000");
    if (!(std::abs(sonar.daemon_stamp_error_after_ms) <= 1000.0))
        p.push_back("sonar.daemon_stamp_error_after_ms must be within +-1000");
    if (!std::isfinite(sonar.daemon_stamp_error_step_s))
        p.push_back("sonar.daemon_stamp_error_step_s must be finite");
    if (backscatter.patch_levels_db.empty() || backscatter.patch_levels_db.size() > 250)
        p.push_back("backscatter.patch_levels_db must hold 1..250 levels");
    for (double v : backscatter.patch_levels_db) {
        if (!(v >= -80 && v <= 0)) p.push_back("backscatter.patch_levels_db must be within -80..0");
    }
    if (!(backscatter.boulder_db >= -80 && backscatter.boulder_db <= 0))
        p.push_back("backscatter.boulder_db must be within -80..0");
    CheckPositive(p, backscatter.patch_size_m, "backscatter.patch_size_m");
    if (!(backscatter.spreading_db_per_decade >= 0 && backscatter.absorption_db_per_m >= 0 &&
          backscatter.speckle_db >= 0 && backscatter.specular_db >= 0 &&
          std::isfinite(backscatter.source_level_db))) {
        p.push_back("backscatter: spreading, absorption, speckle and specular must be >= 0");
    }
    CheckPositive(p, backscatter.specular_width_deg, "backscatter.specular_width_deg");
    if (sonar.format_version != 0 && sonar.format_version != 10)
        p.push_back("sonar.format_version must be 0 or 10");
    if (sonar.dropout_probability < 0 || sonar.outlier_probability < 0 ||
        sonar.dropout_probability + sonar.outlier_probability > 1) {
        p.push_back("sonar: dropout and outlier probabilities must be >= 0 and sum to <= 1");
    }
    if (sonar.nmea_position) {
        CheckPositive(p, sonar.nmea_position_rate_hz, "sonar.nmea_position_rate_hz");
        if (!(sonar.nmea_position_noise_m >= 0) || !(sonar.nmea_speed_noise_mps >= 0))
            p.push_back("sonar: nmea_position_noise_m and nmea_speed_noise_mps must be >= 0");
    }
    if (sonar.nmea_heading) {
        if (!(sonar.nmea_heading_rate_hz >= 1 && sonar.nmea_heading_rate_hz <= 10))
            p.push_back("sonar.nmea_heading_rate_hz must be in [1, 10]");
        if (!(sonar.nmea_heading_noise_deg >= 0))
            p.push_back("sonar.nmea_heading_noise_deg must be >= 0");
    }
    if ((sonar.nmea_position || sonar.nmea_heading) &&
        !(sonar.nmea_latency_s >= 0 && sonar.nmea_latency_s <= 10)) {
        p.push_back("sonar.nmea_latency_s must be in [0, 10]");
    }
    if (sonar.internal_attitude_sensor && !(sonar.internal_attitude_noise_deg >= 0))
        p.push_back("sonar.internal_attitude_noise_deg must be >= 0");
    if (!std::isfinite(sonar.topside_clock_offset_s) ||
        std::abs(sonar.topside_clock_offset_s) > 30.0 * 86400.0) {
        p.push_back("sonar.topside_clock_offset_s must be finite and within +-30 days");
    }
    if (!std::isfinite(sonar.topside_clock_drift_ppm) ||
        std::abs(sonar.topside_clock_drift_ppm) > 1000) {
        p.push_back("sonar.topside_clock_drift_ppm must be within +-1000");
    }
    {
        const EchoArtifactConfig& a = echo_artifacts;
        if (a.num_schools < 0 || a.num_schools > 10000)
            p.push_back("echo_artifacts.num_schools must be 0..10000");
        if (!(a.school_min_radius_m > 0 && a.school_max_radius_m >= a.school_min_radius_m))
            p.push_back("echo_artifacts: need 0 < school_min_radius_m <= school_max_radius_m");
        if (!(a.school_lifetime_s > 0) || !(a.school_drift_mps >= 0) ||
            !(a.school_fill >= 0 && a.school_fill <= 1) || !(a.school_min_depth_m >= 0))
            p.push_back("echo_artifacts: school lifetime > 0, drift >= 0, fill in [0, 1]");
        if (!(a.bubble_episodes_per_min >= 0) || !(a.bubble_manoeuvre_factor >= 1) ||
            !(a.bubble_turn_rate_deg_s > 0) || !(a.bubble_pitch_rate_deg_s > 0))
            p.push_back("echo_artifacts: bubble rates >= 0, manoeuvre factor >= 1");
        if (a.bubble_min_pings < 1 || a.bubble_max_pings < a.bubble_min_pings)
            p.push_back("echo_artifacts: need 1 <= bubble_min_pings <= bubble_max_pings");
        if (!(a.bubble_sector_min > 0 && a.bubble_sector_max >= a.bubble_sector_min &&
              a.bubble_sector_max <= 1))
            p.push_back("echo_artifacts: need 0 < bubble_sector_min <= bubble_sector_max <= 1");
        if (!(a.bubble_return_share >= 0 && a.bubble_dropout_share >= 0 &&
              a.bubble_return_share + a.bubble_dropout_share <= 1))
            p.push_back("echo_artifacts: bubble return and dropout shares >= 0, sum <= 1");
        if (!(a.bubble_min_range_m > 0 && a.bubble_max_range_m >= a.bubble_min_range_m))
            p.push_back("echo_artifacts: need 0 < bubble_min_range_m <= bubble_max_range_m");
        if (!(a.multipath_probability >= 0 && a.multipath_probability <= 1) ||
            !(a.smile_probability >= 0 && a.smile_probability <= 1))
            p.push_back("echo_artifacts: multipath and smile probabilities in [0, 1]");
        if (a.multipath_min_beams < 1 || a.multipath_max_beams < a.multipath_min_beams ||
            a.multipath_min_pings < 1 || a.multipath_max_pings < a.multipath_min_pings)
            p.push_back("echo_artifacts: multipath beams and pings: 1 <= min <= max");
        if (!(a.multipath_min_excess > 0 && a.multipath_max_excess >= a.multipath_min_excess))
            p.push_back("echo_artifacts: need 0 < multipath_min_excess <= multipath_max_excess");
        if (a.smile_min_pings < 1 || a.smile_max_pings < a.smile_min_pings ||
            !(a.smile_max_angle_deg > a.smile_min_angle_deg && a.smile_min_angle_deg >= 0) ||
            !(a.smile_max_nadir_range_m > 0))
            p.push_back("echo_artifacts: smile pings 1 <= min <= max, 0 <= min < max angle");
    }
    if (epoch < 1 || epoch > 9) p.push_back("epoch must be 1..9");
    for (const ChangePart& c : changes) {
        for (auto& q : c.Validate()) p.push_back(std::move(q));
    }
    CheckPositive(p, ins_rate_hz, "ins_rate_hz");
    CheckPositive(p, imu_rate_hz, "imu_rate_hz");
    CheckPositive(p, gnss_rate_hz, "gnss_rate_hz");
    return p;
}

const std::vector<std::string>& BuiltinScenarioNames() {
    static const std::vector<std::string> kNames = {
        "demo", "bejanca", "gps-outage", "quarry", "mine"};
    return kNames;
}

std::string DescribeScenario(const ScenarioConfig& s) {
    char buf[512];
    std::snprintf(buf,
                  sizeof buf,
                  "pit %.0f x %.0f m, %.0f m deep, %d bench(es), %.0f s, %.0f pings",
                  2 * s.pit.half_length_m,
                  2 * s.pit.half_width_m,
                  s.pit.max_depth_m,
                  s.pit.num_benches,
                  s.track.duration_s,
                  std::floor(s.track.duration_s * s.sonar.ping_rate_hz + 1e-9));
    std::string d = buf;
    if (s.track.pattern != TrackPattern::kLaps) {
        d += std::string("; ") + ToString(s.track.pattern) + " lines";
    }
    if (s.pit.high_wall_slope_deg != 0) {
        std::snprintf(buf, sizeof buf, "; %.0f deg high wall", s.pit.high_wall_slope_deg);
        d += buf;
    }
    if (s.pit.ramp_width_m > 0) {
        std::snprintf(buf, sizeof buf, "; %.0f deg ramp", s.pit.ramp_grade_deg);
        d += buf;
    }
    if (s.pit.num_boulders > 0) d += "; " + std::to_string(s.pit.num_boulders) + " boulders";
    if (!s.nav.outages_s.empty()) {
        d += "; GPS outage(s)";
        for (std::size_t i = 0; i + 1 < s.nav.outages_s.size(); i += 2) {
            std::snprintf(
                buf, sizeof buf, " %.0f-%.0f s", s.nav.outages_s[i], s.nav.outages_s[i + 1]);
            d += buf;
        }
    }
    std::snprintf(buf, sizeof buf, "; topside clock %+.3f s", s.sonar.topside_clock_offset_s);
    d += buf;
    std::string aux;
    if (s.sonar.nmea_position) {
        std::snprintf(buf, sizeof buf, "GGA %g Hz", s.sonar.nmea_position_rate_hz);
        aux += buf;
    }
    if (s.sonar.nmea_heading) {
        std::snprintf(
            buf, sizeof buf, "%sHDT %g Hz", aux.empty() ? "" : ", ", s.sonar.nmea_heading_rate_hz);
        aux += buf;
    }
    if (s.sonar.internal_attitude_sensor)
        aux += std::string(aux.empty() ? "" : ", ") + "pitch/roll";
    d += "; 83P header: " + (aux.empty() ? std::string("no NMEA, no attitude") : aux);
    if (s.water.refraction) {
        std::snprintf(buf,
                      sizeof buf,
                      "; refracting water: %.0f m/s to %.1f m, thermocline to %.1f m, %.0f m/s",
                      s.water.surface_speed_mps,
                      s.water.mixed_layer_depth_m,
                      s.water.thermocline_depth_m,
                      s.water.deep_speed_mps);
        d += buf;
    }
    if (s.echo_artifacts.enabled()) d += "; echo artifacts: " + s.echo_artifacts.level;
    return d;
}

double WaterColumnConfig::SpeedAt(double z) const {
    if (z <= mixed_layer_depth_m) return surface_speed_mps;
    if (z >= thermocline_depth_m) {
        return deep_speed_mps + deep_gradient_per_s * (z - thermocline_depth_m);
    }
    const double a = (z - mixed_layer_depth_m) / (thermocline_depth_m - mixed_layer_depth_m);
    return surface_speed_mps + (deep_speed_mps - surface_speed_mps) * 0.5 *
                                   (1.0 - std::cos(3.14159265358979323846 * a));
}

Expected<EchoArtifactConfig> EchoArtifactsAt(const std::string& level) {
    EchoArtifactConfig a;
    a.level = level;
    // The rates scale together; the shares they give on the quarry survey are measured in
    // docs/echo_artifacts.md (tuned so that "typical" is about 1 % of the beams).
    double k = 0;
    if (level == "none") return a;
    if (level == "light") k = 0.3;
    if (level == "typical") k = 1.0;
    if (level == "heavy") k = 3.0;
    if (k == 0)
        return Error{"unknown echo artifact level '" + level +
                     "' (valid: none, light, typical, heavy)"};
    a.num_schools = static_cast<int>(std::lround(12 * k));
    a.bubble_episodes_per_min = 0.35 * k;
    a.multipath_probability = 4.7e-5 * k;
    a.smile_probability = 0.0048 * k;
    return a;
}

VehicleDescription NominalVehicle(const ScenarioConfig& sc) {
    VehicleDescription v;
    v.name = sc.name == "demo" ? "demo-asv" : "roaz";
    const auto vec = [](const std::vector<double>& a) {
        return a.size() == 3 ? Eigen::Vector3d(a[0], a[1], a[2]) : Eigen::Vector3d::Zero();
    };
    v.sonar_lever_arm_m = vec(sc.lever_arms.sonar_m);
    v.orientation = SonarOrientation::kDown;
    v.connector = ConnectorDirection::kAft;
    v.gnss_antenna_lever_arms_m = {vec(sc.lever_arms.antenna_m)};
    v.ins_height_above_waterline_m = 0.0;  // the INS point rides on the water line
    // The error model the simulator injects, as the `uncertainty:` a survey team would state.
    SensorErrorModel m;
    m.range_sigma_m = sc.sonar.range_noise_constant_m;
    m.range_sigma_fraction = sc.sonar.range_noise_fraction;
    m.beam_angle_sigma_deg = 0;           // beam angles are exact (0.01 deg 83P steps)
    m.surface_sound_speed_sigma_mps = 0;  // the water's sound speed is the header's
    m.mean_sound_speed_sigma_mps = 0;
    m.position_sigma_h_m = sc.nav.position_gm_sigma_m;  // what INSSTDEV reports without GNSS
    m.position_sigma_v_m = sc.nav.height_gm_sigma_m;    // outage (the logs carry it anyway)
    m.position_noise_m = sc.nav.position_noise_m;       // white noise INSSTDEV leaves out
    m.roll_pitch_sigma_deg = sc.nav.attitude_gm_sigma_deg;
    m.heading_sigma_deg = sc.nav.heading_gm_sigma_deg;
    m.heave_sigma_m = 0;  // heights are the INS's
    m.latency_sigma_s = sc.sonar.daemon_stamp_error_ms * 1e-3;
    m.lever_arm_sigma_m = 0;  // the lever arms above are the true ones
    // boresight_sigma_deg: the default (what `pitmap calibrate` leaves of the true boresight).
    v.uncertainty = m;
    return v;
}

Expected<ScenarioConfig> BuiltinScenario(const std::string& name) {
    if (name == "demo") return Demo();
    if (name == "bejanca") return Bejanca();
    if (name == "gps-outage") return GpsOutage();
    if (name == "quarry") return Quarry();
    if (name == "mine") return Mine();
    std::string valid;
    for (const auto& n : BuiltinScenarioNames()) valid += (valid.empty() ? "" : ", ") + n;
    return Error{"unknown scenario '" + name + "' (valid: " + valid + ")"};
}

}  // namespace pitmap::sim
