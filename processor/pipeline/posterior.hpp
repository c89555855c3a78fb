// SPDX-License-Identifier: MIT
// Internal to processor/pipeline: SLAM's posterior pose sigma per ping (slam::SlamPosterior;
// docs/uncertainty.md), stored with the SLAM trajectory in the survey model, summarised in
// summary.json, and used by the grid stage's TPU instead of the INS's own sigma where the
// soundings stand on the SLAM trajectory.
#pragma once

#include <array>
#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/georef/georef.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/slam/slam.hpp"
#include "processor/survey/survey.hpp"

namespace pitmap::proc::pipeline::detail {

// Per ping of the model's PingSeries (num_pings): SLAM's posterior 1-sigma (roll, pitch, yaw
// rad; east, north, up m). A ping that is a slice takes its slice's; a georeferenced ping that
// kept no sounding the nearest slice's in time (the posterior changes over seconds). NaN (the
// INS's sigma applies) where the ping is not georeferenced, where its final pose is not SLAM's
// (the INS check put the INS pose back: more than 1 mm from SLAM's slice pose), and everywhere
// when no posterior was computed (then the result is empty).
std::vector<std::array<double, 6>> SlamPingSigma(const georef::GeorefResult& geo,
                                                 const SliceSet& set,
                                                 const slam::SlamResult& r,
                                                 std::size_t num_pings);

// summary.json's posterior windows: how well the trajectory is known along the track (decision
// 012 and 016 read the errors SLAM leaves in 20 s windows).
inline constexpr double kPosteriorWindowS = 20.0;
inline constexpr double kCircular95 = 2.4477;  // 95 % radius / horizontal sigma (IHO S-44)

// summary.json stages.slam.posterior: how it was computed (variance factor, observations,
// cost as a share of the stage, the perturbed-start runs and their spread) and the horizontal
// sigma sqrt((sE^2 + sN^2) / 2) and vertical sigma over the pings: median, 95th percentile,
// and per window_s window from the first ping the maximum sigmas and the median and maximum
// 95 % horizontal radius kCircular95 x the horizontal sigma (the report plots them).
nlohmann::json PosteriorJson(const georef::GeorefResult& geo,
                             const std::vector<std::array<double, 6>>& ping_sigma,
                             const slam::SlamResult& r,
                             double window_s);

// The pose sigma the TPU takes for ping `ping` of the georeferenced view: SLAM's posterior where
// the view stands on the SLAM trajectory and it is known (component-wise), else `ins`.
// `from_slam`, if given, says whether the posterior was used.
PoseSigma ProcessingSigma(const survey::SurveyModel& m,
                          const georef::GeorefPing& ping,
                          const PoseSigma& ins,
                          bool* from_slam = nullptr);

// P/trajectory_sigma.csv: per georeferenced ping, the stated pose uncertainty beside the poses,
// for scoring against a truth (pitmap-eval trajectory_uncertainty): gps_time_s; x_m, y_m, z_m
// (the final pose, world ENU); x0_m, y0_m, z0_m (the pose before SLAM, `before[k]` for
// geo.pings[k]); sigma_east_m, sigma_north_m, sigma_up_m, sigma_roll_deg, sigma_pitch_deg,
// sigma_yaw_deg (what the TPU takes: ProcessingSigma); ins_sigma_east_m, ins_sigma_north_m,
// ins_sigma_up_m (the INS's own, PoseSigmaAt with max_age_s and fallback); slam_posterior (1 if
// the sigma is SLAM's posterior).
Status WriteTrajectorySigmaCsv(const std::string& path,
                               const georef::GeorefResult& geo,
                               const std::vector<Pose>& before,
                               const survey::SurveyModel& m,
                               double max_age_s,
                               const PoseSigma& fallback);

}  // namespace pitmap::proc::pipeline::detail
