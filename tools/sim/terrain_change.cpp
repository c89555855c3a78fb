// SPDX-License-Identifier: MIT
#include "tools/sim/terrain_change.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pitmap::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// The point's local (u, v) coordinates in the part's frame.
Eigen::Vector2d Local(const ChangePart& p, double x, double y) {
    const double c = std::cos(p.heading_deg * kDegToRad), s = std::sin(p.heading_deg * kDegToRad);
    const double dx = x - p.x_m, dy = y - p.y_m;
    return {c * dx + s * dy, -s * dx + c * dy};
}

Eigen::Vector2d World(const ChangePart& p, double u, double v) {
    const double c = std::cos(p.heading_deg * kDegToRad), s = std::sin(p.heading_deg * kDegToRad);
    return {p.x_m + c * u - s * v, p.y_m + s * u + c * v};
}

// Half the extent of the part's outline along u and v (a bounding box in local axes).
Eigen::Vector2d HalfExtent(const ChangePart& p) {
    switch (p.shape) {
        case ChangeShape::kParaboloid:
            return {p.a_m, p.b_m};
        case ChangeShape::kFrustum:
            return {p.b_m, p.b_m};
        case ChangeShape::kBox:
            return {p.a_m + p.ramp_m, p.b_m + p.ramp_m};
    }
    return {0, 0};
}

}  // namespace

bool PartsApart(const ChangePart& a, const ChangePart& b, double gap_m) {
    // a's outline grown by gap_m, sampled every 0.05 m in a's frame, against b's profile.
    const Eigen::Vector2d h = HalfExtent(a) + Eigen::Vector2d::Constant(gap_m);
    constexpr double kStep = 0.05;
    const auto near_a = [&](double x, double y) {
        if (a.Profile(x, y) > 0) return true;
        for (int r = 1; r <= 4; ++r) {
            for (int k = 0; k < 16; ++k) {
                const double phi = k * kPi / 8, d = gap_m * r / 4;
                if (a.Profile(x + d * std::cos(phi), y + d * std::sin(phi)) > 0) return true;
            }
        }
        return false;
    };
    for (double u = -h.x(); u <= h.x(); u += kStep) {
        for (double v = -h.y(); v <= h.y(); v += kStep) {
            const Eigen::Vector2d q = World(a, u, v);
            if (b.Profile(q.x(), q.y()) > 0 && near_a(q.x(), q.y())) return false;
        }
    }
    return true;
}

const char* ToString(ChangeShape s) {
    switch (s) {
        case ChangeShape::kParaboloid:
            return "paraboloid";
        case ChangeShape::kFrustum:
            return "frustum";
        case ChangeShape::kBox:
            return "box";
    }
    return "?";
}

double ChangePart::Profile(double x, double y) const {
    const Eigen::Vector2d l = Local(*this, x, y);
    switch (shape) {
        case ChangeShape::kParaboloid: {
            const double q = 1.0 - (l.x() / a_m) * (l.x() / a_m) - (l.y() / b_m) * (l.y() / b_m);
            return std::max(0.0, q);
        }
        case ChangeShape::kFrustum:
            return std::clamp((b_m - l.norm()) / (b_m - a_m), 0.0, 1.0);
        case ChangeShape::kBox: {
            const auto p = [this](double s, double half) {
                return std::clamp((half + ramp_m - std::abs(s)) / ramp_m, 0.0, 1.0);
            };
            return p(l.x(), a_m) * p(l.y(), b_m);
        }
    }
    return 0.0;
}

double ChangePart::AnalyticVolume() const {
    const double t = thickness_m;
    switch (shape) {
        case ChangeShape::kParaboloid:
            return kPi * a_m * b_m * t / 2.0;
        case ChangeShape::kFrustum:
            return kPi * t * (a_m * a_m + a_m * b_m + b_m * b_m) / 3.0;
        case ChangeShape::kBox:
            return t * (2 * a_m + ramp_m) * (2 * b_m + ramp_m);
    }
    return 0.0;
}

