// SPDX-License-Identifier: MIT
// Gridded surfaces through GDAL (processor/io/grid_io.hpp): a COG GeoTIFF and a BAG read back
// by GDAL with the same values, empty nodes, geometry, horizontal CRS (EPSG) and vertical CRS;
// bad grids and unreadable files are errors naming the file; a VRT of tiles reads back as the
// whole grid.
#include "processor/io/grid_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;

GridRaster Sample(int zone, bool northern) {
    GridRaster g;
    g.nx = 37;
    g.ny = 23;
    g.resolution_m = 0.5;
    g.x0 = 587'312.25;
    g.y0 = 4'477'051.75;
    g.utm_zone = zone;
    g.northern = northern;
    const std::size_t n = static_cast<std::size_t>(g.nx * g.ny);
    GridLayer e{"elevation", "metre", std::vector<float>(n)};
    GridLayer u{"uncertainty", "metre", std::vector<float>(n)};
    GridLayer d{"density", "", std::vector<float>(n)};
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            const std::size_t k = static_cast<std::size_t>(j * g.nx + i);
            // Distinct rows and columns, so a flipped or transposed read shows.
            e.values[k] = static_cast<float>(390.0 - 0.37 * i - 1.13 * j + 1e-3 * (i * j % 7));
            u.values[k] = static_cast<float>(0.05 + 0.001 * i + 0.0001 * j);
            d.values[k] = static_cast<float>(i + 100 * j);
        }
    }
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t k : {std::size_t{0}, std::size_t{5}, n - 1}) {
        e.values[k] = u.values[k] = d.values[k] = nan;
    }
    g.layers = {e, u, d};
    g.metadata = {{"pitmap_vertical_datum", "WGS 84 ellipsoidal height"}};
    return g;
}

class GridIo : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("pitmap_grid_io_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

void ExpectSameLayer(const GridLayer& a, const GridLayer& b) {
    ASSERT_EQ(a.values.size(), b.values.size());
    for (std::size_t k = 0; k < a.values.size(); ++k) {
        if (std::isnan(a.values[k])) {
            EXPECT_TRUE(std::isnan(b.values[k])) << a.name << " " << k;
        } else {
            EXPECT_EQ(a.values[k], b.values[k]) << a.name << " " << k;
        }
    }
}

void ExpectSameGeometry(const GridRaster& a, const GridRaster& b) {
    EXPECT_EQ(a.nx, b.nx);
    EXPECT_EQ(a.ny, b.ny);
    EXPECT_DOUBLE_EQ(a.resolution_m, b.resolution_m);
    EXPECT_NEAR(a.x0, b.x0, 1e-6);
    EXPECT_NEAR(a.y0, b.y0, 1e-6);
}

TEST_F(GridIo, CogGeoTiffReadsBackTheSameValuesAndCrs) {
    const GridRaster g = Sample(29, true);
    const std::string path = (dir_ / "dem.tif").string();
    const Status w = WriteCogGeoTiff(path, g);
    ASSERT_TRUE(w) << w.error().message;
    auto r = ReadGrid(path);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->driver, "GTiff");
    ExpectSameGeometry(g, r->grid);
    ASSERT_EQ(r->grid.layers.size(), 3u);
    for (int b = 0; b < 3; ++b) {
        EXPECT_EQ(r->grid.layers[b].name, g.layers[b].name);
        ExpectSameLayer(g.layers[b], r->grid.layers[b]);
    }
    EXPECT_EQ(r->horizontal_epsg, 32629);
    EXPECT_EQ(r->horizontal_name, "WGS 84 / UTM zone 29N");
    EXPECT_EQ(r->vertical_name, "WGS 84 ellipsoidal height") << r->crs_wkt;
    // A COG: tiled, with the layout GDAL's COG driver writes.
    std::ifstream in(path, std::ios::binary);
    std::string head(512, '\0');
    in.read(head.data(), 512);
    EXPECT_NE(head.find("LAYOUT=IFDS_BEFORE_DATA"), std::string::npos);
}

