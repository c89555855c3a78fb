// SPDX-License-Identifier: MIT
#include "processor/io/xtf.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "processor/io/ingest_collect.hpp"
#include "processor/io/ingest_sessions.hpp"

namespace pitmap::proc::io {

namespace {

// The first few damaged places of a file are warnings of their own, the rest a total.
constexpr int kMaxWarningsPerFile = 5;

class Warner {
public:
    Warner(const std::string& name, XtfFile& f) : name_(name), f_(f) {}
    ~Warner() {
        if (more_ > 0) {
            f_.warnings.push_back(name_ + ": " + std::to_string(more_) +
                                  " more damaged places (counted in the ingest counts)");
        }
    }
    Warner(const Warner&) = delete;
    Warner& operator=(const Warner&) = delete;
    void operator()(std::uint64_t offset, const std::string& what) {
        if (n_++ >= kMaxWarningsPerFile) {
            ++more_;
            return;
        }
        f_.warnings.push_back(name_ + ": " + what + " at byte offset " + std::to_string(offset));
    }

private:
    const std::string& name_;
    XtfFile& f_;
    int n_ = 0;
    int more_ = 0;
};

bool MagicAt(ByteSpan b, std::size_t pos) {
    return pos + 2 <= b.size() && b[pos] == (kXtfMagic & 0xFF) && b[pos + 1] == (kXtfMagic >> 8);
}

// The next offset >= from holding the magic and a packet size of at least a packet header;
// b.size() if none.
std::size_t FindPacket(ByteSpan b, std::size_t from) {
    for (std::size_t p = from; p + kXtfPacketHeaderBytes <= b.size(); ++p) {
        if (!MagicAt(b, p)) continue;
        ByteReader r(b.subspan(p + 10, 4));
        if (r.U32Le() >= kXtfPacketHeaderBytes) return p;
    }
    return b.size();
}

// UTC calendar fields -> Unix microseconds; nullopt for an impossible date.
std::optional<std::int64_t> UnixOf(
    int year, int month, int day, int hour, int minute, int second, std::int64_t micros) {
    UtcCalendar c;
    c.year = year;
    c.month = month;
    c.day = day;
    c.hour = hour;
    c.minute = minute;
    c.second = second;
    c.microsecond = static_cast<int>(micros);
    if (year < 1980 || year > 2200 || micros < 0 || micros > 999'999) return std::nullopt;
    return UnixFromUtcCalendar(c);
}

// XTFATTITUDEDATA: after the packet header, 2 reserved u32, EpochMicroseconds, SourceEpoch,
// f32 pitch, roll, heave, yaw, u32 TimeTag, f32 heading, u16 year, u8 month, day, hour,
// minutes, seconds, u16 milliseconds.
bool DecodeAttitude(ByteSpan packet, XtfAttitude& a) {
    ByteReader r(packet);
    r.Seek(kXtfPacketHeaderBytes + 16);
    a.pitch_deg = r.F32Le();
    a.roll_deg = r.F32Le();
    a.heave_m = r.F32Le();
    (void)r.F32Le();  // yaw (QINSy writes the heading below)
    (void)r.U32Le();  // time tag
    a.heading_deg = r.F32Le();
    const int year = r.U16Le();
    const int month = r.U8(), day = r.U8(), hour = r.U8(), minute = r.U8(), second = r.U8();
    const int ms = r.U16Le();
    if (!r.ok() || ms > 999) return false;
    const auto t = UnixOf(year, month, day, hour, minute, second, std::int64_t{ms} * 1000);
    if (!t) return false;
    a.utime_unix = *t;
    return true;
}

// XTFPOSRAWNAVIGATION: u16 year, u8 month, day, hour, minute, second, u16 fraction of the
// second in units of 0.1 ms (X41 calls it "MicroSeconds" and says 0-9999), f64 RawY, RawX,
// RawAltitude, then f32 pitch, roll, heave, heading (zero in QINSy's files: attitude is type 3).
bool DecodePosition(ByteSpan packet, XtfPosition& p) {
    ByteReader r(packet);
    r.Seek(kXtfPacketHeaderBytes);
    const int year = r.U16Le();
    const int month = r.U8(), day = r.U8(), hour = r.U8(), minute = r.U8(), second = r.U8();
    const int tenth_ms = r.U16Le();
    p.y = r.F64Le();
    p.x = r.F64Le();
    p.altitude_m = r.F64Le();
    if (!r.ok() || tenth_ms > 9999) return false;
    const auto t = UnixOf(year, month, day, hour, minute, second, std::int64_t{tenth_ms} * 100);
    if (!t) return false;
    p.utime_unix = *t;
    return true;
}

constexpr std::uint16_t SectionName(char a, char b) {
    return static_cast<std::uint16_t>((static_cast<unsigned>(a) << 8) | static_cast<unsigned>(b));
}

// R2Sonic BTH0 (big-endian) after the 256-byte XTF ping header. Returns "" or what is wrong.
std::string DecodeBth0(ByteSpan packet, XtfBathyPing& p) {
    if (packet.size() < kXtfPingHeaderBytes + 12) return "too short for a BTH0 packet";
    const ByteSpan b = packet.subspan(kXtfPingHeaderBytes);
    ByteReader r(b);
    if (r.U32Be() != 0x42544830u) return "no BTH0 packet after the XTF ping header";
    const std::uint32_t size = r.U32Be();
    (void)r.U32Be();  // data stream id
    if (size < 12 || size > b.size()) {
        return "BTH0 size " + std::to_string(size) + " outside the " + std::to_string(b.size()) +
               " bytes the XTF packet holds";
    }
    // The sections, found first: H0 gives the number of points the others hold.
    struct Span {
        std::size_t at = 0, size = 0;
    };
    Span h0, r0, a0, a2, i1, q0;
    for (std::size_t at = 12; at < size;) {
        if (size - at < 4) return "a BTH0 section header cut at byte " + std::to_string(at);
        ByteReader s(b.subspan(at, 4));
        const std::uint16_t name = s.U16Be();
        const std::uint16_t len = s.U16Be();
        if (len < 4 || len > size - at) {
            return "BTH0 section at byte " + std::to_string(at) + " has size " +
                   std::to_string(len) + ", " + std::to_string(size - at) + " bytes left";
        }
        const Span sp{at, len};
        switch (name) {
            case SectionName('H', '0'):
                h0 = sp;
                break;
            case SectionName('R', '0'):
                r0 = sp;
                break;
            case SectionName('A', '0'):
                a0 = sp;
                break;
            case SectionName('A', '2'):
                a2 = sp;
                break;
            case SectionName('I', '1'):
                i1 = sp;
                break;
            case SectionName('Q', '0'):
                q0 = sp;
                break;
            default:  // G0, G1 (gates) and sections this reader does not use
                break;
        }
        at += len;
    }
    if (h0.size < 116) return "BTH0 without a complete H0 section";
    if (r0.size == 0) return "BTH0 without ranges (R0)";
    if (a0.size == 0 && a2.size == 0) return "BTH0 without angles (A0 or A2)";
    ByteReader h(b.subspan(h0.at, h0.size));
    h.Seek(4);
    p.model = h.FixedString(12);
    h.Skip(12);  // serial number
    const std::uint32_t seconds = h.U32Be();
    const std::uint32_t nanoseconds = h.U32Be();
    p.ping_number = h.U32Be();
    (void)h.F32Be();  // ping period
    p.sound_speed_mps = h.F32Be();
    p.frequency_hz = h.F32Be();
    h.Seek(68);
    p.tx_steering_vert_rad = h.F32Be();
    h.Seek(88);
    p.range_setting_m = h.F32Be();
    h.Seek(104);
    p.rx_mount_tilt_rad = h.F32Be();
    h.Seek(114);
    const std::size_t n = h.U16Be();
    if (!h.ok()) return "BTH0 H0 section unreadable";
    if (nanoseconds > 999'999'999u) return "BTH0 H0 nanoseconds out of range";
    if (n == 0 || n > kBth0MaxPoints) return "BTH0 with " + std::to_string(n) + " points";
    p.utime_unix = static_cast<std::int64_t>(seconds) * kMicrosPerSecond + nanoseconds / 1000;

    ByteReader rr(b.subspan(r0.at, r0.size));
    rr.Seek(4);
    p.twtt_scale_s = rr.F32Be();
    p.twtt_counts.resize(n);
    for (auto& c : p.twtt_counts) c = rr.U16Be();
    if (!rr.ok()) return "BTH0 R0 section shorter than its " + std::to_string(n) + " points";

    p.angle_rad.resize(n);
    if (a2.size > 0) {
        // angle[i] = first + scale * (32-bit sum of step[0] .. step[i]).
        ByteReader ar(b.subspan(a2.at, a2.size));
        ar.Seek(4);
        const float first = ar.F32Be();
        const float scale = ar.F32Be();
        ar.Seek(36);
        std::uint32_t sum = 0;
        for (std::size_t i = 0; i < n; ++i) {
            sum += ar.U16Be();
            p.angle_rad[i] =
                static_cast<float>(static_cast<double>(first) + static_cast<double>(scale) * sum);
        }
        if (!ar.ok()) return "BTH0 A2 section shorter than its " + std::to_string(n) + " points";
    } else {
        // Equi-angle: first (port) to last (starboard) in equal steps.
        ByteReader ar(b.subspan(a0.at, a0.size));
        ar.Seek(4);
        const double first = ar.F32Be();
        const double last = ar.F32Be();
        if (!ar.ok()) return "BTH0 A0 section too short";
        const double step = n > 1 ? (last - first) / static_cast<double>(n - 1) : 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            p.angle_rad[i] = static_cast<float>(first + step * static_cast<double>(i));
        }
    }
    if (i1.size > 0) {
        ByteReader ir(b.subspan(i1.at, i1.size));
        ir.Seek(4);
        p.intensity_scale = ir.F32Be();
        p.intensity.resize(n);
        for (auto& v : p.intensity) v = ir.U16Be();
        if (!ir.ok()) return "BTH0 I1 section shorter than its " + std::to_string(n) + " points";
    }
    if (q0.size > 0) {
        ByteReader qr(b.subspan(q0.at, q0.size));
        qr.Seek(4);
        p.quality.resize(n);
        std::uint32_t word = 0;
        for (std::size_t i = 0; i < n; ++i) {
            if (i % 8 == 0) word = qr.U32Be();
            p.quality[i] = static_cast<std::uint8_t>((word >> (28 - 4 * (i % 8))) & 0xFu);
        }
        if (!qr.ok()) return "BTH0 Q0 section shorter than its " + std::to_string(n) + " points";
    }
    return {};
}

}  // namespace

bool IsXtfFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::uint8_t head[kXtfFileHeaderBytes + 2] = {};
    in.read(reinterpret_cast<char*>(head), sizeof head);
    const auto got = static_cast<std::size_t>(in.gcount());
    if (got == 0 || head[0] != kXtfFileFormat) return false;
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return ext == ".xtf" ||
           (got == sizeof head && MagicAt(ByteSpan(head, got), kXtfFileHeaderBytes));
}

