// SPDX-License-Identifier: MIT
#include "common/formats/ply.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace pitmap::formats::ply {

namespace {

struct TypeInfo {
    Type type;
    const char* name;
    const char* alias;
    std::size_t size;
};
constexpr TypeInfo kTypes[] = {
    {Type::kInt8, "char", "int8", 1},
    {Type::kUInt8, "uchar", "uint8", 1},
    {Type::kInt16, "short", "int16", 2},
    {Type::kUInt16, "ushort", "uint16", 2},
    {Type::kInt32, "int", "int32", 4},
    {Type::kUInt32, "uint", "uint32", 4},
    {Type::kFloat32, "float", "float32", 4},
    {Type::kFloat64, "double", "float64", 8},
};

const TypeInfo& Info(Type t) {
    return kTypes[static_cast<std::size_t>(t)];
}

bool IsInteger(Type t) {
    return t != Type::kFloat32 && t != Type::kFloat64;
}

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
    }
    return 0;
}

// An integer read as a double, as the header would write it.
std::string CountText(double v) {
    char s[32];
    std::snprintf(s, sizeof s, "%.0f", v);
    return s;
}

// One header line's words.
std::vector<std::string> Words(std::string_view line) {
    std::vector<std::string> w;
    std::istringstream in{std::string(line)};
    for (std::string s; in >> s;) w.push_back(s);
    return w;
}

bool ParseCount(const std::string& s, std::uint64_t* out) {
    if (s.empty() || s.size() > 19 || s.find_first_not_of("0123456789") != std::string::npos) {
        return false;
    }
    *out = std::stoull(s);
    return true;
}

}  // namespace

const char* TypeName(Type t) {
    return Info(t).name;
}

std::optional<Type> ParseType(std::string_view name) {
    for (const TypeInfo& i : kTypes) {
        if (name == i.name || name == i.alias) return i.type;
    }
    return std::nullopt;
}

std::size_t TypeSize(Type t) {
    return Info(t).size;
}

std::string FormatHeader(const Header& h) {
    std::string s = "ply\nformat ";
    s += h.format == Format::kAscii ? "ascii" : "binary_little_endian";
    s += " 1.0\n";
    for (const std::string& c : h.comments) s += "comment " + c + "\n";
    for (const Element& e : h.elements) {
        s += "element " + e.name + " " + std::to_string(e.count) + "\n";
        for (const Property& p : e.properties) {
            s += "property ";
            if (p.list_count) s += std::string("list ") + TypeName(*p.list_count) + " ";
            s += std::string(TypeName(p.type)) + " " + p.name + "\n";
        }
    }
    return s + "end_header\n";
}

Expected<Header> ParseHeader(std::string_view bytes,
                             std::uint64_t file_size,
                             std::size_t* header_bytes) {
    const std::string_view text = bytes.substr(0, kMaxHeaderBytes);
    std::size_t pos = 0;
    auto next_line = [&](std::string_view* line) {
        if (pos >= text.size()) return false;
        const std::size_t nl = text.find('\n', pos);
        if (nl == std::string_view::npos) return false;  // an unterminated line is no line
        *line = text.substr(pos, nl - pos);
        if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
        pos = nl + 1;
        return true;
    };
    std::string_view line;
    if (!next_line(&line) || line != "ply") return Error{"not a PLY file (no \"ply\" line)"};
    Header h;
    bool have_format = false;
    while (true) {
        if (!next_line(&line)) {
            return Error{"truncated or over-long header (no end_header in the first " +
                         std::to_string(kMaxHeaderBytes) + " bytes)"};
        }
        const std::vector<std::string> w = Words(line);
        const std::string shown(line.substr(0, 80));
        if (w.empty() || w[0] == "obj_info") continue;
        if (w[0] == "comment") {
            const std::size_t at = line.find("comment") + 7;
            std::string_view c = line.substr(std::min(line.size(), at));
            if (!c.empty() && c.front() == ' ') c.remove_prefix(1);
            h.comments.emplace_back(c);
        } else if (w[0] == "format") {
            if (w.size() != 3) return Error{"bad format line: " + shown};
            if (w[1] == "binary_little_endian") {
                h.format = Format::kBinaryLittleEndian;
            } else if (w[1] == "ascii") {
                h.format = Format::kAscii;
            } else {
                return Error{"unsupported PLY format " + w[1] +
                             " (ascii and binary_little_endian are read)"};
            }
            if (w[2] != "1.0") return Error{"unsupported PLY version " + w[2]};
            have_format = true;
        } else if (w[0] == "element") {
            Element e;
            // Every record takes at least one byte, so no count exceeds the file size.
            if (w.size() != 3 || !ParseCount(w[2], &e.count) || e.count > file_size) {
                return Error{"bad element line (count beyond the file size?): " + shown};
            }
            e.name = w[1];
            h.elements.push_back(std::move(e));
        } else if (w[0] == "property") {
            if (h.elements.empty()) return Error{"property before any element: " + shown};
            Property p;
            if (w.size() == 5 && w[1] == "list") {
                const auto count = ParseType(w[2]);
                const auto item = ParseType(w[3]);
                if (!count || !IsInteger(*count) || !item) {
                    return Error{"bad list property (integer count type needed): " + shown};
                }
                p.list_count = *count;
                p.type = *item;
                p.name = w[4];
            } else if (w.size() == 3 && ParseType(w[1])) {
                p.type = *ParseType(w[1]);
                p.name = w[2];
            } else {
                return Error{"bad property line: " + shown};
            }
            h.elements.back().properties.push_back(std::move(p));
        } else if (w[0] == "end_header") {
            break;
        } else {
            return Error{"unknown PLY header line: " + shown};
        }
    }
    if (!have_format) return Error{"no format line in the header"};
    *header_bytes = pos;
    return h;
}

