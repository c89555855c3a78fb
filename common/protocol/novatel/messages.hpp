// SPDX-License-Identifier: MIT
// Decoded NovAtel OEM messages as plain structs (shared/specs/novatel_oem.md §2, §3, §5, §6;
// OEM7 firmware 7.x, also OEM6/OEMV layouts where identical).
//
// Units are SI and named in the field: metres, m/s, seconds, radians for IMU increments.
// Latitude/longitude and attitude angles stay in degrees, as the receiver reports them.
// Enumerations are `enum class` over the wire type: a value the tables do not know is kept as
// its raw integer (ToString() returns ""), never rejected. Reserved fields are kept so encoding
// a decoded message reproduces its body.
//
// Times: `utime_gps()` is the time of validity in GPS microseconds since 1980-01-06
// (common/gps_time.hpp), 0 when unknown. It is the body time for INS/IMU logs that carry one
// (§3, §8), the header time minus latency for BESTVEL, else the header time.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/protocol/novatel/framer.hpp"

namespace pitmap::protocol::novatel {

// ---- Message ids (§6.15) ----
namespace msg_id {
inline constexpr std::uint16_t kLog = 1;
inline constexpr std::uint16_t kRxStatus = 93;
inline constexpr std::uint16_t kBestPos = 42;
inline constexpr std::uint16_t kBestVel = 99;
inline constexpr std::uint16_t kTime = 101;
inline constexpr std::uint16_t kMarkTime = 231;
inline constexpr std::uint16_t kInsAtt = 263;
inline constexpr std::uint16_t kRawImu = 268;
inline constexpr std::uint16_t kInsAttS = 319;
inline constexpr std::uint16_t kRawImuS = 325;
inline constexpr std::uint16_t kInsPva = 507;
inline constexpr std::uint16_t kInsPvaS = 508;
inline constexpr std::uint16_t kMark2Time = 616;
inline constexpr std::uint16_t kCorrImuData = 812;
inline constexpr std::uint16_t kCorrImuDataS = 813;
inline constexpr std::uint16_t kMark1Time = 1130;
inline constexpr std::uint16_t kHeading2 = 1335;
inline constexpr std::uint16_t kImuRateCorrImuS = 1362;
inline constexpr std::uint16_t kBestGnssPos = 1429;
inline constexpr std::uint16_t kBestGnssVel = 1430;
inline constexpr std::uint16_t kInsAttX = 1457;
inline constexpr std::uint16_t kRawImuX = 1461;
inline constexpr std::uint16_t kRawImuSX = 1462;
inline constexpr std::uint16_t kInsPvaX = 1465;
inline constexpr std::uint16_t kInsConfig = 1945;
inline constexpr std::uint16_t kDualAntennaHeading = 2042;
inline constexpr std::uint16_t kInsStdDev = 2051;
inline constexpr std::uint16_t kCorrImuS = 2264;
}  // namespace msg_id

// ---- Enumerations (§2.1, §6.10) ----
enum class TimeStatus : std::uint8_t {
    kUnknown = 20,
    kApproximate = 60,
    kCoarseAdjusting = 80,
    kCoarse = 100,
    kCoarseSteering = 120,
    kFreewheeling = 130,
    kFineAdjusting = 140,
    kFine = 160,
    kFineBackupSteering = 170,
    kFineSteering = 180,
    kSatTime = 200,
    kExtern = 220,
    kExact = 240,
};

enum class SolutionStatus : std::uint32_t {
    kSolComputed = 0,
    kInsufficientObs = 1,
    kNoConvergence = 2,
    kSingularity = 3,
    kCovTrace = 4,
    kTestDist = 5,
    kColdStart = 6,
    kVHLimit = 7,
    kVariance = 8,
    kResiduals = 9,
    kDeltaPos = 10,
    kNegativeVar = 11,
    kIntegrityWarning = 13,
    kInsInactive = 14,
    kInsAligning = 15,
    kInsBad = 16,
    kImuUnplugged = 17,
    kPending = 18,
    kInvalidFix = 19,
    kUnauthorized = 20,
    kInvalidRate = 22,
};

enum class PositionType : std::uint32_t {
    kNone = 0,
    kFixedPos = 1,
    kFixedHeight = 2,
    kDopplerVelocity = 8,
    kSingle = 16,
    kPsrDiff = 17,
    kWaas = 18,
    kPropagated = 19,
    kL1Float = 32,
    kIonoFreeFloat = 33,
    kNarrowFloat = 34,
    kL1Int = 48,
    kWideInt = 49,
    kNarrowInt = 50,
    kRtkDirectIns = 51,
    kInsSbas = 52,
    kInsPsrSp = 53,
    kInsPsrDiff = 54,
    kInsRtkFloat = 55,
    kInsRtkFixed = 56,
    kPppConverging = 68,
    kPpp = 69,
    kOperational = 70,
    kWarning = 71,
    kOutOfBounds = 72,
    kInsPppConverging = 73,
    kInsPpp = 74,
    kPppBasicConverging = 77,
    kPppBasic = 78,
    kInsPppBasicConverging = 79,
    kInsPppBasic = 80,
};

enum class InsStatus : std::uint32_t {
    kInactive = 0,
    kAligning = 1,
    kHighVariance = 2,
    kSolutionGood = 3,
    kSolutionFree = 6,
    kAlignmentComplete = 7,
    kDeterminingOrientation = 8,
    kWaitingInitialPos = 9,
    kWaitingAzimuth = 10,
    kInitializingBiases = 11,
    kMotionDetect = 12,
};

enum class ClockModelStatus : std::uint32_t { kValid = 0, kConverging, kIterating, kInvalid };
enum class UtcStatus : std::uint32_t { kInvalid = 0, kValid, kWarning };

// Names as printed in ASCII logs ("FINESTEERING", "SOL_COMPUTED", ...); "" for unknown values.
std::string_view ToString(TimeStatus v);
std::string_view ToString(SolutionStatus v);
std::string_view ToString(PositionType v);
std::string_view ToString(InsStatus v);
std::string_view ToString(ClockModelStatus v);
std::string_view ToString(UtcStatus v);
std::string_view DatumName(std::uint32_t datum_id);  // 61 "WGS84", 63 "USER", else ""

// ---- Header (§2, §3, §5) ----
enum class HeaderKind : std::uint8_t {
    kLongBinary = 0,
    kShortBinary,
    kAscii,
    kShortAscii,
    kAbbreviated,
};

// All long/short/ASCII header fields. Fields a short header lacks stay at their defaults.
struct Header {
    HeaderKind kind = HeaderKind::kLongBinary;
    std::uint16_t message_id = 0;
    // Long binary message type byte without bit 7: bits 0-4 measurement source, 5-6 format.
    std::uint8_t message_type = 0;
    // Bit 7 of the message type (binary), or the 'R' suffix (ASCII): a command response.
    bool is_response = false;
    std::uint8_t port_address = 0;  // long binary port byte (0x20 COM1, 0x40 COM2, ...)
    std::string port_name;          // ASCII header port field ("COM1", "ICOM2"), "" in binary
    std::uint16_t sequence = 0;
    std::uint8_t idle_time = 0;  // 0..200 = idle_percent() * 2
    TimeStatus time_status = TimeStatus::kUnknown;
    std::uint16_t gps_week = 0;
    std::uint32_t gps_ms = 0;  // GPS milliseconds of week
    std::uint32_t receiver_status = 0;
    std::uint16_t reserved = 0;  // message definition word: log it, never validate it
    std::uint16_t sw_build = 0;

