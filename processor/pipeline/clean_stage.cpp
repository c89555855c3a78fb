// SPDX-License-Identifier: MIT
// The clean stage (issue 35): the automatic cleaning in 3D (processor/clean) on the survey's
// newest trajectory. It decides on every candidate sounding (what georef's own filters and the
// hand edits accept, whatever an earlier cleaning said), stores its verdicts in the survey
// model (flags.cleaning: survey.pitmap keeps them) and leaves the stages after it (grid, fuse,
// mesh, the exports) the accepted soundings only. A hand restore wins over its verdict.
#include <cmath>
#include <cstdio>
#include <limits>

#include "common/progress.hpp"
#include "processor/clean/clean.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/result_json.hpp"

namespace pitmap::proc::pipeline::detail {

using nlohmann::json;
using survey::SoundingStatus;

namespace {

std::string Percent(double share) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f %%", 100.0 * share);
    return buf;
}

bool AnyManualReject(const survey::SoundingFlags& f) {
    for (const std::uint8_t m : f.manual) {
        if (m == static_cast<std::uint8_t>(survey::ManualEdit::kReject)) return true;
    }
    return false;
}

}  // namespace

std::size_t FlatIndex(const georef::GeorefResult& geo,
                      const survey::PingSeries& pings,
                      std::size_t j) {
    return pings.pings[geo.pings[geo.points.ping[j]].header_index].beam_offset +
           std::size_t{geo.points.beam[j]};
}

void KeepPoints(georef::GeorefPoints& P, const std::vector<char>& keep) {
    std::size_t out = 0;
    for (std::size_t j = 0; j < P.size(); ++j) {
        if (!keep[j]) continue;
        P.position_world[out] = P.position_world[j];
        P.ping[out] = P.ping[j];
        P.beam[out] = P.beam[j];
        P.range_m[out] = P.range_m[j];
        P.angle_rad[out] = P.angle_rad[j];
        ++out;
    }
    P.position_world.resize(out);
    P.ping.resize(out);
    P.beam.resize(out);
    P.range_m.resize(out);
    P.angle_rad.resize(out);
    P.status.clear();
}

std::vector<char> RejectPoints(StageContext& s, const std::vector<std::uint8_t>& status) {
    survey::SoundingFlags& flags = s.model.flags;
    const survey::PingSeries& pings = s.model.ingest.pings;
    if (flags.cleaning.size() != pings.range_counts.size())
        flags.cleaning.assign(pings.range_counts.size(), 0);
    std::vector<char> keep(s.geo.points.size(), 1);
    georef::GeorefCounts& c = s.geo.counts;
    for (std::size_t j = 0; j < s.geo.points.size(); ++j) {
        if (status[j] == 0) continue;
        const std::size_t flat = FlatIndex(s.geo, pings, j);
        flags.cleaning[flat] = status[j];
        if (flags.Manual(flat) == survey::ManualEdit::kRestore) continue;
        keep[j] = 0;
        --c.status[0];
        ++c.status[status[j]];
        ++c.cleaned;
    }
    KeepPoints(s.geo.points, keep);
    c.points = static_cast<std::int64_t>(s.geo.points.size());
    return keep;
}

