// SPDX-License-Identifier: MIT
#include "processor/calib/pass_pairs.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "processor/georef/georef_blocks.hpp"
#include "processor/registration/neighbours.hpp"
#include "processor/registration/normals.hpp"

namespace pitmap::proc::calib::detail {

namespace {

// The samples cut into blocks of min_separation_s / 2 of time, each with its own k-d tree and
// box. For a sample at time t, a block entirely min_separation_s or more away in time holds
// only other passes (a bounded nearest search, skipped by its box), a block entirely closer
// holds only its own pass (searched once, by IndexOwnPasses, for the normal's neighbours), and
// the few blocks in between are searched with the time of every candidate checked. The pairs
// are those of one search over all samples with the time filter.
struct PassBlock {
    std::size_t p0 = 0, p1 = 0;
    double t0 = 0, t1 = 0;
    Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
    std::unique_ptr<reg::PointIndex3d> tree;
};

std::vector<PassBlock> MakePassBlocks(const std::vector<Eigen::Vector3d>& p,
                                      const Samples& S,
                                      double separation_s) {
    std::vector<PassBlock> blocks;
    const std::size_t n = p.size();
    if (n == 0) return blocks;
    const bool sorted = std::is_sorted(S.t_s.begin(), S.t_s.end());
    const double len = sorted ? 0.5 * separation_s : std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < n;) {
        PassBlock b;
        b.p0 = k;
        const double start = S.t_s[k];
        while (k < n && (S.t_s[k] < start + len || k == b.p0)) ++k;
        b.p1 = k;
        blocks.push_back(std::move(b));
    }
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t i) {
        PassBlock& b = blocks[i];
        b.t0 = std::numeric_limits<double>::infinity();
        b.t1 = -b.t0;
        b.lo.setConstant(std::numeric_limits<double>::infinity());
        b.hi = -b.lo;
        for (std::size_t k = b.p0; k < b.p1; ++k) {
            b.t0 = std::min(b.t0, S.t_s[k]);
            b.t1 = std::max(b.t1, S.t_s[k]);
            b.lo = b.lo.cwiseMin(p[k]);
            b.hi = b.hi.cwiseMax(p[k]);
        }
        b.tree = std::make_unique<reg::PointIndex3d>(p.data() + b.p0, b.p1 - b.p0);
    });
    return blocks;
}

double BoxDistance2(const Eigen::Vector3d& q, const PassBlock& b) {
    const Eigen::Vector3d d = (b.lo - q).cwiseMax(q - b.hi).cwiseMax(0.0);
    return d.squaredNorm();
}

}  // namespace

ViewWindows::ViewWindows(const georef::GeorefResult& geo, const ViewReader& view)
    : geo_(geo), view_(view), ping_first_(geo.pings.size() + 1, 0) {
    // Counts per ping, then their running sum.
    view.read(0,
              view.size,
              [&](const georef::GeorefPoints& P, std::size_t, std::size_t lo, std::size_t hi) {
                  for (std::size_t i = lo; i < hi; ++i) {
                      if (P.ping[i] < geo.pings.size()) ++ping_first_[P.ping[i] + 1];
                  }
              });
    for (std::size_t k = 1; k < ping_first_.size(); ++k) ping_first_[k] += ping_first_[k - 1];
}

void ViewWindows::ForEach(double t0, double t1, const ViewVisit& visit) const {
    std::size_t k_lo = geo_.pings.size(), k_hi = 0;
    for (std::size_t k = 0; k < geo_.pings.size(); ++k) {
        const double t = static_cast<double>(geo_.pings[k].utime_gps) * 1e-6;
        if (t < t0 || t >= t1) continue;
        k_lo = std::min(k_lo, k);
        k_hi = k + 1;
    }
    if (k_lo >= k_hi) return;
    view_.read(ping_first_[k_lo], std::min(ping_first_[k_hi], view_.size), visit);
}

