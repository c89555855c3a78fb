// SPDX-License-Identifier: MIT
#include "processor/hydro/cube.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

namespace pitmap::proc::hydro {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kBandRows = 16;  // node rows per parallel band

bool Valid(const CubeSounding& s) {
    return std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.z) &&
           std::isfinite(s.sigma_v_m) && s.sigma_v_m > 0 && std::isfinite(s.sigma_h_m) &&
           s.sigma_h_m >= 0 && std::isfinite(s.depth_m);
}

// The predicted surface: median height per coarse cell, its gradient by central differences.
// Cells are global (cube.hpp): cell a covers [a cell - half, (a + 1) cell - half), half = res / 2,
// and this surface holds cells a0 .. a0 + nx - 1 (b0 .. along y).
struct Predicted {
    std::int64_t a0 = 0, b0 = 0;
    double half = 0, cell = 1;
    int nx = 0, ny = 0;
    std::vector<double> z, gx, gy;  // NaN where fewer than kMinCount soundings

    static constexpr int kMinCount = 3;

    static std::int64_t Global(double x, double half, double cell) {
        return static_cast<std::int64_t>(std::floor((x + half) / cell));
    }
    bool Inside(int a, int b) const { return a >= 0 && b >= 0 && a < nx && b < ny; }
    double At(int a, int b) const {
        return Inside(a, b) ? z[static_cast<std::size_t>(b) * nx + a] : kNaN;
    }
    std::size_t Cell(double x, double y, int* a_out = nullptr, int* b_out = nullptr) const {
        const int a = static_cast<int>(
            std::clamp<std::int64_t>(Global(x, half, cell) - a0, 0, std::int64_t{nx} - 1));
        const int b = static_cast<int>(
            std::clamp<std::int64_t>(Global(y, half, cell) - b0, 0, std::int64_t{ny} - 1));
        if (a_out) *a_out = a;
        if (b_out) *b_out = b;
        return static_cast<std::size_t>(b) * nx + a;
    }
    // Bilinear between cell centres where all four exist, else the containing cell's value.
    double Interpolate(double x, double y) const {
        const double u = (x + half) / cell - 0.5, v = (y + half) / cell - 0.5;
        const double ug = std::floor(u), vg = std::floor(v);
        const double fu = u - ug, fv = v - vg;
        const int a = static_cast<int>(static_cast<std::int64_t>(ug) - a0);
        const int b = static_cast<int>(static_cast<std::int64_t>(vg) - b0);
        const double z00 = At(a, b), z10 = At(a + 1, b), z01 = At(a, b + 1), z11 = At(a + 1, b + 1);
        if (std::isfinite(z00) && std::isfinite(z10) && std::isfinite(z01) && std::isfinite(z11)) {
            return (1 - fv) * ((1 - fu) * z00 + fu * z10) + fv * ((1 - fu) * z01 + fu * z11);
        }
        return z[Cell(x, y)];
    }
};

Predicted BuildPredicted(const std::vector<CubeSounding>& s,
                         const std::vector<std::uint32_t>& idx,
                         std::int64_t a0,
                         std::int64_t b0,
                         double half,
                         double cell,
                         int nx,
                         int ny) {
    Predicted p;
    p.a0 = a0;
    p.b0 = b0;
    p.half = half;
    p.cell = cell;
    p.nx = nx;
    p.ny = ny;
    const std::size_t nc = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
    // Counting sort of the heights by cell, then the median of each cell.
    std::vector<std::uint32_t> start(nc + 1, 0);
    std::vector<std::uint32_t> cell_of(idx.size());
    for (std::size_t k = 0; k < idx.size(); ++k) {
        cell_of[k] = static_cast<std::uint32_t>(p.Cell(s[idx[k]].x, s[idx[k]].y));
        ++start[cell_of[k] + 1];
    }
    for (std::size_t c = 0; c < nc; ++c) start[c + 1] += start[c];
    std::vector<float> zs(idx.size());
    {
        std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
        for (std::size_t k = 0; k < idx.size(); ++k) {
            zs[fill[cell_of[k]]++] = static_cast<float>(s[idx[k]].z);
        }
    }
    p.z.assign(nc, kNaN);
    tbb::parallel_for(std::size_t{0}, nc, [&](std::size_t c) {
        const std::uint32_t a = start[c], b = start[c + 1];
        if (b - a < static_cast<std::uint32_t>(Predicted::kMinCount)) return;
        auto first = zs.begin() + a, last = zs.begin() + b;
        auto mid = first + (b - a) / 2;
        std::nth_element(first, mid, last);
        p.z[c] = *mid;
    });
    p.gx.assign(nc, 0.0);
    p.gy.assign(nc, 0.0);
    for (int b = 0; b < ny; ++b) {
        for (int a = 0; a < nx; ++a) {
            const std::size_t c = static_cast<std::size_t>(b) * nx + a;
            if (!std::isfinite(p.z[c])) continue;
            const auto diff = [&](double lo, double mid, double hi) {
                if (std::isfinite(lo) && std::isfinite(hi)) return (hi - lo) / (2 * cell);
                if (std::isfinite(hi)) return (hi - mid) / cell;
                if (std::isfinite(lo)) return (mid - lo) / cell;
                return 0.0;
            };
            p.gx[c] = diff(p.At(a - 1, b), p.z[c], p.At(a + 1, b));
            p.gy[c] = diff(p.At(a, b - 1), p.z[c], p.At(a, b + 1));
        }
    }
    return p;
}

double CaptureDistance(double depth_m, double res, const CubeConfig& c) {
    return std::clamp(c.capture_distance_scale * std::max(depth_m, 0.0),
                      c.min_capture_distance_res * res,
                      c.max_capture_distance_res * res);
}

}  // namespace

