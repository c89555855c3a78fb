// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/to_lcm.hpp"

#include <cctype>
#include <cmath>
#include <limits>
#include <type_traits>
#include <variant>

namespace pitmap::acq {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

template <typename E>
std::int32_t Enum32(E e) {
    return static_cast<std::int32_t>(static_cast<std::underlying_type_t<E>>(e));
}

std::int8_t HeaderKindToLcm(novatel::HeaderKind kind) {
    switch (kind) {
        case novatel::HeaderKind::kLongBinary:
            return pitmap::novatel_header_t::KIND_LONG_BINARY;
        case novatel::HeaderKind::kShortBinary:
            return pitmap::novatel_header_t::KIND_SHORT_BINARY;
        case novatel::HeaderKind::kAscii:
            return pitmap::novatel_header_t::KIND_ASCII;
        case novatel::HeaderKind::kShortAscii:
            return pitmap::novatel_header_t::KIND_SHORT_ASCII;
        case novatel::HeaderKind::kAbbreviated:
            break;
    }
    return 0;  // abbreviated responses have no header
}

void FillTriple(double (&dst)[3], const std::array<double, 3>& src) {
    for (std::size_t i = 0; i < 3; ++i) dst[i] = src[i];
}

void FillTripleScaled(double (&dst)[3], const std::array<double, 3>& src, double factor) {
    for (std::size_t i = 0; i < 3; ++i) dst[i] = src[i] * factor;
}

void FillNaN(double (&dst)[3]) {
    for (double& d : dst) d = kNaN;
}

// Common part of the corrected IMU logs: increments and dt -> rates.
void FillCorrected(pitmap::imu_t& out,
                   const std::array<double, 3>& delta_angle_rad,
                   const std::array<double, 3>& delta_velocity_mps,
                   double dt_s) {
    out.frame = pitmap::imu_t::FRAME_VEHICLE_RFU;
    out.corrected = 1;
    out.imu_type = -1;
    out.imu_status = -1;
    out.dt_s = dt_s;
    FillTriple(out.delta_angle_rad, delta_angle_rad);
    FillTriple(out.delta_velocity_mps, delta_velocity_mps);
    if (std::isfinite(dt_s) && dt_s > 0.0) {
        FillTripleScaled(out.angular_rate_radps, delta_angle_rad, 1.0 / dt_s);
        FillTripleScaled(out.acceleration_mps2, delta_velocity_mps, 1.0 / dt_s);
    } else {
        FillNaN(out.angular_rate_radps);
        FillNaN(out.acceleration_mps2);
    }
}

std::string StringFrom(std::string_view s) {
    return std::string(s.data(), s.size());
}

}  // namespace

pitmap::novatel_header_t ToLcm(const novatel::Header& h) {
    pitmap::novatel_header_t out;
    out.message_id = h.message_id;
    out.header_kind = HeaderKindToLcm(h.kind);
    out.is_response = h.is_response ? 1 : 0;
    out.gps_week = h.gps_week;
    out.gps_ms = static_cast<std::int32_t>(h.gps_ms);
    const bool full =
        h.kind == novatel::HeaderKind::kLongBinary || h.kind == novatel::HeaderKind::kAscii;
    if (full) {
        out.port = h.port_address;
        out.sequence = h.sequence;
        out.idle_percent = h.idle_percent();
        out.time_status = static_cast<std::int16_t>(h.time_status);
        out.receiver_status = h.receiver_status;
        out.reserved = h.reserved;
        out.sw_build = h.sw_build;
    } else {
        out.port = -1;
        out.sequence = -1;
        out.idle_percent = -1.0f;
        out.time_status = -1;
        out.receiver_status = -1;
        out.reserved = -1;
        out.sw_build = -1;
        if (h.kind == novatel::HeaderKind::kAbbreviated) {
            out.gps_week = -1;
            out.gps_ms = -1;
        }
    }
    return out;
}

