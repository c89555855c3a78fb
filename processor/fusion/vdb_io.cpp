// SPDX-License-Identifier: MIT
#include "processor/fusion/vdb_io.hpp"

#include <openvdb/io/File.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>

#include "common/byte_io.hpp"
#include "common/formats/replace_file.hpp"
#include "common/protocol/novatel/crc32.hpp"
#include "processor/fusion/detail/tsdf_grids.hpp"

namespace pitmap::proc::fusion {

namespace {

// The checksum trailer appended after OpenVDB's bytes (OpenVDB and other readers ignore bytes
// after the last grid): magic "PMVDBCRC", u64 LE length of the OpenVDB part, u32 LE CRC-32
// (common/protocol/novatel/crc32) of that part, u32 LE trailer version.
constexpr char kTrailerMagic[8] = {'P', 'M', 'V', 'D', 'B', 'C', 'R', 'C'};
constexpr std::uint32_t kTrailerVersion = 1;
constexpr std::size_t kTrailerBytes = 24;

// CRC-32 of the first `length` bytes of `in` (read from its current position), false on a
// short read.
bool CrcOfStream(std::istream& in, std::uint64_t length, std::uint32_t& crc) {
    std::vector<std::uint8_t> buf(1 << 20);
    crc = 0;
    while (length > 0) {
        const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(length, buf.size()));
        if (!in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(n))) {
            return false;
        }
        crc = protocol::novatel::Crc32({buf.data(), n}, crc);
        length -= n;
    }
    return true;
}

// Appends the trailer to a file OpenVDB has just written.
Status AppendTrailer(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return Error{path + ": cannot reopen the written VDB"};
    const auto size = static_cast<std::uint64_t>(in.tellg());
    in.seekg(0);
    std::uint32_t crc = 0;
    if (!CrcOfStream(in, size, crc)) return Error{path + ": cannot re-read the written VDB"};
    in.close();
    std::vector<std::uint8_t> t;
    ByteWriter w(t);
    w.FixedString({kTrailerMagic, sizeof kTrailerMagic}, sizeof kTrailerMagic);
    w.U64Le(size);
    w.U32Le(crc);
    w.U32Le(kTrailerVersion);
    std::FILE* f = std::fopen(path.c_str(), "ab");
    if (f == nullptr)
        return Error{formats::ErrnoMessage(path, "cannot append the checksum", errno)};
    const bool ok = std::fwrite(t.data(), 1, t.size(), f) == t.size();
    if (std::fclose(f) != 0 || !ok) return Error{path + ": write failed (disk full?)"};
    return Ok{};
}

// Checks the trailer and the CRC of everything before it, so that no corrupted or truncated
// byte ever reaches OpenVDB (whose reader crashes on many corruptions). Reads the file once,
// in 1 MiB pieces.
Status VerifyTrailer(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return Error{path + ": cannot read VDB: cannot open"};
    const auto size = static_cast<std::uint64_t>(in.tellg());
    if (size < kTrailerBytes) {
        return Error{path + ": not a pitmap TSDF volume: " + std::to_string(size) +
                     " bytes, too short"};
    }
    std::array<unsigned char, kTrailerBytes> t{};
    in.seekg(static_cast<std::streamoff>(size - kTrailerBytes));
    if (!in.read(reinterpret_cast<char*>(t.data()), kTrailerBytes)) {
        return Error{path + ": cannot read VDB: read error"};
    }
    if (!std::equal(std::begin(kTrailerMagic), std::end(kTrailerMagic), t.begin())) {
        return Error{path +
                     ": no pitmap checksum trailer (truncated, corrupted, or not written "
                     "by this pitmap version)"};
    }
    ByteReader r(reinterpret_cast<const std::uint8_t*>(t.data()) + 8, kTrailerBytes - 8);
    const std::uint64_t length = r.U64Le();
    const std::uint32_t stored = r.U32Le();
    const std::uint32_t version = r.U32Le();
    if (version != kTrailerVersion) {
        return Error{path + ": checksum trailer version " + std::to_string(version) +
                     " not supported"};
    }
    if (length != size - kTrailerBytes) {
        return Error{path + ": file is " + std::to_string(size) + " bytes but its trailer says " +
                     std::to_string(length) + " + " + std::to_string(kTrailerBytes) +
                     " (truncated or corrupted)"};
    }
    in.seekg(0);
    std::uint32_t crc = 0;
    if (!CrcOfStream(in, length, crc)) return Error{path + ": cannot read VDB: read error"};
    if (crc != stored) {
        return Error{path + ": checksum mismatch (file corrupted)"};
    }
    return Ok{};
}