Expected<XtfFile> DecodeXtf(ByteSpan bytes, const std::string& name) {
    if (bytes.size() < kXtfFileHeaderBytes) {
        return Error{name + ": not an XTF file: " + std::to_string(bytes.size()) +
                     " bytes, shorter than the 1024-byte file header"};
    }
    if (bytes[0] != kXtfFileFormat) {
        return Error{name + ": not an XTF file: byte 0 is " + std::to_string(bytes[0]) +
                     ", not 123"};
    }
    XtfFile f;
    XtfFileHeader& fh = f.header;
    ByteReader r(bytes.first(kXtfFileHeaderBytes));
    r.Seek(2);
    fh.recording_program = r.FixedString(8);
    fh.program_version = r.FixedString(8);
    fh.sonar_name = r.FixedString(16);
    fh.sonar_type = r.U16Le();
    r.Seek(164);
    fh.nav_units = r.U16Le();
    fh.sonar_channels = r.U16Le();
    fh.bathymetry_channels = r.U16Le();
    const std::size_t snippet = r.U8();
    r.U8();  // forward-look arrays
    const std::size_t echo = r.U16Le();
    const std::size_t interferometry = r.U8();
    // CHANINFO (128 bytes each from byte 256): the bathymetry channel follows the sonar ones.
    const std::size_t chan = fh.sonar_channels;
    if (fh.bathymetry_channels > 0 && chan < 6) {
        ByteReader c(bytes.subspan(256 + 128 * chan, 128));
        c.Seek(48);
        for (float& v : fh.channel_offset_m) v = c.F32Le();
        for (float& v : fh.channel_offset_deg) v = c.F32Le();
    }
    // More than six channels: their CHANINFO fill further 1024-byte blocks (8 per block).
    const std::size_t channels =
        std::size_t{fh.sonar_channels} + fh.bathymetry_channels + snippet + echo + interferometry;
    std::size_t pos = kXtfFileHeaderBytes;
    if (channels > 6) pos += kXtfFileHeaderBytes * ((channels - 6 + 7) / 8);
    XtfCounts& c = f.counts;
    c.bytes = static_cast<std::int64_t>(bytes.size());
    if (pos > bytes.size()) {
        return Error{name + ": XTF header announces " + std::to_string(channels) +
                     " channels, more than the file holds"};
    }
    Warner warn(name, f);
    while (pos < bytes.size()) {
        const std::size_t left = bytes.size() - pos;
        if (left < kXtfPacketHeaderBytes) {
            warn(pos,
                 "a packet header cut short by the end of the file (" + std::to_string(left) +
                     " bytes skipped)");
            ++c.truncated_packets;
            c.skipped_bytes += static_cast<std::int64_t>(left);
            break;
        }
        ByteReader h(bytes.subspan(pos, kXtfPacketHeaderBytes));
        const std::uint16_t magic = h.U16Le();
        const std::uint8_t type = h.U8();
        h.Seek(10);
        const std::uint32_t size = h.U32Le();
        if (magic != kXtfMagic) {
            const std::size_t next = FindPacket(bytes, pos + 1);
            char hex[8];
            std::snprintf(hex, sizeof hex, "%04X", magic);
            warn(pos,
                 std::string("no packet (magic 0x") + hex + "): " + std::to_string(next - pos) +
                     " bytes skipped to the next packet");
            ++c.resyncs;
            c.skipped_bytes += static_cast<std::int64_t>(next - pos);
            pos = next;
            continue;
        }
        // A size that does not land on the next packet is wrong only if a packet starts inside
        // it (else the next packet's own header is what is damaged, handled there).
        const bool lands = size >= kXtfPacketHeaderBytes && size <= left &&
                           (size == left || MagicAt(bytes, pos + size) ||
                            FindPacket(bytes, pos + 2) >= pos + size);
        if (!lands) {
            const std::size_t next = FindPacket(bytes, pos + 2);
            if (size > left && next == bytes.size()) {
                warn(pos,
                     "packet of type " + std::to_string(type) + " claims " + std::to_string(size) +
                         " bytes, " + std::to_string(left) +
                         " remain: cut short by the end of the file, skipped");
                ++c.truncated_packets;
                c.skipped_bytes += static_cast<std::int64_t>(left);
                break;
            }
            warn(pos,
                 "packet of type " + std::to_string(type) + " has size " + std::to_string(size) +
                     ", which does not land on the next packet: " + std::to_string(next - pos) +
                     " bytes skipped to the next packet");
            ++c.resyncs;
            c.skipped_bytes += static_cast<std::int64_t>(next - pos);
            pos = next;
            continue;
        }
        ++c.packets;
        ++c.packets_by_type[type];
        const ByteSpan packet = bytes.subspan(pos, size);
        switch (type) {
            case kXtfAttitude: {
                XtfAttitude a;
                if (DecodeAttitude(packet, a)) {
                    f.attitude.push_back(a);
                } else {
                    ++c.bad_packets;
                    warn(pos, "attitude packet (type 3) does not decode, skipped");
                }
                break;
            }
            case kXtfPosRawNavigation: {
                XtfPosition p;
                if (DecodePosition(packet, p)) {
                    f.positions.push_back(p);
                } else {
                    ++c.bad_packets;
                    warn(pos, "navigation packet (type 107) does not decode, skipped");
                }
                break;
            }
            case kXtfQinsyR2SonicBathy: {
                XtfBathyPing p;
                const std::string why = DecodeBth0(packet, p);
                if (why.empty()) {
                    p.offset = pos;
                    f.pings.push_back(std::move(p));
                } else {
                    ++c.bad_packets;
                    warn(pos, "R2Sonic bathymetry packet (type 65): " + why + ", skipped");
                }
                break;
            }
            default:
                ++c.unknown_packets;
                break;
        }
        pos += size;
    }
    return f;
}

