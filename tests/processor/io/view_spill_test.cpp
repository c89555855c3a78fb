// SPDX-License-Identifier: MIT
// The view's points spilled to a scratch file and read back (io::SpilledPoints, decision 020):
// bit for bit, the file removed, and a damaged or missing file an error naming it.
#include "processor/io/view_spill.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

georef::GeorefPoints MakePoints(std::size_t n, bool with_status) {
    georef::GeorefPoints P;
    for (std::size_t j = 0; j < n; ++j) {
        const double x = static_cast<double>(j);
        P.position_world.emplace_back(std::nextafter(x * 0.37, 1e9), -x / 3.0, std::sqrt(x));
        P.ping.push_back(static_cast<std::uint32_t>(j / 480));
        P.beam.push_back(static_cast<std::uint16_t>(j % 480));
        P.range_m.push_back(static_cast<float>(1.0 + x * 1e-3));
        P.angle_rad.push_back(static_cast<float>(std::sin(x)));
        if (with_status) P.status.push_back(static_cast<std::uint8_t>(j % 11));
    }
    // Values whose bits a text round trip would lose.
    if (n > 2) {
        P.position_world[1].x() = std::numeric_limits<double>::denorm_min();
        P.range_m[2] = std::numeric_limits<float>::quiet_NaN();
    }
    return P;
}

void ExpectSameBits(const georef::GeorefPoints& a, const georef::GeorefPoints& b) {
    ASSERT_EQ(a.size(), b.size());
    ASSERT_EQ(a.position_world.size(), a.size());
    ASSERT_EQ(b.range_m.size(), a.size());
    EXPECT_EQ(a.ping, b.ping);
    EXPECT_EQ(a.beam, b.beam);
    EXPECT_EQ(a.status, b.status);
    // An empty vector's data() may be null, which memcmp must not be given even for 0 bytes.
    if (a.size() == 0) return;
    EXPECT_EQ(
        0,
        std::memcmp(
            a.position_world.data(), b.position_world.data(), a.size() * sizeof(Eigen::Vector3d)));
    EXPECT_EQ(0, std::memcmp(a.range_m.data(), b.range_m.data(), a.size() * sizeof(float)));
    EXPECT_EQ(0, std::memcmp(a.angle_rad.data(), b.angle_rad.data(), a.size() * sizeof(float)));
}

std::string Scratch(const std::string& name) {
    const fs::path dir = fs::path(::testing::TempDir()) / "view_spill_test";
    fs::create_directories(dir);
    return (dir / name).string();
}

TEST(ViewSpill, PointsComeBackBitForBitAndTheFileGoes) {
    for (const bool with_status : {false, true}) {
        for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{100003}}) {
            const georef::GeorefPoints original = MakePoints(n, with_status);
            georef::GeorefPoints P = original;
            const std::string path = Scratch("points_" + std::to_string(n));
            auto spilled = SpilledPoints::Spill(P, path);
            ASSERT_TRUE(spilled) << spilled.error().message;
            EXPECT_EQ(P.size(), 0u);
            EXPECT_TRUE(P.status.empty());
            EXPECT_EQ(P.position_world.capacity(), 0u);
            EXPECT_EQ(spilled->size(), n);
            EXPECT_TRUE(fs::exists(path));
            ASSERT_TRUE(spilled->Restore(P));
            EXPECT_FALSE(fs::exists(path));
            ExpectSameBits(P, original);
            // Only once.
            EXPECT_FALSE(spilled->Restore(P));
        }
    }
}

TEST(ViewSpill, ADestroyedSpillLeavesNoFile) {
    georef::GeorefPoints P = MakePoints(10, false);
    const std::string path = Scratch("dropped");
    {
        auto spilled = SpilledPoints::Spill(P, path);
        ASSERT_TRUE(spilled);
        SpilledPoints moved = std::move(*spilled);
        EXPECT_TRUE(fs::exists(path));
    }
    EXPECT_FALSE(fs::exists(path));
}

