// SPDX-License-Identifier: MIT
// pitmap-report run as a child of pitmap: the survey report at the end of `pitmap run` (and
// `pitmap report`), the change report at the end of `pitmap compare`. One way to start it, wait
// for it and account for it, so that both behave alike when pitmap is killed or the report
// fails.
#pragma once

#include <string>
#include <vector>

#include "common/result.hpp"

namespace pitmap::proc::pipeline {

struct ReportRun {
    double cpu_seconds = 0;  // the child's user + system time
    double peak_rss_mb = 0;  // its high-water mark
};

// Runs `program` with `args` (its argv[1..]) and waits for it. Errors, each naming the program:
// it is not there or not executable (with `what_without`: what the caller has without it), it
// cannot be started, it was lost, it failed (its exit status).
// The child gets SIGTERM when this process dies (a pitmap killed with -9 takes the report and
// its workers along) and starts with SIGTERM and SIGINT at their default actions.
Expected<ReportRun> RunReportProgram(const std::string& program,
                                     const std::vector<std::string>& args,
                                     const std::string& what_without);

}  // namespace pitmap::proc::pipeline
