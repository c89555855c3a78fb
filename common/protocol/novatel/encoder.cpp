// SPDX-License-Identifier: MIT
#include "common/protocol/novatel/encoder.hpp"

#include <cstdarg>
#include <cstdio>
#include <initializer_list>
#include <string>

#include "common/protocol/novatel/crc32.hpp"

namespace pitmap::protocol::novatel {
namespace {

constexpr std::uint8_t kResponseBit = 0x80;

bool IdIn(std::uint16_t id, std::initializer_list<std::uint16_t> ids) {
    for (auto i : ids) {
        if (i == id) return true;
    }
    return false;
}

bool IsShort(const Header& h) {
    return h.kind == HeaderKind::kShortBinary || h.kind == HeaderKind::kShortAscii;
}

void AppendCrc(std::vector<std::uint8_t>& out, std::size_t start) {
    const std::uint32_t crc = Crc32(ByteSpan(out.data() + start, out.size() - start));
    ByteWriter(out).U32Le(crc);
}

// Writes the header, calls body(w), patches the length and appends the CRC. Returns false and
// restores `out` if the body is too long for the header.
template <typename BodyFn>
bool WriteFrame(const Header& h, std::vector<std::uint8_t>& out, BodyFn&& body) {
    const std::size_t start = out.size();
    ByteWriter w(out);
    const bool is_short = IsShort(h);
    w.U8(0xAA);
    w.U8(0x44);
    if (is_short) {
        w.U8(0x13);
        w.U8(0);  // length, patched below
        w.U16Le(h.message_id);
        w.U16Le(h.gps_week);
        w.U32Le(h.gps_ms);
    } else {
        w.U8(0x12);
        w.U8(static_cast<std::uint8_t>(kLongHeaderMinLength));
        w.U16Le(h.message_id);
        w.U8(static_cast<std::uint8_t>((h.message_type & 0x7F) |
                                       (h.is_response ? kResponseBit : 0)));
        w.U8(h.port_address);
        w.U16Le(0);  // length, patched below
        w.U16Le(h.sequence);
        w.U8(h.idle_time);
        w.U8(static_cast<std::uint8_t>(h.time_status));
        w.U16Le(h.gps_week);
        w.U32Le(h.gps_ms);
        w.U32Le(h.receiver_status);
        w.U16Le(h.reserved);
        w.U16Le(h.sw_build);
    }
    const std::size_t body_start = out.size();
    body(w);
    const std::size_t body_length = out.size() - body_start;
    const std::size_t max_body =
        is_short ? 255 : kMaxLongFrameLength - kLongHeaderMinLength - kCrcLength;
    if (body_length > max_body) {
        out.resize(start);
        return false;
    }
    if (is_short) {
        out[start + 3] = static_cast<std::uint8_t>(body_length);
    } else {
        w.PatchU16Le(start + 8, static_cast<std::uint16_t>(body_length));
    }
    AppendCrc(out, start);
    return true;
}

template <typename E>
void WriteEnum(ByteWriter& w, E v) {
    w.U32Le(static_cast<std::uint32_t>(v));
}

void WriteVec3(ByteWriter& w, const std::array<double, 3>& v) {
    for (double x : v) w.F64Le(x);
}

std::uint32_t Neg32(std::int64_t v) {
    return static_cast<std::uint32_t>(-v);
}

// ---- ASCII ----

class Line {
public:
    explicit Line(std::vector<std::uint8_t>& out) : out_(out), start_(out.size()) {}

