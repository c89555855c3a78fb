// SPDX-License-Identifier: MIT
// Mesh stage: hole filling for display (raw mesh untouched), depth colours, and the PLY, OBJ
// and GLB writers read back (GLB: header, chunks, JSON parsed with nlohmann_json, positions).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "processor/mesh/export.hpp"
#include "processor/mesh/surface.hpp"
#include "tests/processor/fusion/synthetic_scans.hpp"

namespace pitmap::proc::mesh {
namespace {

// An n x n grid of vertices in the plane z = -10, two triangles per cell, CCW from above.
void GridMesh(int n,
              std::vector<Eigen::Vector3f>& v,
              std::vector<Eigen::Vector3i>& t,
              int skip_cell = -1) {
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            v.emplace_back(static_cast<float>(i), static_cast<float>(j), -10.0f);
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            if (j * (n - 1) + i == skip_cell) continue;
            const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
            t.emplace_back(a, b, d);
            t.emplace_back(a, d, c);
        }
}

std::string ReadFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::uint32_t U32(const std::string& s, std::size_t off) {
    std::uint32_t v = 0;
    for (int k = 3; k >= 0; --k)
        v = (v << 8) | static_cast<unsigned char>(s[off + static_cast<std::size_t>(k)]);
    return v;
}

TEST(FillSmallHoles, FillsASmallHoleAndLeavesTheBorderOpen) {
    std::vector<Eigen::Vector3f> v;
    std::vector<Eigen::Vector3i> t;
    GridMesh(6, v, t, 12);  // a one-cell hole inside
    const std::size_t before = t.size();
    const HoleFillResult r = FillSmallHoles(v, t, 8);
    EXPECT_EQ(r.holes_found, 2);  // the hole and the outer border
    EXPECT_EQ(r.holes_filled, 1);
    EXPECT_EQ(r.holes_too_large, 1);
    EXPECT_EQ(r.triangles_added, 4);  // fan around the centroid of a 4-edge loop
    EXPECT_EQ(t.size(), before + 4);
    EXPECT_NEAR(MeshArea(v, t), 25.0, 1e-4);
    // The fill is wound like its neighbours (normals up).
    for (std::size_t k = before; k < t.size(); ++k) {
        const Eigen::Vector3f n = (v[t[k][1]] - v[t[k][0]]).cross(v[t[k][2]] - v[t[k][0]]);
        EXPECT_GT(n.z(), 0.0f);
    }
}

// Holes of 4, 6 and 12 edges in one grid: the two small ones are filled, the large one and the
// border stay open; the filled area is that of the small holes.
TEST(FillSmallHoles, HolesOfSeveralSizes) {
    const int n = 14;
    std::vector<Eigen::Vector3f> v;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            v.emplace_back(static_cast<float>(i), static_cast<float>(j), 0.f);
    auto removed = [](int i, int j) {
        return (i == 2 && j == 2) ||                    // one cell: 4 edges
               (j == 2 && (i == 6 || i == 7)) ||        // two cells: 6 edges
               (i >= 4 && i <= 6 && j >= 7 && j <= 9);  // 3 x 3 cells: 12 edges
    };
    std::vector<Eigen::Vector3i> t;
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            if (removed(i, j)) continue;
            const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
            t.emplace_back(a, b, d);
            t.emplace_back(a, d, c);
        }
    const double area_before = MeshArea(v, t);
    const HoleFillResult r = FillSmallHoles(v, t, 8);
    EXPECT_EQ(r.holes_found, 4);
    EXPECT_EQ(r.holes_filled, 2);
    EXPECT_EQ(r.holes_too_large, 2);
    EXPECT_EQ(r.loops_ambiguous, 0);
    EXPECT_EQ(r.triangles_added, 4 + 6);
    EXPECT_NEAR(MeshArea(v, t) - area_before, 3.0, 1e-4);
}

// Two one-cell holes that touch at a corner: the shared vertex starts two boundary edges, so
// the loop through it is ambiguous and left open (a fan could cross the other hole); the border
// is still found. A triangle listed twice adds no boundary.
TEST(FillSmallHoles, HolesSharingAVertexAreLeftOpen) {
    std::vector<Eigen::Vector3f> v;
    std::vector<Eigen::Vector3i> t;
    const int n = 8;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            v.emplace_back(static_cast<float>(i), static_cast<float>(j), 0.f);
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            if ((i == 2 && j == 2) || (i == 3 && j == 3)) continue;
            const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
            t.emplace_back(a, b, d);
            t.emplace_back(a, d, c);
        }
    t.push_back(t.front());
    const std::size_t before = t.size();
    const HoleFillResult r = FillSmallHoles(v, t, 8);
    EXPECT_GE(r.loops_ambiguous, 1);
    EXPECT_EQ(r.holes_found, 1);  // the border
    EXPECT_EQ(r.holes_filled, 0);
    EXPECT_EQ(t.size(), before);
}

