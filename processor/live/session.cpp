// SPDX-License-Identifier: MIT
#include "processor/live/session.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <pitmap/clock_sync_t.hpp>
#include <pitmap/daemon_status_t.hpp>
#include <pitmap/gnss_position_t.hpp>
#include <pitmap/ins_pva_t.hpp>
#include <pitmap/ins_stddev_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>

#include "lcmtypes/log/channels.hpp"
#include "lcmtypes/log/lcm_wire.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/lcm_messages.hpp"

namespace pitmap::proc::live {

using nlohmann::json;

namespace {

bool StartsWith(std::string_view s, std::string_view prefix) {
    return s.size() >= prefix.size() && s.substr(0, prefix.size()) == prefix;
}

std::string Upper(std::string s) {
    for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

// prefix + id, with id equal to `want` unless want is empty.
bool Matches(std::string_view channel, std::string_view prefix, const std::string& want_upper) {
    if (!StartsWith(channel, prefix)) return false;
    return want_upper.empty() || channel.substr(prefix.size()) == want_upper;
}

constexpr double kNaNd = std::numeric_limits<double>::quiet_NaN();

constexpr char kB64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string Base64(const std::vector<std::uint8_t>& in) {
    std::string out;
    out.reserve((in.size() + 2) / 3 * 4);
    std::size_t i = 0;
    for (; i + 2 < in.size(); i += 3) {
        const std::uint32_t v = (in[i] << 16) | (in[i + 1] << 8) | in[i + 2];
        out.push_back(kB64[(v >> 18) & 63]);
        out.push_back(kB64[(v >> 12) & 63]);
        out.push_back(kB64[(v >> 6) & 63]);
        out.push_back(kB64[v & 63]);
    }
    if (i < in.size()) {
        std::uint32_t v = in[i] << 16;
        if (i + 1 < in.size()) v |= in[i + 1] << 8;
        out.push_back(kB64[(v >> 18) & 63]);
        out.push_back(kB64[(v >> 12) & 63]);
        out.push_back(i + 1 < in.size() ? kB64[(v >> 6) & 63] : '=');
        out.push_back('=');
    }
    return out;
}

void PutU16(std::vector<std::uint8_t>& b, std::uint16_t v) {
    b.push_back(static_cast<std::uint8_t>(v & 0xFF));
    b.push_back(static_cast<std::uint8_t>(v >> 8));
}

void PutF32(std::vector<std::uint8_t>& b, float f) {
    std::uint32_t v;
    static_assert(sizeof(v) == sizeof(f));
    std::memcpy(&v, &f, sizeof(v));
    for (int k = 0; k < 4; ++k) b.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
}

// The tiles' TVU byte per cell: 0 = empty; else bit 7 set = the cell fails the order, bits 0-6
// = its mean TVU in kTvuStepM steps (rounded, at least 1 so a filled cell is never 0, at most
// 127 = 2.54 m or more).
constexpr double kTvuStepM = 0.02;
std::uint8_t TvuByte(const GridCell& c, bool meets) {
    const double mean = static_cast<double>(c.sum_tvu_m) / static_cast<double>(c.count);
    const long q =
        std::isfinite(mean) ? std::lround(std::clamp(mean / kTvuStepM, 1.0, 127.0)) : 127;
    return static_cast<std::uint8_t>(q | (meets ? 0 : 0x80));
}

// A finite JSON number or null.
json Num(double v) {
    return std::isfinite(v) ? json(v) : json(nullptr);
}

std::string UtcStamp(std::int64_t utime) {
    const std::time_t t = static_cast<std::time_t>(utime / 1'000'000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof(buf), "%Y%m%dT%H%M%SZ", &tm);
    return buf;
}

}  // namespace

std::vector<std::string> LiveConfig::Validate() const {
    std::vector<std::string> p = grid.Validate();
    for (auto& s : status.Validate()) p.push_back(s);
    for (auto& s : georef.Validate()) p.push_back(s);
    if (max_recent_soundings < 1) p.push_back("live.max_recent_soundings must be >= 1");
    if (max_track_points < 1) p.push_back("live.max_track_points must be >= 1");
    if (!(process_interval_s >= 0) || !std::isfinite(process_interval_s))
        p.push_back("live.process_interval_s must be >= 0");
    if (!(holiday_refresh_s >= 0) || !std::isfinite(holiday_refresh_s))
        p.push_back("live.holiday_refresh_s must be >= 0");
    for (auto& s : tpu.Validate()) p.push_back("live." + s);
    if (!(ins_sigma_max_age_s > 0) || !std::isfinite(ins_sigma_max_age_s))
        p.push_back("live.ins_sigma_max_age_s must be > 0");
    return p;
}

LiveSession::LiveSession(const LiveConfig& config,
                         const georef::SonarMount& mount,
                         bool mount_known)
    : config_(config),
      mount_known_(mount_known),
      georef_(config.georef, mount),
      grid_(config.grid),
      status_(config.status),
      fallback_sigma_(hydro::FallbackSigma(config.tpu.model)) {
    config_.nav_channel_id = Upper(config_.nav_channel_id);
    config_.sonar_channel_id = Upper(config_.sonar_channel_id);
    config_.tpu.num_threads = 1;
}

void LiveSession::AddStdDevLocked(const georef::NavStdDev& s) {
    if (s.utime_gps <= 0) return;
    if (stddevs_.empty() || s.utime_gps > stddevs_.back().utime_gps) {
        stddevs_.push_back(s);
    } else {
        // INSPVAX and INSSTDEV of one epoch: the first is kept; a late record goes in place.
        auto at = std::lower_bound(
            stddevs_.begin(), stddevs_.end(), s.utime_gps, [](const auto& d, std::int64_t t) {
                return d.utime_gps < t;
            });
        if (at != stddevs_.end() && at->utime_gps == s.utime_gps) return;
        stddevs_.insert(at, s);
    }
    // Records older than the navigation the georeferencing keeps (plus the sigma's reach) can
    // no longer be used: dropped once they are half of the vector (amortised O(1)).
    const auto keep =
        static_cast<std::int64_t>((config_.georef.nav_keep_s + config_.ins_sigma_max_age_s) * 1e6);
    const std::int64_t oldest = stddevs_.back().utime_gps - keep;
    auto stale = std::lower_bound(
        stddevs_.begin(), stddevs_.end(), oldest, [](const auto& d, std::int64_t t) {
            return d.utime_gps < t;
        });
    if (static_cast<std::size_t>(stale - stddevs_.begin()) * 2 > stddevs_.size() ||
        stddevs_.size() > 100'000) {
        stddevs_.erase(stddevs_.begin(), std::max(stale, stddevs_.end() - 100'000));
    }
}

void LiveSession::OnEvent(const std::string& channel,
                          const void* data,
                          std::size_t size,
                          std::int64_t wall_utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_.events;
    const std::string_view ch = channel;
    const auto reject = [&] {
        ++counts_.decode_failures;
        status_.OnDecodeFailure(channel);
        status_.OnMessage(channel, 0, size, wall_utime);
    };
    // The host time of the message is its first field in every pitmap type; it is read after
    // decoding, so a message that does not decode counts under its channel without a time.
    std::int64_t utime = 0;
    if (Matches(ch, lcmlog::kChannelInsPva, config_.nav_channel_id)) {
        pitmap::ins_pva_t m;
        if (!lcmlog::DecodeChecked(m, data, size)) return reject();
        utime = m.utime;
        georef_.AddNav(io::NavSampleOf(m));
        NavStatusIn n;
        n.utime = m.utime;
        n.utime_gps = m.utime_gps;
        n.ins_status = m.ins_status;
        n.position_type = m.position_type;
        if (m.has_stddev) {
            AddStdDevLocked(io::NavStdDevOf(m));
            n.north_sigma_m = std::isfinite(m.latitude_stddev_m) ? m.latitude_stddev_m : -1.f;
            n.east_sigma_m = std::isfinite(m.longitude_stddev_m) ? m.longitude_stddev_m : -1.f;
            n.up_sigma_m = std::isfinite(m.height_stddev_m) ? m.height_stddev_m : -1.f;
            n.heading_sigma_deg = std::isfinite(m.azimuth_stddev_deg) ? m.azimuth_stddev_deg : -1.f;
        } else {
            // INSPVAS carries no sigmas: keep the last ones (from INSPVAX or INSSTDEV).
            const NavStatusIn& last = status_.nav();
            n.north_sigma_m = last.north_sigma_m;
            n.east_sigma_m = last.east_sigma_m;
            n.up_sigma_m = last.up_sigma_m;
            n.heading_sigma_deg = last.heading_sigma_deg;
        }
        status_.OnNav(n);
    } else if (Matches(ch, lcmlog::kChannelInsStdDev, config_.nav_channel_id)) {
        pitmap::ins_stddev_t m;
        if (!lcmlog::DecodeChecked(m, data, size)) return reject();
        utime = m.utime;
        AddStdDevLocked(io::NavStdDevOf(m));
        NavStatusIn n = status_.nav();
        if (n.utime != 0) {
            n.north_sigma_m = m.latitude_stddev_m;
            n.east_sigma_m = m.longitude_stddev_m;
            n.up_sigma_m = m.height_stddev_m;
            n.heading_sigma_deg = m.azimuth_stddev_deg;
            status_.OnNav(n);
        }
    } else if (StartsWith(ch, lcmlog::kChannelGnssPosition)) {
        pitmap::gnss_position_t m;
        if (!lcmlog::DecodeChecked(m, data, size)) return reject();
        utime = m.utime;
        GnssStatusIn g;
        g.utime = m.utime;
        g.solution_status = m.solution_status;
        g.position_type = m.position_type;
        g.horizontal_sigma_m = std::hypot(m.latitude_stddev_m, m.longitude_stddev_m);
        g.satellites = m.num_svs_in_solution;
        status_.OnGnss(g);
    } else if (Matches(ch, lcmlog::kChannelMultibeamPing, config_.sonar_channel_id)) {
        pitmap::multibeam_ping_t m;
        if (!lcmlog::DecodeChecked(m, data, size)) return reject();
        utime = m.utime;
        georef_.AddPing(io::PingHeaderOf(m), m.range_counts.data(), m.range_counts.size());
        status_.OnPing({m.utime, m.utime_gps, m.num_beams});
    } else if (ch == lcmlog::kChannelClockSync) {
        pitmap::clock_sync_t m;
        if (!lcmlog::DecodeChecked(m, data, size)) return reject();
        utime = m.utime;
        status_.OnClock({m.utime,
                         m.source,
                         m.state,
                         static_cast<double>(m.offset_us),
                         m.offset_stddev_us,
                         m.drift_ppm,
                         m.leap_seconds});
    } else if (ch == lcmlog::kChannelDaemonStatus) {
        pitmap::daemon_status_t m;
        if (!lcmlog::DecodeChecked(m, data, size)) return reject();
        utime = m.utime;
        DaemonStatusIn d;
        d.utime = m.utime;
        d.hostname = m.hostname;
        d.uptime_s = m.uptime_s;
        d.logging = m.logging;
        d.disk_free_bytes = m.disk_free_bytes;
        d.log_events_dropped = m.log_events_dropped;
        d.log_bytes_written = m.log_bytes_written;
        for (const pitmap::channel_status_t& c : m.channels) {
            ChannelStatusIn ci;
            ci.name = c.name;
            ci.protocol = c.protocol;
            ci.state = c.state;
            ci.bytes = c.bytes;
            ci.frames = c.frames;
            ci.crc_failures = c.crc_failures;
            ci.decode_errors = c.decode_errors;
            ci.queue_drops = c.queue_drops;
            ci.kernel_drops = c.kernel_drops;
            ci.last_message_age_ms = c.last_message_age_ms;
            d.channels.push_back(std::move(ci));
        }
        status_.OnDaemon(d);
        status_.OnClock({m.host_clock.utime,
                         m.host_clock.source,
                         m.host_clock.state,
                         static_cast<double>(m.host_clock.offset_us),
                         m.host_clock.offset_stddev_us,
                         m.host_clock.drift_ppm,
                         m.host_clock.leap_seconds});
    }
    status_.OnMessage(channel, utime, size, wall_utime);
    data_utime_ = std::max(data_utime_, utime > 1'000'000'000'000'000LL ? utime : 0);
}

void LiveSession::Tick(std::int64_t wall_utime, bool force) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto interval = static_cast<std::int64_t>(config_.process_interval_s * 1e6);
    const bool process = force || data_utime_ - last_process_data_utime_ >= interval;
    if (process) {
        last_process_data_utime_ = data_utime_;
        ProcessLocked();
    }
    // The alarms at most every 100 ms of wall time, or with every batch.
    if (process || wall_utime - last_evaluate_wall_utime_ >= 100'000 ||
        wall_utime < last_evaluate_wall_utime_) {
        last_evaluate_wall_utime_ = wall_utime;
        status_.Evaluate(wall_utime);
    }
}

void LiveSession::ProcessLocked() {
    for (;;) {
        auto b = georef_.Process();
        if (!b) {
            ++counts_.utm_failures;
            return;
        }
        if (!b->has_value()) return;
        const LiveBatch& batch = **b;
        const georef::GeorefPoints& P = batch.result.points;
        if (P.size() == 0 && batch.result.pings.empty()) continue;
        ++version_;
        if (utm_zone_ == 0) {
            utm_zone_ = batch.utm.zone;
            utm_northern_ = batch.utm.northern;
        }
        // TVU of every sounding: the shore's TPU model on this batch, with the INS's own sigma
        // nearest each ping (else the error model's).
        const auto& pings = batch.result.pings;
        ping_sigma_.resize(pings.size());
        for (std::size_t k = 0; k < pings.size(); ++k) {
            bool own = false;
            ping_sigma_[k] = hydro::InsSigmaAt(
                stddevs_, pings[k].utime_gps, config_.ins_sigma_max_age_s, fallback_sigma_, &own);
            ++(own ? pings_with_ins_sigma_ : pings_with_model_sigma_);
        }
        const hydro::TpuResult tpu =
            hydro::ComputeTpu(batch.result, batch.result.mount, ping_sigma_, config_.tpu);
        if (P.size() > 0) last_batch_median_tvu_m_ = tpu.median_tvu_95_m;
        new_cells_.clear();
        for (std::size_t j = 0; j < P.size(); ++j) {
            const Eigen::Vector3d& u = batch.utm.easting_northing_height[j];
            const double depth = pings[P.ping[j]].sensor_world.z() - P.position_world[j].z();
            const double tvu = j < tpu.tvu_95_m.size() ? tpu.tvu_95_m[j] : kNaNd;
            if (grid_.Add(u.x(), u.y(), u.z(), depth, tvu, version_)) {
                new_cells_.emplace_back(grid_.CellIndex(u.x()), grid_.CellIndex(u.y()));
            }
            if (!have_ref_) {
                // The page's frame: the corner of the first sounding's cell.
                ref_ix_ = grid_.CellIndex(u.x());
                ref_iy_ = grid_.CellIndex(u.y());
                have_ref_ = true;
            }
            const double x0 = static_cast<double>(ref_ix_) * config_.grid.cell_size_m;
            const double y0 = static_cast<double>(ref_iy_) * config_.grid.cell_size_m;
            recent_.push_back({static_cast<float>(u.x() - x0),
                               static_cast<float>(u.y() - y0),
                               static_cast<float>(u.z())});
            ++sounding_seq_;
        }
        while (recent_.size() > config_.max_recent_soundings) recent_.pop_front();
        // The new cells' TVU status once the whole batch is in them.
        TvuCellsIn t;
        t.utime = data_utime_;
        t.order = hydro::ToString(grid_.order());
        for (const auto& [ix, iy] : new_cells_) {
            const GridCell* c = grid_.Cell(ix, iy);
            if (c == nullptr || c->count == 0) continue;
            ++t.new_cells;
            if (!grid_.MeetsTvu(*c)) ++t.failing;
        }
        status_.OnTvuCells(t);
        if (have_ref_) {
            const double x0 = static_cast<double>(ref_ix_) * config_.grid.cell_size_m;
            const double y0 = static_cast<double>(ref_iy_) * config_.grid.cell_size_m;
            // The track in the same frame: each ping's transducer, through the UTM Jacobian of
            // the batch (ToUtm's own mapping, so the track and soundings agree).
            // The first sounding of each ping minus its offset from the transducer; pings
            // without soundings are left out.
            std::size_t last_ping = SIZE_MAX;
            for (std::size_t j = 0; j < P.size(); ++j) {
                if (P.ping[j] == last_ping) continue;
                last_ping = P.ping[j];
                const Eigen::Vector3d& u = batch.utm.easting_northing_height[j];
                const Eigen::Vector3d d =
                    P.position_world[j] - batch.result.pings[P.ping[j]].sensor_world;
                track_.push_back({static_cast<float>(u.x() - d.x() - x0),
                                  static_cast<float>(u.y() - d.y() - y0),
                                  static_cast<float>(u.z() - d.z())});
            }
            while (track_.size() > config_.max_track_points) track_.pop_front();
        }
    }
}

void LiveSession::RefreshHolidaysLocked() {
    // Holidays visit every empty cell of the grid: at most once per holiday_refresh_s of wall
    // time, so the page's polls cost little.
    if (holidays_version_ == version_) return;
    const auto now = std::chrono::steady_clock::now();
    if (holidays_version_ != ~0ULL &&
        now - holidays_computed_ < std::chrono::duration<double>(config_.holiday_refresh_s)) {
        return;
    }
    holidays_version_ = version_;
    holidays_computed_ = now;
    stats_cache_ = grid_.Stats(false);
    holidays_ = grid_.Holidays(5000, &holidays_total_);
    stats_cache_.holidays = holidays_total_;
}

void LiveSession::MarkReplay() {
    std::lock_guard<std::mutex> lock(mutex_);
    replay_ = true;
}

void LiveSession::MarkReplayFinished() {
    std::lock_guard<std::mutex> lock(mutex_);
    replay_ = true;
    replay_finished_ = true;
    status_.SetFeedEnded();
}

json LiveSession::StatusJson(std::int64_t wall_utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    RefreshHolidaysLocked();
    const StatusSnapshot s = status_.Snapshot();
    json j;
    j["wall_utime"] = wall_utime;
    j["source"] = {{"kind", replay_ ? "replay" : "lcm"}, {"finished", replay_finished_}};
    j["data_utime"] = s.data_utime;
    j["pings"] = s.pings;
    j["ping_rate_hz"] = s.ping_rate_hz;
    j["last_ping_age_s"] = s.last_ping_utime > 0
                               ? json(static_cast<double>(s.data_utime - s.last_ping_utime) * 1e-6)
                               : json(nullptr);
    if (s.have_nav) {
        j["ins"] = {
            {"status", InsStatusName(s.nav.ins_status)},
            {"status_code", s.nav.ins_status},
            {"position_type", s.nav.position_type},
            {"north_sigma_m", s.nav.north_sigma_m >= 0 ? Num(s.nav.north_sigma_m) : json(nullptr)},
            {"east_sigma_m", s.nav.east_sigma_m >= 0 ? Num(s.nav.east_sigma_m) : json(nullptr)},
            {"up_sigma_m", s.nav.up_sigma_m >= 0 ? Num(s.nav.up_sigma_m) : json(nullptr)},
            {"heading_sigma_deg",
             s.nav.heading_sigma_deg >= 0 ? Num(s.nav.heading_sigma_deg) : json(nullptr)},
            {"age_s", static_cast<double>(s.data_utime - s.nav.utime) * 1e-6}};
    } else {
        j["ins"] = nullptr;
    }
    if (s.have_gnss) {
        j["gnss"] = {{"solution_status", s.gnss.solution_status},
                     {"position_type", s.gnss.position_type},
                     {"horizontal_sigma_m", Num(s.gnss.horizontal_sigma_m)},
                     {"satellites", s.gnss.satellites},
                     {"age_s", static_cast<double>(s.data_utime - s.gnss.utime) * 1e-6},
                     {"outage", s.gnss_outage},
                     {"outage_s", s.gnss_outage_s}};
    } else {
        j["gnss"] = nullptr;
    }
    json clocks = json::array();
    for (const ClockStatusIn& c : s.clocks) {
        // clock_sync_t's offset maps Unix microseconds to GPS microseconds since 1980: without
        // the epochs and the leap seconds it is what the crew wants, UTC minus the input clock.
        constexpr double kGpsEpochUnixUs = 315'964'800e6;
        clocks.push_back(
            {{"source", ClockSourceName(c.source)},
             {"state", ClockStateName(c.state)},
             {"offset_us", c.offset_us},
             {"utc_minus_clock_us", c.offset_us + kGpsEpochUnixUs - c.leap_seconds * 1e6},
             {"stddev_us", Num(c.stddev_us)},
             {"drift_ppm", Num(c.drift_ppm)}});
    }
    j["clocks"] = clocks;
    if (s.have_daemon) {
        json ch = json::array();
        for (const ChannelStatusIn& c : s.daemon.channels) {
            ch.push_back({{"name", c.name},
                          {"protocol", c.protocol},
                          {"state", ChannelStateName(c.state)},
                          {"bytes", c.bytes},
                          {"frames", c.frames},
                          {"crc_failures", c.crc_failures},
                          {"decode_errors", c.decode_errors},
                          {"queue_drops", c.queue_drops},
                          {"kernel_drops", c.kernel_drops},
                          {"last_message_age_ms", c.last_message_age_ms}});
        }
        j["daemon"] = {{"hostname", s.daemon.hostname},
                       {"uptime_s", s.daemon.uptime_s},
                       {"logging", LoggingName(s.daemon.logging)},
                       {"disk_free_bytes", s.daemon.disk_free_bytes},
                       {"log_bytes_written", s.daemon.log_bytes_written},
                       {"log_events_dropped", s.daemon.log_events_dropped},
                       {"drops_total", s.daemon_drops_total},
                       {"channels", ch}};
    } else {
        j["daemon"] = nullptr;
    }
    json lcm = json::object();
    for (const auto& [name, c] : s.lcm_channels) {
        lcm[name] = {
            {"messages", c.messages},
            {"bytes", c.bytes},
            {"decode_failures", c.decode_failures},
            {"age_s",
             c.last_utime > 0 ? json(static_cast<double>(s.data_utime - c.last_utime) * 1e-6)
                              : json(nullptr)}};
    }
    j["lcm_channels"] = lcm;
    const LiveGeorefCounts& g = georef_.counts();
    j["georef"] = {{"nav_samples", g.nav_samples},
                   {"nav_refused", g.nav_refused},
                   {"pings_in", g.pings_in},
                   {"pings_refused", g.pings_refused},
                   {"pings_waiting", georef_.pending()},
                   {"pings_dropped_waiting", g.pings_dropped_waiting},
                   {"pings_georeferenced", g.georef.pings_georeferenced},
                   {"pings_outside_nav", g.georef.pings_outside_nav},
                   {"pings_in_nav_gap", g.georef.pings_in_nav_gap},
                   {"soundings", g.georef.points},
                   {"no_detection", g.georef.no_detection},
                   {"spikes", g.georef.spikes},
                   {"mount_known", mount_known_}};
    const CoverageStats& c = stats_cache_;
    j["grid"] = {{"version", grid_.version()},
                 {"cell_size_m", config_.grid.cell_size_m},
                 {"soundings", c.soundings},
                 {"soundings_dropped", c.soundings_dropped},
                 {"filled_cells", c.filled_cells},
                 {"holidays", c.holidays},
                 {"tiles", c.tiles},
                 {"covered_area_m2", c.covered_area_m2},
                 {"min_depth_m", c.min_depth_m},
                 {"max_depth_m", c.max_depth_m},
                 {"utm_zone", utm_zone_},
                 {"northern", utm_northern_}};
    const hydro::S44Limits& L = hydro::LimitsOf(grid_.order());
    const std::int64_t meeting = c.filled_cells - c.cells_tvu_failing;
    j["grid"]["tvu"] = {{"order", hydro::ToString(grid_.order())},
                        {"limit_a_m", L.tvu_a_m},
                        {"limit_b", L.tvu_b},
                        {"min_share", config_.grid.tvu_min_share},
                        {"cells_meeting", meeting},
                        {"cells_failing", c.cells_tvu_failing},
                        {"share_meeting",
                         c.filled_cells > 0 ? json(static_cast<double>(meeting) /
                                                   static_cast<double>(c.filled_cells))
                                            : json(nullptr)},
                        {"soundings_over", c.soundings_tvu_over},
                        {"last_batch_median_tvu_m", last_batch_median_tvu_m_},
                        {"pings_with_ins_sigma", pings_with_ins_sigma_},
                        {"pings_with_model_sigma", pings_with_model_sigma_}};
    j["counts"] = {{"events", counts_.events},
                   {"decode_failures", counts_.decode_failures},
                   {"utm_failures", counts_.utm_failures}};
    json alarms = json::array();
    for (const Alarm& a : s.alarms) {
        alarms.push_back({{"id", a.id}, {"reason", a.reason}, {"since_utime", a.since_utime}});
    }
    j["alarms"] = alarms;
    return j;
}

json LiveSession::AlarmsJson() {
    std::lock_guard<std::mutex> lock(mutex_);
    const StatusSnapshot s = status_.Snapshot();
    json active = json::array(), history = json::array();
    for (const Alarm& a : s.alarms) {
        active.push_back({{"id", a.id}, {"reason", a.reason}, {"since_utime", a.since_utime}});
    }
    for (const AlarmEvent& e : s.history) {
        history.push_back(
            {{"id", e.id}, {"reason", e.reason}, {"raised", e.raised}, {"utime", e.utime}});
    }
    return {{"data_utime", s.data_utime}, {"active", active}, {"history", history}};
}

json LiveSession::TilesJson(std::uint64_t since, std::int64_t budget_bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    RefreshHolidaysLocked();
    json tiles = json::array();
    const auto changed = grid_.TilesSince(since);
    std::int64_t used = 600;  // the envelope
    std::size_t sent = 0;
    std::uint64_t next_since = since;
    std::vector<std::uint8_t> depth_bytes, count_bytes, tvu_bytes;
    for (const GridTile* t : changed) {
        depth_bytes.clear();
        count_bytes.clear();
        tvu_bytes.clear();
        for (const GridCell& c : t->cells) {
            if (c.count == 0) {
                PutU16(depth_bytes, 0xFFFF);
                count_bytes.push_back(0);
                tvu_bytes.push_back(0);
            } else {
                tvu_bytes.push_back(TvuByte(c, grid_.MeetsTvu(c)));
                const double d =
                    std::clamp(c.sum_depth_m / static_cast<double>(c.count) * 100.0, 0.0, 65534.0);
                PutU16(depth_bytes, static_cast<std::uint16_t>(std::lround(d)));
                count_bytes.push_back(
                    static_cast<std::uint8_t>(std::min<std::uint32_t>(c.count, 255)));
            }
        }
        json tj = {{"tx", t->tx},
                   {"ty", t->ty},
                   {"v", t->version},
                   {"depth_cm", Base64(depth_bytes)},
                   {"count", Base64(count_bytes)},
                   {"tvu", Base64(tvu_bytes)}};
        const auto size = static_cast<std::int64_t>(tj.dump().size()) + 1;
        if (budget_bytes >= 0 && used + size > budget_bytes) break;
        used += size;
        tiles.push_back(std::move(tj));
        ++sent;
        next_since = t->version;
    }
    const bool complete = sent == changed.size();
    if (complete) next_since = std::max<std::uint64_t>(since, grid_.version());
    json holidays = json::array();
    std::size_t n_holidays = 0;
    for (const auto& [ix, iy] : holidays_) {
        if (budget_bytes >= 0 && used + 16 > budget_bytes) break;
        holidays.push_back({ix - ref_ix_, iy - ref_iy_});
        used += 16;
        ++n_holidays;
    }
    const bool thinned = !complete || n_holidays < holidays_.size();
    return {
        {"version", grid_.version()},
        {"next_since", next_since},
        {"tile_cells", kTileCells},
        {"cell_size_m", config_.grid.cell_size_m},
        {"ref_ix", ref_ix_},
        {"ref_iy", ref_iy_},
        {"tiles", tiles},
        {"pending_tiles", changed.size() - sent},
        {"holidays", holidays},
        {"holidays_total", holidays_total_},
        {"thinned", thinned},
        {"tvu",
         {{"order", hydro::ToString(grid_.order())},
          {"limit_a_m", hydro::LimitsOf(grid_.order()).tvu_a_m},
          {"limit_b", hydro::LimitsOf(grid_.order()).tvu_b},
          {"min_share", config_.grid.tvu_min_share},
          {"step_m", kTvuStepM}}},
        {"stats",
         {{"filled_cells", stats_cache_.filled_cells},
          {"cells_tvu_failing", stats_cache_.cells_tvu_failing},
          {"min_depth_m", stats_cache_.min_depth_m},
          {"max_depth_m", stats_cache_.max_depth_m},
          {"min_x", static_cast<double>(stats_cache_.min_ix - ref_ix_) * config_.grid.cell_size_m},
          {"max_x",
           static_cast<double>(stats_cache_.max_ix - ref_ix_ + 1) * config_.grid.cell_size_m},
          {"min_y", static_cast<double>(stats_cache_.min_iy - ref_iy_) * config_.grid.cell_size_m},
          {"max_y",
           static_cast<double>(stats_cache_.max_iy - ref_iy_ + 1) * config_.grid.cell_size_m}}}};
}

json LiveSession::SoundingsJson(std::uint64_t since, std::int64_t budget_bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    // Soundings newer than `since` that the ring still holds.
    const std::uint64_t oldest = sounding_seq_ - recent_.size();  // sequence before recent_[0]
    const std::uint64_t from = std::max(since, oldest);
    const std::size_t n_new =
        static_cast<std::size_t>(sounding_seq_ - std::min(from, sounding_seq_));
    // 12 bytes per sounding, 16 in base64; the track's last 500 points, 16 bytes in base64 each.
    const std::size_t n_track = std::min<std::size_t>(track_.size(), 500);
    std::int64_t room =
        budget_bytes < 0 ? INT64_MAX : budget_bytes - 300 - static_cast<std::int64_t>(n_track) * 16;
    std::size_t stride = 1;
    if (n_new > 0 && room < static_cast<std::int64_t>(n_new) * 16) {
        stride = room <= 16 ? n_new + 1
                            : static_cast<std::size_t>(std::ceil(static_cast<double>(n_new) * 16.0 /
                                                                 static_cast<double>(room)));
    }
    std::vector<std::uint8_t> pts;
    std::size_t n_sent = 0;
    const std::size_t first = recent_.size() - n_new;
    for (std::size_t k = first; k < recent_.size(); k += stride) {
        PutF32(pts, recent_[k].x);
        PutF32(pts, recent_[k].y);
        PutF32(pts, recent_[k].z);
        ++n_sent;
    }
    std::vector<std::uint8_t> tr;
    for (std::size_t k = track_.size() - n_track; k < track_.size(); ++k) {
        for (float v : track_[k]) PutF32(tr, v);
    }
    return {{"seq", sounding_seq_},
            {"new", n_new},
            {"sent", n_sent},
            {"stride", n_new > 0 ? stride : 1},
            {"thinned", n_sent < n_new},
            {"cell_size_m", config_.grid.cell_size_m},
            {"points_xyz_f32", Base64(pts)},
            {"track_xyz_f32", Base64(tr)}};
}

Expected<std::string> LiveSession::WriteSnapshot(const std::string& dir) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (utm_zone_ == 0) return Error{"nothing georeferenced yet: no grid to write"};
    auto raster = grid_.ToRaster(utm_zone_, utm_northern_);
    if (!raster) return raster.error();
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) return Error{"cannot create " + dir + ": " + ec.message()};
    const std::string base = dir + "/live_grid_" + UtcStamp(data_utime_);
    raster->metadata.emplace_back("pitmap_cell_size_m", std::to_string(config_.grid.cell_size_m));
    if (auto w = io::WriteCogGeoTiff(base + ".tif", *raster); !w) return w.error();
    return base + ".tif";
}

SessionCounts LiveSession::counts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return counts_;
}

CoverageStats LiveSession::GridStats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return grid_.Stats();
}

std::uint64_t LiveSession::grid_version() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return grid_.version();
}

}  // namespace pitmap::proc::live
