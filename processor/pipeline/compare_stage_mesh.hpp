// SPDX-License-Identifier: MIT
// pitmap compare's change mesh (issue 37 item 2; processor/compare/change_mesh.hpp): reading
// the two folders' TSDF meshes in the products' CRS (mesh_utm.ply) and writing B's mesh with
// the change per vertex:
//   change_mesh.ply  binary PLY: double x, y, z (A's CRS, the vertical CRS of the mesh), float
//                    nx, ny, nz (B's normal, towards the water), distance_m (B - A along it, NaN
//                    where A has no surface within reach), lod95_m, char significance (-1 loss,
//                    0 no detectable change, +1 gain), uchar red, green, blue (the colours
//                    below); faces as mesh_utm.ply's. CloudCompare and MeshLab show the scalar
//                    properties; the CRS is named in the comments.
//   change_mesh.glb  glTF 2.0 binary, as mesh_utm.glb: float32 positions relative to a whole-
//                    metre offset (the node's translation and extras.pitmap_offset), y-up
//                    (x = easting, y = height, z = -northing), NORMAL, COLOR_0 (the colours),
//                    and the custom attributes _DISTANCE, _LOD95, _SIGNIFICANCE (float; glTF's
//                    application-specific attributes, which Blender imports as mesh
//                    attributes; 0, 0, 0 where not measured: no NaN in a glTF accessor).
// Colours: significant change on a diverging ramp, white at 0 to full red (gain) or blue
// (loss) at colour_scale_m; no detectable change light grey; not measured dark grey.
#pragma once

#include <optional>
#include <string>

#include "common/result.hpp"
#include "processor/compare/change_mesh.hpp"

namespace pitmap::proc::pipeline {

// The folder's mesh_utm.ply (nullopt when it is not there); an error when it is damaged or in
// another horizontal CRS than `epsg`.
Expected<std::optional<compare::TriangleMesh>> ReadMeshUtm(const std::string& dir, int epsg);

Status WriteChangeMesh(const std::string& out_dir,
                       const compare::TriangleMesh& b,
                       const compare::ChangeMeshResult& change,
                       int epsg,
                       const std::string& crs_name,
                       double colour_scale_m);

}  // namespace pitmap::proc::pipeline
