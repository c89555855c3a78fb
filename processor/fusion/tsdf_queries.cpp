// SPDX-License-Identifier: MIT
// Queries and edits of a fused TsdfVolume: the weight filter, the iso-surface (OpenVDB's
// VolumeToMesh), point look-ups, statistics and the weight histogram.
#include <openvdb/tools/Prune.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "common/result.hpp"
#include "processor/fusion/detail/tsdf_grids.hpp"
#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion {

namespace {
using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using openvdb::Coord;
}  // namespace

WeightFilterResult TsdfVolume::FilterByWeight(const WeightFilterConfig& config) {
    WeightFilterResult result;
    FloatTree& wt = impl_->weight->tree();
    FloatTree& dt = impl_->distance->tree();
    result.voxels_before = static_cast<std::int64_t>(wt.activeVoxelCount());
    const float background_d = static_cast<float>(config_.truncation_m);
    auto dacc = impl_->distance->getAccessor();
    for (auto leaf = wt.beginLeaf(); leaf; ++leaf) {
        LeafT* dleaf = dacc.probeLeaf(leaf->origin());
        for (auto v = leaf->beginValueOn(); v; ++v) {
            if (*v >= config.min_weight) continue;
            const openvdb::Index off = v.pos();
            leaf->setValueOff(off, 0.0f);
            if (dleaf != nullptr) dleaf->setValueOff(off, background_d);
            ++result.voxels_removed;
        }
    }
    openvdb::tools::pruneInactive(wt);
    openvdb::tools::pruneInactive(dt);
    result.voxels_after = static_cast<std::int64_t>(wt.activeVoxelCount());
    result.message = "removed " + std::to_string(result.voxels_removed) + " of " +
                     std::to_string(result.voxels_before) + " voxels with weight < " +
                     std::to_string(config.min_weight);
    return result;
}

IsoSurfaceResult TsdfVolume::ExtractIsoSurface(double iso_m) const {
    IsoSurfaceResult result;
    if (impl_->weight->activeVoxelCount() == 0) {
        result.message = "empty volume";
        return result;
    }
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*impl_->distance, points, tris, quads, iso_m, 0.0);
    result.polygons_raw = static_cast<std::int64_t>(tris.size() + quads.size());

    // A vertex (one per cell in OpenVDB's dual mesh) is kept if the sign change it marks lies
    // between observed voxels: its cell must hold observed voxels on both sides of the iso
    // value, and no edge may join a voxel below the level to an unobserved one. Otherwise the
    // crossing is against the background +T, e.g. the false surface at the back of the band.
    const double inv_s = 1.0 / config_.voxel_size_m;
    const float iso = static_cast<float>(iso_m);
    std::vector<std::int32_t> remap(points.size(), -1);
    std::vector<char> ok(points.size(), 0);
    {
        auto wacc = impl_->weight->getConstAccessor();
        auto dacc = impl_->distance->getConstAccessor();
        for (std::size_t i = 0; i < points.size(); ++i) {
            const openvdb::Vec3s& q = points[i];
            const int x0 = static_cast<int>(std::floor(q.x() * inv_s));
            const int y0 = static_cast<int>(std::floor(q.y() * inv_s));
            const int z0 = static_cast<int>(std::floor(q.z() * inv_s));
            // Corner state: 0 unobserved, 1 observed below the iso value, 2 observed above.
            int state[8];
            bool below = false, above = false;
            for (int c = 0; c < 8; ++c) {
                const Coord ijk(x0 + (c & 1), y0 + ((c >> 1) & 1), z0 + (c >> 2));
                state[c] = !wacc.isValueOn(ijk) ? 0 : (dacc.getValue(ijk) < iso ? 1 : 2);
                below |= state[c] == 1;
                above |= state[c] == 2;
            }
            // The vertex averages the crossings on the cell's edges; an edge from a voxel below
            // the level to an unobserved one (read as +T) would pull it off the surface.
            bool contaminated = false;
            for (int c = 0; c < 8 && !contaminated; ++c) {
                for (int bit = 1; bit < 8 && !contaminated; bit <<= 1) {
                    const int o = c ^ bit;
                    contaminated = (state[c] == 1 && state[o] == 0);
                }
            }
            ok[i] = below && above && !contaminated ? 1 : 0;
        }
    }
    TriangleMesh& mesh = result.mesh;
    auto vertex = [&](openvdb::Index i) {
        if (remap[i] < 0) {
            remap[i] = static_cast<std::int32_t>(mesh.vertices.size());
            mesh.vertices.emplace_back(points[i].x(), points[i].y(), points[i].z());
        }
        return remap[i];
    };
    // OpenVDB winds polygons counter-clockwise seen from the positive (water) side.
    auto add = [&](openvdb::Index a, openvdb::Index b, openvdb::Index c) {
        mesh.triangles.emplace_back(vertex(a), vertex(b), vertex(c));
    };
    for (const openvdb::Vec3I& t : tris) {
        if (!ok[t[0]] || !ok[t[1]] || !ok[t[2]]) {
            ++result.polygons_unobserved;
            continue;
        }
        add(t[0], t[1], t[2]);
    }
    for (const openvdb::Vec4I& q : quads) {
        if (!ok[q[0]] || !ok[q[1]] || !ok[q[2]] || !ok[q[3]]) {
            ++result.polygons_unobserved;
            continue;
        }
        add(q[0], q[1], q[2]);
        add(q[0], q[2], q[3]);
    }
    result.message = std::to_string(mesh.vertices.size()) + " vertices, " +
                     std::to_string(mesh.triangles.size()) + " triangles (" +
                     std::to_string(result.polygons_unobserved) +
                     " polygons at unobserved cells dropped)";
    return result;
}

