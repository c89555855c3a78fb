// SPDX-License-Identifier: MIT
#include "common/protocol/novatel/framer.hpp"

#include <algorithm>
#include <array>
#include <cstring>

#include "common/protocol/novatel/crc32.hpp"

namespace pitmap::protocol::novatel {
namespace {

constexpr std::uint8_t kSync0 = 0xAA;
constexpr std::uint8_t kSync1 = 0x44;
constexpr std::uint8_t kSync1Proprietary = 0x45;
constexpr std::uint8_t kSyncLong = 0x12;
constexpr std::uint8_t kSyncShort = 0x13;
constexpr std::uint8_t kCr = 0x0D;
constexpr std::uint8_t kLf = 0x0A;

// Bytes that may start a frame (§1). Everything else is skipped as garbage in one run.
constexpr std::array<bool, 256> MakeStartTable() {
    std::array<bool, 256> t{};
    t[kSync0] = true;
    t['#'] = true;
    t['%'] = true;
    t['<'] = true;
    t['['] = true;
    t['$'] = true;
    return t;
}
constexpr std::array<bool, 256> kIsStart = MakeStartTable();

constexpr bool IsPrintable(std::uint8_t c) {
    return c >= 0x20 && c <= 0x7E;
}
constexpr bool IsUpper(std::uint8_t c) {
    return c >= 'A' && c <= 'Z';
}
constexpr bool IsDigit(std::uint8_t c) {
    return c >= '0' && c <= '9';
}

int HexValue(std::uint8_t c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

std::uint16_t LoadU16(const std::uint8_t* p) {
    return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
std::uint32_t LoadU32(const std::uint8_t* p) {
    return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
           (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}

struct NameId {
    std::string_view name;
    std::uint16_t id;
};

// Names of the logs in spec §6.15 and of the other logs in the real captures (§9.1).
constexpr std::array<NameId, 47> kNames = {{
    {"LOG", 1},
    {"GPSEPHEM", 7},
    {"RAWEPHEM", 41},
    {"BESTPOS", 42},
    {"SATVIS", 48},
    {"TRACKSTAT", 83},
    {"RXSTATUS", 93},
    {"RXSTATUSEVENT", 94},
    {"BESTVEL", 99},
    {"TIME", 101},
    {"RANGECMP", 140},
    {"RXHWLEVELS", 195},
    {"MARKTIME", 231},
    {"BESTXYZ", 241},
    {"PSRXYZ", 243},
    {"INSATT", 263},
    {"INSCOV", 264},
    {"RAWIMU", 268},
    {"RAWWAASFRAME", 287},
    {"INSATTS", 319},
    {"RAWIMUS", 325},
    {"INSPVA", 507},
    {"INSPVAS", 508},
    {"MARK2TIME", 616},
    {"BSLNXYZ", 686},
    {"GLOEPHEMERIS", 723},
    {"BESTUTM", 726},
    {"CORRIMUDATA", 812},
    {"CORRIMUDATAS", 813},
    {"MARK1TIME", 1130},
    {"PSRDOP2", 1163},
    {"HEADING2", 1335},
    {"IMURATECORRIMUS", 1362},
    {"BESTGNSSPOS", 1429},
    {"BESTGNSSVEL", 1430},
    {"INSATTX", 1457},
    {"RAWIMUX", 1461},
    {"RAWIMUSX", 1462},
    {"INSPVAX", 1465},
    {"INSCONFIG", 1945},
    {"DUALANTENNAHEADING", 2042},
    {"INSSTDEV", 2051},
    {"CORRIMUS", 2264},
    {"RANGE", 43},
    {"PSRPOS", 47},
    {"VERSION", 37},
    {"SEND", 177},
}};

// ASCII names carry a format suffix: A (ASCII log), R (response); also B in LOG commands.
std::int32_t IdOfSuffixedName(std::string_view name) {
    if (name.size() < 2) return -1;
    const char suffix = name.back();
    if (suffix != 'A' && suffix != 'R' && suffix != 'B') return -1;
    const auto id = MessageIdFromName(name.substr(0, name.size() - 1));
    return id ? static_cast<std::int32_t>(*id) : -1;
}

}  // namespace

std::string_view ToString(FrameKind kind) {
    switch (kind) {
        case FrameKind::kLongBinary:
            return "long_binary";
        case FrameKind::kShortBinary:
            return "short_binary";
        case FrameKind::kProprietary:
            return "proprietary";
        case FrameKind::kAscii:
            return "ascii";
        case FrameKind::kShortAscii:
            return "short_ascii";
        case FrameKind::kAbbreviated:
            return "abbreviated";
        case FrameKind::kPrompt:
            return "prompt";
        case FrameKind::kNmea:
            return "nmea";
    }
    return "unknown";
}

std::optional<std::uint16_t> MessageIdFromName(std::string_view name) {
    for (const auto& entry : kNames) {
        if (entry.name == name) return entry.id;
    }
    return std::nullopt;
}

std::string_view MessageNameFromId(std::uint16_t id) {
    for (const auto& entry : kNames) {
        if (entry.id == id) return entry.name;
    }
    return {};
}

Framer::Framer() {
    buffer_.reserve(2 * kMaxLongFrameLength);
}

void Framer::Push(ByteSpan bytes) {
    if (bytes.empty()) return;
    // Compact: the consumed head is dropped so the buffer only holds the unconsumed tail.
    if (start_ > 0) {
        const std::size_t tail = buffer_.size() - start_;
        if (tail > 0) std::memmove(buffer_.data(), buffer_.data() + start_, tail);
        buffer_.resize(tail);
        base_offset_ += start_;
        start_ = 0;
    }
    buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

Skipped Framer::Consume(std::size_t n, SkipReason reason) {
    Skipped s{reason, n, base_offset_ + start_};
    start_ += n;
    return s;
}

std::optional<Skipped> Framer::GiveUpCandidate(SkipReason reason) {
    const std::size_t end = buffer_.size();
    if (start_ == end) return std::nullopt;
    // The candidate at start_ waits for bytes that will not come. Only its first byte is given
    // up, with the bytes after it that cannot start a frame; whatever it had buffered behind
    // that is scanned again by Next(), so a false sync cannot hide the frames behind it.
    std::size_t pos = start_ + 1;
    while (pos < end && !kIsStart[buffer_[pos]]) ++pos;
    return Consume(pos - start_, reason);
}

std::optional<Skipped> Framer::Flush() {
    return GiveUpCandidate(SkipReason::kTruncated);
}

std::optional<Skipped> Framer::Expire() {
    // Only a candidate with a complete checksummed frame behind it is given up: it cannot be a
    // real frame then (a real frame does not hold another). A real frame cut by a pause keeps
    // waiting for the rest, so a pause loses nothing.
    if (!ChecksummedFrameBehind()) return std::nullopt;
    return GiveUpCandidate(SkipReason::kStale);
}

bool Framer::ChecksummedFrameBehind() const {
    for (std::size_t pos = start_ + 1; pos < buffer_.size(); ++pos) {
        if (!kIsStart[buffer_[pos]]) continue;
        const Attempt a = TryAt(pos);
        if (a.outcome != Outcome::kFrame) continue;
        switch (a.kind) {
            case FrameKind::kLongBinary:
            case FrameKind::kShortBinary:
            case FrameKind::kProprietary:
            case FrameKind::kAscii:
            case FrameKind::kShortAscii:
                return true;
            default:
                break;
        }
    }
    return false;
}

std::variant<NeedMore, Skipped, Frame> Framer::Next() {
    const std::size_t end = buffer_.size();
    const std::uint8_t* data = buffer_.data();
    std::size_t pos = start_;
    // Garbage run [start_, pos): bytes that start no frame, reported in one Skipped.
    while (pos < end) {
        if (!kIsStart[data[pos]]) {
            ++pos;
            continue;
        }
        const Attempt a = TryAt(pos);
        if (a.outcome == Outcome::kNotAFrame) {
            ++pos;
            continue;
        }
        if (pos > start_) return Consume(pos - start_, SkipReason::kGarbage);
        switch (a.outcome) {
            case Outcome::kFrame: {
                Frame f;
                f.kind = a.kind;
                f.message_id = a.message_id;
                f.bytes = ByteSpan(data + pos, a.length);
                f.offset = base_offset_ + pos;
                start_ = pos + a.length;
                return f;
            }
            case Outcome::kNeedMore:
                return NeedMore{};
            case Outcome::kBadCrc:
                return Consume(1, SkipReason::kBadCrc);
            case Outcome::kBadLength:
                return Consume(1, SkipReason::kBadLength);
            case Outcome::kNotAFrame:
                break;
        }
    }
    if (pos > start_) return Consume(pos - start_, SkipReason::kGarbage);
    return NeedMore{};
}

Framer::Attempt Framer::TryAt(std::size_t pos) const {
    switch (buffer_[pos]) {
        case kSync0:
            return TryBinary(pos);
        case '#':
            return TryCrcText(pos, FrameKind::kAscii);
        case '%':
            return TryCrcText(pos, FrameKind::kShortAscii);
        case '<':
            return TryAbbreviated(pos);
        case '[':
            return TryPrompt(pos);
        case '$':
            return TryNmea(pos);
        default:
            return {};
    }
}

Framer::Attempt Framer::TryBinary(std::size_t pos) const {
    const std::uint8_t* p = buffer_.data() + pos;
    const std::size_t avail = buffer_.size() - pos;
    Attempt a;
    // Sync prefix (§1): AA 44 12 long, AA 44 13 short, AA 45 12 proprietary.
    if (avail < 2) {
        a.outcome = Outcome::kNeedMore;
        return a;
    }
    if (p[1] != kSync1 && p[1] != kSync1Proprietary) return a;
    if (avail < 3) {
        a.outcome = Outcome::kNeedMore;
        return a;
    }
    if (p[1] == kSync1 && p[2] == kSyncShort) {
        a.kind = FrameKind::kShortBinary;
        if (avail < 4) {
            a.outcome = Outcome::kNeedMore;
            return a;
        }
        // 12 + <=255 + 4 <= kMaxShortFrameLength always holds: no length can be impossible.
        const std::size_t total = kShortHeaderLength + p[3] + kCrcLength;
        if (avail < total) {
            a.outcome = Outcome::kNeedMore;
            return a;
        }
        a.length = total;
    } else if (p[2] == kSyncLong) {
        a.kind = p[1] == kSync1 ? FrameKind::kLongBinary : FrameKind::kProprietary;
        if (avail < 10) {
            a.outcome = Outcome::kNeedMore;
            return a;
        }
        const std::size_t header_length = p[3];
        const std::size_t total = header_length + LoadU16(p + 8) + kCrcLength;
        if (header_length < kLongHeaderMinLength || total > kMaxLongFrameLength) {
            a.outcome = Outcome::kBadLength;
            return a;
        }
        if (avail < total) {
            a.outcome = Outcome::kNeedMore;
            return a;
        }
        a.length = total;
    } else {
        return a;
    }
    const std::size_t covered = a.length - kCrcLength;
    if (Crc32(ByteSpan(p, covered)) != LoadU32(p + covered)) {
        a.outcome = Outcome::kBadCrc;
        return a;
    }
    a.outcome = Outcome::kFrame;
    a.message_id = LoadU16(p + 4);
    return a;
}

Framer::Attempt Framer::TryCrcText(std::size_t pos, FrameKind kind) const {
    // '#'/'%' NAME ... '*' 8 hex CR LF, printable in between (§4, §5).
    const std::uint8_t* p = buffer_.data() + pos;
    const std::size_t avail = std::min(buffer_.size() - pos, kMaxAsciiFrameLength);
    Attempt a;
    a.kind = kind;
    std::size_t i = 1;
    // The name: upper-case letters and digits, then ','.
    for (; i < avail; ++i) {
        if (!IsUpper(p[i]) && !IsDigit(p[i])) break;
    }
    if (i == avail) {
        if (avail < kMaxAsciiFrameLength) a.outcome = Outcome::kNeedMore;
        return a;
    }
    if (i == 1 || p[i] != ',') return a;
    const std::size_t name_end = i;
    const auto* star = static_cast<const std::uint8_t*>(std::memchr(p + i, '*', avail - i));
    const std::size_t star_pos = star ? static_cast<std::size_t>(star - p) : avail;
    for (; i < star_pos; ++i) {
        if (!IsPrintable(p[i])) return a;
    }
    if (star_pos == avail) {
        if (avail < kMaxAsciiFrameLength) a.outcome = Outcome::kNeedMore;
        return a;
    }
    const std::size_t total = star_pos + 1 + 8 + 2;
    std::uint32_t stored = 0;
    for (i = star_pos + 1; i < star_pos + 9; ++i) {
        if (i >= avail) {
            if (buffer_.size() - pos < kMaxAsciiFrameLength) a.outcome = Outcome::kNeedMore;
            return a;
        }
        const int v = HexValue(p[i]);
        if (v < 0) return a;
        stored = (stored << 4) | static_cast<std::uint32_t>(v);
    }
    if (total > avail) {
        if (avail < kMaxAsciiFrameLength && total <= kMaxAsciiFrameLength) {
            // Only the terminator is missing; still require what we have of it to match.
            if (star_pos + 9 < avail && p[star_pos + 9] != kCr) return a;
            a.outcome = Outcome::kNeedMore;
        }
        return a;
    }
    if (p[star_pos + 9] != kCr || p[star_pos + 10] != kLf) return a;
    if (Crc32(ByteSpan(p + 1, star_pos - 1)) != stored) {
        a.outcome = Outcome::kBadCrc;
        return a;
    }
    a.outcome = Outcome::kFrame;
    a.length = total;
    a.message_id =
        IdOfSuffixedName(std::string_view(reinterpret_cast<const char*>(p + 1), name_end - 1));
    return a;
}

Framer::Attempt Framer::TryAbbreviated(std::size_t pos) const {
    // '<' printable... CR LF (§5), no checksum.
    const std::uint8_t* p = buffer_.data() + pos;
    const std::size_t avail = std::min(buffer_.size() - pos, kMaxAbbreviatedLineLength);
    Attempt a;
    a.kind = FrameKind::kAbbreviated;
    for (std::size_t i = 1; i < avail; ++i) {
        // '#' and '%' start checksummed frames and never occur inside an abbreviated line: a
        // stray '<' must not swallow the ASCII log behind it.
        if (p[i] == '#' || p[i] == '%') return a;
        if (IsPrintable(p[i])) continue;
        if (p[i] != kCr || i == 1) return a;
        if (i + 1 == avail) break;
        if (p[i + 1] != kLf) return a;
        a.outcome = Outcome::kFrame;
        a.length = i + 2;
        return a;
    }
    if (avail < kMaxAbbreviatedLineLength) a.outcome = Outcome::kNeedMore;
    return a;
}

Framer::Attempt Framer::TryPrompt(std::size_t pos) const {
    // \[[A-Z]+[0-9]*(_[0-9]+)?\] (§9 item 3), no terminator.
    const std::uint8_t* p = buffer_.data() + pos;
    const std::size_t avail = std::min(buffer_.size() - pos, kMaxPromptLength);
    Attempt a;
    a.kind = FrameKind::kPrompt;
    enum class State { kLetters, kDigits, kUnderscore, kSubDigits } state = State::kLetters;
    std::size_t run = 0;
    for (std::size_t i = 1; i < avail; ++i) {
        const std::uint8_t c = p[i];
        switch (state) {
            case State::kLetters:
                if (IsUpper(c)) {
                    ++run;
                    continue;
                }
                if (run == 0) return a;
                if (IsDigit(c)) {
                    state = State::kDigits;
                    continue;
                }
                break;
            case State::kDigits:
                if (IsDigit(c)) continue;
                break;
            case State::kUnderscore:
                if (!IsDigit(c)) return a;
                state = State::kSubDigits;
                continue;
            case State::kSubDigits:
                if (IsDigit(c)) continue;
                if (c == ']') {
                    a.outcome = Outcome::kFrame;
                    a.length = i + 1;
                }
                return a;
        }
        // After letters or digits: '_' starts the sub-port, ']' ends the prompt.
        if (c == '_') {
            state = State::kUnderscore;
            continue;
        }
        if (c == ']') {
            a.outcome = Outcome::kFrame;
            a.length = i + 1;
        }
        return a;
    }
    if (avail < kMaxPromptLength) a.outcome = Outcome::kNeedMore;
    return a;
}

Framer::Attempt Framer::TryNmea(std::size_t pos) const {
    // '$' printable... '*' 2 hex CR LF; checksum = XOR of the bytes between '$' and '*'.
    const std::uint8_t* p = buffer_.data() + pos;
    const std::size_t avail = std::min(buffer_.size() - pos, kMaxNmeaLength);
    Attempt a;
    a.kind = FrameKind::kNmea;
    std::uint8_t sum = 0;
    std::size_t i = 1;
    for (; i < avail && p[i] != '*'; ++i) {
        if (!IsPrintable(p[i]) || p[i] == '$') return a;
        sum ^= p[i];
    }
    if (i + 5 > avail) {
        // Incomplete: check what is there, then wait.
        for (std::size_t k = i + 1; k < avail && k < i + 3; ++k) {
            if (HexValue(p[k]) < 0) return a;
        }
        if (i + 3 < avail && p[i + 3] != kCr) return a;
        if (avail < kMaxNmeaLength) a.outcome = Outcome::kNeedMore;
        return a;
    }
    if (i == 1) return a;
    const int hi = HexValue(p[i + 1]);
    const int lo = HexValue(p[i + 2]);
    if (hi < 0 || lo < 0 || p[i + 3] != kCr || p[i + 4] != kLf) return a;
    if (static_cast<std::uint8_t>((hi << 4) | lo) != sum) {
        a.outcome = Outcome::kBadCrc;
        return a;
    }
    a.outcome = Outcome::kFrame;
    a.length = i + 5;
    return a;
}

}  // namespace pitmap::protocol::novatel
