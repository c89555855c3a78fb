// SPDX-License-Identifier: MIT
#include "common/formats/trajectory_csv.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "common/formats/replace_file.hpp"
#include "common/frames.hpp"

namespace pitmap::formats {

namespace {

constexpr const char* kPoseHeader = "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg";
constexpr const char* kInsHeader = ",vel_e_mps,vel_n_mps,vel_u_mps,ins_status";

}  // namespace

Pose PoseOf(const TrajectoryRow& row) {
    return MakePose(frames::RotationWorldFromRpy(frames::DegToRad(row.roll_deg),
                                                 frames::DegToRad(row.pitch_deg),
                                                 frames::DegToRad(row.yaw_deg)),
                    row.position_world_m);
}

TrajectoryRow RowOf(double gps_time_s, const Pose& T_world_vehicle) {
    TrajectoryRow r;
    r.gps_time_s = gps_time_s;
    r.position_world_m = T_world_vehicle.translation();
    const frames::Rpy a = frames::RpyFromRotationWorld(T_world_vehicle.linear());
    r.roll_deg = frames::RadToDeg(a.roll);
    r.pitch_deg = frames::RadToDeg(a.pitch);
    r.yaw_deg = frames::RadToDeg(a.yaw);
    return r;
}

namespace {

void WriteRow(std::FILE* f, const TrajectoryRow& r, bool ins_columns) {
    std::fprintf(f,
                 "%.6f,%.5f,%.5f,%.5f,%.7f,%.7f,%.7f",
                 r.gps_time_s,
                 r.position_world_m.x(),
                 r.position_world_m.y(),
                 r.position_world_m.z(),
                 r.roll_deg,
                 r.pitch_deg,
                 r.yaw_deg);
    if (ins_columns) {
        std::fprintf(f,
                     ",%.4f,%.4f,%.4f,%d",
                     r.velocity_enu_mps.x(),
                     r.velocity_enu_mps.y(),
                     r.velocity_enu_mps.z(),
                     r.ins_status);
    }
    std::fputc('\n', f);
}

Status WriteTrajectoryCsvTo(const std::string& path, const TrajectoryCsv& t) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) return Error{ErrnoMessage(path, "cannot create", errno)};
    std::fprintf(f, "%s%s\n", kPoseHeader, t.ins_columns ? kInsHeader : "");
    for (const TrajectoryRow& r : t.rows) WriteRow(f, r, t.ins_columns);
    const bool ok = std::ferror(f) == 0 && std::fflush(f) == 0;
    const int err = errno;
    if (std::fclose(f) != 0 || !ok) return Error{ErrnoMessage(path, "write failed", err)};
    return Ok{};
}

}  // namespace

Status WriteTrajectoryCsv(const std::string& path, const TrajectoryCsv& t) {
    return WriteReplacing(
        path, [&](const std::string& partial) { return WriteTrajectoryCsvTo(partial, t); });
}

Expected<std::unique_ptr<TrajectoryCsvWriter>> TrajectoryCsvWriter::Open(const std::string& path,
                                                                         bool ins_columns) {
    const std::string partial = PartialPath(path);
    std::FILE* f = std::fopen(partial.c_str(), "w");
    if (f == nullptr) return Error{ErrnoMessage(partial, "cannot create", errno)};
    std::fprintf(f, "%s%s\n", kPoseHeader, ins_columns ? kInsHeader : "");
    return std::unique_ptr<TrajectoryCsvWriter>(
        new TrajectoryCsvWriter(path, partial, f, ins_columns));
}

TrajectoryCsvWriter::~TrajectoryCsvWriter() {
    if (file_ == nullptr) return;
    std::fclose(file_);
    std::remove(partial_.c_str());
}

void TrajectoryCsvWriter::Append(const TrajectoryRow& row) {
    WriteRow(file_, row, ins_columns_);
}

Status TrajectoryCsvWriter::Finish() {
    if (file_ == nullptr) return Error{path_ + ": the trajectory writer was already finished"};
    const bool ok = std::ferror(file_) == 0 && std::fflush(file_) == 0;
    const int err = errno;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!closed || !ok) {
        std::remove(partial_.c_str());
        return Error{ErrnoMessage(path_, "write failed", err)};
    }
    return CommitPartial(partial_, path_);
}

Expected<TrajectoryCsv> ReadTrajectoryCsv(const std::string& path) {
    std::ifstream in(path);
    if (!in) return Error{path + ": cannot open"};
    std::string line;
    if (!std::getline(in, line) || line.rfind(kPoseHeader, 0) != 0) {
        return Error{path + ": not a trajectory CSV (header " + kPoseHeader + " expected)"};
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    TrajectoryCsv out;
    out.ins_columns = line == std::string(kPoseHeader) + kInsHeader;
    std::size_t line_no = 1;
    while (std::getline(in, line)) {
        ++line_no;
        if (line.empty() || line == "\r") continue;
        const std::string at = path + ":" + std::to_string(line_no);
        double v[10];
        int used = 0;
        if (std::sscanf(line.c_str(),
                        "%lf,%lf,%lf,%lf,%lf,%lf,%lf%n",
                        &v[0],
                        &v[1],
                        &v[2],
                        &v[3],
                        &v[4],
                        &v[5],
                        &v[6],
                        &used) != 7 ||
            !std::all_of(v, v + 7, [](double x) { return std::isfinite(x); })) {
            return Error{at + ": malformed row (7 finite numbers expected)"};
        }
        static const char* const kNames[7] = {
            "gps_time_s", "x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg"};
        for (int k = 0; k < 7; ++k) {
            const double limit = k == 0  ? kMaxGpsTimeS
                                 : k < 4 ? kMaxTrajectoryOffsetM
                                         : kMaxTrajectoryAngleDeg;
            if (std::abs(v[k]) > limit) {
                char msg[160];
                std::snprintf(msg,
                              sizeof msg,
                              ": %s = %g is beyond +-%g%s",
                              kNames[k],
                              v[k],
                              limit,
                              k >= 1 && k < 4 ? " m of the world origin" : "");
                return Error{at + msg};
            }
        }
        if (!out.rows.empty() && v[0] <= out.rows.back().gps_time_s) {
            return Error{at + ": times not increasing"};
        }
        TrajectoryRow r;
        r.gps_time_s = v[0];
        r.position_world_m = Eigen::Vector3d(v[1], v[2], v[3]);
        r.roll_deg = v[4];
        r.pitch_deg = v[5];
        r.yaw_deg = v[6];
        if (out.ins_columns) {
            int status = 0, more = 0;
            if (std::sscanf(line.c_str() + used,
                            ",%lf,%lf,%lf,%d%n",
                            &v[7],
                            &v[8],
                            &v[9],
                            &status,
                            &more) != 4 ||
                !std::all_of(v + 7, v + 10, [](double x) { return std::isfinite(x); })) {
                return Error{at + ": malformed INS columns (3 finite velocities and a status)"};
            }
            r.velocity_enu_mps = Eigen::Vector3d(v[7], v[8], v[9]);
            r.ins_status = status;
        }
        out.rows.push_back(r);
    }
    return out;
}

}  // namespace pitmap::formats
