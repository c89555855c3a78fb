// SPDX-License-Identifier: MIT
// RunSlam on a small synthetic survey: a smooth bumpy seabed, a track with revisits, soundings
// ray-cast from the true trajectory, and an INS trajectory with a smooth drift.
#include "processor/slam/slam.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "common/frames.hpp"

namespace pitmap::proc::slam {
namespace {

double Seabed(double x, double y) {
    return -10.0 + 1.0 * std::sin(x / 4.0) * std::cos(y / 5.0) + 0.5 * std::sin(0.3 * x + 0.2 * y);
}

struct Waypoint {
    double x, y;
};

struct Survey {
    std::vector<Slice> slices;
    std::vector<Pose> truth;
};

// Drives the waypoints at 1 m/s, 5 pings per second; each ping has 61 beams over +-60 deg.
// drift_scale scales a smooth INS error that is zero at t = 0.
Survey MakeSurvey(const std::vector<Waypoint>& wps, double drift_scale, bool flat = false) {
    Survey sv;
    const double dt = 0.2;
    double t = 0;
    for (std::size_t w = 0; w + 1 < wps.size(); ++w) {
        const Eigen::Vector2d a(wps[w].x, wps[w].y), b(wps[w + 1].x, wps[w + 1].y);
        const double len = (b - a).norm();
        const double yaw = std::atan2(b.x() - a.x(), b.y() - a.y());  // clockwise from north
        for (double s = 0; s < len; s += dt) {
            const Eigen::Vector2d p = a + (b - a) * (s / len);
            const Pose T = MakePose(frames::RotationWorldFromRpy(0.02 * std::sin(t), 0.0, yaw),
                                    Eigen::Vector3d(p.x(), p.y(), 0.0));
            Slice sl;
            sl.gps_time_s = 1000.0 + t;
            for (int i = 0; i <= 60; ++i) {
                const double th = frames::DegToRad(-60.0 + 2.0 * i);
                const Eigen::Vector3d dir =
                    T.linear() * Eigen::Vector3d(0, std::sin(th), std::cos(th));
                // March then bisect to the surface.
                double lo = 0, hi = 0;
                for (double r = 0.5; r < 60; r += 0.5) {
                    const Eigen::Vector3d q = T.translation() + r * dir;
                    if (q.z() < (flat ? -10.0 : Seabed(q.x(), q.y()))) {
                        hi = r;
                        break;
                    }
                    lo = r;
                }
                if (hi == 0) continue;
                for (int k = 0; k < 40; ++k) {
                    const double m = 0.5 * (lo + hi);
                    const Eigen::Vector3d q = T.translation() + m * dir;
                    (q.z() < (flat ? -10.0 : Seabed(q.x(), q.y())) ? hi : lo) = m;
                }
                const Eigen::Vector3d pw = T.translation() + 0.5 * (lo + hi) * dir;
                sl.points_vehicle.push_back((T.inverse() * pw).cast<float>());
            }
            // INS error: smooth drift in position and heading, zero at the start.
            const double u = t / 60.0;
            const Eigen::Vector3d dp =
                drift_scale * Eigen::Vector3d(0.05 * u * u, -0.08 * u, 0.04 * u);
            const Eigen::Vector3d dr = drift_scale * Eigen::Vector3d(0.0, 0.001 * u, 0.002 * u);
            sl.T_world_vehicle = MakePose(ExpSO3(dr) * T.linear(), T.translation() + dp);
            sl.pose_sigma << 0.01, 0.01, 0.02, 1.0, 1.0, 1.0;
            sv.slices.push_back(std::move(sl));
            sv.truth.push_back(T);
            t += dt;
        }
    }
    return sv;
}

// RMS position error after removing nothing (the gauge is the first pose).
double Ate(const std::vector<SlamPose>& traj, const std::vector<Pose>& truth) {
    double s = 0;
    for (const SlamPose& p : traj) {
        s += (p.T_world_vehicle.translation() - truth[p.input_index].translation()).squaredNorm();
    }
    return std::sqrt(s / static_cast<double>(traj.size()));
}

std::vector<SlamPose> Initial(const std::vector<Slice>& slices) {
    std::vector<SlamPose> out;
    for (std::size_t i = 0; i < slices.size(); ++i) {
        out.push_back({slices[i].gps_time_s, slices[i].T_world_vehicle, i});
    }
    return out;
}

SlamConfig TestConfig() {
    SlamConfig cfg;
    cfg.min_time_separation_s = 20.0;
    cfg.section_length_s = 8.0;
    cfg.query_stride = 2;
    cfg.absolute_position_terms = false;
    cfg.absolute_attitude_terms = false;
    cfg.min_section_link_pairs = 20;
    cfg.bin_slices = 5;
    cfg.rigid_iterations = 5;
    cfg.rigid_max_pair_distance_m = 0.5;  // drift here is within d_max
    cfg.score_patience = 2;
    cfg.rigid_interpolate_sections = false;  // the paper's rigid sections; see below for the other
    // The mechanisms below (guard, coarse search) were measured at this GICP tangent sigma on
    // these 40 m lines; the default (3.0, set on full-size surveys) is checked where it matters.
    cfg.gicp_tangent_sigma_m = 1.0;
    return cfg;
}

// Two parallel lines and a crossing line, then back over the first line.
const std::vector<Waypoint> kCrossing = {{-20, -8}, {20, -8}, {20, 8}, {-20, 8}, {0, -25}, {0, 25}};

TEST(Slam, RecoversAKnownPerturbation) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    const double before = Ate(Initial(sv.slices), sv.truth);
    for (const auto type : {CorrespondenceType::kPointToPoint,
                            CorrespondenceType::kPointToPlane,
                            CorrespondenceType::kGicp}) {
        SlamConfig cfg = TestConfig();
        cfg.correspondence = type;
        const SlamResult r = RunSlam(sv.slices, cfg);
        ASSERT_NE(r.termination, SlamTermination::kInvalidInput) << r.message;
        ASSERT_NE(r.termination, SlamTermination::kNoOverlap) << r.message;
        const double after = Ate(r.trajectory, sv.truth);
        EXPECT_GT(before, 0.15);
        EXPECT_TRUE(std::isfinite(after));
        EXPECT_LE(r.final_consistency_m, r.initial_consistency_m);
        // Point-to-point (the paper's metric) is biased by the beam spacing (0.35 m here) and
        // is only required to stay finite and not worsen the consistency score.
        if (type != CorrespondenceType::kPointToPoint) {
            EXPECT_LT(after, 0.5 * before) << "type " << static_cast<int>(type) << " " << r.message;
        }
        EXPECT_GT(r.num_pairs, 100u);
        EXPECT_FALSE(r.iterations.empty());
        for (const SlamIteration& it : r.iterations) EXPECT_TRUE(std::isfinite(it.cost));
    }
}

// Every step taken lowers the cost of the pairs it was computed from; the reported best
// iterate is the one with the lowest pair score; the result is never worse than the input.
TEST(Slam, StepsLowerTheCostOfTheirOwnPairs) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    const SlamResult r = RunSlam(sv.slices, TestConfig());
    ASSERT_FALSE(r.iterations.empty()) << r.message;
    double best = r.initial_pair_score_m;
    for (const SlamIteration& it : r.iterations) {
        EXPECT_TRUE(std::isfinite(it.cost_after));
        if (it.max_step_translation_m > 0 || it.max_step_rotation_rad > 0) {
            EXPECT_LT(it.cost_after, it.cost) << "iteration " << it.iteration;
        }
        EXPECT_EQ(it.best, it.pair_score_m < best) << "iteration " << it.iteration;
        if (it.best) best = it.pair_score_m;
    }
    EXPECT_DOUBLE_EQ(r.final_pair_score_m, best);
    EXPECT_LT(r.final_pair_score_m, r.initial_pair_score_m);
}

