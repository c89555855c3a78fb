// SPDX-License-Identifier: MIT
// Helpers shared by the Delta T tests: synthetic pings (spec imagenex_deltat.md §1.2) and a
// framer driver that checks the byte-accounting invariant of common/protocol/framing.hpp.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string_view>
#include <variant>
#include <vector>

#include "common/protocol/deltat/messages.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/framing.hpp"

namespace pitmap::protocol::deltat::test_util {

// Byte-level writers for hand-built records (independent of the encoder).
inline void PutU16Be(std::vector<std::uint8_t>& b, std::size_t off, std::uint16_t v) {
    if (off + 2 > b.size()) return;
    b[off] = static_cast<std::uint8_t>(v >> 8);
    b[off + 1] = static_cast<std::uint8_t>(v & 0xFF);
}
inline void PutU32Be(std::vector<std::uint8_t>& b, std::size_t off, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b[off + i] = static_cast<std::uint8_t>(v >> (24 - 8 * i));
}
inline void PutText(std::vector<std::uint8_t>& b, std::size_t off, std::string_view s) {
    for (std::size_t i = 0; i < s.size(); ++i) b[off + i] = static_cast<std::uint8_t>(s[i]);
}
inline void PutF32(std::vector<std::uint8_t>& b, std::size_t off, float v, bool big_endian) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, 4);
    for (int i = 0; i < 4; ++i) {
        const int shift = big_endian ? 24 - 8 * i : 8 * i;
        b[off + i] = static_cast<std::uint8_t>(bits >> shift);
    }
}

// A ping with every field set to a distinct value that survives quantisation, B beams.
// Float values have few significant bits so their byte-swapped reading is implausible.
inline Ping83P MakePing(std::size_t num_beams,
                        bool intensity,
                        std::uint8_t version,
                        std::uint32_t ping_number = 7) {
    Ping83P p;
    p.format_version = version;
    SetHeaderTime(p, 1709646307678000);  // 2024-03-05T13:45:07.678
    SetHeaderLatitude(p, -23.5);
    SetHeaderLongitude(p, 133.25);
    p.speed_over_ground_knots = 3.2;
    p.course_over_ground_deg = 271.5;
    p.internal_pitch_valid = true;
    p.internal_pitch_deg = -1.5;
    p.internal_roll_valid = true;
    p.internal_roll_deg = 2.5;
    p.internal_heading_valid = true;
    p.internal_heading_deg = 181.3;
    p.samples_per_beam = 500;
    p.sector_size_deg = 120;
    p.start_angle_cdeg = -6000;
    p.angle_increment_cdeg = static_cast<std::uint8_t>(12000 / num_beams);
    p.acoustic_range_m = 50;
    p.frequency_khz = 260;
    p.sound_velocity_flag = true;
    p.sound_velocity_header_mps = 1482.5;
    p.sound_velocity_mps = 1482.5;
    p.sound_velocity_valid = true;
    p.range_resolution_mm = 10;
    p.pulse_length_us = 120;
    p.profile_tilt_deg = 10.0;
    p.repetition_rate_ms = 100;
    p.ping_number = ping_number;
    if (version >= kVersion110) {
        p.sonar_offset_m = {1.5f, -0.25f, 0.75f};
        p.ping_latency_us = 2500;
        p.data_latency_us = 12000;
        p.sample_rate = 1;
        p.option_flags = kOptionRollCorrected | kOptionOverlapped;
        p.pings_averaged = 3;
        p.center_ping_offset_us = 4000;
        p.heave_m = 0.5f;
        p.user_byte = 0xAB;
        p.altitude_m = 12.5f;
        p.external_sensor_flags = 0x0F;
        p.external_pitch_deg = 2.5f;
        p.external_roll_deg = -3.5f;
        p.external_heading_deg = 270.5f;
        p.transmit_scan_flag = 1;
        p.transmit_scan_angle_deg = -15.5f;
        p.intensity_included = intensity;
        p.intensity_flag_raw = intensity ? 1 : 0;
    }
    p.range_counts.resize(num_beams);
    for (std::size_t i = 0; i < num_beams; ++i) {
        // Never "83P" (0x38 0x33 0x50): high byte stays below 0x20.
        p.range_counts[i] = static_cast<std::uint16_t>((i * 37 + ping_number) % 4000);
    }
    if (intensity && version >= kVersion110) {
        p.intensities.resize(num_beams);
        for (std::size_t i = 0; i < num_beams; ++i) {
            p.intensities[i] = static_cast<std::uint16_t>((i * 11 + 5) % 1000);
        }
    }
    return p;
}

// One framer event with the bytes copied out.
struct Event {
    enum class Kind { kFrame, kSkipped } kind;
    std::vector<std::uint8_t> bytes;  // frame bytes
    Skipped skipped;
    std::uint64_t offset = 0;
};

// Drains `framer` until NeedMore, appending events, and checks that event offsets are
// contiguous from `*next_offset` (every byte accounted exactly once, in order).
template <typename Framer, typename Frame>
void Drain(Framer& framer, std::vector<Event>& events, std::uint64_t* next_offset) {
    while (true) {
        auto ev = framer.Next();
        if (std::holds_alternative<NeedMore>(ev)) return;
        Event e;
        if (const auto* s = std::get_if<Skipped>(&ev)) {
            e.kind = Event::Kind::kSkipped;
            e.skipped = *s;
            e.offset = s->offset;
            ASSERT_GT(s->bytes, 0u);
            ASSERT_EQ(s->offset, *next_offset);
            *next_offset += s->bytes;
        } else {
            const Frame& f = std::get<Frame>(ev);
            e.kind = Event::Kind::kFrame;
            e.bytes.assign(f.bytes.begin(), f.bytes.end());
            e.offset = f.offset;
            ASSERT_EQ(f.offset, *next_offset);
            *next_offset += f.bytes.size();
        }
        events.push_back(std::move(e));
    }
}

}  // namespace pitmap::protocol::deltat::test_util
