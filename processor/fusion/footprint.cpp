// SPDX-License-Identifier: MIT
// The beam-width sensor model's footprint (after May et al. 2014): for every beam, the ranges
// of the beams whose axes lie inside its cone are fitted by a robust line (median slope, gated
// inliers), whose value at the beam is the footprint range the rasteriser integrates. Pure
// arithmetic on one ping; no OpenVDB here.
#include <algorithm>
#include <cmath>

#include "processor/fusion/detail/prepared_scan.hpp"

namespace pitmap::proc::fusion::detail {

namespace {

constexpr int kMaxFootprintHalf = 32;  // beams on each side of a footprint considered at most
// Steepest incidence a footprint's slope may imply, across the fan or along the track: tan(80 deg).
const double kTanMaxIncidence = std::tan(80.0 * 3.14159265358979323846 / 180.0);

// Median of a small array (reorders it); the mean of the two middle values for even n.
double SmallMedian(double* v, int n) {
    std::sort(v, v + n);
    return (n & 1) != 0 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The range the footprint of beam i sees, from the beams whose axes lie inside its cone
// (|k| <= half, k = j - i, at angle delta_k = k inc off beam i's axis): a robust straight line
// in the fan plane through their echoes, and where beam i's axis meets it. A line in the plane
// is linear in the inverse range, 1 / r(delta) = B cos(delta) + A sin(delta), so it is fitted
// there. (The range itself is not linear across the cone: on a plane at incidence alpha it is
// convex in the beam angle, and a straight line through the ranges put a level floor too deep
// by ~2 h inc^2 (1 + 2 tan^2 alpha) / cos(alpha): 4 mm at 45 deg and 14 mm at 60 deg under
// 27 m of water.) Robust: A from the median of the neighbouring pairs' exact lines, B from the
// median of (1 / r_k - A sin) / cos; the beams within the gate of that line (in range) are
// inliers, and the weighted least-squares line through them gives the footprint range 1 / B.
// Each beam is weighted by how near its axis lies to beam i's (1 - |k| / (half + 1): the beams
// at the cone's edge see half their footprint outside this one's; unweighted, the line
// smoothed bench faces and rubble across the whole cone). An isolated coarse outlier (or a
// dropout) inside the cone is outvoted. The line must hold a strict majority of the cone's
// valid beams and a plausible slope (|dr/dk| <= max_slope * r, i.e. incidence below ~80 deg);
// otherwise a line of constant range is tried, and a footprint that straddles several surfaces
// with no majority gives no range. r holds the measured ranges, NaN for invalid beams. Returns
// false when there is no range.
struct FootprintRange {
    float range = 0;
    float slope = 0;           // range change per beam of the inlier line at beam i
    float gate = 0;            // inlier gate used
    int support = 0;           // inliers
    bool self_inlier = false;  // beam i itself is valid and an inlier
};
// What FitFootprint needs of a scan: the ranges, their inverses, and cos and sin of k inc for
// k in [-half, half].
struct FootprintInputs {
    const std::vector<float>& r;
    std::vector<double> inv_r;  // 1 / r (NaN where r is)
    std::vector<double> cos_k;  // cos(k inc) at k + half
    std::vector<double> sin_k;  // sin(k inc) at k + half
    int half;
    double inc;
};

bool FitFootprint(const FootprintInputs& in,
                  int i,
                  double gate_vox,
                  double gate_fraction,
                  double max_slope,
                  FootprintRange& out) {
    const std::vector<float>& r = in.r;
    const int half = in.half;
    const double inc = in.inc;
    const int n = static_cast<int>(r.size());
    constexpr int kMax = 2 * kMaxFootprintHalf + 1;
    double ks[kMax], rs[kMax], us[kMax], cs[kMax], ss[kMax], tmp[kMax];
    int m = 0;
    for (int k = -half; k <= half; ++k) {
        const int j = i + k;
        if (j < 0 || j >= n || !std::isfinite(r[static_cast<std::size_t>(j)])) continue;
        ks[m] = k;
        rs[m] = r[static_cast<std::size_t>(j)];
        us[m] = in.inv_r[static_cast<std::size_t>(j)];
        cs[m] = in.cos_k[static_cast<std::size_t>(k + half)];
        ss[m] = in.sin_k[static_cast<std::size_t>(k + half)];
        ++m;
    }
    if (m == 0) return false;
    // Inliers of the line (A, B0) with B0 the median intercept, then the weighted fit.
    auto attempt = [&](double a0) {
        for (int t = 0; t < m; ++t) tmp[t] = (us[t] - a0 * ss[t]) / cs[t];
        const double b0 = SmallMedian(tmp, m);
        if (!(b0 > 0.0)) return false;
        const double gate = gate_vox + gate_fraction / b0;
        double scc = 0, scs = 0, sss = 0, suc = 0, sus = 0, sw = 0;
        bool self_inlier = false;
        int support = 0, last = -1;
        for (int t = 0; t < m; ++t) {
            const double u_line = b0 * cs[t] + a0 * ss[t];
            if (!(u_line > 0.0) || std::abs(rs[t] - 1.0 / u_line) > gate) continue;
            const double w = 1.0 - std::abs(ks[t]) / (half + 1.0);
            scc += w * cs[t] * cs[t];
            scs += w * cs[t] * ss[t];
            sss += w * ss[t] * ss[t];
            suc += w * us[t] * cs[t];
            sus += w * us[t] * ss[t];
            sw += w;
            ++support;
            last = t;
            if (ks[t] == 0) self_inlier = true;
        }
        if (2 * support <= m) return false;
        double a = a0, b = 0;
        const double det = scc * sss - scs * scs;
        if (support >= 2 && det > 1e-12 * sw * sw * inc * inc) {
            b = (suc * sss - sus * scs) / det;
            a = (sus * scc - suc * scs) / det;
        } else {
            // One inlier (or inliers at one angle): moved along the robust line to the axis.
            b = (us[last] - a0 * ss[last]) / cs[last];
        }
        if (!(b > 0.0)) return false;
        const double range = 1.0 / b;
        const double slope = -a / (b * b) * inc;  // dr/dk at k = 0
        if (std::abs(slope) > max_slope * range) return false;
        out.range = static_cast<float>(range);
        out.slope = static_cast<float>(slope);
        out.gate = static_cast<float>(gate);
        out.support = support;
        out.self_inlier = self_inlier;
        return true;
    };
    double a0 = 0;
    if (m >= 2) {
        // A of the exact line through each neighbouring pair (B cos d + A sin d = u at both):
        // (u2 cos d1 - u1 cos d2) / sin(d2 - d1).
        for (int t = 0; t + 1 < m; ++t) {
            const double den = ss[t + 1] * cs[t] - ss[t] * cs[t + 1];  // sin(d2 - d1)
            tmp[t] = (us[t + 1] * cs[t] - us[t] * cs[t + 1]) / den;
        }
        a0 = SmallMedian(tmp, m - 1);
    }
    if (a0 != 0.0 && attempt(a0)) return true;
    return attempt(0.0);
}

}  // namespace

ScanFootprints FitFootprints(const SonarScan& scan, const TsdfConfig& config) {
    const double inv_s = 1.0 / config.voxel_size_m;
    const bool beam_width = config.sensor_model == SensorModel::kBeamWidth;
    ScanFootprints out;
    const std::size_t n = std::min<std::size_t>(scan.ranges_m.size(), 65536);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    out.r.assign(n, nan);
    out.sin_theta.resize(n);
    out.cos_theta.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const float theta = scan.start_angle_rad + static_cast<float>(i) * scan.angle_increment_rad;
        out.sin_theta[i] = std::sin(static_cast<double>(theta));
        out.cos_theta[i] = std::cos(static_cast<double>(theta));
    }
    for (std::size_t i = 0; i < n; ++i) {
        const float range = scan.ranges_m[i];
        if (!std::isfinite(range) || range == 0.0f) {
            ++out.no_detection;
        } else if (range < config.min_range_m || range > config.max_range_m) {
            ++out.out_of_range;
        } else {
            out.r[i] = static_cast<float>(range * inv_s);
        }
    }
    if (!beam_width) return out;
    const double inc = std::abs(static_cast<double>(scan.angle_increment_rad));
    // Footprint: the beams whose axes lie inside the cone of beam i (beam_width / 2 around it).
    const int half =
        inc > 1e-9
            ? std::min(kMaxFootprintHalf,
                       static_cast<int>(std::floor(0.5 * config.beam_width_rad / inc + 1e-6)))
            : 0;
    out.half = half;
    out.range.assign(n, nan);
    out.point_y.assign(n, nan);
    out.point_z.assign(n, nan);
    out.support.assign(n, 0);
    out.slope.assign(n, 0.0f);
    out.gate.assign(n, 0.0f);
    const double gate_vox = config.footprint_gate_m * inv_s;
    // Range change per beam on a plane at incidence alpha: r tan(alpha) inc; up to 80 deg.
    const double max_slope = inc * kTanMaxIncidence;
    FootprintInputs in{out.r, {}, {}, {}, half, static_cast<double>(scan.angle_increment_rad)};
    in.inv_r.resize(n);
    for (std::size_t j = 0; j < n; ++j) in.inv_r[j] = 1.0 / static_cast<double>(out.r[j]);
    for (int k = -half; k <= half; ++k) {
        in.cos_k.push_back(std::cos(k * in.inc));
        in.sin_k.push_back(std::sin(k * in.inc));
    }
    for (std::size_t i = 0; i < n; ++i) {
        FootprintRange fp;
        if (!FitFootprint(
                in, static_cast<int>(i), gate_vox, config.footprint_gate_fraction, max_slope, fp)) {
            continue;
        }
        out.range[i] = fp.range;
        out.point_y[i] = static_cast<float>(fp.range * out.sin_theta[i]);
        out.point_z[i] = static_cast<float>(fp.range * out.cos_theta[i]);
        out.support[i] = fp.support;
        out.slope[i] = fp.slope;
        out.gate[i] = fp.gate;
        if (std::isfinite(out.r[i]) && !fp.self_inlier) ++out.inconsistent;
    }
    return out;
}

namespace {

// Along-track slope of beam i's footprint: dr/dx, the range change per voxel out of the fan
// plane, from the footprints of beam i in the neighbouring pings. Each neighbour's footprint
// point X (its beam axis at its footprint range) is seen from this ping at out-of-plane offset
// x_k and range |X - p|; the part of that range this ping's in-plane line explains (X's
// in-plane angle off the beam axis, times the line's slope) is taken off, and what remains,
// delta_k, is fitted by delta = s x through the origin (this ping's own footprint).
//  - Robust: the median of delta_k / x_k, then least squares over the neighbours within the
//    footprint's gate of it (a neighbour on another surface, past a crest, drops out); two
//    are needed.
//  - Local: a neighbour further out of the plane than kMaxNeighbourReach times the offsets the
//    slope is applied at (x_half), or whose point lies further off the beam axis in the plane
//    than the footprint's half-width (a roll between pings), is not used.
//  - Not extrapolated: the slope holds over the span of offsets it was fitted to; beyond (the
//    far side of the cone at long range, the last ping of a line) the range stays at the
//    span's end (extrapolated, it put rock metres behind bench faces at long range:
//    docs/decisions/008).
//  - Plausible: |s| <= s_max (tan of 80 deg incidence, as across the fan).
constexpr double kMaxNeighbourReach = 4.0;

struct NeighbourFrame {
    const ScanFootprints* fp;
    Eigen::Matrix3d M;  // this ping's sonar frame from the neighbour's: R^T R_nb
    Eigen::Vector3d t;  // the neighbour's position in this ping's sonar frame, voxels
};

struct AlongTrack {
    double s = 0;               // dr/dx; 0 = no fit
    double x_lo = 0, x_hi = 0;  // the span of offsets it was fitted over (contains 0)
};

AlongTrack AlongTrackSlope(std::size_t i,
                           const ScanFootprints& own,
                           const std::vector<NeighbourFrame>& nbs,
                           double si,
                           double ci,
                           double inc,
                           double x_half,
                           double s_max) {
    double xs[2 * kMaxFootprintNeighbourPings];
    double ds[2 * kMaxFootprintNeighbourPings];
    double tmp[2 * kMaxFootprintNeighbourPings];
    int m = 0;
    const double max_x = kMaxNeighbourReach * x_half;
    const double max_dtheta =
        std::tan(std::max(0.5, static_cast<double>(own.half)) * std::abs(inc));
    for (const NeighbourFrame& nb : nbs) {
        if (m == 2 * kMaxFootprintNeighbourPings) break;
        if (i >= nb.fp->range.size() || !std::isfinite(nb.fp->range[i])) continue;
        // X in this ping's sonar frame: M (0, y, z) + t, (y, z) the footprint point in the
        // neighbour's.
        const double y = static_cast<double>(nb.fp->point_y[i]);
        const double z = static_cast<double>(nb.fp->point_z[i]);
        const Eigen::Vector3d q = nb.M.col(1) * y + nb.M.col(2) * z + nb.t;
        const double x = q.x();
        if (!(std::abs(x) > 1e-3 && std::abs(x) <= max_x)) continue;
        const double along = si * q.y() + ci * q.z();
        if (!(along > 0.0)) continue;
        const double dtheta = (ci * q.y() - si * q.z()) / along;  // tan of the in-plane angle
        if (!(std::abs(dtheta) <= max_dtheta)) continue;
        const double r_line =
            static_cast<double>(own.range[i]) + static_cast<double>(own.slope[i]) * dtheta / inc;
        xs[m] = x;
        ds[m] = q.norm() - r_line;
        ++m;
    }
    if (m < 2) return {};
    for (int k = 0; k < m; ++k) tmp[k] = ds[k] / xs[k];
    const double s0 = SmallMedian(tmp, m);
    const double gate = static_cast<double>(own.gate[i]);
    double sxd = 0, sxx = 0;
    int used = 0;
    AlongTrack out;
    for (int k = 0; k < m; ++k) {
        if (!(std::abs(ds[k] - s0 * xs[k]) <= gate)) continue;
        sxd += xs[k] * ds[k];
        sxx += xs[k] * xs[k];
        ++used;
        out.x_lo = std::min(out.x_lo, xs[k]);
        out.x_hi = std::max(out.x_hi, xs[k]);
    }
    if (used < 2) return {};
    const double s = sxd / sxx;
    if (!(std::abs(s) <= s_max)) return {};
    out.s = s;
    return out;
}

// The neighbours the along-track slopes are fitted to (within footprint_neighbour_pings, with
// footprints and finite poses), in this scan's sonar frame, voxels.
std::vector<NeighbourFrame> SlopeNeighbours(const std::vector<ScanNeighbour>& neighbours,
                                            const PreparedScan& ps,
                                            const TsdfConfig& config) {
    const double inv_s = 1.0 / config.voxel_size_m;
    std::vector<NeighbourFrame> slope_nbs;
    for (const ScanNeighbour& nb : neighbours) {
        if (nb.scan == nullptr || nb.footprints == nullptr ||
            std::abs(nb.offset) > config.footprint_neighbour_pings ||
            nb.footprints->range.empty()) {
            continue;
        }
        const Eigen::Matrix3d R_nb = nb.scan->T_world_sonar.linear();
        const Eigen::Vector3d p_nb = nb.scan->T_world_sonar.translation() * inv_s;
        if (!R_nb.allFinite() || !p_nb.allFinite() ||
            nb.footprints->point_y.size() != nb.footprints->range.size()) {
            continue;
        }
        slope_nbs.push_back(
            {nb.footprints, ps.R.transpose() * R_nb, ps.R.transpose() * (p_nb - ps.p_vox)});
    }
    return slope_nbs;
}

// A footprint of the scan being prepared, as the gap rule needs it: the sonar (world metres,
// R_world_sonar), the beam's axis, its footprint range line (range, change per beam, gate; voxels)
// and the cone's half-width across the fan (tan).
struct FootprintHere {
    Eigen::Vector3d p_world;
    const Eigen::Matrix3d* R = nullptr;
    Eigen::Vector3d x_world;  // the footprint point: the beam axis at the footprint range
    double sin_t = 0, cos_t = 0;
    double range_vox = 0, slope_vox = 0, gate_vox = 0;
    double inc = 0;         // angle between beams (signed, as the scan's)
    double max_dtheta = 0;  // tan of the cone's half-width across the fan
    double voxel_m = 0;
};

// The fan planes of the neighbouring pings (point, normal = their sonar x axis), world metres,
// for the gap between pings: on each side the next kDepth pings, with their footprints.
struct NeighbourFans {
    static constexpr int kDepth = kMaxBridgePings + 1;
    struct Plane {
        Eigen::Vector3d p, n;
        Eigen::Matrix3d R;  // R_world_sonar of the ping
        const ScanFootprints* footprints = nullptr;
        bool valid = false;
    };
    Plane fans[2][kDepth];  // [side: before, after][k: the (k + 1)-th ping that way]