std::vector<Eigen::Vector2d> ChangePart::Outline(int vertices) const {
    std::vector<Eigen::Vector2d> ring;
    if (shape == ChangeShape::kBox) {
        const double A = a_m + ramp_m, B = b_m + ramp_m;
        for (const auto& [u, v] : {std::pair{-A, -B}, {A, -B}, {A, B}, {-A, B}})
            ring.push_back(World(*this, u, v));
    } else {
        // Circumscribed: the polygon's edges touch the ellipse, so every changed point is in.
        const Eigen::Vector2d h = HalfExtent(*this) / std::cos(kPi / vertices);
        for (int k = 0; k < vertices; ++k) {
            const double phi = 2 * kPi * k / vertices;
            ring.push_back(World(*this, h.x() * std::cos(phi), h.y() * std::sin(phi)));
        }
    }
    ring.push_back(ring.front());
    return ring;
}

std::vector<std::string> ChangePart::Validate() const {
    std::vector<std::string> p;
    const std::string me = "change part '" + name + "': ";
    if (name.empty()) p.push_back("change part: needs a name");
    if (!(a_m > 0) || !(b_m > 0)) p.push_back(me + "a_m and b_m must be > 0");
    if (shape == ChangeShape::kFrustum && !(b_m > a_m))
        p.push_back(me + "a frustum's base radius b_m must exceed its top radius a_m");
    if (shape == ChangeShape::kBox && !(ramp_m > 0)) p.push_back(me + "a box needs ramp_m > 0");
    if (!std::isfinite(thickness_m) || thickness_m == 0 || std::abs(thickness_m) > 20)
        p.push_back(me + "thickness_m must be non-zero and within +-20 m");
    if (!std::isfinite(x_m) || !std::isfinite(y_m) || !std::isfinite(heading_deg))
        p.push_back(me + "centre and heading must be finite");
    return p;
}

std::vector<float> ChangeGrid(const TerrainGrid& grid, const std::vector<ChangePart>& parts) {
    std::vector<float> delta(grid.height_m.size(), 0.0f);
    for (const ChangePart& part : parts) {
        // Only the nodes inside the part's bounding circle.
        const double reach = HalfExtent(part).norm();
        const int i0 =
            std::max(0, static_cast<int>((part.x_m - reach - grid.x0_m) / grid.resolution_m));
        const int i1 = std::min(
            grid.nx - 1, static_cast<int>((part.x_m + reach - grid.x0_m) / grid.resolution_m) + 1);
        const int j0 =
            std::max(0, static_cast<int>((part.y_m - reach - grid.y0_m) / grid.resolution_m));
        const int j1 = std::min(
            grid.ny - 1, static_cast<int>((part.y_m + reach - grid.y0_m) / grid.resolution_m) + 1);
        for (int j = j0; j <= j1; ++j) {
            for (int i = i0; i <= i1; ++i) {
                const double d = part.Delta(grid.x0_m + i * grid.resolution_m,
                                            grid.y0_m + j * grid.resolution_m);
                delta[static_cast<std::size_t>(j) * static_cast<std::size_t>(grid.nx) +
                      static_cast<std::size_t>(i)] += static_cast<float>(d);
            }
        }
    }
    return delta;
}

double GridVolume(const TerrainGrid& grid, const ChangePart& part) {
    const std::vector<float> d = ChangeGrid(grid, {part});
    double sum = 0;
    for (float v : d) sum += v;
    return sum * grid.resolution_m * grid.resolution_m;
}

