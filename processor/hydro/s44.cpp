// SPDX-License-Identifier: MIT
#include "processor/hydro/s44.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <unordered_map>
#include <utility>

namespace pitmap::proc::hydro {

namespace {

constexpr double kPi = 3.14159265358979323846;

// S-44 Ed. 6.1.0 Table 1 (the header's table).
const S44Limits kLimits[kNumS44Orders] = {
    // THU c, k; TVU a, b; feature, beyond-limit fraction, limit depth; coverage; full
    {0.5, 0.0, 0.15, 0.0075, 0.5, 0.0, 0.0, 200, true},
    {2.0, 0.0, 0.25, 0.0075, 1.0, 0.0, 0.0, 100, true},
    {5.0, 0.05, 0.5, 0.013, 2.0, 0.10, 40.0, 100, true},
    {5.0, 0.05, 0.5, 0.013, 0.0, 0.0, 0.0, 5, false},
    {20.0, 0.10, 1.0, 0.023, 0.0, 0.0, 0.0, 5, false},
};

// Angle difference of two headings as lines (modulo 180 deg), in [0, 90] deg.
double LineAngleDeg(double a_rad, double b_rad) {
    double d = std::fmod(std::abs(a_rad - b_rad) * 180.0 / kPi, 180.0);
    if (d > 90) d = 180 - d;
    return d;
}

}  // namespace

const char* ToString(S44Order o) {
    switch (o) {
        case S44Order::kExclusive:
            return "exclusive";
        case S44Order::kSpecial:
            return "special";
        case S44Order::kOrder1a:
            return "1a";
        case S44Order::kOrder1b:
            return "1b";
        case S44Order::kOrder2:
            return "2";
    }
    return "?";
}

bool S44OrderFromString(const std::string& name, S44Order* o) {
    for (int k = 0; k < kNumS44Orders; ++k) {
        if (name == ToString(static_cast<S44Order>(k))) {
            *o = static_cast<S44Order>(k);
            return true;
        }
    }
    return false;
}

const S44Limits& LimitsOf(S44Order o) {
    return kLimits[static_cast<int>(o)];
}

double S44Limits::Tvu(double d) const {
    return std::sqrt(tvu_a_m * tvu_a_m + tvu_b * tvu_b * d * d);
}
double S44Limits::Thu(double d) const {
    return thu_constant_m + thu_depth_fraction * d;
}
double S44Limits::FeatureSize(double d) const {
    if (feature_size_m <= 0) return 0;
    if (feature_depth_limit_m > 0 && d > feature_depth_limit_m) return feature_depth_fraction * d;
    return feature_size_m;
}

std::vector<std::string> S44Config::Validate() const {
    std::vector<std::string> p;
    if (min_holiday_nodes < 1) p.push_back("s44.min_holiday_nodes must be >= 1");
    if (!(min_time_separation_s >= 0)) p.push_back("s44.min_time_separation_s must be >= 0");
    if (!(crossing_angle_deg > 0 && crossing_angle_deg <= 90)) {
        p.push_back("s44.crossing_angle_deg must be in (0, 90]");
    }
    if (!(crossline_cell_m >= 0)) p.push_back("s44.crossline_cell_m must be >= 0");
    if (min_reference_soundings < 1) p.push_back("s44.min_reference_soundings must be >= 1");
    return p;
}

int StrictestOrderMet(const S44Result& r, double share) {
    for (int o = 0; o < kNumS44Orders; ++o) {
        if (r.soundings > 0 && r.soundings_within_tvu[o] >= share &&
            r.soundings_within_thu[o] >= share) {
            return o;
        }
    }
    return -1;
}

namespace {

// The capture distance of a sounding at depth_m (CUBE's rule, S44Grid), m.
double CaptureDistance(const S44Grid& g, double depth_m) {
    return std::clamp(g.capture_depth_fraction * std::max(depth_m, 0.0),
                      g.capture_min_res * g.resolution_m,
                      g.capture_max_res * g.resolution_m);
}

// The compliance's sums over the soundings, in their order, and the nodes' THU sums.
struct ComplianceSums {
    std::array<std::int64_t, kNumS44Orders> tvu{}, thu{}, both{};
    std::int64_t used = 0;
    std::vector<float> node_thu_sum;
    std::vector<std::int32_t> node_thu_n;
};

// The soundings of `s` (a block of the survey's, in order) added to the compliance's sums.
void ComplianceAdd(const S44Soundings& s, const S44Grid& g, ComplianceSums& c) {
    const std::size_t n = s.z.size();
    // Node THU: the mean THU of the soundings within their capture distance of the node, the
    // soundings CUBE offered it (S44Grid). The nearest node alone would leave a THU-less node
    // wherever the soundings are sparser than the nodes (the outer beams), and such nodes
    // failed every order alike (issue 39: 89.1 % for every order on the demo).
    for (std::size_t j = 0; j < n; ++j) {
        const double d = s.depth_m[j];
        if (!std::isfinite(d) || !std::isfinite(s.tvu_95_m[j]) || !std::isfinite(s.thu_95_m[j])) {
            continue;
        }
        ++c.used;
        for (int o = 0; o < kNumS44Orders; ++o) {
            const bool v = s.tvu_95_m[j] <= kLimits[o].Tvu(d);
            const bool h = s.thu_95_m[j] <= kLimits[o].Thu(d);
            c.tvu[o] += v;
            c.thu[o] += h;
            c.both[o] += v && h;
        }
        if (g.nx <= 0 || g.ny <= 0 || !(g.resolution_m > 0)) continue;
        const double rc = CaptureDistance(g, d);
        const double u = (s.x[j] - g.x0) / g.resolution_m;
        const double v = (s.y[j] - g.y0) / g.resolution_m;
        const double ru = rc / g.resolution_m;
        const long i0 = std::max(0L, static_cast<long>(std::ceil(u - ru)));
        const long i1 =
            std::min(static_cast<long>(g.nx) - 1, static_cast<long>(std::floor(u + ru)));
        const long k0 = std::max(0L, static_cast<long>(std::ceil(v - ru)));
        const long k1 =
            std::min(static_cast<long>(g.ny) - 1, static_cast<long>(std::floor(v + ru)));
        for (long k = k0; k <= k1; ++k) {
            for (long i = i0; i <= i1; ++i) {
                const double du = static_cast<double>(i) - u;
                const double dv = static_cast<double>(k) - v;
                if (du * du + dv * dv > ru * ru) continue;
                const std::size_t q =
                    static_cast<std::size_t>(k) * g.nx + static_cast<std::size_t>(i);
                c.node_thu_sum[q] += s.thu_95_m[j];
                ++c.node_thu_n[q];
            }
        }
    }
}

// The shares within each order's limits, of the soundings and of the nodes.
void ComplianceFinish(const S44Grid& g, const ComplianceSums& c, S44Result& r) {
    std::array<std::int64_t, kNumS44Orders> ntvu{}, nthu{};
    std::int64_t nodes = 0, nodes_thu = 0;
    for (std::size_t q = 0; q < g.elevation_m.size(); ++q) {
        const double d = g.depth_m[q];
        if (!std::isfinite(g.elevation_m[q]) || !std::isfinite(d) ||
            !std::isfinite(g.uncertainty_m[q])) {
            continue;
        }
        ++nodes;
        for (int o = 0; o < kNumS44Orders; ++o) ntvu[o] += g.uncertainty_m[q] <= kLimits[o].Tvu(d);
        if (c.node_thu_n[q] == 0) continue;
        ++nodes_thu;
        const double node_thu = c.node_thu_sum[q] / static_cast<double>(c.node_thu_n[q]);
        for (int o = 0; o < kNumS44Orders; ++o) nthu[o] += node_thu <= kLimits[o].Thu(d);
    }
    const std::int64_t used = c.used;
    r.soundings = used;
    r.nodes = nodes;
    r.nodes_without_thu = nodes - nodes_thu;
    for (int o = 0; o < kNumS44Orders; ++o) {
        const double sn = used > 0 ? static_cast<double>(used) : 1.0;
        const double nn = nodes > 0 ? static_cast<double>(nodes) : 1.0;
        const double nh = nodes_thu > 0 ? static_cast<double>(nodes_thu) : 1.0;
        r.soundings_within_tvu[o] = static_cast<double>(c.tvu[o]) / sn;
        r.soundings_within_thu[o] = static_cast<double>(c.thu[o]) / sn;
        r.soundings_within_both[o] = static_cast<double>(c.both[o]) / sn;
        r.nodes_within_tvu[o] = static_cast<double>(ntvu[o]) / nn;
        r.nodes_within_thu[o] = static_cast<double>(nthu[o]) / nh;
    }
}

// What an empty node of the grid is: inside the survey (a gap) or outside it.
enum class NodeClass : std::uint8_t {
    kCovered = 0,
    kGap = 1,      // empty, not reached from the border
    kOutside = 2,  // empty, reached from the border through empty nodes
};

// Every node's class: the outside grows from the grid's border through 4-neighbours (a
// diagonal between two covered nodes is no way out); the empty nodes it does not reach are gaps.
std::vector<NodeClass> ClassifyNodes(const S44Grid& g) {
    const int nx = g.nx, ny = g.ny;
    std::vector<NodeClass> cls(g.elevation_m.size());
    for (std::size_t q = 0; q < cls.size(); ++q)
        cls[q] = std::isfinite(g.elevation_m[q]) ? NodeClass::kCovered : NodeClass::kGap;
    std::vector<std::size_t> stack;
    const auto seed = [&](int i, int j) {
        const std::size_t q = static_cast<std::size_t>(j) * nx + i;
        if (cls[q] == NodeClass::kGap) {
            cls[q] = NodeClass::kOutside;
            stack.push_back(q);
        }
    };
    for (int i = 0; i < nx; ++i) {
        seed(i, 0);
        seed(i, ny - 1);
    }
    for (int j = 0; j < ny; ++j) {
        seed(0, j);
        seed(nx - 1, j);
    }
    while (!stack.empty()) {
        const std::size_t q = stack.back();
        stack.pop_back();
        const int i = static_cast<int>(q % nx), j = static_cast<int>(q / nx);
        if (i > 0) seed(i - 1, j);
        if (i + 1 < nx) seed(i + 1, j);
        if (j > 0) seed(i, j - 1);
        if (j + 1 < ny) seed(i, j + 1);
    }
    return cls;
}

// The side, in nodes, of the largest square of gap nodes ending (top-right) at each node: a
// dynamic programme over the rows, side(i, j) = 1 + min(side(i-1, j), side(i, j-1),
// side(i-1, j-1)) on gap nodes.
std::vector<std::int32_t> LargestGapSquares(const std::vector<NodeClass>& cls, int nx, int ny) {
    const auto at = [nx](int i, int j) { return static_cast<std::size_t>(j) * nx + i; };
    std::vector<std::int32_t> side(cls.size(), 0);
    for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
            const std::size_t q = at(i, j);
            if (cls[q] != NodeClass::kGap) continue;
            const int left = i > 0 ? side[at(i - 1, j)] : 0;
            const int below = j > 0 ? side[at(i, j - 1)] : 0;
            const int diagonal = i > 0 && j > 0 ? side[at(i - 1, j - 1)] : 0;
            side[q] = 1 + std::min({left, below, diagonal});
        }
    }
    return side;
}

