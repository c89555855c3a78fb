// SPDX-License-Identifier: MIT
// The 3-D stages on a products folder: SLAM, TSDF fusion, mesh, report, and `run`.
#include <sched.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <optional>

#include "common/formats/replace_file.hpp"
#include "common/frames.hpp"
#include "common/peak_memory.hpp"
#include "common/progress.hpp"
#include "processor/calib/ins_slow_error.hpp"
#include "processor/fusion/scan_stream.hpp"
#include "processor/fusion/vdb_io.hpp"
#include "processor/hydro/tpu.hpp"
#include "processor/io/products.hpp"
#include "processor/io/projected_points.hpp"
#include "processor/io/record_spill.hpp"
#include "processor/mesh/export.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/pipeline.hpp"
#include "processor/pipeline/posterior.hpp"
#include "processor/pipeline/report_program.hpp"
#include "processor/pipeline/result_json.hpp"
#include "processor/pipeline/scan_maker.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The file metadata key of tsdf.vdb that holds the survey's run id.
constexpr const char* kRunIdKey = "pitmap_run_id";

}  // namespace

namespace detail {

namespace {

// Position change between two per-ping trajectories: RMS and maximum, metres.
std::pair<double, double> PositionChange(const std::vector<Pose>& a, const std::vector<Pose>& b) {
    double sum = 0, worst = 0;
    const std::size_t n = std::min(a.size(), b.size());
    for (std::size_t i = 0; i < n; ++i) {
        const double d = (a[i].translation() - b[i].translation()).norm();
        sum += d * d;
        worst = std::max(worst, d);
    }
    return {n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0, worst};
}

}  // namespace

// The passes' disagreement after SLAM per window of quality.slam_drift_window_s (the slices'
// plane residuals, slam::SlamResult::final_slice_consistency_m), each with its figures; those
// over slam_consistency_ratio x the range noise's and over twice the median window's are marked
// "drift" and described in `text`.
json ConsistencyWindows(const slam::SlamResult& r,
                        const QualityConfig& q,
                        double expected_m,
                        std::string* text) {
    json out = json::array();
    if (r.trajectory.empty() || r.final_slice_consistency_m.size() != r.trajectory.size() ||
        !(expected_m > 0))
        return out;
    const double t0 = r.trajectory.front().gps_time_s;
    std::map<std::int64_t, std::pair<double, std::int64_t>> w;  // window -> (sum sq, n)
    for (std::size_t i = 0; i < r.trajectory.size(); ++i) {
        const double c = r.final_slice_consistency_m[i];
        if (!std::isfinite(c)) continue;
        auto& [ss, n] =
            w[static_cast<std::int64_t>((r.trajectory[i].gps_time_s - t0) / q.slam_drift_window_s)];
        ss += c * c;
        ++n;
    }
    std::vector<double> rms;
    for (const auto& [k, v] : w) {
        if (v.second >= 20) rms.push_back(std::sqrt(v.first / static_cast<double>(v.second)));
    }
    if (rms.size() < 3) return out;
    std::vector<double> sorted = rms;
    std::nth_element(sorted.begin(),
                     sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                     sorted.end());
    const double median = sorted[sorted.size() / 2];
    std::string t;
    std::size_t suspects = 0;
    for (const auto& [k, v] : w) {
        if (v.second < 20) continue;
        const double m = std::sqrt(v.first / static_cast<double>(v.second));
        const double a = t0 + static_cast<double>(k) * q.slam_drift_window_s;
        const bool suspect = m > q.slam_consistency_ratio * expected_m && m > 2.0 * median;
        out.push_back({{"start_gps_s", a},
                       {"end_gps_s", a + q.slam_drift_window_s},
                       {"consistency_m", m},
                       {"slices", v.second},
                       {"drift", suspect}});
        if (!suspect) continue;
        ++suspects;
        if (t.size() < 500) {
            t += (t.empty() ? "" : "; ") + Fixed(a, 1) + ".." +
                 Fixed(a + q.slam_drift_window_s, 1) + " GPS s: " + Fixed(m, 3) + " m";
        }
    }
    if (suspects > 0) {
        *text += (text->empty() ? "" : "; ") + std::string("after SLAM the passes disagree in ") +
                 std::to_string(suspects) + " window(s) far more than in the rest of the survey (" +
                 Fixed(median, 3) + " m RMS per window, the range noise leaves " +
                 Fixed(expected_m, 3) + " m): " + t;
    }
    return out;
}

// "; worst windows: +60..+90 s 0.244 m (7.2x), ..." of ConsistencyWindows' figures (seconds
// from the first ping), the three worst over the range noise's figure.
std::string WorstWindows(const json& windows, double expected_m) {
    std::vector<const json*> w;
    for (const auto& x : windows) w.push_back(&x);
    std::sort(w.begin(), w.end(), [](const json* a, const json* b) {
        return a->value("consistency_m", 0.0) > b->value("consistency_m", 0.0);
    });
    if (w.empty() || !(expected_m > 0)) return "";
    double t0 = 1e300;
    for (const auto& x : windows) t0 = std::min(t0, x.value("start_gps_s", 0.0));
    std::string s = "; worst windows (from the first ping):";
    for (std::size_t i = 0; i < w.size() && i < 3; ++i) {
        const double c = w[i]->value("consistency_m", 0.0);
        s += std::string(i ? "," : "") + " +" + Fixed(w[i]->value("start_gps_s", 0.0) - t0, 0) +
             "..+" + Fixed(w[i]->value("end_gps_s", 0.0) - t0, 0) + " s " + Fixed(c, 3) + " m (" +
             Fixed(c / expected_m, 1) + "x)";
    }
    return s;
}

namespace {

// SLAM's input from the georeferenced survey, logged.
// The pose sigma where the INS reports none (slam_stage.fallback_*).
PoseSigma FallbackSigma(const SlamStageConfig& sc) {
    PoseSigma fallback;
    fallback << frames::DegToRad(sc.fallback_attitude_deg[0]),
        frames::DegToRad(sc.fallback_attitude_deg[1]),
        frames::DegToRad(sc.fallback_attitude_deg[2]), sc.fallback_position_m[0],
        sc.fallback_position_m[1], sc.fallback_position_m[2];
    return fallback;
}

// What the range noise alone would leave of the plane-fit consistency (calibrate's model,
// sigma = constant + fraction * range, over every 16th sounding of the view), summed a block
// of the view at a time in the view's order: the whole view's figure bit for bit.
struct RangeNoise {
    double sum_squares = 0;
    std::size_t count = 0;
    void Add(const georef::GeorefPoints& b, std::size_t first, const calib::BoresightConfig& cal) {
        for (std::size_t k = (first + 15) / 16 * 16 - first; k < b.size(); k += 16) {
            const double sr = cal.range_noise_constant_m +
                              cal.range_noise_fraction * static_cast<double>(b.range_m[k]);
            if (!std::isfinite(sr)) continue;
            sum_squares += sr * sr;
            ++count;
        }
    }
    // m RMS; 0 without soundings.
    double Rms() const {
        return count > 0 ? std::sqrt(sum_squares / static_cast<double>(count)) : 0.0;
    }
};

// What SLAM's stage takes from the view: its slices and the range noise's consistency.
struct SlamInput {
    SliceSet set;
    double expected_consistency_m = 0;
};

// SLAM's input from the view read a block of `block` soundings at a time (decision 043: from
// its scratch file while spilled, never whole), logged.
Expected<SlamInput> SlamSlices(const StageContext& s,
                               const PipelineConfig& config,
                               std::size_t block,
                               const Log& log) {
    const SlamStageConfig& sc = config.slam_stage;
    SliceBuilder slices(
        s.geo, s.model.ingest.nav, sc.point_stride, sc.sigma_max_age_s, FallbackSigma(sc));
    RangeNoise noise;
    auto st = ForEachViewBlock(s, block, [&](const georef::GeorefPoints& b, std::size_t first) {
        noise.Add(b, first, config.calibrate);
        return slices.Add(b, first);
    });
    if (!st) return st.error();
    SlamInput in{slices.Finish(), noise.Rms()};
    log("slam: " + std::to_string(in.set.slices.size()) + " slices, " +
        std::to_string(in.set.num_points) + " points");
    return in;
}

// SLAM on the slices, each iteration logged; their points move into SLAM (held once).
slam::SlamResult RunSlamLogged(SliceSet& set, const slam::SlamConfig& cfg, const Log& log) {
    slam::SlamResult r =
        slam::RunSlam(std::move(set.slices), cfg, [&log](const slam::SlamIteration& it) {
            log(std::string("slam: ") +
                (it.stage == slam::SlamStage::kRigid ? "rigid" : "semi-rigid") + " iteration " +
                std::to_string(it.iteration));
            return true;
        });
    log("slam: " + std::to_string(r.num_points) + " of " + std::to_string(r.num_points_in) +
        " finite points used (slam.pass_cell_m " + std::to_string(cfg.pass_cell_m) + "; " +
        std::to_string(r.num_sections_every_point) +
        " sections whole by slam.pass_cell_max_sigma_m)");
    log("slam: " + std::string(slam::ToString(r.termination)) + ": " + r.message);
    return r;
}

// The optimised trajectory per ping: slice poses where SLAM has them, interpolated between
// slices for pings that kept no sounding; `before` where SLAM returned no pose.
std::vector<Pose> SlamPingPoses(const georef::GeorefResult& geo,
                                const SliceSet& set,
                                const slam::SlamResult& r,
                                const TimedPoses& before) {
    TimedPoses slices_after;
    for (const slam::SlamPose& p : r.trajectory) {
        if (p.input_index >= set.ping.size()) continue;
        slices_after.gps_time_s.push_back(
            static_cast<double>(geo.pings[set.ping[p.input_index]].utime_gps) * 1e-6);
        slices_after.T_world_vehicle.push_back(p.T_world_vehicle);
    }
    if (slices_after.gps_time_s.empty()) return before.T_world_vehicle;
    return PosesAtPings(geo, slices_after.gps_time_s, slices_after.T_world_vehicle).T_world_vehicle;
}

// The INS's own horizontal 1-sigma at a ping (hydro::InsSigmaAt: the nearest stddev record),
// metres; NaN when no record lies within max_age_s or the record lacks north or east (NaN or
// <= 0: not reported).
double InsHorizontalSigma(const std::vector<survey::NavStdDev>& sd,
                          std::int64_t utime_gps,
                          double max_age_s) {
    constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    hydro::PingSigma unreported;
    unreported.position_enu_m.setConstant(kNaN);
    unreported.attitude_rpy_rad.setConstant(kNaN);
    bool from_ins = false;
    const hydro::PingSigma sigma =
        hydro::InsSigmaAt(sd, utime_gps, max_age_s, unreported, &from_ins);
    if (!from_ins) return kNaN;
    return std::hypot(sigma.position_enu_m.y(), sigma.position_enu_m.x());
}

// How far SLAM moved the pings where the INS is good (horizontal sigma <= slam_good_ins_sigma_m),
// over the survey and per window of quality.slam_drift_window_s.
struct GoodInsMoves {
    // A drift of the INS that it does not report shows as one stretch whose pings SLAM moves
    // beyond their sigma together.
    struct Window {
        std::int64_t good = 0, beyond = 0;
        double worst = 0;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();  // of the moves, east north up, m
    };
    std::vector<std::size_t> good;  // the pings with good INS
    std::int64_t beyond = 0;        // of them moved beyond slam_sigma_multiple x sigma
    double worst = 0;               // their largest move, m
    std::int64_t t_first = 0;       // GPS us of the first ping: window 0 starts there
    std::int64_t window_us = 0;
    std::map<std::int64_t, Window> windows;
};

GoodInsMoves MovesAtGoodIns(const georef::GeorefResult& geo,
                            const survey::NavSeries& nav,
                            const std::vector<Pose>& before,
                            const std::vector<Pose>& after,
                            double sigma_max_age_s,
                            double recovery_time_s,
                            const QualityConfig& q) {
    GoodInsMoves out;
    out.window_us = static_cast<std::int64_t>(q.slam_drift_window_s * 1e6);
    out.t_first = geo.pings.empty() ? 0 : geo.pings.front().utime_gps;
    // As SLAM (slam.ins_sigma_recovery_time_s): a filter that regains GNSS after an outage
    // reports a small sigma at once but pulls its drift back over seconds, so the reported
    // sigma is not believed to fall faster than exp(-dt / recovery_time_s). Without this the
    // pings just after a recovery counted as good and SLAM's correction of their metres of
    // drift as an inconsistency (the quarry with a 180 s outage: 116 INS poses put back, up to
    // 7.4 m off; docs/uncertainty.md).
    double held = 0;
    std::int64_t held_t = 0;
    for (std::size_t i = 0; i < after.size() && i < geo.pings.size(); ++i) {
        const std::int64_t t = geo.pings[i].utime_gps;
        double sigma = InsHorizontalSigma(nav.stddevs, t, sigma_max_age_s);
        if (std::isfinite(sigma) && recovery_time_s > 0) {
            const double dt = std::max(0.0, static_cast<double>(t - held_t) * 1e-6);
            sigma = std::max(sigma, held * std::exp(-dt / recovery_time_s));
            held = sigma;
            held_t = t;
        }
        if (!(sigma <= q.slam_good_ins_sigma_m)) continue;
        out.good.push_back(i);
        const double moved = (after[i].translation() - before[i].translation()).norm();
        const double allowed = std::max(q.slam_sigma_multiple * sigma, q.slam_min_allowance_m);
        if (moved > allowed) ++out.beyond;
        out.worst = std::max(out.worst, moved);
        GoodInsMoves::Window& w = out.windows[(t - out.t_first) / out.window_us];
        ++w.good;
        if (moved > allowed) ++w.beyond;
        w.worst = std::max(w.worst, moved);
        w.sum += after[i].translation() - before[i].translation();
    }
    return out;
}

// The windows where most good pings moved beyond their sigma (not the whole survey), as JSON,
// and described in `text`.
json DriftWindows(const GoodInsMoves& moves, const QualityConfig& q, std::string* text) {
    json drift = json::array();
    for (const auto& [index, w] : moves.windows) {
        if (w.good < 20 || 2 * w.beyond <= w.good) continue;
        const double a = static_cast<double>(moves.t_first + index * moves.window_us) * 1e-6;
        const Eigen::Vector3d mean = w.sum / static_cast<double>(w.good);
        drift.push_back({{"start_gps_s", a},
                         {"end_gps_s", a + q.slam_drift_window_s},
                         {"good_ins_pings", w.good},
                         {"moved_beyond_allowance", w.beyond},
                         {"max_move_m", w.worst},
                         {"mean_move_enu_m", {mean.x(), mean.y(), mean.z()}}});
        if (text->size() < 500) {
            *text += (text->empty() ? "" : "; ") + Fixed(a, 1) + ".." +
                     Fixed(a + q.slam_drift_window_s, 1) + " GPS s: up to " + Fixed(w.worst, 2) +
                     " m (mean east " + Fixed(mean.x(), 2) + ", north " + Fixed(mean.y(), 2) +
                     ", up " + Fixed(mean.z(), 2) + " m)";
        }
    }
    return drift;
}

// Where the INS is good (GNSS, cm-level sigma) SLAM may not move a ping further than its sigma
// allows: a correction beyond that is an inconsistency (a sonar clock or mount error the
// calibration did not remove) and is reported, not absorbed into the trajectory. When too many
// good pings moved, the gate trips and they get their INS poses back in `after`; otherwise the
// windows that drifted are described in `drift_text`. Returns summary.json's "ins_check".
json CheckAgainstGoodIns(StageContext& s,
                         const std::vector<Pose>& before,
                         std::vector<Pose>& after,
                         double sigma_max_age_s,
                         double recovery_time_s,
                         const QualityConfig& q,
                         std::string* drift_text,
                         const Log& log) {
    const GoodInsMoves moves = MovesAtGoodIns(
        s.geo, s.model.ingest.nav, before, after, sigma_max_age_s, recovery_time_s, q);
    json ins_check = {{"good_ins_pings", moves.good.size()},
                      {"moved_beyond_allowance", moves.beyond},
                      {"max_move_good_ins_m", moves.worst},
                      {"reverted", false}};
    if (!moves.good.empty() && static_cast<double>(moves.beyond) >
                                   q.slam_max_fraction * static_cast<double>(moves.good.size())) {
        TripGate(s,
                 Stage::kSlam,
                 "slam_beyond_ins_sigma",
                 "SLAM moved " + std::to_string(moves.beyond) + " of " +
                     std::to_string(moves.good.size()) +
                     " pings with good INS (horizontal sigma <= " +
                     Fixed(q.slam_good_ins_sigma_m, 2) + " m) by more than " +
                     Fixed(q.slam_sigma_multiple, 1) + " sigma (up to " + Fixed(moves.worst, 3) +
                     " m): the soundings disagree with a good INS (sonar clock, mount or "
                     "sound speed?); the INS trajectory is kept at those pings",
                 log);
        for (std::size_t i : moves.good) after[i] = before[i];
        ins_check["reverted"] = true;
        return ins_check;
    }
    std::string text;
    const json drift = DriftWindows(moves, q, &text);
    ins_check["drift_windows"] = drift;
    if (!drift.empty()) {
        *drift_text = "SLAM moved most pings of " + std::to_string(drift.size()) +
                      " window(s) beyond the INS's own sigma, while the INS reported a good "
                      "solution: " +
                      text + " (SLAM's correction is kept)";
    }
    return ins_check;
}

// Far above the expected consistency, the passes still disagree in a way SLAM did not (and
// should not) explain: gate slam_inconsistent, saying whether the disagreement sits in a few
// windows (the navigation of those stretches) or everywhere (a survey-wide input).
void GateConsistency(StageContext& s,
                     const slam::SlamResult& r,
                     const QualityConfig& q,
                     double expected_m,
                     const json& windows,
                     const Log& log) {
    if (!(expected_m > 0) || !(r.final_consistency_m > q.slam_consistency_ratio * expected_m))
        return;
    const bool concentrated = std::any_of(
        windows.begin(), windows.end(), [](const json& w) { return w.value("drift", false); });
    TripGate(s,
             Stage::kSlam,
             "slam_inconsistent",
             "after SLAM the overlapping passes still disagree by " +
                 Fixed(r.final_consistency_m, 3) + " m RMS (plane fits), " +
                 Fixed(r.final_consistency_m / expected_m, 1) + "x what the range noise leaves (" +
                 Fixed(expected_m, 3) + " m): " +
                 (concentrated ? std::string("most of it in a few stretches "
                                             "(slam/navigation_drift): the navigation there")
                               : std::string("the soundings disagree in a way the trajectory "
                                             "within the INS sigma does not explain (navigation "
                                             "drift, sonar clock, mount or sound speed?)")) +
                 WorstWindows(windows, expected_m),
             log);
}

// The view's soundings onto the pings' new poses: the held view, or its scratch file a block of
// `block` soundings at a time (decision 043).
Status MoveView(StageContext& s, const std::vector<Pose>& after, std::size_t block) {
    if (!s.spilled_view) return ApplyVehiclePoses(s.geo, after);
    auto delta = MoveVehiclePings(s.geo, after);
    if (!delta) return delta.error();
    return s.spilled_view->MovePositions(
        block, [&delta](georef::GeorefPoints& b, std::size_t) { georef::MovePoints(b, *delta); });
}

// The per-ping products of this stage, written once: before and after; `after` becomes the
// survey's trajectory, with SLAM's posterior sigma per ping when it was computed.
Status WriteSlamProducts(StageContext& s,
                         const SliceSet& set,
                         const slam::SlamResult& r,
                         const SlamStageConfig& sc,
                         const TimedPoses& before,
                         const std::vector<Pose>& after,
                         std::size_t block) {
    const std::string& P = s.out_dir;
    if (auto w = WriteTrajectoryCsv(P + "/trajectory_initial.csv", before); !w) return w;
    if (auto w = io::WritePly(P + "/points_initial.ply",
                              s.geo,
                              ViewPointBlocks(s, block),
                              nullptr,
                              s.model.run_id,
                              nullptr);
        !w)
        return w;
    if (auto w = MoveView(s, after, block); !w) return w;
    s.model.trajectory(survey::TrajectoryVersion::kSlam) =
        georef::TrajectoryOf(s.geo, s.model.ingest.pings.pings.size());
    s.model.trajectory(survey::TrajectoryVersion::kSlam).sigma =
        SlamPingSigma(s.geo, set, r, s.model.ingest.pings.pings.size());
    if (auto w = WriteTrajectoryCsv(P + "/trajectory.csv", PingPoses(s.geo)); !w) return w;
    return WriteTrajectorySigmaCsv(P + "/trajectory_sigma.csv",
                                   s.geo,
                                   before.T_world_vehicle,
                                   s.model,
                                   sc.sigma_max_age_s,
                                   FallbackSigma(sc));
}

constexpr double kMiB = 1024.0 * 1024.0;

// summary.json's "slam": SLAM's result, the checks' figures and the coarse search's sections
// (INS unsure: GNSS outages) with what it did.
json SlamSummary(const slam::SlamResult& r,
                 const SliceSet& set,
                 const slam::SlamConfig& cfg,
                 double expected_consistency,
                 std::pair<double, double> change,
                 json ins_check,
                 json posterior,
                 json windows) {
    json st = {{"termination", slam::ToString(r.termination)},
               {"message", r.message},
               {"slices", set.slices.size()},
               {"points", set.num_points},
               {"points_used", r.num_points},
               {"sections_every_point", r.num_sections_every_point},
               {"sections", r.num_sections},
               {"section_links", r.num_section_links},
               {"poses", r.num_poses},
               {"pairs", r.num_pairs},
               {"rigid_iterations", r.rigid_iterations},
               {"semi_rigid_iterations", r.semi_rigid_iterations},
               {"initial_pair_score_m", r.initial_pair_score_m},
               {"final_pair_score_m", r.final_pair_score_m},
               {"sections_searched", r.num_sections_searched},
               {"sections_shifted", r.num_sections_shifted},
               {"initial_consistency_m", r.initial_consistency_m},
               {"final_consistency_m", r.final_consistency_m},
               {"expected_consistency_m", expected_consistency},
               {"position_change_rms_m", change.first},
               {"position_change_max_m", change.second},
               {"ins_check", std::move(ins_check)},
               {"posterior", std::move(posterior)},
               {"consistency_windows", std::move(windows)},
               {"correspondence", ToString(cfg.correspondence)},
               {"robust_kernel", ToString(cfg.robust_kernel)},
               {"timings_s",
                {{"trees", r.timings.trees_s},
                 {"coarse_search", r.timings.coarse_search_s},
                 {"search", r.timings.search_s},
                 {"build", r.timings.build_s},
                 {"solve", r.timings.solve_s},
                 {"score", r.timings.score_s},
                 {"total", r.timings.total_s}}},
               {"arrays_mb",
                {{"points", static_cast<double>(r.memory.points_bytes) / kMiB},
                 {"world_points", static_cast<double>(r.memory.world_points_bytes) / kMiB},
                 {"trees", static_cast<double>(r.memory.trees_bytes) / kMiB},
                 {"normal_neighbours", static_cast<double>(r.memory.neighbour_bytes) / kMiB},
                 {"pairs", static_cast<double>(r.memory.pairs_bytes) / kMiB},
                 {"total", static_cast<double>(r.memory.total_bytes) / kMiB}}}};
    st["coarse_search"] = json::array();
    for (const slam::SlamSection& sec : r.sections) {
        if (!sec.searched) continue;
        st["coarse_search"].push_back(
            {{"t0_s", sec.t0_s},
             {"t1_s", sec.t1_s},
             {"ins_sigma_h_m", sec.sigma_h_m},
             {"shifted", sec.shifted},
             {"offset_enu_m",
              {sec.coarse_offset_m.x(), sec.coarse_offset_m.y(), sec.coarse_offset_m.z()}}});
    }
    st["iterations"] = r.iterations;
    return st;
}

// The INS's slow horizontal error from the GNSS fixes in the ping headers (decision 027), set
// into SLAM's config for its posterior's reference; its record for summary.json.
json InsSlowErrorFromFixes(const StageContext& s,
                           const SlamStageConfig& sc,
                           slam::SlamConfig& cfg,
                           const Log& log) {
    if (!sc.ins_slow_error_from_fixes) return {{"estimated", false}, {"message", "off"}};
    calib::InsSlowErrorConfig ic;
    if (s.vehicle && !s.vehicle->gnss_antenna_lever_arms_m.empty())
        ic.antenna_lever_arm_m = s.vehicle->gnss_antenna_lever_arms_m.front();
    const calib::InsSlowError e =
        calib::EstimateInsSlowError(s.model.ingest.pings, s.model.ingest.nav, ic);
    log("slam: " + e.message);
    json out = {{"estimated", e.estimated},
                {"message", e.message},
                {"fixes", e.fixes},
                {"fixes_dropped", e.fixes_dropped},
                {"differences", e.differences}};
    if (e.estimated) {
        cfg.reference_horizontal_sigma_m = e.slow_sigma_m;
        out.update({{"slow_sigma_m", e.slow_sigma_m},
                    {"innovation_rms_m", e.rms_m},
                    {"white_sigma_m", e.white_sigma_m},
                    {"ins_reported_sigma_m", e.reported_sigma_m}});
    }
    return out;
}

// A per-beam array of the ping series set aside in a scratch file (.partial-NAME in the
// products folder) and given back bit for bit; an empty array has no file.
template <typename T>
class ArrayAside {
public:
    Status SetAside(std::vector<T>& v, const std::string& path) {
        if (v.empty()) return Ok{};
        auto f = io::RecordFile::Create(path, sizeof(T));
        if (!f) return f.error();
        if (auto st = f->Append(v.data(), v.size()); !st) return st;
        if (auto st = f->Close(); !st) return st;
        file_ = std::move(*f);
        std::vector<T>().swap(v);
        return Ok{};
    }
    Status GiveBack(std::vector<T>& v) {
        if (!file_) return Ok{};
        v.reserve(file_->size());
        auto st = file_->ForEachBlock(kBlock, [&v](std::size_t, std::size_t n, const std::byte* b) {
            const std::size_t at = v.size();
            v.resize(at + n);
            std::memcpy(v.data() + at, b, n * sizeof(T));
            return Status{Ok{}};
        });
        file_.reset();  // the file removed
        return st;
    }

