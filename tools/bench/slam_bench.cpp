// SPDX-License-Identifier: MIT
// pitmap-bench-slam: continuous-time SLAM on a simulator scenario against its ground truth.
// Builds one Slice per ping straight from the simulator (truth pose times the INS error,
// soundings in the vehicle frame with the true lever arm and boresight), runs RunSlam and
// prints trajectory ATE, track height std, point-to-surface RMS, the per-iteration trend,
// time per phase and peak memory.
//
// Usage: pitmap-bench-slam [scenario] [beam_stride] [correspondence p2p|p2plane|gicp]
//                          [kernel none|huber|cauchy] [bin_slices] [query_stride] [threads]
#include <sys/resource.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "common/frames.hpp"
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
    std::vector<std::size_t> slice;   // scoring subset: valid beams only
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

}  // namespace

int main(int argc, char** argv) {
    const std::string name = argc > 1 ? argv[1] : "gps-outage";
    const int beam_stride = argc > 2 ? std::atoi(argv[2]) : 4;
    const std::string corr = argc > 3 ? argv[3] : "gicp";
    const std::string kernel = argc > 4 ? argv[4] : "none";
    const int bin = argc > 5 ? std::atoi(argv[5]) : 10;
    const int qstride = argc > 6 ? std::atoi(argv[6]) : 8;
    const int threads = argc > 7 ? std::atoi(argv[7]) : 2;

    auto scenario = sim::BuiltinScenario(name);
    if (!scenario.ok()) {
        std::fprintf(stderr, "unknown scenario %s\n", name.c_str());
        return 2;
    }
    const sim::ScenarioConfig& sc = *scenario;
    auto track = sim::SurveyTrack::Plan(sc);
    if (!track.ok()) return 2;
    const sim::PitWorld world(sc.pit, sc.seed);
    const sim::TruthTrajectory truth(sc, *track);
    const sim::NavErrorModel nav(sc.nav, truth.duration_s(), sc.seed);
    const sim::SonarModel sonar(sc.sonar, world, sc.seed);
    const Pose T_vehicle_sonar = MakePose(
        frames::RotationNedFromRpy(frames::DegToRad(sc.boresight_deg[0]),
                                   frames::DegToRad(sc.boresight_deg[1]),
                                   frames::DegToRad(sc.boresight_deg[2])),
        Eigen::Vector3d(sc.lever_arms.sonar_m[0], sc.lever_arms.sonar_m[1],
                        sc.lever_arms.sonar_m[2]));

    const auto num_pings =
        static_cast<std::size_t>(std::floor(truth.duration_s() * sc.sonar.ping_rate_hz + 1e-9));
    std::vector<proc::slam::Slice> slices(num_pings);
    std::vector<Pose> truth_poses(num_pings);
    std::vector<std::vector<std::uint8_t>> valid(num_pings);
    const auto t_sim = std::chrono::steady_clock::now();
    tbb::parallel_for(std::size_t{0}, num_pings, [&](std::size_t k) {
        const double t = static_cast<double>(k) / sc.sonar.ping_rate_hz;
        const Pose T = truth.PoseAt(t);
        const sim::SimPing ping = sonar.Ping(T * T_vehicle_sonar, static_cast<std::int64_t>(k));
        const sim::NavError e = nav.At(t);
        const frames::Rpy rpy = frames::RpyFromRotationWorld(T.linear());
        proc::slam::Slice& s = slices[k];
        s.gps_time_s = 1.0e6 + t;
        s.T_world_vehicle = MakePose(
            frames::RotationWorldFromRpy(rpy.roll + e.attitude_rpy_rad.x(),
                                         rpy.pitch + e.attitude_rpy_rad.y(),
                                         rpy.yaw + e.attitude_rpy_rad.z()),
            T.translation() + e.position_enu_m);
        s.pose_sigma << e.attitude_stddev_rpy_rad, e.position_stddev_enu_m;
        for (int i = 0; i < static_cast<int>(ping.range_counts.size()); i += beam_stride) {
            if (ping.range_counts[static_cast<std::size_t>(i)] == 0) continue;
            const double r = ping.range_counts[static_cast<std::size_t>(i)] *
                             sc.sonar.range_resolution_mm * 1e-3;
            const double th = frames::DegToRad(sonar.BeamAngleDeg(i));
            const Eigen::Vector3d x = T_vehicle_sonar * Eigen::Vector3d(0, r * std::sin(th),
                                                                        r * std::cos(th));
            s.points_vehicle.push_back(x.cast<float>());
            valid[k].push_back(ping.outcome[static_cast<std::size_t>(i)] ==
                               sim::BeamOutcome::kValid);
        }
        truth_poses[k] = T;
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

    proc::slam::SlamConfig cfg;
    cfg.correspondence = corr == "p2p"       ? CorrespondenceType::kPointToPoint
                         : corr == "p2plane" ? CorrespondenceType::kPointToPlane
                                             : CorrespondenceType::kGicp;
    cfg.robust_kernel = kernel == "huber"    ? RobustKernel::kHuber
                        : kernel == "cauchy" ? RobustKernel::kCauchy
                                             : RobustKernel::kNone;
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
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("scenario %s: %zu slices, %zu points (beam stride %d), query stride %d, "
                "bins of %d slices, %s, kernel %s, %d threads (simulation %.1f s)\n",
                name.c_str(), num_pings, npts, beam_stride, qstride, bin, corr.c_str(),
                kernel.c_str(), threads, sim_s);
    std::printf("termination: %s (%s)\n", proc::slam::ToString(r.termination), r.message.c_str());
    std::printf("sections %zu, links %zu, poses %zu\n", r.num_sections, r.num_section_links,
                r.num_poses);
    std::printf("%-5s %4s %9s %12s %10s %12s %10s %10s\n", "stage", "it", "pairs", "cost",
                "pair_rms", "consistency", "dphi_max", "dt_max");
    for (const auto& it : r.iterations) {
        std::printf("%-5s %4d %9zu %12.4g %10.4f %12.5f %10.2e %10.2e%s\n",
                    it.stage == proc::slam::SlamStage::kRigid ? "rigid" : "semi", it.iteration,
                    it.num_pairs, it.cost, it.pair_rms_m, it.consistency_m,
                    it.max_step_rotation_rad, it.max_step_translation_m, it.best ? " *" : "");
    }
    std::printf("consistency %.5f -> %.5f m\n", r.initial_consistency_m, r.final_consistency_m);
    std::printf("ATE %.4f -> %.4f m\n", Ate(before, truth_poses), Ate(after, truth_poses));
    std::printf("track height std %.4f -> %.4f m (truth %.4f m)\n", HeightStd(before),
                HeightStd(after), HeightStd(truth_poses));
    const double rms0 = SurfaceRms(world, scored, before), rms1 = SurfaceRms(world, scored, after);
    std::printf("point-to-surface RMS %.4f -> %.4f m (mean range sigma %.4f m, ratio %.2f)\n",
                rms0, rms1, scored.mean_range_sigma_m, rms1 / scored.mean_range_sigma_m);
    std::printf("time: trees %.1f s, search %.1f s, build %.1f s, solve %.1f s, score %.1f s, "
                "total %.1f s; peak RSS %.0f MB\n",
                r.timings.trees_s, r.timings.search_s, r.timings.build_s, r.timings.solve_s,
                r.timings.score_s, r.timings.total_s, static_cast<double>(ru.ru_maxrss) / 1024.0);
    return 0;
}
