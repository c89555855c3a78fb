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

void StatusTracker::Evaluate(std::int64_t wall_utime) {
    const std::int64_t now = data_utime_;
    const auto window = static_cast<std::int64_t>(config_.rate_window_s * 1e6);
    while (!ping_times_.empty() && ping_times_.front() < now - window) ping_times_.pop_front();
    const auto drops_window = static_cast<std::int64_t>(config_.drops_window_s * 1e6);
    // Keep one sample older than the window as the baseline.
    while (drops_.size() > 1 && drops_[1].first <= now - drops_window) drops_.pop_front();

    std::vector<Alarm> next;
    if (now == 0) {
        active_.clear();
        return;
    }
    // Sonar.
    {
        std::string reason;
        const double quiet_s =
            Seconds(now - (last_ping_utime_ > 0 ? last_ping_utime_ : first_utime_));
        if (quiet_s > config_.sonar_silent_s) {
            reason = last_ping_utime_ > 0
                         ? Fmt("no ping for %.1f s", quiet_s)
                         : Fmt("no ping since the first message (%.1f s)", quiet_s);
        }
        if (have_daemon_) {
            for (const ChannelStatusIn& c : daemon_.channels) {
                if (c.protocol.rfind("deltat", 0) != 0) continue;
                if (c.state == kChannelSilent || c.state == kChannelDisconnected) {
                    if (!reason.empty()) reason += "; ";
                    reason += "daemon reports channel " + c.name + " " + ChannelStateName(c.state);
                }
            }
        }
        Set(next, "sonar_silent", !reason.empty(), reason);
    }
    // INS.
    if (have_nav_) {
        std::string reason;
        if (nav_.ins_status != kInsSolutionGood) {
            reason = std::string("INS status ") + InsStatusName(nav_.ins_status);
        }
        if (nav_.north_sigma_m >= 0 && nav_.east_sigma_m >= 0) {
            const double h = std::hypot(nav_.north_sigma_m, nav_.east_sigma_m);
            if (h > config_.ins_position_sigma_max_m) {
                if (!reason.empty()) reason += "; ";
                reason +=
                    Fmt("horizontal sigma %.2f m > %.2f m", h, config_.ins_position_sigma_max_m);
            }
        }
        if (nav_.heading_sigma_deg > config_.ins_heading_sigma_max_deg) {
            if (!reason.empty()) reason += "; ";
            reason += Fmt("heading sigma %.2f deg > %.2f deg",
                          nav_.heading_sigma_deg,
                          config_.ins_heading_sigma_max_deg);
        }
        const double age_s = Seconds(now - nav_.utime);
        if (age_s > config_.sonar_silent_s) {
            if (!reason.empty()) reason += "; ";
            reason += Fmt("no INS solution for %.1f s", age_s);
        }
        Set(next, "ins_degraded", !reason.empty(), reason);
    }
    // GNSS.
    if (have_gnss_) {
        std::string reason;
        const double age_s = Seconds(now - gnss_.utime);
        if (age_s > config_.gnss_outage_s) {
            reason = Fmt("no GNSS position for %.1f s", age_s);
        } else if (gnss_bad_since_ != 0 && Seconds(now - gnss_bad_since_) > config_.gnss_outage_s) {
            reason = Fmt("GNSS solution not computed for %.1f s (solution status %.0f)",
                         Seconds(now - gnss_bad_since_),
                         gnss_.solution_status);
        }
        Set(next, "gnss_outage", !reason.empty(), reason);
    }
    // Clocks: every model the daemon runs, except the sonar header clock of a daemon that
    // stamps pings on receipt (it reports NO_TIME for it by design).
    {
        std::string reason;
        for (const auto& [source, c] : clocks_) {
            if (source == kSourceSonarHeader && c.state == 0) continue;
            if (c.state != kClockLocked) {
                if (!reason.empty()) reason += "; ";
                reason += std::string(ClockSourceName(source)) + " clock " +
                          ClockStateName(c.state) + Fmt(" (sigma %.0f us)", c.stddev_us);
            }
        }
        Set(next, "clock_not_locked", !reason.empty(), reason);
    }
    // Disk and drops.
    if (have_daemon_) {
        std::string reason;
        if (daemon_.disk_free_bytes >= 0 && daemon_.disk_free_bytes < config_.disk_low_bytes) {
            reason = Fmt("%.0f MB free < %.0f MB",
                         static_cast<double>(daemon_.disk_free_bytes) / 1e6,
                         static_cast<double>(config_.disk_low_bytes) / 1e6);
        }
        if (daemon_.logging == kLoggingDiskGuard || daemon_.logging == kLoggingError) {
            if (!reason.empty()) reason += "; ";
            reason += std::string("logging stopped: ") + LoggingName(daemon_.logging);
        }
        Set(next, "disk_low", !reason.empty(), reason);
        std::string drops;
        if (drops_.size() >= 2 && drops_.back().second > drops_.front().second) {
            drops = Fmt("%.0f drops in the last %.0f s",
                        static_cast<double>(drops_.back().second - drops_.front().second),
                        Seconds(drops_.back().first - drops_.front().first));
        }
        Set(next, "drops_rising", !drops.empty(), drops);
    }
    // TVU of the new coverage.
    {
        const auto tvu_window = static_cast<std::int64_t>(config_.tvu_window_s * 1e6);
        while (!tvu_.empty() && tvu_.front().utime < now - tvu_window) tvu_.pop_front();
        std::int64_t fresh = 0, failing = 0;
        for (const TvuCellsIn& t : tvu_) {
            fresh += t.new_cells;
            failing += t.failing;
        }
        const double pct =
            fresh > 0 ? 100.0 * static_cast<double>(failing) / static_cast<double>(fresh) : 0.0;
        const bool on = fresh >= config_.tvu_min_new_cells && pct > config_.tvu_alarm_percent;
        std::string reason;
        if (on) {
            char buf[200];
            std::snprintf(buf,
                          sizeof buf,
                          " limit in %.0f %% of new cells (%lld of %lld first filled in the last "
                          "%.0f s; alarm above %.0f %%)",
                          pct,
                          static_cast<long long>(failing),
                          static_cast<long long>(fresh),
                          config_.tvu_window_s,
                          config_.tvu_alarm_percent);
            reason = "TVU over the order " + tvu_.back().order + buf;
        }
        Set(next, "tvu_over_limit", on, reason);
    }
    // The feed itself.
    {
        const double quiet_s = Seconds(wall_utime - last_wall_utime_);
        const bool on = !feed_ended_ && last_wall_utime_ > 0 && quiet_s > config_.no_messages_s;
        Set(next, "no_messages", on, Fmt("no LCM message for %.1f s", quiet_s));
    }
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
