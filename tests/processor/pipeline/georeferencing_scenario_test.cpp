// SPDX-License-Identifier: MIT
// Scenario test of the products' georeferencing and metadata (issue 39): 40 s of the demo
// survey, `pitmap run` (no calibration, no SLAM) with a metadata section, once per vertical
// datum (ellipsoid, geoid EGM96, the pit's water level). Every product is read back the way its
// readers read it (GDAL for dem.tif and dem.bag; the LAS WKT VLR, the .prj sidecars and the
// glTF's CRS through GDAL/PROJ, as PDAL's LAS reader hands the VLR to them):
//   - each names the same horizontal CRS (EPSG 32629) and the same vertical CRS as
//     summary.json's metadata (name; EPSG 5773 for the geoid, none for the others);
//   - each carries the metadata where its format has a place for it (TIFF tags and items, the
//     BAG's ISO 19115 XML, the LAS header and its metadata VLR, glTF asset extras, PLY comments),
//     with the survey's dates (from the pings), not the processing time;
//   - mesh_utm.ply's vertices lie on dem.tif (median height difference at the DEM's nodes under
//     them within 2 cm), mesh_utm.glb's vertices plus its node translation are mesh_utm.ply's,
//     and points_utm.ply's first sounding is points.las's first record.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/formats/ply.hpp"
#include "processor/io/grid_io.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using pitmap::proc::io::CrsIdentity;
using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

std::vector<std::uint8_t> ReadBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string ReadText(const fs::path& p) {
    const auto b = ReadBytes(p);
    return {b.begin(), b.end()};
}

// What a LAS 1.4 reader finds in the header and VLRs (ASPRS LAS 1.4 R15 Table 3, section 2.5).
struct LasHeader {
    std::string system_id, software, wkt, metadata_json;
    int day = 0, year = 0;
    double first_xyz[3] = {0, 0, 0};
};

LasHeader ReadLas(const fs::path& p) {
    const auto b = ReadBytes(p);
    LasHeader h;
    if (b.size() < 375) return h;
    auto u16 = [&](std::size_t at) { return static_cast<unsigned>(b[at] | (b[at + 1] << 8)); };
    auto u32 = [&](std::size_t at) {
        return static_cast<std::uint32_t>(u16(at) | (u16(at + 2) << 16));
    };
    auto f64 = [&](std::size_t at) {
        double v;
        std::memcpy(&v, &b[at], 8);
        return v;
    };
    auto text = [&](std::size_t at, std::size_t n) {
        std::string s(reinterpret_cast<const char*>(&b[at]), n);
        return s.substr(0, s.find('\0'));
    };
    h.system_id = text(26, 32);
    h.software = text(58, 32);
    h.day = static_cast<int>(u16(90));
    h.year = static_cast<int>(u16(92));
    std::size_t at = u16(94);
    const std::uint32_t points = u32(96);
    const std::uint32_t n_vlr = u32(100);
    for (std::uint32_t k = 0; k < n_vlr && at + 54 <= b.size(); ++k) {
        const std::string user = text(at + 2, 16);
        const unsigned id = u16(at + 18);
        const std::size_t len = u16(at + 20);
        if (user == "LASF_Projection" && id == 2112) h.wkt = text(at + 54, len);
        if (user == "pitmap" && id == 1) h.metadata_json = text(at + 54, len);
        at += 54 + len;
    }
    for (int a = 0; a < 3; ++a) {
        std::int32_t v;
        std::memcpy(&v, &b[points + 4 * static_cast<std::size_t>(a)], 4);
        h.first_xyz[a] = v * f64(131 + 8 * a) + f64(155 + 8 * a);
    }
    return h;
}

// The JSON chunk of a GLB and its first BIN chunk's offset (glTF 2.0, "GLB File Format").
json ReadGlbJson(const std::vector<std::uint8_t>& b, std::size_t* bin) {
    std::uint32_t n;
    std::memcpy(&n, &b[12], 4);
    *bin = 20 + n + 8;
    return json::parse(std::string(reinterpret_cast<const char*>(&b[20]), n));
}

