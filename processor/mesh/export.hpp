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

#include "common/geodesy.hpp"
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

}  // namespace pitmap::proc::mesh