// One gap: its nodes, bounding box (node indices) and largest square.
struct Gap {
    std::vector<std::size_t> nodes;
    int i_lo = 0, i_hi = -1, j_lo = 0, j_hi = -1;
    int square_side = 0;            // nodes
    std::size_t square_corner = 0;  // the top-right (largest i, j) node of the square
};

// The 8-connected gap that holds node `first`, its nodes marked `id` in `component`.
Gap TraceGap(std::size_t first,
             std::int32_t id,
             const std::vector<NodeClass>& cls,
             const std::vector<std::int32_t>& square_side,
             int nx,
             int ny,
             std::vector<std::int32_t>& component) {
    Gap gap;
    gap.i_lo = nx;
    gap.j_lo = ny;
    gap.square_corner = first;
    std::vector<std::size_t> stack(1, first);
    component[first] = id;
    while (!stack.empty()) {
        const std::size_t q = stack.back();
        stack.pop_back();
        gap.nodes.push_back(q);
        const int i = static_cast<int>(q % nx), j = static_cast<int>(q / nx);
        gap.i_lo = std::min(gap.i_lo, i);
        gap.i_hi = std::max(gap.i_hi, i);
        gap.j_lo = std::min(gap.j_lo, j);
        gap.j_hi = std::max(gap.j_hi, j);
        if (square_side[q] > gap.square_side) {
            gap.square_side = square_side[q];
            gap.square_corner = q;
        }
        for (int dj = -1; dj <= 1; ++dj) {
            for (int di = -1; di <= 1; ++di) {
                const int a = i + di, b = j + dj;
                if (a < 0 || b < 0 || a >= nx || b >= ny) continue;
                const std::size_t p = static_cast<std::size_t>(b) * nx + a;
                if (cls[p] == NodeClass::kGap && component[p] < 0) {
                    component[p] = id;
                    stack.push_back(p);
                }
            }
        }
    }
    return gap;
}

