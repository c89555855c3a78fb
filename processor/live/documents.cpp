// SPDX-License-Identifier: MIT
// The JSON documents pitmap live serves, made from the session's state under its lock: status,
// alarms, coverage tiles and recent soundings (processor/live/server.hpp names the routes). Binary
// arrays in them are little-endian (common's ByteWriter), then base64; the page decodes them.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "common/byte_io.hpp"
#include "processor/live/session.hpp"

namespace pitmap::proc::live {

using nlohmann::json;

namespace {

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

// The INS's last solution and its sigmas (negative sigmas: not reported), or null.
json InsStatus(const StatusSnapshot& s) {
    if (!s.have_nav) return nullptr;
    const auto sigma = [](double v) { return v >= 0 ? Num(v) : json(nullptr); };
    return {{"status", InsStatusName(s.nav.ins_status)},
            {"status_code", s.nav.ins_status},
            {"position_type", s.nav.position_type},
            {"north_sigma_m", sigma(s.nav.north_sigma_m)},
            {"east_sigma_m", sigma(s.nav.east_sigma_m)},
            {"up_sigma_m", sigma(s.nav.up_sigma_m)},
            {"heading_sigma_deg", sigma(s.nav.heading_sigma_deg)},
            {"age_s", static_cast<double>(s.data_utime - s.nav.utime) * 1e-6}};
}

json GnssStatus(const StatusSnapshot& s) {
    if (!s.have_gnss) return nullptr;
    return {{"solution_status", s.gnss.solution_status},
            {"position_type", s.gnss.position_type},
            {"horizontal_sigma_m", Num(s.gnss.horizontal_sigma_m)},
            {"satellites", s.gnss.satellites},
            {"age_s", static_cast<double>(s.data_utime - s.gnss.utime) * 1e-6},
            {"outage", s.gnss_outage},
            {"outage_s", s.gnss_outage_s}};
}

json ClocksStatus(const std::vector<ClockStatusIn>& in) {
    json clocks = json::array();
    for (const ClockStatusIn& c : in) {
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
    return clocks;
}

// The acquisition daemon's health and its channels' counters, or null.
json DaemonStatus(const StatusSnapshot& s) {
    if (!s.have_daemon) return nullptr;
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
    return {{"hostname", s.daemon.hostname},
            {"uptime_s", s.daemon.uptime_s},
            {"logging", LoggingName(s.daemon.logging)},
            {"disk_free_bytes", s.daemon.disk_free_bytes},
            {"log_bytes_written", s.daemon.log_bytes_written},
            {"log_events_dropped", s.daemon.log_events_dropped},
            {"drops_total", s.daemon_drops_total},
            {"channels", ch}};
}

json LcmChannelsStatus(const StatusSnapshot& s) {
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
    return lcm;
}

json AlarmList(const std::vector<Alarm>& alarms) {
    json out = json::array();
    for (const Alarm& a : alarms) {
        out.push_back({{"id", a.id}, {"reason", a.reason}, {"since_utime", a.since_utime}});
    }
    return out;
}

}  // namespace

json LiveSession::GeorefStatusLocked() const {
    const LiveGeorefCounts& g = georef_.counts();
    return {{"nav_samples", g.nav_samples},
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
}

// The coverage grid's figures and its TVU check against the order's limit.
json LiveSession::GridStatusLocked() const {
    const CoverageStats& c = stats_cache_;
    json grid = {{"version", grid_.version()},
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
    grid["tvu"] = {{"order", hydro::ToString(grid_.order())},
                   {"limit_a_m", L.tvu_a_m},
                   {"limit_b", L.tvu_b},
                   {"min_share", config_.grid.tvu_min_share},
                   {"cells_meeting", meeting},
                   {"cells_failing", c.cells_tvu_failing},
                   {"share_meeting",
                    c.filled_cells > 0
                        ? json(static_cast<double>(meeting) / static_cast<double>(c.filled_cells))
                        : json(nullptr)},
                   {"soundings_over", c.soundings_tvu_over},
                   {"last_batch_median_tvu_m", last_batch_median_tvu_m_},
                   {"pings_with_ins_sigma", pings_with_ins_sigma_},
                   {"pings_with_model_sigma", pings_with_model_sigma_}};
    return grid;
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
    j["ins"] = InsStatus(s);
    j["gnss"] = GnssStatus(s);
    j["clocks"] = ClocksStatus(s.clocks);
    j["daemon"] = DaemonStatus(s);
    j["lcm_channels"] = LcmChannelsStatus(s);
    j["georef"] = GeorefStatusLocked();
    j["grid"] = GridStatusLocked();
    j["counts"] = {{"events", counts_.events},
                   {"decode_failures", counts_.decode_failures},
                   {"utm_failures", counts_.utm_failures}};
    j["alarms"] = AlarmList(s.alarms);
    return j;
}

json LiveSession::AlarmsJson() {
    std::lock_guard<std::mutex> lock(mutex_);
    const StatusSnapshot s = status_.Snapshot();
    json history = json::array();
    for (const AlarmEvent& e : s.history) {
        history.push_back(
            {{"id", e.id}, {"reason", e.reason}, {"raised", e.raised}, {"utime", e.utime}});
    }
    return {{"data_utime", s.data_utime}, {"active", AlarmList(s.alarms)}, {"history", history}};
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
        ByteWriter depth(depth_bytes);
        for (const GridCell& c : t->cells) {
            if (c.count == 0) {
                depth.U16Le(0xFFFF);
                count_bytes.push_back(0);
                tvu_bytes.push_back(0);
            } else {
                tvu_bytes.push_back(TvuByte(c, grid_.MeetsTvu(c)));
                const double d =
                    std::clamp(c.sum_depth_m / static_cast<double>(c.count) * 100.0, 0.0, 65534.0);
                depth.U16Le(static_cast<std::uint16_t>(std::lround(d)));
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
    ByteWriter points(pts);
    std::size_t n_sent = 0;
    const std::size_t first = recent_.size() - n_new;
    for (std::size_t k = first; k < recent_.size(); k += stride) {
        points.F32Le(recent_[k].x);
        points.F32Le(recent_[k].y);
        points.F32Le(recent_[k].z);
        ++n_sent;
    }
    std::vector<std::uint8_t> tr;
    ByteWriter track(tr);
    for (std::size_t k = track_.size() - n_track; k < track_.size(); ++k) {
        for (float v : track_[k]) track.F32Le(v);
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

}  // namespace pitmap::proc::live
