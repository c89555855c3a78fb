// SPDX-License-Identifier: MIT
// The LCM contract between the vehicle and the shore: channel names and raw_bytes_t protocol
// names, written here once. The daemon publishes and logs under these names
// (firmware_host/daemon/to_lcm.*); ingest, pitmap-inspect, the simulator and the benches read
// them (docs/conventions.md "LCM channels").
#pragma once

#include <cctype>
#include <string>
#include <string_view>

namespace pitmap::lcmlog {

// raw_bytes_t.protocol / channel_status_t.protocol values.
inline constexpr std::string_view kProtocolNovatel = "novatel";
inline constexpr std::string_view kProtocolDeltat83P = "deltat_83p";
inline constexpr std::string_view kProtocolDeltatHead = "deltat_head";
// Appended to raw_bytes_t.protocol for a UDP datagram from a sender not on the channel's
// allowed_senders ("deltat_83p_foreign"): kept as evidence, never decoded by anyone.
inline constexpr std::string_view kForeignSuffix = "_foreign";

// Channel name prefixes, followed by the channel id upper-cased (ChannelName below), and the
// whole names of the daemon's own channels.
inline constexpr std::string_view kChannelRaw = "RAW_";
inline constexpr std::string_view kChannelInsPva = "INS_PVA_";
inline constexpr std::string_view kChannelInsAttitude = "INS_ATTITUDE_";
inline constexpr std::string_view kChannelInsStdDev = "INS_STDDEV_";
inline constexpr std::string_view kChannelGnssPosition = "GNSS_POSITION_";
inline constexpr std::string_view kChannelGnssVelocity = "GNSS_VELOCITY_";
inline constexpr std::string_view kChannelImu = "IMU_";
inline constexpr std::string_view kChannelGpsTime = "GPS_TIME_";
inline constexpr std::string_view kChannelHeading = "HEADING_";
inline constexpr std::string_view kChannelMarkTime = "MARK_TIME_";
inline constexpr std::string_view kChannelResponse = "RESPONSE_";
inline constexpr std::string_view kChannelMultibeamPing = "MULTIBEAM_PING_";
inline constexpr std::string_view kChannelStatus = "STATUS_";
inline constexpr std::string_view kChannelClockSync = "CLOCK_SYNC";
inline constexpr std::string_view kChannelDaemonStatus = "DAEMON_STATUS";
inline constexpr std::string_view kChannelVehicleConfig = "VEHICLE_CONFIG";

// `prefix` + the channel id upper-cased: ChannelName(kChannelInsPva, "novatel_com1") is
// "INS_PVA_NOVATEL_COM1".
inline std::string ChannelName(std::string_view prefix, std::string_view channel_id) {
    std::string name(prefix);
    name.reserve(prefix.size() + channel_id.size());
    for (char c : channel_id) {
        name.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
    }
    return name;
}

// True when `channel` is `prefix` + an id: any id when `id_upper` is empty, else that id
// (upper-cased, as ChannelName writes it). The readers of logs pick their channels with it.
inline bool ChannelMatches(std::string_view channel,
                           std::string_view prefix,
                           std::string_view id_upper) {
    if (channel.substr(0, prefix.size()) != prefix) return false;
    return id_upper.empty() || channel.substr(prefix.size()) == id_upper;
}

}  // namespace pitmap::lcmlog
