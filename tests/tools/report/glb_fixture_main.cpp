// SPDX-License-Identifier: MIT
// pitmap-test-glb-fixture OUT_DIR: writes OUT_DIR/mesh.glb for the viewer's browser test with the
// pipeline's own mesh code: multibeam scans of a floor with a mound (the fusion tests' synthetic
// world), fused into a TSDF, meshed by RunMesh and written by WriteGlb, as `pitmap mesh` does.
// Prints {"vertices": N, "triangles": M} on stdout. Exit 0, 1 when the file cannot be written,
// 2 on bad arguments.
#include <Eigen/Core>
#include <cstdio>
#include <numbers>
#include <string>

#include "common/geodesy.hpp"
#include "processor/fusion/tsdf.hpp"
#include "processor/mesh/export.hpp"
#include "processor/mesh/surface.hpp"
#include "tests/processor/fusion/synthetic_scans.hpp"

namespace fusion = pitmap::proc::fusion;
namespace mesh = pitmap::proc::mesh;

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
        return 2;
    }
    fusion::testing::SyntheticWorld world;
    world.plane_z_m = -12.0;
    world.spheres.push_back({Eigen::Vector3d(0.0, 0.0, -11.0), 2.5});
    fusion::testing::LineSurvey survey;
    survey.lines_y_m = {-3.0, 3.0};
    survey.x0_m = -6.0;
    survey.x1_m = 6.0;
    survey.spacing_m = 0.1;
    survey.start_angle_rad = -60.0 * std::numbers::pi / 180.0;
    survey.num_beams = 481;
    fusion::TsdfConfig config;
    config.truncation_m = 0.5;
    fusion::TsdfVolume volume(config);
    volume.Integrate(fusion::testing::MakeScans(world, survey));
    volume.FilterByWeight(fusion::WeightFilterConfig{});
    const mesh::MeshResult m = mesh::RunMesh(volume, mesh::MeshConfig{});
    const std::string path = std::string(argv[1]) + "/mesh.glb";
    const pitmap::Geodetic origin{40.4435, -7.7806, 412.0};
    if (auto w = mesh::WriteGlb(m.mesh, path, origin); !w) {
        std::fprintf(stderr, "%s\n", w.error().message.c_str());
        return 1;
    }
    std::printf("{\"vertices\": %zu, \"triangles\": %zu}\n",
                m.mesh.vertices.size(),
                m.mesh.triangles.size());
    return 0;
}
