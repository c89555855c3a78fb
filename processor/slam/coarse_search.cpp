// SPDX-License-Identifier: MIT
// The SLAM coarse horizontal search (not in the seed paper: its closest-point matching starts
// from an INS that drifted less than the pair distance; after a GNSS outage of minutes ours
// drifts metres, beyond any closest-point capture range).
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <unordered_map>
#include <utility>

#include "processor/registration/grid_key.hpp"
#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

namespace {

constexpr double kCoarseScoreUnitM = 0.01;  // fit score unit against the smoothness terms
constexpr double kInfeasible = 1e30;
constexpr double kCoarseExtentMarginM = 0.25;
// Offsets whose points fall on the grid less than this fraction of the best offset's are out (a
// fit on a few points). Not more: a section at the survey's edge overlaps the others only
// partly at its true place, and a larger fraction pushes it inwards.
constexpr double kCoarseMinCoverFraction = 0.25;
constexpr double kCoarseTemperature = 2.0;   // score units (cm of mean deviation)
constexpr double kCoarseMinDriftRw = 0.003;  // m/s/sqrt(s), when the drift term is off
constexpr int kCoarseRefinements = 3;
constexpr double kCoarseWindowSigmas = 3.0;
constexpr double kCoarseMinWindowM = 1.5;

// Largest eigenvalue of a symmetric 2x2 matrix, closed form (Eigen's general EigenSolver costs
// this file a third of its compile time for the same number).
double LargestEigenvalue(const Eigen::Matrix2d& a) {
    const double half_trace = 0.5 * (a(0, 0) + a(1, 1));
    const double half_diff = 0.5 * (a(0, 0) - a(1, 1));
    const double off = 0.5 * (a(0, 1) + a(1, 0));
    return half_trace + std::hypot(half_diff, off);
}

// A section's horizontal sigma: the median over its slices (a section where GNSS returns is
// mostly pulled back already). Marks the sections to search.
std::vector<double> SectionSigmas(const Input& in,
                                  const std::vector<Block>& blocks,
                                  const SlamConfig& cfg,
                                  std::vector<SlamSection>& sections) {
    std::vector<double> sigma_h(blocks.size(), 0.0);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        std::vector<double> sg;
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
            sg.push_back(std::max(in.sigma[s](3), in.sigma[s](4)));
        }
        std::nth_element(
            sg.begin(), sg.begin() + static_cast<std::ptrdiff_t>(sg.size() / 2), sg.end());
        sigma_h[b] = sg[sg.size() / 2];
        sections[b].sigma_h_m = sigma_h[b];
        sections[b].searched = sigma_h[b] > cfg.coarse_search_min_sigma_m;
    }
    return sigma_h;
}

// The world position of point k of slice s.
Eigen::Vector3d WorldPoint(const Input& in,
                           const std::vector<Pose>& T,
                           std::size_t s,
                           std::size_t k) {
    return (T[s] * in.points[k].cast<double>()).eval();
}

// A height grid of the sections the INS is sure about: per cell a plane
// z = c0 + c1 (x - xc) + c2 (y - yc) by least squares (walls are steep).
class HeightGrid {
public:
    explicit HeightGrid(double cell_m) : h_(cell_m) {}

    void Add(const Eigen::Vector3d& p) {
        Cell& c = cells_[Key(p.x(), p.y())];
        const auto [ix, iy] = CellOf(p.x(), p.y());
        c.xc = (static_cast<double>(ix) + 0.5) * h_;
        c.yc = (static_cast<double>(iy) + 0.5) * h_;
        const Eigen::Vector3d u(1.0, p.x() - c.xc, p.y() - c.yc);
        c.A += u * u.transpose();
        c.b += u * p.z();
        c.x0 = std::min(c.x0, p.x());
        c.x1 = std::max(c.x1, p.x());
        c.y0 = std::min(c.y0, p.y());
        c.y1 = std::max(c.y1, p.y());
        ++c.n;
    }

    // Fits the planes; cells with fewer than 4 points or no finite plane are dropped.
    void Fit() {
        for (auto it = cells_.begin(); it != cells_.end();) {
            Cell& c = it->second;
            // Slightly regularised towards a level plane when the points line up.
            Eigen::Matrix3d A = c.A;
            A(1, 1) += 1e-3 * c.n;
            A(2, 2) += 1e-3 * c.n;
            if (c.n >= 4) c.c = A.ldlt().solve(c.b);
            it = c.n < 4 || !c.c.allFinite() ? cells_.erase(it) : std::next(it);
        }
    }

