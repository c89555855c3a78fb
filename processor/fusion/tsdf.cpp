// SPDX-License-Identifier: MIT
// TSDF integration (seed paper section 4.3, Eq. 4-6) with a polar line sensor model after
// May et al. (2014), on OpenVDB grids: the voxel rasteriser and the integration loop. The
// footprint model is in footprint.cpp, queries of the volume in tsdf_queries.cpp.
//
// Work is cut into slabs of kSlabVoxels along the world x index, and the scans into chunks of
// kChunkScans (prepared together, then integrated). One TBB task owns one slab for a chunk: it
// replays the chunk's scans in input order but touches only voxels of its slab, in a grid of
// its own that persists across chunks. Slabs are aligned to leaf nodes, so the per-slab trees
// are disjoint and are merged by moving leaves; each voxel sees the same updates in the same
// order for any thread count.
//
// Beam-width mode walks each ping as a whole (IntegrateFan): one pass over columns of voxels
// along the axis closest to the fan plane, each voxel tested once in the sector of its angle;
// most of its time is the per-voxel work, the per-ping set-up is in fan_columns.cpp.
// docs/decisions/004 (and why not a frustum per beam).
#include "processor/fusion/tsdf.hpp"

#include <openvdb/math/DDA.h>
#include <openvdb/math/Ray.h>
#include <openvdb/openvdb.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <map>

#include "common/result.hpp"
#include "processor/fusion/detail/prepared_scan.hpp"
#include "processor/fusion/detail/tsdf_grids.hpp"

namespace pitmap::proc::fusion {

namespace {

using detail::Geometry;
using detail::PreparedBeam;
using detail::PreparedScan;
using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using openvdb::Coord;

constexpr int kSlabVoxels = 64;  // multiple of LeafT::DIM (8)
static_assert(kRegionAlignVoxels % kSlabVoxels == 0);
// Inside a slab, runs of kBatchScans scans are replayed band by band along y (kBandVoxels wide):
// a ping's fan crosses the whole swath, and walking it band by band keeps the leaves of the
// last few pings in the core's cache instead of streaming the swath's leaves for every ping.
// Each voxel lies in one band, so it still sees its updates in input order.
constexpr int kBandVoxels = 64;
static_assert(kRegionAlignVoxels % kBandVoxels == 0);
constexpr std::size_t kBatchScans = 64;
// Scans prepared at a time (held until the chunk is done: ~36 bytes per beam, and in
// beam-width mode ~40 KB of sectors, boundaries and column bins per ping). 512 keeps the
// integration's memory within the grids + 16 % on bejanca (2048: + 36 %) at the same speed.
constexpr std::size_t kChunkScans = 512;

// The voxels one task may touch: x in [x_min, x_max], y in [y_min, y_max].
struct ClipBox {
    int x_min, x_max, y_min, y_max;
};

// floor(a / b) for b > 0.
int FloorDiv(int a, int b) {
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

openvdb::FloatGrid::Ptr MakeGrid(float background, double voxel_size_m, const char* name) {
    auto grid = openvdb::FloatGrid::create(background);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel_size_m));
    grid->setName(name);
    return grid;
}

// Running weighted average on a pair of leaves (Eq. 5-6). The leaves' value buffers and masks
// are written directly; a small direct-mapped cache keyed by leaf origin keeps the pairs of
// recently used leaves, so a walk that comes back to neighbouring leaves (a ping's neighbouring
// columns, a ray) rarely goes through the tree accessors, and consecutive updates in one leaf
// (a column inside it) skip even the cache lookup.
class VoxelUpdater {
public:
    VoxelUpdater(openvdb::FloatGrid& distance, openvdb::FloatGrid& weight, float f, float w_max)
        : dacc_(distance.getAccessor()), wacc_(weight.getAccessor()), f_(f), w_max_(w_max) {}

    void Update(const Coord& ijk, float d) { Update(ijk, d, f_); }

    // One measurement of weight f (Eq. 5-6 with f in place of the uniform weight). Forced
    // inline: GCC kept it an out-of-line call with its arguments spilled to the stack, a third
    // of the beam-width integration's samples (bejanca, 1 thread: 20.7 -> 19.9 s, the same
    // updates bit for bit).
    __attribute__((always_inline)) inline void Update(const Coord& ijk, float d, float f) {
        UpdateIn(SlotOf(ijk), LeafT::coordToOffset(ijk), d, f);
    }
    struct Slot;
    // The leaf pair of ijk, for a run of updates inside one leaf (UpdateIn).
    __attribute__((always_inline)) inline const Slot& LeafOf(const Coord& ijk) {
        return SlotOf(ijk);
    }
    __attribute__((always_inline)) inline void UpdateIn(const Slot& slot,
                                                        openvdb::Index off,
                                                        float d,
                                                        float f) {
        const float w = slot.w[off];  // 0 (background) when unobserved
        const float s = w > 0.0f ? slot.d[off] : 0.0f;
        slot.d[off] = (w * s + f * d) / (w + f);  // Eq. 5
        slot.w[off] = std::min(w + f, w_max_);    // Eq. 6
        slot.dmask->setOn(off);
        slot.wmask->setOn(off);
        ++updates_;
    }
    std::int64_t updates() const { return updates_; }

    struct Slot {
        Coord origin;
        float* d = nullptr;
        float* w = nullptr;
        LeafT::NodeMaskType* dmask = nullptr;
        LeafT::NodeMaskType* wmask = nullptr;
    };

private:
    static constexpr int kSlots = 64;

