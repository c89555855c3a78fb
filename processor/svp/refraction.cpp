// SPDX-License-Identifier: MIT
#include "processor/svp/refraction.hpp"

#include <algorithm>

#include "common/result.hpp"

namespace pitmap::proc::svp {

const char* ToString(CastSelection s) {
    switch (s) {
        case CastSelection::kNearestPreceding:
            return "nearest_preceding";
        case CastSelection::kNearestInTime:
            return "nearest_in_time";
        case CastSelection::kNearestInDistance:
            return "nearest_in_distance";
    }
    return "?";
}

const char* ToString(SurfaceSpeedSource s) {
    return s == SurfaceSpeedSource::kHeader ? "header" : "profile";
}

bool ParseCastSelection(const std::string& text, CastSelection& out) {
    for (CastSelection s : {CastSelection::kNearestPreceding,
                            CastSelection::kNearestInTime,
                            CastSelection::kNearestInDistance}) {
        if (text == ToString(s)) {
            out = s;
            return true;
        }
    }
    return false;
}

bool ParseSurfaceSpeedSource(const std::string& text, SurfaceSpeedSource& out) {
    for (SurfaceSpeedSource s : {SurfaceSpeedSource::kProfile, SurfaceSpeedSource::kHeader}) {
        if (text == ToString(s)) {
            out = s;
            return true;
        }
    }
    return false;
}

std::vector<std::string> RefractionConfig::Validate() const {
    std::vector<std::string> p;
    for (const auto& f : svp_files) {
        if (f.empty()) p.push_back("refraction.svp_files: an empty file name");
    }
    if (!std::isnan(ins_height_above_waterline_m) &&
        !(std::abs(ins_height_above_waterline_m) <= 20.0)) {
        p.push_back("refraction.ins_height_above_waterline_m must be within +-20 m (or null)");
    }
    return p;
}

std::vector<std::string> Refraction::Check(const std::vector<SoundSpeedCast>& casts,
                                           CastSelection selection,
                                           double ins_height_above_waterline_m) {
    std::vector<std::string> p;
    if (casts.empty()) p.push_back("refraction: no sound-velocity cast");
    for (const auto& c : casts) {
        for (auto& s : ValidateCast(c)) p.push_back("refraction: " + s);
        if (selection == CastSelection::kNearestInDistance && !c.has_position()) {
            p.push_back("refraction: " + c.name +
                        " has no position (selection nearest_in_distance needs one per cast)");
        }
    }
    if (!std::isfinite(ins_height_above_waterline_m)) {
        p.push_back(
            "refraction: the transducer depth needs the INS height above the water line "
            "(vehicle.yaml ins_height_above_waterline_m or "
            "refraction.ins_height_above_waterline_m)");
    }
    return p;
}

Refraction::Refraction(std::vector<SoundSpeedCast> casts,
                       CastSelection selection,
                       SurfaceSpeedSource surface_speed,
                       double ins_height_above_waterline_m)
    : selection_(selection),
      surface_speed_(surface_speed),
      ins_height_above_waterline_m_(ins_height_above_waterline_m) {
    PITMAP_CHECK(Check(casts, selection, ins_height_above_waterline_m).empty(),
                 "Refraction: casts or settings not checked (Refraction::Check)");
    for (auto& c : casts) {
        LayeredProfile prof(c.depth_m, c.speed_mps);
        casts_.push_back({std::move(c), std::move(prof)});
    }
    by_time_.resize(casts_.size());
    for (std::size_t i = 0; i < casts_.size(); ++i) by_time_[i] = static_cast<int>(i);
    std::stable_sort(by_time_.begin(), by_time_.end(), [&](int a, int b) {
        return casts_[a].cast.utime_gps < casts_[b].cast.utime_gps;
    });
}

int Refraction::SelectCast(std::int64_t t, double lat_deg, double lon_deg) const {
    if (casts_.size() == 1) return 0;
    switch (selection_) {
        case CastSelection::kNearestPreceding: {
            int best = by_time_.front();  // before every cast: the first one
            for (int i : by_time_) {
                if (casts_[i].cast.utime_gps <= t) best = i;
            }
            return best;
        }
        case CastSelection::kNearestInTime: {
            int best = 0;
            double best_dt = std::numeric_limits<double>::infinity();
            for (int i : by_time_) {
                const double dt = std::abs(static_cast<double>(casts_[i].cast.utime_gps - t));
                if (dt < best_dt) {
                    best_dt = dt;
                    best = i;
                }
            }
            return best;
        }
        case CastSelection::kNearestInDistance: {
            // Equirectangular distance: exact enough to rank casts kilometres apart or less.
            constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
            int best = 0;
            double best_d2 = std::numeric_limits<double>::infinity();
            const double coslat = std::cos(lat_deg * kDegToRad);
            for (std::size_t i = 0; i < casts_.size(); ++i) {
                const auto& c = casts_[i].cast;
                const double dn = c.latitude_deg - lat_deg;
                double de = c.longitude_deg - lon_deg;
                if (de > 180) de -= 360;
                if (de < -180) de += 360;
                const double d2 = dn * dn + (de * coslat) * (de * coslat);
                if (d2 < best_d2) {
                    best_d2 = d2;
                    best = static_cast<int>(i);
                }
            }
            return best;
        }
    }
    return 0;
}

double Refraction::FaceSpeed(int cast, double transducer_depth_m, double header_speed) const {
    if (surface_speed_ == SurfaceSpeedSource::kHeader) return header_speed;
    return casts_[static_cast<std::size_t>(cast)].profile.SpeedAt(transducer_depth_m);
}

BeamGeometry Refraction::Beam(int cast,
                              const Eigen::Matrix3d& R_world_sonar,
                              double theta,
                              double tilt,
                              double range_m,
                              double c_assumed,
                              double z_tx,
                              double c_face) const {
    BeamGeometry out;
    // 1. Steering: the array's phase delays were set for c_assumed.
    const double s = std::sin(theta) * c_face / c_assumed;
    if (!(std::abs(s) <= 1.0)) {
        out.steering_failed = true;
        return out;
    }
    const double k = std::sqrt((1.0 - s) * (1.0 + s)) * (std::cos(theta) < 0 ? -1.0 : 1.0);
    // 2. The beam in the world: Ry(tilt) (0, sin, cos), then the sonar's attitude.
    const Eigen::Vector3d u_sonar(std::sin(tilt) * k, s, std::cos(tilt) * k);
    const Eigen::Vector3d u = R_world_sonar * u_sonar;
    const double horizontal = std::hypot(u.x(), u.y());
    const double launch = std::atan2(horizontal, -u.z());
    const Eigen::Vector2d dir =
        horizontal > 1e-15 ? Eigen::Vector2d(u.x(), u.y()) / horizontal : Eigen::Vector2d(1, 0);
    // 3.-4. One-way time and the ray.
    const RayEnd ray = TraceRay(
        casts_[static_cast<std::size_t>(cast)].profile, z_tx, launch, range_m / c_assumed, c_face);
    out.status = ray.status;
    if (ray.status != RayStatus::kOk) return out;
    out.offset_world = Eigen::Vector3d(
        dir.x() * ray.horizontal_m, dir.y() * ray.horizontal_m, -(ray.depth_m - z_tx));
    return out;
}

}  // namespace pitmap::proc::svp