pitmap::gnss_position_t ToLcm(const novatel::BestPos& m, std::int64_t utime_host) {
    pitmap::gnss_position_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.solution_status = Enum32(m.solution_status);
    out.position_type = Enum32(m.position_type);
    out.latitude_deg = m.latitude_deg;
    out.longitude_deg = m.longitude_deg;
    out.height_msl_m = m.height_msl_m;
    out.undulation_m = m.undulation_m;
    out.datum_id = static_cast<std::int32_t>(m.datum_id);
    out.latitude_stddev_m = m.latitude_stddev_m;
    out.longitude_stddev_m = m.longitude_stddev_m;
    out.height_stddev_m = m.height_stddev_m;
    out.base_station_id = m.base_station_id;
    out.differential_age_s = m.differential_age_s;
    out.solution_age_s = m.solution_age_s;
    out.num_svs_tracked = m.num_svs_tracked;
    out.num_svs_in_solution = m.num_svs_in_solution;
    out.num_svs_l1_in_solution = m.num_svs_l1_in_solution;
    out.num_svs_multifreq_in_solution = m.num_svs_multifreq_in_solution;
    out.extended_solution_status = m.extended_solution_status;
    out.galileo_beidou_signal_mask = m.galileo_beidou_signal_mask;
    out.gps_glonass_signal_mask = m.gps_glonass_signal_mask;
    return out;
}

pitmap::gnss_velocity_t ToLcm(const novatel::BestVel& m, std::int64_t utime_host) {
    pitmap::gnss_velocity_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.solution_status = Enum32(m.solution_status);
    out.velocity_type = Enum32(m.velocity_type);
    out.latency_s = m.latency_s;
    out.differential_age_s = m.differential_age_s;
    out.horizontal_speed_mps = m.horizontal_speed_mps;
    out.track_over_ground_deg = m.track_over_ground_deg;
    out.vertical_speed_mps = m.vertical_speed_mps;
    return out;
}

pitmap::ins_pva_t ToLcm(const novatel::InsPva& m, std::int64_t utime_host) {
    pitmap::ins_pva_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.ins_status = Enum32(m.ins_status);
    out.position_type = -1;
    out.latitude_deg = m.latitude_deg;
    out.longitude_deg = m.longitude_deg;
    out.height_ellipsoid_m = m.height_ellipsoid_m;
    out.undulation_m = kNaNf;
    out.velocity_north_mps = m.velocity_north_mps;
    out.velocity_east_mps = m.velocity_east_mps;
    out.velocity_up_mps = m.velocity_up_mps;
    out.roll_deg = m.roll_deg;
    out.pitch_deg = m.pitch_deg;
    out.azimuth_deg = m.azimuth_deg;
    out.has_stddev = 0;
    out.latitude_stddev_m = kNaNf;
    out.longitude_stddev_m = kNaNf;
    out.height_stddev_m = kNaNf;
    out.velocity_north_stddev_mps = kNaNf;
    out.velocity_east_stddev_mps = kNaNf;
    out.velocity_up_stddev_mps = kNaNf;
    out.roll_stddev_deg = kNaNf;
    out.pitch_stddev_deg = kNaNf;
    out.azimuth_stddev_deg = kNaNf;
    out.extended_status = -1;
    out.time_since_update_s = -1;
    return out;
}

pitmap::ins_pva_t ToLcm(const novatel::InsPvaX& m, std::int64_t utime_host) {
    pitmap::ins_pva_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.ins_status = Enum32(m.ins_status);
    out.position_type = Enum32(m.position_type);
    out.latitude_deg = m.latitude_deg;
    out.longitude_deg = m.longitude_deg;
    // INSPVAX reports height above mean sea level and the undulation (§6.4).
    out.height_ellipsoid_m = m.height_msl_m + static_cast<double>(m.undulation_m);
    out.undulation_m = m.undulation_m;
    out.velocity_north_mps = m.velocity_north_mps;
    out.velocity_east_mps = m.velocity_east_mps;
    out.velocity_up_mps = m.velocity_up_mps;
    out.roll_deg = m.roll_deg;
    out.pitch_deg = m.pitch_deg;
    out.azimuth_deg = m.azimuth_deg;
    out.has_stddev = 1;
    out.latitude_stddev_m = m.latitude_stddev_m;
    out.longitude_stddev_m = m.longitude_stddev_m;
    out.height_stddev_m = m.height_stddev_m;
    out.velocity_north_stddev_mps = m.velocity_north_stddev_mps;
    out.velocity_east_stddev_mps = m.velocity_east_stddev_mps;
    out.velocity_up_stddev_mps = m.velocity_up_stddev_mps;
    out.roll_stddev_deg = m.roll_stddev_deg;
    out.pitch_stddev_deg = m.pitch_stddev_deg;
    out.azimuth_stddev_deg = m.azimuth_stddev_deg;
    out.extended_status = m.extended_status;
    out.time_since_update_s = m.time_since_update_s;
    return out;
}