    // MB (2^20 bytes) set aside.
    double mb() const {
        return file_ ? static_cast<double>(file_->size() * sizeof(T)) / (1024.0 * 1024.0) : 0.0;
    }

private:
    static constexpr std::size_t kBlock = std::size_t{1} << 20;
    std::optional<io::RecordFile> file_;
};

// The ping series' per-beam arrays (the range counts, and the intensities and beam angles when
// the survey has them: 4 to 10 bytes a sounding of the survey) wait on disk while SLAM's stage
// runs: it reads the pings' headers, the navigation and the view, never them (decision 044).
class BeamArraysAside {
public:
    // An array that cannot be written stays held (the error says which).
    Status SetAside(StageContext& s) {
        survey::PingSeries& p = s.model.ingest.pings;
        const std::string base =
            (std::filesystem::path(s.out_dir) / formats::kPartialPrefix).string() + "slam_beam_";
        if (auto st = ranges_.SetAside(p.range_counts, base + "ranges"); !st) return st;
        if (auto st = intensities_.SetAside(p.intensities, base + "intensities"); !st) return st;
        return angles_.SetAside(p.beam_angles_deg, base + "angles");
    }
    Status GiveBack(StageContext& s) {
        survey::PingSeries& p = s.model.ingest.pings;
        if (auto st = ranges_.GiveBack(p.range_counts); !st) return st;
        if (auto st = intensities_.GiveBack(p.intensities); !st) return st;
        return angles_.GiveBack(p.beam_angles_deg);
    }