    void Raw(std::string_view s) { out_.insert(out_.end(), s.begin(), s.end()); }
    void Printf(const char* fmt, ...) __attribute__((format(printf, 2, 3))) {
        char buf[512];
        va_list args;
        va_start(args, fmt);
        va_list copy;
        va_copy(copy, args);
        const int n = std::vsnprintf(buf, sizeof buf, fmt, args);
        va_end(args);
        if (n >= 0 && static_cast<std::size_t>(n) < sizeof buf) {
            Raw(std::string_view(buf, static_cast<std::size_t>(n)));
        } else if (n > 0) {
            // Long station ids or huge numbers: format again into a buffer of the right size.
            std::string big(static_cast<std::size_t>(n) + 1, '\0');
            std::vsnprintf(big.data(), big.size(), fmt, copy);
            Raw(std::string_view(big.data(), static_cast<std::size_t>(n)));
        }
        va_end(copy);
    }
    void Sep() { out_.push_back(','); }
    template <typename E>
    void Enum(E v) {
        const std::string_view name = ToString(v);
        if (name.empty()) {
            Printf("%u", static_cast<unsigned>(v));
        } else {
            Raw(name);
        }
    }
    // Terminates with "*crc\r\n" (CRC over the bytes after the sync character).
    void FinishCrc() {
        const std::uint32_t crc =
            Crc32(ByteSpan(out_.data() + start_ + 1, out_.size() - start_ - 1));
        Printf("*%08x\r\n", crc);
    }

private:
    std::vector<std::uint8_t>& out_;
    std::size_t start_;
};

void AsciiHeader(Line& l, const Header& h, std::string_view name, char suffix) {
    const bool is_short = IsShort(h);
    l.Raw(is_short ? "%" : "#");
    l.Raw(name);
    l.Raw(std::string_view(&suffix, 1));
    l.Sep();
    if (is_short) {
        l.Printf("%u,%.3f;", h.gps_week, h.gps_ms / 1000.0);
        return;
    }
    const std::string port =
        h.port_name.empty() ? PortNameFromAddress(h.port_address) : h.port_name;
    l.Raw(port.empty() ? "UNKNOWN" : port);
    l.Printf(",%u,%.1f,", h.sequence, h.idle_percent());
    l.Enum(h.time_status);
    l.Printf(",%u,%.3f,%08x,%04x,%u;",
             h.gps_week,
             h.gps_ms / 1000.0,
             h.receiver_status,
             h.reserved,
             h.sw_build);
}

void AsciiBody(Line& l, const BestPos& m) {
    l.Enum(m.solution_status);
    l.Sep();
    l.Enum(m.position_type);
    l.Printf(",%.11f,%.11f,%.4f,%.4f,",
             m.latitude_deg,
             m.longitude_deg,
             m.height_msl_m,
             static_cast<double>(m.undulation_m));
    const std::string_view datum = DatumName(m.datum_id);
    if (datum.empty()) {
        l.Printf("%u", m.datum_id);
    } else {
        l.Raw(datum);
    }
    l.Printf(",%.4f,%.4f,%.4f,\"%.4s\",%.3f,%.3f,%u,%u,%u,%u,%x,%02x,%02x,%02x",
             static_cast<double>(m.latitude_stddev_m),
             static_cast<double>(m.longitude_stddev_m),
             static_cast<double>(m.height_stddev_m),
             m.base_station_id.c_str(),
             static_cast<double>(m.differential_age_s),
             static_cast<double>(m.solution_age_s),
             m.num_svs_tracked,
             m.num_svs_in_solution,
             m.num_svs_l1_in_solution,
             m.num_svs_multifreq_in_solution,
             m.reserved,
             m.extended_solution_status,
             m.galileo_beidou_signal_mask,
             m.gps_glonass_signal_mask);
}

void AsciiBody(Line& l, const BestVel& m) {
    l.Enum(m.solution_status);
    l.Sep();
    l.Enum(m.velocity_type);
    l.Printf(",%.3f,%.3f,%.4f,%.6f,%.4f,%.1f",
             static_cast<double>(m.latency_s),
             static_cast<double>(m.differential_age_s),
             m.horizontal_speed_mps,
             m.track_over_ground_deg,
             m.vertical_speed_mps,
             static_cast<double>(m.reserved));
}

void AsciiBody(Line& l, const InsPva& m) {
    l.Printf("%u,%.9f,%.11f,%.11f,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,",
             m.gps_week,
             m.gps_seconds,
             m.latitude_deg,
             m.longitude_deg,
             m.height_ellipsoid_m,
             m.velocity_north_mps,
             m.velocity_east_mps,
             m.velocity_up_mps,
             m.roll_deg,
             m.pitch_deg,
             m.azimuth_deg);
    l.Enum(m.ins_status);
}

void AsciiBody(Line& l, const InsPvaX& m) {
    l.Enum(m.ins_status);
    l.Sep();
    l.Enum(m.position_type);
    l.Printf(",%.11f,%.11f,%.4f,%.4f,%.4f,%.4f,%.4f,%.9f,%.9f,%.9f,",
             m.latitude_deg,
             m.longitude_deg,
             m.height_msl_m,
             static_cast<double>(m.undulation_m),
             m.velocity_north_mps,
             m.velocity_east_mps,
             m.velocity_up_mps,
             m.roll_deg,
             m.pitch_deg,
             m.azimuth_deg);
    l.Printf("%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%08x,%u",
             static_cast<double>(m.latitude_stddev_m),
             static_cast<double>(m.longitude_stddev_m),
             static_cast<double>(m.height_stddev_m),
             static_cast<double>(m.velocity_north_stddev_mps),
             static_cast<double>(m.velocity_east_stddev_mps),
             static_cast<double>(m.velocity_up_stddev_mps),
             static_cast<double>(m.roll_stddev_deg),
             static_cast<double>(m.pitch_stddev_deg),
             static_cast<double>(m.azimuth_stddev_deg),
             m.extended_status,
             m.time_since_update_s);
}

void AsciiBody(Line& l, const Time& m) {
    l.Enum(m.clock_model_status);
    l.Printf(",%.9e,%.9e,%.11f,%u,%u,%u,%u,%u,%u,",
             m.receiver_clock_offset_s,
             m.receiver_clock_offset_stddev_s,
             m.utc_offset_s,
             m.utc_year,
             m.utc_month,
             m.utc_day,
             m.utc_hour,
             m.utc_minute,
             m.utc_ms);
    l.Enum(m.utc_status);
}

void AsciiBody(Line& l, const Heading2& m) {
    l.Enum(m.solution_status);
    l.Sep();
    l.Enum(m.position_type);
    l.Printf(",%.9f,%.9f,%.9f,%.1f,%.9f,%.9f,",
             static_cast<double>(m.baseline_length_m),
             static_cast<double>(m.heading_deg),
             static_cast<double>(m.pitch_deg),
             static_cast<double>(m.reserved),
             static_cast<double>(m.heading_stddev_deg),
             static_cast<double>(m.pitch_stddev_deg));
    l.Printf("\"%.4s\",\"%.4s\",%u,%u,%u,%u,%02x,%02x,%02x,%02x",
             m.rover_station_id.c_str(),
             m.base_station_id.c_str(),
             m.num_svs_tracked,
             m.num_svs_in_solution,
             m.num_svs_above_mask,
             m.num_svs_multifreq,
             m.solution_source,
             m.extended_solution_status,
             m.galileo_beidou_signal_mask,
             m.gps_glonass_signal_mask);
}

template <typename M>
bool AsciiLog(const M& m,
              std::vector<std::uint8_t>& out,
              std::initializer_list<std::uint16_t> ids) {
    if (!IdIn(m.header.message_id, ids)) return false;
    const std::string_view name = MessageNameFromId(m.header.message_id);
    if (name.empty()) return false;
    Line l(out);
    AsciiHeader(l, m.header, name, 'A');
    AsciiBody(l, m);
    l.FinishCrc();
    return true;
}

bool IsPrintableText(std::string_view s) {
    for (char c : s) {
        if (c < 0x20 || c > 0x7E) return false;
    }
    return true;
}

}  // namespace

std::string PortNameFromAddress(std::uint8_t port_address) {
    const unsigned group = port_address & 0xE0u;
    const unsigned sub = port_address & 0x1Fu;
    const char* base = nullptr;
    if (group == 0x20) base = "COM1";
    if (group == 0x40) base = "COM2";
    if (group == 0x60) base = "COM3";
    if (base == nullptr) return {};
    std::string name = base;
    if (sub != 0) name += "_" + std::to_string(sub);
    return name;
}

bool EncodeBinary(const BestPos& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kBestPos, msg_id::kBestGnssPos})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        WriteEnum(w, m.solution_status);
        WriteEnum(w, m.position_type);
        w.F64Le(m.latitude_deg);
        w.F64Le(m.longitude_deg);
        w.F64Le(m.height_msl_m);
        w.F32Le(m.undulation_m);
        w.U32Le(m.datum_id);
        w.F32Le(m.latitude_stddev_m);
        w.F32Le(m.longitude_stddev_m);
        w.F32Le(m.height_stddev_m);
        w.FixedString(m.base_station_id, 4);
        w.F32Le(m.differential_age_s);
        w.F32Le(m.solution_age_s);
        w.U8(m.num_svs_tracked);
        w.U8(m.num_svs_in_solution);
        w.U8(m.num_svs_l1_in_solution);
        w.U8(m.num_svs_multifreq_in_solution);
        w.U8(m.reserved);
        w.U8(m.extended_solution_status);
        w.U8(m.galileo_beidou_signal_mask);
        w.U8(m.gps_glonass_signal_mask);
    });
}

