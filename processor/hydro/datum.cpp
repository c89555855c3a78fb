// SPDX-License-Identifier: MIT
#include "processor/hydro/datum.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pitmap::proc::hydro {

namespace {

constexpr GeoidCrs kGeoids[] = {
    {5773, "EGM96 height", "EGM96 geoid", 5171, "egm96_15.gtx"},
    {3855, "EGM2008 height", "EGM2008 geoid", 1027, "us_nga_egm08_25.tif"},
};

double Median(std::vector<double>& v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    double m = *mid;
    if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), mid));
    return m;
}

std::string Fixed(double v, int digits) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
}

// A water level's CRS is named after its pit: "Bejanca pit water level ...".
std::string SitePrefix(const DatumInputs& in) {
    return in.site_name.empty() ? std::string() : in.site_name + " ";
}

}  // namespace

const char* ToString(VerticalDatum d) {
    switch (d) {
        case VerticalDatum::kEllipsoid:
            return "ellipsoid";
        case VerticalDatum::kGeoid:
            return "geoid";
        case VerticalDatum::kWaterLevel:
            return "water_level";
    }
    return "?";
}

const char* ToString(WaterLevelSource s) {
    return s == WaterLevelSource::kFile ? "file" : "gnss";
}

const GeoidCrs* FindGeoidCrs(int vertical_epsg) {
    for (const GeoidCrs& g : kGeoids) {
        if (g.vertical_epsg == vertical_epsg) return &g;
    }
    return nullptr;
}

std::vector<std::string> VerticalDatumConfig::Validate() const {
    std::vector<std::string> p;
    if (datum == VerticalDatum::kGeoid && FindGeoidCrs(geoid_vertical_epsg) == nullptr) {
        p.push_back("vertical.geoid_vertical_epsg " + std::to_string(geoid_vertical_epsg) +
                    " is not one pitmap knows (5773 EGM96 height, 3855 EGM2008 height)");
    }
    if (datum == VerticalDatum::kWaterLevel && water_level_source == WaterLevelSource::kFile &&
        water_level_file.empty()) {
        p.push_back("vertical.water_level_file is needed for water_level_source: file");
    }
    if (!(smoothing_window_s > 0 && smoothing_window_s <= 86400)) {
        p.push_back("vertical.smoothing_window_s must be within (0, 86400]");
    }
    if (!(step_s > 0 && step_s <= smoothing_window_s)) {
        p.push_back("vertical.step_s must be > 0 and <= smoothing_window_s");
    }
    if (!std::isnan(ins_height_above_waterline_m) &&
        !(std::abs(ins_height_above_waterline_m) <= 20)) {
        p.push_back("vertical.ins_height_above_waterline_m must be within -20..20 m");
    }
    if (!(max_level_gap_s > 0)) p.push_back("vertical.max_level_gap_s must be > 0");
    return p;
}

double LevelSeries::At(double t) const {
    if (t <= t_s.front()) return level_m.front();
    if (t >= t_s.back()) return level_m.back();
    const auto it = std::upper_bound(t_s.begin(), t_s.end(), t);
    const std::size_t k = static_cast<std::size_t>(it - t_s.begin());
    const double a = (t - t_s[k - 1]) / (t_s[k] - t_s[k - 1]);
    return level_m[k - 1] + a * (level_m[k] - level_m[k - 1]);
}

