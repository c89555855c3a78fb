// SPDX-License-Identifier: MIT
// PLY (Stanford polygon file format, version 1.0): the one place pitmap writes and reads it.
// Writers: points.ply (processor/io/products), mesh*.ply (processor/mesh/export); readers: the
// scorer (tools/eval, ReadMesh) and the report (tools/report, through pitmap-ply-layout's
// DescribeFile, which it memory-maps). Writing is binary_little_endian; reading takes ascii and
// binary_little_endian (big endian is refused with a clear error).
//
// pitmap's own convention: a header comment "pitmap_origin LAT LON H" (degrees, degrees,
// ellipsoidal metres, WGS 84) names the origin of the local East-North-Up world frame the
// coordinates are in (OriginComment / OriginFromComments).
//
// Reading bounds: the header is at most kMaxHeaderBytes of text; no element count may exceed
// the file size (every record takes at least a byte); list counts must fit in what is left;
// vertex coordinates must be finite and within kMaxCoordinateM; face indices must name an
// existing vertex. A file that breaks any of these is an error naming the file, never a crash
// or an allocation beyond the file's size.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/formats/byte_file.hpp"
#include "common/geodesy.hpp"
#include "common/result.hpp"

namespace pitmap::formats::ply {

enum class Type : std::uint8_t {
    kInt8,
    kUInt8,
    kInt16,
    kUInt16,
    kInt32,
    kUInt32,
    kFloat32,
    kFloat64,
};
// The header spelling pitmap writes ("char", "uchar", ..., "float", "double").
const char* TypeName(Type t);
// Both spellings of PLY 1.0 ("uchar" and "uint8", ...); nullopt for anything else.
std::optional<Type> ParseType(std::string_view name);
std::size_t TypeSize(Type t);

struct Property {
    Property() = default;
    Property(std::string name_, Type type_, std::optional<Type> list_count_ = std::nullopt)
        : name(std::move(name_)), type(type_), list_count(list_count_) {}
    std::string name;
    Type type = Type::kFloat32;      // the value's (a list's entries') type
    std::optional<Type> list_count;  // set for a list property: the count's integer type
};

struct Element {
    std::string name;
    std::uint64_t count = 0;
    std::vector<Property> properties;
};

enum class Format { kAscii, kBinaryLittleEndian };

struct Header {
    Format format = Format::kBinaryLittleEndian;
    std::vector<std::string> comments;  // without the "comment " prefix
    std::vector<Element> elements;
};

inline constexpr std::size_t kMaxHeaderBytes = 1 << 16;
inline constexpr double kMaxCoordinateM = 1e9;

// "ply\nformat ...\ncomment ...\nelement ...\nproperty ...\nend_header\n".
std::string FormatHeader(const Header& header);
// Parses a header from the start of `bytes` (the file's first bytes); `file_size` bounds the
// element counts. On success `header_bytes` is the offset of the data. Errors carry no path.
Expected<Header> ParseHeader(std::string_view bytes,
                             std::uint64_t file_size,
                             std::size_t* header_bytes);

// "pitmap_origin LAT LON H" with 9 decimals of a degree (0.1 mm) and 0.1 mm height.
std::string OriginComment(const Geodetic& origin);
// The first well-formed pitmap_origin comment (finite, |lat| <= 90, |lon| <= 360).
std::optional<Geodetic> OriginFromComments(const std::vector<std::string>& comments);
// "pitmap_run_id ID": the run of the survey the file belongs to (processor/survey/survey.hpp).
std::string RunIdComment(const std::string& run_id);
// The first pitmap_run_id comment's id, "" without one.
std::string RunIdFromComments(const std::vector<std::string>& comments);

// A binary_little_endian file: the header at construction, then each record's fields through
// Record() (common's ByteWriter) in the header's order, element by element.
class Writer {
public:
    Writer(const std::string& path, const Header& header);
    ByteWriter& Record() { return file_.out(); }
    // Closes the file; an error names the path.
    Status Close() { return file_.Close(); }

private:
    ByteFileWriter file_;
};

// What the scorer reads: vertex x, y, z (any numeric type), the optional vertex "beam", faces (a
// list property whose name starts with "vertex_ind"), polygons fan-triangulated; every other
// element and property is skipped by its declared type.
struct Mesh {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    std::vector<int> vertex_beam;  // the vertices' "beam" property (points.ply: -1 if out of
                                   // 0..65535), else empty
    std::vector<std::string> comments;
    // The vertex properties asked for, in the order asked, one value per vertex.
    std::vector<std::vector<double>> vertex_properties;
};
// `vertex_properties`: scalar vertex properties to keep (each must exist, else an error).
Expected<Mesh> ReadMesh(const std::string& path,
                        const std::vector<std::string>& vertex_properties = {});

// Where each element's records lie in a binary_little_endian file, for a reader that maps the
// bytes itself (the report memory-maps them with numpy; tools/report/ply_layout_main.cpp).
// Every element must have fixed-size records: a list property must hold the same number of
// entries in every record (a triangle mesh's faces), which is checked record by record.
struct ElementLayout {
    std::uint64_t offset = 0;        // the first record's byte offset in the file
    std::uint64_t record_bytes = 0;  // bytes per record (> 0 for an element with properties)
    // Per property of the header's element: the entries of every record's list (0 for a
    // scalar property).
    std::vector<std::uint64_t> list_entries;
};
struct Layout {
    Header header;
    std::vector<ElementLayout> elements;  // one per header element, in file order
    std::optional<Geodetic> origin;       // OriginFromComments(header.comments)
};
// Reads the header and walks the list counts with a bounded buffer (never the whole file).
// Errors name the path: not binary_little_endian, truncated (an element's records beyond the
// file's end), lists of varying length, a list with no count in its first record.
Expected<Layout> DescribeFile(const std::string& path);

}  // namespace pitmap::formats::ply
