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
// Inside a slab, runs of kBatchScans scans are replayed band by band along y (kBandVoxels wide):
// a ping's fan crosses the whole swath, and walking it band by band keeps the leaves of the
// last few pings in the core's cache instead of streaming the swath's leaves for every ping.
// Each voxel lies in one band, so it still sees its updates in input order.
constexpr int kBandVoxels = 64;
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

// Beam-width mode for one ping, restricted to the voxels of box (x and y). Each voxel belongs
// to the sector of its in-plane angle, [theta_k - inc/2, theta_k + inc/2), and is updated when
// its out-of-plane angle is within the beam (|phi| <= beam_width / 2; see h_out below) and
// d = r_at - |v - p| lies in (-T, T], where r_at is interpolated linearly between the footprint
// range of sector k and its neighbour on the voxel's side. Candidates come in columns along the
// axis closest to the fan plane (FanColumns, fan_columns.cpp): rows and columns whose line
// cannot meet the ping are skipped by linear bounds, and each column is cut to its bin's tau
// and out-of-plane bounds. The sector is tracked along the column by half-plane tests against
// the sector boundaries (exact); a column starts from the previous column's sector, and atan2
// is used only where tracking fails and for fans of 180 deg or more.
void IntegrateFan(const PreparedScan& scan,
                  const Geometry& g,
                  const ClipBox& box,
                  VoxelUpdater& up) {
    const detail::FanColumns& fan = scan.fan;
    if (fan.sectors.empty() || fan.tau_lo.empty()) return;
    const int a = fan.axis;
    const int b_ax = (a + 1) % 3;
    const int c_ax = (a + 2) % 3;
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

    const Eigen::Matrix3d& R = scan.R;
    const Eigen::Vector3d q0 = -(R.transpose() * scan.p_vox);  // sonar frame of voxel (0,0,0)
    const Eigen::Vector3d rb(R(b_ax, 0), R(b_ax, 1), R(b_ax, 2));
    const Eigen::Vector3d rc(R(c_ax, 0), R(c_ax, 1), R(c_ax, 2));
    const Eigen::Vector3d& ra = fan.step;
    const double nx = ra.x();
    const bool in_plane = std::abs(nx) < 1e-9;  // columns parallel to the fan plane
    const double inv_nx = in_plane ? 0.0 : 1.0 / nx;
    const double sgn_nx = nx >= 0.0 ? 1.0 : -1.0;
    const double inv_g = 1.0 / fan.g;
    const double om_end = fan.omega0 + static_cast<double>(fan.tau_lo.size());
    const double X = fan.x_max_all;
    const double T = g.trunc_vox;
    const double tan2_bw = g.tan_half_bw * g.tan_half_bw;
    const int n_sect = static_cast<int>(fan.sectors.size());
    const double* side_y = fan.side_y.data();
    const double* side_z = fan.side_z.data();
    // Index >= k (k in [0, n_sect]) when the voxel lies on the far side of boundary k.
    auto at_or_above = [&](int k, double y, double z) {
        return side_y[k] * y + side_z[k] * z >= 0.0;
    };
    // Sector of (y, z) from a guess k in [-1, n_sect] (-1 and n_sect: outside the fan); the
    // state is exact when both boundary tests agree, which the walk reaches in a step or two.
    // Off a fan of 180 deg or more the tests are not monotone across sectors: only the angle's
    // own sector is checked (exact: a sector's two tests bound it alone).
    const int track_steps = fan.wide ? 0 : 4;
    auto sector = [&](int k, double y, double z, int max_steps, bool& exact) {
        if (fan.wide) max_steps = 0;
        if (max_steps == 0) {
            exact = k >= 0 && k < n_sect && at_or_above(k, y, z) && !at_or_above(k + 1, y, z);
            return k;
        }
        for (int it = 0; it < max_steps; ++it) {
            if (k < n_sect && at_or_above(k + 1, y, z)) {
                ++k;
            } else if (k >= 0 && !at_or_above(k, y, z)) {
                --k;
            } else {
                exact = true;
                return k;
            }
        }
        exact = false;
        return k;
    };
    auto sector_from_angle = [&](double y, double z) {
        const double k = std::floor((std::atan2(y, z) - fan.start_angle) * fan.inv_increment + 0.5);
        return static_cast<int>(std::clamp(k, -1.0, static_cast<double>(n_sect)));
    };

    int k_column = -2;  // sector of the previous column's first voxel (-2: none yet)
    Coord ijk;
    for (int jb = lo[b_ax]; jb <= hi[b_ax]; ++jb) {
        const Eigen::Vector3d base = q0 + static_cast<double>(jb) * rb;  // (a, c) = (0, 0)
        const double om_row = fan.w_y * base.y() + fan.w_z * base.z();
        const double om_c = fan.w_y * rc.y() + fan.w_z * rc.z();
        const double tau_row = fan.c_y * base.y() + fan.c_z * base.z();
        const double tau_c = fan.c_y * rc.y() + fan.c_z * rc.z();
        const double x_row = base.x();
        const double x_c = rc.x();
        int jc0 = lo[c_ax], jc1 = hi[c_ax];
        // omega within the bins.
        ClipLinear(fan.omega0 - om_row, -om_c, jc0, jc1);
        ClipLinear(om_row - om_end, om_c, jc0, jc1);
        if (in_plane) {
            // |x| <= X along the whole column.
            ClipLinear(x_row - X, x_c, jc0, jc1);
            ClipLinear(-X - x_row, -x_c, jc0, jc1);
        } else {
            // The column's stretch within |x| <= X must meet its stretch within the ping's tau
            // range: [(-X sgn - x0) / nx, (X sgn - x0) / nx] against [(tau_min - tau0) / g,
            // (tau_max - tau0) / g], with x0 and tau0 linear in jc.
            ClipLinear((-X * sgn_nx - x_row) * inv_nx - (fan.tau_max - tau_row) * inv_g,
                       -x_c * inv_nx + tau_c * inv_g,
                       jc0,
                       jc1);
            ClipLinear((fan.tau_min - tau_row) * inv_g - (X * sgn_nx - x_row) * inv_nx,
                       -tau_c * inv_g + x_c * inv_nx,
                       jc0,
                       jc1);
        }
        ijk[b_ax] = jb;
        for (int jc = jc0; jc <= jc1; ++jc) {
            const Eigen::Vector3d xs0 = base + static_cast<double>(jc) * rc;  // a = 0
            const double om = fan.w_y * xs0.y() + fan.w_z * xs0.z();
            const double jf = std::floor(om - fan.omega0);
            if (!(jf >= 0.0 && jf < static_cast<double>(fan.tau_lo.size()))) continue;
            const auto j = static_cast<std::size_t>(jf);
            const double tl = fan.tau_lo[j], th = fan.tau_hi[j];
            if (!(tl <= th)) continue;
            const double tau0 = fan.c_y * xs0.y() + fan.c_z * xs0.z();
            double t_lo = (tl - tau0) * inv_g;
            double t_hi = (th - tau0) * inv_g;
            const double xj = fan.x_max[j];
            if (in_plane) {
                if (std::abs(xs0.x()) > xj) continue;
            } else {
                const double t1 = (-xj - xs0.x()) * inv_nx;
                const double t2 = (xj - xs0.x()) * inv_nx;
                t_lo = std::max(t_lo, std::min(t1, t2));
                t_hi = std::min(t_hi, std::max(t1, t2));
            }
            t_lo = std::max(t_lo, static_cast<double>(lo[a]));
            t_hi = std::min(t_hi, static_cast<double>(hi[a]));
            if (!(t_lo <= t_hi)) continue;
            // The cone: further from the fan plane than any sector's h_out here, a voxel needs
            // its in-plane distance rho >= |x| / tan(bw / 2), and rho^2 = omega^2 + tau^2
            // (omega and tau are orthonormal in the plane): |tau| >= sqrt(x^2 / tan^2 -
            // omega^2), with |x| at its smallest over the column's stretch.
            {
                const double x_a = xs0.x() + nx * t_lo;
                const double x_b = xs0.x() + nx * t_hi;
                const double ax =
                    (x_a > 0.0) == (x_b > 0.0) ? std::min(std::abs(x_a), std::abs(x_b)) : 0.0;
                const double q = ax * ax / tan2_bw - om * om;
                if (ax > fan.h_max[j] && q > 0.0) {
                    const double tq = std::sqrt(q) * (1.0 - 1e-9) - 1e-6;
                    const double tau_a = tau0 + fan.g * t_lo;
                    const double tau_b = tau0 + fan.g * t_hi;
                    if (tau_a > -tq && tau_b < tq) continue;  // all of it inside the cut
                    if (tau_a > -tq) {
                        t_lo = std::max(t_lo, (tq - tau0) * inv_g);
                    } else if (tau_b < tq) {
                        t_hi = std::min(t_hi, (-tq - tau0) * inv_g);
                    }
                }
            }
            const int ja0 = static_cast<int>(std::ceil(t_lo - 1e-9));
            const int ja1 = static_cast<int>(std::floor(t_hi + 1e-9));
            if (ja0 > ja1) continue;
            ijk[c_ax] = jc;
            Eigen::Vector3d xs = xs0 + static_cast<double>(ja0) * ra;
            // The first voxel's sector from the previous column's (neighbouring columns start
            // a sector or two apart), else from its angle.
            int k = k_column;
            {
                bool exact = false;
                if (k >= -1) k = sector(k, xs.y(), xs.z(), 8, exact);
                if (!exact) k = sector_from_angle(xs.y(), xs.z());
            }
            k_column = k;
            // The leaf pair of the current stretch of the column (a column enters a new leaf
            // every 8 voxels), looked up once per leaf.
            const VoxelUpdater::Slot* leaf = nullptr;
            int leaf_index = std::numeric_limits<int>::min();
            for (int ja = ja0; ja <= ja1; ++ja, xs += ra) {
                const double x = xs.x(), y = xs.y(), z = xs.z();
                bool exact = false;
                k = sector(k, y, z, track_steps, exact);
                if (!exact) {
                    k = sector(sector_from_angle(y, z), y, z, track_steps, exact);
                    if (!exact) continue;  // only off a degenerate fan; not in any sector
                }
                if (k < 0 || k >= n_sect) continue;
                const detail::FanSector& fs = fan.sectors[static_cast<std::size_t>(k)];
                if (!(fs.weight > 0.0f)) continue;  // no footprint range in this sector
                const double x2 = x * x;
                const double rho2 = y * y + z * z;
                // Beam width: |x| <= max(tan(bw / 2) rho, h_out).
                if (x2 > tan2_bw * rho2 && x2 > fs.h_out2) continue;
                const double dist2 = rho2 + x2;
                if (dist2 >= fs.far2) continue;
                // In-plane angle from the beam axis (|angle| <= inc/2, so tan = angle to 1e-6),
                // as a signed fraction of the increment: > 0 towards sector k + 1.
                const double frac = (fs.cos_theta * y - fs.sin_theta * z) /
                                    (fs.sin_theta * y + fs.cos_theta * z) * fan.inv_increment;
                const double r_at = fs.range +
                                    std::abs(frac) * (frac >= 0.0 ? fs.dr_next : fs.dr_prev) +
                                    fs.dr_dx * std::clamp(x,
                                                          static_cast<double>(fs.x_fit_lo),
                                                          static_cast<double>(fs.x_fit_hi));
                const double d = r_at - std::sqrt(dist2);  // Eq. 4
                if (!(d > -T && d <= T)) continue;
                ijk[a] = ja;
                if ((ja >> 3) != leaf_index) {
                    leaf = &up.LeafOf(ijk);
                    leaf_index = ja >> 3;
                }
                up.UpdateIn(*leaf,
                            LeafT::coordToOffset(ijk),
                            static_cast<float>(std::min(d, T) * g.metres_per_voxel),
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
    auto since = [](std::chrono::steady_clock::time_point t) {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    };
    IntegrateResult result;
    result.scans = static_cast<std::int64_t>(end - begin);
    const double inv_s = 1.0 / config_.voxel_size_m;
    const Geometry geo{config_.truncation_m * inv_s,
                       std::tan(0.5 * config_.beam_width_rad),
                       std::cos(0.5 * config_.beam_width_rad),
                       config_.voxel_size_m};
    const bool beam_width = config_.sensor_model == SensorModel::kBeamWidth;

    const int threads =
        config_.num_threads > 0 ? config_.num_threads : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(threads);

    const float f = config_.weight_per_measurement;
    const float w_max = config_.max_weight;
    const float trunc = static_cast<float>(config_.truncation_m);

    // Existing leaves by slab: a slab's grid starts from copies of them when first touched.
    std::map<int, std::vector<const LeafT*>> old_d, old_w;
    auto bucket = [&](const FloatTree& tree, std::map<int, std::vector<const LeafT*>>& out) {
        for (auto it = tree.cbeginLeaf(); it; ++it) {
            out[FloorDiv(it->origin().x(), kSlabVoxels)].push_back(&*it);
        }
    };
    bucket(impl_->distance->tree(), old_d);
    bucket(impl_->weight->tree(), old_w);

    struct Slab {
        openvdb::FloatGrid::Ptr d, w;
        std::int64_t updates = 0;
        std::int64_t work = 0;  // beams of the current chunk that reach the slab
    };
    std::map<int, Slab> slabs;  // by slab index; std::map keeps references stable
    std::atomic<bool> cancel{false};
    std::size_t total_beams = 0;
    std::vector<PreparedScan> prepared;
    std::vector<detail::ScanFootprints> footprints;  // of one chunk and its neighbours
    const auto reach = static_cast<std::size_t>(std::max(1, config_.footprint_neighbour_pings));

    // Integrates the chunk's scans [0, prepared.size()) into one slab, scan by scan in order.
    auto run_slab = [&](int k, std::size_t scan_offset) {
        Slab& slab = slabs.at(k);
        const int sx0 = k * kSlabVoxels;
        const int sx1 = sx0 + kSlabVoxels - 1;
        VoxelUpdater up(*slab.d, *slab.w, f, w_max);
        for (std::size_t s0 = 0; s0 < prepared.size(); s0 += kBatchScans) {
            if (cancel.load(std::memory_order_relaxed)) break;
            const std::size_t s1 = std::min(prepared.size(), s0 + kBatchScans);
            int y_lo = std::numeric_limits<int>::max();
            int y_hi = std::numeric_limits<int>::min();
            for (std::size_t si = s0; si < s1; ++si) {
                const PreparedScan& ps = prepared[si];
                if (ps.beams.empty() || ps.x_hi < sx0 || ps.x_lo > sx1) continue;
                y_lo = std::min(y_lo, ps.y_lo);
                y_hi = std::max(y_hi, ps.y_hi);
            }
            if (y_lo > y_hi) continue;
            for (int band = FloorDiv(y_lo, kBandVoxels); band <= FloorDiv(y_hi, kBandVoxels);
                 ++band) {
                const ClipBox box{
                    sx0, sx1, band * kBandVoxels, band * kBandVoxels + kBandVoxels - 1};
                for (std::size_t si = s0; si < s1; ++si) {
                    const PreparedScan& ps = prepared[si];
                    if (ps.beams.empty() || ps.x_hi < box.x_min || ps.x_lo > box.x_max ||
                        ps.y_hi < box.y_min || ps.y_lo > box.y_max) {
                        continue;
                    }
                    if (beam_width) {
                        IntegrateFan(ps, geo, box, up);
                        continue;
                    }
                    const SonarScan& scan = scans[scan_offset + si];
                    for (const PreparedBeam& pb : ps.beams) {
                        if (pb.x_hi < box.x_min || pb.x_lo > box.x_max || pb.y_hi < box.y_min ||
                            pb.y_lo > box.y_max) {
                            continue;
                        }
                        const float theta = scan.start_angle_rad +
                                            static_cast<float>(pb.beam) * scan.angle_increment_rad;
                        IntegrateRay(ps, pb, theta, geo, box, up);
                    }
                }
            }
        }
        slab.updates += up.updates();
    };

    // Chunk by chunk: prepare the chunk's scans (valid beams, footprint ranges, the x and y
    // range of every beam) in parallel, then integrate it slab by slab. Only one chunk's
    // prepared beams are held at a time; the slab grids persist across chunks.
    for (std::size_t c0 = begin; c0 < end && !cancel.load(); c0 += kChunkScans) {
        const std::size_t c1 = std::min(end, c0 + kChunkScans);
        const auto t_prepare = std::chrono::steady_clock::now();
        prepared.assign(c1 - c0, PreparedScan{});
        // Footprints of the chunk's scans and of the neighbours each one needs (the previous and
        // next for the gap between pings, footprint_neighbour_pings each side for the
        // along-track slope), fitted once.
        const std::size_t f0 = c0 - std::min(c0, reach);
        const std::size_t f1 = std::min(scans.size(), c1 + reach);
        footprints.assign(f1 - f0, detail::ScanFootprints{});
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<std::size_t>(f0, f1, 64),
                              [&](const tbb::blocked_range<std::size_t>& range) {
                                  for (std::size_t si = range.begin(); si != range.end(); ++si) {
                                      footprints[si - f0] =
                                          detail::FitFootprints(scans[si], config_);
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
                            detail::PrepareScan(scans[si], footprints[si - f0], config_, geo, nbs);
                    }
                });
        });
        for (auto& entry : slabs) entry.second.work = 0;  // (views::values: not with clang 14)
        int last_k = std::numeric_limits<int>::min();
        Slab* last = nullptr;
        for (const PreparedScan& ps : prepared) {
            result.beams_used += ps.beams_used;
            result.beams_no_detection += ps.beams_no_detection;
            result.beams_out_of_range += ps.beams_out_of_range;
            result.scans_out_of_bounds += ps.out_of_bounds ? 1 : 0;
            result.beams_inconsistent += ps.beams_inconsistent;
            total_beams += ps.beams.size();
            for (const PreparedBeam& pb : ps.beams) {
                for (int k = FloorDiv(pb.x_lo, kSlabVoxels); k <= FloorDiv(pb.x_hi, kSlabVoxels);
                     ++k) {
                    if (k != last_k) {
                        last = &slabs[k];
                        last_k = k;
                    }
                    Slab& slab = *last;
                    if (!slab.d) {
                        slab.d = MakeGrid(trunc, config_.voxel_size_m, "tsdf");
                        slab.w = MakeGrid(0.0f, config_.voxel_size_m, "weight");
                        for (const LeafT* leaf : old_d[k]) slab.d->tree().addLeaf(new LeafT(*leaf));
                        for (const LeafT* leaf : old_w[k]) slab.w->tree().addLeaf(new LeafT(*leaf));
                    }
                    ++slab.work;
                }
            }
        }
        result.prepare_s += since(t_prepare);
        // Largest slabs first, each worker taking the next (greedy longest-processing-time
        // order, so the last slab of a chunk is a small one).
        std::vector<std::pair<std::int64_t, int>> order;
        for (const auto& [k, slab] : slabs) {
            if (slab.work > 0) order.emplace_back(-slab.work, k);
        }
        std::sort(order.begin(), order.end());
        const auto t_raster = std::chrono::steady_clock::now();
        std::atomic<std::size_t> next{0};
        arena.execute([&] {
            tbb::task_group tasks;
            for (int t = 0; t < threads; ++t) {
                tasks.run([&] {
                    for (std::size_t i = next++; i < order.size(); i = next++) {
                        run_slab(order[i].second, c0);
                    }
                });
            }
            tasks.wait();
        });
        result.rasterise_s += since(t_raster);
        if (progress &&
            !progress(static_cast<double>(c1 - begin) / static_cast<double>(end - begin))) {
            cancel = true;
        }
    }
    prepared = {};
    footprints = {};
    if (total_beams == 0) {
        result.active_voxels = static_cast<std::int64_t>(impl_->weight->activeVoxelCount());
        result.elapsed_s = since(t_start);
        result.cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
        result.message = "no valid beams";
        return result;
    }

    const auto t_merge = std::chrono::steady_clock::now();
    // Rebuild the global trees: the old leaves of untouched slabs plus every slab's leaves
    // (moved, not copied).
    auto new_d = MakeGrid(trunc, config_.voxel_size_m, "tsdf");
    auto new_w = MakeGrid(0.0f, config_.voxel_size_m, "weight");
    auto keep_outside = [&](const FloatTree& from, FloatTree& to) {
        for (auto it = from.cbeginLeaf(); it; ++it) {
            if (!slabs.contains(FloorDiv(it->origin().x(), kSlabVoxels))) {
                to.addLeaf(new LeafT(*it));
            }
        }
    };
    keep_outside(impl_->distance->tree(), new_d->tree());
    keep_outside(impl_->weight->tree(), new_w->tree());
    impl_->distance.reset();
    impl_->weight.reset();
    for (auto& [k, slab] : slabs) {
        new_d->tree().merge(slab.d->tree());
        new_w->tree().merge(slab.w->tree());
        slab.d.reset();
        slab.w.reset();
        result.voxel_updates += slab.updates;
    }
    impl_->distance = new_d;
    impl_->weight = new_w;

    result.merge_s = since(t_merge);
    result.cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    result.cancelled = cancel.load();
    result.active_voxels = static_cast<std::int64_t>(impl_->weight->activeVoxelCount());
    result.elapsed_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    result.message = std::string(result.cancelled ? "cancelled: " : "") +
                     std::to_string(result.beams_used) + " beams (" +
                     std::to_string(result.beams_inconsistent) + " outvoted by footprints), " +
                     std::to_string(result.voxel_updates) + " voxel updates, " +
                     std::to_string(result.active_voxels) + " active voxels";
    return result;
}

}  // namespace pitmap::proc::fusion