Expected<XtfFile> ReadXtfFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open"};
    std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
    if (in.bad()) return Error{path + ": read error"};
    return DecodeXtf(ByteSpan(bytes.data(), bytes.size()), path);
}

namespace {

// Linear interpolation of the attitude at t (heading along the shorter arc); outside the
// attitude's span the end sample within hold_us; false when no two samples within max_gap_us
// bracket t (an exact time needs only itself).
bool AttitudeAt(const std::vector<XtfAttitude>& a,
                std::int64_t t,
                std::int64_t max_gap_us,
                std::int64_t hold_us,
                XtfAttitude& out) {
    auto it = std::lower_bound(a.begin(), a.end(), t, [](const XtfAttitude& x, std::int64_t v) {
        return x.utime_unix < v;
    });
    if (it != a.end() && it->utime_unix == t) {
        out = *it;
        return true;
    }
    if (a.empty()) return false;
    if (it == a.begin() || it == a.end()) {
        const XtfAttitude& end = it == a.begin() ? a.front() : a.back();
        if (std::llabs(end.utime_unix - t) > hold_us) return false;
        out = end;
        out.utime_unix = t;
        return true;
    }
    const XtfAttitude& p = *(it - 1);
    const XtfAttitude& n = *it;
    if (n.utime_unix - p.utime_unix > max_gap_us) return false;
    const double w =
        static_cast<double>(t - p.utime_unix) / static_cast<double>(n.utime_unix - p.utime_unix);
    out.utime_unix = t;
    out.roll_deg = p.roll_deg + w * (n.roll_deg - p.roll_deg);
    out.pitch_deg = p.pitch_deg + w * (n.pitch_deg - p.pitch_deg);
    out.heave_m = p.heave_m + w * (n.heave_m - p.heave_m);
    const double dh = std::remainder(n.heading_deg - p.heading_deg, 360.0);
    out.heading_deg = p.heading_deg + w * dh;
    return true;
}

std::string Fixed(double v, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

}  // namespace

Expected<XtfConversion> AddXtfToIngest(const XtfFile& file,
                                       const std::string& path,
                                       const XtfAssumptions& as,
                                       int leap_seconds,
                                       IngestResult& into) {
    XtfConversion cv;
    const XtfFileHeader& fh = file.header;
    if (!file.positions.empty() && fh.nav_units != kXtfNavUnitsLatLon) {
        return Error{path + ": XTF navigation in nav units " + std::to_string(fh.nav_units) +
                     (fh.nav_units == kXtfNavUnitsMetres ? " (projected metres)" : "") +
                     ": pitmap needs latitude/longitude (nav units 3); the projection is not "
                     "in the file"};
    }
    const auto gps = [&](std::int64_t unix_us) {
        return leap_seconds >= 0 ? GpsFromUnix(unix_us, leap_seconds) : GpsFromUnix(unix_us);
    };
    detail::Collector col(into);
    const detail::SpanMark mark = detail::MarkSpan(into);

    // Navigation: each position with the attitude interpolated at its time.
    std::vector<XtfAttitude> att = file.attitude;
    std::stable_sort(att.begin(), att.end(), [](const auto& a, const auto& b) {
        return a.utime_unix < b.utime_unix;
    });
    std::vector<XtfPosition> pos = file.positions;
    std::stable_sort(pos.begin(), pos.end(), [](const auto& a, const auto& b) {
        return a.utime_unix < b.utime_unix;
    });
    const auto max_gap_us = static_cast<std::int64_t>(as.max_attitude_gap_s * 1e6);
    const auto hold_us = static_cast<std::int64_t>(as.attitude_hold_s * 1e6);
    constexpr double kEarthRadiusM = 6371000.0;
    for (std::size_t i = 0; i < pos.size(); ++i) {
        const XtfPosition& p = pos[i];
        XtfAttitude a;
        if (!AttitudeAt(att, p.utime_unix, max_gap_us, hold_us, a)) {
            ++cv.nav_without_attitude;
            continue;
        }
        // Velocity from the neighbouring positions (XTF carries none); only the ingest's
        // session checks and reports look at it.
        Eigen::Vector3d v = Eigen::Vector3d::Zero();
        const std::size_t i0 = i > 0 ? i - 1 : i;
        const std::size_t i1 = i + 1 < pos.size() ? i + 1 : i;
        const double dt = static_cast<double>(pos[i1].utime_unix - pos[i0].utime_unix) * 1e-6;
        if (dt > 0 && dt < 2.0) {
            const double lat = frames::DegToRad(p.y);
            v.x() = frames::DegToRad(pos[i1].x - pos[i0].x) * kEarthRadiusM * std::cos(lat) / dt;
            v.y() = frames::DegToRad(pos[i1].y - pos[i0].y) * kEarthRadiusM / dt;
            v.z() = (pos[i1].altitude_m - pos[i0].altitude_m) / dt;
        }
        const std::int64_t t = gps(p.utime_unix);
        col.AddNav(detail::FromPva(t,
                                   p.y,
                                   p.x,
                                   p.altitude_m,
                                   v.y(),
                                   v.x(),
                                   v.z(),
                                   a.roll_deg,
                                   a.pitch_deg,
                                   a.heading_deg,
                                   -1,
                                   -1));
        survey::NavStdDev sd;
        sd.utime_gps = t;
        sd.north_m = sd.east_m = static_cast<float>(as.position_sigma_horizontal_m);
        sd.up_m = static_cast<float>(as.position_sigma_vertical_m);
        sd.roll_deg = sd.pitch_deg = static_cast<float>(as.roll_pitch_sigma_deg);
        sd.yaw_deg = static_cast<float>(as.heading_sigma_deg);
        col.AddStdDev(sd);
        ++cv.nav_samples;
    }

    // Pings: R0 counts with the range resolution c/2 * scale, the per-point angles beside.
    std::vector<std::int32_t> counts;
    std::vector<std::uint16_t> intensity;
    std::vector<float> angle_deg;
    for (const XtfBathyPing& p : file.pings) {
        const std::size_t n = p.twtt_counts.size();
        survey::PingHeader h;
        h.utime_gps = gps(p.utime_unix);
        h.ping_number = p.ping_number;
        h.sound_speed_mps = p.sound_speed_mps;
        h.sound_speed_valid = std::isfinite(p.sound_speed_mps) && p.sound_speed_mps > 0;
        const double res = 0.5 * p.sound_speed_mps * p.twtt_scale_s;
        h.range_resolution_m = std::isfinite(res) && res > 0 ? res : 0.0;
        // Consumers without per-beam angles see the fan from the first to the last point.
        h.start_angle_deg = frames::RadToDeg(p.angle_rad.front());
        h.angle_increment_deg = n > 1 ? frames::RadToDeg(p.angle_rad.back() - p.angle_rad.front()) /
                                            static_cast<double>(n - 1)
                                      : 0.0;
        h.profile_tilt_deg = 0;
        if (p.tx_steering_vert_rad != 0) ++cv.pings_steered;
        counts.assign(n, 0);
        angle_deg.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            angle_deg[i] = static_cast<float>(frames::RadToDeg(p.angle_rad[i]));
            std::int32_t c = p.twtt_counts[i];
            const std::uint8_t q = p.quality.empty() ? 0xF : p.quality[i];
            constexpr std::uint8_t kTests = kBth0QualityBrightness | kBth0QualityColinearity;
            if (c == 0 || (q & (kBth0QualityMagnitude | kBth0QualityPhase)) == 0) {
                ++cv.points_no_detection;
                c = 0;
            } else if (as.drop_failed_quality && (q & kTests) != kTests) {
                ++cv.points_failed_quality;
                c = 0;
            }
            counts[i] = c;
        }
        const bool with_intensity = p.intensity.size() == n;
        if (with_intensity) {
            intensity.resize(n);
            const double scale =
                std::isfinite(p.intensity_scale) && p.intensity_scale > 0 ? p.intensity_scale : 1.0;
            for (std::size_t i = 0; i < n; ++i) {
                intensity[i] = static_cast<std::uint16_t>(
                    std::clamp(std::lround(p.intensity[i] * scale), 0L, 65535L));
            }
        }
        const std::int64_t pings_before = static_cast<std::int64_t>(into.pings.pings.size());
        col.AddPing(
            h, counts.data(), n, with_intensity ? intensity.data() : nullptr, angle_deg.data());
        if (static_cast<std::int64_t>(into.pings.pings.size()) > pings_before) {
            ++cv.pings;
            cv.points += static_cast<std::int64_t>(n);
        }
    }
    detail::RecordSpan(into, path, mark);

