// SPDX-License-Identifier: MIT
#include "common/peak_memory.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

namespace pitmap {
namespace {

TEST(PeakRss, GrowsWithMemoryTouched) {
    ResetPeakRss();
    const double before = PeakRssMb();
    EXPECT_GT(before, 0.0);
    std::vector<char> block(64u << 20);
    std::memset(block.data(), 1, block.size());
    EXPECT_GE(PeakRssMb(), before + 32.0) << "64 MiB touched";
    EXPECT_EQ(block[block.size() / 2], 1);
}

TEST(HugePageTunables, SetWhenTheKernelAsksForMadvise) {
    const std::string madvise = "always [madvise] never\n";
    EXPECT_EQ(HugePageTunables(nullptr, nullptr, madvise), "glibc.malloc.hugetlb=1");
    EXPECT_EQ(HugePageTunables("", nullptr, madvise), "glibc.malloc.hugetlb=1");
    // The user's own tunables are kept, ours appended.
    EXPECT_EQ(HugePageTunables("glibc.malloc.arena_max=2", nullptr, madvise),
              "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1");
    EXPECT_EQ(HugePageTunables(nullptr, "1", madvise), "glibc.malloc.hugetlb=1");
}

TEST(HugePageTunables, LeftAloneOtherwise) {
    const std::string madvise = "always [madvise] never\n";
    // Already chosen (by the user, either way, or by the first start: no second re-exec).
    EXPECT_FALSE(HugePageTunables("glibc.malloc.hugetlb=1", nullptr, madvise));
    EXPECT_FALSE(HugePageTunables("glibc.malloc.hugetlb=0", nullptr, madvise));
    EXPECT_FALSE(HugePageTunables("a=1:glibc.malloc.hugetlb=2", nullptr, madvise));
    // Turned off.
    EXPECT_FALSE(HugePageTunables(nullptr, "0", madvise));
    // THP on for everything, off, or no such file (not Linux, or a kernel without THP).
    EXPECT_FALSE(HugePageTunables(nullptr, nullptr, "[always] madvise never\n"));
    EXPECT_FALSE(HugePageTunables(nullptr, nullptr, "always madvise [never]\n"));
    EXPECT_FALSE(HugePageTunables(nullptr, nullptr, ""));
}

}  // namespace
}  // namespace pitmap