TEST(ViewSpill, ADamagedFileIsAnErrorNamingIt) {
    const georef::GeorefPoints original = MakePoints(1000, true);
    struct Damage {
        const char* name;
        void (*apply)(const std::string&);
        const char* says;
    };
    const Damage damages[] = {
        {"truncated",
         [](const std::string& p) { fs::resize_file(p, fs::file_size(p) - 5); },
         "shorter than written"},
        {"longer",
         [](const std::string& p) { std::ofstream(p, std::ios::app | std::ios::binary) << 'x'; },
         "longer than written"},
        {"header",
         [](const std::string& p) {
             std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
             f.seekp(8);
             f.put(7);  // the count's low byte
         },
         "header differs"},
        {"removed", [](const std::string& p) { fs::remove(p); }, "cannot read"},
    };
    for (const Damage& d : damages) {
        georef::GeorefPoints P = original;
        const std::string path = Scratch(std::string("damaged_") + d.name);
        auto spilled = SpilledPoints::Spill(P, path);
        ASSERT_TRUE(spilled) << d.name;
        d.apply(path);
        const Status st = spilled->Restore(P);
        ASSERT_FALSE(st) << d.name;
        EXPECT_NE(st.error().message.find(path), std::string::npos) << st.error().message;
        EXPECT_NE(st.error().message.find(d.says), std::string::npos) << st.error().message;
        EXPECT_EQ(P.size(), 0u) << d.name;
        EXPECT_FALSE(fs::exists(path)) << d.name;
    }
}

TEST(ViewSpill, AnUnwritablePlaceOrUnequalArraysLeaveThePointsHeld) {
    georef::GeorefPoints P = MakePoints(10, false);
    const std::string nowhere = Scratch("no_such_folder") + "/deeper/points";
    auto spilled = SpilledPoints::Spill(P, nowhere);
    ASSERT_FALSE(spilled);
    EXPECT_NE(spilled.error().message.find(nowhere), std::string::npos);
    EXPECT_EQ(P.size(), 10u);
    P.beam.pop_back();
    auto unequal = SpilledPoints::Spill(P, Scratch("unequal"));
    ASSERT_FALSE(unequal);
    EXPECT_NE(unequal.error().message.find("differ in length"), std::string::npos);
    EXPECT_EQ(P.size(), 10u);
    EXPECT_FALSE(fs::exists(Scratch("unequal")));
}

TEST(ViewSpill, BlocksReadFromTheFileAreTheViewBitForBit) {
    for (const bool with_status : {false, true}) {
        const std::size_t n = 10007;
        const georef::GeorefPoints original = MakePoints(n, with_status);
        georef::GeorefPoints P = original;
        const std::string path = Scratch("blocks");
        auto spilled = SpilledPoints::Spill(P, path);
        ASSERT_TRUE(spilled) << spilled.error().message;
        // Blocks of 1 (the first and the last few points), an odd size, the whole, larger.
        for (const std::size_t block : {std::size_t{1}, std::size_t{977}, n, n + 13}) {
            georef::GeorefPoints joined;
            for (std::size_t first = 0; first < n; first += block) {
                if (block == 1 && first > 20 && first + 20 < n) continue;
                georef::GeorefPoints b;
                ASSERT_TRUE(spilled->ReadBlock(first, block, b)) << block;
                const std::size_t count = std::min(block, n - first);
                ASSERT_EQ(b.size(), count);
                ExpectSameBits(b, georef::SliceOf(original, first, count));
                if (block != 1) georef::AppendPoints(b, joined);
            }
            if (block != 1) ExpectSameBits(joined, original);
        }
        // Past the end: nothing at the end, an error beyond it.
        georef::GeorefPoints b;
        EXPECT_TRUE(spilled->ReadBlock(n, 5, b));
        EXPECT_EQ(b.size(), 0u);
        EXPECT_FALSE(spilled->ReadBlock(n + 1, 5, b));
        // The file stays: Restore still gives the whole view.
        ASSERT_TRUE(spilled->Restore(P));
        ExpectSameBits(P, original);
        EXPECT_FALSE(spilled->ReadBlock(0, 5, b));
    }
}

TEST(ViewSpill, ADamagedFileIsAnErrorWhenABlockIsRead) {
    georef::GeorefPoints P = MakePoints(1000, false);
    const std::string path = Scratch("damaged_block");
    auto spilled = SpilledPoints::Spill(P, path);
    ASSERT_TRUE(spilled);
    fs::resize_file(path, fs::file_size(path) - 3);
    georef::GeorefPoints b;
    const Status st = spilled->ReadBlock(0, 10, b);
    ASSERT_FALSE(st);
    EXPECT_NE(st.error().message.find(path), std::string::npos) << st.error().message;
    EXPECT_NE(st.error().message.find("shorter than written"), std::string::npos);
    EXPECT_EQ(b.size(), 0u);
}