const char* ToString(Disambiguation d) {
    switch (d) {
        case Disambiguation::kDensity:
            return "density";
        case Disambiguation::kLocale:
            return "locale";
        case Disambiguation::kPredictedSurface:
            return "predicted_surface";
    }
    return "?";
}

std::vector<std::string> CubeConfig::Validate() const {
    std::vector<std::string> out;
    const auto positive = [&](double v, const char* name) {
        if (!(std::isfinite(v) && v > 0))
            out.push_back(std::string("grid.") + name + " must be > 0");
    };
    if (!(std::isfinite(resolution_m) && resolution_m >= 0)) {
        out.push_back("grid.resolution_m must be >= 0 (0 = from the depth)");
    }
    positive(resolution_depth_fraction, "resolution_depth_fraction");
    positive(min_resolution_m, "min_resolution_m");
    positive(max_resolution_m, "max_resolution_m");
    if (min_resolution_m > max_resolution_m) {
        out.push_back("grid.min_resolution_m must not exceed max_resolution_m");
    }
    positive(capture_distance_scale, "capture_distance_scale");
    positive(min_capture_distance_res, "min_capture_distance_res");
    positive(max_capture_distance_res, "max_capture_distance_res");
    if (min_capture_distance_res > max_capture_distance_res) {
        out.push_back("grid.min_capture_distance_res must not exceed max_capture_distance_res");
    }
    if (max_capture_distance_res > 10) out.push_back("grid.max_capture_distance_res must be <= 10");
    positive(distance_exponent, "distance_exponent");
    if (!(std::isfinite(horizontal_error_scale) && horizontal_error_scale >= 0)) {
        out.push_back("grid.horizontal_error_scale must be >= 0");
    }
    if (queue_length < 1 || queue_length > 101) out.push_back("grid.queue_length must be 1..101");
    if (!(pass_gap_s > 0)) out.push_back("grid.pass_gap_s must be > 0");
    if (!(common_correlation_s > 0)) out.push_back("grid.common_correlation_s must be > 0");
    positive(hypothesis_gate, "hypothesis_gate");
    if (predicted_surface_cells < 1 || predicted_surface_cells > 64) {
        out.push_back("grid.predicted_surface_cells must be 1..64");
    }
    if (locale_radius < 1 || locale_radius > 16) out.push_back("grid.locale_radius must be 1..16");
    if (max_nodes < 1) out.push_back("grid.max_nodes must be >= 1");
    if (num_threads < 0) out.push_back("grid.num_threads must be >= 0 (0 = all cores)");
    return out;
}

double CubeHypothesis::SampleSd() const {
    return count > 1 ? std::sqrt(m2 / static_cast<double>(count - 1)) : 0.0;
}

double CubeHypothesis::PassModelSd(double tau_s) const {
    if (count == 0 || common_count != count || !(independent_information > 0) || passes < 1) {
        return std::numeric_limits<double>::quiet_NaN();
    }
    // The mean correlation of the passes' common errors, (1 / P^2) sum_p sum_q rho_pq.
    double rho = 0;
    for (int p = 0; p < passes; ++p) {
        for (int q = 0; q < passes; ++q) {
            const double dt =
                std::abs(static_cast<double>(pass_time_s[static_cast<std::size_t>(p)]) -
                         pass_time_s[static_cast<std::size_t>(q)]);
            rho += std::exp(-dt / tau_s);
        }
    }
    rho /= static_cast<double>(passes) * passes;
    const double independent = measured_count == count && weight_sum > 0
                                   ? weighted_independent / (weight_sum * weight_sum)
                                   : 1.0 / independent_information;
    return std::sqrt(independent + common_variance_sum / static_cast<double>(common_count) * rho);
}

double CubeHypothesis::UncertaintySd(double tau_s) const {
    const double pass = PassModelSd(tau_s);
    return std::isnan(pass) ? std::max(std::sqrt(variance_m2), SampleSd()) : pass;
}

namespace {

// The pass-common bookkeeping of a hypothesis taking a sounding (cube.hpp).
void TakeCommon(CubeHypothesis& h,
                double v,
                double common_variance,
                float time_s,
                double gap_s,
                double measured_variance) {
    if (!std::isfinite(common_variance) || common_variance < 0) return;
    // The independent part at the node, kept at >= 1 % of the whole against rounding.
    h.independent_information += 1.0 / std::max(v - common_variance, 0.01 * v);
    if (std::isfinite(measured_variance) && measured_variance > 0 && v > 0) {
        const double s2 = std::max(measured_variance - common_variance, 0.01 * measured_variance);
        h.weight_sum += 1.0 / v;
        h.weighted_independent += s2 / (v * v);
        ++h.measured_count;
    }
    h.common_variance_sum += common_variance;
    ++h.common_count;
    for (int k = 0; k < h.passes; ++k) {
        if (std::abs(static_cast<double>(time_s) - h.pass_time_s[static_cast<std::size_t>(k)]) <=
            gap_s) {
            return;
        }
    }
    if (h.passes < kMaxPasses) h.pass_time_s[static_cast<std::size_t>(h.passes++)] = time_s;
}

}  // namespace

double ResolutionFromDepth(double median_depth_m, const CubeConfig& c) {
    const double want = std::clamp(
        median_depth_m * c.resolution_depth_fraction, c.min_resolution_m, c.max_resolution_m);
    // The largest 1, 2, 2.5 or 5 x 10^k not above `want` (and not below the minimum).
    const double decade = std::pow(10.0, std::floor(std::log10(want)));
    double best = decade;
    for (double m : {1.0, 2.0, 2.5, 5.0, 10.0}) {
        if (m * decade <= want * (1 + 1e-9)) best = m * decade;
    }
    return std::max(best, c.min_resolution_m);
}

