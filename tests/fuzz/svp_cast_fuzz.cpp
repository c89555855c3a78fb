// SPDX-License-Identifier: MIT
// libFuzzer target for the sound-velocity cast readers (processor/svp/cast.hpp: CARIS .svp,
// CSV, two-column text; processor/svp/probe_casts.hpp: the eight probe formats), in every
// format and by content. A parse either fails with a message naming the input, or gives casts
// that pass ValidateCast; the probe readers' counts add up (rows = kept + dropped).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "processor/svp/cast.hpp"
#include "processor/svp/probe_casts.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace svp = pitmap::proc::svp;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const std::string name = "fuzz-cast.svp";
    for (svp::CastFormat f : {svp::CastFormat::kAuto,
                              svp::CastFormat::kCaris,
                              svp::CastFormat::kCsv,
                              svp::CastFormat::kTwoColumn,
                              svp::CastFormat::kAml,
                              svp::CastFormat::kCastAway,
                              svp::CastFormat::kHypackVel,
                              svp::CastFormat::kKongsbergAsvp,
                              svp::CastFormat::kSimradS12,
                              svp::CastFormat::kSeaBirdCnv,
                              svp::CastFormat::kSimradS10,
                              svp::CastFormat::kValeportMidas}) {
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
    const svp::CastFormat probe = svp::SniffProbeFormat(text);
    if (probe != svp::CastFormat::kAuto) {
        svp::ProbeCastStats st;
        const auto c = svp::ParseProbeCast(text, name, probe, &st);
        if (!c) {
            pitmap::fuzz::CheckNamesFile(c.error().message, name);
        } else if (st.invalid + st.up_cast + st.soak + st.thinned + c->depth_m.size() != st.rows) {
            std::abort();
        }
    }
    return 0;
}