bool EncodeBinary(const BestVel& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kBestVel, msg_id::kBestGnssVel})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        WriteEnum(w, m.solution_status);
        WriteEnum(w, m.velocity_type);
        w.F32Le(m.latency_s);
        w.F32Le(m.differential_age_s);
        w.F64Le(m.horizontal_speed_mps);
        w.F64Le(m.track_over_ground_deg);
        w.F64Le(m.vertical_speed_mps);
        w.F32Le(m.reserved);
    });
}

bool EncodeBinary(const InsPva& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kInsPva, msg_id::kInsPvaS})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.U32Le(m.gps_week);
        w.F64Le(m.gps_seconds);
        w.F64Le(m.latitude_deg);
        w.F64Le(m.longitude_deg);
        w.F64Le(m.height_ellipsoid_m);
        w.F64Le(m.velocity_north_mps);
        w.F64Le(m.velocity_east_mps);
        w.F64Le(m.velocity_up_mps);
        w.F64Le(m.roll_deg);
        w.F64Le(m.pitch_deg);
        w.F64Le(m.azimuth_deg);
        WriteEnum(w, m.ins_status);
    });
}

bool EncodeBinary(const InsPvaX& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kInsPvaX})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        WriteEnum(w, m.ins_status);
        WriteEnum(w, m.position_type);
        w.F64Le(m.latitude_deg);
        w.F64Le(m.longitude_deg);
        w.F64Le(m.height_msl_m);
        w.F32Le(m.undulation_m);
        w.F64Le(m.velocity_north_mps);
        w.F64Le(m.velocity_east_mps);
        w.F64Le(m.velocity_up_mps);
        w.F64Le(m.roll_deg);
        w.F64Le(m.pitch_deg);
        w.F64Le(m.azimuth_deg);
        w.F32Le(m.latitude_stddev_m);
        w.F32Le(m.longitude_stddev_m);
        w.F32Le(m.height_stddev_m);
        w.F32Le(m.velocity_north_stddev_mps);
        w.F32Le(m.velocity_east_stddev_mps);
        w.F32Le(m.velocity_up_stddev_mps);
        w.F32Le(m.roll_stddev_deg);
        w.F32Le(m.pitch_stddev_deg);
        w.F32Le(m.azimuth_stddev_deg);
        w.U32Le(m.extended_status);
        w.U16Le(m.time_since_update_s);
    });
}