// Rejects a (checksummed) file whose grid metadata does not describe a pitmap volume, before
// any tree is read: the two float grids, and an in-memory size OpenVDB recorded at writing
// that is plausible for the file size.
Status CheckGridMetadata(openvdb::io::File& file, const std::string& path) {
    const openvdb::GridPtrVecPtr meta = file.readAllGridMetadata();
    bool tsdf = false, weight = false;
    std::int64_t mem_bytes = 0;
    for (const openvdb::GridBase::Ptr& g : *meta) {
        if (g->getName() == "tsdf") tsdf = g->isType<openvdb::FloatGrid>();
        if (g->getName() == "weight") weight = g->isType<openvdb::FloatGrid>();
        if (const auto m = g->getMetadata<openvdb::Int64Metadata>("file_mem_bytes")) {
            if (m->value() < 0) return Error{path + ": negative grid size in the metadata"};
            mem_bytes += m->value();
        }
    }
    if (!tsdf || !weight) {
        return Error{path +
                     ": not a pitmap TSDF volume (needs float grids \"tsdf\" and "
                     "\"weight\")"};
    }
    const std::int64_t file_bytes = static_cast<std::int64_t>(file.getSize());
    constexpr std::int64_t kMaxExpansion = 256;  // in-memory bytes per file byte, generous
    if (mem_bytes > (1ll << 30) && mem_bytes / kMaxExpansion > file_bytes) {
        return Error{path + ": grid metadata claims " + std::to_string(mem_bytes) +
                     " bytes in memory for a " + std::to_string(file_bytes) + "-byte file"};
    }
    return Ok{};
}

}  // namespace

namespace {

Status WriteVdbTo(const TsdfVolume& volume,
                  const std::string& path,
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
    return AppendTrailer(path);
}

}  // namespace

Status WriteVdb(const TsdfVolume& volume,
                const std::string& path,
                const std::vector<std::pair<std::string, std::string>>& metadata) {
    return formats::WriteReplacing(
        path, [&](const std::string& partial) { return WriteVdbTo(volume, partial, metadata); });
}

Expected<VdbFileInfo> ReadVdbInfo(const std::string& path) {
    VdbFileInfo info;
    if (auto st = VerifyTrailer(path); !st) return st.error();
    try {
        openvdb::initialize();
        openvdb::io::File file(path);
        file.open(/*delayLoad=*/false);
        openvdb::MetaMap::Ptr meta = file.getMetadata();
        for (auto it = meta->beginMeta(); it != meta->endMeta(); ++it) {
            info.metadata.push_back(it->first + "=" + it->second->str());
        }
        openvdb::GridPtrVecPtr grids = file.getGrids();
        for (const openvdb::GridBase::Ptr& g : *grids) {
            info.grids.push_back({g->getName(),
                                  static_cast<std::int64_t>(g->activeVoxelCount()),
                                  g->voxelSize()[0]});
        }
        file.close();
    } catch (const std::exception& e) {
        return Error{path + ": cannot read VDB: " + e.what()};
    }
    return info;
}

Expected<TsdfVolume> ReadVdb(const std::string& path,
                             const TsdfConfig& config,
                             std::vector<std::pair<std::string, std::string>>* metadata) {
    if (auto st = VerifyTrailer(path); !st) return st.error();
    openvdb::FloatGrid::Ptr distance;
    openvdb::FloatGrid::Ptr weight;
    try {
        openvdb::initialize();
        openvdb::io::File file(path);
        file.open(/*delayLoad=*/false);
        if (auto st = CheckGridMetadata(file, path); !st) return st.error();
        if (metadata != nullptr) {
            openvdb::MetaMap::Ptr meta = file.getMetadata();
            for (auto it = meta->beginMeta(); it != meta->endMeta(); ++it) {
                metadata->emplace_back(it->first, it->second->str());
            }
        }
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
        return Error{path +
                     ": not a pitmap TSDF volume (needs float grids \"tsdf\" and "
                     "\"weight\")"};
    }
    const openvdb::math::Transform& xf = distance->transform();
    if (!xf.isLinear() || !xf.hasUniformScale() || !(xf == weight->transform())) {
        return Error{path +
                     ": grids \"tsdf\" and \"weight\" must share one uniform, linear "
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
