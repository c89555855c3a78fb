// SPDX-License-Identifier: MIT
// SLAM sections and correspondences: k-d tree blocks of consecutive slices, closest-point
// pairs between slices at least t_d apart (seed paper §4.2: "we match only to points, if they
// were recorded at least td time steps away", within a maximal point-to-point distance), their
// normals, the section graph of the rigid stage (links with enough pairs, Borrmann et al.
// 2008), and the two scores that judge an iterate: the truncated pair score and the plane-fit
// consistency score.
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include "processor/registration/grid_key.hpp"
#include "processor/registration/normals.hpp"
#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

std::vector<std::size_t> SectionStarts(const Input& in, double length_s) {
    std::vector<std::size_t> starts;
    std::size_t s = 0;
    double t_break = -std::numeric_limits<double>::infinity();
    while (s < in.num_slices()) {
        if (in.IsBreak(s)) t_break = in.t_s[s];
        const std::size_t s0 = s++;
        starts.push_back(s0);
        // After a GNSS recovery the INS error falls within seconds: sections of 1, 1, 2, 4, 8 s
        // there (doubling up to length_s), so that the rigid stage can follow the fall.
        const double since = in.t_s[s0] - t_break;
        const double len =
            since < length_s ? std::clamp(since, kBreakFirstSectionS, length_s) : length_s;
        while (s < in.num_slices() && in.t_s[s] < in.t_s[s0] + len && !in.IsBreak(s)) ++s;
    }
    starts.push_back(in.num_slices());
    return starts;
}

std::vector<Block> MakeBlocks(const Input& in, double length_s) {
    const std::vector<std::size_t> starts = SectionStarts(in, length_s);
    std::vector<Block> blocks(starts.size() - 1);
    for (std::size_t i = 0; i + 1 < starts.size(); ++i) {
        Block& b = blocks[i];
        b.s0 = starts[i];
        b.s1 = starts[i + 1];
        b.p0 = in.offset[b.s0];
        b.p1 = in.offset[b.s1];
        b.t0 = in.t_s[b.s0];
        b.t1 = in.t_s[b.s1 - 1];
    }
    return blocks;
}

NeighbourPacking::NeighbourPacking(const Block& b, std::size_t k_in)
    : none(static_cast<std::uint32_t>(b.p1 - b.p0)), k(k_in) {
    while (bits < 32 && (std::uint64_t{none} >> bits) != 0) ++bits;
    words = (k * static_cast<std::size_t>(bits) + 63) / 64;
}

void NeighbourPacking::Pack(const std::size_t* idx, std::size_t n, std::uint64_t* w) const {
    const auto b = static_cast<std::size_t>(bits);
    for (std::size_t j = 0; j < k; ++j) {
        const std::uint64_t v = j < n ? std::uint64_t{idx[j]} : std::uint64_t{none};
        const std::size_t pos = j * b, word = pos / 64, shift = pos % 64;
        w[word] |= v << shift;
        if (shift + b > 64) w[word + 1] |= v >> (64 - shift);
    }
}

void NeighbourPacking::Unpack(const std::uint64_t* w, std::uint32_t* out) const {
    const auto b = static_cast<std::size_t>(bits);
    const std::uint64_t mask = (std::uint64_t{1} << b) - 1;
    for (std::size_t j = 0; j < k; ++j) {
        const std::size_t pos = j * b, word = pos / 64, shift = pos % 64;
        std::uint64_t v = w[word] >> shift;
        if (shift + b > 64) v |= w[word + 1] << (64 - shift);
        out[j] = static_cast<std::uint32_t>(v & mask);
    }
}

