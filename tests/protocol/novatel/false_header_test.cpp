// SPDX-License-Identifier: MIT
// False sync headers whose length field claims more bytes than will come, in a real INS
// capture: before the end of input, before a pause (Expire), back to back, and inside a real
// frame. The framer must find every checksummed frame that an independent byte-by-byte
// reference framer finds (issue: a 28-byte `AA 44 12 1C` insert claiming 30 000 bytes made
// Flush()/Expire() throw away the 147 frames behind it).
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "common/protocol/novatel/crc32.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "tests/protocol/novatel/test_util.hpp"

namespace pitmap::protocol::novatel {
namespace {

using testing::Bytes;

// --- the reference: written from the spec (§2-§4), shares no code with the framer ----------

std::uint32_t Le32(const Bytes& s, std::size_t i) {
    return std::uint32_t{s[i]} | (std::uint32_t{s[i + 1]} << 8) | (std::uint32_t{s[i + 2]} << 16) |
           (std::uint32_t{s[i + 3]} << 24);
}

// Length of the checksummed frame (binary or '#'/'%' ASCII) that starts at i, or 0.
std::size_t CrcFrameAt(const Bytes& s, std::size_t i) {
    const std::size_t left = s.size() - i;
    if (left >= 12 && s[i] == 0xAA && (s[i + 1] == 0x44 || s[i + 1] == 0x45)) {
        std::size_t total = 0;
        if (s[i + 1] == 0x44 && s[i + 2] == 0x13) {
            total = 12 + std::size_t{s[i + 3]} + 4;
        } else if (s[i + 2] == 0x12 && s[i + 3] >= 28) {
            total =
                std::size_t{s[i + 3]} + (std::size_t{s[i + 8]} | (std::size_t{s[i + 9]} << 8)) + 4;
            if (total > 32768) return 0;
        } else {
            return 0;
        }
        if (total > left) return 0;
        return Crc32(ByteSpan(s.data() + i, total - 4)) == Le32(s, i + total - 4) ? total : 0;
    }
    if (s[i] == '#' || s[i] == '%') {
        std::size_t star = i + 1;
        while (star < s.size() && s[star] != '*') {
            if (s[star] < 0x20 || s[star] > 0x7E) return 0;
            ++star;
        }
        if (star + 11 > s.size() || s[star + 9] != '\r' || s[star + 10] != '\n') return 0;
        const std::string hex(reinterpret_cast<const char*>(&s[star + 1]), 8);
        if (hex.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos) return 0;
        const auto stored = static_cast<std::uint32_t>(std::stoul(hex, nullptr, 16));
        if (Crc32(ByteSpan(s.data() + i + 1, star - i - 1)) != stored) return 0;
        return star + 11 - i;
    }
    return 0;
}

std::vector<std::uint64_t> ReferenceOffsets(const Bytes& s) {
    std::vector<std::uint64_t> out;
    std::size_t i = 0;
    while (i < s.size()) {
        const std::size_t n = CrcFrameAt(s, i);
        if (n == 0) {
            ++i;
            continue;
        }
        out.push_back(i);
        i += n;
    }
    return out;
}

bool Checksummed(FrameKind k) {
    return k == FrameKind::kLongBinary || k == FrameKind::kShortBinary ||
           k == FrameKind::kProprietary || k == FrameKind::kAscii || k == FrameKind::kShortAscii;
}

// --- the framer, driven as a transport does --------------------------------------------------

// Pushes `s` in 512-byte reads; at each offset in `pauses` the input stops and the transport's
// maximum wait runs out (Expire while it gives something up); at the end, Flush until empty.
// Returns the offsets of the checksummed frames and checks that every byte is accounted for.
std::vector<std::uint64_t> FramerOffsets(const Bytes& s, std::vector<std::size_t> pauses = {}) {
    Framer framer;
    std::vector<std::uint64_t> out;
    std::uint64_t accounted = 0;
    const auto drain = [&] {
        for (;;) {
            auto ev = framer.Next();
            if (std::holds_alternative<NeedMore>(ev)) return;
            if (const auto* sk = std::get_if<Skipped>(&ev)) {
                EXPECT_EQ(sk->offset, accounted);
                accounted += sk->bytes;
                continue;
            }
            const Frame& f = std::get<Frame>(ev);
            EXPECT_EQ(f.offset, accounted);
            accounted += f.bytes.size();
            if (Checksummed(f.kind)) out.push_back(f.offset);
        }
    };
    const auto give_up = [&](bool end) {
        while (auto sk = end ? framer.Flush() : framer.Expire()) {
            EXPECT_EQ(sk->reason, end ? SkipReason::kTruncated : SkipReason::kStale);
            EXPECT_EQ(sk->offset, accounted);
            accounted += sk->bytes;
            drain();
        }
        if (end) {
            EXPECT_EQ(framer.buffered(), 0u);
        }
    };
    pauses.push_back(s.size());
    std::size_t pos = 0;
    for (const std::size_t stop : pauses) {
        while (pos < stop) {
            const std::size_t n = std::min<std::size_t>(512, stop - pos);
            framer.Push(ByteSpan(s.data() + pos, n));
            pos += n;
            drain();
        }
        give_up(stop == s.size());
    }
    EXPECT_EQ(accounted, s.size());
    return out;
}

// A false header with its padding drawn from `seed` (7-bit bytes, so no 0xAA inside).
Bytes MakeFalseHeader(std::uint32_t seed) {
    Bytes h = testing::FalseLongHeader();
    std::mt19937 rng(seed);
    for (std::size_t i = 10; i < h.size(); ++i) h[i] = static_cast<std::uint8_t>(rng() & 0x7F);
    return h;
}

Bytes Insert(Bytes s, std::size_t at, const Bytes& what) {
    s.insert(s.begin() + static_cast<std::ptrdiff_t>(at), what.begin(), what.end());
    return s;
}

class FalseHeader : public ::testing::Test {
protected:
    void SetUp() override {
        capture_ = testing::ReadFile("oem7drv_ins2.gps");
        clean_ = ReferenceOffsets(capture_);
        ASSERT_GT(clean_.size(), 100u);
        ASSERT_EQ(FramerOffsets(capture_), clean_);
    }
    // Offset of the k-th frame of the clean capture (a frame boundary).
    std::size_t Boundary(std::size_t k) const { return static_cast<std::size_t>(clean_.at(k)); }