void CubeNode::Update(double z, double v, const CubeConfig& c, double cv, float t, double mv) {
    // The smallest squared normalised innovation (z - mu)^2 / (s^2 + sigma_n^2).
    int best = -1;
    double best_e2 = std::numeric_limits<double>::infinity();
    for (std::size_t h = 0; h < hyps_.size(); ++h) {
        const double d = z - hyps_[h].mean_m;
        const double e2 = d * d / (hyps_[h].variance_m2 + v);
        if (e2 < best_e2) {
            best_e2 = e2;
            best = static_cast<int>(h);
        }
    }
    if (best < 0 || best_e2 > c.hypothesis_gate * c.hypothesis_gate) {
        CubeHypothesis h;
        h.mean_m = z;
        h.variance_m2 = v;
        h.count = 1;
        h.sample_mean_m = z;
        TakeCommon(h, v, cv, t, c.pass_gap_s, mv);
        hyps_.push_back(h);
        return;
    }
    CubeHypothesis& h = hyps_[static_cast<std::size_t>(best)];
    // Kalman step with the sounding as the observation of a constant depth.
    // s'^2 = s^2 v / (s^2 + v), mu' = mu + s^2 / (s^2 + v) (z - mu).
    const double gain = h.variance_m2 / (h.variance_m2 + v);
    h.mean_m += gain * (z - h.mean_m);
    h.variance_m2 *= (1.0 - gain);
    ++h.count;
    const double delta = z - h.sample_mean_m;
    h.sample_mean_m += delta / h.count;
    h.m2 += delta * (z - h.sample_mean_m);
    TakeCommon(h, v, cv, t, c.pass_gap_s, mv);
}

void CubeNode::Add(double z, double v, const CubeConfig& c, double cv, float t, double mv) {
    if (c.queue_length <= 1) {
        Update(z, v, c, cv, t, mv);
        return;
    }
    const Queued e{static_cast<float>(z),
                   static_cast<float>(v),
                   static_cast<float>(cv),
                   t,
                   static_cast<float>(mv)};
    queue_.insert(std::upper_bound(queue_.begin(),
                                   queue_.end(),
                                   e,
                                   [](const Queued& a, const Queued& b) { return a.z < b.z; }),
                  e);
    if (static_cast<int>(queue_.size()) >= c.queue_length) {
        const auto mid = queue_.begin() + static_cast<std::ptrdiff_t>(queue_.size() / 2);
        const Queued m = *mid;
        queue_.erase(mid);
        Update(m.z, m.variance, c, m.common_variance, m.time_s, m.measured_variance);
    }
}

void CubeNode::Flush(const CubeConfig& c) {
    while (!queue_.empty()) {
        const auto mid = queue_.begin() + static_cast<std::ptrdiff_t>(queue_.size() / 2);
        const Queued m = *mid;
        queue_.erase(mid);
        Update(m.z, m.variance, c, m.common_variance, m.time_s, m.measured_variance);
    }
    queue_.shrink_to_fit();
}

int CubeNode::Choose(double reference) const {
    int best = -1;
    for (std::size_t h = 0; h < hyps_.size(); ++h) {
        if (best < 0) {
            best = static_cast<int>(h);
            continue;
        }
        const CubeHypothesis& a = hyps_[h];
        const CubeHypothesis& b = hyps_[static_cast<std::size_t>(best)];
        bool better = false;
        if (std::isfinite(reference)) {
            const double da = std::abs(a.mean_m - reference), db = std::abs(b.mean_m - reference);
            better = da < db || (da == db && a.count > b.count);
        } else {
            better = a.count > b.count || (a.count == b.count && a.variance_m2 < b.variance_m2);
        }
        if (better) best = static_cast<int>(h);
    }
    return best;
}

