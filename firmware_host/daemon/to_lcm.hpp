// SPDX-License-Identifier: MIT
// Conversions from the protocol layer's plain structs (common/protocol/novatel/messages.hpp,
// common/protocol/deltat/messages.hpp) to the pitmap lcmtypes (lcmtypes/pitmap/*.lcm), and the
// LCM channel names of docs/conventions.md.
//
// Pure functions: no clock, no LCM object, no I/O. The daemon's SensorChannel and the
// simulator (`pitmap-sim synth`) both call them, so a simulated log carries exactly the
// decoded channels the daemon would publish. Every lcmtype field is filled: where the message
// has no value the field gets what its .lcm comment says (-1 for absent integers, NaN for
// absent floats, 0 for an unknown utime_gps).
//
// Units: as the lcmtypes say (degrees for angles, metres, seconds, Unix microseconds for
// `utime`, GPS microseconds since 1980-01-06 for `utime_gps`).
// Thread safety: all functions are reentrant. Nothing throws for any input value.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/protocol/deltat/messages.hpp"
#include "common/protocol/novatel/messages.hpp"
#include "firmware_host/io/byte_source.hpp"
#include "lcmtypes/log/channels.hpp"
#include "pitmap/gnss_position_t.hpp"
#include "pitmap/gnss_velocity_t.hpp"
#include "pitmap/gps_time_t.hpp"
#include "pitmap/heading_t.hpp"
#include "pitmap/imu_t.hpp"
#include "pitmap/ins_attitude_t.hpp"
#include "pitmap/ins_pva_t.hpp"
#include "pitmap/ins_stddev_t.hpp"
#include "pitmap/mark_time_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "pitmap/novatel_header_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "pitmap/receiver_response_t.hpp"