    Bytes capture_;
    std::vector<std::uint64_t> clean_;
};

TEST_F(FalseHeader, BeforeEndOfInput) {
    // 40 frames before the end: everything behind the insert waits for 30 000 bytes that never
    // come.
    const Bytes s = Insert(capture_, Boundary(clean_.size() - 40), MakeFalseHeader(1));
    ASSERT_LT(s.size() - Boundary(clean_.size() - 40), 30000u);
    const auto ref = ReferenceOffsets(s);
    EXPECT_EQ(ref.size(), clean_.size());
    EXPECT_EQ(FramerOffsets(s), ref);
}

TEST_F(FalseHeader, BeforeAPause) {
    const std::size_t at = Boundary(clean_.size() / 3);
    const Bytes s = Insert(capture_, at, MakeFalseHeader(2));
    // The input pauses a few frames after the insert and resumes later.
    const std::size_t pause =
        static_cast<std::size_t>(ReferenceOffsets(s).at(clean_.size() / 3 + 5));
    const auto ref = ReferenceOffsets(s);
    EXPECT_EQ(ref.size(), clean_.size());
    EXPECT_EQ(FramerOffsets(s, {pause}), ref);
}

TEST_F(FalseHeader, BackToBackBeforePauseAndEnd) {
    Bytes two = MakeFalseHeader(3);
    const Bytes second = MakeFalseHeader(4);
    two.insert(two.end(), second.begin(), second.end());
    Bytes s = Insert(capture_, Boundary(clean_.size() - 10), two);
    s = Insert(s, Boundary(20), two);
    const auto ref = ReferenceOffsets(s);
    EXPECT_EQ(ref.size(), clean_.size());
    const std::size_t pause = static_cast<std::size_t>(ref.at(25));
    EXPECT_EQ(FramerOffsets(s, {pause}), ref);
    EXPECT_EQ(FramerOffsets(s), ref);
}

TEST_F(FalseHeader, InsideARealFrame) {
    // Inside frame 40: that frame is broken (its CRC fails), every other one is found.
    const std::size_t at = Boundary(40) + 17;
    const Bytes s = Insert(capture_, at, MakeFalseHeader(5));
    const auto ref = ReferenceOffsets(s);
    EXPECT_EQ(ref.size(), clean_.size() - 1);
    EXPECT_EQ(FramerOffsets(s), ref);
    EXPECT_EQ(FramerOffsets(s, {at + 100}), ref);
}

TEST_F(FalseHeader, RandomInsertsAndPauses) {
    std::mt19937 rng(20261125);
    for (int round = 0; round < 20; ++round) {
        Bytes s = capture_;
        const int inserts = 1 + static_cast<int>(rng() % 4);
        for (int i = 0; i < inserts; ++i) {
            s = Insert(s, rng() % s.size(), MakeFalseHeader(static_cast<std::uint32_t>(rng())));
        }
        std::vector<std::size_t> pauses;
        for (int i = 0; i < 3; ++i) pauses.push_back(rng() % s.size());
        std::sort(pauses.begin(), pauses.end());
        EXPECT_EQ(FramerOffsets(s, pauses), ReferenceOffsets(s)) << "round " << round;
    }
}

TEST(FalseHeaderAscii, StrayStartsBeforeAsciiLogsAndTheEnd) {
    // A '#' log header with no '*' yet, a '<' and a '$' before real ASCII logs, then the end.
    const Bytes log1 = testing::AsciiLine('#',
                                          "TIMEA,COM1,0,50.0,FINESTEERING,2000,1.0,0,0,0;"
                                          "VALID,0,0,0,2018,5,1,0,0,1000,VALID");
    const Bytes log2 = testing::AsciiLine('%',
                                          "INSPVASA,2000,1.0;2000,1.0,51,-114,1000,0,0,0,0,0,"
                                          "90,INS_SOLUTION_GOOD");
    Bytes s = testing::FromText("#BESTPOSA,COM1,0,83.5,FINESTEERING,1419,336148.000");
    for (const auto* part : {&log1, &log2}) s.insert(s.end(), part->begin(), part->end());
    const Bytes stray = testing::FromText("<garbage $GPGGA,1");
    s.insert(s.end(), stray.begin(), stray.end());
    s.insert(s.end(), log1.begin(), log1.end());
    s.insert(s.end(), log2.begin(), log2.end());
    const Bytes cut = testing::FromText("#INSPVAXA,COM1,0,80.0");
    s.insert(s.end(), cut.begin(), cut.end());
    const auto ref = ReferenceOffsets(s);
    EXPECT_EQ(ref.size(), 4u);
    EXPECT_EQ(FramerOffsets(s), ref);
    EXPECT_EQ(FramerOffsets(s, {s.size() - 5}), ref);
}

}  // namespace
}  // namespace pitmap::protocol::novatel
