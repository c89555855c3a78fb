// SPDX-License-Identifier: MIT
// Refraction set-up for a new georeference: the config's casts, with the INS height above the
// water line; the later stages build it again from the survey model's record.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "common/gps_time.hpp"
#include "processor/io/svp_files.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The cast profiles in summary.json are for the report's speed-against-depth plot: at most this
// many points each (every k-th, the deepest kept), so a CTD's thousands of samples stay small.
constexpr std::size_t kMaxRecordedProfilePoints = 200;

json Profile(const svp::SoundSpeedCast& c) {
    json depth = json::array(), speed = json::array();
    const std::size_t n = c.depth_m.size();
    const std::size_t step =
        std::max<std::size_t>(1, (n + kMaxRecordedProfilePoints - 1) / kMaxRecordedProfilePoints);
    for (std::size_t i = 0; i < n; i += step) {
        depth.push_back(c.depth_m[i]);
        speed.push_back(c.speed_mps[i]);
    }
    if (n > 0 && (n - 1) % step != 0) {
        depth.push_back(c.depth_m.back());
        speed.push_back(c.speed_mps.back());
    }
    return {{"depth_m", std::move(depth)}, {"speed_mps", std::move(speed)}};
}

json Record(const svp::Refraction& r, const std::vector<std::string>& files) {
    json j = {{"svp_files", json::array()},
              {"selection", svp::ToString(r.selection())},
              {"surface_speed", svp::ToString(r.surface_speed())},
              {"ins_height_above_waterline_m", r.ins_height_above_waterline_m()},
              {"casts", json::array()}};
    for (const auto& f : files) j["svp_files"].push_back(fs::absolute(f).string());
    for (const auto& pc : r.casts()) {
        const auto& c = pc.cast;
        j["casts"].push_back(
            {{"name", c.name},
             {"time_utc",
              c.has_time() ? json(FormatUnixIso8601(UnixFromGps(c.utime_gps))) : json(nullptr)},
             {"latitude_deg", c.has_position() ? json(c.latitude_deg) : json(nullptr)},
             {"longitude_deg", c.has_position() ? json(c.longitude_deg) : json(nullptr)},
             {"points", c.depth_m.size()},
             {"max_depth_m", c.depth_m.back()},
             {"surface_speed_mps", c.speed_mps.front()},
             {"profile", Profile(c)}});
    }
    return j;
}

}  // namespace

Status SetUpRefraction(StageContext& s,
                       const PipelineConfig& config,
                       std::optional<double> vehicle_ins_height_m,
                       const Log& log) {
    const svp::RefractionConfig& rc = config.refraction;
    s.refraction.reset();
    if (!rc.enabled()) {
        s.summary.erase("refraction");
        return Ok{};
    }
    const double height = !std::isnan(rc.ins_height_above_waterline_m)
                              ? rc.ins_height_above_waterline_m
                              : vehicle_ins_height_m.value_or(std::nan(""));
    survey::RefractionRecord record;
    for (const auto& f : rc.svp_files) record.svp_files.push_back(fs::absolute(f).string());
    record.selection = rc.selection;
    record.surface_speed = rc.surface_speed;
    record.ins_height_above_waterline_m = height;
    auto r = io::BuildRefraction(record);
    if (!r) return r.error();
    s.refraction = *r;
    s.model.refraction = std::move(record);
    s.summary["refraction"] = Record(**r, rc.svp_files);
    log("refraction: " + std::to_string((*r)->casts().size()) + " cast(s), selection " +
        svp::ToString(rc.selection) + ", face speed from the " + svp::ToString(rc.surface_speed));
    return Ok{};
}

}  // namespace pitmap::proc::pipeline::detail