// Progress is told every iteration of both stages, in order, with the iteration's record; a
// false answer cancels at once and keeps a finite trajectory.
TEST(Slam, ProgressSeesEveryIterationAndCanCancel) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    std::vector<std::pair<SlamStage, int>> told;
    const SlamResult r = RunSlam(sv.slices, TestConfig(), [&](const SlamIteration& it) {
        told.emplace_back(it.stage, it.iteration);
        return true;
    });
    ASSERT_NE(r.termination, SlamTermination::kCancelled) << r.message;
    ASSERT_GE(told.size(), 2u);
    EXPECT_EQ(told.front(), std::make_pair(SlamStage::kRigid, 1));
    EXPECT_EQ(told.back().first, SlamStage::kSemiRigid);
    // Only an iteration that ends its stage (converged, stalled, budget) may go untold.
    EXPECT_GE(told.size() + 2, r.iterations.size());

    int calls = 0;
    const SlamResult cancelled = RunSlam(sv.slices, TestConfig(), [&](const SlamIteration&) {
        ++calls;
        return false;
    });
    EXPECT_EQ(cancelled.termination, SlamTermination::kCancelled);
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(cancelled.trajectory.size(), sv.slices.size());
    for (const SlamPose& p : cancelled.trajectory)
        EXPECT_TRUE(p.T_world_vehicle.matrix().allFinite());
}

// The old guard (a plane-fit score) stopped the rigid stage at iteration 2 while the alignment
// still improved. With a drift of about a metre and patience 1, the stage must go on as long
// as the pair score falls: more than two iterations, and each stop follows a non-improving one.
TEST(Slam, GuardDoesNotStopWhileTheScoreFalls) {
    const Survey sv = MakeSurvey(kCrossing, 4.0);
    SlamConfig cfg = TestConfig();
    cfg.rigid_iterations = 8;
    cfg.rigid_max_pair_distance_m = 2.0;
    cfg.max_iterations = 0;
    cfg.score_patience = 1;
    const SlamResult r = RunSlam(sv.slices, cfg);
    EXPECT_GT(r.rigid_iterations, 2) << r.message << " " << Ate(r.trajectory, sv.truth) << " "
                                     << Ate(Initial(sv.slices), sv.truth);
    if (r.termination == SlamTermination::kScoreStalled) {
        // A stop follows an iteration that gained no more than the tolerance on the best before
        // it (it may still be a hair lower: `best`).
        double best_before = r.initial_pair_score_m;
        for (std::size_t i = 0; i + 1 < r.iterations.size(); ++i)
            best_before = std::min(best_before, r.iterations[i].pair_score_m);
        EXPECT_GE(r.iterations.back().pair_score_m, best_before * (1.0 - cfg.score_tolerance));
    }
    EXPECT_LT(Ate(r.trajectory, sv.truth), 0.5 * Ate(Initial(sv.slices), sv.truth)) << r.message;
}

// GNSS good (2 cm) except in one leg, a GNSS outage: the INS drifts away by up to 2.4 m and says
// so (its sigma grows to 1.5 m), then pulls the drift back within seconds when GNSS returns.
// The coarse search moves that leg's sections into the capture range of the pair matching.
TEST(Slam, CoarseSearchFindsAnOffsetLeg) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    const Eigen::Vector3d offset(2.0, -1.2, 0.3);
    std::vector<bool> leg(sv.slices.size(), false);
    for (std::size_t i = 0; i < sv.slices.size(); ++i) {
        Slice& s = sv.slices[i];
        const double t = s.gps_time_s - 1000.0;
        s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
        if (t >= 60.0 && t < 96.0) {
            // Drift that grows like dead reckoning with a velocity error (quadratic from the
            // start, then about linear).
            const double f =
                std::min(1.0, 0.3 + 0.7 * (t - 60.0) / 36.0) * std::min(1.0, (t - 60.0) / 6.0);
            leg[i] = true;
            s.T_world_vehicle.translation() += f * offset;
            s.pose_sigma.tail<3>().setConstant(std::max(0.02, 1.5 * f));
        } else if (t >= 96.0) {
            s.T_world_vehicle.translation() += std::exp(-(t - 96.0) / 1.0) * offset;
        }
    }
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.rigid_max_pair_distance_m = 4.0;
    // The INS's steady sigma as stated: there ICP alone stops at 0.23 m of the leg. With the
    // steady part weighted up (the default 0.4) ICP alone gets as far as with the search (0.17
    // against 0.16 m), so the comparison below is made as stated.
    cfg.absolute_sigma_scale = 1.0;
    auto leg_ate = [&](const std::vector<SlamPose>& traj) {
        double s = 0;
        std::size_t n = 0;
        for (const SlamPose& p : traj) {
            if (!leg[p.input_index]) continue;
            s += (p.T_world_vehicle.translation() - sv.truth[p.input_index].translation())
                     .squaredNorm();
            ++n;
        }
        return std::sqrt(s / static_cast<double>(n));
    };
    const SlamResult r = RunSlam(sv.slices, cfg);
    EXPECT_GT(r.num_sections_searched, 0u);
    EXPECT_GT(r.num_sections_shifted, 0u);
    EXPECT_LT(leg_ate(r.trajectory), 0.25 * leg_ate(Initial(sv.slices))) << r.message;
    // Without the search, ICP alone: the search must not leave the leg more than a quarter worse
    // (docs/decisions/011: why it no longer beats ICP alone here).
    cfg.coarse_search_m = 0;
    const SlamResult r0 = RunSlam(sv.slices, cfg);
    EXPECT_EQ(r0.num_sections_searched, 0u);
    EXPECT_LT(leg_ate(r.trajectory), 1.25 * leg_ate(r0.trajectory))
        << leg_ate(r.trajectory) << " " << leg_ate(r0.trajectory) << " "
        << leg_ate(Initial(sv.slices));
    // And with the default weight and tangent sigma the search still brings the leg back.
    cfg.coarse_search_m = SlamConfig{}.coarse_search_m;
    cfg.absolute_sigma_scale = SlamConfig{}.absolute_sigma_scale;
    cfg.gicp_tangent_sigma_m = SlamConfig{}.gicp_tangent_sigma_m;
    const SlamResult rd = RunSlam(sv.slices, cfg);
    EXPECT_GT(rd.num_sections_shifted, 0u);
    EXPECT_LT(leg_ate(rd.trajectory), 0.25 * leg_ate(Initial(sv.slices))) << rd.message;
}

// A GNSS recovery (the reported sigma falls sharply) starts a section, and the sections after it
// double from 1 s (the INS pulls its drift back within seconds); sections elsewhere keep
// section_length_s. A survey without one has none.
TEST(Slam, GnssRecoveryStartsShortSections) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) {
        const double t = s.gps_time_s - 1000.0;
        s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
        if (t >= 60.0 && t < 96.0) s.pose_sigma.tail<3>().setConstant(1.5);
    }
    SlamConfig cfg = TestConfig();
    cfg.max_iterations = 0;
    cfg.rigid_iterations = 1;
    const SlamResult r = RunSlam(sv.slices, cfg);
    std::size_t at = r.sections.size();
    for (std::size_t k = 0; k < r.sections.size(); ++k) {
        if (std::abs(r.sections[k].t0_s - 1096.0) < 0.05) at = k;
    }
    ASSERT_LT(at + 4, r.sections.size());
    const double ping_s = 0.2;  // MakeSurvey pings at 5 Hz
    const double expected[4] = {1.0, 1.0, 2.0, 4.0};
    for (int i = 0; i < 4; ++i) {
        const SlamSection& sec = r.sections[at + static_cast<std::size_t>(i)];
        EXPECT_NEAR(sec.t1_s - sec.t0_s + ping_s, expected[i], 0.21) << "section " << i;
    }
    EXPECT_NEAR(
        r.sections.front().t1_s - r.sections.front().t0_s + ping_s, cfg.section_length_s, 0.21);
    // Every section is searched where the (recovery-smoothed) sigma is large, and only there.
    for (const SlamSection& sec : r.sections) {
        EXPECT_EQ(sec.searched, sec.sigma_h_m > cfg.coarse_search_min_sigma_m);
    }

    const SlamResult r0 = RunSlam(MakeSurvey(kCrossing, 0.0).slices, cfg);
    for (const SlamSection& sec : r0.sections) {
        if (&sec == &r0.sections.back()) break;
        EXPECT_NEAR(sec.t1_s - sec.t0_s + ping_s, cfg.section_length_s, 0.21);
    }
}

