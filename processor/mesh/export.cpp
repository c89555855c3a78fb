// SPDX-License-Identifier: MIT
// glTF 2.0 binary container (Khronos glTF 2.0 specification, section "GLB File Format
// Specification"): 12-byte header (magic "glTF", version 2, total length), a JSON chunk padded
// with spaces to 4 bytes, then a BIN chunk padded with zeros to 4 bytes; all little endian.
#include "processor/mesh/export.hpp"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

namespace pitmap::proc::mesh {

namespace {

void PutU32(std::string& out, std::uint32_t v) {
    for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xffu));
}

void PutF32(std::string& out, float f) {
    std::uint32_t v = 0;
    std::memcpy(&v, &f, sizeof v);
    PutU32(out, v);
}

std::string OriginText(const Geodetic& g) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "%.9f %.9f %.4f", g.latitude_deg, g.longitude_deg, g.height_m);
    return buf;
}

Status WriteAll(const std::string& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) return Error{path + ": cannot open for writing"};
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) return Error{path + ": write failed"};
    return Ok{};
}

bool HasColours(const ColouredMesh& m) {
    return m.colours.size() == m.vertices.size();
}

}  // namespace

Status WritePly(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin) {
    const bool colours = HasColours(mesh);
    std::string out;
    out += "ply\nformat binary_little_endian 1.0\ncomment generator pitmap proc_mesh\n";
    if (origin) out += "comment pitmap_origin " + OriginText(*origin) + "\n";
    out += "element vertex " + std::to_string(mesh.vertices.size()) + "\n";
    out += "property float x\nproperty float y\nproperty float z\n";
    if (colours) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out += "element face " + std::to_string(mesh.triangles.size()) + "\n";
    out += "property list uchar int vertex_indices\nend_header\n";
    out.reserve(out.size() + mesh.vertices.size() * 15 + mesh.triangles.size() * 13);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        for (int k = 0; k < 3; ++k) PutF32(out, mesh.vertices[i][k]);
        if (colours) {
            for (std::uint8_t c : mesh.colours[i]) out.push_back(static_cast<char>(c));
        }
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
        out.push_back(3);
        for (int k = 0; k < 3; ++k) PutU32(out, static_cast<std::uint32_t>(t[k]));
    }
    return WriteAll(path, out);
}

Status WriteObj(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) return Error{path + ": cannot open for writing"};
    std::fprintf(f, "# pitmap proc_mesh: local ENU metres, vertex colours by depth\n");
    if (origin) std::fprintf(f, "# pitmap_origin %s\n", OriginText(*origin).c_str());
    const bool colours = HasColours(mesh);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Eigen::Vector3f& p = mesh.vertices[i];
        if (colours) {
            const auto& c = mesh.colours[i];
            std::fprintf(f,
                         "v %.4f %.4f %.4f %.4f %.4f %.4f\n",
                         p.x(),
                         p.y(),
                         p.z(),
                         c[0] / 255.0,
                         c[1] / 255.0,
                         c[2] / 255.0);
        } else {
            std::fprintf(f, "v %.4f %.4f %.4f\n", p.x(), p.y(), p.z());
        }
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
        std::fprintf(f, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    const bool ok = std::ferror(f) == 0;
    if (std::fclose(f) != 0 || !ok) return Error{path + ": write failed"};
    return Ok{};
}