    // Counts: packets as events by type; damage as the LCM reader's damage is counted.
    IngestCounts& c = into.counts;
    const XtfCounts& xc = file.counts;
    ++c.files;
    c.bytes += xc.bytes;
    c.events += xc.packets;
    for (const auto& [type, k] : xc.packets_by_type) {
        c.events_by_channel["XTF_TYPE_" + std::to_string(type)] += k;
    }
    c.corrupt_events += xc.resyncs;
    c.resync_bytes += xc.skipped_bytes;
    c.truncated_events += xc.truncated_packets;
    c.decode_failures += xc.bad_packets;
    c.pings_bad += static_cast<std::int64_t>(file.pings.size()) - cv.pings;
    into.warnings.insert(into.warnings.end(), file.warnings.begin(), file.warnings.end());
    if (xc.unknown_packets > 0) {
        std::string types;
        for (const auto& [type, k] : xc.packets_by_type) {
            if (type == kXtfAttitude || type == kXtfPosRawNavigation ||
                type == kXtfQinsyR2SonicBathy)
                continue;
            types +=
                (types.empty() ? "" : ", ") + std::to_string(type) + " (" + std::to_string(k) + ")";
        }
        into.warnings.push_back(
            path + ": " + std::to_string(xc.unknown_packets) +
            " XTF packets of types this reader does not use, skipped: " + types);
    }
    if (cv.nav_without_attitude > 0) {
        into.warnings.push_back(path + ": " + std::to_string(cv.nav_without_attitude) +
                                " navigation packets without attitude within " +
                                Fixed(as.max_attitude_gap_s, 1) + " s, left out");
    }

