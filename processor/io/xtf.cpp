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
    Warner(const Warner&) = delete;
    Warner& operator=(const Warner&) = delete;
    void operator()(std::uint64_t offset, const std::string& what) {
        if (n_++ >= kMaxWarningsPerFile) {
            ++more_;
            return;
        }
        f_.warnings.push_back(name_ + ": " + what + " at byte offset " + std::to_string(offset));
    }
    // The total of the places beyond the first few. Called explicitly, not from a destructor:
    // a destructor runs after the file has been moved into the decoder's result.
    void Finish() {
        if (more_ > 0) {
            f_.warnings.push_back(name_ + ": " + std::to_string(more_) +
                                  " more damaged places (counted in the ingest counts)");
        }
        more_ = 0;
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

// Where one BTH0 section lies in its packet, from its 4-byte name and size on (size 0: absent).
struct Bth0Section {
    std::size_t at = 0;
    std::size_t size = 0;
};

// The sections this reader uses; G0, G1 (gates) and sections it does not know are passed over.
struct Bth0Sections {
    Bth0Section h0, r0, a0, a2, i1, q0;
};

// A reader over one section, after its name and size.
ByteReader SectionReader(ByteSpan bth0, Bth0Section section) {
    ByteReader r(bth0.subspan(section.at, section.size));
    r.Seek(4);
    return r;
}

// The BTH0 packet after the XTF ping header, as many bytes as its own size says; its magic and
// size checked against the XTF packet. Returns "" or what is wrong.
std::string FindBth0(ByteSpan packet, ByteSpan& bth0) {
    if (packet.size() < kXtfPingHeaderBytes + 12) return "too short for a BTH0 packet";
    const ByteSpan after_ping_header = packet.subspan(kXtfPingHeaderBytes);
    ByteReader r(after_ping_header);
    if (r.U32Be() != 0x42544830u) return "no BTH0 packet after the XTF ping header";
    const std::uint32_t size = r.U32Be();
    (void)r.U32Be();  // data stream id
    if (size < 12 || size > after_ping_header.size()) {
        return "BTH0 size " + std::to_string(size) + " outside the " +
               std::to_string(after_ping_header.size()) + " bytes the XTF packet holds";
    }
    bth0 = after_ping_header.first(size);
    return {};
}

// The sections after the 12-byte BTH0 header, found before any is read because H0 gives the
// number of points the others hold. Each section's size counts its own 4-byte header; one that
// runs past the packet ends the ping. Returns "" or what is wrong (also when H0, R0 or the
// angles are missing).
std::string FindBth0Sections(ByteSpan bth0, Bth0Sections& sections) {
    const std::size_t size = bth0.size();
    for (std::size_t at = 12; at < size;) {
        if (size - at < 4) return "a BTH0 section header cut at byte " + std::to_string(at);
        ByteReader header(bth0.subspan(at, 4));
        const std::uint16_t name = header.U16Be();
        const std::uint16_t len = header.U16Be();
        if (len < 4 || len > size - at) {
            return "BTH0 section at byte " + std::to_string(at) + " has size " +
                   std::to_string(len) + ", " + std::to_string(size - at) + " bytes left";
        }
        const Bth0Section section{at, len};
        switch (name) {
            case SectionName('H', '0'):
                sections.h0 = section;
                break;
            case SectionName('R', '0'):
                sections.r0 = section;
                break;
            case SectionName('A', '0'):
                sections.a0 = section;
                break;
            case SectionName('A', '2'):
                sections.a2 = section;
                break;
            case SectionName('I', '1'):
                sections.i1 = section;
                break;
            case SectionName('Q', '0'):
                sections.q0 = section;
                break;
            default:
                break;
        }
        at += len;
    }
    if (sections.h0.size < 116) return "BTH0 without a complete H0 section";
    if (sections.r0.size == 0) return "BTH0 without ranges (R0)";
    if (sections.a0.size == 0 && sections.a2.size == 0) return "BTH0 without angles (A0 or A2)";
    return {};
}

// H0: the ping's time, number and sonar settings, and into num_points how many points the
// other sections hold. Returns "" or what is wrong.
std::string ReadBth0PingHeader(ByteReader h0, XtfBathyPing& p, std::size_t& num_points) {
    p.model = h0.FixedString(12);
    h0.Skip(12);  // serial number
    const std::uint32_t seconds = h0.U32Be();
    const std::uint32_t nanoseconds = h0.U32Be();
    p.ping_number = h0.U32Be();
    (void)h0.F32Be();  // ping period
    p.sound_speed_mps = h0.F32Be();
    p.frequency_hz = h0.F32Be();
    h0.Seek(68);
    p.tx_steering_vert_rad = h0.F32Be();
    h0.Seek(88);
    p.range_setting_m = h0.F32Be();
    h0.Seek(104);
    p.rx_mount_tilt_rad = h0.F32Be();
    h0.Seek(114);
    const std::size_t n = h0.U16Be();
    if (!h0.ok()) return "BTH0 H0 section unreadable";
    if (nanoseconds > 999'999'999u) return "BTH0 H0 nanoseconds out of range";
    if (n == 0 || n > kBth0MaxPoints) return "BTH0 with " + std::to_string(n) + " points";
    p.utime_unix = static_cast<std::int64_t>(seconds) * kMicrosPerSecond + nanoseconds / 1000;
    num_points = n;
    return {};
}

// R0 and I1: a scale, then one 16-bit value per point. Returns "" or what is wrong.
std::string ReadBth0ScaledValues(ByteReader section,
                                 const char* name,
                                 std::size_t num_points,
                                 double& scale,
                                 std::vector<std::uint16_t>& values) {
    scale = section.F32Be();
    values.resize(num_points);
    for (auto& value : values) value = section.U16Be();
    if (!section.ok()) {
        return std::string("BTH0 ") + name + " section shorter than its " +
               std::to_string(num_points) + " points";
    }
    return {};
}

// A2: angle[i] = first + scale * (32-bit sum of step[0] .. step[i]). Returns "" or what is
// wrong.
std::string ReadBth0SummedAngles(ByteReader a2, std::size_t num_points, XtfBathyPing& p) {
    const float first = a2.F32Be();
    const float scale = a2.F32Be();
    a2.Seek(36);
    p.angle_rad.resize(num_points);
    std::uint32_t sum = 0;
    for (std::size_t i = 0; i < num_points; ++i) {
        sum += a2.U16Be();
        p.angle_rad[i] =
            static_cast<float>(static_cast<double>(first) + static_cast<double>(scale) * sum);
    }
    if (!a2.ok()) {
        return "BTH0 A2 section shorter than its " + std::to_string(num_points) + " points";
    }
    return {};
}

// A0, equi-angle: first (port) to last (starboard) in equal steps. Returns "" or what is wrong.
std::string ReadBth0EquiAngles(ByteReader a0, std::size_t num_points, XtfBathyPing& p) {
    p.angle_rad.resize(num_points);
    const double first = a0.F32Be();
    const double last = a0.F32Be();
    if (!a0.ok()) return "BTH0 A0 section too short";
    const double step = num_points > 1 ? (last - first) / static_cast<double>(num_points - 1) : 0.0;
    for (std::size_t i = 0; i < num_points; ++i) {
        p.angle_rad[i] = static_cast<float>(first + step * static_cast<double>(i));
    }
    return {};
}

// Q0: 4 flag bits per point, eight to a big-endian word from its most significant nibble.
// Returns "" or what is wrong.
std::string ReadBth0Quality(ByteReader q0, std::size_t num_points, XtfBathyPing& p) {
    p.quality.resize(num_points);
    std::uint32_t word = 0;
    for (std::size_t i = 0; i < num_points; ++i) {
        if (i % 8 == 0) word = q0.U32Be();
        p.quality[i] = static_cast<std::uint8_t>((word >> (28 - 4 * (i % 8))) & 0xFu);
    }
    if (!q0.ok()) {
        return "BTH0 Q0 section shorter than its " + std::to_string(num_points) + " points";
    }
    return {};
}

// R2Sonic BTH0 (big-endian) after the 256-byte XTF ping header. Returns "" or what is wrong;
// the first problem found ends the ping.
std::string DecodeBth0(ByteSpan packet, XtfBathyPing& p) {
    ByteSpan bth0;
    Bth0Sections sections;
    std::size_t num_points = 0;
    std::string why = FindBth0(packet, bth0);
    if (why.empty()) why = FindBth0Sections(bth0, sections);
    if (why.empty()) why = ReadBth0PingHeader(SectionReader(bth0, sections.h0), p, num_points);
    if (why.empty()) {
        why = ReadBth0ScaledValues(
            SectionReader(bth0, sections.r0), "R0", num_points, p.twtt_scale_s, p.twtt_counts);
    }
    if (why.empty()) {
        why = sections.a2.size > 0
                  ? ReadBth0SummedAngles(SectionReader(bth0, sections.a2), num_points, p)
                  : ReadBth0EquiAngles(SectionReader(bth0, sections.a0), num_points, p);
    }
    if (why.empty() && sections.i1.size > 0) {
        why = ReadBth0ScaledValues(
            SectionReader(bth0, sections.i1), "I1", num_points, p.intensity_scale, p.intensity);
    }
    if (why.empty() && sections.q0.size > 0) {
        why = ReadBth0Quality(SectionReader(bth0, sections.q0), num_points, p);
    }
    return why;
}

// The 1024-byte file header into `header`; returns where the first packet starts (after the
// further CHANINFO blocks of more than six channels). Errors: shorter than the header, a wrong
// format byte, more channel blocks than the file holds.
Expected<std::size_t> ReadXtfFileHeader(ByteSpan bytes,
                                        const std::string& name,
                                        XtfFileHeader& header) {
    if (bytes.size() < kXtfFileHeaderBytes) {
        return Error{name + ": not an XTF file: " + std::to_string(bytes.size()) +
                     " bytes, shorter than the 1024-byte file header"};
    }
    if (bytes[0] != kXtfFileFormat) {
        return Error{name + ": not an XTF file: byte 0 is " + std::to_string(bytes[0]) +
                     ", not 123"};
    }
    ByteReader r(bytes.first(kXtfFileHeaderBytes));
    r.Seek(2);
    header.recording_program = r.FixedString(8);
    header.program_version = r.FixedString(8);
    header.sonar_name = r.FixedString(16);
    header.sonar_type = r.U16Le();
    r.Seek(164);
    header.nav_units = r.U16Le();
    header.sonar_channels = r.U16Le();
    header.bathymetry_channels = r.U16Le();
    const std::size_t snippet = r.U8();
    r.U8();  // forward-look arrays
    const std::size_t echo = r.U16Le();
    const std::size_t interferometry = r.U8();
    // CHANINFO (128 bytes each from byte 256): the bathymetry channel follows the sonar ones.
    const std::size_t bathy_channel = header.sonar_channels;
    if (header.bathymetry_channels > 0 && bathy_channel < 6) {
        ByteReader chaninfo(bytes.subspan(256 + 128 * bathy_channel, 128));
        chaninfo.Seek(48);
        for (float& v : header.channel_offset_m) v = chaninfo.F32Le();
        for (float& v : header.channel_offset_deg) v = chaninfo.F32Le();
    }
    // More than six channels: their CHANINFO fill further 1024-byte blocks (8 per block).
    const std::size_t channels = std::size_t{header.sonar_channels} + header.bathymetry_channels +
                                 snippet + echo + interferometry;
    std::size_t first_packet = kXtfFileHeaderBytes;
    if (channels > 6) first_packet += kXtfFileHeaderBytes * ((channels - 6 + 7) / 8);
    if (first_packet > bytes.size()) {
        return Error{name + ": XTF header announces " + std::to_string(channels) +
                     " channels, more than the file holds"};
    }
    return first_packet;
}

// What the packet walk finds at one offset: a packet, damage it skips to the next packet, or
// a packet the end of the file cuts short (the walk's end).
enum class XtfPlace { kPacket, kDamaged, kCutByEnd };

struct XtfPlaceAt {
    XtfPlace place = XtfPlace::kPacket;
    std::uint8_t type = 0;  // the packet's header type (kPacket)
    std::size_t bytes = 0;  // the packet's size, or the bytes skipped
    std::string warning;    // what is wrong (kDamaged, kCutByEnd)
};

XtfPlaceAt ExamineXtfPlace(ByteSpan bytes, std::size_t pos) {
    const std::size_t left = bytes.size() - pos;
    if (left < kXtfPacketHeaderBytes) {
        return {XtfPlace::kCutByEnd,
                0,
                left,
                "a packet header cut short by the end of the file (" + std::to_string(left) +
                    " bytes skipped)"};
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
        return {XtfPlace::kDamaged,
                type,
                next - pos,
                std::string("no packet (magic 0x") + hex + "): " + std::to_string(next - pos) +
                    " bytes skipped to the next packet"};
    }
    // A size that does not land on the next packet is wrong only if a packet starts inside
    // it (else the next packet's own header is what is damaged, handled there).
    const bool lands =
        size >= kXtfPacketHeaderBytes && size <= left &&
        (size == left || MagicAt(bytes, pos + size) || FindPacket(bytes, pos + 2) >= pos + size);
    if (lands) return {XtfPlace::kPacket, type, size, {}};
    const std::size_t next = FindPacket(bytes, pos + 2);
    if (size > left && next == bytes.size()) {
        return {XtfPlace::kCutByEnd,
                type,
                left,
                "packet of type " + std::to_string(type) + " claims " + std::to_string(size) +
                    " bytes, " + std::to_string(left) +
                    " remain: cut short by the end of the file, skipped"};
    }
    return {XtfPlace::kDamaged,
            type,
            next - pos,
            "packet of type " + std::to_string(type) + " has size " + std::to_string(size) +
                ", which does not land on the next packet: " + std::to_string(next - pos) +
                " bytes skipped to the next packet"};
}

// One packet by its header type into f: attitude, navigation, R2Sonic bathymetry; a known type
// that does not decode is counted bad and said, an unknown one counted.
void DecodeXtfPacket(
    std::uint8_t type, ByteSpan packet, std::size_t pos, XtfFile& f, Warner& warn) {
    XtfCounts& counts = f.counts;
    switch (type) {
        case kXtfAttitude: {
            XtfAttitude a;
            if (DecodeAttitude(packet, a)) {
                f.attitude.push_back(a);
            } else {
                ++counts.bad_packets;
                warn(pos, "attitude packet (type 3) does not decode, skipped");
            }
            break;
        }
        case kXtfPosRawNavigation: {
            XtfPosition p;
            if (DecodePosition(packet, p)) {
                f.positions.push_back(p);
            } else {
                ++counts.bad_packets;
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
                ++counts.bad_packets;
                warn(pos, "R2Sonic bathymetry packet (type 65): " + why + ", skipped");
            }
            break;
        }
        default:
            ++counts.unknown_packets;
            break;
    }
}

// The packets from `pos` to the end of the file into f: nothing here is fatal, every damaged
// place is counted, and the first few are warnings naming the file and the offset.
void WalkXtfPackets(ByteSpan bytes, std::size_t pos, const std::string& name, XtfFile& f) {
    Warner warn(name, f);
    XtfCounts& counts = f.counts;
    while (pos < bytes.size()) {
        const XtfPlaceAt at = ExamineXtfPlace(bytes, pos);
        if (at.place == XtfPlace::kPacket) {
            ++counts.packets;
            ++counts.packets_by_type[at.type];
            DecodeXtfPacket(at.type, bytes.subspan(pos, at.bytes), pos, f, warn);
        } else {
            warn(pos, at.warning);
            ++(at.place == XtfPlace::kCutByEnd ? counts.truncated_packets : counts.resyncs);
            counts.skipped_bytes += static_cast<std::int64_t>(at.bytes);
            if (at.place == XtfPlace::kCutByEnd) break;
        }
        pos += at.bytes;
    }
    warn.Finish();
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
    XtfFile f;
    const auto first_packet = ReadXtfFileHeader(bytes, name, f.header);
    if (!first_packet) return first_packet.error();
    f.counts.bytes = static_cast<std::int64_t>(bytes.size());
    WalkXtfPackets(bytes, *first_packet, name, f);
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

// XTF's UTC times in GPS time: + GPS-UTC from `leap_seconds` when >= 0, else the table.
std::int64_t GpsTimeOfXtf(std::int64_t utime_unix, int leap_seconds) {
    return leap_seconds >= 0 ? GpsFromUnix(utime_unix, leap_seconds) : GpsFromUnix(utime_unix);
}

// A copy sorted by time (stable: records at one time keep the file's order).
template <typename Record>
std::vector<Record> SortedByTime(std::vector<Record> records) {
    std::stable_sort(records.begin(), records.end(), [](const auto& a, const auto& b) {
        return a.utime_unix < b.utime_unix;
    });
    return records;
}

// East, north and up velocity at positions[i] from its neighbours (XTF carries none); zero
// when they are not within 2 s. Only the ingest's session checks and reports look at it.
Eigen::Vector3d VelocityFromNeighbours(const std::vector<XtfPosition>& positions, std::size_t i) {
    constexpr double kEarthRadiusM = 6371000.0;
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    const XtfPosition& before = positions[i > 0 ? i - 1 : i];
    const XtfPosition& after = positions[i + 1 < positions.size() ? i + 1 : i];
    const double dt = static_cast<double>(after.utime_unix - before.utime_unix) * 1e-6;
    if (dt > 0 && dt < 2.0) {
        const double lat = frames::DegToRad(positions[i].y);
        v.x() = frames::DegToRad(after.x - before.x) * kEarthRadiusM * std::cos(lat) / dt;
        v.y() = frames::DegToRad(after.y - before.y) * kEarthRadiusM / dt;
        v.z() = (after.altitude_m - before.altitude_m) / dt;
    }
    return v;
}

// The standard deviations XTF does not carry, as assumed, at one navigation time.
survey::NavStdDev AssumedStdDev(std::int64_t utime_gps, const XtfAssumptions& as) {
    survey::NavStdDev sd;
    sd.utime_gps = utime_gps;
    sd.north_m = sd.east_m = static_cast<float>(as.position_sigma_horizontal_m);
    sd.up_m = static_cast<float>(as.position_sigma_vertical_m);
    sd.roll_deg = sd.pitch_deg = static_cast<float>(as.roll_pitch_sigma_deg);
    sd.yaw_deg = static_cast<float>(as.heading_sigma_deg);
    return sd;
}

// Navigation: each position with the attitude interpolated at its time and the assumed sigmas;
// a position without attitude within the gap is counted and left out.
void AddXtfNavigation(const XtfFile& file,
                      const XtfAssumptions& as,
                      int leap_seconds,
                      detail::Collector& col,
                      XtfConversion& cv) {
    const std::vector<XtfAttitude> attitude = SortedByTime(file.attitude);
    const std::vector<XtfPosition> positions = SortedByTime(file.positions);
    const auto max_gap_us = static_cast<std::int64_t>(as.max_attitude_gap_s * 1e6);
    const auto hold_us = static_cast<std::int64_t>(as.attitude_hold_s * 1e6);
    for (std::size_t i = 0; i < positions.size(); ++i) {
        const XtfPosition& p = positions[i];
        XtfAttitude a;
        if (!AttitudeAt(attitude, p.utime_unix, max_gap_us, hold_us, a)) {
            ++cv.nav_without_attitude;
            continue;
        }
        const Eigen::Vector3d v = VelocityFromNeighbours(positions, i);
        const std::int64_t t = GpsTimeOfXtf(p.utime_unix, leap_seconds);
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
        col.AddStdDev(AssumedStdDev(t, as));
        ++cv.nav_samples;
    }
}

// A ping's header: time, number, sound speed, the range resolution c/2 * scale of its R0
// counts, and for consumers without per-beam angles the fan from its first to its last point.
survey::PingHeader XtfPingHeader(const XtfBathyPing& p, int leap_seconds) {
    const std::size_t n = p.twtt_counts.size();
    survey::PingHeader h;
    h.utime_gps = GpsTimeOfXtf(p.utime_unix, leap_seconds);
    h.ping_number = p.ping_number;
    h.sound_speed_mps = p.sound_speed_mps;
    h.sound_speed_valid = std::isfinite(p.sound_speed_mps) && p.sound_speed_mps > 0;
    const double resolution_m = 0.5 * p.sound_speed_mps * p.twtt_scale_s;
    h.range_resolution_m = std::isfinite(resolution_m) && resolution_m > 0 ? resolution_m : 0.0;
    h.start_angle_deg = frames::RadToDeg(p.angle_rad.front());
    h.angle_increment_deg = n > 1 ? frames::RadToDeg(p.angle_rad.back() - p.angle_rad.front()) /
                                        static_cast<double>(n - 1)
                                  : 0.0;
    h.profile_tilt_deg = 0;
    return h;
}

// A ping's R0 counts, 0 where its Q0 flags say no detection or (drop_failed_quality) a failed
// brightness or colinearity test, both counted; and its per-point angles in degrees.
void XtfRangesAndAngles(const XtfBathyPing& p,
                        const XtfAssumptions& as,
                        std::vector<std::int32_t>& counts,
                        std::vector<float>& angle_deg,
                        XtfConversion& cv) {
    constexpr std::uint8_t kDetected = kBth0QualityMagnitude | kBth0QualityPhase;
    constexpr std::uint8_t kTests = kBth0QualityBrightness | kBth0QualityColinearity;
    const std::size_t n = p.twtt_counts.size();
    counts.assign(n, 0);
    angle_deg.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        angle_deg[i] = static_cast<float>(frames::RadToDeg(p.angle_rad[i]));
        std::int32_t count = p.twtt_counts[i];
        const std::uint8_t quality = p.quality.empty() ? 0xF : p.quality[i];
        if (count == 0 || (quality & kDetected) == 0) {
            ++cv.points_no_detection;
            count = 0;
        } else if (as.drop_failed_quality && (quality & kTests) != kTests) {
            ++cv.points_failed_quality;
            count = 0;
        }
        counts[i] = count;
    }
}

// A ping's I1 values x scale, clamped to 16 bits; false when I1 does not hold one per point.
bool XtfIntensities(const XtfBathyPing& p, std::vector<std::uint16_t>& intensity) {
    const std::size_t n = p.twtt_counts.size();
    if (p.intensity.size() != n) return false;
    intensity.resize(n);
    const double scale =
        std::isfinite(p.intensity_scale) && p.intensity_scale > 0 ? p.intensity_scale : 1.0;
    for (std::size_t i = 0; i < n; ++i) {
        intensity[i] =
            static_cast<std::uint16_t>(std::clamp(std::lround(p.intensity[i] * scale), 0L, 65535L));
    }
    return true;
}

// The pings with their per-point angles; the collector decides which it keeps (cv counts
// those).
void AddXtfPings(const XtfFile& file,
                 const XtfAssumptions& as,
                 int leap_seconds,
                 IngestResult& into,
                 detail::Collector& col,
                 XtfConversion& cv) {
    std::vector<std::int32_t> counts;
    std::vector<std::uint16_t> intensity;
    std::vector<float> angle_deg;
    for (const XtfBathyPing& p : file.pings) {
        const std::size_t n = p.twtt_counts.size();
        const survey::PingHeader h = XtfPingHeader(p, leap_seconds);
        if (p.tx_steering_vert_rad != 0) ++cv.pings_steered;
        XtfRangesAndAngles(p, as, counts, angle_deg, cv);
        const bool with_intensity = XtfIntensities(p, intensity);
        const std::size_t pings_before = into.pings.pings.size();
        col.AddPing(
            h, counts.data(), n, with_intensity ? intensity.data() : nullptr, angle_deg.data());
        if (into.pings.pings.size() > pings_before) {
            ++cv.pings;
            cv.points += static_cast<std::int64_t>(n);
        }
    }
}

// The file's packets as ingest events by type, its damage as the LCM reader's is counted.
void AddXtfCounts(const XtfFile& file, const XtfConversion& cv, IngestCounts& c) {
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
}

// The decoder's warnings, then the packet types left unread and the positions left out.
void AddXtfWarnings(const XtfFile& file,
                    const std::string& path,
                    const XtfAssumptions& as,
                    const XtfConversion& cv,
                    std::vector<std::string>& warnings) {
    const XtfCounts& xc = file.counts;
    warnings.insert(warnings.end(), file.warnings.begin(), file.warnings.end());
    if (xc.unknown_packets > 0) {
        std::string types;
        for (const auto& [type, k] : xc.packets_by_type) {
            if (type == kXtfAttitude || type == kXtfPosRawNavigation ||
                type == kXtfQinsyR2SonicBathy)
                continue;
            types +=
                (types.empty() ? "" : ", ") + std::to_string(type) + " (" + std::to_string(k) + ")";
        }
        warnings.push_back(path + ": " + std::to_string(xc.unknown_packets) +
                           " XTF packets of types this reader does not use, skipped: " + types);
    }
    if (cv.nav_without_attitude > 0) {
        warnings.push_back(path + ": " + std::to_string(cv.nav_without_attitude) +
                           " navigation packets without attitude within " +
                           Fixed(as.max_attitude_gap_s, 1) + " s, left out");
    }
}

// `text` under `key` unless an assumption under that key is already said.
void AssumeOnce(std::vector<std::string>& assumed,
                const std::string& key,
                const std::string& text) {
    for (const auto& a : assumed) {
        if (a.rfind(key, 0) == 0) return;
    }
    assumed.push_back(key + text);
}

// What had to be assumed, said once per ingest (the first XTF file's values).
void SayXtfAssumptions(const XtfFile& file,
                       const std::string& path,
                       const XtfAssumptions& as,
                       int leap_seconds,
                       const XtfConversion& cv,
                       std::vector<std::string>& assumed) {
    const int leap = leap_seconds >= 0 || file.pings.empty()
                         ? leap_seconds
                         : LeapSecondsAtUnix(file.pings.front().utime_unix);
    AssumeOnce(assumed,
               "XTF times: ",
               "the R2Sonic H0 ping times and the packets' UTC times + GPS-UTC (" +
                   std::to_string(leap) +
                   " s); the ping times taken as GPS-synchronised (no sonar clock search)");
    AssumeOnce(assumed,
               "XTF navigation: ",
               "RawAltitude of the type-107 packets taken as the ellipsoidal height (XTF does not "
               "say which datum); heave not applied (the navigation height is used); attitude of "
               "the type-3 packets (roll + starboard down, pitch + bow up, heading) interpolated "
               "at the navigation times");
    AssumeOnce(assumed,
               "XTF navigation sigmas: ",
               "no INS status or standard deviations in XTF: assumed 1 sigma " +
                   Fixed(as.position_sigma_horizontal_m, 2) + " m horizontal, " +
                   Fixed(as.position_sigma_vertical_m, 2) + " m vertical, roll/pitch " +
                   Fixed(as.roll_pitch_sigma_deg, 2) + " deg, heading " +
                   Fixed(as.heading_sigma_deg, 2) + " deg");
    if (!file.pings.empty()) {
        AssumeOnce(assumed,
                   "XTF sound speed: ",
                   "ranges = two-way travel time x the H0 surface sound speed / 2 of each ping "
                   "(first " +
                       Fixed(file.pings.front().sound_speed_mps, 2) +
                       " m/s); beam angles as the head gives them (A2), straight rays unless a "
                       "cast is given");
        AssumeOnce(assumed,
                   "XTF quality: ",
                   "R2Sonic Q0 points without a detection bit" +
                       std::string(as.drop_failed_quality
                                       ? " or failing the brightness or colinearity test"
                                       : "") +
                       " taken as no detection (" + std::to_string(cv.points_failed_quality) +
                       " failed a test in " + path + ")");
        AssumeOnce(assumed,
                   "XTF intensities: ",
                   "R2Sonic I1 values x scale (micropascals), as relative intensity");
    }
    if (cv.pings_steered > 0) {
        AssumeOnce(assumed,
                   "XTF fan steering: ",
                   std::to_string(cv.pings_steered) +
                       " pings with a non-zero H0 TxSteeringVert: not applied (fan taken as "
                       "vertical)");
    }
    const float* offset_m = file.header.channel_offset_m;
    const float* offset_deg = file.header.channel_offset_deg;
    if (offset_m[0] != 0 || offset_m[1] != 0 || offset_m[2] != 0 || offset_deg[0] != 0 ||
        offset_deg[1] != 0 || offset_deg[2] != 0) {
        AssumeOnce(assumed,
                   "XTF sonar offsets: ",
                   "the file header's bathymetry channel offsets (X " + Fixed(offset_m[0], 3) +
                       ", Y " + Fixed(offset_m[1], 3) + ", Z " + Fixed(offset_m[2], 3) +
                       " m; yaw " + Fixed(offset_deg[0], 2) + ", pitch " + Fixed(offset_deg[1], 2) +
                       ", roll " + Fixed(offset_deg[2], 2) +
                       " deg) are reported, not applied: XTF fixes neither their reference point "
                       "nor their signs; the vehicle file's lever arm and mount are used");
    }
}

}  // namespace

Expected<XtfConversion> AddXtfToIngest(const XtfFile& file,
                                       const std::string& path,
                                       const XtfAssumptions& as,
                                       int leap_seconds,
                                       IngestResult& into) {
    const XtfFileHeader& fh = file.header;
    if (!file.positions.empty() && fh.nav_units != kXtfNavUnitsLatLon) {
        return Error{path + ": XTF navigation in nav units " + std::to_string(fh.nav_units) +
                     (fh.nav_units == kXtfNavUnitsMetres ? " (projected metres)" : "") +
                     ": pitmap needs latitude/longitude (nav units 3); the projection is not "
                     "in the file"};
    }
    XtfConversion cv;
    detail::Collector col(into);
    const detail::SpanMark mark = detail::MarkSpan(into);
    AddXtfNavigation(file, as, leap_seconds, col, cv);
    AddXtfPings(file, as, leap_seconds, into, col, cv);
    detail::RecordSpan(into, path, mark);
    AddXtfCounts(file, cv, into.counts);
    AddXtfWarnings(file, path, as, cv, into.warnings);
    SayXtfAssumptions(file, path, as, leap_seconds, cv, into.assumed);
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