    double mb() const { return ranges_.mb() + intensities_.mb() + angles_.mb(); }

private:
    ArrayAside<std::uint32_t> ranges_;
    ArrayAside<std::uint16_t> intensities_;
    ArrayAside<float> angles_;
};

// SLAM's stage on the survey whose beams are set aside: its products and summary record, not
// the export.
Status SlamOnView(StageContext& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    // The view waits on disk through the stage (issue 38, decision 043): the slices, the range
    // noise, points_initial.ply and the move onto SLAM's trajectory read it a block at a time,
    // and it stays in its file for the stages after (the cleaning and the export read it there,
    // decision 041). The stage's peak past
    // this point is SLAM's, not the view's (`peak_rss_mb_blocks`).
    if (auto st = SpillView(s); !st)
        log("slam: the view stays in memory (" + st.error().message + ")");
    const double peak_view_mb = clock.peak_rss_mb();
    clock.ResetPeakWithinStage();
    const std::size_t block = BlockWithinBudget(config.run, ResidentMb());
    const QualityConfig& q = config.quality;
    auto input = SlamSlices(s, config, block, log);
    if (!input) return Error{"slam: " + input.error().message};
    SliceSet& set = input->set;
    slam::SlamConfig slam_cfg = config.slam;
    json slow_error = InsSlowErrorFromFixes(s, config.slam_stage, slam_cfg, log);
    const slam::SlamResult r = RunSlamLogged(set, slam_cfg, log);
    const TimedPoses before = PingPoses(s.geo);
    std::vector<Pose> after = SlamPingPoses(s.geo, set, r, before);

    ClearGates(s, Stage::kSlam);
    if (r.termination == slam::SlamTermination::kNoOverlap) {
        TripGate(s,
                 Stage::kSlam,
                 "slam_no_overlap",
                 "SLAM found no overlapping passes to register (" + r.message +
                     "): the trajectory is the " + survey::ToString(s.model.latest()) +
                     " one, uncorrected; survey crosslines or overlapping lines to use SLAM",
                 log);
    }
    std::string drift_text;  // where the navigation drifted, by either test below
    json ins_check = CheckAgainstGoodIns(s,
                                         before.T_world_vehicle,
                                         after,
                                         config.slam_stage.sigma_max_age_s,
                                         config.slam.ins_sigma_recovery_time_s,
                                         q,
                                         &drift_text,
                                         log);
    const auto change = PositionChange(before.T_world_vehicle, after);
    // Where the passes still disagree, per window: a stretch far worse than the rest of the
    // survey is the navigation of that stretch; disagreement everywhere is a survey-wide input.
    const double expected_consistency = input->expected_consistency_m;
    json windows_json = ConsistencyWindows(r, q, expected_consistency, &drift_text);
    GateConsistency(s, r, q, expected_consistency, windows_json, log);
    if (!drift_text.empty()) {
        TripGate(s,
                 Stage::kSlam,
                 "navigation_drift",
                 drift_text +
                     ": the navigation drifted there while it reported a good solution "
                     "(check the INS and GNSS logs of those times)",
                 log);
    }

    if (auto w = WriteSlamProducts(s, set, r, config.slam_stage, before, after, block); !w)
        return w;
    log("slam: trajectory moved by " + Fixed(change.first, 3) + " m RMS, " +
        Fixed(change.second, 3) + " m at most; pair score " + Fixed(r.initial_pair_score_m, 4) +
        " -> " + Fixed(r.final_pair_score_m, 4) + " m, consistency " +
        Fixed(r.initial_consistency_m, 4) + " -> " + Fixed(r.final_consistency_m, 4) + " m");
    json posterior = PosteriorJson(
        s.geo, s.model.trajectory(survey::TrajectoryVersion::kSlam).sigma, r, kPosteriorWindowS);
    posterior["ins_slow_error"] = std::move(slow_error);
    json record = SlamSummary(r,
                              set,
                              slam_cfg,
                              expected_consistency,
                              change,
                              std::move(ins_check),
                              std::move(posterior),
                              std::move(windows_json));
    record.update({{"block_soundings", block},
                   {"peak_rss_mb_view", peak_view_mb},
                   {"peak_rss_mb_blocks", PeakRssMb()}});
    RecordStage(s.summary, Stage::kSlam, std::move(record), clock);
    if (r.termination == slam::SlamTermination::kInvalidInput) {
        (void)SaveSummary(s);
        return Error{"slam: " + r.message};
    }
    return Ok{};
}

}  // namespace

Status SlamSurvey(StageContext& s, const PipelineConfig& config, const Log& log) {
    BeamArraysAside aside;
    if (auto st = aside.SetAside(s); !st)
        log("slam: the pings' beams stay in memory (" + st.error().message + ")");
    const double aside_mb = aside.mb();
    const Status slam = SlamOnView(s, config, log);
    const Status back = aside.GiveBack(s);
    const std::string slam_key = ToString(Stage::kSlam);
    if (s.summary.contains("stages") && s.summary["stages"].contains(slam_key))
        s.summary["stages"][slam_key]["beam_arrays_aside_mb"] = aside_mb;
    if (!slam) return slam;
    if (!back) return Error{"slam: " + back.error().message};
    // The export reads the view from its file too (decision 041).
    return s.defer_products ? SaveSummary(s) : ExportSurvey(s, config);
}

namespace {

// One TSDF tile's mesh: the triangles whose centroid lies in its core (fusion::KeepTrianglesIn).
struct MeshTile {
    TileIndex index;
    fusion::VoxelColumns core;
    fusion::TriangleMesh mesh;
};

// The TSDF of the whole survey tile by tile (tiles.hpp): each tile a volume restricted to its
// core and overlap that integrates the scans reaching it, its core copied into `volume` (the
// same voxels as one volume of the whole survey, fusion::VoxelColumns), and, for P/tiles/mesh,
// its own mesh (weight filter, iso-surface, the seam rule). The tiles cover every voxel a scan
// can reach (fusion::ReachOf, the bound TsdfVolume skips scans by). Returns the tiles' integration
// counts summed (a scan reaching several tiles is counted in each) and the record.
// The survey's TSDF tiles: the tile lattice over the columns the scans reach; nullopt when no
// scan has a valid beam.
std::optional<std::vector<VoxelTile>> SurveyVoxelTiles(const std::vector<fusion::SonarScan>& scans,
                                                       const fusion::TsdfConfig& tcfg,
                                                       const PipelineConfig& config) {
    const double vs = tcfg.voxel_size_m;
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (const fusion::SonarScan& scan : scans) {
        const fusion::ScanReach r = fusion::ReachOf(scan, tcfg);
        if (r.empty() || !(r.x_max - r.x_min < 1e6)) continue;  // no beams, or not finite
        x0 = std::min(x0, r.x_min);
        x1 = std::max(x1, r.x_max);
        y0 = std::min(y0, r.y_min);
        y1 = std::max(y1, r.y_max);
    }
    if (!(x0 <= x1)) return std::nullopt;
    const fusion::VoxelColumns extent{static_cast<std::int32_t>(std::floor(x0 / vs)),
                                      static_cast<std::int32_t>(std::ceil(x1 / vs)),
                                      static_cast<std::int32_t>(std::floor(y0 / vs)),
                                      static_cast<std::int32_t>(std::ceil(y1 / vs))};
    return VoxelTiles(extent, VoxelsPerTile(config.tiles, vs), OverlapVoxels(config.tiles, vs));
}

fusion::IntegrateResult IntegrateByTiles(const std::vector<fusion::SonarScan>& scans,
                                         const fusion::TsdfConfig& tcfg,
                                         const PipelineConfig& config,
                                         fusion::TsdfVolume& volume,
                                         std::vector<MeshTile>* meshes,
                                         const ProgressCallback& progress,
                                         json& record,
                                         const std::optional<TileIndex>& only = std::nullopt) {
    const auto start = std::chrono::steady_clock::now();
    fusion::IntegrateResult sum;
    sum.scans = static_cast<std::int64_t>(scans.size());
    const std::optional<std::vector<VoxelTile>> survey_tiles =
        SurveyVoxelTiles(scans, tcfg, config);
    if (!survey_tiles) {
        sum.message = "no valid beams";
        return sum;
    }
    const std::vector<VoxelTile>& tiles = *survey_tiles;
    const double vs = tcfg.voxel_size_m;
    const int m = VoxelsPerTile(config.tiles, vs);
    const int overlap = OverlapVoxels(config.tiles, vs);
    std::int64_t tiles_with_voxels = 0, max_tile_voxels = 0;
    std::size_t max_tile_bytes = 0;
    bool found = false;
    json with_voxels = json::array();
    for (std::size_t k = 0; k < tiles.size() && !sum.cancelled; ++k) {
        const VoxelTile& tile = tiles[k];
        if (only && !(tile.index == *only)) continue;
        found = true;
        fusion::TsdfVolume part(tcfg, tile.region);
        const auto tile_progress = [&](double f) {
            return !progress || progress((static_cast<double>(k) + f) / tiles.size());
        };
        const fusion::IntegrateResult ir = part.Integrate(scans, tile_progress);
        sum.scans_out_of_bounds += ir.scans_out_of_bounds;
        sum.beams_used += ir.beams_used;
        sum.beams_no_detection += ir.beams_no_detection;
        sum.beams_out_of_range += ir.beams_out_of_range;
        sum.beams_inconsistent += ir.beams_inconsistent;
        sum.voxel_updates += ir.voxel_updates;
        sum.prepare_s += ir.prepare_s;
        sum.rasterise_s += ir.rasterise_s;
        sum.merge_s += ir.merge_s;
        sum.cpu_s += ir.cpu_s;
        sum.cancelled = ir.cancelled;
        const fusion::VolumeStats st = part.Stats();
        if (st.active_voxels == 0) continue;
        ++tiles_with_voxels;
        with_voxels.push_back({tile.index.i, tile.index.j});
        max_tile_voxels = std::max(max_tile_voxels, st.active_voxels);
        max_tile_bytes = std::max(max_tile_bytes, st.memory_bytes);
        volume.CopyColumns(part, tile.core);
        if (meshes != nullptr) {
            part.FilterByWeight(config.weight_filter);
            fusion::TriangleMesh cut = fusion::KeepTrianglesIn(
                part.ExtractIsoSurface(config.mesh.iso_m).mesh, tile.core, vs);
            if (!cut.triangles.empty()) meshes->push_back({tile.index, tile.core, std::move(cut)});
        }
    }
    sum.active_voxels = volume.Stats().active_voxels;
    sum.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    sum.message = std::string(sum.cancelled ? "cancelled: " : "") + std::to_string(tiles.size()) +
                  " tiles of " + std::to_string(m) + " voxels (overlap " + std::to_string(overlap) +
                  "), " + std::to_string(tiles_with_voxels) + " with voxels; " +
                  std::to_string(sum.voxel_updates) + " voxel updates, " +
                  std::to_string(sum.active_voxels) + " active voxels";
    record = {{"tile_size_m", config.tiles.tile_size_m},
              {"overlap_m", config.tiles.overlap_m},
              {"voxels_per_tile", m},
              {"overlap_voxels", overlap},
              {"tiles", tiles.size()},
              {"tiles_with_voxels", tiles_with_voxels},
              {"tile_found", found},
              {"tiles_with_voxels_ij", with_voxels},
              {"max_tile_active_voxels", max_tile_voxels},
              {"max_tile_memory_mb", static_cast<double>(max_tile_bytes) / (1024.0 * 1024.0)},
              {"counts", "summed over the tiles (a scan reaching several is counted in each)"}};
    return sum;
}

// The depth colour range of the mesh tiles: mesh.colour_*, else the tiles' joint z range.
std::pair<double, double> TileColourRange(const std::vector<MeshTile>& tiles,
                                          const PipelineConfig& config) {
    double lo = config.mesh.colour_min_z_m, hi = config.mesh.colour_max_z_m;
    if (lo != 0 || hi != 0) return {lo, hi};
    lo = std::numeric_limits<double>::infinity();
    hi = -lo;
    for (const MeshTile& t : tiles) {
        for (const Eigen::Vector3f& v : t.mesh.vertices) {
            lo = std::min(lo, static_cast<double>(v.z()));
            hi = std::max(hi, static_cast<double>(v.z()));
        }
    }
    return {lo, hi};
}

// P/tiles/mesh/mesh_I_J.glb of one tile; returns its entry of index.json: file, bounds (local
// ENU, m: the core's x, y and the mesh's z) and counts.
Expected<json> WriteMeshTile(const StageContext& s,
                             const MeshTile& t,
                             std::pair<double, double> colour_z,
                             double voxel_size_m) {
    mesh::ColouredMesh m;
    m.vertices = t.mesh.vertices;
    m.triangles = t.mesh.triangles;
    double z0 = std::numeric_limits<double>::infinity(), z1 = -z0;
    for (const Eigen::Vector3f& v : m.vertices) {
        m.colours.push_back(mesh::DepthColour(v.z(), colour_z.first, colour_z.second));
        z0 = std::min(z0, static_cast<double>(v.z()));
        z1 = std::max(z1, static_cast<double>(v.z()));
    }
    const std::string name = "mesh_" + TileName(t.index) + ".glb";
    const std::string dir = s.out_dir + "/tiles/mesh";
    if (auto w = mesh::WriteGlb(m, dir + "/" + name, s.model.origin, s.model.run_id); !w)
        return w.error();
    const double vs = voxel_size_m;
    return json{{"i", t.index.i},
                {"j", t.index.j},
                {"file", name},
                {"min_m", {(t.core.x_min - 0.5) * vs, (t.core.y_min - 0.5) * vs, z0}},
                {"max_m", {(t.core.x_max + 0.5) * vs, (t.core.y_max + 0.5) * vs, z1}},
                {"vertices", m.vertices.size()},
                {"triangles", m.triangles.size()}};
}

Status WriteJsonFile(const std::string& path, const json& j) {
    return formats::WriteReplacing(path, [&](const std::string& partial) -> Status {
        std::ofstream f(partial);
        f << j.dump(1) << "\n";
        if (!f) return Error{partial + ": cannot write"};
        return Ok{};
    });
}

// P/tiles/mesh/index.json over the tiles' entries, for a viewer that loads the tiles in view.
Status WriteMeshIndex(const StageContext& s,
                      const json& entries,
                      const fusion::TsdfConfig& tcfg,
                      const PipelineConfig& config,
                      std::pair<double, double> colour_z) {
    const double vs = tcfg.voxel_size_m;
    const json index = {
        {"format", "pitmap mesh tiles 1"},
        {"frame", "local ENU at the origin, metres (glTF files: y up, (E, U, -N))"},
        {"origin",
         {{"latitude_deg", s.model.origin.latitude_deg},
          {"longitude_deg", s.model.origin.longitude_deg},
          {"height_m", s.model.origin.height_m}}},
        {"seam_rule", "a triangle belongs to the tile whose core holds its centroid"},
        {"voxel_size_m", vs},
        {"tile_size_m", VoxelsPerTile(config.tiles, vs) * vs},
        {"colour_z_m", {colour_z.first, colour_z.second}},
        {"tiles", entries}};
    return WriteJsonFile(s.out_dir + "/tiles/mesh/index.json", index);
}

// Every tile's mesh (the folder emptied first) and index.json.
Status WriteMeshTiles(const StageContext& s,
                      const std::vector<MeshTile>& tiles,
                      const fusion::TsdfConfig& tcfg,
                      const PipelineConfig& config,
                      json& record) {
    namespace fs = std::filesystem;
    const std::string dir = s.out_dir + "/tiles/mesh";
    std::error_code ec;
    fs::remove_all(dir, ec);
    fs::create_directories(dir, ec);
    if (ec) return Error{dir + ": " + ec.message()};
    const auto colour_z = TileColourRange(tiles, config);
    json list = json::array();
    std::int64_t triangles = 0;
    for (const MeshTile& t : tiles) {
        auto entry = WriteMeshTile(s, t, colour_z, tcfg.voxel_size_m);
        if (!entry) return entry.error();
        triangles += (*entry)["triangles"].get<std::int64_t>();
        list.push_back(std::move(*entry));
    }
    if (auto w = WriteMeshIndex(s, list, tcfg, config, colour_z); !w) return w;
    record["mesh_tiles"] = list.size();
    record["mesh_tile_triangles"] = triangles;
    return Ok{};
}

// After integration: the weight histogram (before the filter, so the report shows what the
// filter removes), the weight filter, and the stage's record.
json FinishFuse(fusion::TsdfVolume& volume,
                const PipelineConfig& config,
                const fusion::TsdfConfig& tcfg,
                int ping_stride,
                const fusion::IntegrateResult& ir,
                double integrate_peak_mb,
                const Log& log,
                const std::string& name) {
    const fusion::WeightHistogram hist = volume.ComputeWeightHistogram();
    const fusion::WeightFilterResult wf = volume.FilterByWeight(config.weight_filter);
    log(name + ": weight filter: " + wf.message);
    const fusion::VolumeStats vs = volume.Stats();
    json st = ir;  // the integration counts
    st.update({{"sensor_model", ToString(config.tsdf.sensor_model)},
               {"voxel_size_m", tcfg.voxel_size_m},
               {"ping_stride", ping_stride},
               {"truncation_m", config.tsdf.truncation_m},
               {"integrate_seconds", ir.elapsed_s},
               {"integrate_peak_rss_growth_mb", integrate_peak_mb},
               {"min_weight", config.weight_filter.min_weight},
               {"voxels_before_filter", wf.voxels_before},
               {"voxels_removed", wf.voxels_removed},
               {"active_voxels", vs.active_voxels},
               {"grid_memory_mb", static_cast<double>(vs.memory_bytes) / (1024.0 * 1024.0)}});
    st["weight_histogram"] = hist;
    st["weight_histogram"]["before_filter"] = true;
    return st;
}

// A .vdb of the survey's volume (or of a tile's core) with the world frame's origin.
Status WriteTsdf(const StageContext& s, const fusion::TsdfVolume& volume, const std::string& path) {
    const std::vector<std::pair<std::string, std::string>> meta = {
        {"pitmap_origin_latitude_deg", Fixed(s.model.origin.latitude_deg, 9)},
        {"pitmap_origin_longitude_deg", Fixed(s.model.origin.longitude_deg, 9)},
        {"pitmap_origin_height_m", Fixed(s.model.origin.height_m, 4)},
        {"pitmap_frame", "local ENU at the origin, metres"},
        {kRunIdKey, s.model.run_id}};
    return fusion::WriteVdb(volume, path, meta);
}

}  // namespace

// `pitmap fuse --tile I,J`: one TSDF tile alone (tiles.hpp) on the survey's current
// trajectory: P/tiles/tsdf/tsdf_I_J.vdb (its core's voxels before the weight filter),
// P/tiles/mesh/mesh_I_J.glb and mesh_I_J.json (its index entry). Other tiles' files stay.
Status FuseTile(StageContext& s, const PipelineConfig& config, TileIndex tile, const Log& log) {
    namespace fs = std::filesystem;
    const fusion::TsdfConfig& tcfg = config.tsdf;
    const std::vector<fusion::SonarScan> scans =
        MakeScans(s.geo, s.model.ingest.pings, s.model.mount, 1);
    fusion::TsdfVolume volume(tcfg);
    std::vector<MeshTile> meshes;
    json record;
    const fusion::IntegrateResult ir =
        IntegrateByTiles(scans, tcfg, config, volume, &meshes, nullptr, record, tile);
    if (!record.value("tile_found", false)) {
        return Error{"fuse: tile " + TileName(tile) + " is not one of the survey's " +
                     std::to_string(record.value("tiles", 0)) + " TSDF tiles"};
    }
    log("fuse: tile " + TileName(tile) + ": " + ir.message);
    std::error_code ec;
    fs::create_directories(s.out_dir + "/tiles/tsdf", ec);
    fs::create_directories(s.out_dir + "/tiles/mesh", ec);
    if (ec) return Error{s.out_dir + "/tiles: " + ec.message()};
    const std::string name = TileName(tile);
    if (auto w = WriteTsdf(s, volume, s.out_dir + "/tiles/tsdf/tsdf_" + name + ".vdb"); !w)
        return w;
    fs::remove(s.out_dir + "/tiles/mesh/mesh_" + name + ".json", ec);
    if (meshes.empty()) return Ok{};
    auto entry =
        WriteMeshTile(s, meshes.front(), TileColourRange(meshes, config), tcfg.voxel_size_m);
    if (!entry) return entry.error();
    return WriteJsonFile(s.out_dir + "/tiles/mesh/mesh_" + name + ".json", *entry);
}

// `pitmap fuse --list-tiles`: the survey's TSDF tiles, every one of the lattice over the
// columns the scans reach (a tile may turn out empty).
Expected<std::vector<TileIndex>> ListFuseTiles(StageContext& s, const PipelineConfig& config) {
    const std::vector<fusion::SonarScan> scans =
        MakeScans(s.geo, s.model.ingest.pings, s.model.mount, 1);
    const auto tiles = SurveyVoxelTiles(scans, config.tsdf, config);
    if (!tiles) return Error{"fuse: no valid beams: the survey has no TSDF tiles"};
    std::vector<TileIndex> out;
    for (const VoxelTile& t : *tiles) out.push_back(t.index);
    return out;
}

// `pitmap fuse --merge-tiles`: the tiles' cores (P/tiles/tsdf/*.vdb) as the survey's volume,
// then the fuse stage's weight filter, record and tsdf.vdb, and P/tiles/mesh/index.json from the
// tiles' entries.
Status MergeFuseTiles(StageContext& s, const PipelineConfig& config, const Log& log) {
    namespace fs = std::filesystem;
    StageClock clock;
    const fusion::TsdfConfig& tcfg = config.tsdf;
    fusion::TsdfVolume volume(tcfg);
    // Every column (the tile files hold their cores only).
    constexpr std::int32_t kFar = 1 << 30;
    const fusion::VoxelColumns all{-kFar, kFar - 1, -kFar, kFar - 1};
    std::vector<std::string> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(s.out_dir + "/tiles/tsdf", ec)) {
        if (e.path().extension() == ".vdb") files.push_back(e.path().string());
    }
    if (files.empty()) return Error{"fuse: no tiles in " + s.out_dir + "/tiles/tsdf"};
    std::sort(files.begin(), files.end());
    fusion::IntegrateResult ir;
    for (const std::string& f : files) {
        auto part = fusion::ReadVdb(f, tcfg);
        if (!part) return part.error();
        volume.CopyColumns(*part, all);
    }
    ir.active_voxels = volume.Stats().active_voxels;
    ir.message = "merged " + std::to_string(files.size()) +
                 " tiles: " + std::to_string(ir.active_voxels) + " active voxels";
    log("fuse: " + ir.message);
    json st = FinishFuse(volume, config, tcfg, 1, ir, 0.0, log, "fuse");
    json entries = json::array();
    std::vector<std::string> entry_files;
    for (const auto& e : fs::directory_iterator(s.out_dir + "/tiles/mesh", ec)) {
        if (e.path().extension() == ".json" && e.path().filename() != "index.json")
            entry_files.push_back(e.path().string());
    }
    std::sort(entry_files.begin(), entry_files.end());
    std::int64_t triangles = 0;
    for (const std::string& f : entry_files) {
        std::ifstream in(f);
        const json entry = json::parse(in, nullptr, false);
        if (entry.is_discarded()) return Error{f + ": not JSON"};
        triangles += entry.value("triangles", std::int64_t{0});
        entries.push_back(entry);
    }
    const std::pair<double, double> colour_z{config.mesh.colour_min_z_m,
                                             config.mesh.colour_max_z_m};
    if (auto w = WriteMeshIndex(s, entries, tcfg, config, colour_z); !w) return w;
    st["tiles"] = {{"merged", files.size()},
                   {"mesh_tiles", entries.size()},
                   {"mesh_tile_triangles", triangles}};
    if (auto w = WriteTsdf(s, volume, s.out_dir + "/tsdf.vdb"); !w) return w;
    RecordStage(s.summary, Stage::kFuse, st, clock);
    return SaveSummary(s);
}

