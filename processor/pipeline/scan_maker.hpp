// SPDX-License-Identifier: MIT
// The TSDF's scans (MakeScans, adapters.hpp) made from the georeferenced view a block at a time,
// for a stage that reads the view by blocks from its scratch file. No I/O. docs/decisions/034.
#pragma once

#include <cstddef>
#include <vector>

#include "common/result.hpp"
#include "common/se3.hpp"
#include "processor/fusion/tsdf.hpp"
#include "processor/georef/georef.hpp"
#include "processor/survey/series.hpp"

namespace pitmap::proc::pipeline {

// MakeScans a block of the view's points at a time, for a stage that reads the view by blocks
// (io::SpilledPoints::ReadBlock) and never holds it whole: Add the view's points in blocks, in
// their order (ping order, as georef makes them), then Finish. A ping's scan is complete once a
// point of a later ping is added (or at Finish); Take moves out the scans completed since the
// last Take, in ping order. Each is the scan MakeScans gives that ping, bit for bit, whatever
// the blocks. `geo_pings` (GeorefResult::pings), `pings` and `mount` must outlive the maker.
class ScanMaker {
public:
    ScanMaker(const std::vector<georef::GeorefPing>& geo_pings,
              const survey::PingSeries& pings,
              const survey::SonarMount& mount,
              int ping_stride = 1);

    // The view's next points. An error (nothing of the block taken) when a point's ping lies
    // before the previous point's, or is not one of geo_pings.
    Status Add(const georef::GeorefPoints& block);
    // No more points: every ping's scan is complete.
    void Finish();
    // The scans completed and not yet taken.
    std::vector<fusion::SonarScan> Take();

    std::size_t num_scans() const { return num_scans_; }  // the survey's, taken or not

private:
    void OpenThrough(std::size_t ping);     // the scans of pings next_ping_ .. ping
    void CompleteBefore(std::size_t scan);  // scans before index `scan` completed

    const std::vector<georef::GeorefPing>& geo_pings_;
    const survey::PingSeries& pings_;
    Pose T_vehicle_sonar_;
    std::size_t stride_;
    std::size_t num_scans_;
    std::vector<fusion::SonarScan> open_;  // scans first_ .. first_ + open_.size() - 1
    std::size_t first_ = 0;
    std::size_t complete_ = 0;   // scans before this index are complete
    std::size_t next_ping_ = 0;  // pings before it have their scans opened
    std::size_t last_ping_ = 0;  // ping of the last point added
};

}  // namespace pitmap::proc::pipeline