float TsdfVolume::DistanceAt(const Eigen::Vector3d& p_world) const {
    const Eigen::Vector3d q = p_world / config_.voxel_size_m;
    return impl_->distance->tree().getValue(Coord(static_cast<int>(std::lround(q.x())),
                                                  static_cast<int>(std::lround(q.y())),
                                                  static_cast<int>(std::lround(q.z()))));
}

float TsdfVolume::WeightAt(const Eigen::Vector3d& p_world) const {
    const Eigen::Vector3d q = p_world / config_.voxel_size_m;
    return impl_->weight->tree().getValue(Coord(static_cast<int>(std::lround(q.x())),
                                                static_cast<int>(std::lround(q.y())),
                                                static_cast<int>(std::lround(q.z()))));
}

VolumeStats TsdfVolume::Stats() const {
    VolumeStats s;
    s.active_voxels = static_cast<std::int64_t>(impl_->weight->activeVoxelCount());
    s.leaf_nodes = static_cast<std::int64_t>(impl_->weight->tree().leafCount());
    s.memory_bytes =
        static_cast<std::size_t>(impl_->distance->memUsage() + impl_->weight->memUsage());
    bool first = true;
    for (auto v = impl_->weight->tree().cbeginValueOn(); v; ++v) {
        s.min_weight = first ? *v : std::min(s.min_weight, *v);
        s.max_weight = first ? *v : std::max(s.max_weight, *v);
        first = false;
    }
    return s;
}