Status WriteGlb(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin) {
    using nlohmann::json;
    json doc;
    doc["asset"] = {{"version", "2.0"}, {"generator", "pitmap proc_mesh"}};
    if (origin) {
        doc["asset"]["extras"]["pitmap_origin"] = {{"latitude_deg", origin->latitude_deg},
                                                   {"longitude_deg", origin->longitude_deg},
                                                   {"height_m", origin->height_m}};
    }
    doc["scene"] = 0;
    std::string bin;
    if (mesh.empty()) {
        doc["scenes"] = json::array({json::object()});
    } else {
        const bool colours = HasColours(mesh);
        const std::size_t nv = mesh.vertices.size();
        float lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::numeric_limits<float>::max();
            hi[k] = -std::numeric_limits<float>::max();
        }
        for (const Eigen::Vector3f& p : mesh.vertices) {
            const float g[3] = {p.x(), p.z(), -p.y()};  // ENU -> glTF y-up
            for (int k = 0; k < 3; ++k) {
                PutF32(bin, g[k]);
                lo[k] = std::min(lo[k], g[k]);
                hi[k] = std::max(hi[k], g[k]);
            }
        }
        const std::size_t pos_bytes = bin.size();
        std::size_t col_bytes = 0;
        if (colours) {
            for (const auto& c : mesh.colours) {
                for (std::uint8_t v : c) PutF32(bin, static_cast<float>(v) / 255.0f);
            }
            col_bytes = bin.size() - pos_bytes;
        }
        const std::size_t idx_offset = bin.size();
        for (const Eigen::Vector3i& t : mesh.triangles) {
            for (int k = 0; k < 3; ++k) PutU32(bin, static_cast<std::uint32_t>(t[k]));
        }
        const std::size_t idx_bytes = bin.size() - idx_offset;
        json views = json::array();
        json accessors = json::array();
        views.push_back(
            {{"buffer", 0}, {"byteOffset", 0}, {"byteLength", pos_bytes}, {"target", 34962}});
        accessors.push_back({{"bufferView", 0},
                             {"componentType", 5126},
                             {"count", nv},
                             {"type", "VEC3"},
                             {"min", {lo[0], lo[1], lo[2]}},
                             {"max", {hi[0], hi[1], hi[2]}}});
        json attributes = {{"POSITION", 0}};
        if (colours) {
            views.push_back({{"buffer", 0},
                             {"byteOffset", pos_bytes},
                             {"byteLength", col_bytes},
                             {"target", 34962}});
            accessors.push_back(
                {{"bufferView", 1}, {"componentType", 5126}, {"count", nv}, {"type", "VEC3"}});
            attributes["COLOR_0"] = 1;
        }
        const int idx_view = static_cast<int>(views.size());
        views.push_back({{"buffer", 0},
                         {"byteOffset", idx_offset},
                         {"byteLength", idx_bytes},
                         {"target", 34963}});
        accessors.push_back({{"bufferView", idx_view},
                             {"componentType", 5125},
                             {"count", mesh.triangles.size() * 3},
                             {"type", "SCALAR"}});
        const int idx_accessor = static_cast<int>(accessors.size()) - 1;
        doc["scenes"] = json::array({{{"nodes", {0}}}});
        doc["nodes"] = json::array({{{"mesh", 0}, {"name", "pit_surface"}}});
        doc["meshes"] = json::array(
            {{{"name", "pit_surface"},
              {"primitives",
               json::array(
                   {{{"attributes", attributes}, {"indices", idx_accessor}, {"mode", 4}}})}}});
        doc["bufferViews"] = views;
        doc["accessors"] = accessors;
        doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
    }
    std::string json_text = doc.dump();
    while (json_text.size() % 4 != 0) json_text.push_back(' ');
    while (bin.size() % 4 != 0) bin.push_back('\0');
    const std::size_t total = 12 + 8 + json_text.size() + (bin.empty() ? 0 : 8 + bin.size());
    if (total > std::numeric_limits<std::uint32_t>::max()) {
        return Error{path + ": mesh too large for a GLB file (4 GiB limit)"};
    }
    std::string out;
    out.reserve(total);
    PutU32(out, 0x46546C67u);  // "glTF"
    PutU32(out, 2);
    PutU32(out, static_cast<std::uint32_t>(total));
    PutU32(out, static_cast<std::uint32_t>(json_text.size()));
    PutU32(out, 0x4E4F534Au);  // "JSON"
    out += json_text;
    if (!bin.empty()) {
        PutU32(out, static_cast<std::uint32_t>(bin.size()));
        PutU32(out, 0x004E4942u);  // "BIN\0"
        out += bin;
    }
    return WriteAll(path, out);
}

}  // namespace pitmap::proc::mesh