    float idle_percent() const { return static_cast<float>(idle_time) * 0.5f; }
    std::uint8_t measurement_source() const { return message_type & 0x1F; }
    // Header time; 0 when week is 0 or time status is UNKNOWN (time since power-up, §8).
    std::int64_t utime_gps() const;

    bool operator==(const Header&) const = default;
};

// ---- Message bodies (§6) ----

// BESTPOS (42) / BESTGNSSPOS (1429), §6.1.
struct BestPos {
    Header header;
    SolutionStatus solution_status = SolutionStatus::kSolComputed;
    PositionType position_type = PositionType::kNone;
    double latitude_deg = 0.0;
    double longitude_deg = 0.0;
    double height_msl_m = 0.0;
    float undulation_m = 0.0f;  // h_ellipsoid = height_msl_m + undulation_m
    std::uint32_t datum_id = 61;
    float latitude_stddev_m = 0.0f;
    float longitude_stddev_m = 0.0f;
    float height_stddev_m = 0.0f;
    std::string base_station_id;  // up to 4 characters
    float differential_age_s = 0.0f;
    float solution_age_s = 0.0f;
    std::uint8_t num_svs_tracked = 0;
    std::uint8_t num_svs_in_solution = 0;
    std::uint8_t num_svs_l1_in_solution = 0;
    std::uint8_t num_svs_multifreq_in_solution = 0;
    std::uint8_t reserved = 0;
    std::uint8_t extended_solution_status = 0;
    std::uint8_t galileo_beidou_signal_mask = 0;
    std::uint8_t gps_glonass_signal_mask = 0;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const BestPos&) const = default;
};

