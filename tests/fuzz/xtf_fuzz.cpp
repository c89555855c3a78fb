// SPDX-License-Identifier: MIT
// libFuzzer target for the XTF reader (processor/io/xtf.hpp): the input decoded as an XTF
// file, then converted into the ingest series. A decode either fails with a message naming the
// input or walks every byte: what it keeps is bounded by the packets it read, every ping holds
// one angle (and at most one intensity and quality flag) per range, and the conversion keeps
// the flat arrays consistent. Seeded with the first packets of tests/data/xtf's line
// (tests/fuzz/seeds/xtf/).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "processor/io/xtf.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace io = pitmap::proc::io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string name = "fuzz.xtf";
    const auto f = io::DecodeXtf(pitmap::ByteSpan(data, size), name);
    if (!f) {
        pitmap::fuzz::CheckNamesFile(f.error().message, name);
        return 0;
    }
    const io::XtfCounts& c = f->counts;
    if (f->pings.size() + f->attitude.size() + f->positions.size() >
        static_cast<std::size_t>(c.packets)) {
        std::abort();
    }
    if (c.skipped_bytes < 0 || c.skipped_bytes > static_cast<std::int64_t>(size)) std::abort();
    for (const auto& p : f->pings) {
        const std::size_t n = p.twtt_counts.size();
        if (n == 0 || n > io::kBth0MaxPoints || p.angle_rad.size() != n) std::abort();
        if (!p.intensity.empty() && p.intensity.size() != n) std::abort();
        if (!p.quality.empty() && p.quality.size() != n) std::abort();
    }
    io::IngestResult r;
    const auto cv = io::AddXtfToIngest(*f, name, io::XtfAssumptions{}, -1, r);
    if (!cv) {
        pitmap::fuzz::CheckNamesFile(cv.error().message, name);
        return 0;
    }
    const auto& s = r.pings;
    if (s.has_beam_angles() && s.beam_angles_deg.size() != s.range_counts.size()) std::abort();
    if (s.has_intensities() && s.intensities.size() != s.range_counts.size()) std::abort();
    for (const auto& h : s.pings) {
        if (static_cast<std::uint64_t>(h.beam_offset) + h.num_beams > s.range_counts.size())
            std::abort();
    }
    return 0;
}