    __attribute__((always_inline)) inline const Slot& SlotOf(const Coord& ijk) {
        const Coord origin(ijk.x() & ~7, ijk.y() & ~7, ijk.z() & ~7);
        // Columns run along one axis: most updates land in the leaf of the previous one.
        if (last_ != nullptr && last_->origin == origin) return *last_;
        const unsigned h = (static_cast<unsigned>(origin.x()) * 73856093u) ^
                           (static_cast<unsigned>(origin.y()) * 19349663u) ^
                           (static_cast<unsigned>(origin.z()) * 83492791u);
        Slot& slot = slots_[(h >> 3) & (kSlots - 1)];
        if (slot.d == nullptr || slot.origin != origin) Fill(slot, ijk, origin);
        last_ = &slot;
        return slot;
    }
    void Fill(Slot& slot, const Coord& ijk, const Coord& origin) {
        LeafT* dl = dacc_.touchLeaf(ijk);
        LeafT* wl = wacc_.touchLeaf(ijk);
        slot.origin = origin;
        slot.d = dl->buffer().data();
        slot.w = wl->buffer().data();
        slot.dmask = &dl->getValueMask();
        slot.wmask = &wl->getValueMask();
    }

    openvdb::FloatGrid::Accessor dacc_;
    openvdb::FloatGrid::Accessor wacc_;
    std::array<Slot, kSlots> slots_{};
    const Slot* last_ = nullptr;
    float f_;
    float w_max_;
    std::int64_t updates_ = 0;
};

// Constraint alpha + beta * j <= 0 on an integer j in [lo, hi] (tightened in place; a slack of
// 1e-7 keeps the bounds conservative against rounding).
void ClipLinear(double alpha, double beta, int& lo, int& hi) {
    if (beta > 1e-12) {
        const double j = -alpha / beta + 1e-7;
        if (j < static_cast<double>(lo)) {
            hi = lo - 1;
        } else if (j < static_cast<double>(hi)) {
            hi = static_cast<int>(std::floor(j));
        }
    } else if (beta < -1e-12) {
        const double j = -alpha / beta - 1e-7;
        if (j > static_cast<double>(hi)) {
            lo = hi + 1;
        } else if (j > static_cast<double>(lo)) {
            lo = static_cast<int>(std::ceil(j));
        }
    } else if (alpha > 1e-7) {
        hi = lo - 1;
    }
}

// The sector of a voxel of one ping's fan. Sector k is [beta_k, beta_{k+1}) of the in-plane
// angle (FanColumns); -1 and n_sect are outside the fan.
class SectorTracker {
public:
    explicit SectorTracker(const detail::FanColumns& fan)
        : fan_(fan),
          n_sect_(static_cast<int>(fan.sectors.size())),
          side_y_(fan.side_y.data()),
          side_z_(fan.side_z.data()) {}

    int count() const { return n_sect_; }
    // Steps of tracking along a column before falling back to the angle.
    int column_steps() const { return fan_.wide ? 0 : 4; }

    // Index >= k (k in [0, n_sect]) when the voxel lies on the far side of boundary k.
    __attribute__((always_inline)) inline bool AtOrAbove(int k, double y, double z) const {
        return side_y_[k] * y + side_z_[k] * z >= 0.0;
    }
    // Sector of (y, z) from a guess k in [-1, n_sect]; `exact` when both boundary tests agree,
    // which the walk reaches in a step or two. Off a fan of 180 deg or more the tests are not
    // monotone across sectors: only the guess's own sector is checked (exact: a sector's two
    // tests bound it alone).
    __attribute__((always_inline)) inline int Track(
        int k, double y, double z, int max_steps, bool& exact) const {
        if (fan_.wide) max_steps = 0;
        if (max_steps == 0) {
            exact = k >= 0 && k < n_sect_ && AtOrAbove(k, y, z) && !AtOrAbove(k + 1, y, z);
            return k;
        }
        for (int it = 0; it < max_steps; ++it) {
            if (k < n_sect_ && AtOrAbove(k + 1, y, z)) {
                ++k;
            } else if (k >= 0 && !AtOrAbove(k, y, z)) {
                --k;
            } else {
                exact = true;
                return k;
            }
        }
        exact = false;
        return k;
    }
    // Sector of (y, z) from its angle (atan2), clamped to [-1, n_sect].
    int FromAngle(double y, double z) const {
        const double k =
            std::floor((std::atan2(y, z) - fan_.start_angle) * fan_.inv_increment + 0.5);
        return static_cast<int>(std::clamp(k, -1.0, static_cast<double>(n_sect_)));
    }

private:
    const detail::FanColumns& fan_;
    const int n_sect_;
    const double* side_y_;
    const double* side_z_;
};

// The constants of one ping's column walk. The columns run along world axis a (the fan's axis);
// rows along axis b, the voxels of a row along axis c. Positions are in the sonar frame, voxel
// units: x out of the fan plane, (y, z) in it; omega and tau are the in-plane coordinates
// across and along the columns (FanColumns).
struct FanWalk {
    FanWalk(const PreparedScan& scan, const Geometry& g)
        : fan(scan.fan),
          a(fan.axis),
          b(axis_after(a, 1)),
          c(axis_after(a, 2)),
          origin(-(scan.R.transpose() * scan.p_vox)),
          step_b(scan.R(b, 0), scan.R(b, 1), scan.R(b, 2)),
          step_c(scan.R(c, 0), scan.R(c, 1), scan.R(c, 2)),
          step_a(fan.step),
          nx(step_a.x()),
          in_plane(std::abs(nx) < 1e-9),
          inv_nx(in_plane ? 0.0 : 1.0 / nx),
          sgn_nx(nx >= 0.0 ? 1.0 : -1.0),
          inv_g(1.0 / fan.g),
          omega_end(fan.omega0 + static_cast<double>(fan.tau_lo.size())),
          x_max(fan.x_max_all),
          trunc(g.trunc_vox),
          tan2_bw(g.tan_half_bw * g.tan_half_bw) {}

    static int axis_after(int axis, int n) { return (axis + n) % 3; }

