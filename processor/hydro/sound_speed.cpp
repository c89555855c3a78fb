// SPDX-License-Identifier: MIT
#include "processor/hydro/sound_speed.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <unordered_map>

#include "processor/svp/seawater.hpp"

namespace pitmap::proc::hydro {

namespace {

constexpr int kGroups = 8;  // jackknife groups of cells
// |dc / c| beyond which a fit is no column speed error (100 m/s of 1450).
constexpr double kMaxRelativeError = 0.07;

double Square(double x) {
    return x * x;
}

// The sums of one cell: regressors A = (1, x, y) (x, y from the cell's corner), the refraction
// regressor g, the height z, the depth d.
struct CellSums {
    std::size_t n = 0;
    Eigen::Matrix3d AA = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Ag = Eigen::Vector3d::Zero(), Az = Eigen::Vector3d::Zero();
    double gg = 0, gz = 0, zz = 0, d = 0;
};

}  // namespace

std::vector<std::string> SoundSpeedSigmaConfig::Validate() const {
    std::vector<std::string> out;
    const auto nonneg = [&](double v, const char* name) {
        if (!(std::isfinite(v) && v >= 0)) out.push_back(std::string(name) + " must be >= 0");
    };
    nonneg(cast_age_rate_mps_per_h, "sound_speed.cast_age_rate_mps_per_h");
    nonneg(cast_distance_rate_mps_per_km, "sound_speed.cast_distance_rate_mps_per_km");
    nonneg(overlap_min_weight_m2, "sound_speed.overlap_min_weight_m2");
    nonneg(overlap_stratified_mps, "sound_speed.overlap_stratified_mps");
    if (!(overlap_min_estimated_share >= 0 && overlap_min_estimated_share <= 1)) {
        out.push_back("sound_speed.overlap_min_estimated_share must be within [0, 1]");
    }
    if (!(overlap_cell_m > 0 && overlap_cell_m <= 100)) {
        out.push_back("sound_speed.overlap_cell_m must be within (0, 100]");
    }
    if (!(overlap_max_slope_deg > 0 && overlap_max_slope_deg < 90)) {
        out.push_back("sound_speed.overlap_max_slope_deg must be within (0, 90)");
    }
    if (!(overlap_max_angle_deg > 0 && overlap_max_angle_deg < 85)) {
        out.push_back("sound_speed.overlap_max_angle_deg must be within (0, 85)");
    }
    if (overlap_min_cell_soundings < 4) {
        out.push_back("sound_speed.overlap_min_cell_soundings must be >= 4 (a plane and k)");
    }
    const auto& e = overlap_depth_edges_m;
    if (e.size() < 2 || !std::is_sorted(e.begin(), e.end()) ||
        std::adjacent_find(e.begin(), e.end()) != e.end() || !(e.front() >= 0)) {
        out.push_back("sound_speed.overlap_depth_edges_m: at least two, increasing, from >= 0");
    }
    if (overlap_max_soundings == 0) out.push_back("sound_speed.overlap_max_soundings must be > 0");
    return out;
}

double CastSpeedSigma(double base_sigma_mps,
                      double age_s,
                      double distance_m,
                      double surface_disagreement_mps,
                      const SoundSpeedSigmaConfig& config) {
    double v = Square(base_sigma_mps);
    if (std::isfinite(age_s)) v += Square(config.cast_age_rate_mps_per_h * std::abs(age_s) / 3600);
    if (std::isfinite(distance_m)) {
        v += Square(config.cast_distance_rate_mps_per_km * std::abs(distance_m) / 1000);
    }
    if (std::isfinite(surface_disagreement_mps)) v += Square(surface_disagreement_mps);
    return std::sqrt(v);
}

double NoCastPriorSigma(double surface_speed_mps) {
    return std::abs(surface_speed_mps - svp::SoundSpeedChenMillero(0.0, 4.0, 0.0)) / std::sqrt(3.0);
}

double RefractionRegressor(const Eigen::Vector3d& o) {
    const double d = -o.z();
    if (!(d > 0)) return 0.0;
    const double tan2 = (o.x() * o.x() + o.y() * o.y()) / (d * d);
    return d * (1.0 - tan2);
}

bool OverlapSpeedEstimate::estimated() const {
    return std::any_of(
        classes.begin(), classes.end(), [](const OverlapDepthClass& c) { return c.estimated; });
}

double OverlapSpeedEstimate::EstimatedShare() const {
    std::size_t all = 0, est = 0;
    for (const auto& c : classes) {
        all += c.soundings;
        if (c.estimated) est += c.soundings;
    }
    return all > 0 ? static_cast<double>(est) / static_cast<double>(all) : 0.0;
}

int OverlapSpeedEstimate::StratifiedClass(double c_mps, double stratified_mps) const {
    int out = -1;
    double worst = 0;
    for (std::size_t k = 0; k < classes.size(); ++k) {
        const OverlapDepthClass& c = classes[k];
        const double e = std::abs(c.relative_error);
        if (!c.estimated || !(e * c_mps > stratified_mps) || !(e > 3 * c.relative_error_se))
            continue;
        if (e > worst) {
            worst = e;
            out = static_cast<int>(k);
        }
    }
    return out;
}

double ColumnRelativeSigma(double p, double e, double se) {
    if (std::abs(e) > 3 * se) return std::sqrt(p * p + e * e + se * se);
    const double p2 = p * p, se2 = se * se;
    if (!(p2 + se2 > 0)) return 0.0;
    const double k = p2 / (p2 + se2);
    return std::sqrt(k * e * k * e + k * se2);
}

double OverlapSpeedEstimate::RelativeSigmaAt(double depth_m, double prior_relative_sigma) const {
    const auto sigma = [&](const OverlapDepthClass& c) {
        return ColumnRelativeSigma(prior_relative_sigma, c.relative_error, c.relative_error_se);
    };
    const int n = static_cast<int>(classes.size());
    int k = 0;
    while (k + 1 < n && !(depth_m < classes[static_cast<std::size_t>(k)].hi_m)) ++k;
    if (n == 0) return std::nan("");
    if (classes[static_cast<std::size_t>(k)].estimated) {
        return sigma(classes[static_cast<std::size_t>(k)]);
    }
    double out = std::nan("");
    for (int step = -1; step <= 1; step += 2) {
        for (int j = k + step; j >= 0 && j < n; j += step) {
            const OverlapDepthClass& c = classes[static_cast<std::size_t>(j)];
            if (!c.estimated) continue;
            out = std::isnan(out) ? sigma(c) : std::max(out, sigma(c));
            break;
        }
    }
    return out;
}

namespace {

// The depth classes between the configured edges, nothing estimated yet.
std::vector<OverlapDepthClass> DepthClasses(const std::vector<double>& edges) {
    std::vector<OverlapDepthClass> out;
    for (std::size_t c = 0; c + 1 < edges.size(); ++c) {
        OverlapDepthClass k;
        k.lo_m = edges[c];
        k.hi_m = edges[c + 1];
        out.push_back(k);
    }
    return out;
}

// The cells' sums over the soundings (at most overlap_max_soundings of them, evenly strided)
// within overlap_max_angle_deg of the vertical, keyed by the cell's (x, y) index.
std::unordered_map<std::int64_t, CellSums> SumCells(const std::vector<Eigen::Vector3d>& points,
                                                    const std::vector<Eigen::Vector3d>& offsets,
                                                    const SoundSpeedSigmaConfig& config) {
    const std::size_t n = std::min(points.size(), offsets.size());
    const std::size_t stride = OverlapStride(n, config);
    const double cell = config.overlap_cell_m;
    const double max_tan2 = Square(std::tan(config.overlap_max_angle_deg * M_PI / 180.0));
    std::unordered_map<std::int64_t, CellSums> cells;
    for (std::size_t i = 0; i < n; i += stride) {
        const Eigen::Vector3d& o = offsets[i];
        const Eigen::Vector3d& p = points[i];
        const double d = -o.z();
        if (!(d > 0) || !p.allFinite()) continue;
        if ((o.x() * o.x() + o.y() * o.y()) / (d * d) > max_tan2) continue;
        const double fx = std::floor(p.x() / cell), fy = std::floor(p.y() / cell);
        if (std::abs(fx) > 1e9 || std::abs(fy) > 1e9) continue;
        const std::int64_t key =
            (static_cast<std::int64_t>(fx) << 32) ^ (static_cast<std::int64_t>(fy) & 0xffffffffLL);
        CellSums& s = cells[key];
        const Eigen::Vector3d a(1.0, p.x() - fx * cell, p.y() - fy * cell);
        const double g = RefractionRegressor(o);
        ++s.n;
        s.AA += a * a.transpose();
        s.Ag += a * g;
        s.Az += a * p.z();
        s.gg += g * g;
        s.gz += g * p.z();
        s.zz += p.z() * p.z();
        s.d += d;
    }
    return cells;
}

// A floor cell's residual cross products after its own plane, its depth class and jackknife
// group.
struct CellResidual {
    std::size_t cls, group, n;
    double rgg, rgz, rzz;
    bool used = true;  // kept by the robust fit
};

// The residuals of the cells with enough soundings, a well-posed plane no steeper than
// overlap_max_slope_deg and a mean depth within the depth classes.
std::vector<CellResidual> FloorCellResiduals(
    const std::unordered_map<std::int64_t, CellSums>& cells, const SoundSpeedSigmaConfig& config) {
    const std::vector<double>& edges = config.overlap_depth_edges_m;
    std::vector<CellResidual> kept;
    const double max_slope = std::tan(config.overlap_max_slope_deg * M_PI / 180.0);
    for (const auto& [key, s] : cells) {
        if (s.n < static_cast<std::size_t>(config.overlap_min_cell_soundings)) continue;
        const Eigen::LDLT<Eigen::Matrix3d> ldlt(s.AA);
        if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-9)) continue;
        const Eigen::Vector3d bz = ldlt.solve(s.Az), bg = ldlt.solve(s.Ag);
        if (std::hypot(bz[1], bz[2]) > max_slope) continue;  // not a floor
        const double rgg = s.gg - s.Ag.dot(bg);
        const double rgz = s.gz - s.Ag.dot(bz);
        const double rzz = s.zz - s.Az.dot(bz);
        if (!(rgg > 0) || !std::isfinite(rgz) || !std::isfinite(rzz)) continue;
        const double dmean = s.d / static_cast<double>(s.n);
        const auto it = std::upper_bound(edges.begin(), edges.end(), dmean);
        if (it == edges.begin() || it == edges.end()) continue;
        const std::size_t c = static_cast<std::size_t>(it - edges.begin()) - 1;
        const std::size_t grp = static_cast<std::size_t>(
            (static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ull) >> 61);  // 0..7
        kept.push_back({c, grp, s.n, rgg, rgz, std::max(rzz, 0.0)});
    }
    return kept;
}