namespace {

// The cleaning's verdicts on the soundings of the pings whose INS horizontal 1-sigma is at most
// max_sigma_m, the others left out of the view it judges (status 0 for them); `left_out` counts
// their soundings.
clean::CleanResult CleanTrustedPings(const StageContext& s,
                                     const PipelineConfig& config,
                                     double max_sigma_m,
                                     const ProgressCallback& progress,
                                     std::int64_t* left_out) {
    const georef::GeorefResult& geo = s.geo;
    // Where the INS reports no sigma, SLAM's assumption (slam_stage.fallback_position_m).
    const SlamStageConfig& sc = config.slam_stage;
    PoseSigma fallback;
    fallback << 0.0, 0.0, 0.0, sc.fallback_position_m[0], sc.fallback_position_m[1],
        sc.fallback_position_m[2];
    std::vector<char> trusted(geo.pings.size(), 0);
    for (std::size_t k = 0; k < geo.pings.size(); ++k) {
        const PoseSigma sg = PoseSigmaAt(s.model.ingest.nav,
                                         geo.pings[k].utime_gps,
                                         config.slam_stage.sigma_max_age_s,
                                         fallback);
        trusted[k] = std::sqrt(0.5 * (sg(3) * sg(3) + sg(4) * sg(4))) <= max_sigma_m ? 1 : 0;
    }
    std::size_t num_trusted = 0;
    for (std::size_t j = 0; j < geo.points.size(); ++j) num_trusted += trusted[geo.points.ping[j]];
    *left_out = static_cast<std::int64_t>(geo.points.size() - num_trusted);
    // Every ping trusted (no outage): the cleaning judges the view itself, not a copy of it
    // (38 bytes a sounding; it reads only the points and the pings).
    if (num_trusted == geo.points.size()) return clean::Clean(geo, config.clean, progress);
    // Else a view of the trusted pings' soundings, sized once; its verdicts go back to the
    // soundings in order (the trusted ones are those of trusted pings).
    georef::GeorefResult view;
    view.world_origin = geo.world_origin;
    view.pings = geo.pings;
    view.mount = geo.mount;
    view.refraction = geo.refraction;
    const bool with_status = !geo.points.status.empty();
    view.points.position_world.reserve(num_trusted);
    view.points.ping.reserve(num_trusted);
    view.points.beam.reserve(num_trusted);
    view.points.range_m.reserve(num_trusted);
    view.points.angle_rad.reserve(num_trusted);
    if (with_status) view.points.status.reserve(num_trusted);
    for (std::size_t j = 0; j < geo.points.size(); ++j) {
        if (!trusted[geo.points.ping[j]]) continue;
        view.points.position_world.push_back(geo.points.position_world[j]);
        view.points.ping.push_back(geo.points.ping[j]);
        view.points.beam.push_back(geo.points.beam[j]);
        view.points.range_m.push_back(geo.points.range_m[j]);
        view.points.angle_rad.push_back(geo.points.angle_rad[j]);
        if (with_status) view.points.status.push_back(geo.points.status[j]);
    }
    clean::CleanResult part = clean::Clean(view, config.clean, progress);
    view = georef::GeorefResult{};
    clean::CleanResult out;
    out.counts = part.counts;
    out.cancelled = part.cancelled;
    out.status.assign(geo.points.size(), 0);
    if (part.status.size() == num_trusted) {
        std::size_t i = 0;
        for (std::size_t j = 0; j < geo.points.size(); ++j) {
            if (trusted[geo.points.ping[j]]) out.status[j] = part.status[i++];
        }
    }
    return out;
}

}  // namespace

