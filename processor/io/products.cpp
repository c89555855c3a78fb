// SPDX-License-Identifier: MIT
#include "processor/io/products.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <type_traits>
#include <unordered_map>
#include <utility>

#include "common/formats/byte_file.hpp"
#include "common/formats/ply.hpp"
#include "common/formats/trajectory_csv.hpp"
#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/product_metadata_json.hpp"
#include "common/protocol/novatel/crc32.hpp"

namespace pitmap::proc::io {

std::string VehicleFilePath(const std::vector<std::string>& files,
                            const std::string& explicit_path) {
    if (!explicit_path.empty() || files.empty()) return explicit_path;
    const std::filesystem::path beside =
        std::filesystem::path(files.front()).parent_path() / "vehicle.yaml";
    std::error_code err;
    return std::filesystem::exists(beside, err) ? beside.string() : "";
}

Expected<VehicleConfig> ReadVehicleYaml(const std::string& path) {
    auto d = ReadVehicleFile(path);
    if (!d) return d.error();
    VehicleConfig v;
    v.description = std::move(*d);
    v.mount.lever_arm_m = v.description.sonar_lever_arm_m;
    const frames::Rpy rpy = frames::RpyFromRotationNed(v.description.R_vehicle_sonar());
    v.mount.boresight_roll_deg = frames::RadToDeg(rpy.roll);
    v.mount.boresight_pitch_deg = frames::RadToDeg(rpy.pitch);
    v.mount.boresight_yaw_deg = frames::RadToDeg(rpy.yaw);
    return v;
}

nlohmann::json VehicleJson(const VehicleDescription& v) {
    auto vec = [](const Eigen::Vector3d& x) { return nlohmann::json{x.x(), x.y(), x.z()}; };
    nlohmann::json antennas = nlohmann::json::array();
    for (const auto& a : v.gnss_antenna_lever_arms_m) antennas.push_back(vec(a));
    nlohmann::json j = {
        {"schema", kVehicleSchemaVersion},
        {"name", v.name},
        {"sonar_lever_arm_m", vec(v.sonar_lever_arm_m)},
        {"orientation", ToString(v.orientation)},
        {"tilt_deg", v.tilt_deg},
        {"connector", ToString(v.connector)},
        {"boresight_deg", vec(v.boresight_deg)},
        {"sonar_clock_offset_s", nullptr},
        {"sound_velocity_source", ToString(v.sound_velocity_source)},
        {"gnss_antenna_lever_arms_m", antennas},
        {"ins_height_above_waterline_m", nullptr},
        {"sonar_model", v.sonar_model},
        {"ins_model", v.ins_model},
    };
    if (v.sonar_clock_offset_s) j["sonar_clock_offset_s"] = *v.sonar_clock_offset_s;
    if (v.ins_height_above_waterline_m) {
        j["ins_height_above_waterline_m"] = *v.ins_height_above_waterline_m;
    }
    return j;
}

namespace {

// "status: 0 accepted, 1 no_detection, ..." for the PLY header.
std::string StatusComment() {
    std::string c = "status: SoundingStatus, 0 = accepted, else the reason of the rejection:";
    for (int k = 0; k < survey::kNumSoundingStatus; ++k) {
        c += " " + std::to_string(k) + " " +
             std::string(survey::ToString(static_cast<survey::SoundingStatus>(k)));
    }
    return c;
}

// The rejected soundings to write beside `result`: none without them or without a status each.
const georef::GeorefResult* UsableRejected(const georef::GeorefResult* rejected) {
    if (rejected == nullptr) return nullptr;
    const georef::GeorefPoints& q = rejected->points;
    if (q.size() == 0 || q.status.size() != q.size()) return nullptr;
    return rejected;
}

// The pings to take intensities from: none unless they carry intensities.
const survey::PingSeries* IntensityPings(const PointExtras* extras) {
    if (extras == nullptr || extras->pings == nullptr) return nullptr;
    return extras->pings->has_intensities() ? extras->pings : nullptr;
}

}  // namespace

std::uint16_t SoundingIntensity(const georef::GeorefResult& g,
                                std::size_t i,
                                const survey::PingSeries& pings) {
    if (!pings.has_intensities() || i >= g.points.size()) return 0;
    const std::uint32_t k = g.points.ping[i];
    if (k >= g.pings.size()) return 0;
    const std::uint32_t h = g.pings[k].header_index;
    if (h >= pings.pings.size()) return 0;
    const survey::PingHeader& head = pings.pings[h];
    const std::uint16_t beam = g.points.beam[i];
    if (beam >= head.num_beams) return 0;
    const std::size_t at = static_cast<std::size_t>(head.beam_offset) + beam;
    return at < pings.intensities.size() ? pings.intensities[at] : 0;
}

PointBlocks WholePoints(const georef::GeorefResult& r) {
    PointBlocks blocks;
    blocks.count = r.points.size();
    blocks.for_each =
        [&r](const std::function<Status(const georef::GeorefResult&, std::size_t)>& fn) {
            return fn(r, 0);
        };
    return blocks;
}

Status WritePly(const std::string& path,
                const georef::GeorefResult& r,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected) {
    return WritePly(path, r, WholePoints(r), extras, run_id, rejected);
}

Status WritePly(const std::string& path,
                const georef::GeorefResult& r,
                const PointBlocks& blocks,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected) {
    namespace ply = formats::ply;
    const std::size_t num_accepted = blocks.count;
    const georef::GeorefResult* rej = UsableRejected(rejected);
    const std::size_t n_rejected = rej != nullptr ? rej->points.size() : 0;
    const bool tpu = extras != nullptr && extras->thu_95_m.size() == num_accepted &&
                     extras->tvu_95_m.size() == num_accepted;
    const bool datum = extras != nullptr && extras->datum_height_m.size() == r.pings.size() &&
                       (rej == nullptr || rej->pings.size() == r.pings.size());
    ply::Header h;
    h.comments = {"generated by pitmap georef",
                  ply::OriginComment(r.world_origin),
                  "frame world: East-North-Up metres at pitmap_origin; gps_time_s since "
                  "1980-01-06"};
    if (!run_id.empty()) h.comments.push_back(ply::RunIdComment(run_id));
    std::vector<ply::Property> props = {{"x", ply::Type::kFloat32},
                                        {"y", ply::Type::kFloat32},
                                        {"z", ply::Type::kFloat32},
                                        {"gps_time_s", ply::Type::kFloat64},
                                        {"range_m", ply::Type::kFloat32},
                                        {"ping", ply::Type::kUInt32},
                                        {"beam", ply::Type::kUInt16}};
    const survey::PingSeries* intensities = IntensityPings(extras);
    if (intensities != nullptr) {
        props.push_back({"intensity", ply::Type::kUInt16});
        h.comments.push_back(
            "intensity: the 83P per-beam intensity as recorded (u16 normalized amplitude, no "
            "physical unit; 0 none)");
    }
    if (tpu) {
        props.push_back({"thu_95_m", ply::Type::kFloat32});
        props.push_back({"tvu_95_m", ply::Type::kFloat32});
        h.comments.push_back(
            "thu_95_m, tvu_95_m: total propagated uncertainty, 95 %, m (NaN: rejected)");
    }
    if (datum) {
        props.push_back({"depth_m", ply::Type::kFloat32});
        h.comments.push_back("pitmap_vertical_datum " + extras->vertical_name);
        h.comments.push_back("depth_m: below the vertical datum, m (x, y, z stay ellipsoidal)");
    }
    props.push_back({"status", ply::Type::kUInt8});
    h.comments.push_back(StatusComment());
    h.comments.push_back("soundings: " + std::to_string(num_accepted) + " accepted, then " +
                         std::to_string(n_rejected) + " rejected");
    h.elements.push_back({"vertex", num_accepted + n_rejected, props});
    std::optional<LocalTangentFrame> world;
    if (datum) world.emplace(r.world_origin);
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    ply::Writer w(path, h);
    // Sounding j of g (the accepted ones' first + j when accepted).
    const auto write = [&](const georef::GeorefResult& g, bool accepted, std::size_t first) {
        const georef::GeorefPoints& Q = g.points;
        for (std::size_t j = 0; j < Q.size(); ++j) {
            ByteWriter& o = w.Record();
            const Eigen::Vector3d& p = Q.position_world[j];
            o.F32Le(static_cast<float>(p.x()));
            o.F32Le(static_cast<float>(p.y()));
            o.F32Le(static_cast<float>(p.z()));
            o.F64Le(static_cast<double>(g.pings[Q.ping[j]].utime_gps) * 1e-6);
            o.F32Le(Q.range_m[j]);
            o.U32Le(Q.ping[j]);
            o.U16Le(Q.beam[j]);
            if (intensities != nullptr) o.U16Le(SoundingIntensity(g, j, *intensities));
            if (tpu) {
                o.F32Le(accepted ? extras->thu_95_m[first + j] : kNaN);
                o.F32Le(accepted ? extras->tvu_95_m[first + j] : kNaN);
            }
            if (datum) {
                const double height = world->FromEnu(p).height_m;
                o.F32Le(static_cast<float>(extras->datum_height_m[Q.ping[j]] - height));
            }
            o.U8(accepted ? 0 : Q.status[j]);
        }
    };
    std::size_t written = 0;
    auto st = blocks.for_each([&](const georef::GeorefResult& g, std::size_t first) {
        if (first != written || first + g.points.size() > num_accepted)
            return Status{Error{path + ": the soundings' blocks are out of order"}};
        write(g, true, first);
        written += g.points.size();
        return Status{Ok{}};
    });
    if (!st) return st;
    if (written != num_accepted)
        return Error{path + ": " + std::to_string(written) + " of " + std::to_string(num_accepted) +
                     " soundings given"};
    if (rej != nullptr) write(*rej, false, 0);
    return w.Close();
}

std::string UtmWkt(int zone, bool northern) {
    const int epsg = UtmEpsgCode(zone, northern);
    const std::string name = "WGS 84 / UTM zone " + std::to_string(zone) + (northern ? "N" : "S");
    return "PROJCS[\"" + name +
           "\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563,"
           "AUTHORITY[\"EPSG\",\"7030\"]],AUTHORITY[\"EPSG\",\"6326\"]],PRIMEM[\"Greenwich\",0,"
           "AUTHORITY[\"EPSG\",\"8901\"]],UNIT[\"degree\",0.0174532925199433,AUTHORITY[\"EPSG\","
           "\"9122\"]],AUTHORITY[\"EPSG\",\"4326\"]],PROJECTION[\"Transverse_Mercator\"],"
           "PARAMETER[\"latitude_of_origin\",0],PARAMETER[\"central_meridian\"," +
           std::to_string(zone * 6 - 183) +
           "],PARAMETER[\"scale_factor\",0.9996],PARAMETER[\"false_easting\",500000],"
           "PARAMETER[\"false_northing\"," +
           (northern ? "0" : "10000000") +
           "],UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Easting\",EAST],"
           "AXIS[\"Northing\",NORTH],AUTHORITY[\"EPSG\",\"" +
           std::to_string(epsg) + "\"]]";
}

std::string LasWkt(int zone, bool northern, const std::string& vertical_wkt) {
    std::string vertical = vertical_wkt;
    if (vertical.empty()) {
        vertical =
            "VERT_CS[\"WGS 84 ellipsoidal height\",VERT_DATUM[\"World Geodetic System 1984\","
            "2002],UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Ellipsoidal height\","
            "UP]]";
    }
    // The VERT_CS's name: its first quoted string.
    std::string vname = "vertical";
    if (const auto a = vertical.find('"'); a != std::string::npos) {
        if (const auto b = vertical.find('"', a + 1); b != std::string::npos) {
            vname = vertical.substr(a + 1, b - a - 1);
        }
    }
    return "COMPD_CS[\"WGS 84 / UTM zone " + std::to_string(zone) + (northern ? "N" : "S") + " + " +
           vname + "\"," + UtmWkt(zone, northern) + "," + vertical + "]";
}

namespace {

// One LAS 1.4 Extra Bytes descriptor (R15 Table 24, 192 bytes) of a float32 in metres.
void ExtraBytesFloat(ByteWriter& w, const std::string& name, const std::string& description) {
    w.U8(0);  // reserved
    w.U8(0);
    w.U8(9);  // data type: float
    w.U8(0);  // options: no no_data, min, max, scale or offset
    w.FixedString(name, 32);
    for (int i = 0; i < 4; ++i) w.U8(0);       // unused
    for (int i = 0; i < 8 + 16; ++i) w.U8(0);  // no_data, deprecated
    for (int i = 0; i < 8 + 16; ++i) w.U8(0);  // min, deprecated
    for (int i = 0; i < 8 + 16; ++i) w.U8(0);  // max, deprecated
    w.F64Le(0);                                // scale (unused: option bit 3 clear)
    for (int i = 0; i < 16; ++i) w.U8(0);
    w.F64Le(0);  // offset
    for (int i = 0; i < 16; ++i) w.U8(0);
    w.FixedString(description, 32);
}

// The header's System Identifier (32 bytes): the vessel and its multibeam where known.
std::string LasSystemIdentifier(const ProductMetadata* meta) {
    if (meta == nullptr) return "pitmap ASV multibeam";
    std::string s = meta->vessel;
    for (const Equipment& e : meta->equipment) {
        if (e.role == "multibeam") s += (s.empty() ? "" : " ") + e.model;
    }
    return s.empty() ? "pitmap ASV multibeam" : s.substr(0, 32);
}

// The metadata VLR's payload: JSON, "" without metadata. A VLR holds at most 65535 bytes: the
// notes are cut to fit (the config limits every field to 500 characters, so they seldom are).
std::string LasMetadataPayload(const ProductMetadata* meta) {
    if (meta == nullptr) return "";
    ProductMetadata m = *meta;
    std::string text = ProductMetadataJson(m).dump();
    while (text.size() > 65535 && !m.notes.empty()) {
        m.notes.resize(m.notes.size() / 2);
        text = ProductMetadataJson(m).dump();
    }
    return text.size() > 65535 ? std::string() : text;
}

// The soundings of points.las in record order: the accepted ones, then the rejected (withheld),
// each with its UTM position and, where the extras give the datum, its height on it.
struct LasSoundings {
    const georef::GeorefResult* accepted = nullptr;
    // The accepted soundings' UTM positions: held (a UtmPoints) or placed one at a time.
    const georef::UtmPoints* accepted_utm = nullptr;
    const georef::UtmProjection* accepted_projection = nullptr;
    const georef::GeorefResult* rejected = nullptr;  // null: none written
    georef::UtmProjection rejected_projection;
    const PointExtras* extras = nullptr;
    std::size_t num_accepted = 0;
    std::size_t size = 0;
    bool tpu = false;    // the extras hold THU and TVU for every accepted sounding
    bool datum = false;  // the extras hold the datum height at every ping

