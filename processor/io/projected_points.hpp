// SPDX-License-Identifier: MIT
// The soundings in the products' projected CRS (issue 39, docs/georeferencing.md):
// points_utm.ply beside points.las, for viewers that read PLY (CloudCompare, MeshLab) and
// overlay it on dem.tif, and the `.prj` sidecars that name the CRS of such a file.
// Failure model: an error naming the file and the reason; nothing half-written stays
// (common/formats/replace_file.hpp).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "common/product_metadata.hpp"
#include "common/result.hpp"

namespace pitmap::proc::io {

struct ProjectedPoints {
    std::vector<Eigen::Vector3d> positions;  // UTM easting, northing; height in the vertical CRS
    std::vector<double> gps_time_s;          // per point, GPS seconds since 1980-01-06
    std::vector<std::uint8_t> status;        // per point: 0 accepted, else SoundingStatus
    std::string crs_name;                    // "WGS 84 / UTM zone 29N + EGM96 height"
    int horizontal_epsg = 0;
    int vertical_epsg = 0;  // 0 = none
};

// Binary little-endian PLY: vertex properties double x, y, z (absolute UTM metres and height:
// no offset a reader would have to apply), double gps_time_s, uchar status; comments
// "pitmap_crs NAME", "pitmap_crs_epsg H V", "pitmap_metadata JSON" (common/product_metadata_json)
// and the run id. Precondition: the three vectors have one entry per point.
Status WriteProjectedPointsPly(const std::string& path,
                               const ProjectedPoints& points,
                               const ProductMetadata* meta = nullptr,
                               const std::string& run_id = "");

// One point of points_utm.ply.
struct ProjectedPoint {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();  // as ProjectedPoints::positions
    double gps_time_s = 0;
    std::uint8_t status = 0;
};
// Fills `out` with points first, first + 1, ... (out.size() of them).
using ProjectedPointBlock = std::function<void(std::size_t first, std::span<ProjectedPoint> out)>;

// The same file from `n` points made a block at a time: `fill` is asked for blocks of at most
// `block_points` points in order, so that the caller computes them where it reads them and
// holds one block (block_points x 32 bytes) instead of the survey's (33 bytes a sounding).
// `crs` gives the CRS fields (its vectors are not read). Precondition: block_points > 0.
Status WriteProjectedPointsPly(const std::string& path,
                               const ProjectedPoints& crs,
                               std::size_t n,
                               std::size_t block_points,
                               const ProjectedPointBlock& fill,
                               const ProductMetadata* meta = nullptr,
                               const std::string& run_id = "");

// `wkt` (WKT1, the ESRI .prj convention QGIS and CloudCompare read) as a text file.
Status WritePrj(const std::string& path, const std::string& wkt);

}  // namespace pitmap::proc::io