LevelSeries SmoothWaterSurface(const std::vector<HeightSample>& ins,
                               double height_above_waterline_m,
                               double window_s,
                               double step_s,
                               WaterSurfaceStats* stats) {
    WaterSurfaceStats st;
    std::vector<HeightSample> s;
    s.reserve(ins.size());
    for (const HeightSample& h : ins) {
        if (std::isfinite(h.t_s) && std::isfinite(h.height_m)) {
            s.push_back({h.t_s, h.height_m - height_above_waterline_m});
        } else {
            ++st.samples_rejected;
        }
    }
    std::sort(s.begin(), s.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
    st.samples_used = static_cast<std::int64_t>(s.size());
    LevelSeries out;
    if (s.empty()) {
        if (stats != nullptr) *stats = st;
        return out;
    }
    const double t0 = s.front().t_s, t1 = s.back().t_s;
    const auto steps = static_cast<std::int64_t>(std::floor((t1 - t0) / step_s)) + 1;
    std::vector<double> window;
    std::size_t lo = 0, hi = 0;
    for (std::int64_t k = 0; k < steps; ++k) {
        const double t = t0 + static_cast<double>(k) * step_s;
        while (lo < s.size() && s[lo].t_s < t - window_s / 2) ++lo;
        while (hi < s.size() && s[hi].t_s <= t + window_s / 2) ++hi;
        window.clear();
        for (std::size_t i = lo; i < hi; ++i) window.push_back(s[i].height_m);
        if (window.empty()) continue;  // a gap longer than the window: interpolated over
        out.t_s.push_back(t);
        out.level_m.push_back(Median(window));
    }
    std::vector<double> v = out.level_m;
    st.level_median_m = Median(v);
    st.level_min_m = *std::min_element(out.level_m.begin(), out.level_m.end());
    st.level_max_m = *std::max_element(out.level_m.begin(), out.level_m.end());
    std::vector<double> dev(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) dev[i] = std::abs(s[i].height_m - out.At(s[i].t_s));
    st.raw_mad_m = 1.4826 * Median(dev);
    if (stats != nullptr) *stats = st;
    return out;
}

std::string EllipsoidalVerticalWkt() {
    return "VERT_CS[\"WGS 84 ellipsoidal height\",VERT_DATUM[\"World Geodetic System 1984\",2002],"
           "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Ellipsoidal height\",UP]]";
}

std::string DatumModel::VerticalWkt() const {
    const std::string unit = "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]]";
    switch (datum) {
        case VerticalDatum::kEllipsoid:
            break;
        case VerticalDatum::kGeoid: {
            const GeoidCrs* g = FindGeoidCrs(vertical_epsg);
            if (g == nullptr) break;
            return "VERT_CS[\"" + std::string(g->crs_name) + "\",VERT_DATUM[\"" + g->datum_name +
                   "\",2005,AUTHORITY[\"EPSG\",\"" + std::to_string(g->datum_epsg) + "\"]]," +
                   unit + ",AXIS[\"Gravity-related height\",UP],AUTHORITY[\"EPSG\",\"" +
                   std::to_string(g->vertical_epsg) + "\"]]";
        }
        case VerticalDatum::kWaterLevel:
            // OGC 01-009 type 2005 (geoidally referenced): a water surface is a level surface.
            return "VERT_CS[\"" + crs_name + "\",VERT_DATUM[\"" + crs_name + "\",2005]," + unit +
                   ",AXIS[\"Gravity-related height\",UP]]";
    }
    return EllipsoidalVerticalWkt();
}

DatumBuild BuildDatum(const VerticalDatumConfig& c, const DatumInputs& in) {
    DatumBuild b;
    DatumModel& m = b.model;
    m.datum = c.datum;
    const std::size_t n = in.ping_t_s.size();
    m.datum_height_m.assign(n, 0.0);
    switch (c.datum) {
        case VerticalDatum::kEllipsoid:
            m.description = "heights above the WGS 84 ellipsoid";
            break;
        case VerticalDatum::kGeoid: {
            const GeoidCrs* g = FindGeoidCrs(c.geoid_vertical_epsg);
            if (g == nullptr || in.geoid_n_m.size() != n) {
                b.message = "vertical datum: no geoid undulations for the pings";
                return b;
            }
            m.crs_name = g->crs_name;
            m.vertical_epsg = g->vertical_epsg;
            for (std::size_t k = 0; k < n; ++k) {
                if (!std::isfinite(in.geoid_n_m[k])) {
                    b.message = "vertical datum: the geoid grid " + in.source_name +
                                " has no value at ping " + std::to_string(k);
                    return b;
                }
                m.datum_height_m[k] = in.geoid_n_m[k];
            }
            m.description = std::string(g->crs_name) +
                            " (EPSG:" + std::to_string(g->vertical_epsg) + "), geoid grid " +
                            in.source_name;
            break;
        }
        case VerticalDatum::kWaterLevel: {
            if (in.surface.empty()) {
                b.message = "vertical datum: no water surface from the INS heights";
                return b;
            }
            if (c.water_level_source == WaterLevelSource::kGnss) {
                std::vector<double> v = in.surface.level_m;
                const double level = Median(v);
                m.datum_height_m.assign(n, level);
                m.crs_name = SitePrefix(in) + "pit water level (GNSS, survey median)";
                m.description =
                    "depths below the pit's water level, the median of the water "
                    "surface from the GNSS heights over the survey: " +
                    Fixed(level, 3) + " m above the WGS 84 ellipsoid";
            } else {
                if (in.levels.empty()) {
                    b.message = "vertical datum: the water-level file " + in.source_name +
                                " holds no level";
                    return b;
                }
                for (std::size_t k = 0; k < n; ++k) {
                    const double t = in.ping_t_s[k];
                    const auto& T = in.levels.t_s;
                    const auto it = std::lower_bound(T.begin(), T.end(), t);
                    double gap = std::numeric_limits<double>::infinity();
                    if (it != T.end()) gap = *it - t;
                    if (it != T.begin()) gap = std::min(gap, t - *(it - 1));
                    if (gap > c.max_level_gap_s) {
                        b.message = "vertical datum: ping " + std::to_string(k) + " lies " +
                                    Fixed(gap, 0) + " s from the nearest level of " +
                                    in.source_name + " (vertical.max_level_gap_s " +
                                    Fixed(c.max_level_gap_s, 0) + ")";
                        return b;
                    }
                    m.datum_height_m[k] = in.surface.At(t) - in.levels.At(t);
                }
                m.crs_name =
                    SitePrefix(in) + "pit water level datum (gauge " + in.source_name + ")";
                m.description = "depths below the datum of the water levels in " + in.source_name +
                                " (the water surface from the GNSS heights minus the level)";
            }
            break;
        }
    }
    double sum = 0;
    for (double d : m.datum_height_m) sum += d;
    m.mean_datum_height_m = n > 0 ? sum / static_cast<double>(n) : 0.0;
    b.ok = true;
    return b;
}

}  // namespace pitmap::proc::hydro
