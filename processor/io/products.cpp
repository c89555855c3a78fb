// SPDX-License-Identifier: MIT
#include "processor/io/products.hpp"

#include <sys/resource.h>
#include <sys/stat.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <type_traits>

#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/protocol/novatel/crc32.hpp"

namespace pitmap::proc::io {

namespace {

// Little-endian byte sink over a buffered file.
class LeWriter {
public:
    explicit LeWriter(const std::string& path) : path_(path), f_(std::fopen(path.c_str(), "wb")) {
        buf_.reserve(1 << 20);
    }
    ~LeWriter() {
        if (f_ != nullptr) std::fclose(f_);
    }
    bool ok() const { return f_ != nullptr && ok_; }
    void Bytes(const void* p, std::size_t n) {
        const auto* b = static_cast<const std::uint8_t*>(p);
        buf_.insert(buf_.end(), b, b + n);
        if (buf_.size() >= (1 << 20)) Drain();
    }
    template <typename T>
    void Put(T v) {
        static_assert(std::is_arithmetic_v<T>);
        using U = std::conditional_t<
            sizeof(T) == 1,
            std::uint8_t,
            std::conditional_t<sizeof(T) == 2,
                               std::uint16_t,
                               std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;
        U u;
        std::memcpy(&u, &v, sizeof(T));
        std::uint8_t b[sizeof(T)];
        for (std::size_t i = 0; i < sizeof(T); ++i) b[i] = static_cast<std::uint8_t>(u >> (8 * i));
        Bytes(b, sizeof(T));
    }
    void Text(const std::string& s) { Bytes(s.data(), s.size()); }
    void Fixed(const std::string& s, std::size_t n) {
        std::string t = s.substr(0, n);
        t.resize(n, '\0');
        Bytes(t.data(), n);
    }
    Status Close() {
        Drain();
        if (f_ == nullptr) return Error{path_ + ": cannot create"};
        const bool closed = std::fclose(f_) == 0;
        f_ = nullptr;
        if (!ok_ || !closed) return Error{path_ + ": write failed (disk full?)"};
        return Ok{};
    }

private:
    void Drain() {
        if (f_ != nullptr && !buf_.empty() &&
            std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size()) {
            ok_ = false;
        }
        buf_.clear();
    }
    std::string path_;
    std::FILE* f_;
    bool ok_ = true;
    std::vector<std::uint8_t> buf_;
};

std::string Fmt(const char* fmt, double a, double b, double c) {
    char s[160];
    std::snprintf(s, sizeof(s), fmt, a, b, c);
    return s;
}

bool ReadVec3(const YAML::Node& n, Eigen::Vector3d& v) {
    if (!n || !n.IsSequence() || n.size() != 3) return false;
    try {
        for (int i = 0; i < 3; ++i) v[i] = n[i].as<double>();
    } catch (const YAML::Exception&) {
        return false;
    }
    return true;
}

}  // namespace

Expected<VehicleConfig> ReadVehicleYaml(const std::string& path) {
    YAML::Node root;
    try {
        root = YAML::LoadFile(path);
    } catch (const YAML::BadFile&) {
        return Error{path + ": cannot open"};
    } catch (const YAML::Exception& e) {
        return Error{path + ": " + e.what()};
    }
    if (!root.IsMap()) return Error{path + ": not a YAML map"};
    if (root["vehicle"] && root["vehicle"].IsMap()) root = root["vehicle"];
    VehicleConfig v;
    try {
        if (root["name"]) v.name = root["name"].as<std::string>();
        if (root["vehicle"] && root["vehicle"].IsScalar())
            v.name = root["vehicle"].as<std::string>();
        const YAML::Node arms = root["lever_arms_m"];
        if (!(arms && (ReadVec3(arms["sonar"], v.mount.lever_arm_m) ||
                       ReadVec3(arms["imu_to_sonar"], v.mount.lever_arm_m)))) {
            v.missing.push_back("lever_arms_m.sonar (or lever_arms_m.imu_to_sonar) [x, y, z]");
        }
        Eigen::Vector3d b;
        if (ReadVec3(root["boresight_deg"], b)) {
            v.mount.boresight_roll_deg = b[0];
            v.mount.boresight_pitch_deg = b[1];
            v.mount.boresight_yaw_deg = b[2];
        } else if (const YAML::Node bs = root["boresight_sonar_deg"]; bs && bs.IsMap()) {
            v.mount.boresight_roll_deg = bs["roll"] ? bs["roll"].as<double>() : 0.0;
            v.mount.boresight_pitch_deg = bs["pitch"] ? bs["pitch"].as<double>() : 0.0;
            v.mount.boresight_yaw_deg = bs["yaw"] ? bs["yaw"].as<double>() : 0.0;
        } else {
            v.missing.push_back(
                "boresight_deg [roll, pitch, yaw] (or boresight_sonar_deg {roll, pitch, yaw})");
        }
        if (root["navigation_channel"])
            v.navigation_channel = root["navigation_channel"].as<std::string>();
        if (root["sonar_channel"]) v.sonar_channel = root["sonar_channel"].as<std::string>();
    } catch (const YAML::Exception& e) {
        return Error{path + ": " + e.what()};
    }
    return v;
}

Status WritePly(const std::string& path, const georef::GeorefResult& r) {
    LeWriter w(path);
    const georef::GeorefPoints& P = r.points;
    w.Text("ply\nformat binary_little_endian 1.0\n");
    w.Text("comment generated by pitmap georef\n");
    w.Text(Fmt("comment pitmap_origin %.10f %.10f %.4f\n",
               r.world_origin.latitude_deg,
               r.world_origin.longitude_deg,
               r.world_origin.height_m));
    w.Text(
        "comment frame world: East-North-Up metres at pitmap_origin; gps_time_s since "
        "1980-01-06\n");
    w.Text("element vertex " + std::to_string(P.size()) + "\n");
    w.Text(
        "property float x\nproperty float y\nproperty float z\nproperty double gps_time_s\n"
        "property float range_m\nproperty uint ping\nproperty ushort beam\nend_header\n");
    for (std::size_t j = 0; j < P.size(); ++j) {
        const Eigen::Vector3d& p = P.position_world[j];
        w.Put(static_cast<float>(p.x()));
        w.Put(static_cast<float>(p.y()));
        w.Put(static_cast<float>(p.z()));
        w.Put(static_cast<double>(r.pings[P.ping[j]].utime_gps) * 1e-6);
        w.Put(P.range_m[j]);
        w.Put(P.ping[j]);
        w.Put(P.beam[j]);
    }
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

std::string LasWkt(int zone, bool northern) {
    return "COMPD_CS[\"WGS 84 / UTM zone " + std::to_string(zone) + (northern ? "N" : "S") +
           " + WGS 84 ellipsoidal height\"," + UtmWkt(zone, northern) +
           ",VERT_CS[\"WGS 84 ellipsoidal height\",VERT_DATUM[\"World Geodetic System 1984\","
           "2002],UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Ellipsoidal height\","
           "UP]]]";
}

Status WriteLas(const std::string& path,
                const georef::GeorefResult& r,
                const georef::UtmPoints& utm) {
    const auto& E = utm.easting_northing_height;
    const std::size_t n = E.size();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
    Eigen::Vector3d hi = -lo;
    for (const auto& p : E) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    if (n == 0) lo = hi = Eigen::Vector3d::Zero();
    const double scale = 0.001;
    const Eigen::Vector3d offset(std::floor(lo.x()), std::floor(lo.y()), std::floor(lo.z()));
    const std::string wkt = LasWkt(utm.zone, utm.northern) + std::string(1, '\0');
    constexpr std::uint16_t kHeaderSize = 375;
    constexpr std::uint16_t kVlrHeaderSize = 54;
    constexpr std::uint16_t kRecordLength = 30;
    const std::uint32_t point_offset =
        kHeaderSize + kVlrHeaderSize + static_cast<std::uint32_t>(wkt.size());
    // File creation date: the survey's first ping, so the file depends only on the data.
    int day_of_year = 1, year = 1980;
    if (!r.pings.empty()) {
        const UtcCalendar c = UtcCalendarFromUnix(UnixFromGps(r.pings.front().utime_gps));
        const auto jan1 = UnixFromUtcCalendar({c.year, 1, 1, 0, 0, 0, 0});
        const auto today = UnixFromUtcCalendar({c.year, c.month, c.day, 0, 0, 0, 0});
        if (jan1 && today) day_of_year = static_cast<int>((*today - *jan1) / 86'400'000'000LL) + 1;
        year = c.year;
    }

    LeWriter w(path);
    // Public header block (LAS 1.4 R15 Table 3).
    w.Text("LASF");
    w.Put<std::uint16_t>(0);                      // file source id
    w.Put<std::uint16_t>((1u << 0) | (1u << 4));  // adjusted standard GPS time, WKT CRS
    w.Put<std::uint32_t>(0);                      // GUID 1..4
    w.Put<std::uint16_t>(0);
    w.Put<std::uint16_t>(0);
    w.Fixed("", 8);
    w.Put<std::uint8_t>(1);  // version 1.4
    w.Put<std::uint8_t>(4);
    w.Fixed("pitmap ASV multibeam", 32);
    w.Fixed("pitmap georef", 32);
    w.Put<std::uint16_t>(static_cast<std::uint16_t>(day_of_year));
    w.Put<std::uint16_t>(static_cast<std::uint16_t>(year));
    w.Put<std::uint16_t>(kHeaderSize);
    w.Put<std::uint32_t>(point_offset);
    w.Put<std::uint32_t>(1);  // number of VLRs
    w.Put<std::uint8_t>(6);   // point data record format
    w.Put<std::uint16_t>(kRecordLength);
    w.Put<std::uint32_t>(0);  // legacy point count: 0 for formats 6-10
    for (int i = 0; i < 5; ++i) w.Put<std::uint32_t>(0);
    w.Put(scale);
    w.Put(scale);
    w.Put(scale);
    w.Put(offset.x());
    w.Put(offset.y());
    w.Put(offset.z());
    w.Put(hi.x());
    w.Put(lo.x());
    w.Put(hi.y());
    w.Put(lo.y());
    w.Put(hi.z());
    w.Put(lo.z());
    w.Put<std::uint64_t>(0);  // start of waveform data
    w.Put<std::uint64_t>(0);  // start of first EVLR
    w.Put<std::uint32_t>(0);  // number of EVLRs
    w.Put<std::uint64_t>(n);  // number of point records
    w.Put<std::uint64_t>(n);  // points by return: all single returns
    for (int i = 1; i < 15; ++i) w.Put<std::uint64_t>(0);
    // VLR: OGC coordinate system WKT (record id 2112).
    w.Put<std::uint16_t>(0);
    w.Fixed("LASF_Projection", 16);
    w.Put<std::uint16_t>(2112);
    w.Put<std::uint16_t>(static_cast<std::uint16_t>(wkt.size()));
    w.Fixed("OGC WKT, ellipsoidal heights", 32);
    w.Bytes(wkt.data(), wkt.size());
    // Point records, format 6.
    const georef::GeorefPoints& P = r.points;
    for (std::size_t j = 0; j < n; ++j) {
        for (int a = 0; a < 3; ++a) {
            w.Put(static_cast<std::int32_t>(std::llround((E[j][a] - offset[a]) / scale)));
        }
        w.Put<std::uint16_t>(0);            // intensity
        w.Put<std::uint8_t>(1 | (1 << 4));  // return 1 of 1
        w.Put<std::uint8_t>(0);             // flags, channel, scan direction, edge
        w.Put<std::uint8_t>(1);             // classification: unclassified
        w.Put<std::uint8_t>(0);             // user data
        const double angle_deg = frames::RadToDeg(P.angle_rad[j]);
        w.Put(static_cast<std::int16_t>(std::lround(std::clamp(angle_deg, -180.0, 180.0) / 0.006)));
        w.Put<std::uint16_t>(0);  // point source id
        w.Put(static_cast<double>(r.pings[P.ping[j]].utime_gps) * 1e-6 - 1e9);
    }
    return w.Close();
}

Status WriteTrajectoryCsv(const std::string& path,
                          const georef::NavSeries& nav,
                          const Geodetic& origin) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) return Error{path + ": cannot create"};
    const LocalTangentFrame world(origin);
    std::fprintf(f,
                 "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg,vel_e_mps,vel_n_mps,vel_u_mps,"
                 "ins_status\n");
    for (const auto& s : nav.samples) {
        const Eigen::Vector3d p = world.ToEnu(s.position);
        std::fprintf(f,
                     "%.6f,%.4f,%.4f,%.4f,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%d\n",
                     static_cast<double>(s.utime_gps) * 1e-6,
                     p.x(),
                     p.y(),
                     p.z(),
                     frames::RadToDeg(s.roll_rad),
                     frames::RadToDeg(s.pitch_rad),
                     frames::RadToDeg(s.yaw_rad),
                     s.velocity_enu_mps.x(),
                     s.velocity_enu_mps.y(),
                     s.velocity_enu_mps.z(),
                     s.ins_status);
    }
    const bool ok = std::ferror(f) == 0;
    if (std::fclose(f) != 0 || !ok) return Error{path + ": write failed"};
    return Ok{};
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
    std::ofstream out(path);
    if (!out) return Error{path + ": cannot create"};
    out << j.dump(2) << "\n";
    if (!out) return Error{path + ": write failed"};
    return Ok{};
}

namespace {
// Ingest cache layout (native byte order and struct layout; read only by the build that wrote
// it): u32 magic "PMIC", u32 version, u32 byte order (1 little, 2 big), i32 leap seconds, u32
// ping clock (georef::PingClock), then
// four arrays (nav samples, nav stddevs, ping headers, range counts), each as u64 count, u64
// element size, count * size bytes; then a u32 CRC-32 (common/protocol/novatel/crc32) of every
// byte before it. Version 1 had no CRC; version 2 no ping clock and no header aids.
constexpr std::uint32_t kCacheMagic = 0x43494D50;  // "PMIC"
constexpr std::uint32_t kCacheVersion = 3;

struct DiskNav {
    std::int64_t utime_gps;
    double v[12];
    std::int32_t ins_status, position_type;
};
DiskNav ToDisk(const georef::NavSample& s) {
    return {s.utime_gps,
            {s.position.latitude_deg,
             s.position.longitude_deg,
             s.position.height_m,
             s.roll_rad,
             s.pitch_rad,
             s.yaw_rad,
             s.velocity_enu_mps.x(),
             s.velocity_enu_mps.y(),
             s.velocity_enu_mps.z(),
             0,
             0,
             0},
            s.ins_status,
            s.position_type};
}
georef::NavSample FromDisk(const DiskNav& d) {
    georef::NavSample s;
    s.utime_gps = d.utime_gps;
    s.position = {d.v[0], d.v[1], d.v[2]};
    s.roll_rad = d.v[3];
    s.pitch_rad = d.v[4];
    s.yaw_rad = d.v[5];
    s.velocity_enu_mps = Eigen::Vector3d(d.v[6], d.v[7], d.v[8]);
    s.ins_status = d.ins_status;
    s.position_type = d.position_type;
    return s;
}

// Writes through a FILE and keeps the CRC-32 of everything written.
class CacheWriter {
public:
    explicit CacheWriter(std::FILE* f) : f_(f) {}
    void Bytes(const void* p, std::size_t n) {
        if (n == 0) return;
        if (std::fwrite(p, 1, n, f_) != n) ok_ = false;
        crc_ = protocol::novatel::Crc32({static_cast<const std::uint8_t*>(p), n}, crc_);
    }
    template <typename T>
    void Vec(const std::vector<T>& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        const std::uint64_t n = v.size();
        const std::uint64_t sz = sizeof(T);
        Bytes(&n, sizeof n);
        Bytes(&sz, sizeof sz);
        Bytes(v.data(), v.size() * sizeof(T));
    }
    void Finish() {
        const std::uint32_t crc = crc_;
        if (std::fwrite(&crc, sizeof crc, 1, f_) != 1) ok_ = false;
    }
    bool ok() const { return ok_; }

private:
    std::FILE* f_;
    std::uint32_t crc_ = 0;
    bool ok_ = true;
};

// Reads a cache file of known size: never reads past `size` minus the CRC trailer and never
// allocates more than the bytes that remain, so memory stays bounded by the file size whatever
// the counts say. The first problem found is kept in `error` (without the path).
class CacheReader {
public:
    CacheReader(std::FILE* f, std::uint64_t size) : f_(f), size_(size) {}
    bool Bytes(void* p, std::size_t n, const char* what) {
        if (!error.empty()) return false;
        if (n > Remaining()) return Fail(std::string("truncated in ") + what);
        if (n > 0 && std::fread(p, 1, n, f_) != n)
            return Fail(std::string("read error in ") + what);
        crc_ = protocol::novatel::Crc32({static_cast<const std::uint8_t*>(p), n}, crc_);
        pos_ += n;
        return true;
    }
    template <typename T>
    bool Vec(std::vector<T>& v, const char* what) {
        static_assert(std::is_trivially_copyable_v<T>);
        std::uint64_t n = 0, sz = 0;
        if (!Bytes(&n, sizeof n, what) || !Bytes(&sz, sizeof sz, what)) return false;
        if (sz != sizeof(T)) {
            return Fail(std::string(what) + ": element size " + std::to_string(sz) + ", expected " +
                        std::to_string(sizeof(T)));
        }
        if (n > Remaining() / sizeof(T)) {
            return Fail(std::string(what) + ": count " + std::to_string(n) + " needs " +
                        std::to_string(n) + " x " + std::to_string(sizeof(T)) + " bytes but only " +
                        std::to_string(Remaining()) + " remain");
        }
        v.resize(n);
        return Bytes(v.data(), n * sizeof(T), what);
    }
    // At the trailer: every byte consumed and the CRC matches.
    bool Finish() {
        if (!error.empty()) return false;
        if (Remaining() != 0) {
            return Fail(std::to_string(Remaining()) + " unexpected bytes before the checksum");
        }
        std::uint32_t stored = 0;
        if (std::fread(&stored, sizeof stored, 1, f_) != 1) return Fail("read error in checksum");
        if (stored != crc_) return Fail("checksum mismatch (file corrupted)");
        return true;
    }
    std::string error;

private:
    std::uint64_t Remaining() const { return size_ - 4 - pos_; }  // size_ >= 4 checked by caller
    bool Fail(std::string message) {
        if (error.empty()) error = std::move(message);
        return false;
    }
    std::FILE* f_;
    std::uint64_t size_;
    std::uint64_t pos_ = 0;
    std::uint32_t crc_ = 0;
};

std::uint64_t FileSize(std::FILE* f) {
    struct stat st {};
    if (fstat(fileno(f), &st) != 0 || st.st_size < 0) return 0;
    return static_cast<std::uint64_t>(st.st_size);
}

}  // namespace

Status WriteIngestCache(const std::string& path, const IngestResult& r) {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) return Error{path + ": cannot create"};
    CacheWriter w(f);
    const std::uint32_t head[3] = {
        kCacheMagic, kCacheVersion, std::endian::native == std::endian::little ? 1u : 2u};
    w.Bytes(head, sizeof head);
    const std::int32_t leap = r.nav.leap_seconds;
    w.Bytes(&leap, sizeof leap);
    const auto clock = static_cast<std::uint32_t>(r.pings.clock);
    w.Bytes(&clock, sizeof clock);
    std::vector<DiskNav> nav(r.nav.samples.size());
    for (std::size_t i = 0; i < nav.size(); ++i) nav[i] = ToDisk(r.nav.samples[i]);
    w.Vec(nav);
    w.Vec(r.nav.stddevs);
    w.Vec(r.pings.pings);
    w.Vec(r.pings.range_counts);
    w.Finish();
    const bool ok = w.ok() && std::ferror(f) == 0;
    if (std::fclose(f) != 0 || !ok) return Error{path + ": write failed"};
    return Ok{};
}

