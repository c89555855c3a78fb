// SPDX-License-Identifier: MIT
// The OpenVDB grids behind TsdfVolume. Included only by tsdf.cpp and vdb_io.cpp (OpenVDB
// headers cost ~15 s of CPU per translation unit).
#pragma once

#include <openvdb/openvdb.h>

#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion {

struct TsdfVolume::Impl {
    // Signed distance s(v), metres; background +T (unobserved reads as far in front).
    openvdb::FloatGrid::Ptr distance;
    // Weight w(v); background 0. A voxel is observed iff it is active in this grid.
    openvdb::FloatGrid::Ptr weight;
};

}  // namespace pitmap::proc::fusion