bool EncodeBinary(const InsAtt& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kInsAtt, msg_id::kInsAttS})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.U32Le(m.gps_week);
        w.F64Le(m.gps_seconds);
        w.F64Le(m.roll_deg);
        w.F64Le(m.pitch_deg);
        w.F64Le(m.azimuth_deg);
        WriteEnum(w, m.ins_status);
    });
}

bool EncodeBinary(const InsAttX& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kInsAttX})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        WriteEnum(w, m.ins_status);
        WriteEnum(w, m.position_type);
        w.F64Le(m.roll_deg);
        w.F64Le(m.pitch_deg);
        w.F64Le(m.azimuth_deg);
        w.F32Le(m.roll_stddev_deg);
        w.F32Le(m.pitch_stddev_deg);
        w.F32Le(m.azimuth_stddev_deg);
        w.U32Le(m.extended_status);
        w.U16Le(m.time_since_update_s);
    });
}

bool EncodeBinary(const CorrImuData& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id,
              {msg_id::kCorrImuData, msg_id::kCorrImuDataS, msg_id::kImuRateCorrImuS})) {
        return false;
    }
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.U32Le(m.gps_week);
        w.F64Le(m.gps_seconds);
        WriteVec3(w, m.delta_angle_rad);
        WriteVec3(w, m.delta_velocity_mps);
    });
}

