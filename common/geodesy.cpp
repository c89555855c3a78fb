// SPDX-License-Identifier: MIT
#include "common/geodesy.hpp"

#include <GeographicLib/LocalCartesian.hpp>
#include <GeographicLib/UTMUPS.hpp>
#include <cmath>
#include <string>

namespace pitmap {

LocalTangentFrame::LocalTangentFrame(const Geodetic& origin)
    : origin_(origin),
      impl_(std::make_unique<GeographicLib::LocalCartesian>(
          origin.latitude_deg, origin.longitude_deg, origin.height_m)) {}

LocalTangentFrame::~LocalTangentFrame() = default;

LocalTangentFrame::LocalTangentFrame(const LocalTangentFrame& other)
    : origin_(other.origin_),
      impl_(std::make_unique<GeographicLib::LocalCartesian>(*other.impl_)) {}

LocalTangentFrame& LocalTangentFrame::operator=(const LocalTangentFrame& other) {
    if (this != &other) {
        origin_ = other.origin_;
        impl_ = std::make_unique<GeographicLib::LocalCartesian>(*other.impl_);
    }
    return *this;
}

Eigen::Vector3d LocalTangentFrame::ToEnu(const Geodetic& p) const {
    Eigen::Vector3d enu;
    impl_->Forward(p.latitude_deg, p.longitude_deg, p.height_m, enu.x(), enu.y(), enu.z());
    return enu;
}

Geodetic LocalTangentFrame::FromEnu(const Eigen::Vector3d& enu_m) const {
    Geodetic p;
    impl_->Reverse(enu_m.x(), enu_m.y(), enu_m.z(), p.latitude_deg, p.longitude_deg, p.height_m);
    return p;
}

Expected<UtmCoordinate> UtmFromGeodetic(const Geodetic& p, int zone) {
    if (!std::isfinite(p.latitude_deg) || !std::isfinite(p.longitude_deg) ||
        std::abs(p.latitude_deg) > 90.0) {
        return Error{"latitude/longitude out of range: " + std::to_string(p.latitude_deg) + ", " +
                     std::to_string(p.longitude_deg)};
    }
    if (zone < -1 || zone > 60) return Error{"UTM zone must be 1..60 (or -1 = standard)"};
    UtmCoordinate u;
    u.height_m = p.height_m;
    try {
        const int setzone = zone == -1 ? GeographicLib::UTMUPS::STANDARD : zone;
        GeographicLib::UTMUPS::Forward(p.latitude_deg,
                                       p.longitude_deg,
                                       u.zone,
                                       u.northern,
                                       u.easting_m,
                                       u.northing_m,
                                       setzone);
    } catch (const GeographicLib::GeographicErr& e) {
        return Error{std::string("UTM conversion failed: ") + e.what()};
    }
    return u;
}

Expected<Geodetic> GeodeticFromUtm(const UtmCoordinate& u) {
    Geodetic p;
    p.height_m = u.height_m;
    try {
        GeographicLib::UTMUPS::Reverse(
            u.zone, u.northern, u.easting_m, u.northing_m, p.latitude_deg, p.longitude_deg);
    } catch (const GeographicLib::GeographicErr& e) {
        return Error{std::string("UTM inverse conversion failed: ") + e.what()};
    }
    return p;
}

int UtmEpsgCode(int zone, bool northern) {
    if (zone == 0) return northern ? 32661 : 32761;
    return (northern ? 32600 : 32700) + zone;
}

}  // namespace pitmap
