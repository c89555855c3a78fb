// SPDX-License-Identifier: MIT
// Conversions between the georeferenced survey (processor/georef) and the inputs and outputs of
// the 3-D stages: SLAM slices (processor/slam), sonar scans for the TSDF (processor/fusion), and
// corrected trajectories applied back to the soundings. No I/O.
//
// Frames (docs/conventions.md): world local ENU (z up), vehicle FRD, sonar x forward, y
// starboard, z down. A georeferenced sounding is p_world = T_world_vehicle * T_vehicle_sonar *
// Ry(tilt) * (0, r sin theta, r cos theta), so its vehicle-frame point is
// T_world_vehicle^-1 * p_world exactly, and the fan frame of a ping is
// T_world_vehicle * T_vehicle_sonar * Ry(tilt).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/formats/trajectory_csv.hpp"
#include "common/result.hpp"
#include "common/se3.hpp"
#include "processor/fusion/tsdf.hpp"
#include "processor/georef/georef.hpp"
#include "processor/slam/slam.hpp"
#include "processor/survey/series.hpp"

namespace pitmap::proc::pipeline {

// 1-sigma pose uncertainty in the order slam::Slice::pose_sigma uses: roll, pitch, yaw (rad),
// east, north, up (m).
using PoseSigma = Eigen::Matrix<double, 6, 1>;

// The INS's own 1-sigma at a time: the stddev record nearest in time (records are ~1 Hz; the
// INS error changes slowly). Components the receiver did not report (NaN), and all of them when
// there is no record within max_age_s, take `fallback` (hydro::InsSigmaAt, which pitmap live
// uses too).
PoseSigma PoseSigmaAt(const survey::NavSeries& nav,
                      std::int64_t utime_gps,
                      double max_age_s,
                      const PoseSigma& fallback);

// SLAM input: one slice per georeferenced ping that kept at least one sounding, its initial
// pose the georeferenced one, every `point_stride`-th kept sounding in the vehicle frame.
struct SliceSet {
    std::vector<slam::Slice> slices;
    std::vector<std::uint32_t> ping;  // slice -> index into GeorefResult::pings
    // The slices' points as made (SLAM moves them out of the slices: RunSlam's rvalue form).
    std::size_t num_points = 0;
};
SliceSet MakeSlices(const georef::GeorefResult& geo,
                    const survey::NavSeries& nav,
                    int point_stride,
                    double sigma_max_age_s,
                    const PoseSigma& fallback_sigma);

// MakeSlices with the view's points given a block at a time (decision 043: the view read from
// its scratch file, never whole): Add each block in the view's order, `first` its first
// sounding, then Finish. The same slices bit for bit as MakeSlices on the whole view, whatever
// the blocks (a ping's soundings may straddle blocks: the stride counts on across them).
// `geo`'s pings and mount are read, not its points; `geo` and `nav` must outlive the builder.
class SliceBuilder {
public:
    SliceBuilder(const georef::GeorefResult& geo,
                 const survey::NavSeries& nav,
                 int point_stride,
                 double sigma_max_age_s,
                 const PoseSigma& fallback_sigma);
    // An error (nothing taken from the block): `first` is not the sounding after the last
    // block's, or a sounding names a ping the view does not have.
    Status Add(const georef::GeorefPoints& block, std::size_t first);
    // The slices; none when the soundings were not in ping order (as MakeSlices).
    SliceSet Finish();

private:
    void Open(std::uint32_t ping);
    void Close();

    const georef::GeorefResult& geo_;
    const survey::NavSeries& nav_;
    std::size_t stride_;
    double sigma_max_age_s_;
    PoseSigma fallback_sigma_;
    Pose T_vehicle_sonar_;
    std::size_t next_ = 0;     // the sounding the next block starts at
    bool open_ = false;        // slice_ holds the soundings of ping_ so far
    std::uint32_t ping_ = 0;   // the open ping
    std::size_t in_ping_ = 0;  // its soundings seen (the stride's count)
    bool sorted_ = true;
    slam::Slice slice_;
    SliceSet out_;
};

// Moves every sounding and ping of `geo` to new vehicle poses, one per ping
// (T_world_vehicle[k] for GeorefResult::pings[k]): p' = T'_k T_k^-1 p, through
// georef::ApplyTrajectory. A pose count other than geo.pings.size() is an error (nothing moves).
Status ApplyVehiclePoses(georef::GeorefResult& geo, const std::vector<Pose>& T_world_vehicle);
// Its first step, for soundings read a block at a time: the pings moved, each ping's move
// returned (georef::MovePoints moves a block's soundings by them); geo.points are not read.
Expected<std::vector<Pose>> MoveVehiclePings(georef::GeorefResult& geo,
                                             const std::vector<Pose>& T_world_vehicle);

// New poses for every ping of `geo` from a time-stamped trajectory (e.g. trajectory.csv of the
// SLAM stage): interpolated between the bracketing samples (position linear, attitude slerp);
// pings outside the trajectory's span keep their pose and are counted.
struct PoseLookup {
    std::vector<Pose> T_world_vehicle;  // one per ping of geo
    std::size_t outside_span = 0;
};
PoseLookup PosesAtPings(const georef::GeorefResult& geo,
                        const std::vector<double>& gps_time_s,
                        const std::vector<Pose>& T_world_vehicle);

// TSDF input: one scan per georeferenced ping (every ping_stride-th of them); a beam's range is
// the kept sounding's range, 0 where the georeferencing dropped it (no detection, range gate,
// spike). The fan's angles come from the ping header (theta_i = start + i * increment); a ping
// with its own beam angles (PingSeries::beam_angles_deg, R2Sonic equi-distant beams) is
// resampled onto as many equally spaced beams from its first to its last angle (the TSDF's
// footprint model needs equal spacing): a slot's range is interpolated linearly in angle
// between the two beams around it when both have one within 10% of each other, else taken from
// the nearer beam within half a slot, else none.
std::vector<fusion::SonarScan> MakeScans(const georef::GeorefResult& geo,
                                         const survey::PingSeries& pings,
                                         const survey::SonarMount& mount,
                                         int ping_stride = 1);

// A vehicle trajectory in the world frame with GPS times (seconds), for trajectory CSVs.
struct TimedPoses {
    std::vector<double> gps_time_s;
    std::vector<Pose> T_world_vehicle;
};
TimedPoses PingPoses(const georef::GeorefResult& geo);

// Per-ping trajectories (trajectory.csv, trajectory_initial.csv) as poses, through the one
// trajectory CSV reader and writer (common/formats/trajectory_csv.hpp: columns, frames, and the
// plausibility limits a read enforces).
using formats::kMaxGpsTimeS;
using formats::kMaxTrajectoryAngleDeg;
using formats::kMaxTrajectoryOffsetM;
Status WriteTrajectoryCsv(const std::string& path, const TimedPoses& trajectory);
Expected<TimedPoses> ReadTrajectoryCsv(const std::string& path);

}  // namespace pitmap::proc::pipeline
