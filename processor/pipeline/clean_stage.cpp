// SPDX-License-Identifier: MIT
// The clean stage (issue 35): the automatic cleaning in 3D (processor/clean) on the survey's
// newest trajectory. It decides on every candidate sounding (what georef's own filters and the
// hand edits accept, whatever an earlier cleaning said), stores its verdicts in the survey
// model (flags.cleaning: survey.pitmap keeps them) and leaves the stages after it (grid, fuse,
// mesh, the exports) the accepted soundings only. A hand restore wins over its verdict.
// The view waits on disk meanwhile (SpillView): the cleaning reads it a block at a time
// (clean::CleanBlocks) and its verdicts go to the scratch file (SpilledPoints::KeepOnly), so
// that the stage does not hold the view whole (issue 38, docs/decisions/037).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "common/peak_memory.hpp"
#include "common/progress.hpp"
#include "processor/clean/clean.hpp"
#include "processor/clean/clean_blocks.hpp"
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

// The plane fits' batches (clean::CleanBlocks' fit_soundings) in blocks of the view: 8 blocks'
// soundings' positions, 24 bytes each (3 blocks at kBlockBytesPerSounding); the view is read
// once per batch (bejanca 4x: 3 batches of 8 M soundings).
constexpr std::size_t kFitBlocks = 8;

// ForEachViewBlock with a visitor that cannot fail (the cleaning's).
Status ForEachBlock(const StageContext& s,
                    std::size_t block,
                    const std::function<void(const georef::GeorefPoints&, std::size_t)>& fn) {
    return ForEachViewBlock(s, block, [&fn](const georef::GeorefPoints& b, std::size_t first) {
        fn(b, first);
        return Status{Ok{}};
    });
}

// The view the cleaning judges, `size` soundings read a block of `block` at a time
// (ForEachBlock): the soundings of the pings `trusted` marks, in their order (all when it is
// empty).
clean::ViewBlocks CleanInput(const StageContext& s,
                             std::size_t size,
                             std::size_t block,
                             const std::vector<char>& trusted) {
    clean::ViewBlocks view;
    view.size = size;
    view.pings = &s.geo.pings;
    view.sweep = [&s, block, trusted](const clean::TakeBlock& take) -> Status {
        std::vector<char> keep;
        georef::GeorefPoints part;
        return ForEachBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t) {
            if (trusted.empty()) {
                take(b);
                return;
            }
            keep.resize(b.size());
            for (std::size_t j = 0; j < b.size(); ++j) keep[j] = trusted[b.ping[j]];
            part = b;
            KeepPoints(part, keep);
            take(part);
        });
    };
    return view;
}

// The cleaning's verdicts on the soundings of the pings whose INS horizontal 1-sigma is at most
// max_sigma_m, the others left out of the view it judges (status 0 for them); `left_out` counts
// their soundings. The view is read a block of `block` at a time.
Expected<clean::CleanResult> CleanTrustedPings(const StageContext& s,
                                               const PipelineConfig& config,
                                               double max_sigma_m,
                                               std::size_t block,
                                               const ProgressCallback& progress,
                                               std::int64_t* left_out) {
    const georef::GeorefResult& geo = s.geo;
    const std::size_t n = s.spilled_view ? s.spilled_view->size() : geo.points.size();
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
    const bool all = std::all_of(trusted.begin(), trusted.end(), [](char t) { return t != 0; });
    const std::vector<char> none;
    if (all) {
        return clean::CleanBlocks(
            CleanInput(s, n, block, none), config.clean, progress, kFitBlocks * block);
    }
    // Else the trusted pings' soundings; their verdicts go back to the soundings in order (the
    // trusted ones are those of trusted pings).
    std::size_t num_trusted = 0;
    const auto count = [&](const georef::GeorefPoints& b, std::size_t) {
        for (const std::uint32_t k : b.ping) num_trusted += trusted[k];
    };
    if (auto st = ForEachBlock(s, block, count); !st) return st.error();
    *left_out = static_cast<std::int64_t>(n - num_trusted);
    auto part = clean::CleanBlocks(
        CleanInput(s, num_trusted, block, trusted), config.clean, progress, kFitBlocks * block);
    if (!part) return part.error();
    clean::CleanResult out;
    out.counts = part->counts;
    out.cancelled = part->cancelled;
    if (part->status.size() != num_trusted) return out;
    out.status.assign(n, 0);
    std::size_t i = 0;
    const auto scatter = [&](const georef::GeorefPoints& b, std::size_t first) {
        for (std::size_t j = 0; j < b.size(); ++j) {
            if (trusted[b.ping[j]]) out.status[first + j] = part->status[i++];
        }
    };
    if (auto st = ForEachBlock(s, block, scatter); !st) return st.error();
    return out;
}