    const detail::FanColumns& fan;
    const int a, b, c;              // world axes of the columns, rows and voxels of a row
    const Eigen::Vector3d origin;   // sonar frame of voxel (0, 0, 0)
    const Eigen::Vector3d step_b;   // sonar-frame change per voxel along b
    const Eigen::Vector3d step_c;   // ... along c
    const Eigen::Vector3d& step_a;  // ... along a (the columns)
    const double nx;                // out-of-plane change per column step
    const bool in_plane;            // columns parallel to the fan plane
    const double inv_nx, sgn_nx;
    const double inv_g;      // 1 / in-plane length of a column step
    const double omega_end;  // omega of the last bin's upper edge
    const double x_max;      // largest |x| any sector can update
    const double trunc;      // T, voxels
    const double tan2_bw;    // tan^2(beam width / 2)
};

// The voxels [jc0, jc1] along c of row jb whose column can meet the ping: omega within the
// bins, and |x| <= x_max within the ping's tau range. Returns the row's voxel (a, c) = (0, 0).
Eigen::Vector3d ClipRow(const FanWalk& w, int jb, int& jc0, int& jc1) {
    const detail::FanColumns& fan = w.fan;
    const Eigen::Vector3d base = w.origin + static_cast<double>(jb) * w.step_b;
    const double om_row = fan.w_y * base.y() + fan.w_z * base.z();
    const double om_c = fan.w_y * w.step_c.y() + fan.w_z * w.step_c.z();
    const double tau_row = fan.c_y * base.y() + fan.c_z * base.z();
    const double tau_c = fan.c_y * w.step_c.y() + fan.c_z * w.step_c.z();
    const double x_row = base.x();
    const double x_c = w.step_c.x();
    const double X = w.x_max;
    // omega within the bins.
    ClipLinear(fan.omega0 - om_row, -om_c, jc0, jc1);
    ClipLinear(om_row - w.omega_end, om_c, jc0, jc1);
    if (w.in_plane) {
        // |x| <= X along the whole column.
        ClipLinear(x_row - X, x_c, jc0, jc1);
        ClipLinear(-X - x_row, -x_c, jc0, jc1);
    } else {
        // The column's stretch within |x| <= X must meet its stretch within the ping's tau
        // range: [(-X sgn - x0) / nx, (X sgn - x0) / nx] against [(tau_min - tau0) / g,
        // (tau_max - tau0) / g], with x0 and tau0 linear in jc.
        ClipLinear((-X * w.sgn_nx - x_row) * w.inv_nx - (fan.tau_max - tau_row) * w.inv_g,
                   -x_c * w.inv_nx + tau_c * w.inv_g,
                   jc0,
                   jc1);
        ClipLinear((fan.tau_min - tau_row) * w.inv_g - (X * w.sgn_nx - x_row) * w.inv_nx,
                   -tau_c * w.inv_g + x_c * w.inv_nx,
                   jc0,
                   jc1);
    }
    return base;
}

// The stretch [ja0, ja1] (within [lo_a, hi_a]) of the column starting at xs0 (its voxel a = 0)
// that can meet the ping: inside its bin's tau range and |x| <= the bin's x_max, and outside
// the cone cut. False when the column misses the ping.
bool ClipColumn(
    const FanWalk& w, const Eigen::Vector3d& xs0, int lo_a, int hi_a, int& ja0, int& ja1) {
    const detail::FanColumns& fan = w.fan;
    const double om = fan.w_y * xs0.y() + fan.w_z * xs0.z();
    const double jf = std::floor(om - fan.omega0);
    if (!(jf >= 0.0 && jf < static_cast<double>(fan.tau_lo.size()))) return false;
    const auto j = static_cast<std::size_t>(jf);
    const double tl = fan.tau_lo[j], th = fan.tau_hi[j];
    if (!(tl <= th)) return false;
    const double tau0 = fan.c_y * xs0.y() + fan.c_z * xs0.z();
    double t_lo = (tl - tau0) * w.inv_g;
    double t_hi = (th - tau0) * w.inv_g;
    const double xj = fan.x_max[j];
    if (w.in_plane) {
        if (std::abs(xs0.x()) > xj) return false;
    } else {
        const double t1 = (-xj - xs0.x()) * w.inv_nx;
        const double t2 = (xj - xs0.x()) * w.inv_nx;
        t_lo = std::max(t_lo, std::min(t1, t2));
        t_hi = std::min(t_hi, std::max(t1, t2));
    }
    t_lo = std::max(t_lo, static_cast<double>(lo_a));
    t_hi = std::min(t_hi, static_cast<double>(hi_a));
    if (!(t_lo <= t_hi)) return false;
    // The cone: further from the fan plane than any sector's h_out here, a voxel needs its
    // in-plane distance rho >= |x| / tan(bw / 2), and rho^2 = omega^2 + tau^2 (omega and tau are
    // orthonormal in the plane): |tau| >= sqrt(x^2 / tan^2 - omega^2), with |x| at its smallest
    // over the column's stretch.
    const double x_a = xs0.x() + w.nx * t_lo;
    const double x_b = xs0.x() + w.nx * t_hi;
    const double ax = (x_a > 0.0) == (x_b > 0.0) ? std::min(std::abs(x_a), std::abs(x_b)) : 0.0;
    const double q = ax * ax / w.tan2_bw - om * om;
    if (ax > fan.h_max[j] && q > 0.0) {
        const double tq = std::sqrt(q) * (1.0 - 1e-9) - 1e-6;
        const double tau_a = tau0 + fan.g * t_lo;
        const double tau_b = tau0 + fan.g * t_hi;
        if (tau_a > -tq && tau_b < tq) return false;  // all of it inside the cut
        if (tau_a > -tq) {
            t_lo = std::max(t_lo, (tq - tau0) * w.inv_g);
        } else if (tau_b < tq) {
            t_hi = std::min(t_hi, (-tq - tau0) * w.inv_g);
        }
    }
    ja0 = static_cast<int>(std::ceil(t_lo - 1e-9));
    ja1 = static_cast<int>(std::floor(t_hi + 1e-9));
    return ja0 <= ja1;
}

// The signed distance d (Eq. 4, voxels) of the voxel at sonar-frame (x, y, z) in sector fs:
// false when it lies outside the beam width or beyond the sector's reach, or |d| beyond T. The
// range at the voxel is interpolated linearly between the footprint range of the sector and its
// neighbour on the voxel's side, and along x by the footprint's along-track slope.
__attribute__((always_inline)) inline bool SectorDistance(
    const detail::FanSector& fs, const FanWalk& w, double x, double y, double z, double& d) {
    const double x2 = x * x;
    const double rho2 = y * y + z * z;
    // Beam width: |x| <= max(tan(bw / 2) rho, h_out).
    if (x2 > w.tan2_bw * rho2 && x2 > fs.h_out2) return false;
    const double dist2 = rho2 + x2;
    if (dist2 >= fs.far2) return false;
    // In-plane angle from the beam axis (|angle| <= inc/2, so tan = angle to 1e-6), as a signed
    // fraction of the increment: > 0 towards sector k + 1.
    const double frac = (fs.cos_theta * y - fs.sin_theta * z) /
                        (fs.sin_theta * y + fs.cos_theta * z) * w.fan.inv_increment;
    const double r_at =
        fs.range + std::abs(frac) * (frac >= 0.0 ? fs.dr_next : fs.dr_prev) +
        fs.dr_dx *
            std::clamp(x, static_cast<double>(fs.x_fit_lo), static_cast<double>(fs.x_fit_hi));
    d = r_at - std::sqrt(dist2);  // Eq. 4
    return d > -w.trunc && d <= w.trunc;
}

// Beam-width mode for one ping, restricted to the voxels of box (x and y). Each voxel belongs
// to the sector of its in-plane angle, [theta_k - inc/2, theta_k + inc/2), and is updated when
// its out-of-plane angle is within the beam (|phi| <= beam_width / 2; see h_out) and
// d = r_at - |v - p| lies in (-T, T] (SectorDistance). Candidates come in columns along the
// axis closest to the fan plane (FanColumns, fan_columns.cpp): rows and columns whose line
// cannot meet the ping are skipped by linear bounds (ClipRow), and each column is cut to its
// bin's tau and out-of-plane bounds (ClipColumn). The sector is tracked along the column by
// half-plane tests against the sector boundaries (SectorTracker, exact); a column starts from
// the previous column's sector, and atan2 is used only where tracking fails and for fans of
// 180 deg or more.
void IntegrateFan(const PreparedScan& scan,
                  const Geometry& g,
                  const ClipBox& box,
                  VoxelUpdater& up) {
    const detail::FanColumns& fan = scan.fan;
    if (fan.sectors.empty() || fan.tau_lo.empty()) return;
    const FanWalk w(scan, g);
    int lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
        lo[k] = fan.lo[k];
        hi[k] = fan.hi[k];
    }
    lo[0] = std::max(lo[0], box.x_min);
    hi[0] = std::min(hi[0], box.x_max);
    lo[1] = std::max(lo[1], box.y_min);
    hi[1] = std::min(hi[1], box.y_max);
    if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) return;
    const SectorTracker sectors(fan);
    const int track_steps = sectors.column_steps();

    int k_column = -2;  // sector of the previous column's first voxel (-2: none yet)
    Coord ijk;
    for (int jb = lo[w.b]; jb <= hi[w.b]; ++jb) {
        int jc0 = lo[w.c], jc1 = hi[w.c];
        const Eigen::Vector3d base = ClipRow(w, jb, jc0, jc1);  // (a, c) = (0, 0)
        ijk[w.b] = jb;
        for (int jc = jc0; jc <= jc1; ++jc) {
            const Eigen::Vector3d xs0 = base + static_cast<double>(jc) * w.step_c;  // a = 0
            int ja0, ja1;
            if (!ClipColumn(w, xs0, lo[w.a], hi[w.a], ja0, ja1)) continue;
            ijk[w.c] = jc;
            Eigen::Vector3d xs = xs0 + static_cast<double>(ja0) * w.step_a;
            // The first voxel's sector from the previous column's (neighbouring columns start
            // a sector or two apart), else from its angle.
            int k = k_column;
            {
                bool exact = false;
                if (k >= -1) k = sectors.Track(k, xs.y(), xs.z(), 8, exact);
                if (!exact) k = sectors.FromAngle(xs.y(), xs.z());
            }
            k_column = k;
            // The leaf pair of the current stretch of the column (a column enters a new leaf
            // every 8 voxels), looked up once per leaf.
            const VoxelUpdater::Slot* leaf = nullptr;
            int leaf_index = std::numeric_limits<int>::min();
            for (int ja = ja0; ja <= ja1; ++ja, xs += w.step_a) {
                const double x = xs.x(), y = xs.y(), z = xs.z();
                bool exact = false;
                k = sectors.Track(k, y, z, track_steps, exact);
                if (!exact) {
                    k = sectors.Track(sectors.FromAngle(y, z), y, z, track_steps, exact);
                    if (!exact) continue;  // only off a degenerate fan; not in any sector
                }
                if (k < 0 || k >= sectors.count()) continue;
                const detail::FanSector& fs = fan.sectors[static_cast<std::size_t>(k)];
                if (!(fs.weight > 0.0f)) continue;  // no footprint range in this sector
                double d;
                if (!SectorDistance(fs, w, x, y, z, d)) continue;
                ijk[w.a] = ja;
                if ((ja >> 3) != leaf_index) {
                    leaf = &up.LeafOf(ijk);
                    leaf_index = ja >> 3;
                }
                up.UpdateIn(*leaf,
                            LeafT::coordToOffset(ijk),
                            static_cast<float>(std::min(d, w.trunc) * g.metres_per_voxel),
                            fs.weight);
            }
        }
    }
}

