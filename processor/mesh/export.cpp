// SPDX-License-Identifier: MIT
// glTF 2.0 binary container (Khronos glTF 2.0 specification, section "GLB File Format
// Specification"): 12-byte header (magic "glTF", version 2, total length), a JSON chunk padded
// with spaces to 4 bytes, then a BIN chunk padded with zeros to 4 bytes; all little endian.
#include "processor/mesh/export.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/byte_io.hpp"
#include "common/formats/byte_file.hpp"
#include "common/formats/ply.hpp"
#include "common/formats/replace_file.hpp"
#include "common/product_metadata_json.hpp"

namespace pitmap::proc::mesh {

namespace {

bool HasColours(const ColouredMesh& m) {
    return m.colours.size() == m.vertices.size();
}

}  // namespace

namespace {

// The mesh as a binary PLY with the comments of `h`: vertices of `coord` type written by
// xyz(ByteWriter&, vertex index), their colours when the mesh has them, then the triangles.
template <class Xyz>
Status WriteMeshPly(const ColouredMesh& mesh,
                    const std::string& path,
                    formats::ply::Header h,
                    formats::ply::Type coord,
                    Xyz&& xyz) {
    namespace ply = formats::ply;
    const bool colours = HasColours(mesh);
    ply::Element vertex{"vertex", mesh.vertices.size(), {{"x", coord}, {"y", coord}, {"z", coord}}};
    if (colours) {
        for (const char* c : {"red", "green", "blue"}) {
            vertex.properties.push_back({c, ply::Type::kUInt8});
        }
    }
    h.elements.push_back(std::move(vertex));
    h.elements.push_back({"face",
                          mesh.triangles.size(),
                          {{"vertex_indices", ply::Type::kInt32, ply::Type::kUInt8}}});
    ply::Writer w(path, h);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        ByteWriter& o = w.Record();
        xyz(o, i);
        if (colours) {
            for (std::uint8_t c : mesh.colours[i]) o.U8(c);
        }
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
        ByteWriter& o = w.Record();
        o.U8(3);
        for (int k = 0; k < 3; ++k) o.I32Le(t[k]);
    }
    return w.Close();
}

}  // namespace

Status WritePly(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin,
                const std::string& run_id) {
    namespace ply = formats::ply;
    ply::Header h;
    h.comments.push_back("generator pitmap proc_mesh");
    if (origin) h.comments.push_back(ply::OriginComment(*origin));
    if (!run_id.empty()) h.comments.push_back(ply::RunIdComment(run_id));
    return WriteMeshPly(
        mesh, path, std::move(h), ply::Type::kFloat32, [&](ByteWriter& o, std::size_t i) {
            for (int k = 0; k < 3; ++k) o.F32Le(mesh.vertices[i][k]);
        });
}

namespace {

// OBJ text, formatted with std::to_chars into a buffer written in large blocks: printf's float
// formatting was a third of the mesh stage on bejanca (two 150 MB files).
Status WriteObjTo(const ColouredMesh& mesh,
                  const std::string& path,
                  const std::optional<Geodetic>& origin,
                  const std::string& run_id) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) return Error{formats::ErrnoMessage(path, "cannot create", errno)};
    std::string head = "# pitmap proc_mesh: local ENU metres, vertex colours by depth\n";
    if (origin) head += "# " + formats::ply::OriginComment(*origin) + "\n";
    if (!run_id.empty()) head += "# " + formats::ply::RunIdComment(run_id) + "\n";
    bool ok = std::fwrite(head.data(), 1, head.size(), f) == head.size();
    constexpr std::size_t kBlock = 1 << 20;
    constexpr std::size_t kLineMax = 160;  // longer than any line below
    std::vector<char> buf(kBlock + kLineMax);
    char* out = buf.data();
    auto flush = [&] {
        const auto n = static_cast<std::size_t>(out - buf.data());
        ok = ok && std::fwrite(buf.data(), 1, n, f) == n;
        out = buf.data();
    };
    auto put = [&](char c) { *out++ = c; };
    auto fixed4 = [&](double v) {
        out = std::to_chars(out, out + 48, v, std::chars_format::fixed, 4).ptr;
    };
    auto integer = [&](long long v) { out = std::to_chars(out, out + 24, v).ptr; };
    // The colour channels as OBJ's 0..1 reals, formatted once.
    std::array<std::string, 256> channel;
    for (int c = 0; c < 256; ++c) {
        char tmp[16];
        char* e = std::to_chars(tmp, tmp + sizeof tmp, c / 255.0, std::chars_format::fixed, 4).ptr;
        channel[c].assign(tmp, e);
    }
    const bool colours = HasColours(mesh);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Eigen::Vector3f& p = mesh.vertices[i];
        put('v');
        for (int k = 0; k < 3; ++k) {
            put(' ');
            fixed4(p[k]);
        }
        if (colours) {
            for (std::uint8_t c : mesh.colours[i]) {
                put(' ');
                out = std::copy(channel[c].begin(), channel[c].end(), out);
            }
        }
        put('\n');
        if (out - buf.data() >= static_cast<std::ptrdiff_t>(kBlock)) flush();
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
        put('f');
        for (int k = 0; k < 3; ++k) {
            put(' ');
            integer(static_cast<long long>(t[k]) + 1);
        }
        put('\n');
        if (out - buf.data() >= static_cast<std::ptrdiff_t>(kBlock)) flush();
    }
    flush();
    ok = ok && std::ferror(f) == 0 && std::fflush(f) == 0;
    const int err = errno;
    if (std::fclose(f) != 0 || !ok) return Error{formats::ErrnoMessage(path, "write failed", err)};
    return Ok{};
}

}  // namespace

