// SPDX-License-Identifier: MIT
#include "processor/clean/clean.hpp"

#include "processor/clean/clean_blocks.hpp"

#include <openvdb/math/DDA.h>
#include <openvdb/math/Ray.h>
#include <openvdb/openvdb.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <numeric>
#include <utility>

namespace pitmap::proc::clean {

namespace {

using openvdb::Coord;
using survey::SoundingStatus;
using IndexTree = openvdb::Int32Tree;
using RayT = openvdb::math::Ray<double>;
// The hierarchical DDA enters at the root's children and descends to the leaves.
using Hdda =
    openvdb::math::VolumeHDDA<IndexTree, RayT, IndexTree::RootNodeType::ChildNodeType::LEVEL>;

constexpr std::int32_t kNone = -1;

// Per voxel: soundings, their moments, the component, the plane patch.
struct Voxels {
    std::vector<Coord> coord;
    std::vector<std::int32_t> count;
    std::vector<std::int32_t> component;  // after Components
    // Plane patches (terrain voxels with enough soundings), after Patches.
    std::vector<Eigen::Vector3d> centroid, normal, axis_major, axis_minor;  // the plane's axes
    std::vector<double> sigma_major, sigma_minor;  // the soundings' spread along them
    std::vector<double> thickness;
    std::vector<char> patch;
    std::size_t size() const { return coord.size(); }
};

double Seconds(std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Union-find with path halving.
std::int32_t Find(std::vector<std::int32_t>& parent, std::int32_t i) {
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

// Marches rays through the active voxels of one grid: visit(voxel index, t_enter) for every
// voxel the segment [t0, t1] (index units) of a ray passes through, in order; visit returns
// false to stop. One per thread: it keeps its accessor (the tree's node cache) and its list of
// spans between rays.
class Marcher {
public:
    explicit Marcher(const openvdb::Int32Grid& grid) : acc_(grid.getConstAccessor()) {}

    template <typename Visit>
    void operator()(const RayT& ray_in, double t0, double t1, Visit&& visit) {
        if (!(t1 > t0)) return;
        RayT ray = ray_in;
        ray.setTimes(t0, t1);
        hdda_.hits(ray, acc_, spans_);
        for (const RayT::TimeSpan& span : spans_) {
            RayT segment = ray_in;
            segment.setTimes(std::max(t0, span.t0), std::min(t1, span.t1));
            if (!segment.valid()) continue;
            openvdb::math::DDA<RayT, 0> dda(segment);
            do {
                std::int32_t v = kNone;
                if (acc_.probeValue(dda.voxel(), v) && !visit(v, dda.time())) return;
            } while (dda.step());
        }
    }

private:
    openvdb::Int32Grid::ConstAccessor acc_;
    Hdda hdda_;
    std::vector<RayT::TimeSpan> spans_;
};

double Median(std::vector<double>& v) {
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

// What the range profiles (steps 5-8) read of the view: each sounding's ping, beam, range and
// beam angle (the angle only where the smile is looked for), 14 bytes a sounding, without the
// positions (24).
struct RangeView {
    std::vector<std::uint32_t> ping;
    std::vector<std::uint16_t> beam;
    std::vector<float> range_m, angle_rad;
    std::size_t num_pings = 0;
    std::size_t size() const { return ping.size(); }
};

// The soundings on their (ping, beam) grid, and the nearest sounding in a direction over up to
// 3 missing ones (echo runs have dropouts).
class SoundingGrid {
public:
    explicit SoundingGrid(const RangeView& P) : P_(P), pings_(P.num_pings) {
        for (const std::uint16_t b : P_.beam) beams_ = std::max<std::size_t>(beams_, b + 1u);
        cell_.assign(pings_ * beams_, -1);
        for (std::size_t j = 0; j < P_.size(); ++j)
            cell_[P_.ping[j] * beams_ + P_.beam[j]] = static_cast<std::int32_t>(j);
    }
    std::size_t pings() const { return pings_; }
    std::size_t beams() const { return beams_; }
    bool Inside(std::int64_t q, std::int64_t c) const {
        return q >= 0 && q < static_cast<std::int64_t>(pings_) && c >= 0 &&
               c < static_cast<std::int64_t>(beams_);
    }
    // The median range of beam b over up to w pings on one side of ping k (dir -1: before, 1:
    // after), of what range_at(q) gives for ping q (NaN: nothing to count there); NaN with
    // fewer than 3. side: the caller's scratch.
    template <class RangeAt>
    double SideMedian(std::int64_t k,
                      std::int64_t b,
                      int dir,
                      int w,
                      const RangeAt& range_at,
                      std::vector<double>& side) const {
        side.clear();
        for (int d = 1; d <= w; ++d) {
            const std::int64_t q = k + dir * d;
            if (!Inside(q, b)) break;
            const double x = range_at(static_cast<std::size_t>(q));
            if (std::isfinite(x)) side.push_back(x);
        }
        return side.size() < 3 ? std::numeric_limits<double>::quiet_NaN() : Median(side);
    }
    // The nearest sounding to j in direction (dk, db) (pings, beams), up to 4 cells away; -1
    // when none. Its distance in cells in *at.
    std::int32_t Nearest(std::size_t j, int dk, int db, int* at = nullptr) const {
        const auto k = static_cast<std::int64_t>(P_.ping[j]);
        const auto b = static_cast<std::int64_t>(P_.beam[j]);
        for (int step = 1; step <= 4; ++step) {
            const std::int64_t q = k + step * dk, c = b + step * db;
            if (!Inside(q, c)) return -1;
            const std::int32_t x =
                cell_[static_cast<std::size_t>(q) * beams_ + static_cast<std::size_t>(c)];
            if (x >= 0) {
                if (at != nullptr) *at = step;
                return x;
            }
        }
        return -1;
    }

private:
    const RangeView& P_;
    std::size_t pings_;
    std::size_t beams_ = 0;
    std::vector<std::int32_t> cell_;
};

// Scratch of LineScore, one per thread.
struct LineScratch {
    std::vector<double> slopes, icept, res, d, r;
};

// A robust line's value at the sounding (d = 0) and its spread (1.4826 MAD of the residuals of
// the points it was fitted to); ok when it had enough points.
struct ProfileLine {
    double value = 0, spread = 0;
    bool ok = false;
};

// The median intercept at d = 0 of the points (s.d, s.r) under `slope`, and their spread.
ProfileLine LineThrough(double slope, LineScratch& s) {
    s.icept.clear();
    for (std::size_t i = 0; i < s.d.size(); ++i) s.icept.push_back(s.r[i] - slope * s.d[i]);
    ProfileLine line;
    line.value = Median(s.icept);
    s.res.clear();
    for (const double x : s.icept) s.res.push_back(std::abs(x - line.value));
    line.spread = 1.4826 * Median(s.res);
    line.ok = true;
    return line;
}

// The line through the neighbours on both sides: Theil-Sen over the symmetric pairs.
template <class At>
ProfileLine SymmetricLine(int w, const At& at, LineScratch& s) {
    s.slopes.clear();
    s.d.clear();
    s.r.clear();
    for (int d = 1; d <= w; ++d) {
        const double a = at(-d), c = at(d);
        if (std::isfinite(a) && std::isfinite(c)) s.slopes.push_back((c - a) / (2.0 * d));
    }
    if (static_cast<int>(s.slopes.size()) < std::max(2, w / 2)) return {};
    for (int d = -w; d <= w; ++d) {
        const double a = at(d);
        if (d != 0 && std::isfinite(a)) {
            s.d.push_back(d);
            s.r.push_back(a);
        }
    }
    return LineThrough(Median(s.slopes), s);
}

// The line through the neighbours on one side (side -1: the pings before, +1: after),
// extrapolated to the sounding: Theil-Sen over the pairs half the side's soundings apart. The
// edge pings of an echo run have one clean side and one the run contaminates, where the
// symmetric pairs mix both.
template <class At>
ProfileLine SideLine(int w, int side, const At& at, LineScratch& s) {
    s.d.clear();
    s.r.clear();
    for (int d = 1; d <= w; ++d) {
        const double a = at(side * d);
        if (std::isfinite(a)) {
            s.d.push_back(side * d);
            s.r.push_back(a);
        }
    }
    const std::size_t n = s.d.size();
    if (static_cast<int>(n) < std::max(3, w / 2)) return {};
    const std::size_t h = (n + 1) / 2;
    s.slopes.clear();
    for (std::size_t i = 0; i + h < n; ++i)
        s.slopes.push_back((s.r[i + h] - s.r[i]) / (s.d[i + h] - s.d[i]));
    return LineThrough(Median(s.slopes), s);
}

// A sounding's distance (range r0) to the robust line through its neighbours at(-w..w)
// (without 0) over the threshold max(profile_min_m, margin_rel of the range, profile_sigmas
// spreads); 0 where it cannot be judged: the line's spread over profile_max_spread of the
// range (the neighbours disagree). The symmetric line (SymmetricLine) judges where its
// neighbours agree; where they do not, the lines of each side (SideLine) that agree do, and the
// sounding is off only when it is off every one of them (a step of the terrain is on one).
template <class At>
double LineScore(int w, const At& at, double r0, const CleanConfig& config, LineScratch& s) {
    if (w <= 0) return 0.0;
    // Most soundings lie on a smooth profile: halfway between the window's ends and between its
    // half-way points (an echo run shorter than the window cannot hold both pairs), they are
    // far from off it.
    {
        // The midpoint of the first symmetric pair at d, d - 1, d + 1 with both ranges (a
        // dropout moves the pair by one); NaN when none has.
        auto midpoint = [&](int d) {
            for (const int e : {d, d - 1, d + 1}) {
                if (e < 1 || e > w) continue;
                const double a = at(-e), c = at(e);
                if (std::isfinite(a) && std::isfinite(c)) return 0.5 * (a + c);
            }
            return std::nan("");
        };
        const double tol = 0.5 * std::max(config.profile_min_m, config.margin_rel * r0);
        const double outer = midpoint(w), inner = midpoint(w / 2);
        if (std::abs(r0 - inner) < tol) {
            if (std::abs(r0 - outer) < tol) return 0.0;
            // A profile that bends: the midpoints of pairs at d lie c d^2 off the sounding's
            // value, so (4 inner - outer) / 3 is the value at d = 0 of the parabola through
            // them (Richardson).
            if (std::abs(r0 - (4.0 * inner - outer) / 3.0) < tol) return 0.0;
        }
    }
    auto score = [&](const ProfileLine& line) {
        if (!line.ok || line.spread > config.profile_max_spread * line.value) return -1.0;
        return std::abs(r0 - line.value) / std::max({config.profile_min_m,
                                                     config.margin_rel * line.value,
                                                     config.profile_sigmas * line.spread});
    };
    const double both = score(SymmetricLine(w, at, s));
    if (both >= 0) return both;
    // The neighbours disagree: the edge of a run of echoes in the water has one side the run
    // disturbs and one the terrain's line goes on. Judged on that side's line when it is far
    // in front of it (more than kFarInFront of the range: further than the terrain's profile
    // bends in a few pings) and the other side has soundings missing (kMinMissing: the run's
    // dropouts and the echoes the 3D tests rejected; a ledge the terrain steps to has none), at
    // half its score (an extrapolated line misses by more). Where both sides agree within
    // themselves and not with each other, the terrain steps.
    constexpr double kFarInFront = 0.15;
    constexpr int kMinMissing = 2;
    const ProfileLine before = SideLine(w, -1, at, s), after = SideLine(w, 1, at, s);
    const double sb = score(before), sa = score(after);
    if ((sb >= 0) == (sa >= 0)) return 0.0;
    const ProfileLine& line = sb >= 0 ? before : after;
    if (line.value - r0 < kFarInFront * line.value) return 0.0;
    int missing = 0;
    for (int d = 1; d <= w; ++d) missing += !std::isfinite(at(sb >= 0 ? d : -d));
    if (missing < kMinMissing) return 0.0;
    return 0.5 * std::max(sb, sa);
}

constexpr float kDecided = 1e9f;  // the score of a sounding the 3D tests rejected

// Every sounding's profile score: the larger of the along-track and across-fan LineScore;
// kDecided for those already rejected.
std::vector<float> ProfileScores(const RangeView& P,
                                 const SoundingGrid& grid,
                                 const CleanConfig& config,
                                 const std::vector<std::uint8_t>& decided) {
    const std::size_t n = P.size();
    const std::size_t beams = grid.beams();
    std::vector<float> range(grid.pings() * beams, std::numeric_limits<float>::quiet_NaN());
    // The neighbours are the soundings the 3D tests accepted: an echo they rejected does not
    // pull its run's line.
    for (std::size_t j = 0; j < n; ++j) {
        if (decided[j] == 0) range[P.ping[j] * beams + P.beam[j]] = P.range_m[j];
    }
    std::vector<float> score(n, 0.0f);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& r) {
        LineScratch scratch;
        for (std::size_t j = r.begin(); j != r.end(); ++j) {
            if (decided[j] != 0) {
                score[j] = kDecided;
                continue;
            }
            const auto k = static_cast<std::int64_t>(P.ping[j]);
            const auto b = static_cast<std::int64_t>(P.beam[j]);
            auto value = [&](std::int64_t q, std::int64_t c) -> double {
                if (!grid.Inside(q, c)) return std::nan("");
                return range[static_cast<std::size_t>(q) * beams + static_cast<std::size_t>(c)];
            };
            const double r0 = P.range_m[j];
            score[j] = static_cast<float>(std::max(LineScore(
                                                       config.profile_pings,
                                                       [&](int d) { return value(k + d, b); },
                                                       r0,
                                                       config,
                                                       scratch),
                                                   LineScore(
                                                       config.profile_beams,
                                                       [&](int d) { return value(k, b + d); },
                                                       r0,
                                                       config,
                                                       scratch)));
        }
    });
    return score;
}

// Hysteresis: soundings scoring 1 or more (and those the 3D tests rejected) seed runs, which
// grow over neighbours (beams and pings, across up to 3 dropouts) scoring 0.75 or more; what
// the 3D tests rejected joins runs but does not grow them. Returns the soundings of a run with
// a neighbour in a run (runs of 2 or more), not already rejected.
std::vector<char> RunsOfTwoOrMore(const std::vector<float>& score,
                                  const SoundingGrid& grid,
                                  const std::vector<std::uint8_t>& decided) {
    constexpr int kDirections[4][2] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
    const std::size_t n = score.size();
    std::vector<char> in_run(n, 0);
    std::vector<std::int32_t> stack;
    for (std::size_t j = 0; j < n; ++j) {
        if (score[j] >= kDecided) {
            in_run[j] = 1;  // in a run, not a seed: what the 3D tests rejected does not grow
        } else if (score[j] >= 1.0f) {
            in_run[j] = 1;
            stack.push_back(static_cast<std::int32_t>(j));
        }
    }
    while (!stack.empty()) {
        const auto j = static_cast<std::size_t>(stack.back());
        stack.pop_back();
        for (int dir = 0; dir < 4; ++dir) {
            const std::int32_t q = grid.Nearest(j, kDirections[dir][0], kDirections[dir][1]);
            if (q < 0 || in_run[q] || score[q] < 0.75f) continue;
            in_run[q] = 1;
            stack.push_back(q);
        }
    }
    std::vector<char> result(n, 0);
    for (std::size_t j = 0; j < n; ++j) {
        if (!in_run[j] || decided[j] != 0) continue;
        for (int dir = 0; dir < 4 && !result[j]; ++dir) {
            const std::int32_t q = grid.Nearest(j, kDirections[dir][0], kDirections[dir][1]);
            result[j] = q >= 0 && in_run[q];
        }
    }
    return result;
}

// The range profiles: each sounding's range against a robust line through its neighbours'
// ranges, along track (the same beam over `profile_pings` pings each side) and across the
// fan (the same ping over `profile_beams` beams each side) (ProfileScores). A sounding's score
// is its distance to the line over the threshold max(profile_min_m, margin_rel of the range,
// profile_sigmas spreads), where the neighbours agree (spread below profile_max_spread of the
// range). Hysteresis, as an edge detector does it (RunsOfTwoOrMore); an echo run's edge pings,
// where the line is pulled towards it, are taken with it. Only runs of 2 or more are rejected:
// a lone range off its line is the terrain's (an edge the line does not follow) or the spike
// filter's.
std::vector<char> Profiles(const RangeView& P,
                           const SoundingGrid& grid,
                           const CleanConfig& config,
                           const std::vector<std::uint8_t>& decided) {
    const std::size_t n = P.size();
    if (n == 0 || (config.profile_pings <= 0 && config.profile_beams <= 0))
        return std::vector<char>(n, 0);
    return RunsOfTwoOrMore(ProfileScores(P, grid, config, decided), grid, decided);
}

// Near-field echoes (bubble sweep-down, aeration under the hull): returns from a cloud within
// a few metres of the transducer, far in front of what the same beam saw over the pings
// before and after. A sounding at most near_field_max_range_m away whose range is under
// near_field_ratio times the median range of the same beam over the profile_pings pings on
// each side (the soundings the 3D tests accepted, at least 3 a side), and near_field_min_m
// short of both, is flagged; only runs are rejected (a flagged nearest neighbour along track
// or across the fan, over dropouts): a cloud covers neighbouring beams. The profiles' lines
// (Profiles) miss such a sounding where an episode's pings or a turn bend the line of one
// side (the neighbours disagree) and the sides' medians do not: the terrain a beam sees moves
// by a few per cent a ping, a cloud is a third to a half of the range in front. A bench edge
// swept across the beam in a turn is as far in front, but continuous with the terrain beside
// it (ReleaseTerrain keeps it). Returns the soundings of such runs, not already rejected.
std::vector<char> NearField(const RangeView& P,
                            const SoundingGrid& grid,
                            const CleanConfig& config,
                            const std::vector<std::uint8_t>& decided) {
    const std::size_t n = P.size();
    std::vector<char> flagged(n, 0);
    const int w = config.profile_pings;
    if (n == 0 || w <= 0 || !(config.near_field_max_range_m > 0)) return flagged;
    const std::size_t beams = grid.beams();
    std::vector<float> range(grid.pings() * beams, std::numeric_limits<float>::quiet_NaN());
    bool any = false;
    for (std::size_t j = 0; j < n; ++j) {
        if (decided[j] == 0) range[P.ping[j] * beams + P.beam[j]] = P.range_m[j];
        any = any || P.range_m[j] <= config.near_field_max_range_m;
    }
    if (!any) return flagged;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192), [&](const auto& r) {
        std::vector<double> side;
        for (std::size_t j = r.begin(); j != r.end(); ++j) {
            const double r0 = P.range_m[j];
            if (decided[j] != 0 || r0 > config.near_field_max_range_m) continue;
            const auto k = static_cast<std::int64_t>(P.ping[j]);
            const auto b = static_cast<std::int64_t>(P.beam[j]);
            const auto range_at = [&](std::size_t q) {
                return double{range[q * beams + static_cast<std::size_t>(b)]};
            };
            bool in_front = true;
            for (const int dir : {-1, 1}) {
                const double med = grid.SideMedian(k, b, dir, w, range_at, side);
                if (!(r0 < config.near_field_ratio * med && med - r0 > config.near_field_min_m)) {
                    in_front = false;
                    break;
                }
            }
            flagged[j] = in_front;
        }
    });
    constexpr int kDirections[4][2] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
    std::vector<char> runs(n, 0);
    for (std::size_t j = 0; j < n; ++j) {
        if (!flagged[j]) continue;
        for (const auto& dir : kDirections) {
            const std::int32_t q = grid.Nearest(j, dir[0], dir[1]);
            if (q >= 0 && flagged[q]) {
                runs[j] = 1;
                break;
            }
        }
    }
    return runs;
}

// The nadir side-lobe "smile": the strong specular echo of the nadir comes back through the
// side lobes of the beams beside it, at the nadir's range. Where the terrain a beam sees is
// further than the nadir (by more than the range resolution of the side lobe's echo), the beam
// may return that range instead: across the fan an arc of constant range, the nadir's, over
// consecutive pings. The terrain at those beams cannot lie there when the same beam, over the
// pings on each side, sees it further by more than a break in the range. A sounding of a ping
// whose nadir (the accepted sounding nearest to 0 deg, within smile_nadir_deg, and the 2
// beams each side: their median range) is known, within a break (fill_break_m, margin_rel of
// the range) of the nadir's range, and more than a break in front of the median range of the
// same beam over the profile_pings pings on each side (the soundings still accepted, at least
// 3 a side), is flagged; flagged soundings with a flagged neighbour across the fan (the arc
// spans beams; over dropouts) are rejected with the profiles. Twice: an episode's soundings
// flagged in the first pass no longer hold the median of a side for a ping of the same episode
// a few pings on. A ridge crossed under the track is as near as its nadir over a few beams, and
// in front of both sides, but continuous with the nadir's terrain (ReleaseTerrain keeps it); the
// smile is parted from the nadir's terrain by the step where the terrain gets further than the
// nadir by more than the side lobe's resolution. Returns the soundings of such runs, not already
// rejected.
std::vector<char> Smile(const RangeView& P,
                        const SoundingGrid& grid,
                        const CleanConfig& config,
                        const std::vector<std::uint8_t>& decided) {
    const std::size_t n = P.size();
    std::vector<char> runs(n, 0);
    const int w = config.profile_pings;
    if (n == 0 || w <= 0 || !(config.smile_nadir_deg > 0)) return runs;
    const std::size_t beams = grid.beams(), pings = grid.pings();
    auto cell = [beams](std::size_t k, std::size_t b) { return k * beams + b; };
    // The soundings still accepted per cell (-1: none, or rejected).
    std::vector<std::int32_t> at(pings * beams, -1);
    for (std::size_t j = 0; j < n; ++j) {
        if (decided[j] == 0) at[cell(P.ping[j], P.beam[j])] = static_cast<std::int32_t>(j);
    }
    // Each ping's nadir range (NaN: no accepted sounding near nadir).
    const double max_angle = config.smile_nadir_deg * M_PI / 180.0;
    std::vector<double> nadir(pings, std::nan(""));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pings, 256), [&](const auto& r) {
        std::vector<double> near;
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            std::int64_t best = -1;
            double best_angle = max_angle;
            for (std::size_t b = 0; b < beams; ++b) {
                const std::int32_t j = at[cell(k, b)];
                if (j < 0) continue;
                const double a = std::abs(double{P.angle_rad[static_cast<std::size_t>(j)]});
                if (a <= best_angle) {
                    best_angle = a;
                    best = static_cast<std::int64_t>(b);
                }
            }
            if (best < 0) continue;
            near.clear();
            for (std::int64_t b = best - 2; b <= best + 2; ++b) {
                if (b < 0 || b >= static_cast<std::int64_t>(beams)) continue;
                const std::int32_t j = at[cell(k, static_cast<std::size_t>(b))];
                if (j >= 0) near.push_back(P.range_m[static_cast<std::size_t>(j)]);
            }
            nadir[k] = Median(near);
        }
    });
    std::vector<char> flagged(n, 0);
    for (int pass = 0; pass < 2; ++pass) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192), [&](const auto& r) {
            std::vector<double> side;
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                if (decided[j] != 0 || runs[j]) continue;
                const std::size_t k = P.ping[j];
                const double rn = nadir[k], r0 = P.range_m[j];
                if (!std::isfinite(rn)) continue;
                const double brk = std::max(config.fill_break_m, config.margin_rel * rn);
                if (std::abs(r0 - rn) > brk) continue;
                const auto range_at = [&](std::size_t q) {
                    const std::int32_t x = at[cell(q, P.beam[j])];
                    return x >= 0 && !runs[static_cast<std::size_t>(x)]
                               ? double{P.range_m[static_cast<std::size_t>(x)]}
                               : std::numeric_limits<double>::quiet_NaN();
                };
                bool in_front = true;
                for (const int dir : {-1, 1}) {
                    const double med = grid.SideMedian(
                        static_cast<std::int64_t>(k), P.beam[j], dir, w, range_at, side);
                    if (!(med - r0 > brk)) {
                        in_front = false;
                        break;
                    }
                }
                flagged[j] = in_front;
            }
        });
        for (std::size_t j = 0; j < n; ++j) {
            if (!flagged[j]) continue;
            for (const int db : {-1, 1}) {
                const std::int32_t q = grid.Nearest(j, 0, db);
                if (q >= 0 && flagged[q]) {
                    runs[j] = 1;
                    break;
                }
            }
        }
    }
    return runs;
}