// A triangle whose index lies outside the vertices (or is negative) is left out, not read.
TEST(FillSmallHoles, TrianglesWithBadIndicesAreLeftOut) {
    std::vector<Eigen::Vector3f> v;
    std::vector<Eigen::Vector3i> t;
    GridMesh(6, v, t, 12);
    t.emplace_back(0, 1, 1000000);
    t.emplace_back(-5, 2, 3);
    const std::size_t before = t.size();
    const HoleFillResult r = FillSmallHoles(v, t, 8);
    EXPECT_EQ(r.holes_found, 2);
    EXPECT_EQ(r.holes_filled, 1);
    EXPECT_EQ(t.size(), before + 4);
}

TEST(RunMesh, PlaneFromTheVolumeWithColoursAndAFilledCopy) {
    fusion::testing::SyntheticWorld world;
    fusion::testing::LineSurvey survey;
    auto scans = fusion::testing::MakeScans(world, survey);
    for (auto& s : scans) s.ranges_m[200] = 0.0f;  // a dead beam leaves a narrow gap
    fusion::TsdfConfig config;
    config.truncation_m = 0.5;
    config.sensor_model = fusion::SensorModel::kRay;
    fusion::TsdfVolume volume(config);
    volume.Integrate(scans);
    MeshConfig mc;
    ASSERT_TRUE(mc.Validate().empty());
    const MeshResult r = RunMesh(volume, mc);
    ASSERT_FALSE(r.mesh.empty());
    EXPECT_EQ(r.mesh.colours.size(), r.mesh.vertices.size());
    EXPECT_EQ(r.mesh_filled.colours.size(), r.mesh_filled.vertices.size());
    EXPECT_GE(r.mesh_filled.triangles.size(), r.mesh.triangles.size());
    EXPECT_EQ(static_cast<std::int64_t>(r.mesh_filled.triangles.size() - r.mesh.triangles.size()),
              r.holes.triangles_added);
    EXPECT_NEAR(r.min_z_m, -10.0, 0.05);
    EXPECT_NEAR(r.max_z_m, -10.0, 0.05);
    EXPECT_GT(r.area_m2, 100.0);
}

TEST(RunMesh, EmptyVolumeGivesEmptyMeshesAndValidFiles) {
    fusion::TsdfVolume volume(fusion::TsdfConfig{});
    const MeshResult r = RunMesh(volume, MeshConfig{});
    EXPECT_TRUE(r.mesh.empty());
    EXPECT_TRUE(r.mesh_filled.empty());
    const std::string dir = ::testing::TempDir();
    ASSERT_TRUE(WritePly(r.mesh, dir + "/empty.ply"));
    ASSERT_TRUE(WriteObj(r.mesh, dir + "/empty.obj"));
    ASSERT_TRUE(WriteGlb(r.mesh, dir + "/empty.glb"));
    const std::string ply = ReadFile(dir + "/empty.ply");
    EXPECT_NE(ply.find("element vertex 0\n"), std::string::npos);
    const std::string glb = ReadFile(dir + "/empty.glb");
    ASSERT_GE(glb.size(), 20u);
    EXPECT_EQ(U32(glb, 8), glb.size());
    const auto doc = nlohmann::json::parse(glb.substr(20, U32(glb, 12)));
    EXPECT_EQ(doc["asset"]["version"], "2.0");
    EXPECT_FALSE(doc.contains("meshes"));
}

TEST(DepthColour, RampEndsAndClamping) {
    const auto deep = DepthColour(-30.0, -25.0, 0.0);
    EXPECT_EQ(deep, DepthColour(-25.0, -25.0, 0.0));
    const auto shallow = DepthColour(0.0, -25.0, 0.0);
    EXPECT_GT(shallow[0], deep[0]);  // shallow is red, deep is blue
    EXPECT_GT(deep[2], shallow[2]);
}