Samples Collect(const ViewWindows& view, double t0, double t1, int stride) {
    Samples S;
    const georef::GeorefResult& geo = view.geo();
    view.ForEach(
        t0, t1, [&](const georef::GeorefPoints& P, std::size_t, std::size_t lo, std::size_t hi) {
            for (std::size_t j = lo; j < hi; ++j) {
                if (P.beam[j] % stride != 0) continue;
                const auto& ping = geo.pings[P.ping[j]];
                const double t = static_cast<double>(ping.utime_gps) * 1e-6;
                if (t < t0 || t >= t1) continue;
                S.ping.push_back(P.ping[j]);
                // With refraction: the traced sounding seen from the head at the current mount
                // (the ray's bend changes little over the boresight's fraction of a degree).
                S.s_sonar.push_back(georef::SoundingVectorSonar(geo, P, j));
                S.t_s.push_back(t - t0);
            }
        });
    return S;
}

Samples Collect(const georef::GeorefResult& geo, double t0, double t1, int stride) {
    Samples S;
    const auto& P = geo.points;
    for (std::size_t j = 0; j < P.size(); ++j) {
        if (P.beam[j] % stride != 0) continue;
        const auto& ping = geo.pings[P.ping[j]];
        const double t = static_cast<double>(ping.utime_gps) * 1e-6;
        if (t < t0 || t >= t1) continue;
        S.ping.push_back(P.ping[j]);
        // With refraction: the traced sounding seen from the head at the current mount (the
        // ray's bend changes little over the boresight's fraction of a degree).
        S.s_sonar.push_back(georef::SoundingVectorSonar(geo, j));
        S.t_s.push_back(t - t0);
    }
    return S;
}

// The own pass's neighbours of every sample (Samples::own), from a radius search of the blocks
// not entirely min_separation_s or more away in time.
void IndexOwnPasses(const std::vector<Eigen::Vector3d>& p, Samples& S, const BoresightConfig& cfg) {
    const double sep = cfg.min_separation_s;
    const std::vector<PassBlock> blocks = MakePassBlocks(p, S, sep);
    const double nr2 = cfg.normal_radius_m * cfg.normal_radius_m;
    // Chunks of samples, each filling its own compact list, joined in order afterwards.
    constexpr std::size_t kChunk = 512;
    const std::size_t n_chunks = (p.size() + kChunk - 1) / kChunk;
    std::vector<std::vector<std::uint32_t>> chunk_own(n_chunks);
    S.own_begin.assign(p.size() + 1, 0);
    tbb::parallel_for(std::size_t{0}, n_chunks, [&](std::size_t c) {
        std::vector<reg::PointIndex3d::Hit> hits;
        std::vector<std::uint32_t>& own = chunk_own[c];
        const std::size_t k1 = std::min(p.size(), (c + 1) * kChunk);
        for (std::size_t k = c * kChunk; k < k1; ++k) {
            const Eigen::Vector3d& q = p[k];
            const double t = S.t_s[k];
            const std::size_t first = own.size();
            if (!S.IsQuery(k)) {
                S.own_begin[k + 1] = 0;
                continue;
            }
            for (const PassBlock& b : blocks) {
                if (b.t1 <= t - sep || b.t0 >= t + sep) continue;  // other passes only
                if (BoxDistance2(q, b) >= nr2) continue;
                b.tree->WithinRadius(q, nr2, hits);
                for (const auto& [i, d2] : hits) {
                    const std::size_t j = b.p0 + i;
                    if (d2 < nr2 && std::abs(S.t_s[j] - t) < sep)
                        own.push_back(static_cast<std::uint32_t>(j));
                }
            }
            std::sort(own.begin() + static_cast<std::ptrdiff_t>(first), own.end());
            S.own_begin[k + 1] = own.size() - first;  // a count until the prefix sum below
        }
        own.shrink_to_fit();
    });
    for (std::size_t k = 0; k < p.size(); ++k) S.own_begin[k + 1] += S.own_begin[k];
    S.own.clear();
    S.own.reserve(S.own_begin.back());
    for (auto& own : chunk_own) {
        S.own.insert(S.own.end(), own.begin(), own.end());
        std::vector<std::uint32_t>().swap(own);
    }
}