// A gap as a holiday: the centre of its largest square, its bounding box and area, in metres.
S44Holiday HolidayOf(const Gap& gap, const S44Grid& g) {
    const double res = g.resolution_m;
    const int corner_i = static_cast<int>(gap.square_corner % g.nx);
    const int corner_j = static_cast<int>(gap.square_corner / g.nx);
    S44Holiday h;
    h.x = g.x0 + (corner_i - (gap.square_side - 1) / 2.0) * res;
    h.y = g.y0 + (corner_j - (gap.square_side - 1) / 2.0) * res;
    h.x_min = g.x0 + (gap.i_lo - 0.5) * res;
    h.x_max = g.x0 + (gap.i_hi + 0.5) * res;
    h.y_min = g.y0 + (gap.j_lo - 0.5) * res;
    h.y_max = g.y0 + (gap.j_hi + 0.5) * res;
    h.nodes = static_cast<std::int64_t>(gap.nodes.size());
    h.area_m2 = static_cast<double>(h.nodes) * res * res;
    h.largest_square_m = gap.square_side * res;
    return h;
}

// The coverage check: the gaps inside the survey (empty nodes not reached from the border), of
// which those holding a square of the order's feature size (and min_holiday_nodes) are holidays
// where the order asks for full coverage; the holiday map (0 covered, 1 gap, 2 holiday, NaN
// outside) and the coverage share.
void Holidays(const S44Grid& g, const S44Config& c, double median_depth_m, S44Result& r) {
    const std::size_t num_nodes = g.elevation_m.size();
    r.holiday_map.assign(num_nodes, std::numeric_limits<float>::quiet_NaN());
    if (num_nodes == 0) return;
    const S44Limits& limits = LimitsOf(c.order);
    r.feature_size_m = limits.full_coverage ? limits.FeatureSize(median_depth_m) : 0.0;
    const std::vector<NodeClass> cls = ClassifyNodes(g);
    const std::vector<std::int32_t> square_side = LargestGapSquares(cls, g.nx, g.ny);
    const int min_side = std::max(
        c.min_holiday_nodes, static_cast<int>(std::ceil(r.feature_size_m / g.resolution_m - 1e-9)));
    std::vector<std::int32_t> component(num_nodes, -1);
    std::int64_t in_gaps = 0, covered = 0;
    std::vector<S44Holiday> holidays;
    for (std::size_t q = 0; q < num_nodes; ++q) {
        if (cls[q] == NodeClass::kCovered) ++covered;
        if (cls[q] != NodeClass::kGap || component[q] >= 0) continue;
        const auto id = static_cast<std::int32_t>(r.gaps++);
        const Gap gap = TraceGap(q, id, cls, square_side, g.nx, g.ny, component);
        in_gaps += static_cast<std::int64_t>(gap.nodes.size());
        const bool holiday = limits.full_coverage && gap.square_side >= min_side;
        for (std::size_t node : gap.nodes) r.holiday_map[node] = holiday ? 2.0f : 1.0f;
        if (holiday) holidays.push_back(HolidayOf(gap, g));
    }
    for (std::size_t q = 0; q < num_nodes; ++q) {
        if (cls[q] == NodeClass::kCovered) r.holiday_map[q] = 0.0f;
    }
    std::sort(holidays.begin(), holidays.end(), [](const auto& a, const auto& b) {
        return a.nodes > b.nodes;
    });
    r.holidays = std::move(holidays);
    r.nodes_in_gaps = in_gaps;
    r.nodes_survey_area = covered + in_gaps;
    r.coverage_share =
        r.nodes_survey_area > 0 ? static_cast<double>(covered) / r.nodes_survey_area : 0.0;
}

