// SPDX-License-Identifier: MIT
// Writing the TSDF volume as an OpenVDB .vdb file (grids "tsdf" and "weight"), reading a
// file's summary back, and reading the volume itself back (e.g. to mesh a fused volume).
// The file I/O unit of the fusion stage (the stage itself does no I/O).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion {

struct VdbGridInfo {
    std::string name;
    std::int64_t active_voxels = 0;
    double voxel_size_m = 0;
};

struct VdbFileInfo {
    std::vector<VdbGridInfo> grids;
    std::vector<std::string> metadata;  // "key=value" of the file metadata
};

// Writes both grids, with the file metadata given as key/value strings (e.g. the world
// origin). Fails (no throw) when the file cannot be written.
Status WriteVdb(const TsdfVolume& volume, const std::string& path,
                const std::vector<std::pair<std::string, std::string>>& metadata = {});

// Opens a .vdb file and lists its grids with their active voxel counts.
Expected<VdbFileInfo> ReadVdbInfo(const std::string& path);

// Reads a volume written by WriteVdb. The grid parameters come from the file: voxel_size_m
// from the grids' transform, truncation_m from the "tsdf" grid's background (+T). Every other
// field (weights, sensor model, ranges, threads) is taken from `config`, so a later Integrate
// or FilterByWeight behaves as with that config. Fails (no throw) when the file cannot be
// read, lacks a float grid "tsdf" or "weight", the two grids disagree in their transform, the
// transform is not a uniform scale without rotation, or the resulting config is invalid.
Expected<TsdfVolume> ReadVdb(const std::string& path, const TsdfConfig& config = {});

}  // namespace pitmap::proc::fusion