WeightHistogram TsdfVolume::ComputeWeightHistogram(int num_bins) const {
    PITMAP_CHECK(num_bins >= 0, "num_bins must be >= 0");
    WeightHistogram h;
    const float w_max = config_.max_weight;
    if (num_bins == 0) {
        const int top = static_cast<int>(std::ceil(w_max));
        for (int k = 0; k <= top + 1; ++k) h.edges.push_back(static_cast<float>(k));
    } else {
        for (int k = 0; k <= num_bins; ++k) {
            h.edges.push_back(w_max * static_cast<float>(k) / static_cast<float>(num_bins));
        }
        h.edges.back() = w_max;
    }
    const std::size_t bins = h.edges.size() - 1;
    h.counts.assign(bins, 0);
    const float width = h.edges[1] - h.edges[0];
    for (auto v = impl_->weight->tree().cbeginValueOn(); v; ++v) {
        const float w = *v;
        std::size_t k = w <= 0.0f ? 0 : static_cast<std::size_t>(w / width);
        k = std::min(k, bins - 1);
        // Guard rounding at the edges of equal-width bins.
        while (k > 0 && w < h.edges[k]) --k;
        while (k + 1 < bins && w >= h.edges[k + 1]) ++k;
        ++h.counts[k];
        ++h.total;
    }
    return h;
}

void TsdfVolume::ForEachVoxel(
    const std::function<void(const Eigen::Vector3i&, float, float)>& visit) const {
    auto dacc = impl_->distance->getConstAccessor();
    for (auto v = impl_->weight->cbeginValueOn(); v; ++v) {
        if (!v.isVoxelValue()) continue;
        const Coord c = v.getCoord();
        visit(Eigen::Vector3i(c.x(), c.y(), c.z()), dacc.getValue(c), *v);
    }
}

void TsdfVolume::CopyColumns(const TsdfVolume& from, const VoxelColumns& columns) {
    PITMAP_CHECK(columns.Aligned(), "CopyColumns: columns not on kRegionAlignVoxels");
    PITMAP_CHECK(from.config_.voxel_size_m == config_.voxel_size_m &&
                     from.config_.truncation_m == config_.truncation_m,
                 "CopyColumns: volumes of different voxel size or truncation");
    const auto inside = [&](const Coord& o) {
        return o.x() >= columns.x_min && o.x() <= columns.x_max && o.y() >= columns.y_min &&
               o.y() <= columns.y_max;
    };
    // The columns are whole leaves (kRegionAlignVoxels is a multiple of 8): leaves are copied.
    const auto copy = [&](const FloatTree& src, FloatTree& dst) {
        for (auto it = src.cbeginLeaf(); it; ++it) {
            if (!inside(it->origin())) continue;
            dst.addLeaf(new LeafT(*it));
        }
    };
    copy(from.impl_->distance->tree(), impl_->distance->tree());
    copy(from.impl_->weight->tree(), impl_->weight->tree());
}

TriangleMesh KeepTrianglesIn(const TriangleMesh& mesh,
                             const VoxelColumns& columns,
                             double voxel_size_m) {
    const double x_lo = (columns.x_min - 0.5) * voxel_size_m;
    const double x_hi = (columns.x_max + 0.5) * voxel_size_m;
    const double y_lo = (columns.y_min - 0.5) * voxel_size_m;
    const double y_hi = (columns.y_max + 0.5) * voxel_size_m;
    TriangleMesh out;
    std::vector<std::int32_t> remap(mesh.vertices.size(), -1);
    for (const Eigen::Vector3i& t : mesh.triangles) {
        const Eigen::Vector3f c = (mesh.vertices[static_cast<std::size_t>(t[0])] +
                                   mesh.vertices[static_cast<std::size_t>(t[1])] +
                                   mesh.vertices[static_cast<std::size_t>(t[2])]) /
                                  3.0f;
        if (!(c.x() >= x_lo && c.x() < x_hi && c.y() >= y_lo && c.y() < y_hi)) continue;
        Eigen::Vector3i kept;
        for (int k = 0; k < 3; ++k) {
            auto& r = remap[static_cast<std::size_t>(t[k])];
            if (r < 0) {
                r = static_cast<std::int32_t>(out.vertices.size());
                out.vertices.push_back(mesh.vertices[static_cast<std::size_t>(t[k])]);
            }
            kept[k] = r;
        }
        out.triangles.push_back(kept);
    }
    return out;
}

}  // namespace pitmap::proc::fusion
