// SPDX-License-Identifier: MIT
// libFuzzer target for the gridded-surface reader (processor/io/grid_io.hpp ReadGrid, GDAL
// underneath), which pitmap-eval uses on P/dem.tif. A read either fails with an error naming
// the file or gives a raster whose every band holds nx * ny values and a positive resolution.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "processor/io/grid_io.hpp"
#include "tests/fuzz/fuzz_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    const auto r = pitmap::proc::io::ReadGrid(file.path(), 1'000'000);
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return 0;
    }
    const auto& g = r->grid;
    if (g.nx <= 0 || g.ny <= 0 || !(g.resolution_m > 0)) std::abort();
    for (const auto& l : g.layers) {
        if (l.values.size() != static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny)) {
            std::abort();
        }
    }
    return 0;
}
