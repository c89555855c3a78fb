// SPDX-License-Identifier: MIT
// The live page's byte budget (token bucket) and the checked query parameters.
#include "processor/live/budget.hpp"

#include <gtest/gtest.h>

namespace pitmap::proc::live {
namespace {

constexpr std::int64_t kS = 1'000'000;

TEST(ByteBudget, RefillsAtTheRateUpToTheBurst) {
    ByteBudget b(50'000, 2.0);
    EXPECT_EQ(b.Available(1 * kS), 100'000);  // starts full: one burst
    b.Spend(100'000, 1 * kS);
    EXPECT_EQ(b.Available(1 * kS), 0);
    EXPECT_EQ(b.Available(1 * kS + kS / 2), 25'000);
    EXPECT_EQ(b.Available(10 * kS), 100'000);  // capped at the burst
    EXPECT_EQ(b.spent(), 100'000);
}

TEST(ByteBudget, OverspendingIsPaidBackBeforeMoreIsAvailable) {
    ByteBudget b(10'000, 1.0);
    b.Spend(15'000, 1 * kS);  // 5000 in debt
    EXPECT_EQ(b.Available(1 * kS), 0);
    EXPECT_EQ(b.Available(1 * kS + kS / 2), 0);  // 5000 refilled = debt paid
    EXPECT_EQ(b.Available(2 * kS), 5'000);
    // Debt is capped at one burst.
    b.Spend(1'000'000, 2 * kS);
    EXPECT_EQ(b.Available(3 * kS), 0);
    EXPECT_EQ(b.Available(4 * kS), 10'000);
}

TEST(LiveQuery, ParsesKnownKeysAndIgnoresOthers) {
    const LiveQuery q = ParseLiveQuery({{"since", "42"}, {"max_bytes", "1000"}, {"x", "y"}});
    EXPECT_TRUE(q.error.empty());
    EXPECT_EQ(q.since, 42u);
    EXPECT_EQ(q.max_bytes, 1000);
    const LiveQuery none = ParseLiveQuery({});
    EXPECT_EQ(none.since, 0u);
    EXPECT_EQ(none.max_bytes, -1);
}

TEST(LiveQuery, RefusesBadNumbersWithTheKeyNamed) {
    for (const char* bad : {"",
                            "-1",
                            "+1",
                            " 1",
                            "1 ",
                            "0x10",
                            "1e3",
                            "abc",
                            "99999999999999999999",
                            "9223372036854775808"}) {
        const LiveQuery q = ParseLiveQuery({{"since", bad}});
        EXPECT_NE(q.error.find("since"), std::string::npos) << bad;
    }
    EXPECT_TRUE(ParseLiveQuery({{"since", "9223372036854775807"}}).error.empty());
    EXPECT_FALSE(ParseLiveQuery({{"max_bytes", "2147483648"}}).error.empty());
    EXPECT_TRUE(ParseLiveQuery({{"max_bytes", "2147483647"}}).error.empty());
}

TEST(ParseDecimal, Bounds) {
    EXPECT_EQ(ParseDecimal("0", 10), 0u);
    EXPECT_EQ(ParseDecimal("10", 10), 10u);
    EXPECT_FALSE(ParseDecimal("11", 10));
    EXPECT_EQ(ParseDecimal("18446744073709551615", UINT64_MAX), UINT64_MAX);
    EXPECT_FALSE(ParseDecimal("18446744073709551616", UINT64_MAX));
}

}  // namespace
}  // namespace pitmap::proc::live
