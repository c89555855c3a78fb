// SPDX-License-Identifier: MIT
// libFuzzer target for the water-level CSV reader (processor/io/water_level.hpp), from memory
// and through a file: a parse either fails with a message naming the input, or gives levels
// with strictly increasing times and finite levels within 10 km; both paths agree.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "processor/io/water_level.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace io = pitmap::proc::io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const std::string name = "fuzz-levels.csv";
    const auto r = io::ParseWaterLevelText(text, name);
    pitmap::fuzz::MemFile file(data, size);
    const auto f = io::ReadWaterLevelFile(file.path());
    if (r.ok() != f.ok()) std::abort();
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, name);
        pitmap::fuzz::CheckNamesFile(f.error().message, file.path());
        return 0;
    }
    if (r->empty() || r->size() != f->size()) std::abort();
    for (std::size_t k = 0; k < r->size(); ++k) {
        const auto& s = (*r)[k];
        if (!std::isfinite(s.level_m) || std::abs(s.level_m) > 10000) std::abort();
        if (k > 0 && s.utime_gps <= (*r)[k - 1].utime_gps) std::abort();
        if (s.utime_gps != (*f)[k].utime_gps || s.level_m != (*f)[k].level_m) std::abort();
    }
    return 0;
}
