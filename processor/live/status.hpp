// SPDX-License-Identifier: MIT
// Live survey status and alarms from the daemon's decoded messages (plain structs here; the
// LCM decoding is in session.cpp).
//
// Two clocks: the data clock is the newest host receive time (`utime`) of any message, so a
// replay at any speed ages its own data; the wall clock (the caller's, injected) only decides
// whether messages still arrive at all (no_messages).
// Alarms, each with a reason in words (thresholds in StatusConfig):
//   sonar_silent      no ping for sonar_silent_s of data time, or the daemon reports the
//                     sonar channel silent or disconnected
//   ins_degraded      INS status not INS_SOLUTION_GOOD, or position / heading sigma above limit
//   gnss_outage       no GNSS position for gnss_outage_s, or its solution not computed
//   clock_not_locked  the host clock model (CLOCK_SYNC / DAEMON_STATUS) is not LOCKED
//   disk_low          free log space below disk_low_bytes, or logging stopped by the disk guard
//                     or a write error
//   drops_rising      queue, kernel or log-writer drops grew within drops_window_s
//   no_messages       nothing arrived for no_messages_s of wall time
//   tvu_over_limit    of the cells first filled within tvu_window_s of data time (at least
//                     tvu_min_new_cells of them), more than tvu_alarm_percent fail the S-44
//                     order's TVU (coverage_grid.hpp: their status once their batch is in)
// Thread safety: none; LiveSession serialises access.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <vector>

namespace pitmap::proc::live {

struct StatusConfig {
    double sonar_silent_s = 3.0;
    double gnss_outage_s = 3.0;
    double ins_position_sigma_max_m = 0.5;   // horizontal, 1 sigma
    double ins_heading_sigma_max_deg = 0.5;  // 1 sigma
    std::int64_t disk_low_bytes = 1LL << 30;
    double drops_window_s = 10.0;
    double no_messages_s = 5.0;
    double rate_window_s = 5.0;       // ping rate over this much data time
    double tvu_alarm_percent = 10.0;  // new cells failing the order's TVU, % (0..100)
    double tvu_window_s = 30.0;       // "new": first filled within this much data time
    int tvu_min_new_cells = 20;       // fewer new cells in the window: no verdict
    std::vector<std::string> Validate() const;
};

struct NavStatusIn {
    std::int64_t utime = 0, utime_gps = 0;
    int ins_status = -1, position_type = -1;
    float north_sigma_m = -1, east_sigma_m = -1, up_sigma_m = -1,
          heading_sigma_deg = -1;  // <0 none
};
struct GnssStatusIn {
    std::int64_t utime = 0;
    int solution_status = -1, position_type = -1;
    float horizontal_sigma_m = -1;
    int satellites = -1;
};
struct PingStatusIn {
    std::int64_t utime = 0, utime_gps = 0;
    int num_beams = 0;
};
struct ClockStatusIn {
    std::int64_t utime = 0;
    int source = 0;  // clock_sync_t SOURCE_*
    int state = 0;   // clock_sync_t STATE_*
    double offset_us = 0, stddev_us = 0, drift_ppm = 0;
    int leap_seconds = 0;  // GPS - UTC, s
};
// One georeferencing batch's new cells: how many were first filled, and how many of them fail
// the order's TVU.
struct TvuCellsIn {
    std::int64_t utime = 0;  // data clock
    std::int64_t new_cells = 0, failing = 0;
    std::string order;  // "1a", for the reason
};
struct ChannelStatusIn {
    std::string name, protocol;
    int state = 0;  // channel_status_t STATE_*
    std::int64_t bytes = 0, frames = 0, crc_failures = 0, decode_errors = 0;
    std::int64_t queue_drops = 0, kernel_drops = 0, last_message_age_ms = -1;
};
struct DaemonStatusIn {
    std::int64_t utime = 0;
    std::string hostname;
    std::int64_t uptime_s = 0;
    int logging = 0;  // daemon_status_t LOGGING_*
    std::int64_t disk_free_bytes = -1, log_events_dropped = 0, log_bytes_written = 0;
    std::vector<ChannelStatusIn> channels;
};

struct Alarm {
    std::string id;                // "sonar_silent", ...
    std::string reason;            // what tripped it, with the numbers
    std::int64_t since_utime = 0;  // data time it became active
};
struct AlarmEvent {
    std::string id, reason;
    bool raised = true;  // false = cleared
    std::int64_t utime = 0;
};

// Per LCM channel: messages, bytes, decode failures, last host time.
struct ChannelCounter {
    std::int64_t messages = 0, bytes = 0, decode_failures = 0, last_utime = 0;
};

struct StatusSnapshot {
    std::int64_t data_utime = 0;  // data clock
    double ping_rate_hz = 0;
    std::int64_t pings = 0;
    std::int64_t last_ping_utime = 0;
    bool have_nav = false;
    NavStatusIn nav;
    bool have_gnss = false;
    GnssStatusIn gnss;
    bool gnss_outage = false;
    double gnss_outage_s = 0;           // length of the current outage, 0 when none
    std::vector<ClockStatusIn> clocks;  // latest per source
    bool have_daemon = false;
    DaemonStatusIn daemon;
    std::int64_t daemon_drops_total = 0;
    std::map<std::string, ChannelCounter> lcm_channels;
    std::vector<Alarm> alarms;        // active now
    std::vector<AlarmEvent> history;  // latest transitions, newest last
};

std::string InsStatusName(int status);
const char* ClockStateName(int state);
const char* ClockSourceName(int source);
const char* ChannelStateName(int state);
const char* LoggingName(int logging);

class StatusTracker {
public:
    explicit StatusTracker(const StatusConfig& config) : config_(config) {}

