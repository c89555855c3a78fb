// SPDX-License-Identifier: MIT
// Mesh file writers of the mesh stage (a separate writer unit; the stage itself does no I/O):
// PLY (binary little endian, per-vertex RGB), OBJ (ASCII, "v x y z r g b" vertex colours as
// MeshLab reads them) and glTF 2.0 binary (.glb, for VR engines and Blender).
// Coordinates are the local ENU world frame in metres. When an origin is given it is written as
// "comment pitmap_origin LAT LON H" (PLY, read by tools/eval), "# pitmap_origin ..." (OBJ) and
// asset.extras.pitmap_origin (glTF). glTF is y-up: it stores (x, y, z)_gltf = (E, U, -N).
// A run id (the survey's, processor/survey/survey.hpp) is written when given, as
// "comment pitmap_run_id ID" (PLY), "# pitmap_run_id ID" (OBJ), asset.extras.pitmap_run_id (glTF).
// Each file is written under a temporary name and renamed (common/formats/replace_file.hpp).
// All writers fail with an Error naming the path and the reason (no throw).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/product_metadata.hpp"
#include "common/result.hpp"
#include "processor/mesh/surface.hpp"

namespace pitmap::proc::mesh {

Status WritePly(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin = std::nullopt,
                const std::string& run_id = "");
Status WriteObj(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin = std::nullopt,
                const std::string& run_id = "");
Status WriteGlb(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin = std::nullopt,
                const std::string& run_id = "");

// The mesh in the products' projected CRS (issue 39: mesh_utm.*, docs/georeferencing.md): every
// vertex as UTM easting, northing and height in the products' vertical CRS, so the mesh
// overlays dem.tif and points.las.
struct ProjectedMesh {
    std::vector<Eigen::Vector3d> positions;  // one per mesh vertex, metres
    // A whole-metre point near the vertices (the floor of their minimum): glTF's vertices are
    // float32 relative to it (a float holds UTM coordinates to 0.5 m only).
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
    std::string crs_name;     // "WGS 84 / UTM zone 29N + EGM96 height"
    std::string crs_wkt;      // WKT1 COMPD_CS (io::LasWkt), as the .prj sidecar holds it
    int horizontal_epsg = 0;  // 326zz / 327zz
    int vertical_epsg = 0;    // 0 = none
};
// Sets `offset` from the positions (the floor of their minimum; 0 without vertices).
void SetOffset(ProjectedMesh& p);

// PLY, binary little endian: vertex properties double x, y, z (UTM easting, northing, height:
// absolute, doubles lose nothing, and CloudCompare and QGIS's mesh reader take them as they are,
// where no reader applies an offset stored beside float coordinates), uchar red, green, blue;
// comments name the CRS ("pitmap_crs NAME", "pitmap_crs_epsg H V"), the metadata
// ("pitmap_metadata JSON") and the run id. Precondition: positions.size() == vertices.size().
Status WriteProjectedPly(const ColouredMesh& mesh,
                         const ProjectedMesh& projected,
                         const std::string& path,
                         const ProductMetadata* meta = nullptr,
                         const std::string& run_id = "");
// glTF 2.0 binary: float32 vertices relative to the offset, in glTF's y-up axes (x = easting,
// y = height, z = -northing), the offset as the node's translation (the same axes) and in the
// node's extras (pitmap_offset {easting_m, northing_m, height_m}, pitmap_crs {name,
// horizontal_epsg, vertical_epsg, wkt}); asset.extras.pitmap_metadata the metadata (JSON).
Status WriteProjectedGlb(const ColouredMesh& mesh,
                         const ProjectedMesh& projected,
                         const std::string& path,
                         const ProductMetadata* meta = nullptr,
                         const std::string& run_id = "");

}  // namespace pitmap::proc::mesh