    bool empty() const { return cells_.empty(); }

    // The plane's height at (x, y), if a fitted cell covers it.
    std::optional<double> HeightAt(double x, double y) const {
        const auto it = cells_.find(Key(x, y));
        if (it == cells_.end() || !it->second.Covers(x, y)) return std::nullopt;
        const Cell& g = it->second;
        return g.c(0) + g.c(1) * (x - g.xc) + g.c(2) * (y - g.yc);
    }

private:
    struct Cell {
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        double xc = 0, yc = 0;
        // Extent of the cell's points: a point outside it (beyond kCoarseExtentMarginM) is off
        // the grid rather than an extrapolation of the plane (the grid's edges are swath edges).
        double x0 = std::numeric_limits<double>::max(), x1 = std::numeric_limits<double>::lowest();
        double y0 = std::numeric_limits<double>::max(), y1 = std::numeric_limits<double>::lowest();
        int n = 0;
        bool Covers(double x, double y) const {
            return x >= x0 - kCoarseExtentMarginM && x <= x1 + kCoarseExtentMarginM &&
                   y >= y0 - kCoarseExtentMarginM && y <= y1 + kCoarseExtentMarginM;
        }
    };
    std::pair<std::int64_t, std::int64_t> CellOf(double x, double y) const {
        return std::pair{static_cast<std::int64_t>(std::floor(x / h_)),
                         static_cast<std::int64_t>(std::floor(y / h_))};
    }
    std::uint64_t Key(double x, double y) const {
        const auto [ix, iy] = CellOf(x, y);
        return reg::CellKey(ix, iy);
    }

    double h_;
    std::unordered_map<std::uint64_t, Cell> cells_;
};

// The grid of the trusted sections' points (sigma_h within coarse_search_min_sigma_m).
HeightGrid TrustedGrid(const Input& in,
                       const std::vector<Pose>& T,
                       const std::vector<Block>& blocks,
                       const std::vector<double>& sigma_h,
                       const SlamConfig& cfg) {
    HeightGrid grid(cfg.coarse_search_cell_m);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        if (sigma_h[b] > cfg.coarse_search_min_sigma_m) continue;
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
            for (std::size_t k = in.offset[s]; k < in.offset[s + 1]; ++k)
                grid.Add(WorldPoint(in, T, s, k));
        }
    }
    grid.Fit();
    return grid;
}

// The candidate horizontal offsets: a square of side x side on a coarse_search_step_m grid,
// within coarse_search_m of zero, the same for every searched section.
class Candidates {
public:
    explicit Candidates(const SlamConfig& cfg)
        : step_(cfg.coarse_search_step_m),
          half_(std::lround(std::floor(cfg.coarse_search_m / cfg.coarse_search_step_m))),
          side_(2 * half_ + 1) {}

    std::size_t size() const { return static_cast<std::size_t>(side_ * side_); }
    Eigen::Vector2d operator[](std::size_t c) const {
        const auto i = static_cast<long>(c);
        return Eigen::Vector2d(static_cast<double>(i % side_ - half_) * step_,
                               static_cast<double>(i / side_ - half_) * step_);
    }
    // The candidate nearest to offset o (clamped to the square).
    std::size_t Nearest(const Eigen::Vector2d& o) const {
        const long ix = std::clamp(std::lround(o.x() / step_), -half_, half_);
        const long iy = std::clamp(std::lround(o.y() / step_), -half_, half_);
        return static_cast<std::size_t>((iy + half_) * side_ + ix + half_);
    }

private:
    double step_;
    long half_;  // candidates either side of zero
    long side_;
};

// How well each candidate offset fits one searched section to the grid. Empty when the section
// did not overlap the grid.
struct SectionFit {
    std::vector<double> score;      // per candidate; kInfeasible = seen on too little grid
    std::vector<double> median_dz;  // per candidate: grid minus section heights, median, m
    bool empty() const { return score.empty(); }
};