// Holes and edges of an echo run: a sounding accepted between two soundings of one rejection
// status (the nearest on each side, along track or across the fan, over up to 3 dropouts) and
// on the line between their ranges (within hole_tolerance of the range, and 0.1 m) is of their
// run: a ghost whose ray happened to cross no patch between two that did, a smile's ping the
// profile's line passed. So is one at a run's edge: continuous with a rejected neighbour, with
// a break in the range (profile_min_m, margin_rel) within 3 soundings on its other side. Two
// passes (a hole of two soundings closes from both ends).
void FillHoles(const RangeView& P,
               const SoundingGrid& grid,
               const CleanConfig& config,
               std::vector<std::uint8_t>& status) {
    const std::size_t n = P.size();
    if (n == 0 || !(config.hole_tolerance > 0)) return;
    auto nearest = [&grid](std::size_t j, int dk, int db, int* at) {
        return grid.Nearest(j, dk, db, at);
    };
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<std::uint8_t> next = status;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                if (status[j] != 0) continue;
                // Both rules need a rejected nearest neighbour: most soundings have none.
                bool near_rejected = false;
                for (const auto& [dk, db] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
                    const std::int32_t q = grid.Nearest(j, dk, db);
                    near_rejected = near_rejected || (q >= 0 && status[q] != 0);
                }
                if (!near_rejected) continue;
                for (int axis = 0; axis < 2; ++axis) {
                    const int dk = axis == 0 ? 1 : 0, db = axis == 0 ? 0 : 1;
                    int da = 0, dc = 0;
                    const std::int32_t a = nearest(j, -dk, -db, &da);
                    const std::int32_t c = nearest(j, dk, db, &dc);
                    if (a < 0 || c < 0 || status[a] == 0 || status[a] != status[c]) continue;
                    const double ra = P.range_m[a], rc = P.range_m[c];
                    const double line = ra + (rc - ra) * da / static_cast<double>(da + dc);
                    const double r0 = P.range_m[j];
                    if (std::abs(r0 - line) <= std::max(0.1, config.hole_tolerance * r0)) {
                        next[j] = status[a];
                        break;
                    }
                }
                if (next[j] != 0) continue;
                // The edge of a run: continuous with a rejected neighbour on one side, and on
                // the other side a break in the range within 3 soundings (where the run's
                // echo ends and the seabed resumes).
                for (int dir = 0; dir < 4 && next[j] == 0; ++dir) {
                    const int dk = dir < 2 ? (dir == 0 ? -1 : 1) : 0;
                    const int db = dir < 2 ? 0 : (dir == 2 ? -1 : 1);
                    int da = 0;
                    const std::int32_t a = nearest(j, dk, db, &da);
                    if (a < 0 || status[a] == 0) continue;
                    const double r0 = P.range_m[j];
                    const double cont = std::max(0.1, config.hole_tolerance * r0);
                    if (std::abs(double{P.range_m[a]} - r0) > cont) continue;
                    const double jump = std::max(config.profile_min_m, config.margin_rel * r0);
                    std::size_t from = j;
                    double prev = r0;
                    for (int walk = 0; walk < 3; ++walk) {
                        int dc = 0;
                        const std::int32_t c = nearest(from, -dk, -db, &dc);
                        if (c < 0 || status[c] != 0) break;
                        const double rc = P.range_m[c];
                        if (std::abs(rc - prev) > jump) {
                            next[j] = status[a];
                            break;
                        }
                        if (std::abs(rc - prev) > cont) break;
                        from = static_cast<std::size_t>(c);
                        prev = rc;
                    }
                }
            }
        });
        status.swap(next);
    }
}

