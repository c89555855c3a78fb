// SPDX-License-Identifier: MIT
// The vertical reference on disk (issue 17 item 2): the EGM96 geoid through PROJ against NGA's
// published test values, a missing grid is an error (never a silent zero); the water-level CSV
// reader and its errors; points.las with the datum's compound CRS, heights above the datum and
// THU/TVU as LAS 1.4 extra bytes described in their VLR; points.ply with THU/TVU/depth
// properties; dem.tif and dem.bag read back by GDAL with the datum's vertical CRS.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/gps_time.hpp"
#include "processor/hydro/datum.hpp"
#include "processor/io/geoid.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/products.hpp"
#include "processor/io/water_level.hpp"

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

class DatumIo : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("pitmap_datum_io_" + std::to_string(::getpid()));
        fs::create_directories(dir_);
    }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(dir_);
    }
    fs::path dir_;
};

std::vector<std::uint8_t> ReadBytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(Geoid, Egm96MatchesNgaTestValues) {
    auto g = GeoidGrid::Open("egm96_15.gtx");
    ASSERT_TRUE(g) << g.error().message;
    // NGA's EGM96 test points (readme of the EGM96 15' grid interpolation program): latitude,
    // longitude (0..360), N in metres. PROJ interpolates the 15' grid bilinearly; the
    // published values come from the spherical harmonics: agreement within 0.1 m (5.6 cm off
    // in central Australia, the others within 5 cm); a wrong sign or grid is metres off.
    struct Ref {
        double lat, lon, n;
    };
    const Ref refs[] = {{38.6281550, 269.7791550, -31.628},
                        {-14.6212170, 305.0211140, -2.969},
                        {46.8743190, 102.4487290, -43.575},
                        {-23.6174460, 133.8747120, 15.871},
                        {38.6254730, 359.9995000, 50.066},
                        {-0.4667440, 0.0023000, 17.329}};
    std::vector<Geodetic> pts;
    for (const Ref& r : refs) pts.push_back({r.lat, r.lon > 180 ? r.lon - 360 : r.lon, 123.0});
    auto n = g->Undulations(pts);
    ASSERT_TRUE(n) << n.error().message;
    for (std::size_t k = 0; k < pts.size(); ++k) EXPECT_NEAR((*n)[k], refs[k].n, 0.1) << k;
}

TEST(Geoid, MissingGridIsAnErrorNamingIt) {
    auto g = GeoidGrid::Open("pitmap_no_such_geoid.gtx");
    ASSERT_FALSE(g);
    EXPECT_NE(g.error().message.find("'pitmap_no_such_geoid.gtx' cannot be opened by PROJ"),
              std::string::npos)
        << g.error().message;
    EXPECT_FALSE(GeoidGrid::Open(""));
    EXPECT_FALSE(GeoidGrid::Open("egm96_15.gtx +proj=noop"));  // no PROJ string injection
}