// Score: the truncated mean |dz - median dz| over the points that fall on the grid (inside a
// cell's own extent: no extrapolation past swath edges), in kCoarseScoreUnitM, plus the INS prior
// on the offset (sigma_h), among offsets that see enough of the grid.
SectionFit FitSection(const Input& in,
                      const std::vector<Pose>& T,
                      const Block& block,
                      double sigma_h,
                      const HeightGrid& grid,
                      const Candidates& cand,
                      const SlamConfig& cfg) {
    const double trunc = 0.5 * cfg.coarse_search_cell_m;  // beyond half a cell counts as a miss
    // At most ~2000 points of the section, spread over its slices.
    const std::size_t np = block.p1 - block.p0;
    const std::size_t stride = std::max<std::size_t>(1, np / 2000);
    std::vector<Eigen::Vector3d> pts;
    for (std::size_t s = block.s0; s < block.s1; ++s) {
        for (std::size_t k = in.offset[s] + (s % stride); k < in.offset[s + 1]; k += stride) {
            pts.push_back(WorldPoint(in, T, s, k));
        }
    }
    SectionFit fit;
    if (pts.empty()) return fit;
    const std::size_t nc = cand.size();
    fit.score.assign(nc, 0.0);
    fit.median_dz.assign(nc, 0.0);
    std::vector<std::size_t> cover(nc, 0);
    tbb::parallel_for(std::size_t{0}, nc, [&](std::size_t c) {
        const Eigen::Vector2d o = cand[c];
        std::vector<double> dz;
        dz.reserve(pts.size());
        for (const Eigen::Vector3d& p : pts) {
            const auto z = grid.HeightAt(p.x() + o.x(), p.y() + o.y());
            if (z) dz.push_back(*z - p.z());
        }
        double med = 0;
        if (!dz.empty()) {
            auto mid = dz.begin() + static_cast<std::ptrdiff_t>(dz.size() / 2);
            std::nth_element(dz.begin(), mid, dz.end());
            med = *mid;
        }
        double sum = 0;
        for (double v : dz) sum += std::min(std::abs(v - med), trunc);
        cover[c] = dz.size();
        fit.score[c] = dz.empty() ? 0.0
                                  : sum / static_cast<double>(dz.size()) / kCoarseScoreUnitM +
                                        0.5 * o.squaredNorm() / (sigma_h * sigma_h);
        fit.median_dz[c] = med;
    });
    const std::size_t max_cover = *std::max_element(cover.begin(), cover.end());
    if (max_cover < std::max<std::size_t>(20, pts.size() / 10)) return SectionFit{};
    for (std::size_t c = 0; c < nc; ++c) {
        if (static_cast<double>(cover[c]) <
            kCoarseMinCoverFraction * static_cast<double>(max_cover)) {
            fit.score[c] = kInfeasible;
        }
    }
    return fit;
}

// A section's fit surface summarised as a Gaussian: the mean and covariance of
// exp(-score / kCoarseTemperature) over its feasible offsets within `radius` of `centre` (an
// along-track valley gives a long axis), plus the candidate cell's own variance. False when no
// feasible offset is within reach.
bool Summarise(const SectionFit& fit,
               const Candidates& cand,
               const Eigen::Vector2d& centre,
               double radius,
               double cell_var,
               Eigen::Vector2d* mu,
               Eigen::Matrix2d* cov) {
    const std::size_t nc = cand.size();
    double best = kInfeasible;
    for (std::size_t c = 0; c < nc; ++c) {
        if ((cand[c] - centre).norm() <= radius) best = std::min(best, fit.score[c]);
    }
    if (best >= kInfeasible) return false;
    double w_sum = 0;
    Eigen::Vector2d m = Eigen::Vector2d::Zero();
    Eigen::Matrix2d s2 = Eigen::Matrix2d::Zero();
    for (std::size_t c = 0; c < nc; ++c) {
        if (fit.score[c] >= kInfeasible || (cand[c] - centre).norm() > radius) continue;
        const double w = std::exp(-(fit.score[c] - best) / kCoarseTemperature);
        w_sum += w;
        m += w * cand[c];
        s2 += w * cand[c] * cand[c].transpose();
    }
    *mu = m / w_sum;
    *cov = s2 / w_sum - *mu * mu->transpose() + cell_var * Eigen::Matrix2d::Identity();
    return true;
}

// The smoothed horizontal offsets of the sections [first, first + m) and their posterior
// covariances.
struct RunSolution {
    std::vector<Eigen::Vector2d> offset;
    std::vector<Eigen::Matrix2d> cov;
};

