// SPDX-License-Identifier: MIT
#include "tools/sim/scenario.hpp"

#include <cmath>

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

void CheckPositive(std::vector<std::string>& p, double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) p.push_back(std::string(name) + " must be > 0");
}

}  // namespace

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
    CheckPositive(p, track.speed_mps, "track.speed_mps");
    CheckPositive(p, track.lap_spacing_m, "track.lap_spacing_m");
    if (track.num_laps < 1) p.push_back("track.num_laps must be >= 1");
    if (track.num_tie_lines < 0) p.push_back("track.num_tie_lines must be >= 0");
    if (track.duration_s < 0) p.push_back("track.duration_s must be >= 0 (0 = whole track)");
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
    for (std::size_t i = 0; i + 1 < nav.outages_s.size(); i += 2) {
        if (!(nav.outages_s[i] < nav.outages_s[i + 1]))
            p.push_back("nav.outages_s: start must be < end");
        if (i >= 2 && nav.outages_s[i] < nav.outages_s[i - 1])
            p.push_back("nav.outages_s must be sorted");
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
    if (sonar.format_version != 0 && sonar.format_version != 10)
        p.push_back("sonar.format_version must be 0 or 10");
    if (sonar.dropout_probability < 0 || sonar.outlier_probability < 0 ||
        sonar.dropout_probability + sonar.outlier_probability > 1) {
        p.push_back("sonar: dropout and outlier probabilities must be >= 0 and sum to <= 1");
    }
    CheckPositive(p, ins_rate_hz, "ins_rate_hz");
    CheckPositive(p, imu_rate_hz, "imu_rate_hz");
    CheckPositive(p, gnss_rate_hz, "gnss_rate_hz");
    return p;
}

const std::vector<std::string>& BuiltinScenarioNames() {
    static const std::vector<std::string> kNames = {"demo", "bejanca", "gps-outage"};
    return kNames;
}

Expected<ScenarioConfig> BuiltinScenario(const std::string& name) {
    if (name == "demo") return Demo();
    if (name == "bejanca") return Bejanca();
    if (name == "gps-outage") return GpsOutage();
    std::string valid;
    for (const auto& n : BuiltinScenarioNames()) valid += (valid.empty() ? "" : ", ") + n;
    return Error{"unknown scenario '" + name + "' (valid: " + valid + ")"};
}

}  // namespace pitmap::sim
