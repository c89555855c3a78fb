// SPDX-License-Identifier: MIT
// pitmap-acqd configuration: one YAML file (firmware_host/config/*.yaml), read with
// common/config.hpp's ConfigReader so every problem is listed at once; unknown keys are
// problems. Units are in the key names.
//
// Top level keys:
//   lcm_url            LCM provider URL ("" = log only); e.g. udpm://239.255.76.67:7667?ttl=0;
//                      checked by ValidateLcmUrl (startup_check.hpp)
//   status_period_ms   STATUS_<ID>, CLOCK_SYNC and DAEMON_STATUS period (1000)
//   pps_device         RFC 2783 PPS device feeding the host clock model, e.g. /dev/pps0;
//                      absent or "" = none. Must exist (a character device) at start-up.
//   pps_fetch_timeout_ms  one wait for a pulse (1500)
//   log                directory, prefix, rotate_bytes, rotate_interval_s, flush_interval_ms,
//                      min_free_bytes, resume_margin_bytes, disk_check_interval_ms,
//                      queue_max_events, queue_max_bytes, error_retry_ms; optional
//                      fallback_dir: where files go when `directory` cannot be (re)created
//                      or written (e.g. its file system was unmounted)
//   publisher          queue_max_events, queue_max_bytes (outbound LCM queue)
//   clock              fixed_latency_us (host model), sonar_header_resolution_us
//   channels           list; each: id, protocol (novatel | deltat_83p), exactly one of
//                      serial {path, baud, rtscts, exclusive}, tcp {host, port,
//                      connect_timeout_ms}, udp {port, allowed_senders [..], bind_address,
//                      reply_to, receive_buffer_bytes} (udp_source.hpp: allowed_senders is
//                      required, bind_address defaults to the interface facing the first
//                      allowed sender, EC frames go to reply_to or the first allowed sender),
//                      file {path, chunk_bytes, bytes_per_second}; optional read_timeout_ms,
//                      silent_timeout_ms, setup_commands [..], command_timeout_ms,
//                      command_retries, imu_type, imu_rate_hz, corrimu_rate_hz,
//                      ec {enabled, range_m, start_gain_db, display_gain_pct, sector_deg,
//                      num_beams, interval_ms}
//   vehicle            the vehicle description for the processor (common/vehicle.hpp, schema
//                      `pitmap_vehicle: 1`: lever arms, mount, boresight, ...): checked
//                      against the schema here (every problem listed), then copied into the log
//                      directory as vehicle.yaml at start (see DaemonConfig::vehicle_yaml).
#pragma once

#include <string>
#include <vector>

#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/publisher.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"
#include "firmware_host/daemon/time_keeper.hpp"
#include "firmware_host/io/file_source.hpp"
#include "firmware_host/io/pps_source.hpp"
#include "firmware_host/io/serial_source.hpp"
#include "firmware_host/io/tcp_client_source.hpp"
#include "firmware_host/io/udp_source.hpp"

namespace pitmap::acq {

enum class SourceKind { kSerial, kTcp, kUdp, kFile };

struct ChannelSpec {
    SensorChannelConfig channel;
    SourceKind kind = SourceKind::kSerial;
    SerialConfig serial;
    TcpClientConfig tcp;
    UdpConfig udp;
    FileSourceConfig file;
};

struct DaemonConfig {
    std::string lcm_url = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
    int status_period_ms = 1000;
    LogWriterConfig log;
    LcmPublisherConfig publisher;
    HostClockConfig host_clock;
    SonarClockConfig sonar_clock;
    PpsConfig pps;  // pps.device "" = no PPS
    std::vector<ChannelSpec> channels;
    std::string vehicle_yaml;  // the `vehicle` section re-emitted as YAML, "" if absent
};

struct LoadedConfig {
    DaemonConfig config;
    std::vector<std::string> problems;  // empty when the config can be run
};

// Reads and validates a config file: parse errors, wrong types, unknown keys and every
// Validate() of the parts, each as one line naming the key. What depends on the host (the log
// directory, devices, ports) is CheckHost's (startup_check.hpp).
LoadedConfig LoadDaemonConfig(const std::string& path);
LoadedConfig LoadDaemonConfigFromString(const std::string& yaml, const std::string& origin);

}  // namespace pitmap::acq