void PartnerBlocks(const std::vector<Block>& blocks,
                   const std::vector<std::uint32_t>& listed,
                   std::uint32_t own,
                   double t,
                   double td,
                   int max_passes,
                   std::vector<std::uint32_t>& partners) {
    partners.clear();
    const auto mid = std::lower_bound(listed.begin(), listed.end(), own);
    // Earlier blocks, walking back in time. Blocks are in time order, so once one ends td
    // before t every earlier one does: the separated blocks form the runs (passes) counted.
    int passes = 0;
    for (auto it = mid; it != listed.begin();) {
        --it;
        if (!(blocks[*it].t1 <= t - td)) continue;
        if (partners.empty() || *it + 1 != partners.back()) {
            if (max_passes > 0 && passes == max_passes) break;
            ++passes;
        }
        partners.push_back(*it);
    }
    std::reverse(partners.begin(), partners.end());  // ascending, as the later ones
    const std::size_t earlier = partners.size();
    passes = 0;
    for (auto it = mid; it != listed.end(); ++it) {
        if (!(blocks[*it].t0 >= t + td)) continue;
        if (partners.size() == earlier || *it != partners.back() + 1) {
            if (max_passes > 0 && passes == max_passes) break;
            ++passes;
        }
        partners.push_back(*it);
    }
}

namespace {

void BuildTrees(std::vector<Block>& blocks, const std::vector<Eigen::Vector3f>& pw) {
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t i) {
        Block& b = blocks[i];
        b.lo.setConstant(std::numeric_limits<float>::max());
        b.hi.setConstant(std::numeric_limits<float>::lowest());
        for (std::size_t k = b.p0; k < b.p1; ++k) {
            b.lo = b.lo.cwiseMin(pw[k]);
            b.hi = b.hi.cwiseMax(pw[k]);
        }
        b.tree.reset();
        if (b.p1 > b.p0) b.tree = std::make_unique<SectionTree>(pw.data() + b.p0, b.p1 - b.p0);
    });
}

// Horizontal cells for the lists of blocks per cell.
struct CellGrid {
    float cell;  // m
    std::int64_t Index(float v) const { return static_cast<std::int64_t>(std::floor(v / cell)); }
    std::uint64_t Key(float x, float y) const { return reg::CellKey(Index(x), Index(y)); }
};

// The cells block b's points come within dmax of (corners of the point's dmax square; cells
// are at least 2 dmax). They are marked in a bitmap over the block's bounding box (a few
// hundred cells; the sort of four keys per point it replaces was 5 % of SLAM's CPU on
// bejanca); a box too large for one (non-finite or runaway poses) falls back to sorting the
// keys.
std::vector<std::uint64_t> BlockCellKeys(const Block& b,
                                         const std::vector<Eigen::Vector3f>& pw,
                                         float dmax,
                                         const CellGrid& grid) {
    constexpr std::int64_t kMaxBitmapCells = std::int64_t{1} << 22;
    std::vector<std::uint64_t> keys;
    if (b.p1 == b.p0) return keys;
    const bool finite_box = b.lo.allFinite() && b.hi.allFinite();
    const std::int64_t x0 = finite_box ? grid.Index(b.lo.x() - dmax) : 0;
    const std::int64_t y0 = finite_box ? grid.Index(b.lo.y() - dmax) : 0;
    const std::int64_t nx = finite_box ? grid.Index(b.hi.x() + dmax) - x0 + 1 : 0;
    const std::int64_t ny = finite_box ? grid.Index(b.hi.y() + dmax) - y0 + 1 : 0;
    if (finite_box && nx > 0 && ny > 0 && nx <= kMaxBitmapCells / ny) {
        std::vector<char> mark(static_cast<std::size_t>(nx * ny), 0);
        for (std::size_t k = b.p0; k < b.p1; ++k) {
            const Eigen::Vector3f& p = pw[k];
            for (const float dx : {-dmax, dmax}) {
                for (const float dy : {-dmax, dmax}) {
                    const std::int64_t ix = grid.Index(p.x() + dx) - x0;
                    const std::int64_t iy = grid.Index(p.y() + dy) - y0;
                    mark[static_cast<std::size_t>(iy * nx + ix)] = 1;
                }
            }
        }
        for (std::int64_t iy = 0; iy < ny; ++iy) {
            for (std::int64_t ix = 0; ix < nx; ++ix) {
                if (mark[static_cast<std::size_t>(iy * nx + ix)] != 0) {
                    keys.push_back(reg::CellKey(x0 + ix, y0 + iy));
                }
            }
        }
        return keys;
    }
    for (std::size_t k = b.p0; k < b.p1; ++k) {
        const Eigen::Vector3f& p = pw[k];
        for (const float dx : {-dmax, dmax}) {
            for (const float dy : {-dmax, dmax}) {
                const std::uint64_t key = grid.Key(p.x() + dx, p.y() + dy);
                if (keys.empty() || keys.back() != key) keys.push_back(key);
            }
        }
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    keys.shrink_to_fit();  // all blocks' lists live at once: keep what is used, not the peak
    return keys;
}

// Blocks per horizontal cell: a block is listed in every cell its points come within dmax of,
// so that a query visits only the trees that can hold its partner, not every tree whose
// bounding box it touches.
using CellBlocks = std::unordered_map<std::uint64_t, std::vector<std::uint32_t>>;
CellBlocks ListBlocksByCell(const std::vector<Block>& blocks,
                            const std::vector<Eigen::Vector3f>& pw,
                            float dmax,
                            const CellGrid& grid) {
    std::vector<std::vector<std::uint64_t>> block_cells(blocks.size());
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t bi) {
        block_cells[bi] = BlockCellKeys(blocks[bi], pw, dmax, grid);
    });
    CellBlocks cell_blocks;
    for (std::uint32_t bi = 0; bi < blocks.size(); ++bi) {
        for (const std::uint64_t key : block_cells[bi]) cell_blocks[key].push_back(bi);
    }
    return cell_blocks;
}

