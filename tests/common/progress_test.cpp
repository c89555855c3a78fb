// SPDX-License-Identifier: MIT
#include "common/progress.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace pitmap {
namespace {

TEST(Progress, FormatLine) {
    EXPECT_EQ(FormatProgressLine("georef", 250, 1000, 5.0),
              "georef  25.0 %  [250/1000]  5.0 s, eta 15.0 s");
    EXPECT_EQ(FormatProgressLine("georef", 1000, 1000, 20.0),
              "georef 100.0 %  [1000/1000]  20.0 s");
    EXPECT_EQ(FormatProgressLine("ingest", 42, 0, 1.25), "ingest  [42]  1.2 s");
    // Over-counting does not print more than 100 %.
    EXPECT_EQ(FormatProgressLine("x", 20, 10, 1.0), "x 100.0 %  [20/10]  1.0 s");
}

TEST(Progress, NonTerminalPrintsOnDecilesAndFinishOnce) {
    std::FILE* f = std::tmpfile();
    ASSERT_NE(f, nullptr);
    {
        ProgressReporter p("stage", 100, f);
        for (int i = 0; i <= 100; ++i) p.Update(i);
        p.Finish();
        p.Finish();
    }
    std::rewind(f);
    int lines = 0;
    char buf[512];
    std::string last;
    while (std::fgets(buf, sizeof buf, f)) {
        ++lines;
        last = buf;
    }
    std::fclose(f);
    // One line per decile 0..10 plus the final line; never one per update.
    EXPECT_EQ(lines, 12);
    EXPECT_EQ(last.rfind("stage 100.0 %  [100/100]", 0), 0u) << last;
}

TEST(Progress, CallbackMapsFractions) {
    std::FILE* f = std::tmpfile();
    ASSERT_NE(f, nullptr);
    ProgressReporter p("cb", 0, f);
    auto cb = p.AsCallback();
    EXPECT_TRUE(cb(0.5));
    EXPECT_TRUE(cb(2.0));
    p.Finish();
    std::fclose(f);
}

}  // namespace
}  // namespace pitmap
