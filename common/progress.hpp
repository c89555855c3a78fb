// SPDX-License-Identifier: MIT
// A small progress reporter for long stages, used by apps and tools (stages themselves only
// take a callback). On a terminal it redraws one line at most 5 times a second; otherwise
// (logs, CI) it prints a line every 10 % or every 10 s, whichever comes first.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>

namespace pitmap {

// The callback a stage takes: called with the fraction done in [0, 1]; returning false asks
// the stage to stop early (it then reports termination "cancelled").
using ProgressCallback = std::function<bool(double fraction)>;

// "label  42.0 %  [1234/5000]  12.3 s, eta 17.0 s"; total <= 0 prints the count only.
std::string FormatProgressLine(const std::string& label,
                               std::int64_t done,
                               std::int64_t total,
                               double elapsed_s);

// Thread safety: one reporter per thread; Update is cheap when nothing is printed.
class ProgressReporter {
public:
    ProgressReporter(std::string label, std::int64_t total, std::FILE* out = stderr);
    ~ProgressReporter();
    ProgressReporter(const ProgressReporter&) = delete;
    ProgressReporter& operator=(const ProgressReporter&) = delete;

    void Update(std::int64_t done);
    // Prints the final line with the elapsed time (once; also done by the destructor).
    void Finish();
    // A ProgressCallback that maps the fraction onto [0, total] (total 1000 if unset).
    ProgressCallback AsCallback();
    double elapsed_s() const;

private:
    void Print(std::int64_t done, bool final_line);

    std::string label_;
    std::int64_t total_;
    std::FILE* out_;
    bool tty_;
    bool finished_ = false;
    std::int64_t last_done_ = 0;
    int last_decile_ = -1;
    std::chrono::steady_clock::time_point start_;
    std::chrono::steady_clock::time_point last_print_;
};

}  // namespace pitmap