// Ray mode: voxels traversed by the beam's centre ray between r - T and r + T (3-D DDA,
// Amanatides & Woo 1987), each updated with d = r - |v - p|.
void IntegrateRay(const PreparedScan& scan,
                  const PreparedBeam& beam,
                  float theta,
                  const Geometry& g,
                  const ClipBox& box,
                  VoxelUpdater& up) {
    const double r = beam.range_vox;
    const double T = g.trunc_vox;
    const Eigen::Vector3d u = scan.R * Eigen::Vector3d(0.0, std::sin(theta), std::cos(theta));
    const double q0 = std::max(0.0, r - T);
    const double q1 = r + T;
    // Voxel k covers [k - 0.5, k + 0.5): OpenVDB's DDA (Amanatides & Woo) walks the cells
    // [k, k + 1) of the shifted coordinates s = x + 0.5, from q0 to q1 along the beam.
    using Ray = openvdb::math::Ray<double>;
    const Eigen::Vector3d s0 = scan.p_vox + q0 * u + Eigen::Vector3d::Constant(0.5);
    const double length = q1 - q0;
    const Ray ray(Ray::Vec3Type(s0.x(), s0.y(), s0.z()), Ray::Vec3Type(u.x(), u.y(), u.z()));
    openvdb::math::DDA<Ray, 0> dda(ray, 0.0, length);
    do {
        const Coord& c = dda.voxel();
        if (c.x() >= box.x_min && c.x() <= box.x_max && c.y() >= box.y_min && c.y() <= box.y_max) {
            const Eigen::Vector3d v(c.x(), c.y(), c.z());
            const double d = r - (v - scan.p_vox).norm();  // Eq. 4
            if (d > -T && d <= T)
                up.Update(c, static_cast<float>(std::min(d, T) * g.metres_per_voxel));
        }
    } while (dda.step());
}