// Interpolated section corrections (the default): on this small world they recover less than
// rigid sections (measured 0.145 m from 0.265 m, rigid sections 0.13 m or less), but still most
// of the perturbation; on the gps-outage scenario they do better (continuous track).
// N passes back and forth over one 40 m line. With max_partner_passes the sections one section
// is paired with, and the node pairs of the normal equations per pose, stay as they are when
// the survey doubles (docs/decisions/015); with every pass (0, the seed paper) they grow with N.
// The pairs found are the same on every run.
SlamResult RepeatedLine(int passes,
                        int max_partner_passes,
                        double window_s = 0,
                        bool posterior = true) {
    std::vector<Waypoint> wps;
    for (int i = 0; i <= passes; ++i) wps.push_back({i % 2 == 0 ? -20.0 : 20.0, 0.0});
    const Survey sv = MakeSurvey(wps, 1.0);
    SlamConfig cfg = TestConfig();
    cfg.rigid_iterations = 1;
    cfg.max_iterations = 1;
    cfg.max_partner_passes = max_partner_passes;
    cfg.semi_rigid_window_s = window_s;
    cfg.semi_rigid_window_overlap_s = 20.0;
    cfg.posterior = posterior;
    return RunSlam(sv.slices, cfg);
}

TEST(Slam, PartnersPerSectionStayBoundedAsPassesRepeat) {
    struct Links {
        std::size_t section_partners = 0;  // most over the iterations
        double blocks_per_pose = 0;        // semi-rigid normal equations
    };
    auto links = [](const SlamResult& r) {
        Links l;
        for (const SlamIteration& it : r.iterations) {
            l.section_partners = std::max(l.section_partners, it.max_section_partners);
            if (it.stage == SlamStage::kSemiRigid) {
                l.blocks_per_pose = static_cast<double>(it.normal_equation_blocks) /
                                    static_cast<double>(r.num_poses);
            }
        }
        return l;
    };
    const SlamResult eight = RepeatedLine(8, 2);
    const SlamResult sixteen = RepeatedLine(16, 2);
    const SlamResult all = RepeatedLine(16, 0);
    for (const SlamResult* r : {&eight, &sixteen, &all}) {
        ASSERT_EQ(r->iterations.size(), 2u) << r->message;
        EXPECT_GT(r->iterations.front().num_pairs, 1000u);
    }
    const Links l8 = links(eight), l16 = links(sixteen), l_all = links(all);
    // Measured: 13 and 13 sections (30 with every pass); 7.6 and 9.0 node pairs per pose (20.9
    // with every pass: the mean still rises from 8 to 16 passes as the first and last passes,
    // which have partners on one side only, weigh less).
    EXPECT_EQ(l16.section_partners, l8.section_partners);
    EXPECT_GT(l_all.section_partners, 2 * l16.section_partners);
    EXPECT_LT(l16.blocks_per_pose, 0.6 * l_all.blocks_per_pose);
    // The same pairs and links on a second run (the first search, from the input poses: later
    // ones follow steps whose sums depend on the thread order at the level of rounding).
    const SlamResult again = RepeatedLine(16, 2);
    ASSERT_FALSE(again.iterations.empty());
    const SlamIteration& a = again.iterations.front();
    const SlamIteration& b = sixteen.iterations.front();
    EXPECT_EQ(a.num_pairs, b.num_pairs);
    EXPECT_EQ(a.num_section_pairs, b.num_section_pairs);
    EXPECT_EQ(a.max_section_partners, b.max_section_partners);
    EXPECT_EQ(a.normal_equation_blocks, b.normal_equation_blocks);
}

// The semi-rigid solve by windows in time (SlamConfig::semi_rigid_window_s, docs/decisions/017)
// on the crossing pattern driven twice (408 s), against the whole solve: windows of 80 s (5
// cores, 20 s of overlap) or one system.
struct WindowedRuns {
    Survey sv;
    SlamResult whole, windowed;
};

WindowedRuns RunWindowedAndWhole() {
    std::vector<Waypoint> wps;
    for (int r = 0; r < 2; ++r) wps.insert(wps.end(), kCrossing.begin(), kCrossing.end());
    WindowedRuns out{MakeSurvey(wps, 0.25), {}, {}};
    SlamConfig cfg = TestConfig();
    cfg.rigid_iterations = 0;  // the semi-rigid stage from the INS: the windows do the work
    cfg.semi_rigid_window_s = 0;
    out.whole = RunSlam(out.sv.slices, cfg);
    cfg.semi_rigid_window_s = 80.0;
    cfg.semi_rigid_window_overlap_s = 20.0;
    out.windowed = RunSlam(out.sv.slices, cfg);
    return out;
}

// The position correction SLAM applied to each slice, in time order.
std::vector<Eigen::Vector3d> Corrections(const std::vector<Slice>& slices, const SlamResult& r) {
    std::vector<Eigen::Vector3d> c;
    for (const SlamPose& p : r.trajectory) {
        c.push_back(p.T_world_vehicle.translation() -
                    slices[p.input_index].T_world_vehicle.translation());
    }
    return c;
}

TEST(Slam, WindowedSolveFollowsTheWholeSolve) {
    const WindowedRuns r = RunWindowedAndWhole();
    ASSERT_EQ(r.windowed.trajectory.size(), r.whole.trajectory.size());
    std::size_t windowed_steps = 0;
    for (const SlamIteration& it : r.windowed.iterations) {
        if (it.stage != SlamStage::kSemiRigid) continue;
        ++windowed_steps;
        EXPECT_GE(it.windows, 5u);
    }
    ASSERT_GT(windowed_steps, 0u) << r.windowed.message;
    for (const SlamIteration& it : r.whole.iterations) EXPECT_EQ(it.windows, 1u);
    const double before = Ate(Initial(r.sv.slices), r.sv.truth);
    const double whole = Ate(r.whole.trajectory, r.sv.truth);
    const double windowed = Ate(r.windowed.trajectory, r.sv.truth);
    EXPECT_LT(whole, 0.5 * before) << r.whole.message;
    // Measured: ATE 0.273 m before, 0.0214 m whole, 0.0246 m windowed (the same iterations,
    // costs within 1 %); without the coarse level 0.287 m (the windows' own drift is held by
    // their neighbours: the gauge of this survey, no absolute terms, is its first pose).
    EXPECT_LT(windowed, whole + 0.005) << r.windowed.message << " before " << before << " whole "
                                       << whole << " windowed " << windowed;
    double max_diff = 0;
    for (std::size_t s = 0; s < r.whole.trajectory.size(); ++s) {
        max_diff = std::max(max_diff,
                            (r.whole.trajectory[s].T_world_vehicle.translation() -
                             r.windowed.trajectory[s].T_world_vehicle.translation())
                                .norm());
    }
    EXPECT_LT(max_diff, 0.02) << "ATE before " << before << " whole " << whole << " windowed "
                              << windowed;
    // The posterior, by the same windows, is computed for every slice.
    ASSERT_TRUE(r.windowed.posterior.computed) << r.windowed.posterior.message;
    EXPECT_EQ(r.windowed.posterior.windows, 5u);
    EXPECT_EQ(r.windowed.posterior.slice_sigma.size(), r.windowed.trajectory.size());
    EXPECT_LT(r.windowed.posterior.largest_factor_nonzeros,
              r.whole.posterior.largest_factor_nonzeros);
}