// Enclosed runs: the soundings still accepted form pieces of continuous range over the (ping,
// beam) grid (neighbours along track and across the fan, over up to 3 dropouts, within
// hole_tolerance of the range and 0.1 m; along track also short of a break: where the range
// grows fast from ping to ping, towards a wall, a long ghost's pings step by more than the
// continuity and would part into pieces open to each other). A small piece (fill_max_soundings at
// most) touching rejected soundings continuously (fill_min_contacts or more contacts) is the rest
// of their run: the part of a ghost or an echo cloud whose rays and profiles happened to pass, held
// between the run's rejected soundings and breaks in the range (fill_break_m, margin_rel of the
// range: at 1-4 m a ghost's 8-45 % or the smile's 5 % is less than the profiles' 0.3 m). A piece
// with an accepted neighbour outside it nearer than a break is open: the terrain's noise parted
// them (the terrain is one large piece, or pieces its noise parts). An enclosed piece takes the
// status most of its contacts have.
void FillEnclosed(const RangeView& P,
                  const SoundingGrid& grid,
                  const CleanConfig& config,
                  std::vector<std::uint8_t>& status) {
    const std::size_t n = P.size();
    if (n == 0 || config.fill_max_soundings <= 0 || !(config.hole_tolerance > 0)) return;
    auto continuous = [&](std::size_t a, std::size_t b) {
        const double ra = P.range_m[a], rb = P.range_m[b];
        return std::abs(ra - rb) <= std::max(0.1, config.hole_tolerance * std::min(ra, rb));
    };
    auto within_break = [&](std::size_t a, std::size_t b) {
        const double ra = P.range_m[a], rb = P.range_m[b];
        return std::abs(ra - rb) <= std::max(config.fill_break_m, config.margin_rel * ra);
    };
    constexpr int kDirections[4][2] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
    // The pieces are grown from the accepted soundings that touch a rejected one continuously,
    // at most fill_max_soundings + 1 each: the terrain's piece is found large once (its
    // soundings marked) and costs nothing more. piece[j]: 0 unseen, -1 in a large or open
    // piece, else the id of the piece being grown (its verdict in `verdict`).
    std::vector<std::int32_t> piece(n, 0);
    std::vector<std::uint8_t> verdict(1, 0);
    std::vector<std::int32_t> members, stack, outside;
    std::array<std::int32_t, survey::kNumSoundingStatus> votes{};
    const auto limit = static_cast<std::size_t>(config.fill_max_soundings);
    for (std::size_t seed = 0; seed < n; ++seed) {
        if (status[seed] != 0 || piece[seed] != 0) continue;
        bool touches = false;
        for (const auto& dir : kDirections) {
            const std::int32_t q = grid.Nearest(seed, dir[0], dir[1]);
            touches = touches || (q >= 0 && status[q] != 0 && continuous(seed, q));
        }
        if (!touches) continue;
        const auto id = static_cast<std::int32_t>(verdict.size());
        verdict.push_back(0);
        members.clear();
        outside.clear();
        votes.fill(0);
        int behind_echoes = 0;
        bool large = false;
        stack.assign(1, static_cast<std::int32_t>(seed));
        piece[seed] = id;
        while (!stack.empty() && !large) {
            const auto j = static_cast<std::size_t>(stack.back());
            stack.pop_back();
            members.push_back(static_cast<std::int32_t>(j));
            for (const auto& dir : kDirections) {
                const std::int32_t q = grid.Nearest(j, dir[0], dir[1]);
                if (q < 0 || piece[q] == id) continue;
                if (status[q] != 0) {
                    if (continuous(j, q)) {
                        ++votes[status[q]];
                    } else if (P.range_m[q] < P.range_m[j] && !within_break(j, q)) {
                        ++behind_echoes;  // seen behind a rejected echo in front of it
                    }
                } else if (continuous(j, q) ||
                           ((dir[0] != 0 || config.fill_across_fan) && within_break(j, q))) {
                    if (piece[q] != 0 || members.size() + stack.size() >= limit) {
                        large = true;  // joins a large piece, or is one
                        break;
                    }
                    piece[q] = id;
                    stack.push_back(q);
                } else if (within_break(j, q)) {
                    outside.push_back(q);  // open unless the piece reaches it another way
                }
            }
        }
        bool open = large;
        for (const std::int32_t q : outside) open = open || piece[q] != id;
        const int contacts = std::accumulate(votes.begin(), votes.end(), 0);
        // Held more by echoes in front of it than by its run's soundings: terrain seen between
        // them (a strip of pings between those a school fills), not the rest of a run.
        if (open || contacts < config.fill_min_contacts || behind_echoes > contacts) {
            for (const std::int32_t j : members) piece[j] = -1;
            for (const std::int32_t j : stack) piece[j] = -1;
            continue;
        }
        verdict[id] =
            static_cast<std::uint8_t>(std::max_element(votes.begin(), votes.end()) - votes.begin());
    }
    for (std::size_t j = 0; j < n; ++j) {
        if (status[j] == 0 && piece[j] > 0) status[j] = verdict[piece[j]];
    }
}