namespace {

// The soundings CUBE takes (finite, with positive sigmas) and their horizontal extent.
struct ValidSoundings {
    std::vector<std::uint32_t> index;  // into the input, in input order
    double min_x = std::numeric_limits<double>::max(), min_y = min_x;
    double max_x = -min_x, max_y = -min_x;
    std::int64_t rejected = 0;
};

ValidSoundings SelectValid(const std::vector<CubeSounding>& soundings) {
    ValidSoundings valid;
    valid.index.reserve(soundings.size());
    for (std::size_t k = 0; k < soundings.size(); ++k) {
        const CubeSounding& s = soundings[k];
        if (!Valid(s)) {
            ++valid.rejected;
            continue;
        }
        valid.index.push_back(static_cast<std::uint32_t>(k));
        valid.min_x = std::min(valid.min_x, s.x);
        valid.max_x = std::max(valid.max_x, s.x);
        valid.min_y = std::min(valid.min_y, s.y);
        valid.max_y = std::max(valid.max_y, s.y);
    }
    return valid;
}

double MedianDepth(const std::vector<CubeSounding>& soundings, const ValidSoundings& valid) {
    std::vector<float> depths(valid.index.size());
    for (std::size_t k = 0; k < valid.index.size(); ++k)
        depths[k] = soundings[valid.index[k]].depth_m;
    const auto mid = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
    std::nth_element(depths.begin(), mid, depths.end());
    return *mid;
}

// The nodes at `resolution_m` over the soundings' extent, with a node of margin beyond it; "" or
// why not (more than max_nodes).
std::string LayOutGrid(const ValidSoundings& valid,
                       double resolution_m,
                       const CubeConfig& config,
                       CubeGrid& grid) {
    const double res = resolution_m;
    grid.resolution_m = res;
    grid.i0 = static_cast<std::int64_t>(std::floor(valid.min_x / res));
    grid.j0 = static_cast<std::int64_t>(std::floor(valid.min_y / res));
    grid.x0 = static_cast<double>(grid.i0) * res;
    grid.y0 = static_cast<double>(grid.j0) * res;
    const double nxd = std::ceil((valid.max_x - grid.x0) / res) + 2;
    const double nyd = std::ceil((valid.max_y - grid.y0) / res) + 2;
    if (nxd * nyd > static_cast<double>(config.max_nodes) || nxd > 1e7 || nyd > 1e7) {
        char buf[200];
        std::snprintf(buf,
                      sizeof buf,
                      "grid: %.0f x %.0f nodes at %.3g m exceed grid.max_nodes (%lld); set a "
                      "coarser grid.resolution_m",
                      nxd,
                      nyd,
                      res,
                      static_cast<long long>(config.max_nodes));
        return buf;
    }
    grid.nx = static_cast<int>(nxd);
    grid.ny = static_cast<int>(nyd);
    return {};
}

// The predicted surface on the global cells (edges on node half-spacings) over the nodes and
// soundings, a cell beyond them on each side (so that no sounding or node is clamped into a
// cell that is not its own).
Predicted PredictedSurface(const std::vector<CubeSounding>& soundings,
                           const ValidSoundings& valid,
                           const CubeGrid& grid,
                           const CubeConfig& config) {
    const double res = grid.resolution_m;
    const double cell = res * config.predicted_surface_cells;
    const double half = res / 2;
    const double nx_last = static_cast<double>(grid.i0 + grid.nx - 1) * res;
    const double ny_last = static_cast<double>(grid.j0 + grid.ny - 1) * res;
    const std::int64_t a0 = Predicted::Global(std::min(valid.min_x, grid.x0), half, cell) - 1;
    const std::int64_t b0 = Predicted::Global(std::min(valid.min_y, grid.y0), half, cell) - 1;
    const std::int64_t a1 = Predicted::Global(std::max(valid.max_x, nx_last), half, cell) + 1;
    const std::int64_t b1 = Predicted::Global(std::max(valid.max_y, ny_last), half, cell) + 1;
    return BuildPredicted(soundings,
                          valid.index,
                          a0,
                          b0,
                          half,
                          cell,
                          static_cast<int>(a1 - a0 + 1),
                          static_cast<int>(b1 - b0 + 1));
}

// The node index range [lo, hi] (global) within r of x at resolution res.
void NodesWithin(double x, double r, double res, std::int64_t& lo, std::int64_t& hi) {
    lo = static_cast<std::int64_t>(std::ceil((x - r) / res));
    hi = static_cast<std::int64_t>(std::floor((x + r) / res));
}

// Bands of kBandRows node rows, each with the soundings that reach it (their capture distance),
// in input order (CSR: band b's soundings are items[start[b]] .. items[start[b + 1]]). The bands
// are processed in parallel, each by one thread.
struct Bands {
    int count = 0;
    std::vector<std::uint32_t> start;
    std::vector<std::uint32_t> items;
};

Bands BandsOf(const std::vector<CubeSounding>& soundings,
              const ValidSoundings& valid,
              const CubeGrid& grid,
              const CubeConfig& config) {
    const double res = grid.resolution_m;
    Bands bands;
    bands.count = (grid.ny + kBandRows - 1) / kBandRows;
    bands.start.assign(static_cast<std::size_t>(bands.count) + 1, 0);
    const auto rows_of = [&](const CubeSounding& s, int& j0, int& j1) {
        const double r = CaptureDistance(s.depth_m, res, config);
        std::int64_t lo = 0, hi = 0;
        NodesWithin(s.y, r, res, lo, hi);
        j0 = static_cast<int>(std::max<std::int64_t>(0, lo - grid.j0));
        j1 = static_cast<int>(std::min<std::int64_t>(grid.ny - 1, hi - grid.j0));
    };
    for (std::uint32_t k : valid.index) {
        int j0 = 0, j1 = 0;
        rows_of(soundings[k], j0, j1);
        if (j1 < j0) continue;
        for (int b = j0 / kBandRows; b <= j1 / kBandRows; ++b) ++bands.start[b + 1];
    }
    for (int b = 0; b < bands.count; ++b) bands.start[b + 1] += bands.start[b];
    bands.items.resize(bands.start.back());
    std::vector<std::uint32_t> fill(bands.start.begin(), bands.start.end() - 1);
    for (std::uint32_t k : valid.index) {
        int j0 = 0, j1 = 0;
        rows_of(soundings[k], j0, j1);
        if (j1 < j0) continue;
        for (int b = j0 / kBandRows; b <= j1 / kBandRows; ++b) bands.items[fill[b]++] = k;
    }
    return bands;
}

// The median pre-filter queues of one band's nodes: queue_length slots a node, (z, variance)
// sorted by z. A full queue releases its median to the node's hypotheses (CubeNode::Update).
// They live only while the band is processed, so that the queues of the whole grid are never
// held at once.
class BandQueues {
public:
    BandQueues(std::vector<CubeNode>& nodes,
               std::size_t first_node,
               std::size_t band_nodes,
               const CubeConfig& config)
        : nodes_(nodes),
          first_node_(first_node),
          length_(config.queue_length),
          config_(config),
          queue_(length_ > 1 ? band_nodes * length_ : 0),
          queued_(length_ > 1 ? band_nodes : 0, 0) {}

    // Offers a sounding propagated to node `node` (height z, variance v, its pass-common
    // variance cv and time t: cube.hpp).
    void Offer(std::size_t node, double z, double v, float cv, float t, float mv) {
        if (length_ <= 1) {
            nodes_[node].Update(z, v, config_, cv, t, mv);
            return;
        }
        const std::size_t local = node - first_node_;
        auto* q = queue_.data() + local * length_;
        int k = queued_[local];
        const CubeNode::Queued e{static_cast<float>(z), static_cast<float>(v), cv, t, mv};
        // Insertion into the sorted queue.
        int pos = k;
        while (pos > 0 && q[pos - 1].z > e.z) {
            q[pos] = q[pos - 1];
            --pos;
        }
        q[pos] = e;
        ++k;
        if (k == length_) ReleaseMedian(q, k, nodes_[node]);
        queued_[local] = static_cast<std::uint8_t>(k);
    }

