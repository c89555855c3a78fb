// SPDX-License-Identifier: MIT
// Products folder I/O: vehicle.yaml, point clouds (binary PLY, LAS 1.4), trajectory CSV, JSON
// summaries. The state the stages share is the survey model's file (processor/survey).
//
// PLY (written with common/formats/ply): binary_little_endian 1.0, vertex properties float x, y, z
// (world ENU metres), double
//   gps_time_s (GPS seconds since 1980-01-06), float range_m, uint ping, ushort beam, then the
//   extras (PointExtras) and last uchar status (survey::SoundingStatus: 0 accepted, else the
//   reason the sounding was rejected; a header comment lists the codes' names); a header
//   comment "pitmap_origin LAT LON H" (degrees, degrees, ellipsoidal metres) names the origin.
// LAS 1.4 (ASPRS LAS 1.4 R15): header 375 bytes, point data record format 6 (30 bytes), UTM
//   coordinates with scale 0.001 m, GPS time as Adjusted Standard GPS time (GPS s - 1e9,
//   global encoding bit 0), CRS as an OGC WKT VLR (LASF_Projection / 2112, global encoding
//   bit 4): a COMPD_CS of the UTM PROJCS and the heights' VERT_CS: "WGS 84 ellipsoidal height"
//   (OGC 01-009 vertical datum type 2002) as georef writes it, the vertical datum's (geoid,
//   water level; hydro/datum.hpp) when the grid stage writes the file again (PointExtras).
//   Classification: accepted soundings class 40 (bathymetric point, "submerged topography":
//   the ASPRS topo-bathy lidar domain profile's class, in R15's range reserved for ASPRS
//   definitions), rejected ones 7 (low noise) or 18 (high noise) (R15 Table 17; the rule is
//   LasNoiseClasses') with the withheld flag (classification flags bit 2) set. Intensity: the
//   sounding's 83P intensity as recorded (SoundingIntensity), 0 where the pings have none.
// Rejected soundings (issue 35): both files hold, after the accepted soundings in their order,
// the rejected soundings of the same survey that have a position (a georeference in the view
// survey::SoundingView::kRejected: every status but no detection and refraction) when the
// writer is given them; a reader that wants the surface keeps status 0 (PLY) or drops the
// withheld points (LAS). THU, TVU of a rejected sounding are NaN (the grid stage computes them
// for the accepted soundings only).
// Run id (processor/survey/survey.hpp): when given, PLY has a comment "pitmap_run_id ID" and LAS
// the id's 16 bytes as its Project ID (GUID) (RunIdBytes).
// Every file is written under a temporary name and renamed into place
// (common/formats/replace_file.hpp): a reader never sees half a file.
// Failure model: every function returns an error naming the file and the system's reason.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/product_metadata.hpp"
#include "common/result.hpp"
#include "common/vehicle.hpp"
#include "processor/georef/georef.hpp"
#include "processor/io/ingest.hpp"