    // Record j: accepted sounding j for j < num_accepted, else rejected j - num_accepted.
    std::pair<const georef::GeorefResult*, std::size_t> Source(std::size_t j) const {
        return j < num_accepted ? std::pair{accepted, j} : std::pair{rejected, j - num_accepted};
    }
    Eigen::Vector3d Position(std::size_t j) const {
        const auto [geo, i] = Source(j);
        Eigen::Vector3d enh = geo != accepted           ? rejected_projection.At(*rejected, i)
                              : accepted_utm != nullptr ? accepted_utm->easting_northing_height[i]
                                                        : accepted_projection->At(*accepted, i);
        if (datum) enh.z() -= extras->datum_height_m[geo->points.ping[i]];
        return enh;
    }
};

// The rejected soundings are written only in the accepted ones' UTM zone (an error otherwise).
// `utm` or `projection` (the other null) places the accepted soundings.
Expected<LasSoundings> LasSoundingsOf(const std::string& path,
                                      const georef::GeorefResult& r,
                                      const georef::UtmPoints* utm,
                                      const georef::UtmProjection* projection,
                                      const PointExtras* extras,
                                      const georef::GeorefResult* rejected) {
    LasSoundings s;
    s.accepted = &r;
    s.accepted_utm = utm;
    s.accepted_projection = projection;
    s.extras = extras;
    s.num_accepted = utm != nullptr ? utm->easting_northing_height.size() : r.points.size();
    s.rejected = UsableRejected(rejected);
    std::size_t num_rejected = 0;
    if (s.rejected != nullptr) {
        auto u = georef::UtmProjectionOf(*s.rejected);
        if (!u) return Error{path + ": UTM of the rejected soundings: " + u.error().message};
        const int zone = utm != nullptr ? utm->zone : projection->zone;
        const bool northern = utm != nullptr ? utm->northern : projection->northern;
        if (u->zone != zone || u->northern != northern) {
            return Error{path + ": the rejected soundings are in another UTM zone"};
        }
        s.rejected_projection = std::move(*u);
        num_rejected = s.rejected->points.size();
    }
    s.size = s.num_accepted + num_rejected;
    s.tpu = extras != nullptr && extras->thu_95_m.size() == s.num_accepted &&
            extras->tvu_95_m.size() == s.num_accepted && r.points.size() == s.num_accepted;
    s.datum = extras != nullptr && extras->datum_height_m.size() == r.pings.size() &&
              r.points.size() == s.num_accepted &&
              (s.rejected == nullptr || s.rejected->pings.size() == r.pings.size());
    return s;
}

// The points' bounds and the coordinates' scale and offset: 1 mm steps from whole metres at or
// below the lowest point (the record's 32-bit integers then reach 2147 km).
struct LasExtent {
    Eigen::Vector3d lo = Eigen::Vector3d::Zero();
    Eigen::Vector3d hi = Eigen::Vector3d::Zero();
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
    double scale = 0.001;
};

LasExtent LasExtentOf(const LasSoundings& s) {
    LasExtent extent;
    extent.lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
    extent.hi = -extent.lo;
    for (std::size_t j = 0; j < s.size; ++j) {
        const Eigen::Vector3d p = s.Position(j);
        extent.lo = extent.lo.cwiseMin(p);
        extent.hi = extent.hi.cwiseMax(p);
    }
    if (s.size == 0) extent.lo = extent.hi = Eigen::Vector3d::Zero();
    extent.offset = Eigen::Vector3d(
        std::floor(extent.lo.x()), std::floor(extent.lo.y()), std::floor(extent.lo.z()));
    return extent;
}

// What precedes the points: the VLRs written (the CRS always; the Extra Bytes of the TPU and
// the metadata when there are any), the record length and where the points start.
struct LasLayout {
    static constexpr std::uint16_t kHeaderSize = 375;
    static constexpr std::uint16_t kVlrHeaderSize = 54;
    static constexpr std::uint16_t kExtraBytesVlrSize = 2 * 192;
    std::string wkt;            // NUL-terminated
    std::string metadata_json;  // "" = no metadata VLR
    bool tpu = false;
    std::uint16_t record_length = 30;
    std::uint32_t point_offset = 0;
    std::uint32_t num_vlrs = 1;
};

LasLayout LasLayoutOf(const LasSoundings& s, int zone, bool northern, const ProductMetadata* meta) {
    LasLayout layout;
    layout.wkt =
        LasWkt(zone, northern, s.extras != nullptr ? s.extras->vertical_wkt : std::string()) +
        std::string(1, '\0');
    layout.metadata_json = LasMetadataPayload(meta);
    layout.tpu = s.tpu;
    layout.record_length = s.tpu ? 38 : 30;
    layout.point_offset =
        LasLayout::kHeaderSize + LasLayout::kVlrHeaderSize +
        static_cast<std::uint32_t>(layout.wkt.size()) +
        (s.tpu ? LasLayout::kVlrHeaderSize + LasLayout::kExtraBytesVlrSize : 0) +
        (layout.metadata_json.empty()
             ? 0
             : LasLayout::kVlrHeaderSize + static_cast<std::uint32_t>(layout.metadata_json.size()));
    layout.num_vlrs = 1u + (s.tpu ? 1u : 0u) + (layout.metadata_json.empty() ? 0u : 1u);
    return layout;
}

// The header's file creation date: the survey's first ping (1980, day 1 without pings), so that
// the file depends only on the data.
struct LasDate {
    int day_of_year = 1;
    int year = 1980;
};

LasDate LasCreationDate(const georef::GeorefResult& r) {
    LasDate date;
    if (r.pings.empty()) return date;
    const UtcCalendar c = UtcCalendarFromUnix(UnixFromGps(r.pings.front().utime_gps));
    const auto jan1 = UnixFromUtcCalendar({c.year, 1, 1, 0, 0, 0, 0});
    const auto today = UnixFromUtcCalendar({c.year, c.month, c.day, 0, 0, 0, 0});
    if (jan1 && today) date.day_of_year = static_cast<int>((*today - *jan1) / 86'400'000'000LL) + 1;
    date.year = c.year;
    return date;
}

// The public header block (LAS 1.4 R15 Table 3), point data record format 6.
void WriteLasHeader(ByteWriter& w,
                    const LasLayout& layout,
                    const LasExtent& extent,
                    std::uint64_t num_points,
                    const LasDate& date,
                    const std::string& run_id,
                    const ProductMetadata* meta) {
    w.FixedString("LASF", 4);
    w.U16Le(0);                      // file source id
    w.U16Le((1u << 0) | (1u << 4));  // adjusted standard GPS time, WKT CRS
    // Project ID (GUID 1..4): the run id's 16 bytes in the order of its hex digits.
    for (std::uint8_t b : RunIdBytes(run_id)) w.U8(b);
    w.U8(1);  // version 1.4
    w.U8(4);
    w.FixedString(LasSystemIdentifier(meta), 32);
    w.FixedString(meta != nullptr && !meta->software.empty() ? meta->software : "pitmap georef",
                  32);
    w.U16Le(static_cast<std::uint16_t>(date.day_of_year));
    w.U16Le(static_cast<std::uint16_t>(date.year));
    w.U16Le(LasLayout::kHeaderSize);
    w.U32Le(layout.point_offset);
    w.U32Le(layout.num_vlrs);
    w.U8(6);  // point data record format
    w.U16Le(layout.record_length);
    w.U32Le(0);  // legacy point count: 0 for formats 6-10
    for (int i = 0; i < 5; ++i) w.U32Le(0);
    for (int axis = 0; axis < 3; ++axis) w.F64Le(extent.scale);
    for (int axis = 0; axis < 3; ++axis) w.F64Le(extent.offset[axis]);
    for (int axis = 0; axis < 3; ++axis) {
        w.F64Le(extent.hi[axis]);
        w.F64Le(extent.lo[axis]);
    }
    w.U64Le(0);           // start of waveform data
    w.U64Le(0);           // start of first EVLR
    w.U32Le(0);           // number of EVLRs
    w.U64Le(num_points);  // number of point records
    w.U64Le(num_points);  // points by return: all single returns
    for (int i = 1; i < 15; ++i) w.U64Le(0);
}

// The variable length records: the CRS as WKT, the TPU's Extra Bytes, the survey's metadata.
void WriteLasVlrs(ByteWriter& w, const LasLayout& layout) {
    // OGC coordinate system WKT (record id 2112).
    w.U16Le(0);
    w.FixedString("LASF_Projection", 16);
    w.U16Le(2112);
    w.U16Le(static_cast<std::uint16_t>(layout.wkt.size()));
    w.FixedString("OGC WKT, compound CRS", 32);
    w.Bytes({reinterpret_cast<const std::uint8_t*>(layout.wkt.data()), layout.wkt.size()});
    if (layout.tpu) {
        // Extra Bytes (record id 4): the per-sounding uncertainty after the format-6 fields.
        w.U16Le(0);
        w.FixedString("LASF_Spec", 16);
        w.U16Le(4);
        w.U16Le(LasLayout::kExtraBytesVlrSize);
        w.FixedString("pitmap TPU: THU, TVU 95 %, m", 32);
        ExtraBytesFloat(w, kLasThuName, "horizontal uncertainty 95 %, m");
        ExtraBytesFloat(w, kLasTvuName, "vertical uncertainty 95 %, m");
    }
    if (!layout.metadata_json.empty()) {
        // The survey's metadata as JSON (pitmap's own record, ProductMetadataJson).
        const std::string& json = layout.metadata_json;
        w.U16Le(0);
        w.FixedString(kLasMetadataUserId, 16);
        w.U16Le(kLasMetadataRecordId);
        w.U16Le(static_cast<std::uint16_t>(json.size()));
        w.FixedString("pitmap survey metadata, JSON", 32);
        w.Bytes({reinterpret_cast<const std::uint8_t*>(json.data()), json.size()});
    }
}

// One point record, format 6 (and the TPU's extra bytes): bathymetry for an accepted
// sounding, withheld with its noise class `noise` for a rejected one (THU/TVU NaN).
struct LasRecord {
    Eigen::Vector3d enh;
    std::uint16_t intensity = 0;
    bool accepted = true;
    std::uint8_t noise = 0;
    double angle_rad = 0;
    double gps_time_s = 0;
    float thu_95_m = 0, tvu_95_m = 0;
};

void WriteLasRecord(ByteWriter& rec, const LasRecord& p, const LasExtent& extent, bool tpu) {
    for (int axis = 0; axis < 3; ++axis) {
        rec.I32Le(static_cast<std::int32_t>(
            std::llround((p.enh[axis] - extent.offset[axis]) / extent.scale)));
    }
    rec.U16Le(p.intensity);
    rec.U8(1 | (1 << 4));                                // return 1 of 1
    rec.U8(p.accepted ? 0 : kLasFlagWithheld);           // flags, channel, scan direction, edge
    rec.U8(p.accepted ? kLasClassBathymetry : p.noise);  // classification
    rec.U8(0);                                           // user data
    const double angle_deg = frames::RadToDeg(p.angle_rad);
    rec.I16Le(static_cast<std::int16_t>(std::lround(std::clamp(angle_deg, -180.0, 180.0) / 0.006)));
    rec.U16Le(0);  // point source id
    rec.F64Le(p.gps_time_s - 1e9);
    if (tpu) {
        rec.F32Le(p.thu_95_m);
        rec.F32Le(p.tvu_95_m);
    }
}

// The point records, format 6 (and the TPU's extra bytes): bathymetry for the accepted
// soundings, withheld with their noise class for the rejected ones (THU/TVU NaN).
void WriteLasPoints(formats::ByteFileWriter& file, const LasSoundings& s, const LasExtent& extent) {
    std::vector<std::uint8_t> noise;
    if (s.rejected != nullptr) noise = LasNoiseClasses(s.accepted->points, s.rejected->points);
    // LAS 1.4 R15 asks for the sensor's intensity scaled to 16 bits: the 83P's is 16 bits.
    const auto* intensities = IntensityPings(s.extras);
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t j = 0; j < s.size; ++j) {
        const auto [geo, i] = s.Source(j);
        const bool accepted = geo == s.accepted;
        const georef::GeorefPoints& points = geo->points;
        LasRecord p;
        p.enh = s.Position(j);
        p.intensity = intensities != nullptr ? SoundingIntensity(*geo, i, *intensities) : 0;
        p.accepted = accepted;
        p.noise = accepted ? 0 : noise[i];
        p.angle_rad = points.angle_rad[i];
        p.gps_time_s = static_cast<double>(geo->pings[points.ping[i]].utime_gps) * 1e-6;
        if (s.tpu) {
            p.thu_95_m = accepted ? s.extras->thu_95_m[i] : kNaN;
            p.tvu_95_m = accepted ? s.extras->tvu_95_m[i] : kNaN;
        }
        WriteLasRecord(file.out(), p, extent, s.tpu);
    }
}

}  // namespace

namespace {

Status WriteLasOf(const std::string& path,
                  const georef::GeorefResult& r,
                  const LasSoundings& soundings,
                  int zone,
                  bool northern,
                  const std::string& run_id,
                  const ProductMetadata* meta) {
    const LasExtent extent = LasExtentOf(soundings);
    const LasLayout layout = LasLayoutOf(soundings, zone, northern, meta);
    formats::ByteFileWriter file(path);
    WriteLasHeader(file.out(), layout, extent, soundings.size, LasCreationDate(r), run_id, meta);
    WriteLasVlrs(file.out(), layout);
    WriteLasPoints(file, soundings, extent);
    return file.Close();
}

}  // namespace

Status WriteLas(const std::string& path,
                const georef::GeorefResult& r,
                const georef::UtmPoints& utm,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected,
                const ProductMetadata* meta) {
    auto soundings = LasSoundingsOf(path, r, &utm, nullptr, extras, rejected);
    if (!soundings) return soundings.error();
    return WriteLasOf(path, r, *soundings, utm.zone, utm.northern, run_id, meta);
}

Status WriteLas(const std::string& path,
                const georef::GeorefResult& r,
                const georef::UtmProjection& utm,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected,
                const ProductMetadata* meta) {
    return WriteLas(path, r, WholePoints(r), utm, extras, run_id, rejected, meta);
}

namespace {

// The extent of the points grown by p (LasExtentOf's arithmetic, in its order).
void GrowExtent(LasExtent& extent, const Eigen::Vector3d& p) {
    extent.lo = extent.lo.cwiseMin(p);
    extent.hi = extent.hi.cwiseMax(p);
}

// Accepted sounding i of a block in UTM, on the datum when the extras give it.
Eigen::Vector3d AcceptedPosition(const LasSoundings& s,
                                 const georef::UtmProjection& utm,
                                 const georef::GeorefResult& block,
                                 std::size_t i) {
    Eigen::Vector3d enh = utm.At(block, i);
    if (s.datum) enh.z() -= s.extras->datum_height_m[block.points.ping[i]];
    return enh;
}

// The first pass over the blocks: the points' extent and the accepted heights the rejected
// soundings' noise classes take.
Expected<LasExtent> LasExtentOfBlocks(const std::string& path,
                                      const LasSoundings& s,
                                      const PointBlocks& blocks,
                                      const georef::UtmProjection& utm,
                                      NoiseHeights& heights) {
    LasExtent extent;
    extent.lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
    extent.hi = -extent.lo;
    std::size_t given = 0;
    auto st = blocks.for_each([&](const georef::GeorefResult& g, std::size_t first) {
        if (first != given || first + g.points.size() > s.num_accepted)
            return Status{Error{path + ": the soundings' blocks are out of order"}};
        for (std::size_t i = 0; i < g.points.size(); ++i)
            GrowExtent(extent, AcceptedPosition(s, utm, g, i));
        if (s.rejected != nullptr) heights.Add(g.points);
        given += g.points.size();
        return Status{Ok{}};
    });
    if (!st) return st.error();
    if (given != s.num_accepted)
        return Error{path + ": " + std::to_string(given) + " of " + std::to_string(s.num_accepted) +
                     " soundings given"};
    for (std::size_t j = s.num_accepted; j < s.size; ++j) GrowExtent(extent, s.Position(j));
    if (s.size == 0) extent.lo = extent.hi = Eigen::Vector3d::Zero();
    extent.offset = Eigen::Vector3d(
        std::floor(extent.lo.x()), std::floor(extent.lo.y()), std::floor(extent.lo.z()));
    return extent;
}

// The second pass: the accepted soundings' records a block at a time, then the rejected ones'.
Status WriteLasBlocks(formats::ByteFileWriter& file,
                      const LasSoundings& s,
                      const PointBlocks& blocks,
                      const georef::UtmProjection& utm,
                      const LasExtent& extent,
                      const std::vector<std::uint8_t>& noise) {
    const auto* intensities = IntensityPings(s.extras);
    auto st = blocks.for_each([&](const georef::GeorefResult& g, std::size_t first) {
        for (std::size_t i = 0; i < g.points.size(); ++i) {
            LasRecord p;
            p.enh = AcceptedPosition(s, utm, g, i);
            p.intensity = intensities != nullptr ? SoundingIntensity(g, i, *intensities) : 0;
            p.angle_rad = g.points.angle_rad[i];
            p.gps_time_s = static_cast<double>(g.pings[g.points.ping[i]].utime_gps) * 1e-6;
            if (s.tpu) {
                p.thu_95_m = s.extras->thu_95_m[first + i];
                p.tvu_95_m = s.extras->tvu_95_m[first + i];
            }
            WriteLasRecord(file.out(), p, extent, s.tpu);
        }
        return Status{Ok{}};
    });
    if (!st) return st;
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t i = 0; s.rejected != nullptr && i < s.rejected->points.size(); ++i) {
        const georef::GeorefResult& g = *s.rejected;
        LasRecord p;
        p.enh = s.Position(s.num_accepted + i);
        p.intensity = intensities != nullptr ? SoundingIntensity(g, i, *intensities) : 0;
        p.accepted = false;
        p.noise = noise[i];
        p.angle_rad = g.points.angle_rad[i];
        p.gps_time_s = static_cast<double>(g.pings[g.points.ping[i]].utime_gps) * 1e-6;
        p.thu_95_m = p.tvu_95_m = kNaN;
        WriteLasRecord(file.out(), p, extent, s.tpu);
    }
    return Ok{};
}

}  // namespace