constexpr double kBlockS = 20.0;
constexpr int kHeadingBins = 12;  // 15 deg, modulo 180 deg
constexpr int kAngleBins = 7;     // 0-10 ... 60-70 deg

int HeadingBin(double yaw) {
    double d = std::fmod(yaw * 180.0 / kPi, 180.0);
    if (d < 0) d += 180.0;
    return std::min(kHeadingBins - 1, static_cast<int>(d / (180.0 / kHeadingBins)));
}

// The crossline check's state: the earlier soundings pooled per cell, time block and heading
// bin (first pass), then the comparisons' sums (second pass), in the soundings' order.
struct Crossline {
    struct Acc {
        double sz = 0, sx = 0, sy = 0, st = 0;
        std::int32_t n = 0;
        std::int32_t key = 0;  // time block * kHeadingBins + heading bin
    };
    bool on = false;
    double cell = 0, t0 = 0;
    std::int64_t ncx = 0;
    std::unordered_map<std::int64_t, std::vector<Acc>> cells;
    std::array<double, kAngleBins> bs{}, bss{};
    std::array<std::int64_t, kAngleBins> bn{}, bin_ok{};
    double sum = 0, sumsq = 0;
    std::int64_t n = 0, ok = 0;

    Crossline(const S44Grid& g, const S44Config& c, const std::vector<double>& ping_t_s) {
        cell = c.crossline_cell_m > 0 ? c.crossline_cell_m : 2.0 * g.resolution_m;
        on = cell > 0 && !ping_t_s.empty();
        if (!on) return;
        t0 = ping_t_s.front();
        ncx = static_cast<std::int64_t>(std::ceil(g.nx * g.resolution_m / cell)) + 2;
    }
    std::int64_t CellOf(const S44Grid& g, double x, double y) const {
        const auto i = static_cast<std::int64_t>(std::floor((x - g.x0) / cell)) + 1;
        const auto j = static_cast<std::int64_t>(std::floor((y - g.y0) / cell)) + 1;
        return j * ncx + i;
    }
};