// The closest point to p in the partner blocks, within sqrt(best_d2) (dmax on entry).
struct Closest {
    bool found = false;
    float d2;                 // squared distance (the bound when not found)
    std::size_t index = 0;    // into pw
    std::uint32_t block = 0;  // its block
};
Closest ClosestInBlocks(const Eigen::Vector3f& p,
                        float dmax,
                        const std::vector<Block>& blocks,
                        const std::vector<std::uint32_t>& partners) {
    Closest c;
    c.d2 = dmax * dmax;
    for (const std::uint32_t bi : partners) {
        const Block& b = blocks[bi];
        if (!b.tree) continue;
        if ((p.array() < b.lo.array() - dmax).any() || (p.array() > b.hi.array() + dmax).any()) {
            continue;
        }
        std::size_t idx = 0;
        float d2 = 0;
        if (b.tree->NearestWithin(p, c.d2, &idx, &d2)) {
            c.d2 = d2;
            c.index = b.p0 + idx;
            c.block = bi;
            c.found = true;
        }
    }
    return c;
}

// Closest point of pw[q] among blocks entirely at least t_d away in time, within d_max.
// Also the pair score of the current poses: sqrt(mean(min(d, score_m)^2)) over the query
// points that have a partner block (time and bounding box), d the distance to the closest
// point (score_m when none is within the search distance); score_m <= the search distance.
std::vector<Pair> FindPairs(const Input& in,
                            const std::vector<Block>& blocks,
                            const std::vector<std::uint32_t>& slice_block,
                            const std::vector<Eigen::Vector3f>& pw,
                            const SlamConfig& cfg,
                            double score_m,
                            double* score) {
    const float dmax = static_cast<float>(cfg.max_pair_distance_m);
    const double score2 = score_m * score_m;
    std::vector<double> slice_sum(in.num_slices(), 0.0);
    std::vector<std::uint32_t> slice_count(in.num_slices(), 0);
    const double td = cfg.min_time_separation_s;
    const auto stride = static_cast<std::size_t>(cfg.query_stride);
    const CellGrid grid{std::max(2.0f * dmax, 2.0f)};
    const CellBlocks cell_blocks = ListBlocksByCell(blocks, pw, dmax, grid);
    tbb::enumerable_thread_specific<std::vector<Pair>> local;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, in.num_slices(), 64),
        [&](const tbb::blocked_range<std::size_t>& range) {
            static const std::vector<std::uint32_t> no_blocks;
            auto& out = local.local();
            const float sm = static_cast<float>(score_m);
            std::vector<std::uint32_t> partners;  // of the slice's queries in the cell `key`
            for (std::size_t s = range.begin(); s != range.end(); ++s) {
                const double t = in.t_s[s];
                std::uint64_t key = 0;
                bool have_key = false;
                for (std::size_t q = in.offset[s] + s % stride; q < in.offset[s + 1]; q += stride) {
                    const Eigen::Vector3f& p = pw[q];
                    // A slice's consecutive queries mostly share a cell: its partners once.
                    const std::uint64_t k = grid.Key(p.x(), p.y());
                    if (!have_key || k != key) {
                        key = k;
                        have_key = true;
                        const auto cb = cell_blocks.find(key);
                        PartnerBlocks(blocks,
                                      cb == cell_blocks.end() ? no_blocks : cb->second,
                                      slice_block[s],
                                      t,
                                      td,
                                      cfg.max_partner_passes,
                                      partners);
                    }
                    // Score bookkeeping: does a partner block's box come within score_m?
                    const bool candidate =
                        std::any_of(partners.begin(), partners.end(), [&](std::uint32_t bi) {
                            const Block& b = blocks[bi];
                            return !((p.array() < b.lo.array() - sm).any() ||
                                     (p.array() > b.hi.array() + sm).any());
                        });
                    const Closest c = ClosestInBlocks(p, dmax, blocks, partners);
                    if (candidate) {
                        slice_sum[s] +=
                            c.found ? std::min(static_cast<double>(c.d2), score2) : score2;
                        ++slice_count[s];
                    }
                    if (!c.found) continue;
                    Pair pr;
                    pr.slice_a = static_cast<std::uint32_t>(s);
                    pr.c.query = q;
                    pr.block_a = slice_block[s];
                    pr.c.target = c.index;
                    pr.block_b = c.block;
                    const auto it = std::upper_bound(in.offset.begin(), in.offset.end(), c.index);
                    pr.slice_b = static_cast<std::uint32_t>(it - in.offset.begin() - 1);
                    out.push_back(pr);
                }
            }
        });
    double sum = 0, count = 0;
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        sum += slice_sum[s];
        count += slice_count[s];
    }
    *score = count > 0 ? std::sqrt(sum / count) : 0.0;
    std::vector<Pair> pairs;
    for (auto& v : local) pairs.insert(pairs.end(), v.begin(), v.end());
    // Thread order is arbitrary; sort so that the sums below see the same order every run.
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
        return a.c.query < b.c.query;
    });
    return pairs;
}

