// SPDX-License-Identifier: MIT
// libFuzzer target for the survey file reader (processor/survey/survey_file.cpp). The input is
// read as the file, then again with every section's CRC-32 recomputed, so that the fuzzer
// reaches the count, JSON and consistency checks behind the checksums too. A read either fails
// with an error naming the file or gives a consistent survey (the cleaning's flags included: one
// per sounding, each a cleaning status or 0); a state-only read never fails where a full read
// succeeds.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "common/protocol/novatel/crc32.hpp"
#include "processor/survey/survey_file.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace {

using pitmap::proc::survey::LoadParts;
using pitmap::proc::survey::LoadSurvey;

void ReadOne(const std::vector<std::uint8_t>& bytes) {
    const pitmap::fuzz::MemFile file(bytes.data(), bytes.size());
    const auto r = LoadSurvey(file.path());
    const auto state = LoadSurvey(file.path(), LoadParts::kState);
    if (!state) pitmap::fuzz::CheckNamesFile(state.error().message, file.path());
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return;
    }
    if (!state) std::abort();
    const auto& pings = r->ingest.pings;
    if (pings.has_intensities() && pings.intensities.size() != pings.range_counts.size())
        std::abort();
    if (pings.has_beam_angles() && pings.beam_angles_deg.size() != pings.range_counts.size())
        std::abort();
    // The cleaning's flags: one per sounding, each accepted or a cleaning status.
    const auto& cleaning = r->flags.cleaning;
    if (!cleaning.empty() && cleaning.size() != pings.range_counts.size()) std::abort();
    for (const std::uint8_t c : cleaning) {
        if (c != 0 && !pitmap::proc::survey::IsCleaningStatus(
                          static_cast<pitmap::proc::survey::SoundingStatus>(c)))
            std::abort();
    }
    if (!r->flags.manual.empty()) std::abort();  // the hand edits are never in the file
    for (const auto& p : pings.pings) {
        if (static_cast<std::uint64_t>(p.beam_offset) + p.num_beams > pings.range_counts.size())
            std::abort();
    }
    for (const auto& t : r->trajectories) {
        if (!t.empty() && (t.T_world_vehicle.size() != pings.pings.size() ||
                           t.valid.size() != pings.pings.size())) {
            std::abort();
        }
    }
}

// Every section's CRC set to the CRC of its payload (layout in survey_file.hpp).
void FixCrcs(std::vector<std::uint8_t>& b) {
    if (b.size() < 20) return;
    std::uint32_t count = 0;
    std::memcpy(&count, b.data() + 16, 4);
    std::size_t pos = 20;
    for (std::uint32_t i = 0; i < count && pos + 28 <= b.size(); ++i) {
        std::uint64_t n = 0;
        std::memcpy(&n, b.data() + pos + 16, 8);
        if (n > b.size() - pos - 28) return;
        const std::uint32_t crc = pitmap::protocol::novatel::Crc32({b.data() + pos + 28, n});
        std::memcpy(b.data() + pos + 24, &crc, 4);
        pos += 28 + n;
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    std::vector<std::uint8_t> bytes(data, data + size);
    ReadOne(bytes);
    FixCrcs(bytes);
    ReadOne(bytes);
    return 0;
}
