// SPDX-License-Identifier: MIT
#include "tools/sim/truth_io.hpp"

#include "tools/sim/terrain_change.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/byte_io.hpp"
#include "common/formats/trajectory_csv.hpp"
#include "common/frames.hpp"
#include "common/gps_time.hpp"

namespace pitmap::sim {
namespace {

using nlohmann::json;

json BackscatterToJson(const BackscatterConfig& b) {
    return {{"patch_levels_db", b.patch_levels_db},
            {"patch_size_m", b.patch_size_m},
            {"boulder_db", b.boulder_db},
            {"source_level_db", b.source_level_db},
            {"spreading_db_per_decade", b.spreading_db_per_decade},
            {"absorption_db_per_m", b.absorption_db_per_m},
            {"specular_db", b.specular_db},
            {"specular_width_deg", b.specular_width_deg},
            {"speckle_db", b.speckle_db}};
}

json EchoArtifactsToJson(const EchoArtifactConfig& a) {
    return {{"level", a.level},
            {"num_schools", a.num_schools},
            {"school_min_radius_m", a.school_min_radius_m},
            {"school_max_radius_m", a.school_max_radius_m},
            {"school_lifetime_s", a.school_lifetime_s},
            {"school_drift_mps", a.school_drift_mps},
            {"school_fill", a.school_fill},
            {"school_min_depth_m", a.school_min_depth_m},
            {"bubble_episodes_per_min", a.bubble_episodes_per_min},
            {"bubble_turn_rate_deg_s", a.bubble_turn_rate_deg_s},
            {"bubble_pitch_rate_deg_s", a.bubble_pitch_rate_deg_s},
            {"bubble_manoeuvre_factor", a.bubble_manoeuvre_factor},
            {"bubble_min_pings", a.bubble_min_pings},
            {"bubble_max_pings", a.bubble_max_pings},
            {"bubble_sector_min", a.bubble_sector_min},
            {"bubble_sector_max", a.bubble_sector_max},
            {"bubble_return_share", a.bubble_return_share},
            {"bubble_dropout_share", a.bubble_dropout_share},
            {"bubble_min_range_m", a.bubble_min_range_m},
            {"bubble_max_range_m", a.bubble_max_range_m},
            {"multipath_probability", a.multipath_probability},
            {"multipath_grazing_deg", a.multipath_grazing_deg},
            {"multipath_wall_slope_deg", a.multipath_wall_slope_deg},
            {"multipath_min_beams", a.multipath_min_beams},
            {"multipath_max_beams", a.multipath_max_beams},
            {"multipath_min_pings", a.multipath_min_pings},
            {"multipath_max_pings", a.multipath_max_pings},
            {"multipath_min_excess", a.multipath_min_excess},
            {"multipath_max_excess", a.multipath_max_excess},
            {"smile_probability", a.smile_probability},
            {"smile_max_nadir_range_m", a.smile_max_nadir_range_m},
            {"smile_min_angle_deg", a.smile_min_angle_deg},
            {"smile_max_angle_deg", a.smile_max_angle_deg},
            {"smile_min_pings", a.smile_min_pings},
            {"smile_max_pings", a.smile_max_pings}};
}

// "0_20", "20_45", "45_91": slope class c's key.
std::string SlopeKey(int c) {
    return std::to_string(static_cast<int>(kArtifactSlopeEdgesDeg[c])) + "_" +
           std::to_string(static_cast<int>(kArtifactSlopeEdgesDeg[c + 1]));
}

json ArtifactCountsToJson(const ArtifactTruth& a) {
    json beams;
    for (int k = 1; k < kNumEchoArtifactKinds; ++k) {
        beams[EchoArtifactName(static_cast<EchoArtifactKind>(k))] = a.beams_by_kind[k];
    }
    json slope = json::object();
    for (int c = 0; c < kNumArtifactSlopeClasses; ++c) {
        slope[SlopeKey(c)] = a.good_by_slope[c];
    }
    const double total = static_cast<double>(a.pings) * a.beams_per_ping;
    return {{"pings", a.pings},
            {"beams_per_ping", a.beams_per_ping},
            {"beams", beams},
            {"artifact_soundings", a.artifact_soundings()},
            {"artifact_share", total > 0 ? static_cast<double>(a.artifact_soundings()) / total : 0},
            {"good_soundings", a.good_soundings},
            {"good_soundings_by_slope_deg", slope}};
}

json ScenarioToJson(const ScenarioConfig& s) {
    json j;
    j["name"] = s.name;
    j["seed"] = s.seed;
    j["epoch"] = s.epoch;
    j["terrain_seed"] = s.TerrainSeed();
    j["changes"] = json::array();
    for (const ChangePart& c : s.changes) {
        j["changes"].push_back({{"name", c.name},
                                {"change", c.change},
                                {"shape", ToString(c.shape)},
                                {"x_m", c.x_m},
                                {"y_m", c.y_m},
                                {"heading_deg", c.heading_deg},
                                {"a_m", c.a_m},
                                {"b_m", c.b_m},
                                {"ramp_m", c.ramp_m},
                                {"thickness_m", c.thickness_m}});
    }
    j["start_utc"] = s.start_utc;
    j["origin"] = {{"latitude_deg", s.origin_latitude_deg},
                   {"longitude_deg", s.origin_longitude_deg},
                   {"height_m", s.origin_height_m},
                   {"geoid_undulation_m", s.geoid_undulation_m}};
    const PitConfig& p = s.pit;
    j["pit"] = {{"half_length_m", p.half_length_m},
                {"half_width_m", p.half_width_m},
                {"superellipse_exponent", p.superellipse_exponent},
                {"max_depth_m", p.max_depth_m},
                {"floor_depth_m", p.floor_depth_m},
                {"num_benches", p.num_benches},
                {"bench_width_m", p.bench_width_m},
                {"wall_slope_deg", p.wall_slope_deg},
                {"shore_slope_deg", p.shore_slope_deg},
                {"backfill_amplitude_m", p.backfill_amplitude_m},
                {"backfill_wavelength_m", p.backfill_wavelength_m},
                {"rubble_amplitude_m", p.rubble_amplitude_m},
                {"rubble_wavelength_m", p.rubble_wavelength_m},
                {"grid_resolution_m", p.grid_resolution_m},
                {"land_height_m", p.land_height_m},
                {"high_wall_slope_deg", p.high_wall_slope_deg},
                {"high_wall_direction_deg", p.high_wall_direction_deg},
                {"high_wall_half_angle_deg", p.high_wall_half_angle_deg},
                {"high_wall_blend_deg", p.high_wall_blend_deg},
                {"ramp_width_m", p.ramp_width_m},
                {"ramp_direction_deg", p.ramp_direction_deg},
                {"ramp_grade_deg", p.ramp_grade_deg},
                {"ramp_bench", p.ramp_bench},
                {"ramp_clockwise", p.ramp_clockwise},
                {"num_boulders", p.num_boulders},
                {"boulder_min_diameter_m", p.boulder_min_diameter_m},
                {"boulder_max_diameter_m", p.boulder_max_diameter_m}};
    const TrackConfig& t = s.track;
    j["track"] = {{"pattern", ToString(t.pattern)},
                  {"star_lines", t.star_lines},
                  {"zigzag_legs", t.zigzag_legs},
                  {"speed_mps", t.speed_mps},
                  {"first_lap_offset_m", t.first_lap_offset_m},
                  {"lap_spacing_m", t.lap_spacing_m},
                  {"num_laps", t.num_laps},
                  {"num_tie_lines", t.num_tie_lines},
                  {"clockwise", t.clockwise},
                  {"duration_s", t.duration_s},
                  {"turn_radius_m", t.turn_radius_m},
                  {"roll_amplitude_deg", t.roll_amplitude_deg},
                  {"pitch_amplitude_deg", t.pitch_amplitude_deg},
                  {"heave_amplitude_m", t.heave_amplitude_m},
                  {"yaw_oscillation_deg", t.yaw_oscillation_deg},
                  {"wave_period_s", t.wave_period_s}};
    j["lever_arms"] = {{"sonar_m", s.lever_arms.sonar_m}, {"antenna_m", s.lever_arms.antenna_m}};
    j["boresight_deg"] = s.boresight_deg;
    const NavErrorConfig& n = s.nav;
    j["nav"] = {{"position_noise_m", n.position_noise_m},
                {"position_gm_sigma_m", n.position_gm_sigma_m},
                {"height_gm_sigma_m", n.height_gm_sigma_m},
                {"position_gm_tau_s", n.position_gm_tau_s},
                {"attitude_gm_sigma_deg", n.attitude_gm_sigma_deg},
                {"heading_gm_sigma_deg", n.heading_gm_sigma_deg},
                {"attitude_gm_tau_s", n.attitude_gm_tau_s},
                {"outages_s", n.outages_s},
                {"outage_velocity_random_walk_mps_per_sqrt_s",
                 n.outage_velocity_random_walk_mps_per_sqrt_s},
                {"outage_vertical_fraction", n.outage_vertical_fraction},
                {"recovery_time_s", n.recovery_time_s},
                {"status_windows", n.status_windows},
                {"drift_windows", n.drift_windows}};
    const WaterColumnConfig& w = s.water;
    j["water"] = {{"refraction", w.refraction},
                  {"surface_speed_mps", w.surface_speed_mps},
                  {"mixed_layer_depth_m", w.mixed_layer_depth_m},
                  {"thermocline_depth_m", w.thermocline_depth_m},
                  {"deep_speed_mps", w.deep_speed_mps},
                  {"deep_gradient_per_s", w.deep_gradient_per_s},
                  {"cast_spacing_m", w.cast_spacing_m}};
    const SonarConfig& o = s.sonar;
    j["sonar"] = {{"ping_rate_hz", o.ping_rate_hz},
                  {"num_beams", o.num_beams},
                  {"start_angle_deg", o.start_angle_deg},
                  {"angle_increment_deg", o.angle_increment_deg},
                  {"beam_width_deg", o.beam_width_deg},
                  {"footprint_rays", o.footprint_rays},
                  {"max_range_m", o.max_range_m},
                  {"range_resolution_mm", o.range_resolution_mm},
                  {"range_noise_fraction", o.range_noise_fraction},
                  {"range_noise_constant_m", o.range_noise_constant_m},
                  {"dropout_probability", o.dropout_probability},
                  {"outlier_probability", o.outlier_probability},
                  {"sound_speed_mps", o.sound_speed_mps},
                  {"intensities", o.intensities},
                  {"format_version", o.format_version},
                  {"topside_clock_offset_s", o.topside_clock_offset_s},
                  {"topside_clock_drift_ppm", o.topside_clock_drift_ppm},
                  {"topside_clock_step_at_s", o.topside_clock_step_at_s},
                  {"topside_clock_step_s", o.topside_clock_step_s},
                  {"ping_latency_ms", o.ping_latency_ms},
                  {"daemon_stamp_error_ms", o.daemon_stamp_error_ms},
                  {"daemon_stamp_error_step_s", o.daemon_stamp_error_step_s},
                  {"daemon_stamp_error_after_ms", o.daemon_stamp_error_after_ms},
                  {"data_latency_ms", o.data_latency_ms},
                  {"nmea_position", o.nmea_position},
                  {"nmea_position_rate_hz", o.nmea_position_rate_hz},
                  {"nmea_latency_s", o.nmea_latency_s},
                  {"nmea_position_noise_m", o.nmea_position_noise_m},
                  {"nmea_speed_noise_mps", o.nmea_speed_noise_mps},
                  {"nmea_heading", o.nmea_heading},
                  {"nmea_heading_rate_hz", o.nmea_heading_rate_hz},
                  {"nmea_heading_noise_deg", o.nmea_heading_noise_deg},
                  {"internal_attitude_sensor", o.internal_attitude_sensor},
                  {"internal_attitude_noise_deg", o.internal_attitude_noise_deg}};
    j["backscatter"] = BackscatterToJson(s.backscatter);
    j["echo_artifacts"] = EchoArtifactsToJson(s.echo_artifacts);
    j["ins_rate_hz"] = s.ins_rate_hz;
    j["imu_rate_hz"] = s.imu_rate_hz;
    j["gnss_rate_hz"] = s.gnss_rate_hz;
    return j;
}

Status WriteText(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    if (!out) return Error{path + ": cannot create"};
    out << text;
    out.close();
    if (!out) return Error{path + ": write failed"};
    return Ok{};
}

Expected<json> ReadJson(const std::string& path) {
    std::ifstream in(path);
    if (!in) return Error{path + ": cannot open"};
    json j = json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded()) return Error{path + ": not valid JSON"};
    return j;
}

json SonarClockToJson(const SonarClockTruth& c) {
    return {
        {"topside_clock_offset_s", c.offset_s},
        {"topside_clock_drift_ppm", c.drift_ppm},
        {"survey_start_gps_s", c.survey_start_gps_s},
        {"gps_minus_utc_s", c.gps_minus_utc_s},
        {"ping_latency_s", c.ping_latency_s},
        {"header_resolution_s", c.header_resolution_s},
        {"first_ping_offset_s", c.first_ping_offset_s},
        {"last_ping_offset_s", c.last_ping_offset_s},
        {"ingest_sonar_clock_offset_s", c.ingest_sonar_clock_offset_s},
        {"definition",
         "offset(t) = sonar header time - UTC = topside_clock_offset_s + "
         "topside_clock_drift_ppm * 1e-6 * t, t = seconds since the survey start "
         "(survey_start_gps_s). A positive offset means the topside PC clock is ahead of UTC."},
        {"gps_from_header",
         "GPS time of the interrogation = header time (read as UTC) + (GPS - UTC) - offset(t); "
         "GPS time of the transmit = that + ping_latency_s. The header time marks the "
         "interrogation, truncated to header_resolution_s."},
        {"ingest",
         "ingest_sonar_clock_offset_s = first_ping_offset_s - ping_latency_s: the value of "
         "pitmap's sonar clock offset (sonar clock minus UTC), which ingest subtracts from the "
         "header time (after GPS - UTC) to get the transmit time "
         "(exact at the first ping; the drift moves it by last - first over the survey)."},
        {"header_aux",
         {{"nmea_position", c.nmea_position},
          {"nmea_position_rate_hz", c.nmea_position_rate_hz},
          {"nmea_latency_s", c.nmea_latency_s},
          {"nmea_position_noise_m", c.nmea_position_noise_m},
          {"nmea_heading", c.nmea_heading},
          {"nmea_heading_rate_hz", c.nmea_heading_rate_hz},
          {"internal_attitude_sensor", c.internal_attitude_sensor},
          {"staleness",
           "header latitude/longitude/speed/course (and external heading) are those of the last "
           "NMEA sentence received at the interrogation: epoch k / rate with k / rate + "
           "nmea_latency_s <= interrogation; latitude/longitude are the GNSS antenna's "
           "(lever_arms.antenna_m) plus nmea_position_noise_m"}}}};
}

Expected<ArtifactTruth> ReadArtifacts(const std::string& dir) {
    auto aj = ReadJson(dir + "/artifacts.json");
    if (!aj) return aj.error();
    ArtifactTruth a;
    try {
        a.first_ping_gps_s = aj->at("first_ping_gps_s").get<double>();
        a.ping_rate_hz = aj->at("ping_rate_hz").get<double>();
        const json& c = aj->at("counts");
        a.pings = c.at("pings").get<std::int64_t>();
        a.beams_per_ping = c.at("beams_per_ping").get<int>();
        for (int k = 1; k < kNumEchoArtifactKinds; ++k) {
            a.beams_by_kind[k] = c.at("beams")
                                     .at(EchoArtifactName(static_cast<EchoArtifactKind>(k)))
                                     .get<std::int64_t>();
        }
        a.good_soundings = c.at("good_soundings").get<std::int64_t>();
        for (int i = 0; i < kNumArtifactSlopeClasses; ++i) {
            a.good_by_slope[i] =
                c.at("good_soundings_by_slope_deg").at(SlopeKey(i)).get<std::int64_t>();
        }
        a.config.level = aj->at("model").at("level").get<std::string>();
    } catch (const json::exception& e) {
        return Error{dir + "/artifacts.json: " + e.what()};
    }
    if (!(a.ping_rate_hz > 0)) return Error{dir + "/artifacts.json: ping_rate_hz must be > 0"};
    const std::string path = dir + "/artifacts.bin";
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open"};
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ByteReader r(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    if (bytes.size() < 16 || bytes.compare(0, 4, "PMEA") != 0)
        return Error{path + ": not an artifact truth file (no PMEA header)"};
    r.Skip(4);
    if (const std::uint16_t version = r.U16Le(); version != 1)
        return Error{path + ": version " + std::to_string(version) + " (this reader knows 1)"};
    a.beams_per_ping = r.U16Le();
    const std::uint64_t n = r.U64Le();
    if (n > r.remaining() / 9 || r.remaining() != n * 9)
        return Error{path + ": size does not match its number of runs"};
    a.runs.resize(n);
    for (ArtifactRun& run : a.runs) {
        run.ping_number = r.U32Le();
        run.first_beam = r.U16Le();
        run.num_beams = r.U16Le();
        const std::uint8_t kind = r.U8();
        if (kind == 0 || kind >= kNumEchoArtifactKinds)
            return Error{path + ": unknown kind " + std::to_string(kind)};
        run.kind = static_cast<EchoArtifactKind>(kind);
    }
    for (std::size_t i = 1; i < a.runs.size(); ++i) {
        const ArtifactRun& p = a.runs[i - 1];
        const ArtifactRun& q = a.runs[i];
        if (q.ping_number < p.ping_number ||
            (q.ping_number == p.ping_number && q.first_beam < p.first_beam + p.num_beams))
            return Error{path + ": runs out of order or overlapping"};
    }
    return a;
}

}  // namespace

SonarClockTruth MakeSonarClockTruth(const ScenarioConfig& sc,
                                    std::int64_t start_utime_gps,
                                    double duration_s) {
    const SonarConfig& so = sc.sonar;
    SonarClockTruth c;
    c.offset_s = so.topside_clock_offset_s;
    c.drift_ppm = so.topside_clock_drift_ppm;
    c.survey_start_gps_s = static_cast<double>(start_utime_gps) * 1e-6;
    c.gps_minus_utc_s = LeapSecondsAtGps(start_utime_gps);
    c.ping_latency_s = so.ping_latency_ms * 1e-3;
    c.header_resolution_s = so.format_version >= 10 ? 0.001 : 0.01;
    const auto pings = static_cast<std::int64_t>(std::floor(duration_s * so.ping_rate_hz + 1e-9));
    const auto offset_at = [&](double t) { return c.offset_s + c.drift_ppm * 1e-6 * t; };
    c.first_ping_offset_s = offset_at(-c.ping_latency_s);
    c.last_ping_offset_s =
        offset_at(static_cast<double>(std::max<std::int64_t>(pings - 1, 0)) / so.ping_rate_hz -
                  c.ping_latency_s);
    c.ingest_sonar_clock_offset_s = c.first_ping_offset_s - c.ping_latency_s;
    c.nmea_position = so.nmea_position;
    c.nmea_position_rate_hz = so.nmea_position_rate_hz;
    c.nmea_latency_s = so.nmea_latency_s;
    c.nmea_position_noise_m = so.nmea_position_noise_m;
    c.nmea_heading = so.nmea_heading;
    c.nmea_heading_rate_hz = so.nmea_heading_rate_hz;
    c.internal_attitude_sensor = so.internal_attitude_sensor;
    return c;
}

Status WriteScenarioJson(const std::string& path, const ScenarioConfig& sc) {
    return WriteText(path, ScenarioToJson(sc).dump(2) + "\n");
}

Status WriteTruth(const std::string& dir, const ScenarioConfig& sc, const Truth& truth) {
    {
        json j = ScenarioToJson(sc);
        if (truth.artifacts) j["echo_artifacts"]["counts"] = ArtifactCountsToJson(*truth.artifacts);
        if (auto s = WriteText(dir + "/scenario.json", j.dump(2) + "\n"); !s) return s;
    }
    if (truth.artifacts) {
        const ArtifactTruth& a = *truth.artifacts;
        json aj = {{"model", EchoArtifactsToJson(a.config)},
                   {"first_ping_gps_s", a.first_ping_gps_s},
                   {"ping_rate_hz", a.ping_rate_hz},
                   {"counts", ArtifactCountsToJson(a)},
                   {"data", "artifacts.bin"},
                   {"kinds",
                    {{"1", "mid_water"},
                     {"2", "bubble"},
                     {"3", "dropout"},
                     {"4", "multipath"},
                     {"5", "smile"},
                     {"6", "outlier"}}},
                   {"layout",
                    "\"PMEA\", u16 version 1, u16 beams per ping, u64 runs; per run u32 ping "
                    "number, u16 first beam, u16 beams, u8 kind; little-endian"},
                   {"definition",
                    "every beam that is not its own echo: artifact soundings (mid_water, bubble, "
                    "multipath, smile) whose range replaced the true one, bubble dropouts (no "
                    "detection) and the uncorrelated coarse outliers (outlier). good_soundings: "
                    "the beams with a detection not listed, by the true slope under the beam"}};
        if (auto s = WriteText(dir + "/artifacts.json", aj.dump(2) + "\n"); !s) return s;
        std::vector<std::uint8_t> bytes;
        bytes.reserve(16 + a.runs.size() * 9);
        ByteWriter w(bytes);
        for (const char c : std::string("PMEA")) w.U8(static_cast<std::uint8_t>(c));
        w.U16Le(1);
        w.U16Le(static_cast<std::uint16_t>(a.beams_per_ping));
        w.U64Le(a.runs.size());
        for (const ArtifactRun& r : a.runs) {
            w.U32Le(r.ping_number);
            w.U16Le(r.first_beam);
            w.U16Le(r.num_beams);
            w.U8(static_cast<std::uint8_t>(r.kind));
        }
        if (auto s = WriteText(dir + "/artifacts.bin", std::string(bytes.begin(), bytes.end()));
            !s) {
            return s;
        }
    }
    const TerrainGrid& g = truth.terrain;
    json th = {{"x0_m", g.x0_m},
               {"y0_m", g.y0_m},
               {"resolution_m", g.resolution_m},
               {"nx", g.nx},
               {"ny", g.ny},
               {"data", "terrain.f32"},
               {"layout", "float32 little-endian, row-major iy*nx+ix, z up, metres"},
               {"frame", "world: ENU at origin"},
               {"origin",
                {{"latitude_deg", truth.origin.latitude_deg},
                 {"longitude_deg", truth.origin.longitude_deg},
                 {"height_m", truth.origin.height_m}}}};
    if (auto s = WriteText(dir + "/terrain.json", th.dump(2) + "\n"); !s) return s;
    {
        std::vector<std::uint8_t> bytes;
        bytes.reserve(g.height_m.size() * 4);
        ByteWriter w(bytes);
        for (const float h : g.height_m) w.F32Le(h);
        if (auto s = WriteText(dir + "/terrain.f32", std::string(bytes.begin(), bytes.end())); !s)
            return s;
    }
    if (!truth.trajectory_written) {
        formats::TrajectoryCsv csv;
        for (const TruthPose& p : truth.trajectory) {
            csv.rows.push_back(formats::RowOf(p.gps_time_s, p.T_world_vehicle));
        }
        if (auto s = formats::WriteTrajectoryCsv(dir + "/trajectory.csv", csv); !s) return s;
    }
    if (!truth.backscatter_db.empty()) {
        if (truth.backscatter_db.size() != g.height_m.size())
            return Error{"backscatter does not match the terrain grid"};
        json bj = BackscatterToJson(truth.backscatter);
        bj["data"] = "backscatter.f32";
        bj["layout"] = "float32 little-endian, row-major iy*nx+ix as terrain.f32, dB";
        bj["model"] =
            "BS(x, y): squares of patch_size_m (world x, y) of one of patch_levels_db each, "
            "boulders boulder_db. Echo level L = source_level_db - spreading_db_per_decade "
            "log10(R) - 2 absorption_db_per_m R + BS + AR(theta) + speckle_db N(0, 1), "
            "AR(theta) = 10 log10(cos^2 theta) + specular_db exp(-(theta / "
            "specular_width_deg)^2), theta the incidence on the true terrain; 83P intensity = "
            "round(10^(L / 20)) in 1..65535";
        if (auto s = WriteText(dir + "/backscatter.json", bj.dump(2) + "\n"); !s) return s;
        std::vector<std::uint8_t> bytes;
        bytes.reserve(truth.backscatter_db.size() * 4);
        ByteWriter w(bytes);
        for (const float v : truth.backscatter_db) w.F32Le(v);
        if (auto s = WriteText(dir + "/backscatter.f32", std::string(bytes.begin(), bytes.end()));
            !s) {
            return s;
        }
    }
    if (!truth.coverage.empty()) {
        if (truth.coverage.size() != g.height_m.size())
            return Error{"coverage does not match the terrain grid"};
        if (auto s = WriteText(dir + "/coverage.u8",
                               std::string(truth.coverage.begin(), truth.coverage.end()));
            !s) {
            return s;
        }
    }
    if (truth.sonar_clock) {
        if (auto s = WriteText(dir + "/sonar_clock.json",
                               SonarClockToJson(*truth.sonar_clock).dump(2) + "\n");
            !s) {
            return s;
        }
    }
    if (auto s = WriteChangeTruth(dir, truth); !s) return s;
    json b = {
        {"roll_deg", truth.boresight.roll_deg},
        {"pitch_deg", truth.boresight.pitch_deg},
        {"yaw_deg", truth.boresight.yaw_deg},
        {"lever_arm_sonar_m", truth.boresight.lever_arm_sonar_m},
        {"convention",
         "R_vehicle_sonar = Rz(yaw) Ry(pitch) Rx(roll), vehicle FRD, sonar x fwd y stbd z down"}};
    return WriteText(dir + "/boresight.json", b.dump(2) + "\n");
}

namespace {

std::string F32Bytes(const std::vector<float>& values) {
    std::vector<std::uint8_t> bytes;
    bytes.reserve(values.size() * 4);
    ByteWriter w(bytes);
    for (const float v : values) w.F32Le(v);
    return std::string(bytes.begin(), bytes.end());
}

}  // namespace

Status WriteChangeTruth(const std::string& dir, const Truth& truth) {
    const TerrainGrid& g = truth.terrain;
    {
        // The capacity curve of this epoch's terrain (the water surface of the survey at 0).
        float lowest = 0;
        for (const float h : g.height_m) lowest = std::min(lowest, h);
        const double step = 0.25;
        const double start = std::floor(lowest / step) * step;
        std::string csv = "level_m,level_height_m,area_m2,volume_m3\n";
        char line[160];
        for (const CapacityPoint& c : CapacityCurve(g, start, 0.0, step)) {
            std::snprintf(line,
                          sizeof line,
                          "%.3f,%.4f,%.3f,%.3f\n",
                          c.level_m,
                          truth.origin.height_m + c.level_m,
                          c.area_m2,
                          c.volume_m3);
            csv += line;
        }
        if (auto s = WriteText(dir + "/capacity.csv", csv); !s) return s;
    }
    if (truth.changes.empty()) return Ok{};
    const LocalTangentFrame tf(truth.origin);
    json parts = json::array();
    json features = json::array();
    double gain = 0, loss = 0;
    for (const ChangePart& c : truth.changes) {
        const double v = c.AnalyticVolume();
        (v > 0 ? gain : loss) += v;
        json ring = json::array(), lonlat = json::array();
        for (const Eigen::Vector2d& p : c.Outline()) {
            ring.push_back({p.x(), p.y()});
            const Geodetic geo = tf.FromEnu(Eigen::Vector3d(p.x(), p.y(), 0.0));
            lonlat.push_back({geo.longitude_deg, geo.latitude_deg});
        }
        const std::string sign = c.thickness_m > 0 ? "gain" : "loss";
        parts.push_back({{"name", c.name},
                         {"change", c.change},
                         {"shape", ToString(c.shape)},
                         {"x_m", c.x_m},
                         {"y_m", c.y_m},
                         {"heading_deg", c.heading_deg},
                         {"a_m", c.a_m},
                         {"b_m", c.b_m},
                         {"ramp_m", c.ramp_m},
                         {"thickness_m", c.thickness_m},
                         {"sign", sign},
                         {"volume_m3", v},
                         {"volume_grid_m3", GridVolume(g, c)},
                         {"max_thickness_m", std::abs(c.thickness_m)},
                         {"outline", ring}});
        features.push_back(
            {{"type", "Feature"},
             {"geometry", {{"type", "Polygon"}, {"coordinates", {lonlat}}}},
             {"properties",
              {{"name", c.name}, {"change", c.change}, {"sign", sign}, {"volume_m3", v}}}});
    }
    const json j = {{"epoch", truth.epoch},
                    {"frame", "world: ENU at the terrain's origin; heights z up"},
                    {"gain_m3", gain},
                    {"loss_m3", loss},
                    {"parts", parts}};
    if (auto s = WriteText(dir + "/changes.json", j.dump(2) + "\n"); !s) return s;
    const json fc = {{"type", "FeatureCollection"}, {"features", features}};
    if (auto s = WriteText(dir + "/changes.geojson", fc.dump(1) + "\n"); !s) return s;
    if (truth.change_m.size() == g.height_m.size()) {
        if (auto s = WriteText(dir + "/change.f32", F32Bytes(truth.change_m)); !s) return s;
    }
    return Ok{};
}

namespace {

Expected<std::vector<ChangePart>> ChangesFromJson(const nlohmann::json& parts,
                                                  const std::string& where) {
    std::vector<ChangePart> out;
    try {
        for (const json& p : parts) {
            ChangePart c;
            c.name = p.at("name").get<std::string>();
            c.change = p.at("change").get<std::string>();
            const std::string shape = p.at("shape").get<std::string>();
            if (shape == "paraboloid") {
                c.shape = ChangeShape::kParaboloid;
            } else if (shape == "frustum") {
                c.shape = ChangeShape::kFrustum;
            } else if (shape == "box") {
                c.shape = ChangeShape::kBox;
            } else {
                return Error{where + ": unknown shape '" + shape + "'"};
            }
            c.x_m = p.at("x_m").get<double>();
            c.y_m = p.at("y_m").get<double>();
            c.heading_deg = p.at("heading_deg").get<double>();
            c.a_m = p.at("a_m").get<double>();
            c.b_m = p.at("b_m").get<double>();
            c.ramp_m = p.at("ramp_m").get<double>();
            c.thickness_m = p.at("thickness_m").get<double>();
            if (auto problems = c.Validate(); !problems.empty())
                return Error{where + ": " + problems.front()};
            out.push_back(c);
        }
    } catch (const json::exception& e) {
        return Error{where + ": " + e.what()};
    }
    return out;
}

// A float32 little-endian value per terrain cell (backscatter.f32, change.f32): `cells` of them.
Expected<std::vector<float>> ReadTerrainFloats(const std::string& path,
                                               std::size_t cells,
                                               const std::string& why_needed) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open" + why_needed};
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes.size() != cells * 4) return Error{path + ": size does not match terrain.json"};
    std::vector<float> values(cells);
    ByteReader r(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    for (float& v : values) v = r.F32Le();
    return values;
}

}  // namespace