// Correspondences for every sample: normal of its own pass (its neighbours of
// IndexOwnPasses at the current positions), closest point of another pass (within d_max); the
// normal is fitted only where a pair is made.
std::vector<Pair> FindPairs(const std::vector<Eigen::Vector3d>& p,
                            const Samples& S,
                            const BoresightConfig& cfg,
                            double d_max) {
    const double sep = cfg.min_separation_s;
    const std::vector<PassBlock> blocks = MakePassBlocks(p, S, sep);
    const double d2_max = d_max * d_max;
    std::vector<Pair> pairs(p.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, p.size(), 512), [&](const auto& r) {
        // The previous sample's match (the next beam of the same ping, mostly) is a candidate
        // of this one too: starting from its distance, the searches below prune with a tight
        // bound from the first block on. They return only points strictly closer, so the
        // result is the nearest point all the same.
        std::size_t hint = p.size();
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            if (!S.IsQuery(k)) continue;
            const Eigen::Vector3d& q = p[k];
            const double t = S.t_s[k];
            double best = d2_max;
            std::size_t best_j = 0;
            bool found = false;
            if (hint < p.size() && std::abs(S.t_s[hint] - t) >= sep) {
                const double d2 = (q - p[hint]).squaredNorm();
                if (d2 < best) {
                    best = d2;
                    best_j = hint;
                    found = true;
                }
            }
            for (const PassBlock& b : blocks) {
                if (b.t0 > t - sep && b.t1 < t + sep) continue;  // its own pass only
                if (BoxDistance2(q, b) >= best) continue;
                const bool far = b.t1 <= t - sep || b.t0 >= t + sep;
                std::size_t i = 0;
                double d2 = 0;
                const bool hit =
                    far ? b.tree->NearestWithin(q, best, &i, &d2)
                        : b.tree->NearestWithinIf(
                              q,
                              best,
                              [&](std::size_t c) { return std::abs(S.t_s[b.p0 + c] - t) >= sep; },
                              &i,
                              &d2);
                if (hit) {
                    best = d2;
                    best_j = b.p0 + i;
                    found = true;
                }
            }
            if (!found) continue;
            hint = best_j;
            reg::MomentAccumulator m;
            for (std::size_t o = S.own_begin[k]; o < S.own_begin[k + 1]; ++o) m.Add(p[S.own[o]]);
            if (m.count() < 8) continue;
            const reg::PlaneFit f = reg::FitPlane(m);
            if (!f.Planar(0.1)) continue;  // not planar enough
            Pair& pr = pairs[k];
            pr.ok = true;
            pr.c.query = k;
            pr.c.target = best_j;
            pr.c.query_normal = f.normal;
            pr.r = pr.c.query_normal.dot(q - p[best_j]);
            // 1 / sigma^2 of the difference, sigma = fraction * range + constant per sounding.
            const double sp =
                cfg.range_noise_fraction * S.s_sonar[k].norm() + cfg.range_noise_constant_m;
            const double sq =
                cfg.range_noise_fraction * S.s_sonar[best_j].norm() + cfg.range_noise_constant_m;
            pr.w = 1.0 / (sp * sp + sq * sq);
        }
    });
    return pairs;
}

ResidualStats Stats(const std::vector<Pair>& pairs) {
    std::vector<double> a;
    double ss = 0, var = 0;
    for (const auto& pr : pairs) {
        if (!pr.ok) continue;
        a.push_back(std::abs(pr.r));
        ss += pr.r * pr.r;
        var += 1.0 / pr.w;
    }
    ResidualStats s;
    s.pairs = static_cast<std::int64_t>(a.size());
    if (a.empty()) return s;
    s.rms_m = std::sqrt(ss / static_cast<double>(a.size()));
    s.expected_rms_m = std::sqrt(var / static_cast<double>(a.size()));
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
    s.median_abs_m = a[a.size() / 2];
    return s;
}

}  // namespace pitmap::proc::calib::detail
