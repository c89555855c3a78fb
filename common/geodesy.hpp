// SPDX-License-Identifier: MIT
// Geodesy on GeographicLib (WGS84): geodetic <-> local ENU tangent frame, UTM/UPS.
// Heights are ellipsoidal. NovAtel reports the geoid undulation with every position
// (h_ellipsoid = h_msl + undulation), so no geoid model file is needed on board or on shore.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "common/result.hpp"

namespace GeographicLib {
class LocalCartesian;
}

namespace pitmap {

struct Geodetic {
    double latitude_deg = 0;   // WGS84 geodetic latitude, degrees, north positive
    double longitude_deg = 0;  // degrees, east positive
    double height_m = 0;       // ellipsoidal height, metres
};

// The project's "world" frame: East-North-Up at an origin, metres.
// Thread safety: const methods may be called concurrently.
class LocalTangentFrame {
public:
    explicit LocalTangentFrame(const Geodetic& origin);
    ~LocalTangentFrame();
    LocalTangentFrame(const LocalTangentFrame& other);
    LocalTangentFrame& operator=(const LocalTangentFrame& other);

    const Geodetic& origin() const { return origin_; }
    Eigen::Vector3d ToEnu(const Geodetic& p) const;
    Geodetic FromEnu(const Eigen::Vector3d& enu_m) const;

private:
    Geodetic origin_;
    std::unique_ptr<GeographicLib::LocalCartesian> impl_;
};

struct UtmCoordinate {
    int zone = 0;          // 1..60 for UTM, 0 for UPS (polar)
    bool northern = true;  // hemisphere
    double easting_m = 0;
    double northing_m = 0;
    double height_m = 0;  // ellipsoidal height, passed through
};

// Geodetic -> UTM (or UPS at the poles). zone = -1 picks the standard zone; a zone 1..60
// forces that zone (to keep a whole survey in one zone). Fails for latitudes outside
// [-90, 90] or a zone that cannot hold the point.
Expected<UtmCoordinate> UtmFromGeodetic(const Geodetic& p, int zone = -1);
Expected<Geodetic> GeodeticFromUtm(const UtmCoordinate& u);
// EPSG code of the WGS84 UTM zone (32601..32660 north, 32701..32760 south); UPS: 32661 north,
// 32761 south.
int UtmEpsgCode(int zone, bool northern);

}  // namespace pitmap
