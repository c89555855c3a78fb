// SPDX-License-Identifier: MIT
// The bounded LCM log reader: garbage, impossible headers, a truncated last event, damaged
// data lengths and damaged sync words are counted and resynchronised, and an event is never
// allowed to swallow the events behind it.
#include "lcmtypes/log/lcm_log_reader.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace pitmap::lcmlog {
namespace {

using Bytes = std::vector<std::uint8_t>;

void PutBe(Bytes& b, std::uint64_t v, int n) {
    for (int i = n - 1; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// One event whose data bytes encode its number (so a returned event can be checked intact).
Bytes Event(std::int64_t num, const std::string& ch, std::size_t len) {
    Bytes b;
    PutBe(b, kLcmSyncWord, 4);
    PutBe(b, static_cast<std::uint64_t>(num), 8);
    PutBe(b, 1'700'000'000'000'000ull + static_cast<std::uint64_t>(num), 8);
    PutBe(b, ch.size(), 4);
    PutBe(b, len, 4);
    b.insert(b.end(), ch.begin(), ch.end());
    for (std::size_t i = 0; i < len; ++i) b.push_back(static_cast<std::uint8_t>(num * 31 + i));
    return b;
}

bool Intact(const LcmEvent& ev, std::size_t len) {
    if (ev.data.size() != len) return false;
    for (std::size_t i = 0; i < len; ++i) {
        if (ev.data[i] !=
            static_cast<std::uint8_t>(ev.eventnum * 31 + static_cast<std::int64_t>(i)))
            return false;
    }
    return true;
}

std::string WriteFile(const std::string& name, const Bytes& b) {
    const std::string path = ::testing::TempDir() + "/" + name;
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    return path;
}

std::size_t LenOf(std::int64_t num) {
    return 50 + static_cast<std::size_t>(num * 7919 % 4000);
}

// A log of n events of 50..4050 bytes on two channels; offsets of each event.
Bytes MakeLog(int n, std::vector<std::size_t>* offsets = nullptr) {
    Bytes b;
    for (int i = 0; i < n; ++i) {
        if (offsets) offsets->push_back(b.size());
        const Bytes e = Event(i, i % 3 ? "MULTIBEAM_PING_DELTAT" : "RAW_NOVATEL_COM1", LenOf(i));
        b.insert(b.end(), e.begin(), e.end());
    }
    return b;
}

TEST(LcmLogReader, CountsCorruptAndTruncatedEvents) {
    Bytes b;
    for (int i = 0; i < 3; ++i) {
        auto e = Event(i, "CH_A", 10);
        b.insert(b.end(), e.begin(), e.end());
    }
    b.insert(b.end(), {1, 2, 3, 4, 5});  // garbage between events
    auto bad = Event(3, "CH_B", 4);
    bad[20] = 0x7F;  // channel length 2 GB: corrupt header
    b.insert(b.end(), bad.begin(), bad.end());
    auto ok = Event(4, "CH_A", 10);
    b.insert(b.end(), ok.begin(), ok.end());
    auto cut = Event(5, "CH_A", 100);
    cut.resize(60);  // power cut
    b.insert(b.end(), cut.begin(), cut.end());
    auto reader = LcmLogReader::Open(WriteFile("corrupt.lcmlog", b));
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    LcmEvent ev;
    int n = 0;
    while ((*reader)->Next(ev)) {
        EXPECT_EQ(ev.channel, "CH_A");
        EXPECT_TRUE(Intact(ev, 10));
        ++n;
    }
    EXPECT_EQ(n, 4);
    EXPECT_EQ((*reader)->counts().corrupt_headers, 1);
    EXPECT_EQ((*reader)->counts().truncated_events, 1);
    EXPECT_GT((*reader)->counts().resync_bytes, 0);
}

TEST(LcmLogReader, MissingFileIsAnErrorNamingIt) {
    auto r = LcmLogReader::Open(::testing::TempDir() + "/nope.lcmlog");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("nope.lcmlog"), std::string::npos);
}

TEST(LcmLogReader, EmptyFileHasNoEvents) {
    auto r = LcmLogReader::Open(WriteFile("empty.lcmlog", {}));
    ASSERT_TRUE(r.ok());
    LcmEvent ev;
    EXPECT_FALSE((*r)->Next(ev));
    EXPECT_EQ((*r)->counts().events, 0);
}

// A data length that grew (here by 9.8 MB, as in the field) must not swallow the events after
// it: the length is trusted only when the next sync word is where it says.
TEST(LcmLogReader, DamagedDataLengthIsRepairedNotTrusted) {
    std::vector<std::size_t> at;
    Bytes b = MakeLog(200, &at);
    for (const int victim : {50, 120}) {
        const std::size_t len_field = at[static_cast<std::size_t>(victim)] + 24;
        b[len_field] = 0x00;
        b[len_field + 1] = 0x95;  // 0x0095xxxx: ~9.8 MB
    }
    auto reader = LcmLogReader::Open(WriteFile("longlen.lcmlog", b));
    ASSERT_TRUE(reader.ok());
    LcmEvent ev;
    int intact = 0;
    int total = 0;
    while ((*reader)->Next(ev)) {
        ++total;
        if (Intact(ev, LenOf(ev.eventnum))) ++intact;
    }
    // Only the length was hit: both events are repaired exactly, nothing is lost.
    EXPECT_EQ(total, 200);
    EXPECT_EQ(intact, 200);
    EXPECT_EQ((*reader)->counts().length_repairs, 2);
}

TEST(LcmLogReader, ShrunkDataLengthResynchronises) {
    std::vector<std::size_t> at;
    Bytes b = MakeLog(50, &at);
    b[at[10] + 27] = 3;  // low byte of event 10's length
    auto reader = LcmLogReader::Open(WriteFile("shortlen.lcmlog", b));
    ASSERT_TRUE(reader.ok());
    LcmEvent ev;
    int intact = 0;
    while ((*reader)->Next(ev)) intact += Intact(ev, LenOf(ev.eventnum)) ? 1 : 0;
    EXPECT_EQ(intact, 49);  // event 10 cannot be known; all the others are
    EXPECT_GT((*reader)->counts().resync_bytes, 0);
}

TEST(LcmLogReader, DamagedSyncWordLosesOnlyItsEvent) {
    std::vector<std::size_t> at;
    Bytes b = MakeLog(50, &at);
    b[at[20] + 1] ^= 0xFF;
    auto reader = LcmLogReader::Open(WriteFile("sync.lcmlog", b));
    ASSERT_TRUE(reader.ok());
    LcmEvent ev;
    std::vector<std::int64_t> nums;
    while ((*reader)->Next(ev)) {
        EXPECT_TRUE(Intact(ev, LenOf(ev.eventnum))) << ev.eventnum;
        nums.push_back(ev.eventnum);
    }
    EXPECT_EQ(nums.size(), 49u);
    EXPECT_EQ(std::count(nums.begin(), nums.end(), 20), 0);
}

// Random bytes overwritten all over a log: every event whose own bytes were not hit comes back
// intact, and nothing is reported as an event that spans others.
TEST(LcmLogReader, RandomOverwritesLoseOnlyTheEventsHit) {
    std::vector<std::size_t> at;
    const Bytes clean = MakeLog(1200, &at);
    at.push_back(clean.size());
    for (std::uint32_t seed = 1; seed <= 10; ++seed) {
        Bytes b = clean;
        std::mt19937 rng(seed);
        std::vector<bool> hit(1200, false);
        for (int k = 0; k < 100; ++k) {
            const std::size_t pos = rng() % b.size();
            b[pos] = static_cast<std::uint8_t>(rng());
            const auto it = std::upper_bound(at.begin(), at.end(), pos);
            hit[static_cast<std::size_t>(it - at.begin() - 1)] = true;
        }
        auto reader = LcmLogReader::Open(WriteFile("random.lcmlog", b));
        ASSERT_TRUE(reader.ok());
        LcmEvent ev;
        std::vector<bool> got(1200, false);
        while ((*reader)->Next(ev)) {
            EXPECT_LE(ev.data.size(), 4050u) << "seed " << seed << ": an event spans others";
            if (ev.eventnum >= 0 && ev.eventnum < 1200 && Intact(ev, LenOf(ev.eventnum))) {
                got[static_cast<std::size_t>(ev.eventnum)] = true;
            }
        }
        int lost = 0;
        for (std::size_t i = 0; i < 1200; ++i) {
            if (!hit[i] && !got[i]) ++lost;
        }
        EXPECT_EQ(lost, 0) << "seed " << seed;
    }
}

}  // namespace
}  // namespace pitmap::lcmlog
