// SPDX-License-Identifier: MIT
// libFuzzer target for the edit log reader (processor/survey/edit_log.cpp). The input is read
// as P/edits.json and applied to a small fixed survey: a read either fails naming the file or
// gives a log whose application either fails naming the file or gives one ManualEdit code per
// sounding; a log that applies is written and read back to the same flags.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "processor/survey/edit_log.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace {

namespace sv = pitmap::proc::survey;

const pitmap::proc::survey::PingSeries& Pings() {
    static const pitmap::proc::survey::PingSeries s = [] {
        pitmap::proc::survey::PingSeries p;
        std::uint32_t offset = 0;
        for (int i = 0; i < 4; ++i) {
            pitmap::proc::survey::PingHeader h;
            h.ping_number = 10 + i;
            h.beam_offset = offset;
            h.num_beams = static_cast<std::uint16_t>(3 + i);
            offset += h.num_beams;
            p.pings.push_back(h);
        }
        p.range_counts.assign(offset, 1);
        return p;
    }();
    return s;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    const auto log = sv::ReadEditLog(file.path());
    if (!log) {
        pitmap::fuzz::CheckNamesFile(log.error().message, file.path());
        return 0;
    }
    const auto manual = sv::ApplyEditLog(*log, Pings(), file.path());
    if (!manual) {
        pitmap::fuzz::CheckNamesFile(manual.error().message, file.path());
        return 0;
    }
    if (manual->size() != Pings().num_soundings()) std::abort();
    for (const std::uint8_t m : *manual) {
        if (m > 2) std::abort();
    }
    static const std::string out =
        (std::filesystem::temp_directory_path() / "pitmap_edit_log_fuzz.json").string();
    if (!sv::WriteEditLog(out, *log)) std::abort();
    const auto again = sv::ReadEditLog(out);
    if (!again) std::abort();
    const auto manual2 = sv::ApplyEditLog(*again, Pings(), out);
    if (!manual2 || *manual2 != *manual) std::abort();
    return 0;
}
