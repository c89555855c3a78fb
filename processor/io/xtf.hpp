// SPDX-License-Identifier: MIT
// XTF (eXtended Triton Format) as a vendor input: the file header, the packet walk, attitude
// (header type 3), raw navigation (type 107) and the R2Sonic bathymetry that QINSy writes as
// header type 65 (R2Sonic's own big-endian BTH0 packet after a 256-byte XTF ping header).
//
// Sources: Triton Imaging, "eXtended Triton Format (XTF)", revisions X40/X41 (file header,
// CHANINFO, XTFATTITUDEDATA, XTFPOSRAWNAVIGATION, the 14-byte packet header: magic 0xFACE at
// byte 0, header type at byte 2, packet size at byte 10, little-endian); R2Sonic, "Sonic
// 2020/2022/2024/2026 data format" (BTH0: sections H0, R0, A0/A2, I1, G0/G1, Q0, each a
// 16-bit name and a 16-bit size, big-endian). Checked against QINSy 223 files of an R2Sonic
// 2026 (tests/data/xtf/).
//
// Failure model (docs/architecture.md, "bad sensor data is data"): a file that is not XTF
// (short, wrong format byte) or whose navigation is not latitude/longitude is an error naming
// the file. Inside the packet walk nothing is fatal: every length is checked against the bytes
// left; a packet whose size does not land on the next packet (a corrupted size) is skipped up
// to the next magic, a packet cut by the end of the file is skipped, unknown header types are
// skipped and counted per type, and a BTH0 packet whose sections do not add up is counted bad.
// Each such place is a warning naming the file and the byte offset (the first few per file,
// then a total). The decoder never reads outside the input and allocates at most what the
// input's own sizes allow (bounded by the input size).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/byte_io.hpp"
#include "common/result.hpp"
#include "processor/io/ingest.hpp"