// The cleaning's verdicts applied to the view (RejectPoints: the model's flags, the view's
// counts; a sounding a hand edit restored stays): to the held points, or, while the view is
// spilled, a block of `block` at a time and then to its file (SpilledPoints::KeepOnly), so that
// the view is not read back whole. Returns which soundings stayed.
Expected<std::vector<char>> RejectInView(StageContext& s,
                                         const std::vector<std::uint8_t>& status,
                                         std::size_t block) {
    if (!s.spilled_view) return RejectPoints(s, status);
    survey::SoundingFlags& flags = s.model.flags;
    if (flags.cleaning.size() != s.model.ingest.pings.range_counts.size())
        flags.cleaning.assign(s.model.ingest.pings.range_counts.size(), 0);
    std::vector<char> keep(status.size(), 1);
    std::vector<std::uint8_t> part;
    auto st = ForEachBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
        const auto from = status.begin() + static_cast<std::ptrdiff_t>(first);
        const auto to = from + static_cast<std::ptrdiff_t>(b.size());
        if (std::all_of(from, to, [](std::uint8_t v) { return v == 0; })) return;
        part.assign(from, to);
        s.geo.points = b;  // RejectPoints reads the block as the view (its pings are the view's)
        const std::vector<char> k = RejectPoints(s, part);
        s.geo.points = georef::GeorefPoints();
        std::copy(k.begin(), k.end(), keep.begin() + static_cast<std::ptrdiff_t>(first));
    });
    if (!st) return Error{"clean: " + st.error().message};
    if (auto k = s.spilled_view->KeepOnly(keep, block); !k)
        return Error{"clean: " + k.error().message};
    // RejectPoints counted each block's points as the view's: the view's own count.
    s.geo.counts.points = static_cast<std::int64_t>(s.spilled_view->size());
    return keep;
}

// A pass before this one in the same run (run: before the calibration): its record, to stay in
// this one's as "earlier_pass" so that the stage's whole cost is in the summary; null when none.
nlohmann::json EarlierPass(const StageContext& s) {
    // summary.json is read back from disk: a member of another type is not this pass's record.
    auto member = [](const nlohmann::json& o, const char* key, auto is_type) {
        return o.contains(key) && is_type(o[key]) ? o[key] : nlohmann::json();
    };
    auto is_string = [](const nlohmann::json& v) { return v.is_string(); };
    auto is_number = [](const nlohmann::json& v) { return v.is_number(); };
    if (!(s.summary.contains("stages") && s.summary["stages"].contains("clean") &&
          member(s.summary["stages"]["clean"], "run_id", is_string) == s.model.run_id &&
          s.summary["stages"]["clean"].contains("seconds")))
        return nlohmann::json();
    const nlohmann::json& e = s.summary["stages"]["clean"];
    return {{"seconds", e["seconds"]},
            {"cpu_seconds", member(e, "cpu_seconds", is_number)},
            {"rejected", member(e, "rejected", is_number)},
            {"trajectory", member(e, "trajectory", is_string)}};
}

// The pass's verdicts in the log.
void LogVerdicts(const clean::CleanCounts& c,
                 std::int64_t rejected,
                 double share,
                 std::int64_t changed,
                 const Log& log) {
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
}

}  // namespace

