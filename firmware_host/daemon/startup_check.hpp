// SPDX-License-Identifier: MIT
// What pitmap-acqd checks before it starts anything (issue 14 case 7), at --check-config and
// again at start-up before any thread runs, so a config that cannot work on this host fails
// there with every problem listed rather than half-way through a run:
//   - ValidateLcmUrl: the LCM URL is provider://[network][?key=value&...] with a provider LCM
//     1.3 has (udpm, mpudpm, tcpq, memq, file) and a network and options that provider takes.
//     Pure: part of LoadDaemonConfig's problems.
//   - CheckHost: the log directory can be created (mkdir -p, undone afterwards: start-up
//     creates it for good) and a file can be created and removed in it (a regular file, /proc or
//     /sys, a read-only file system are errors); the fallback directory likewise, as warnings; a
//     serial device that does not exist or cannot be opened read-write by this user is a warning
//     (USB may come later, the channel keeps retrying); a serial path that exists but is not a
//     terminal device (a regular file, /dev/null: S_ISCHR, then isatty on a non-blocking open)
//     is an error (no serial port will ever be there); a UDP port that cannot be bound (in use)
//     is a warning (the channel keeps retrying).
#pragma once

#include <string>
#include <vector>

#include "firmware_host/daemon/daemon_config.hpp"

namespace pitmap::acq {

// Problems of an LCM URL, each naming it; empty when LCM would take it. "" (no LCM) is valid.
std::vector<std::string> ValidateLcmUrl(const std::string& url);

struct HostCheck {
    std::vector<std::string> errors;    // the daemon cannot run like this
    std::vector<std::string> warnings;  // it runs, but something will not work yet
};

// Problems of a log directory: creates what is missing of it, creates and removes a file in
// it, and removes again what it created.
std::vector<std::string> CheckLogDirectory(const std::string& dir);

// Runs every check above on `config` (fields left empty are skipped, so a config that did not
// load completely can still be checked).
HostCheck CheckHost(const DaemonConfig& config);

}  // namespace pitmap::acq