// Terrain after all: a rejected sounding continuous in range with a piece of at least
// terrain_piece_soundings accepted soundings (continuity and pieces as FillEnclosed measures
// them: neighbours along track and across the fan over up to 3 dropouts, within
// hole_tolerance of the range and 0.1 m) is terrain, and so is a rejected sounding continuous
// with one released so. A bench crest the beam grazes for a few pings, a ledge in front of the
// wall, are off their beam's range profile and their rays cross the crest's patch, but their
// ranges go on smoothly into the terrain beside them; the echoes of the water (schools, bubble
// clouds, the smile, ghosts) are parted from it by breaks in the range: an echo that is not is
// on the surface within the noise. Returns the soundings released.
std::int64_t ReleaseTerrain(const RangeView& P,
                            const SoundingGrid& grid,
                            const CleanConfig& config,
                            std::vector<std::uint8_t>& status) {
    const std::size_t n = P.size();
    if (n == 0 || config.terrain_piece_soundings <= 0 || !(config.hole_tolerance > 0)) return 0;
    auto continuous = [&](std::size_t a, std::size_t b) {
        const double ra = P.range_m[a], rb = P.range_m[b];
        return std::abs(ra - rb) <= std::max(0.1, config.hole_tolerance * std::min(ra, rb));
    };
    constexpr int kDirections[4][2] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
    // The accepted pieces are grown only from the accepted soundings beside a rejected one, up
    // to the limit: piece[j] 0 unseen, 1 in a large piece, 2 in a small one; each sounding is
    // visited once (a growth that meets a large piece is large).
    enum : std::uint8_t { kUnseen = 0, kLarge = 1, kSmall = 2, kGrowing = 3 };
    std::vector<std::uint8_t> piece(n, kUnseen);
    std::vector<std::int32_t> members, stack;
    const auto limit = static_cast<std::size_t>(config.terrain_piece_soundings);
    auto in_large_piece = [&](std::size_t seed) {
        if (piece[seed] != kUnseen) return piece[seed] == kLarge;
        members.clear();
        stack.assign(1, static_cast<std::int32_t>(seed));
        piece[seed] = kGrowing;
        bool large = false;
        while (!stack.empty() && !large) {
            const auto j = static_cast<std::size_t>(stack.back());
            stack.pop_back();
            members.push_back(static_cast<std::int32_t>(j));
            for (const auto& dir : kDirections) {
                const std::int32_t q = grid.Nearest(j, dir[0], dir[1]);
                if (q < 0 || status[q] != 0 || piece[q] == kGrowing || !continuous(j, q)) continue;
                if (piece[q] == kLarge || members.size() + stack.size() >= limit) {
                    large = true;
                    break;
                }
                piece[q] = kGrowing;  // kSmall is never met: a small piece is found whole
                stack.push_back(q);
            }
        }
        for (const std::int32_t j : members) piece[j] = large ? kLarge : kSmall;
        for (const std::int32_t j : stack) piece[j] = large ? kLarge : kSmall;
        return large;
    };
    std::vector<char> released(n, 0);
    std::vector<std::int32_t> flood;
    for (std::size_t j = 0; j < n; ++j) {
        if (status[j] == 0) continue;
        for (const auto& dir : kDirections) {
            const std::int32_t q = grid.Nearest(j, dir[0], dir[1]);
            if (q >= 0 && status[q] == 0 && continuous(j, q) && in_large_piece(q)) {
                released[j] = 1;
                flood.push_back(static_cast<std::int32_t>(j));
                break;
            }
        }
    }
    while (!flood.empty()) {
        const auto j = static_cast<std::size_t>(flood.back());
        flood.pop_back();
        for (const auto& dir : kDirections) {
            const std::int32_t q = grid.Nearest(j, dir[0], dir[1]);
            if (q < 0 || status[q] == 0 || released[q] || !continuous(j, q)) continue;
            released[q] = 1;
            flood.push_back(q);
        }
    }
    std::int64_t count = 0;
    for (std::size_t j = 0; j < n; ++j) {
        if (!released[j]) continue;
        status[j] = static_cast<std::uint8_t>(SoundingStatus::kAccepted);
        ++count;
    }
    return count;
}

