// SPDX-License-Identifier: MIT
// Writing the TSDF volume as an OpenVDB .vdb file (grids "tsdf" and "weight"), reading a
// file's summary back, and reading the volume itself back (e.g. to mesh a fused volume).
// The file I/O unit of the fusion stage (the stage itself does no I/O).
//
// Integrity: OpenVDB's reader is not robust to damaged files (overwritten bytes crash it), so
// WriteVdb appends a 24-byte trailer after OpenVDB's bytes, which OpenVDB and other VDB tools
// ignore: "PMVDBCRC", u64 LE length of the OpenVDB part, u32 LE CRC-32 of it (the NovAtel CRC
// of common/protocol), u32 LE trailer version (1). ReadVdb and ReadVdbInfo verify it before
// OpenVDB sees a byte, so a truncated or corrupted file, or a file without the trailer, is an
// error naming the file. A file crafted with a matching CRC is not protected against.
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
// origin, the run id "pitmap_run_id"). The file is written under a temporary name and renamed
// (common/formats/replace_file.hpp). Fails (no throw) when the file cannot be written.
Status WriteVdb(const TsdfVolume& volume,
                const std::string& path,
                const std::vector<std::pair<std::string, std::string>>& metadata = {});

// Opens a .vdb file written by WriteVdb (trailer verified) and lists its grids with their
// active voxel counts.
Expected<VdbFileInfo> ReadVdbInfo(const std::string& path);

// Reads a volume written by WriteVdb. The grid parameters come from the file: voxel_size_m
// from the grids' transform, truncation_m from the "tsdf" grid's background (+T). Every other
// field (weights, sensor model, ranges, threads) is taken from `config`, so a later Integrate
// or FilterByWeight behaves as with that config. The grids are read completely here (no delayed
// loading), so no read happens, and no read error surfaces, after it returns. Fails (no throw)
// when the file cannot be read or its trailer does not match, lacks a float grid "tsdf" or
// "weight", its metadata claims far more memory than the file size allows, the two grids
// disagree in their transform, the transform is not a uniform scale without rotation, or the
// resulting config is invalid.
// `metadata` (when given) receives the file metadata as key/value strings.
Expected<TsdfVolume> ReadVdb(const std::string& path,
                             const TsdfConfig& config = {},
                             std::vector<std::pair<std::string, std::string>>* metadata = nullptr);

}  // namespace pitmap::proc::fusion
