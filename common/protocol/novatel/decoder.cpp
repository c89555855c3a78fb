// SPDX-License-Identifier: MIT
#include "common/protocol/novatel/decoder.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <string_view>
#include <utility>

namespace pitmap::protocol::novatel {
namespace {

constexpr std::uint8_t kResponseBit = 0x80;

DecodeError Error(DecodeErrorKind kind, std::size_t offset) {
    return DecodeError{kind, offset};
}

// ---------------------------------------------------------------------------------------------
// Binary bodies (§6). Each reads its fields in wire order; the table below guarantees the body
// is at least the minimum length, so reads cannot fail.

template <typename E>
E ReadEnum(ByteReader& r) {
    return static_cast<E>(r.U32Le());
}

std::array<double, 3> ReadVec3(ByteReader& r) {
    std::array<double, 3> v{};
    for (auto& x : v) x = r.F64Le();
    return v;
}

DecodeResult DecodeBestPos(Header&& h, ByteReader& r) {
    BestPos m;
    m.header = std::move(h);
    m.solution_status = ReadEnum<SolutionStatus>(r);
    m.position_type = ReadEnum<PositionType>(r);
    m.latitude_deg = r.F64Le();
    m.longitude_deg = r.F64Le();
    m.height_msl_m = r.F64Le();
    m.undulation_m = r.F32Le();
    m.datum_id = r.U32Le();
    m.latitude_stddev_m = r.F32Le();
    m.longitude_stddev_m = r.F32Le();
    m.height_stddev_m = r.F32Le();
    m.base_station_id = r.FixedString(4);
    m.differential_age_s = r.F32Le();
    m.solution_age_s = r.F32Le();
    m.num_svs_tracked = r.U8();
    m.num_svs_in_solution = r.U8();
    m.num_svs_l1_in_solution = r.U8();
    m.num_svs_multifreq_in_solution = r.U8();
    m.reserved = r.U8();
    m.extended_solution_status = r.U8();
    m.galileo_beidou_signal_mask = r.U8();
    m.gps_glonass_signal_mask = r.U8();
    return m;
}

DecodeResult DecodeBestVel(Header&& h, ByteReader& r) {
    BestVel m;
    m.header = std::move(h);
    m.solution_status = ReadEnum<SolutionStatus>(r);
    m.velocity_type = ReadEnum<PositionType>(r);
    m.latency_s = r.F32Le();
    m.differential_age_s = r.F32Le();
    m.horizontal_speed_mps = r.F64Le();
    m.track_over_ground_deg = r.F64Le();
    m.vertical_speed_mps = r.F64Le();
    m.reserved = r.F32Le();
    return m;
}

DecodeResult DecodeInsPva(Header&& h, ByteReader& r) {
    InsPva m;
    m.header = std::move(h);
    m.gps_week = r.U32Le();
    m.gps_seconds = r.F64Le();
    m.latitude_deg = r.F64Le();
    m.longitude_deg = r.F64Le();
    m.height_ellipsoid_m = r.F64Le();
    m.velocity_north_mps = r.F64Le();
    m.velocity_east_mps = r.F64Le();
    m.velocity_up_mps = r.F64Le();
    m.roll_deg = r.F64Le();
    m.pitch_deg = r.F64Le();
    m.azimuth_deg = r.F64Le();
    m.ins_status = ReadEnum<InsStatus>(r);
    return m;
}

DecodeResult DecodeInsPvaX(Header&& h, ByteReader& r) {
    InsPvaX m;
    m.header = std::move(h);
    m.ins_status = ReadEnum<InsStatus>(r);
    m.position_type = ReadEnum<PositionType>(r);
    m.latitude_deg = r.F64Le();
    m.longitude_deg = r.F64Le();
    m.height_msl_m = r.F64Le();
    m.undulation_m = r.F32Le();
    m.velocity_north_mps = r.F64Le();
    m.velocity_east_mps = r.F64Le();
    m.velocity_up_mps = r.F64Le();
    m.roll_deg = r.F64Le();
    m.pitch_deg = r.F64Le();
    m.azimuth_deg = r.F64Le();
    m.latitude_stddev_m = r.F32Le();
    m.longitude_stddev_m = r.F32Le();
    m.height_stddev_m = r.F32Le();
    m.velocity_north_stddev_mps = r.F32Le();
    m.velocity_east_stddev_mps = r.F32Le();
    m.velocity_up_stddev_mps = r.F32Le();
    m.roll_stddev_deg = r.F32Le();
    m.pitch_stddev_deg = r.F32Le();
    m.azimuth_stddev_deg = r.F32Le();
    m.extended_status = r.U32Le();
    m.time_since_update_s = r.U16Le();
    return m;
}

DecodeResult DecodeInsAtt(Header&& h, ByteReader& r) {
    InsAtt m;
    m.header = std::move(h);
    m.gps_week = r.U32Le();
    m.gps_seconds = r.F64Le();
    m.roll_deg = r.F64Le();
    m.pitch_deg = r.F64Le();
    m.azimuth_deg = r.F64Le();
    m.ins_status = ReadEnum<InsStatus>(r);
    return m;
}

DecodeResult DecodeInsAttX(Header&& h, ByteReader& r) {
    InsAttX m;
    m.header = std::move(h);
    m.ins_status = ReadEnum<InsStatus>(r);
    m.position_type = ReadEnum<PositionType>(r);
    m.roll_deg = r.F64Le();
    m.pitch_deg = r.F64Le();
    m.azimuth_deg = r.F64Le();
    m.roll_stddev_deg = r.F32Le();
    m.pitch_stddev_deg = r.F32Le();
    m.azimuth_stddev_deg = r.F32Le();
    m.extended_status = r.U32Le();
    m.time_since_update_s = r.U16Le();
    return m;
}

DecodeResult DecodeCorrImuData(Header&& h, ByteReader& r) {
    CorrImuData m;
    m.header = std::move(h);
    m.gps_week = r.U32Le();
    m.gps_seconds = r.F64Le();
    m.delta_angle_rad = ReadVec3(r);
    m.delta_velocity_mps = ReadVec3(r);
    return m;
}

DecodeResult DecodeCorrImuS(Header&& h, ByteReader& r) {
    CorrImuS m;
    m.header = std::move(h);
    m.imu_data_count = r.U32Le();
    m.delta_angle_rad = ReadVec3(r);
    m.delta_velocity_mps = ReadVec3(r);
    m.reserved1 = r.U32Le();
    m.reserved2 = r.U32Le();
    return m;
}

DecodeResult DecodeRawImu(Header&& h, ByteReader& r) {
    RawImu m;
    const bool extended = h.message_id == msg_id::kRawImuX || h.message_id == msg_id::kRawImuSX;
    m.header = std::move(h);
    if (extended) {
        m.imu_info = r.U8();
        m.imu_type = r.U8();
        m.gps_week = r.U16Le();
    } else {
        m.gps_week = r.U32Le();
    }
    m.gps_seconds = r.F64Le();
    m.imu_status = r.U32Le();
    // Wire order Z, -Y, X (§6.8).
    const std::int64_t az = r.I32Le();
    const std::int64_t ay_neg = r.I32Le();
    const std::int64_t ax = r.I32Le();
    const std::int64_t gz = r.I32Le();
    const std::int64_t gy_neg = r.I32Le();
    const std::int64_t gx = r.I32Le();
    m.accel_counts = {ax, -ay_neg, az};
    m.gyro_counts = {gx, -gy_neg, gz};
    return m;
}

DecodeResult DecodeTime(Header&& h, ByteReader& r) {
    Time m;
    m.header = std::move(h);
    m.clock_model_status = ReadEnum<ClockModelStatus>(r);
    m.receiver_clock_offset_s = r.F64Le();
    m.receiver_clock_offset_stddev_s = r.F64Le();
    m.utc_offset_s = r.F64Le();
    m.utc_year = r.U32Le();
    m.utc_month = r.U8();
    m.utc_day = r.U8();
    m.utc_hour = r.U8();
    m.utc_minute = r.U8();
    m.utc_ms = r.U32Le();
    m.utc_status = ReadEnum<UtcStatus>(r);
    return m;
}

DecodeResult DecodeHeading2(Header&& h, ByteReader& r) {
    Heading2 m;
    const bool dual = h.message_id == msg_id::kDualAntennaHeading;
    m.header = std::move(h);
    m.solution_status = ReadEnum<SolutionStatus>(r);
    m.position_type = ReadEnum<PositionType>(r);
    m.baseline_length_m = r.F32Le();
    m.heading_deg = r.F32Le();
    m.pitch_deg = r.F32Le();
    m.reserved = r.F32Le();
    m.heading_stddev_deg = r.F32Le();
    m.pitch_stddev_deg = r.F32Le();
    m.rover_station_id = r.FixedString(4);
    if (!dual) m.base_station_id = r.FixedString(4);
    m.num_svs_tracked = r.U8();
    m.num_svs_in_solution = r.U8();
    m.num_svs_above_mask = r.U8();
    m.num_svs_multifreq = r.U8();
    m.solution_source = r.U8();
    m.extended_solution_status = r.U8();
    m.galileo_beidou_signal_mask = r.U8();
    m.gps_glonass_signal_mask = r.U8();
    return m;
}

DecodeResult DecodeMarkTime(Header&& h, ByteReader& r) {
    MarkTime m;
    m.header = std::move(h);
    m.gps_week = r.I32Le();
    m.gps_seconds = r.F64Le();
    m.clock_offset_s = r.F64Le();
    m.clock_offset_stddev_s = r.F64Le();
    m.utc_offset_s = r.F64Le();
    m.clock_model_status = ReadEnum<ClockModelStatus>(r);
    return m;
}

DecodeResult DecodeInsStdDev(Header&& h, ByteReader& r) {
    InsStdDev m;
    m.header = std::move(h);
    m.latitude_stddev_m = r.F32Le();
    m.longitude_stddev_m = r.F32Le();
    m.height_stddev_m = r.F32Le();
    m.velocity_north_stddev_mps = r.F32Le();
    m.velocity_east_stddev_mps = r.F32Le();
    m.velocity_up_stddev_mps = r.F32Le();
    m.roll_stddev_deg = r.F32Le();
    m.pitch_stddev_deg = r.F32Le();
    m.azimuth_stddev_deg = r.F32Le();
    m.extended_status = r.U32Le();
    m.time_since_update_s = r.U16Le();
    for (auto& b : m.reserved) b = r.U8();
    return m;
}

DecodeResult DecodeInsConfig(Header&& h, ByteReader& r) {
    InsConfig m;
    m.header = std::move(h);
    m.imu_type = r.U32Le();
    const ByteSpan rest = r.Bytes(r.remaining());
    m.rest.assign(rest.begin(), rest.end());
    return m;
}

DecodeResult DecodeRxStatus(Header&& h, ByteReader& r) {
    RxStatus m;
    m.header = std::move(h);
    m.error_word = r.U32Le();
    m.num_status_codes = r.U32Le();
    while (m.num_groups < m.num_status_codes && m.num_groups < RxStatus::kMaxGroups &&
           r.remaining() >= 16) {
        auto& g = m.groups[m.num_groups++];
        g.status = r.U32Le();
        g.priority_mask = r.U32Le();
        g.set_mask = r.U32Le();
        g.clear_mask = r.U32Le();
    }
    const ByteSpan rest = r.Bytes(r.remaining());
    m.trailing.assign(rest.begin(), rest.end());
    return m;
}

using BinaryDecodeFn = DecodeResult (*)(Header&&, ByteReader&);

struct BinaryEntry {
    std::uint16_t id;
    std::uint16_t min_body_length;
    BinaryDecodeFn decode;
};

// Minimum body lengths from §6 (runt check).
constexpr std::array<BinaryEntry, 28> kBinaryTable = {{
    {msg_id::kBestPos, 72, DecodeBestPos},
    {msg_id::kBestGnssPos, 72, DecodeBestPos},
    {msg_id::kBestVel, 44, DecodeBestVel},
    {msg_id::kBestGnssVel, 44, DecodeBestVel},
    {msg_id::kInsPva, 88, DecodeInsPva},
    {msg_id::kInsPvaS, 88, DecodeInsPva},
    {msg_id::kInsPvaX, 126, DecodeInsPvaX},
    {msg_id::kInsAtt, 40, DecodeInsAtt},
    {msg_id::kInsAttS, 40, DecodeInsAtt},
    {msg_id::kInsAttX, 50, DecodeInsAttX},
    {msg_id::kCorrImuData, 60, DecodeCorrImuData},
    {msg_id::kCorrImuDataS, 60, DecodeCorrImuData},
    {msg_id::kImuRateCorrImuS, 60, DecodeCorrImuData},
    {msg_id::kCorrImuS, 60, DecodeCorrImuS},
    {msg_id::kRawImu, 40, DecodeRawImu},
    {msg_id::kRawImuS, 40, DecodeRawImu},
    {msg_id::kRawImuX, 40, DecodeRawImu},
    {msg_id::kRawImuSX, 40, DecodeRawImu},
    {msg_id::kTime, 44, DecodeTime},
    {msg_id::kHeading2, 48, DecodeHeading2},
    {msg_id::kDualAntennaHeading, 44, DecodeHeading2},
    {msg_id::kMarkTime, 40, DecodeMarkTime},
    {msg_id::kMark1Time, 40, DecodeMarkTime},
    {msg_id::kMark2Time, 40, DecodeMarkTime},
    {msg_id::kInsStdDev, 52, DecodeInsStdDev},
    {msg_id::kInsConfig, 4, DecodeInsConfig},
    {msg_id::kRxStatus, 8, DecodeRxStatus},
    {msg_id::kLog, 0, nullptr},  // a command: only its responses are decoded
}};

const BinaryEntry* FindBinary(std::uint16_t id) {
    for (const auto& e : kBinaryTable) {
        if (e.id == id && e.decode != nullptr) return &e;
    }
    return nullptr;
}

DecodeResult DecodeBinary(const Frame& frame) {
    const ByteSpan bytes = frame.bytes;
    ByteReader r(bytes);
    Header h;
    std::size_t body_offset = 0;
    std::size_t body_length = 0;
    r.Skip(3);
    if (frame.kind == FrameKind::kShortBinary) {
        if (bytes.size() < kShortHeaderLength + kCrcLength)
            return Error(DecodeErrorKind::kBadHeader, 0);
        h.kind = HeaderKind::kShortBinary;
        body_length = r.U8();
        h.message_id = r.U16Le();
        h.gps_week = r.U16Le();
        h.gps_ms = r.U32Le();
        body_offset = kShortHeaderLength;
    } else {
        if (bytes.size() < kLongHeaderMinLength + kCrcLength) {
            return Error(DecodeErrorKind::kBadHeader, 0);
        }
        h.kind = HeaderKind::kLongBinary;
        body_offset = r.U8();
        h.message_id = r.U16Le();
        const std::uint8_t type = r.U8();
        h.is_response = (type & kResponseBit) != 0;
        h.message_type = static_cast<std::uint8_t>(type & ~kResponseBit);
        h.port_address = r.U8();
        body_length = r.U16Le();
        h.sequence = r.U16Le();
        h.idle_time = r.U8();
        h.time_status = static_cast<TimeStatus>(r.U8());
        h.gps_week = r.U16Le();
        h.gps_ms = r.U32Le();
        h.receiver_status = r.U32Le();
        h.reserved = r.U16Le();
        h.sw_build = r.U16Le();
        if (body_offset < kLongHeaderMinLength) return Error(DecodeErrorKind::kBadHeader, 3);
    }
    if (body_offset + body_length + kCrcLength != bytes.size()) {
        return Error(DecodeErrorKind::kBadHeader, 3);
    }
    ByteReader body(bytes.subspan(body_offset, body_length));
    if (h.is_response) {
        Response m;
        m.header = std::move(h);
        m.form = Response::Form::kBinary;
        if (body_length < 4) return Error(DecodeErrorKind::kRunt, body_offset);
        m.response_id = static_cast<std::int32_t>(body.U32Le());
        m.text = body.FixedString(body.remaining());
        return m;
    }
    const BinaryEntry* entry = FindBinary(h.message_id);
    if (entry == nullptr) return Unsupported{h.message_id, frame.kind};
    if (body_length < entry->min_body_length) {
        return Error(DecodeErrorKind::kRunt, body_offset + body_length);
    }
    return entry->decode(std::move(h), body);
}

// ---------------------------------------------------------------------------------------------
// ASCII (§5): "#NAME,hdr,...;field,...*crc" and "%NAME,week,seconds;field,...*crc".

// Splits comma-separated fields; records the byte offset of a failure in the frame.
class Fields {
public:
    Fields(std::string_view text, std::size_t base_offset) : text_(text), base_(base_offset) {}

