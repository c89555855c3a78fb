// SPDX-License-Identifier: MIT
// Daemon: pitmap-acqd assembled from a DaemonConfig: one ByteSource + SensorChannel per
// configured channel, the shared TimeKeeper, the LcmPublisher and the LogWriter, and the
// periodic status (STATUS_<ID> channel_status_t, CLOCK_SYNC clock_sync_t for the host and
// the sonar model, DAEMON_STATUS daemon_status_t).
//
// At Start() the log directory is created if missing (log.fallback_dir is used when that
// fails) and the config's `vehicle` section is written there as vehicle.yaml (lever arms and
// nominal boresight for the processor; it is not published on LCM: the processor reads it
// next to the logs). The log writer reports through the daemon's rate-limited human log.
//
// THREADING: one reader thread per channel (SensorChannel), the publisher thread, the log
// writer thread, the PPS thread when a device is configured. Start(), PublishStatus(),
// Rotate() and Stop() are called from the one controlling thread (main, which also owns the
// signals).
#pragma once

#include <memory>
#include <vector>

#include "common/result.hpp"
#include "firmware_host/daemon/clock.hpp"
#include "firmware_host/daemon/daemon_config.hpp"
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/pps_channel.hpp"
#include "firmware_host/daemon/publisher.hpp"
#include "firmware_host/daemon/rate_limited_log.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"
#include "firmware_host/daemon/time_keeper.hpp"
#include "pitmap/daemon_status_t.hpp"

namespace pitmap::acq {

class Daemon {
public:
    // Precondition: the config loaded without problems.
    Daemon(DaemonConfig config, Clock& clock);
    // As above with the PPS source given (tests): used when config.pps.device is set.
    Daemon(DaemonConfig config, Clock& clock, std::unique_ptr<PpsSource> pps);
    ~Daemon();
    Daemon(const Daemon&) = delete;
    Daemon& operator=(const Daemon&) = delete;

    // Creates the log directory, writes vehicle.yaml, starts the log writer, the publisher
    // and every channel. Fails (naming the path or URL) when the log or LCM cannot start;
    // a device that cannot be opened yet is not a failure (its channel keeps retrying).
    Status Start();
    // Publishes STATUS_<ID> for every channel, CLOCK_SYNC (host, then sonar) and
    // DAEMON_STATUS; prints rate-limited human lines for unhealthy channels.
    void PublishStatus();
    // Starts a new log file (SIGHUP).
    void Rotate();
    // Stops the channels, publishes a last status, drains the publisher, flushes and closes
    // the log. Idempotent.
    void Stop();
    // True when every channel reached the end of its source (file replays).
    bool AllFinished() const;

    pitmap::daemon_status_t Snapshot() const;
    // PPS counters; all zero without a PPS device.
    PpsCounters pps_counters() const;
    const DaemonConfig& config() const { return config_; }

private:
    // Logs where UDP channel `index` listens and whom it accepts (before its thread starts).
    void NoteUdpListening(std::size_t index);

    DaemonConfig config_;
    Clock& clock_;
    RateLimitedLog human_log_;
    TimeKeeper time_;
    LogWriter log_;
    LcmPublisher publisher_;
    std::vector<std::unique_ptr<ByteSource>> sources_;
    std::vector<std::unique_ptr<SensorChannel>> channels_;
    std::unique_ptr<PpsSource> pps_source_;
    std::unique_ptr<PpsChannel> pps_;
    std::int64_t start_mono_us_ = 0;
    bool started_ = false;
};

}  // namespace pitmap::acq