TEST(WaterLevel, ParsesTheCsvAndNamesEveryProblem) {
    auto r = ParseWaterLevelText(
        "# gauge at the pit's east ramp\ntime,level_m\n2026-06-15T09:00:00Z,2.150\n"
        "2026-06-15T09:10:00.5Z; 2.140 ;extra\n\n2026-06-15 09:20:00Z\t2.13\n",
        "gauge.csv");
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(r->size(), 3u);
    const std::int64_t t0 = GpsFromUnix(*UnixFromUtcCalendar({2026, 6, 15, 9, 0, 0, 0}));
    EXPECT_EQ((*r)[0].utime_gps, t0);
    EXPECT_EQ((*r)[1].utime_gps, t0 + 600'500'000);
    EXPECT_DOUBLE_EQ((*r)[1].level_m, 2.14);
    EXPECT_EQ((*r)[2].utime_gps, t0 + 1'200'000'000);
    const auto fails = [](const std::string& text, const std::string& what) {
        const auto e = ParseWaterLevelText(text, "g.csv");
        ASSERT_FALSE(e) << text;
        EXPECT_NE(e.error().message.find(what), std::string::npos) << e.error().message;
    };
    fails("", "g.csv: no water level");
    fails("2026-06-15T09:00:00Z,2.1\n2026-06-15T09:00:00Z,2.2\n", "g.csv:2: time");
    fails("2026-06-15T09:00:00Z,abc\n", "g.csv:1: level must be a number");
    fails("2026-06-15T09:00:00,2.1\n", "g.csv:1: time must be UTC");
    fails("2026-13-15T09:00:00Z,2.1\n", "g.csv:1: time must be UTC");
    fails("2026-06-15T09:00:00Z 2.1\n", "g.csv:1: expected 'time,level'");
    fails("time,level\nlevel,time\n", "g.csv:2: time must be UTC");
    fails("2026-06-15T09:00:00Z,1e9\n", "beyond 10 km");
    fails("2026-06-15T09:00:00Z,nan\n", "level must be a number");
    const auto missing = ReadWaterLevelFile("/nonexistent/pitmap/gauge.csv");
    ASSERT_FALSE(missing);
    EXPECT_NE(missing.error().message.find("/nonexistent/pitmap/gauge.csv"), std::string::npos);
}

georef::GeorefResult TwoSoundings() {
    georef::GeorefResult r;
    r.world_origin = {40.4435, -7.7806, 412.0};
    georef::GeorefPing ping;
    ping.utime_gps = 1'400'000'000'000'000;
    r.pings = {ping, ping};
    r.points.position_world = {Eigen::Vector3d(1, 2, -10), Eigen::Vector3d(3, 4, -12)};
    r.points.ping = {0, 1};
    r.points.beam = {0, 1};
    r.points.range_m = {10.0f, 12.0f};
    r.points.angle_rad = {0.0f, 0.1f};
    return r;
}

hydro::DatumModel Egm96() {
    hydro::DatumInputs in;
    in.ping_t_s = {0, 1};
    in.geoid_n_m = {55.0, 56.0};
    hydro::VerticalDatumConfig c;
    c.datum = hydro::VerticalDatum::kGeoid;
    auto b = hydro::BuildDatum(c, in);
    EXPECT_TRUE(b.ok);
    return b.model;
}

TEST_F(DatumIo, LasCarriesTheDatumAndTheUncertainty) {
    const georef::GeorefResult r = TwoSoundings();
    const auto utm = georef::ToUtm(r);
    ASSERT_TRUE(utm) << utm.error().message;
    const hydro::DatumModel m = Egm96();
    PointExtras x;
    x.thu_95_m = {0.11f, 0.22f};
    x.tvu_95_m = {0.33f, 0.44f};
    x.datum_height_m = m.datum_height_m;
    x.vertical_wkt = m.VerticalWkt();
    x.vertical_name = m.crs_name;
    const fs::path las = dir_ / "points.las";
    ASSERT_TRUE(WriteLas(las.string(), r, *utm, &x));
    const std::vector<std::uint8_t> b = ReadBytes(las);
    auto u16 = [&](std::size_t at) { return static_cast<unsigned>(b[at] | (b[at + 1] << 8)); };
    auto u32 = [&](std::size_t at) {
        return static_cast<std::uint32_t>(u16(at) | (u16(at + 2) << 16));
    };
    auto f64 = [&](std::size_t at) {
        double v;
        std::memcpy(&v, &b[at], 8);
        return v;
    };
    auto f32 = [&](std::size_t at) {
        float v;
        std::memcpy(&v, &b[at], 4);
        return v;
    };
    ASSERT_EQ(u32(100), 2u) << "CRS and Extra Bytes VLRs";
    EXPECT_EQ(b[104], 6u);
    EXPECT_EQ(u16(105), 38u) << "format 6 + two float32";
    std::size_t vlr = u16(94);
    const std::size_t wkt_len = u16(vlr + 20);
    const std::string wkt(reinterpret_cast<const char*>(&b[vlr + 54]), wkt_len - 1);
    EXPECT_EQ(wkt.rfind("COMPD_CS[\"WGS 84 / UTM zone 29N + EGM96 height\",PROJCS[", 0), 0u) << wkt;
    EXPECT_NE(wkt.find("VERT_CS[\"EGM96 height\""), std::string::npos) << wkt;
    EXPECT_NE(wkt.find("AUTHORITY[\"EPSG\",\"5773\"]]]"), std::string::npos) << wkt;
    vlr += 54 + wkt_len;
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(&b[vlr + 2])), "LASF_Spec");
    EXPECT_EQ(u16(vlr + 18), 4u);
    ASSERT_EQ(u16(vlr + 20), 384u);
    EXPECT_EQ(b[vlr + 54 + 2], 9u) << "float";
    // Names PDAL keeps as they are (letters, digits, '_'; issue 39: "THU 95%" became "THU_95_").
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(&b[vlr + 54 + 4])), "thu_95_m");
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(&b[vlr + 54 + 192 + 4])), "tvu_95_m");
    EXPECT_NE(std::string(reinterpret_cast<const char*>(&b[vlr + 54 + 192 + 160]), 32)
                  .find("vertical uncertainty"),
              std::string::npos);
    const std::size_t points = u32(96);
    EXPECT_EQ(points, vlr + 54 + 384);
    const double sz = f64(131 + 16), oz = f64(131 + 40);
    for (int k = 0; k < 2; ++k) {
        const std::size_t rec = points + 38 * static_cast<std::size_t>(k);
        std::int32_t z;
        std::memcpy(&z, &b[rec + 8], 4);
        const double h = utm->easting_northing_height[static_cast<std::size_t>(k)].z();
        EXPECT_NEAR(z * sz + oz, h - m.datum_height_m[static_cast<std::size_t>(k)], 1e-3) << k;
        EXPECT_FLOAT_EQ(f32(rec + 30), x.thu_95_m[static_cast<std::size_t>(k)]);
        EXPECT_FLOAT_EQ(f32(rec + 34), x.tvu_95_m[static_cast<std::size_t>(k)]);
    }
    EXPECT_EQ(b.size(), points + 2 * 38);
}