pitmap::ins_attitude_t ToLcm(const novatel::InsAtt& m, std::int64_t utime_host) {
    pitmap::ins_attitude_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.ins_status = Enum32(m.ins_status);
    out.position_type = -1;
    out.roll_deg = m.roll_deg;
    out.pitch_deg = m.pitch_deg;
    out.azimuth_deg = m.azimuth_deg;
    out.has_stddev = 0;
    out.roll_stddev_deg = kNaNf;
    out.pitch_stddev_deg = kNaNf;
    out.azimuth_stddev_deg = kNaNf;
    out.extended_status = -1;
    out.time_since_update_s = -1;
    return out;
}

pitmap::ins_attitude_t ToLcm(const novatel::InsAttX& m, std::int64_t utime_host) {
    pitmap::ins_attitude_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.ins_status = Enum32(m.ins_status);
    out.position_type = Enum32(m.position_type);
    out.roll_deg = m.roll_deg;
    out.pitch_deg = m.pitch_deg;
    out.azimuth_deg = m.azimuth_deg;
    out.has_stddev = 1;
    out.roll_stddev_deg = m.roll_stddev_deg;
    out.pitch_stddev_deg = m.pitch_stddev_deg;
    out.azimuth_stddev_deg = m.azimuth_stddev_deg;
    out.extended_status = m.extended_status;
    out.time_since_update_s = m.time_since_update_s;
    return out;
}

pitmap::ins_stddev_t ToLcm(const novatel::InsStdDev& m, std::int64_t utime_host) {
    pitmap::ins_stddev_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.latitude_stddev_m = m.latitude_stddev_m;
    out.longitude_stddev_m = m.longitude_stddev_m;
    out.height_stddev_m = m.height_stddev_m;
    out.velocity_north_stddev_mps = m.velocity_north_stddev_mps;
    out.velocity_east_stddev_mps = m.velocity_east_stddev_mps;
    out.velocity_up_stddev_mps = m.velocity_up_stddev_mps;
    out.roll_stddev_deg = m.roll_stddev_deg;
    out.pitch_stddev_deg = m.pitch_stddev_deg;
    out.azimuth_stddev_deg = m.azimuth_stddev_deg;
    out.extended_status = m.extended_status;
    out.time_since_update_s = m.time_since_update_s;
    return out;
}

pitmap::imu_t ToLcm(const novatel::CorrImuData& m, std::int64_t utime_host, double rate_hz) {
    pitmap::imu_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.sample_count = 1;
    FillCorrected(
        out, m.delta_angle_rad, m.delta_velocity_mps, rate_hz > 0.0 ? 1.0 / rate_hz : kNaN);
    return out;
}

pitmap::imu_t ToLcm(const novatel::CorrImuS& m, std::int64_t utime_host, double imu_rate_hz) {
    pitmap::imu_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.sample_count = static_cast<std::int32_t>(m.imu_data_count);
    const double dt_s = (imu_rate_hz > 0.0 && m.imu_data_count > 0)
                            ? static_cast<double>(m.imu_data_count) / imu_rate_hz
                            : kNaN;
    FillCorrected(out, m.delta_angle_rad, m.delta_velocity_mps, dt_s);
    return out;
}