// The fit, robust to cells that are no floor (a bench edge, an echo, two surfaces): a cell
// whose residual RMS after the plane and the class's k exceeds 3 times the class's median
// cell RMS (and 2 cm) is left out (`used` false), three times over.
void LeaveOutNonFloorCells(std::vector<CellResidual>& kept, std::size_t nclass) {
    std::vector<double> kappa(nclass, 0.0);
    const auto fit = [&]() {
        for (std::size_t c = 0; c < nclass; ++c) {
            double gg = 0, gz = 0;
            for (const CellResidual& k : kept) {
                if (k.used && k.cls == c) {
                    gg += k.rgg;
                    gz += k.rgz;
                }
            }
            kappa[c] = gg > 0 ? gz / gg : 0.0;
        }
    };
    const auto cell_rms = [&](const CellResidual& k) {
        const double ss = k.rzz - 2 * kappa[k.cls] * k.rgz + kappa[k.cls] * kappa[k.cls] * k.rgg;
        return std::sqrt(std::max(ss, 0.0) /
                         static_cast<double>(std::max<std::size_t>(k.n, 5) - 4));
    };
    fit();
    for (int iter = 0; iter < 3; ++iter) {
        for (std::size_t c = 0; c < nclass; ++c) {
            std::vector<double> rms;
            for (const CellResidual& k : kept) {
                if (k.cls == c) rms.push_back(cell_rms(k));
            }
            if (rms.empty()) continue;
            std::nth_element(
                rms.begin(), rms.begin() + static_cast<std::ptrdiff_t>(rms.size() / 2), rms.end());
            const double limit = std::max(0.02, 3.0 * rms[rms.size() / 2]);
            for (CellResidual& k : kept) {
                if (k.cls == c) k.used = cell_rms(k) <= limit;
            }
        }
        fit();
    }
}