// A window boundary leaves no step in the trajectory: the correction changes from one slice to
// the next no more than where the whole survey is one system.
TEST(Slam, WindowBoundariesLeaveNoStep) {
    const WindowedRuns r = RunWindowedAndWhole();
    const auto largest_change = [&](const SlamResult& res) {
        const std::vector<Eigen::Vector3d> c = Corrections(r.sv.slices, res);
        double m = 0;
        for (std::size_t s = 1; s < c.size(); ++s) m = std::max(m, (c[s] - c[s - 1]).norm());
        return m;
    };
    const double whole = largest_change(r.whole), windowed = largest_change(r.windowed);
    EXPECT_GT(whole, 0.0);
    EXPECT_LT(windowed, 1.5 * whole + 1e-4) << "whole " << whole << " windowed " << windowed;
}

// With windows (SlamConfig::semi_rigid_window_s, docs/decisions/017) the factor of the
// semi-rigid normal equations (the largest window's, and the posterior's) stays as it is when
// the passes over the line double; as one system it grows with them. Measured (nonzeros of L,
// 8 and 16 passes): whole 196 k and 797 k; windowed 42 k and 35 k (the posterior's 42 k, 35 k).
TEST(Slam, WindowedFactorStaysBoundedAsPassesRepeat) {
    const auto factor = [](const SlamResult& r) {
        double nnz = 0;
        for (const SlamIteration& it : r.iterations) {
            if (it.stage == SlamStage::kSemiRigid) nnz = std::max(nnz, it.factor_nonzeros);
        }
        return nnz;
    };
    // The whole systems without the posterior (its marginals cost nodes x factor).
    const SlamResult whole8 = RepeatedLine(8, 2, 0, false), whole16 = RepeatedLine(16, 2, 0, false);
    const SlamResult win8 = RepeatedLine(8, 2, 80.0), win16 = RepeatedLine(16, 2, 80.0);
    for (const SlamResult* r : {&whole8, &whole16, &win8, &win16}) {
        ASSERT_GT(factor(*r), 0.0) << r->message;
    }
    for (const SlamResult* r : {&win8, &win16}) {
        ASSERT_TRUE(r->posterior.computed) << r->posterior.message;
    }
    const std::string figures = "factor nonzeros whole " + std::to_string(factor(whole8)) + ", " +
                                std::to_string(factor(whole16)) + "; windowed " +
                                std::to_string(factor(win8)) + ", " +
                                std::to_string(factor(win16)) + "; posterior windowed " +
                                std::to_string(win8.posterior.largest_factor_nonzeros) + ", " +
                                std::to_string(win16.posterior.largest_factor_nonzeros);
    RecordProperty("figures", figures);
    EXPECT_GT(factor(whole16), 1.8 * factor(whole8)) << figures;
    EXPECT_LT(factor(win16), 1.1 * factor(win8)) << figures;
    EXPECT_LT(factor(win16), 0.6 * factor(whole16)) << figures;
    EXPECT_LT(win16.posterior.largest_factor_nonzeros, 1.1 * win8.posterior.largest_factor_nonzeros)
        << figures;
    EXPECT_GT(win16.posterior.windows, win8.posterior.windows);
}

// The rigid stage by windows in time over a coarse level (SlamConfig::rigid_window_s,
// docs/decisions/021) on the crossing pattern driven twice (408 s), the rigid stage alone
// (interpolated sections, as by default): windows of 80 s (5 cores, 20 s of overlap) over
// coarse nodes every 24 s (3 sections), against the whole rigid solve; and windows longer than
// half the survey, which are one system: the whole solve (to the rounding of the threads' sums,
// which differ from run to run; bit for bit in SlamWindows.OneWindowIsTheWholeSolve).
TEST(Slam, RigidWindowsFollowTheWholeRigidSolve) {
    std::vector<Waypoint> wps;
    for (int r = 0; r < 2; ++r) wps.insert(wps.end(), kCrossing.begin(), kCrossing.end());
    const Survey sv = MakeSurvey(wps, 1.0);
    SlamConfig cfg = TestConfig();
    cfg.rigid_interpolate_sections = true;
    cfg.rigid_iterations = 8;
    cfg.max_iterations = 0;  // the rigid stage alone
    cfg.posterior = false;
    cfg.rigid_window_s = 0;
    const SlamResult whole = RunSlam(sv.slices, cfg);
    cfg.rigid_window_s = 300.0;  // 408 s < 2 x 300 s: one window
    const SlamResult one = RunSlam(sv.slices, cfg);
    cfg.rigid_window_s = 80.0;
    cfg.rigid_window_overlap_s = 20.0;
    cfg.rigid_window_coarse_s = 24.0;
    const SlamResult windowed = RunSlam(sv.slices, cfg);

    ASSERT_EQ(one.trajectory.size(), whole.trajectory.size());
    ASSERT_EQ(one.iterations.size(), whole.iterations.size());
    for (std::size_t s = 0; s < whole.trajectory.size(); ++s) {
        ASSERT_LT((one.trajectory[s].T_world_vehicle.matrix() -
                   whole.trajectory[s].T_world_vehicle.matrix())
                      .cwiseAbs()
                      .maxCoeff(),
                  1e-6)
            << "slice " << s;
    }
    std::size_t windowed_steps = 0;
    for (const SlamIteration& it : windowed.iterations) {
        ASSERT_EQ(it.stage, SlamStage::kRigid);
        windowed_steps += it.windows >= 5 ? 1 : 0;
    }
    for (const SlamIteration& it : whole.iterations) EXPECT_EQ(it.windows, 1u);
    ASSERT_GT(windowed_steps, 1u) << windowed.message;

    const double before = Ate(Initial(sv.slices), sv.truth);
    const double a_whole = Ate(whole.trajectory, sv.truth);
    const double a_windowed = Ate(windowed.trajectory, sv.truth);
    double max_diff = 0;
    for (std::size_t s = 0; s < whole.trajectory.size(); ++s) {
        max_diff = std::max(max_diff,
                            (whole.trajectory[s].T_world_vehicle.translation() -
                             windowed.trajectory[s].T_world_vehicle.translation())
                                .norm());
    }
    const std::string figures = "ATE before " + std::to_string(before) + " whole " +
                                std::to_string(a_whole) + " windowed " +
                                std::to_string(a_windowed) + ", largest position difference " +
                                std::to_string(max_diff);
    RecordProperty("figures", figures);
    EXPECT_LT(a_whole, 0.8 * before) << figures;
    EXPECT_LT(a_windowed, a_whole + 0.005) << figures;
    EXPECT_LT(max_diff, 0.03) << figures;
}

TEST(Slam, InterpolatedSectionsRecoverMostOfAPerturbation) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    SlamConfig cfg = TestConfig();
    cfg.rigid_interpolate_sections = true;
    const SlamResult r = RunSlam(sv.slices, cfg);
    EXPECT_LT(Ate(r.trajectory, sv.truth), 0.6 * Ate(Initial(sv.slices), sv.truth)) << r.message;
    EXPECT_LE(r.final_pair_score_m, r.initial_pair_score_m);
}

TEST(Slam, ZeroCorrectionAtTheTruth) {
    const Survey sv = MakeSurvey(kCrossing, 0.0);
    const SlamResult r = RunSlam(sv.slices, TestConfig());
    EXPECT_LT(Ate(r.trajectory, sv.truth), 0.02) << r.message;
}

