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
struct Predicted {
    double x0 = 0, y0 = 0, cell = 1;
    int nx = 0, ny = 0;
    std::vector<double> z, gx, gy;  // NaN where fewer than kMinCount soundings

    static constexpr int kMinCount = 3;

    bool Inside(int a, int b) const { return a >= 0 && b >= 0 && a < nx && b < ny; }
    double At(int a, int b) const {
        return Inside(a, b) ? z[static_cast<std::size_t>(b) * nx + a] : kNaN;
    }
    std::size_t Cell(double x, double y, int* a_out = nullptr, int* b_out = nullptr) const {
        const int a = std::clamp(static_cast<int>(std::floor((x - x0) / cell)), 0, nx - 1);
        const int b = std::clamp(static_cast<int>(std::floor((y - y0) / cell)), 0, ny - 1);
        if (a_out) *a_out = a;
        if (b_out) *b_out = b;
        return static_cast<std::size_t>(b) * nx + a;
    }
    // Bilinear between cell centres where all four exist, else the containing cell's value.
    double Interpolate(double x, double y) const {
        const double u = (x - x0) / cell - 0.5, v = (y - y0) / cell - 0.5;
        const int a = static_cast<int>(std::floor(u)), b = static_cast<int>(std::floor(v));
        const double fu = u - a, fv = v - b;
        const double z00 = At(a, b), z10 = At(a + 1, b), z01 = At(a, b + 1), z11 = At(a + 1, b + 1);
        if (std::isfinite(z00) && std::isfinite(z10) && std::isfinite(z01) && std::isfinite(z11)) {
            return (1 - fv) * ((1 - fu) * z00 + fu * z10) + fv * ((1 - fu) * z01 + fu * z11);
        }
        return z[Cell(x, y)];
    }
};

Predicted BuildPredicted(const std::vector<CubeSounding>& s,
                         const std::vector<std::uint32_t>& idx,
                         double x0,
                         double y0,
                         double cell,
                         int nx,
                         int ny) {
    Predicted p;
    p.x0 = x0;
    p.y0 = y0;
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
    return std::sqrt(1.0 / independent_information +
                     common_variance_sum / static_cast<double>(common_count) * rho);
}

double CubeHypothesis::UncertaintySd(double tau_s) const {
    const double pass = PassModelSd(tau_s);
    return std::isnan(pass) ? std::max(std::sqrt(variance_m2), SampleSd()) : pass;
}