namespace {

// The view's points to `maker` a block of `block` soundings at a time from its scratch file
// (the held view at once when it could not be spilled), the scans each block completes to
// `take` as they come.
Status MakeScansByBlocks(const StageContext& s,
                         ScanMaker& maker,
                         std::size_t block,
                         const std::function<void(std::vector<fusion::SonarScan>&&)>& take) {
    if (!s.spilled_view) {
        if (auto st = maker.Add(s.geo.points); !st) return st;
    } else {
        georef::GeorefPoints points;
        for (std::size_t first = 0; first < s.spilled_view->size(); first += block) {
            if (auto st = s.spilled_view->ReadBlock(first, block, points); !st) return st;
            if (auto st = maker.Add(points); !st) return st;
            take(maker.Take());
        }
    }
    maker.Finish();
    take(maker.Take());
    return Ok{};
}

// Scans integrated per call by blocks (fusion::ScanStreamIntegrator): as many as make their
// ranges (4 bytes a beam of the widest ping) the size of a block of the view (38 bytes a
// sounding), so that the scans held never outweigh the block read, and the calls (each lists
// the volume's leaves and moves those of the slabs it touches out and back, decision 040) stay
// few: about 20 000 pings of 480 beams at 1 M soundings a block.
std::size_t ScansPerBatch(const StageContext& s, std::size_t block_soundings) {
    std::size_t beams = 1;
    for (const georef::GeorefPing& p : s.geo.pings) {
        if (p.header_index < s.model.ingest.pings.pings.size())
            beams =
                std::max<std::size_t>(beams, s.model.ingest.pings.pings[p.header_index].num_beams);
    }
    constexpr std::size_t kViewBytes = 38, kRangeBytes = 4, kMinScans = 512;
    return std::max(kMinScans, block_soundings * kViewBytes / (kRangeBytes * beams));
}

// The integration of the survey's scans, made from the view by blocks: one batch of scans and
// its neighbours held at a time, or, by tiles (each tile reads every scan), all the scans.
Expected<fusion::IntegrateResult> IntegrateView(StageContext& s,
                                                const PipelineConfig& config,
                                                const fusion::TsdfConfig& tcfg,
                                                int ping_stride,
                                                bool by_tiles,
                                                fusion::TsdfVolume& volume,
                                                std::vector<MeshTile>* mesh_tiles,
                                                ProgressReporter& bar,
                                                json& record) {
    ScanMaker maker(s.geo.pings, s.model.ingest.pings, s.model.mount, ping_stride);
    const std::size_t block = BlockWithinBudget(config.run, ResidentMb());
    record["view_block_soundings"] = s.spilled_view ? block : s.geo.points.size();
    if (by_tiles) {
        std::vector<fusion::SonarScan> scans;
        scans.reserve(maker.num_scans());
        const auto take = [&](std::vector<fusion::SonarScan>&& part) {
            scans.insert(scans.end(),
                         std::make_move_iterator(part.begin()),
                         std::make_move_iterator(part.end()));
        };
        if (auto st = MakeScansByBlocks(s, maker, block, take); !st) return st.error();
        return IntegrateByTiles(
            scans, tcfg, config, volume, mesh_tiles, bar.AsCallback(), record["tiles"]);
    }
    fusion::ScanStreamIntegrator stream(
        volume, ScansPerBatch(s, block), maker.num_scans(), bar.AsCallback());
    const auto take = [&](std::vector<fusion::SonarScan>&& part) { stream.Add(std::move(part)); };
    if (auto st = MakeScansByBlocks(s, maker, block, take); !st) return st.error();
    fusion::IntegrateResult ir = stream.Finish();
    record["scan_batches"] = {{"calls", stream.calls()},
                              {"scans_per_call", ScansPerBatch(s, block)},
                              {"max_scans_held", stream.max_held()}};
    return ir;
}

}  // namespace