    bool ok() const { return ok_; }
    bool empty() const { return pos_ > text_.size(); }
    std::size_t offset() const { return base_ + std::min(pos_, text_.size()); }
    std::size_t Remaining() const {
        if (pos_ > text_.size()) return 0;
        std::size_t n = 1;
        for (std::size_t i = pos_; i < text_.size(); ++i) n += text_[i] == ',' ? 1 : 0;
        return n;
    }

    std::string_view Next() {
        if (pos_ > text_.size()) {
            Fail();
            return {};
        }
        const std::size_t comma = text_.find(',', pos_);
        const std::size_t end = comma == std::string_view::npos ? text_.size() : comma;
        const std::string_view f = text_.substr(pos_, end - pos_);
        field_start_ = pos_;
        pos_ = end + 1;
        return f;
    }

    template <typename T>
    T Int(int base = 10) {
        const std::string_view f = Next();
        T v{};
        const auto [p, ec] = std::from_chars(f.data(), f.data() + f.size(), v, base);
        if (ec != std::errc() || p != f.data() + f.size() || f.empty()) Fail();
        return v;
    }

    double Double() {
        const std::string_view f = Next();
        double v = 0.0;
        const auto [p, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
        if (ec != std::errc() || p != f.data() + f.size() || f.empty()) Fail();
        return v;
    }
    float Float() { return static_cast<float>(Double()); }

    std::string Quoted() {
        std::string_view f = Next();
        if (f.size() >= 2 && f.front() == '"' && f.back() == '"') f = f.substr(1, f.size() - 2);
        return std::string(f);
    }

    // An enum by ASCII name, or its number. Names are searched over [0, limit).
    template <typename E>
    E Enum(unsigned limit) {
        const std::string_view f = Next();
        for (unsigned v = 0; v < limit; ++v) {
            if (!f.empty() && ToString(static_cast<E>(v)) == f) return static_cast<E>(v);
        }
        std::uint32_t v = 0;
        const auto [p, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
        if (ec != std::errc() || p != f.data() + f.size() || f.empty()) Fail();
        return static_cast<E>(v);
    }

    void Fail() {
        if (ok_) fail_offset_ = base_ + std::min(field_start_, text_.size());
        ok_ = false;
    }
    std::size_t fail_offset() const { return fail_offset_; }

private:
    std::string_view text_;
    std::size_t base_ = 0;
    std::size_t pos_ = 0;
    std::size_t field_start_ = 0;
    std::size_t fail_offset_ = 0;
    bool ok_ = true;
};

std::uint32_t MsFromSeconds(double seconds) {
    if (!std::isfinite(seconds) || seconds < 0.0 || seconds > 4.0e6) return 0;
    return static_cast<std::uint32_t>(std::llround(seconds * 1000.0));
}

std::uint8_t ParsePortAddress(std::string_view port) {
    // COM1/COM2/COM3 map to 0x20/0x40/0x60 (§2); a "_n" suffix is the virtual sub-port.
    std::uint8_t base = 0;
    if (port.substr(0, 4) == "COM1") base = 0x20;
    if (port.substr(0, 4) == "COM2") base = 0x40;
    if (port.substr(0, 4) == "COM3") base = 0x60;
    if (base == 0) return 0;
    const std::size_t us = port.find('_');
    if (us == std::string_view::npos) return base;
    unsigned sub = 0;
    const auto [p, ec] = std::from_chars(port.data() + us + 1, port.data() + port.size(), sub);
    if (ec != std::errc() || sub > 31) return base;
    return static_cast<std::uint8_t>(base | sub);
}

template <typename M>
DecodeResult Finish(M&& m, const Fields& f) {
    if (!f.ok()) return Error(DecodeErrorKind::kBadField, f.fail_offset());
    return std::forward<M>(m);
}

DecodeResult ParseBestPosA(Header&& h, Fields& f) {
    BestPos m;
    m.header = std::move(h);
    if (f.Remaining() < 21) return Error(DecodeErrorKind::kBadField, f.offset());
    const std::size_t extra = f.Remaining() - 21;
    m.solution_status = f.Enum<SolutionStatus>(32);
    m.position_type = f.Enum<PositionType>(128);
    m.latitude_deg = f.Double();
    m.longitude_deg = f.Double();
    m.height_msl_m = f.Double();
    m.undulation_m = f.Float();
    const std::string_view datum = f.Next();
    if (datum == "WGS84") {
        m.datum_id = 61;
    } else if (datum == "USER") {
        m.datum_id = 63;
    } else {
        const auto [p, ec] = std::from_chars(datum.data(), datum.data() + datum.size(), m.datum_id);
        if (ec != std::errc() || p != datum.data() + datum.size()) f.Fail();
    }
    m.latitude_stddev_m = f.Float();
    m.longitude_stddev_m = f.Float();
    m.height_stddev_m = f.Float();
    m.base_station_id = f.Quoted();
    m.differential_age_s = f.Float();
    m.solution_age_s = f.Float();
    m.num_svs_tracked = f.Int<std::uint8_t>();
    m.num_svs_in_solution = f.Int<std::uint8_t>();
    m.num_svs_l1_in_solution = f.Int<std::uint8_t>();
    m.num_svs_multifreq_in_solution = f.Int<std::uint8_t>();
    // Some firmware prints extra reserved fields here: the last three are always the masks.
    for (std::size_t i = 0; i < extra; ++i) f.Next();
    m.reserved = f.Int<std::uint8_t>(16);
    m.extended_solution_status = f.Int<std::uint8_t>(16);
    m.galileo_beidou_signal_mask = f.Int<std::uint8_t>(16);
    m.gps_glonass_signal_mask = f.Int<std::uint8_t>(16);
    return Finish(std::move(m), f);
}

DecodeResult ParseBestVelA(Header&& h, Fields& f) {
    BestVel m;
    m.header = std::move(h);
    m.solution_status = f.Enum<SolutionStatus>(32);
    m.velocity_type = f.Enum<PositionType>(128);
    m.latency_s = f.Float();
    m.differential_age_s = f.Float();
    m.horizontal_speed_mps = f.Double();
    m.track_over_ground_deg = f.Double();
    m.vertical_speed_mps = f.Double();
    m.reserved = f.Float();
    return Finish(std::move(m), f);
}

DecodeResult ParseInsPvaA(Header&& h, Fields& f) {
    InsPva m;
    m.header = std::move(h);
    m.gps_week = f.Int<std::uint32_t>();
    m.gps_seconds = f.Double();
    m.latitude_deg = f.Double();
    m.longitude_deg = f.Double();
    m.height_ellipsoid_m = f.Double();
    m.velocity_north_mps = f.Double();
    m.velocity_east_mps = f.Double();
    m.velocity_up_mps = f.Double();
    m.roll_deg = f.Double();
    m.pitch_deg = f.Double();
    m.azimuth_deg = f.Double();
    m.ins_status = f.Enum<InsStatus>(32);
    return Finish(std::move(m), f);
}

DecodeResult ParseInsPvaXA(Header&& h, Fields& f) {
    InsPvaX m;
    m.header = std::move(h);
    m.ins_status = f.Enum<InsStatus>(32);
    m.position_type = f.Enum<PositionType>(128);
    m.latitude_deg = f.Double();
    m.longitude_deg = f.Double();
    m.height_msl_m = f.Double();
    m.undulation_m = f.Float();
    m.velocity_north_mps = f.Double();
    m.velocity_east_mps = f.Double();
    m.velocity_up_mps = f.Double();
    m.roll_deg = f.Double();
    m.pitch_deg = f.Double();
    m.azimuth_deg = f.Double();
    m.latitude_stddev_m = f.Float();
    m.longitude_stddev_m = f.Float();
    m.height_stddev_m = f.Float();
    m.velocity_north_stddev_mps = f.Float();
    m.velocity_east_stddev_mps = f.Float();
    m.velocity_up_stddev_mps = f.Float();
    m.roll_stddev_deg = f.Float();
    m.pitch_stddev_deg = f.Float();
    m.azimuth_stddev_deg = f.Float();
    m.extended_status = f.Int<std::uint32_t>(16);
    m.time_since_update_s = f.Int<std::uint16_t>();
    return Finish(std::move(m), f);
}

DecodeResult ParseTimeA(Header&& h, Fields& f) {
    Time m;
    m.header = std::move(h);
    m.clock_model_status = f.Enum<ClockModelStatus>(4);
    m.receiver_clock_offset_s = f.Double();
    m.receiver_clock_offset_stddev_s = f.Double();
    m.utc_offset_s = f.Double();
    m.utc_year = f.Int<std::uint32_t>();
    m.utc_month = f.Int<std::uint8_t>();
    m.utc_day = f.Int<std::uint8_t>();
    m.utc_hour = f.Int<std::uint8_t>();
    m.utc_minute = f.Int<std::uint8_t>();
    m.utc_ms = f.Int<std::uint32_t>();
    m.utc_status = f.Enum<UtcStatus>(3);
    return Finish(std::move(m), f);
}

DecodeResult ParseHeading2A(Header&& h, Fields& f) {
    Heading2 m;
    m.header = std::move(h);
    m.solution_status = f.Enum<SolutionStatus>(32);
    m.position_type = f.Enum<PositionType>(128);
    m.baseline_length_m = f.Float();
    m.heading_deg = f.Float();
    m.pitch_deg = f.Float();
    m.reserved = f.Float();
    m.heading_stddev_deg = f.Float();
    m.pitch_stddev_deg = f.Float();
    m.rover_station_id = f.Quoted();
    m.base_station_id = f.Quoted();
    m.num_svs_tracked = f.Int<std::uint8_t>();
    m.num_svs_in_solution = f.Int<std::uint8_t>();
    m.num_svs_above_mask = f.Int<std::uint8_t>();
    m.num_svs_multifreq = f.Int<std::uint8_t>();
    m.solution_source = f.Int<std::uint8_t>(16);
    m.extended_solution_status = f.Int<std::uint8_t>(16);
    m.galileo_beidou_signal_mask = f.Int<std::uint8_t>(16);
    m.gps_glonass_signal_mask = f.Int<std::uint8_t>(16);
    return Finish(std::move(m), f);
}

using AsciiParseFn = DecodeResult (*)(Header&&, Fields&);

struct AsciiEntry {
    std::uint16_t id;
    AsciiParseFn parse;
};

constexpr std::array<AsciiEntry, 9> kAsciiTable = {{
    {msg_id::kBestPos, ParseBestPosA},
    {msg_id::kBestGnssPos, ParseBestPosA},
    {msg_id::kBestVel, ParseBestVelA},
    {msg_id::kBestGnssVel, ParseBestVelA},
    {msg_id::kInsPva, ParseInsPvaA},
    {msg_id::kInsPvaS, ParseInsPvaA},
    {msg_id::kInsPvaX, ParseInsPvaXA},
    {msg_id::kTime, ParseTimeA},
    {msg_id::kHeading2, ParseHeading2A},
}};

DecodeResult DecodeAscii(const Frame& frame) {
    const std::string_view text(reinterpret_cast<const char*>(frame.bytes.data()),
                                frame.bytes.size());
    const std::size_t semi = text.find(';');
    const std::size_t star = text.rfind('*');
    if (semi == std::string_view::npos || star == std::string_view::npos || star < semi ||
        text.size() < 2) {
        return Error(DecodeErrorKind::kBadHeader, 0);
    }
    Fields hf(text.substr(1, semi - 1), 1);
    Header h;
    const std::string_view name = hf.Next();
    if (name.size() < 2) return Error(DecodeErrorKind::kBadHeader, 1);
    const char suffix = name.back();
    const std::string_view base_name = name.substr(0, name.size() - 1);
    const auto id = MessageIdFromName(base_name);
    h.message_id = id.value_or(0);
    h.is_response = suffix == 'R';
    if (frame.kind == FrameKind::kShortAscii) {
        h.kind = HeaderKind::kShortAscii;
        h.gps_week = hf.Int<std::uint16_t>();
        h.gps_ms = MsFromSeconds(hf.Double());
    } else {
        h.kind = HeaderKind::kAscii;
        h.port_name = std::string(hf.Next());
        h.port_address = ParsePortAddress(h.port_name);
        h.sequence = hf.Int<std::uint16_t>();
        const double idle = hf.Double();
        h.idle_time = static_cast<std::uint8_t>(
            std::isfinite(idle) && idle >= 0.0 && idle <= 127.5 ? std::lround(idle * 2.0) : 0);
        h.time_status = hf.Enum<TimeStatus>(256);
        h.gps_week = hf.Int<std::uint16_t>();
        h.gps_ms = MsFromSeconds(hf.Double());
        h.receiver_status = hf.Int<std::uint32_t>(16);
        h.reserved = hf.Int<std::uint16_t>(16);
        h.sw_build = hf.Int<std::uint16_t>();
    }
    if (!hf.ok()) return Error(DecodeErrorKind::kBadHeader, hf.fail_offset());
    const std::string_view body = text.substr(semi + 1, star - semi - 1);
    if (h.is_response) {
        Response m;
        m.header = std::move(h);
        m.form = Response::Form::kAscii;
        m.text = std::string(body);
        m.command_name = std::string(base_name);
        return m;
    }
    if (suffix != 'A' || !id) return Unsupported{frame.message_id, frame.kind};
    for (const auto& e : kAsciiTable) {
        if (e.id == *id) {
            Fields bf(body, semi + 1);
            return e.parse(std::move(h), bf);
        }
    }
    return Unsupported{frame.message_id, frame.kind};
}

DecodeResult DecodeAbbreviated(const Frame& frame) {
    std::string_view text(reinterpret_cast<const char*>(frame.bytes.data()), frame.bytes.size());
    if (text.size() < 3) return Error(DecodeErrorKind::kBadHeader, 0);
    text = text.substr(1, text.size() - 3);  // drop '<' and CR LF
    if (text == "OK" || text.substr(0, 5) == "ERROR") {
        Response m;
        m.header.kind = HeaderKind::kAbbreviated;
        m.form = Response::Form::kAbbreviated;
        m.text = std::string(text);
        return m;
    }
    return Unsupported{-1, frame.kind};
}

}  // namespace

std::optional<std::size_t> MinimumBodyLength(std::uint16_t message_id) {
    const BinaryEntry* e = FindBinary(message_id);
    if (e == nullptr) return std::nullopt;
    return e->min_body_length;
}

DecodeResult Decode(const Frame& frame) {
    switch (frame.kind) {
        case FrameKind::kLongBinary:
        case FrameKind::kShortBinary:
            return DecodeBinary(frame);
        case FrameKind::kAscii:
        case FrameKind::kShortAscii:
            return DecodeAscii(frame);
        case FrameKind::kAbbreviated:
            return DecodeAbbreviated(frame);
        case FrameKind::kPrompt: {
            if (frame.bytes.size() < 2) return Error(DecodeErrorKind::kBadHeader, 0);
            PortPrompt p;
            p.port.assign(reinterpret_cast<const char*>(frame.bytes.data()) + 1,
                          frame.bytes.size() - 2);
            return p;
        }
        case FrameKind::kProprietary:
        case FrameKind::kNmea:
            break;
    }
    return Unsupported{frame.message_id, frame.kind};
}

Message ToMessage(DecodeResult r) {
    return std::visit(
        [](auto&& v) -> Message {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, Unsupported> || std::is_same_v<T, DecodeError>) {
                return PortPrompt{};  // precondition violated: IsMessage(r) was false
            } else {
                return Message(std::move(v));
            }
        },
        std::move(r));
}

}  // namespace pitmap::protocol::novatel