TEST(ViewSpill, KeepOnlyLeavesTheKeptPointsInTheirOrder) {
    for (const bool with_status : {false, true}) {
        const std::size_t n = 5003;
        const georef::GeorefPoints original = MakePoints(n, with_status);
        std::vector<char> keep(n);
        for (std::size_t j = 0; j < n; ++j) keep[j] = (j % 7 == 3 || j % 13 == 0) ? 0 : 1;
        georef::GeorefPoints expected;
        for (std::size_t j = 0; j < n; ++j) {
            if (!keep[j]) continue;
            const georef::GeorefPoints one = georef::SliceOf(original, j, 1);
            expected.position_world.push_back(one.position_world[0]);
            expected.ping.push_back(one.ping[0]);
            expected.beam.push_back(one.beam[0]);
            expected.range_m.push_back(one.range_m[0]);
            expected.angle_rad.push_back(one.angle_rad[0]);
            if (with_status) expected.status.push_back(one.status[0]);
        }
        for (const std::size_t block : {std::size_t{1}, std::size_t{333}, n}) {
            georef::GeorefPoints P = original;
            const std::string path = Scratch("keep_" + std::to_string(block));
            auto spilled = SpilledPoints::Spill(P, path);
            ASSERT_TRUE(spilled);
            ASSERT_TRUE(spilled->KeepOnly(keep, block));
            EXPECT_EQ(spilled->size(), expected.size());
            EXPECT_FALSE(fs::exists(path + ".next"));
            ASSERT_TRUE(spilled->Restore(P));
            ExpectSameBits(P, expected);
        }
        // Verdicts of another length: an error, the file as it was.
        georef::GeorefPoints P = original;
        auto spilled = SpilledPoints::Spill(P, Scratch("keep_wrong"));
        ASSERT_TRUE(spilled);
        keep.pop_back();
        EXPECT_FALSE(spilled->KeepOnly(keep, 100));
        ASSERT_TRUE(spilled->Restore(P));
        ExpectSameBits(P, original);
    }
}

// SLAM's move of the spilled view onto its trajectory (decision 043): each block's positions
// rewritten where they are, every other array untouched, whatever the block size; a block whose
// positions come back resized is an error and leaves the file as it was.
TEST(ViewSpill, MovePositionsRewritesThePositionsBlockByBlock) {
    for (const bool with_status : {false, true}) {
        const std::size_t n = 5003;
        const georef::GeorefPoints original = MakePoints(n, with_status);
        georef::GeorefPoints expected = original;
        for (std::size_t j = 0; j < n; ++j) {
            expected.position_world[j] =
                expected.position_world[j] * 0.5 + Eigen::Vector3d(static_cast<double>(j), 1, 2);
        }
        for (const std::size_t block : {std::size_t{1}, std::size_t{333}, n, n + 7}) {
            georef::GeorefPoints P = original;
            const std::string path = Scratch("move_" + std::to_string(block));
            auto spilled = SpilledPoints::Spill(P, path);
            ASSERT_TRUE(spilled);
            std::size_t seen = 0;
            const Status st =
                spilled->MovePositions(block, [&](georef::GeorefPoints& b, std::size_t first) {
                    EXPECT_EQ(first, seen);
                    EXPECT_EQ(b.ping.size(), b.size());
                    for (std::size_t i = 0; i < b.size(); ++i) {
                        b.position_world[i] = b.position_world[i] * 0.5 +
                                              Eigen::Vector3d(static_cast<double>(first + i), 1, 2);
                    }
                    seen += b.size();
                });
            ASSERT_TRUE(st) << st.error().message;
            EXPECT_EQ(seen, n);
            EXPECT_EQ(spilled->size(), n);
            EXPECT_FALSE(fs::exists(path + ".next"));
            ASSERT_TRUE(spilled->Restore(P));
            ExpectSameBits(P, expected);
        }
        georef::GeorefPoints P = original;
        auto spilled = SpilledPoints::Spill(P, Scratch("move_wrong"));
        ASSERT_TRUE(spilled);
        EXPECT_FALSE(spilled->MovePositions(100, [](georef::GeorefPoints& b, std::size_t first) {
            if (first == 200) b.position_world.pop_back();
            for (Eigen::Vector3d& x : b.position_world) x.x() += 1.0;
        }));
        ASSERT_TRUE(spilled->Restore(P));
        ExpectSameBits(P, original);
    }
}