TEST(Slam, InvariantToInputOrder) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    std::vector<Slice> shuffled = sv.slices;
    std::vector<std::size_t> perm(shuffled.size());
    for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = i;
    std::shuffle(perm.begin(), perm.end(), std::mt19937(42));
    for (std::size_t i = 0; i < perm.size(); ++i) shuffled[i] = sv.slices[perm[i]];
    const SlamResult a = RunSlam(sv.slices, TestConfig());
    const SlamResult b = RunSlam(shuffled, TestConfig());
    ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
    for (std::size_t i = 0; i < a.trajectory.size(); ++i) {
        EXPECT_DOUBLE_EQ(a.trajectory[i].gps_time_s, b.trajectory[i].gps_time_s);
        EXPECT_EQ(perm[b.trajectory[i].input_index], a.trajectory[i].input_index);
        EXPECT_LT((a.trajectory[i].T_world_vehicle.translation() -
                   b.trajectory[i].T_world_vehicle.translation())
                      .norm(),
                  1e-4);
    }
}

TEST(Slam, ThreadCountChangesOnlyRounding) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    SlamConfig one = TestConfig();
    one.num_threads = 1;
    SlamConfig two = TestConfig();
    two.num_threads = 2;
    const SlamResult a = RunSlam(sv.slices, one);
    const SlamResult b = RunSlam(sv.slices, two);
    ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
    for (std::size_t i = 0; i < a.trajectory.size(); ++i) {
        EXPECT_LT((a.trajectory[i].T_world_vehicle.translation() -
                   b.trajectory[i].T_world_vehicle.translation())
                      .norm(),
                  1e-3);
    }
}

void ExpectUnchangedAndFinite(const SlamResult& r, const std::vector<Slice>& slices) {
    ASSERT_EQ(r.trajectory.size(), slices.size());
    for (const SlamPose& p : r.trajectory) {
        EXPECT_TRUE(p.T_world_vehicle.matrix().allFinite());
        EXPECT_TRUE(p.T_world_vehicle.isApprox(slices[p.input_index].T_world_vehicle, 1e-9));
    }
}

TEST(Slam, SinglePassHasNoOverlap) {
    const Survey sv = MakeSurvey({{-20, 0}, {20, 0}}, 1.0);
    const SlamResult r = RunSlam(sv.slices, TestConfig());
    EXPECT_EQ(r.termination, SlamTermination::kNoOverlap) << r.message;
    EXPECT_FALSE(r.message.empty());
    ExpectUnchangedAndFinite(r, sv.slices);
}

TEST(Slam, LongStraightLineHasNoOverlap) {
    const Survey sv = MakeSurvey({{-60, 0}, {60, 0}}, 1.0);
    const SlamResult r = RunSlam(sv.slices, TestConfig());
    EXPECT_EQ(r.termination, SlamTermination::kNoOverlap) << r.message;
    ExpectUnchangedAndFinite(r, sv.slices);
}

TEST(Slam, SlicesWithoutPointsHaveNoOverlap) {
    Survey sv = MakeSurvey(kCrossing, 1.0);
    for (Slice& s : sv.slices) s.points_vehicle.clear();
    const SlamResult r = RunSlam(sv.slices, TestConfig());
    EXPECT_EQ(r.termination, SlamTermination::kNoOverlap) << r.message;
    ExpectUnchangedAndFinite(r, sv.slices);
}

TEST(Slam, FlatSeabedBackAndForthStaysFinite) {
    // A flat floor constrains only height, roll and pitch: the INS terms carry the rest.
    const Survey sv = MakeSurvey({{-20, 0}, {20, 0}, {20, 1}, {-20, 1}}, 1.0, /*flat=*/true);
    const SlamResult r = RunSlam(sv.slices, TestConfig());
    EXPECT_NE(r.termination, SlamTermination::kSolverFailed) << r.message;
    EXPECT_NE(r.termination, SlamTermination::kInvalidInput) << r.message;
    for (const SlamPose& p : r.trajectory) EXPECT_TRUE(p.T_world_vehicle.matrix().allFinite());
    EXPECT_LE(r.final_consistency_m, r.initial_consistency_m + 1e-12);
}

TEST(Slam, InvalidInputIsReported) {
    EXPECT_EQ(RunSlam({}, SlamConfig{}).termination, SlamTermination::kInvalidInput);
    Survey sv = MakeSurvey({{-5, 0}, {5, 0}}, 0.0);
    sv.slices[3].T_world_vehicle.translation().x() = std::nan("");
    const SlamResult r = RunSlam(sv.slices, SlamConfig{});
    EXPECT_EQ(r.termination, SlamTermination::kInvalidInput);
    EXPECT_NE(r.message.find("slice"), std::string::npos);
}

TEST(Slam, ValidateListsEveryProblem) {
    SlamConfig cfg;
    EXPECT_TRUE(cfg.Validate().empty());
    cfg.max_pair_distance_m = 0;
    cfg.bin_slices = 0;
    cfg.query_stride = 0;
    EXPECT_EQ(cfg.Validate().size(), 3u);
    const SlamResult r = RunSlam(MakeSurvey({{-5, 0}, {5, 0}}, 0.0).slices, cfg);
    EXPECT_EQ(r.termination, SlamTermination::kInvalidInput);
}

TEST(Slam, TimeBinsInterpolateSlicePoses) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    SlamConfig cfg = TestConfig();
    cfg.bin_slices = 10;
    const SlamResult r = RunSlam(sv.slices, cfg);
    EXPECT_EQ(r.num_poses, (sv.slices.size() + 9) / 10);
    EXPECT_LT(Ate(r.trajectory, sv.truth), 0.5 * Ate(Initial(sv.slices), sv.truth)) << r.message;
}

// The posterior (SlamPosterior): one finite sigma per slice; the formal one (no variance
// factor) never exceeds what the absolute INS terms alone allow (terms only add information),
// is far below the INS's sigma in an outage that the overlapping passes constrain, and the
// cluster-robust one is never below the formal one.
TEST(Slam, PosteriorIsBoundedByThePriorsAndShrinksAnOutage) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) {
        const double t = s.gps_time_s - 1000.0;
        s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
        if (t >= 60.0 && t < 96.0) s.pose_sigma.tail<3>().setConstant(1.5);
    }
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_cluster_robust = false;
    cfg.posterior_reference_sigma = false;
    cfg.posterior_variance_factor = false;
    cfg.posterior_start_runs = 0;  // the normal equations' part alone (see below for the rest)
    const SlamResult r = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(r.posterior.computed) << r.posterior.message << " / " << r.message;
    ASSERT_EQ(r.posterior.slice_sigma.size(), r.trajectory.size());
    EXPECT_GT(r.posterior.num_pairs, 100u);
    EXPECT_TRUE(std::isfinite(r.posterior.variance_factor));
    EXPECT_GT(r.posterior.variance_factor, 0.0);
    EXPECT_GT(r.posterior.observations, r.posterior.unknowns);
    // The absolute position term's sigma where GNSS is good: absolute_sigma_scale x the floor.
    const double abs_sigma = cfg.absolute_sigma_scale * 0.02;
    double outage_max = 0;
    std::size_t outage = 0;
    for (std::size_t s = 0; s < r.trajectory.size(); ++s) {
        const Vector6d& sig = r.posterior.slice_sigma[s];
        for (int c = 0; c < 6; ++c) {
            ASSERT_TRUE(std::isfinite(sig(c)) && sig(c) > 0) << s << " " << c;
        }
        const double t = r.trajectory[s].gps_time_s - 1000.0;
        if (t < 55.0) {  // well before the outage (the recovery after it is smoothed)
            for (int c = 3; c < 6; ++c) EXPECT_LE(sig(c), abs_sigma * 1.001) << s << " " << c;
        }
        if (t >= 65.0 && t < 91.0) {
            ++outage;
            outage_max = std::max(outage_max, std::max(sig(3), sig(4)));
        }
    }
    ASSERT_GT(outage, 50u);
    EXPECT_LT(outage_max, 0.3) << "the passes constrain the outage to well below 1.5 m";

    // The cluster-robust sandwich adds H^-1 M H^-1 (positive semi-definite) to the formal one.
    SlamConfig robust = cfg;
    robust.posterior_cluster_robust = true;
    const SlamResult rr = RunSlam(sv.slices, robust);
    ASSERT_TRUE(rr.posterior.computed) << rr.posterior.message;
    EXPECT_GT(rr.posterior.clusters, 1u);
    ASSERT_EQ(rr.posterior.slice_sigma.size(), r.posterior.slice_sigma.size());
    for (std::size_t s = 0; s < r.trajectory.size(); ++s) {
        for (int c = 0; c < 6; ++c) {
            EXPECT_GE(rr.posterior.slice_sigma[s](c), r.posterior.slice_sigma[s](c) * (1 - 1e-6))
                << s << " " << c;
        }
    }

    SlamConfig off = cfg;
    off.posterior = false;
    EXPECT_FALSE(RunSlam(sv.slices, off).posterior.computed);
}