// Unit normal of the points around pw[k] in its block (smallest eigenvector of the local
// covariance of its num_neighbours nearest); zero if fewer than 3 neighbours.
// Normals of the points items[i] = (global point index, block), each fitted to the current
// world positions of its normal_neighbours nearest points of its own block. The neighbours are
// searched once per run and kept in the block: a block is 15 s of one pass, which SLAM moves as
// a whole or bends smoothly, so its points keep their neighbours while their positions (and
// normals) change (bejanca: the k-NN search was 14 % of SLAM's CPU, a search per iteration).
// Zero where no plane fits.
std::vector<Eigen::Vector3f> LocalNormals(
    std::vector<Block>& blocks,
    const std::vector<Eigen::Vector3f>& pw,
    const std::vector<std::pair<std::size_t, std::uint32_t>>& items,
    int num_neighbours) {
    const auto k = static_cast<std::size_t>(num_neighbours);
    // Slots for the points seen for the first time (sequential: it grows the blocks' tables).
    std::vector<std::vector<std::uint32_t>> fresh(blocks.size());
    for (const auto& [point, bi] : items) {
        const Block& b = blocks[bi];
        const auto local = static_cast<std::uint32_t>(point - b.p0);
        if (b.NeighbourSlot(local) == Block::kNoSlot) fresh[bi].push_back(local);
    }
    std::vector<std::pair<std::size_t, std::uint32_t>> todo;  // (point, block)
    for (std::uint32_t bi = 0; bi < blocks.size(); ++bi) {
        std::vector<std::uint32_t>& f = fresh[bi];
        if (f.empty()) continue;
        std::sort(f.begin(), f.end());
        f.erase(std::unique(f.begin(), f.end()), f.end());
        Block& b = blocks[bi];
        auto& slots = b.neighbour_slots;
        const std::size_t old_size = slots.size();
        auto next = static_cast<std::uint32_t>(old_size);
        // Grown to the exact size (reserve allocates what it is asked): push_back's doubling
        // would leave up to half of each table unused for the rest of the run.
        slots.reserve(old_size + f.size());
        for (const std::uint32_t local : f) {
            slots.emplace_back(local, next++);
            todo.emplace_back(b.p0 + local, bi);
        }
        std::inplace_merge(
            slots.begin(), slots.begin() + static_cast<std::ptrdiff_t>(old_size), slots.end());
        const std::size_t words = std::size_t{next} * NeighbourPacking(b, k).words;
        b.neighbours.reserve(words);
        b.neighbours.resize(words, 0);
    }
    tbb::parallel_for(std::size_t{0}, todo.size(), [&](std::size_t i) {
        const auto [point, bi] = todo[i];
        Block& b = blocks[bi];
        std::size_t idx[kMaxNormalNeighbours];
        float d2[kMaxNormalNeighbours];
        const std::size_t n = b.tree->Nearest(pw[point], k, idx, d2);
        const std::uint32_t slot = b.NeighbourSlot(static_cast<std::uint32_t>(point - b.p0));
        const NeighbourPacking pk(b, k);
        pk.Pack(idx, n, b.neighbours.data() + std::size_t{slot} * pk.words);
    });
    std::vector<Eigen::Vector3f> normals(items.size());
    tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) {
        const auto [point, bi] = items[i];
        const Block& b = blocks[bi];
        const std::uint32_t slot = b.NeighbourSlot(static_cast<std::uint32_t>(point - b.p0));
        const NeighbourPacking pk(b, k);
        std::uint32_t nb[kMaxNormalNeighbours];
        pk.Unpack(b.neighbours.data() + std::size_t{slot} * pk.words, nb);
        reg::MomentAccumulator m;
        for (std::size_t j = 0; j < k && nb[j] != pk.none; ++j)
            m.Add(pw[b.p0 + nb[j]].cast<double>());
        const reg::PlaneFit f = reg::FitPlane(m);
        normals[i] = f.valid ? Eigen::Vector3f(f.normal.cast<float>()) : Eigen::Vector3f::Zero();
    });
    return normals;
}

}  // namespace

