// SPDX-License-Identifier: MIT
#include "tools/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "common/frames.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Closed superellipse loop with half sizes (a, b), starting at (a, 0), counter-clockwise.
std::vector<Eigen::Vector2d> SuperellipseLoop(double a, double b, double p) {
    std::vector<Eigen::Vector2d> pts;
    const int n = 2000;
    for (int i = 0; i <= n; ++i) {
        const double phi = 2 * kPi * i / n;
        const double c = std::cos(phi), s = std::sin(phi);
        pts.emplace_back(a * std::copysign(std::pow(std::abs(c), 2.0 / p), c),
                         b * std::copysign(std::pow(std::abs(s), 2.0 / p), s));
    }
    return pts;
}

void AppendLine(std::vector<Eigen::Vector2d>& pts, const Eigen::Vector2d& to, double step) {
    const Eigen::Vector2d from = pts.back();
    const int n = std::max(1, static_cast<int>(std::ceil((to - from).norm() / step)));
    for (int i = 1; i <= n; ++i) pts.push_back(from + (to - from) * (static_cast<double>(i) / n));
}

// Rounds corners: repeated Chaikin corner cutting keeps the path within the original polygon.
std::vector<Eigen::Vector2d> Chaikin(const std::vector<Eigen::Vector2d>& in, int iterations) {
    std::vector<Eigen::Vector2d> cur = in;
    for (int it = 0; it < iterations; ++it) {
        std::vector<Eigen::Vector2d> next;
        next.reserve(cur.size() * 2);
        next.push_back(cur.front());
        for (std::size_t i = 0; i + 1 < cur.size(); ++i) {
            next.push_back(0.75 * cur[i] + 0.25 * cur[i + 1]);
            next.push_back(0.25 * cur[i] + 0.75 * cur[i + 1]);
        }
        next.push_back(cur.back());
        cur.swap(next);
    }
    return cur;
}

std::vector<Eigen::Vector2d> ResampleByArcLength(const std::vector<Eigen::Vector2d>& in,
                                                 double step) {
    std::vector<Eigen::Vector2d> out{in.front()};
    double carried = 0;  // arc length since the last output point
    for (std::size_t i = 0; i + 1 < in.size(); ++i) {
        const Eigen::Vector2d a = in[i], b = in[i + 1];
        const double len = (b - a).norm();
        double pos = step - carried;
        while (pos <= len) {
            out.push_back(a + (b - a) * (pos / len));
            pos += step;
        }
        carried = len - (pos - step);
    }
    return out;
}

// kStar: star_lines lines through the pit centre at directions 180 k / n deg, alternating in
// direction so that each starts near where the previous one ended (each end `offset` from the
// shore); appended to `pts` (joined by a straight leg to its last point). With an even number
// of lines every other repetition (`repetition` odd) runs them backwards, so that it too starts
// next to where the last one ended.
void AppendStar(std::vector<Eigen::Vector2d>& pts,
                const PitConfig& pit,
                const TrackConfig& tr,
                int repetition) {
    const int n = tr.star_lines;
    const bool backwards = n % 2 == 0 && repetition % 2 == 1;
    for (int k = 0; k < n; ++k) {
        const double dir = 180.0 * k / n;
        Eigen::Vector2d a = PointFromShore(pit, dir, tr.first_lap_offset_m);
        Eigen::Vector2d b = PointFromShore(pit, dir + 180.0, tr.first_lap_offset_m);
        if ((k % 2 == 1) != backwards) std::swap(a, b);
        if (pts.empty()) {
            pts.push_back(a);
        } else {
            AppendLine(pts, a, 0.5);
        }
        AppendLine(pts, b, 0.5);
    }
}

// The largest |y| <= the pit's half width at which (x, +-y) lies `offset` from the shore.
double ZigzagReach(const PitConfig& pit, double x, double offset) {
    double y = pit.half_width_m - offset;
    while (y > 0.5 &&
           (DistanceFromShore(pit, x, y) < offset || DistanceFromShore(pit, x, -y) < offset))
        y -= 0.25;
    return std::max(y, 0.0);
}