    // Empties every queue: the median first, until the queue is empty.
    void Flush() {
        for (std::size_t local = 0; local < queued_.size(); ++local) {
            auto* q = queue_.data() + local * length_;
            int k = queued_[local];
            CubeNode& node = nodes_[local + first_node_];
            while (k > 0) ReleaseMedian(q, k, node);
        }
    }

private:
    void ReleaseMedian(CubeNode::Queued* q, int& k, CubeNode& node) {
        const int mid = k / 2;
        const CubeNode::Queued m = q[mid];
        for (int i = mid; i + 1 < k; ++i) q[i] = q[i + 1];
        --k;
        node.Update(m.z, m.variance, config_, m.common_variance, m.time_s, m.measured_variance);
    }

    std::vector<CubeNode>& nodes_;
    std::size_t first_node_;
    int length_;
    const CubeConfig& config_;
    std::vector<CubeNode::Queued> queue_;
    std::vector<std::uint8_t> queued_;
};

// Offers sounding `s` to every node of rows first_row..last_row within its capture distance:
// its height carried along the predicted surface's slope to the node (slope_correction), its
// variance grown with the distance. Returns the number of nodes offered.
std::int64_t OfferSounding(const CubeSounding& s,
                           const CubeGrid& grid,
                           int first_row,
                           int last_row,
                           const Predicted& predicted,
                           const CubeConfig& config,
                           BandQueues& queues) {
    const double res = grid.resolution_m;
    const bool square = config.distance_exponent == 2.0;
    const double r = CaptureDistance(s.depth_m, res, config);
    const double r2 = r * r;
    std::int64_t ilo = 0, ihi = 0, jlo = 0, jhi = 0;
    NodesWithin(s.x, r, res, ilo, ihi);
    NodesWithin(s.y, r, res, jlo, jhi);
    const int i0 = static_cast<int>(std::max<std::int64_t>(0, ilo - grid.i0));
    const int i1 = static_cast<int>(std::min<std::int64_t>(grid.nx - 1, ihi - grid.i0));
    const int j0 = static_cast<int>(std::max<std::int64_t>(first_row, jlo - grid.j0));
    const int j1 = static_cast<int>(std::min<std::int64_t>(last_row, jhi - grid.j0));
    double gx = 0, gy = 0;
    if (config.slope_correction) {
        const std::size_t c = predicted.Cell(s.x, s.y);
        gx = predicted.gx[c];
        gy = predicted.gy[c];
    }
    const double sv2 = static_cast<double>(s.sigma_v_m) * s.sigma_v_m;
    const double slope_var = (gx * gx + gy * gy) * static_cast<double>(s.sigma_h_m) * s.sigma_h_m;
    const double rho_sh = config.horizontal_error_scale * s.sigma_h_m;
    // The part of the variance common to the sounding's pass (cube.hpp), at most all of it:
    // the vertical part, and the slope's share of the horizontal part (the INS's horizontal
    // error moves the whole pass, so on a wall it does not average over its soundings).
    const double sh_common =
        std::isfinite(s.sigma_h_common_m) ? std::min(s.sigma_h_common_m, s.sigma_h_m) : 0.0;
    const float common_var =
        std::isfinite(s.sigma_common_m)
            ? static_cast<float>(static_cast<double>(std::min(s.sigma_common_m, s.sigma_v_m)) *
                                     std::min(s.sigma_common_m, s.sigma_v_m) +
                                 (gx * gx + gy * gy) * sh_common * sh_common)
            : std::numeric_limits<float>::quiet_NaN();
    // The sounding's own variance at the node, without the distance growth (cube.hpp).
    const auto measured_var = static_cast<float>(sv2 + slope_var);
    std::int64_t offered = 0;
    for (int j = j0; j <= j1; ++j) {
        const double dy = static_cast<double>(grid.j0 + j) * res - s.y;
        for (int i = i0; i <= i1; ++i) {
            const double dx = static_cast<double>(grid.i0 + i) * res - s.x;
            const double d2 = dx * dx + dy * dy;
            if (d2 > r2) continue;
            // C&M eq. 9: sigma_v^2 (1 + ((d + rho sigma_h) / resolution)^alpha).
            const double u = (std::sqrt(d2) + rho_sh) / res;
            const double grow = square ? u * u : std::pow(u, config.distance_exponent);
            const double v = sv2 * (1.0 + grow) + slope_var;
            queues.Offer(static_cast<std::size_t>(j) * grid.nx + i,
                         s.z + gx * dx + gy * dy,
                         v,
                         common_var,
                         s.time_s,
                         measured_var);
            ++offered;
        }
    }
    return offered;
}

// Every node's hypotheses from the soundings that reach it, band by band in parallel (a band's
// soundings in input order, so the result does not depend on the thread count). Returns the
// number of node updates.
std::int64_t AccumulateNodes(const std::vector<CubeSounding>& soundings,
                             const Bands& bands,
                             const CubeGrid& grid,
                             const Predicted& predicted,
                             const CubeConfig& config,
                             std::vector<CubeNode>& nodes) {
    std::atomic<std::int64_t> updates{0};
    tbb::parallel_for(0, bands.count, [&](int band) {
        const int first_row = band * kBandRows;
        const int last_row = std::min(grid.ny - 1, first_row + kBandRows - 1);
        const std::size_t band_nodes = static_cast<std::size_t>(last_row - first_row + 1) * grid.nx;
        BandQueues queues(nodes, static_cast<std::size_t>(first_row) * grid.nx, band_nodes, config);
        std::int64_t band_updates = 0;
        for (std::uint32_t p = bands.start[band]; p < bands.start[band + 1]; ++p) {
            band_updates += OfferSounding(
                soundings[bands.items[p]], grid, first_row, last_row, predicted, config, queues);
        }
        queues.Flush();
        updates += band_updates;
    });
    return updates.load();
}

// kLocale's reference for node (i, j): the median of the densest hypotheses' means of the nodes
// within locale_radius (`strongest`, NaN where empty), the node itself excluded; NaN if none.
double LocaleReference(const std::vector<double>& strongest,
                       const CubeGrid& grid,
                       int i,
                       int j,
                       int radius,
                       std::vector<double>& around) {
    around.clear();
    for (int b = std::max(0, j - radius); b <= std::min(grid.ny - 1, j + radius); ++b) {
        for (int a = std::max(0, i - radius); a <= std::min(grid.nx - 1, i + radius); ++a) {
            const double z = strongest[static_cast<std::size_t>(b) * grid.nx + a];
            if ((a != i || b != j) && std::isfinite(z)) around.push_back(z);
        }
    }
    if (around.empty()) return kNaN;
    const auto mid = around.begin() + static_cast<std::ptrdiff_t>(around.size() / 2);
    std::nth_element(around.begin(), mid, around.end());
    return *mid;
}

// The grid's layers from each node's chosen hypothesis: the only one, else the one nearest the
// disambiguation's reference (the predicted surface, the locale's median) or the densest.
void ChooseHypotheses(const std::vector<CubeNode>& nodes,
                      const Predicted& predicted,
                      const CubeConfig& config,
                      CubeGrid& grid) {
    const std::size_t nn = grid.size();
    const double res = grid.resolution_m;
    grid.elevation_m.assign(nn, static_cast<float>(kNaN));
    grid.uncertainty_m.assign(nn, static_cast<float>(kNaN));
    grid.density.assign(nn, 0.0f);
    grid.hypotheses.assign(nn, 0.0f);
    // The densest hypothesis' mean of every node (kLocale's neighbourhood).
    std::vector<double> strongest(nn, kNaN);
    if (config.disambiguation == Disambiguation::kLocale) {
        tbb::parallel_for(std::size_t{0}, nn, [&](std::size_t n) {
            const int h = nodes[n].Choose(kNaN);
            if (h >= 0) strongest[n] = nodes[n].hypotheses()[static_cast<std::size_t>(h)].mean_m;
        });
    }
    tbb::parallel_for(0, grid.ny, [&](int j) {
        std::vector<double> around;
        for (int i = 0; i < grid.nx; ++i) {
            const std::size_t n = static_cast<std::size_t>(j) * grid.nx + i;
            const auto& hyps = nodes[n].hypotheses();
            if (hyps.empty()) continue;
            double reference = kNaN;
            if (hyps.size() > 1) {
                if (config.disambiguation == Disambiguation::kPredictedSurface) {
                    reference = predicted.Interpolate(static_cast<double>(grid.i0 + i) * res,
                                                      static_cast<double>(grid.j0 + j) * res);
                } else if (config.disambiguation == Disambiguation::kLocale) {
                    reference =
                        LocaleReference(strongest, grid, i, j, config.locale_radius, around);
                }
            }
            const CubeHypothesis& h = hyps[static_cast<std::size_t>(nodes[n].Choose(reference))];
            grid.elevation_m[n] = static_cast<float>(h.mean_m);
            grid.uncertainty_m[n] =
                static_cast<float>(1.96 * h.UncertaintySd(config.common_correlation_s));
            grid.density[n] = static_cast<float>(h.count);
            grid.hypotheses[n] = static_cast<float>(hyps.size());
        }
    });
}

void CountHypotheses(const std::vector<CubeNode>& nodes, CubeResult& out) {
    for (const CubeNode& node : nodes) {
        const auto k = node.hypotheses().size();
        out.hypotheses_total += static_cast<std::int64_t>(k);
        if (k > 0) ++out.nodes_filled;
        if (k > 1) ++out.nodes_multiple;
    }
}

}  // namespace