namespace pitmap::proc::io {

inline constexpr std::size_t kXtfFileHeaderBytes = 1024;
inline constexpr std::uint8_t kXtfFileFormat = 123;  // byte 0 of every XTF file
inline constexpr std::uint16_t kXtfMagic = 0xFACE;
inline constexpr std::size_t kXtfPacketHeaderBytes = 14;
inline constexpr std::size_t kXtfPingHeaderBytes = 256;  // XTFPINGHEADER, incl. the 14 above
inline constexpr std::uint8_t kXtfAttitude = 3;
inline constexpr std::uint8_t kXtfQinsyR2SonicBathy = 65;
inline constexpr std::uint8_t kXtfPosRawNavigation = 107;
inline constexpr std::uint16_t kXtfNavUnitsMetres = 0;
inline constexpr std::uint16_t kXtfNavUnitsLatLon = 3;
inline constexpr std::size_t kBth0MaxPoints = 1024;  // R2Sonic's largest point count

// What the 1024-byte file header says (the fields the processor reports or needs).
struct XtfFileHeader {
    std::string recording_program;  // e.g. "QINSy"
    std::string program_version;    // e.g. "223"
    std::string sonar_name;
    std::uint16_t sonar_type = 0;  // XTF sonar type enum (53 = R2Sonic QINSy)
    std::uint16_t nav_units = 0;   // 0 = projected metres, 3 = latitude/longitude degrees
    std::uint16_t sonar_channels = 0;
    std::uint16_t bathymetry_channels = 0;
    // The first bathymetry channel's CHANINFO offsets, as written (XTF gives no reference point
    // or axes for them beyond "X athwartships, Y forward, Z down"): reported, never applied.
    float channel_offset_m[3] = {0, 0, 0};    // X, Y, Z
    float channel_offset_deg[3] = {0, 0, 0};  // yaw, pitch, roll
};

// XTFATTITUDEDATA (type 3). Time: the packet's UTC calendar fields, Unix microseconds.
struct XtfAttitude {
    std::int64_t utime_unix = 0;
    double pitch_deg = 0;    // positive bow up
    double roll_deg = 0;     // positive starboard down
    double heave_m = 0;      // positive up
    double heading_deg = 0;  // clockwise from north
};

// XTFPOSRAWNAVIGATION (type 107): a position in the file's nav units.
struct XtfPosition {
    std::int64_t utime_unix = 0;
    double y = 0;           // latitude (deg) or northing (m)
    double x = 0;           // longitude (deg) or easting (m)
    double altitude_m = 0;  // RawAltitude (datum not stated by the format)
};

// One R2Sonic BTH0 ping (type 65), in the sonar's own units.
struct XtfBathyPing {
    std::int64_t utime_unix = 0;  // H0 ping time (UTC), microseconds
    std::uint32_t ping_number = 0;
    std::string model;           // H0 model number, e.g. "2026"
    double sound_speed_mps = 0;  // H0 (the head's surface sound speed)
    double frequency_hz = 0;
    double range_setting_m = 0;              // H0 RxRange
    double tx_steering_vert_rad = 0;         // H0 TxSteeringVert (fore/aft steering of the fan)
    double rx_mount_tilt_rad = 0;            // H0 RxMountTilt
    double twtt_scale_s = 0;                 // R0 scaling: two-way travel time = count * scale
    std::vector<std::uint16_t> twtt_counts;  // R0, one per point
    std::vector<float> angle_rad;  // A0 or A2: per point, from the array's normal, + starboard
    std::vector<std::uint16_t> intensity;  // I1 raw values (empty if absent)
    double intensity_scale = 0;            // I1 scaling: micropascals = value * scale
    std::vector<std::uint8_t> quality;     // Q0 4-bit flags per point (empty if absent)
    std::uint64_t offset = 0;              // byte offset of the XTF packet in its file
};

// Q0 bits of a point (R2Sonic: 4 flag bits per point, packed from the most significant nibble
// of each big-endian 32-bit word).
inline constexpr std::uint8_t kBth0QualityBrightness = 0x1;   // passed the brightness test
inline constexpr std::uint8_t kBth0QualityColinearity = 0x2;  // passed the colinearity test
inline constexpr std::uint8_t kBth0QualityMagnitude = 0x4;    // bottom found by magnitude
inline constexpr std::uint8_t kBth0QualityPhase = 0x8;        // bottom found by phase

struct XtfCounts {
    std::int64_t bytes = 0;
    std::int64_t packets = 0;                     // packets whose header was read
    std::map<int, std::int64_t> packets_by_type;  // header type -> packets (known or not)
    std::int64_t unknown_packets = 0;             // types this reader does not decode (skipped)
    std::int64_t bad_packets = 0;                 // known types whose contents did not decode
    std::int64_t skipped_bytes = 0;               // bytes skipped to resynchronise or at a cut end
    std::int64_t resyncs = 0;                     // places where the walk lost the packet chain
    std::int64_t truncated_packets = 0;           // cut by the end of the file
};

struct XtfFile {
    XtfFileHeader header;
    std::vector<XtfAttitude> attitude;
    std::vector<XtfPosition> positions;
    std::vector<XtfBathyPing> pings;
    XtfCounts counts;
    std::vector<std::string> warnings;  // damaged places, "NAME: ... at byte offset N"
};

// True if the file is XTF: format byte 123 first, and a name ending in .xtf (any case) or the
// magic 0xFACE at byte 1024 (the first packet after a one-block header).
bool IsXtfFile(const std::string& path);

// Decodes a whole XTF file held in memory; `name` is used in messages. Errors: shorter than the
// file header, wrong format byte. Everything inside is counted (see the failure model above).
Expected<XtfFile> DecodeXtf(ByteSpan bytes, const std::string& name);

// Reads and decodes a file (an unreadable file is an error naming the path).
Expected<XtfFile> ReadXtfFile(const std::string& path);

// What the conversion assumes for what XTF does not carry: the navigation sigmas (XTF has no
// INS status or standard deviations), given as NavStdDev records at every navigation sample.
struct XtfAssumptions {
    double position_sigma_horizontal_m = 0.10;  // 1 sigma north and east
    double position_sigma_vertical_m = 0.15;    // 1 sigma up
    double roll_pitch_sigma_deg = 0.05;
    double heading_sigma_deg = 0.10;
    double max_attitude_gap_s = 1.0;  // positions between attitude samples further apart: dropped
    double attitude_hold_s = 0.1;     // before the first or after the last attitude: held this long
    // Points whose Q0 flags say the sonar's own brightness or colinearity test failed are
    // taken as no detection (counted); a point with neither detection bit is none either.
    bool drop_failed_quality = true;
};

// What a conversion took from or assumed about one decoded file.
struct XtfConversion {
    std::int64_t nav_samples = 0;
    std::int64_t nav_without_attitude = 0;  // positions with no attitude within the gap
    std::int64_t pings = 0;
    std::int64_t points = 0;
    std::int64_t points_no_detection = 0;    // R0 = 0 or no detection bit in Q0
    std::int64_t points_failed_quality = 0;  // brightness or colinearity test failed
    std::int64_t pings_steered = 0;          // non-zero TxSteeringVert (not applied)
};

// Adds a decoded file to `into` (navigation in GPS time: UTC + GPS-UTC, from `leap_seconds`
// when >= 0, else the table) through the ingest collector; appends warnings and, once per
// ingest, the assumptions (into.assumed). Error: navigation in projected metres (nav units 0),
// which pitmap cannot place without the projection.
Expected<XtfConversion> AddXtfToIngest(const XtfFile& file,
                                       const std::string& path,
                                       const XtfAssumptions& assumptions,
                                       int leap_seconds,
                                       IngestResult& into);

// Reads .xtf files into `into` (IngestFiles calls it for the files Sniff finds to be XTF).
Status IngestXtfFiles(const std::vector<std::string>& paths, int leap_seconds, IngestResult& into);

}  // namespace pitmap::proc::io
