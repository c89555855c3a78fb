// SPDX-License-Identifier: MIT
#include "processor/fusion/vdb_io.hpp"

#include <openvdb/io/File.h>

#include <exception>

#include "processor/fusion/detail/tsdf_grids.hpp"

namespace pitmap::proc::fusion {

Status WriteVdb(const TsdfVolume& volume, const std::string& path,
                const std::vector<std::pair<std::string, std::string>>& metadata) {
    try {
        openvdb::initialize();
        openvdb::GridPtrVec grids;
        grids.push_back(volume.impl().distance);
        grids.push_back(volume.impl().weight);
        openvdb::MetaMap meta;
        for (const auto& [key, value] : metadata) {
            meta.insertMeta(key, openvdb::StringMetadata(value));
        }
        openvdb::io::File file(path);
        file.write(grids, meta);
        file.close();
    } catch (const std::exception& e) {
        return Error{path + ": cannot write VDB: " + e.what()};
    }
    return Ok{};
}

Expected<VdbFileInfo> ReadVdbInfo(const std::string& path) {
    VdbFileInfo info;
    try {
        openvdb::initialize();
        openvdb::io::File file(path);
        file.open();
        openvdb::MetaMap::Ptr meta = file.getMetadata();
        for (auto it = meta->beginMeta(); it != meta->endMeta(); ++it) {
            info.metadata.push_back(it->first + "=" + it->second->str());
        }
        openvdb::GridPtrVecPtr grids = file.getGrids();
        for (const openvdb::GridBase::Ptr& g : *grids) {
            info.grids.push_back({g->getName(), static_cast<std::int64_t>(g->activeVoxelCount()),
                                  g->voxelSize()[0]});
        }
        file.close();
    } catch (const std::exception& e) {
        return Error{path + ": cannot read VDB: " + e.what()};
    }
    return info;
}

}  // namespace pitmap::proc::fusion