std::vector<ChangePart> DefaultChanges(const PitConfig& pit, const PitWorld* ground) {
    // Laid out on the quarry (70 m x 50 m, 14 m floor) and scaled to other pits.
    const double sx = pit.half_length_m / 35.0, sy = pit.half_width_m / 25.0;
    const double s = std::min(sx, sy);
    std::vector<ChangePart> parts;
    // The slump: a scar on the deepest face at 80 deg, 1 m deep (vertically) at its centre,
    // its material in a lobe on the floor at the face's foot.
    const double direction = 80.0;
    const FaceSpan face = DeepestFace(pit, direction);
    const double face_width = face.foot_m - face.top_m;
    ChangePart scar;
    scar.name = "slump_scar";
    scar.change = "slump";
    scar.shape = ChangeShape::kParaboloid;
    const Eigen::Vector2d c_scar = PointFromShore(pit, direction, face.top_m + 0.55 * face_width);
    scar.x_m = c_scar.x();
    scar.y_m = c_scar.y();
    scar.heading_deg = direction + 90.0;  // u along the face, v down the slope
    scar.a_m = 4.0 * s;
    scar.b_m = 0.3 * face_width;
    scar.thickness_m = -1.0;
    ChangePart toe;
    toe.name = "slump_toe";
    toe.change = "slump";
    toe.shape = ChangeShape::kParaboloid;
    toe.b_m = 2.2 * s;
    const Eigen::Vector2d c_toe = PointFromShore(pit, direction, face.foot_m + toe.b_m);
    toe.x_m = c_toe.x();
    toe.y_m = c_toe.y();
    toe.heading_deg = scar.heading_deg;
    toe.a_m = 5.0 * s;
    // The lobe holds what the scar lost: pi a b t / 2 equal on both sides.
    toe.thickness_m = -scar.AnalyticVolume() * 2.0 / (kPi * toe.a_m * toe.b_m);
    parts.push_back(scar);
    parts.push_back(toe);
    // A heap of backfill dumped on the floor (sides at 35 deg, 0.6 m high) ...
    ChangePart heap;
    heap.name = "backfill";
    heap.change = "backfill";
    heap.shape = ChangeShape::kFrustum;
    heap.x_m = -9.0 * sx;
    heap.y_m = 1.5 * sy;
    heap.thickness_m = 0.6;
    heap.b_m = 3.0 * s;
    heap.a_m = heap.b_m - heap.thickness_m / std::tan(35.0 * kDegToRad);
    parts.push_back(heap);
    // ... a thin spill of fines beside it (0.2 m) ...
    ChangePart spill;
    spill.name = "spill";
    spill.change = "spill";
    spill.shape = ChangeShape::kFrustum;
    spill.x_m = 11.0 * sx;
    spill.y_m = 2.0 * sy;
    spill.thickness_m = 0.2;
    spill.b_m = 3.0 * s;
    spill.a_m = spill.b_m - 0.5 * s;
    parts.push_back(spill);
    // ... and a cut the mining vehicle made in the floor: 4 m x 3 m, 0.35 m deep, sides
    // 0.5 m wide.
    ChangePart cut;
    cut.name = "cut";
    cut.change = "cut";
    cut.shape = ChangeShape::kBox;
    cut.x_m = 1.0 * sx;
    cut.y_m = -2.0 * sy;
    cut.heading_deg = 20.0;
    cut.a_m = 2.0 * s;
    cut.b_m = 1.5 * s;
    cut.ramp_m = 0.5 * s;
    cut.thickness_m = -0.35;
    parts.push_back(cut);
    // Parts apart: a survey sees the net change, so where two parts overlap neither's volume
    // can be measured alone (on bejanca, scaled from the quarry's layout, the slump's toe ran
    // 0.5 m into the cut's side: 6.4 m^2 where the toe's +0.36 m^3 and the cut's -1.24 m^3 net
    // out). Each part after the slump, in order, that comes within kPartGapM of an earlier one
    // is moved to the nearest place (rings of 0.25 m around it, 24 directions, the direction
    // away from that part first) where it is apart from every earlier one and, given the
    // ground, still on the floor (slope at its centre below kFloorSlopeDeg, its outline under
    // water).
    constexpr double kPartGapM = 1.0, kFloorSlopeDeg = 30.0;
    for (std::size_t i = 2; i < parts.size(); ++i) {
        const auto clash = [&](const ChangePart& p) -> const ChangePart* {
            for (std::size_t k = 0; k < i; ++k) {
                if (!PartsApart(p, parts[k], kPartGapM)) return &parts[k];
            }
            return nullptr;
        };
        const ChangePart* first = clash(parts[i]);
        if (first == nullptr) continue;
        const auto on_floor = [&](const ChangePart& p) {
            if (ground == nullptr) return true;
            const double slope = std::atan(ground->Gradient(p.x_m, p.y_m).norm()) / kDegToRad;
            if (!(slope < kFloorSlopeDeg)) return false;
            for (const Eigen::Vector2d& q : p.Outline(24)) {
                if (!(ground->Height(q.x(), q.y()) < -1.0)) return false;
            }
            return true;
        };
        const double away = std::atan2(parts[i].y_m - first->y_m, parts[i].x_m - first->x_m);
        const ChangePart original = parts[i];
        bool placed = false;
        for (int ring = 1; ring <= 80 && !placed; ++ring) {
            for (int k = 0; k < 24 && !placed; ++k) {
                // 0, +15, -15, +30, ... deg from the direction away.
                const double turn = ((k + 1) / 2) * (k % 2 == 1 ? 1 : -1) * 15.0 * kDegToRad;
                ChangePart c = original;
                c.x_m += 0.25 * ring * std::cos(away + turn);
                c.y_m += 0.25 * ring * std::sin(away + turn);
                if (clash(c) == nullptr && on_floor(c)) {
                    parts[i] = c;
                    placed = true;
                }
            }
        }
    }
    return parts;
}

