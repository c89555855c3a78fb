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

// The georeferenced mesh (issue 39): mesh_utm.ply's double UTM coordinates and mesh_utm.glb's
// float vertices plus the node translation, as Assimp reads them with the node transforms
// applied (aiProcess_PreTransformVertices: what a viewer shows). Assimp computes in float, so a
// UTM northing of 4.48e6 m holds to 0.5 m there; pitmap's own offset keeps the GLB's vertices
// to micrometres (checked in tests/processor/pipeline/georeferencing_scenario_test.cpp).
TEST_F(MeshReadBack, ProjectedPlyAndGlbLandAtTheirUtmCoordinates) {
    const ColouredMesh& m = result_->mesh;
    ProjectedMesh p;
    const Eigen::Vector3d utm0(603'512.25, 4'477'731.5, -3.75);  // east, north, height
    for (const Eigen::Vector3f& v : m.vertices) p.positions.push_back(utm0 + v.cast<double>());
    SetOffset(p);
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3d& x : p.positions) box.extend(x);
    EXPECT_EQ(p.offset, box.min().array().floor().matrix().eval());
    p.crs_name = "WGS 84 / UTM zone 29N + EGM96 height";
    p.horizontal_epsg = 32629;
    p.vertical_epsg = 5773;
    const std::string ply = dir_ + "/readback_mesh_utm.ply";
    ASSERT_TRUE(WriteProjectedPly(m, p, ply));
    Counts c;
    std::string error;
    ASSERT_TRUE(ReadWithAssimp(ply, 0, c, error)) << error;
    EXPECT_EQ(c.vertices, m.vertices.size());
    EXPECT_EQ(c.faces, m.triangles.size());
    EXPECT_TRUE(c.colours);
    EXPECT_TRUE(c.box.min().cast<double>().isApprox(box.min(), 1e-7)) << c.box.min();
    EXPECT_TRUE(c.box.max().cast<double>().isApprox(box.max(), 1e-7)) << c.box.max();

    const std::string glb = dir_ + "/readback_mesh_utm.glb";
    ASSERT_TRUE(WriteProjectedGlb(m, p, glb));
    Counts g;
    ASSERT_TRUE(ReadWithAssimp(glb, aiProcess_PreTransformVertices, g, error)) << error;
    EXPECT_EQ(g.vertices, m.vertices.size());
    EXPECT_EQ(g.faces, m.triangles.size());
    // glTF y-up: (E, H, -N).
    const Eigen::Vector3d lo(box.min().x(), box.min().z(), -box.max().y());
    const Eigen::Vector3d hi(box.max().x(), box.max().z(), -box.min().y());
    EXPECT_LT((g.box.min().cast<double>() - lo).cwiseAbs().maxCoeff(), 1.0) << g.box.min();
    EXPECT_LT((g.box.max().cast<double>() - hi).cwiseAbs().maxCoeff(), 1.0) << g.box.max();
    // A mismatched projection is refused, not written.
    ProjectedMesh short_p = p;
    short_p.positions.pop_back();
    EXPECT_FALSE(WriteProjectedPly(m, short_p, ply));
    EXPECT_FALSE(WriteProjectedGlb(m, short_p, glb));
    std::filesystem::remove(ply);
    std::filesystem::remove(glb);
}

}  // namespace
}  // namespace pitmap::proc::mesh