// ---- consistency score ----------------------------------------------------------------------

// Plane-fit vertical RMS over grid cells that hold query points of passes at least t_d apart:
// per cell, z = a + b x + c y by least squares; score = sqrt(sum SSR / sum (n - 3)).
namespace {

// The plane-fit cells of the consistency score: per cell of score_cell_m, the least-squares
// plane z - z0 = beta . (1, dx, dy) of the points of every slice in it, kept where at least six
// points of passes min_time_separation_s apart fall. z0 is the cell's first z: the sums then
// hold heights of a few metres at most, so the residual sum zz - b . beta keeps its digits at
// any |z| (with raw heights of 1e3 m and millimetre residuals it would cancel to noise).
struct ScoreCell {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    double z0 = std::numeric_limits<double>::quiet_NaN();
    double zz = 0;
    double t_min = std::numeric_limits<double>::max();
    double t_max = std::numeric_limits<double>::lowest();
    int n = 0;
    bool used = false;
    Eigen::Vector3d beta = Eigen::Vector3d::Zero();
};

template <class F>
void ForEachScorePoint(const Input& in, const std::vector<Pose>& T, const SlamConfig& cfg, F&& f) {
    const double h = cfg.score_cell_m;
    const auto stride = static_cast<std::size_t>(cfg.query_stride);
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        for (std::size_t q = in.offset[s] + s % stride; q < in.offset[s + 1]; q += stride) {
            const Eigen::Vector3d p = T[s] * in.points[q].cast<double>();
            const double fx = std::floor(p.x() / h), fy = std::floor(p.y() / h);
            const std::uint64_t key =
                reg::CellKey(static_cast<std::int64_t>(fx), static_cast<std::int64_t>(fy));
            const Eigen::Vector3d u(1.0, p.x() - (fx + 0.5) * h, p.y() - (fy + 0.5) * h);
            f(s, key, u, p.z());
        }
    }
}

