// SPDX-License-Identifier: MIT
// The exit status of every pitmap program (pitmap, pitmap-live, pitmap-acqd, pitmap-sim,
// pitmap-eval, pitmap-inspect, pitmap-ply-layout, pitmap-report): one table, one meaning per
// code, documented in docs/cli.md. A program may use fewer codes, never another meaning.
// CLI11's own parse-error codes (106, 109, ...) never reach the shell: common/cli/parse.hpp maps
// every command-line error to kUsage.
#pragma once

namespace pitmap::exit_code {

// Done (also: --help, --version, a stop by SIGINT/SIGTERM where the program documents it).
inline constexpr int kOk = 0;
// The run failed: an input could not be read or decoded, a stage failed, an output could not be
// written, a device or LCM could not be opened. The message names the path or the stage.
inline constexpr int kFailure = 1;
// Usage: an unknown command or option, a missing or malformed value, an invalid config, an
// input that does not exist. Checked before any work: nothing was started or written.
inline constexpr int kUsage = 2;
// An internal error (an unexpected exception: a bug); the message says what was thrown.
inline constexpr int kInternal = 3;
// `--strict` only: a quality gate tripped. The products are written and say why
// (summary.json quality_gates).
inline constexpr int kQualityGate = 4;

}  // namespace pitmap::exit_code