Status CleanSurvey(StageContext& s,
                   const PipelineConfig& config,
                   const Log& log,
                   double max_ins_sigma_h_m) {
    StageClock clock;
    const nlohmann::json earlier = EarlierPass(s);
    ClearGates(s, Stage::kClean);
    survey::SoundingFlags& flags = s.model.flags;
    const survey::PingSeries& pings = s.model.ingest.pings;
    // The candidates: the current view is them when nothing was cleaned before and nothing is
    // rejected by hand (a new run); otherwise the survey is viewed again.
    bool cleaned_before = false;
    for (const std::uint8_t f : flags.cleaning) cleaned_before = cleaned_before || f != 0;
    const bool held_on_entry = !s.spilled_view;
    if (cleaned_before || AnyManualReject(flags)) {
        // Made in its file a block of pings at a time, never held whole (decisions 041, 047):
        // the final pass of a long survey held 38 bytes a sounding here (bejanca 8x: 1.9 GB).
        const ViewMaker make = ModelViewMaker(s, config, survey::SoundingView::kCandidates);
        if (auto st = ViewToFile(s, make, log, true); !st)
            return Error{"clean: " + st.error().message};
    }
    // The view waits on disk while the cleaning reads it a block at a time (issue 38): the
    // stage's peak past this point is the cleaning's arrays, not the view (`peak_rss_mb_blocks`).
    if (auto st = SpillView(s); !st)
        log("clean: the view stays in memory (" + st.error().message + ")");
    const double peak_view_mb = clock.peak_rss_mb();
    clock.ResetPeakWithinStage();
    const std::size_t block = BlockWithinBudget(config.run, ResidentMb());
    ProgressReporter bar(ToString(Stage::kClean), 1000);
    std::int64_t left_out = 0;
    const std::size_t n = s.spilled_view ? s.spilled_view->size() : s.geo.points.size();
    const Expected<clean::CleanResult> cleaned =
        std::isfinite(max_ins_sigma_h_m)
            ? CleanTrustedPings(s, config, max_ins_sigma_h_m, block, bar.AsCallback(), &left_out)
            : clean::CleanBlocks(
                  CleanInput(s, n, block, {}), config.clean, bar.AsCallback(), kFitBlocks * block);
    bar.Finish();
    if (left_out > 0) {
        log("clean: " + std::to_string(left_out) +
            " soundings of pings whose INS horizontal sigma exceeds " +
            std::to_string(max_ins_sigma_h_m) + " m left out of this pass (kept)");
    }
    if (!cleaned) return Error{"clean: " + cleaned.error().message};
    const clean::CleanResult& r = *cleaned;
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
    auto kept = RejectInView(s, r.status, block);
    if (!kept) return kept.error();
    const std::vector<char>& keep = *kept;
    std::int64_t restored_by_hand = 0;
    for (std::size_t j = 0; j < keep.size(); ++j) restored_by_hand += keep[j] && r.status[j] != 0;
    std::int64_t changed = 0;
    for (std::size_t i = 0; i < flags.cleaning.size(); ++i) {
        changed += flags.cleaning[i] != (i < before.size() ? before[i] : 0);
    }
    const clean::CleanCounts& c = r.counts;
    const std::int64_t rejected = c.free_space + c.cluster + c.multipath + c.profile;
    const double share = c.soundings > 0 ? static_cast<double>(rejected) / c.soundings : 0.0;
    LogVerdicts(c, rejected, share, changed, log);
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
                 {"seconds_terrain", c.seconds_terrain},
                 {"block_soundings", block},
                 {"peak_rss_mb_view", peak_view_mb},
                 {"peak_rss_mb_blocks", PeakRssMb()}},
                clock);
    // The stage after it reads the view held, as it was given (a stage that reads blocks of it
    // finds it spilled).
    // The candidates' earlier verdicts (GeorefPoints::status) are not the view's after it: the
    // accepted soundings are (RejectPoints leaves held points without them).
    if (held_on_entry) {
        if (auto st = RestoreView(s); !st) return Error{"clean: " + st.error().message};
        s.geo.points.status.clear();
    }
    return Ok{};
}

}  // namespace pitmap::proc::pipeline::detail

namespace pitmap::proc::pipeline {

Status RunCleanStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    // The cleaning and the export read the view by blocks from its file (decision 047).
    auto s = detail::LoadSurveyReplacing(
        out_dir, config, detail::StartFrom::kLatest, Stage::kClean, log);
    if (!s) return s.error();
    if (auto st = detail::CleanSurvey(*s, config, log); !st) {
        (void)detail::SaveSummary(*s);
        return st;
    }
    return detail::ExportSurvey(*s, config);
}

}  // namespace pitmap::proc::pipeline