TEST_F(DatumIo, PlyCarriesTheUncertaintyAndTheDepth) {
    const georef::GeorefResult r = TwoSoundings();
    const hydro::DatumModel m = Egm96();
    PointExtras x;
    x.thu_95_m = {0.11f, 0.22f};
    x.tvu_95_m = {0.33f, 0.44f};
    x.datum_height_m = m.datum_height_m;
    x.vertical_name = m.crs_name;
    const fs::path ply = dir_ / "points.ply";
    ASSERT_TRUE(WritePly(ply.string(), r, &x));
    const std::vector<std::uint8_t> b = ReadBytes(ply);
    const std::string text(b.begin(), b.end());
    const std::size_t end = text.find("end_header\n");
    ASSERT_NE(end, std::string::npos);
    const std::string header = text.substr(0, end);
    EXPECT_NE(header.find("comment pitmap_vertical_datum EGM96 height\n"), std::string::npos);
    EXPECT_NE(header.find("property ushort beam\nproperty float thu_95_m\nproperty float "
                          "tvu_95_m\nproperty float depth_m\n"),
              std::string::npos)
        << header;
    const std::size_t rec = 4 * 3 + 8 + 4 + 4 + 2 + 3 * 4 + 1;  // ... depth_m, uchar status
    ASSERT_EQ(b.size(), end + 11 + 2 * rec);
    for (int k = 0; k < 2; ++k) {
        const std::size_t at = end + 11 + rec * static_cast<std::size_t>(k) + 30;
        float thu, tvu, depth;
        std::memcpy(&thu, &b[at], 4);
        std::memcpy(&tvu, &b[at + 4], 4);
        std::memcpy(&depth, &b[at + 8], 4);
        EXPECT_FLOAT_EQ(thu, x.thu_95_m[static_cast<std::size_t>(k)]);
        EXPECT_FLOAT_EQ(tvu, x.tvu_95_m[static_cast<std::size_t>(k)]);
        // depth = N - h: h = 412 - 10 (or - 12), less the earth's curvature over metres.
        const double h = 412.0 + r.points.position_world[static_cast<std::size_t>(k)].z();
        EXPECT_NEAR(depth, m.datum_height_m[static_cast<std::size_t>(k)] - h, 1e-3) << k;
    }
}