// BESTVEL (99) / BESTGNSSVEL (1430), §6.2.
struct BestVel {
    Header header;
    SolutionStatus solution_status = SolutionStatus::kSolComputed;
    PositionType velocity_type = PositionType::kNone;
    float latency_s = 0.0f;
    float differential_age_s = 0.0f;
    double horizontal_speed_mps = 0.0;
    double track_over_ground_deg = 0.0;  // course, clockwise from true north
    double vertical_speed_mps = 0.0;     // positive up
    float reserved = 0.0f;

    // Header time minus latency (§8).
    std::int64_t utime_gps() const;
    bool operator==(const BestVel&) const = default;
};

// INSPVA (507) / INSPVAS (508), §6.3. Vehicle frame x right, y forward, z up.
struct InsPva {
    Header header;
    std::uint32_t gps_week = 0;
    double gps_seconds = 0.0;  // exact time of validity
    double latitude_deg = 0.0;
    double longitude_deg = 0.0;
    double height_ellipsoid_m = 0.0;
    double velocity_north_mps = 0.0;
    double velocity_east_mps = 0.0;
    double velocity_up_mps = 0.0;
    double roll_deg = 0.0;     // about y (forward)
    double pitch_deg = 0.0;    // about x (right)
    double azimuth_deg = 0.0;  // clockwise from true north, 0..360
    InsStatus ins_status = InsStatus::kInactive;

    std::int64_t utime_gps() const;
    bool operator==(const InsPva&) const = default;
};

// INSPVAX (1465), §6.4.
struct InsPvaX {
    Header header;
    InsStatus ins_status = InsStatus::kInactive;
    PositionType position_type = PositionType::kNone;
    double latitude_deg = 0.0;
    double longitude_deg = 0.0;
    double height_msl_m = 0.0;
    float undulation_m = 0.0f;
    double velocity_north_mps = 0.0;
    double velocity_east_mps = 0.0;
    double velocity_up_mps = 0.0;
    double roll_deg = 0.0;
    double pitch_deg = 0.0;
    double azimuth_deg = 0.0;
    float latitude_stddev_m = 0.0f;
    float longitude_stddev_m = 0.0f;
    float height_stddev_m = 0.0f;
    float velocity_north_stddev_mps = 0.0f;
    float velocity_east_stddev_mps = 0.0f;
    float velocity_up_stddev_mps = 0.0f;
    float roll_stddev_deg = 0.0f;
    float pitch_stddev_deg = 0.0f;
    float azimuth_stddev_deg = 0.0f;
    std::uint32_t extended_status = 0;
    std::uint16_t time_since_update_s = 0;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const InsPvaX&) const = default;
};

// INSATT (263) / INSATTS (319), §6.5.
struct InsAtt {
    Header header;
    std::uint32_t gps_week = 0;
    double gps_seconds = 0.0;
    double roll_deg = 0.0;
    double pitch_deg = 0.0;
    double azimuth_deg = 0.0;
    InsStatus ins_status = InsStatus::kInactive;

    std::int64_t utime_gps() const;
    bool operator==(const InsAtt&) const = default;
};

// INSATTX (1457), §6.5.
struct InsAttX {
    Header header;
    InsStatus ins_status = InsStatus::kInactive;
    PositionType position_type = PositionType::kNone;
    double roll_deg = 0.0;
    double pitch_deg = 0.0;
    double azimuth_deg = 0.0;
    float roll_stddev_deg = 0.0f;
    float pitch_stddev_deg = 0.0f;
    float azimuth_stddev_deg = 0.0f;
    std::uint32_t extended_status = 0;
    std::uint16_t time_since_update_s = 0;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const InsAttX&) const = default;
};

// CORRIMUDATA (812) / CORRIMUDATAS (813) / IMURATECORRIMUS (1362), §6.6: increments per
// sample (or accumulated over the log period for CORRIMUDATA(S)) in the vehicle frame, x y z.
// CORRIMUDATA(S): rate = increment * log rate (Hz); IMURATECORRIMUS: increment * IMU rate.
struct CorrImuData {
    Header header;
    std::uint32_t gps_week = 0;
    double gps_seconds = 0.0;
    std::array<double, 3> delta_angle_rad{};     // pitch (x), roll (y), yaw (z)
    std::array<double, 3> delta_velocity_mps{};  // lateral (x), longitudinal (y), vertical (z)

    std::int64_t utime_gps() const;
    bool operator==(const CorrImuData&) const = default;
};