// One depth class's residual cross products per jackknife group.
struct GroupSums {
    std::array<double, kGroups> gg{};
    std::array<double, kGroups> gz{};
};

// The used cells' sums per class and group; their cells and soundings counted into `out`.
std::vector<GroupSums> SumGroups(const std::vector<CellResidual>& kept, OverlapSpeedEstimate& out) {
    std::vector<GroupSums> sums(out.classes.size());
    for (const CellResidual& k : kept) {
        if (!k.used) continue;
        sums[k.cls].gg[k.group] += k.rgg;
        sums[k.cls].gz[k.group] += k.rgz;
        ++out.classes[k.cls].cells;
        out.classes[k.cls].soundings += k.n;
        ++out.cells_used;
        out.soundings_used += k.n;
    }
    return sums;
}

// The class's relative column speed error and its standard error, `estimated` when the class
// weighs enough, the error is within any water's and the jackknife has two groups or more.
void EstimateClass(const GroupSums& sums,
                   const SoundSpeedSigmaConfig& config,
                   OverlapDepthClass& k) {
    double gg = 0, gz = 0;
    for (int g = 0; g < kGroups; ++g) {
        gg += sums.gg[g];
        gz += sums.gz[g];
    }
    k.weight_m2 = gg;
    if (!(gg >= config.overlap_min_weight_m2) || !(gg > 0)) return;
    k.relative_error = gz / gg;
    // Beyond any water (fresh water at 0-30 degC spans about 1400-1510 m/s) the fit
    // explains something else: not an estimate.
    if (std::abs(k.relative_error) > kMaxRelativeError) return;
    // Delete-a-group jackknife: the cells of a group share no sounding, but the passes that
    // make their overlaps do, so the formal sigma^2 / gg would be too small.
    double ss = 0;
    int used = 0;
    for (int g = 0; g < kGroups; ++g) {
        const double gg_g = gg - sums.gg[g];
        if (!(gg_g > 0)) continue;
        ss += Square((gz - sums.gz[g]) / gg_g - k.relative_error);
        ++used;
    }
    if (used < 2) return;
    k.relative_error_se = std::sqrt(static_cast<double>(used - 1) / used * ss);
    k.estimated = true;
}

