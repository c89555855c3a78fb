// SPDX-License-Identifier: MIT
// Gridded surfaces through GDAL (Debian's libgdal): a Cloud Optimized GeoTIFF with every layer
// as a band, and a BAG (Bathymetry Attributed Grid, ONS BAG 1.6 via GDAL's BAG driver) with
// elevation and uncertainty.
//
// Geometry: node (i, j) lies at x0 + i * resolution, y0 + j * resolution (row j = 0 is the
// southernmost) and is the centre of its pixel; the files are north-up (the first row is the
// northernmost). CRS: WGS 84 / UTM zone (EPSG 326zz / 327zz) compound with the vertical CRS
// GridRaster::vertical_wkt (the vertical datum of the heights, hydro/datum.hpp; default "WGS 84
// ellipsoidal height", as io::LasWkt). GeoTIFF stores the vertical CRS by its EPSG code where it
// has one (EGM96 height 5773) and by name otherwise; BAG stores it in its XML metadata.
// No data: NaN in the GeoTIFF (every band), 1000000 in the BAG (the BAG convention); reading
// back gives NaN for both.
// Failure model: every function returns an error naming the file and GDAL's message.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::io {

// How a layer's values combine (its overviews) and what they are.
enum class GridBandKind {
    kContinuous = 0,  // a measured quantity (heights, uncertainty, dB): overviews average
    kCount,           // whole numbers counted per node: overviews take the nearest node's
    kClass,           // class codes 0..254 named in class_names: overviews take the mode
};

struct GridLayer {
    GridLayer() = default;
    GridLayer(std::string name_,
              std::string unit_,
              std::vector<float> values_,
              GridBandKind kind_ = GridBandKind::kContinuous)
        : name(std::move(name_)), unit(std::move(unit_)), values(std::move(values_)), kind(kind_) {}
    std::string name;           // band description ("elevation", "uncertainty", ...)
    std::string unit;           // "metre", "dB", "count"; "" for none (class codes)
    std::vector<float> values;  // nx * ny, row-major from the south (j * nx + i); NaN = empty
    GridBandKind kind = GridBandKind::kContinuous;
    // kClass: the name and the RGBA colour of class v at index v (a GDAL category table and
    // colour table; a Byte raster only).
    std::vector<std::string> class_names;
    std::vector<std::array<std::uint8_t, 4>> class_colours;
    std::vector<std::pair<std::string, std::string>> metadata;  // band metadata (key, value)
};

// The GeoTIFF's one sample type (a TIFF holds one for all its bands).
enum class GridSampleType {
    kFloat32 = 0,  // no data NaN
    kByte,         // whole numbers 0..254, no data 255 (kByteNoData)
};
inline constexpr std::uint8_t kByteNoData = 255;

struct GridRaster {
    double x0 = 0, y0 = 0;  // centre of node (0, 0), the south-west one, m (UTM)
    double resolution_m = 0;
    int nx = 0, ny = 0;
    int utm_zone = 0;  // 1..60
    bool northern = true;
    std::vector<GridLayer> layers;
    // The heights' vertical CRS as OGC WKT1 VERT_CS (hydro::DatumModel::VerticalWkt); "" = WGS 84
    // ellipsoidal height.
    std::string vertical_wkt;
    // The values are not heights (a backscatter mosaic, a class map): the file names the
    // horizontal CRS only and vertical_wkt is not used.
    bool horizontal_only = false;
    // Free-form dataset metadata (key, value).
    std::vector<std::pair<std::string, std::string>> metadata;
    GridSampleType sample_type = GridSampleType::kFloat32;  // GeoTIFF only (the BAG is Float32)
};

// Every layer as a band of a COG (DEFLATE, predictor, 256 x 256 tiles) of the grid's sample
// type. Overviews (2, 4, ... until both sides are at most 256 pixels) per band by its kind:
// average (continuous), nearest (counts), mode (classes; no data is never a mode), so a class
// or count band zoomed out holds only values the band has. A band's unit is its GDAL unit type;
// note that GDAL's GeoTIFF reader gives a band without one the vertical CRS's unit (metre),
// so a band that is not a height in a file with a vertical CRS needs a unit of its own.
// kClass bands: band metadata item "pitmap_classes" ("0 NAME, 1 NAME, ...") in the TIFF, the
// colour table in the TIFF, the category names in PATH.aux.xml (GDAL keeps category names
// only there), which is written and renamed with the file, or removed when there is none.
// Errors: sample values a Byte band cannot hold (not a whole number 0..254, nor NaN), class
// names or colours on a Float32 raster, and GDAL's.
Status WriteCogGeoTiff(const std::string& path, const GridRaster& grid);
// The layers named "elevation" and "uncertainty" (both required) as a BAG.
Status WriteBag(const std::string& path, const GridRaster& grid);

// Reads a north-up raster back (any GDAL format): geometry, every band (nodata -> NaN) with its
// description, unit type and category names (class_names), the sample type (kByte for a Byte
// raster, else kFloat32: values are read as float), and the CRS as WKT1 (empty if none). Refuses
// rotated geotransforms and rasters of more than max_cells cells.
struct GridReadBack {
    GridRaster grid;  // utm_zone/northern stay 0/true: see crs_wkt
    std::string crs_wkt;
    std::string horizontal_name;  // e.g. "WGS 84 / UTM zone 29N"
    std::string vertical_name;    // e.g. "WGS 84 ellipsoidal height", "" if none
    int horizontal_epsg = 0;      // 0 if none
    std::string driver;           // GDAL short name ("GTiff", "BAG")
};
Expected<GridReadBack> ReadGrid(const std::string& path, std::size_t max_cells = 200'000'000);

// Per-sounding uncertainty beside the soundings: binary little-endian PLY, vertex properties
// float x, y, z (world ENU, as points.ply), double gps_time_s, float angle_deg (beam angle,
// sonar frame), float thu_95_m, float tvu_95_m; comment "pitmap_origin LAT LON H" and, when
// given, "pitmap_run_id ID".
// Precondition: thu/tvu have one value per sounding of `geo`.
Status WriteSoundingTpuPly(const std::string& path,
                           const georef::GeorefResult& geo,
                           const std::vector<float>& thu_95_m,
                           const std::vector<float>& tvu_95_m,
                           const std::string& run_id = "");

}  // namespace pitmap::proc::io