// The INS's slow error stated from the data (SlamConfig::reference_horizontal_sigma_m, set by
// the pipeline from the header GNSS fixes; docs/decisions/027): where it exceeds the INS's
// steady sigma the posterior's reference takes it for east and north (not up), so a GNSS-good
// slice's horizontal sigma is at least it; below the INS's own it changes nothing.
TEST(Slam, TheDataStatedSlowErrorEntersTheReference) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) s.pose_sigma << 0.002, 0.002, 0.004, 0.01, 0.01, 0.015;
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_start_runs = 0;
    const SlamResult plain = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(plain.posterior.computed) << plain.posterior.message;
    EXPECT_NEAR(plain.posterior.reference_horizontal_sigma_m, 0.01, 1e-9);
    SlamConfig stated = cfg;
    stated.reference_horizontal_sigma_m = 0.03;
    const SlamResult r = RunSlam(sv.slices, stated);
    ASSERT_TRUE(r.posterior.computed) << r.posterior.message;
    EXPECT_NEAR(r.posterior.reference_horizontal_sigma_m, 0.03, 1e-9);
    ASSERT_EQ(r.posterior.slice_sigma.size(), plain.posterior.slice_sigma.size());
    for (std::size_t s = 0; s < r.posterior.slice_sigma.size(); ++s) {
        const Vector6d& a = plain.posterior.slice_sigma[s];
        const Vector6d& b = r.posterior.slice_sigma[s];
        for (int c = 3; c < 5; ++c) {
            EXPECT_GE(b(c), 0.03) << s << " " << c;
            // The same posterior with 0.03^2 - 0.01^2 more variance in the reference.
            EXPECT_NEAR(b(c) * b(c), a(c) * a(c) + 0.03 * 0.03 - 0.01 * 0.01, 1e-8) << s;
        }
        EXPECT_DOUBLE_EQ(b(5), a(5)) << s;
        EXPECT_DOUBLE_EQ(b(2), a(2)) << s;
    }
    SlamConfig below = cfg;
    below.reference_horizontal_sigma_m = 0.005;
    const SlamResult q = RunSlam(sv.slices, below);
    ASSERT_TRUE(q.posterior.computed) << q.posterior.message;
    for (std::size_t s = 0; s < q.posterior.slice_sigma.size(); ++s) {
        EXPECT_DOUBLE_EQ(q.posterior.slice_sigma[s](3), plain.posterior.slice_sigma[s](3)) << s;
    }
    SlamConfig bad = cfg;
    bad.reference_horizontal_sigma_m = -0.01;
    EXPECT_EQ(RunSlam(sv.slices, bad).termination, SlamTermination::kInvalidInput);
}

// The survey driven along wps with the INS's steady error as the simulator's INS makes it
// (Gauss-Markov, 10 / 10 / 15 mm, 60 s), the INS reporting those sigmas.
Survey SteadyErrorSurvey(const std::vector<Waypoint>& wps) {
    Survey sv = MakeSurvey(wps, 0.0);
    std::mt19937_64 rng(42);
    std::normal_distribution<double> normal;
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    const Eigen::Vector3d sd(0.01, 0.01, 0.015);
    for (std::size_t i = 0; i < sv.slices.size(); ++i) {
        const double a = i == 0 ? 0.0 : std::exp(-0.2 / 60.0);
        for (int c = 0; c < 3; ++c) e(c) = a * e(c) + std::sqrt(1 - a * a) * sd(c) * normal(rng);
        Slice& s = sv.slices[i];
        s.T_world_vehicle =
            MakePose(s.T_world_vehicle.linear(), s.T_world_vehicle.translation() + e);
        s.pose_sigma << 0.002, 0.002, 0.004, sd(0), sd(1), sd(2);
    }
    return sv;
}

SlamConfig SteadyErrorConfig() {
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_start_runs = 0;
    return cfg;
}

// The INS's steady position error is a Gauss-Markov process of ins_correlation_time_s (60 s).
// Where GNSS is good the semi-rigid stage usually keeps its start, the rigid stage's result
// (bejanca: both semi-rigid iterates scored worse), whose error from that process is far less
// than the INS's: bejanca's INS erred 14.2 mm vertically, the result 8.9 mm (decision 042). The
// posterior then states the rigid result's response to the process (RigidSteadyVariance), not
// the INS's whole steady sigma (which it added to every slice before: 15 mm or more, everywhere
// here). Bounds: no combination of the INS's positions whose weights sum to one (only the
// absolute terms place the survey) errs less than the process's mean over the whole survey,
// f sqrt(2 tau / (2 tau + D)); the crossing pattern driven three times (D = 612 s) ties each
// place to passes minutes apart. The INS here errs as the simulator's does (Gauss-Markov), and
// as on bejanca the semi-rigid iterates score worse than the rigid result, which is kept.
TEST(Slam, TheRigidResultStatesTheInsSteadyErrorAsItCarriesIt) {
    std::vector<Waypoint> wps;
    for (int r = 0; r < 3; ++r) wps.insert(wps.end(), kCrossing.begin(), kCrossing.end());
    const Survey sv = SteadyErrorSurvey(wps);
    const double f = 0.015;
    SlamConfig cfg = SteadyErrorConfig();
    const double D = sv.slices.back().gps_time_s - sv.slices.front().gps_time_s;
    const double tau = cfg.ins_correlation_time_s;
    const double least = f * std::sqrt(2 * tau / (2 * tau + D));
    for (const bool interpolate : {false, true}) {
        cfg.rigid_interpolate_sections = interpolate;
        const SlamResult r = RunSlam(sv.slices, cfg);
        ASSERT_TRUE(r.posterior.computed) << r.posterior.message << " / " << r.message;
        EXPECT_EQ(r.posterior.steady_model, "rigid_response");
        std::vector<double> up;
        for (const Vector6d& sg : r.posterior.slice_sigma) up.push_back(sg(5));
        std::sort(up.begin(), up.end());
        const double median = up[up.size() / 2];
        const std::string what = std::string(interpolate ? "interpolated" : "rigid sections") +
                                 ": median " + std::to_string(median) + ", least " +
                                 std::to_string(up.front()) + ", most " + std::to_string(up.back());
        EXPECT_LT(median, 0.8 * f) << what;
        EXPECT_GT(up.front(), least) << what;
        // The draws' noise (256: a slice's sigma to about +-4.5 %) and the formal part.
        EXPECT_LE(up.back(), 1.15 * f) << what;
    }
}

