// SPDX-License-Identifier: MIT
#include "processor/svp/ray_trace.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

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

// Where the ray is between legs: its depth, the horizontal distance so far and the travel time
// still to go.
struct RayPoint {
    double depth_m = 0;
    double horizontal_m = 0;
    double time_left_s = 0;
};

void SetEnd(RayEnd& out,
            RayStatus status,
            double horizontal_m,
            double depth_m,
            double time_s,
            double sin_angle) {
    out.status = status;
    out.horizontal_m = horizontal_m;
    out.depth_m = depth_m;
    out.time_s = time_s;
    out.sin_angle = sin_angle;
}

// The end of the leg from depth z: the next profile depth in the direction of travel, the
// surface upwards, or none (constant speed to infinity) below the last depth.
std::optional<double> LegEndDepth(const std::vector<double>& depth_m, double z, bool down) {
    if (down) {
        const auto it = std::upper_bound(depth_m.begin(), depth_m.end(), z);
        if (it == depth_m.end()) return std::nullopt;
        return *it;
    }
    const auto it = std::lower_bound(depth_m.begin(), depth_m.end(), z);
    double z_end = it == depth_m.begin() ? 0.0 : *(it - 1);
    if (z_end >= z) z_end = 0.0;
    return std::max(0.0, z_end);
}

// Beyond the profile (below its last depth, or above its first on the way up) the speed c is
// constant: a straight segment for the time left, or to the surface if that comes first.
void TraceStraight(
    double p, double c, double k, bool down, double T, const RayPoint& from, RayEnd& out) {
    const double s = p * c;
    const double step = from.time_left_s * c;
    if (!down) {
        const double reach = from.depth_m / std::max(k, 1e-300);
        if (step > reach) {
            SetEnd(out,
                   RayStatus::kSurfaced,
                   from.horizontal_m + s * reach,
                   0,
                   T - from.time_left_s + reach / c,
                   s);
            return;
        }
    }
    SetEnd(out,
           RayStatus::kOk,
           from.horizontal_m + s * step,
           from.depth_m + (down ? 1.0 : -1.0) * k * step,
           T,
           s);
    ++out.layers;
}

// A leg through one layer from z to z_end: its depth extent d and the speed and cos at its far
// end. Where p c reaches 1 inside the layer the ray turns there: c = c_a + g (z - z_a) gives
// d = (1/p - c_a) / g, with c = 1/p and cos = 0 at that end.
struct LayerLeg {
    double d = 0;
    LegEnds far;
    bool turns = false;
};

LayerLeg LegThroughLayer(
    const LayeredProfile& prof, double p, double z, double z_end, const LegEnds& near) {
    LayerLeg leg;
    leg.far = At(prof, p, z_end);
    leg.d = std::abs(z_end - z);
    if (p * leg.far.c >= 1.0) {
        leg.turns = true;
        const double g = (leg.far.c - near.c) / leg.d;
        leg.d = (1.0 / p - near.c) / g;
        if (!(leg.d >= 0)) leg.d = 0;
        leg.far = {1.0 / p, 0.0};
    }
    return leg;
}

// The time runs out inside a leg of extent d_leg: LegTime(d) = time left solved for d in
// [0, d_leg] by Newton steps (dt/dd = 1 / (c k) at the far end) kept inside a bisection bracket.
void EndInsideLeg(const LayeredProfile& prof,
                  double p,
                  bool down,
                  const LegEnds& near,
                  double d_leg,
                  double T,
                  const RayPoint& from,
                  RayEnd& out) {
    const double z = from.depth_m;
    const double left = from.time_left_s;
    const double sgn = down ? 1.0 : -1.0;
    double lo = 0, hi = d_leg;
    double d = std::min(d_leg, left * near.c * near.k);
    for (int it = 0; it < 100 && hi - lo > 1e-10; ++it) {
        const LegEnds e = At(prof, p, z + sgn * d);
        const double f = LegTime(d, near.c, e.c, near.k, e.k) - left;
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
    SetEnd(out,
           RayStatus::kOk,
           from.horizontal_m + LegHorizontal(p, d, near.c, e.c, near.k, e.k),
           z + sgn * d,
           T,
           p * e.c);
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
    const bool down = std::cos(launch) > 0;
    out.depth_m = z0;
    if (std::abs(std::cos(launch)) < 1e-9 || p * prof.SpeedAt(z0) >= 1.0) {
        out.status = RayStatus::kHorizontal;
        return out;
    }
    const std::vector<double>& D = prof.depth_m();
    const std::vector<double>& C = prof.speed_mps();
    RayPoint at{z0, 0.0, T};
    for (int guard = 0; guard < static_cast<int>(D.size()) + 4; ++guard) {
        const LegEnds near = At(prof, p, at.depth_m);
        const std::optional<double> z_end = LegEndDepth(D, at.depth_m, down);
        if (!z_end || (!down && at.depth_m <= D.front())) {
            // Below the last depth the last speed holds, above the first the first.
            TraceStraight(p, down ? C.back() : C.front(), near.k, down, T, at, out);
            return out;
        }
        const LayerLeg leg = LegThroughLayer(prof, p, at.depth_m, *z_end, near);
        const double t_leg = LegTime(leg.d, near.c, leg.far.c, near.k, leg.far.k);
        ++out.layers;
        if (t_leg >= at.time_left_s) {
            EndInsideLeg(prof, p, down, near, leg.d, T, at, out);
            return out;
        }
        at.horizontal_m += LegHorizontal(p, leg.d, near.c, leg.far.c, near.k, leg.far.k);
        at.time_left_s -= t_leg;
        at.depth_m = down ? at.depth_m + leg.d : at.depth_m - leg.d;
        if (leg.turns) {
            SetEnd(out, RayStatus::kTurned, at.horizontal_m, at.depth_m, T - at.time_left_s, 1.0);
            return out;
        }
        if (!down && at.depth_m <= 0.0) {
            SetEnd(
                out, RayStatus::kSurfaced, at.horizontal_m, 0, T - at.time_left_s, p * leg.far.c);
            return out;
        }
    }
    return out;  // kInvalid: more legs than the profile has (a bug guard)
}

}  // namespace pitmap::proc::svp