Expected<ScenarioConfig> RepeatEpoch(const ScenarioConfig& first, int epoch) {
    if (epoch < 1 || epoch > 9) {
        return Error{"epoch " + std::to_string(epoch) + ": a repeat survey's epoch is 1 to 9"};
    }
    ScenarioConfig sc = first;
    sc.epoch = epoch;
    if (epoch == 1) return sc;
    const auto k = static_cast<std::uint64_t>(epoch - 1);
    sc.terrain_seed = first.TerrainSeed();
    sc.seed = first.seed + 7919u * k;  // own noise: sonar, navigation errors, waves
    {
        const PitWorld ground(first.pit, first.TerrainSeed());
        sc.changes = DefaultChanges(first.pit, &ground);
    }
    // Surveyed (k x 91) days later, by a crew that remounted the sonar and whose topside PC
    // has a clock of its own.
    {
        const std::string& utc = first.start_utc;  // "YYYY-MM-DDTHH:MM:SSZ"
        int y = 0, mo = 0, d = 0, hh = 0, mi = 0, ss = 0;
        if (std::sscanf(utc.c_str(), "%d-%d-%dT%d:%d:%dZ", &y, &mo, &d, &hh, &mi, &ss) != 6)
            return Error{"start_utc '" + utc + "' is not YYYY-MM-DDTHH:MM:SSZ"};
        // Civil date from days (H. Hinnant's days_from_civil / civil_from_days algorithms).
        const auto days_from_civil = [](int yy, int mm, int dd) {
            yy -= mm <= 2;
            const int era = (yy >= 0 ? yy : yy - 399) / 400;
            const int yoe = yy - era * 400;
            const int doy = (153 * (mm + (mm > 2 ? -3 : 9)) + 2) / 5 + dd - 1;
            const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
            return era * 146097 + doe - 719468;
        };
        int z = days_from_civil(y, mo, d) + 91 * static_cast<int>(k) + 719468;
        const int era = (z >= 0 ? z : z - 146096) / 146097;
        const int doe = z - era * 146097;
        const int yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
        const int doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
        const int mp = (5 * doy + 2) / 153;
        const int dd = doy - (153 * mp + 2) / 5 + 1;
        const int mm = mp < 10 ? mp + 3 : mp - 9;
        const int yy = yoe + era * 400 + (mm <= 2);
        char buf[80];
        std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02dZ", yy, mm, dd, hh, mi, ss);
        sc.start_utc = buf;
    }
    sc.track.clockwise = !first.track.clockwise;
    sc.track.first_lap_offset_m = first.track.first_lap_offset_m + 1.5;
    sc.boresight_deg = {
        first.boresight_deg[0] - 0.5, first.boresight_deg[1] + 0.3, first.boresight_deg[2] - 1.4};
    sc.sonar.topside_clock_offset_s = first.sonar.topside_clock_offset_s + 17.43 * k;
    sc.sonar.topside_clock_drift_ppm = first.sonar.topside_clock_drift_ppm - 48.0 * k;
    return sc;
}

PitWorld MakeWorld(const ScenarioConfig& sc) {
    PitWorld world(sc.pit, sc.TerrainSeed());
    if (!sc.changes.empty()) world.AddHeights(ChangeGrid(world.grid(), sc.changes));
    return world;
}

std::vector<CapacityPoint> CapacityCurve(const TerrainGrid& grid,
                                         double min_level_m,
                                         double max_level_m,
                                         double step_m) {
    std::vector<CapacityPoint> out;
    const double cell = grid.resolution_m * grid.resolution_m;
    const int n = static_cast<int>(std::floor((max_level_m - min_level_m) / step_m + 1e-9));
    for (int k = 0; k <= n; ++k) {
        CapacityPoint p;
        p.level_m = min_level_m + k * step_m;
        for (float h : grid.height_m) {
            if (h < p.level_m) {
                p.area_m2 += cell;
                p.volume_m3 += (p.level_m - h) * cell;
            }
        }
        out.push_back(p);
    }
    return out;
}

}  // namespace pitmap::sim
