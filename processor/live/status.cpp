// SPDX-License-Identifier: MIT
#include "processor/live/status.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/protocol/novatel/messages.hpp"

namespace pitmap::proc::live {

namespace {

constexpr int kInsSolutionGood = 3;
constexpr int kSolComputed = 0;
constexpr int kClockLocked = 2;
constexpr int kSourceSonarHeader = 3;
constexpr int kChannelSilent = 3, kChannelDisconnected = 4;
constexpr int kLoggingDiskGuard = 2, kLoggingError = 3;
constexpr std::size_t kHistory = 50;

std::string Fmt(const char* f, double a, double b = 0) {
    char buf[160];
    std::snprintf(buf, sizeof(buf), f, a, b);
    return buf;
}

double Seconds(std::int64_t us) {
    return static_cast<double>(us) * 1e-6;
}

}  // namespace

std::vector<std::string> StatusConfig::Validate() const {
    std::vector<std::string> p;
    const auto positive = [&](double v, const char* name) {
        if (!(v > 0) || !std::isfinite(v))
            p.push_back(std::string("live.") + name + " must be > 0");
    };
    positive(sonar_silent_s, "sonar_silent_s");
    positive(gnss_outage_s, "gnss_outage_s");
    positive(ins_position_sigma_max_m, "ins_position_sigma_max_m");
    positive(ins_heading_sigma_max_deg, "ins_heading_sigma_max_deg");
    positive(drops_window_s, "drops_window_s");
    positive(no_messages_s, "no_messages_s");
    positive(rate_window_s, "rate_window_s");
    positive(tvu_window_s, "tvu_window_s");
    if (disk_low_bytes < 0) p.push_back("live.disk_low_bytes must be >= 0");
    if (!(tvu_alarm_percent >= 0 && tvu_alarm_percent <= 100))
        p.push_back("live.tvu_alarm_percent must lie in [0, 100]");
    if (tvu_min_new_cells < 1) p.push_back("live.tvu_min_new_cells must be >= 1");
    return p;
}

std::string InsStatusName(int status) {
    if (status < 0) return "unknown";
    const auto name = protocol::novatel::ToString(
        static_cast<protocol::novatel::InsStatus>(static_cast<std::uint32_t>(status)));
    return name.empty() ? "unknown (" + std::to_string(status) + ")" : std::string(name);
}

const char* ClockStateName(int state) {
    switch (state) {
        case 0:
            return "no_time";
        case 1:
            return "converging";
        case 2:
            return "locked";
        case 3:
            return "holdover";
        default:
            return "unknown";
    }
}

const char* ClockSourceName(int source) {
    switch (source) {
        case 1:
            return "host_from_novatel";
        case 2:
            return "host_from_pps";
        case 3:
            return "sonar_header";
        default:
            return "unknown";
    }
}

const char* ChannelStateName(int state) {
    switch (state) {
        case 0:
            return "stopped";
        case 1:
            return "connecting";
        case 2:
            return "running";
        case 3:
            return "silent";
        case 4:
            return "disconnected";
        default:
            return "unknown";
    }
}

const char* LoggingName(int logging) {
    switch (logging) {
        case 0:
            return "off";
        case 1:
            return "on";
        case 2:
            return "disk_guard";
        case 3:
            return "error";
        default:
            return "unknown";
    }
}

void StatusTracker::OnMessage(const std::string& channel,
                              std::int64_t utime,
                              std::size_t bytes,
                              std::int64_t wall_utime) {
    ChannelCounter& c = channels_[channel];
    ++c.messages;
    c.bytes += static_cast<std::int64_t>(bytes);
    c.last_utime = utime;
    // A message from far in the future of the data clock (a corrupt stamp) would hold every
    // alarm off until the data caught up: only plausible stamps (after 2001) advance it.
    if (utime > 1'000'000'000'000'000LL && utime > data_utime_) data_utime_ = utime;
    if (first_utime_ == 0) first_utime_ = data_utime_;
    last_wall_utime_ = wall_utime;
}

void StatusTracker::OnDecodeFailure(const std::string& channel) {
    ++channels_[channel].decode_failures;
}

void StatusTracker::OnNav(const NavStatusIn& n) {
    nav_ = n;
    have_nav_ = true;
}

void StatusTracker::OnGnss(const GnssStatusIn& g) {
    gnss_ = g;
    have_gnss_ = true;
    const bool good = g.solution_status == kSolComputed && g.position_type != 0;
    if (good) {
        gnss_bad_since_ = 0;
    } else if (gnss_bad_since_ == 0) {
        gnss_bad_since_ = g.utime;
    }
}

void StatusTracker::OnPing(const PingStatusIn& p) {
    ++pings_;
    last_ping_utime_ = std::max(last_ping_utime_, p.utime);
    ping_times_.push_back(p.utime);
}

void StatusTracker::OnClock(const ClockStatusIn& c) {
    clocks_[c.source] = c;
}

void StatusTracker::OnDaemon(const DaemonStatusIn& d) {
    daemon_ = d;
    have_daemon_ = true;
    std::int64_t total = d.log_events_dropped;
    for (const ChannelStatusIn& c : d.channels) total += c.queue_drops + c.kernel_drops;
    drops_.emplace_back(d.utime, total);
}

void StatusTracker::OnTvuCells(const TvuCellsIn& t) {
    if (t.new_cells <= 0) return;
    tvu_.push_back(t);
    // Bounded even when the data clock stands still (Evaluate prunes by data time).
    while (tvu_.size() > 10'000) tvu_.pop_front();
}

void StatusTracker::Set(std::vector<Alarm>& next,
                        const std::string& id,
                        bool on,
                        const std::string& reason) {
    auto was =
        std::find_if(active_.begin(), active_.end(), [&](const Alarm& a) { return a.id == id; });
    if (on) {
        Alarm a{id, reason, was != active_.end() ? was->since_utime : data_utime_};
        if (was == active_.end()) history_.push_back({id, reason, true, data_utime_});
        next.push_back(std::move(a));
    } else if (was != active_.end()) {
        history_.push_back({id, was->reason, false, data_utime_});
    }
    while (history_.size() > kHistory) history_.pop_front();
}

namespace {

// "a" + "; " + "b": the reasons of one alarm.
void Append(std::string& reason, const std::string& more) {
    if (!reason.empty()) reason += "; ";
    reason += more;
}

// Sonar: no ping for sonar_silent_s (since the last, or since the first message), or the
// daemon's sonar channel silent or disconnected.
std::string SonarSilence(std::int64_t now,
                         std::int64_t last_ping_utime,
                         std::int64_t first_utime,
                         const DaemonStatusIn* daemon,
                         const StatusConfig& config) {
    std::string reason;
    const double quiet_s = Seconds(now - (last_ping_utime > 0 ? last_ping_utime : first_utime));
    if (quiet_s > config.sonar_silent_s) {
        reason = last_ping_utime > 0 ? Fmt("no ping for %.1f s", quiet_s)
                                     : Fmt("no ping since the first message (%.1f s)", quiet_s);
    }
    if (daemon != nullptr) {
        for (const ChannelStatusIn& c : daemon->channels) {
            if (c.protocol.rfind("deltat", 0) != 0) continue;
            if (c.state == kChannelSilent || c.state == kChannelDisconnected)
                Append(reason,
                       "daemon reports channel " + c.name + " " + ChannelStateName(c.state));
        }
    }
    return reason;
}

// INS: its status, its horizontal and heading sigmas, its age.
std::string InsDegraded(const NavStatusIn& nav, std::int64_t now, const StatusConfig& config) {
    std::string reason;
    if (nav.ins_status != kInsSolutionGood) {
        reason = std::string("INS status ") + InsStatusName(nav.ins_status);
    }
    if (nav.north_sigma_m >= 0 && nav.east_sigma_m >= 0) {
        const double h = std::hypot(nav.north_sigma_m, nav.east_sigma_m);
        if (h > config.ins_position_sigma_max_m)
            Append(reason,
                   Fmt("horizontal sigma %.2f m > %.2f m", h, config.ins_position_sigma_max_m));
    }
    if (nav.heading_sigma_deg > config.ins_heading_sigma_max_deg) {
        Append(reason,
               Fmt("heading sigma %.2f deg > %.2f deg",
                   nav.heading_sigma_deg,
                   config.ins_heading_sigma_max_deg));
    }
    const double age_s = Seconds(now - nav.utime);
    if (age_s > config.sonar_silent_s) Append(reason, Fmt("no INS solution for %.1f s", age_s));
    return reason;
}

// GNSS: no position, or no computed solution, for gnss_outage_s.
std::string GnssOutage(const GnssStatusIn& gnss,
                       std::int64_t bad_since,
                       std::int64_t now,
                       const StatusConfig& config) {
    const double age_s = Seconds(now - gnss.utime);
    if (age_s > config.gnss_outage_s) return Fmt("no GNSS position for %.1f s", age_s);
    if (bad_since != 0 && Seconds(now - bad_since) > config.gnss_outage_s) {
        return Fmt("GNSS solution not computed for %.1f s (solution status %.0f)",
                   Seconds(now - bad_since),
                   gnss.solution_status);
    }
    return "";
}

// Clocks: every model the daemon runs that is not locked, except the sonar header clock of a
// daemon that stamps pings on receipt (it reports NO_TIME for it by design).
std::string ClocksNotLocked(const std::map<int, ClockStatusIn>& clocks) {
    std::string reason;
    for (const auto& [source, c] : clocks) {
        if (source == kSourceSonarHeader && c.state == 0) continue;
        if (c.state != kClockLocked) {
            Append(reason,
                   std::string(ClockSourceName(source)) + " clock " + ClockStateName(c.state) +
                       Fmt(" (sigma %.0f us)", c.stddev_us));
        }
    }
    return reason;
}

// Disk: little free space, or the daemon's logging stopped.
std::string DiskLow(const DaemonStatusIn& daemon, const StatusConfig& config) {
    std::string reason;
    if (daemon.disk_free_bytes >= 0 && daemon.disk_free_bytes < config.disk_low_bytes) {
        reason = Fmt("%.0f MB free < %.0f MB",
                     static_cast<double>(daemon.disk_free_bytes) / 1e6,
                     static_cast<double>(config.disk_low_bytes) / 1e6);
    }
    if (daemon.logging == kLoggingDiskGuard || daemon.logging == kLoggingError)
        Append(reason, std::string("logging stopped: ") + LoggingName(daemon.logging));
    return reason;
}

// Drops: the daemon's drop count rose within the window (the first sample its baseline).
std::string DropsRising(const std::deque<std::pair<std::int64_t, std::int64_t>>& drops) {
    if (drops.size() < 2 || drops.back().second <= drops.front().second) return "";
    return Fmt("%.0f drops in the last %.0f s",
               static_cast<double>(drops.back().second - drops.front().second),
               Seconds(drops.back().first - drops.front().first));
}

// TVU: the share of the cells first filled within the window that fail the order's TVU, when
// enough were filled and it is over tvu_alarm_percent; empty otherwise.
std::string TvuOverLimit(const std::deque<TvuCellsIn>& tvu, const StatusConfig& config) {
    std::int64_t fresh = 0, failing = 0;
    for (const TvuCellsIn& t : tvu) {
        fresh += t.new_cells;
        failing += t.failing;
    }
    const double pct =
        fresh > 0 ? 100.0 * static_cast<double>(failing) / static_cast<double>(fresh) : 0.0;
    if (!(fresh >= config.tvu_min_new_cells && pct > config.tvu_alarm_percent)) return "";
    char buf[200];
    std::snprintf(buf,
                  sizeof buf,
                  " limit in %.0f %% of new cells (%lld of %lld first filled in the last "
                  "%.0f s; alarm above %.0f %%)",
                  pct,
                  static_cast<long long>(failing),
                  static_cast<long long>(fresh),
                  config.tvu_window_s,
                  config.tvu_alarm_percent);
    return "TVU over the order " + tvu.back().order + buf;
}

}  // namespace

void StatusTracker::Evaluate(std::int64_t wall_utime) {
    const std::int64_t now = data_utime_;
    const auto window = static_cast<std::int64_t>(config_.rate_window_s * 1e6);
    while (!ping_times_.empty() && ping_times_.front() < now - window) ping_times_.pop_front();
    const auto drops_window = static_cast<std::int64_t>(config_.drops_window_s * 1e6);
    // Keep one sample older than the window as the baseline.
    while (drops_.size() > 1 && drops_[1].first <= now - drops_window) drops_.pop_front();
    const auto tvu_window = static_cast<std::int64_t>(config_.tvu_window_s * 1e6);

    std::vector<Alarm> next;
    if (now == 0) {
        active_.clear();
        return;
    }
    const std::string sonar = SonarSilence(
        now, last_ping_utime_, first_utime_, have_daemon_ ? &daemon_ : nullptr, config_);
    Set(next, "sonar_silent", !sonar.empty(), sonar);
    if (have_nav_) {
        const std::string ins = InsDegraded(nav_, now, config_);
        Set(next, "ins_degraded", !ins.empty(), ins);
    }
    if (have_gnss_) {
        const std::string gnss = GnssOutage(gnss_, gnss_bad_since_, now, config_);
        Set(next, "gnss_outage", !gnss.empty(), gnss);
    }
    const std::string clocks = ClocksNotLocked(clocks_);
    Set(next, "clock_not_locked", !clocks.empty(), clocks);
    if (have_daemon_) {
        const std::string disk = DiskLow(daemon_, config_);
        Set(next, "disk_low", !disk.empty(), disk);
        const std::string drops = DropsRising(drops_);
        Set(next, "drops_rising", !drops.empty(), drops);
    }
    while (!tvu_.empty() && tvu_.front().utime < now - tvu_window) tvu_.pop_front();
    const std::string tvu = TvuOverLimit(tvu_, config_);
    Set(next, "tvu_over_limit", !tvu.empty(), tvu);
    // The feed itself.
    const double quiet_s = Seconds(wall_utime - last_wall_utime_);
    const bool quiet = !feed_ended_ && last_wall_utime_ > 0 && quiet_s > config_.no_messages_s;
    Set(next, "no_messages", quiet, Fmt("no LCM message for %.1f s", quiet_s));
    active_ = std::move(next);
}

StatusSnapshot StatusTracker::Snapshot() const {
    StatusSnapshot s;
    s.data_utime = data_utime_;
    s.pings = pings_;
    s.last_ping_utime = last_ping_utime_;
    if (ping_times_.size() >= 2) {
        const double span = Seconds(ping_times_.back() - ping_times_.front());
        if (span > 0) s.ping_rate_hz = static_cast<double>(ping_times_.size() - 1) / span;
    }
    s.have_nav = have_nav_;
    s.nav = nav_;
    s.have_gnss = have_gnss_;
    s.gnss = gnss_;
    for (const Alarm& a : active_) {
        if (a.id == "gnss_outage") {
            s.gnss_outage = true;
            s.gnss_outage_s = Seconds(data_utime_ - a.since_utime) + config_.gnss_outage_s;
        }
    }
    for (const auto& [source, c] : clocks_) s.clocks.push_back(c);
    s.have_daemon = have_daemon_;
    s.daemon = daemon_;
    if (!drops_.empty()) s.daemon_drops_total = drops_.back().second;
    s.lcm_channels = channels_;
    s.alarms = active_;
    s.history.assign(history_.begin(), history_.end());
    return s;
}

}  // namespace pitmap::proc::live