// Where the semi-rigid stage's iterate is kept (no rigid stage here), the INS's steady error
// enters as that estimator carries it (decision 045): through the semi-rigid stage's own normal
// equations, its pairs at the solver's weights. Where the passes tie a place to passes minutes
// apart the stated steady error is below the INS's f (never below the process's mean over the
// tied part); on a leg that no other pass sees, minutes after the last tie, nothing averages
// it and it is f whole (the draws' noise aside). Before, every slice stated at least f.
TEST(Slam, TheSemiRigidResultStatesTheInsSteadyErrorAsItCarriesIt) {
    std::vector<Waypoint> wps;
    for (int r = 0; r < 3; ++r) wps.insert(wps.end(), kCrossing.begin(), kCrossing.end());
    const double tied_until = 1000.0 + [&] {  // the time the crossing pattern ends
        double len = 0;
        for (std::size_t w = 0; w + 1 < wps.size(); ++w) {
            len += std::hypot(wps[w + 1].x - wps[w].x, wps[w + 1].y - wps[w].y);
        }
        return len;  // at 1 m/s
    }();
    wps.push_back({0, 300});  // a leg of 275 s no other pass sees
    const Survey sv = SteadyErrorSurvey(wps);
    const double f = 0.015;
    SlamConfig cfg = SteadyErrorConfig();
    cfg.rigid_iterations = 0;
    cfg.max_iterations = 3;
    const double tau = cfg.ins_correlation_time_s;
    const double least = f * std::sqrt(2 * tau / (2 * tau + (tied_until - 1000.0)));
    const SlamResult r = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(r.posterior.computed) << r.posterior.message << " / " << r.message;
    EXPECT_EQ(r.posterior.steady_model, "semi_rigid_response");
    ASSERT_EQ(r.posterior.slice_sigma.size(), sv.slices.size());
    std::vector<double> tied, free;
    for (std::size_t s = 0; s < sv.slices.size(); ++s) {
        const double t = sv.slices[s].gps_time_s;
        const double up = r.posterior.slice_sigma[s](5);
        if (t < tied_until) tied.push_back(up);
        if (t > tied_until + 3 * tau) free.push_back(up);
    }
    ASSERT_FALSE(tied.empty());
    ASSERT_FALSE(free.empty());
    std::sort(tied.begin(), tied.end());
    std::sort(free.begin(), free.end());
    const std::string what = "tied: median " + std::to_string(tied[tied.size() / 2]) + ", least " +
                             std::to_string(tied.front()) + "; free: median " +
                             std::to_string(free[free.size() / 2]) + ", least " +
                             std::to_string(free.front());
    RecordProperty("steady", what);
    EXPECT_LT(tied[tied.size() / 2], 0.8 * f) << what;
    EXPECT_GT(tied.front(), least) << what;
    // The draws' noise: a slice's sigma to about +-4.5 % (256 draws).
    EXPECT_GT(free.front(), 0.9 * f) << what;
    EXPECT_GT(free[free.size() / 2], 0.97 * f) << what;
}

// Only the absolute terms know where the survey is: the pair, relative-motion and drift-
// smoothness terms are all relative, so the posterior of a common east offset is at least the
// absolute terms' sigma over sqrt(poses). (The drift-smoothness term's Jacobian had the sign of
// its first pose wrong, which anchored every pose to about 1 mm: the posterior stayed near 1 mm
// whatever the absolute terms' weight.)
TEST(Slam, OnlyTheAbsoluteTermsAnchorTheSurvey) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_cluster_robust = false;
    cfg.posterior_reference_sigma = false;
    cfg.posterior_variance_factor = false;
    cfg.absolute_sigma_scale = 40.0;  // 0.8 m a pose
    cfg.posterior_start_runs = 0;
    const SlamResult r = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(r.posterior.computed) << r.posterior.message << " / " << r.message;
    std::vector<double> east;
    for (const Vector6d& sg : r.posterior.slice_sigma) east.push_back(sg(3));
    std::sort(east.begin(), east.end());
    const double bound = 0.8 / std::sqrt(static_cast<double>(r.num_poses));
    EXPECT_GT(east.front(), 0.95 * bound);
}

// The perturbed-start runs (posterior_start_runs): their spread is what SLAM's result
// depends on the start, added in quadrature to the normal equations' posterior; it is zero
// where the INS reports no drift to perturb (the runs start alike there and end alike) and
// not where the outage left the result free to stop elsewhere.
TEST(Slam, StartSpreadIsAddedWhereTheOutageLeavesTheResultFree) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) {
        const double t = s.gps_time_s - 1000.0;
        s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
        if (t >= 60.0 && t < 96.0) s.pose_sigma.tail<3>().setConstant(0.3);
    }
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_start_runs = 0;
    const SlamResult plain = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(plain.posterior.computed) << plain.posterior.message;
    EXPECT_EQ(plain.posterior.start_runs, 0u);
    EXPECT_TRUE(plain.posterior.start_spread.empty());

    cfg.posterior_start_runs = 3;
    const SlamResult r = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(r.posterior.computed) << r.posterior.message;
    EXPECT_EQ(r.posterior.start_runs, 3u);
    ASSERT_EQ(r.posterior.start_spread.size(), r.trajectory.size());
    ASSERT_EQ(plain.trajectory.size(), r.trajectory.size());
    std::vector<double> outage_spread, good_spread;  // horizontal
    for (std::size_t s = 0; s < r.trajectory.size(); ++s) {
        const Eigen::Vector3d& d = r.posterior.start_spread[s];
        ASSERT_TRUE(d.allFinite() && (d.array() >= 0).all()) << s;
        // The main run is the same with and without the extra runs (up to the rounding of
        // TBB's reductions), and its sigma is the posterior's and the spread in quadrature.
        for (int c = 0; c < 3; ++c) {
            const double expected = std::hypot(plain.posterior.slice_sigma[s](3 + c), d(c));
            EXPECT_NEAR(r.posterior.slice_sigma[s](3 + c), expected, 1e-6 + 1e-3 * expected)
                << s << " " << c;
        }
        for (int c = 0; c < 3; ++c) {  // attitudes are not perturbed: their sigma is as it was
            const double a = plain.posterior.slice_sigma[s](c);
            EXPECT_NEAR(r.posterior.slice_sigma[s](c), a, 1e-9 + 1e-3 * a) << s << " " << c;
        }
        const double t = r.trajectory[s].gps_time_s - 1000.0;
        if (t >= 65.0 && t < 95.0) outage_spread.push_back(d.head<2>().norm());
        if (t < 50.0) good_spread.push_back(d.head<2>().norm());
    }
    // Medians: the stretch next to the outage shares its pairs and moves with it a little.
    const auto median = [](std::vector<double> v) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return v[v.size() / 2];
    };
    ASSERT_FALSE(outage_spread.empty() || good_spread.empty());
    EXPECT_GT(median(outage_spread), 0.01) << "the runs from perturbed starts all ended alike";
    EXPECT_LT(median(good_spread), 0.1 * median(outage_spread))
        << "GNSS-good stretches should not spread";
}

// Without a drift beyond a point's sigma the perturbed starts would end where this run did:
// the runs are not made and the posterior is the normal equations' alone.
TEST(Slam, NoStartRunsWithoutInsDrift) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
    sv.slices[100].pose_sigma.tail<3>().setConstant(0.04);  // 35 mm above the floor: < 5 cm
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_start_runs = 3;
    const SlamResult r = RunSlam(sv.slices, cfg);
    ASSERT_TRUE(r.posterior.computed) << r.posterior.message;
    EXPECT_EQ(r.posterior.start_runs, 0u);
    EXPECT_TRUE(r.posterior.start_spread.empty());
    EXPECT_NE(r.posterior.start_runs_note.find("no horizontal drift"), std::string::npos)
        << r.posterior.start_runs_note;
}

