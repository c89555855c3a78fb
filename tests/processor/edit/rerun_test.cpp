// SPDX-License-Identifier: MIT
// The re-run child of pitmap edit (processor/edit/rerun.hpp), with /bin/sh as a stub for
// `pitmap rerun P`: its output lines (stdout and stderr, the last max_lines kept), its exit
// status, one child at a time, a program that cannot start, a child still running at
// destruction is killed.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "processor/edit/rerun.hpp"

namespace pitmap::proc::edit {
namespace {

RerunState WaitExit(const RerunProcess& p) {
    for (int i = 0; i < 200 && p.running(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(25));
    return p.state();
}

TEST(RerunProcess, LinesAndExitStatus) {
    RerunProcess p(3);
    EXPECT_EQ(p.state().kind, RerunState::Kind::kIdle);
    ASSERT_TRUE(p.Start("/bin/sh", {"-c", "echo one; echo two >&2; printf 'a\\nb\\nc'; exit 3"}));
    const RerunState s = WaitExit(p);
    EXPECT_EQ(s.kind, RerunState::Kind::kExited);
    EXPECT_EQ(s.exit_code, 3);
    EXPECT_EQ(s.runs, 1);
    EXPECT_EQ(s.lines, (std::vector<std::string>{"a", "b", "c"}));
    // Again, after the first has ended.
    ASSERT_TRUE(p.Start("/bin/sh", {"-c", "echo rerun P"}));
    const RerunState s2 = WaitExit(p);
    EXPECT_EQ(s2.exit_code, 0);
    EXPECT_EQ(s2.runs, 2);
    EXPECT_EQ(s2.lines, (std::vector<std::string>{"rerun P"}));
}

TEST(RerunProcess, OneAtATimeAndKilledAtTheEnd) {
    const auto t0 = std::chrono::steady_clock::now();
    {
        RerunProcess p;
        ASSERT_TRUE(p.Start("/bin/sh", {"-c", "sleep 30"}));
        EXPECT_TRUE(p.running());
        const auto second = p.Start("/bin/sh", {"-c", "true"});
        ASSERT_FALSE(second);
        EXPECT_NE(second.error().message.find("already running"), std::string::npos);
    }
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(10));
}

TEST(RerunProcess, ProgramThatCannotStart) {
    RerunProcess p;
    const auto r = p.Start("/nonexistent/pitmap", {"rerun", "P"});
    if (r) {  // posix_spawn may report exec failures as exit status 127 instead
        EXPECT_EQ(WaitExit(p).exit_code, 127);
    } else {
        EXPECT_NE(r.error().message.find("/nonexistent/pitmap"), std::string::npos);
    }
}

}  // namespace
}  // namespace pitmap::proc::edit
