// SPDX-License-Identifier: MIT
// The command-line front of every CLI11 program: --version, CLI11's parse errors mapped to the
// one usage exit status (common/exit_codes.hpp: 2, never CLI11's raw 106, 109, ...), and a
// "did you mean" for an unknown command or option (suggest.hpp).
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace pitmap::cli {

// Adds --version (VersionLine(program), common/version.hpp) to `app`, then parses. nullopt: go
// on. Else the exit status to return at once: kOk after --help or --version (printed on
// stdout), kUsage after a command-line error (on stderr: the problem, a suggestion when a
// command or option looks mistyped, and where --help is).
std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv, std::string_view program);

// The first argument of `args` (argv without the program name) that `app` does not know, as a
// message with the closest known name: "unknown command 'lve'; did you mean 'live'?",
// "unknown option '--otu' for 'run'; did you mean '--out'?". Commands are looked for at the top
// level only (the first argument that is neither an option nor an option's value); options in
// the command they follow and its parents. "" when every name is known (values are not
// checked: that is CLI11's part).
std::string UnknownNameMessage(const CLI::App& app, const std::vector<std::string>& args);

}  // namespace pitmap::cli
