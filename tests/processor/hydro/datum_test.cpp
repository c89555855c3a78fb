// SPDX-License-Identifier: MIT
// Vertical datum (processor/hydro/datum.hpp): the GNSS water surface is found through heave
// and GNSS blunders; each datum gives the right per-ping datum height (ellipsoid 0, geoid N,
// water level from GNSS the survey median, water level from a file W(t) - L(t)); missing
// inputs and pings far from the levels are errors; the vertical CRS WKT names the datum.
#include "processor/hydro/datum.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

namespace pitmap::proc::hydro {
namespace {

// 50 Hz INS heights of a vehicle riding a water surface at `level(t)`, INS 0.35 m above the
// water line, with 0.1 m heave and 1 % blunders of +-5 m.
std::vector<HeightSample> Ins(double t0,
                              double seconds,
                              const std::function<double(double)>& level) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<HeightSample> out;
    for (double t = t0; t < t0 + seconds; t += 0.02) {
        double h = level(t) + 0.35 + 0.1 * std::sin(2 * M_PI * t / 4.3) +
                   0.03 * std::sin(2 * M_PI * t / 1.7);
        if (u(rng) < 0.01) h += u(rng) < 0.5 ? 5.0 : -5.0;
        out.push_back({t, h});
    }
    return out;
}

TEST(Datum, GnssWaterSurfaceIsRobustToHeaveAndBlunders) {
    const double t0 = 1.4e9;
    // The water level falls 2 cm an hour (pumping).
    const auto level = [&](double t) { return 412.0 - 0.02 * (t - t0) / 3600.0; };
    auto ins = Ins(t0, 1800, level);
    ins.push_back({t0 + 5, std::nan("")});
    WaterSurfaceStats st;
    const LevelSeries s = SmoothWaterSurface(ins, 0.35, 120, 1.0, &st);
    ASSERT_FALSE(s.empty());
    EXPECT_EQ(st.samples_rejected, 1);
    EXPECT_EQ(st.samples_used, static_cast<std::int64_t>(ins.size()) - 1);
    for (double t : {t0 + 100, t0 + 900, t0 + 1700}) EXPECT_NEAR(s.At(t), level(t), 0.01) << t;
    EXPECT_NEAR(st.level_median_m, level(t0 + 900), 0.01);
    EXPECT_GT(st.raw_mad_m, 0.03);  // the heave is seen as scatter about the surface
    EXPECT_LT(st.raw_mad_m, 0.15);
    EXPECT_TRUE(SmoothWaterSurface({}, 0.35, 120, 1.0, &st).empty());
}

TEST(Datum, LevelSeriesInterpolatesAndHoldsAtTheEnds) {
    LevelSeries s{{10, 20, 40}, {1.0, 2.0, 0.0}};
    EXPECT_DOUBLE_EQ(s.At(0), 1.0);
    EXPECT_DOUBLE_EQ(s.At(15), 1.5);
    EXPECT_DOUBLE_EQ(s.At(30), 1.0);
    EXPECT_DOUBLE_EQ(s.At(50), 0.0);
}

TEST(Datum, EachDatumGivesItsHeights) {
    DatumInputs in;
    in.ping_t_s = {100, 200, 300};
    VerticalDatumConfig c;
    DatumBuild e = BuildDatum(c, in);
    ASSERT_TRUE(e.ok) << e.message;
    EXPECT_EQ(e.model.datum_height_m, (std::vector<double>{0, 0, 0}));
    EXPECT_EQ(e.model.crs_name, "WGS 84 ellipsoidal height");
    EXPECT_EQ(e.model.VerticalWkt(), EllipsoidalVerticalWkt());

    c.datum = VerticalDatum::kGeoid;
    EXPECT_FALSE(BuildDatum(c, in).ok);  // no undulations
    in.geoid_n_m = {55.1, 55.2, 55.3};
    in.source_name = "egm96_15.gtx";
    DatumBuild g = BuildDatum(c, in);
    ASSERT_TRUE(g.ok) << g.message;
    EXPECT_EQ(g.model.datum_height_m, in.geoid_n_m);
    EXPECT_EQ(g.model.crs_name, "EGM96 height");
    EXPECT_EQ(g.model.vertical_epsg, 5773);
    EXPECT_NE(g.model.VerticalWkt().find("AUTHORITY[\"EPSG\",\"5773\"]"), std::string::npos);
    in.geoid_n_m[1] = std::nan("");
    EXPECT_FALSE(BuildDatum(c, in).ok);

    c.datum = VerticalDatum::kWaterLevel;
    EXPECT_FALSE(BuildDatum(c, in).ok);  // no water surface
    in.surface = {{0, 150, 400}, {412.0, 412.2, 411.9}};
    DatumBuild w = BuildDatum(c, in);
    ASSERT_TRUE(w.ok) << w.message;
    for (double d : w.model.datum_height_m) EXPECT_DOUBLE_EQ(d, 412.0);  // median of the series
    EXPECT_NE(w.model.VerticalWkt().find("pit water level"), std::string::npos);

    c.water_level_source = WaterLevelSource::kFile;
    in.source_name = "gauge.csv";
    EXPECT_FALSE(BuildDatum(c, in).ok);  // no levels
    in.levels = {{50, 350}, {2.0, 2.3}};
    DatumBuild f = BuildDatum(c, in);
    ASSERT_TRUE(f.ok) << f.message;
    // D(t) = W(t) - L(t): at 200 s W = 412.2 - 0.3 * 50 / 250, L = 2.15.
    EXPECT_NEAR(f.model.datum_height_m[0], 412.0 + 0.2 * 100 / 150 - 2.05, 1e-9);
    EXPECT_NEAR(f.model.datum_height_m[1], 412.2 - 0.3 * 50 / 250 - 2.15, 1e-9);
    EXPECT_NE(f.model.crs_name.find("gauge.csv"), std::string::npos);
    c.max_level_gap_s = 100;  // the ping at 200 s is 150 s from the nearest level
    const DatumBuild gap = BuildDatum(c, in);
    EXPECT_FALSE(gap.ok);
    EXPECT_NE(gap.message.find("ping 1 lies 150 s"), std::string::npos) << gap.message;
}

TEST(Datum, ValidateListsEveryProblem) {
    VerticalDatumConfig c;
    EXPECT_TRUE(c.Validate().empty());
    c.datum = VerticalDatum::kGeoid;
    c.geoid_vertical_epsg = 4326;
    c.smoothing_window_s = 0;
    c.ins_height_above_waterline_m = 99;
    EXPECT_EQ(c.Validate().size(), 4u);  // epsg, window, step > window, height
    c.datum = VerticalDatum::kWaterLevel;
    c.water_level_source = WaterLevelSource::kFile;
    c.geoid_vertical_epsg = 5773;
    c.smoothing_window_s = 60;
    c.ins_height_above_waterline_m = 0.3;
    const auto p = c.Validate();
    ASSERT_EQ(p.size(), 1u);
    EXPECT_NE(p[0].find("water_level_file"), std::string::npos);
    EXPECT_EQ(std::string(ToString(VerticalDatum::kWaterLevel)), "water_level");
    EXPECT_EQ(FindGeoidCrs(3855)->vertical_epsg, 3855);
    EXPECT_EQ(FindGeoidCrs(1), nullptr);
}

}  // namespace
}  // namespace pitmap::proc::hydro
