// SPDX-License-Identifier: MIT
// The selection of pitmap edit (processor/edit): which soundings lie inside a lasso or box
// drawn on a view of the page. Pure maths, no I/O.
//
// The page draws on a three.js view; it sends the polygon in normalised device coordinates
// (NDC: x, y in [-1, 1], y up) and the view's view-projection matrix (projection times the
// inverse of the camera's world matrix, column-major as three.js Matrix4.elements keeps it) in
// the frame the soundings were sent in (metres east, north, up from the session's centre). The
// server projects every sounding with it, not only those the page shows: clip = M [x y z 1]^T,
// NDC = clip.xyz / clip.w. A sounding is inside when clip.w > 0 (in front of the camera),
// -1 <= NDC.z <= 1 (between the near and far planes: for the cross-section view, whose
// orthographic camera's near and far planes bound the slab, this is the slab) and (NDC.x,
// NDC.y) lies inside the polygon by the even-odd rule (a self-crossing lasso selects what an
// odd number of its loops enclose). A point exactly on an edge is inside for the edges on its
// left and bottom, outside for those on its right and top (the half-open crossing test), so
// that two polygons sharing an edge never both hold a point.
// Failure model: a query with fewer than 3 vertices, more than kMaxPolygonVertices, or a
// non-finite number is refused by Validate (the server answers 400); a degenerate polygon
// (zero area) selects nothing. Soundings with non-finite coordinates are never inside.
// Thread safety: the functions are pure; SelectInPolygon runs on TBB's threads (num_threads,
// 0 = all cores) and its result (sorted indices) does not depend on their number.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace pitmap::proc::edit {

inline constexpr std::size_t kMaxPolygonVertices = 4096;

struct NdcPoint {
    double x = 0;
    double y = 0;
};

struct SelectionQuery {
    std::array<double, 16> view_projection{};  // column-major (three.js Matrix4.elements)
    std::vector<NdcPoint> polygon;             // NDC; closed implicitly (last -> first)
    // Every problem ("" none): vertex count, non-finite numbers.
    std::vector<std::string> Validate() const;
};

// The polygon of an axis-aligned box between two corners (any two opposite ones).
std::vector<NdcPoint> BoxPolygon(NdcPoint a, NdcPoint b);

// Even-odd point in polygon (half-open edges, as above).
bool InsidePolygon(const std::vector<NdcPoint>& polygon, double x, double y);

// A sounding projected: NDC and whether it is in front of the camera and between the planes.
struct Projected {
    double x = 0, y = 0, z = 0;
    bool in_view = false;  // clip.w > 0 and -1 <= z <= 1, all finite
};
Projected Project(const std::array<double, 16>& m, double x, double y, double z);

// The indices i in [0, n) of the soundings xyz[3i..3i+2] (float, the session's frame) inside
// the query's polygon for which `eligible(i)` is true (no function: all), sorted ascending.
// Precondition: query.Validate() is empty.
std::vector<std::uint32_t> SelectInPolygon(const float* xyz,
                                           std::size_t n,
                                           const SelectionQuery& query,
                                           const std::function<bool(std::size_t)>& eligible = {},
                                           int num_threads = 0);

}  // namespace pitmap::proc::edit
