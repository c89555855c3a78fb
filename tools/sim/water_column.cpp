// SPDX-License-Identifier: MIT
#include "tools/sim/water_column.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pitmap::sim {

WaterColumn::WaterColumn(const WaterColumnConfig& config, double max_depth_m)
    : config_(config), max_depth_m_(std::max(1.0, max_depth_m)) {
    double c_min = std::numeric_limits<double>::infinity();
    for (double z = 0; z <= max_depth_m_ + 1e-9; z += 0.01) c_min = std::min(c_min, SpeedAt(z));
    dp_ = (1.0 / c_min) / (kNumP - 1);
    nodes_ = static_cast<int>(std::ceil(max_depth_m_ / kNodeM)) + 1;
    x_.assign(static_cast<std::size_t>(kNumP) * static_cast<std::size_t>(nodes_), 0.0);
    t_.assign(x_.size(), 0.0);
    constexpr int kSub = 50;  // 5 mm midpoint steps per 0.25 m node
    const double dz = kNodeM / kSub;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (int i = 0; i < kNumP; ++i) {
        const double p = i * dp_;
        double x = 0, t = 0;
        bool turned = false;
        double* xi = &x_[static_cast<std::size_t>(i) * static_cast<std::size_t>(nodes_)];
        double* ti = &t_[static_cast<std::size_t>(i) * static_cast<std::size_t>(nodes_)];
        for (int k = 1; k < nodes_; ++k) {
            for (int j = 0; j < kSub && !turned; ++j) {
                const double zm = (k - 1) * kNodeM + (j + 0.5) * dz;
                const double c = SpeedAt(zm);
                const double s = p * c;
                if (s >= 0.999999) {
                    turned = true;
                    break;
                }
                const double cs = std::sqrt((1 - s) * (1 + s));
                x += dz * s / cs;
                t += dz / (c * cs);
            }
            xi[k] = turned ? nan : x;
            ti[k] = turned ? nan : t;
        }
    }
}

double WaterColumn::At(const std::vector<double>& table, double p, double z) const {
    const double u = std::clamp(p / dp_, 0.0, static_cast<double>(kNumP - 1));
    const int i = std::min(static_cast<int>(u), kNumP - 2);
    const double a = u - i;
    const double v = std::clamp(z / kNodeM, 0.0, static_cast<double>(nodes_ - 1));
    const int k = std::min(static_cast<int>(v), nodes_ - 2);
    const double b = v - k;
    const auto n = static_cast<std::size_t>(nodes_);
    const double* r0 = &table[static_cast<std::size_t>(i) * n];
    const double* r1 = r0 + n;
    const double f0 = r0[k] + b * (r0[k + 1] - r0[k]);
    const double f1 = r1[k] + b * (r1[k + 1] - r1[k]);
    return f0 + a * (f1 - f0);
}

std::optional<CurvedHit> WaterColumn::Cast(const PitWorld& world,
                                           const Eigen::Vector3d& origin,
                                           const Eigen::Vector3d& dir,
                                           double max_time_s) const {
    const double z0 = std::max(0.0, -origin.z());
    const double c0 = SpeedAt(z0);
    const double k0 = -dir.z();  // cos of the angle from the downward vertical
    if (k0 < 1e-3 || z0 >= max_depth_m_) {
        // Upwards or horizontal: within the mixed layer, straight.
        auto r = world.RayCast(origin, dir, max_time_s * c0);
        if (!r) return std::nullopt;
        return CurvedHit{*r / c0, origin + *r * dir};
    }
    const double s0 = std::hypot(dir.x(), dir.y());
    const Eigen::Vector2d h =
        s0 > 1e-12 ? Eigen::Vector2d(dir.x() / s0, dir.y() / s0) : Eigen::Vector2d(1, 0);
    const double p = s0 / c0;
    if (p > dp_ * (kNumP - 1)) return std::nullopt;  // beyond the table: a turning ray
    const double x0 = At(x_, p, z0), t0 = At(t_, p, z0);
    Eigen::Vector3d prev = origin;
    double t_prev = 0;
    for (int k = static_cast<int>(std::floor(z0 / kNodeM)) + 1; k < nodes_; ++k) {
        const double zk = k * kNodeM;
        const double xk = At(x_, p, zk) - x0, tk = At(t_, p, zk) - t0;
        if (!std::isfinite(xk) || !std::isfinite(tk)) return std::nullopt;  // turned
        const Eigen::Vector3d next(origin.x() + h.x() * xk, origin.y() + h.y() * xk, -zk);
        const Eigen::Vector3d seg = next - prev;
        const double len = seg.norm();
        if (len > 0) {
            if (auto r = world.RayCast(prev, seg / len, len)) {
                const double t = t_prev + (*r / len) * (tk - t_prev);
                if (t > max_time_s) return std::nullopt;
                return CurvedHit{t, prev + *r * (seg / len)};
            }
        }
        if (tk > max_time_s) return std::nullopt;
        prev = next;
        t_prev = tk;
    }
    return std::nullopt;
}

std::vector<std::pair<double, double>> WaterColumn::Sampled(double spacing_m,
                                                            double max_depth_m) const {
    std::vector<std::pair<double, double>> out;
    const int n = static_cast<int>(std::floor(max_depth_m / spacing_m + 1e-9));
    for (int i = 0; i <= n; ++i) out.emplace_back(i * spacing_m, SpeedAt(i * spacing_m));
    return out;
}

}  // namespace pitmap::sim
