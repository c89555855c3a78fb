// SPDX-License-Identifier: MIT
// libFuzzer target for the ingest.cache reader (processor/io/products.cpp). The input is read
// as the file, then again with its last 4 bytes replaced by the CRC-32 of the rest, so that the
// fuzzer reaches the array and consistency checks behind the checksum too. A read either fails
// with an error naming the file or gives consistent pings.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "common/protocol/novatel/crc32.hpp"
#include "processor/io/products.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace {

void ReadOne(const std::vector<std::uint8_t>& bytes) {
    const pitmap::fuzz::MemFile file(bytes.data(), bytes.size());
    const auto r = pitmap::proc::io::ReadIngestCache(file.path());
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return;
    }
    for (const auto& p : r->pings.pings) {
        if (static_cast<std::uint64_t>(p.beam_offset) + p.num_beams >
            r->pings.range_counts.size()) {
            std::abort();
        }
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    std::vector<std::uint8_t> bytes(data, data + size);
    ReadOne(bytes);
    if (size >= 4) {
        const std::uint32_t crc =
            pitmap::protocol::novatel::Crc32({bytes.data(), bytes.size() - 4});
        for (int i = 0; i < 4; ++i) bytes[size - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
        ReadOne(bytes);
    }
    return 0;
}