std::string OriginComment(const Geodetic& g) {
    char s[160];
    std::snprintf(
        s, sizeof s, "pitmap_origin %.9f %.9f %.4f", g.latitude_deg, g.longitude_deg, g.height_m);
    return s;
}

std::string RunIdComment(const std::string& run_id) {
    return "pitmap_run_id " + run_id;
}

std::string RunIdFromComments(const std::vector<std::string>& comments) {
    constexpr std::string_view kTag = "pitmap_run_id ";
    for (const std::string& c : comments) {
        if (c.rfind(kTag, 0) == 0) return c.substr(kTag.size());
    }
    return "";
}

std::optional<Geodetic> OriginFromComments(const std::vector<std::string>& comments) {
    for (const std::string& c : comments) {
        std::istringstream in(c);
        std::string tag;
        Geodetic g;
        if (!(in >> tag >> g.latitude_deg >> g.longitude_deg >> g.height_m) ||
            tag != "pitmap_origin") {
            continue;
        }
        if (std::isfinite(g.latitude_deg) && std::isfinite(g.longitude_deg) &&
            std::isfinite(g.height_m) && std::abs(g.latitude_deg) <= 90 &&
            std::abs(g.longitude_deg) <= 360) {
            return g;
        }
    }
    return std::nullopt;
}

Writer::Writer(const std::string& path, const Header& header) : file_(path) {
    PITMAP_CHECK(header.format == Format::kBinaryLittleEndian, "ply::Writer writes binary only");
    file_.Text(FormatHeader(header));
}