Status WriteLas(const std::string& path,
                const georef::GeorefResult& r,
                const PointBlocks& blocks,
                const georef::UtmProjection& utm,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected,
                const ProductMetadata* meta) {
    if (utm.sensor_utm.size() != r.pings.size()) {
        return Error{path + ": the UTM projection is not of these soundings (" +
                     std::to_string(utm.sensor_utm.size()) + " pings, the soundings have " +
                     std::to_string(r.pings.size()) + ")"};
    }
    auto made = LasSoundingsOf(path, r, nullptr, &utm, extras, rejected);
    if (!made) return made.error();
    LasSoundings s = std::move(*made);
    const std::size_t num_rejected = s.size - s.num_accepted;
    s.num_accepted = blocks.count;
    s.size = s.num_accepted + num_rejected;
    s.tpu = extras != nullptr && extras->thu_95_m.size() == s.num_accepted &&
            extras->tvu_95_m.size() == s.num_accepted;
    s.datum = extras != nullptr && extras->datum_height_m.size() == r.pings.size() &&
              (s.rejected == nullptr || s.rejected->pings.size() == r.pings.size());
    NoiseHeights heights;
    auto extent = LasExtentOfBlocks(path, s, blocks, utm, heights);
    if (!extent) return extent.error();
    std::vector<std::uint8_t> noise;
    if (s.rejected != nullptr) noise = heights.Classes(s.rejected->points);
    const LasLayout layout = LasLayoutOf(s, utm.zone, utm.northern, meta);
    formats::ByteFileWriter file(path);
    WriteLasHeader(file.out(), layout, *extent, s.size, LasCreationDate(r), run_id, meta);
    WriteLasVlrs(file.out(), layout);
    if (auto w = WriteLasBlocks(file, s, blocks, utm, *extent, noise); !w) return w;
    return file.Close();
}