// First pass: the soundings of `s` (a block, in order) pooled into their cells.
void CrosslineCells(const S44Soundings& s,
                    const S44Grid& g,
                    const std::vector<double>& ping_t_s,
                    const std::vector<double>& ping_yaw_rad,
                    Crossline& x) {
    if (!x.on) return;
    for (std::size_t j = 0; j < s.z.size(); ++j) {
        if (!std::isfinite(s.z[j])) continue;
        const std::uint32_t p = s.ping[j];
        const auto key = static_cast<std::int32_t>(
            static_cast<std::int32_t>((ping_t_s[p] - x.t0) / kBlockS) * kHeadingBins +
            HeadingBin(ping_yaw_rad[p]));
        auto& v = x.cells[x.CellOf(g, s.x[j], s.y[j])];
        auto it = std::find_if(
            v.begin(), v.end(), [key](const Crossline::Acc& e) { return e.key == key; });
        if (it == v.end()) {
            v.push_back(Crossline::Acc{});
            it = v.end() - 1;
            it->key = key;
        }
        it->sz += s.z[j];
        it->sx += s.x[j];
        it->sy += s.y[j];
        it->st += ping_t_s[p];
        ++it->n;
    }
}

// The DEM's gradient at a point (central differences of the elevation; 0 where missing).
void DemGradient(const S44Grid& g, double x, double y, double* gx, double* gy) {
    *gx = *gy = 0;
    const long i = std::lround((x - g.x0) / g.resolution_m);
    const long k = std::lround((y - g.y0) / g.resolution_m);
    if (i < 1 || k < 1 || i + 1 >= g.nx || k + 1 >= g.ny) return;
    auto e = [&](long a, long b) {
        return g.elevation_m[static_cast<std::size_t>(b) * g.nx + static_cast<std::size_t>(a)];
    };
    const double ex = e(i + 1, k) - e(i - 1, k), ey = e(i, k + 1) - e(i, k - 1);
    if (std::isfinite(ex)) *gx = ex / (2 * g.resolution_m);
    if (std::isfinite(ey)) *gy = ey / (2 * g.resolution_m);
}

