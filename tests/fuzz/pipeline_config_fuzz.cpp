// SPDX-License-Identifier: MIT
// libFuzzer target for the processor's YAML config loader (processor/pipeline/config.cpp). A
// load either fails with a message (parse error or the list of problems) or gives a config
// whose Validate() is empty.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "processor/pipeline/pipeline.hpp"
#include "tests/fuzz/fuzz_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    const auto r = pitmap::proc::pipeline::LoadConfig(file.path());
    if (!r) {
        if (r.error().message.empty()) std::abort();
        return 0;
    }
    if (!r->Validate().empty()) std::abort();
    return 0;
}