// The normal equations of a run (2 m unknowns, dense: runs are short): the sections' Gaussian
// terms (info, mu) plus the INS drift model, a random walk of the velocity error (q, m/s per
// sqrt(s)) loosened where the sigma's growth rate bends.
RunSolution SolveRun(std::size_t first,
                     const std::vector<Eigen::Matrix2d>& info,
                     const std::vector<Eigen::Vector2d>& mu,
                     const std::vector<Block>& blocks,
                     const std::vector<double>& sigma_h,
                     double q) {
    const std::size_t m = info.size();
    auto centre_t = [&](std::size_t k) { return 0.5 * (blocks[k].t0 + blocks[k].t1); };
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2 * m, 2 * m);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(2 * m);
    for (std::size_t i = 0; i < m; ++i) {
        const auto r = static_cast<Eigen::Index>(2 * i);
        H.block<2, 2>(r, r) += info[i];
        g.segment<2>(r) += info[i] * mu[i];
    }
    for (std::size_t i = 1; i + 1 < m; ++i) {
        const std::size_t k = first + i;
        const double d0 = std::max(centre_t(k) - centre_t(k - 1), 1e-3);
        const double d1 = std::max(centre_t(k + 1) - centre_t(k), 1e-3);
        const double dm = 0.5 * (d0 + d1);
        // The velocity error changes by about the change of the sigma's growth rate where that
        // is larger (a GNSS outage starting or ending).
        const double bend =
            std::abs((sigma_h[k + 1] - sigma_h[k]) / d1 - (sigma_h[k] - sigma_h[k - 1]) / d0);
        const double w = 1.0 / (q * q * dm + bend * bend);
        // r = o_{i+1} / d1 - o_i (1/d0 + 1/d1) + o_{i-1} / d0, per axis.
        const double c[3] = {1.0 / d0, -(1.0 / d0 + 1.0 / d1), 1.0 / d1};
        for (int u = 0; u < 3; ++u) {
            for (int v = 0; v < 3; ++v) {
                const auto ru = static_cast<Eigen::Index>(2 * (i - 1 + u));
                const auto rv = static_cast<Eigen::Index>(2 * (i - 1 + v));
                H.block<2, 2>(ru, rv) += w * c[u] * c[v] * Eigen::Matrix2d::Identity();
            }
        }
    }
    H.diagonal().array() += 1e-9;
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
    const Eigen::VectorXd x = ldlt.solve(g);
    const Eigen::MatrixXd P = ldlt.solve(Eigen::MatrixXd::Identity(2 * m, 2 * m));
    RunSolution sol{std::vector<Eigen::Vector2d>(m), std::vector<Eigen::Matrix2d>(m)};
    for (std::size_t i = 0; i < m; ++i) {
        const auto r = static_cast<Eigen::Index>(2 * i);
        sol.offset[i] = x.segment<2>(r);
        sol.cov[i] = P.block<2, 2>(r, r);
    }
    return sol;
}

// The offsets of the searched sections [b, e) chosen together, with the trusted sections on
// either side held at zero within their INS sigma: the sections' summaries (Summarise) are taken
// again within kCoarseWindowSigmas of the smoothed offsets (kCoarseRefinements times), so that a
// section with two candidate places takes the one its neighbours agree with. Returns the
// smoothed offsets of [first, last] (first = b - 1 or b, last = e or e - 1; `first` set), empty
// when no section of the run overlapped the grid.
std::vector<Eigen::Vector2d> SmoothRun(std::size_t b,
                                       std::size_t e,
                                       const std::vector<Block>& blocks,
                                       const std::vector<double>& sigma_h,
                                       const std::vector<SlamSection>& sections,
                                       const std::vector<SectionFit>& fits,
                                       const Candidates& cand,
                                       const SlamConfig& cfg,
                                       std::size_t* first_out) {
    const std::size_t nb = blocks.size();
    const double q = std::max(cfg.drift_velocity_random_walk_mps_per_sqrt_s, kCoarseMinDriftRw);
    const double cell_var = cfg.coarse_search_step_m * cfg.coarse_search_step_m / 12.0;
    // Unknowns: the run and its trusted neighbours (offset 0 within their sigma).
    const std::size_t first = b > 0 ? b - 1 : b, last = e < nb ? e : e - 1;
    *first_out = first;
    const std::size_t m = last - first + 1;
    std::vector<Eigen::Vector2d> mu(m, Eigen::Vector2d::Zero());
    std::vector<Eigen::Matrix2d> info(m, Eigen::Matrix2d::Zero());
    RunSolution sol{std::vector<Eigen::Vector2d>(m),
                    std::vector<Eigen::Matrix2d>(m, Eigen::Matrix2d::Identity() * 1e6)};
    bool any = false;
    for (int pass = 0; pass <= kCoarseRefinements; ++pass) {
        any = false;
        for (std::size_t i = 0; i < m; ++i) {
            const std::size_t k = first + i;
            info[i].setZero();
            mu[i].setZero();
            if (!sections[k].searched) {
                info[i] = Eigen::Matrix2d::Identity() / std::max(sigma_h[k] * sigma_h[k], cell_var);
                continue;
            }
            if (fits[k].empty()) continue;
            Eigen::Vector2d c0 = Eigen::Vector2d::Zero();
            double radius = std::numeric_limits<double>::infinity();
            if (pass > 0) {
                c0 = sol.offset[i];
                const double sd = std::sqrt(std::max(0.0, LargestEigenvalue(sol.cov[i])));
                radius = std::max(kCoarseMinWindowM, kCoarseWindowSigmas * sd);
            }
            Eigen::Matrix2d cov;
            if (!Summarise(fits[k], cand, c0, radius, cell_var, &mu[i], &cov)) continue;
            info[i] = cov.inverse();
            any = true;
        }
        if (!any) break;
        sol = SolveRun(first, info, mu, blocks, sigma_h, q);
    }
    if (!any) return {};
    return std::move(sol.offset);
}

}  // namespace