Expected<fusion::TsdfVolume> FuseSurvey(StageContext& s,
                                        const PipelineConfig& config,
                                        Stage stage,
                                        ViewAfterScans view,
                                        const Log& log) {
    const std::string name = ToString(stage);
    // The stage reads the view by blocks from its scratch file (decision 034): a view still
    // held by the stage before is put there before this stage's clock starts, so that its peak
    // is its own. A view that cannot be spilled is read where it is held.
    const auto spill_start = std::chrono::steady_clock::now();
    if (auto st = SpillView(s); !st) {
        log(name + ": warning: " + st.error().message + "; the view is read where it is held");
    }
    const double spill_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - spill_start).count();
    StageClock clock;
    fusion::TsdfConfig tcfg = config.tsdf;
    int ping_stride = 1;
    if (stage == Stage::kFuseInitial) {
        // A picture for the report: coarser voxels, fewer pings (RunOptions).
        tcfg.voxel_size_m *= config.run.initial_mesh_voxel_factor;
        ping_stride = std::max(1, config.run.initial_mesh_ping_stride);
        // The kept pings are ping_stride times as far apart: bridged as the full set would be.
        tcfg.ping_gap_fill_m *= ping_stride;
    }
    fusion::TsdfVolume volume(tcfg);
    ProgressReporter bar(name, 1000);
    // What the stage holds at its peak beyond what it started with (the blocks of the view,
    // the scans, the grids): the resident high-water mark is reset here (where the kernel
    // allows; else it stays the stage's) and compared with the memory the finished grids hold.
    clock.ResetPeakWithinStage();
    const double rss_before_integrate_mb = PeakRssMb();
    // Tiles: the final fuse only (the initial one is a picture at coarser voxels).
    const bool by_tiles = config.tiles.enabled && stage == Stage::kFuse;
    std::vector<MeshTile> mesh_tiles;
    json record;
    auto integrated = IntegrateView(s,
                                    config,
                                    tcfg,
                                    ping_stride,
                                    by_tiles,
                                    volume,
                                    config.tiles.write_products ? &mesh_tiles : nullptr,
                                    bar,
                                    record);
    if (!integrated) return Error{name + ": " + integrated.error().message};
    const fusion::IntegrateResult& ir = *integrated;
    if (view == ViewAfterScans::kReleased) {
        s.spilled_view.reset();  // the file removed
        s.geo.points = georef::GeorefPoints{};
    }
    const double integrate_peak_mb = PeakRssMb() - rss_before_integrate_mb;
    bar.Finish();
    log(name + ": " + ir.message);
    json st = FinishFuse(volume, config, tcfg, ping_stride, ir, integrate_peak_mb, log, name);
    if (by_tiles && config.tiles.write_products) {
        if (auto w = WriteMeshTiles(s, mesh_tiles, tcfg, config, record["tiles"]); !w)
            return w.error();
    }
    if (by_tiles) st["tiles"] = record["tiles"];
    st["view_block_soundings"] = record["view_block_soundings"];
    if (!by_tiles) st["scan_batches"] = record["scan_batches"];
    st["view_spill_seconds_before_stage"] = spill_s;
    if (stage == Stage::kFuse) {
        if (auto w = WriteTsdf(s, volume, s.out_dir + "/tsdf.vdb"); !w) return w.error();
    }
    RecordStage(s.summary, stage, st, clock);
    if (auto w = SaveSummary(s); !w) return w.error();
    if (ir.cancelled) return Error{name + ": cancelled"};
    return volume;
}