Status WriteObj(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin,
                const std::string& run_id) {
    return formats::WriteReplacing(path, [&](const std::string& partial) {
        return WriteObjTo(mesh, partial, origin, run_id);
    });
}

// The binary chunk is streamed to the file (ByteFileWriter) after the JSON chunk, whose
// offsets are known from the counts: the file is never held in memory (on bejanca a 77 MB GLB
// was built in a growing buffer and copied once more, 220 MB at the mesh stage's peak).
namespace {

// A GLB of `mesh` whose vertex i is at gltf(i) (glTF's y-up axes), with `asset` as the asset
// object and `node` merged into the mesh's node (a translation, extras).
template <class Position>
Status WriteGlbWith(const ColouredMesh& mesh,
                    const std::string& path,
                    const nlohmann::json& asset,
                    const nlohmann::json& node,
                    Position gltf_at) {
    using nlohmann::json;
    json doc;
    doc["asset"] = asset;
    doc["scene"] = 0;
    const bool colours = !mesh.empty() && HasColours(mesh);
    const std::size_t nv = mesh.vertices.size();
    const std::size_t pos_bytes = mesh.empty() ? 0 : nv * 12;
    const std::size_t col_bytes = colours ? nv * 12 : 0;
    const std::size_t idx_bytes = mesh.empty() ? 0 : mesh.triangles.size() * 12;
    const std::size_t bin_bytes = pos_bytes + col_bytes + idx_bytes;  // a multiple of 4
    if (mesh.empty()) {
        doc["scenes"] = json::array({json::object()});
    } else {
        float lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::numeric_limits<float>::max();
            hi[k] = -std::numeric_limits<float>::max();
        }
        for (std::size_t i = 0; i < nv; ++i) {
            const std::array<float, 3> g = gltf_at(i);
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], g[k]);
                hi[k] = std::max(hi[k], g[k]);
            }
        }
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
                         {"byteOffset", pos_bytes + col_bytes},
                         {"byteLength", idx_bytes},
                         {"target", 34963}});
        accessors.push_back({{"bufferView", idx_view},
                             {"componentType", 5125},
                             {"count", mesh.triangles.size() * 3},
                             {"type", "SCALAR"}});
        const int idx_accessor = static_cast<int>(accessors.size()) - 1;
        doc["scenes"] = json::array({{{"nodes", {0}}}});
        json n = {{"mesh", 0}, {"name", "pit_surface"}};
        n.update(node);
        doc["nodes"] = json::array({n});
        doc["meshes"] = json::array(
            {{{"name", "pit_surface"},
              {"primitives",
               json::array(
                   {{{"attributes", attributes}, {"indices", idx_accessor}, {"mode", 4}}})}}});
        doc["bufferViews"] = views;
        doc["accessors"] = accessors;
        doc["buffers"] = json::array({{{"byteLength", bin_bytes}}});
    }
    std::string json_text = doc.dump();
    while (json_text.size() % 4 != 0) json_text.push_back(' ');
    const std::size_t total = 12 + 8 + json_text.size() + (bin_bytes == 0 ? 0 : 8 + bin_bytes);
    if (total > std::numeric_limits<std::uint32_t>::max()) {
        return Error{path + ": mesh too large for a GLB file (4 GiB limit)"};
    }
    formats::ByteFileWriter f(path);
    ByteWriter& h = f.out();
    h.U32Le(0x46546C67u);  // "glTF"
    h.U32Le(2);
    h.U32Le(static_cast<std::uint32_t>(total));
    h.U32Le(static_cast<std::uint32_t>(json_text.size()));
    h.U32Le(0x4E4F534Au);  // "JSON"
    f.Text(json_text);
    if (bin_bytes > 0) {
        ByteWriter& b = f.out();
        b.U32Le(static_cast<std::uint32_t>(bin_bytes));
        b.U32Le(0x004E4942u);  // "BIN\0"
        for (std::size_t i = 0; i < nv; ++i) {
            ByteWriter& o = f.out();
            for (const float v : gltf_at(i)) o.F32Le(v);
        }
        if (colours) {
            for (const auto& c : mesh.colours) {
                ByteWriter& o = f.out();
                for (const std::uint8_t v : c) o.F32Le(static_cast<float>(v) / 255.0f);
            }
        }
        for (const Eigen::Vector3i& t : mesh.triangles) {
            ByteWriter& o = f.out();
            for (int k = 0; k < 3; ++k) o.U32Le(static_cast<std::uint32_t>(t[k]));
        }
    }
    return f.Close();
}

}  // namespace