TEST_F(DatumIo, GridsNameTheirVerticalDatum) {
    GridRaster g;
    g.nx = 4;
    g.ny = 3;
    g.resolution_m = 1;
    g.x0 = 587'312.5;
    g.y0 = 4'477'051.5;
    g.utm_zone = 29;
    g.layers = {{"elevation", "metre", std::vector<float>(12, -5.0f)},
                {"uncertainty", "metre", std::vector<float>(12, 0.1f)}};
    hydro::DatumModel water;
    water.datum = hydro::VerticalDatum::kWaterLevel;
    water.crs_name = "pit water level (GNSS, survey median)";
    for (const auto& [model, name] :
         {std::pair{Egm96(), std::string("EGM96 height")},
          std::pair{water, std::string("pit water level (GNSS, survey median)")},
          std::pair{hydro::DatumModel{}, std::string("WGS 84 ellipsoidal height")}}) {
        g.vertical_wkt = model.VerticalWkt();
        for (const char* file : {"dem.tif", "dem.bag"}) {
            const fs::path p = dir_ / file;
            fs::remove(p);
            const Status w = std::string(file) == "dem.tif" ? WriteCogGeoTiff(p.string(), g)
                                                            : WriteBag(p.string(), g);
            ASSERT_TRUE(w) << w.error().message;
            auto back = ReadGrid(p.string());
            ASSERT_TRUE(back) << back.error().message;
            EXPECT_EQ(back->vertical_name, name) << file;
            EXPECT_EQ(back->horizontal_epsg, 32629) << file;
        }
    }
}

// Issue 39: the survey's metadata in the grids and the LAS, special characters kept (GDAL
// escapes the BAG's XML, pitmap its citation); the water level's CRS named after the site reads
// back by that name from every product; the BAG is dated by the survey, not the processing.
ProductMetadata SampleMetadata() {
    ProductMetadata m;
    m.project = "Pit & Lake <2026>";
    m.client = "Mina";
    m.site = "Bejanca";
    m.survey_id = "BJ-7";
    m.surveyor = "A. Surveyor";
    m.organisation = "Pit Survey";
    m.vessel = "asv-1";
    m.equipment = {{"multibeam", "Imagenex Delta T"}, {"gnss_ins", "NovAtel SPAN"}};
    m.survey_start_utc = "2026-06-15T09:00:00Z";
    m.survey_end_utc = "2026-06-16T10:01:01Z";
    m.processed_utc = "2027-01-15T08:00:00Z";
    m.software = "pitmap 9.9.9";
    m.horizontal_crs_name = "WGS 84 / UTM zone 29N";
    m.horizontal_epsg = 32629;
    m.vertical_crs_name = "Bejanca pit water level (GNSS, survey median)";
    return m;
}

std::string ItemOf(const GridRaster& g, const std::string& key) {
    for (const auto& [k, v] : g.metadata) {
        if (k == key) return v;
    }
    return "";
}

