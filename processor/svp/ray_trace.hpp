// SPDX-License-Identifier: MIT
// Ray tracing through a layered sound-speed profile (constant gradient between the cast's
// depths; above the first and below the last depth the speed stays constant).
//
// Physics (e.g. Jensen et al., Computational Ocean Acoustics, ch. 3): Snell's law keeps
// p = sin(phi) / c(z) constant along a ray, phi measured from the vertical. In a layer where
// c = c1 + g (z - z1) the ray is a circular arc of radius 1 / (p |g|); between depths z1, z2 of
// one layer (speeds c1, c2, cos(phi) values k1, k2, both taken >= 0, d = |z2 - z1|):
//   horizontal   dx = p (c1 + c2) d / (k1 + k2)                   (= (k1 - k2) / (p g))
//   travel time  dt = ln[c2 (1 + k1) / (c1 (1 + k2))] / g'       (g' = (c2 - c1) / d)
//                   = d B log1p(u) / u,  B = [1 + (c1 + c2) / (c2 k1 + c1 k2)] / (c1 (1 + k2)),
//                     u = (c2 - c1) B,
// the last form being finite for g -> 0 (a straight segment: dt = d / (c k)) and for p -> 0
// (a vertical ray: dt = ln(c2 / c1) / g). Where the one-way travel time runs out inside a layer
// the depth is found by safeguarded Newton iteration on dt(d) (d(dt)/dd = 1 / (c k)).
// A ray that would turn (p c reaches 1) before its time is spent stops with kTurned.
//
// Thread safety: all functions are reentrant; a LayeredProfile is immutable.
#pragma once

#include <vector>

namespace pitmap::proc::svp {

class LayeredProfile {
public:
    LayeredProfile() = default;
    // Preconditions: same sizes, at least one point, depths strictly increasing, speeds > 0.
    LayeredProfile(std::vector<double> depth_m, std::vector<double> speed_mps);
    // Speed at a depth (linear between the points, constant beyond them).
    double SpeedAt(double depth_m) const;
    const std::vector<double>& depth_m() const { return depth_m_; }
    const std::vector<double>& speed_mps() const { return speed_mps_; }
    bool empty() const { return depth_m_.empty(); }

private:
    std::vector<double> depth_m_;
    std::vector<double> speed_mps_;
};

enum class RayStatus {
    kOk = 0,
    kTurned,      // the ray turned (horizontal) before its travel time was spent
    kSurfaced,    // an upward ray reached the water surface (depth 0)
    kHorizontal,  // launched horizontally (or Snell's parameter exceeds 1/c at the start)
    kInvalid,     // non-finite or negative time, empty profile
};
const char* ToString(RayStatus s);

struct RayEnd {
    RayStatus status = RayStatus::kInvalid;
    double horizontal_m = 0;  // distance along the horizontal direction of the launch
    double depth_m = 0;       // depth of the end point below the water surface
    double time_s = 0;        // one-way travel time used
    double sin_angle = 0;     // sin(phi) at the end point (phi from the vertical)
    int layers = 0;           // layer legs crossed (for tests and statistics)
};

// Traces a ray from `start_depth_m` launched at `launch_angle_rad` from the downward vertical
// (0 = straight down, pi/2 = horizontal, > pi/2 = upward) for `one_way_time_s` seconds.
// `start_speed_mps` is the sound speed the launch angle refers to (the speed at the transducer
// face); <= 0 = the profile's speed at the start depth. Snell's parameter is
// p = sin(launch) / start_speed.
RayEnd TraceRay(const LayeredProfile& profile,
                double start_depth_m,
                double launch_angle_rad,
                double one_way_time_s,
                double start_speed_mps = 0);

// One leg inside a constant-gradient layer (the closed forms above), exposed for tests:
// horizontal distance and time over a depth interval d between speeds c1, c2 with
// cos(phi) k1, k2 (>= 0) and Snell parameter p.
double LegHorizontal(double p, double d, double c1, double c2, double k1, double k2);
double LegTime(double d, double c1, double c2, double k1, double k2);

}  // namespace pitmap::proc::svp