// CORRIMUS (2264), §6.7: rate = increment * IMU rate / imu_data_count.
struct CorrImuS {
    Header header;
    std::uint32_t imu_data_count = 0;
    std::array<double, 3> delta_angle_rad{};
    std::array<double, 3> delta_velocity_mps{};
    std::uint32_t reserved1 = 0;
    std::uint32_t reserved2 = 0;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const CorrImuS&) const = default;
};

// RAWIMU (268) / RAWIMUS (325) / RAWIMUX (1461) / RAWIMUSX (1462), §6.8. Counts are
// increments in the IMU body frame, already reordered to x, y, z with Y's sign restored
// (the wire order is Z, -Y, X). Scale with ImuScaleFor() / ScaleRawImu().
struct RawImu {
    Header header;
    std::uint8_t imu_info = 0;   // RAWIMU(S)X only: bit 0 = IMU error
    std::int32_t imu_type = -1;  // RAWIMU(S)X: IMU type enum (§6.9); -1 for RAWIMU(S)
    std::uint32_t gps_week = 0;
    double gps_seconds = 0.0;
    std::uint32_t imu_status = 0;
    std::array<std::int64_t, 3> accel_counts{};  // x, y, z
    std::array<std::int64_t, 3> gyro_counts{};   // x, y, z

    std::int64_t utime_gps() const;
    bool operator==(const RawImu&) const = default;
};

// TIME (101), §6.11. UTC = GPS + utc_offset_s.
struct Time {
    Header header;
    ClockModelStatus clock_model_status = ClockModelStatus::kValid;
    double receiver_clock_offset_s = 0.0;
    double receiver_clock_offset_stddev_s = 0.0;
    double utc_offset_s = 0.0;
    std::uint32_t utc_year = 0;
    std::uint8_t utc_month = 0;
    std::uint8_t utc_day = 0;
    std::uint8_t utc_hour = 0;
    std::uint8_t utc_minute = 0;
    std::uint32_t utc_ms = 0;  // milliseconds into the minute, seconds included
    UtcStatus utc_status = UtcStatus::kInvalid;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const Time&) const = default;
};

// HEADING2 (1335) / DUALANTENNAHEADING (2042, no base station id), §6.12.
struct Heading2 {
    Header header;
    SolutionStatus solution_status = SolutionStatus::kSolComputed;
    PositionType position_type = PositionType::kNone;
    float baseline_length_m = 0.0f;
    float heading_deg = 0.0f;  // primary -> secondary antenna, clockwise from true north
    float pitch_deg = 0.0f;
    float reserved = 0.0f;
    float heading_stddev_deg = 0.0f;
    float pitch_stddev_deg = 0.0f;
    std::string rover_station_id;
    std::string base_station_id;  // "" for DUALANTENNAHEADING
    std::uint8_t num_svs_tracked = 0;
    std::uint8_t num_svs_in_solution = 0;
    std::uint8_t num_svs_above_mask = 0;
    std::uint8_t num_svs_multifreq = 0;
    std::uint8_t solution_source = 0;
    std::uint8_t extended_solution_status = 0;
    std::uint8_t galileo_beidou_signal_mask = 0;
    std::uint8_t gps_glonass_signal_mask = 0;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const Heading2&) const = default;
};

// MARKTIME (231) / MARK1TIME (1130) / MARK2TIME (616), §6.13.
struct MarkTime {
    Header header;
    std::int32_t gps_week = 0;
    double gps_seconds = 0.0;  // receiver clock at the leading edge
    double clock_offset_s = 0.0;
    double clock_offset_stddev_s = 0.0;
    double utc_offset_s = 0.0;
    ClockModelStatus clock_model_status = ClockModelStatus::kValid;

    std::int64_t utime_gps() const;  // event time from the body
    bool operator==(const MarkTime&) const = default;
};

// INSSTDEV (2051), §6.14.
struct InsStdDev {
    Header header;
    float latitude_stddev_m = 0.0f;
    float longitude_stddev_m = 0.0f;
    float height_stddev_m = 0.0f;
    float velocity_north_stddev_mps = 0.0f;
    float velocity_east_stddev_mps = 0.0f;
    float velocity_up_stddev_mps = 0.0f;
    float roll_stddev_deg = 0.0f;
    float pitch_stddev_deg = 0.0f;
    float azimuth_stddev_deg = 0.0f;
    std::uint32_t extended_status = 0;
    std::uint16_t time_since_update_s = 0;
    std::array<std::uint8_t, 10> reserved{};

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const InsStdDev&) const = default;
};

// INSCONFIG (1945), §6.14: only the IMU type is interpreted; the rest is kept raw.
struct InsConfig {
    Header header;
    std::uint32_t imu_type = 0;
    std::vector<std::uint8_t> rest;

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const InsConfig&) const = default;
};

