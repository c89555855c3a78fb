// SPDX-License-Identifier: MIT
// Decoded field values against the spec's worked examples (shared/specs/novatel_oem.md §3-§6)
// and against NovAtel's own ASCII conversion of a binary capture (GAVLab OneEach .GPS/.ASC).
#include "common/protocol/novatel/decoder.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <type_traits>
#include <utility>
#include <variant>

#include "common/gps_time.hpp"
#include "tests/protocol/novatel/test_util.hpp"

namespace pitmap::protocol::novatel {
namespace {

using testing::AsciiLine;
using testing::Bytes;
using testing::FrameAll;
using testing::FromHex;
using testing::FromText;
using testing::LongFrame;
using testing::ShortFrame;

DecodeResult DecodeOne(const Bytes& bytes) {
    const auto ev = FrameAll(bytes);
    EXPECT_EQ(ev.frames.size(), 1u);
    if (ev.frames.empty()) return Unsupported{};
    const auto& f = ev.frames[0];
    return Decode(Frame{f.kind, f.message_id, ByteSpan(f.bytes), f.offset});
}

// All decoded results of a capture file, in order.
std::vector<DecodeResult> DecodeFile(const std::string& name) {
    const auto ev = FrameAll(testing::ReadFile(name));
    std::vector<DecodeResult> out;
    for (const auto& f : ev.frames) {
        out.push_back(Decode(Frame{f.kind, f.message_id, ByteSpan(f.bytes), f.offset}));
    }
    return out;
}

template <typename T>
std::vector<T> All(const std::vector<DecodeResult>& results) {
    std::vector<T> out;
    for (const auto& r : results) {
        if (const auto* m = std::get_if<T>(&r)) out.push_back(*m);
    }
    return out;
}

TEST(NovatelDecoder, TimeBWorkedExample) {
    const auto r =
        DecodeOne(FromHex("aa44121c 65000040 2c000000 a2b41608 60a65e0e 20400002 24990080"
                          "00000000 3fdc41c9af91123e 52580931837b133e ce550a00000032c0"
                          "e3070000 09 0a 12 39 b0b30000 01000000 46ed42b9"));
    ASSERT_TRUE(std::holds_alternative<Time>(r));
    const auto& t = std::get<Time>(r);
    EXPECT_EQ(t.header.kind, HeaderKind::kLongBinary);
    EXPECT_EQ(t.header.message_id, 101);
    EXPECT_EQ(t.header.port_address, 0x40);
    EXPECT_FALSE(t.header.is_response);
    EXPECT_FLOAT_EQ(t.header.idle_percent(), 81.0f);
    EXPECT_EQ(t.header.time_status, TimeStatus::kFineSteering);
    EXPECT_EQ(t.header.gps_week, 2070);
    EXPECT_EQ(t.header.gps_ms, 241084000u);
    EXPECT_EQ(t.header.receiver_status, 0x02004020u);
    EXPECT_EQ(t.header.reserved, 0x9924);
    EXPECT_EQ(t.header.sw_build, 0x8000);
    EXPECT_EQ(t.utime_gps(), GpsUtimeFromWeekMs(2070, 241084000));
    EXPECT_EQ(t.clock_model_status, ClockModelStatus::kValid);
    EXPECT_NEAR(t.receiver_clock_offset_s, 1.08e-9, 0.01e-9);
    EXPECT_NEAR(t.utc_offset_s, -18.0, 1e-6);
    EXPECT_EQ(t.utc_year, 2019u);
    EXPECT_EQ(t.utc_month, 9);
    EXPECT_EQ(t.utc_day, 10);
    EXPECT_EQ(t.utc_hour, 18);
    EXPECT_EQ(t.utc_minute, 57);
    EXPECT_EQ(t.utc_ms, 46000u);
    EXPECT_EQ(t.utc_status, UtcStatus::kValid);
}

TEST(NovatelDecoder, BinaryResponseWorkedExample) {
    const auto r = DecodeOne(FromHex(
        "aa44121c 0100 80 20 0600 0000 ff b4 9706 1d3dfd18 00000000 ffff 0000 01000000 4f4b "
        "ea247892"));
    ASSERT_TRUE(std::holds_alternative<Response>(r));
    const auto& m = std::get<Response>(r);
    EXPECT_EQ(m.form, Response::Form::kBinary);
    EXPECT_EQ(m.header.message_id, 1);
    EXPECT_TRUE(m.header.is_response);
    EXPECT_EQ(m.header.port_address, 0x20);
    EXPECT_EQ(m.response_id, 1);
    EXPECT_EQ(m.text, "OK");
    EXPECT_TRUE(m.ok());
}

TEST(NovatelDecoder, AsciiBestPosVector) {
    const auto r = DecodeOne(FromText(
        "#BESTPOSA,COM1,0,83.5,FINESTEERING,1419,336148.000,02000040,6145,2724;SOL_COMPUTED,"
        "SINGLE,51.11636418888,-114.03832502118,1064.9520,-16.2712,WGS84,1.6961,1.3636,3.6449,"
        "\"\",0.000,0.000,8,8,8,8,0,0,0,06,0,03*f181ad10\r\n"));
    ASSERT_TRUE(std::holds_alternative<BestPos>(r));
    const auto& m = std::get<BestPos>(r);
    EXPECT_EQ(m.header.kind, HeaderKind::kAscii);
    EXPECT_EQ(m.header.message_id, 42);
    EXPECT_EQ(m.header.port_name, "COM1");
    EXPECT_EQ(m.header.port_address, 0x20);
    EXPECT_EQ(m.header.idle_time, 167);
    EXPECT_EQ(m.header.time_status, TimeStatus::kFineSteering);
    EXPECT_EQ(m.header.gps_week, 1419);
    EXPECT_EQ(m.header.gps_ms, 336148000u);
    EXPECT_EQ(m.header.receiver_status, 0x02000040u);
    EXPECT_EQ(m.header.reserved, 0x6145);
    EXPECT_EQ(m.header.sw_build, 2724);
    EXPECT_EQ(m.solution_status, SolutionStatus::kSolComputed);
    EXPECT_EQ(m.position_type, PositionType::kSingle);
    EXPECT_DOUBLE_EQ(m.latitude_deg, 51.11636418888);
    EXPECT_DOUBLE_EQ(m.longitude_deg, -114.03832502118);
    EXPECT_DOUBLE_EQ(m.height_msl_m, 1064.9520);
    EXPECT_FLOAT_EQ(m.undulation_m, -16.2712f);
    EXPECT_EQ(m.datum_id, 61u);
    EXPECT_FLOAT_EQ(m.latitude_stddev_m, 1.6961f);
    EXPECT_FLOAT_EQ(m.height_stddev_m, 3.6449f);
    EXPECT_EQ(m.base_station_id, "");
    EXPECT_EQ(m.num_svs_tracked, 8);
    EXPECT_EQ(m.num_svs_multifreq_in_solution, 8);
    EXPECT_EQ(m.extended_solution_status, 0x06);
    EXPECT_EQ(m.gps_glonass_signal_mask, 0x03);
}

TEST(NovatelDecoder, OneEachBinaryMatchesAsciiTwin) {
    const auto bin = DecodeFile("gavlab_OneEach.GPS");
    const auto asc = DecodeFile("gavlab_OneEach.ASC");
    const auto bp = All<BestPos>(bin);
    const auto ap = All<BestPos>(asc);
    ASSERT_EQ(bp.size(), 1u);
    ASSERT_EQ(ap.size(), 1u);
    const BestPos& b = bp[0];
    const BestPos& a = ap[0];
    EXPECT_EQ(b.header.message_type, 0x02);  // OEMV reserved source bits, masked (§9 item 7)
    EXPECT_FALSE(b.header.is_response);
    EXPECT_EQ(b.header.gps_week, a.header.gps_week);
    EXPECT_EQ(b.header.gps_ms, a.header.gps_ms);
    EXPECT_EQ(b.header.time_status, a.header.time_status);
    EXPECT_EQ(b.header.idle_time, a.header.idle_time);
    EXPECT_EQ(b.header.reserved, a.header.reserved);
    EXPECT_EQ(b.header.sw_build, a.header.sw_build);
    EXPECT_EQ(b.header.receiver_status, a.header.receiver_status);
    EXPECT_EQ(b.solution_status, a.solution_status);
    EXPECT_EQ(b.position_type, a.position_type);
    EXPECT_NEAR(b.latitude_deg, a.latitude_deg, 0.6e-11);
    EXPECT_NEAR(b.longitude_deg, a.longitude_deg, 0.6e-11);
    EXPECT_NEAR(b.height_msl_m, a.height_msl_m, 0.6e-4);
    EXPECT_NEAR(b.undulation_m, a.undulation_m, 0.6e-4);
    EXPECT_EQ(b.datum_id, a.datum_id);
    EXPECT_NEAR(b.latitude_stddev_m, a.latitude_stddev_m, 0.6e-4);
    EXPECT_NEAR(b.longitude_stddev_m, a.longitude_stddev_m, 0.6e-4);
    EXPECT_NEAR(b.height_stddev_m, a.height_stddev_m, 0.6e-4);
    EXPECT_EQ(b.base_station_id, a.base_station_id);
    EXPECT_EQ(b.num_svs_tracked, a.num_svs_tracked);
    EXPECT_EQ(b.num_svs_in_solution, a.num_svs_in_solution);
    EXPECT_EQ(b.extended_solution_status, a.extended_solution_status);
    EXPECT_EQ(b.gps_glonass_signal_mask, a.gps_glonass_signal_mask);
    EXPECT_DOUBLE_EQ(a.latitude_deg, 32.59535912622);
    EXPECT_DOUBLE_EQ(a.longitude_deg, -85.29567789741);

    const auto bv = All<BestVel>(bin);
    const auto av = All<BestVel>(asc);
    ASSERT_EQ(bv.size(), 1u);
    ASSERT_EQ(av.size(), 1u);
    EXPECT_EQ(bv[0].header.gps_ms, av[0].header.gps_ms);
    EXPECT_EQ(bv[0].solution_status, av[0].solution_status);
    EXPECT_EQ(bv[0].velocity_type, PositionType::kDopplerVelocity);
    EXPECT_EQ(bv[0].velocity_type, av[0].velocity_type);
    EXPECT_NEAR(bv[0].latency_s, av[0].latency_s, 0.6e-3);
    EXPECT_NEAR(bv[0].differential_age_s, av[0].differential_age_s, 0.6e-3);
    EXPECT_NEAR(bv[0].horizontal_speed_mps, av[0].horizontal_speed_mps, 0.6e-4);
    EXPECT_NEAR(bv[0].track_over_ground_deg, av[0].track_over_ground_deg, 0.6e-6);
    EXPECT_NEAR(bv[0].vertical_speed_mps, av[0].vertical_speed_mps, 0.6e-4);
    EXPECT_DOUBLE_EQ(av[0].track_over_ground_deg, 19.451947);
    // Time of validity = header time - latency (§8).
    EXPECT_EQ(bv[0].utime_gps(), bv[0].header.utime_gps() - 150000);

    // Responses: 7 "#SENDR" (ASCII) and the abbreviated <OK / <ERROR lines; 14 prompts.
    const auto resp = All<Response>(bin);
    std::size_t ascii = 0, ok = 0, errors = 0;
    for (const auto& r : resp) {
        ascii += r.form == Response::Form::kAscii ? 1 : 0;
        ok += r.ok() ? 1 : 0;
        errors += r.text.rfind("ERROR:", 0) == 0 ? 1 : 0;
    }
    EXPECT_EQ(ascii, 7u);
    EXPECT_EQ(errors, 2u);
    EXPECT_EQ(All<PortPrompt>(bin).size(), 14u);
    EXPECT_EQ(All<PortPrompt>(bin)[0].port, "COM1");
}

TEST(NovatelDecoder, InsBodyTimeWinsOverHeader) {
    // §3: header 600118378 ms, body 600118.378036 s (oem7 driver ins2.gps, IMURATECORRIMUS).
    const auto ins2 = DecodeFile("oem7drv_ins2.gps");
    const auto imu = All<CorrImuData>(ins2);
    ASSERT_EQ(imu.size(), 766u);
    const CorrImuData* hit = nullptr;
    for (const auto& p : imu) {
        if (p.header.gps_ms == 600118378u) hit = &p;
    }
    ASSERT_NE(hit, nullptr);
    EXPECT_EQ(hit->header.kind, HeaderKind::kShortBinary);
    EXPECT_EQ(hit->header.message_id, 1362);
    EXPECT_EQ(hit->gps_week, 2100u);
    EXPECT_NEAR(hit->gps_seconds, 600118.378036, 1e-6);
    EXPECT_EQ(hit->utime_gps(), GpsUtimeFromWeekTow(2100, hit->gps_seconds));
    EXPECT_EQ(hit->utime_gps() - hit->header.utime_gps(), 36);  // microseconds
    const auto pvas = All<InsPva>(ins2);
    ASSERT_EQ(pvas.size(), 62u);
    EXPECT_EQ(pvas[0].header.message_id, 508);
    EXPECT_EQ(pvas[0].gps_week, pvas[0].header.gps_week);
    EXPECT_GE(pvas[0].azimuth_deg, 0.0);
    EXPECT_LT(pvas[0].azimuth_deg, 360.0);
    const auto cfg = All<InsConfig>(DecodeFile("oem7drv_ins1.gps"));
    ASSERT_EQ(cfg.size(), 2u);
    EXPECT_EQ(cfg[0].imu_type, 41u);  // Epson G320N
    const auto corr = All<CorrImuS>(DecodeFile("oem7drv_ins1.gps"));
    ASSERT_EQ(corr.size(), 10u);
    EXPECT_EQ(corr[0].imu_data_count, 22u);  // §6.7: first output after LOG is partial
    EXPECT_EQ(corr[1].imu_data_count, 125u);
}

TEST(NovatelDecoder, RealCaptureTypes) {
    EXPECT_EQ(All<Heading2>(DecodeFile("oem7drv_align.gps")).size(), 12u);
    const auto rx = All<RxStatus>(DecodeFile("oem7drv_rxstatus.gps"));
    ASSERT_EQ(rx.size(), 3u);
    EXPECT_GE(rx[0].num_groups, 4u);
    EXPECT_EQ(rx[0].num_groups, std::min<std::uint32_t>(rx[0].num_status_codes, 8));
    const auto parsing = DecodeFile("gavlab_ParsingData.GPS");
    std::size_t binary_responses = 0;
    for (const auto& r : All<Response>(parsing)) {
        binary_responses += r.form == Response::Form::kBinary ? 1 : 0;
    }
    EXPECT_EQ(binary_responses, 23u);
    const auto rt = DecodeFile("rtklib_oemv_200911218.gps");
    const auto pos = All<BestPos>(rt);
    ASSERT_EQ(pos.size(), 49u);
    EXPECT_EQ(pos[0].header.port_address & 0xE0, 0xA0);  // USB1
}

TEST(NovatelDecoder, RuntUnknownIdAndUnknownEnum) {
    const auto runt = DecodeOne(LongFrame(42, Bytes(71, 0)));
    ASSERT_TRUE(std::holds_alternative<DecodeError>(runt));
    EXPECT_EQ(std::get<DecodeError>(runt).kind, DecodeErrorKind::kRunt);
    EXPECT_EQ(std::get<DecodeError>(runt).offset, 28u + 71u);

    const auto unknown = DecodeOne(LongFrame(4321, Bytes(10, 0)));
    ASSERT_TRUE(std::holds_alternative<Unsupported>(unknown));
    EXPECT_EQ(std::get<Unsupported>(unknown).message_id, 4321);

    Bytes body(72, 0);
    body[0] = 99;   // solution status 99: not in the table
    body[4] = 250;  // position type 250
    const auto r = DecodeOne(LongFrame(42, body, 0x01));
    ASSERT_TRUE(std::holds_alternative<BestPos>(r));
    EXPECT_EQ(static_cast<std::uint32_t>(std::get<BestPos>(r).solution_status), 99u);
    EXPECT_EQ(ToString(std::get<BestPos>(r).solution_status), "");
    EXPECT_EQ(static_cast<std::uint32_t>(std::get<BestPos>(r).position_type), 250u);
    EXPECT_EQ(std::get<BestPos>(r).header.measurement_source(), 1);

    // Longer bodies (newer firmware) decode; the extra bytes are ignored.
    EXPECT_TRUE(std::holds_alternative<BestPos>(DecodeOne(LongFrame(42, Bytes(80, 0)))));
}

TEST(NovatelDecoder, RawImuAxisOrderAndScale) {
    Bytes body(40, 0);
    body[0] = 0x01;  // IMU info: error bit
    body[1] = 32;    // STIM300
    body[2] = 0x16;  // week 2070
    body[3] = 0x08;
    const std::int32_t counts[6] = {100, 200, 300, -400, -500, 600};  // Z, -Y, X, Z, -Y, X
    for (int i = 0; i < 6; ++i) {
        const auto u = static_cast<std::uint32_t>(counts[i]);
        for (int k = 0; k < 4; ++k) body[16 + 4 * i + k] = static_cast<std::uint8_t>(u >> (8 * k));
    }
    const auto r = DecodeOne(ShortFrame(1462, body));
    ASSERT_TRUE(std::holds_alternative<RawImu>(r));
    const auto& m = std::get<RawImu>(r);
    EXPECT_EQ(m.imu_info, 1);
    EXPECT_EQ(m.imu_type, 32);
    EXPECT_EQ(m.gps_week, 2070u);
    EXPECT_EQ(m.accel_counts, (std::array<std::int64_t, 3>{300, -200, 100}));
    EXPECT_EQ(m.gyro_counts, (std::array<std::int64_t, 3>{600, 500, -400}));
    const auto scale = ImuScaleFor(m.imu_type);
    ASSERT_TRUE(scale.has_value());
    EXPECT_DOUBLE_EQ(scale->nominal_rate_hz, 125.0);
    const auto inc = ScaleRawImu(m, *scale, 125.0);
    EXPECT_DOUBLE_EQ(inc.delta_velocity_mps[0], 300.0 * std::ldexp(1.0, -22));
    EXPECT_NEAR(
        inc.angular_rate_radps[2], -400.0 * std::ldexp(1.0, -21) * M_PI / 180.0 * 125.0, 1e-15);
    EXPECT_FALSE(ImuScaleFor(9999).has_value());
    // HG1700-AG58: ft/s counts.
    EXPECT_DOUBLE_EQ(ImuScaleFor(11)->accel_mps_per_count, std::ldexp(1.0, -27) * 0.3048);
    // Epson G320N at rest would read ~1 g: the scale depends on the rate.
    EXPECT_DOUBLE_EQ(ImuScaleFor(41, 125.0)->accel_mps_per_count,
                     0.2 / 65536.0 * 9.80665e-3 / 125.0);

    // RAWIMU (268): ULong week, no type.
    Bytes raw(40, 0);
    raw[0] = 0x16;
    raw[1] = 0x08;
    const auto r2 = DecodeOne(LongFrame(268, raw));
    ASSERT_TRUE(std::holds_alternative<RawImu>(r2));
    EXPECT_EQ(std::get<RawImu>(r2).imu_type, -1);
    EXPECT_EQ(std::get<RawImu>(r2).gps_week, 2070u);
}

TEST(NovatelDecoder, TextFrames) {
    const auto ok = DecodeOne(FromText("<OK\r\n"));
    ASSERT_TRUE(std::holds_alternative<Response>(ok));
    EXPECT_TRUE(std::get<Response>(ok).ok());
    EXPECT_EQ(std::get<Response>(ok).form, Response::Form::kAbbreviated);
    const auto err = DecodeOne(FromText("<ERROR:Invalid Message. Field = BESTGPSB\r\n"));
    ASSERT_TRUE(std::holds_alternative<Response>(err));
    EXPECT_FALSE(std::get<Response>(err).ok());
    EXPECT_EQ(std::get<Response>(err).text, "ERROR:Invalid Message. Field = BESTGPSB");
    const auto prompt = DecodeOne(FromText("[COM1_30]"));
    ASSERT_TRUE(std::holds_alternative<PortPrompt>(prompt));
    EXPECT_EQ(std::get<PortPrompt>(prompt).port, "COM1_30");
    const auto ascii_resp = DecodeOne(AsciiLine('#', "LOGR,COM1,0,0.0,UNKNOWN,0,0.000,0,0,0;OK"));
    ASSERT_TRUE(std::holds_alternative<Response>(ascii_resp));
    EXPECT_EQ(std::get<Response>(ascii_resp).command_name, "LOG");
    EXPECT_EQ(std::get<Response>(ascii_resp).header.message_id, 1);
    EXPECT_TRUE(std::get<Response>(ascii_resp).ok());
    const auto abbrev_log = DecodeOne(FromText("<     SOL_COMPUTED SINGLE\r\n"));
    EXPECT_TRUE(std::holds_alternative<Unsupported>(abbrev_log));
    const auto nmea = DecodeOne(FromText("$GPGGA,1*4B\r\n"));
    EXPECT_TRUE(std::holds_alternative<Unsupported>(nmea));
}

TEST(NovatelDecoder, AsciiShortHeaderAndBadFields) {
    const auto r = DecodeOne(
        AsciiLine('%',
                  "INSPVASA,2209,490712.000;2209,490712.002135700,51.116680071,-114.037929194,"
                  "515.286704183,277.896368884,84.915188605,-8.488207941,0.759619515,-2.892414901,"
                  "6.179554750,INS_SOLUTION_GOOD"));
    ASSERT_TRUE(std::holds_alternative<InsPva>(r));
    const auto& m = std::get<InsPva>(r);
    EXPECT_EQ(m.header.kind, HeaderKind::kShortAscii);
    EXPECT_EQ(m.header.message_id, 508);
    EXPECT_EQ(m.header.gps_ms, 490712000u);
    EXPECT_DOUBLE_EQ(m.gps_seconds, 490712.002135700);
    EXPECT_DOUBLE_EQ(m.azimuth_deg, 6.179554750);
    EXPECT_EQ(m.ins_status, InsStatus::kSolutionGood);

    const auto bad = DecodeOne(
        AsciiLine('#',
                  "BESTVELA,COM1,0,62.5,FINESTEERING,1687,419959.000,00000000,827b,3153;"
                  "SOL_COMPUTED,DOPPLER_VELOCITY,0.150,abc,0.0239,19.451947,-0.0290,0.0"));
    ASSERT_TRUE(std::holds_alternative<DecodeError>(bad));
    EXPECT_EQ(std::get<DecodeError>(bad).kind, DecodeErrorKind::kBadField);
    const auto missing =
        DecodeOne(AsciiLine('#',
                            "BESTVELA,COM1,0,62.5,FINESTEERING,1687,419959.000,00000000,827b,3153;"
                            "SOL_COMPUTED,DOPPLER_VELOCITY,0.150"));
    ASSERT_TRUE(std::holds_alternative<DecodeError>(missing));
    const auto bad_header = DecodeOne(AsciiLine('#', "BESTVELA,COM1,x;SOL_COMPUTED"));
    ASSERT_TRUE(std::holds_alternative<DecodeError>(bad_header));
    EXPECT_EQ(std::get<DecodeError>(bad_header).kind, DecodeErrorKind::kBadHeader);
}

// The decoder's result and Message share one list of message structs (messages.hpp): every
// Message alternative is the DecodeResult alternative of the same index, and ToMessage keeps it.
template <std::size_t... I>
void ExpectToMessageKeepsEveryAlternative(std::index_sequence<I...>) {
    (
        [] {
            using T = std::variant_alternative_t<I, Message>;
            static_assert(std::is_same_v<T, std::variant_alternative_t<I, DecodeResult>>);
            const Message m = ToMessage(DecodeResult(std::in_place_index<I>, T{}));
            EXPECT_EQ(m.index(), I);
        }(),
        ...);
}

TEST(NovatelDecoder, ResultListsEveryMessageThenTheTwoOtherOutcomes) {
    static_assert(std::variant_size_v<DecodeResult> == std::variant_size_v<Message> + 2);
    static_assert(
        std::is_same_v<std::variant_alternative_t<std::variant_size_v<Message>, DecodeResult>,
                       Unsupported>);
    static_assert(
        std::is_same_v<std::variant_alternative_t<std::variant_size_v<Message> + 1, DecodeResult>,
                       DecodeError>);
    ExpectToMessageKeepsEveryAlternative(std::make_index_sequence<std::variant_size_v<Message>>{});
    EXPECT_FALSE(IsMessage(DecodeResult(Unsupported{})));
    EXPECT_FALSE(IsMessage(DecodeResult(DecodeError{})));
}

}  // namespace
}  // namespace pitmap::protocol::novatel