    // What had to be assumed, said once per ingest (the first XTF file's values).
    const auto once = [&](const std::string& key, const std::string& text) {
        for (const auto& a : into.assumed) {
            if (a.rfind(key, 0) == 0) return;
        }
        into.assumed.push_back(key + text);
    };
    const int leap = leap_seconds >= 0 || file.pings.empty()
                         ? leap_seconds
                         : LeapSecondsAtUnix(file.pings.front().utime_unix);
    once("XTF times: ",
         "the R2Sonic H0 ping times and the packets' UTC times + GPS-UTC (" + std::to_string(leap) +
             " s); the ping times taken as GPS-synchronised (no sonar clock search)");
    once("XTF navigation: ",
         "RawAltitude of the type-107 packets taken as the ellipsoidal height (XTF does not say "
         "which datum); heave not applied (the navigation height is used); attitude of the "
         "type-3 packets (roll + starboard down, pitch + bow up, heading) interpolated at the "
         "navigation times");
    once("XTF navigation sigmas: ",
         "no INS status or standard deviations in XTF: assumed 1 sigma " +
             Fixed(as.position_sigma_horizontal_m, 2) + " m horizontal, " +
             Fixed(as.position_sigma_vertical_m, 2) + " m vertical, roll/pitch " +
             Fixed(as.roll_pitch_sigma_deg, 2) + " deg, heading " + Fixed(as.heading_sigma_deg, 2) +
             " deg");
    if (!file.pings.empty()) {
        once("XTF sound speed: ",
             "ranges = two-way travel time x the H0 surface sound speed / 2 of each ping (first " +
                 Fixed(file.pings.front().sound_speed_mps, 2) +
                 " m/s); beam angles as the head gives them (A2), straight rays unless a cast "
                 "is given");
        once("XTF quality: ",
             "R2Sonic Q0 points without a detection bit" +
                 std::string(as.drop_failed_quality
                                 ? " or failing the brightness or colinearity test"
                                 : "") +
                 " taken as no detection (" + std::to_string(cv.points_failed_quality) +
                 " failed a test in " + path + ")");
        once("XTF intensities: ",
             "R2Sonic I1 values x scale (micropascals), as relative intensity");
    }
    if (cv.pings_steered > 0) {
        once("XTF fan steering: ",
             std::to_string(cv.pings_steered) +
                 " pings with a non-zero H0 TxSteeringVert: not applied (fan taken as vertical)");
    }
    const float* o = fh.channel_offset_m;
    const float* d = fh.channel_offset_deg;
    if (o[0] != 0 || o[1] != 0 || o[2] != 0 || d[0] != 0 || d[1] != 0 || d[2] != 0) {
        once("XTF sonar offsets: ",
             "the file header's bathymetry channel offsets (X " + Fixed(o[0], 3) + ", Y " +
                 Fixed(o[1], 3) + ", Z " + Fixed(o[2], 3) + " m; yaw " + Fixed(d[0], 2) +
                 ", pitch " + Fixed(d[1], 2) + ", roll " + Fixed(d[2], 2) +
                 " deg) are reported, not applied: XTF fixes neither their reference point nor "
                 "their signs; the vehicle file's lever arm and mount are used");
    }
    return cv;
}

Status IngestXtfFiles(const std::vector<std::string>& paths, int leap_seconds, IngestResult& into) {
    const XtfAssumptions assumptions;
    for (const std::string& path : paths) {
        auto f = ReadXtfFile(path);
        if (!f) return f.error();
        auto cv = AddXtfToIngest(*f, path, assumptions, leap_seconds, into);
        if (!cv) return cv.error();
    }
    return Ok{};
}

}  // namespace pitmap::proc::io
