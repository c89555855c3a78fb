// SPDX-License-Identifier: MIT
// The mesh files open in other tools: mesh.ply, mesh.obj and mesh.glb of a fused scene (a
// sphere on the floor) and an empty glTF scene are read back with Assimp (the importer behind
// many viewers and engines), with the same vertex and face counts, vertex colours and
// coordinates (glTF is y-up: (E, U, -N)).
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <gtest/gtest.h>
#include <assimp/Importer.hpp>

#include <filesystem>
#include <numbers>

#include "processor/mesh/export.hpp"
#include "processor/mesh/surface.hpp"
#include "tests/processor/fusion/synthetic_scans.hpp"

namespace pitmap::proc::mesh {
namespace {

struct Counts {
    unsigned meshes = 0;
    unsigned vertices = 0;
    unsigned faces = 0;
    unsigned non_triangles = 0;
    bool colours = true;
    Eigen::AlignedBox3f box;
};

// Reads a file with Assimp. flags 0: the file's own vertices (PLY, glTF keep indexed
// vertices; OBJ gives one vertex per face corner).
bool ReadWithAssimp(const std::string& path, unsigned flags, Counts& c, std::string& error) {
    Assimp::Importer importer;
    const aiScene* scene = importer.ReadFile(path, flags);
    if (scene == nullptr) {
        error = importer.GetErrorString();
        return false;
    }
    c.meshes = scene->mNumMeshes;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* mesh = scene->mMeshes[m];
        c.vertices += mesh->mNumVertices;
        c.faces += mesh->mNumFaces;
        c.colours = c.colours && mesh->HasVertexColors(0);
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            c.non_triangles += mesh->mFaces[f].mNumIndices != 3 ? 1u : 0u;
        }
        for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
            const aiVector3D& p = mesh->mVertices[v];
            c.box.extend(Eigen::Vector3f(p.x, p.y, p.z));
        }
    }
    return true;
}

class MeshReadBack : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        fusion::testing::SyntheticWorld world;
        world.plane_z_m = -12.0;
        world.spheres.push_back({Eigen::Vector3d(0.0, 0.0, -10.0), 1.5});
        fusion::testing::LineSurvey survey;
        survey.lines_y_m = {-3.0, 3.0};
        survey.x0_m = -4.0;
        survey.x1_m = 4.0;
        survey.spacing_m = 0.1;
        survey.start_angle_rad = -60.0 * std::numbers::pi / 180.0;
        survey.num_beams = 481;
        fusion::TsdfConfig config;
        config.truncation_m = 0.5;
        fusion::TsdfVolume volume(config);
        volume.Integrate(fusion::testing::MakeScans(world, survey));
        volume.FilterByWeight(fusion::WeightFilterConfig{});
        result_ = new MeshResult(RunMesh(volume, MeshConfig{}));
    }
    static void TearDownTestSuite() {
        delete result_;
        result_ = nullptr;
    }
    static MeshResult* result_;
    const Geodetic origin_{40.4435, -7.7806, 412.0};
    const std::string dir_ = ::testing::TempDir();
};

MeshResult* MeshReadBack::result_ = nullptr;

TEST_F(MeshReadBack, PlyHasTheSameVerticesFacesColoursAndCoordinates) {
    const ColouredMesh& m = result_->mesh;
    ASSERT_GT(m.triangles.size(), 10000u);
    const std::string path = dir_ + "/readback_mesh.ply";
    ASSERT_TRUE(WritePly(m, path, origin_));
    Counts c;
    std::string error;
    ASSERT_TRUE(ReadWithAssimp(path, 0, c, error)) << error;
    EXPECT_EQ(c.meshes, 1u);
    EXPECT_EQ(c.vertices, m.vertices.size());
    EXPECT_EQ(c.faces, m.triangles.size());
    EXPECT_EQ(c.non_triangles, 0u);
    EXPECT_TRUE(c.colours);
    Eigen::AlignedBox3f box;
    for (const Eigen::Vector3f& v : m.vertices) box.extend(v);
    EXPECT_TRUE(c.box.min().isApprox(box.min(), 1e-5f));
    EXPECT_TRUE(c.box.max().isApprox(box.max(), 1e-5f));
    std::filesystem::remove(path);
}

TEST_F(MeshReadBack, ObjHasTheSameFacesAndVertices) {
    const ColouredMesh& m = result_->mesh;
    const std::string path = dir_ + "/readback_mesh.obj";
    ASSERT_TRUE(WriteObj(m, path, origin_));
    Counts c;
    std::string error;
    // OBJ import gives one vertex per face corner; joining identical ones restores the mesh's
    // own vertices (every vertex of the mesh is used by a face).
    ASSERT_TRUE(ReadWithAssimp(path, aiProcess_JoinIdenticalVertices, c, error)) << error;
    EXPECT_EQ(c.meshes, 1u);
    EXPECT_EQ(c.faces, m.triangles.size());
    EXPECT_EQ(c.vertices, m.vertices.size());
    EXPECT_EQ(c.non_triangles, 0u);
    EXPECT_TRUE(c.colours);
    std::filesystem::remove(path);
}

TEST_F(MeshReadBack, GlbHasTheSameVerticesFacesColoursAndYUpCoordinates) {
    for (const ColouredMesh* m : {&result_->mesh, &result_->mesh_filled}) {
        const std::string path = dir_ + "/readback_mesh.glb";
        ASSERT_TRUE(WriteGlb(*m, path, origin_));
        Counts c;
        std::string error;
        ASSERT_TRUE(ReadWithAssimp(path, 0, c, error)) << error;
        EXPECT_EQ(c.meshes, 1u);
        EXPECT_EQ(c.vertices, m->vertices.size());
        EXPECT_EQ(c.faces, m->triangles.size());
        EXPECT_EQ(c.non_triangles, 0u);
        EXPECT_TRUE(c.colours);
        Eigen::AlignedBox3f box;  // (E, U, -N)
        for (const Eigen::Vector3f& v : m->vertices)
            box.extend(Eigen::Vector3f(v.x(), v.z(), -v.y()));
        EXPECT_TRUE(c.box.min().isApprox(box.min(), 1e-5f));
        EXPECT_TRUE(c.box.max().isApprox(box.max(), 1e-5f));
        std::filesystem::remove(path);
    }
}

TEST(MeshReadBackEmpty, EmptyGlbOpensWithNoMesh) {
    const ColouredMesh empty;
    const std::string dir = ::testing::TempDir();
    // An empty glTF scene is valid glTF and Assimp opens it with no mesh.
    ASSERT_TRUE(WriteGlb(empty, dir + "/readback_empty.glb"));
    Assimp::Importer importer;
    const aiScene* scene = importer.ReadFile(dir + "/readback_empty.glb", 0);
    ASSERT_NE(scene, nullptr) << importer.GetErrorString();
    EXPECT_EQ(scene->mNumMeshes, 0u);
    std::filesystem::remove(dir + "/readback_empty.glb");
}

}  // namespace
}  // namespace pitmap::proc::mesh
