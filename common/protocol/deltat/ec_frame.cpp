// SPDX-License-Identifier: MIT
// External Control frame. Spec: shared/specs/imagenex_deltat.md §3.2.
#include "common/protocol/deltat/ec_frame.hpp"

#include <cmath>

namespace pitmap::protocol::deltat {
namespace {

constexpr std::array<std::uint16_t, 13> kRangeByCode = {
    5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 250, 300};
constexpr std::uint8_t kFirstRangeCode = 2;
constexpr std::array<std::uint16_t, 4> kSectorByCode = {30, 60, 90, 120};
constexpr std::array<std::uint16_t, 3> kBeamsByCode = {480, 240, 120};

template <std::size_t N>
std::optional<std::uint8_t> CodeOf(const std::array<std::uint16_t, N>& table, std::uint16_t v) {
    for (std::size_t i = 0; i < N; ++i) {
        if (table[i] == v) return static_cast<std::uint8_t>(i);
    }
    return std::nullopt;
}

DecodeError BadValue(std::size_t offset, std::string_view message) {
    return DecodeError{DecodeErrorKind::kBadValue, offset, message};
}

}  // namespace

std::optional<std::uint16_t> EcRangeMetresFromCode(std::uint8_t code) {
    if (code < kFirstRangeCode || code - kFirstRangeCode >= static_cast<int>(kRangeByCode.size())) {
        return std::nullopt;
    }
    return kRangeByCode[code - kFirstRangeCode];
}

std::optional<std::uint8_t> EcRangeCodeFromMetres(std::uint16_t range_m) {
    const auto code = CodeOf(kRangeByCode, range_m);
    if (!code) return std::nullopt;
    return static_cast<std::uint8_t>(*code + kFirstRangeCode);
}

std::optional<std::uint16_t> EcSectorDegFromCode(std::uint8_t code) {
    if (code >= kSectorByCode.size()) return std::nullopt;
    return kSectorByCode[code];
}

std::optional<std::uint8_t> EcSectorCodeFromDeg(std::uint16_t sector_deg) {
    return CodeOf(kSectorByCode, sector_deg);
}

std::optional<std::uint16_t> EcBeamsFromCode(std::uint8_t code) {
    if (code >= kBeamsByCode.size()) return std::nullopt;
    return kBeamsByCode[code];
}

std::optional<std::uint8_t> EcBeamsCodeFromCount(std::uint16_t num_beams) {
    return CodeOf(kBeamsByCode, num_beams);
}

std::variant<EcFrame, DecodeError> DecodeEcFrame(ByteSpan frame) {
    if (frame.size() < kEcFrameBytes) {
        return DecodeError{DecodeErrorKind::kTruncated, frame.size(), "EC frame shorter than 256"};
    }
    if (frame.size() > kEcFrameBytes) {
        return DecodeError{
            DecodeErrorKind::kTrailingBytes, kEcFrameBytes, "EC frame longer than 256"};
    }
    ByteReader r(frame);
    if (r.U8() != 'E' || r.U8() != 'C') {
        return DecodeError{DecodeErrorKind::kBadMarker, 0, "no EC marker"};
    }
    EcFrame f;
    const auto read_bool = [&r](std::size_t offset, bool& dst) {
        r.Seek(offset);
        const std::uint8_t v = r.U8();
        dst = v == 1;
        return v <= 1;
    };
    if (!read_bool(3, f.external_control)) return BadValue(3, "external control not 0/1");
    if (!read_bool(4, f.receive_only)) return BadValue(4, "receive-only not 0/1");
    r.Seek(7);
    const auto range = EcRangeMetresFromCode(r.U8());
    if (!range) return BadValue(7, "range code outside 2..14");
    f.range_m = *range;
    f.start_gain_db = r.U8();
    f.display_gain_pct = r.U8();
    if (!read_bool(10, f.gain_equalisation)) return BadValue(10, "gain equalisation not 0/1");
    const auto sector = EcSectorDegFromCode(r.U8());
    if (!sector) return BadValue(11, "sector code outside 0..3");
    f.sector_deg = *sector;
    const std::uint8_t width = r.U8();
    if (width > 3) return BadValue(12, "beam width code outside 0..3");
    f.beam_width = static_cast<EcBeamWidth>(width);
    const auto beams = EcBeamsFromCode(r.U8());
    if (!beams) return BadValue(13, "beams code outside 0..2");
    f.num_beams = *beams;
    f.averaging = r.U8();
    if (f.averaging > 10) return BadValue(14, "averaging outside 0..10");
    f.persistence_s = r.U16Be();
    f.sound_velocity_mps = r.U16Be() / 10.0;
    const std::uint8_t mode = r.U8();
    if (mode > 4) return BadValue(19, "mode outside 0..4");
    f.mode = static_cast<EcMode>(mode);
    const std::uint8_t output = r.U8();
    if (output > 2) return BadValue(20, "output outside 0..2");
    f.output = static_cast<EcOutput>(output);
    if (!read_bool(21, f.profile_points)) return BadValue(21, "profile points not 0/1");
    f.profile_min_range_m = r.U8();
    f.profile_min_level_pct = r.U8();
    if (f.profile_min_level_pct > 100) return BadValue(23, "profile min level above 100 %");
    if (!read_bool(24, f.transducer_up)) return BadValue(24, "transducer not 0/1");
    f.profile_tilt_deg = static_cast<std::int16_t>(r.U8() - 180);
    if (!read_bool(26, f.roll_compensation)) return BadValue(26, "roll compensation not 0/1");
    if (!read_bool(28, f.record_837)) return BadValue(28, "837 recording not 0/1");
    if (!read_bool(29, f.record_83p)) return BadValue(29, "83P recording not 0/1");
    r.Seek(31);
    f.control = r.U8();
    f.trigger_delay = r.U16Be();
    const std::uint8_t filter = r.U8();
    if (filter > 2) return BadValue(34, "profile filter outside 0..2");
    f.profile_filter = static_cast<EcProfileFilter>(filter);
    return f;
}

bool EncodeEcFrame(const EcFrame& frame, std::vector<std::uint8_t>& out) {
    const auto range = EcRangeCodeFromMetres(frame.range_m);
    const auto sector = EcSectorCodeFromDeg(frame.sector_deg);
    const auto beams = EcBeamsCodeFromCount(frame.num_beams);
    const double sv = std::round(frame.sound_velocity_mps * 10.0);
    if (!range || !sector || !beams || !(sv >= 0.0 && sv <= 65535.0) ||
        frame.profile_tilt_deg < -180 || frame.profile_tilt_deg > 75) {
        return false;
    }
    out.reserve(out.size() + kEcFrameBytes);
    ByteWriter w(out);
    const auto b = [](bool v) { return static_cast<std::uint8_t>(v ? 1 : 0); };
    w.U8('E');                                                      // 0
    w.U8('C');                                                      // 1
    w.U8(0);                                                        // 2
    w.U8(b(frame.external_control));                                // 3
    w.U8(b(frame.receive_only));                                    // 4
    w.Zeros(2);                                                     // 5-6
    w.U8(*range);                                                   // 7
    w.U8(frame.start_gain_db);                                      // 8
    w.U8(frame.display_gain_pct);                                   // 9
    w.U8(b(frame.gain_equalisation));                               // 10
    w.U8(*sector);                                                  // 11
    w.U8(static_cast<std::uint8_t>(frame.beam_width));              // 12
    w.U8(*beams);                                                   // 13
    w.U8(frame.averaging);                                          // 14
    w.U16Be(frame.persistence_s);                                   // 15-16
    w.U16Be(static_cast<std::uint16_t>(sv));                        // 17-18
    w.U8(static_cast<std::uint8_t>(frame.mode));                    // 19
    w.U8(static_cast<std::uint8_t>(frame.output));                  // 20
    w.U8(b(frame.profile_points));                                  // 21
    w.U8(frame.profile_min_range_m);                                // 22
    w.U8(frame.profile_min_level_pct);                              // 23
    w.U8(b(frame.transducer_up));                                   // 24
    w.U8(static_cast<std::uint8_t>(frame.profile_tilt_deg + 180));  // 25
    w.U8(b(frame.roll_compensation));                               // 26
    w.U8(0);                                                        // 27
    w.U8(b(frame.record_837));                                      // 28
    w.U8(b(frame.record_83p));                                      // 29
    w.U8(0);                                                        // 30
    w.U8(frame.control);                                            // 31
    w.U16Be(frame.trigger_delay);                                   // 32-33
    w.U8(static_cast<std::uint8_t>(frame.profile_filter));          // 34
    w.Zeros(kEcFrameBytes - 35);
    return true;
}

std::vector<std::uint8_t> EncodeEcFrame(const EcFrame& frame) {
    std::vector<std::uint8_t> out;
    if (!EncodeEcFrame(frame, out)) out.clear();
    return out;
}

}  // namespace pitmap::protocol::deltat