// Calls fn(block, first) on the view's blocks in order (first: the block's first sounding in
// the view); false when a block could not be read or the blocks do not add up to the view
// (*error says which).
bool Sweep(const ViewBlocks& view,
           const std::function<void(const georef::GeorefPoints&, std::size_t)>& fn,
           std::string* error) {
    std::size_t first = 0;
    const Status st = view.sweep([&](const georef::GeorefPoints& b) {
        if (first + b.size() <= view.size) fn(b, first);
        first += b.size();
    });
    if (!st) {
        *error = st.error().message;
        return false;
    }
    if (first != view.size) {
        *error = "the view's blocks hold " + std::to_string(first) + " soundings, not " +
                 std::to_string(view.size);
        return false;
    }
    return true;
}

// The soundings' voxels in an index grid (voxel id per active voxel, numbered in the view's
// order), each voxel's coordinate and sounding count in X; voxel_of per sounding; the view's
// longest range in *max_range. Null when the view could not be read.
openvdb::Int32Grid::Ptr IndexVoxels(const ViewBlocks& view,
                                    double v,
                                    Voxels& X,
                                    std::vector<std::int32_t>& voxel_of,
                                    double* max_range,
                                    std::string* error) {
    auto index = openvdb::Int32Grid::create(kNone);
    voxel_of.resize(view.size);
    auto acc = index->getAccessor();
    double longest = 0;
    const bool ok = Sweep(
        view,
        [&](const georef::GeorefPoints& P, std::size_t first) {
            for (std::size_t j = 0; j < P.size(); ++j) {
                const Eigen::Vector3d& p = P.position_world[j];
                const Coord ijk = Coord::floor(openvdb::Vec3d(p.x() / v, p.y() / v, p.z() / v));
                std::int32_t id = kNone;
                if (!acc.probeValue(ijk, id)) {
                    id = static_cast<std::int32_t>(X.size());
                    acc.setValue(ijk, id);
                    X.coord.push_back(ijk);
                    X.count.push_back(0);
                }
                voxel_of[first + j] = id;
                ++X.count[id];
                longest = std::max(longest, double{P.range_m[j]});
            }
        },
        error);
    *max_range = longest;
    return ok ? index : nullptr;
}

// The 26-connected components of the voxels (X.component: the smallest voxel id of each);
// returns the voxel count per component root.
std::vector<std::int32_t> Components(const openvdb::Int32Grid& index, Voxels& X) {
    const std::size_t nv = X.size();
    std::vector<std::int32_t> parent(nv);
    std::iota(parent.begin(), parent.end(), 0);
    auto acc = index.getConstAccessor();
    for (std::size_t i = 0; i < nv; ++i) {
        for (int dx = -1; dx <= 1; ++dx) {
            for (int dy = -1; dy <= 1; ++dy) {
                for (int dz = -1; dz <= 1; ++dz) {
                    // Each pair once: the 13 neighbours after this voxel in (x, y, z) order.
                    if (dx < 0 || (dx == 0 && (dy < 0 || (dy == 0 && dz <= 0)))) continue;
                    std::int32_t k = kNone;
                    if (!acc.probeValue(X.coord[i].offsetBy(dx, dy, dz), k)) continue;
                    const std::int32_t a = Find(parent, static_cast<std::int32_t>(i));
                    const std::int32_t b = Find(parent, k);
                    if (a != b) parent[std::max(a, b)] = std::min(a, b);
                }
            }
        }
    }
    std::vector<std::int32_t> comp_voxels(nv, 0);
    X.component.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) {
        X.component[i] = Find(parent, static_cast<std::int32_t>(i));
        ++comp_voxels[X.component[i]];
    }
    return comp_voxels;
}

// Voxel i's plane patch from its m soundings' positions (in the view's order): a robust fit
// (Cauchy-weighted PCA), so that the echoes in a voxel do not tilt the surface they are judged
// against. w: the caller's scratch.
void FitPatch(const Eigen::Vector3d* pts,
              std::size_t m,
              std::size_t i,
              const CleanConfig& config,
              Voxels& X,
              std::vector<double>& w) {
    w.assign(m, 1.0);
    Eigen::Vector3d mean, normal;
    Eigen::Vector3d ev;
    Eigen::Matrix3d axes;
    for (int iter = 0; iter < 4; ++iter) {
        double sw = 0;
        mean.setZero();
        for (std::size_t k = 0; k < m; ++k) {
            mean += w[k] * pts[k];
            sw += w[k];
        }
        mean /= sw;
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        for (std::size_t k = 0; k < m; ++k) {
            const Eigen::Vector3d d = pts[k] - mean;
            cov += w[k] * d * d.transpose();
        }
        cov /= sw;
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
        es.computeDirect(cov);
        ev = es.eigenvalues().cwiseMax(0.0);
        axes = es.eigenvectors();
        normal = axes.col(0);
        // Cauchy weights on the distance to the plane, scale: the range noise's order.
        const double scale = std::max(0.05, std::sqrt(ev[0]));
        for (std::size_t k = 0; k < m; ++k) {
            const double d = normal.dot(pts[k] - mean) / scale;
            w[k] = 1.0 / (1.0 + d * d);
        }
    }
    // Thickness: the weighted spread across the plane of the soundings that support it.
    double sw = 0, s2 = 0;
    for (std::size_t k = 0; k < m; ++k) {
        if (w[k] < 0.2) continue;
        const double d = normal.dot(pts[k] - mean);
        s2 += d * d;
        sw += 1;
    }
    X.centroid[i] = mean;
    X.normal[i] = normal;
    X.thickness[i] = sw > 0 ? std::sqrt(s2 / sw) : 1e9;
    X.axis_major[i] = axes.col(2);
    X.axis_minor[i] = axes.col(1);
    X.sigma_major[i] = std::sqrt(ev[2]);
    X.sigma_minor[i] = std::sqrt(ev[1]);
    // One surface: most of the voxel's soundings on it (a floor's toe, with the wall's
    // soundings beside the floor's, is two).
    X.patch[i] = sw >= config.surface_min_hits && sw >= 0.8 * static_cast<double>(m) &&
                 X.thickness[i] <= config.surface_max_thickness_m;
}

// The voxels from v0 on whose soundings to fit (surface_min_hits or more) add up to at most
// `limit` (at least one voxel): returns the end of the batch; offset[i - v0] .. offset[i - v0
// + 1] is voxel i's part of the batch's positions (empty for a voxel not fitted).
std::size_t FitBatch(const Voxels& X,
                     std::size_t v0,
                     std::size_t limit,
                     int min_hits,
                     std::vector<std::size_t>& offset) {
    offset.assign(1, 0);
    std::size_t v1 = v0, total = 0;
    for (; v1 < X.size(); ++v1) {
        const auto m = static_cast<std::size_t>(X.count[v1] >= min_hits ? X.count[v1] : 0);
        if (v1 > v0 && total + m > limit) break;
        total += m;
        offset.push_back(total);
    }
    return v1;
}

