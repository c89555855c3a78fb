// SPDX-License-Identifier: MIT
// The typing of the GeoTIFF bands (processor/io/grid_io.hpp, issue 39 item 4), read back with
// GDAL itself: units as written (a count says "count", not the vertical CRS's metre); a class
// raster is Byte with no data 255, a category table (in PATH.aux.xml, renamed with the file)
// and a colour table; overviews of class and count bands hold only values the band has, those
// of a continuous band are block means; bad class rasters are errors.
#include <cpl_conv.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <vector>

#include "processor/io/grid_io.hpp"

namespace pitmap::proc::io {
namespace {

namespace fs = std::filesystem;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

class GridTyping : public ::testing::Test {
protected:
    void SetUp() override {
        GDALAllRegister();
        dir_ = fs::temp_directory_path() /
               ("pitmap_grid_typing_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

// A 600 x 520 grid (two overview levels: 300 x 260, 150 x 130) in UTM 29N.
GridRaster Empty() {
    GridRaster g;
    g.nx = 600;
    g.ny = 520;
    g.resolution_m = 0.25;
    g.x0 = 587'000.125;
    g.y0 = 4'477'000.125;
    g.utm_zone = 29;
    g.northern = true;
    return g;
}

struct Closer {
    void operator()(GDALDataset* d) const { GDALClose(d); }
};
using Dataset = std::unique_ptr<GDALDataset, Closer>;
Dataset Open(const std::string& path) {
    return Dataset(static_cast<GDALDataset*>(
        GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
}

// Every value of a band (as double), file order.
std::vector<double> Values(GDALRasterBand* b) {
    std::vector<double> v(static_cast<std::size_t>(b->GetXSize()) * b->GetYSize());
    EXPECT_EQ(b->RasterIO(GF_Read,
                          0,
                          0,
                          b->GetXSize(),
                          b->GetYSize(),
                          v.data(),
                          b->GetXSize(),
                          b->GetYSize(),
                          GDT_Float64,
                          0,
                          0),
              CE_None);
    return v;
}

// The holiday map's shape: 0 covered, 1 in gaps, 2 in a holiday, NaN outside (a border 40
// nodes wide), in a checkerboard of 3 x 3 blocks so that any average of two classes would
// fall between them.
std::vector<float> Classes(const GridRaster& g) {
    std::vector<float> v(static_cast<std::size_t>(g.nx) * g.ny);
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            const bool outside = i < 40 || j < 40 || i >= g.nx - 40 || j >= g.ny - 40;
            v[static_cast<std::size_t>(j) * g.nx + i] =
                outside ? kNaN : static_cast<float>(((i / 3) + 2 * (j / 3)) % 3);
        }
    }
    return v;
}

GridRaster HolidayLike() {
    GridRaster g = Empty();
    g.horizontal_only = true;
    g.sample_type = GridSampleType::kByte;
    GridLayer l("holiday", "", Classes(g), GridBandKind::kClass);
    l.class_names = {"covered", "gap", "holiday"};
    l.class_colours = {{{190, 190, 190, 255}, {255, 190, 0, 255}, {220, 0, 0, 255}}};
    g.layers = {l};
    return g;
}

TEST_F(GridTyping, UnitsAreTheLayersOwnCountsSayCount) {
    // A grid with a vertical CRS: GDAL's GeoTIFF reader gives a band without a unit the
    // vertical CRS's (metre), so a count carries "count".
    GridRaster g = Empty();
    const std::size_t n = static_cast<std::size_t>(g.nx) * g.ny;
    g.layers = {{"elevation", "metre", std::vector<float>(n, 400.5f)},
                {"density", "count", std::vector<float>(n, 7.0f), GridBandKind::kCount}};
    const std::string path = (dir_ / "dem.tif").string();
    ASSERT_TRUE(WriteCogGeoTiff(path, g));
    Dataset ds = Open(path);
    ASSERT_TRUE(ds);
    EXPECT_STREQ(ds->GetRasterBand(1)->GetUnitType(), "metre");
    EXPECT_STREQ(ds->GetRasterBand(2)->GetUnitType(), "count");
    EXPECT_EQ(ds->GetRasterBand(2)->GetRasterDataType(), GDT_Float32);
    EXPECT_FALSE(fs::exists(path + ".aux.xml"));  // nothing that needs one
    auto r = ReadGrid(path);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->grid.layers[1].unit, "count");
    EXPECT_EQ(r->grid.sample_type, GridSampleType::kFloat32);
}

TEST_F(GridTyping, ClassRasterIsByteWithCategoryAndColourTables) {
    const GridRaster g = HolidayLike();
    const std::string path = (dir_ / "s44_holidays.tif").string();
    const Status w = WriteCogGeoTiff(path, g);
    ASSERT_TRUE(w) << w.error().message;
    // The category names live in GDAL's side file, renamed with the file; no partial file left.
    EXPECT_TRUE(fs::exists(path + ".aux.xml"));
    for (const auto& e : fs::directory_iterator(dir_)) {
        EXPECT_EQ(e.path().filename().string().rfind(".partial-", 0), std::string::npos)
            << e.path();
    }
    Dataset ds = Open(path);
    ASSERT_TRUE(ds);
    GDALRasterBand* b = ds->GetRasterBand(1);
    EXPECT_EQ(b->GetRasterDataType(), GDT_Byte);
    EXPECT_STREQ(b->GetUnitType(), "");  // no vertical CRS, no unit
    int has_nodata = 0;
    EXPECT_EQ(b->GetNoDataValue(&has_nodata), 255.0);
    EXPECT_TRUE(has_nodata);
    char** names = b->GetCategoryNames();
    ASSERT_NE(names, nullptr);
    ASSERT_EQ(CSLCount(names), 3);
    EXPECT_STREQ(names[0], "covered");
    EXPECT_STREQ(names[1], "gap");
    EXPECT_STREQ(names[2], "holiday");
    EXPECT_STREQ(b->GetMetadataItem("pitmap_classes"), "0 covered, 1 gap, 2 holiday");
    const GDALColorTable* ct = b->GetColorTable();
    ASSERT_NE(ct, nullptr);
    EXPECT_EQ(b->GetColorInterpretation(), GCI_PaletteIndex);
    const GDALColorEntry* red = ct->GetColorEntry(2);
    ASSERT_NE(red, nullptr);
    EXPECT_EQ(red->c1, 220);
    EXPECT_EQ(red->c2, 0);
    EXPECT_EQ(red->c4, 255);
    EXPECT_EQ(ct->GetColorEntry(255)->c4, 0);  // no data: transparent
    // The values: the classes where given, 255 outside; ReadGrid turns 255 back into NaN.
    const std::vector<double> v = Values(b);
    std::set<double> seen(v.begin(), v.end());
    EXPECT_EQ(seen, (std::set<double>{0, 1, 2, 255}));
    auto r = ReadGrid(path);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->grid.sample_type, GridSampleType::kByte);
    EXPECT_EQ(r->grid.layers[0].class_names, g.layers[0].class_names);
    const auto& back = r->grid.layers[0].values;
    ASSERT_EQ(back.size(), g.layers[0].values.size());
    for (std::size_t k = 0; k < back.size(); ++k) {
        const float a = g.layers[0].values[k];
        if (std::isnan(a)) {
            ASSERT_TRUE(std::isnan(back[k])) << k;
        } else {
            ASSERT_EQ(back[k], a) << k;
        }
    }
    // Written again without classes: the stale side file goes.
    GridRaster plain = Empty();
    plain.horizontal_only = true;
    plain.layers = {
        {"x", "", std::vector<float>(static_cast<std::size_t>(plain.nx) * plain.ny, 1.0f)}};
    ASSERT_TRUE(WriteCogGeoTiff(path, plain));
    EXPECT_FALSE(fs::exists(path + ".aux.xml"));
}

TEST_F(GridTyping, OverviewsOfClassesAndCountsHoldOnlyTheBandsValues) {
    // The class raster: every overview pixel is a class of the band or no data.
    const std::string hol = (dir_ / "hol.tif").string();
    ASSERT_TRUE(WriteCogGeoTiff(hol, HolidayLike()));
    {
        Dataset ds = Open(hol);
        ASSERT_TRUE(ds);
        GDALRasterBand* b = ds->GetRasterBand(1);
        ASSERT_EQ(b->GetOverviewCount(), 2);
        for (int k = 0; k < b->GetOverviewCount(); ++k) {
            const std::vector<double> v = Values(b->GetOverview(k));
            const std::set<double> seen(v.begin(), v.end());
            for (double x : seen) EXPECT_TRUE(x == 0 || x == 1 || x == 2 || x == 255) << x;
            EXPECT_GE(seen.size(), 3u);  // the classes survive the zoom
        }
    }
    // A Float32 file: a continuous band (a plane), a count band and a class band (0/1 flags).
    GridRaster g = Empty();
    const std::size_t n = static_cast<std::size_t>(g.nx) * g.ny;
    GridLayer plane("elevation", "metre", std::vector<float>(n));
    GridLayer count("density", "count", std::vector<float>(n), GridBandKind::kCount);
    GridLayer flag("meets", "", std::vector<float>(n), GridBandKind::kClass);
    std::set<double> counts;
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            const std::size_t k = static_cast<std::size_t>(j) * g.nx + i;
            plane.values[k] = static_cast<float>(i + 1000 * j);
            count.values[k] = static_cast<float>((i * 7 + j * 3) % 11);  // 0..10
            flag.values[k] = static_cast<float>((i + j) % 2);
            counts.insert(count.values[k]);
        }
    }
    g.layers = {plane, count, flag};
    const std::string dem = (dir_ / "dem.tif").string();
    ASSERT_TRUE(WriteCogGeoTiff(dem, g));
    Dataset ds = Open(dem);
    ASSERT_TRUE(ds);
    for (int k = 0; k < 2; ++k) {
        GDALRasterBand* o = ds->GetRasterBand(2)->GetOverview(k);
        ASSERT_NE(o, nullptr);
        for (double x : Values(o)) ASSERT_TRUE(counts.count(x)) << "count overview value " << x;
        for (double x : Values(ds->GetRasterBand(3)->GetOverview(k))) {
            ASSERT_TRUE(x == 0 || x == 1) << "flag overview value " << x;
        }
    }
    // The continuous band's first overview is the mean of each 2 x 2 block. File row y holds
    // grid row ny - 1 - y: overview pixel (0, 0) averages file rows 0, 1 (grid rows 519, 518)
    // and columns 0, 1: (0.5 + 1000 x 518.5).
    GDALRasterBand* o = ds->GetRasterBand(1)->GetOverview(0);
    ASSERT_EQ(o->GetXSize(), 300);
    const std::vector<double> v = Values(o);
    EXPECT_NEAR(v[0], 0.5 + 1000 * 518.5, 0.05);
    EXPECT_NEAR(v[1], 2.5 + 1000 * 518.5, 0.05);
}

TEST_F(GridTyping, BadClassRastersAreErrors) {
    const std::string path = (dir_ / "bad.tif").string();
    GridRaster g = HolidayLike();
    g.layers[0].values[100 * g.nx + 100] = 2.5f;  // not a whole number
    auto s = WriteCogGeoTiff(path, g);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("whole number"), std::string::npos) << s.error().message;
    g = HolidayLike();
    g.layers[0].values[100 * g.nx + 100] = 255.0f;  // the no-data value
    EXPECT_FALSE(WriteCogGeoTiff(path, g));
    g = HolidayLike();
    g.sample_type = GridSampleType::kFloat32;  // class names need a Byte raster
    s = WriteCogGeoTiff(path, g);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("Byte"), std::string::npos) << s.error().message;
    EXPECT_FALSE(fs::exists(path));
    EXPECT_FALSE(fs::exists(path + ".aux.xml"));
}

}  // namespace
}  // namespace pitmap::proc::io