pitmap::imu_t ToLcm(const novatel::RawImu& m,
                    std::int64_t utime_host,
                    double imu_rate_hz,
                    std::int32_t imu_type) {
    pitmap::imu_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.frame = pitmap::imu_t::FRAME_IMU_BODY;
    out.corrected = 0;
    out.imu_type = m.imu_type >= 0 ? m.imu_type : imu_type;
    out.imu_status = m.imu_status;
    out.sample_count = 1;
    const auto scale = novatel::ImuScaleFor(out.imu_type, imu_rate_hz);
    if (!scale) {
        out.dt_s = kNaN;
        FillNaN(out.delta_angle_rad);
        FillNaN(out.delta_velocity_mps);
        FillNaN(out.angular_rate_radps);
        FillNaN(out.acceleration_mps2);
        return out;
    }
    const double rate_hz = imu_rate_hz > 0.0 ? imu_rate_hz : scale->nominal_rate_hz;
    const novatel::ImuIncrements inc = novatel::ScaleRawImu(m, *scale, rate_hz);
    FillTriple(out.delta_angle_rad, inc.delta_angle_rad);
    FillTriple(out.delta_velocity_mps, inc.delta_velocity_mps);
    if (rate_hz > 0.0) {
        out.dt_s = 1.0 / rate_hz;
        FillTriple(out.angular_rate_radps, inc.angular_rate_radps);
        FillTriple(out.acceleration_mps2, inc.acceleration_mps2);
    } else {
        out.dt_s = kNaN;
        FillNaN(out.angular_rate_radps);
        FillNaN(out.acceleration_mps2);
    }
    return out;
}

pitmap::gps_time_t ToLcm(const novatel::Time& m, std::int64_t utime_host) {
    pitmap::gps_time_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.clock_model_status = Enum32(m.clock_model_status);
    out.receiver_clock_offset_s = m.receiver_clock_offset_s;
    out.receiver_clock_offset_stddev_s = m.receiver_clock_offset_stddev_s;
    out.utc_offset_s = m.utc_offset_s;
    out.utc_year = static_cast<std::int32_t>(m.utc_year);
    out.utc_month = static_cast<std::int8_t>(m.utc_month);
    out.utc_day = static_cast<std::int8_t>(m.utc_day);
    out.utc_hour = static_cast<std::int8_t>(m.utc_hour);
    out.utc_minute = static_cast<std::int8_t>(m.utc_minute);
    out.utc_ms = static_cast<std::int32_t>(m.utc_ms);
    out.utc_status = Enum32(m.utc_status);
    return out;
}

pitmap::heading_t ToLcm(const novatel::Heading2& m, std::int64_t utime_host) {
    pitmap::heading_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.solution_status = Enum32(m.solution_status);
    out.position_type = Enum32(m.position_type);
    out.baseline_length_m = m.baseline_length_m;
    out.heading_deg = m.heading_deg;
    out.pitch_deg = m.pitch_deg;
    out.heading_stddev_deg = m.heading_stddev_deg;
    out.pitch_stddev_deg = m.pitch_stddev_deg;
    out.rover_station_id = m.rover_station_id;
    out.base_station_id = m.base_station_id;
    out.num_svs_tracked = m.num_svs_tracked;
    out.num_svs_in_solution = m.num_svs_in_solution;
    return out;
}

pitmap::mark_time_t ToLcm(const novatel::MarkTime& m, std::int64_t utime_host) {
    pitmap::mark_time_t out;
    out.utime = utime_host;
    out.utime_gps = m.utime_gps();
    out.header = ToLcm(m.header);
    out.gps_week = m.gps_week;
    out.gps_seconds = m.gps_seconds;
    out.clock_offset_s = m.clock_offset_s;
    out.clock_offset_stddev_s = m.clock_offset_stddev_s;
    out.utc_offset_s = m.utc_offset_s;
    out.clock_model_status = Enum32(m.clock_model_status);
    return out;
}