std::unordered_map<std::uint64_t, ScoreCell> ScoreCells(const Input& in,
                                                        const std::vector<Pose>& T,
                                                        const SlamConfig& cfg) {
    std::unordered_map<std::uint64_t, ScoreCell> cells;
    ForEachScorePoint(
        in, T, cfg, [&](std::size_t s, std::uint64_t key, const Eigen::Vector3d& u, double z) {
            ScoreCell& c = cells[key];
            if (c.n == 0) c.z0 = z;
            const double dz = z - c.z0;
            c.A += u * u.transpose();
            c.b += u * dz;
            c.zz += dz * dz;
            c.t_min = std::min(c.t_min, in.t_s[s]);
            c.t_max = std::max(c.t_max, in.t_s[s]);
            ++c.n;
        });
    for (auto& [key, c] : cells) {
        if (c.n < 6 || c.t_max - c.t_min < cfg.min_time_separation_s) continue;
        Eigen::LDLT<Eigen::Matrix3d> ldlt(c.A);
        if (ldlt.info() != Eigen::Success) continue;
        c.beta = ldlt.solve(c.b);
        c.used = c.beta.allFinite();
    }
    return cells;
}

}  // namespace

namespace {

double ScoreOf(const std::unordered_map<std::uint64_t, ScoreCell>& cells) {
    double ssr = 0, dof = 0;
    for (const auto& [key, c] : cells) {
        if (!c.used) continue;
        const double v = std::max(0.0, c.zz - c.b.dot(c.beta));
        if (!std::isfinite(v)) continue;
        ssr += v;
        dof += c.n - 3;
    }
    return dof > 0 ? std::sqrt(ssr / dof) : 0.0;
}

}  // namespace

double ConsistencyScore(const Input& in, const std::vector<Pose>& T, const SlamConfig& cfg) {
    return ScoreOf(ScoreCells(in, T, cfg));
}