// The volume's existing leaves by slab: a slab's grid starts from copies of them when first
// touched.
struct OldLeaves {
    std::map<int, std::vector<const LeafT*>> distance, weight;
};
std::map<int, std::vector<const LeafT*>> LeavesBySlab(const FloatTree& tree) {
    std::map<int, std::vector<const LeafT*>> out;
    for (auto it = tree.cbeginLeaf(); it; ++it) {
        out[FloorDiv(it->origin().x(), kSlabVoxels)].push_back(&*it);
    }
    return out;
}

// One slab's own grids, persisting across chunks.
struct Slab {
    openvdb::FloatGrid::Ptr d, w;
    std::int64_t updates = 0;
    std::int64_t work = 0;  // beams of the current chunk that reach the slab
};
using SlabMap = std::map<int, Slab>;  // by slab index; std::map keeps references stable

// The scans [c0, c1) prepared (valid beams, footprint ranges, the x and y range of every beam),
// in parallel. Footprints of the chunk's scans and of the neighbours each one needs (`reach`
// each side, NeighbourPings: for the gap between pings and the along-track slope)
// are fitted once, into `footprints` (reused across chunks).
void PrepareChunk(const std::vector<SonarScan>& scans,
                  std::size_t c0,
                  std::size_t c1,
                  std::size_t reach,
                  const TsdfConfig& config,
                  const Geometry& geo,
                  tbb::task_arena& arena,
                  std::vector<detail::ScanFootprints>& footprints,
                  std::vector<PreparedScan>& prepared) {
    prepared.assign(c1 - c0, PreparedScan{});
    const std::size_t f0 = c0 - std::min(c0, reach);
    const std::size_t f1 = std::min(scans.size(), c1 + reach);
    footprints.assign(f1 - f0, detail::ScanFootprints{});
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(f0, f1, 64),
                          [&](const tbb::blocked_range<std::size_t>& range) {
                              for (std::size_t si = range.begin(); si != range.end(); ++si) {
                                  footprints[si - f0] = detail::FitFootprints(scans[si], config);
                              }
                          });
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(c0, c1, 64),
            [&](const tbb::blocked_range<std::size_t>& range) {
                std::vector<detail::ScanNeighbour> nbs;
                for (std::size_t si = range.begin(); si != range.end(); ++si) {
                    nbs.clear();
                    for (std::size_t j = std::max(f0, si - std::min(si, reach));
                         j < std::min(f1, si + reach + 1);
                         ++j) {
                        if (j == si) continue;
                        nbs.push_back({&scans[j],
                                       &footprints[j - f0],
                                       static_cast<int>(static_cast<std::ptrdiff_t>(j) -
                                                        static_cast<std::ptrdiff_t>(si))});
                    }
                    prepared[si - c0] =
                        detail::PrepareScan(scans[si], footprints[si - f0], config, geo, nbs);
                }
            });
    });
}

// Adds the prepared scans' counters to `result`; returns their beams.
std::size_t CountPrepared(const std::vector<PreparedScan>& prepared, IntegrateResult& result) {
    std::size_t beams = 0;
    for (const PreparedScan& ps : prepared) {
        result.beams_used += ps.beams_used;
        result.beams_no_detection += ps.beams_no_detection;
        result.beams_out_of_range += ps.beams_out_of_range;
        result.scans_out_of_bounds += ps.out_of_bounds ? 1 : 0;
        result.beams_inconsistent += ps.beams_inconsistent;
        beams += ps.beams.size();
    }
    return beams;
}

// Each slab's work for the chunk: the beams that reach it. A slab reached for the first time
// gets its grids, from copies of the volume's old leaves there.
void AssignSlabs(const std::vector<PreparedScan>& prepared,
                 const OldLeaves& old,
                 float trunc,
                 double voxel_size_m,
                 const ClipBox& region,
                 SlabMap& slabs) {
    for (auto& entry : slabs) entry.second.work = 0;  // (views::values: not with clang 14)
    int last_k = std::numeric_limits<int>::min();
    Slab* last = nullptr;
    const int k_min = FloorDiv(region.x_min, kSlabVoxels);
    const int k_max = FloorDiv(region.x_max, kSlabVoxels);
    for (const PreparedScan& ps : prepared) {
        for (const PreparedBeam& pb : ps.beams) {
            if (pb.y_hi < region.y_min || pb.y_lo > region.y_max) continue;
            for (int k = std::max(k_min, FloorDiv(pb.x_lo, kSlabVoxels));
                 k <= std::min(k_max, FloorDiv(pb.x_hi, kSlabVoxels));
                 ++k) {
                if (k != last_k) {
                    last = &slabs[k];
                    last_k = k;
                }
                Slab& slab = *last;
                if (!slab.d) {
                    slab.d = MakeGrid(trunc, voxel_size_m, "tsdf");
                    slab.w = MakeGrid(0.0f, voxel_size_m, "weight");
                    if (auto it = old.distance.find(k); it != old.distance.end()) {
                        for (const LeafT* leaf : it->second)
                            slab.d->tree().addLeaf(new LeafT(*leaf));
                    }
                    if (auto it = old.weight.find(k); it != old.weight.end()) {
                        for (const LeafT* leaf : it->second)
                            slab.w->tree().addLeaf(new LeafT(*leaf));
                    }
                }
                ++slab.work;
            }
        }
    }
}

