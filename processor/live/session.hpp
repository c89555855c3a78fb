// SPDX-License-Identifier: MIT
// The live survey state behind `pitmap live`: LCM events in (from a subscription or a log
// file, the same path), JSON documents and grid products out.
//
// OnEvent() takes one LCM event (channel, encoded bytes): every message is bounds-checked
// (lcmlog::DecodeChecked) before it is decoded, counted per channel, and routed by the channel
// names of the vehicle-shore contract (lcmtypes/log/channels.hpp): INS_PVA_ and MULTIBEAM_PING_
// feed the incremental georeferencing (live_georef.hpp), INS_STDDEV_, GNSS_POSITION_,
// CLOCK_SYNC and DAEMON_STATUS the status and alarms (status.hpp). Tick() georeferences what
// navigation now brackets, computes each sounding's TVU with the shore processor's TPU model
// (processor/hydro/tpu.hpp ComputeTpu, the vehicle's error model, the INS's own sigmas from
// INSPVAX / INSSTDEV nearest each ping, as the grid stage does), puts the soundings into the
// coverage grid (coverage_grid.hpp: depth, density, TVU status against the S-44 order) and the
// recent-soundings ring, and re-evaluates the alarms (tvu_over_limit among them). The TPU's
// latency term takes the vehicle's motion from the neighbouring pings of the same batch (a
// batch of one ping has none: that term is then zero; a few millimetres at survey speed).
// The JSON documents (status, alarms, tiles, soundings) fit a byte budget given by the caller
// (budget.hpp) and say when they were thinned.
// Thread safety: every public member locks one mutex; the LCM thread and the HTTP threads may
// call concurrently.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/hydro/tpu.hpp"
#include "processor/live/coverage_grid.hpp"
#include "processor/live/live_georef.hpp"
#include "processor/live/status.hpp"

namespace pitmap::proc::live {

struct LiveConfig {
    CoverageGridConfig grid;
    StatusConfig status;
    LiveGeorefConfig georef;
    // TPU: the vehicle's sensor error model (vehicle.yaml `uncertainty:`), the nominal sound
    // speed; num_threads is forced to 1 (the LCM thread computes it).
    hydro::TpuConfig tpu;
    double ins_sigma_max_age_s = 5.0;  // INS sigma records further from a ping: the model's
    std::string nav_channel_id;        // "" = every INS channel
    std::string sonar_channel_id;      // "" = every sonar channel
    std::size_t max_recent_soundings = 200'000;  // ring for the 3D view
    std::size_t max_track_points = 20'000;       // vehicle track ring (one per georeferenced ping)
    double process_interval_s = 0.1;             // data time between georeferencing batches
    double holiday_refresh_s = 1.0;  // wall time between holiday counts (visit every cell)
    std::vector<std::string> Validate() const;
};

struct SessionCounts {
    std::int64_t events = 0;
    std::int64_t decode_failures = 0;
    std::int64_t utm_failures = 0;
};

class LiveSession {
public:
    LiveSession(const LiveConfig& config, const survey::SonarMount& mount, bool mount_known);

    // One LCM event; `wall_utime` is the receiving machine's clock (Unix microseconds).
    void OnEvent(const std::string& channel,
                 const void* data,
                 std::size_t size,
                 std::int64_t wall_utime);
    // Georeferences what is ready (at most once per process_interval_s of data time unless
    // `force`), then evaluates the alarms at `wall_utime` (with every batch, else at most every
    // 100 ms of wall time).
    void Tick(std::int64_t wall_utime, bool force = false);

    // Where the events come from: a replay of log files (MarkReplay, before the first event),
    // else a live subscription. At the replay's end (MarkReplayFinished) the status says
    // source.finished and the silence that follows raises no no_messages alarm.
    void MarkReplay();
    void MarkReplayFinished();

    // JSON documents for the page (documents.cpp; budget in bytes: the caller's share; < 0 =
    // unlimited).
    nlohmann::json StatusJson(std::int64_t wall_utime);
    nlohmann::json AlarmsJson();
    nlohmann::json TilesJson(std::uint64_t since, std::int64_t budget_bytes);
    nlohmann::json SoundingsJson(std::uint64_t since, std::int64_t budget_bytes);

    // Writes the coverage grid as a COG GeoTIFF (processor/io/grid_io) into `dir` as
    // live_grid_<UTC of the data clock>.tif (layers: coverage_grid.hpp ToRaster); the path
    // written, or an error.
    Expected<std::string> WriteSnapshot(const std::string& dir);

    SessionCounts counts() const;
    CoverageStats GridStats() const;
    std::uint64_t grid_version() const;  // the newest tile version

private:
    void ProcessLocked();
    void RefreshHolidaysLocked();
    // StatusJson's "georef" and "grid" documents (mutex_ held).
    nlohmann::json GeorefStatusLocked() const;
    nlohmann::json GridStatusLocked() const;
    void AddStdDevLocked(const survey::NavStdDev& s);

    mutable std::mutex mutex_;
    LiveConfig config_;
    bool mount_known_;
    bool replay_ = false, replay_finished_ = false;
    LiveGeoref georef_;
    CoverageGrid grid_;
    StatusTracker status_;
    SessionCounts counts_;
    std::uint64_t version_ = 0;
    std::int64_t last_process_data_utime_ = 0;
    std::int64_t last_evaluate_wall_utime_ = 0;
    std::int64_t data_utime_ = 0;
    int utm_zone_ = 0;
    bool utm_northern_ = true;
    bool have_ref_ = false;
    std::int64_t ref_ix_ = 0, ref_iy_ = 0;  // the local frame of the page: this cell's corner
    struct Sounding {
        float x, y, z;  // metres from the reference corner (UTM east, north; ellipsoidal height)
    };
    std::deque<Sounding> recent_;
    std::uint64_t sounding_seq_ = 0;  // soundings ever added; recent_.back() has this number
    std::deque<std::array<float, 3>> track_;
    // Holidays (and the grid statistics) are recomputed at most once per grid version and per
    // holiday_refresh_s.
    std::uint64_t holidays_version_ = ~0ULL;
    std::chrono::steady_clock::time_point holidays_computed_;
    std::vector<std::pair<std::int64_t, std::int64_t>> holidays_;
    std::int64_t holidays_total_ = 0;
    CoverageStats stats_cache_;
    // TVU: the INS sigma records (time-sorted, trimmed to the georeferencing's navigation
    // window), the fallback from the error model, and running figures.
    std::vector<survey::NavStdDev> stddevs_;
    hydro::PingSigma fallback_sigma_;
    std::vector<hydro::PingSigma> ping_sigma_;
    std::vector<std::pair<std::int64_t, std::int64_t>> new_cells_;
    double last_batch_median_tvu_m_ = 0;
    std::int64_t pings_with_ins_sigma_ = 0, pings_with_model_sigma_ = 0;
};

}  // namespace pitmap::proc::live