namespace {

// The datum the grid stage of this run applied (summary.json "vertical_datum", this run's:
// LoadSummaryOfRun), when it is the config's: its CRS and mean height, what the mesh needs.
std::optional<hydro::DatumModel> DatumOfGridStage(const json& summary,
                                                  const PipelineConfig& config) {
    const auto r = summary.find("vertical_datum");
    if (r == summary.end() || !r->is_object()) return std::nullopt;
    if (r->value("datum", "") != hydro::ToString(config.grid.vertical.datum)) return std::nullopt;
    if (!r->value("vertical_crs", json()).is_string() ||
        !r->value("mean_datum_height_m", json()).is_number()) {
        return std::nullopt;
    }
    hydro::DatumModel d;
    d.datum = config.grid.vertical.datum;
    d.crs_name = (*r)["vertical_crs"].get<std::string>();
    const json epsg = r->value("vertical_epsg", json());
    d.vertical_epsg = epsg.is_number_integer() ? epsg.get<int>() : 0;
    d.description = r->value("description", "");
    d.mean_datum_height_m = (*r)["mean_datum_height_m"].get<double>();
    return d;
}

// mesh_utm.{ply,glb,prj}: the mesh in the products' CRS (projected_products.cpp), in the
// vertical datum of this run's points and DEM: the grid stage's (in memory, else as it recorded
// it), the ellipsoid when no grid stage applied one.
Status WriteProjectedMeshes(StageContext& s,
                            const mesh::ColouredMesh& m,
                            const PipelineConfig& config,
                            const Log& log) {
    if (!s.datum) {
        // The datum of this run's points and DEM: the grid stage's, else none was applied
        // (the points are ellipsoidal) and the mesh follows them.
        s.datum = DatumOfGridStage(s.summary, config).value_or(hydro::DatumModel{});
    }
    const auto start = std::chrono::steady_clock::now();
    auto projected = ProjectMesh(m, s.model.origin, *s.datum, config);
    if (!projected) return projected.error();
    const ProductMetadata meta = SurveyProductMetadata(s, config, &*s.datum);
    const std::string& P = s.out_dir;
    if (auto w = mesh::WriteProjectedPly(m, *projected, P + "/mesh_utm.ply", &meta, s.model.run_id);
        !w)
        return w;
    if (auto w = mesh::WriteProjectedGlb(m, *projected, P + "/mesh_utm.glb", &meta, s.model.run_id);
        !w)
        return w;
    if (auto w = io::WritePrj(P + "/mesh_utm.prj", projected->crs_wkt); !w) return w;
    log("mesh: mesh_utm.{ply,glb} in " + projected->crs_name + " (" +
        Fixed(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2) +
        " s)");
    return Ok{};
}

}  // namespace