// A plane patch per voxel with enough soundings (FitPatch), batch by batch of voxels: each
// batch's soundings' positions gathered from one read of the view, voxel by voxel in the view's
// order (the whole view's members in the order a counting sort gives them). False when the view
// could not be read.
bool FitPatches(const ViewBlocks& view,
                const std::vector<std::int32_t>& voxel_of,
                std::size_t fit_soundings,
                const CleanConfig& config,
                Voxels& X,
                std::string* error) {
    const std::size_t nv = X.size();
    X.centroid.resize(nv);
    X.normal.resize(nv);
    X.axis_major.resize(nv);
    X.axis_minor.resize(nv);
    X.sigma_major.assign(nv, 0);
    X.sigma_minor.assign(nv, 0);
    X.thickness.assign(nv, 0);
    X.patch.assign(nv, 0);
    const int min_hits = config.surface_min_hits;
    std::vector<std::size_t> offset, at;
    std::vector<Eigen::Vector3d> pts;
    for (std::size_t v0 = 0; v0 < nv;) {
        const std::size_t v1 =
            FitBatch(X, v0, std::max<std::size_t>(fit_soundings, 1), min_hits, offset);
        if (offset.back() > 0) {
            pts.resize(offset.back());
            at.assign(offset.begin(), offset.end() - 1);
            const auto gather = [&](const georef::GeorefPoints& P, std::size_t first) {
                for (std::size_t j = 0; j < P.size(); ++j) {
                    const auto i = static_cast<std::size_t>(voxel_of[first + j]);
                    if (i < v0 || i >= v1 || X.count[i] < min_hits) continue;
                    pts[at[i - v0]++] = P.position_world[j];
                }
            };
            if (!Sweep(view, gather, error)) return false;
            tbb::parallel_for(tbb::blocked_range<std::size_t>(v0, v1, 1024), [&](const auto& r) {
                std::vector<double> w;
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    const std::size_t m = offset[i - v0 + 1] - offset[i - v0];
                    if (m == 0) continue;
                    FitPatch(pts.data() + offset[i - v0], m, i, config, X, w);
                }
            });
        }
        v0 = v1;
    }
    return true;
}

// The soundings' rays: from the transducer to the sounding, in index space. Soundings are a
// block's (P, j).
struct SoundingRays {
    const std::vector<georef::GeorefPing>& pings;
    const CleanConfig& config;
    double v;  // voxel size, m

    const Eigen::Vector3d& Sensor(const georef::GeorefPoints& P, std::size_t j) const {
        return pings[P.ping[j]].sensor_world;
    }
    // How far short of its end a ray counts as free space, m.
    double Margin(double range) const {
        return std::max(config.margin_m, config.margin_rel * range);
    }
    // Sounding j's ray in index space (unit direction: t is in voxels) and its length in
    // voxels.
    RayT Ray(const georef::GeorefPoints& P, std::size_t j, double* length_vox) const {
        const Eigen::Vector3d s = Sensor(P, j) / v;
        Eigen::Vector3d d = P.position_world[j] / v - s;
        *length_vox = d.norm();
        if (*length_vox > 0) d /= *length_vox;
        return RayT(openvdb::Vec3d(s.x(), s.y(), s.z()), openvdb::Vec3d(d.x(), d.y(), d.z()));
    }
};

// Where the line s + t d (unit d, t in metres) goes through voxel vox's plane patch for t in
// (t_min, t_max): into the plane at more than the crossing angle (min_sin: its sine), the
// crossing inside the voxel and within the patch's own extent (2 sigma of its soundings along
// each axis of the plane), not across the part of the voxel it does not cover. Returns the
// crossing's t, or -1 where it does not.
double CrossesPatch(const Voxels& X,
                    std::int32_t vox,
                    const Eigen::Vector3d& s,
                    const Eigen::Vector3d& d,
                    double t_min,
                    double t_max,
                    double min_sin,
                    double v) {
    const Eigen::Vector3d& m = X.centroid[vox];
    const Eigen::Vector3d& nrm = X.normal[vox];
    const double dn = nrm.dot(d);
    if (std::abs(dn) < min_sin) return -1;  // grazing
    const double t_cross = nrm.dot(m - s) / dn;
    if (!(t_cross > t_min && t_cross < t_max)) return -1;
    const Eigen::Vector3d x = s + t_cross * d;
    const Eigen::Vector3d xi = x / v;
    if (Coord::floor(openvdb::Vec3d(xi.x(), xi.y(), xi.z())) != X.coord[vox]) return -1;
    const Eigen::Vector3d u = x - m;
    if (std::abs(u.dot(X.axis_major[vox])) > 2.0 * X.sigma_major[vox] + 0.05 ||
        std::abs(u.dot(X.axis_minor[vox])) > 2.0 * X.sigma_minor[vox] + 0.05)
        return -1;
    return t_cross;
}

// What the rays say of each voxel: how many went through it, and each ray's first crossing of
// a plane patch (kNone: none).
struct RayEvidence {
    std::vector<std::atomic<std::int32_t>> free_rays;
    std::vector<std::int32_t> first_crossing;
};

// Every sounding's ray, from the transducer to `margin` before its end, through every voxel it
// passes (not its own): free_rays counts them per voxel; where it goes through a plane patch
// (into the plane at more than min_crossing_deg, within the patch's extent) that is a crossing
// of that patch, and the ray's first crossing is kept. A block of the view at a time, into
// `ev` (sized: X's voxels, the view's soundings); false when the view could not be read.
bool MarchRays(const ViewBlocks& view,
               const SoundingRays& rays,
               const openvdb::Int32Grid& index,
               const Voxels& X,
               const std::vector<std::int32_t>& voxel_of,
               RayEvidence& ev,
               std::string* error) {
    const double v = rays.v;
    auto& free_rays = ev.free_rays;
    auto& first_crossing = ev.first_crossing;
    const double min_sin = std::sin(rays.config.min_crossing_deg * M_PI / 180.0);
    const auto block = [&](const georef::GeorefPoints& P, std::size_t first) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P.size(), 8192), [&](const auto& r) {
            Marcher march(index);
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const std::size_t j = first + i;
                double len = 0;
                const RayT ray = rays.Ray(P, i, &len);
                if (!(len > 0)) continue;
                const double range = len * v;
                const double stop = range - rays.Margin(range);
                const std::int32_t own_id = voxel_of[j];
                const Eigen::Vector3d& s = rays.Sensor(P, i);
                const Eigen::Vector3d d = (P.position_world[i] - s) / range;
                march(ray, 0.0, stop / v, [&](std::int32_t vox, double) {
                    if (vox == own_id) return true;
                    free_rays[vox].fetch_add(1, std::memory_order_relaxed);
                    // Only the first crossing counts: after it, only the rays through.
                    if (!X.patch[vox] || first_crossing[j] != kNone) return true;
                    if (CrossesPatch(X, vox, s, d, 0.0, stop, min_sin, v) >= 0)
                        first_crossing[j] = vox;
                    return true;
                });
            }
        });
    };
    return Sweep(view, block, error);
}

// The patches judged by the crossings: per patch its soundings whose rays crossed no patch
// (the surface's own support), and the credible crossings of it. A crossing is evidence of
// water only when the crossing ray ends on a supported surface: a floor sounding whose ray went
// through a fish school is; a ghost, whose ray went through the floor, ends where no ray ends
// without crossing something, and is not.
class PatchVerdicts {
public:
    PatchVerdicts(const Voxels& X,
                  const std::vector<std::int32_t>& voxel_of,
                  const std::vector<std::int32_t>& first_crossing,
                  const CleanConfig& config)
        : X_(X), config_(config), clean_hits_(X.size(), 0), credible_(X.size(), 0) {
        const std::size_t n = voxel_of.size();
        for (std::size_t j = 0; j < n; ++j) clean_hits_[voxel_of[j]] += first_crossing[j] == kNone;
        for (std::size_t j = 0; j < n; ++j) {
            if (first_crossing[j] != kNone &&
                2 * clean_hits_[voxel_of[j]] >= config.surface_min_hits)
                ++credible_[first_crossing[j]];
        }
    }
    // A "surface" other rays went through: echoes in the water.
    bool Transient(std::int32_t vox) const {
        const std::int32_t x = credible_[vox];
        return X_.patch[vox] && x >= config_.free_min_rays &&
               x >= config_.free_ratio * clean_hits_[vox];
    }
    // A surface observed from elsewhere and hardly crossed.
    bool Solid(std::int32_t vox) const {
        const std::int32_t x = credible_[vox];
        return X_.patch[vox] && clean_hits_[vox] >= config_.surface_min_hits &&
               x < config_.solid_ratio * clean_hits_[vox];
    }

private:
    const Voxels& X_;
    const CleanConfig& config_;
    std::vector<std::int32_t> clean_hits_, credible_;
};

