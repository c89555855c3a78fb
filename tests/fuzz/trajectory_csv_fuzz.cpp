// SPDX-License-Identifier: MIT
// libFuzzer target for the trajectory CSV reader (common/formats/trajectory_csv.cpp), used on
// trajectory.csv (whose positions set the TSDF's extent), trajectory_initial.csv,
// trajectory_ins.csv and the simulator's truth. A read either fails with an error naming the
// file or gives increasing times and finite values within the reader's limits.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "common/formats/trajectory_csv.hpp"
#include "tests/fuzz/fuzz_file.hpp"

namespace fmt = pitmap::formats;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const pitmap::fuzz::MemFile file(data, size);
    const auto r = fmt::ReadTrajectoryCsv(file.path());
    if (!r) {
        pitmap::fuzz::CheckNamesFile(r.error().message, file.path());
        return 0;
    }
    for (std::size_t i = 0; i < r->rows.size(); ++i) {
        const fmt::TrajectoryRow& row = r->rows[i];
        if (i > 0 && !(row.gps_time_s > r->rows[i - 1].gps_time_s)) std::abort();
        if (!row.position_world_m.allFinite() ||
            row.position_world_m.cwiseAbs().maxCoeff() > fmt::kMaxTrajectoryOffsetM)
            std::abort();
        for (double a : {row.roll_deg, row.pitch_deg, row.yaw_deg}) {
            if (!(std::abs(a) <= fmt::kMaxTrajectoryAngleDeg)) std::abort();
        }
        if (!row.velocity_enu_mps.allFinite()) std::abort();
        if (!fmt::PoseOf(row).matrix().allFinite()) std::abort();
    }
    return 0;
}
