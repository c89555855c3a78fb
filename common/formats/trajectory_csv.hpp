// SPDX-License-Identifier: MIT
// Trajectory CSV: the one reader and writer of pitmap's vehicle trajectories.
//
//   gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg[,vel_e_mps,vel_n_mps,vel_u_mps,ins_status]
//
// gps_time_s: GPS seconds since 1980-01-06; x, y, z: the vehicle reference point in the local
// world frame (East, North, Up metres at the products' world origin); roll, pitch, yaw: the
// attitude of the vehicle FRD frame relative to NED (docs/conventions.md), degrees. The four
// INS columns (velocity East, North, Up in m/s and the receiver's INS status) are present only
// in an INS-rate file. Files that use it:
//   trajectory_ins.csv       the INS solution at its own rate, with the INS columns (georef)
//   trajectory_initial.csv   one pose per georeferenced ping, before SLAM (slam)
//   trajectory.csv           one pose per ping, after SLAM: the trajectory of points.ply (slam)
//   <truth>/trajectory.csv   the simulator's true trajectory (tools/sim)
// Reading: the header must start with the seven pose columns; further columns other than the
// four INS ones are ignored. Every value must be finite and plausible for a survey (positions
// within kMaxTrajectoryOffsetM of the origin per axis, angles within kMaxTrajectoryAngleDeg,
// times within kMaxGpsTimeS) and times strictly increasing, or the read fails naming the file
// and line.
#pragma once

#include <Eigen/Core>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "common/se3.hpp"

namespace pitmap::formats {

struct TrajectoryRow {
    double gps_time_s = 0;
    Eigen::Vector3d position_world_m = Eigen::Vector3d::Zero();
    double roll_deg = 0, pitch_deg = 0, yaw_deg = 0;
    // INS-rate files only (TrajectoryCsv::ins_columns).
    Eigen::Vector3d velocity_enu_mps = Eigen::Vector3d::Zero();
    int ins_status = 0;
};

struct TrajectoryCsv {
    bool ins_columns = false;  // write / were read: vel_e_mps, vel_n_mps, vel_u_mps, ins_status
    std::vector<TrajectoryRow> rows;
};

// T_world_vehicle of a row, and a row of a pose (attitude through common/frames).
Pose PoseOf(const TrajectoryRow& row);
TrajectoryRow RowOf(double gps_time_s, const Pose& T_world_vehicle);

inline constexpr double kMaxTrajectoryOffsetM = 50'000.0;
inline constexpr double kMaxTrajectoryAngleDeg = 720.0;
inline constexpr double kMaxGpsTimeS = 1e11;

Status WriteTrajectoryCsv(const std::string& path, const TrajectoryCsv& trajectory);

// The same file written row by row, for a trajectory too long to hold (the simulator's truth of
// an hours-long survey): rows go to DIR/.partial-NAME as they come, and Finish renames it over
// PATH (replace_file.hpp). Destroyed unfinished, it removes the partial file and PATH stays as it
// was. Rows must come in increasing time (not checked here; the reader checks). Not thread-safe.
class TrajectoryCsvWriter {
public:
    // Creates the partial file and writes the header; fails naming the path.
    static Expected<std::unique_ptr<TrajectoryCsvWriter>> Open(const std::string& path,
                                                               bool ins_columns = false);
    ~TrajectoryCsvWriter();
    TrajectoryCsvWriter(const TrajectoryCsvWriter&) = delete;
    TrajectoryCsvWriter& operator=(const TrajectoryCsvWriter&) = delete;

    void Append(const TrajectoryRow& row);
    // Flushes, closes and renames; a write error (disk full) is reported here, naming PATH.
    Status Finish();

private:
    TrajectoryCsvWriter(std::string path, std::string partial, std::FILE* file, bool ins_columns)
        : path_(std::move(path)),
          partial_(std::move(partial)),
          file_(file),
          ins_columns_(ins_columns) {}
    std::string path_, partial_;
    std::FILE* file_ = nullptr;
    bool ins_columns_ = false;
};
Expected<TrajectoryCsv> ReadTrajectoryCsv(const std::string& path);

}  // namespace pitmap::formats
