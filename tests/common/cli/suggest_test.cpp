// SPDX-License-Identifier: MIT
// The edit distance against hand-counted values, and which candidate "did you mean" picks (and
// when it picks none).
#include "common/cli/suggest.hpp"

#include <gtest/gtest.h>

namespace pitmap::cli {
namespace {

TEST(EditDistance, HandCountedValues) {
    EXPECT_EQ(EditDistance("", ""), 0u);
    EXPECT_EQ(EditDistance("", "abc"), 3u);
    EXPECT_EQ(EditDistance("abc", ""), 3u);
    EXPECT_EQ(EditDistance("live", "live"), 0u);
    EXPECT_EQ(EditDistance("lve", "live"), 1u);   // one deletion
    EXPECT_EQ(EditDistance("lvie", "live"), 1u);  // one transposition
    EXPECT_EQ(EditDistance("georf", "georef"), 1u);
    EXPECT_EQ(EditDistance("kitten", "sitting"), 3u);  // k->s, e->i, +g
    EXPECT_EQ(EditDistance("--otu", "--out"), 1u);
    EXPECT_EQ(EditDistance("ca", "abc"), 3u);  // optimal string alignment: no edit of a swap
    // Symmetric.
    EXPECT_EQ(EditDistance("calibrate", "clibrte"), EditDistance("clibrte", "calibrate"));
}

const std::vector<std::string> kCommands = {"info",
                                            "georef",
                                            "calibrate",
                                            "slam",
                                            "clean",
                                            "grid",
                                            "fuse",
                                            "mesh",
                                            "report",
                                            "rerun",
                                            "run",
                                            "edit",
                                            "config",
                                            "live"};

TEST(ClosestMatch, TyposOfCommands) {
    EXPECT_EQ(ClosestMatch("lve", kCommands), "live");
    EXPECT_EQ(ClosestMatch("lvie", kCommands), "live");
    EXPECT_EQ(ClosestMatch("gerf", kCommands), "georef");
    EXPECT_EQ(ClosestMatch("calibrat", kCommands), "calibrate");
    EXPECT_EQ(ClosestMatch("rn", kCommands), "run");
    EXPECT_EQ(ClosestMatch("repotr", kCommands), "report");
}

TEST(ClosestMatch, NothingCloseIsNoSuggestion) {
    EXPECT_EQ(ClosestMatch("xyzzy", kCommands), std::nullopt);
    EXPECT_EQ(ClosestMatch("", kCommands), std::nullopt);
    EXPECT_EQ(ClosestMatch("live", kCommands), std::nullopt);  // known: nothing to suggest
    EXPECT_EQ(ClosestMatch("lve", {}), std::nullopt);
}

TEST(ClosestMatch, OptionsAndPrefixes) {
    const std::vector<std::string> options = {
        "--out", "--config", "--vehicle", "--svp", "--sonar-clock-offset", "--version", "--help"};
    EXPECT_EQ(ClosestMatch("--otu", options), "--out");
    EXPECT_EQ(ClosestMatch("--confg", options), "--config");
    EXPECT_EQ(ClosestMatch("--verison", options), "--version");
    EXPECT_EQ(ClosestMatch("--vehic", options), "--vehicle");  // a prefix of one
    EXPECT_EQ(ClosestMatch("--sonar", options), "--sonar-clock-offset");
    EXPECT_EQ(ClosestMatch("--ve", options), std::nullopt);  // a prefix of two: ambiguous
    EXPECT_EQ(ClosestMatch("--", options), std::nullopt);    // dashes alone prefix everything
}

TEST(ClosestMatch, TiesGoToTheFirstCandidate) {
    EXPECT_EQ(ClosestMatch("ab", {"ax", "xb"}), "ax");
    EXPECT_EQ(ClosestMatch("ab", {"xb", "ax"}), "xb");
}

TEST(DidYouMean, Text) {
    EXPECT_EQ(DidYouMean("lve", kCommands), "; did you mean 'live'?");
    EXPECT_EQ(DidYouMean("xyzzy", kCommands), "");
}

}  // namespace
}  // namespace pitmap::cli
