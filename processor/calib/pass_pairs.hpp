// SPDX-License-Identifier: MIT
// Correspondences between the passes of a calibration segment (boresight.hpp's model): the
// soundings of the segment, subsampled (Samples, Collect); for each, the own pass's neighbours
// (IndexOwnPasses: closer than min_separation_s in time and normal_radius_m in space, found
// once) and then, at every iteration, the normal of its own pass fitted to the current positions
// and the closest sounding of another pass (FindPairs: at least min_separation_s apart in time,
// within d_max), with the point-to-plane residual and its weight 1 / sigma^2.
// Positions are world-frame metres; times seconds since the segment start.
// Thread safety: reentrant; results do not depend on the thread count.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "processor/calib/boresight.hpp"
#include "processor/calib/boresight_blocks.hpp"
#include "processor/registration/correspondence.hpp"

namespace pitmap::proc::calib::detail {

// Soundings of one segment, subsampled.
struct Samples {
    std::vector<std::uint32_t> ping;
    std::vector<Eigen::Vector3d> s_sonar;  // beam vectors, sonar frame
    std::vector<double> t_s;               // seconds since the segment start
    // The neighbours of sample k in its own pass (closer than min_separation_s in time and
    // normal_radius_m in space, itself included) are own[own_begin[k] .. own_begin[k + 1]).
    // Found once (IndexOwnPasses), at the positions of the mount and latency the segment is
    // first seen with: a boresight or latency update moves a sounding and its own pass's
    // neighbours (the same and adjacent pings) alike, so the neighbourhood holds while the
    // normal is fitted to the current positions at every iteration.
    std::vector<std::size_t> own_begin;
    std::vector<std::uint32_t> own;
    // Only samples k with k % query_every == 0 seek a pair (and get their own pass indexed);
    // all of them can be paired with.
    int query_every = 1;
    bool IsQuery(std::size_t k) const {
        return query_every <= 1 || k % static_cast<std::size_t>(query_every) == 0;
    }
};

// The soundings of pings in [t0, t1) (GPS seconds), every stride-th beam.
Samples Collect(const georef::GeorefResult& geo, double t0, double t1, int stride);

// A view read by time windows: which soundings the pings of a window hold (the view's
// soundings come in ping order), so that a window reads only its range of the view.
class ViewWindows {
public:
    // One pass over the view for each ping's first sounding. `geo` (its pings) and `view`
    // must outlive it.
    ViewWindows(const georef::GeorefResult& geo, const ViewReader& view);
    // Visits, in the view's order, the soundings from the first ping whose time lies in
    // [t0, t1) (GPS seconds) to the last (the caller filters by time, as over the whole view).
    void ForEach(double t0, double t1, const ViewVisit& visit) const;
    const georef::GeorefResult& geo() const { return geo_; }

private:
    const georef::GeorefResult& geo_;
    const ViewReader& view_;
    std::vector<std::size_t> ping_first_;  // per ping and one past the last: a sounding index
};

// Collect over a view read by windows: the same samples.
Samples Collect(const ViewWindows& view, double t0, double t1, int stride);

// A correspondence (query: the sample, target: its closest point of another pass; the normal
// is the query's, from its own pass), its point-to-plane residual and 1 / sigma^2.
struct Pair {
    bool ok = false;
    reg::Correspondence3d c;
    double r = 0;
    double w = 1;
};

// Fills S.own_begin / S.own from the positions p (one per sample).
void IndexOwnPasses(const std::vector<Eigen::Vector3d>& p, Samples& S, const BoresightConfig& cfg);

// One Pair per sample (ok = false where no other pass is within d_max metres or the own pass's
// neighbourhood is not planar).
std::vector<Pair> FindPairs(const std::vector<Eigen::Vector3d>& p,
                            const Samples& S,
                            const BoresightConfig& cfg,
                            double d_max);

// RMS, median |r| and the RMS the weights expect, over the pairs that are ok.
ResidualStats Stats(const std::vector<Pair>& pairs);

}  // namespace pitmap::proc::calib::detail