    bool any() const { return fans[0][0].valid || fans[1][0].valid; }

    // The largest distance from the footprint `here` of beam i to a neighbouring fan it is
    // widened to, on either side; 0 if none. On each side the next ping's fan within fill_m; or,
    // where that ping has no footprint at beam i (its echo there was rejected or it had none):
    //  - the ping after it, when it has, within fill_m: a beam missing in one ping leaves the
    //    same strip unobserved as a missing ping, and is bridged the same way;
    //  - past a run of up to bridge_pings pings without it, the first ping that has it, within
    //    the run's length times fill_m, when its footprint agrees with this one (Agrees);
    //  - otherwise the next ping's fan within fill_m, as without per_beam.
    // The beam is widened to half the gap on both sides of its plane, so a run's bridge is taken
    // only where the other side holds the same surface that far (Supports): a step under a run
    // on the other side is not bridged from this one.
    double GapAt(const FootprintHere& here,
                 std::size_t i,
                 double fill_m,
                 bool per_beam,
                 int bridge_pings) const {
        double gap_m = 0.0;
        Bridge bridge[2];
        for (int s = 0; s < 2; ++s) {
            const auto& side = fans[s];
            if (!side[0].valid) continue;
            if (per_beam && !HasFootprint(side[0], i)) {
                bridge[s] = BridgedGap(side, here, i, fill_m, bridge_pings);
            }
            const double next_m = Distance(side[0], here.x_world);
            if (bridge[s].rule == 1) {
                gap_m = std::max(gap_m, bridge[s].gap_m);
            } else if (next_m <= fill_m) {
                gap_m = std::max(gap_m, next_m);
            }
        }
        for (int s = 0; s < 2; ++s) {
            if (bridge[s].rule == 2 && bridge[s].gap_m > gap_m &&
                Supports(fans[1 - s], here, i, 0.5 * bridge[s].gap_m, bridge[1 - s])) {
                gap_m = bridge[s].gap_m;
            }
        }
        return gap_m;
    }