TEST_F(DatumIo, MetadataAndTheSitesWaterLevelReachEveryProduct) {
    hydro::DatumInputs in;
    in.ping_t_s = {0, 1};
    in.surface.t_s = {0, 1};
    in.surface.level_m = {412.0, 412.0};
    in.site_name = "Bejanca";
    hydro::VerticalDatumConfig c;
    c.datum = hydro::VerticalDatum::kWaterLevel;
    const auto b = hydro::BuildDatum(c, in);
    ASSERT_TRUE(b.ok) << b.message;
    EXPECT_EQ(b.model.crs_name, "Bejanca pit water level (GNSS, survey median)");
    const ProductMetadata meta = SampleMetadata();

    GridRaster g;
    g.nx = 4;
    g.ny = 3;
    g.resolution_m = 1;
    g.x0 = 587'312.5;
    g.y0 = 4'477'051.5;
    g.utm_zone = 29;
    g.layers = {{"elevation", "metre", std::vector<float>(12, -5.0f)},
                {"uncertainty", "metre", std::vector<float>(12, 0.1f)}};
    g.vertical_wkt = b.model.VerticalWkt();
    g.product = meta;
    const fs::path tif = dir_ / "dem.tif", bag = dir_ / "dem.bag";
    ASSERT_TRUE(WriteCogGeoTiff(tif.string(), g));
    ASSERT_TRUE(WriteBag(bag.string(), g));
    auto t = ReadGrid(tif.string());
    ASSERT_TRUE(t) << t.error().message;
    EXPECT_EQ(t->vertical_name, b.model.crs_name);
    EXPECT_EQ(ItemOf(t->grid, "TIFFTAG_DOCUMENTNAME"), "Pit & Lake <2026>");
    EXPECT_EQ(ItemOf(t->grid, "TIFFTAG_DATETIME"), "2026:06:16 10:01:01");
    EXPECT_EQ(ItemOf(t->grid, "TIFFTAG_ARTIST"), "A. Surveyor, Pit Survey");
    EXPECT_EQ(ItemOf(t->grid, "TIFFTAG_COPYRIGHT"), "Pit Survey for Mina");
    EXPECT_EQ(ItemOf(t->grid, "TIFFTAG_SOFTWARE"), "pitmap 9.9.9");
    EXPECT_EQ(ItemOf(t->grid, "pitmap_equipment"),
              "multibeam: Imagenex Delta T; gnss_ins: NovAtel SPAN");
    // The whole CRS beside the keys, with the datum's name GeoTIFF's keys cannot hold.
    auto wkt = DescribeCrsWkt(ItemOf(t->grid, "pitmap_crs_wkt"));
    ASSERT_TRUE(wkt) << wkt.error().message;
    EXPECT_EQ(wkt->vertical_datum, b.model.crs_name);
    EXPECT_EQ(wkt->horizontal_epsg, 32629);

    auto r = ReadGrid(bag.string());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->vertical_name, b.model.crs_name);
    for (const char* s : {"<gco:CharacterString>A. Surveyor</gco:CharacterString>",
                          "<gco:CharacterString>Pit Survey</gco:CharacterString>",
                          "Pit &amp; Lake &lt;2026&gt; / Bejanca / BJ-7",
                          "<gco:Date>2026-06-15</gco:Date>",
                          "<gco:Date>2026-06-16</gco:Date>",
                          "<gco:DateTime>2026-06-16T10:01:01Z</gco:DateTime>",
                          "codeListValue=\"productUncert\"",
                          "processed 2027-01-15T08:00:00Z with pitmap 9.9.9"}) {
        EXPECT_NE(r->bag_xml.find(s), std::string::npos) << s << "\n" << r->bag_xml;
    }
    EXPECT_EQ(r->bag_xml.find("&amp;amp;"), std::string::npos) << "escaped once";
    EXPECT_EQ(r->bag_xml.find("<gco:Date>2027-01-15"), std::string::npos);

    const georef::GeorefResult pts = TwoSoundings();
    const auto utm = georef::ToUtm(pts);
    ASSERT_TRUE(utm) << utm.error().message;
    PointExtras x;
    x.datum_height_m = b.model.datum_height_m;
    x.vertical_wkt = b.model.VerticalWkt();
    const fs::path las = dir_ / "points.las";
    ASSERT_TRUE(WriteLas(las.string(), pts, *utm, &x, "", nullptr, &meta));
    const std::vector<std::uint8_t> bytes = ReadBytes(las);
    const auto text = [&](std::size_t at, std::size_t n) {
        std::string s(reinterpret_cast<const char*>(&bytes[at]), n);
        return s.substr(0, s.find('\0'));
    };
    EXPECT_EQ(text(26, 32), "asv-1 Imagenex Delta T");
    EXPECT_EQ(text(58, 32), "pitmap 9.9.9");
    const auto u16 = [&](std::size_t at) {
        return static_cast<std::size_t>(bytes[at] | (bytes[at + 1] << 8));
    };
    EXPECT_EQ(bytes[100], 2u) << "the CRS and the metadata VLRs";
    std::size_t vlr = u16(94);
    auto crs = DescribeCrsWkt(text(vlr + 54, u16(vlr + 20)));
    ASSERT_TRUE(crs) << crs.error().message;
    EXPECT_EQ(crs->vertical_name, b.model.crs_name);
    EXPECT_EQ(crs->vertical_datum, b.model.crs_name);
    vlr += 54 + u16(vlr + 20);
    EXPECT_EQ(text(vlr + 2, 16), kLasMetadataUserId);
    EXPECT_EQ(u16(vlr + 18), kLasMetadataRecordId);
    const nlohmann::json j = nlohmann::json::parse(text(vlr + 54, u16(vlr + 20)));
    EXPECT_EQ(j["project"], "Pit & Lake <2026>");
    EXPECT_EQ(j["equipment"][1]["model"], "NovAtel SPAN");
    EXPECT_TRUE(j["vertical_crs"]["epsg"].is_null());
}

}  // namespace
}  // namespace pitmap::proc::io
