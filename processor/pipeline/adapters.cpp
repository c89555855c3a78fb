// SPDX-License-Identifier: MIT
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/scan_maker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <sstream>

#include "common/formats/trajectory_csv.hpp"
#include "common/frames.hpp"
#include "processor/georef/survey_view.hpp"
#include "processor/hydro/tpu.hpp"

namespace pitmap::proc::pipeline {

namespace {

// [first, last) point index range of every ping; points are stored in ping order.
std::vector<std::size_t> PingOffsets(const georef::GeorefResult& geo) {
    std::vector<std::size_t> offset(geo.pings.size() + 1, 0);
    for (std::uint32_t k : geo.points.ping) ++offset[k + 1];
    for (std::size_t k = 0; k < geo.pings.size(); ++k) offset[k + 1] += offset[k];
    return offset;
}

// MakeScans: a ping with its own beam angles onto equally spaced ones (adapters.hpp).
void ResampleToEqualAngles(const survey::PingSeries& pings,
                           const survey::PingHeader& h,
                           fusion::SonarScan& s) {
    const std::size_t n = h.num_beams;
    if (n < 2 || s.ranges_m.size() != n) return;
    std::vector<double> a(n);
    for (std::size_t i = 0; i < n; ++i) {
        const float deg = pings.beam_angles_deg[h.beam_offset + i];
        if (!std::isfinite(deg)) return;  // the header's equal spacing holds
        a[i] = frames::DegToRad(deg);
        if (i > 0 && !(a[i] > a[i - 1])) return;  // not increasing: left as the header says
    }
    const double start = a.front();
    const double inc = (a.back() - a.front()) / static_cast<double>(n - 1);
    const std::vector<float> src = s.ranges_m;
    const auto valid = [&](std::size_t i) { return std::isfinite(src[i]) && src[i] > 0.0f; };
    std::size_t i = 0;
    for (std::size_t j = 0; j < n; ++j) {
        const double th = start + inc * static_cast<double>(j);
        while (i + 2 < n && a[i + 1] <= th) ++i;
        const double w = std::clamp((th - a[i]) / (a[i + 1] - a[i]), 0.0, 1.0);
        float r = 0.0f;
        if (valid(i) && valid(i + 1) &&
            std::abs(src[i + 1] - src[i]) <= 0.1f * std::min(src[i], src[i + 1])) {
            r = static_cast<float>(src[i] + w * (src[i + 1] - src[i]));
        } else {
            const std::size_t near = w < 0.5 ? i : i + 1;
            if (valid(near) && std::abs(th - a[near]) <= 0.5 * inc) r = src[near];
        }
        s.ranges_m[j] = r;
    }
    s.start_angle_rad = static_cast<float>(start);
    s.angle_increment_rad = static_cast<float>(inc);
}

bool IsSortedByPing(const georef::GeorefResult& geo) {
    return std::is_sorted(geo.points.ping.begin(), geo.points.ping.end());
}

}  // namespace

PoseSigma PoseSigmaAt(const survey::NavSeries& nav,
                      std::int64_t utime_gps,
                      double max_age_s,
                      const PoseSigma& fallback) {
    hydro::PingSigma fb;
    fb.attitude_rpy_rad = fallback.head<3>();
    fb.position_enu_m = fallback.tail<3>();
    const hydro::PingSigma s = hydro::InsSigmaAt(nav.stddevs, utime_gps, max_age_s, fb);
    PoseSigma out;
    out << s.attitude_rpy_rad, s.position_enu_m;
    return out;
}

SliceSet MakeSlices(const georef::GeorefResult& geo,
                    const survey::NavSeries& nav,
                    int point_stride,
                    double sigma_max_age_s,
                    const PoseSigma& fallback_sigma) {
    SliceSet out;
    if (!IsSortedByPing(geo)) return out;
    const std::vector<std::size_t> offset = PingOffsets(geo);
    const std::size_t stride = static_cast<std::size_t>(std::max(1, point_stride));
    const Pose T_vehicle_sonar = geo.mount.T_vehicle_sonar();
    for (std::size_t k = 0; k < geo.pings.size(); ++k) {
        if (offset[k + 1] == offset[k]) continue;
        const georef::GeorefPing& ping = geo.pings[k];
        slam::Slice s;
        s.gps_time_s = static_cast<double>(ping.utime_gps) * 1e-6;
        s.T_world_vehicle = ping.T_world_vehicle;
        s.pose_sigma = PoseSigmaAt(nav, ping.utime_gps, sigma_max_age_s, fallback_sigma);
        // In the vehicle frame straight from the sonar frame (lever arm and mount), not back
        // from the world.
        s.points_vehicle.reserve((offset[k + 1] - offset[k] + stride - 1) / stride);
        for (std::size_t i = offset[k]; i < offset[k + 1]; i += stride) {
            s.points_vehicle.push_back(
                (T_vehicle_sonar * georef::SoundingVectorSonar(geo, i)).cast<float>());
        }
        out.num_points += s.points_vehicle.size();
        out.slices.push_back(std::move(s));
        out.ping.push_back(static_cast<std::uint32_t>(k));
    }
    return out;
}

SliceBuilder::SliceBuilder(const georef::GeorefResult& geo,
                           const survey::NavSeries& nav,
                           int point_stride,
                           double sigma_max_age_s,
                           const PoseSigma& fallback_sigma)
    : geo_(geo),
      nav_(nav),
      stride_(static_cast<std::size_t>(std::max(1, point_stride))),
      sigma_max_age_s_(sigma_max_age_s),
      fallback_sigma_(fallback_sigma),
      T_vehicle_sonar_(geo.mount.T_vehicle_sonar()) {}

void SliceBuilder::Open(std::uint32_t ping) {
    const georef::GeorefPing& p = geo_.pings[ping];
    slice_ = slam::Slice();
    slice_.gps_time_s = static_cast<double>(p.utime_gps) * 1e-6;
    slice_.T_world_vehicle = p.T_world_vehicle;
    slice_.pose_sigma = PoseSigmaAt(nav_, p.utime_gps, sigma_max_age_s_, fallback_sigma_);
    ping_ = ping;
    in_ping_ = 0;
    open_ = true;
}

void SliceBuilder::Close() {
    if (!open_) return;
    open_ = false;
    // A ping's count is not known before its last block: its points held as MakeSlices' are.
    slice_.points_vehicle.shrink_to_fit();
    out_.num_points += slice_.points_vehicle.size();
    out_.slices.push_back(std::move(slice_));
    out_.ping.push_back(ping_);
}

Status SliceBuilder::Add(const georef::GeorefPoints& block, std::size_t first) {
    if (first != next_) {
        return Error{"internal: a block of the view from sounding " + std::to_string(first) +
                     ", expected " + std::to_string(next_)};
    }
    for (std::uint32_t k : block.ping) {
        if (k >= geo_.pings.size()) {
            return Error{"internal: a sounding of ping " + std::to_string(k) + " of " +
                         std::to_string(geo_.pings.size())};
        }
    }
    next_ += block.size();
    for (std::size_t i = 0; i < block.size() && sorted_; ++i) {
        const std::uint32_t k = block.ping[i];
        if (!open_ || k != ping_) {
            if (open_ && k < ping_) {
                sorted_ = false;
                break;
            }
            Close();
            Open(k);
        }
        // In the vehicle frame straight from the sonar frame, as MakeSlices.
        if (in_ping_ % stride_ == 0) {
            slice_.points_vehicle.push_back(
                (T_vehicle_sonar_ * georef::SoundingVectorSonar(geo_, block, i)).cast<float>());
        }
        ++in_ping_;
    }
    return Ok{};
}

SliceSet SliceBuilder::Finish() {
    Close();
    if (!sorted_) return SliceSet{};
    return std::move(out_);
}

Expected<std::vector<Pose>> MoveVehiclePings(georef::GeorefResult& geo,
                                             const std::vector<Pose>& T_world_vehicle) {
    if (T_world_vehicle.size() != geo.pings.size()) {
        return Error{"internal: " + std::to_string(T_world_vehicle.size()) + " poses for " +
                     std::to_string(geo.pings.size()) + " georeferenced pings"};
    }
    std::size_t n = 0;
    for (const auto& p : geo.pings) n = std::max<std::size_t>(n, p.header_index + 1);
    survey::PingTrajectory t;
    t.T_world_vehicle.assign(n, Pose::Identity());
    t.valid.assign(n, 0);
    for (std::size_t k = 0; k < geo.pings.size(); ++k) {
        t.T_world_vehicle[geo.pings[k].header_index] = T_world_vehicle[k];
        t.valid[geo.pings[k].header_index] = 1;
    }
    return georef::MovePings(geo, t, nullptr);
}

Status ApplyVehiclePoses(georef::GeorefResult& geo, const std::vector<Pose>& T_world_vehicle) {
    auto delta = MoveVehiclePings(geo, T_world_vehicle);
    if (!delta) return delta.error();
    georef::MovePoints(geo.points, *delta);
    return Ok{};
}

PoseLookup PosesAtPings(const georef::GeorefResult& geo,
                        const std::vector<double>& t,
                        const std::vector<Pose>& T) {
    PoseLookup out;
    out.T_world_vehicle.reserve(geo.pings.size());
    const std::size_t n = std::min(t.size(), T.size());
    for (const georef::GeorefPing& ping : geo.pings) {
        const double tp = static_cast<double>(ping.utime_gps) * 1e-6;
        // Times in the CSV carry 1 us: a ping's own sample matches within that.
        constexpr double kTolerance = 2e-6;
        if (n == 0 || tp < t.front() - kTolerance || tp > t[n - 1] + kTolerance) {
            out.T_world_vehicle.push_back(ping.T_world_vehicle);
            ++out.outside_span;
            continue;
        }
        const auto it = std::lower_bound(t.begin(), t.begin() + static_cast<long>(n), tp);
        const std::size_t j = static_cast<std::size_t>(it - t.begin());
        if (j < n && std::abs(t[j] - tp) <= kTolerance) {
            out.T_world_vehicle.push_back(T[j]);
        } else if (j > 0 && j < n && std::abs(t[j - 1] - tp) <= kTolerance) {
            out.T_world_vehicle.push_back(T[j - 1]);
        } else if (j == 0) {
            out.T_world_vehicle.push_back(T[0]);
        } else if (j >= n) {
            out.T_world_vehicle.push_back(T[n - 1]);
        } else {
            const double a = (tp - t[j - 1]) / (t[j] - t[j - 1]);
            out.T_world_vehicle.push_back(InterpolatePose(T[j - 1], T[j], a));
        }
    }
    return out;
}

std::vector<fusion::SonarScan> MakeScans(const georef::GeorefResult& geo,
                                         const survey::PingSeries& pings,
                                         const survey::SonarMount& mount,
                                         int ping_stride) {
    if (!IsSortedByPing(geo)) return {};
    ScanMaker maker(geo.pings, pings, mount, ping_stride);
    if (!maker.Add(geo.points)) return {};
    maker.Finish();
    return maker.Take();
}

ScanMaker::ScanMaker(const std::vector<georef::GeorefPing>& geo_pings,
                     const survey::PingSeries& pings,
                     const survey::SonarMount& mount,
                     int ping_stride)
    : geo_pings_(geo_pings),
      pings_(pings),
      T_vehicle_sonar_(mount.T_vehicle_sonar()),
      stride_(static_cast<std::size_t>(std::max(1, ping_stride))),
      num_scans_((geo_pings.size() + stride_ - 1) / stride_) {}

Status ScanMaker::Add(const georef::GeorefPoints& block) {
    std::size_t last = last_ping_;
    for (const std::uint32_t k : block.ping) {
        if (k < last || k >= geo_pings_.size()) {
            return Error{"internal: the view's points are not in ping order (ping " +
                         std::to_string(k) + " after " + std::to_string(last) + " of " +
                         std::to_string(geo_pings_.size()) + ")"};
        }
        last = k;
    }
    for (std::size_t i = 0; i < block.ping.size(); ++i) {
        const std::size_t k = block.ping[i];
        OpenThrough(k);
        if (k > last_ping_) CompleteBefore((k + stride_ - 1) / stride_);  // pings before k
        last_ping_ = k;
        if (k % stride_ != 0) continue;
        std::vector<float>& ranges = open_[k / stride_ - first_].ranges_m;
        const std::uint16_t b = block.beam[i];
        if (b < ranges.size()) ranges[b] = block.range_m[i];
    }
    return Ok{};
}

void ScanMaker::Finish() {
    if (!geo_pings_.empty()) OpenThrough(geo_pings_.size() - 1);
    CompleteBefore(num_scans_);
}

std::vector<fusion::SonarScan> ScanMaker::Take() {
    const std::size_t n = complete_ - first_;
    std::vector<fusion::SonarScan> out(
        std::make_move_iterator(open_.begin()),
        std::make_move_iterator(open_.begin() + static_cast<long>(n)));
    open_.erase(open_.begin(), open_.begin() + static_cast<long>(n));
    first_ = complete_;
    return out;
}

void ScanMaker::OpenThrough(std::size_t ping) {
    for (; next_ping_ <= ping; ++next_ping_) {
        if (next_ping_ % stride_ != 0) continue;
        const georef::GeorefPing& p = geo_pings_[next_ping_];
        fusion::SonarScan& s = open_.emplace_back();
        s.gps_time_s = static_cast<double>(p.utime_gps) * 1e-6;
        Pose tilt = Pose::Identity();
        tilt.linear() =
            Eigen::AngleAxisd(p.profile_tilt_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
        s.T_world_sonar = p.T_world_vehicle * T_vehicle_sonar_ * tilt;
        if (p.header_index >= pings_.pings.size()) continue;
        const survey::PingHeader& h = pings_.pings[p.header_index];
        s.start_angle_rad = static_cast<float>(frames::DegToRad(h.start_angle_deg));
        s.angle_increment_rad = static_cast<float>(frames::DegToRad(h.angle_increment_deg));
        s.ranges_m.assign(h.num_beams, 0.0f);
    }
}

void ScanMaker::CompleteBefore(std::size_t scan) {
    for (; complete_ < scan; ++complete_) {
        const georef::GeorefPing& p = geo_pings_[complete_ * stride_];
        if (p.header_index >= pings_.pings.size() || !pings_.has_beam_angles()) continue;
        ResampleToEqualAngles(pings_, pings_.pings[p.header_index], open_[complete_ - first_]);
    }
}

TimedPoses PingPoses(const georef::GeorefResult& geo) {
    TimedPoses out;
    out.gps_time_s.reserve(geo.pings.size());
    out.T_world_vehicle.reserve(geo.pings.size());
    for (const auto& p : geo.pings) {
        out.gps_time_s.push_back(static_cast<double>(p.utime_gps) * 1e-6);
        out.T_world_vehicle.push_back(p.T_world_vehicle);
    }
    return out;
}

Status WriteTrajectoryCsv(const std::string& path, const TimedPoses& trajectory) {
    formats::TrajectoryCsv csv;
    const std::size_t n = std::min(trajectory.gps_time_s.size(), trajectory.T_world_vehicle.size());
    csv.rows.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        csv.rows.push_back(formats::RowOf(trajectory.gps_time_s[i], trajectory.T_world_vehicle[i]));
    }
    return formats::WriteTrajectoryCsv(path, csv);
}

Expected<TimedPoses> ReadTrajectoryCsv(const std::string& path) {
    auto csv = formats::ReadTrajectoryCsv(path);
    if (!csv) return csv.error();
    TimedPoses out;
    out.gps_time_s.reserve(csv->rows.size());
    out.T_world_vehicle.reserve(csv->rows.size());
    for (const formats::TrajectoryRow& r : csv->rows) {
        out.gps_time_s.push_back(r.gps_time_s);
        out.T_world_vehicle.push_back(formats::PoseOf(r));
    }
    return out;
}

}  // namespace pitmap::proc::pipeline
