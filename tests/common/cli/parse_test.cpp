// SPDX-License-Identifier: MIT
// The CLI11 front: every command-line error is the usage exit status (never CLI11's 106, 109,
// ...), --help and --version exit 0, a good command line goes on; the unknown command or
// option is named with the closest known one; the exit-code table's values are distinct and
// the documented ones; --version's line.
#include "common/cli/parse.hpp"

#include <gtest/gtest.h>

#include <regex>
#include <set>

#include "common/exit_codes.hpp"
#include "common/version.hpp"

namespace pitmap::cli {
namespace {

// An app shaped like pitmap's: two commands with options, one flag.
struct TestApp {
    CLI::App app{"test"};
    std::string out, config;
    std::vector<std::string> inputs;
    double offset = 0;
    bool strict = false;
    CLI::App* run = nullptr;
    CLI::App* slam = nullptr;
    TestApp() {
        app.require_subcommand(1);
        run = app.add_subcommand("run", "everything");
        run->add_option("inputs", inputs)->required();
        run->add_option("--out", out)->required();
        run->add_option("--config", config);
        run->add_option("--sonar-clock-offset", offset);
        run->add_flag("--strict", strict);
        slam = app.add_subcommand("slam", "slam");
        slam->add_option("--out", out)->required();
    }
    std::optional<int> Parse(std::vector<std::string> args) {
        args.insert(args.begin(), "prog");
        std::vector<char*> argv;
        for (auto& a : args) argv.push_back(a.data());
        return ParseCommandLine(app, static_cast<int>(argv.size()), argv.data(), "prog");
    }
};

TEST(ExitCodes, DistinctAndAsDocumented) {
    EXPECT_EQ(exit_code::kOk, 0);
    EXPECT_EQ(exit_code::kFailure, 1);
    EXPECT_EQ(exit_code::kUsage, 2);
    EXPECT_EQ(exit_code::kInternal, 3);
    EXPECT_EQ(exit_code::kQualityGate, 4);
    const std::set<int> all = {exit_code::kOk,
                               exit_code::kFailure,
                               exit_code::kUsage,
                               exit_code::kInternal,
                               exit_code::kQualityGate};
    EXPECT_EQ(all.size(), 5u);
}

TEST(ParseCommandLine, GoodLineGoesOn) {
    TestApp t;
    EXPECT_EQ(t.Parse({"run", "a.lcmlog", "--out", "P", "--sonar-clock-offset", "-2"}),
              std::nullopt);
    EXPECT_EQ(t.out, "P");
    EXPECT_DOUBLE_EQ(t.offset, -2.0);
}

TEST(ParseCommandLine, EveryParseErrorIsUsage) {
    // CLI11 would exit 106 (required), 109 (extras), 114 (conversion), ...: all are 2 here.
    const std::vector<std::vector<std::string>> bad = {
        {},                                                       // a command is required
        {"lve"},                                                  // unknown command
        {"run", "a"},                                             // --out missing
        {"run", "a", "--out", "P", "--otu", "Q"},                 // unknown option
        {"run", "a", "--out", "P", "--sonar-clock-offset", "x"},  // not a number
        {"slam", "--out"},                                        // no value
    };
    for (const auto& args : bad) {
        TestApp t;
        testing::internal::CaptureStderr();
        EXPECT_EQ(t.Parse(args), exit_code::kUsage) << testing::PrintToString(args);
        const std::string err = testing::internal::GetCapturedStderr();
        EXPECT_NE(err.find("--help"), std::string::npos) << err;
    }
}

TEST(ParseCommandLine, HelpAndVersionExitZero) {
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{"--help"}, {"--version"}, {"run", "--help"}}) {
        TestApp t;
        testing::internal::CaptureStdout();
        EXPECT_EQ(t.Parse(args), exit_code::kOk) << testing::PrintToString(args);
        const std::string out = testing::internal::GetCapturedStdout();
        if (args.front() == "--version") {
            EXPECT_EQ(out, VersionLine("prog") + "\n");
        }
    }
}

TEST(ParseCommandLine, TheErrorNamesTheClosestNameAndTheCommandsHelp) {
    TestApp t;
    testing::internal::CaptureStderr();
    EXPECT_EQ(t.Parse({"run", "a", "--otu", "P"}), exit_code::kUsage);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find("prog: unknown option '--otu' for 'run'; did you mean '--out'?"),
              std::string::npos)
        << err;
    EXPECT_NE(err.find("Run 'prog run --help'"), std::string::npos) << err;
}

TEST(UnknownNameMessage, CommandsAndOptions) {
    TestApp t;
    const auto msg = [&](std::vector<std::string> args) { return UnknownNameMessage(t.app, args); };
    EXPECT_EQ(msg({"lve"}), "unknown command 'lve'");  // nothing close among run, slam
    EXPECT_EQ(msg({"rnu", "a"}), "unknown command 'rnu'; did you mean 'run'?");
    EXPECT_EQ(msg({"slma"}), "unknown command 'slma'; did you mean 'slam'?");
    EXPECT_EQ(msg({"run", "a", "--otu", "P"}),
              "unknown option '--otu' for 'run'; did you mean '--out'?");
    EXPECT_EQ(msg({"run", "a", "--otu=P"}),
              "unknown option '--otu' for 'run'; did you mean '--out'?");
    EXPECT_EQ(msg({"run", "a", "-out", "P"}),
              "unknown option '-out' for 'run'; did you mean '--out'?");
    EXPECT_EQ(msg({"run", "--strcit"}),
              "unknown option '--strcit' for 'run'; did you mean '--strict'?");
    // An option of the other command is unknown here, and said so.
    TestApp u;
    u.slam->add_option("--window");
    EXPECT_EQ(UnknownNameMessage(u.app, {"run", "--window", "3"}),
              "unknown option '--window' for 'run'");
    // Known names, values that look like options or commands: nothing to say.
    EXPECT_EQ(msg({"run", "a", "--out", "P", "--sonar-clock-offset", "-2.5"}), "");
    EXPECT_EQ(msg({"run", "slam", "--out", "run"}), "");
    EXPECT_EQ(msg({"run", "a", "--out=P", "--help"}), "");
    EXPECT_EQ(msg({}), "");
}

TEST(Version, LineNamesProgramVersionAndCommit) {
    const std::string line = VersionLine("pitmap-x");
    EXPECT_EQ(std::string(Version()), PITMAP_PROJECT_VERSION);
    EXPECT_EQ(line, "pitmap-x " + std::string(Version()) + " (git " + GitCommit() + ")");
    const std::string commit = GitCommit();
    if (std::string(PITMAP_GIT_COMMIT_OVERRIDE).empty()) {
        EXPECT_TRUE(std::regex_match(commit, std::regex("[0-9a-f]{12}(-dirty)?|unknown")))
            << commit;
    } else {
        EXPECT_EQ(commit, PITMAP_GIT_COMMIT_OVERRIDE);
    }
}

}  // namespace
}  // namespace pitmap::cli