    // A side's bridge: the gap to the fan it reaches, and by which rule (0 = none, 1 = one ping
    // missing the beam within fill_m, 2 = a run whose far footprint agrees).
    struct Bridge {
        double gap_m = 0.0;
        int rule = 0;
    };

    // One side's gap past the pings without a footprint at beam i: to the first ping that has
    // one (side[k], k >= 1; the pings between are consecutive scans of the input), within fill_m
    // for k = 1, or k times fill_m when k <= bridge_pings and its footprint agrees with this
    // one's.
    static Bridge BridgedGap(const Plane (&side)[kDepth],
                             const FootprintHere& here,
                             std::size_t i,
                             double fill_m,
                             int bridge_pings) {
        for (int k = 1; k < kDepth; ++k) {
            if (!side[k].valid) return {};
            if (!HasFootprint(side[k], i)) continue;
            const double s_m = Distance(side[k], here.x_world);
            if (k == 1 && s_m <= fill_m) return {s_m, 1};
            if (k > bridge_pings || !(s_m <= k * fill_m)) return {};
            return Agrees(side[k], here, i) ? Bridge{s_m, 2} : Bridge{};
        }
        return {};
    }

    // The other side holds the surface of `here` out to reach_m: it is bridged that far itself,
    // or its pings within reach_m all have a footprint at beam i that agrees with this one.
    static bool Supports(const Plane (&side)[kDepth],
                         const FootprintHere& here,
                         std::size_t i,
                         double reach_m,
                         const Bridge& its_bridge) {
        constexpr double kEps = 1e-6;  // m: a reach equal to the other side's gap is held
        if (its_bridge.rule >= 1 && its_bridge.gap_m >= reach_m - kEps) return true;
        for (int k = 0; k < kDepth; ++k) {
            if (!side[k].valid || !HasFootprint(side[k], i) || !Agrees(side[k], here, i)) {
                return false;
            }
            if (Distance(side[k], here.x_world) >= reach_m - kEps) return true;
        }
        return false;
    }