Expected<Mesh> ReadMesh(const std::string& path,
                        const std::vector<std::string>& vertex_properties) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open"};
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) return Error{path + ": read error"};
    std::size_t data_offset = 0;
    auto header = ParseHeader(bytes, bytes.size(), &data_offset);
    if (!header) return Error{path + ": " + header.error().message};
    const bool binary = header->format == Format::kBinaryLittleEndian;
    Mesh out;
    out.comments = header->comments;

    ByteReader r(reinterpret_cast<const std::uint8_t*>(bytes.data()) + data_offset,
                 bytes.size() - data_offset);
    std::istringstream text;
    if (!binary) text.str(bytes.substr(data_offset));
    std::string line;
    // One record's line of an ASCII file. Made once: a stream's construction (its locale's
    // facets) cost more than a binary record's reading, once per record (2 s of pitmap
    // compare's CPU on bejanca).
    std::istringstream ls;
    for (const Element& e : header->elements) {
        const bool is_vertex = e.name == "vertex";
        const bool is_face = e.name == "face";
        int ix = -1, iy = -1, iz = -1, ibeam = -1;
        for (std::size_t k = 0; k < e.properties.size(); ++k) {
            const Property& p = e.properties[k];
            if (p.list_count) continue;
            if (p.name == "beam") ibeam = static_cast<int>(k);
            if (p.name == "x") ix = static_cast<int>(k);
            if (p.name == "y") iy = static_cast<int>(k);
            if (p.name == "z") iz = static_cast<int>(k);
        }
        if (is_vertex && (ix < 0 || iy < 0 || iz < 0)) {
            return Error{path + ": vertex without x, y, z"};
        }
        // Property index -> slot in out.vertex_properties (-1: not kept).
        std::vector<int> keep(e.properties.size(), -1);
        if (is_vertex) {
            out.vertex_properties.assign(vertex_properties.size(), {});
            for (std::size_t w = 0; w < vertex_properties.size(); ++w) {
                bool found = false;
                for (std::size_t k = 0; k < e.properties.size(); ++k) {
                    if (e.properties[k].name == vertex_properties[w] &&
                        !e.properties[k].list_count) {
                        keep[k] = static_cast<int>(w);
                        found = true;
                    }
                }
                if (!found) return Error{path + ": no vertex property " + vertex_properties[w]};
            }
        }
        const std::string where = path + ": " + e.name + " ";
        std::vector<int> face;
        for (std::uint64_t n = 0; n < e.count; ++n) {
            Eigen::Vector3d v = Eigen::Vector3d::Zero();
            double beam = -1;
            face.clear();
            if (!binary) {
                if (!std::getline(text, line)) return Error{where + "data truncated"};
                ls.clear();
                ls.str(line);
            }
            auto value = [&](Type t) {
                double x = 0;
                if (binary) {
                    x = ReadBinary(r, t);
                } else {
                    ls >> x;
                }
                return x;
            };
            for (std::size_t k = 0; k < e.properties.size(); ++k) {
                const Property& p = e.properties[k];
                if (!p.list_count) {
                    const double x = value(p.type);
                    if (is_vertex && static_cast<int>(k) == ix) v.x() = x;
                    if (is_vertex && static_cast<int>(k) == iy) v.y() = x;
                    if (is_vertex && static_cast<int>(k) == iz) v.z() = x;
                    if (is_vertex && static_cast<int>(k) == ibeam) beam = x;
                    if (is_vertex && keep[k] >= 0) {
                        out.vertex_properties[static_cast<std::size_t>(keep[k])].push_back(x);
                    }
                    continue;
                }
                const double cnt = value(*p.list_count);
                // The entries must fit in what is left (binary) or on the line (ascii, at least
                // two characters each).
                const double room = binary ? static_cast<double>(r.remaining() / TypeSize(p.type))
                                           : static_cast<double>(line.size() / 2 + 1);
                if (!(cnt >= 0 && cnt <= room) || cnt != std::floor(cnt)) {
                    return Error{where + std::to_string(n) + ": list count " + std::to_string(cnt) +
                                 " is negative or beyond the data (file truncated?)"};
                }
                const bool indices = is_face && p.name.rfind("vertex_ind", 0) == 0;
                for (std::size_t j = 0; j < static_cast<std::size_t>(cnt); ++j) {
                    const double x = value(p.type);
                    if (!indices) continue;
                    if (!(x >= 0 && x < static_cast<double>(out.vertices.size()) &&
                          x <= static_cast<double>(INT_MAX)) ||
                        x != std::floor(x)) {
                        return Error{where + std::to_string(n) + ": vertex index " +
                                     std::to_string(x) + " out of range"};
                    }
                    face.push_back(static_cast<int>(x));
                }
            }
            if (binary ? !r.ok() : ls.fail()) return Error{where + "data truncated or malformed"};
            if (is_vertex) {
                if (!v.allFinite() || v.cwiseAbs().maxCoeff() > kMaxCoordinateM) {
                    return Error{where + std::to_string(n) +
                                 ": coordinate not finite or beyond 1e9 m"};
                }
                out.vertices.push_back(v);
                if (ibeam >= 0) {
                    out.vertex_beam.push_back(beam >= 0 && beam < 65536 ? static_cast<int>(beam)
                                                                        : -1);
                }
            }
            for (std::size_t j = 2; is_face && j < face.size(); ++j) {
                out.triangles.push_back({face[0], face[j - 1], face[j]});
            }
        }
    }
    return out;
}