// What a slab task needs besides its slab: the chunk's scans and how to integrate them.
struct ChunkWork {
    const std::vector<PreparedScan>& prepared;
    const std::vector<SonarScan>& scans;
    std::size_t scan_offset;  // scans[scan_offset + i] is prepared[i]
    const Geometry& geo;
    bool beam_width;  // IntegrateFan, else IntegrateRay per beam
    float f, w_max;
    const std::atomic<bool>& cancel;
    ClipBox region;  // the volume's region (slab- and band-aligned), or everything
};

// One scan's voxels inside box.
void IntegrateScanInBox(const ChunkWork& work,
                        std::size_t si,
                        const ClipBox& box,
                        VoxelUpdater& up) {
    const PreparedScan& ps = work.prepared[si];
    if (ps.beams.empty() || ps.x_hi < box.x_min || ps.x_lo > box.x_max || ps.y_hi < box.y_min ||
        ps.y_lo > box.y_max) {
        return;
    }
    if (work.beam_width) {
        IntegrateFan(ps, work.geo, box, up);
        return;
    }
    const SonarScan& scan = work.scans[work.scan_offset + si];
    for (const PreparedBeam& pb : ps.beams) {
        if (pb.x_hi < box.x_min || pb.x_lo > box.x_max || pb.y_hi < box.y_min ||
            pb.y_lo > box.y_max) {
            continue;
        }
        const float theta =
            scan.start_angle_rad + static_cast<float>(pb.beam) * scan.angle_increment_rad;
        IntegrateRay(ps, pb, theta, work.geo, box, up);
    }
}

// Integrates the chunk's scans into slab k, scan by scan in input order: runs of kBatchScans
// scans, band by band along y.
void IntegrateSlab(const ChunkWork& work, int k, Slab& slab) {
    const int sx0 = k * kSlabVoxels;
    const int sx1 = sx0 + kSlabVoxels - 1;
    const std::vector<PreparedScan>& prepared = work.prepared;
    VoxelUpdater up(*slab.d, *slab.w, work.f, work.w_max);
    for (std::size_t s0 = 0; s0 < prepared.size(); s0 += kBatchScans) {
        if (work.cancel.load(std::memory_order_relaxed)) break;
        const std::size_t s1 = std::min(prepared.size(), s0 + kBatchScans);
        int y_lo = std::numeric_limits<int>::max();
        int y_hi = std::numeric_limits<int>::min();
        for (std::size_t si = s0; si < s1; ++si) {
            const PreparedScan& ps = prepared[si];
            if (ps.beams.empty() || ps.x_hi < sx0 || ps.x_lo > sx1) continue;
            y_lo = std::min(y_lo, ps.y_lo);
            y_hi = std::max(y_hi, ps.y_hi);
        }
        y_lo = std::max(y_lo, work.region.y_min);
        y_hi = std::min(y_hi, work.region.y_max);
        if (y_lo > y_hi) continue;
        for (int band = FloorDiv(y_lo, kBandVoxels); band <= FloorDiv(y_hi, kBandVoxels); ++band) {
            const ClipBox box{sx0, sx1, band * kBandVoxels, band * kBandVoxels + kBandVoxels - 1};
            for (std::size_t si = s0; si < s1; ++si) IntegrateScanInBox(work, si, box, up);
        }
    }
    slab.updates += up.updates();
}

// The chunk's slabs in parallel, largest first, each worker taking the next (greedy
// longest-processing-time order, so the last slab of a chunk is a small one).
void RasteriseChunk(const ChunkWork& work, SlabMap& slabs, tbb::task_arena& arena, int threads) {
    std::vector<std::pair<std::int64_t, int>> order;
    for (const auto& [k, slab] : slabs) {
        if (slab.work > 0) order.emplace_back(-slab.work, k);
    }
    std::sort(order.begin(), order.end());
    std::atomic<std::size_t> next{0};
    arena.execute([&] {
        tbb::task_group tasks;
        for (int t = 0; t < threads; ++t) {
            tasks.run([&] {
                for (std::size_t i = next++; i < order.size(); i = next++) {
                    const int k = order[i].second;
                    IntegrateSlab(work, k, slabs.at(k));
                }
            });
        }
        tasks.wait();
    });
}

// The volume's new grids: the old leaves of untouched slabs plus every slab's leaves (moved,
// not copied). Returns the slabs' voxel updates.
std::int64_t MergeSlabs(SlabMap& slabs,
                        float trunc,
                        double voxel_size_m,
                        openvdb::FloatGrid::Ptr& distance,
                        openvdb::FloatGrid::Ptr& weight) {
    auto new_d = MakeGrid(trunc, voxel_size_m, "tsdf");
    auto new_w = MakeGrid(0.0f, voxel_size_m, "weight");
    auto keep_outside = [&](const FloatTree& from, FloatTree& to) {
        for (auto it = from.cbeginLeaf(); it; ++it) {
            if (!slabs.contains(FloorDiv(it->origin().x(), kSlabVoxels))) {
                to.addLeaf(new LeafT(*it));
            }
        }
    };
    keep_outside(distance->tree(), new_d->tree());
    keep_outside(weight->tree(), new_w->tree());
    distance.reset();
    weight.reset();
    std::int64_t updates = 0;
    for (auto& [k, slab] : slabs) {
        new_d->tree().merge(slab.d->tree());
        new_w->tree().merge(slab.w->tree());
        slab.d.reset();
        slab.w.reset();
        updates += slab.updates;
    }
    distance = new_d;
    weight = new_w;
    return updates;
}

