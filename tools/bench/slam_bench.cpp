// SPDX-License-Identifier: MIT
// pitmap-bench-slam: continuous-time SLAM on a simulator scenario against its ground truth.
// Builds one Slice per ping straight from the simulator (truth pose times the INS error,
// soundings in the vehicle frame with the true lever arm and boresight), runs RunSlam and
// prints trajectory ATE, track height std, point-to-surface RMS, the per-iteration trend,
// time per phase and peak memory.
//
// Usage: pitmap-bench-slam [scenario] [beam_stride] [correspondence p2p|p2plane|gicp]
//                          [kernel none|huber|cauchy] [bin_slices] [query_stride] [threads]
//                          [key=value ...] [seed=N]
// Positional arguments may be cut short; key=value pairs override SlamConfig fields (see
// Override below for the keys). ATE is also reported per phase: GNSS good, GNSS outage and
// the 30 s after each outage (where the INS pulls its drift back). With SLAM_BENCH_SECTIONS set
// in the environment, the mean position error per 15 s is printed before and after.
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "common/frames.hpp"
#include "common/peak_memory.hpp"
#include "processor/slam/slam.hpp"
#include "tools/sim/nav_errors.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/sonar_model.hpp"
#include "tools/sim/trajectory.hpp"
#include "tools/sim/world.hpp"

