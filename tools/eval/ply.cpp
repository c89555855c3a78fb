// SPDX-License-Identifier: MIT
#include "tools/eval/ply.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "common/byte_io.hpp"

namespace pitmap::eval {
namespace {

enum class Type { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64, kInvalid };

Type ParseType(const std::string& s) {
    if (s == "char" || s == "int8") return Type::kInt8;
    if (s == "uchar" || s == "uint8") return Type::kUInt8;
    if (s == "short" || s == "int16") return Type::kInt16;
    if (s == "ushort" || s == "uint16") return Type::kUInt16;
    if (s == "int" || s == "int32") return Type::kInt32;
    if (s == "uint" || s == "uint32") return Type::kUInt32;
    if (s == "float" || s == "float32") return Type::kFloat32;
    if (s == "double" || s == "float64") return Type::kFloat64;
    return Type::kInvalid;
}

struct Property {
    std::string name;
    Type type = Type::kInvalid;
    bool is_list = false;
    Type count_type = Type::kInvalid;
};

struct Element {
    std::string name;
    std::size_t count = 0;
    std::vector<Property> props;
};

double ReadBinary(ByteReader& r, Type t) {
    switch (t) {
        case Type::kInt8:
            return r.I8();
        case Type::kUInt8:
            return r.U8();
        case Type::kInt16:
            return r.I16Le();
        case Type::kUInt16:
            return r.U16Le();
        case Type::kInt32:
            return r.I32Le();
        case Type::kUInt32:
            return r.U32Le();
        case Type::kFloat32:
            return r.F32Le();
        case Type::kFloat64:
            return r.F64Le();
        case Type::kInvalid:
            break;
    }
    return 0;
}

std::size_t TypeSize(Type t) {
    switch (t) {
        case Type::kInt8:
        case Type::kUInt8:
            return 1;
        case Type::kInt16:
        case Type::kUInt16:
            return 2;
        case Type::kInt32:
        case Type::kUInt32:
        case Type::kFloat32:
            return 4;
        case Type::kFloat64:
            return 8;
        case Type::kInvalid:
            break;
    }
    return 1;
}

// The header is text; a real one is a few hundred bytes.
constexpr std::size_t kMaxHeaderBytes = 1 << 16;
// Vertex coordinates beyond this (metres) are not a survey product.
constexpr double kMaxCoordinate = 1e9;

}  // namespace

Expected<PlyData> ReadPly(const std::string& path,
                          const std::vector<std::string>& vertex_properties) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return Error{path + ": cannot open"};
    const auto file_size = static_cast<std::uint64_t>(std::max<std::streamoff>(in.tellg(), 0));
    in.seekg(0);
    std::string line;
    if (!std::getline(in, line) || (line != "ply" && line != "ply\r")) {
        return Error{path + ": not a PLY file (no \"ply\" line)"};
    }
    bool binary = false, have_format = false, have_end = false;
    std::vector<Element> elements;
    PlyData out;
    while (static_cast<std::uint64_t>(in.tellg()) < kMaxHeaderBytes && std::getline(in, line)) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream ls(line);
        std::string word;
        ls >> word;
        if (word == "format") {
            std::string fmt, version;
            ls >> fmt >> version;
            if (fmt == "binary_little_endian")
                binary = true;
            else if (fmt != "ascii")
                return Error{path + ": unsupported PLY format " + fmt};
            if (version != "1.0") return Error{path + ": unsupported PLY version " + version};
            have_format = true;
        } else if (word.empty() || word == "comment" || word == "obj_info") {
            if (word == "comment") out.comments.push_back(line.size() > 8 ? line.substr(8) : "");
        } else if (word == "element") {
            Element e;
            std::string count;
            ls >> e.name >> count;
            // Every element record takes at least one byte, so no count exceeds the file size.
            if (!ls || count.empty() ||
                count.find_first_not_of("0123456789") != std::string::npos || count.size() > 19 ||
                std::stoull(count) > file_size) {
                return Error{path + ": bad element line (count beyond the file size?): " + line};
            }
            e.count = static_cast<std::size_t>(std::stoull(count));
            elements.push_back(e);
        } else if (word == "property") {
            if (elements.empty()) return Error{path + ": property before any element"};
            Property p;
            std::string t;
            ls >> t;
            if (t == "list") {
                std::string ct, it;
                ls >> ct >> it >> p.name;
                p.is_list = true;
                p.count_type = ParseType(ct);
                p.type = ParseType(it);
                if (p.count_type == Type::kFloat32 || p.count_type == Type::kFloat64) {
                    p.count_type = Type::kInvalid;  // a list count is an integer type
                }
            } else {
                p.type = ParseType(t);
                ls >> p.name;
            }
            if (!ls || p.type == Type::kInvalid || (p.is_list && p.count_type == Type::kInvalid)) {
                return Error{path + ": bad property line: " + line};
            }
            elements.back().props.push_back(p);
        } else if (word == "end_header") {
            have_end = true;
            break;
        } else {
            return Error{path + ": unknown PLY header line: " + line.substr(0, 80)};
        }
    }
    if (!have_end) return Error{path + ": truncated or over-long header (no end_header)"};
    if (!have_format) return Error{path + ": no format line in the header"};

    std::vector<std::uint8_t> body;
    if (binary) {
        body.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    ByteReader r(body);
    for (const Element& e : elements) {
        const bool is_vertex = e.name == "vertex";
        const bool is_face = e.name == "face";
        int ix = -1, iy = -1, iz = -1;
        for (std::size_t k = 0; k < e.props.size(); ++k) {
            if (e.props[k].name == "x") ix = static_cast<int>(k);
            if (e.props[k].name == "y") iy = static_cast<int>(k);
            if (e.props[k].name == "z") iz = static_cast<int>(k);
        }
        if (is_vertex && (ix < 0 || iy < 0 || iz < 0))
            return Error{path + ": vertex without x, y, z"};
        // Property index -> slot in out.vertex_properties (-1: not kept).
        std::vector<int> keep(e.props.size(), -1);
        if (is_vertex) {
            if (out.vertex_properties.size() != vertex_properties.size()) {
                out.vertex_properties.assign(vertex_properties.size(), {});
            }
            for (std::size_t w = 0; w < vertex_properties.size(); ++w) {
                bool found = false;
                for (std::size_t k = 0; k < e.props.size(); ++k) {
                    if (e.props[k].name == vertex_properties[w] && !e.props[k].is_list) {
                        keep[k] = static_cast<int>(w);
                        found = true;
                    }
                }
                if (!found) return Error{path + ": no vertex property " + vertex_properties[w]};
            }
        }
        const std::string where = path + ": " + e.name + " ";
        for (std::size_t n = 0; n < e.count; ++n) {
            Eigen::Vector3d v = Eigen::Vector3d::Zero();
            std::vector<int> face;
            std::istringstream ls;
            if (!binary) {
                if (!std::getline(in, line)) return Error{where + "data truncated"};
                ls.str(line);
            }
            for (std::size_t k = 0; k < e.props.size(); ++k) {
                const Property& p = e.props[k];
                if (p.is_list) {
                    double cnt = 0;
                    if (binary)
                        cnt = ReadBinary(r, p.count_type);
                    else
                        ls >> cnt;
                    // The entries must fit in what is left (binary) or on the line (ascii,
                    // at least two characters each).
                    const double room = binary
                                            ? static_cast<double>(r.remaining() / TypeSize(p.type))
                                            : static_cast<double>(line.size() / 2 + 1);
                    if (!(cnt >= 0 && cnt <= room) || cnt != std::floor(cnt)) {
                        return Error{where + std::to_string(n) + ": list count " +
                                     std::to_string(cnt) + " is negative or beyond the data"};
                    }
                    for (std::size_t j = 0; j < static_cast<std::size_t>(cnt); ++j) {
                        double val = 0;
                        if (binary)
                            val = ReadBinary(r, p.type);
                        else
                            ls >> val;
                        if (!is_face || p.name.find("vertex_ind") != 0) continue;
                        if (!(val >= 0 && val < static_cast<double>(out.vertices.size())) ||
                            val != std::floor(val)) {
                            return Error{where + std::to_string(n) + ": vertex index " +
                                         std::to_string(val) + " out of range"};
                        }
                        face.push_back(static_cast<int>(val));
                    }
                } else {
                    double val = 0;
                    if (binary)
                        val = ReadBinary(r, p.type);
                    else
                        ls >> val;
                    if (is_vertex && static_cast<int>(k) == ix) v.x() = val;
                    if (is_vertex && static_cast<int>(k) == iy) v.y() = val;
                    if (is_vertex && static_cast<int>(k) == iz) v.z() = val;
                    if (is_vertex && keep[k] >= 0) {
                        out.vertex_properties[static_cast<std::size_t>(keep[k])].push_back(val);
                    }
                }
            }
            if (binary ? !r.ok() : ls.fail()) return Error{where + "data truncated or malformed"};
            if (is_vertex) {
                if (!v.allFinite() || v.cwiseAbs().maxCoeff() > kMaxCoordinate) {
                    return Error{where + std::to_string(n) +
                                 ": coordinate not finite or beyond 1e9 m"};
                }
                out.vertices.push_back(v);
            }
            for (std::size_t j = 2; is_face && j < face.size(); ++j) {
                out.triangles.push_back({face[0], face[j - 1], face[j]});
            }
        }
    }
    return out;
}

}  // namespace pitmap::eval