Status WriteInsTrajectoryCsv(const std::string& path,
                             const survey::NavSeries& nav,
                             const Geodetic& origin) {
    const LocalTangentFrame world(origin);
    formats::TrajectoryCsv t;
    t.ins_columns = true;
    t.rows.reserve(nav.samples.size());
    for (const auto& s : nav.samples) {
        formats::TrajectoryRow& r = t.rows.emplace_back();
        r.gps_time_s = static_cast<double>(s.utime_gps) * 1e-6;
        r.position_world_m = world.ToEnu(s.position);
        r.roll_deg = frames::RadToDeg(s.roll_rad);
        r.pitch_deg = frames::RadToDeg(s.pitch_rad);
        r.yaw_deg = frames::RadToDeg(s.yaw_rad);
        r.velocity_enu_mps = s.velocity_enu_mps;
        r.ins_status = s.ins_status;
    }
    return formats::WriteTrajectoryCsv(path, t);
}

Expected<nlohmann::json> ReadJsonFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return Error{path + ": cannot open"};
    const auto size = static_cast<std::uint64_t>(std::max<std::streamoff>(in.tellg(), 0));
    if (size > kMaxJsonFileBytes) {
        return Error{path + ": " + std::to_string(size) + " bytes, more than the " +
                     std::to_string(kMaxJsonFileBytes) + " a JSON product may have"};
    }
    in.seekg(0);
    std::string text(static_cast<std::size_t>(size), '\0');
    if (!in.read(text.data(), static_cast<std::streamsize>(size))) {
        return Error{path + ": read error"};
    }
    try {
        return nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
        return Error{path + ": not valid JSON: " + e.what()};
    }
}

