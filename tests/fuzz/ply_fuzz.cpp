// SPDX-License-Identifier: MIT
// libFuzzer target for the PLY reader of the evaluation tool (tools/eval/ply.cpp), which reads
// points.ply and mesh.ply. A read either fails with an error naming the file or gives finite
// vertices and triangles whose indices are in range.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "tests/fuzz/fuzz_file.hpp"
#include "tools/eval/ply.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    // With the soundings_tpu.ply properties asked for on odd sizes, so both paths are fuzzed.
    const auto r = size % 2 == 0 ? pitmap::eval::ReadPly(file.path())
                                 : pitmap::eval::ReadPly(file.path(), {"gps_time_s", "tvu_95_m"});
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return 0;
    }
    for (const auto& p : r->vertex_properties) {
        if (p.size() != r->vertices.size()) std::abort();
    }
    for (const auto& v : r->vertices) {
        if (!v.allFinite()) std::abort();
    }
    for (const auto& t : r->triangles) {
        for (int i : t) {
            if (i < 0 || static_cast<std::size_t>(i) >= r->vertices.size()) std::abort();
        }
    }
    return 0;
}