class ExportTest : public ::testing::Test {
protected:
    void SetUp() override {
        GridMesh(4, mesh_.vertices, mesh_.triangles);
        for (const auto& p : mesh_.vertices) mesh_.colours.push_back(DepthColour(p.x(), 0, 3));
    }
    ColouredMesh mesh_;
    Geodetic origin_{40.4435, -7.7806, 412.0};
    std::string dir_ = ::testing::TempDir();
};

TEST_F(ExportTest, PlyReadsBackWithOriginComment) {
    const std::string path = dir_ + "/mesh_test.ply";
    ASSERT_TRUE(WritePly(mesh_, path, origin_));
    const std::string s = ReadFile(path);
    const std::size_t end = s.find("end_header\n");
    ASSERT_NE(end, std::string::npos);
    const std::string header = s.substr(0, end);
    EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
    EXPECT_NE(header.find("comment pitmap_origin 40.443500000 -7.780600000 412.0000"),
              std::string::npos);
    EXPECT_NE(header.find("element vertex 16"), std::string::npos);
    EXPECT_NE(header.find("element face 18"), std::string::npos);
    const std::size_t body = end + 11;
    ASSERT_EQ(s.size(), body + 16 * 15 + 18 * 13);
    for (std::size_t i = 0; i < 16; ++i) {
        float xyz[3];
        std::memcpy(xyz, s.data() + body + i * 15, 12);
        EXPECT_FLOAT_EQ(xyz[0], mesh_.vertices[i].x());
        EXPECT_FLOAT_EQ(xyz[2], -10.0f);
        EXPECT_EQ(static_cast<unsigned char>(s[body + i * 15 + 12]), mesh_.colours[i][0]);
    }
    const std::size_t faces = body + 16 * 15;
    for (std::size_t f = 0; f < 18; ++f) {
        EXPECT_EQ(s[faces + f * 13], 3);
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(
                static_cast<int>(U32(s, faces + f * 13 + 1 + 4 * static_cast<std::size_t>(k))),
                mesh_.triangles[f][k]);
        }
    }
}

// The OBJ writer formats with std::to_chars into 1 MB blocks: every line is what printf's
// "%.4f" and "%d" write, across block boundaries, for coordinates of either sign and any colour.
TEST_F(ExportTest, ObjTextEqualsPrintfAcrossBlocks) {
    ColouredMesh m;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> coord(-2000.0f, 2000.0f);
    for (int i = 0; i < 60000; ++i) {
        m.vertices.emplace_back(coord(rng), coord(rng), i % 7 == 0 ? -0.00001f : coord(rng));
        m.colours.push_back({static_cast<std::uint8_t>(rng() & 0xff),
                             static_cast<std::uint8_t>(rng() & 0xff),
                             static_cast<std::uint8_t>(rng() & 0xff)});
    }
    for (int i = 0; i + 2 < 60000; i += 3) m.triangles.emplace_back(i, i + 1, i + 2);
    const std::string path = dir_ + "/printf.obj";
    ASSERT_TRUE(WriteObj(m, path));
    std::ifstream in(path);
    std::string line;
    std::size_t v = 0, f = 0;
    char want[256];
    while (std::getline(in, line)) {
        if (line.rfind("v ", 0) == 0) {
            ASSERT_LT(v, m.vertices.size());
            const auto& p = m.vertices[v];
            const auto& c = m.colours[v];
            std::snprintf(want,
                          sizeof want,
                          "v %.4f %.4f %.4f %.4f %.4f %.4f",
                          p.x(),
                          p.y(),
                          p.z(),
                          c[0] / 255.0,
                          c[1] / 255.0,
                          c[2] / 255.0);
            ASSERT_EQ(line, want) << "vertex " << v;
            ++v;
        } else if (line.rfind("f ", 0) == 0) {
            ASSERT_LT(f, m.triangles.size());
            const auto& t = m.triangles[f];
            std::snprintf(want, sizeof want, "f %d %d %d", t[0] + 1, t[1] + 1, t[2] + 1);
            ASSERT_EQ(line, want) << "face " << f;
            ++f;
        }
    }
    EXPECT_EQ(v, m.vertices.size());
    EXPECT_EQ(f, m.triangles.size());
}