namespace {

// "" if `j[key]` is a finite number, else what is wrong with it.
std::string CheckNumber(const nlohmann::json& j, const char* key, const std::string& where) {
    const auto it = j.find(key);
    if (it == j.end()) return where + "." + key + " missing";
    if (!it->is_number()) return where + "." + key + " must be a number, is " + it->type_name();
    if (!std::isfinite(it->get<double>())) return where + "." + key + " is not finite";
    return "";
}

std::string CheckSummary(const nlohmann::json& j) {
    if (!j.is_object()) return std::string("must be a JSON object, is ") + j.type_name();
    if (const auto o = j.find("world_origin"); o != j.end()) {
        if (!o->is_object()) return "world_origin must be an object";
        for (const char* k : {"latitude_deg", "longitude_deg", "height_m"}) {
            if (auto e = CheckNumber(*o, k, "world_origin"); !e.empty()) return e;
        }
        if (std::abs(o->at("latitude_deg").get<double>()) > 90.0) {
            return "world_origin.latitude_deg beyond +-90";
        }
    }
    if (const auto m = j.find("mount"); m != j.end()) {
        if (!m->is_object()) return "mount must be an object";
        for (const char* k : {"roll_deg", "pitch_deg", "yaw_deg"}) {
            if (auto e = CheckNumber(*m, k, "mount"); !e.empty()) return e;
        }
        const auto a = m->find("lever_arm_sonar_m");
        if (a == m->end() || !a->is_array() || a->size() != 3 ||
            !std::all_of(a->begin(), a->end(), [](const nlohmann::json& x) {
                return x.is_number() && std::isfinite(x.get<double>());
            })) {
            return "mount.lever_arm_sonar_m must be 3 finite numbers";
        }
    }
    if (const auto u = j.find("utm"); u != j.end() && !u->is_object()) {
        return "utm must be an object";
    }
    if (const auto st = j.find("stages"); st != j.end()) {
        if (!st->is_object()) return "stages must be an object";
        for (const auto& [name, stage] : st->items()) {
            if (!stage.is_object()) return "stages." + name + " must be an object";
        }
    }
    if (const auto so = j.find("stage_order"); so != j.end() && !so->is_array()) {
        return "stage_order must be an array";
    }
    if (const auto c = j.find("sonar_clock"); c != j.end()) {
        if (!c->is_object()) return "sonar_clock must be an object";
        for (const char* k : {"correction_s",
                              "sigma_s",
                              "latency_s",
                              "latency_formal_sd_s",
                              "rate_ppm",
                              "rate_sigma_ppm",
                              "rate_reference_gps_s",
                              "configured_offset_s",
                              "estimated_offset_s"}) {
            if (c->contains(k)) {
                if (auto e = CheckNumber(*c, k, "sonar_clock"); !e.empty()) return e;
            }
        }
    }
    if (const auto g = j.find("quality_gates"); g != j.end()) {
        if (!g->is_array()) return "quality_gates must be an array";
        for (const auto& e : *g) {
            if (!e.is_object()) return "quality_gates entries must be objects";
            for (const char* k : {"stage", "gate", "message"}) {
                const auto it = e.find(k);
                if (it == e.end() || !it->is_string())
                    return std::string("quality_gates[].") + k + " must be a string";
            }
        }
    }
    return "";
}

}  // namespace