TEST(ViewSpill, TheScratchFileIsAPartialFileOfTheFolder) {
    const std::string p = ViewSpillPath("some/products");
    EXPECT_EQ(fs::path(p).parent_path(), fs::path("some/products"));
    EXPECT_EQ(fs::path(p).filename().string().rfind(".partial-", 0), 0u) << p;
}

std::string FileBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Decision 033: georef writes the view to its file as it makes it, a block at a time, into a
// file laid out for every beam; the finished file is Spill's byte for byte.
TEST(ViewSpill, AFileWrittenByBlocksIsTheFileSpillWrites) {
    for (const bool with_status : {false, true}) {
        for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{100003}}) {
            const georef::GeorefPoints original = MakePoints(n, with_status);
            georef::GeorefPoints P = original;
            const std::string whole = Scratch("whole_" + std::to_string(n));
            auto spilled = SpilledPoints::Spill(P, whole);
            ASSERT_TRUE(spilled) << spilled.error().message;
            for (const std::size_t block : {std::size_t{1}, std::size_t{977}, n + 5}) {
                if (block == 1 && n > 1000) continue;  // 100 003 opens of the file
                // Capacity: the points themselves, and more (the beams georef drops).
                for (const std::size_t capacity : {n, 3 * n + 7}) {
                    const std::string path = Scratch("blocks_" + std::to_string(n));
                    auto writer = SpillWriter::Open(path, capacity, with_status);
                    ASSERT_TRUE(writer) << writer.error().message;
                    for (std::size_t first = 0; first < n; first += block) {
                        ASSERT_TRUE(writer->Append(
                            georef::SliceOf(original, first, std::min(block, n - first))));
                    }
                    EXPECT_EQ(writer->size(), n);
                    auto finished = writer->Finish();
                    ASSERT_TRUE(finished) << finished.error().message;
                    EXPECT_EQ(finished->size(), n);
                    EXPECT_EQ(finished->with_status(), with_status && n > 0);
                    EXPECT_TRUE(FileBytes(path) == FileBytes(whole))
                        << "n " << n << " block " << block << " capacity " << capacity;
                    georef::GeorefPoints back;
                    ASSERT_TRUE(finished->Restore(back));
                    ExpectSameBits(back, original);
                    EXPECT_FALSE(fs::exists(path));
                }
            }
        }
    }
}

TEST(ViewSpill, AWriterRefusesMoreThanItsCapacityAndLeavesNoFileUnfinished) {
    const georef::GeorefPoints P = MakePoints(10, false);
    const std::string path = Scratch("capacity");
    {
        auto writer = SpillWriter::Open(path, 9, false);
        ASSERT_TRUE(writer);
        const Status st = writer->Append(P);
        ASSERT_FALSE(st);
        EXPECT_NE(st.error().message.find(path), std::string::npos) << st.error().message;
        EXPECT_FALSE(writer->Finish()) << "a failed writer cannot be finished";
    }
    EXPECT_FALSE(fs::exists(path)) << "an unfinished file stays";
    {
        auto writer = SpillWriter::Open(path, 100, false);
        ASSERT_TRUE(writer);
        ASSERT_TRUE(writer->Append(P));
        // Statuses in a view written without them: an error, not a file of another layout.
        EXPECT_FALSE(writer->Append(MakePoints(3, true)));
    }
    EXPECT_FALSE(fs::exists(path));
    auto nowhere = SpillWriter::Open(Scratch("no_such_dir") + "/sub/points", 10, false);
    ASSERT_FALSE(nowhere);
    EXPECT_NE(nowhere.error().message.find("no_such_dir"), std::string::npos);
}

TEST(ViewSpill, TheNextFileIsBesideTheViewsAndAlternates) {
    const std::string first = ViewSpillPath("/p");
    const std::string next = NextViewSpillPath("/p", first);
    EXPECT_NE(next, first);
    EXPECT_EQ(fs::path(next).parent_path(), fs::path("/p"));
    EXPECT_EQ(fs::path(next).filename().string().rfind(".partial-", 0), 0u) << next;
    EXPECT_EQ(NextViewSpillPath("/p", next), first);
}

}  // namespace
}  // namespace pitmap::proc::io
