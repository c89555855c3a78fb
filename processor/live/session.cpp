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

std::string Upper(std::string s) {
    for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

constexpr double kNaNd = std::numeric_limits<double>::quiet_NaN();

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
                         const survey::SonarMount& mount,
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

void LiveSession::AddStdDevLocked(const survey::NavStdDev& s) {
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
    if (lcmlog::ChannelMatches(ch, lcmlog::kChannelInsPva, config_.nav_channel_id)) {
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
    } else if (lcmlog::ChannelMatches(ch, lcmlog::kChannelInsStdDev, config_.nav_channel_id)) {
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
    } else if (lcmlog::ChannelMatches(ch, lcmlog::kChannelGnssPosition, "")) {
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
    } else if (lcmlog::ChannelMatches(
                   ch, lcmlog::kChannelMultibeamPing, config_.sonar_channel_id)) {
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