// Second pass: each sounding of `s` (a block, in order) against the earlier crossing
// soundings of its cell.
void CrosslineCompare(const S44Soundings& s,
                      const S44Grid& g,
                      const S44Config& c,
                      const std::vector<double>& ping_t_s,
                      const std::vector<double>& ping_yaw_rad,
                      Crossline& x) {
    if (!x.on) return;
    const S44Limits& lim = LimitsOf(c.order);
    for (std::size_t j = 0; j < s.z.size(); ++j) {
        if (!std::isfinite(s.z[j])) continue;
        const auto it = x.cells.find(x.CellOf(g, s.x[j], s.y[j]));
        if (it == x.cells.end()) continue;
        const double t = ping_t_s[s.ping[j]];
        const double yaw = ping_yaw_rad[s.ping[j]];
        Crossline::Acc ref;
        for (const Crossline::Acc& a : it->second) {
            const double bin_yaw = ((a.key % kHeadingBins) + 0.5) * (kPi / kHeadingBins);
            if (a.st / a.n > t - c.min_time_separation_s ||
                LineAngleDeg(bin_yaw, yaw) < c.crossing_angle_deg) {
                continue;
            }
            ref.sz += a.sz;
            ref.sx += a.sx;
            ref.sy += a.sy;
            ref.n += a.n;
        }
        if (ref.n < c.min_reference_soundings) continue;
        const double mx = ref.sx / ref.n, my = ref.sy / ref.n;
        double gx = 0, gy = 0;
        DemGradient(g, s.x[j], s.y[j], &gx, &gy);
        const double zref = ref.sz / ref.n + gx * (s.x[j] - mx) + gy * (s.y[j] - my);
        const double d = s.z[j] - zref;
        const bool within = std::abs(d) <= lim.Tvu(s.depth_m[j]);
        x.sum += d;
        x.sumsq += d * d;
        ++x.n;
        x.ok += within;
        const int b =
            std::clamp(static_cast<int>(std::abs(s.angle_deg[j]) / 10.0), 0, kAngleBins - 1);
        x.bs[b] += d;
        x.bss[b] += d * d;
        ++x.bn[b];
        x.bin_ok[b] += within;
    }
}

void CrosslineFinish(const Crossline& x, S44Result& r) {
    r.crossline_compared = x.n;
    if (x.n == 0) return;
    const double nn = static_cast<double>(x.n);
    r.crossline_mean_m = x.sum / nn;
    r.crossline_rms_m = std::sqrt(x.sumsq / nn);
    r.crossline_sd_m =
        std::sqrt(std::max(0.0, x.sumsq / nn - r.crossline_mean_m * r.crossline_mean_m));
    r.crossline_within_tvu = static_cast<double>(x.ok) / nn;
    for (int b = 0; b < kAngleBins; ++b) {
        if (x.bn[b] == 0) continue;
        S44AngleBin a;
        a.angle_lo_deg = 10.0 * b;
        a.angle_hi_deg = 10.0 * (b + 1);
        a.count = x.bn[b];
        const double m = static_cast<double>(x.bn[b]);
        a.mean_m = x.bs[b] / m;
        a.rms_m = std::sqrt(x.bss[b] / m);
        a.sd_m = std::sqrt(std::max(0.0, x.bss[b] / m - a.mean_m * a.mean_m));
        a.within_tvu = static_cast<double>(x.bin_ok[b]) / m;
        r.crossline_by_angle.push_back(a);
    }
}

}  // namespace

