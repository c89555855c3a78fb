// SPDX-License-Identifier: MIT
// Wire checks before lcm-gen's decode(): every message the project defines passes when lcm
// encoded it, and damaged counts (negative, huge, a string length of 0) fail with a reason
// instead of throwing or allocating what they claim.
#include "lcmtypes/log/lcm_wire.hpp"

#include <gtest/gtest.h>

#include <pitmap/channel_status_t.hpp>
#include <pitmap/daemon_status_t.hpp>
#include <pitmap/ins_pva_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>
#include <pitmap/raw_bytes_t.hpp>
#include <random>
#include <vector>

namespace pitmap::lcmlog {
namespace {

using Bytes = std::vector<std::uint8_t>;

template <class T>
Bytes Encode(const T& msg) {
    Bytes b(static_cast<std::size_t>(msg.getEncodedSize()));
    EXPECT_EQ(msg.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
    return b;
}

void PutBe32(Bytes& b, std::size_t at, std::int32_t v) {
    const auto u = static_cast<std::uint32_t>(v);
    for (int i = 0; i < 4; ++i)
        b[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(u >> (24 - 8 * i));
}
void PutBe16(Bytes& b, std::size_t at, std::int16_t v) {
    const auto u = static_cast<std::uint16_t>(v);
    b[at] = static_cast<std::uint8_t>(u >> 8);
    b[at + 1] = static_cast<std::uint8_t>(u);
}

pitmap::multibeam_ping_t Ping(int beams, bool intensities) {
    pitmap::multibeam_ping_t m{};
    m.utime_gps = 1'400'000'000'000'000;
    m.num_beams = static_cast<std::int16_t>(beams);
    m.range_counts.assign(static_cast<std::size_t>(beams), 1234);
    m.num_intensities = static_cast<std::int16_t>(intensities ? beams : 0);
    m.intensities.assign(static_cast<std::size_t>(m.num_intensities), 7);
    return m;
}

pitmap::raw_bytes_t Raw(std::size_t n) {
    pitmap::raw_bytes_t r{};
    r.source = "novatel_com1";
    r.protocol = "novatel";
    r.peer = "/dev/ttyUSB0";
    r.num_bytes = static_cast<std::int32_t>(n);
    r.data.assign(n, 0xAA);
    return r;
}

TEST(LcmWire, SchemaHasEveryProjectType) {
    for (const char* name : {"multibeam_ping_t",
                             "raw_bytes_t",
                             "ins_pva_t",
                             "ins_stddev_t",
                             "gps_time_t",
                             "channel_status_t",
                             "daemon_status_t",
                             "novatel_header_t",
                             "clock_sync_t"}) {
        EXPECT_NE(Schema::Pitmap().Find(name), nullptr) << name;
    }
}

TEST(LcmWire, WellFormedMessagesPass) {
    for (int beams : {0, 1, 120, 256}) {
        for (bool in : {false, true}) {
            const auto m = Ping(beams, in);
            const Bytes b = Encode(m);
            pitmap::multibeam_ping_t out;
            std::string why;
            EXPECT_TRUE(DecodeChecked(out, b.data(), b.size(), &why)) << beams << ": " << why;
            EXPECT_EQ(out.range_counts.size(), static_cast<std::size_t>(beams));
        }
    }
    for (std::size_t n : {0u, 1u, 4096u}) {
        const Bytes b = Encode(Raw(n));
        pitmap::raw_bytes_t out;
        EXPECT_TRUE(DecodeChecked(out, b.data(), b.size()));
        EXPECT_EQ(out.data.size(), n);
    }
    // Nested structs (daemon_status_t holds channel_status_t's) and string arrays.
    pitmap::daemon_status_t d{};
    const Bytes db = Encode(d);
    EXPECT_EQ(Schema::Pitmap().Check("daemon_status_t", db.data(), db.size()), "");
}

TEST(LcmWire, NegativeBeamCountFailsWithoutThrowing) {
    const auto m = Ping(120, false);
    Bytes b = Encode(m);
    // num_beams sits before range_counts[120] and num_intensities (int16) at the end.
    const std::size_t at = b.size() - 2 - 4 * 120 - 2;
    PutBe16(b, at, -1);
    pitmap::multibeam_ping_t out;
    std::string why;
    EXPECT_FALSE(DecodeChecked(out, b.data(), b.size(), &why));
    EXPECT_NE(why.find("num_beams = -1"), std::string::npos) << why;
    // lcm-gen's own decode throws here: the reason for the check.
    EXPECT_ANY_THROW(out.decode(b.data(), 0, static_cast<int>(b.size())));
}

TEST(LcmWire, RawByteCountsNegativeOrHugeFail) {
    for (const std::int32_t bad : {-5, 0x7fffffff, 4097, 4095}) {
        Bytes b = Encode(Raw(4096));
        PutBe32(b, b.size() - 4096 - 4, bad);
        pitmap::raw_bytes_t out;
        std::string why;
        EXPECT_FALSE(DecodeChecked(out, b.data(), b.size(), &why)) << bad;
        EXPECT_FALSE(why.empty());
        EXPECT_LT(out.data.capacity(), 8192u) << "allocated what the count claimed";
    }
}

TEST(LcmWire, StringLengthZeroOrNegativeFails) {
    for (const std::int32_t bad : {0, -1, -100000, 1 << 30}) {
        Bytes b = Encode(Raw(16));
        // source: after the fingerprint, utime, utime_gps and gps_time_valid.
        PutBe32(b, 8 + 8 + 8 + 1, bad);
        pitmap::raw_bytes_t out;
        EXPECT_FALSE(DecodeChecked(out, b.data(), b.size())) << bad;
    }
}

TEST(LcmWire, OtherTypeAndTruncationsFail) {
    const Bytes ping = Encode(Ping(64, true));
    pitmap::raw_bytes_t raw;
    EXPECT_FALSE(DecodeChecked(raw, ping.data(), ping.size()));
    pitmap::multibeam_ping_t out;
    for (std::size_t n = 0; n < ping.size(); n += 7) {
        EXPECT_FALSE(DecodeChecked(out, ping.data(), n)) << n;
    }
    Bytes longer = ping;
    longer.push_back(0);
    EXPECT_FALSE(DecodeChecked(out, longer.data(), longer.size()));
}

TEST(LcmWire, RandomDamageNeverThrowsOrOverAllocates) {
    const Bytes clean = Encode(Ping(200, true));
    std::mt19937 rng(7);
    for (int round = 0; round < 20000; ++round) {
        Bytes b = clean;
        for (int k = 0; k < 3; ++k)
            b[8 + rng() % (b.size() - 8)] = static_cast<std::uint8_t>(rng());
        pitmap::multibeam_ping_t out;
        if (DecodeChecked(out, b.data(), b.size())) {
            EXPECT_LE(out.range_counts.size() * 4 + out.intensities.size() * 4, b.size());
        }
    }
}

}  // namespace
}  // namespace pitmap::lcmlog