pitmap::receiver_response_t ToLcm(const novatel::Response& m,
                                  std::int64_t utime_host,
                                  std::string_view source,
                                  std::string_view command) {
    pitmap::receiver_response_t out;
    out.utime = utime_host;
    out.source = StringFrom(source);
    out.message_id = m.form == novatel::Response::Form::kAbbreviated
                         ? -1
                         : static_cast<std::int32_t>(m.header.message_id);
    out.ok = m.ok() ? 1 : 0;
    out.response_id = m.response_id;
    out.text = m.text;
    out.command = StringFrom(command);
    return out;
}

std::optional<EncodedMessage> EncodeNovatel(const novatel::Message& message,
                                            std::int64_t utime_host,
                                            std::string_view channel_id,
                                            const ImuContext& imu) {
    const auto make = [&](std::string_view prefix, const auto& lcm) {
        return std::optional<EncodedMessage>(
            EncodedMessage{ChannelName(prefix, channel_id), EncodeLcm(lcm)});
    };
    return std::visit(
        [&](const auto& m) -> std::optional<EncodedMessage> {
            using T = std::decay_t<decltype(m)>;
            if constexpr (std::is_same_v<T, novatel::BestPos>) {
                return make(kChannelGnssPosition, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::BestVel>) {
                return make(kChannelGnssVelocity, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::InsPva> ||
                                 std::is_same_v<T, novatel::InsPvaX>) {
                return make(kChannelInsPva, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::InsAtt> ||
                                 std::is_same_v<T, novatel::InsAttX>) {
                return make(kChannelInsAttitude, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::InsStdDev>) {
                return make(kChannelInsStdDev, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::CorrImuData>) {
                const double rate = m.header.message_id == novatel::msg_id::kImuRateCorrImuS
                                        ? imu.imu_rate_hz
                                        : imu.corrimu_rate_hz;
                return make(kChannelImu, ToLcm(m, utime_host, rate));
            } else if constexpr (std::is_same_v<T, novatel::CorrImuS>) {
                return make(kChannelImu, ToLcm(m, utime_host, imu.imu_rate_hz));
            } else if constexpr (std::is_same_v<T, novatel::RawImu>) {
                return make(kChannelImu, ToLcm(m, utime_host, imu.imu_rate_hz, imu.imu_type));
            } else if constexpr (std::is_same_v<T, novatel::Time>) {
                return make(kChannelGpsTime, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::Heading2>) {
                return make(kChannelHeading, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::MarkTime>) {
                return make(kChannelMarkTime, ToLcm(m, utime_host));
            } else if constexpr (std::is_same_v<T, novatel::Response>) {
                return make(kChannelResponse, ToLcm(m, utime_host, channel_id));
            } else {
                return std::nullopt;
            }
        },
        message);
}

pitmap::multibeam_ping_t ToLcm(const protocol::deltat::Ping83P& p,
                               std::int64_t utime_host,
                               std::int64_t utime_gps,
                               std::int8_t time_source,
                               float time_stddev_s) {
    pitmap::multibeam_ping_t out;
    out.utime = utime_host;
    out.utime_gps = utime_gps;
    out.gps_time_source = time_source;
    out.gps_time_stddev_s = time_stddev_s;
    out.utime_sonar_header = p.header_time_valid ? p.utime_sonar_header : 0;
    out.format_version = static_cast<std::int8_t>(p.format_version);
    out.ping_number = p.ping_number;
    out.sound_speed_mps = static_cast<float>(p.sound_velocity_mps);
    out.sound_speed_valid = p.sound_velocity_valid ? 1 : 0;
    out.range_resolution_m = static_cast<float>(p.range_resolution_mm / 1000.0);
    out.start_angle_deg = static_cast<float>(p.start_angle_deg());
    out.angle_increment_deg = static_cast<float>(p.angle_increment_deg());
    out.sector_size_deg = static_cast<std::int16_t>(p.sector_size_deg);
    out.acoustic_range_m = static_cast<std::int16_t>(p.acoustic_range_m);
    out.frequency_khz = static_cast<std::int16_t>(p.frequency_khz);
    out.samples_per_beam = static_cast<std::int16_t>(p.samples_per_beam);
    out.profile_tilt_deg = static_cast<std::int16_t>(std::lround(p.profile_tilt_deg));
    out.repetition_rate_ms = static_cast<std::int16_t>(p.repetition_rate_ms);
    out.pulse_length_us = static_cast<std::int16_t>(p.pulse_length_us);
    for (std::size_t i = 0; i < 3; ++i) out.sonar_offset_m[i] = p.sonar_offset_m[i];
    out.intensity_included = p.intensity_included ? 1 : 0;
    out.ping_latency_us = p.is_v110() ? p.ping_latency_us : -1;
    out.data_latency_us = p.is_v110() ? p.data_latency_us : -1;
    out.sample_rate_high = p.sample_rate != 0 ? 1 : 0;
    out.option_flags = p.option_flags;
    out.pings_averaged = p.pings_averaged;
    out.center_ping_offset_us = p.center_ping_offset_us;
    out.internal_attitude_valid = static_cast<std::int8_t>((p.internal_pitch_valid ? 1 : 0) |
                                                           (p.internal_roll_valid ? 2 : 0) |
                                                           (p.internal_heading_valid ? 4 : 0));
    out.internal_pitch_deg = static_cast<float>(p.internal_pitch_deg);
    out.internal_roll_deg = static_cast<float>(p.internal_roll_deg);
    out.internal_heading_deg = static_cast<float>(p.internal_heading_deg);
    out.external_sensor_flags = static_cast<std::int8_t>(p.external_sensor_flags);
    out.external_pitch_deg = p.external_pitch_deg;
    out.external_roll_deg = p.external_roll_deg;
    out.external_heading_deg = p.external_heading_deg;
    out.heave_m = p.heave_m;
    out.altitude_m = p.altitude_m;
    out.transmit_scan_flag = static_cast<std::int8_t>(p.transmit_scan_flag);
    out.transmit_scan_angle_deg = p.transmit_scan_angle_deg;
    out.header_latitude_deg = p.latitude_deg;
    out.header_longitude_deg = p.longitude_deg;
    out.speed_over_ground_knots = static_cast<float>(p.speed_over_ground_knots);
    out.course_over_ground_deg = static_cast<float>(p.course_over_ground_deg);
    out.num_beams = static_cast<std::int16_t>(p.range_counts.size());
    out.range_counts.assign(p.range_counts.begin(), p.range_counts.end());
    if (p.intensity_included) {
        out.num_intensities = static_cast<std::int16_t>(p.intensities.size());
        out.intensities.assign(p.intensities.begin(), p.intensities.end());
    } else {
        out.num_intensities = 0;
        out.intensities.clear();
    }
    return out;
}

pitmap::raw_bytes_t MakeRawBytes(std::int64_t utime_host,
                                 std::string_view source,
                                 std::string_view protocol,
                                 Transport transport,
                                 std::int64_t seq,
                                 std::span<const std::uint8_t> data,
                                 const RawBytesExtra& extra) {
    pitmap::raw_bytes_t out;
    out.utime = utime_host;
    out.utime_gps = extra.utime_gps;
    out.gps_time_valid = extra.gps_time_valid ? 1 : 0;
    out.source = StringFrom(source);
    out.protocol = StringFrom(protocol);
    out.transport = static_cast<std::int8_t>(transport);
    out.seq = seq;
    out.peer = extra.peer;
    out.utime_kernel = extra.utime_kernel;
    out.num_bytes = static_cast<std::int32_t>(data.size());
    out.data.assign(data.begin(), data.end());
    return out;
}

pitmap::raw_bytes_t MakeRawBytes(std::int64_t utime_host,
                                 std::string_view source,
                                 std::string_view protocol,
                                 Transport transport,
                                 std::int64_t seq,
                                 std::span<const std::byte> data,
                                 const RawBytesExtra& extra) {
    return MakeRawBytes(utime_host,
                        source,
                        protocol,
                        transport,
                        seq,
                        std::span<const std::uint8_t>(
                            reinterpret_cast<const std::uint8_t*>(data.data()), data.size()),
                        extra);
}

}  // namespace pitmap::acq