std::string DescribeCube(const CubeResult& out) {
    const CubeGrid& g = out.grid;
    char buf[256];
    std::snprintf(buf,
                  sizeof buf,
                  "%d x %d nodes at %.3g m (median depth %.1f m, capture %.2f m): %lld filled, "
                  "%lld with several hypotheses; %lld soundings, %lld node updates",
                  g.nx,
                  g.ny,
                  g.resolution_m,
                  out.median_depth_m,
                  out.capture_distance_m,
                  static_cast<long long>(out.nodes_filled),
                  static_cast<long long>(out.nodes_multiple),
                  static_cast<long long>(out.soundings_used),
                  static_cast<long long>(out.node_updates));
    return buf;
}

namespace {

// The thread limit of one call (num_threads > 0).
std::unique_ptr<tbb::global_control> ThreadLimit(const CubeConfig& config) {
    if (config.num_threads <= 0) return nullptr;
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                 config.num_threads);
}

// The valid soundings, their median depth, the resolution and the whole survey's nodes; false
// (out.message) where there is no grid.
bool LayOut(const std::vector<CubeSounding>& soundings,
            const CubeConfig& config,
            ValidSoundings& valid,
            CubeResult& out) {
    valid = SelectValid(soundings);
    out.soundings_rejected = valid.rejected;
    if (valid.index.empty()) {
        out.message = "grid: no valid soundings";
        return false;
    }
    out.median_depth_m = MedianDepth(soundings, valid);
    const double res = config.resolution_m > 0 ? config.resolution_m
                                               : ResolutionFromDepth(out.median_depth_m, config);
    if (std::string why = LayOutGrid(valid, res, config, out.grid); !why.empty()) {
        out.message = std::move(why);
        return false;
    }
    out.capture_distance_m = CaptureDistance(out.median_depth_m, res, config);
    return true;
}