namespace pitmap::acq {

// The vehicle-shore contract (channel and protocol names) lives in lcmtypes/log/channels.hpp.
using lcmlog::ChannelName;
using lcmlog::kChannelClockSync;
using lcmlog::kChannelDaemonStatus;
using lcmlog::kChannelGnssPosition;
using lcmlog::kChannelGnssVelocity;
using lcmlog::kChannelGpsTime;
using lcmlog::kChannelHeading;
using lcmlog::kChannelImu;
using lcmlog::kChannelInsAttitude;
using lcmlog::kChannelInsPva;
using lcmlog::kChannelInsStdDev;
using lcmlog::kChannelMarkTime;
using lcmlog::kChannelMultibeamPing;
using lcmlog::kChannelRaw;
using lcmlog::kChannelResponse;
using lcmlog::kChannelStatus;
using lcmlog::kChannelVehicleConfig;
using lcmlog::kForeignSuffix;
using lcmlog::kProtocolDeltat83P;
using lcmlog::kProtocolDeltatHead;
using lcmlog::kProtocolNovatel;

// ---- NovAtel ----
namespace novatel = protocol::novatel;

// Header fields; those the header kind lacks (short binary / short ASCII / abbreviated) -1.
pitmap::novatel_header_t ToLcm(const novatel::Header& header);

pitmap::gnss_position_t ToLcm(const novatel::BestPos& m, std::int64_t utime_host);
pitmap::gnss_velocity_t ToLcm(const novatel::BestVel& m, std::int64_t utime_host);
// INSPVA/INSPVAS: position_type -1, undulation and standard deviations NaN, has_stddev 0,
// extended_status and time_since_update_s -1.
pitmap::ins_pva_t ToLcm(const novatel::InsPva& m, std::int64_t utime_host);
// INSPVAX: height_ellipsoid_m = height_msl_m + undulation_m.
pitmap::ins_pva_t ToLcm(const novatel::InsPvaX& m, std::int64_t utime_host);
pitmap::ins_attitude_t ToLcm(const novatel::InsAtt& m, std::int64_t utime_host);
pitmap::ins_attitude_t ToLcm(const novatel::InsAttX& m, std::int64_t utime_host);
pitmap::ins_stddev_t ToLcm(const novatel::InsStdDev& m, std::int64_t utime_host);

// CORRIMUDATA / CORRIMUDATAS / IMURATECORRIMUS (vehicle frame, corrected). `rate_hz` is the
// rate at which the increments are accumulated: the log rate for CORRIMUDATA(S) (increments
// summed over the log period), the IMU rate for IMURATECORRIMUS. dt_s = 1 / rate_hz; with
// rate_hz <= 0 (unknown) dt_s and the rates are NaN, the increments are still filled.
pitmap::imu_t ToLcm(const novatel::CorrImuData& m, std::int64_t utime_host, double rate_hz);
// CORRIMUS: dt_s = imu_data_count / imu_rate_hz (NaN when either is 0).
pitmap::imu_t ToLcm(const novatel::CorrImuS& m, std::int64_t utime_host, double imu_rate_hz);
// RAWIMU / RAWIMUS / RAWIMUX / RAWIMUSX (IMU body frame, raw), scaled with ImuScaleFor().
// The IMU type is the message's own (RAWIMU(S)X) or, for RAWIMU(S), `imu_type` (from INSCONFIG
// or the config; -1 = unknown). `imu_rate_hz` <= 0 uses the scale table's nominal rate.
// An unknown IMU type leaves increments, rates and dt_s NaN (the raw bytes are in the log).
pitmap::imu_t ToLcm(const novatel::RawImu& m,
                    std::int64_t utime_host,
                    double imu_rate_hz,
                    std::int32_t imu_type = -1);
pitmap::gps_time_t ToLcm(const novatel::Time& m, std::int64_t utime_host);
pitmap::heading_t ToLcm(const novatel::Heading2& m, std::int64_t utime_host);
pitmap::mark_time_t ToLcm(const novatel::MarkTime& m, std::int64_t utime_host);
// `source` is the channel id; `command` the command this answers when known, else "".
pitmap::receiver_response_t ToLcm(const novatel::Response& m,
                                  std::int64_t utime_host,
                                  std::string_view source,
                                  std::string_view command = {});

// What a channel needs to turn IMU logs into rates.
struct ImuContext {
    std::int32_t imu_type = -1;    // IMU type enum for RAWIMU(S) (INSCONFIG or config); -1 unknown
    double imu_rate_hz = 0.0;      // IMU data rate, Hz; 0 = the table's nominal rate / unknown
    double corrimu_rate_hz = 0.0;  // CORRIMUDATA(S) log rate, Hz; 0 = unknown (rates NaN)
};

// One LCM message ready to publish: its channel and its encoded bytes.
struct EncodedMessage {
    std::string channel;
    std::vector<std::uint8_t> data;
};

// The channel and encoded lcmtype of one decoded NovAtel message, as the daemon publishes it
// for channel `channel_id`. nullopt for messages without an lcmtype (INSCONFIG, RXSTATUS,
// port prompts). Responses go to RESPONSE_<ID> with `command` = "".
std::optional<EncodedMessage> EncodeNovatel(const novatel::Message& message,
                                            std::int64_t utime_host,
                                            std::string_view channel_id,
                                            const ImuContext& imu = {});

// ---- Delta T ----

// One 83P ping. `utime_gps` (0 = unknown), `time_source` (multibeam_ping_t.TIME_SOURCE_*) and
// `time_stddev_s` (NaN = unknown) are what the daemon's sonar clock model assigned.
pitmap::multibeam_ping_t ToLcm(const protocol::deltat::Ping83P& ping,
                               std::int64_t utime_host,
                               std::int64_t utime_gps,
                               std::int8_t time_source,
                               float time_stddev_s);

// ---- Raw bytes ----

// Optional fields of a raw chunk.
struct RawBytesExtra {
    std::int64_t utime_gps = 0;     // GPS time of utime_host, 0 = unknown
    bool gps_time_valid = false;    // utime_gps came from a locked clock model
    std::string peer;               // "address:port", device path, "" for files
    std::int64_t utime_kernel = 0;  // SO_TIMESTAMPNS, Unix us; 0 = not available
};

// A raw_bytes_t holding `data` unmodified. `seq` counts chunks per source from 0.
pitmap::raw_bytes_t MakeRawBytes(std::int64_t utime_host,
                                 std::string_view source,
                                 std::string_view protocol,
                                 Transport transport,
                                 std::int64_t seq,
                                 std::span<const std::byte> data,
                                 const RawBytesExtra& extra = {});
pitmap::raw_bytes_t MakeRawBytes(std::int64_t utime_host,
                                 std::string_view source,
                                 std::string_view protocol,
                                 Transport transport,
                                 std::int64_t seq,
                                 std::span<const std::uint8_t> data,
                                 const RawBytesExtra& extra = {});

// Encodes any lcmtype into its wire bytes (getEncodedSize + encode).
template <typename LcmType>
std::vector<std::uint8_t> EncodeLcm(const LcmType& msg) {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(msg.getEncodedSize()));
    msg.encode(out.data(), 0, static_cast<int>(out.size()));
    return out;
}

}  // namespace pitmap::acq
