// SPDX-License-Identifier: MIT
#include "processor/survey/survey.hpp"

#include <cstdio>
#include <exception>
#include <random>
#include <utility>

namespace pitmap::proc::survey {

std::string NewRunId() {
    std::random_device rd;
    std::string id;
    for (int i = 0; i < 4; ++i) {
        char b[9];
        std::snprintf(b, sizeof b, "%08x", static_cast<unsigned>(rd()));
        id += b;
    }
    return id;
}

bool IsRunId(const std::string& id) {
    if (id.size() != 32) return false;
    for (char c : id) {
        if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
    }
    return true;
}

using nlohmann::json;

const char* ToString(TrajectoryVersion v) {
    switch (v) {
        case TrajectoryVersion::kIns:
            return "ins";
        case TrajectoryVersion::kCalibrated:
            return "calibrated";
        case TrajectoryVersion::kSlam:
            return "slam";
    }
    return "?";
}

const char* ToString(CalibrationState s) {
    switch (s) {
        case CalibrationState::kNotRun:
            return "not_run";
        case CalibrationState::kCalibrated:
            return "calibrated";
        case CalibrationState::kKeptNominal:
            return "kept_nominal";
        case CalibrationState::kNoOverlap:
            return "no_overlap";
    }
    return "?";
}

TrajectoryVersion SurveyModel::latest() const {
    for (int v = kNumTrajectoryVersions - 1; v > 0; --v) {
        if (!trajectories[v].empty()) return static_cast<TrajectoryVersion>(v);
    }
    return TrajectoryVersion::kIns;
}

void SurveyModel::DropFrom(TrajectoryVersion v) {
    for (int i = static_cast<int>(v); i < kNumTrajectoryVersions; ++i) trajectories[i] = {};
}

bool SurveyModel::ResetCalibration() {
    bool changed = calibration != CalibrationState::kNotRun ||
                   has(TrajectoryVersion::kCalibrated) || has(TrajectoryVersion::kSlam);
    if (clock.latency_applied) {
        survey::ShiftPingTimes(ingest.pings, -clock.latency_s);
        changed = true;
    }
    clock.latency_applied = false;
    clock.latency_s = 0;
    clock.latency_formal_sd_s = 0;
    const auto same = [](const survey::SonarMount& a, const survey::SonarMount& b) {
        return a.lever_arm_m == b.lever_arm_m && a.boresight_roll_deg == b.boresight_roll_deg &&
               a.boresight_pitch_deg == b.boresight_pitch_deg &&
               a.boresight_yaw_deg == b.boresight_yaw_deg;
    };
    if (!same(mount, nominal_mount)) changed = true;
    mount = nominal_mount;
    boresight_sd_deg = kNoBoresightSd;
    calibration = CalibrationState::kNotRun;
    DropFrom(TrajectoryVersion::kCalibrated);
    return changed;
}

json ClockJson(const SonarClockState& c) {
    return {{"configured", c.configured},
            {"configured_offset_s", c.configured_offset_s},
            {"coarse_correction_s", c.coarse_correction_s},
            {"coarse_sigma_s", c.coarse_sigma_s},
            {"latency_applied", c.latency_applied},
            {"latency_s", c.latency_s},
            {"latency_formal_sd_s", c.latency_formal_sd_s},
            {"rate_ppm", c.rate_ppm},
            {"rate_sigma_ppm", c.rate_sigma_ppm},
            {"rate_reference_utime", c.rate_reference_utime}};
}

json MountJson(const survey::SonarMount& m) {
    return {{"roll_deg", m.boresight_roll_deg},
            {"pitch_deg", m.boresight_pitch_deg},
            {"yaw_deg", m.boresight_yaw_deg},
            {"lever_arm_sonar_m", {m.lever_arm_m.x(), m.lever_arm_m.y(), m.lever_arm_m.z()}},
            {"convention", "R_vehicle_sonar = Rz(yaw) Ry(pitch) Rx(roll), vehicle FRD"}};
}

Expected<survey::SonarMount> MountFromJson(const json& m) {
    survey::SonarMount mount;
    try {
        mount.boresight_roll_deg = m.at("roll_deg").get<double>();
        mount.boresight_pitch_deg = m.at("pitch_deg").get<double>();
        mount.boresight_yaw_deg = m.at("yaw_deg").get<double>();
        const auto arm = m.at("lever_arm_sonar_m").get<std::vector<double>>();
        if (arm.size() != 3) return Error{"lever_arm_sonar_m needs 3 values"};
        mount.lever_arm_m = Eigen::Vector3d(arm[0], arm[1], arm[2]);
    } catch (const std::exception& e) {
        return Error{std::string("malformed mount: ") + e.what()};
    }
    return mount;
}

json OriginJson(const Geodetic& g) {
    return {{"latitude_deg", g.latitude_deg},
            {"longitude_deg", g.longitude_deg},
            {"height_m", g.height_m}};
}

Expected<Geodetic> OriginFromJson(const json& o) {
    try {
        return Geodetic{o.at("latitude_deg").get<double>(),
                        o.at("longitude_deg").get<double>(),
                        o.at("height_m").get<double>()};
    } catch (const std::exception& e) {
        return Error{std::string("malformed world_origin: ") + e.what()};
    }
}

}  // namespace pitmap::proc::survey