// The hypotheses of every node of `grid` from the soundings `valid` with their predicted
// surface, then one chosen a node.
std::vector<CubeNode> GridNodes(const std::vector<CubeSounding>& soundings,
                                const ValidSoundings& valid,
                                const Predicted& predicted,
                                const CubeConfig& config,
                                CubeResult& out) {
    CubeGrid& grid = out.grid;
    const Bands bands = BandsOf(soundings, valid, grid, config);
    std::vector<CubeNode> nodes(grid.size());
    out.node_updates = AccumulateNodes(soundings, bands, grid, predicted, config, nodes);
    out.soundings_used = static_cast<std::int64_t>(valid.index.size());
    ChooseHypotheses(nodes, predicted, config, grid);
    return nodes;
}

}  // namespace

// CUBE (Calder & Mayer 2003): the grid from the soundings' extent and median depth, the
// predicted surface, every node's hypotheses from the soundings within its capture distance,
// then one hypothesis chosen a node.
CubeResult RunCube(const std::vector<CubeSounding>& soundings, const CubeConfig& config) {
    CubeResult out;
    const auto limit = ThreadLimit(config);
    ValidSoundings valid;
    if (!LayOut(soundings, config, valid, out)) return out;
    const Predicted predicted = PredictedSurface(soundings, valid, out.grid, config);
    const std::vector<CubeNode> nodes = GridNodes(soundings, valid, predicted, config, out);
    CountHypotheses(nodes, out);
    out.ok = true;
    out.message = DescribeCube(out);
    return out;
}

CubeResult LayOutCube(const std::vector<CubeSounding>& soundings, const CubeConfig& config) {
    CubeResult out;
    ValidSoundings valid;
    if (!LayOut(soundings, config, valid, out)) return out;
    out.soundings_used = static_cast<std::int64_t>(valid.index.size());
    out.ok = true;
    return out;
}

double CubeTileReach(double resolution_m, const CubeConfig& config) {
    const int locale = config.disambiguation == Disambiguation::kLocale ? config.locale_radius : 0;
    // + 1 node of slack against rounding at the edges of the cells.
    return (config.max_capture_distance_res + 2.0 * config.predicted_surface_cells + locale + 1) *
           resolution_m;
}

// A tile: the soundings by their global predicted-surface cell (all of a cell or none, so every
// cell the core's soundings and nodes read holds the median of the whole run), the grid of the
// core (grown by kLocale's radius, inside the survey's nodes), then the core cut out.
CubeResult RunCubeTile(const std::vector<CubeSounding>& soundings,
                       const CubeConfig& config,
                       const CubeNodeRange& core,
                       const CubeNodeRange& survey,
                       double overlap_m) {
    CubeResult out;
    const auto limit = ThreadLimit(config);
    const double res = config.resolution_m;
    if (!(res > 0) || core.nx() <= 0 || core.ny() <= 0 || !(overlap_m >= 0)) {
        out.message = "grid: a tile needs the survey's resolution, a core and an overlap";
        return out;
    }
    const double cell = res * config.predicted_surface_cells;
    const double half = res / 2;
    const CubeCellRows columns = CubeTileCellRows(core.i0, core.i1, res, config, overlap_m);
    const CubeCellRows rows = CubeTileCellRows(core.j0, core.j1, res, config, overlap_m);
    const std::int64_t a0 = columns.first, a1 = columns.last, b0 = rows.first, b1 = rows.last;
    ValidSoundings valid;
    for (std::size_t k = 0; k < soundings.size(); ++k) {
        const CubeSounding& s = soundings[k];
        if (!Valid(s)) continue;
        const std::int64_t a = Predicted::Global(s.x, half, cell);
        const std::int64_t b = Predicted::Global(s.y, half, cell);
        if (a < a0 || a > a1 || b < b0 || b > b1) continue;
        valid.index.push_back(static_cast<std::uint32_t>(k));
    }
    // The tile's nodes: the core and, for kLocale, the neighbourhood of its edge nodes.
    const std::int64_t grow =
        config.disambiguation == Disambiguation::kLocale ? config.locale_radius : 0;
    CubeGrid& grid = out.grid;
    grid.resolution_m = res;
    grid.i0 = std::max(survey.i0, core.i0 - grow);
    grid.j0 = std::max(survey.j0, core.j0 - grow);
    const std::int64_t gi1 = std::min(survey.i1, core.i1 + grow);
    const std::int64_t gj1 = std::min(survey.j1, core.j1 + grow);
    if (static_cast<double>(gi1 - grid.i0) * static_cast<double>(gj1 - grid.j0) >
        static_cast<double>(config.max_nodes)) {
        out.message = "grid: a tile's nodes exceed grid.max_nodes";
        return out;
    }
    grid.nx = static_cast<int>(gi1 - grid.i0);
    grid.ny = static_cast<int>(gj1 - grid.j0);
    grid.x0 = static_cast<double>(grid.i0) * res;
    grid.y0 = static_cast<double>(grid.j0) * res;
    const Predicted predicted = BuildPredicted(soundings,
                                               valid.index,
                                               a0,
                                               b0,
                                               half,
                                               cell,
                                               static_cast<int>(a1 - a0 + 1),
                                               static_cast<int>(b1 - b0 + 1));
    std::vector<CubeNode> nodes = GridNodes(soundings, valid, predicted, config, out);
    // The core cut out of the tile's grid (the nodes and the layers).
    const int ci = static_cast<int>(core.i0 - grid.i0), cj = static_cast<int>(core.j0 - grid.j0);
    const int cnx = static_cast<int>(core.nx()), cny = static_cast<int>(core.ny());
    CubeGrid cut;
    cut.resolution_m = res;
    cut.i0 = core.i0;
    cut.j0 = core.j0;
    cut.x0 = static_cast<double>(core.i0) * res;
    cut.y0 = static_cast<double>(core.j0) * res;
    cut.nx = cnx;
    cut.ny = cny;
    std::vector<CubeNode> core_nodes;
    core_nodes.reserve(cut.size());
    cut.elevation_m.resize(cut.size());
    cut.uncertainty_m.resize(cut.size());
    cut.density.resize(cut.size());
    cut.hypotheses.resize(cut.size());
    for (int j = 0; j < cny; ++j) {
        for (int i = 0; i < cnx; ++i) {
            const std::size_t from = static_cast<std::size_t>(j + cj) * grid.nx + (i + ci);
            const std::size_t to = static_cast<std::size_t>(j) * cnx + i;
            cut.elevation_m[to] = grid.elevation_m[from];
            cut.uncertainty_m[to] = grid.uncertainty_m[from];
            cut.density[to] = grid.density[from];
            cut.hypotheses[to] = grid.hypotheses[from];
            core_nodes.push_back(std::move(nodes[from]));
        }
    }
    out.grid = std::move(cut);
    CountHypotheses(core_nodes, out);
    // Every sounding a node was offered went to one of its hypotheses (CubeNode::Update): the
    // core's own updates, without the halo's.
    out.node_updates = 0;
    for (const CubeNode& node : core_nodes) {
        for (const CubeHypothesis& h : node.hypotheses()) out.node_updates += h.count;
    }
    out.ok = true;
    out.message = DescribeCube(out);
    return out;
}

