// SPDX-License-Identifier: MIT
// Georeferencing a block of pings at a time (decision 033): the survey's view written where it
// is kept (the products folder's scratch file) as it is made, never held whole; the new mount
// on a view read a block at a time. Both are RunGeoref's and Regeoreference's arithmetic: the
// blocks joined are their points bit for bit. Thread safety: as RunGeoref.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "processor/georef/georef.hpp"

namespace pitmap::proc::georef {

// Receives RunGeorefByBlocks' blocks: the block's soundings (their ping indices into
// `so_far.pings`) and the result so far (its pings and counts; its points are the block). False
// stops the georeference.
using GeorefBlockSink = std::function<bool(const GeorefPoints& block, const GeorefResult& so_far)>;

// RunGeoref a block of pings at a time: whole pings of at most `block_soundings` beams (at least
// one ping) are georeferenced and compacted into a block handed to `sink`, then dropped, so that
// the survey's view is never held. The blocks joined are RunGeoref's points bit for bit; the
// result returned is RunGeoref's without them (pings, counts, message). A sink that returns
// false stops it (cancelled, with a message).
GeorefResult RunGeorefByBlocks(const survey::NavSeries& nav,
                               const survey::PingSeries& pings,
                               const survey::SonarMount& mount,
                               const GeorefConfig& config,
                               std::size_t block_soundings,
                               const GeorefBlockSink& sink,
                               std::optional<Geodetic> origin = std::nullopt,
                               const ProgressCallback& progress = {},
                               std::shared_ptr<const svp::Refraction> refraction = nullptr,
                               const survey::SoundingFlags* flags = nullptr,
                               survey::SoundingView view = survey::SoundingView::kAccepted);

// Regeoreference for a view read a block at a time: construction sets the result's pings
// (sensor positions) and mount as Regeoreference does; Apply then places a block of its
// soundings (their ping indices into the result's pings), the same arithmetic. `result` must
// outlive it.
class Remount {
public:
    Remount(GeorefResult& result, const survey::SonarMount& mount);
    void Apply(GeorefPoints& points) const;

private:
    const GeorefResult& result_;
    Pose T_vehicle_sonar_;
    std::vector<double> depth_m_, face_speed_mps_;  // per ping, with refraction
};

// SoundingVectorSonar for sounding j of `points`, a block of the result's view (its pings,
// mount and refraction from `result`).
Eigen::Vector3d SoundingVectorSonar(const GeorefResult& result,
                                    const GeorefPoints& points,
                                    std::size_t j);

}  // namespace pitmap::proc::georef