// SLAM given its slices to keep (the rvalue RunSlam) moves their points into its own array and
// holds them once: the same run bit for bit (one thread, so that no reduction's order differs),
// with an outage's perturbed-start runs (which read the points again) and non-finite points;
// the slices are left with their times and poses and no points; the array is sized once (its
// capacity the finite points, not push_back's growth).
TEST(Slam, SlicesGivenToKeepGiveTheSameRunBitForBit) {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    std::size_t finite = 0;
    for (Slice& s : sv.slices) {
        const double t = s.gps_time_s - 1000.0;
        s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
        if (t >= 60.0 && t < 96.0) s.pose_sigma.tail<3>().setConstant(0.3);
        if (s.points_vehicle.size() > 3) s.points_vehicle[3].x() = std::nanf("");
        for (const auto& x : s.points_vehicle) finite += x.allFinite() ? 1 : 0;
    }
    SlamConfig cfg = TestConfig();
    cfg.absolute_position_terms = true;
    cfg.absolute_attitude_terms = true;
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_start_runs = 2;
    cfg.num_threads = 1;
    const SlamResult kept = RunSlam(sv.slices, cfg);
    std::vector<Slice> given = sv.slices;
    const SlamResult moved = RunSlam(std::move(given), cfg);
    ASSERT_EQ(kept.termination, moved.termination);
    ASSERT_EQ(kept.posterior.start_runs, 2u) << kept.posterior.start_runs_note;
    ASSERT_EQ(moved.posterior.start_runs, 2u);
    ASSERT_EQ(kept.trajectory.size(), moved.trajectory.size());
    for (std::size_t i = 0; i < kept.trajectory.size(); ++i) {
        EXPECT_EQ(kept.trajectory[i].input_index, moved.trajectory[i].input_index);
        EXPECT_TRUE(kept.trajectory[i].T_world_vehicle.matrix() ==
                    moved.trajectory[i].T_world_vehicle.matrix())
            << i;
        EXPECT_TRUE(kept.posterior.slice_sigma[i] == moved.posterior.slice_sigma[i]) << i;
        EXPECT_TRUE(kept.posterior.start_spread[i] == moved.posterior.start_spread[i]) << i;
    }
    EXPECT_EQ(kept.iterations.size(), moved.iterations.size());
    EXPECT_EQ(kept.final_pair_score_m, moved.final_pair_score_m);
    ASSERT_EQ(given.size(), sv.slices.size());
    for (std::size_t i = 0; i < given.size(); ++i) {
        EXPECT_TRUE(given[i].points_vehicle.empty()) << i;
        EXPECT_EQ(given[i].gps_time_s, sv.slices[i].gps_time_s);
    }
    EXPECT_EQ(kept.memory.points_bytes, finite * sizeof(Eigen::Vector3f));
    EXPECT_EQ(moved.memory.points_bytes, finite * sizeof(Eigen::Vector3f));
    EXPECT_EQ(moved.memory.world_points_bytes, finite * sizeof(Eigen::Vector3f));
    EXPECT_GT(moved.memory.trees_bytes, 0u);
    EXPECT_GT(moved.memory.neighbour_bytes, 0u);
    EXPECT_GT(moved.memory.pairs_bytes, 0u);
    EXPECT_EQ(moved.memory.total_bytes,
              moved.memory.points_bytes + moved.memory.world_points_bytes +
                  moved.memory.trees_bytes + moved.memory.neighbour_bytes +
                  moved.memory.pairs_bytes);
}

// The points each pass contributes, bounded per cube (SlamConfig::pass_cell_m, decision 036):
// a survey whose cubes hold no more of a section's points than the bound gives the same run to
// the bit as one without the bound (the perturbed-start runs included); a bound that thins
// still recovers the drift, and the run given its slices to keep and the one given them to
// move agree to the bit (the start runs take the points the main run kept).
SlamResult RunBounded(const Survey& sv, double cell_m, int per_cell, bool move) {
    SlamConfig cfg = TestConfig();
    cfg.coarse_search_m = 0;
    cfg.posterior = true;
    cfg.posterior_start_runs = 2;
    cfg.num_threads = 1;
    cfg.pass_cell_m = cell_m;
    cfg.pass_cell_points = per_cell;
    if (!move) return RunSlam(sv.slices, cfg);
    std::vector<Slice> given = sv.slices;
    return RunSlam(std::move(given), cfg);
}

void ExpectSameRun(const SlamResult& a, const SlamResult& b) {
    ASSERT_EQ(a.termination, b.termination);
    ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
    ASSERT_EQ(a.posterior.start_runs, b.posterior.start_runs);
    for (std::size_t i = 0; i < a.trajectory.size(); ++i) {
        EXPECT_TRUE(a.trajectory[i].T_world_vehicle.matrix() ==
                    b.trajectory[i].T_world_vehicle.matrix())
            << i;
        EXPECT_TRUE(a.posterior.slice_sigma[i] == b.posterior.slice_sigma[i]) << i;
        EXPECT_TRUE(a.posterior.start_spread[i] == b.posterior.start_spread[i]) << i;
    }
    EXPECT_EQ(a.final_pair_score_m, b.final_pair_score_m);
}

// The crossing with an outage's sigmas from 60 s to 96 s (the perturbed-start runs are made).
Survey OutageCrossing() {
    Survey sv = MakeSurvey(kCrossing, 0.0);
    for (Slice& s : sv.slices) {
        const double t = s.gps_time_s - 1000.0;
        s.pose_sigma << 0.002, 0.002, 0.004, 0.02, 0.02, 0.02;
        if (t >= 60.0 && t < 96.0) s.pose_sigma.tail<3>().setConstant(0.3);
    }
    return sv;
}

TEST(Slam, CubesBelowThePassBoundGiveTheSameRun) {
    const Survey sv = OutageCrossing();
    const SlamResult all = RunBounded(sv, 0.0, 1, true);
    // 2 m cubes hold at most a few hundred of a section's points (40 pings of 61 beams).
    const SlamResult loose = RunBounded(sv, 2.0, 100000, true);
    ASSERT_EQ(all.posterior.start_runs, 2u) << all.posterior.start_runs_note;
    EXPECT_EQ(loose.num_points, loose.num_points_in);
    EXPECT_EQ(all.num_points, all.num_points_in);
    ExpectSameRun(all, loose);
}

TEST(Slam, APassBoundThatThinsStillRecoversTheDrift) {
    const Survey sv = MakeSurvey(kCrossing, 1.0);
    const double before = Ate(Initial(sv.slices), sv.truth);
    SlamConfig cfg = TestConfig();
    const SlamResult all = RunSlam(sv.slices, cfg);
    cfg.pass_cell_m = 0.5;
    cfg.pass_cell_points = 1;
    const SlamResult thin = RunSlam(sv.slices, cfg);
    ASSERT_NE(thin.termination, SlamTermination::kInvalidInput) << thin.message;
    ASSERT_NE(thin.termination, SlamTermination::kNoOverlap) << thin.message;
    EXPECT_LT(thin.num_points, all.num_points * 3 / 4);
    EXPECT_EQ(thin.num_points_in, all.num_points);
    EXPECT_LT(thin.memory.points_bytes, all.memory.points_bytes);
    EXPECT_EQ(thin.memory.points_bytes, thin.num_points * sizeof(Eigen::Vector3f));
    const double ate_all = Ate(all.trajectory, sv.truth), ate_thin = Ate(thin.trajectory, sv.truth);
    EXPECT_LT(ate_thin, 0.5 * before);
    EXPECT_LT(ate_thin, 2.0 * ate_all + 0.01) << "all points " << ate_all;
}

TEST(Slam, APassBoundGivesTheSameRunToSlicesKeptOrMoved) {
    const Survey sv = OutageCrossing();
    const SlamResult moved = RunBounded(sv, 0.5, 1, true);
    EXPECT_LT(moved.num_points, moved.num_points_in);
    ASSERT_EQ(moved.posterior.start_runs, 2u) << moved.posterior.start_runs_note;
    ExpectSameRun(moved, RunBounded(sv, 0.5, 1, false));
}

}  // namespace
}  // namespace pitmap::proc::slam
