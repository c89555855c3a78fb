// SPDX-License-Identifier: MIT
// libFuzzer target for the trajectory.csv reader (processor/pipeline/adapters.cpp), whose
// positions set the TSDF's extent. A read either fails with an error naming the file or gives
// increasing times and finite positions within the survey extent.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "processor/pipeline/adapters.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace pl = pitmap::proc::pipeline;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    const auto r = pl::ReadTrajectoryCsv(file.path());
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return 0;
    }
    if (r->gps_time_s.size() != r->T_world_vehicle.size()) std::abort();
    for (std::size_t i = 0; i < r->gps_time_s.size(); ++i) {
        if (i > 0 && !(r->gps_time_s[i] > r->gps_time_s[i - 1])) std::abort();
        const auto& t = r->T_world_vehicle[i].translation();
        if (!t.allFinite() || t.cwiseAbs().maxCoeff() > pl::kMaxTrajectoryOffsetM) std::abort();
    }
    return 0;
}
