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

#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::io {

struct GridLayer {
    std::string name;           // band description ("elevation", "uncertainty", ...)
    std::string unit;           // "metre", "" for counts
    std::vector<float> values;  // nx * ny, row-major from the south (j * nx + i); NaN = empty
};

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
    // The values are not heights (a backscatter mosaic): the file names the horizontal CRS only
    // and vertical_wkt is not used.
    bool horizontal_only = false;
    // Free-form dataset metadata (key, value).
    std::vector<std::pair<std::string, std::string>> metadata;
};

// Every layer as a Float32 band of a COG (DEFLATE, floating-point predictor, overviews).
Status WriteCogGeoTiff(const std::string& path, const GridRaster& grid);
// The layers named "elevation" and "uncertainty" (both required) as a BAG.
Status WriteBag(const std::string& path, const GridRaster& grid);

// Reads a north-up raster back (any GDAL format): geometry, every band (nodata -> NaN) and its
// description, and the CRS as WKT1 (empty if none). Refuses rotated geotransforms and rasters
// of more than max_cells cells.
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
