// SPDX-License-Identifier: MIT
#include "processor/compare/registration.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "processor/registration/robust.hpp"

namespace pitmap::proc::compare {
namespace {

constexpr double kPi = 3.14159265358979323846;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

Eigen::Matrix3d Exp(const Eigen::Vector3d& w) {
    const double a = w.norm();
    if (a < 1e-15) return Eigen::Matrix3d::Identity();
    return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

Eigen::Vector3d Log(const Eigen::Matrix3d& R) {
    const Eigen::AngleAxisd aa(R);
    return aa.angle() * aa.axis();
}

double Median(std::vector<double> v) {
    if (v.empty()) return 0;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

struct Sample {
    Eigen::Vector3d p;  // node of B (its CRS)
    double sigma = 0;   // 1-sigma of B's height there
};

struct Residual {
    double d = 0;   // point-to-plane distance
    double e = 0;   // vertical
    double nz = 1;  // cosine of the slope
    Eigen::Matrix<double, 1, 6> J;
    double sigma = 0;  // of d (both surfaces' heights, projected on the normal)
    bool valid = false;
};

// The residual of B's node p (already carried) against the reference surface.
Residual Evaluate(const SurfaceGrid& ref,
                  const SurfaceGrid& ref_raw,
                  int grad_step,
                  const Eigen::Vector3d& q,
                  const Eigen::Vector3d& pivot,
                  double sigma_b,
                  double max_tan_slope,
                  double min_soundings) {
    Residual r;
    const double h = ref.HeightAt(q.x(), q.y());
    if (!std::isfinite(h)) return r;
    // A's nodes under q must each hold the soundings asked for (unknown density: +inf).
    if (!(ref_raw.MinDensityAt(q.x(), q.y()) >= min_soundings)) return r;
    const int i = static_cast<int>(std::lround((q.x() - ref.x0) / ref.resolution_m));
    const int j = static_cast<int>(std::lround((q.y() - ref.y0) / ref.resolution_m));
    const Eigen::Vector2d g = GradientAt(ref, i, j, grad_step);
    if (!std::isfinite(g.x()) || !std::isfinite(g.y()) || g.norm() > max_tan_slope) return r;
    const double sigma_a = ref_raw.SigmaAt(q.x(), q.y());
    const Eigen::Vector3d m(-g.x(), -g.y(), 1.0);
    const Eigen::Vector3d n = m / m.norm();
    r.e = q.z() - h;
    r.nz = n.z();
    r.d = r.e * n.z();
    r.J.head<3>() = ((q - pivot).cross(n)).transpose();
    r.J.tail<3>() = n.transpose();
    const double sv = std::hypot(std::isfinite(sigma_a) ? sigma_a : sigma_b, sigma_b);
    r.sigma = sv * n.z();
    r.valid = true;
    return r;
}

// B's nodes over A's surface: how many, and their centroid (the correction's
// pivot); of them, those where both surfaces hold at least min_soundings.
struct Overlap {
    std::size_t nodes = 0;
    std::size_t dense = 0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
};

// The soundings behind B's node (i, j); +inf when B's density is not known.
double DensityOf(const SurfaceGrid& b, int i, int j) {
    return b.density.empty() ? std::numeric_limits<double>::infinity()
                             : static_cast<double>(b.density[b.index(i, j)]);
}

Overlap FindOverlap(const SurfaceGrid& a, const SurfaceGrid& b, double min_soundings) {
    Overlap o;
    for (int j = 0; j < b.ny; ++j) {
        for (int i = 0; i < b.nx; ++i) {
            if (!b.filled(i, j)) continue;
            const double x = b.x0 + i * b.resolution_m, y = b.y0 + j * b.resolution_m;
            if (!std::isfinite(a.HeightAt(x, y))) continue;
            ++o.nodes;
            o.dense += DensityOf(b, i, j) >= min_soundings && a.MinDensityAt(x, y) >= min_soundings;
            o.centroid += Eigen::Vector3d(x, y, b.z_m[b.index(i, j)]);
        }
    }
    if (o.nodes > 0) o.centroid /= static_cast<double>(o.nodes);
    return o;
}

// The subsampling of B's nodes that keeps at most about max_points of them.
int SampleStride(const SurfaceGrid& b, const RegistrationConfig& cfg) {
    const std::size_t filled_b = b.CountFilled();
    return std::max(1,
                    static_cast<int>(std::ceil(std::sqrt(static_cast<double>(filled_b) /
                                                         static_cast<double>(cfg.max_points)))));
}

// B's smoothed nodes every stride that hold at least min_soundings, with B's
// 1-sigma there (min_sigma_m where none).
std::vector<Sample> LevelSamples(const SurfaceGrid& rb,
                                 const SurfaceGrid& b,
                                 int stride,
                                 double min_soundings,
                                 const RegistrationConfig& cfg) {
    std::vector<Sample> samples;
    for (int j = 0; j < rb.ny; j += stride) {
        for (int i = 0; i < rb.nx; i += stride) {
            if (!rb.filled(i, j) || !(DensityOf(b, i, j) >= min_soundings)) continue;
            const float sg = b.sigma_m[b.index(i, j)];
            samples.push_back({Eigen::Vector3d(rb.x0 + i * rb.resolution_m,
                                               rb.y0 + j * rb.resolution_m,
                                               rb.z_m[rb.index(i, j)]),
                               std::isfinite(sg) ? static_cast<double>(sg) : cfg.min_sigma_m});
        }
    }
    return samples;
}

// Yaw and translation only: roll and pitch held at zero.
void HoldRollPitch(Mat6& H) {
    for (int k = 0; k < 2; ++k) {
        H.row(k).setZero();
        H.col(k).setZero();
        H(k, k) = 1.0;
    }
}

// The coarse-to-fine Gauss-Newton solve's state.
struct Refinement {
    RigidCorrection T;
    std::vector<Sample> last_samples;  // of the last step taken
    int iterations = 0;
    bool singular = false, converged_last = false;
    bool too_few_points = false;      // a step found too few valid residuals ...
    std::size_t valid_residuals = 0;  // ... this many
    double min_soundings = 0;         // both surfaces' nodes hold at least this many
};

// One Gauss-Newton step on the samples against ra; false when it could not be
// taken (too few valid residuals or singular normal equations, recorded in
// ref).
bool GaussNewtonStep(const SurfaceGrid& ra,
                     const SurfaceGrid& a,
                     int grad_step,
                     const std::vector<Sample>& samples,
                     double max_tan_slope,
                     const RegistrationConfig& cfg,
                     Refinement& ref) {
    RigidCorrection& T = ref.T;
    std::vector<Residual> rs(samples.size());
    std::vector<double> whitened;
    whitened.reserve(samples.size());
    for (std::size_t k = 0; k < samples.size(); ++k) {
        rs[k] = Evaluate(ra,
                         a,
                         grad_step,
                         T.Apply(samples[k].p),
                         T.pivot,
                         samples[k].sigma,
                         max_tan_slope,
                         ref.min_soundings);
        if (rs[k].valid) whitened.push_back(std::abs(rs[k].d));
    }
    if (whitened.size() < cfg.min_points) {
        ref.too_few_points = true;
        ref.valid_residuals = whitened.size();
        return false;
    }
    // The robust spread of the point-to-plane distances (MAD), floored.
    const double s = std::max(cfg.min_sigma_m, 1.4826 * Median(whitened));
    Mat6 H = Mat6::Zero();
    Vec6 g = Vec6::Zero();
    for (const Residual& r : rs) {
        if (!r.valid) continue;
        const double z = std::abs(r.d) / s;
        if (z > cfg.outlier_sigmas) continue;
        const double w = reg::RobustWeight(reg::RobustKernel::kCauchy, z, cfg.cauchy_width);
        H.noalias() += w * r.J.transpose() * r.J;
        g.noalias() += w * r.J.transpose() * r.d;
    }
    if (!cfg.estimate_roll_pitch) {
        HoldRollPitch(H);
        g(0) = g(1) = 0.0;
    }
    // A touch of damping keeps a direction the terrain does not fix at its value.
    const double damping = 1e-9 * H.trace();
    const Mat6 Hd = H + damping * Mat6::Identity();
    const Eigen::LDLT<Mat6> ldlt(Hd);
    if (ldlt.info() != Eigen::Success) {
        ref.singular = true;
        return false;
    }
    const Vec6 delta = -ldlt.solve(g);
    const Eigen::Matrix3d dR = Exp(delta.head<3>());
    T.rotation_rad = Log(dR * T.R());
    T.translation_m = dR * T.translation_m + delta.tail<3>();
    // The largest displacement of a node the step caused (rotation at the
    // overlap's radius plus translation).
    double radius_m = 0;
    for (std::size_t k = 0; k < samples.size(); k += 97)
        radius_m = std::max(radius_m, (samples[k].p - T.pivot).norm());
    const double step = delta.tail<3>().norm() + delta.head<3>().norm() * radius_m;
    ref.last_samples = samples;
    ref.converged_last = step < cfg.converged_step_m;
    return true;
}

// Coarse to fine: at each smoothing level, Gauss-Newton steps until converged
// or iterations_per_level; stops at a step that could not be taken.
Refinement Refine(const SurfaceGrid& a,
                  const SurfaceGrid& b,
                  const Eigen::Vector3d& pivot,
                  int stride,
                  double max_tan_slope,
                  double min_soundings,
                  const RegistrationConfig& cfg) {
    Refinement ref;
    ref.T.pivot = pivot;
    ref.min_soundings = min_soundings;
    for (const double smoothing : cfg.smoothing_m) {
        const int radius = static_cast<int>(std::lround(smoothing / a.resolution_m));
        const SurfaceGrid ra = Smoothed(a, radius);
        const SurfaceGrid rb =
            Smoothed(b, static_cast<int>(std::lround(smoothing / b.resolution_m)));
        const int grad_step =
            std::max({1, radius, static_cast<int>(std::lround(0.2 / a.resolution_m))});
        const std::vector<Sample> samples = LevelSamples(rb, b, stride, min_soundings, cfg);
        ref.converged_last = false;
        for (int it = 0; it < cfg.iterations_per_level; ++it) {
            ++ref.iterations;
            if (!GaussNewtonStep(ra, a, grad_step, samples, max_tan_slope, cfg, ref)) break;
            if (ref.converged_last) break;
        }
        if (ref.singular || ref.too_few_points) break;
    }
    return ref;
}

// The final residuals at the correction (full resolution) into res (nodes used
// and stable, robust sigma, vertical RMS before and after); returns the normal
// matrix of the stable set.
Mat6 FinalResiduals(const SurfaceGrid& a,
                    const RigidCorrection& T,
                    const std::vector<Sample>& samples,
                    double max_tan_slope,
                    double min_soundings,
                    const RegistrationConfig& cfg,
                    RegistrationResult& res) {
    Mat6 H = Mat6::Zero();
    double sum2_before = 0, sum2_after = 0, sum_after = 0, sum2_normal = 0, sum2_floor = 0;
    std::size_t n_stable = 0, n_valid = 0, n_floor = 0;
    // Floors: slope below 45 deg (the walls' edge everywhere in pitmap compare and its scores).
    const double floor_nz = std::cos(45.0 * kPi / 180.0);
    const int grad_step = std::max(1, static_cast<int>(std::lround(0.2 / a.resolution_m)));
    std::vector<double> abs_d;
    std::vector<Residual> fin(samples.size());
    for (std::size_t k = 0; k < samples.size(); ++k) {
        fin[k] = Evaluate(a,
                          a,
                          grad_step,
                          T.Apply(samples[k].p),
                          T.pivot,
                          samples[k].sigma,
                          max_tan_slope,
                          min_soundings);
        if (fin[k].valid) abs_d.push_back(std::abs(fin[k].d));
    }
    const double s = std::max(cfg.min_sigma_m, 1.4826 * Median(abs_d));
    for (std::size_t k = 0; k < fin.size(); ++k) {
        const Residual& r = fin[k];
        if (!r.valid) continue;
        ++n_valid;
        const double z = std::abs(r.d) / s;
        if (z > cfg.outlier_sigmas) continue;
        ++n_stable;
        const double w = reg::RobustWeight(reg::RobustKernel::kCauchy, z, cfg.cauchy_width);
        H.noalias() += w * r.J.transpose() * r.J;
        sum2_after += r.e * r.e;
        sum_after += r.e;
        sum2_normal += r.d * r.d;
        if (r.nz >= floor_nz) {
            sum2_floor += r.e * r.e;
            ++n_floor;
        }
        const double before = samples[k].p.z() - a.HeightAt(samples[k].p.x(), samples[k].p.y());
        if (std::isfinite(before)) sum2_before += before * before;
    }
    res.points_overlap = n_valid;
    res.points_stable = n_stable;
    res.robust_sigma_m = s;
    if (n_stable > 0) {
        res.rms_vertical_after_m = std::sqrt(sum2_after / static_cast<double>(n_stable));
        res.mean_vertical_after_m = sum_after / static_cast<double>(n_stable);
        res.rms_vertical_before_m = std::sqrt(sum2_before / static_cast<double>(n_stable));
        res.rms_normal_after_m = std::sqrt(sum2_normal / static_cast<double>(n_stable));
    }
    res.points_stable_floor = n_floor;
    if (n_floor > 0) res.rms_vertical_floor_after_m = std::sqrt(sum2_floor / n_floor);
    if (!cfg.estimate_roll_pitch) HoldRollPitch(H);
    return H;
}

// The correction's covariance and 1-sigma into res from the stable set's normal
// matrix; false when the stable terrain does not fix every component.
bool SetCovariance(const Mat6& H,
                   int stride,
                   double resolution_b_m,
                   const RegistrationConfig& cfg,
                   RegistrationResult& res) {
    const Eigen::SelfAdjointEigenSolver<Mat6> eig(H);
    if (eig.eigenvalues()(0) <= 1e-12 * std::max(1.0, eig.eigenvalues()(5))) return false;
    // Correlated neighbours: the stable area holds N_eff independent patches.
    const double s = res.robust_sigma_m;
    const std::size_t n_stable = res.points_stable;
    const double area_stable = static_cast<double>(n_stable) *
                               static_cast<double>(stride * stride) * resolution_b_m *
                               resolution_b_m;
    const double n_eff =
        std::max(1.0, area_stable / (cfg.correlation_length_m * cfg.correlation_length_m));
    const double growth = std::max(1.0, static_cast<double>(n_stable) / n_eff);
    res.covariance = s * s * growth * H.inverse();
    if (!cfg.estimate_roll_pitch) {
        res.covariance.row(0).setZero();
        res.covariance.col(0).setZero();
        res.covariance.row(1).setZero();
        res.covariance.col(1).setZero();
    }
    for (int k = 0; k < 6; ++k) res.sigma(k) = std::sqrt(std::max(0.0, res.covariance(k, k)));
    return true;
}

std::string RegistrationMessage(const RegistrationResult& res, int dof) {
    const RigidCorrection& T = res.correction;
    char buf[320];
    std::snprintf(buf,
                  sizeof buf,
                  "%s after %d iterations (%d DoF): translation %.3f %.3f %.3f m, roll "
                  "%.4f "
                  "pitch %.4f yaw %.4f deg; %zu of %zu nodes stable, residual %.3f m RMS "
                  "vertical (%.3f before)",
                  ToString(res.termination),
                  res.iterations,
                  dof,
                  T.translation_m.x(),
                  T.translation_m.y(),
                  T.translation_m.z(),
                  T.rotation_rad.x() * 180 / kPi,
                  T.rotation_rad.y() * 180 / kPi,
                  T.rotation_rad.z() * 180 / kPi,
                  res.points_stable,
                  res.points_overlap,
                  res.rms_vertical_after_m,
                  res.rms_vertical_before_m);
    return buf;
}

}  // namespace

const char* ToString(RegistrationTermination t) {
    switch (t) {
        case RegistrationTermination::kConverged:
            return "converged";
        case RegistrationTermination::kMaxIterations:
            return "max_iterations";
        case RegistrationTermination::kTooFewPoints:
            return "too_few_points";
        case RegistrationTermination::kSingular:
            return "singular";
    }
    return "?";
}

Eigen::Matrix3d RigidCorrection::R() const {
    return Exp(rotation_rad);
}

Eigen::Vector3d RigidCorrection::Apply(const Eigen::Vector3d& p) const {
    return R() * (p - pivot) + pivot + translation_m;
}

Eigen::Vector3d RigidCorrection::CarryOnto(const SurfaceGrid& b, double x, double y) const {
    // Find b_xy such that Apply(b_xy, H_B(b_xy)).xy = (x, y): start from the
    // inverse map of the target at the pivot's height and correct by the residual
    // (the map is nearly the identity).
    const Eigen::Matrix3d Rm = R();
    Eigen::Vector3d target(x, y, pivot.z());
    Eigen::Vector3d src = Rm.transpose() * (target - pivot - translation_m) + pivot;
    for (int k = 0; k < 4; ++k) {
        src.z() = b.HeightAt(src.x(), src.y());
        if (!std::isfinite(src.z())) return {x, y, std::numeric_limits<double>::quiet_NaN()};
        const Eigen::Vector3d moved = Rm * (src - pivot) + pivot + translation_m;
        const Eigen::Vector2d miss(x - moved.x(), y - moved.y());
        if (miss.norm() < 1e-5) return {x, y, moved.z()};
        src.head<2>() += (Rm.transpose().topLeftCorner<2, 2>() * miss);
    }
    src.z() = b.HeightAt(src.x(), src.y());
    if (!std::isfinite(src.z())) return {x, y, std::numeric_limits<double>::quiet_NaN()};
    return {x, y, (Rm * (src - pivot) + pivot + translation_m).z()};
}

std::vector<std::string> RegistrationConfig::Validate() const {
    std::vector<std::string> p;
    if (smoothing_m.empty()) p.push_back("registration.smoothing_m: at least one level");
    for (double s : smoothing_m) {
        if (!(s >= 0 && s < 100)) p.push_back("registration.smoothing_m: each in [0, 100) m");
    }
    if (iterations_per_level < 1 || iterations_per_level > 100)
        p.push_back("registration.iterations_per_level must be 1..100");
    if (max_points < 100) p.push_back("registration.max_points must be >= 100");
    if (!(cauchy_width > 0)) p.push_back("registration.cauchy_width must be > 0");
    if (!(outlier_sigmas > 1)) p.push_back("registration.outlier_sigmas must be > 1");
    if (!(max_slope_deg > 0 && max_slope_deg < 90))
        p.push_back("registration.max_slope_deg must be in (0, 90)");
    if (!(min_sigma_m > 0)) p.push_back("registration.min_sigma_m must be > 0");
    if (!(correlation_length_m > 0)) p.push_back("registration.correlation_length_m must be > 0");
    if (min_points < 10) p.push_back("registration.min_points must be >= 10");
    if (!(converged_step_m > 0)) p.push_back("registration.converged_step_m must be > 0");
    if (!(min_soundings >= 0 && min_soundings < 1e6))
        p.push_back("registration.min_soundings must be in [0, 1e6)");
    return p;
}

RegistrationResult RegisterSurfaces(const SurfaceGrid& a,
                                    const SurfaceGrid& b,
                                    const RegistrationConfig& cfg) {
    RegistrationResult res;
    const double max_tan_slope = std::tan(cfg.max_slope_deg * kPi / 180.0);
    // The overlap and the pivot: B's nodes over A's surface.
    const int stride = SampleStride(b, cfg);
    const Overlap overlap = FindOverlap(a, b, cfg.min_soundings);
    res.overlap_area_m2 = static_cast<double>(overlap.nodes) * b.resolution_m * b.resolution_m;
    if (overlap.nodes < cfg.min_points) {
        res.termination = RegistrationTermination::kTooFewPoints;
        res.message = "the surfaces overlap on " + std::to_string(overlap.nodes) + " nodes (" +
                      std::to_string(static_cast<long>(res.overlap_area_m2)) + " m2); at least " +
                      std::to_string(cfg.min_points) + " needed";
        return res;
    }
    // The nodes both surveys sounded enough, when at least half of the overlap is such.
    const bool dense = 2 * overlap.dense >= overlap.nodes;
    res.min_soundings_applied = dense ? cfg.min_soundings : 0.0;
    res.points_sparse = dense ? overlap.nodes - overlap.dense : 0;
    const Refinement ref =
        Refine(a, b, overlap.centroid, stride, max_tan_slope, res.min_soundings_applied, cfg);
    res.correction = ref.T;
    if (ref.too_few_points) {
        res.termination = RegistrationTermination::kTooFewPoints;
        res.message = "too few nodes of B over A's surface after the correction (" +
                      std::to_string(ref.valid_residuals) + ")";
        return res;
    }
    res.iterations = ref.iterations;
    if (ref.singular) {
        res.termination = RegistrationTermination::kSingular;
        res.message =
            "the normal equations are singular: the overlap does not fix "
            "the correction";
        return res;
    }
    const Mat6 H = FinalResiduals(
        a, ref.T, ref.last_samples, max_tan_slope, res.min_soundings_applied, cfg, res);
    // The residuals over every overlapping node, the sparse ones too (the record).
    {
        RegistrationResult all;
        FinalResiduals(
            a, ref.T, LevelSamples(b, b, stride, 0.0, cfg), max_tan_slope, 0.0, cfg, all);
        res.rms_vertical_all_nodes_after_m = all.rms_vertical_after_m;
        res.rms_normal_all_nodes_after_m = all.rms_normal_after_m;
        res.points_stable_all_nodes = all.points_stable;
    }
    if (!SetCovariance(H, stride, b.resolution_m, cfg, res)) {
        res.termination = RegistrationTermination::kSingular;
        res.message = "the stable terrain does not fix every component of the correction";
        return res;
    }
    res.termination = ref.converged_last ? RegistrationTermination::kConverged
                                         : RegistrationTermination::kMaxIterations;
    res.message = RegistrationMessage(res, cfg.estimate_roll_pitch ? 6 : 4);
    return res;
}

}  // namespace pitmap::proc::compare