// Everything, as a ClipBox (far beyond kMaxSonarOffsetM + kMaxRangeVoxels voxels, and with
// room for FloorDiv).
constexpr int kFar = 1 << 30;
constexpr ClipBox kEverywhere{-kFar, kFar, -kFar, kFar};

// Whether scan `scan` can update a voxel of `region` (voxel indices): ReachOf meets the
// region's columns (their world extent, half a voxel beyond the centres).
bool ScanReaches(const SonarScan& scan, const TsdfConfig& config, const ClipBox& region) {
    const ScanReach r = ReachOf(scan, config);
    if (r.empty()) return false;
    const double s = config.voxel_size_m;
    return r.x_max >= (region.x_min - 0.5) * s && r.x_min <= (region.x_max + 0.5) * s &&
           r.y_max >= (region.y_min - 0.5) * s && r.y_min <= (region.y_max + 0.5) * s;
}

// The runs of consecutive scans of [begin, end) that can reach the region (all of them without
// one).
std::vector<std::pair<std::size_t, std::size_t>> ScanRuns(const std::vector<SonarScan>& scans,
                                                          std::size_t begin,
                                                          std::size_t end,
                                                          const TsdfConfig& config,
                                                          const std::optional<VoxelColumns>& r) {
    std::vector<std::pair<std::size_t, std::size_t>> runs;
    if (!r) {
        if (begin < end) runs.emplace_back(begin, end);
        return runs;
    }
    const ClipBox region{r->x_min, r->x_max, r->y_min, r->y_max};
    for (std::size_t i = begin; i < end; ++i) {
        if (!ScanReaches(scans[i], config, region)) continue;
        if (!runs.empty() && runs.back().second == i) {
            runs.back().second = i + 1;
        } else {
            runs.emplace_back(i, i + 1);
        }
    }
    return runs;
}

double SecondsSince(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Valid beams of one scan with the x range of world voxel indices each can touch. Beam-width
// mode replaces each range by its footprint range (FitFootprint) and gives each sector the
// weight f times the footprint's support; a sector whose own beam is a dropout but whose
// footprint sees the surface is integrated too (the footprint covers it).

}  // namespace

std::vector<std::string> TsdfConfig::Validate() const {
    std::vector<std::string> problems;
    if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m)) {
        problems.push_back("voxel_size_m must be > 0");
    }
    if (!(truncation_m > 0.0) || !std::isfinite(truncation_m)) {
        problems.push_back("truncation_m must be > 0");
    } else if (voxel_size_m > 0.0 && truncation_m < voxel_size_m) {
        problems.push_back("truncation_m must be at least one voxel (voxel_size_m)");
    }
    if (!(weight_per_measurement > 0.0f) || !std::isfinite(weight_per_measurement)) {
        problems.push_back("weight_per_measurement must be > 0");
    }
    if (!(max_weight >= weight_per_measurement) || !std::isfinite(max_weight)) {
        problems.push_back("max_weight must be >= weight_per_measurement and finite");
    }
    if (!(beam_width_rad > 0.0) || beam_width_rad >= 3.0) {
        problems.push_back("beam_width_rad must be in (0, 3)");
    }
    if (!(min_range_m >= 0.0)) problems.push_back("min_range_m must be >= 0");
    if (!(max_range_m > min_range_m)) problems.push_back("max_range_m must be > min_range_m");
    // The beam-width rasteriser bins each ping's fan per voxel across its columns (~16 bytes
    // a bin, 4 x the range in voxels); a range gate of more than kMaxRangeVoxels would let a
    // file of absurd ranges take gigabytes per chunk of pings.
    if (voxel_size_m > 0.0 && std::isfinite(voxel_size_m) &&
        !(max_range_m <= kMaxRangeVoxels * voxel_size_m)) {
        problems.push_back("max_range_m must be at most " +
                           std::to_string(static_cast<int>(kMaxRangeVoxels)) + " voxels (" +
                           std::to_string(kMaxRangeVoxels * voxel_size_m) + " m at voxel_size_m " +
                           std::to_string(voxel_size_m) + ")");
    }
    if (!(footprint_gate_m > 0.0) || !std::isfinite(footprint_gate_m)) {
        problems.push_back("footprint_gate_m must be > 0");
    }
    if (!(footprint_gate_fraction >= 0.0) || !std::isfinite(footprint_gate_fraction)) {
        problems.push_back("footprint_gate_fraction must be >= 0");
    }
    if (!(ping_gap_fill_m >= 0.0) || !std::isfinite(ping_gap_fill_m)) {
        problems.push_back("ping_gap_fill_m must be >= 0 (0 = off)");
    }
    if (ping_gap_bridge_pings < 0 || ping_gap_bridge_pings > kMaxBridgePings) {
        problems.push_back("ping_gap_bridge_pings must be in [0, " +
                           std::to_string(kMaxBridgePings) + "] (0 = off)");
    }
    if (footprint_neighbour_pings < 0 || footprint_neighbour_pings > kMaxFootprintNeighbourPings) {
        problems.push_back("footprint_neighbour_pings must be in [0, " +
                           std::to_string(kMaxFootprintNeighbourPings) + "] (0 = off)");
    }
    if (num_threads < 0) problems.push_back("num_threads must be >= 0 (0 = all cores)");
    return problems;
}

std::vector<std::string> WeightFilterConfig::Validate() const {
    std::vector<std::string> problems;
    if (!(min_weight >= 0.0f) || !std::isfinite(min_weight)) {
        problems.push_back("min_weight must be >= 0 and finite");
    }
    return problems;
}

TsdfVolume::TsdfVolume(const TsdfConfig& config) : config_(config), impl_(new Impl) {
    openvdb::initialize();
    impl_->distance =
        MakeGrid(static_cast<float>(config_.truncation_m), config_.voxel_size_m, "tsdf");
    impl_->weight = MakeGrid(0.0f, config_.voxel_size_m, "weight");
}

TsdfVolume::TsdfVolume(const TsdfConfig& config, const VoxelColumns& region) : TsdfVolume(config) {
    PITMAP_CHECK(region.Aligned(), "TsdfVolume: region not on kRegionAlignVoxels");
    region_ = region;
}