// The estimate's one-line summary.
std::string EstimateMessage(const OverlapSpeedEstimate& e) {
    char buf[200];
    int estimated = 0;
    double worst = 0;
    for (const auto& k : e.classes) {
        if (!k.estimated) continue;
        ++estimated;
        worst = std::max(worst, std::hypot(k.relative_error, k.relative_error_se));
    }
    std::snprintf(buf,
                  sizeof buf,
                  "%zu soundings in %zu overlap cells: %d depth classes estimated, largest "
                  "relative column speed sigma %.4f",
                  e.soundings_used,
                  e.cells_used,
                  estimated,
                  worst);
    return buf;
}

}  // namespace

std::size_t OverlapStride(std::size_t soundings, const SoundSpeedSigmaConfig& config) {
    const std::size_t most = std::max<std::size_t>(1, config.overlap_max_soundings);
    return std::max<std::size_t>(1, (soundings + most - 1) / most);
}

OverlapSpeedEstimate EstimateColumnSpeedError(const std::vector<Eigen::Vector3d>& points,
                                              const std::vector<Eigen::Vector3d>& offsets,
                                              const SoundSpeedSigmaConfig& config) {
    OverlapSpeedEstimate out;
    out.classes = DepthClasses(config.overlap_depth_edges_m);
    std::vector<CellResidual> cells = FloorCellResiduals(SumCells(points, offsets, config), config);
    LeaveOutNonFloorCells(cells, out.classes.size());
    const std::vector<GroupSums> sums = SumGroups(cells, out);
    for (std::size_t c = 0; c < out.classes.size(); ++c) {
        EstimateClass(sums[c], config, out.classes[c]);
    }
    out.message = EstimateMessage(out);
    return out;
}

}  // namespace pitmap::proc::hydro
