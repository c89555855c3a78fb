// SPDX-License-Identifier: MIT
// libFuzzer target for the PLY reader (common/formats/ply.cpp), which the scorer uses on
// points.ply and mesh.ply. A read either fails with an error naming the file or gives finite
// vertices within the coordinate bound and triangles whose indices are in range; a header that
// parses is formatted and parsed again to the same elements. DescribeFile (what the report
// memory-maps) either fails naming the file or gives elements that follow each other within the
// file, one layout per header element.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "common/formats/ply.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace ply = pitmap::formats::ply;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    std::size_t header_bytes = 0;
    if (auto h = ply::ParseHeader(bytes, size, &header_bytes)) {
        if (header_bytes > size) std::abort();
        const std::string again = ply::FormatHeader(*h);
        std::size_t again_bytes = 0;
        const auto h2 = ply::ParseHeader(again, size, &again_bytes);
        if (!h2 || again_bytes != again.size() || h2->elements.size() != h->elements.size())
            std::abort();
        for (std::size_t i = 0; i < h->elements.size(); ++i) {
            if (h2->elements[i].count != h->elements[i].count ||
                h2->elements[i].properties.size() != h->elements[i].properties.size())
                std::abort();
        }
    }
    const pitmap::fuzz::MemFile file(data, size);
    if (const auto layout = ply::DescribeFile(file.path()); !layout) {
        pitmap::fuzz::CheckNamesFile(layout.error().message, file.path());
    } else {
        if (layout->elements.size() != layout->header.elements.size()) std::abort();
        std::uint64_t end = 0;
        for (std::size_t i = 0; i < layout->elements.size(); ++i) {
            const auto& el = layout->elements[i];
            const std::uint64_t count = layout->header.elements[i].count;
            if (el.offset < end || el.offset > size) std::abort();
            if (el.record_bytes != 0 && count > (size - el.offset) / el.record_bytes) std::abort();
            end = el.offset + count * el.record_bytes;
        }
    }
    // With the soundings_tpu.ply properties asked for on odd sizes, so both paths are fuzzed.
    const auto r = size % 2 == 0 ? ply::ReadMesh(file.path())
                                 : ply::ReadMesh(file.path(), {"gps_time_s", "tvu_95_m"});
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return 0;
    }
    for (const auto& p : r->vertex_properties) {
        if (p.size() != r->vertices.size()) std::abort();
    }
    for (const auto& v : r->vertices) {
        if (!v.allFinite() || v.cwiseAbs().maxCoeff() > ply::kMaxCoordinateM) std::abort();
    }
    for (const auto& t : r->triangles) {
        for (int i : t) {
            if (i < 0 || static_cast<std::size_t>(i) >= r->vertices.size()) std::abort();
        }
    }
    return 0;
}