Expected<nlohmann::json> ReadSummaryJson(const std::string& path) {
    auto j = ReadJsonFile(path);
    if (!j) return j;
    if (const std::string e = CheckSummary(*j); !e.empty()) return Error{path + ": " + e};
    return j;
}

Status WriteJsonFile(const std::string& path, const nlohmann::json& j) {
    const std::string text = j.dump(2) + "\n";
    return formats::WriteFileBytes(path, std::vector<std::uint8_t>(text.begin(), text.end()));
}

namespace {

std::int64_t CellKey(std::int64_t ix, std::int64_t iy) {
    return (ix << 32) ^ static_cast<std::int64_t>(static_cast<std::uint32_t>(iy));
}

}  // namespace

void NoiseHeights::Add(const georef::GeorefPoints& accepted) {
    for (const Eigen::Vector3d& p : accepted.position_world) {
        const std::int64_t ix = static_cast<std::int64_t>(std::floor(p.x() / cell_m));
        const std::int64_t iy = static_cast<std::int64_t>(std::floor(p.y() / cell_m));
        heights[CellKey(ix, iy)].push_back(static_cast<float>(p.z()));
    }
}

std::vector<std::uint8_t> NoiseHeights::Classes(const georef::GeorefPoints& rejected) {
    const auto cell = [this](double v) {
        return static_cast<std::int64_t>(std::floor(v / cell_m));
    };
    const auto median = [](std::vector<float>& v) {
        const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
        std::nth_element(v.begin(), mid, v.end());
        return *mid;
    };
    // The accepted heights' median per cell.
    std::unordered_map<std::int64_t, float> surface;
    surface.reserve(heights.size());
    for (auto& [key, v] : heights) {
        surface.emplace(key, median(v));
        std::vector<float>().swap(v);
    }
    heights.clear();
    std::vector<std::uint8_t> out(rejected.size());
    std::vector<float> around;
    for (std::size_t j = 0; j < rejected.size(); ++j) {
        const Eigen::Vector3d& p = rejected.position_world[j];
        const std::int64_t ix = cell(p.x()), iy = cell(p.y());
        std::optional<float> ref;
        if (const auto it = surface.find(CellKey(ix, iy)); it != surface.end()) {
            ref = it->second;
        } else {
            around.clear();
            for (std::int64_t dx = -1; dx <= 1; ++dx) {
                for (std::int64_t dy = -1; dy <= 1; ++dy) {
                    const auto n = surface.find(CellKey(ix + dx, iy + dy));
                    if (n != surface.end()) around.push_back(n->second);
                }
            }
            if (!around.empty()) ref = median(around);
        }
        const bool multipath =
            j < rejected.status.size() &&
            rejected.status[j] == static_cast<std::uint8_t>(survey::SoundingStatus::kMultipath);
        const bool below = ref ? p.z() < *ref : multipath;
        out[j] = below ? kLasClassLowNoise : kLasClassHighNoise;
    }
    return out;
}

std::vector<std::uint8_t> LasNoiseClasses(const georef::GeorefPoints& accepted,
                                          const georef::GeorefPoints& rejected,
                                          double cell_m) {
    NoiseHeights heights;
    heights.cell_m = cell_m;
    heights.Add(accepted);
    return heights.Classes(rejected);
}

std::array<std::uint8_t, 16> RunIdBytes(const std::string& run_id) {
    std::array<std::uint8_t, 16> out{};
    if (run_id.size() != 32) return out;
    for (std::size_t i = 0; i < 16; ++i) {
        unsigned v = 0;
        for (std::size_t k = 0; k < 2; ++k) {
            const char c = run_id[2 * i + k];
            const int d = c >= '0' && c <= '9'   ? c - '0'
                          : c >= 'a' && c <= 'f' ? c - 'a' + 10
                          : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                                 : -1;
            if (d < 0) return {};
            v = v * 16 + static_cast<unsigned>(d);
        }
        out[i] = static_cast<std::uint8_t>(v);
    }
    return out;
}

}  // namespace pitmap::proc::io