TEST_F(ExportTest, ObjReadsBack) {
    const std::string path = dir_ + "/mesh_test.obj";
    ASSERT_TRUE(WriteObj(mesh_, path, origin_));
    std::ifstream in(path);
    std::string line;
    int v = 0, f = 0;
    bool origin = false;
    while (std::getline(in, line)) {
        if (line.rfind("v ", 0) == 0) {
            double x, y, z, r, g, b;
            ASSERT_EQ(
                std::sscanf(line.c_str(), "v %lf %lf %lf %lf %lf %lf", &x, &y, &z, &r, &g, &b), 6);
            EXPECT_NEAR(x, mesh_.vertices[static_cast<std::size_t>(v)].x(), 1e-4);
            ++v;
        } else if (line.rfind("f ", 0) == 0) {
            int a, b, c;
            ASSERT_EQ(std::sscanf(line.c_str(), "f %d %d %d", &a, &b, &c), 3);
            EXPECT_EQ(a - 1, mesh_.triangles[static_cast<std::size_t>(f)][0]);
            EXPECT_GE(std::min({a, b, c}), 1);
            EXPECT_LE(std::max({a, b, c}), 16);
            ++f;
        } else if (line.rfind("# pitmap_origin ", 0) == 0) {
            origin = true;
        }
    }
    EXPECT_EQ(v, 16);
    EXPECT_EQ(f, 18);
    EXPECT_TRUE(origin);
}

TEST_F(ExportTest, GlbContainerParsesAndPositionsReadBack) {
    const std::string path = dir_ + "/mesh_test.glb";
    ASSERT_TRUE(WriteGlb(mesh_, path, origin_));
    const std::string s = ReadFile(path);
    ASSERT_GE(s.size(), 28u);
    EXPECT_EQ(U32(s, 0), 0x46546C67u);
    EXPECT_EQ(U32(s, 4), 2u);
    EXPECT_EQ(U32(s, 8), s.size());
    const std::uint32_t json_len = U32(s, 12);
    EXPECT_EQ(U32(s, 16), 0x4E4F534Au);
    EXPECT_EQ(json_len % 4, 0u);
    const auto doc = nlohmann::json::parse(s.substr(20, json_len));
    const std::size_t bin_hdr = 20 + json_len;
    const std::uint32_t bin_len = U32(s, bin_hdr);
    EXPECT_EQ(U32(s, bin_hdr + 4), 0x004E4942u);
    EXPECT_EQ(bin_hdr + 8 + bin_len, s.size());
    EXPECT_EQ(doc["buffers"][0]["byteLength"].get<std::uint32_t>(), bin_len);
    EXPECT_DOUBLE_EQ(doc["asset"]["extras"]["pitmap_origin"]["latitude_deg"].get<double>(),
                     40.4435);
    const auto& prim = doc["meshes"][0]["primitives"][0];
    EXPECT_EQ(prim["mode"], 4);
    const auto& pos = doc["accessors"][prim["attributes"]["POSITION"].get<int>()];
    EXPECT_EQ(pos["count"], 16);
    EXPECT_EQ(pos["componentType"], 5126);
    ASSERT_TRUE(pos.contains("min") && pos.contains("max"));
    const auto& idx = doc["accessors"][prim["indices"].get<int>()];
    EXPECT_EQ(idx["count"], 54);
    for (const auto& view : doc["bufferViews"]) {
        EXPECT_LE(view["byteOffset"].get<std::size_t>() + view["byteLength"].get<std::size_t>(),
                  bin_len);
        EXPECT_EQ(view["byteOffset"].get<std::size_t>() % 4, 0u);
    }
    // Positions: glTF y-up (E, U, -N).
    const auto& pv = doc["bufferViews"][pos["bufferView"].get<int>()];
    const std::size_t base = bin_hdr + 8 + pv["byteOffset"].get<std::size_t>();
    for (std::size_t i = 0; i < 16; ++i) {
        float g[3];
        std::memcpy(g, s.data() + base + i * 12, 12);
        EXPECT_FLOAT_EQ(g[0], mesh_.vertices[i].x());
        EXPECT_FLOAT_EQ(g[1], mesh_.vertices[i].z());
        EXPECT_FLOAT_EQ(g[2], -mesh_.vertices[i].y());
    }
}

TEST(MeshConfig, EveryProblemIsListed) {
    MeshConfig bad;
    bad.max_hole_edges = -1;
    bad.colour_min_z_m = 1.0;
    bad.colour_max_z_m = 0.0;
    EXPECT_EQ(bad.Validate().size(), 2u);
}

}  // namespace
}  // namespace pitmap::proc::mesh
