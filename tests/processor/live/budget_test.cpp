// SPDX-License-Identifier: MIT
// The live pages' byte budgets (a token bucket per client, the link shared among them) and the
// checked query parameters.
#include "processor/live/budget.hpp"

#include <gtest/gtest.h>

namespace pitmap::proc::live {
namespace {

constexpr std::int64_t kS = 1'000'000;

TEST(ClientBudgets, OneClientRefillsAtTheRateUpToTheBurst) {
    ClientBudgets b(50'000, 2.0);
    EXPECT_EQ(b.Available("a", 1 * kS), 100'000);  // starts full: one burst
    b.Spend("a", 100'000, 1 * kS);
    EXPECT_EQ(b.Available("a", 1 * kS), 0);
    EXPECT_EQ(b.Available("a", 1 * kS + kS / 2), 25'000);
    EXPECT_EQ(b.Available("a", 10 * kS), 100'000);  // capped at the burst
    EXPECT_EQ(b.spent(), 100'000);
    EXPECT_EQ(b.spent("a"), 100'000);
}

TEST(ClientBudgets, OverspendingIsPaidBackBeforeMoreIsAvailable) {
    ClientBudgets b(10'000, 1.0);
    b.Spend("a", 15'000, 1 * kS);  // 5000 in debt
    EXPECT_EQ(b.Available("a", 1 * kS), 0);
    EXPECT_EQ(b.Available("a", 1 * kS + kS / 2), 0);  // 5000 refilled = debt paid
    EXPECT_EQ(b.Available("a", 2 * kS), 5'000);
    // Debt is capped at one burst.
    b.Spend("a", 1'000'000, 2 * kS);
    EXPECT_EQ(b.Available("a", 3 * kS), 0);
    EXPECT_EQ(b.Available("a", 4 * kS), 10'000);
}

TEST(ClientBudgets, AGreedyClientCannotStarveAnother) {
    ClientBudgets b(10'000, 1.0);
    // Both pages are open; "greedy" asks 20 times a second and takes everything it may.
    EXPECT_EQ(b.Available("greedy", 0), 10'000);
    EXPECT_EQ(b.Available("calm", 0), 5'000);  // the second client: a burst of its share
    EXPECT_EQ(b.ActiveClients(0), 2u);
    EXPECT_DOUBLE_EQ(b.ShareBytesPerS(0), 5'000);
    std::int64_t greedy = 0, calm = 0;
    for (std::int64_t t = 50'000; t <= 10 * kS; t += 50'000) {
        const std::int64_t g = b.Available("greedy", t);
        b.Spend("greedy", g, t);
        greedy += g;
        if (t % kS == 0) {  // the calm one once a second
            const std::int64_t c = b.Available("calm", t);
            b.Spend("calm", c, t);
            calm += c;
        }
    }
    // Each had half the link: 10 s x 5000 B/s (plus what was saved at the start).
    EXPECT_NEAR(static_cast<double>(calm), 50'000, 5'001);
    EXPECT_NEAR(static_cast<double>(greedy), 50'000, 10'001);
    EXPECT_LE(greedy + calm, 10'000 * 10 + 15'000);  // never more than the link plus bursts
    EXPECT_EQ(b.spent(), greedy + calm);
    EXPECT_EQ(b.spent("calm"), calm);
}

TEST(ClientBudgets, AnIdleClientGivesItsShareBack) {
    ClientBudgets b(10'000, 1.0, 16, 5.0);
    b.Available("a", 0);
    b.Available("b", 0);
    EXPECT_DOUBLE_EQ(b.ShareBytesPerS(1 * kS), 5'000);
    b.Spend("a", 10'000, 1 * kS);
    // "b" silent for more than 5 s: "a" refills at the whole rate.
    b.Spend("a", b.Available("a", 7 * kS), 7 * kS);
    EXPECT_EQ(b.ActiveClients(7 * kS), 1u);
    EXPECT_DOUBLE_EQ(b.ShareBytesPerS(7 * kS), 10'000);
    EXPECT_EQ(b.Available("a", 7 * kS + kS / 2), 5'000);
}

TEST(ClientBudgets, TracksAtMostMaxClientsEvictingTheLeastRecentlySeen) {
    ClientBudgets b(10'000, 1.0, 3, 100.0);
    b.Spend("a", 1, 1);
    b.Spend("b", 1, 2);
    b.Spend("c", 1, 3);
    b.Available("a", 4);  // "b" is now the least recently seen
    b.Spend("d", 1, 5);
    EXPECT_EQ(b.tracked(), 3u);
    EXPECT_EQ(b.evicted(), 1);
    EXPECT_EQ(b.spent("b"), 0);  // gone
    EXPECT_EQ(b.spent("a"), 1);
    EXPECT_EQ(b.spent("d"), 1);
    EXPECT_EQ(b.spent(), 4);  // the total keeps what the evicted client spent
    for (int k = 0; k < 1000; ++k) b.Available("x" + std::to_string(k), 10 + k);
    EXPECT_EQ(b.tracked(), 3u);
    EXPECT_EQ(b.evicted(), 1001);
}

TEST(LiveQuery, ParsesKnownKeysAndIgnoresOthers) {
    const LiveQuery q = ParseLiveQuery({{"since", "42"}, {"max_bytes", "1000"}, {"x", "y"}});
    EXPECT_TRUE(q.error.empty());
    EXPECT_EQ(q.since, 42u);
    EXPECT_EQ(q.max_bytes, 1000);
    const LiveQuery none = ParseLiveQuery({});
    EXPECT_EQ(none.since, 0u);
    EXPECT_EQ(none.max_bytes, -1);
    EXPECT_EQ(none.client, "");
    EXPECT_EQ(ParseLiveQuery({{"client", "k3x_9-Z"}}).client, "k3x_9-Z");
    EXPECT_TRUE(ParseLiveQuery({{"client", std::string(32, 'a')}}).error.empty());
}

TEST(LiveQuery, RefusesABadClientId) {
    for (const std::string& bad : {std::string(""),
                                   std::string(33, 'a'),
                                   std::string("a b"),
                                   std::string("a/b"),
                                   std::string("a\0b", 3),
                                   std::string("\xc3\xa9t\xc3\xa9"),
                                   std::string("a%20b")}) {
        const LiveQuery q = ParseLiveQuery({{"client", bad}});
        EXPECT_NE(q.error.find("client"), std::string::npos) << bad;
    }
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
