// SPDX-License-Identifier: MIT
// Vertical reference of the products (issue 17 item 2). pitmap computes every height on the
// WGS 84 ellipsoid; a vertical datum is a surface whose ellipsoidal height D is known where and
// when a ping was made, and a product height is h - D (up, metres), a depth D - h:
//   ellipsoid    D = 0: heights above the WGS 84 ellipsoid (as before; the default)
//   geoid        D = N(lat, lon), the geoid undulation from a PROJ grid (processor/io/geoid.hpp;
//                EGM96 by default: heights are "EGM96 height", EPSG:5773)
//   water_level  the pit's water surface:
//                gnss: the water surface at every INS sample is the INS height minus the INS
//                  height above the water line (vehicle.yaml ins.height_above_waterline_m);
//                  the series is smoothed by a running median over smoothing_window_s (heave,
//                  GNSS blunders; the water surface of a pit moves by centimetres a day) and
//                  the datum is one level surface at the median of the smoothed series over the
//                  survey (D constant): depths below the survey's mean water level.
//                file: a water-level time series (processor/io/water_level.hpp: time, level of
//                  the water surface above the datum, e.g. a gauge read against a benchmark);
//                  D(t) = W(t) - L(t), W the smoothed GNSS water surface above and L the level
//                  linearly interpolated at the ping (the classic water-level reduction: the
//                  depth below the water surface plus the level of the surface above the datum,
//                  so a bias of the GNSS heights cancels).
// The water surface is taken as a level surface: over a pit a few kilometres wide the geoid's
// slope moves it by millimetres.
// Pure code: the geoid undulations and the water-level file come in as values.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace pitmap::proc::hydro {

enum class VerticalDatum { kEllipsoid = 0, kGeoid, kWaterLevel };
enum class WaterLevelSource { kGnss = 0, kFile };
const char* ToString(VerticalDatum d);
const char* ToString(WaterLevelSource s);

// The geoids pitmap can name (its vertical CRS and the WKT it writes).
struct GeoidCrs {
    int vertical_epsg = 0;  // EPSG code of the gravity-related height (5773 EGM96, 3855 EGM2008)
    const char* crs_name = "";      // "EGM96 height"
    const char* datum_name = "";    // "EGM96 geoid"
    int datum_epsg = 0;             // 5171
    const char* default_grid = "";  // the PROJ grid (proj-data's egm96_15.gtx)
};
// nullptr for a code pitmap does not know.
const GeoidCrs* FindGeoidCrs(int vertical_epsg);

struct VerticalDatumConfig {
    VerticalDatum datum = VerticalDatum::kEllipsoid;
    int geoid_vertical_epsg = 5773;  // geoid: the gravity-related height (5773, 3855)
    std::string geoid_grid;          // geoid: PROJ grid name or path; "" = the CRS's default
    WaterLevelSource water_level_source = WaterLevelSource::kGnss;
    std::string water_level_file;     // source file: CSV time (UTC ISO 8601), level (m)
    double smoothing_window_s = 120;  // running median of the GNSS water surface, s
    double step_s = 1.0;              // the smoothed series' spacing, s
    // INS height above the water line, m; NaN = vehicle.yaml's.
    double ins_height_above_waterline_m = std::numeric_limits<double>::quiet_NaN();
    double max_level_gap_s = 3600;  // file: a ping further from any level is an error, s

    std::vector<std::string> Validate() const;
};

// A time series of a water surface: GPS seconds, ellipsoidal height (or level) in metres,
// strictly increasing times.
struct LevelSeries {
    std::vector<double> t_s;
    std::vector<double> level_m;
    bool empty() const { return t_s.empty(); }
    // Linear interpolation, held constant beyond the ends. Precondition: !empty().
    double At(double t_s) const;
};

struct HeightSample {
    double t_s = 0;       // GPS seconds
    double height_m = 0;  // ellipsoidal height of the INS reference point
};

struct WaterSurfaceStats {
    std::int64_t samples_used = 0;
    std::int64_t samples_rejected = 0;                                 // non-finite
    double level_median_m = std::numeric_limits<double>::quiet_NaN();  // of the smoothed series
    double level_min_m = std::numeric_limits<double>::quiet_NaN();
    double level_max_m = std::numeric_limits<double>::quiet_NaN();
    double raw_mad_m = std::numeric_limits<double>::quiet_NaN();  // raw - smoothed, 1.4826 MAD
};

// The water surface from INS heights: height - height_above_waterline_m, running median over
// window_s on a step_s grid spanning the samples. Empty when no finite sample.
LevelSeries SmoothWaterSurface(const std::vector<HeightSample>& ins,
                               double height_above_waterline_m,
                               double window_s,
                               double step_s,
                               WaterSurfaceStats* stats);

// The datum applied: a name for the products and, per ping, the datum surface's ellipsoidal
// height D (product height = ellipsoidal height - D).
struct DatumModel {
    VerticalDatum datum = VerticalDatum::kEllipsoid;
    std::string crs_name = "WGS 84 ellipsoidal height";  // the vertical CRS of the products
    int vertical_epsg = 0;                               // 0 = no EPSG code
    std::string description;                             // one line for the report
    std::vector<double> datum_height_m;                  // per ping
    double mean_datum_height_m = 0;
    // The vertical CRS as OGC WKT1 (VERT_CS) for LAS, GeoTIFF and BAG.
    std::string VerticalWkt() const;
};

// Per-ping datum heights. `ping_t_s` GPS seconds of the pings; `geoid_n_m` the undulation at
// each ping (geoid only, else ignored); `surface` the smoothed GNSS water surface and
// `levels` the file's series (water_level only). Fails (message) when an input the datum
// needs is missing or a ping lies further than max_level_gap_s from the file's series.
struct DatumInputs {
    std::vector<double> ping_t_s;
    std::vector<double> geoid_n_m;
    LevelSeries surface;
    LevelSeries levels;
    std::string source_name;  // the geoid grid or the water-level file, for the description
    std::string site_name;    // water_level: the pit's name, the first word of the CRS's name
};
struct DatumBuild {
    bool ok = false;
    std::string message;
    DatumModel model;
};
DatumBuild BuildDatum(const VerticalDatumConfig& config, const DatumInputs& in);

// OGC WKT1 VERT_CS of the WGS 84 ellipsoidal height (OGC 01-009 datum type 2002).
std::string EllipsoidalVerticalWkt();

}  // namespace pitmap::proc::hydro