Expected<Layout> DescribeFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open"};
    in.seekg(0, std::ios::end);
    const std::streamoff end = in.tellg();
    if (end < 0) return Error{path + ": cannot find the file's size"};
    const std::uint64_t file_size = static_cast<std::uint64_t>(end);
    in.seekg(0);
    std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(file_size, kMaxHeaderBytes)),
                     '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    if (!in) return Error{path + ": read error"};
    std::size_t data_offset = 0;
    auto header = ParseHeader(head, file_size, &data_offset);
    if (!header) return Error{path + ": " + header.error().message};
    if (header->format != Format::kBinaryLittleEndian) {
        return Error{path + ": format ascii: only binary_little_endian PLY has records to map"};
    }
    Layout out;
    out.origin = OriginFromComments(header->comments);
    std::uint64_t offset = data_offset;
    // Reads `n` bytes at `at` into `buf`; false at the end of the file.
    std::vector<std::uint8_t> buf;
    auto read_at = [&](std::uint64_t at, std::size_t n) {
        buf.resize(n);
        in.clear();
        in.seekg(static_cast<std::streamoff>(at));
        in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(n));
        return static_cast<std::size_t>(in.gcount()) == n;
    };
    for (const Element& e : header->elements) {
        ElementLayout el;
        el.offset = offset;
        el.list_entries.assign(e.properties.size(), 0);
        const std::string where = path + ": element " + e.name;
        // Fixed part of a record and, for lists, the entry counts of the first record.
        std::uint64_t pos = 0;
        bool lists = false;
        for (std::size_t k = 0; k < e.properties.size(); ++k) {
            const Property& p = e.properties[k];
            if (!p.list_count) {
                pos += TypeSize(p.type);
                continue;
            }
            lists = true;
            if (e.count == 0) continue;
            const std::size_t cs = TypeSize(*p.list_count);
            if (offset + pos + cs > file_size || !read_at(offset + pos, cs)) {
                return Error{path + ": truncated (element " + e.name + ": no list count in " +
                             "its first record)"};
            }
            ByteReader r(buf.data(), cs);
            const double n = ReadBinary(r, *p.list_count);
            if (!(n >= 0) || n > static_cast<double>(file_size)) {
                return Error{where + ": list count " + CountText(n) + " beyond the file"};
            }
            el.list_entries[k] = static_cast<std::uint64_t>(n);
            pos += cs + el.list_entries[k] * TypeSize(p.type);
        }
        el.record_bytes = pos;
        // A list count near 2^64 / 8 could make count * record_bytes wrap: checked first.
        const bool overflow =
            el.record_bytes != 0 && e.count > (UINT64_MAX - offset) / el.record_bytes;
        const std::uint64_t need = overflow ? 0 : offset + e.count * el.record_bytes;
        if (overflow || need > file_size) {
            return Error{path + ": truncated (element " + e.name + " needs " +
                         (overflow ? std::string("more than 2^64") : std::to_string(need)) +
                         " bytes, file has " + std::to_string(file_size) + ")"};
        }
        if (lists && e.count > 1) {
            // Every record's list counts must equal the first record's: checked in chunks of
            // whole records (at most about 1 MiB).
            const std::uint64_t per_chunk =
                std::max<std::uint64_t>(1, (std::uint64_t{1} << 20) / el.record_bytes);
            for (std::uint64_t first = 0; first < e.count; first += per_chunk) {
                const std::uint64_t n = std::min(per_chunk, e.count - first);
                if (!read_at(offset + first * el.record_bytes,
                             static_cast<std::size_t>(n * el.record_bytes))) {
                    return Error{where + ": read error"};
                }
                for (std::uint64_t i = 0; i < n; ++i) {
                    ByteReader r(buf.data() + i * el.record_bytes,
                                 static_cast<std::size_t>(el.record_bytes));
                    for (std::size_t k = 0; k < e.properties.size(); ++k) {
                        const Property& p = e.properties[k];
                        if (!p.list_count) {
                            r.Skip(TypeSize(p.type));
                            continue;
                        }
                        const double c = ReadBinary(r, *p.list_count);
                        if (c != static_cast<double>(el.list_entries[k])) {
                            return Error{where + ": record " + std::to_string(first + i) +
                                         ": list " + p.name + " has " + CountText(c) +
                                         " entries, the first record " +
                                         std::to_string(el.list_entries[k]) +
                                         " (lists of varying length are not supported)"};
                        }
                        r.Skip(el.list_entries[k] * TypeSize(p.type));
                    }
                }
            }
        }
        offset = need;
        out.elements.push_back(std::move(el));
    }
    out.header = std::move(*header);
    return out;
}

}  // namespace pitmap::formats::ply