// A VRT of two tiles of the sample (west and east halves, in a folder of their own) reads back
// as the whole sample, band for band, from its relative paths after the folder moved; a missing
// tile is an error naming the VRT.
TEST_F(GridIo, VrtOfTilesReadsBackAsTheWholeGrid) {
    const GridRaster g = Sample(29, true);
    fs::create_directories(dir_ / "out/tiles");
    std::vector<std::string> names;
    for (int part = 0; part < 2; ++part) {
        GridRaster t = g;
        const int i0 = part == 0 ? 0 : 20;
        t.nx = part == 0 ? 20 : g.nx - 20;
        t.x0 = g.x0 + i0 * g.resolution_m;
        for (std::size_t l = 0; l < g.layers.size(); ++l) {
            t.layers[l].values.clear();
            for (int j = 0; j < g.ny; ++j) {
                for (int i = 0; i < t.nx; ++i) {
                    t.layers[l].values.push_back(
                        g.layers[l].values[static_cast<std::size_t>(j * g.nx + i0 + i)]);
                }
            }
        }
        names.push_back("tiles/t" + std::to_string(part) + ".tif");
        ASSERT_TRUE(WriteCogGeoTiff((dir_ / "out" / names.back()).string(), t));
    }
    const Status w = WriteVrt((dir_ / "out/dem.vrt").string(), names);
    ASSERT_TRUE(w) << w.error().message;
    fs::rename(dir_ / "out", dir_ / "moved");
    auto r = ReadGrid((dir_ / "moved/dem.vrt").string());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->driver, "VRT");
    ExpectSameGeometry(g, r->grid);
    ASSERT_EQ(r->grid.layers.size(), 3u);
    for (int b = 0; b < 3; ++b) ExpectSameLayer(g.layers[b], r->grid.layers[b]);
    EXPECT_EQ(r->horizontal_epsg, 32629);
    const Status missing = WriteVrt((dir_ / "moved/bad.vrt").string(), {"tiles/none.tif"});
    ASSERT_FALSE(missing);
    EXPECT_NE(missing.error().message.find("bad.vrt"), std::string::npos);
}

// A mosaic's values are not heights: its GeoTIFF names the horizontal CRS only, and the
// bands keep their dB unit.
TEST_F(GridIo, AHorizontalOnlyGeoTiffHasNoVerticalCrs) {
    GridRaster g = Sample(29, true);
    g.horizontal_only = true;
    g.layers[0].name = "backscatter";
    g.layers[0].unit = "dB";
    const std::string path = (dir_ / "mosaic.tif").string();
    const Status w = WriteCogGeoTiff(path, g);
    ASSERT_TRUE(w) << w.error().message;
    auto r = ReadGrid(path);
    ASSERT_TRUE(r) << r.error().message;
    ExpectSameGeometry(g, r->grid);
    ExpectSameLayer(g.layers[0], r->grid.layers[0]);
    EXPECT_EQ(r->grid.layers[0].name, "backscatter");
    EXPECT_EQ(r->grid.layers[0].unit, "dB");
    EXPECT_EQ(r->horizontal_epsg, 32629);
    EXPECT_EQ(r->vertical_name, "") << r->crs_wkt;
}

TEST_F(GridIo, BagReadsBackElevationUncertaintyAndCrs) {
    const GridRaster g = Sample(33, false);
    const std::string path = (dir_ / "dem.bag").string();
    const Status w = WriteBag(path, g);
    ASSERT_TRUE(w) << w.error().message;
    auto r = ReadGrid(path);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->driver, "BAG");
    ExpectSameGeometry(g, r->grid);
    ASSERT_GE(r->grid.layers.size(), 2u);
    ExpectSameLayer(g.layers[0], r->grid.layers[0]);
    ExpectSameLayer(g.layers[1], r->grid.layers[1]);
    EXPECT_EQ(r->horizontal_epsg, 32733);
    EXPECT_EQ(r->vertical_name, "WGS 84 ellipsoidal height") << r->crs_wkt;
    EXPECT_NE(r->crs_wkt.find("2002"), std::string::npos) << r->crs_wkt;  // ellipsoidal datum
}

TEST_F(GridIo, BadGridsAndFilesAreErrorsNamingTheFile) {
    GridRaster g = Sample(29, true);
    const std::string path = (dir_ / "x.tif").string();
    g.layers[1].values.pop_back();
    auto s = WriteCogGeoTiff(path, g);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find(path), std::string::npos);
    g = Sample(0, true);
    EXPECT_FALSE(WriteBag((dir_ / "x.bag").string(), g));
    g = Sample(29, true);
    g.layers.erase(g.layers.begin() + 1);
    EXPECT_FALSE(WriteBag((dir_ / "x.bag").string(), g));  // no uncertainty
    EXPECT_FALSE(WriteCogGeoTiff((dir_ / "no/such/dir/a.tif").string(), Sample(29, true)));
    std::ofstream(dir_ / "garbage.tif") << "II*\0 not really a tiff";
    auto r = ReadGrid((dir_ / "garbage.tif").string());
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find("garbage.tif"), std::string::npos);
    EXPECT_FALSE(ReadGrid((dir_ / "missing.bag").string()));
}

}  // namespace
}  // namespace pitmap::proc::io