Status MeshSurvey(StageContext& s,
                  const fusion::TsdfVolume& volume,
                  const PipelineConfig& config,
                  Stage stage,
                  const Log& log) {
    StageClock clock;
    const std::string stage_name = ToString(stage);
    mesh::MeshConfig mcfg = config.mesh;
    if (stage == Stage::kMeshInitial) mcfg.max_hole_edges = 0;  // a picture: no display mesh
    const mesh::MeshResult m = mesh::RunMesh(volume, mcfg);
    log(stage_name + ": " + m.message);
    const std::string& P = s.out_dir;
    const std::optional<Geodetic> origin = s.model.origin;
    if (stage == Stage::kMesh) {
        // Six independent files (two meshes in three formats), written concurrently, largest
        // first: the OBJ text is most of the stage's export time. The first failure in this
        // fixed order is reported, whatever the threads' timing.
        using Writer = Status (*)(const mesh::ColouredMesh&,
                                  const std::string&,
                                  const std::optional<Geodetic>&,
                                  const std::string&);
        struct Job {
            const mesh::ColouredMesh* mesh;
            std::string path;
            Writer write;
        };
        std::vector<Job> jobs;
        for (const auto& [writer, ext] : {std::pair<Writer, const char*>{&mesh::WriteObj, ".obj"},
                                          {&mesh::WriteGlb, ".glb"},
                                          {&mesh::WritePly, ".ply"}}) {
            jobs.push_back({&m.mesh, P + "/mesh" + ext, writer});
            jobs.push_back({&m.mesh_filled, P + "/mesh_filled" + ext, writer});
        }
        std::vector<Status> written(jobs.size(), Ok{});
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, jobs.size(), 1),
            [&](const tbb::blocked_range<std::size_t>& range) {
                for (std::size_t i = range.begin(); i != range.end(); ++i) {
                    written[i] = jobs[i].write(*jobs[i].mesh, jobs[i].path, origin, s.model.run_id);
                }
            },
            tbb::simple_partitioner());
        for (Status& w : written) {
            if (!w) return w;
        }
        if (auto w = WriteProjectedMeshes(s, m.mesh, config, log); !w) return w;
    } else {
        if (auto w = mesh::WritePly(m.mesh, P + "/" + stage_name + ".ply", origin, s.model.run_id);
            !w)
            return w;
    }
    json st = {{"vertices", m.mesh.vertices.size()},
               {"triangles", m.mesh.triangles.size()},
               {"polygons_raw", m.polygons_raw},
               {"polygons_unobserved", m.polygons_unobserved},
               {"area_m2", m.area_m2},
               {"min_z_m", m.min_z_m},
               {"max_z_m", m.max_z_m},
               {"filled_triangles", m.mesh_filled.triangles.size()},
               {"holes_found", m.holes.holes_found},
               {"holes_filled", m.holes.holes_filled},
               {"holes_too_large", m.holes.holes_too_large}};
    RecordStage(s.summary, stage, st, clock);
    return SaveSummary(s);
}

Status ReportSurvey(StageContext& s, const PipelineConfig& config, const Log& log) {
    StageClock clock;
    if (auto w = SaveSummary(s); !w) return w;
    std::vector<std::string> args = {s.out_dir};
    if (!config.run.report_equipment.empty()) {
        args.push_back("--equipment");
        args.push_back(config.run.report_equipment);
    }
    auto run = RunReportProgram(
        config.report_program, args, "the products are complete without report.html");
    if (!run) return run.error();
    log("report: " + s.out_dir + "/report.html");
    RecordStage(s.summary,
                Stage::kReport,
                {{"file", "report.html"}, {"engineering_file", "report_engineering.html"}},
                clock);
    json& rst = s.summary["stages"][ToString(Stage::kReport)];
    rst["peak_rss_mb"] = run->peak_rss_mb;
    rst["cpu_seconds"] = run->cpu_seconds;
    return SaveSummary(s);
}

}  // namespace detail

Status RunSlamStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    // The view made in its file by blocks of pings, never held (decisions 041, 044).
    auto s = detail::LoadSurveyReplacing(
        out_dir, config, detail::StartFrom::kBeforeSlam, Stage::kSlam, log);
    if (!s) return s.error();
    return detail::SlamSurvey(*s, config, log);
}

Status RunFuseTile(const std::string& out_dir,
                   const PipelineConfig& config,
                   TileIndex tile,
                   const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kLatest, log);
    if (!s) return s.error();
    return detail::FuseTile(*s, config, tile, log);
}

Expected<std::vector<TileIndex>> ListTiles(const std::string& out_dir,
                                           const PipelineConfig& config,
                                           Stage stage,
                                           const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kLatest, log);
    if (!s) return s.error();
    if (stage == Stage::kGrid) return detail::ListGridTiles(*s, config, log);
    return detail::ListFuseTiles(*s, config);
}

