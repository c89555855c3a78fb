// SPDX-License-Identifier: MIT
#include "processor/compare/surface.hpp"

#include <algorithm>
#include <limits>

namespace pitmap::proc::compare {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double Bilinear(const SurfaceGrid& s, const std::vector<float>& v, double x, double y) {
    const double gx = (x - s.x0) / s.resolution_m, gy = (y - s.y0) / s.resolution_m;
    if (!(gx >= 0 && gy >= 0 && gx <= s.nx - 1 && gy <= s.ny - 1)) return kNaN;
    const int i = std::min(static_cast<int>(gx), s.nx - 2);
    const int j = std::min(static_cast<int>(gy), s.ny - 2);
    const double u = gx - i, w = gy - j;
    const double a = v[s.index(i, j)], b = v[s.index(i + 1, j)];
    const double c = v[s.index(i, j + 1)], d = v[s.index(i + 1, j + 1)];
    return (a * (1 - u) + b * u) * (1 - w) + (c * (1 - u) + d * u) * w;  // NaN propagates
}

}  // namespace

double SurfaceGrid::HeightAt(double x, double y) const {
    return Bilinear(*this, z_m, x, y);
}

double SurfaceGrid::SigmaAt(double x, double y) const {
    return Bilinear(*this, sigma_m, x, y);
}

double SurfaceGrid::MinDensityAt(double x, double y) const {
    if (density.empty()) return std::numeric_limits<double>::infinity();
    const double gx = (x - x0) / resolution_m, gy = (y - y0) / resolution_m;
    if (!(gx >= 0 && gy >= 0 && gx <= nx - 1 && gy <= ny - 1)) return kNaN;
    const int i = std::min(static_cast<int>(gx), nx - 2);
    const int j = std::min(static_cast<int>(gy), ny - 2);
    return std::min({density[index(i, j)],
                     density[index(i + 1, j)],
                     density[index(i, j + 1)],
                     density[index(i + 1, j + 1)]});
}

std::size_t SurfaceGrid::CountFilled() const {
    return static_cast<std::size_t>(
        std::count_if(z_m.begin(), z_m.end(), [](float v) { return std::isfinite(v); }));
}

SurfaceGrid TentFiltered(const SurfaceGrid& s, int k) {
    if (k <= 1) return s;
    std::vector<double> w;
    for (int i = -(k - 1); i <= k - 1; ++i) w.push_back(static_cast<double>(k - std::abs(i)) / k);
    const int h = k - 1;
    const std::size_t n = s.z_m.size();
    // Along x: weighted sums and weights of the filled nodes; then along y.
    std::vector<double> sum_x(n, 0.0), wt_x(n, 0.0);
    for (int j = 0; j < s.ny; ++j) {
        for (int i = 0; i < s.nx; ++i) {
            double sum = 0, wt = 0;
            for (int d = -h; d <= h; ++d) {
                const int u = i + d;
                if (u < 0 || u >= s.nx) continue;
                const float v = s.z_m[s.index(u, j)];
                if (!std::isfinite(v)) continue;
                sum += w[static_cast<std::size_t>(d + h)] * v;
                wt += w[static_cast<std::size_t>(d + h)];
            }
            sum_x[s.index(i, j)] = sum;
            wt_x[s.index(i, j)] = wt;
        }
    }
    SurfaceGrid out = s;
    for (int j = 0; j < s.ny; ++j) {
        for (int i = 0; i < s.nx; ++i) {
            if (!s.filled(i, j)) continue;
            double sum = 0, wt = 0;
            for (int d = -h; d <= h; ++d) {
                const int v = j + d;
                if (v < 0 || v >= s.ny) continue;
                sum += w[static_cast<std::size_t>(d + h)] * sum_x[s.index(i, v)];
                wt += w[static_cast<std::size_t>(d + h)] * wt_x[s.index(i, v)];
            }
            if (wt > 0) out.z_m[s.index(i, j)] = static_cast<float>(sum / wt);
        }
    }
    return out;
}

SurfaceGrid Smoothed(const SurfaceGrid& s, int r) {
    if (r <= 0) return s;
    SurfaceGrid out = s;
    // Separable box mean over the filled nodes: sums and counts along x, then along y.
    const auto n = s.z_m.size();
    std::vector<double> sum_x(n, 0.0), cnt_x(n, 0.0);
    for (int j = 0; j < s.ny; ++j) {
        double sum = 0, cnt = 0;
        const auto add = [&](int i, double sign) {
            const float v = s.z_m[s.index(i, j)];
            if (std::isfinite(v)) {
                sum += sign * v;
                cnt += sign;
            }
        };
        for (int i = 0; i < std::min(r, s.nx); ++i) add(i, 1);
        for (int i = 0; i < s.nx; ++i) {
            if (i + r < s.nx) add(i + r, 1);
            if (i - r - 1 >= 0) add(i - r - 1, -1);
            sum_x[s.index(i, j)] = sum;
            cnt_x[s.index(i, j)] = cnt;
        }
    }
    for (int i = 0; i < s.nx; ++i) {
        double sum = 0, cnt = 0;
        for (int j = 0; j < std::min(r, s.ny); ++j) {
            sum += sum_x[s.index(i, j)];
            cnt += cnt_x[s.index(i, j)];
        }
        for (int j = 0; j < s.ny; ++j) {
            if (j + r < s.ny) {
                sum += sum_x[s.index(i, j + r)];
                cnt += cnt_x[s.index(i, j + r)];
            }
            if (j - r - 1 >= 0) {
                sum -= sum_x[s.index(i, j - r - 1)];
                cnt -= cnt_x[s.index(i, j - r - 1)];
            }
            const std::size_t k = s.index(i, j);
            if (std::isfinite(s.z_m[k]) && cnt > 0.5) out.z_m[k] = static_cast<float>(sum / cnt);
        }
    }
    return out;
}

Eigen::Vector2d GradientAt(const SurfaceGrid& s, int i, int j, int step) {
    if (i - step < 0 || j - step < 0 || i + step >= s.nx || j + step >= s.ny) return {kNaN, kNaN};
    const double zxm = s.z_m[s.index(i - step, j)], zxp = s.z_m[s.index(i + step, j)];
    const double zym = s.z_m[s.index(i, j - step)], zyp = s.z_m[s.index(i, j + step)];
    const double h = 2.0 * step * s.resolution_m;
    return {(zxp - zxm) / h, (zyp - zym) / h};
}

}  // namespace pitmap::proc::compare