Status CleanSurvey(StageContext& s,
                   const PipelineConfig& config,
                   const Log& log,
                   double max_ins_sigma_h_m) {
    StageClock clock;
    // A pass before this one in the same run (run: before the calibration) stays in the
    // record, as "earlier_pass", so that the stage's whole cost is in the summary.
    nlohmann::json earlier;
    // summary.json is read back from disk: a member of another type is not this pass's record.
    auto member = [](const nlohmann::json& o, const char* key, auto is_type) {
        return o.contains(key) && is_type(o[key]) ? o[key] : nlohmann::json();
    };
    auto is_string = [](const nlohmann::json& v) { return v.is_string(); };
    auto is_number = [](const nlohmann::json& v) { return v.is_number(); };
    if (s.summary.contains("stages") && s.summary["stages"].contains("clean") &&
        member(s.summary["stages"]["clean"], "run_id", is_string) == s.model.run_id &&
        s.summary["stages"]["clean"].contains("seconds")) {
        const nlohmann::json& e = s.summary["stages"]["clean"];
        earlier = {{"seconds", e["seconds"]},
                   {"cpu_seconds", member(e, "cpu_seconds", is_number)},
                   {"rejected", member(e, "rejected", is_number)},
                   {"trajectory", member(e, "trajectory", is_string)}};
    }
    ClearGates(s, Stage::kClean);
    survey::SoundingFlags& flags = s.model.flags;
    const survey::PingSeries& pings = s.model.ingest.pings;
    // The candidates: the current view is them when nothing was cleaned before and nothing is
    // rejected by hand (a new run); otherwise the survey is viewed again.
    bool cleaned_before = false;
    for (const std::uint8_t f : flags.cleaning) cleaned_before = cleaned_before || f != 0;
    if (cleaned_before || AnyManualReject(flags)) {
        s.geo = georef::GeorefResult{};  // one view at a time (decision 020)
        s.geo = georef::Georeference(s.model,
                                     s.model.latest(),
                                     config.georef,
                                     s.refraction,
                                     {},
                                     nullptr,
                                     survey::SoundingView::kCandidates);
    }
    ProgressReporter bar(ToString(Stage::kClean), 1000);
    std::int64_t left_out = 0;
    const clean::CleanResult r =
        std::isfinite(max_ins_sigma_h_m)
            ? CleanTrustedPings(s, config, max_ins_sigma_h_m, bar.AsCallback(), &left_out)
            : clean::Clean(s.geo, config.clean, bar.AsCallback());
    bar.Finish();
    if (left_out > 0) {
        log("clean: " + std::to_string(left_out) +
            " soundings of pings whose INS horizontal sigma exceeds " +
            std::to_string(max_ins_sigma_h_m) + " m left out of this pass (kept)");
    }
    if (r.cancelled) return Error{"clean: cancelled"};

    std::vector<std::uint8_t> before = std::move(flags.cleaning);
    flags.cleaning.assign(pings.range_counts.size(), 0);
    // The candidates' earlier verdicts are decided again: counted as accepted until then.
    georef::GeorefCounts& counts = s.geo.counts;
    for (int code = 0; code < survey::kNumSoundingStatus; ++code) {
        if (!survey::IsCleaningStatus(static_cast<SoundingStatus>(code))) continue;
        counts.status[0] += counts.status[code];
        counts.status[code] = 0;
    }
    counts.cleaned = 0;
    const std::vector<char> keep = RejectPoints(s, r.status);
    std::int64_t restored_by_hand = 0;
    for (std::size_t j = 0; j < keep.size(); ++j) restored_by_hand += keep[j] && r.status[j] != 0;
    std::int64_t changed = 0;
    for (std::size_t i = 0; i < flags.cleaning.size(); ++i) {
        changed += flags.cleaning[i] != (i < before.size() ? before[i] : 0);
    }
    const clean::CleanCounts& c = r.counts;
    const std::int64_t rejected = c.free_space + c.cluster + c.multipath + c.profile;
    const double share = c.soundings > 0 ? static_cast<double>(rejected) / c.soundings : 0.0;
    char line[256];
    std::snprintf(line,
                  sizeof line,
                  "clean: %lld of %lld soundings rejected (%.2f %%): free space %lld, cluster "
                  "%lld, multipath %lld, off profile %lld; %lld kept as continuous with the "
                  "terrain; %lld flags changed",
                  static_cast<long long>(rejected),
                  static_cast<long long>(c.soundings),
                  100.0 * share,
                  static_cast<long long>(c.free_space),
                  static_cast<long long>(c.cluster),
                  static_cast<long long>(c.multipath),
                  static_cast<long long>(c.profile),
                  static_cast<long long>(c.terrain),
                  static_cast<long long>(changed));
    log(line);
    if (share > config.quality.max_cleaned_share) {
        TripGate(s,
                 Stage::kClean,
                 "cleaning_rejects_many",
                 "the cleaning rejected " + Percent(share) + " of the soundings (more than " +
                     "quality.max_cleaned_share " + Percent(config.quality.max_cleaned_share) +
                     "): the soundings do not agree between pings beyond what echoes explain "
                     "(a wrong mount, sonar clock or sound speed moves whole swaths); check "
                     "calibrate's and SLAM's gates, or clean.voxel_m for this survey's scale",
                 log);
    }
    RecordStage(s.summary,
                Stage::kClean,
                {{"soundings", c.soundings},
                 {"rejected", rejected},
                 {"free_space", c.free_space},
                 {"cluster", c.cluster},
                 {"multipath", c.multipath},
                 {"profile", c.profile},
                 {"near_field", c.near_field},
                 {"smile", c.smile},
                 {"kept_as_terrain", c.terrain},
                 {"restored_by_hand", restored_by_hand},
                 {"left_out_ins_sigma", left_out},
                 {"flags_changed", changed},
                 {"voxels", c.voxels},
                 {"terrain_components", c.terrain_components},
                 {"clusters", c.clusters},
                 {"trajectory", survey::ToString(s.model.latest())},
                 {"run_id", s.model.run_id},
                 {"earlier_pass", earlier},
                 {"seconds_voxels", c.seconds_voxels},
                 {"seconds_rays", c.seconds_rays},
                 {"seconds_clusters", c.seconds_clusters},
                 {"seconds_verdicts", c.seconds_verdicts},
                 {"seconds_profiles", c.seconds_profiles},
                 {"seconds_terrain", c.seconds_terrain}},
                clock);
    return Ok{};
}

}  // namespace pitmap::proc::pipeline::detail

namespace pitmap::proc::pipeline {

Status RunCleanStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kLatest, log);
    if (!s) return s.error();
    if (auto r = detail::RemoveProducts(out_dir, detail::ProductsReplacedBy(Stage::kClean)); !r)
        return r;
    if (auto st = detail::CleanSurvey(*s, config, log); !st) {
        (void)detail::SaveSummary(*s);
        return st;
    }
    return detail::ExportSurvey(*s, config);
}

}  // namespace pitmap::proc::pipeline