Status RunMergeFuseTiles(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto s = detail::LoadSurvey(out_dir, config, detail::StartFrom::kLatest, log);
    if (!s) return s.error();
    if (auto r = detail::RemoveProducts(out_dir, detail::ProductsReplacedBy(Stage::kFuse)); !r)
        return r;
    return detail::MergeFuseTiles(*s, config, log);
}

Status RunFuseStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    // The TSDF reads the view by blocks from its file (decision 034): made there, never held.
    auto s =
        detail::LoadSurveyReplacing(out_dir, config, detail::StartFrom::kLatest, Stage::kFuse, log);
    if (!s) return s.error();
    auto v = detail::FuseSurvey(*s, config, Stage::kFuse, detail::ViewAfterScans::kReleased, log);
    if (!v) return v.error();
    return Ok{};
}

namespace {

// A survey of which only the model's state is needed (mesh, report): the world origin, and
// summary.json to add the stage's record to.
Expected<detail::StageContext> LoadState(const std::string& out_dir, const Log& log) {
    auto model =
        survey::LoadSurvey(out_dir + "/" + survey::kSurveyFileName, survey::LoadParts::kState);
    if (!model) return model.error();
    detail::StageContext s;
    s.out_dir = out_dir;
    s.model = std::move(*model);
    s.summary = detail::LoadSummaryOfRun(out_dir, s.model, log);
    return s;
}

// The CPUs this process may run on (its affinity mask), else the machine's.
int CoresAvailable() {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (::sched_getaffinity(0, sizeof set, &set) == 0) return CPU_COUNT(&set);
    return static_cast<int>(::sysconf(_SC_NPROCESSORS_ONLN));
}

}  // namespace

Status RunMeshStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto s = LoadState(out_dir, log);
    if (!s) return s.error();
    std::vector<std::pair<std::string, std::string>> meta;
    auto volume = fusion::ReadVdb(out_dir + "/tsdf.vdb", {}, &meta);
    if (!volume) return Error{volume.error().message + " (run `pitmap fuse` first)"};
    // A volume of another survey (or of a run killed before it replaced the volume) would mesh
    // the wrong seabed under this survey's name.
    std::string volume_run;
    for (const auto& [k, v] : meta) {
        if (k == kRunIdKey) volume_run = v;
    }
    if (const std::string foreign = detail::ForeignProduct(*s, "tsdf.vdb", volume_run);
        !foreign.empty()) {
        return Error{foreign + ": run `pitmap fuse` again"};
    }
    if (auto r = detail::RemoveProducts(out_dir, detail::ProductsReplacedBy(Stage::kMesh)); !r)
        return r;
    return detail::MeshSurvey(*s, *volume, config, Stage::kMesh, log);
}

Status RunReportStage(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    auto s = LoadState(out_dir, log);
    if (!s) return s.error();
    if (auto r = detail::RemoveProducts(out_dir, detail::ProductsReplacedBy(Stage::kReport)); !r)
        return r;
    return detail::ReportSurvey(*s, config, log);
}

namespace {

// `run` after georef, and `rerun`: calibrate, the mesh before SLAM, SLAM, clean, the export,
// grid, fuse, mesh, report, on a survey georeferenced (s.geo) on its newest trajectory.
Status RunAfterGeoref(detail::StageContext& s,
                      const PipelineConfig& config,
                      const Log& log,
                      std::chrono::steady_clock::time_point start) {
    const std::string& out_dir = s.out_dir;
    // The stages that change the survey (georef, calibrate, SLAM, clean) leave points.ply/las,
    // boresight.json and survey.pitmap to one export once the last of them has run.
    s.defer_products = true;
    // With the grid in the run and its points with THU/TVU, the grid stage writes the points.
    const bool grid_points = config.grid.in_run && config.grid.write_point_tpu;
    auto export_now = [&](Status failed, bool points = true) -> Status {
        s.defer_products = false;
        // The point writers read the view from its file (decision 041); the grid stage that
        // follows reads it there too (a view that cannot go there stays held).
        (void)detail::SpillView(s);
        if (auto w = detail::ExportSurvey(s, config, points); !w) return w;
        return failed;
    };
    // The cleaning runs twice: on the navigation's trajectory, so that the calibration and SLAM
    // register accepted soundings only, and after them on the final trajectory, where its
    // verdicts are decided again (and kept) for the grid, the TSDF and the products.
    // The first pass is the 3D tests alone (the echoes that would pull a registration); the
    // range profiles and the enclosed pieces wait for the final one (a tenth of the run's time
    // saved on bejanca).
    const bool clean_first = config.clean.enabled && (config.run.calibrate || config.run.slam);
    if (clean_first) {
        PipelineConfig first = config;
        first.clean.profile_pings = 0;
        first.clean.profile_beams = 0;
        first.clean.fill_max_soundings = 0;
        // Pings whose INS may have drifted by more than a voxel (a GNSS outage: its passes
        // disagree with the others by the drift, not by echoes) wait for the final pass:
        // the first removed 9.4 % of gps-outage's soundings, the overlaps SLAM needs, and SLAM
        // on what was left ended at 0.110 m ATE instead of 0.064 m (docs/uncertainty.md).
        constexpr double kCircular95 = 2.4477;  // 95 % radius over sigma, circular normal
        const double max_sigma_m = first.clean.voxel_m / kCircular95;
        // The cleaning reads the view from the file georef left it in (decisions 037, 041).
        if (auto st = detail::CleanSurvey(s, first, log, max_sigma_m); !st) return export_now(st);
    }
    if (config.run.calibrate) {
        if (auto st = detail::CalibrateSurvey(s, config, log); !st) {
            // No overlap to calibrate on is a property of the survey, not a failure of the run.
            // (the stage's gate says so and keeps the mount of vehicle.yaml).
            if (s.model.calibration != survey::CalibrationState::kNoOverlap) return export_now(st);
        }
    }
    if (config.run.slam && config.run.mesh_before_slam) {
        // The view waits on disk through the mesh before SLAM (SlamSurvey reads it back).
        auto v = detail::FuseSurvey(
            s, config, Stage::kFuseInitial, detail::ViewAfterScans::kSpilled, log);
        if (!v) return export_now(v.error());
        if (auto st = detail::MeshSurvey(s, *v, config, Stage::kMeshInitial, log); !st)
            return export_now(st);
    }
    if (config.run.slam) {
        if (auto st = detail::SlamSurvey(s, config, log); !st) return export_now(st);
    }
    if (config.clean.enabled) {
        if (auto st = detail::CleanSurvey(s, config, log); !st) return export_now(st);
    }
    if (auto st = export_now(Ok{}, !grid_points); !st) return st;
    if (config.grid.in_run) {
        if (auto st = detail::GridSurvey(s, config, log); !st) {
            // The points without THU/TVU rather than none.
            if (grid_points) (void)detail::WritePoints(s, config);
            return st;
        }
    }
    {
        // The TSDF reads the view by blocks from its file (decisions 034, 040).
        auto v =
            detail::FuseSurvey(s, config, Stage::kFuse, detail::ViewAfterScans::kReleased, log);
        if (!v) return v.error();
        // The soundings and the ingested series are saved (survey.pitmap, the points): free
        // them before the mesh, the run's largest stage (~0.4 GB on bejanca).
        s.geo = georef::GeorefResult{};
        s.model.ingest = survey::IngestedSeries{};
        s.model.trajectories = {};
        if (auto st = detail::MeshSurvey(s, *v, config, Stage::kMesh, log); !st) return st;
    }
    auto total = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    s.summary["total_seconds"] = total();
    // What the figures were measured on: the cores this process could use, and whether malloc
    // put large blocks on huge pages (ReexecWithHugePageMalloc in common/peak_memory.hpp).
    s.summary["process"] = {{"cores", CoresAvailable()},
                            {"malloc_huge_pages", MallocOnHugePages()}};
    if (auto st = detail::SaveSummary(s); !st) return st;
    if (config.run.report) {
        auto st = detail::ReportSurvey(s, config, log);
        s.summary["total_seconds"] = total();
        if (auto w = detail::SaveSummary(s); !w) return w;
        if (!st) return st;
    }
    log("done in " + detail::Fixed(total(), 1) + " s; products in " + out_dir);
    return Ok{};
}

}  // namespace

Status RunAll(const std::vector<std::string>& inputs,
              const std::string& out_dir,
              const PipelineConfig& config,
              const Log& log) {
    const auto start = std::chrono::steady_clock::now();
    detail::StageContext s;
    s.out_dir = out_dir;
    s.defer_products = true;
    if (auto st = detail::GeorefSurvey(s, inputs, config, log); !st) return st;
    return RunAfterGeoref(s, config, log, start);
}

Status RunFromSurvey(const std::string& out_dir, const PipelineConfig& config, const Log& log) {
    const auto start = std::chrono::steady_clock::now();
    // From the state georef left: the calibration (when it runs) starts from the nominal
    // mount, and every later version goes.
    // The stages after georef read the view from its file, as `run` leaves it (decision 041).
    auto s = detail::LoadSurveyReplacing(
        out_dir,
        config,
        config.run.calibrate ? detail::StartFrom::kNominal : detail::StartFrom::kBeforeSlam,
        Stage::kCalibrate,
        log);
    if (!s) return s.error();
    log("rerun: the stages after georef on " + out_dir + "/" + survey::kSurveyFileName);
    return RunAfterGeoref(*s, config, log, start);
}

}  // namespace pitmap::proc::pipeline