bool EncodeBinary(const CorrImuS& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kCorrImuS})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.U32Le(m.imu_data_count);
        WriteVec3(w, m.delta_angle_rad);
        WriteVec3(w, m.delta_velocity_mps);
        w.U32Le(m.reserved1);
        w.U32Le(m.reserved2);
    });
}

bool EncodeBinary(const RawImu& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id,
              {msg_id::kRawImu, msg_id::kRawImuS, msg_id::kRawImuX, msg_id::kRawImuSX})) {
        return false;
    }
    const bool extended =
        m.header.message_id == msg_id::kRawImuX || m.header.message_id == msg_id::kRawImuSX;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        if (extended) {
            w.U8(m.imu_info);
            w.U8(static_cast<std::uint8_t>(m.imu_type));
            w.U16Le(static_cast<std::uint16_t>(m.gps_week));
        } else {
            w.U32Le(m.gps_week);
        }
        w.F64Le(m.gps_seconds);
        w.U32Le(m.imu_status);
        // Wire order Z, -Y, X (§6.8).
        w.U32Le(static_cast<std::uint32_t>(m.accel_counts[2]));
        w.U32Le(Neg32(m.accel_counts[1]));
        w.U32Le(static_cast<std::uint32_t>(m.accel_counts[0]));
        w.U32Le(static_cast<std::uint32_t>(m.gyro_counts[2]));
        w.U32Le(Neg32(m.gyro_counts[1]));
        w.U32Le(static_cast<std::uint32_t>(m.gyro_counts[0]));
    });
}

bool EncodeBinary(const Time& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kTime})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        WriteEnum(w, m.clock_model_status);
        w.F64Le(m.receiver_clock_offset_s);
        w.F64Le(m.receiver_clock_offset_stddev_s);
        w.F64Le(m.utc_offset_s);
        w.U32Le(m.utc_year);
        w.U8(m.utc_month);
        w.U8(m.utc_day);
        w.U8(m.utc_hour);
        w.U8(m.utc_minute);
        w.U32Le(m.utc_ms);
        WriteEnum(w, m.utc_status);
    });
}

bool EncodeBinary(const Heading2& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kHeading2, msg_id::kDualAntennaHeading})) {
        return false;
    }
    const bool dual = m.header.message_id == msg_id::kDualAntennaHeading;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        WriteEnum(w, m.solution_status);
        WriteEnum(w, m.position_type);
        w.F32Le(m.baseline_length_m);
        w.F32Le(m.heading_deg);
        w.F32Le(m.pitch_deg);
        w.F32Le(m.reserved);
        w.F32Le(m.heading_stddev_deg);
        w.F32Le(m.pitch_stddev_deg);
        w.FixedString(m.rover_station_id, 4);
        if (!dual) w.FixedString(m.base_station_id, 4);
        w.U8(m.num_svs_tracked);
        w.U8(m.num_svs_in_solution);
        w.U8(m.num_svs_above_mask);
        w.U8(m.num_svs_multifreq);
        w.U8(m.solution_source);
        w.U8(m.extended_solution_status);
        w.U8(m.galileo_beidou_signal_mask);
        w.U8(m.gps_glonass_signal_mask);
    });
}

bool EncodeBinary(const MarkTime& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kMarkTime, msg_id::kMark1Time, msg_id::kMark2Time})) {
        return false;
    }
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.I32Le(m.gps_week);
        w.F64Le(m.gps_seconds);
        w.F64Le(m.clock_offset_s);
        w.F64Le(m.clock_offset_stddev_s);
        w.F64Le(m.utc_offset_s);
        WriteEnum(w, m.clock_model_status);
    });
}

bool EncodeBinary(const InsStdDev& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kInsStdDev})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.F32Le(m.latitude_stddev_m);
        w.F32Le(m.longitude_stddev_m);
        w.F32Le(m.height_stddev_m);
        w.F32Le(m.velocity_north_stddev_mps);
        w.F32Le(m.velocity_east_stddev_mps);
        w.F32Le(m.velocity_up_stddev_mps);
        w.F32Le(m.roll_stddev_deg);
        w.F32Le(m.pitch_stddev_deg);
        w.F32Le(m.azimuth_stddev_deg);
        w.U32Le(m.extended_status);
        w.U16Le(m.time_since_update_s);
        w.Bytes(m.reserved);
    });
}