// kZigzag: legs between the south and north reaches from the west end to the east end, then
// back with the turning points half a leg shifted so that the legs cross the first pass's. Each
// turning point is a short run along x (a quarter of the legs' spacing, at most two turn radii)
// so that the boat turns twice by about 90 deg instead of reversing at once.
void AppendZigzag(std::vector<Eigen::Vector2d>& pts, const PitConfig& pit, const TrackConfig& tr) {
    const double off = tr.first_lap_offset_m;
    double xe = pit.half_length_m - off;
    while (xe > 1.0 && DistanceFromShore(pit, xe, 0.0) < off + 3.0) xe -= 0.5;
    const int n = tr.zigzag_legs;
    const double half_run = 0.5 * std::min(2.0 * tr.turn_radius_m, 0.25 * 2.0 * xe / n);
    // The turning point at u in [0, 1] (west to east), south for even k, run towards `east`.
    const auto turn = [&](double u, int k, bool east) {
        const double x = -xe + 2.0 * xe * u;
        const double sign = (k % 2 == 0) ? -1.0 : 1.0;
        const double from = std::max(-xe, x - half_run), to = std::min(xe, x + half_run);
        const double a = east ? from : to, b = east ? to : from;
        const Eigen::Vector2d pa(a, sign * ZigzagReach(pit, a, off));
        if (pts.empty()) {
            pts.push_back(pa);
        } else {
            AppendLine(pts, pa, 0.5);
        }
        AppendLine(pts, Eigen::Vector2d(b, sign * ZigzagReach(pit, b, off)), 0.5);
    };
    for (int k = 0; k <= n; ++k) turn(static_cast<double>(k) / n, k, true);
    // Back: turning points at (k + 0.5) / n, on the opposite side to the first pass's nearest.
    for (int k = n - 1; k >= 0; --k) turn((k + 0.5) / n, k + 1, false);
}

}  // namespace

Expected<SurveyTrack> SurveyTrack::Plan(const ScenarioConfig& sc) {
    const PitConfig& pit = sc.pit;
    const TrackConfig& tr = sc.track;
    const double p = pit.superellipse_exponent;
    const double min_half = std::min(pit.half_length_m, pit.half_width_m);
    std::vector<Eigen::Vector2d> coarse;
    auto add_laps = [&]() {
        for (int k = 0; k < tr.num_laps; ++k) {
            const double off = tr.first_lap_offset_m + k * tr.lap_spacing_m;
            if (off >= min_half - 1.0) break;
            auto loop = SuperellipseLoop(pit.half_length_m - off, pit.half_width_m - off, p);
            if (tr.clockwise) std::reverse(loop.begin(), loop.end());
            if (coarse.empty()) {
                coarse.push_back(loop.front());
            } else {
                AppendLine(coarse, loop.front(), 0.5);
            }
            coarse.insert(coarse.end(), loop.begin() + 1, loop.end());
        }
        // Tie lines across the long axis, alternating direction, spread over the width.
        const double inner = tr.first_lap_offset_m;
        for (int i = 0; i < tr.num_tie_lines; ++i) {
            const double y = (tr.num_tie_lines == 1) ? 0.0
                                                     : (pit.half_width_m - inner - 6.0) *
                                                           (2.0 * i / (tr.num_tie_lines - 1) - 1.0);
            double xe = pit.half_length_m - inner;
            // Keep the ends inside the lap: shrink until the shore is far enough.
            while (xe > 1.0 && DistanceFromShore(pit, xe, y) < inner) xe -= 0.5;
            const Eigen::Vector2d a((i % 2 == 0) ? xe : -xe, y), b((i % 2 == 0) ? -xe : xe, y);
            AppendLine(coarse, a, 0.5);
            AppendLine(coarse, b, 0.5);
        }
    };
    int repetition = 0;
    const auto add_pattern = [&]() {
        switch (tr.pattern) {
            case TrackPattern::kLaps:
                add_laps();
                break;
            case TrackPattern::kStar:
                AppendStar(coarse, pit, tr, repetition);
                break;
            case TrackPattern::kZigzag:
                AppendZigzag(coarse, pit, tr);
                break;
        }
        ++repetition;
    };
    add_pattern();
    if (coarse.size() < 2) return Error{"track: no lap fits inside the pit"};
    // Repeat the pattern until it is long enough for the requested duration.
    auto length = [&]() {
        double l = 0;
        for (std::size_t i = 0; i + 1 < coarse.size(); ++i) l += (coarse[i + 1] - coarse[i]).norm();
        return l;
    };
    const double needed = tr.duration_s * tr.speed_mps + 5.0;
    for (int rep = 0; rep < 20 && tr.duration_s > 0 && length() < needed; ++rep) add_pattern();

    SurveyTrack track;
    // Corner cutting on a polyline of turn_radius-long pieces rounds each corner to about that
    // radius (the limit of Chaikin's scheme is a quadratic B-spline through the piece midpoints).
    const double piece = std::max(1.0, 1.5 * tr.turn_radius_m);
    std::vector<Eigen::Vector2d> smooth = Chaikin(ResampleByArcLength(coarse, piece), 5);
    track.points_ = ResampleByArcLength(smooth, track.spacing_m_);
    if (track.points_.size() < 2) return Error{"track: degenerate path"};
    return track;
}