struct S44ByBlocks::State {
    const S44Grid& grid;
    S44Config config;
    std::vector<double> ping_t_s, ping_yaw_rad;
    ComplianceSums compliance;
    std::vector<float> depths;  // the finite depths, for the median
    Crossline crossline;

    State(const S44Grid& g,
          const S44Config& c,
          std::vector<double> t_s,
          std::vector<double> yaw_rad)
        : grid(g),
          config(c),
          ping_t_s(std::move(t_s)),
          ping_yaw_rad(std::move(yaw_rad)),
          crossline(g, c, ping_t_s) {
        compliance.node_thu_sum.assign(g.elevation_m.size(), 0.0f);
        compliance.node_thu_n.assign(g.elevation_m.size(), 0);
    }
};

S44ByBlocks::S44ByBlocks(const S44Grid& g,
                         const S44Config& c,
                         std::vector<double> ping_t_s,
                         std::vector<double> ping_yaw_rad)
    : state_(std::make_unique<State>(g, c, std::move(ping_t_s), std::move(ping_yaw_rad))) {}

S44ByBlocks::~S44ByBlocks() = default;

void S44ByBlocks::AddFirst(const S44Soundings& block) {
    State& st = *state_;
    ComplianceAdd(block, st.grid, st.compliance);
    for (float v : block.depth_m) {
        if (std::isfinite(v)) st.depths.push_back(v);
    }
    CrosslineCells(block, st.grid, st.ping_t_s, st.ping_yaw_rad, st.crossline);
}

void S44ByBlocks::AddSecond(const S44Soundings& block) {
    State& st = *state_;
    CrosslineCompare(block, st.grid, st.config, st.ping_t_s, st.ping_yaw_rad, st.crossline);
}

S44Result S44ByBlocks::Finish() {
    State& st = *state_;
    const S44Config& c = st.config;
    S44Result r;
    r.order = c.order;
    ComplianceFinish(st.grid, st.compliance, r);
    std::vector<float>& d = st.depths;
    double median_depth = 0;
    if (!d.empty()) {
        std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
        median_depth = d[d.size() / 2];
    }
    std::vector<float>().swap(d);
    Holidays(st.grid, c, median_depth, r);
    CrosslineFinish(st.crossline, r);
    char b[360];
    std::snprintf(
        b,
        sizeof b,
        "order %s: %.1f %% of %lld soundings within TVU, %.1f %% within THU; %.1f %% of "
        "nodes within TVU, %.1f %% within THU; %zu holidays (feature %.2f m), coverage %.1f %%; "
        "%lld crossline differences, RMS %.3f m",
        ToString(c.order),
        100 * r.soundings_within_tvu[static_cast<int>(c.order)],
        static_cast<long long>(r.soundings),
        100 * r.soundings_within_thu[static_cast<int>(c.order)],
        100 * r.nodes_within_tvu[static_cast<int>(c.order)],
        100 * r.nodes_within_thu[static_cast<int>(c.order)],
        r.holidays.size(),
        r.feature_size_m,
        100 * r.coverage_share,
        static_cast<long long>(r.crossline_compared),
        r.crossline_rms_m);
    r.message = b;
    return r;
}

S44Result RunS44(const S44Soundings& s, const S44Grid& g, const S44Config& c) {
    S44ByBlocks blocks(g, c, s.ping_t_s, s.ping_yaw_rad);
    blocks.AddFirst(s);
    blocks.AddSecond(s);
    return blocks.Finish();
}

}  // namespace pitmap::proc::hydro
