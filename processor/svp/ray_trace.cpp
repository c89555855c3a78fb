// SPDX-License-Identifier: MIT
#include "processor/svp/ray_trace.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/result.hpp"

namespace pitmap::proc::svp {

LayeredProfile::LayeredProfile(std::vector<double> depth_m, std::vector<double> speed_mps)
    : depth_m_(std::move(depth_m)), speed_mps_(std::move(speed_mps)) {
    PITMAP_CHECK(!depth_m_.empty() && depth_m_.size() == speed_mps_.size(),
                 "LayeredProfile: depths and speeds must be non-empty and of one size");
    for (std::size_t i = 0; i < depth_m_.size(); ++i) {
        PITMAP_CHECK(speed_mps_[i] > 0, "LayeredProfile: speeds must be > 0");
        PITMAP_CHECK(i == 0 || depth_m_[i] > depth_m_[i - 1],
                     "LayeredProfile: depths must increase");
    }
}

double LayeredProfile::SpeedAt(double z) const {
    if (depth_m_.empty()) return 0.0;
    if (z <= depth_m_.front()) return speed_mps_.front();
    if (z >= depth_m_.back()) return speed_mps_.back();
    const auto it = std::upper_bound(depth_m_.begin(), depth_m_.end(), z);
    const std::size_t i = static_cast<std::size_t>(it - depth_m_.begin());
    const double a = (z - depth_m_[i - 1]) / (depth_m_[i] - depth_m_[i - 1]);
    return speed_mps_[i - 1] + a * (speed_mps_[i] - speed_mps_[i - 1]);
}

const char* ToString(RayStatus s) {
    switch (s) {
        case RayStatus::kOk:
            return "ok";
        case RayStatus::kTurned:
            return "turned";
        case RayStatus::kSurfaced:
            return "surfaced";
        case RayStatus::kHorizontal:
            return "horizontal";
        case RayStatus::kInvalid:
            return "invalid";
    }
    return "?";
}

double LegHorizontal(double p, double d, double c1, double c2, double k1, double k2) {
    const double k = k1 + k2;
    if (!(k > 0)) return 0.0;
    return p * (c1 + c2) * d / k;
}

double LegTime(double d, double c1, double c2, double k1, double k2) {
    if (d <= 0) return 0.0;
    const double den = c2 * k1 + c1 * k2;
    if (!(den > 0)) return std::numeric_limits<double>::infinity();
    // Relative speed change below 1e-12: a straight segment (g ~ 0).
    if (std::abs(c2 - c1) <= 1e-12 * c1) return d / (0.5 * (c1 + c2) * 0.5 * (k1 + k2));
    const double B = (1.0 + (c1 + c2) / den) / (c1 * (1.0 + k2));
    const double u = (c2 - c1) * B;
    // log1p(u) / u, with its series where u is tiny.
    const double f = std::abs(u) < 1e-8 ? 1.0 - 0.5 * u + u * u / 3.0 : std::log1p(u) / u;
    return d * B * f;
}

namespace {

struct LegEnds {
    double c = 0;  // speed at the point
    double k = 0;  // cos(phi) at the point, >= 0
};

LegEnds At(const LayeredProfile& prof, double p, double z) {
    const double c = prof.SpeedAt(z);
    const double s = std::min(1.0, p * c);
    return {c, std::sqrt(std::max(0.0, (1.0 - s) * (1.0 + s)))};
}

}  // namespace

RayEnd TraceRay(
    const LayeredProfile& prof, double z0, double launch, double T, double start_speed) {
    RayEnd out;
    if (prof.empty() || !std::isfinite(z0) || !std::isfinite(launch) || !std::isfinite(T) ||
        T < 0) {
        return out;
    }
    const double c0 = start_speed > 0 ? start_speed : prof.SpeedAt(z0);
    const double p = std::abs(std::sin(launch)) / c0;
    const bool down0 = std::cos(launch) > 0;
    out.depth_m = z0;
    if (std::abs(std::cos(launch)) < 1e-9 || p * prof.SpeedAt(z0) >= 1.0) {
        out.status = RayStatus::kHorizontal;
        return out;
    }
    const std::vector<double>& D = prof.depth_m();
    const std::vector<double>& C = prof.speed_mps();
    double z = z0, x = 0, left = T;
    const bool down = down0;
    for (int guard = 0; guard < static_cast<int>(D.size()) + 4; ++guard) {
        const LegEnds a = At(prof, p, z);
        // The end of this leg: the next profile depth in the direction of travel, the surface
        // upwards, or nothing (constant speed to infinity) below the last depth.
        double z_end = 0;
        bool unbounded = false;
        if (down) {
            const auto it = std::upper_bound(D.begin(), D.end(), z);
            if (it == D.end()) {
                unbounded = true;
            } else {
                z_end = *it;
            }
        } else {
            const auto it = std::lower_bound(D.begin(), D.end(), z);
            z_end = it == D.begin() ? 0.0 : *(it - 1);
            if (z_end >= z) z_end = 0.0;
            z_end = std::max(0.0, z_end);
        }
        if (unbounded || (!down && z <= D.front())) {
            // Constant speed from here on: a straight segment.
            const double c = unbounded ? C.back() : C.front();
            const double s = p * c, k = a.k;
            double step = left * c;
            if (!down) {
                const double reach = (z - 0.0) / std::max(k, 1e-300);
                if (step > reach) {
                    out.status = RayStatus::kSurfaced;
                    out.horizontal_m = x + s * reach;
                    out.depth_m = 0;
                    out.time_s = T - left + reach / c;
                    out.sin_angle = s;
                    return out;
                }
            }
            out.horizontal_m = x + s * step;
            out.depth_m = z + (down ? 1.0 : -1.0) * k * step;
            out.time_s = T;
            out.sin_angle = s;
            out.status = RayStatus::kOk;
            ++out.layers;
            return out;
        }
        LegEnds b = At(prof, p, z_end);
        bool turns = false;
        double d_leg = std::abs(z_end - z);
        if (p * b.c >= 1.0) {
            // The ray turns inside the layer where p c = 1: c = c_a + g (z - z_a).
            turns = true;
            const double g = (b.c - a.c) / d_leg;
            d_leg = (1.0 / p - a.c) / g;
            if (!(d_leg >= 0)) d_leg = 0;
            b = {1.0 / p, 0.0};
        }
        const double t_leg = LegTime(d_leg, a.c, b.c, a.k, b.k);
        ++out.layers;
        if (t_leg >= left) {
            // The time runs out in this leg: solve LegTime(d) = left for d in [0, d_leg].
            const double sgn = down ? 1.0 : -1.0;
            double lo = 0, hi = d_leg;
            double d = std::min(d_leg, left * a.c * a.k);
            for (int it = 0; it < 100 && hi - lo > 1e-10; ++it) {
                const LegEnds e = At(prof, p, z + sgn * d);
                const double f = LegTime(d, a.c, e.c, a.k, e.k) - left;
                if (f > 0) {
                    hi = d;
                } else {
                    lo = d;
                }
                if (std::abs(f) < 1e-13) break;
                double next = d - f * e.c * e.k;
                if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
                d = next;
            }
            const LegEnds e = At(prof, p, z + sgn * d);
            out.horizontal_m = x + LegHorizontal(p, d, a.c, e.c, a.k, e.k);
            out.depth_m = z + sgn * d;
            out.time_s = T;
            out.sin_angle = p * e.c;
            out.status = RayStatus::kOk;
            return out;
        }
        x += LegHorizontal(p, d_leg, a.c, b.c, a.k, b.k);
        left -= t_leg;
        z = down ? z + d_leg : z - d_leg;
        if (turns) {
            out.status = RayStatus::kTurned;
            out.horizontal_m = x;
            out.depth_m = z;
            out.time_s = T - left;
            out.sin_angle = 1.0;
            return out;
        }
        if (!down && z <= 0.0) {
            out.status = RayStatus::kSurfaced;
            out.horizontal_m = x;
            out.depth_m = 0;
            out.time_s = T - left;
            out.sin_angle = p * b.c;
            return out;
        }
    }
    return out;  // kInvalid: more legs than the profile has (a bug guard)
}

}  // namespace pitmap::proc::svp