Consistency ConsistencyBySlice(const Input& in, const std::vector<Pose>& T, const SlamConfig& cfg) {
    const auto cells = ScoreCells(in, T, cfg);
    std::vector<double> ss(in.num_slices(), 0.0);
    std::vector<std::int64_t> n(in.num_slices(), 0);
    ForEachScorePoint(
        in, T, cfg, [&](std::size_t s, std::uint64_t key, const Eigen::Vector3d& u, double z) {
            const auto it = cells.find(key);
            if (it == cells.end() || !it->second.used) return;
            const double r = (z - it->second.z0) - u.dot(it->second.beta);
            ss[s] += r * r;
            ++n[s];
        });
    Consistency out;
    out.score_m = ScoreOf(cells);
    out.by_slice_m.assign(in.num_slices(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t s = 0; s < out.by_slice_m.size(); ++s) {
        if (n[s] > 0) out.by_slice_m[s] = std::sqrt(ss[s] / static_cast<double>(n[s]));
    }
    return out;
}

Search SearchPairs(const Input& in,
                   const std::vector<Pose>& T,
                   SlamStage stage,
                   double search_m,
                   std::vector<Block>& blocks,
                   const std::vector<std::uint32_t>& slice_block,
                   std::vector<Eigen::Vector3f>& pw,
                   const SlamConfig& cfg,
                   SlamResult& res) {
    auto t0 = Clock::now();
    tbb::parallel_for(std::size_t{0}, in.num_slices(), [&](std::size_t s) {
        const Eigen::Matrix3f R = T[s].linear().cast<float>();
        const Eigen::Vector3f t = T[s].translation().cast<float>();
        for (std::size_t k = in.offset[s]; k < in.offset[s + 1]; ++k) pw[k] = R * in.points[k] + t;
    });
    BuildTrees(blocks, pw);
    res.timings.trees_s += Seconds(t0);
    t0 = Clock::now();
    SlamConfig it_cfg = cfg;
    it_cfg.max_pair_distance_m = search_m;
    Search out;
    out.pairs = FindPairs(in, blocks, slice_block, pw, it_cfg, cfg.max_pair_distance_m, &out.score);
    std::vector<Pair>& pairs = out.pairs;
    if (stage == SlamStage::kRigid) {
        // Section graph: keep links with enough pairs (overlap heuristic of the paper).
        std::unordered_map<std::uint64_t, std::size_t> link;
        auto key = [](const Pair& pr) { return reg::UnorderedPairKey(pr.block_a, pr.block_b); };
        for (const Pair& pr : pairs) ++link[key(pr)];
        std::erase_if(pairs, [&](const Pair& pr) {
            return link[key(pr)] < static_cast<std::size_t>(cfg.min_section_link_pairs);
        });
        for (const auto& [k, c] : link) {
            if (c >= static_cast<std::size_t>(cfg.min_section_link_pairs)) ++out.num_links;
        }
    }
    if (cfg.correspondence != CorrespondenceType::kPointToPoint) {
        // A point is the target of several pairs: its normal is fitted once.
        std::vector<std::pair<std::size_t, std::uint32_t>> targets(pairs.size());
        for (std::size_t k = 0; k < pairs.size(); ++k)
            targets[k] = {pairs[k].c.target, pairs[k].block_b};
        std::sort(targets.begin(), targets.end());
        targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
        const std::vector<Eigen::Vector3f> target_normal =
            LocalNormals(blocks, pw, targets, cfg.normal_neighbours);
        std::vector<Eigen::Vector3f> query_normal;
        if (cfg.correspondence == CorrespondenceType::kGicp) {
            std::vector<std::pair<std::size_t, std::uint32_t>> queries(pairs.size());
            for (std::size_t k = 0; k < pairs.size(); ++k)
                queries[k] = {pairs[k].c.query, pairs[k].block_a};
            query_normal = LocalNormals(blocks, pw, queries, cfg.normal_neighbours);
        }
        tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t k) {
            Pair& pr = pairs[k];
            const auto it = std::lower_bound(
                targets.begin(), targets.end(), std::make_pair(pr.c.target, pr.block_b));
            pr.c.target_normal = target_normal[static_cast<std::size_t>(it - targets.begin())];
            if (!query_normal.empty()) pr.c.query_normal = query_normal[k];
        });
        std::erase_if(pairs, [&](const Pair& pr) {
            return pr.c.target_normal.isZero() ||
                   (cfg.correspondence == CorrespondenceType::kGicp && pr.c.query_normal.isZero());
        });
    }
    // The section graph the pairs make (SlamIteration reports it).
    std::vector<std::uint64_t> links(pairs.size());
    for (std::size_t k = 0; k < pairs.size(); ++k)
        links[k] = reg::UnorderedPairKey(pairs[k].block_a, pairs[k].block_b);
    std::sort(links.begin(), links.end());
    links.erase(std::unique(links.begin(), links.end()), links.end());
    std::vector<std::size_t> partners(blocks.size(), 0);
    for (const std::uint64_t l : links) {
        const auto a = static_cast<std::uint32_t>(l >> 32), b = static_cast<std::uint32_t>(l);
        ++partners[a];
        if (b != a) ++partners[b];
    }
    out.num_section_pairs = links.size();
    SlamMemory m;
    m.points_bytes = in.points.capacity() * sizeof(Eigen::Vector3f);
    m.world_points_bytes = pw.capacity() * sizeof(Eigen::Vector3f);
    for (const Block& b : blocks) {
        if (b.tree) m.trees_bytes += b.tree->memory_bytes();
        m.neighbour_bytes += b.neighbours.capacity() * sizeof(std::uint64_t) +
                             b.neighbour_slots.capacity() * sizeof(b.neighbour_slots[0]);
    }
    m.pairs_bytes = pairs.capacity() * sizeof(Pair);
    m.total_bytes =
        m.points_bytes + m.world_points_bytes + m.trees_bytes + m.neighbour_bytes + m.pairs_bytes;
    if (m.total_bytes > res.memory.total_bytes) res.memory = m;
    out.max_section_partners =
        partners.empty() ? 0 : *std::max_element(partners.begin(), partners.end());
    res.timings.search_s += Seconds(t0);
    return out;
}

}  // namespace pitmap::proc::slam::detail