    // The footprint of beam i in the ping `far` lies where the widened beam `here` writes the
    // surface: seen from here, within the cone's half-width across the fan, at a range within the
    // footprint's gate of its range line there (the rasteriser holds a sector's range out of its
    // plane, so the test is of that sphere, not of a plane: on a level floor the far point lies
    // beyond it by x^2 / 2r at the offset x, and the bridge reaches x / 2).
    static bool Agrees(const Plane& far, const FootprintHere& here, std::size_t i) {
        const double s = here.voxel_m;
        const ScanFootprints& fp = *far.footprints;
        const Eigen::Vector3d x_far =
            far.p + far.R * Eigen::Vector3d(0.0,
                                            static_cast<double>(fp.point_y[i]) * s,
                                            static_cast<double>(fp.point_z[i]) * s);
        const Eigen::Vector3d q = here.R->transpose() * (x_far - here.p_world) / s;
        const double along = here.sin_t * q.y() + here.cos_t * q.z();
        if (!(along > 0.0)) return false;
        const double dtheta = (here.cos_t * q.y() - here.sin_t * q.z()) / along;
        if (!(std::abs(dtheta) <= here.max_dtheta)) return false;
        const double r_line = here.range_vox + here.slope_vox * dtheta / here.inc;
        return std::abs(q.norm() - r_line) <= here.gate_vox;
    }

