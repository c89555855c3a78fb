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
    std::vector<int> vertex_beam;  // the vertices' "beam" property (points.ply), else empty
    std::vector<std::string> comments;
};

Expected<PlyData> ReadPly(const std::string& path);

}  // namespace pitmap::eval