Status WriteGlb(const ColouredMesh& mesh,
                const std::string& path,
                const std::optional<Geodetic>& origin,
                const std::string& run_id) {
    using nlohmann::json;
    json asset = {{"version", "2.0"}, {"generator", "pitmap proc_mesh"}};
    if (origin) {
        asset["extras"]["pitmap_origin"] = {{"latitude_deg", origin->latitude_deg},
                                            {"longitude_deg", origin->longitude_deg},
                                            {"height_m", origin->height_m}};
    }
    if (!run_id.empty()) asset["extras"]["pitmap_run_id"] = run_id;
    return WriteGlbWith(mesh, path, asset, json::object(), [&mesh](std::size_t i) {
        const Eigen::Vector3f& p = mesh.vertices[i];
        return std::array<float, 3>{p.x(), p.z(), -p.y()};  // ENU -> glTF y-up
    });
}

void SetOffset(ProjectedMesh& p) {
    if (p.positions.empty()) {
        p.offset.setZero();
        return;
    }
    Eigen::Vector3d lo = p.positions.front();
    for (const Eigen::Vector3d& x : p.positions) lo = lo.cwiseMin(x);
    p.offset = lo.array().floor().matrix();
}

namespace {

Status CheckProjected(const ColouredMesh& mesh,
                      const ProjectedMesh& projected,
                      const std::string& path) {
    if (projected.positions.size() != mesh.vertices.size()) {
        return Error{path + ": " + std::to_string(projected.positions.size()) +
                     " projected positions for " + std::to_string(mesh.vertices.size()) +
                     " vertices"};
    }
    return Ok{};
}

}  // namespace

Status WriteProjectedPly(const ColouredMesh& mesh,
                         const ProjectedMesh& projected,
                         const std::string& path,
                         const ProductMetadata* meta,
                         const std::string& run_id) {
    namespace ply = formats::ply;
    if (auto c = CheckProjected(mesh, projected, path); !c) return c;
    ply::Header h;
    h.comments.push_back("generator pitmap proc_mesh");
    h.comments.push_back("pitmap_crs " + projected.crs_name);
    h.comments.push_back("pitmap_crs_epsg " + std::to_string(projected.horizontal_epsg) + " " +
                         std::to_string(projected.vertical_epsg));
    h.comments.push_back(
        "x, y, z: UTM easting, northing (m) and height in the vertical CRS (m), absolute; the "
        "CRS as WKT in the .prj beside this file");
    if (meta != nullptr)
        h.comments.push_back("pitmap_metadata " + ProductMetadataJson(*meta).dump());
    if (!run_id.empty()) h.comments.push_back(ply::RunIdComment(run_id));
    return WriteMeshPly(
        mesh, path, std::move(h), ply::Type::kFloat64, [&](ByteWriter& o, std::size_t i) {
            for (int k = 0; k < 3; ++k) o.F64Le(projected.positions[i][k]);
        });
}

Status WriteProjectedGlb(const ColouredMesh& mesh,
                         const ProjectedMesh& projected,
                         const std::string& path,
                         const ProductMetadata* meta,
                         const std::string& run_id) {
    using nlohmann::json;
    if (auto c = CheckProjected(mesh, projected, path); !c) return c;
    const Eigen::Vector3d& o = projected.offset;
    json asset = {{"version", "2.0"}, {"generator", "pitmap proc_mesh"}};
    if (meta != nullptr) asset["extras"]["pitmap_metadata"] = ProductMetadataJson(*meta);
    if (!run_id.empty()) asset["extras"]["pitmap_run_id"] = run_id;
    const auto code = [](int epsg) { return epsg > 0 ? json(epsg) : json(); };
    const json node = {
        {"translation", {o.x(), o.z(), -o.y()}},
        {"extras",
         {{"pitmap_offset", {{"easting_m", o.x()}, {"northing_m", o.y()}, {"height_m", o.z()}}},
          {"pitmap_crs",
           {{"name", projected.crs_name},
            {"horizontal_epsg", code(projected.horizontal_epsg)},
            {"vertical_epsg", code(projected.vertical_epsg)},
            {"wkt", projected.crs_wkt}}},
          {"pitmap_axes", "glTF y-up: x = easting, y = height, z = -northing, metres"}}}};
    return WriteGlbWith(mesh, path, asset, node, [&projected, &o](std::size_t i) {
        const Eigen::Vector3d d = projected.positions[i] - o;
        return std::array<float, 3>{
            static_cast<float>(d.x()), static_cast<float>(d.z()), static_cast<float>(-d.y())};
    });
}

}  // namespace pitmap::proc::mesh
