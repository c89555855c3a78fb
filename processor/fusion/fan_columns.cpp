// SPDX-License-Identifier: MIT
// The beam-width rasteriser's per-ping set-up (tsdf.cpp walks the columns): sector table,
// sector boundaries, and per column bin the bounds that contain every voxel a sector of the
// ping can update. Pure arithmetic on one ping; no OpenVDB here.
//
// Why a ping and not a beam: the sectors of one ping tile its fan, and a voxel belongs to at
// most one of them, so one walk per ping visits each candidate voxel once. Walking beam by beam
// needs a frustum per beam (about a voxel thick across the fan, oblique to the axes: ~3.6
// candidates per column) and spent a third of the integration on set-up and clipping.
#include <algorithm>
#include <cmath>
#include <limits>

#include "processor/fusion/detail/prepared_scan.hpp"

namespace pitmap::proc::fusion::detail {

namespace {

// The world axis most parallel to the fan plane (smallest component of the fan normal); z
// unless another axis is clearly better, so a level head gets vertical columns, which cross a
// floor's band along its whole length and run along z inside OpenVDB leaves.
int ColumnAxis(const Eigen::Vector3d& n) {
    int best = 2;
    double best_v = std::abs(n.z());
    for (int k = 0; k < 2; ++k) {
        if (std::abs(n[k]) < best_v - 1e-9) {
            best = k;
            best_v = std::abs(n[k]);
        }
    }
    return best;
}

// Sector k is [beta_k, beta_{k+1}) of the in-plane angle in index order, beta_k = start +
// (k - 1/2) increment: its boundaries as half-plane normals.
void SectorBoundaries(double start, double inc, std::size_t num_beams, FanColumns& fan) {
    const double sgn = inc > 0.0 ? 1.0 : -1.0;
    fan.side_y.resize(num_beams + 1);
    fan.side_z.resize(num_beams + 1);
    for (std::size_t k = 0; k <= num_beams; ++k) {
        const double beta = start + (static_cast<double>(k) - 0.5) * inc;
        fan.side_y[k] = sgn * std::cos(beta);
        fan.side_z[k] = -sgn * std::sin(beta);
    }
}

// The columns' world axis and their in-plane frame: direction (c_y, c_z), normal (w_y, w_z)
// and the in-plane length g of a step. n is the fan normal (R's x column).
void ColumnFrame(const Eigen::Matrix3d& R, FanColumns& fan) {
    fan.axis = ColumnAxis(R.col(0));
    const int a = fan.axis;
    fan.step = Eigen::Vector3d(R(a, 0), R(a, 1), R(a, 2));
    fan.g = std::hypot(fan.step.y(), fan.step.z());  // >= sqrt(2/3): |n_a| <= 1/sqrt(3)
    fan.c_y = fan.step.y() / fan.g;
    fan.c_z = fan.step.z() / fan.g;
    fan.w_y = -fan.c_z;
    fan.w_z = fan.c_y;
}

// The ranges a sector's voxels can have: the footprint range widened halfway to its
// neighbours' and by the along-track slope's reach, and its off-cone half-thickness.
struct SectorReach {
    double r_min, r_max;  // voxels
    double h_out;         // voxels
};

// The sector table entry of beam pb (h_cube: half a voxel's extent across the fan plane).
FanSector MakeSector(const PreparedBeam& pb,
                     const ScanFootprints& footprints,
                     double T,
                     double h_cube,
                     SectorReach& reach) {
    const double r = pb.range_vox;
    const double r_prev = pb.range_prev_vox, r_next = pb.range_next_vox;
    double r_min = r, r_max = r;
    for (double rn : {r_prev, r_next}) {
        if (!std::isfinite(rn)) continue;
        r_min = std::min(r_min, 0.5 * (r + rn));
        r_max = std::max(r_max, 0.5 * (r + rn));
    }
    const double h_out = std::max(h_cube, static_cast<double>(pb.half_gap_vox));
    // The along-track slope moves the range by up to dev over the voxels the beam updates.
    const double dev = AlongTrackReach(pb);
    reach = {r_min - dev, r_max + dev, h_out};
    FanSector fs;
    // The beam axis as the reference takes it: theta in float, as every reader of the scan
    // computes it.
    fs.cos_theta = footprints.cos_theta[pb.beam];
    fs.sin_theta = footprints.sin_theta[pb.beam];
    fs.far2 = (reach.r_max + T + 1e-6) * (reach.r_max + T + 1e-6);
    fs.h_out2 = h_out * h_out;
    fs.range = pb.range_vox;
    fs.dr_prev = std::isfinite(r_prev) ? static_cast<float>(r_prev - r) : 0.0f;
    fs.dr_next = std::isfinite(r_next) ? static_cast<float>(r_next - r) : 0.0f;
    fs.weight = pb.weight;
    fs.dr_dx = pb.dr_dx;
    fs.x_fit_lo = pb.x_fit_lo;
    fs.x_fit_hi = pb.x_fit_hi;
    return fs;
}

// A sector's in-plane region: a segment along its mid axis from a (in-plane distance rho_lo
// cos(h)) to b (rho_hi), widened by hw across it (h = inc / 2); out of the plane within x_max.
struct Segment {
    double a_y, a_z, b_y, b_z;        // its ends, sonar frame, voxels
    double om_a, tau_a, om_b, tau_b;  // the same in the columns' frame
    double hw, x_max, h_out;
};

// rho_hi: the far test (|v - p| < r_max + T); rho_lo: d <= T needs |v - p| >= r_min - T, and the
// in-plane part of that is at least (r_min - T) cos(bw / 2) inside the cone and
// sqrt((r_min - T)^2 - h_out^2) off it. Small slacks cover rounding and the interpolation's
// |frac| reaching tan(h) / inc, a hair above 1/2.
Segment SectorSegment(const FanSector& fs,
                      const SectorReach& reach,
                      const FanColumns& fan,
                      const Geometry& geo,
                      double sin_h,
                      double cos_h) {
    const double T = geo.trunc_vox;
    const double rho_hi = reach.r_max + T + 1e-3;
    const double q = reach.r_min - T - 1e-3 - 1e-4 * reach.r_max;
    const double rho_lo =
        q > 0.0 ? std::min(q * geo.cos_half_bw,
                           std::sqrt(std::max(0.0, q * q - reach.h_out * reach.h_out)))
                : 0.0;
    // (The float axis lies within 3e-7 rad of start + beam inc: 0.006 voxels at the range
    // gate's 20000, inside the bins' slack below.)
    const double uy = fs.sin_theta, uz = fs.cos_theta;
    Segment sg;
    sg.a_y = rho_lo * cos_h * uy;
    sg.a_z = rho_lo * cos_h * uz;
    sg.b_y = rho_hi * uy;
    sg.b_z = rho_hi * uz;
    sg.om_a = fan.w_y * sg.a_y + fan.w_z * sg.a_z;
    sg.tau_a = fan.c_y * sg.a_y + fan.c_z * sg.a_z;
    sg.om_b = fan.w_y * sg.b_y + fan.w_z * sg.b_z;
    sg.tau_b = fan.c_y * sg.b_y + fan.c_z * sg.b_z;
    // (+ 0.01 + 1e-6 rho_hi: the bins are floats; rounding to them stays inside this)
    sg.hw = rho_hi * sin_h + 0.01 + 1e-6 * rho_hi;
    sg.x_max = std::max(geo.tan_half_bw * rho_hi, reach.h_out) + 1e-6;
    sg.h_out = reach.h_out;
    return sg;
}

// Widens the fan's world voxel bounds by the segment: both ends, widened by the cross-section
// (norm <= hw + x_max).
void ExtendWorldBounds(const Segment& sg, const PreparedScan& ps, FanColumns& fan) {
    const double reach = sg.hw + sg.x_max + 1.0;
    for (const Eigen::Vector3d& e :
         {Eigen::Vector3d(0.0, sg.a_y, sg.a_z), Eigen::Vector3d(0.0, sg.b_y, sg.b_z)}) {
        const Eigen::Vector3d v = ps.p_vox + ps.R * e;
        for (int k = 0; k < 3; ++k) {
            const auto lo = static_cast<std::int32_t>(std::floor(v[k] - reach));
            const auto hi = static_cast<std::int32_t>(std::ceil(v[k] + reach));
            if (fan.hi[k] < fan.lo[k]) {
                fan.lo[k] = lo;
                fan.hi[k] = hi;
            } else {
                fan.lo[k] = std::min(fan.lo[k], lo);
                fan.hi[k] = std::max(fan.hi[k], hi);
            }
        }
    }
}

// The column bins (one voxel of omega each, from omega0): per bin the tau range, |x| bound and
// off-cone half-thickness of the segments that reach within hw of it.
void BinSegments(const std::vector<Segment>& segs, std::size_t num_bins, FanColumns& fan) {
    const float inf = std::numeric_limits<float>::infinity();
    fan.tau_lo.assign(num_bins, inf);
    fan.tau_hi.assign(num_bins, -inf);
    fan.x_max.assign(num_bins, 0.0f);
    fan.h_max.assign(num_bins, 0.0f);
    for (const Segment& sg : segs) {
        const double d_om = sg.om_b - sg.om_a;
        const auto x_max = static_cast<float>(sg.x_max * (1.0 + 1e-6));
        const auto h_max = static_cast<float>(sg.h_out * (1.0 + 1e-6) + 1e-6);
        const bool along = std::abs(d_om) > 1e-12;  // the segment crosses bins
        const double inv_d_om = along ? 1.0 / d_om : 0.0;
        const double d_tau = sg.tau_b - sg.tau_a;
        const auto j0 =
            static_cast<std::size_t>(std::floor(std::min(sg.om_a, sg.om_b) - sg.hw - fan.omega0));
        const auto j1 = std::min(
            num_bins - 1,
            static_cast<std::size_t>(std::floor(std::max(sg.om_a, sg.om_b) + sg.hw - fan.omega0)));
        for (std::size_t j = j0; j <= j1; ++j) {
            // The part of the segment whose omega lies within hw of the bin.
            const double lo = fan.omega0 + static_cast<double>(j) - sg.hw;
            const double hi = lo + 1.0 + 2.0 * sg.hw;
            double s0 = 0.0, s1 = 1.0;
            if (along) {
                const double sa = (lo - sg.om_a) * inv_d_om;
                const double sb = (hi - sg.om_a) * inv_d_om;
                s0 = std::max(s0, std::min(sa, sb));
                s1 = std::min(s1, std::max(sa, sb));
                if (s0 > s1) continue;
            } else if (sg.om_a < lo || sg.om_a > hi) {
                continue;
            }
            const double t0 = sg.tau_a + s0 * d_tau;
            const double t1 = sg.tau_a + s1 * d_tau;
            fan.tau_lo[j] = std::min(fan.tau_lo[j], static_cast<float>(std::min(t0, t1) - sg.hw));
            fan.tau_hi[j] = std::max(fan.tau_hi[j], static_cast<float>(std::max(t0, t1) + sg.hw));
            fan.x_max[j] = std::max(fan.x_max[j], x_max);
            fan.h_max[j] = std::max(fan.h_max[j], h_max);
        }
    }
    fan.tau_min = std::numeric_limits<double>::infinity();
    fan.tau_max = -fan.tau_min;
    for (std::size_t j = 0; j < num_bins; ++j) {
        if (!(fan.tau_lo[j] <= fan.tau_hi[j])) continue;
        fan.tau_min = std::min(fan.tau_min, static_cast<double>(fan.tau_lo[j]));
        fan.tau_max = std::max(fan.tau_max, static_cast<double>(fan.tau_hi[j]));
        fan.x_max_all = std::max(fan.x_max_all, static_cast<double>(fan.x_max[j]));
    }
}

}  // namespace

void BuildFanColumns(PreparedScan& ps,
                     const SonarScan& scan,
                     const ScanFootprints& footprints,
                     const Geometry& geo) {
    const std::size_t num_beams = footprints.r.size();
    FanColumns& fan = ps.fan;
    fan = FanColumns{};
    const double inc = static_cast<double>(scan.angle_increment_rad);
    const double start = static_cast<double>(scan.start_angle_rad);
    // A sector must be a proper wedge (under 180 deg) for the half-plane tests; beams further
    // apart than that are not a multibeam (the per-beam footprint has no geometry either).
    constexpr double kPi = 3.14159265358979323846;
    if (ps.beams.empty() || !std::isfinite(inc) || !std::isfinite(start) || inc == 0.0 ||
        std::abs(inc) >= kPi) {
        return;
    }
    // Tracking a voxel's sector by the boundary tests alone needs the whole fan within 180 deg
    // (the Delta T's is 120 deg); wider fans take each voxel's sector from its angle.
    fan.wide = std::abs(inc) * static_cast<double>(num_beams) >= kPi;
    fan.start_angle = start;
    fan.increment = inc;
    fan.inv_increment = 1.0 / inc;
    SectorBoundaries(start, inc, num_beams, fan);
    ColumnFrame(ps.R, fan);

    const Eigen::Vector3d n = ps.R.col(0);
    const double h_cube = 0.5 * (std::abs(n.x()) + std::abs(n.y()) + std::abs(n.z()));
    const double half_inc = 0.5 * std::abs(inc);
    const double sin_h = std::sin(half_inc), cos_h = std::cos(half_inc);
    std::vector<Segment> segs;
    segs.reserve(ps.beams.size());
    fan.sectors.assign(num_beams, FanSector{});
    double om_lo = std::numeric_limits<double>::infinity();
    double om_hi = -om_lo;
    for (const PreparedBeam& pb : ps.beams) {
        SectorReach reach;
        FanSector& fs = fan.sectors[pb.beam];
        fs = MakeSector(pb, footprints, geo.trunc_vox, h_cube, reach);
        const Segment sg = SectorSegment(fs, reach, fan, geo, sin_h, cos_h);
        om_lo = std::min(om_lo, std::min(sg.om_a, sg.om_b) - sg.hw);
        om_hi = std::max(om_hi, std::max(sg.om_a, sg.om_b) + sg.hw);
        ExtendWorldBounds(sg, ps, fan);
        segs.push_back(sg);
    }
    fan.omega0 = std::floor(om_lo);
    BinSegments(segs, static_cast<std::size_t>(std::floor(om_hi) - fan.omega0) + 1, fan);
}

}  // namespace pitmap::proc::fusion::detail