ScanReach ReachOf(const SonarScan& scan, const TsdfConfig& config) {
    ScanReach out;
    const Eigen::Vector3d p = scan.T_world_sonar.translation();
    const Eigen::Matrix3d R = scan.T_world_sonar.linear();
    if (!p.allFinite() || !R.allFinite()) {
        constexpr double kAll = 1e12;
        return {-kAll, kAll, -kAll, kAll};
    }
    double r_max = 0;
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
        const float r = scan.ranges_m[i];
        if (!(std::isfinite(r) && r >= config.min_range_m && r <= config.max_range_m)) continue;
        const float theta = scan.start_angle_rad + static_cast<float>(i) * scan.angle_increment_rad;
        const Eigen::Vector3d hit =
            p + R * Eigen::Vector3d(0.0, std::sin(theta), std::cos(theta)) * static_cast<double>(r);
        x0 = std::min(x0, hit.x());
        x1 = std::max(x1, hit.x());
        y0 = std::min(y0, hit.y());
        y1 = std::max(y1, hit.y());
        r_max = std::max(r_max, static_cast<double>(r));
    }
    if (r_max == 0) return out;
    const double margin =
        config.truncation_m + 0.1 * r_max + detail::WidestGapM(config) + 2 * config.voxel_size_m;
    return {x0 - margin, x1 + margin, y0 - margin, y1 + margin};
}

bool VoxelColumns::Aligned() const {
    const auto on = [](std::int32_t v) { return v % kRegionAlignVoxels == 0; };
    return x_min <= x_max && y_min <= y_max && on(x_min) && on(y_min) && on(x_max + 1) &&
           on(y_max + 1);
}

TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

IntegrateResult TsdfVolume::Integrate(const std::vector<SonarScan>& scans,
                                      const ProgressCallback& progress) {
    return Integrate(scans, 0, scans.size(), progress);
}

IntegrateResult TsdfVolume::Integrate(const std::vector<SonarScan>& scans,
                                      std::size_t begin,
                                      std::size_t end,
                                      const ProgressCallback& progress) {
    end = std::min(end, scans.size());
    begin = std::min(begin, end);
    const auto t_start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    IntegrateResult result;
    result.scans = static_cast<std::int64_t>(end - begin);
    const double inv_s = 1.0 / config_.voxel_size_m;
    const Geometry geo{config_.truncation_m * inv_s,
                       std::tan(0.5 * config_.beam_width_rad),
                       std::cos(0.5 * config_.beam_width_rad),
                       config_.voxel_size_m};
    const int threads =
        config_.num_threads > 0 ? config_.num_threads : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(threads);
    const float trunc = static_cast<float>(config_.truncation_m);
    const OldLeaves old{LeavesBySlab(impl_->distance->tree()), LeavesBySlab(impl_->weight->tree())};
    const auto reach = static_cast<std::size_t>(NeighbourPings(config_));

    // Chunk by chunk: prepare the chunk's scans in parallel, then integrate it slab by slab.
    // Only one chunk's prepared beams are held at a time; the slab grids persist across chunks.
    SlabMap slabs;
    std::atomic<bool> cancel{false};
    std::size_t total_beams = 0;
    std::vector<PreparedScan> prepared;
    std::vector<detail::ScanFootprints> footprints;  // of one chunk and its neighbours
    const ClipBox region =
        region_ ? ClipBox{region_->x_min, region_->x_max, region_->y_min, region_->y_max}
                : kEverywhere;
    // Chunks of the runs of scans that can reach the region (one run of all without a region).
    std::vector<std::pair<std::size_t, std::size_t>> chunks;
    for (const auto& [r0, r1] : ScanRuns(scans, begin, end, config_, region_)) {
        for (std::size_t c0 = r0; c0 < r1; c0 += kChunkScans)
            chunks.emplace_back(c0, std::min(r1, c0 + kChunkScans));
    }
    for (const auto& [c0, c1] : chunks) {
        if (cancel.load()) break;
        const auto t_prepare = std::chrono::steady_clock::now();
        PrepareChunk(scans, c0, c1, reach, config_, geo, arena, footprints, prepared);
        total_beams += CountPrepared(prepared, result);
        AssignSlabs(prepared, old, trunc, config_.voxel_size_m, region, slabs);
        result.prepare_s += SecondsSince(t_prepare);

        const auto t_raster = std::chrono::steady_clock::now();
        const ChunkWork work{prepared,
                             scans,
                             c0,
                             geo,
                             config_.sensor_model == SensorModel::kBeamWidth,
                             config_.weight_per_measurement,
                             config_.max_weight,
                             cancel,
                             region};
        RasteriseChunk(work, slabs, arena, threads);
        result.rasterise_s += SecondsSince(t_raster);
        if (progress &&
            !progress(static_cast<double>(c1 - begin) / static_cast<double>(end - begin))) {
            cancel = true;
        }
    }
    prepared = {};
    footprints = {};
    if (total_beams == 0) {
        result.active_voxels = static_cast<std::int64_t>(impl_->weight->activeVoxelCount());
        result.elapsed_s = SecondsSince(t_start);
        result.cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
        result.message = "no valid beams";
        return result;
    }

    const auto t_merge = std::chrono::steady_clock::now();
    result.voxel_updates +=
        MergeSlabs(slabs, trunc, config_.voxel_size_m, impl_->distance, impl_->weight);
    result.merge_s = SecondsSince(t_merge);
    result.cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    result.cancelled = cancel.load();
    result.active_voxels = static_cast<std::int64_t>(impl_->weight->activeVoxelCount());
    result.elapsed_s = SecondsSince(t_start);
    result.message = std::string(result.cancelled ? "cancelled: " : "") +
                     std::to_string(result.beams_used) + " beams (" +
                     std::to_string(result.beams_inconsistent) + " outvoted by footprints), " +
                     std::to_string(result.voxel_updates) + " voxel updates, " +
                     std::to_string(result.active_voxels) + " active voxels";
    return result;
}

}  // namespace pitmap::proc::fusion
