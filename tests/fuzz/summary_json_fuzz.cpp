// SPDX-License-Identifier: MIT
// libFuzzer target for the summary.json reader (processor/io/products.cpp) and the readers of
// its world origin and mount (processor/survey). A read either fails with an error naming
// the file, or the keys the stages use have their types, so that reading them cannot throw.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "processor/io/products.hpp"
#include "processor/survey/survey.hpp"
#include "tests/fuzz/fuzz_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    const auto r = pitmap::proc::io::ReadSummaryJson(file.path());
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return 0;
    }
    namespace survey = pitmap::proc::survey;
    if (r->contains("world_origin")) {
        const auto o = survey::OriginFromJson(r->at("world_origin"));
        if (!o || !std::isfinite(o->latitude_deg)) std::abort();
    }
    if (r->contains("mount") && !survey::MountFromJson(r->at("mount"))) std::abort();
    return 0;
}
