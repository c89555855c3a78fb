// SPDX-License-Identifier: MIT
// Mesh file writers of the mesh stage (a separate writer unit; the stage itself does no I/O):
// PLY (binary little endian, per-vertex RGB), OBJ (ASCII, "v x y z r g b" vertex colours as
// MeshLab reads them) and glTF 2.0 binary (.glb, for VR engines and Blender).
// Coordinates are the local ENU world frame in metres. When an origin is given it is written as
// "comment pitmap_origin LAT LON H" (PLY, read by tools/eval), "# pitmap_origin ..." (OBJ) and
// asset.extras.pitmap_origin (glTF). glTF is y-up: it stores (x, y, z)_gltf = (E, U, -N).
// All writers fail with an Error naming the path (no throw).
#pragma once

#include <optional>
#include <string>

#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "processor/mesh/surface.hpp"

namespace pitmap::proc::mesh {

Status WritePly(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin = std::nullopt);
Status WriteObj(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin = std::nullopt);
Status WriteGlb(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin = std::nullopt);

}  // namespace pitmap::proc::mesh