// Per cluster (component root): its soundings, those with terrain behind them along their
// rays (as far as 1.5 x the survey's longest range), and those whose rays went through the
// terrain before their ends: into a solid patch's plane at more than the crossing angle, within
// a voxel of the patch's centre (a long ghost behind a wall that its own pings observed only
// sparsely: its rays pass the wall between the patches' extents).
struct ClusterRays {
    std::vector<std::atomic<std::int32_t>> behind, through, points;
    std::vector<char> went_through;  // per sounding of a cluster: its ray went through terrain
};

// A cluster sounding's two marches (above), into `out`: whether terrain lies behind it, and
// whether its ray went through a solid patch before its end.
void MarchBehindCluster(const georef::GeorefPoints& P,
                        std::size_t i,
                        std::size_t j,
                        std::int32_t k,
                        const SoundingRays& rays,
                        const Voxels& X,
                        const PatchVerdicts& patches,
                        double behind_vox,
                        double min_sin,
                        Marcher& march,
                        ClusterRays& out) {
    out.points[k].fetch_add(1, std::memory_order_relaxed);
    double len = 0;
    const RayT ray = rays.Ray(P, i, &len);
    if (!(len > 0)) return;
    const double range = len * rays.v;
    const double margin = rays.Margin(range);
    const double from = len + margin / rays.v;
    bool behind = false;
    march(ray, from, from + behind_vox, [&](std::int32_t, double) {
        behind = true;
        return false;
    });
    if (behind) out.behind[k].fetch_add(1, std::memory_order_relaxed);
    const Eigen::Vector3d& s = rays.Sensor(P, i);
    const Eigen::Vector3d d = (P.position_world[i] - s) / range;
    bool through = false;
    march(ray, 0.0, (range - margin) / rays.v, [&](std::int32_t vox, double) {
        if (!patches.Solid(vox)) return true;
        const double dn = X.normal[vox].dot(d);
        if (std::abs(dn) < min_sin) return true;  // grazing
        const double t_cross = X.normal[vox].dot(X.centroid[vox] - s) / dn;
        through = t_cross > 0 && t_cross < range - margin &&
                  (s + t_cross * d - X.centroid[vox]).norm() <= rays.v;
        return !through;
    });
    if (through) {
        out.through[k].fetch_add(1, std::memory_order_relaxed);
        out.went_through[j] = 1;
    }
}

// The clusters' soundings' marches through the terrain's voxels (MarchBehindCluster), a block
// of the view at a time, into `out` (sized: X's voxels, the view's soundings); `max_range`: the
// view's longest range. False when the view could not be read.
bool RaysBehindClusters(const ViewBlocks& view,
                        const SoundingRays& rays,
                        const openvdb::Int32Grid& terrain_grid,
                        const Voxels& X,
                        const std::vector<std::int32_t>& voxel_of,
                        const std::vector<char>& terrain_voxel,
                        const PatchVerdicts& patches,
                        double max_range,
                        ClusterRays& out,
                        std::string* error) {
    const double behind_vox = 1.5 * max_range / rays.v;
    const double min_sin = std::sin(rays.config.min_crossing_deg * M_PI / 180.0);
    const auto block = [&](const georef::GeorefPoints& P, std::size_t first) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P.size(), 8192), [&](const auto& r) {
            Marcher march(terrain_grid);
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const std::size_t j = first + i;
                const std::int32_t own = voxel_of[j];
                if (terrain_voxel[own]) continue;
                MarchBehindCluster(
                    P, i, j, X.component[own], rays, X, patches, behind_vox, min_sin, march, out);
            }
        });
    };
    return Sweep(view, block, error);
}

// Each sounding's verdict from its voxel and its ray.
void Verdicts(const Voxels& X,
              const std::vector<std::int32_t>& voxel_of,
              const std::vector<char>& terrain_voxel,
              const RayEvidence& rays,
              const PatchVerdicts& patches,
              const ClusterRays& clusters,
              const CleanConfig& config,
              std::vector<std::uint8_t>& status) {
    auto free_voxel = [&](std::int32_t vox, double ratio) {
        const std::int32_t f = rays.free_rays[vox].load(std::memory_order_relaxed);
        return f >= config.free_min_rays && f >= ratio * X.count[vox];
    };
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, voxel_of.size(), 8192), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                const std::int32_t own = voxel_of[j];
                const std::int32_t crossed = rays.first_crossing[j];
                SoundingStatus st = SoundingStatus::kAccepted;
                if (patches.Transient(own)) {
                    // A "surface" other rays went through: echoes in the water.
                    st = SoundingStatus::kFreeSpace;
                } else if (crossed != kNone && patches.Solid(crossed) &&
                           (terrain_voxel[crossed] || !free_voxel(crossed, config.free_ratio))) {
                    // The ray went through a surface observed from elsewhere: a ghost behind it.
                    // Not a cluster voxel whose own soundings are echoes in the water (below):
                    // the terrain seen through a fish school between its pings is no ghost.
                    st = SoundingStatus::kMultipath;
                } else if (!terrain_voxel[own]) {
                    const std::int32_t k = X.component[own];
                    if (free_voxel(own, config.free_ratio)) {
                        st = SoundingStatus::kFreeSpace;
                    } else if (2 * clusters.through[k].load() > clusters.points[k].load() ||
                               (!clusters.went_through.empty() && clusters.went_through[j])) {
                        // Its rays went through the terrain: a ghost behind a wall.
                        st = SoundingStatus::kMultipath;
                    } else if (2 * clusters.behind[k].load() > clusters.points[k].load()) {
                        st = SoundingStatus::kCluster;
                    }
                }
                status[j] = static_cast<std::uint8_t>(st);
            }
        });
}

// The counts of the cleaning statuses.
void CountVerdicts(const std::vector<std::uint8_t>& status, CleanCounts& c) {
    for (const std::uint8_t s : status) {
        switch (static_cast<SoundingStatus>(s)) {
            case SoundingStatus::kProfile:
                ++c.profile;
                break;
            case SoundingStatus::kFreeSpace:
                ++c.free_space;
                break;
            case SoundingStatus::kCluster:
                ++c.cluster;
                break;
            case SoundingStatus::kMultipath:
                ++c.multipath;
                break;
            default:
                break;
        }
    }
}

// Steps 1-4: each sounding's verdict from its voxel and its ray, into `status`; false when
// cancelled (through `report`) or when the view could not be read (*error says). Reads the view
// in blocks (one read for the voxels, one per batch of plane fits, one for the rays, one for
// the clusters' marches) and holds the voxels and, per sounding, its voxel, its ray's first
// crossing and the cluster marches' marks (9 bytes), all freed on return: the range profiles
// after it read the verdicts alone, and their own arrays are not held beside these.
bool VoxelVerdicts(const ViewBlocks& view,
                   const CleanConfig& config,
                   const std::function<bool(double)>& report,
                   std::size_t fit_soundings,
                   CleanCounts& c,
                   std::vector<std::uint8_t>& status,
                   std::string* error) {
    const double v = config.voxel_m;
    auto t_start = std::chrono::steady_clock::now();
    // ---- 1. voxels, moments, components ----
    Voxels X;
    std::vector<std::int32_t> voxel_of;
    double max_range = 0;
    const auto index = IndexVoxels(view, v, X, voxel_of, &max_range, error);
    if (!index) return false;
    const std::size_t nv = X.size();
    c.voxels = static_cast<std::int64_t>(nv);
    const std::vector<std::int32_t> comp_voxels = Components(*index, X);
    // Terrain: the voxels of components of cluster_max_voxels or more.
    std::vector<char> terrain_voxel(nv);
    for (std::size_t i = 0; i < nv; ++i)
        terrain_voxel[i] = comp_voxels[X.component[i]] >= config.cluster_max_voxels;
    for (std::size_t i = 0; i < nv; ++i) {
        if (X.component[i] != static_cast<std::int32_t>(i)) continue;
        (comp_voxels[i] >= config.cluster_max_voxels ? c.terrain_components : c.clusters) += 1;
    }
    // The terrain's voxels, for the marches behind clusters.
    auto terrain_grid = openvdb::Int32Grid::create(kNone);
    {
        auto ta = terrain_grid->getAccessor();
        for (std::size_t i = 0; i < nv; ++i) {
            if (terrain_voxel[i]) ta.setValue(X.coord[i], static_cast<std::int32_t>(i));
        }
    }
    if (!FitPatches(view, voxel_of, fit_soundings, config, X, error)) return false;
    c.seconds_voxels = Seconds(t_start);
    if (!report(0.1)) return false;

    // ---- 2. rays through the voxels: free space and crossings of plane patches ----
    t_start = std::chrono::steady_clock::now();
    const SoundingRays rays{*view.pings, config, v};
    RayEvidence evidence{std::vector<std::atomic<std::int32_t>>(nv),
                         std::vector<std::int32_t>(view.size, kNone)};
    if (!MarchRays(view, rays, *index, X, voxel_of, evidence, error)) return false;
    const PatchVerdicts patches(X, voxel_of, evidence.first_crossing, config);
    c.seconds_rays = Seconds(t_start);
    if (!report(0.4)) return false;

    // ---- 3. clusters in front of the terrain ----
    // A cluster is judged by its soundings: off the surface when most of them have terrain
    // behind them along their rays.
    t_start = std::chrono::steady_clock::now();
    ClusterRays clusters{std::vector<std::atomic<std::int32_t>>(nv),
                         std::vector<std::atomic<std::int32_t>>(nv),
                         std::vector<std::atomic<std::int32_t>>(nv),
                         {}};
    if (c.clusters > 0) {
        clusters.went_through.assign(view.size, 0);
        if (!RaysBehindClusters(view,
                                rays,
                                *terrain_grid,
                                X,
                                voxel_of,
                                terrain_voxel,
                                patches,
                                max_range,
                                clusters,
                                error))
            return false;
    }
    c.seconds_clusters = Seconds(t_start);

    // ---- 4. each sounding: its voxel, its ray ----
    t_start = std::chrono::steady_clock::now();
    Verdicts(X, voxel_of, terrain_voxel, evidence, patches, clusters, config, status);
    c.seconds_verdicts = Seconds(t_start);
    return true;
}