bool EncodeBinary(const InsConfig& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kInsConfig})) return false;
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.U32Le(m.imu_type);
        w.Bytes(m.rest);
    });
}

bool EncodeBinary(const RxStatus& m, std::vector<std::uint8_t>& out) {
    if (!IdIn(m.header.message_id, {msg_id::kRxStatus}) || m.num_groups > RxStatus::kMaxGroups) {
        return false;
    }
    return WriteFrame(m.header, out, [&](ByteWriter& w) {
        w.U32Le(m.error_word);
        w.U32Le(m.num_status_codes);
        for (std::size_t i = 0; i < m.num_groups; ++i) {
            w.U32Le(m.groups[i].status);
            w.U32Le(m.groups[i].priority_mask);
            w.U32Le(m.groups[i].set_mask);
            w.U32Le(m.groups[i].clear_mask);
        }
        w.Bytes(m.trailing);
    });
}

bool EncodeBinary(const Response& m, std::vector<std::uint8_t>& out) {
    if (m.form != Response::Form::kBinary || IsShort(m.header)) return false;
    Header h = m.header;
    h.is_response = true;
    return WriteFrame(h, out, [&](ByteWriter& w) {
        w.U32Le(static_cast<std::uint32_t>(m.response_id));
        w.Bytes(ByteSpan(reinterpret_cast<const std::uint8_t*>(m.text.data()), m.text.size()));
    });
}

bool EncodeBinary(const Message& message, std::vector<std::uint8_t>& out) {
    return std::visit(
        [&](const auto& m) -> bool {
            using T = std::decay_t<decltype(m)>;
            if constexpr (std::is_same_v<T, PortPrompt>) {
                return false;
            } else {
                return EncodeBinary(m, out);
            }
        },
        message);
}

bool EncodeAscii(const Message& message, std::vector<std::uint8_t>& out) {
    return std::visit(
        [&](const auto& m) -> bool {
            using T = std::decay_t<decltype(m)>;
            if constexpr (std::is_same_v<T, BestPos>) {
                return AsciiLog(m, out, {msg_id::kBestPos, msg_id::kBestGnssPos});
            } else if constexpr (std::is_same_v<T, BestVel>) {
                return AsciiLog(m, out, {msg_id::kBestVel, msg_id::kBestGnssVel});
            } else if constexpr (std::is_same_v<T, InsPva>) {
                return AsciiLog(m, out, {msg_id::kInsPva, msg_id::kInsPvaS});
            } else if constexpr (std::is_same_v<T, InsPvaX>) {
                return AsciiLog(m, out, {msg_id::kInsPvaX});
            } else if constexpr (std::is_same_v<T, Time>) {
                return AsciiLog(m, out, {msg_id::kTime});
            } else if constexpr (std::is_same_v<T, Heading2>) {
                return AsciiLog(m, out, {msg_id::kHeading2});
            } else if constexpr (std::is_same_v<T, PortPrompt>) {
                if (!IsPrintableText(m.port)) return false;
                Line l(out);
                l.Raw("[");
                l.Raw(m.port);
                l.Raw("]");
                return true;
            } else if constexpr (std::is_same_v<T, Response>) {
                if (!IsPrintableText(m.text)) return false;
                if (m.form == Response::Form::kAbbreviated) {
                    Line l(out);
                    l.Raw("<");
                    l.Raw(m.text);
                    l.Raw("\r\n");
                    return true;
                }
                if (m.form != Response::Form::kAscii || m.command_name.empty() ||
                    !IsPrintableText(m.command_name) || IsShort(m.header) ||
                    m.text.find('*') != std::string::npos) {
                    return false;
                }
                Line l(out);
                AsciiHeader(l, m.header, m.command_name, 'R');
                l.Raw(m.text);
                l.FinishCrc();
                return true;
            } else {
                return false;
            }
        },
        message);
}

}  // namespace pitmap::protocol::novatel
