// SPDX-License-Identifier: MIT
// The georeferenced view of the survey model (processor/survey/survey.hpp): its soundings on a
// trajectory version with its current mount (RunGeoref on the model's navigation, pings and
// flags), and back from a georeference to a per-ping trajectory version. The model is the state;
// this is how the stages see it in 3D. Thread safety: as RunGeoref.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "common/progress.hpp"
#include "processor/georef/georef.hpp"
#include "processor/georef/georef_blocks.hpp"
#include "processor/survey/sounding_status.hpp"
#include "processor/survey/survey.hpp"
#include "processor/svp/refraction.hpp"

namespace pitmap::proc::georef {

// The view: the survey's soundings on trajectory version `v` (the newest present at or before
// it) with the current mount, those of `which` status (the accepted ones by default; the
// model's flags decide). Pings without a valid pose in that version keep the navigation's
// pose; `kept` (when given) receives their number, for the caller to report.
GeorefResult Georeference(const survey::SurveyModel& m,
                          survey::TrajectoryVersion v,
                          const GeorefConfig& config,
                          std::shared_ptr<const svp::Refraction> refraction,
                          const ProgressCallback& progress = {},
                          std::size_t* kept = nullptr,
                          survey::SoundingView which = survey::SoundingView::kAccepted);

// Georeference a block of whole pings at a time (decision 041): each block of at most
// `block_soundings` soundings, already on trajectory `v`, is handed to `sink` (its ping indices
// into `so_far.pings`, whose poses are still the navigation's until the end), then dropped. The
// blocks joined are Georeference's points bit for bit; the result returned is Georeference's
// without them (its pings on `v`, its counts). A sink that returns false stops it (cancelled).
GeorefResult GeoreferenceByBlocks(const survey::SurveyModel& m,
                                  survey::TrajectoryVersion v,
                                  const GeorefConfig& config,
                                  std::shared_ptr<const svp::Refraction> refraction,
                                  std::size_t block_soundings,
                                  const GeorefBlockSink& sink,
                                  const ProgressCallback& progress = {},
                                  std::size_t* kept = nullptr,
                                  survey::SoundingView which = survey::SoundingView::kAccepted);

// The per-ping trajectory of a georeferenced survey of `num_pings` pings.
survey::PingTrajectory TrajectoryOf(const GeorefResult& geo, std::size_t num_pings);

// Moves the soundings and pings of `geo` onto trajectory `t` (indexed by the ping series).
// Pings without a valid pose in `t` keep theirs; returns how many kept theirs.
std::size_t ApplyTrajectory(GeorefResult& geo, const survey::PingTrajectory& t);
// ApplyTrajectory in two steps, for soundings read a block at a time (decision 043): MovePings
// moves the pings and returns each ping's move (identity where it kept its pose; `kept` counts
// those), MovePoints moves soundings (any block of the view) by their ping's move.
std::vector<Pose> MovePings(GeorefResult& geo, const survey::PingTrajectory& t, std::size_t* kept);
void MovePoints(GeorefPoints& points, const std::vector<Pose>& delta);

}  // namespace pitmap::proc::georef