// What the range profiles read of the view (RangeView), from one read of its blocks; the angles
// only where the smile is looked for. False when the view could not be read.
bool ReadRanges(const ViewBlocks& view,
                const CleanConfig& config,
                RangeView& P,
                std::string* error) {
    const bool angles = config.profile_pings > 0 && config.smile_nadir_deg > 0;
    P.num_pings = view.pings->size();
    P.ping.reserve(view.size);
    P.beam.reserve(view.size);
    P.range_m.reserve(view.size);
    if (angles) P.angle_rad.reserve(view.size);
    const auto append = [](const auto& from, auto& to) {
        to.insert(to.end(), from.begin(), from.end());
    };
    return Sweep(
        view,
        [&](const georef::GeorefPoints& b, std::size_t) {
            append(b.ping, P.ping);
            append(b.beam, P.beam);
            append(b.range_m, P.range_m);
            if (angles) append(b.angle_rad, P.angle_rad);
        },
        error);
}

// Steps 5-8 on the range view: the range profiles, the near-field echoes and the smile, the
// holes and the enclosed pieces, then what is continuous with the terrain.
void RangeVerdicts(const RangeView& P,
                   const CleanConfig& config,
                   CleanCounts& c,
                   std::vector<std::uint8_t>& status) {
    const std::size_t n = P.size();
    // ---- 5. the range profiles: what the 3D tests left ----
    auto t_start = std::chrono::steady_clock::now();
    const SoundingGrid grid(P);
    const std::vector<char> along = Profiles(P, grid, config, status);
    const std::vector<char> near = NearField(P, grid, config, status);
    const std::vector<char> smile = Smile(P, grid, config, status);
    for (std::size_t j = 0; j < n; ++j) {
        if (status[j] != 0) continue;
        if (along[j] || near[j] || smile[j])
            status[j] = static_cast<std::uint8_t>(SoundingStatus::kProfile);
    }
    FillHoles(P, grid, config, status);
    FillEnclosed(P, grid, config, status);
    c.seconds_profiles = Seconds(t_start);

    // ---- 6. what is continuous with the terrain is terrain ----
    t_start = std::chrono::steady_clock::now();
    c.terrain = ReleaseTerrain(P, grid, config, status);
    CountVerdicts(status, c);
    for (std::size_t j = 0; j < n; ++j) {
        c.near_field += near[j] && !along[j] &&
                        status[j] == static_cast<std::uint8_t>(SoundingStatus::kProfile);
        c.smile += smile[j] && !along[j] && !near[j] &&
                   status[j] == static_cast<std::uint8_t>(SoundingStatus::kProfile);
    }
    c.seconds_terrain = Seconds(t_start);
}

}  // namespace

std::vector<std::string> CleanConfig::Validate() const {
    std::vector<std::string> p;
    if (!(voxel_m > 0.01 && voxel_m < 100)) p.push_back("clean.voxel_m must be in (0.01, 100)");
    if (cluster_max_voxels < 1) p.push_back("clean.cluster_max_voxels must be >= 1");
    if (!(margin_m >= 0)) p.push_back("clean.margin_m must be >= 0");
    if (!(margin_rel >= 0 && margin_rel < 1)) p.push_back("clean.margin_rel must be in [0, 1)");
    if (free_min_rays < 1) p.push_back("clean.free_min_rays must be >= 1");
    if (!(free_ratio >= 0)) p.push_back("clean.free_ratio must be >= 0");
    if (surface_min_hits < 3) p.push_back("clean.surface_min_hits must be >= 3");
    if (!(surface_max_thickness_m > 0)) p.push_back("clean.surface_max_thickness_m must be > 0");
    if (!(solid_ratio > 0 && solid_ratio <= free_ratio))
        p.push_back("clean.solid_ratio must be in (0, free_ratio]");
    if (profile_pings < 0) p.push_back("clean.profile_pings must be >= 0");
    if (profile_beams < 0) p.push_back("clean.profile_beams must be >= 0");
    if (!(near_field_max_range_m >= 0)) p.push_back("clean.near_field_max_range_m must be >= 0");
    if (!(near_field_ratio > 0 && near_field_ratio < 1))
        p.push_back("clean.near_field_ratio must be in (0, 1)");
    if (!(near_field_min_m >= 0)) p.push_back("clean.near_field_min_m must be >= 0");
    if (!(smile_nadir_deg >= 0 && smile_nadir_deg < 90))
        p.push_back("clean.smile_nadir_deg must be in [0, 90)");
    if (!(hole_tolerance >= 0 && hole_tolerance < 1))
        p.push_back("clean.hole_tolerance must be in [0, 1)");
    if (fill_max_soundings < 0) p.push_back("clean.fill_max_soundings must be >= 0");
    if (fill_min_contacts < 1) p.push_back("clean.fill_min_contacts must be >= 1");
    if (!(fill_break_m > 0)) p.push_back("clean.fill_break_m must be > 0");
    if (terrain_piece_soundings < 0) p.push_back("clean.terrain_piece_soundings must be >= 0");
    if (!(profile_sigmas > 0)) p.push_back("clean.profile_sigmas must be > 0");
    if (!(profile_min_m >= 0)) p.push_back("clean.profile_min_m must be >= 0");
    if (!(profile_max_spread > 0)) p.push_back("clean.profile_max_spread must be > 0");
    return p;
}

CleanResult Clean(const georef::GeorefResult& geo,
                  const CleanConfig& config,
                  const ProgressCallback& progress) {
    ViewBlocks view;
    view.size = geo.points.size();
    view.pings = &geo.pings;
    view.sweep = [&geo](const TakeBlock& take) {
        take(geo.points);
        return Status{Ok{}};
    };
    auto r = CleanBlocks(view, config, progress);
    PITMAP_CHECK(r, "clean: a held view's one block is always read");
    return std::move(*r);
}

Expected<CleanResult> CleanBlocks(const ViewBlocks& view,
                                  const CleanConfig& config,
                                  const ProgressCallback& progress,
                                  std::size_t fit_soundings) {
    openvdb::initialize();
    CleanResult result;
    const std::size_t n = view.size;
    result.status.assign(n, static_cast<std::uint8_t>(SoundingStatus::kAccepted));
    CleanCounts& c = result.counts;
    c.soundings = static_cast<std::int64_t>(n);
    if (n == 0) return result;
    PITMAP_CHECK(view.pings != nullptr && view.sweep, "clean: a view without pings or blocks");
    std::unique_ptr<tbb::global_control> limit;
    if (config.num_threads > 0) {
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      static_cast<std::size_t>(config.num_threads));
    }
    const std::function<bool(double)> report = [&](double share) {
        return !progress || progress(share);
    };
    std::string error;
    const auto failed = [&]() -> Expected<CleanResult> {
        if (!error.empty()) return Error{error};
        result.cancelled = true;
        return result;
    };

    // ---- 1.-4. voxels, rays, clusters: each sounding's 3D verdict ----
    if (!VoxelVerdicts(view, config, report, fit_soundings, c, result.status, &error))
        return failed();

    // ---- 5.-8. the range profiles on the soundings' ranges ----
    {
        RangeView ranges;
        if (!ReadRanges(view, config, ranges, &error)) return failed();
        RangeVerdicts(ranges, config, c, result.status);
    }
    report(1.0);
    return result;
}

}  // namespace pitmap::proc::clean