// RXSTATUS (93), basic: error word and the status/priority/set/clear word groups.
struct RxStatus {
    struct Group {
        std::uint32_t status = 0;
        std::uint32_t priority_mask = 0;
        std::uint32_t set_mask = 0;
        std::uint32_t clear_mask = 0;
        bool operator==(const Group&) const = default;
    };
    static constexpr std::size_t kMaxGroups = 8;

    Header header;
    std::uint32_t error_word = 0;
    std::uint32_t num_status_codes = 0;      // as sent
    std::uint32_t num_groups = 0;            // groups decoded (<= kMaxGroups)
    std::array<Group, kMaxGroups> groups{};  // [0] receiver status, [1..] auxiliary 1, 2, ...
    std::vector<std::uint8_t> trailing;      // body bytes after the decoded groups

    std::int64_t utime_gps() const { return header.utime_gps(); }
    bool operator==(const RxStatus&) const = default;
};

// A command response (§5): abbreviated "<OK"/"<ERROR:...", ASCII "#...R", binary (bit 7).
struct Response {
    enum class Form : std::uint8_t { kAbbreviated = 0, kAscii, kBinary };
    Header header;  // message_id = the command's id (binary/ASCII); kind kAbbreviated
    Form form = Form::kAbbreviated;
    std::int32_t response_id = -1;  // binary: NovAtel response id (1 = OK); -1 otherwise
    std::string text;               // "OK", "ERROR:Invalid Message. Field = ..."
    std::string command_name;       // ASCII: the name before 'R' ("LOG", "SEND"); else ""

    bool ok() const;
    bool operator==(const Response&) const = default;
};

// A port prompt such as "[COM1]" or "[ICOM1]" (§1).
struct PortPrompt {
    std::string port;  // without brackets
    bool operator==(const PortPrompt&) const = default;
};

// A valid frame whose id (or framing kind) has no decoder: counted per id by callers.
struct Unsupported {
    std::int32_t message_id = -1;
    FrameKind kind = FrameKind::kLongBinary;
    bool operator==(const Unsupported&) const = default;
};

enum class DecodeErrorKind : std::uint8_t {
    kRunt = 0,   // body shorter than the id's minimum length
    kBadHeader,  // header length inconsistent with the frame, or unparsable ASCII header
    kBadField,   // ASCII field missing or unparsable
    kCount
};
std::string_view ToString(DecodeErrorKind kind);

struct DecodeError {
    DecodeErrorKind kind = DecodeErrorKind::kRunt;
    std::size_t offset = 0;  // byte offset in the frame where decoding failed
    bool operator==(const DecodeError&) const = default;
};

// Every decoded message struct, listed once: a Message holds one of them; the decoder's
// DecodeResult (decoder.hpp) holds one of them or one of its `Extra` outcomes.
template <class... Extra>
using MessageOr = std::variant<BestPos,
                               BestVel,
                               InsPva,
                               InsPvaX,
                               InsAtt,
                               InsAttX,
                               CorrImuData,
                               CorrImuS,
                               RawImu,
                               Time,
                               Heading2,
                               MarkTime,
                               InsStdDev,
                               InsConfig,
                               RxStatus,
                               Response,
                               PortPrompt,
                               Extra...>;
using Message = MessageOr<>;

// ---- IMU scale factors (§6.8, §6.9) ----
struct ImuScale {
    double gyro_rad_per_count = 0.0;
    double accel_mps_per_count = 0.0;
    double nominal_rate_hz = 0.0;  // the table's rate; prefer a measured rate (§6.9 note)
};
// Scale factors for an IMU type. `imu_rate_hz` (0 = use the nominal rate) matters for the Epson
// rows whose scale depends on the rate. nullopt for unknown types. The KVH rows follow
// NovAtel's own driver (1.0851e-7 rad/count), which §6.9 flags as unverified.
std::optional<ImuScale> ImuScaleFor(std::int32_t imu_type, double imu_rate_hz = 0.0);

struct ImuIncrements {
    std::array<double, 3> delta_angle_rad{};  // IMU body x, y, z
    std::array<double, 3> delta_velocity_mps{};
    std::array<double, 3> angular_rate_radps{};  // delta / dt, dt = 1 / imu_rate_hz
    std::array<double, 3> acceleration_mps2{};
};
// Raw counts -> increments and rates at `imu_rate_hz` (measure it from consecutive body times).
ImuIncrements ScaleRawImu(const RawImu& raw, const ImuScale& scale, double imu_rate_hz);

}  // namespace pitmap::protocol::novatel
