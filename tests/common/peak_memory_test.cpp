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

TEST(MallocOnHugePages, FollowsTheKernelAndTheTunable) {
    const std::string madvise = "always [madvise] never\n";
    EXPECT_TRUE(MallocOnHugePages("glibc.malloc.hugetlb=1", madvise));
    EXPECT_TRUE(MallocOnHugePages("glibc.malloc.arena_max=2:glibc.malloc.hugetlb=2", madvise));
    EXPECT_FALSE(MallocOnHugePages("glibc.malloc.hugetlb=0", madvise));
    EXPECT_FALSE(MallocOnHugePages("glibc.malloc.hugetlb=1:glibc.malloc.hugetlb=0", madvise));
    EXPECT_FALSE(MallocOnHugePages("glibc.malloc.hugetlb=", madvise));
    EXPECT_FALSE(MallocOnHugePages("xglibc.malloc.hugetlb=1", madvise));
    EXPECT_FALSE(MallocOnHugePages(nullptr, madvise));
    EXPECT_TRUE(MallocOnHugePages(nullptr, "[always] madvise never\n"));
    EXPECT_FALSE(MallocOnHugePages("glibc.malloc.hugetlb=1", "always madvise [never]\n"));
}

}  // namespace
}  // namespace pitmap