    static double Distance(const Plane& f, const Eigen::Vector3d& x_world) {
        return std::abs(f.n.dot(x_world - f.p));
    }

    static bool HasFootprint(const Plane& f, std::size_t i) {
        return f.footprints != nullptr && i < f.footprints->range.size() &&
               std::isfinite(f.footprints->range[i]) && i < f.footprints->point_y.size();
    }
};

NeighbourFans FansOf(const std::vector<ScanNeighbour>& neighbours) {
    NeighbourFans out;
    for (const ScanNeighbour& nb : neighbours) {
        const int side = nb.offset < 0 ? 0 : 1;
        const int k = std::abs(nb.offset) - 1;
        if (nb.scan == nullptr || k < 0 || k >= NeighbourFans::kDepth) continue;
        const Eigen::Vector3d q = nb.scan->T_world_sonar.translation();
        const Eigen::Matrix3d R = nb.scan->T_world_sonar.linear();
        const Eigen::Vector3d nn = R.col(0);
        if (!q.allFinite() || !R.allFinite() || !(nn.norm() > 0.5)) continue;
        out.fans[side][k] = {q, nn.normalized(), R, nb.footprints, true};
    }
    return out;
}

// Beam-width mode: the neighbouring sectors' footprint ranges that pb interpolates towards,
// only on the same surface: a neighbour's range must lie on this footprint's line (a bench
// crest next to the floor below would otherwise span a false surface across the shadow).
void SameSurfaceNeighbours(std::size_t i,
                           std::size_t n,
                           const ScanFootprints& footprints,
                           PreparedBeam& pb) {
    const std::vector<float>& fr = footprints.range;
    const std::vector<float>& slope = footprints.slope;
    const std::vector<float>& gate = footprints.gate;
    if (i > 0 && std::abs(fr[i - 1] - (fr[i] - slope[i])) <= gate[i]) {
        pb.range_prev_vox = fr[i - 1];
    }
    if (i + 1 < n && std::abs(fr[i + 1] - (fr[i] + slope[i])) <= gate[i]) {
        pb.range_next_vox = fr[i + 1];
    }
}

// The world x and y voxel range of beam pb's frustum: along the axis u (its x and y
// components) from r_lo - T to r_hi + T plus the cross-section's reach (spread per voxel of
// range) and the widening towards the neighbouring pings.
void BeamBounds(const PreparedScan& ps,
                double u_x,
                double u_y,
                double spread,
                const Geometry& geo,
                PreparedBeam& pb) {
    double r_lo = pb.range_vox, r_hi = pb.range_vox;
    for (float rn : {pb.range_prev_vox, pb.range_next_vox}) {
        if (!std::isfinite(rn)) continue;
        r_lo = std::min(r_lo, static_cast<double>(rn));
        r_hi = std::max(r_hi, static_cast<double>(rn));
    }
    const double dev = AlongTrackReach(pb);
    r_lo -= dev;
    r_hi += dev;
    const double q0 = std::max(0.0, r_lo - geo.trunc_vox);
    const double q1 = r_hi + geo.trunc_vox;
    const double half_gap = static_cast<double>(pb.half_gap_vox);
    const double reach_x = q1 * spread * (std::abs(ps.R(0, 0)) + 1.0) + 1.0 + half_gap;
    const double xa = ps.p_vox.x() + q0 * u_x;
    const double xb = ps.p_vox.x() + q1 * u_x;
    pb.x_lo = static_cast<std::int32_t>(std::floor(std::min(xa, xb) - reach_x));
    pb.x_hi = static_cast<std::int32_t>(std::ceil(std::max(xa, xb) + reach_x));
    const double reach_y = q1 * spread * (std::abs(ps.R(1, 0)) + 1.0) + 1.0 + half_gap;
    const double ya = ps.p_vox.y() + q0 * u_y;
    const double yb = ps.p_vox.y() + q1 * u_y;
    pb.y_lo = static_cast<std::int32_t>(std::floor(std::min(ya, yb) - reach_y));
    pb.y_hi = static_cast<std::int32_t>(std::ceil(std::max(ya, yb) + reach_y));
}

}  // namespace

PreparedScan PrepareScan(const SonarScan& scan,
                         const ScanFootprints& footprints,
                         const TsdfConfig& config,
                         const Geometry& geo,
                         const std::vector<ScanNeighbour>& neighbours) {
    const double inv_s = 1.0 / config.voxel_size_m;
    const bool beam_width = config.sensor_model == SensorModel::kBeamWidth;
    PreparedScan ps;
    ps.R = scan.T_world_sonar.linear();
    const Eigen::Vector3d p_world = scan.T_world_sonar.translation();
    if (!p_world.allFinite() || !ps.R.allFinite() ||
        p_world.cwiseAbs().maxCoeff() > kMaxSonarOffsetM) {
        ps.out_of_bounds = true;  // would make the x range (and the slab arrays) unbounded
        return ps;
    }
    ps.p_vox = p_world * inv_s;
    const std::vector<float>& r = footprints.r;
    const std::size_t n = r.size();
    ps.beams_no_detection = footprints.no_detection;
    ps.beams_out_of_range = footprints.out_of_range;
    ps.beams_inconsistent = footprints.inconsistent;
    for (float v : r) ps.beams_used += std::isfinite(v) ? 1 : 0;
    const double half_inc = 0.5 * std::abs(static_cast<double>(scan.angle_increment_rad));
    const double spread =
        beam_width ? std::tan(half_inc) + geo.tan_half_bw / std::cos(half_inc) : 0.0;
    const std::vector<float>& ranges = beam_width ? footprints.range : r;
    const std::vector<NeighbourFrame> slope_nbs = beam_width && config.footprint_neighbour_pings > 0
                                                      ? SlopeNeighbours(neighbours, ps, config)
                                                      : std::vector<NeighbourFrame>{};
    const NeighbourFans fans =
        beam_width && config.ping_gap_fill_m > 0.0 ? FansOf(neighbours) : NeighbourFans{};
    const double max_dtheta = std::tan(std::max(0.5, static_cast<double>(footprints.half)) *
                                       std::abs(static_cast<double>(scan.angle_increment_rad)));
    ps.beams.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(ranges[i])) continue;
        const double sin_t = footprints.sin_theta[i], cos_t = footprints.cos_theta[i];
        PreparedBeam pb;
        pb.range_vox = ranges[i];
        pb.range_prev_vox = std::numeric_limits<float>::quiet_NaN();
        pb.range_next_vox = std::numeric_limits<float>::quiet_NaN();
        if (beam_width) SameSurfaceNeighbours(i, n, footprints, pb);
        pb.weight = beam_width
                        ? config.weight_per_measurement * static_cast<float>(footprints.support[i])
                        : config.weight_per_measurement;
        pb.beam = static_cast<std::uint16_t>(i);
        // Gap to the neighbouring fans at the footprint (X on the beam axis at the footprint
        // range); a neighbour further than ping_gap_fill_m is not bridged.
        double gap_m = 0.0;
        if (fans.any()) {
            const FootprintHere here{
                p_world,
                &ps.R,
                p_world + ps.R * Eigen::Vector3d(0.0, sin_t, cos_t) *
                              (static_cast<double>(pb.range_vox) * config.voxel_size_m),
                sin_t,
                cos_t,
                static_cast<double>(footprints.range[i]),
                static_cast<double>(footprints.slope[i]),
                static_cast<double>(footprints.gate[i]),
                static_cast<double>(scan.angle_increment_rad),
                max_dtheta,
                config.voxel_size_m};
            gap_m = fans.GapAt(here,
                               i,
                               config.ping_gap_fill_m,
                               config.ping_gap_fill_per_beam,
                               config.ping_gap_bridge_pings);
        }
        pb.half_gap_vox = static_cast<float>(0.5 * gap_m * inv_s);
        if (!slope_nbs.empty()) {
            // The offsets out of the plane the slope is applied at: the cone's half-width at the
            // footprint, half the gap to the neighbouring pings, or a voxel.
            const double x_half =
                std::max({geo.tan_half_bw * static_cast<double>(footprints.range[i]),
                          static_cast<double>(pb.half_gap_vox),
                          1.0});
            const AlongTrack at = AlongTrackSlope(i,
                                                  footprints,
                                                  slope_nbs,
                                                  footprints.sin_theta[i],
                                                  footprints.cos_theta[i],
                                                  scan.angle_increment_rad,
                                                  x_half,
                                                  kTanMaxIncidence);
            if (at.s != 0.0) {
                pb.dr_dx = static_cast<float>(at.s);
                pb.x_fit_lo = static_cast<float>(at.x_lo);
                pb.x_fit_hi = static_cast<float>(at.x_hi);
            }
        }
        const double u_x = ps.R(0, 1) * sin_t + ps.R(0, 2) * cos_t;
        const double u_y = ps.R(1, 1) * sin_t + ps.R(1, 2) * cos_t;
        BeamBounds(ps, u_x, u_y, spread, geo, pb);
        ps.x_lo = std::min(ps.x_lo, pb.x_lo);
        ps.x_hi = std::max(ps.x_hi, pb.x_hi);
        ps.y_lo = std::min(ps.y_lo, pb.y_lo);
        ps.y_hi = std::max(ps.y_hi, pb.y_hi);
        ps.beams.push_back(pb);
    }
    if (beam_width) BuildFanColumns(ps, scan, footprints, geo);
    return ps;
}

PreparedScan PrepareScan(const std::vector<SonarScan>& scans,
                         std::size_t index,
                         const TsdfConfig& config,
                         const Geometry& geo) {
    const int k_max = NeighbourPings(config);
    std::vector<ScanFootprints> fps;
    fps.reserve(static_cast<std::size_t>(2 * k_max));  // the neighbours point into it
    std::vector<ScanNeighbour> nbs;
    for (int off = -k_max; off <= k_max; ++off) {
        const auto j = static_cast<std::ptrdiff_t>(index) + off;
        if (off == 0 || j < 0 || j >= static_cast<std::ptrdiff_t>(scans.size())) continue;
        const SonarScan& nb = scans[static_cast<std::size_t>(j)];
        fps.push_back(FitFootprints(nb, config));
        nbs.push_back({&nb, &fps.back(), off});
    }
    return PrepareScan(scans[index], FitFootprints(scans[index], config), config, geo, nbs);
}

PreparedScan PrepareScan(const SonarScan& scan, const TsdfConfig& config, const Geometry& geo) {
    return PrepareScan(scan, FitFootprints(scan, config), config, geo, {});
}

}  // namespace pitmap::proc::fusion::detail