// For every section whose INS horizontal 1-sigma exceeds coarse_search_min_sigma_m: how well
// each horizontal offset (within coarse_search_m, on a coarse_search_step_m grid) fits its
// points to a height grid of the sections the INS is sure about, the vertical offset taken as
// the median height difference. Score: mean |dz - median dz| over the points that fall on the
// grid (inside a cell's own extent: no extrapolation past swath edges), plus the INS prior on
// the offset, among offsets that see enough of the grid. The offsets of a run of such sections
// are then chosen together under the INS drift model (see below). Closest-point matching alone
// creeps towards offsets of several metres along smooth terrain (each step is bounded by the
// closest-point distances); this puts the sections inside its capture range.
// Returns the world translation per section (zero where not searched).
std::vector<Eigen::Vector3d> CoarseSectionSearch(const Input& in,
                                                 const std::vector<Pose>& T,
                                                 const std::vector<Block>& blocks,
                                                 const SlamConfig& cfg,
                                                 std::vector<SlamSection>* sections) {
    const std::size_t nb = blocks.size();
    std::vector<Eigen::Vector3d> offset(nb, Eigen::Vector3d::Zero());
    sections->resize(nb);
    const std::vector<double> sigma_h = SectionSigmas(in, blocks, cfg, *sections);
    const HeightGrid grid = TrustedGrid(in, T, blocks, sigma_h, cfg);
    if (grid.empty()) return offset;

    const Candidates cand(cfg);
    std::vector<SectionFit> fits(nb);
    for (std::size_t b = 0; b < nb; ++b) {
        if (sigma_h[b] > cfg.coarse_search_min_sigma_m)
            fits[b] = FitSection(in, T, blocks[b], sigma_h[b], grid, cand, cfg);
    }

    // Runs of consecutive searched sections, smoothed jointly (SmoothRun). Searched sections
    // that did not overlap the grid are carried by their neighbours.
    std::size_t b = 0;
    while (b < nb) {
        if (!(*sections)[b].searched) {
            ++b;
            continue;
        }
        std::size_t e = b;
        while (e < nb && (*sections)[e].searched) ++e;  // run [b, e)
        std::size_t first = 0;
        const std::vector<Eigen::Vector2d> smooth =
            SmoothRun(b, e, blocks, sigma_h, *sections, fits, cand, cfg, &first);
        for (std::size_t k = b; k < e && !smooth.empty(); ++k) {
            // A run at the survey's start or end with one fitted section leaves a trend barely
            // determined: never more than the search reach, never non-finite.
            if (!smooth[k - first].allFinite()) continue;
            const Eigen::Vector2d o =
                smooth[k - first].cwiseMax(-cfg.coarse_search_m).cwiseMin(cfg.coarse_search_m);
            // The vertical offset of the nearest candidate; without overlap the INS height.
            const double dz = fits[k].empty() ? 0.0 : fits[k].median_dz[cand.Nearest(o)];
            offset[k] = Eigen::Vector3d(o.x(), o.y(), dz);
            (*sections)[k].shifted = true;
            (*sections)[k].coarse_offset_m = offset[k];
        }
        b = e;
    }
    return offset;
}

}  // namespace pitmap::proc::slam::detail
