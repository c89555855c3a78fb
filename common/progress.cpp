// SPDX-License-Identifier: MIT
#include "common/progress.hpp"

#include <unistd.h>

#include <algorithm>

namespace pitmap {

std::string FormatProgressLine(const std::string& label,
                               std::int64_t done,
                               std::int64_t total,
                               double elapsed_s) {
    char buf[256];
    if (total > 0) {
        const double frac =
            std::clamp(static_cast<double>(done) / static_cast<double>(total), 0.0, 1.0);
        if (frac > 0 && frac < 1) {
            const double eta = elapsed_s * (1.0 - frac) / frac;
            std::snprintf(buf,
                          sizeof buf,
                          "%s %5.1f %%  [%lld/%lld]  %.1f s, eta %.1f s",
                          label.c_str(),
                          100.0 * frac,
                          static_cast<long long>(done),
                          static_cast<long long>(total),
                          elapsed_s,
                          eta);
        } else {
            std::snprintf(buf,
                          sizeof buf,
                          "%s %5.1f %%  [%lld/%lld]  %.1f s",
                          label.c_str(),
                          100.0 * frac,
                          static_cast<long long>(done),
                          static_cast<long long>(total),
                          elapsed_s);
        }
    } else {
        std::snprintf(buf,
                      sizeof buf,
                      "%s  [%lld]  %.1f s",
                      label.c_str(),
                      static_cast<long long>(done),
                      elapsed_s);
    }
    return buf;
}

ProgressReporter::ProgressReporter(std::string label, std::int64_t total, std::FILE* out)
    : label_(std::move(label)),
      total_(total),
      out_(out),
      tty_(out != nullptr && isatty(fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

ProgressReporter::~ProgressReporter() {
    Finish();
}

double ProgressReporter::elapsed_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void ProgressReporter::Update(std::int64_t done) {
    if (finished_ || out_ == nullptr) return;
    last_done_ = done;
    const auto now = std::chrono::steady_clock::now();
    const double since = std::chrono::duration<double>(now - last_print_).count();
    if (tty_) {
        if (since < 0.2) return;
    } else {
        const int decile = total_ > 0 ? static_cast<int>(10 * done / total_) : -1;
        if (decile == last_decile_ && since < 10.0) return;
        last_decile_ = decile;
    }
    last_print_ = now;
    Print(done, false);
}

void ProgressReporter::Finish() {
    if (finished_ || out_ == nullptr) return;
    finished_ = true;
    Print(total_ > 0 ? total_ : last_done_, true);
}

ProgressCallback ProgressReporter::AsCallback() {
    const std::int64_t scale = total_ > 0 ? total_ : 1000;
    return [this, scale](double fraction) {
        Update(
            static_cast<std::int64_t>(std::clamp(fraction, 0.0, 1.0) * static_cast<double>(scale)));
        return true;
    };
}

void ProgressReporter::Print(std::int64_t done, bool final_line) {
    const std::string line = FormatProgressLine(label_, done, total_, elapsed_s());
    if (tty_) {
        std::fprintf(out_, "\r\033[K%s%s", line.c_str(), final_line ? "\n" : "");
    } else {
        std::fprintf(out_, "%s\n", line.c_str());
    }
    std::fflush(out_);
}

}  // namespace pitmap