namespace {

// The pass-common bookkeeping of a hypothesis taking a sounding (cube.hpp).
void TakeCommon(CubeHypothesis& h, double v, double common_variance, float time_s, double gap_s) {
    if (!std::isfinite(common_variance) || common_variance < 0) return;
    // The independent part at the node, kept at >= 1 % of the whole against rounding.
    h.independent_information += 1.0 / std::max(v - common_variance, 0.01 * v);
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

void CubeNode::Update(double z, double v, const CubeConfig& c, double cv, float t) {
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
        TakeCommon(h, v, cv, t, c.pass_gap_s);
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
    TakeCommon(h, v, cv, t, c.pass_gap_s);
}

void CubeNode::Add(double z, double v, const CubeConfig& c, double cv, float t) {
    if (c.queue_length <= 1) {
        Update(z, v, c, cv, t);
        return;
    }
    const Queued e{static_cast<float>(z), static_cast<float>(v), static_cast<float>(cv), t};
    queue_.insert(std::upper_bound(queue_.begin(),
                                   queue_.end(),
                                   e,
                                   [](const Queued& a, const Queued& b) { return a.z < b.z; }),
                  e);
    if (static_cast<int>(queue_.size()) >= c.queue_length) {
        const auto mid = queue_.begin() + static_cast<std::ptrdiff_t>(queue_.size() / 2);
        const Queued m = *mid;
        queue_.erase(mid);
        Update(m.z, m.variance, c, m.common_variance, m.time_s);
    }
}

void CubeNode::Flush(const CubeConfig& c) {
    while (!queue_.empty()) {
        const auto mid = queue_.begin() + static_cast<std::ptrdiff_t>(queue_.size() / 2);
        const Queued m = *mid;
        queue_.erase(mid);
        Update(m.z, m.variance, c, m.common_variance, m.time_s);
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

CubeResult RunCube(const std::vector<CubeSounding>& soundings, const CubeConfig& config) {
    CubeResult out;
    std::unique_ptr<tbb::global_control> limit;
    if (config.num_threads > 0) {
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      config.num_threads);
    }
    std::vector<std::uint32_t> idx;
    idx.reserve(soundings.size());
    double minx = std::numeric_limits<double>::max(), miny = minx;
    double maxx = -minx, maxy = -minx;
    for (std::size_t k = 0; k < soundings.size(); ++k) {
        const CubeSounding& s = soundings[k];
        if (!Valid(s)) {
            ++out.soundings_rejected;
            continue;
        }
        idx.push_back(static_cast<std::uint32_t>(k));
        minx = std::min(minx, s.x);
        maxx = std::max(maxx, s.x);
        miny = std::min(miny, s.y);
        maxy = std::max(maxy, s.y);
    }
    if (idx.empty()) {
        out.message = "grid: no valid soundings";
        return out;
    }
    {
        std::vector<float> depths(idx.size());
        for (std::size_t k = 0; k < idx.size(); ++k) depths[k] = soundings[idx[k]].depth_m;
        const auto mid = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
        std::nth_element(depths.begin(), mid, depths.end());
        out.median_depth_m = *mid;
    }
    const double res = config.resolution_m > 0 ? config.resolution_m
                                               : ResolutionFromDepth(out.median_depth_m, config);
    CubeGrid& g = out.grid;
    g.resolution_m = res;
    g.x0 = std::floor(minx / res) * res;
    g.y0 = std::floor(miny / res) * res;
    const double nxd = std::ceil((maxx - g.x0) / res) + 2, nyd = std::ceil((maxy - g.y0) / res) + 2;
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
        out.message = buf;
        return out;
    }
    g.nx = static_cast<int>(nxd);
    g.ny = static_cast<int>(nyd);
    out.capture_distance_m = CaptureDistance(out.median_depth_m, res, config);

    // Predicted surface on coarse cells whose edges fall on node half-spacings.
    const double cell = res * config.predicted_surface_cells;
    const int pnx = static_cast<int>(std::ceil(g.nx * res / cell)) + 1;
    const int pny = static_cast<int>(std::ceil(g.ny * res / cell)) + 1;
    const Predicted pred =
        BuildPredicted(soundings, idx, g.x0 - res / 2, g.y0 - res / 2, cell, pnx, pny);

    // Row bands, each with the soundings that reach it, in input order (CSR).
    const int nbands = (g.ny + kBandRows - 1) / kBandRows;
    std::vector<std::uint32_t> band_start(static_cast<std::size_t>(nbands) + 1, 0);
    const auto rows_of = [&](const CubeSounding& s, int& j0, int& j1) {
        const double r = CaptureDistance(s.depth_m, res, config);
        j0 = std::max(0, static_cast<int>(std::ceil((s.y - r - g.y0) / res)));
        j1 = std::min(g.ny - 1, static_cast<int>(std::floor((s.y + r - g.y0) / res)));
    };
    for (std::uint32_t k : idx) {
        int j0 = 0, j1 = 0;
        rows_of(soundings[k], j0, j1);
        if (j1 < j0) continue;
        for (int b = j0 / kBandRows; b <= j1 / kBandRows; ++b) ++band_start[b + 1];
    }
    for (int b = 0; b < nbands; ++b) band_start[b + 1] += band_start[b];
    std::vector<std::uint32_t> band_items(band_start.back());
    {
        std::vector<std::uint32_t> fill(band_start.begin(), band_start.end() - 1);
        for (std::uint32_t k : idx) {
            int j0 = 0, j1 = 0;
            rows_of(soundings[k], j0, j1);
            if (j1 < j0) continue;
            for (int b = j0 / kBandRows; b <= j1 / kBandRows; ++b) band_items[fill[b]++] = k;
        }
    }

    std::vector<CubeNode> nodes(g.size());
    std::atomic<std::int64_t> updates{0};
    const int Q = config.queue_length;
    const bool square = config.distance_exponent == 2.0;
    tbb::parallel_for(0, nbands, [&](int band) {
        const int jb0 = band * kBandRows, jb1 = std::min(g.ny - 1, jb0 + kBandRows - 1);
        // The band's median queues, (z, variance) sorted by z, Q slots a node: they live only
        // while the band is processed.
        const std::size_t band_nodes = static_cast<std::size_t>(jb1 - jb0 + 1) * g.nx;
        std::vector<CubeNode::Queued> queue(Q > 1 ? band_nodes * Q : 0);
        std::vector<std::uint8_t> queued(Q > 1 ? band_nodes : 0, 0);
        const auto offer = [&](std::size_t n, double z, double v, float cv, float t) {
            CubeNode& node = nodes[n];
            if (Q <= 1) {
                node.Update(z, v, config, cv, t);
                return;
            }
            const std::size_t local = n - static_cast<std::size_t>(jb0) * g.nx;
            auto* q = queue.data() + local * Q;
            int k = queued[local];
            const CubeNode::Queued e{static_cast<float>(z), static_cast<float>(v), cv, t};
            // Insertion into the sorted queue.
            int pos = k;
            while (pos > 0 && q[pos - 1].z > e.z) {
                q[pos] = q[pos - 1];
                --pos;
            }
            q[pos] = e;
            ++k;
            if (k == Q) {
                const int mid = k / 2;
                const auto m = q[mid];
                for (int i = mid; i + 1 < k; ++i) q[i] = q[i + 1];
                --k;
                node.Update(m.z, m.variance, config, m.common_variance, m.time_s);
            }
            queued[local] = static_cast<std::uint8_t>(k);
        };
        std::int64_t local_updates = 0;
        for (std::uint32_t p = band_start[band]; p < band_start[band + 1]; ++p) {
            const CubeSounding& s = soundings[band_items[p]];
            const double r = CaptureDistance(s.depth_m, res, config);
            const double r2 = r * r;
            const int i0 = std::max(0, static_cast<int>(std::ceil((s.x - r - g.x0) / res)));
            const int i1 = std::min(g.nx - 1, static_cast<int>(std::floor((s.x + r - g.x0) / res)));
            const int j0 = std::max(jb0, static_cast<int>(std::ceil((s.y - r - g.y0) / res)));
            const int j1 = std::min(jb1, static_cast<int>(std::floor((s.y + r - g.y0) / res)));
            double gx = 0, gy = 0;
            if (config.slope_correction) {
                const std::size_t c = pred.Cell(s.x, s.y);
                gx = pred.gx[c];
                gy = pred.gy[c];
            }
            const double sv2 = static_cast<double>(s.sigma_v_m) * s.sigma_v_m;
            const double slope_var =
                (gx * gx + gy * gy) * static_cast<double>(s.sigma_h_m) * s.sigma_h_m;
            const double rho_sh = config.horizontal_error_scale * s.sigma_h_m;
            const float common_var = std::isfinite(s.sigma_common_m)
                                         ? std::min(s.sigma_common_m, s.sigma_v_m) *
                                               std::min(s.sigma_common_m, s.sigma_v_m)
                                         : std::numeric_limits<float>::quiet_NaN();
            for (int j = j0; j <= j1; ++j) {
                const double dy = g.y0 + j * res - s.y;
                for (int i = i0; i <= i1; ++i) {
                    const double dx = g.x0 + i * res - s.x;
                    const double d2 = dx * dx + dy * dy;
                    if (d2 > r2) continue;
                    // C&M eq. 9: sigma_v^2 (1 + ((d + rho sigma_h) / resolution)^alpha).
                    const double u = (std::sqrt(d2) + rho_sh) / res;
                    const double grow = square ? u * u : std::pow(u, config.distance_exponent);
                    const double v = sv2 * (1.0 + grow) + slope_var;
                    offer(static_cast<std::size_t>(j) * g.nx + i,
                          s.z + gx * dx + gy * dy,
                          v,
                          common_var,
                          s.time_s);
                    ++local_updates;
                }
            }
        }
        // Flush: the median first, until the queue is empty.
        for (std::size_t local = 0; local < queued.size(); ++local) {
            auto* q = queue.data() + local * Q;
            int k = queued[local];
            CubeNode& node = nodes[local + static_cast<std::size_t>(jb0) * g.nx];
            while (k > 0) {
                const int mid = k / 2;
                const auto m = q[mid];
                for (int i = mid; i + 1 < k; ++i) q[i] = q[i + 1];
                --k;
                node.Update(m.z, m.variance, config, m.common_variance, m.time_s);
            }
        }
        updates += local_updates;
    });
    out.node_updates = updates.load();
    out.soundings_used = static_cast<std::int64_t>(idx.size());

    const std::size_t nn = g.size();
    g.elevation_m.assign(nn, static_cast<float>(kNaN));
    g.uncertainty_m.assign(nn, static_cast<float>(kNaN));
    g.density.assign(nn, 0.0f);
    g.hypotheses.assign(nn, 0.0f);
    // The densest hypothesis' mean of every node (kLocale's neighbourhood).
    std::vector<double> strongest(nn, kNaN);
    if (config.disambiguation == Disambiguation::kLocale) {
        tbb::parallel_for(std::size_t{0}, nn, [&](std::size_t n) {
            const int h = nodes[n].Choose(kNaN);
            if (h >= 0) strongest[n] = nodes[n].hypotheses()[static_cast<std::size_t>(h)].mean_m;
        });
    }
    tbb::parallel_for(0, g.ny, [&](int j) {
        std::vector<double> around;
        for (int i = 0; i < g.nx; ++i) {
            const std::size_t n = static_cast<std::size_t>(j) * g.nx + i;
            const auto& hyps = nodes[n].hypotheses();
            if (hyps.empty()) continue;
            double reference = kNaN;
            if (hyps.size() > 1) {
                if (config.disambiguation == Disambiguation::kPredictedSurface) {
                    reference = pred.Interpolate(g.x0 + i * res, g.y0 + j * res);
                } else if (config.disambiguation == Disambiguation::kLocale) {
                    around.clear();
                    const int R = config.locale_radius;
                    for (int b = std::max(0, j - R); b <= std::min(g.ny - 1, j + R); ++b) {
                        for (int a = std::max(0, i - R); a <= std::min(g.nx - 1, i + R); ++a) {
                            const double z = strongest[static_cast<std::size_t>(b) * g.nx + a];
                            if ((a != i || b != j) && std::isfinite(z)) around.push_back(z);
                        }
                    }
                    if (!around.empty()) {
                        const auto mid =
                            around.begin() + static_cast<std::ptrdiff_t>(around.size() / 2);
                        std::nth_element(around.begin(), mid, around.end());
                        reference = *mid;
                    }
                }
            }
            const CubeHypothesis& h = hyps[static_cast<std::size_t>(nodes[n].Choose(reference))];
            g.elevation_m[n] = static_cast<float>(h.mean_m);
            g.uncertainty_m[n] =
                static_cast<float>(1.96 * h.UncertaintySd(config.common_correlation_s));
            g.density[n] = static_cast<float>(h.count);
            g.hypotheses[n] = static_cast<float>(hyps.size());
        }
    });
    for (std::size_t n = 0; n < nn; ++n) {
        const auto k = nodes[n].hypotheses().size();
        out.hypotheses_total += static_cast<std::int64_t>(k);
        if (k > 0) ++out.nodes_filled;
        if (k > 1) ++out.nodes_multiple;
    }
    out.ok = true;
    char buf[256];
    std::snprintf(buf,
                  sizeof buf,
                  "%d x %d nodes at %.3g m (median depth %.1f m, capture %.2f m): %lld filled, "
                  "%lld with several hypotheses; %lld soundings, %lld node updates",
                  g.nx,
                  g.ny,
                  res,
                  out.median_depth_m,
                  out.capture_distance_m,
                  static_cast<long long>(out.nodes_filled),
                  static_cast<long long>(out.nodes_multiple),
                  static_cast<long long>(out.soundings_used),
                  static_cast<long long>(out.node_updates));
    out.message = buf;
    return out;
}

}  // namespace pitmap::proc::hydro
