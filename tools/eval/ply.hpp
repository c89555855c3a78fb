// SPDX-License-Identifier: MIT
// A small PLY reader for scoring products: vertices (x, y, z as float or double) and faces
// (vertex index lists), from ascii or binary_little_endian files. Other elements and
// properties are skipped by their declared types. Comments are returned (products carry their
// world origin in a "comment pitmap_origin lat lon h" line).
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "common/result.hpp"

namespace pitmap::eval {

struct PlyData {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;  // polygons fan-triangulated
    std::vector<std::string> comments;
    // The vertex properties asked for, in the order asked, one value per vertex.
    std::vector<std::vector<double>> vertex_properties;
};

// `vertex_properties`: further scalar vertex properties to keep (e.g. "gps_time_s"); a file
// without one of them is an error naming it.
Expected<PlyData> ReadPly(const std::string& path,
                          const std::vector<std::string>& vertex_properties = {});

}  // namespace pitmap::eval