Expected<IngestResult> ReadIngestCache(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (f == nullptr) return Error{path + ": cannot open (run `pitmap georef` first)"};
    const std::uint64_t size = FileSize(f);
    const std::string rerun = " (run `pitmap georef` again)";
    constexpr std::uint64_t kHeadBytes = 3 * 4 + 4 + 4;
    if (size < kHeadBytes + 4) {
        std::fclose(f);
        return Error{path + ": not a pitmap ingest cache (" + std::to_string(size) + " bytes)" +
                     rerun};
    }
    CacheReader in(f, size);
    IngestResult r;
    std::uint32_t head[3] = {0, 0, 0};
    std::int32_t leap = -1;
    std::vector<DiskNav> nav;
    in.Bytes(head, sizeof head, "header");
    if (in.error.empty() && head[0] != kCacheMagic) {
        std::fclose(f);
        return Error{path + ": not a pitmap ingest cache (bad magic)" + rerun};
    }
    if (in.error.empty() && (head[1] != kCacheVersion ||
                             head[2] != (std::endian::native == std::endian::little ? 1u : 2u))) {
        std::fclose(f);
        return Error{path + ": ingest cache version " + std::to_string(head[1]) +
                     " or byte order not of this build" + rerun};
    }
    in.Bytes(&leap, sizeof leap, "header");
    std::uint32_t clock = 0;
    in.Bytes(&clock, sizeof clock, "header");
    if (in.error.empty() && clock > static_cast<std::uint32_t>(georef::PingClock::kTopsideHeader)) {
        std::fclose(f);
        return Error{path + ": corrupt ingest cache: ping clock " + std::to_string(clock) + rerun};
    }
    r.pings.clock = static_cast<georef::PingClock>(clock);
    in.Vec(nav, "nav samples");
    in.Vec(r.nav.stddevs, "nav stddevs");
    in.Vec(r.pings.pings, "pings");
    in.Vec(r.pings.range_counts, "range counts");
    in.Finish();
    std::fclose(f);
    if (!in.error.empty()) return Error{path + ": corrupt ingest cache: " + in.error + rerun};
    for (auto& p : r.pings.pings) {
        // A bool read from bytes must hold 0 or 1 (the CRC does not stop crafted files).
        auto* flag =
            reinterpret_cast<unsigned char*>(&p) + offsetof(georef::PingHeader, sound_speed_valid);
        *flag = *flag != 0 ? 1 : 0;
        if (static_cast<std::uint64_t>(p.beam_offset) + p.num_beams > r.pings.range_counts.size()) {
            return Error{path + ": corrupt ingest cache: inconsistent beam offsets" + rerun};
        }
    }
    r.nav.leap_seconds = leap;
    r.nav.samples.resize(nav.size());
    for (std::size_t i = 0; i < nav.size(); ++i) r.nav.samples[i] = FromDisk(nav[i]);
    r.counts.nav_samples = static_cast<std::int64_t>(r.nav.samples.size());
    r.counts.pings = static_cast<std::int64_t>(r.pings.pings.size());
    return r;
}

double PeakRssMb() {
    struct rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) / 1024.0;
}

}  // namespace pitmap::proc::io