Eigen::Vector2d SurveyTrack::PositionAt(double s) const {
    // Catmull-Rom through the 0.1 m samples: C1, so heading and yaw rate are continuous.
    const double u = std::clamp(s / spacing_m_, 0.0, static_cast<double>(points_.size() - 1));
    const auto n = static_cast<std::ptrdiff_t>(points_.size());
    const auto i = std::min(static_cast<std::ptrdiff_t>(u), n - 2);
    const double f = u - static_cast<double>(i);
    const auto at = [&](std::ptrdiff_t k) {
        return points_[static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(k, 0, n - 1))];
    };
    const Eigen::Vector2d p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
    const double f2 = f * f, f3 = f2 * f;
    return 0.5 * ((2.0 * p1) + (p2 - p0) * f + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2 +
                  (3.0 * p1 - p0 - 3.0 * p2 + p3) * f3);
}

double SurveyTrack::HeadingAt(double s) const {
    // Tangent over +-1 m for a smooth heading; heading is clockwise from north (the y axis).
    const Eigen::Vector2d d = PositionAt(s + 1.0) - PositionAt(s - 1.0);
    return std::atan2(d.x(), d.y());
}

TruthTrajectory::TruthTrajectory(const ScenarioConfig& sc, SurveyTrack track)
    : cfg_(sc.track), track_(std::move(track)) {
    const double full = track_.length_m() / cfg_.speed_mps;
    duration_s_ = cfg_.duration_s > 0 ? std::min(cfg_.duration_s, full) : full;
    std::mt19937_64 rng(sc.seed ^ 0x7A7Eull);
    std::uniform_real_distribution<double> u(0, 2 * kPi);
    for (double& ph : phase_) ph = u(rng);
}

Pose TruthTrajectory::PoseAt(double t) const {
    const double s = cfg_.speed_mps * t;
    const Eigen::Vector2d xy = track_.PositionAt(s);
    const double w = 2 * kPi / cfg_.wave_period_s;
    // Two incommensurate components per axis make the motion look irregular.
    const double roll =
        frames::DegToRad(cfg_.roll_amplitude_deg) *
        (0.8 * std::sin(w * t + phase_[0]) + 0.2 * std::sin(1.63 * w * t + phase_[1]));
    const double pitch =
        frames::DegToRad(cfg_.pitch_amplitude_deg) *
        (0.8 * std::sin(1.21 * w * t + phase_[2]) + 0.2 * std::sin(2.1 * w * t + phase_[3]));
    const double heave = cfg_.heave_amplitude_m * (0.7 * std::sin(0.93 * w * t + phase_[4]) +
                                                   0.3 * std::sin(1.7 * w * t + phase_[5]));
    const double yaw = track_.HeadingAt(s) + frames::DegToRad(cfg_.yaw_oscillation_deg) *
                                                 std::sin(0.37 * w * t + phase_[1]);
    return MakePose(frames::RotationWorldFromRpy(roll, pitch, yaw),
                    Eigen::Vector3d(xy.x(), xy.y(), heave));
}

TruthState TruthTrajectory::StateAt(double t) const {
    constexpr double h = 1e-3;
    const Pose a = PoseAt(t - h), b = PoseAt(t), c = PoseAt(t + h);
    TruthState st;
    st.t_s = t;
    st.T_world_vehicle = b;
    st.velocity_world = (c.translation() - a.translation()) / (2 * h);
    st.acceleration_world = (c.translation() - 2 * b.translation() + a.translation()) / (h * h);
    // Body rates: R(t+h) = R(t) Exp(omega h)  ->  omega = Log(R(t-h)^T R(t+h)) / (2h).
    st.angular_rate_vehicle = LogSO3(a.linear().transpose() * c.linear()) / (2 * h);
    return st;
}

}  // namespace pitmap::sim
