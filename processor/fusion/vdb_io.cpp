// SPDX-License-Identifier: MIT
#include "processor/fusion/vdb_io.hpp"

#include <openvdb/io/File.h>

#include <cmath>
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

Expected<TsdfVolume> ReadVdb(const std::string& path, const TsdfConfig& config) {
    openvdb::FloatGrid::Ptr distance;
    openvdb::FloatGrid::Ptr weight;
    try {
        openvdb::initialize();
        openvdb::io::File file(path);
        file.open();
        openvdb::GridPtrVecPtr grids = file.getGrids();
        file.close();
        for (const openvdb::GridBase::Ptr& g : *grids) {
            if (g->getName() == "tsdf") distance = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            if (g->getName() == "weight") weight = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        }
    } catch (const std::exception& e) {
        return Error{path + ": cannot read VDB: " + e.what()};
    }
    if (!distance || !weight) {
        return Error{path + ": not a pitmap TSDF volume (needs float grids \"tsdf\" and "
                            "\"weight\")"};
    }
    const openvdb::math::Transform& xf = distance->transform();
    if (!xf.isLinear() || !xf.hasUniformScale() || !(xf == weight->transform())) {
        return Error{path + ": grids \"tsdf\" and \"weight\" must share one uniform, linear "
                            "transform"};
    }
    // A pure uniform scale maps voxel (0,0,0) to the world origin and has no rotation.
    const openvdb::Vec3d voxel = xf.voxelSize();
    const openvdb::Vec3d origin = xf.indexToWorld(openvdb::Vec3d(0.0, 0.0, 0.0));
    const openvdb::Vec3d ex = xf.indexToWorld(openvdb::Vec3d(1.0, 0.0, 0.0)) - origin;
    if (origin.length() > 1e-9 || std::abs(ex.x() - voxel.x()) > 1e-9 * voxel.x()) {
        return Error{path + ": grid transform must be a scale about the world origin"};
    }
    TsdfConfig c = config;
    c.voxel_size_m = voxel.x();
    c.truncation_m = static_cast<double>(distance->background());
    const std::vector<std::string> problems = c.Validate();
    if (!problems.empty()) {
        std::string msg = path + ": volume parameters invalid:";
        for (const std::string& p : problems) msg += " " + p + ";";
        return Error{msg};
    }
    TsdfVolume volume(c);
    distance->setName("tsdf");
    weight->setName("weight");
    volume.impl().distance = distance;
    volume.impl().weight = weight;
    return volume;
}

}  // namespace pitmap::proc::fusion
