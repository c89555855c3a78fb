// SPDX-License-Identifier: MIT
// External Control frame tests against the byte table of spec imagenex_deltat.md §3.2.
#include "common/protocol/deltat/ec_frame.hpp"

#include <gtest/gtest.h>

namespace pitmap::protocol::deltat {
namespace {

EcFrame SampleFrame() {
    EcFrame f;
    f.external_control = true;
    f.receive_only = true;
    f.range_m = 80;
    f.start_gain_db = 12;
    f.display_gain_pct = 65;
    f.gain_equalisation = true;
    f.sector_deg = 90;
    f.beam_width = EcBeamWidth::kNarrow;
    f.num_beams = 240;
    f.averaging = 4;
    f.persistence_s = 0x0102;
    f.sound_velocity_mps = 1487.3;
    f.mode = EcMode::kProfile;
    f.output = EcOutput::k83B;
    f.profile_points = true;
    f.profile_min_range_m = 2;
    f.profile_min_level_pct = 35;
    f.transducer_up = true;
    f.profile_tilt_deg = -20;
    f.roll_compensation = true;
    f.record_837 = true;
    f.record_83p = false;
    f.control = 0x5A;
    f.trigger_delay = 0x0304;
    f.profile_filter = EcProfileFilter::kBottomFollow;
    return f;
}

TEST(EcFrame, EncodesEveryByteOfTheTable) {
    const auto b = EncodeEcFrame(SampleFrame());
    ASSERT_EQ(b.size(), 256u);
    EXPECT_EQ(b[0], 'E');
    EXPECT_EQ(b[1], 'C');
    EXPECT_EQ(b[2], 0);
    EXPECT_EQ(b[3], 1);
    EXPECT_EQ(b[4], 1);
    EXPECT_EQ(b[5], 0);
    EXPECT_EQ(b[6], 0);
    EXPECT_EQ(b[7], 9);  // 80 m
    EXPECT_EQ(b[8], 12);
    EXPECT_EQ(b[9], 65);
    EXPECT_EQ(b[10], 1);
    EXPECT_EQ(b[11], 2);  // 90 deg
    EXPECT_EQ(b[12], 2);  // narrow
    EXPECT_EQ(b[13], 1);  // 240 beams
    EXPECT_EQ(b[14], 4);
    EXPECT_EQ(b[15], 0x01);
    EXPECT_EQ(b[16], 0x02);
    EXPECT_EQ(b[17] << 8 | b[18], 14873);
    EXPECT_EQ(b[19], 3);  // profile
    EXPECT_EQ(b[20], 1);  // 83B
    EXPECT_EQ(b[21], 1);
    EXPECT_EQ(b[22], 2);
    EXPECT_EQ(b[23], 35);
    EXPECT_EQ(b[24], 1);
    EXPECT_EQ(b[25], 160);  // -20 + 180
    EXPECT_EQ(b[26], 1);
    EXPECT_EQ(b[27], 0);
    EXPECT_EQ(b[28], 1);
    EXPECT_EQ(b[29], 0);
    EXPECT_EQ(b[30], 0);
    EXPECT_EQ(b[31], 0x5A);
    EXPECT_EQ(b[32], 0x03);
    EXPECT_EQ(b[33], 0x04);
    EXPECT_EQ(b[34], 2);  // bottom follow
    for (std::size_t i = 35; i < 256; ++i) EXPECT_EQ(b[i], 0) << i;
}

TEST(EcFrame, DecodesHandBuiltBytes) {
    std::vector<std::uint8_t> b(256, 0);
    b[0] = 'E';
    b[1] = 'C';
    b[3] = 1;
    b[7] = 14;  // 300 m
    b[8] = 20;
    b[9] = 100;
    b[11] = 3;  // 120 deg
    b[12] = 3;  // narrow-mixed
    b[13] = 2;  // 120 beams
    b[14] = 10;
    b[17] = 0x3A;  // 0x3A98 = 15000 -> 1500.0 m/s
    b[18] = 0x98;
    b[19] = 4;
    b[20] = 2;
    b[23] = 90;
    b[25] = 255;  // +75 deg
    b[34] = 1;
    const auto d = DecodeEcFrame(b);
    ASSERT_TRUE(std::holds_alternative<EcFrame>(d));
    const EcFrame& f = std::get<EcFrame>(d);
    EXPECT_TRUE(f.external_control);
    EXPECT_FALSE(f.receive_only);
    EXPECT_EQ(f.range_m, 300);
    EXPECT_EQ(f.start_gain_db, 20);
    EXPECT_EQ(f.display_gain_pct, 100);
    EXPECT_FALSE(f.gain_equalisation);
    EXPECT_EQ(f.sector_deg, 120);
    EXPECT_EQ(f.beam_width, EcBeamWidth::kNarrowMixed);
    EXPECT_EQ(f.num_beams, 120);
    EXPECT_EQ(f.averaging, 10);
    EXPECT_DOUBLE_EQ(f.sound_velocity_mps, 1500.0);
    EXPECT_EQ(f.mode, EcMode::kBeamTest);
    EXPECT_EQ(f.output, EcOutput::k83F);
    EXPECT_FALSE(f.profile_points);
    EXPECT_EQ(f.profile_min_level_pct, 90);
    EXPECT_EQ(f.profile_tilt_deg, 75);
    EXPECT_EQ(f.profile_filter, EcProfileFilter::kMaxReturn);
}

TEST(EcFrame, RoundTrip) {
    const EcFrame f = SampleFrame();
    const auto d = DecodeEcFrame(EncodeEcFrame(f));
    ASSERT_TRUE(std::holds_alternative<EcFrame>(d));
    const EcFrame& g = std::get<EcFrame>(d);
    EXPECT_EQ(g.external_control, f.external_control);
    EXPECT_EQ(g.receive_only, f.receive_only);
    EXPECT_EQ(g.range_m, f.range_m);
    EXPECT_EQ(g.start_gain_db, f.start_gain_db);
    EXPECT_EQ(g.display_gain_pct, f.display_gain_pct);
    EXPECT_EQ(g.gain_equalisation, f.gain_equalisation);
    EXPECT_EQ(g.sector_deg, f.sector_deg);
    EXPECT_EQ(g.beam_width, f.beam_width);
    EXPECT_EQ(g.num_beams, f.num_beams);
    EXPECT_EQ(g.averaging, f.averaging);
    EXPECT_EQ(g.persistence_s, f.persistence_s);
    EXPECT_DOUBLE_EQ(g.sound_velocity_mps, 1487.3);
    EXPECT_EQ(g.mode, f.mode);
    EXPECT_EQ(g.output, f.output);
    EXPECT_EQ(g.profile_points, f.profile_points);
    EXPECT_EQ(g.profile_min_range_m, f.profile_min_range_m);
    EXPECT_EQ(g.profile_min_level_pct, f.profile_min_level_pct);
    EXPECT_EQ(g.transducer_up, f.transducer_up);
    EXPECT_EQ(g.profile_tilt_deg, f.profile_tilt_deg);
    EXPECT_EQ(g.roll_compensation, f.roll_compensation);
    EXPECT_EQ(g.record_837, f.record_837);
    EXPECT_EQ(g.record_83p, f.record_83p);
    EXPECT_EQ(g.control, f.control);
    EXPECT_EQ(g.trigger_delay, f.trigger_delay);
    EXPECT_EQ(g.profile_filter, f.profile_filter);
    EXPECT_EQ(EncodeEcFrame(g), EncodeEcFrame(f));
}

TEST(EcFrame, CodeTables) {
    const std::uint16_t ranges[] = {5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 250, 300};
    for (std::uint8_t code = 2; code <= 14; ++code) {
        EXPECT_EQ(EcRangeMetresFromCode(code), ranges[code - 2]);
        EXPECT_EQ(EcRangeCodeFromMetres(ranges[code - 2]), code);
        EcFrame f;
        f.range_m = ranges[code - 2];
        const auto b = EncodeEcFrame(f);
        ASSERT_EQ(b.size(), 256u);
        EXPECT_EQ(b[7], code);
        EXPECT_EQ(std::get<EcFrame>(DecodeEcFrame(b)).range_m, ranges[code - 2]);
    }
    EXPECT_FALSE(EcRangeMetresFromCode(0).has_value());
    EXPECT_FALSE(EcRangeMetresFromCode(1).has_value());
    EXPECT_FALSE(EcRangeMetresFromCode(15).has_value());
    EXPECT_FALSE(EcRangeCodeFromMetres(70).has_value());
    EXPECT_EQ(EcSectorDegFromCode(0), 30);
    EXPECT_EQ(EcSectorDegFromCode(3), 120);
    EXPECT_FALSE(EcSectorDegFromCode(4).has_value());
    EXPECT_EQ(EcSectorCodeFromDeg(60), 1);
    EXPECT_FALSE(EcSectorCodeFromDeg(45).has_value());
    EXPECT_EQ(EcBeamsFromCode(0), 480);
    EXPECT_EQ(EcBeamsFromCode(1), 240);
    EXPECT_EQ(EcBeamsFromCode(2), 120);
    EXPECT_FALSE(EcBeamsFromCode(3).has_value());
    EXPECT_EQ(EcBeamsCodeFromCount(120), 2);
    EXPECT_FALSE(EcBeamsCodeFromCount(256).has_value());
}

TEST(EcFrame, DecoderRejectsBadFrames) {
    const auto good = EncodeEcFrame(SampleFrame());
    const auto expect_error =
        [](std::vector<std::uint8_t> b, DecodeErrorKind kind, std::size_t offset) {
            const auto d = DecodeEcFrame(b);
            ASSERT_TRUE(std::holds_alternative<DecodeError>(d));
            EXPECT_EQ(std::get<DecodeError>(d).kind, kind);
            EXPECT_EQ(std::get<DecodeError>(d).offset, offset);
        };
    auto b = good;
    b.pop_back();
    expect_error(b, DecodeErrorKind::kTruncated, 255);
    b = good;
    b.push_back(0);
    expect_error(b, DecodeErrorKind::kTrailingBytes, 256);
    b = good;
    b[1] = 'X';
    expect_error(b, DecodeErrorKind::kBadMarker, 0);
    const std::pair<std::size_t, std::uint8_t> bad_values[] = {{3, 2},
                                                               {4, 7},
                                                               {7, 1},
                                                               {7, 15},
                                                               {10, 2},
                                                               {11, 4},
                                                               {12, 4},
                                                               {13, 3},
                                                               {14, 11},
                                                               {19, 5},
                                                               {20, 3},
                                                               {21, 2},
                                                               {23, 101},
                                                               {24, 2},
                                                               {26, 2},
                                                               {28, 2},
                                                               {29, 2},
                                                               {34, 3}};
    for (const auto& [offset, value] : bad_values) {
        b = good;
        b[offset] = value;
        expect_error(b, DecodeErrorKind::kBadValue, offset);
    }
}

TEST(EcFrame, EncoderRejectsUnrepresentableValues) {
    EcFrame f;
    f.range_m = 70;
    EXPECT_TRUE(EncodeEcFrame(f).empty());
    f = EcFrame{};
    f.sector_deg = 45;
    EXPECT_TRUE(EncodeEcFrame(f).empty());
    f = EcFrame{};
    f.num_beams = 360;
    EXPECT_TRUE(EncodeEcFrame(f).empty());
    f = EcFrame{};
    f.sound_velocity_mps = 7000.0;
    EXPECT_TRUE(EncodeEcFrame(f).empty());
    f = EcFrame{};
    f.profile_tilt_deg = 76;
    EXPECT_TRUE(EncodeEcFrame(f).empty());
    f.profile_tilt_deg = -180;
    EXPECT_EQ(EncodeEcFrame(f)[25], 0);
}

}  // namespace
}  // namespace pitmap::protocol::deltat
