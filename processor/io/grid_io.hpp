// SPDX-License-Identifier: MIT
// Gridded surfaces through GDAL (Debian's libgdal): a Cloud Optimized GeoTIFF with every layer
// as a band, and a BAG (Bathymetry Attributed Grid, ONS BAG 1.6 via GDAL's BAG driver) with
// elevation and uncertainty.
//
// Geometry: node (i, j) lies at x0 + i * resolution, y0 + j * resolution (row j = 0 is the
// southernmost) and is the centre of its pixel; the files are north-up (the first row is the
// northernmost). CRS: WGS 84 / UTM zone (EPSG 326zz / 327zz) with the vertical CRS
// GridRaster::vertical_wkt (the vertical datum of the heights, hydro/datum.hpp; default "WGS 84
// ellipsoidal height", as io::LasWkt). GeoTIFF: ellipsoidal heights as the UTM CRS promoted to
// 3D (ISO 19111 allows no compound of an ellipsoidal height; GeoTIFF 1.1 keys, read back by
// PROJ as LAS's COMPD_CS is), a gravity-related height as a compound CRS with the vertical
// EPSG code where it has one (EGM96 height 5773) and by name otherwise (GeoTIFF has no key for
// a user datum's name: the item pitmap_crs_wkt holds the whole CRS as WKT2); BAG stores the
// vertical CRS as WKT in its XML metadata (docs/georeferencing.md).
// No data: NaN in the GeoTIFF (every band), 1000000 in the BAG (the BAG convention); reading
// back gives NaN for both.
// Failure model: every function returns an error naming the file and GDAL's message.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/geodesy.hpp"
#include "common/product_metadata.hpp"
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
    // The survey's metadata (common/product_metadata.hpp), written where the format has a place
    // (GeoTIFF: TIFF tags DOCUMENTNAME, IMAGEDESCRIPTION, DATETIME (the survey's end), ARTIST,
    // COPYRIGHT, SOFTWARE and pitmap_* items; BAG: the ISO 19115 responsible party, citation,
    // dates and vertical uncertainty type). Empty: none of it.
    std::optional<ProductMetadata> product;
    GridSampleType sample_type = GridSampleType::kFloat32;  // GeoTIFF only (the BAG is Float32)

    // A raster on the same grid, CRS and survey metadata whose values are not heights (a
    // mosaic, a class map, slopes): horizontal CRS only, no layers yet, Float32.
    GridRaster OnSameGrid() const {
        GridRaster r;
        r.x0 = x0;
        r.y0 = y0;
        r.resolution_m = resolution_m;
        r.nx = nx;
        r.ny = ny;
        r.utm_zone = utm_zone;
        r.northern = northern;
        r.horizontal_only = true;
        r.metadata = metadata;
        r.product = product;
        return r;
    }

    // The values of the layer named `name`, or nullptr.
    const std::vector<float>* Values(const std::string& name) const {
        for (const GridLayer& l : layers) {
            if (l.name == name) return &l.values;
        }
        return nullptr;
    }
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

// A GDAL VRT mosaic of GeoTIFF tiles (GDALBuildVRT: every band, no data NaN, the tiles' CRS),
// the tiles named relative to the VRT's folder (`tiles` are paths relative to it), so the
// folder can be moved. Fails naming the VRT and GDAL's message (a tile missing or of another
// CRS or band count).
Status WriteVrt(const std::string& vrt_path, const std::vector<std::string>& tiles);

// How a reader sees a CRS (GDAL's OGRSpatialReference on PROJ): the horizontal CRS's name and
// EPSG code, the vertical CRS's name, datum and EPSG code, a compound CRS's vertical part or
// "<datum> ellipsoidal height" for a projected CRS promoted to 3D (the ISO 19111 form of
// ellipsoidal heights over a projected CRS, how PROJ reads LAS's COMPD_CS of a VERT_CS of
// datum type 2002). Empty names and 0 codes where the CRS has none.
struct CrsIdentity {
    std::string horizontal_name;
    int horizontal_epsg = 0;
    std::string vertical_name;
    std::string vertical_datum;
    int vertical_epsg = 0;
};
Expected<CrsIdentity> DescribeCrsWkt(const std::string& wkt);

// Reads a north-up raster back (any GDAL format): geometry, every band (nodata -> NaN) with its
// description, unit type and category names (class_names), the sample type (kByte for a Byte
// raster, else kFloat32: values are read as float), and the CRS as WKT1 (empty if none). Refuses
// rotated geotransforms and rasters of more than max_cells cells. The CRS's names and codes are
// DescribeCrsWkt's; grid.metadata holds the dataset's default-domain metadata items (the TIFF
// tags too).
struct GridReadBack {
    GridRaster grid;  // utm_zone/northern stay 0/true: see crs_wkt
    std::string crs_wkt;
    std::string horizontal_name;  // e.g. "WGS 84 / UTM zone 29N"
    std::string vertical_name;    // e.g. "WGS 84 ellipsoidal height", "" if none
    int horizontal_epsg = 0;      // 0 if none
    int vertical_epsg = 0;        // 0 if none (ellipsoidal heights, a water level)
    std::string driver;           // GDAL short name ("GTiff", "BAG")
    std::string bag_xml;          // BAG: its ISO 19115 XML ("xml:BAG" domain); "" otherwise
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