CrsIdentity Describe(const std::string& wkt) {
    auto id = pitmap::proc::io::DescribeCrsWkt(wkt);
    EXPECT_TRUE(id) << id.error().message;
    return id ? *id : CrsIdentity{};
}

void ExpectSameCrs(const CrsIdentity& id, const json& meta, const std::string& product) {
    EXPECT_EQ(id.horizontal_epsg, meta["horizontal_crs"]["epsg"].get<int>()) << product;
    EXPECT_EQ(id.vertical_name, meta["vertical_crs"]["name"].get<std::string>()) << product;
    const json& v = meta["vertical_crs"]["epsg"];
    EXPECT_EQ(id.vertical_epsg, v.is_null() ? 0 : v.get<int>()) << product;
}

std::string Item(const pitmap::proc::io::GridRaster& g, const std::string& key) {
    for (const auto& [k, v] : g.metadata) {
        if (k == key) return v;
    }
    return "";
}

TEST(GeoreferencingScenario, EveryProductNamesOneCrsAndTheSurveysMetadata) {
    const fs::path dir = FreshDir("pitmap_georeferencing");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario demo --duration 40 --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    const std::string metadata =
        "metadata:\n  project: \"Bejanca bathymetry 2026\"\n  client: \"Mina & Filhos <SA>\"\n"
        "  site: Bejanca\n  survey_id: BJ-7\n  surveyor: \"A. Surveyor\"\n"
        "  organisation: \"Pit Survey Lda\"\n  s44_order_target: special\n"
        "  notes: \"first line\\nsecond line\"\n";
    for (const std::string datum : {"ellipsoid", "geoid", "water_level"}) {
        SCOPED_TRACE(datum);
        const fs::path P = dir / ("p_" + datum);
        std::ofstream(dir / (datum + ".yaml"))
            << metadata << "vertical:\n  datum: " << datum << "\n";
        ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir / "sim" / "log") + " --out " +
                                 Quote(P) + " --config " + Quote(dir / (datum + ".yaml")) +
                                 " --no-calibrate --no-slam --no-report",
                             &out),
                  0)
            << out;
        const json summary = ReadJson(P / "summary.json");
        ASSERT_TRUE(summary.contains("metadata")) << summary.dump();
        const json& m = summary["metadata"];
        // The schema the report's cover reads: every key there, text fields strings.
        for (const char* k : {"project",
                              "client",
                              "site",
                              "survey_id",
                              "surveyor",
                              "organisation",
                              "vessel",
                              "notes",
                              "survey_start_utc",
                              "survey_end_utc",
                              "processed_utc",
                              "software"}) {
            ASSERT_TRUE(m.contains(k) && m[k].is_string()) << k << " " << m.dump();
        }
        EXPECT_EQ(m["project"], "Bejanca bathymetry 2026");
        EXPECT_EQ(m["notes"], "first line\nsecond line");
        EXPECT_EQ(m["vessel"], "demo-asv") << "vessel unset: vehicle.yaml's name";
        EXPECT_EQ(m["s44_order_target"], "special");
        ASSERT_EQ(m["equipment"].size(), 2u) << m.dump();
        EXPECT_EQ(m["equipment"][0]["role"], "multibeam");
        EXPECT_EQ(m["equipment"][0]["model"], "Imagenex Delta T (pitmap-sim)");
        EXPECT_EQ(m["equipment"][1]["role"], "gnss_ins");
        // The survey's dates are its pings' (summary.json "time"), to the second.
        const std::string start = m["survey_start_utc"], end = m["survey_end_utc"];
        EXPECT_EQ(start, summary["time"]["first_ping_utc"].get<std::string>().substr(0, 19) + "Z");
        EXPECT_EQ(end, summary["time"]["last_ping_utc"].get<std::string>().substr(0, 19) + "Z");
        EXPECT_EQ(m["horizontal_crs"]["epsg"], summary["utm"]["epsg"]);
        if (datum == "geoid") {
            EXPECT_EQ(m["vertical_crs"]["epsg"], 5773);
            EXPECT_EQ(m["vertical_crs"]["name"], "EGM96 height");
        } else {
            EXPECT_TRUE(m["vertical_crs"]["epsg"].is_null());
        }
        if (datum == "water_level") {
            EXPECT_EQ(
                m["vertical_crs"]["name"].get<std::string>().rfind("Bejanca pit water level", 0),
                0u)
                << "named after the site";
        }
        EXPECT_EQ(m["vertical_crs"]["name"], summary["vertical_datum"]["vertical_crs"]);

        // dem.tif: the CRS and the metadata (TIFF tags and pitmap_* items).
        auto tif = pitmap::proc::io::ReadGrid((P / "dem.tif").string());
        ASSERT_TRUE(tif) << tif.error().message;
        CrsIdentity tif_id;
        tif_id.horizontal_epsg = tif->horizontal_epsg;
        tif_id.vertical_name = tif->vertical_name;
        tif_id.vertical_epsg = tif->vertical_epsg;
        ExpectSameCrs(tif_id, m, "dem.tif");
        EXPECT_EQ(Item(tif->grid, "TIFFTAG_DOCUMENTNAME"), "Bejanca bathymetry 2026");
        EXPECT_EQ(Item(tif->grid, "TIFFTAG_ARTIST"), "A. Surveyor, Pit Survey Lda");
        EXPECT_EQ(Item(tif->grid, "TIFFTAG_DATETIME"),
                  end.substr(0, 4) + ":" + end.substr(5, 2) + ":" + end.substr(8, 2) + " " +
                      end.substr(11, 8));
        EXPECT_EQ(Item(tif->grid, "pitmap_survey_start_utc"), start);
        EXPECT_EQ(Item(tif->grid, "pitmap_client"), "Mina & Filhos <SA>");
        // The whole CRS beside GeoTIFF's keys, read as the same CRS.
        ExpectSameCrs(Describe(Item(tif->grid, "pitmap_crs_wkt")), m, "dem.tif pitmap_crs_wkt");

        // dem.bag: the CRS and its ISO 19115 XML.
        auto bag = pitmap::proc::io::ReadGrid((P / "dem.bag").string());
        ASSERT_TRUE(bag) << bag.error().message;
        CrsIdentity bag_id;
        bag_id.horizontal_epsg = bag->horizontal_epsg;
        bag_id.vertical_name = bag->vertical_name;
        bag_id.vertical_epsg = bag->vertical_epsg;
        ExpectSameCrs(bag_id, m, "dem.bag");
        const std::string& xml = bag->bag_xml;
        for (const std::string& s :
             {std::string("<gco:CharacterString>A. Surveyor</gco:CharacterString>"),
              std::string("<gco:CharacterString>Pit Survey Lda</gco:CharacterString>"),
              std::string("codeListValue=\"productUncert\""),
              "<gco:Date>" + start.substr(0, 10) + "</gco:Date>",
              "<gco:DateTime>" + end + "</gco:DateTime>",
              std::string("Bejanca bathymetry 2026 / Bejanca / BJ-7"),
              std::string("Mina &amp; Filhos &lt;SA&gt;")}) {
            EXPECT_NE(xml.find(s), std::string::npos) << s;
        }
        EXPECT_EQ(xml.find("<gco:CharacterString>unknown</gco:CharacterString>\n      </gmd:"
                           "individualName>"),
                  std::string::npos);
        // No date of the BAG is the processing time's (the simulated survey is dated 2026-06-15).
        const std::string processed = m["processed_utc"];
        if (processed.substr(0, 10) != start.substr(0, 10)) {
            EXPECT_EQ(xml.find("<gco:Date>" + processed.substr(0, 10)), std::string::npos);
            EXPECT_EQ(xml.find("<gco:DateTime>" + processed.substr(0, 10)), std::string::npos);
        }

        // points.las: the WKT VLR as PROJ reads it, the header and the metadata VLR.
        const LasHeader las = ReadLas(P / "points.las");
        ExpectSameCrs(Describe(las.wkt), m, "points.las");
        EXPECT_EQ(las.software, m["software"].get<std::string>());
        EXPECT_EQ(las.system_id.rfind("demo-asv Imagenex Delta T", 0), 0u) << las.system_id;
        EXPECT_EQ(las.year, std::stoi(start.substr(0, 4)));
        ASSERT_FALSE(las.metadata_json.empty());
        const json las_meta = json::parse(las.metadata_json);
        EXPECT_EQ(las_meta["project"], m["project"]);
        EXPECT_EQ(las_meta["survey_start_utc"], start);
        EXPECT_EQ(las_meta["vertical_crs"], m["vertical_crs"]);

        // The sidecars and the glTF's CRS.
        ExpectSameCrs(Describe(ReadText(P / "points_utm.prj")), m, "points_utm.prj");
        ExpectSameCrs(Describe(ReadText(P / "mesh_utm.prj")), m, "mesh_utm.prj");
        const auto glb = ReadBytes(P / "mesh_utm.glb");
        std::size_t bin = 0;
        const json gltf = ReadGlbJson(glb, &bin);
        const json& node = gltf["nodes"][0];
        ExpectSameCrs(Describe(node["extras"]["pitmap_crs"]["wkt"]), m, "mesh_utm.glb");
        EXPECT_EQ(gltf["asset"]["extras"]["pitmap_metadata"]["project"], m["project"]);
        EXPECT_EQ(gltf["asset"]["extras"]["pitmap_metadata"]["survey_end_utc"], end);

        // mesh_utm.ply on dem.tif; the GLB's vertices are the PLY's.
        auto mesh = pitmap::formats::ply::ReadMesh((P / "mesh_utm.ply").string());
        ASSERT_TRUE(mesh) << mesh.error().message;
        ASSERT_GT(mesh->vertices.size(), 1000u);
        EXPECT_NE(std::find_if(mesh->comments.begin(),
                               mesh->comments.end(),
                               [](const std::string& c) {
                                   return c.rfind("pitmap_metadata {", 0) == 0 &&
                                          c.find("Bejanca bathymetry 2026") != std::string::npos;
                               }),
                  mesh->comments.end());
        const auto& g = tif->grid;
        const std::vector<float>& z = g.layers.front().values;
        std::vector<double> dz;
        for (const Eigen::Vector3d& v : mesh->vertices) {
            const long i = std::lround((v.x() - g.x0) / g.resolution_m);
            const long j = std::lround((v.y() - g.y0) / g.resolution_m);
            if (i < 0 || j < 0 || i >= g.nx || j >= g.ny) continue;
            const float e = z[static_cast<std::size_t>(j) * g.nx + static_cast<std::size_t>(i)];
            if (std::isfinite(e)) dz.push_back(std::abs(v.z() - e));
        }
        ASSERT_GT(dz.size(), mesh->vertices.size() / 2) << "the mesh over the DEM";
        std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
        EXPECT_LT(dz[dz.size() / 2], 0.02) << "median |mesh - DEM|, m";
        const double t[3] = {
            node["translation"][0], node["translation"][1], node["translation"][2]};
        double worst = 0;
        for (std::size_t i = 0; i < mesh->vertices.size(); i += 97) {
            float f[3];
            std::memcpy(f, &glb[bin + 12 * i], 12);
            const Eigen::Vector3d& v = mesh->vertices[i];
            worst = std::max({worst,
                              std::abs(f[0] + t[0] - v.x()),
                              std::abs(f[1] + t[1] - v.z()),
                              std::abs(-(f[2] + t[2]) - v.y())});
        }
        EXPECT_LT(worst, 1e-3) << "GLB vertex + translation vs PLY vertex, m";

        auto points = pitmap::formats::ply::ReadMesh((P / "points_utm.ply").string());
        ASSERT_TRUE(points) << points.error().message;
        ASSERT_FALSE(points->vertices.empty());
        for (int a = 0; a < 3; ++a) {
            EXPECT_NEAR(points->vertices.front()[a], las.first_xyz[a], 1e-3) << a;
        }
    }
}

}  // namespace