namespace {

using namespace pitmap;
using proc::slam::CorrespondenceType;
using proc::slam::RobustKernel;

struct Scored {
    std::vector<std::size_t> slice;  // scoring subset: valid beams only
    std::vector<Eigen::Vector3f> x_vehicle;
    double mean_range_sigma_m = 0;
};

double Ate(const std::vector<Pose>& poses, const std::vector<Pose>& truth) {
    double s = 0;
    for (std::size_t i = 0; i < poses.size(); ++i) {
        s += (poses[i].translation() - truth[i].translation()).squaredNorm();
    }
    return std::sqrt(s / static_cast<double>(poses.size()));
}

// ATE over the slices whose phase (0 good, 1 outage, 2 recovery) is `phase`; also the max.
void AtePhase(const std::vector<Pose>& poses,
              const std::vector<Pose>& truth,
              const std::vector<int>& phase,
              int which,
              double* rms,
              double* max,
              std::size_t* count) {
    double s = 0;
    *max = 0;
    *count = 0;
    for (std::size_t i = 0; i < poses.size(); ++i) {
        if (phase[i] != which) continue;
        const double e2 = (poses[i].translation() - truth[i].translation()).squaredNorm();
        s += e2;
        *max = std::max(*max, std::sqrt(e2));
        ++*count;
    }
    *rms = *count > 0 ? std::sqrt(s / static_cast<double>(*count)) : 0.0;
}

double HeightStd(const std::vector<Pose>& poses) {
    double m = 0, q = 0;
    for (const Pose& p : poses) m += p.translation().z();
    m /= static_cast<double>(poses.size());
    for (const Pose& p : poses) q += std::pow(p.translation().z() - m, 2);
    return std::sqrt(q / static_cast<double>(poses.size()));
}

double SurfaceRms(const sim::PitWorld& world, const Scored& sc, const std::vector<Pose>& poses) {
    double s = 0;
    for (std::size_t i = 0; i < sc.slice.size(); ++i) {
        const Eigen::Vector3d p = poses[sc.slice[i]] * sc.x_vehicle[i].cast<double>();
        s += std::pow(world.SignedDistance(p), 2);
    }
    return std::sqrt(s / static_cast<double>(sc.slice.size()));
}

// Applies "key=value" to the config; false for an unknown key.
bool Override(proc::slam::SlamConfig& c, const std::string& kv) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) return false;
    const std::string k = kv.substr(0, eq);
    const double v = std::atof(kv.c_str() + eq + 1);
    const int i = static_cast<int>(v);
    if (k == "t_d")
        c.min_time_separation_s = v;
    else if (k == "d_max")
        c.max_pair_distance_m = v;
    else if (k == "section_s")
        c.section_length_s = v;
    else if (k == "rigid_it")
        c.rigid_iterations = i;
    else if (k == "rigid_d_max")
        c.rigid_max_pair_distance_m = v;
    else if (k == "link_pairs")
        c.min_section_link_pairs = i;
    else if (k == "it")
        c.max_iterations = i;
    else if (k == "point_sigma")
        c.point_sigma_m = v;
    else if (k == "tangent_sigma")
        c.gicp_tangent_sigma_m = v;
    else if (k == "robust_width")
        c.robust_width = v;
    else if (k == "ins_tau")
        c.ins_correlation_time_s = v;
    else if (k == "ins_scale")
        c.ins_sigma_scale = v;
    else if (k == "abs_pos")
        c.absolute_position_terms = i != 0;
    else if (k == "abs_att")
        c.absolute_attitude_terms = i != 0;
    else if (k == "abs_scale")
        c.absolute_sigma_scale = v;
    else if (k == "recovery_s")
        c.ins_sigma_recovery_time_s = v;
    else if (k == "coarse_m")
        c.coarse_search_m = v;
    else if (k == "coarse_step")
        c.coarse_search_step_m = v;
    else if (k == "coarse_cell")
        c.coarse_search_cell_m = v;
    else if (k == "coarse_sigma")
        c.coarse_search_min_sigma_m = v;
    else if (k == "vrw")
        c.drift_velocity_random_walk_mps_per_sqrt_s = v;
    else if (k == "patience")
        c.score_patience = i;
    else if (k == "rigid_interp")
        c.rigid_interpolate_sections = i != 0;
    else if (k == "score_tol")
        c.score_tolerance = v;
    else
        return false;
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    proc::slam::SlamConfig cfg;
    // SLAM itself, as before the posterior was on by default (its cost and that of its
    // perturbed-start runs: docs/uncertainty.md, docs/decisions/016).
    cfg.posterior = false;
    int npos = argc;
    long seed = -1;  // seed=N: another draw of the scenario's world, INS errors and noise
    for (int a = 1; a < argc; ++a) {
        if (std::string(argv[a]).find('=') != std::string::npos) {
            npos = std::min(npos, a);
            if (std::string(argv[a]).rfind("seed=", 0) == 0) {
                seed = std::atol(argv[a] + 5);
            } else if (!Override(cfg, argv[a])) {
                std::fprintf(stderr, "unknown override %s\n", argv[a]);
                return 2;
            }
        }
    }
    const std::string name = npos > 1 ? argv[1] : "gps-outage";
    const int beam_stride = npos > 2 ? std::atoi(argv[2]) : 4;
    const std::string corr = npos > 3 ? argv[3] : "default";
    const std::string kernel = npos > 4 ? argv[4] : "default";
    const int bin = npos > 5 ? std::atoi(argv[5]) : cfg.bin_slices;
    const int qstride = npos > 6 ? std::atoi(argv[6]) : cfg.query_stride;
    const int threads = npos > 7 ? std::atoi(argv[7]) : 2;

    auto scenario = sim::BuiltinScenario(name);
    if (!scenario.ok()) {
        std::fprintf(stderr, "unknown scenario %s\n", name.c_str());
        return 2;
    }
    if (seed >= 0) scenario->seed = static_cast<std::uint64_t>(seed);
    const sim::ScenarioConfig& sc = *scenario;
    auto track = sim::SurveyTrack::Plan(sc);
    if (!track.ok()) return 2;
    const sim::PitWorld world(sc.pit, sc.seed);
    const sim::TruthTrajectory truth(sc, *track);
    const sim::NavErrorModel nav(sc.nav, truth.duration_s(), sc.seed);
    const sim::SonarModel sonar(sc.sonar, world, sc.seed);
    const Pose T_vehicle_sonar =
        MakePose(frames::RotationNedFromRpy(frames::DegToRad(sc.boresight_deg[0]),
                                            frames::DegToRad(sc.boresight_deg[1]),
                                            frames::DegToRad(sc.boresight_deg[2])),
                 Eigen::Vector3d(
                     sc.lever_arms.sonar_m[0], sc.lever_arms.sonar_m[1], sc.lever_arms.sonar_m[2]));

    const auto num_pings =
        static_cast<std::size_t>(std::floor(truth.duration_s() * sc.sonar.ping_rate_hz + 1e-9));
    std::vector<proc::slam::Slice> slices(num_pings);
    std::vector<Pose> truth_poses(num_pings);
    std::vector<std::vector<std::uint8_t>> valid(num_pings);
    std::vector<int> phase(num_pings, 0);
    constexpr double kRecoveryWindowS = 30.0;
    const auto t_sim = std::chrono::steady_clock::now();
    tbb::parallel_for(std::size_t{0}, num_pings, [&](std::size_t k) {
        const double t = static_cast<double>(k) / sc.sonar.ping_rate_hz;
        const Pose T = truth.PoseAt(t);
        const sim::SimPing ping = sonar.Ping(T * T_vehicle_sonar, static_cast<std::int64_t>(k));
        const sim::NavError e = nav.At(t);
        const frames::Rpy rpy = frames::RpyFromRotationWorld(T.linear());
        proc::slam::Slice& s = slices[k];
        s.gps_time_s = 1.0e6 + t;
        s.T_world_vehicle =
            MakePose(frames::RotationWorldFromRpy(rpy.roll + e.attitude_rpy_rad.x(),
                                                  rpy.pitch + e.attitude_rpy_rad.y(),
                                                  rpy.yaw + e.attitude_rpy_rad.z()),
                     T.translation() + e.position_enu_m);
        s.pose_sigma << e.attitude_stddev_rpy_rad, e.position_stddev_enu_m;
        for (int i = 0; i < static_cast<int>(ping.range_counts.size()); i += beam_stride) {
            if (ping.range_counts[static_cast<std::size_t>(i)] == 0) continue;
            const double r = ping.range_counts[static_cast<std::size_t>(i)] *
                             sc.sonar.range_resolution_mm * 1e-3;
            const double th = frames::DegToRad(sonar.BeamAngleDeg(i));
            const Eigen::Vector3d x =
                T_vehicle_sonar * Eigen::Vector3d(0, r * std::sin(th), r * std::cos(th));
            s.points_vehicle.push_back(x.cast<float>());
            valid[k].push_back(ping.outcome[static_cast<std::size_t>(i)] ==
                               sim::BeamOutcome::kValid);
        }
        truth_poses[k] = T;
        if (!e.gnss_available) {
            phase[k] = 1;
        } else if (t >= kRecoveryWindowS && !nav.At(t - kRecoveryWindowS).gnss_available) {
            phase[k] = 2;
        } else {
            for (double b = 1.0; b < kRecoveryWindowS; b += 1.0) {
                if (t >= b && !nav.At(t - b).gnss_available) phase[k] = 2;
            }
        }
    });
    const double sim_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_sim).count();
    Scored scored;
    double sig = 0;
    std::size_t npts = 0;
    for (std::size_t k = 0; k < num_pings; ++k) {
        npts += slices[k].points_vehicle.size();
        for (std::size_t i = 0; i < slices[k].points_vehicle.size(); i += 5) {
            if (!valid[k][i]) continue;
            scored.slice.push_back(k);
            scored.x_vehicle.push_back(slices[k].points_vehicle[i]);
            sig += sonar.RangeSigma(slices[k].points_vehicle[i].norm());
        }
    }
    scored.mean_range_sigma_m = sig / static_cast<double>(scored.slice.size());

    if (corr != "default") {
        cfg.correspondence = corr == "p2p"       ? CorrespondenceType::kPointToPoint
                             : corr == "p2plane" ? CorrespondenceType::kPointToPlane
                                                 : CorrespondenceType::kGicp;
    }
    if (kernel != "default") {
        cfg.robust_kernel = kernel == "huber"    ? RobustKernel::kHuber
                            : kernel == "cauchy" ? RobustKernel::kCauchy
                                                 : RobustKernel::kNone;
    }
    cfg.bin_slices = bin;
    cfg.query_stride = qstride;
    cfg.num_threads = threads;
    const proc::slam::SlamResult r = proc::slam::RunSlam(slices, cfg);

    std::vector<Pose> before(num_pings), after(num_pings), truth_sorted(num_pings);
    for (std::size_t i = 0; i < num_pings; ++i) {
        const std::size_t k = r.trajectory[i].input_index;
        before[k] = slices[k].T_world_vehicle;
        after[k] = r.trajectory[i].T_world_vehicle;
    }
    std::printf(
        "scenario %s: %zu slices, %zu points (beam stride %d), query stride %d, "
        "bins of %d slices, %s, kernel %s, %d threads (simulation %.1f s)\n",
        name.c_str(),
        num_pings,
        npts,
        beam_stride,
        qstride,
        bin,
        cfg.correspondence == CorrespondenceType::kPointToPoint   ? "p2p"
        : cfg.correspondence == CorrespondenceType::kPointToPlane ? "p2plane"
                                                                  : "gicp",
        cfg.robust_kernel == RobustKernel::kHuber    ? "huber"
        : cfg.robust_kernel == RobustKernel::kCauchy ? "cauchy"
                                                     : "none",
        threads,
        sim_s);
    std::printf("termination: %s (%s)\n", proc::slam::ToString(r.termination), r.message.c_str());
    std::printf("sections %zu, links %zu, poses %zu, coarse search: %zu searched, %zu shifted\n",
                r.num_sections,
                r.num_section_links,
                r.num_poses,
                r.num_sections_searched,
                r.num_sections_shifted);
    std::printf("%-5s %4s %9s %11s %11s %3s %8s %10s %10s %12s %9s %9s\n",
                "stage",
                "it",
                "pairs",
                "cost",
                "cost_after",
                "rej",
                "pair_rms",
                "pair_score",
                "plane_fit",
                "dphi_max",
                "dt_max",
                "ATE");
    for (const auto& it : r.iterations) {
        std::printf("%-5s %4d %9zu %11.4g %11.4g %3d %8.4f %10.5f %10.5f %12.2e %9.2e %9s%s\n",
                    it.stage == proc::slam::SlamStage::kRigid ? "rigid" : "semi",
                    it.iteration,
                    it.num_pairs,
                    it.cost,
                    it.cost_after,
                    it.rejected_steps,
                    it.pair_rms_m,
                    it.pair_score_m,
                    it.consistency_m,
                    it.max_step_rotation_rad,
                    it.max_step_translation_m,
                    "",
                    it.best ? " *" : "");
    }
    std::printf("pair score %.5f -> %.5f m\n", r.initial_pair_score_m, r.final_pair_score_m);
    std::printf(
        "plane-fit consistency %.5f -> %.5f m\n", r.initial_consistency_m, r.final_consistency_m);
    std::printf("ATE %.4f -> %.4f m\n", Ate(before, truth_poses), Ate(after, truth_poses));
    const char* kPhase[3] = {"GNSS good", "GNSS outage", "recovery"};
    for (int ph = 0; ph < 3; ++ph) {
        double r0, m0, r1, m1;
        std::size_t c = 0;
        AtePhase(before, truth_poses, phase, ph, &r0, &m0, &c);
        AtePhase(after, truth_poses, phase, ph, &r1, &m1, &c);
        if (c == 0) continue;
        std::printf("  %-12s %5zu slices: ATE %.4f -> %.4f m, max %.3f -> %.3f m\n",
                    kPhase[ph],
                    c,
                    r0,
                    r1,
                    m0,
                    m1);
    }
    if (std::getenv("SLAM_BENCH_SECTIONS") != nullptr) {
        // Mean position error (after - truth, before - truth) per window, for debugging.
        // SLAM_BENCH_SECTIONS=<seconds> sets the window (default 15 s).
        const double env_s = std::atof(std::getenv("SLAM_BENCH_SECTIONS"));
        const double win_s = env_s > 0 ? env_s : 15.0;
        const auto win =
            static_cast<std::size_t>(std::max(1.0, std::round(win_s * sc.sonar.ping_rate_hz)));
        for (std::size_t k0 = 0; k0 < num_pings; k0 += win) {
            Eigen::Vector3d eb = Eigen::Vector3d::Zero(), ea = Eigen::Vector3d::Zero();
            const std::size_t k1 = std::min(num_pings, k0 + win);
            for (std::size_t k = k0; k < k1; ++k) {
                eb += before[k].translation() - truth_poses[k].translation();
                ea += after[k].translation() - truth_poses[k].translation();
            }
            eb /= static_cast<double>(k1 - k0);
            ea /= static_cast<double>(k1 - k0);
            std::printf(
                "  t %6.1f  pos (%6.1f,%6.1f)  err before %6.2f %6.2f %6.2f  after %6.2f %6.2f "
                "%6.2f\n",
                static_cast<double>(k0) / sc.sonar.ping_rate_hz,
                truth_poses[k0].translation().x(),
                truth_poses[k0].translation().y(),
                eb.x(),
                eb.y(),
                eb.z(),
                ea.x(),
                ea.y(),
                ea.z());
        }
    }
    if (std::getenv("SLAM_BENCH_SECTIONS") != nullptr) {
        // Coarse search per searched section: the offset applied and the one the truth asks for
        // (minus the mean position error of the section's slices).
        for (const auto& sec : r.sections) {
            if (!sec.searched) continue;
            Eigen::Vector3d e = Eigen::Vector3d::Zero();
            std::size_t n = 0;
            for (std::size_t k = 0; k < num_pings; ++k) {
                const double t = slices[k].gps_time_s;
                if (t < sec.t0_s || t > sec.t1_s) continue;
                e += before[k].translation() - truth_poses[k].translation();
                ++n;
            }
            e /= static_cast<double>(std::max<std::size_t>(n, 1));
            std::printf(
                "  section %6.1f-%6.1f s  sigma %5.2f m  coarse %6.2f %6.2f %6.2f  "
                "truth %6.2f %6.2f %6.2f%s\n",
                sec.t0_s,
                sec.t1_s,
                sec.sigma_h_m,
                sec.coarse_offset_m.x(),
                sec.coarse_offset_m.y(),
                sec.coarse_offset_m.z(),
                -e.x(),
                -e.y(),
                -e.z(),
                sec.shifted ? "" : "  (not shifted)");
        }
    }
    std::printf("track height std %.4f -> %.4f m (truth %.4f m)\n",
                HeightStd(before),
                HeightStd(after),
                HeightStd(truth_poses));
    const double rms0 = SurfaceRms(world, scored, before), rms1 = SurfaceRms(world, scored, after);
    std::printf("point-to-surface RMS %.4f -> %.4f m (mean range sigma %.4f m, ratio %.2f)\n",
                rms0,
                rms1,
                scored.mean_range_sigma_m,
                rms1 / scored.mean_range_sigma_m);
    std::printf(
        "time: coarse search %.1f s, trees %.1f s, search %.1f s, build %.1f s, solve %.1f s, "
        "score %.1f s, "
        "total %.1f s; peak RSS %.0f MB\n",
        r.timings.coarse_search_s,
        r.timings.trees_s,
        r.timings.search_s,
        r.timings.build_s,
        r.timings.solve_s,
        r.timings.score_s,
        r.timings.total_s,
        PeakRssMb());
    return 0;
}