Expected<Truth> ReadTruth(const std::string& dir) {
    Truth t;
    auto th = ReadJson(dir + "/terrain.json");
    if (!th) return th.error();
    try {
        t.terrain.x0_m = th->at("x0_m").get<double>();
        t.terrain.y0_m = th->at("y0_m").get<double>();
        t.terrain.resolution_m = th->at("resolution_m").get<double>();
        t.terrain.nx = th->at("nx").get<int>();
        t.terrain.ny = th->at("ny").get<int>();
        t.origin.latitude_deg = th->at("origin").at("latitude_deg").get<double>();
        t.origin.longitude_deg = th->at("origin").at("longitude_deg").get<double>();
        t.origin.height_m = th->at("origin").at("height_m").get<double>();
    } catch (const json::exception& e) {
        return Error{dir + "/terrain.json: " + e.what()};
    }
    if (t.terrain.nx < 2 || t.terrain.ny < 2 || !(t.terrain.resolution_m > 0)) {
        return Error{dir + "/terrain.json: bad grid size"};
    }
    {
        const std::string path = dir + "/terrain.f32";
        std::ifstream in(path, std::ios::binary);
        if (!in) return Error{path + ": cannot open"};
        const std::string bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
        const std::size_t n =
            static_cast<std::size_t>(t.terrain.nx) * static_cast<std::size_t>(t.terrain.ny);
        if (bytes.size() != n * 4) return Error{path + ": size does not match terrain.json"};
        t.terrain.height_m.resize(n);
        ByteReader r(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
        for (std::size_t i = 0; i < n; ++i) t.terrain.height_m[i] = r.F32Le();
    }
    {
        auto csv = formats::ReadTrajectoryCsv(dir + "/trajectory.csv");
        if (!csv) return csv.error();
        t.trajectory.reserve(csv->rows.size());
        for (const formats::TrajectoryRow& r : csv->rows) {
            t.trajectory.push_back({r.gps_time_s, formats::PoseOf(r)});
        }
    }
    {
        const std::string path = dir + "/coverage.u8";
        std::ifstream in(path, std::ios::binary);
        if (in) {
            t.coverage.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
            if (t.coverage.size() != t.terrain.height_m.size())
                return Error{path + ": size does not match terrain.json"};
        }
    }
    if (std::ifstream probe(dir + "/backscatter.json"); probe) {
        auto bj = ReadJson(dir + "/backscatter.json");
        if (!bj) return bj.error();
        try {
            BackscatterConfig& b = t.backscatter;
            b.patch_levels_db = bj->at("patch_levels_db").get<std::vector<double>>();
            b.patch_size_m = bj->at("patch_size_m").get<double>();
            b.boulder_db = bj->at("boulder_db").get<double>();
            b.source_level_db = bj->at("source_level_db").get<double>();
            b.spreading_db_per_decade = bj->at("spreading_db_per_decade").get<double>();
            b.absorption_db_per_m = bj->at("absorption_db_per_m").get<double>();
            b.specular_db = bj->at("specular_db").get<double>();
            b.specular_width_deg = bj->at("specular_width_deg").get<double>();
            b.speckle_db = bj->at("speckle_db").get<double>();
        } catch (const json::exception& e) {
            return Error{dir + "/backscatter.json: " + e.what()};
        }
        if (!(t.backscatter.patch_size_m > 0) || !std::isfinite(t.backscatter.patch_size_m))
            return Error{dir + "/backscatter.json: patch_size_m must be > 0"};
        auto values = ReadTerrainFloats(dir + "/backscatter.f32", t.terrain.height_m.size(), "");
        if (!values) return values.error();
        t.backscatter_db = std::move(*values);
    }
    if (std::ifstream probe(dir + "/sonar_clock.json"); probe) {
        auto cj = ReadJson(dir + "/sonar_clock.json");
        if (!cj) return cj.error();
        try {
            SonarClockTruth c;
            c.offset_s = cj->at("topside_clock_offset_s").get<double>();
            c.drift_ppm = cj->at("topside_clock_drift_ppm").get<double>();
            c.survey_start_gps_s = cj->at("survey_start_gps_s").get<double>();
            c.gps_minus_utc_s = cj->at("gps_minus_utc_s").get<int>();
            c.ping_latency_s = cj->at("ping_latency_s").get<double>();
            c.header_resolution_s = cj->at("header_resolution_s").get<double>();
            c.first_ping_offset_s = cj->at("first_ping_offset_s").get<double>();
            c.last_ping_offset_s = cj->at("last_ping_offset_s").get<double>();
            c.ingest_sonar_clock_offset_s = cj->at("ingest_sonar_clock_offset_s").get<double>();
            const json& a = cj->at("header_aux");
            c.nmea_position = a.at("nmea_position").get<bool>();
            c.nmea_position_rate_hz = a.at("nmea_position_rate_hz").get<double>();
            c.nmea_latency_s = a.at("nmea_latency_s").get<double>();
            c.nmea_position_noise_m = a.at("nmea_position_noise_m").get<double>();
            c.nmea_heading = a.at("nmea_heading").get<bool>();
            c.nmea_heading_rate_hz = a.at("nmea_heading_rate_hz").get<double>();
            c.internal_attitude_sensor = a.at("internal_attitude_sensor").get<bool>();
            t.sonar_clock = c;
        } catch (const json::exception& e) {
            return Error{dir + "/sonar_clock.json: " + e.what()};
        }
    }
    if (std::ifstream probe(dir + "/scenario.json"); probe) {
        auto sj = ReadJson(dir + "/scenario.json");
        if (!sj) return sj.error();
        if (sj->contains("water") && sj->at("water").value("refraction", false)) {
            try {
                const json& w = sj->at("water");
                WaterColumnConfig c;
                c.refraction = true;
                c.surface_speed_mps = w.at("surface_speed_mps").get<double>();
                c.mixed_layer_depth_m = w.at("mixed_layer_depth_m").get<double>();
                c.thermocline_depth_m = w.at("thermocline_depth_m").get<double>();
                c.deep_speed_mps = w.at("deep_speed_mps").get<double>();
                c.deep_gradient_per_s = w.at("deep_gradient_per_s").get<double>();
                c.cast_spacing_m = w.at("cast_spacing_m").get<double>();
                t.water = c;
            } catch (const json::exception& e) {
                return Error{dir + "/scenario.json: water: " + e.what()};
            }
        }
    }
    if (std::ifstream probe(dir + "/artifacts.json"); probe) {
        auto r = ReadArtifacts(dir);
        if (!r) return r.error();
        t.artifacts = std::move(*r);
    }
    if (std::ifstream probe(dir + "/changes.json"); probe) {
        auto cj = ReadJson(dir + "/changes.json");
        if (!cj) return cj.error();
        if (!cj->contains("parts") || !(*cj)["parts"].is_array())
            return Error{dir + "/changes.json: no parts"};
        auto parts = ChangesFromJson((*cj)["parts"], dir + "/changes.json");
        if (!parts) return parts.error();
        t.changes = std::move(*parts);
        t.epoch = cj->value("epoch", 2);
        auto values = ReadTerrainFloats(
            dir + "/change.f32", t.terrain.height_m.size(), " (changes.json names changes)");
        if (!values) return values.error();
        t.change_m = std::move(*values);
    }
    auto bj = ReadJson(dir + "/boresight.json");
    if (!bj) return bj.error();
    try {
        t.boresight.roll_deg = bj->at("roll_deg").get<double>();
        t.boresight.pitch_deg = bj->at("pitch_deg").get<double>();
        t.boresight.yaw_deg = bj->at("yaw_deg").get<double>();
        t.boresight.lever_arm_sonar_m = bj->at("lever_arm_sonar_m").get<std::vector<double>>();
    } catch (const json::exception& e) {
        return Error{dir + "/boresight.json: " + e.what()};
    }
    return t;
}

Expected<Pose> InterpolateTruth(const std::vector<TruthPose>& traj, double gps_time_s) {
    if (traj.size() < 2 || gps_time_s < traj.front().gps_time_s ||
        gps_time_s > traj.back().gps_time_s) {
        return Error{"time outside the true trajectory"};
    }
    const auto it =
        std::lower_bound(traj.begin(), traj.end(), gps_time_s, [](const TruthPose& p, double t) {
            return p.gps_time_s < t;
        });
    if (it == traj.begin()) return traj.front().T_world_vehicle;
    const TruthPose& b = *it;
    const TruthPose& a = *(it - 1);
    const double alpha = (gps_time_s - a.gps_time_s) / std::max(b.gps_time_s - a.gps_time_s, 1e-12);
    return InterpolatePose(a.T_world_vehicle, b.T_world_vehicle, alpha);
}

}  // namespace pitmap::sim
