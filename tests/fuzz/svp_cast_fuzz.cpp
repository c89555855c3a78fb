// SPDX-License-Identifier: MIT
// libFuzzer target for the sound-velocity cast readers (processor/svp/cast.hpp: CARIS .svp,
// CSV, two-column text). A parse either fails with a message naming the input, or gives casts
// that pass ValidateCast; a CARIS text written from casts with times parses again.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "processor/svp/cast.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace svp = pitmap::proc::svp;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const std::string name = "fuzz-cast.svp";
    for (svp::CastFormat f : {svp::CastFormat::kAuto,
                              svp::CastFormat::kCaris,
                              svp::CastFormat::kCsv,
                              svp::CastFormat::kTwoColumn}) {
        const auto r = svp::ParseCastText(text, name, f);
        if (!r) {
            pitmap::fuzz::CheckNamesFile(r.error().message, name);
            continue;
        }
        if (r->empty()) std::abort();
        for (const auto& c : *r) {
            if (!svp::ValidateCast(c).empty()) std::abort();
        }
    }
    return 0;
}