bool CubeTakes(const CubeSounding& sounding) {
    return Valid(sounding);
}

void CubeLayout::Add(const CubeSounding& s) {
    if (!Valid(s)) {
        ++rejected_;
        return;
    }
    depths_.push_back(s.depth_m);
    min_x_ = std::min(min_x_, s.x);
    max_x_ = std::max(max_x_, s.x);
    min_y_ = std::min(min_y_, s.y);
    max_y_ = std::max(max_y_, s.y);
}

// LayOut's arithmetic on what Add kept (the median depth: the same element of the same depths).
CubeResult CubeLayout::Finish(const CubeConfig& config) {
    CubeResult out;
    out.soundings_rejected = rejected_;
    if (depths_.empty()) {
        out.message = "grid: no valid soundings";
        return out;
    }
    const auto mid = depths_.begin() + static_cast<std::ptrdiff_t>(depths_.size() / 2);
    std::nth_element(depths_.begin(), mid, depths_.end());
    out.median_depth_m = *mid;
    out.soundings_used = static_cast<std::int64_t>(depths_.size());
    std::vector<float>().swap(depths_);
    ValidSoundings extent;
    extent.min_x = min_x_;
    extent.max_x = max_x_;
    extent.min_y = min_y_;
    extent.max_y = max_y_;
    const double res = config.resolution_m > 0 ? config.resolution_m
                                               : ResolutionFromDepth(out.median_depth_m, config);
    if (std::string why = LayOutGrid(extent, res, config, out.grid); !why.empty()) {
        out.message = std::move(why);
        return out;
    }
    out.capture_distance_m = CaptureDistance(out.median_depth_m, res, config);
    out.ok = true;
    return out;
}

std::int64_t CubeCellIndex(double x, double resolution_m, const CubeConfig& config) {
    return Predicted::Global(x, resolution_m / 2, resolution_m * config.predicted_surface_cells);
}

CubeCellRows CubeTileCellRows(
    std::int64_t j0, std::int64_t j1, double res, const CubeConfig& config, double overlap_m) {
    const double cell = res * config.predicted_surface_cells;
    const double half = res / 2;
    return {Predicted::Global(static_cast<double>(j0) * res - overlap_m, half, cell),
            Predicted::Global(static_cast<double>(j1 - 1) * res + overlap_m, half, cell)};
}

std::vector<CubeBand> PlanCubeBands(const CubeGrid& layout,
                                    std::int64_t first_cell,
                                    const std::vector<std::int64_t>& cell_soundings,
                                    const CubeConfig& config,
                                    double overlap_m,
                                    std::int64_t max_soundings,
                                    std::int64_t max_nodes) {
    // prefix[k]: the soundings of cell rows first_cell .. first_cell + k - 1.
    std::vector<std::int64_t> prefix(cell_soundings.size() + 1, 0);
    for (std::size_t k = 0; k < cell_soundings.size(); ++k)
        prefix[k + 1] = prefix[k] + cell_soundings[k];
    const auto last_cell = first_cell + static_cast<std::int64_t>(cell_soundings.size()) - 1;
    const auto soundings_in = [&](const CubeCellRows& c) -> std::int64_t {
        const std::int64_t a = std::max(c.first, first_cell), b = std::min(c.last, last_cell);
        if (b < a) return 0;
        return prefix[static_cast<std::size_t>(b - first_cell + 1)] -
               prefix[static_cast<std::size_t>(a - first_cell)];
    };
    const double res = layout.resolution_m;
    const std::int64_t step = std::max(1, config.predicted_surface_cells);
    const std::int64_t end = layout.j0 + layout.ny;
    std::vector<CubeBand> bands;
    for (std::int64_t j = layout.j0; j < end;) {
        std::int64_t j1 = std::min(end, j + step);
        while (j1 < end) {
            const std::int64_t next = std::min(end, j1 + step);
            if ((next - j) * layout.nx > max_nodes ||
                soundings_in(CubeTileCellRows(j, next, res, config, overlap_m)) > max_soundings)
                break;
            j1 = next;
        }
        CubeBand band;
        band.core = {layout.i0, j, layout.i0 + layout.nx, j1};
        band.cells = CubeTileCellRows(j, j1, res, config, overlap_m);
        band.soundings = soundings_in(band.cells);
        bands.push_back(band);
        j = j1;
    }
    return bands;
}

}  // namespace pitmap::proc::hydro