    // Every message, before decoding: the data clock and the channel counters.
    void OnMessage(const std::string& channel,
                   std::int64_t utime,
                   std::size_t bytes,
                   std::int64_t wall_utime);
    void OnDecodeFailure(const std::string& channel);
    void OnNav(const NavStatusIn& n);
    void OnGnss(const GnssStatusIn& g);
    void OnPing(const PingStatusIn& p);
    void OnClock(const ClockStatusIn& c);
    void OnDaemon(const DaemonStatusIn& d);
    void OnTvuCells(const TvuCellsIn& t);

    // The feed has ended on purpose (a replayed log reached its end): silence is expected, so
    // the no_messages alarm stays off from now on.
    void SetFeedEnded() { feed_ended_ = true; }
    bool feed_ended() const { return feed_ended_; }
    // Re-evaluates the alarms at the data clock and the given wall time; keeps the transitions.
    void Evaluate(std::int64_t wall_utime);
    StatusSnapshot Snapshot() const;
    const std::vector<Alarm>& alarms() const { return active_; }
    const NavStatusIn& nav() const { return nav_; }

private:
    void Set(std::vector<Alarm>& next, const std::string& id, bool on, const std::string& reason);

    StatusConfig config_;
    std::int64_t data_utime_ = 0;
    std::int64_t last_wall_utime_ = 0;  // wall time of the last message
    bool feed_ended_ = false;
    std::deque<std::int64_t> ping_times_;
    std::int64_t pings_ = 0, last_ping_utime_ = 0, first_utime_ = 0;
    bool have_nav_ = false, have_gnss_ = false, have_daemon_ = false;
    NavStatusIn nav_;
    GnssStatusIn gnss_;
    std::int64_t gnss_bad_since_ = 0;  // data time the GNSS solution went bad, 0 = good
    std::map<int, ClockStatusIn> clocks_;
    DaemonStatusIn daemon_;
    std::deque<std::pair<std::int64_t, std::int64_t>> drops_;  // (utime, total drops)
    std::deque<TvuCellsIn> tvu_;                               // within tvu_window_s
    std::map<std::string, ChannelCounter> channels_;
    std::vector<Alarm> active_;
    std::deque<AlarmEvent> history_;
};

}  // namespace pitmap::proc::live