namespace pitmap::proc::io {

// What vehicle.yaml says (common/vehicle.hpp: the one schema, `pitmap_vehicle: 1`), with the
// sonar mount as the georeferencing uses it: `mount` holds the lever arm and the whole
// R_vehicle_sonar = R_boresight * R_mount as roll, pitch, yaw. A file that is not a pitmap
// vehicle file, lacks a required key (sonar.lever_arm_m, sonar.mount.orientation,
// sonar.mount.connector) or has any other problem is an error listing every problem.
struct VehicleConfig {
    VehicleDescription description;
    survey::SonarMount mount;
};
Expected<VehicleConfig> ReadVehicleYaml(const std::string& path);
// Which vehicle file a command reads: `explicit_path` (--vehicle, the config's vehicle_yaml)
// when given, else vehicle.yaml beside the first of `files` (the logs, as pitmap-sim and the
// daemon write them) when it exists, else "". `pitmap run`, `pitmap georef` and `pitmap live`
// all decide it here.
std::string VehicleFilePath(const std::vector<std::string>& files,
                            const std::string& explicit_path);
// summary.json's record of the vehicle file.
nlohmann::json VehicleJson(const VehicleDescription& v);

// What the grid stage adds to the point files (issue 17): per-sounding uncertainty and the
// vertical datum. Empty vectors are not written.
struct PointExtras {
    std::vector<float> thu_95_m;         // one per sounding: THU, 95 %, m
    std::vector<float> tvu_95_m;         // one per sounding: TVU, 95 %, m
    std::vector<double> datum_height_m;  // one per ping: the datum's ellipsoidal height D, m
    std::string vertical_wkt;            // the datum's VERT_CS (WKT1); "" = WGS 84 ellipsoidal
    std::string vertical_name;           // its name, for the PLY comment
    // The pings the soundings came from (GeorefPing::header_index into it), for the 83P
    // intensity of each sounding: LAS intensity and PLY ushort intensity (SoundingIntensity).
    // Not written when null or when the pings carry no intensities.
    const survey::PingSeries* pings = nullptr;
};

// The 83P intensity of sounding i of `g`: PingSeries::intensities of its ping's beam, as
// recorded (u16 "normalized amplitude", no physical unit; the LAS intensity's 16 bits need no
// scaling); 0 (none) when the pings carry no intensities or the beam is outside its ping.
std::uint16_t SoundingIntensity(const georef::GeorefResult& g,
                                std::size_t i,
                                const survey::PingSeries& pings);
// The names of the LAS extra bytes of THU and TVU: PDAL keeps a dimension name that starts with
// a letter and holds only letters, digits and '_' (others it replaces by '_').
inline constexpr const char* kLasThuName = "thu_95_m";
inline constexpr const char* kLasTvuName = "tvu_95_m";

// With extras, PLY adds ushort intensity (with extras->pings carrying intensities, after beam:
// SoundingIntensity), float thu_95_m, tvu_95_m (when given) and, with datum heights, float
// depth_m (D - h: below the datum, m) and a comment "pitmap_vertical_datum NAME"; x, y, z stay
// world ENU (ellipsoidal). `rejected` (optional): the kRejected view of the same survey
// (GeorefPoints::status filled, its pings those of `result`, as georef::Georeference gives both),
// written after the accepted soundings with their status; without it every status is 0.
Status WritePly(const std::string& path,
                const georef::GeorefResult& result,
                const PointExtras* extras = nullptr,
                const std::string& run_id = "",
                const georef::GeorefResult* rejected = nullptr);
// The accepted soundings given a block at a time (decision 035: a writer need not hold them
// all): for_each(fn) calls fn(block, first) for the soundings first, first + 1, ... in order,
// `block` the survey (its pings and origin: the writer's `result`) holding them as its points,
// until `count` are given; it returns fn's first error. WholePoints: `r`'s, one block.
struct PointBlocks {
    std::size_t count = 0;
    std::function<Status(const std::function<Status(const georef::GeorefResult&, std::size_t)>&)>
        for_each;
};
PointBlocks WholePoints(const georef::GeorefResult& r);
// WritePly with the accepted soundings given by `accepted` (their pings and origin those of
// `result`, whose points are not read): the same file byte for byte, whatever the blocks.
Status WritePly(const std::string& path,
                const georef::GeorefResult& result,
                const PointBlocks& accepted,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected);
// With extras, LAS heights are h - D (above the datum; the WKT's VERT_CS names it) and THU/TVU
// are LAS 1.4 extra bytes (two float32 after the format-6 fields, record length 38), described
// in an Extra Bytes VLR (LASF_Spec / 4: names kLasThuName and kLasTvuName, metres); with
// extras->pings, the intensity of each record is SoundingIntensity (else 0). `rejected` as
// WritePly's (its UTM positions in `utm`'s zone), classified by LasNoiseClasses and withheld.
// `meta` (optional, common/product_metadata.hpp): the header's System Identifier is the vessel
// and its multibeam, Generating Software the software's name and version, and a VLR (user id
// "pitmap", record id 1) holds the metadata as JSON (ProductMetadataJson). The file creation
// day is always the survey's first ping's (UTC).
Status WriteLas(const std::string& path,
                const georef::GeorefResult& result,
                const georef::UtmPoints& utm,
                const PointExtras* extras = nullptr,
                const std::string& run_id = "",
                const georef::GeorefResult* rejected = nullptr,
                const ProductMetadata* meta = nullptr);
// The same with the accepted soundings placed one at a time by `utm` (georef::UtmProjectionOf
// of `result`), the file byte for byte the one of ToUtm's points, without their 24 bytes a
// sounding (the rejected soundings are always placed so). A projection of other pings is an
// error.
Status WriteLas(const std::string& path,
                const georef::GeorefResult& result,
                const georef::UtmProjection& utm,
                const PointExtras* extras = nullptr,
                const std::string& run_id = "",
                const georef::GeorefResult* rejected = nullptr,
                const ProductMetadata* meta = nullptr);
// The same with the accepted soundings given by `accepted` (their pings those of `result`, whose
// points are not read; two passes: the extent and the noise classes' surface, then the
// records): the same file byte for byte, whatever the blocks (decision 035).
Status WriteLas(const std::string& path,
                const georef::GeorefResult& result,
                const PointBlocks& accepted,
                const georef::UtmProjection& utm,
                const PointExtras* extras,
                const std::string& run_id,
                const georef::GeorefResult* rejected,
                const ProductMetadata* meta);
// The LAS metadata VLR's ids.
inline constexpr const char* kLasMetadataUserId = "pitmap";
inline constexpr std::uint16_t kLasMetadataRecordId = 1;

// LAS classes of the point records (ASPRS LAS 1.4 R15 Table 17; 40: topo-bathy domain profile).
inline constexpr std::uint8_t kLasClassBathymetry = 40;    // accepted sounding
inline constexpr std::uint8_t kLasClassLowNoise = 7;       // rejected, below the surface
inline constexpr std::uint8_t kLasClassHighNoise = 18;     // rejected, above the surface
inline constexpr std::uint8_t kLasFlagWithheld = 1u << 2;  // classification flags, format 6
// The LAS class of each rejected sounding: 7 (low noise) when it lies below the accepted
// surface there, else 18 (high noise). The surface: the median height (world z) of the
// accepted soundings in the rejected sounding's horizontal cell of cell_m (a grid from the
// world origin); in a cell without any, the median of the medians of its eight neighbours
// that have them; where none of those nine has an accepted sounding, by the reason: multipath
// (an echo from behind a surface) 7, every other reason 18 (fish, bubbles and spikes are
// mostly in the water above the floor).
std::vector<std::uint8_t> LasNoiseClasses(const georef::GeorefPoints& accepted,
                                          const georef::GeorefPoints& rejected,
                                          double cell_m = 2.0);
// LasNoiseClasses with the accepted soundings added a block at a time, in order (Add), then the
// classes (Classes, once): the same classes.
struct NoiseHeights {
    double cell_m = 2.0;
    std::unordered_map<std::int64_t, std::vector<float>> heights;  // the accepted z per cell
    void Add(const georef::GeorefPoints& accepted);
    std::vector<std::uint8_t> Classes(const georef::GeorefPoints& rejected);
};
// The 16 bytes of a 32-hex-digit run id, in the order of its digits; zeros for anything else.
std::array<std::uint8_t, 16> RunIdBytes(const std::string& run_id);
// OGC WKT (WKT1) of WGS 84 / UTM zone.
std::string UtmWkt(int zone, bool northern);
// The LAS file's CRS: COMPD_CS[UtmWkt, vertical], WKT1; vertical_wkt "" = VERT_CS WGS 84
// ellipsoidal height.
std::string LasWkt(int zone, bool northern, const std::string& vertical_wkt = "");

// trajectory_ins.csv: the INS solution at its own rate in the trajectory CSV format
// (common/formats/trajectory_csv.hpp) with the INS columns, world ENU at `origin`.
Status WriteInsTrajectoryCsv(const std::string& path,
                             const survey::NavSeries& nav,
                             const Geodetic& origin);

// Reads a JSON file of at most kMaxJsonFileBytes. Errors name the file and, for a syntax error,
// the line and column.
inline constexpr std::uint64_t kMaxJsonFileBytes = 64ull << 20;
Expected<nlohmann::json> ReadJsonFile(const std::string& path);
// summary.json of a products folder: ReadJsonFile, then the keys the stages read, where
// present, must have their types (an object at the top; world_origin {latitude_deg,
// longitude_deg, height_m} finite numbers with |latitude| <= 90; mount {roll_deg, pitch_deg,
// yaw_deg, lever_arm_sonar_m [3]} finite numbers; utm and every entry of stages objects;
// stage_order an array; sonar_clock an object whose *_s members are finite numbers;
// quality_gates an array of {stage, gate, message} strings), or the read fails naming the file
// and the key.
Expected<nlohmann::json> ReadSummaryJson(const std::string& path);
Status WriteJsonFile(const std::string& path, const nlohmann::json& j);

}  // namespace pitmap::proc::io
