// SPDX-License-Identifier: MIT
#include "processor/georef/georef.hpp"
#include "processor/georef/georef_blocks.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>

#include "common/frames.hpp"

namespace pitmap::proc::georef {

std::vector<std::string> GeorefConfig::Validate() const {
    std::vector<std::string> p;
    if (!(max_nav_gap_s > 0)) p.push_back("georef.max_nav_gap_s must be > 0");
    if (!(max_nav_extrapolation_s >= 0 && max_nav_extrapolation_s <= max_nav_gap_s)) {
        p.push_back("georef.max_nav_extrapolation_s must be in [0, max_nav_gap_s]");
    }
    if (!(min_range_m >= 0)) p.push_back("georef.min_range_m must be >= 0");
    if (!(max_range_m > min_range_m)) p.push_back("georef.max_range_m must be > min_range_m");
    if (!(nominal_sound_speed_mps > 1000 && nominal_sound_speed_mps < 2000)) {
        p.push_back("georef.nominal_sound_speed_mps must be in (1000, 2000)");
    }
    if (spike_half_window < 0 || spike_half_window > 50) {
        p.push_back("georef.spike_half_window must be in 0..50");
    }
    if (!(spike_abs_m > 0)) p.push_back("georef.spike_abs_m must be > 0");
    if (!(spike_rel >= 0)) p.push_back("georef.spike_rel must be >= 0");
    if (num_threads < 0) p.push_back("georef.num_threads must be >= 0 (0 = all cores)");
    return p;
}

Trajectory::Trajectory(const survey::NavSeries& nav, const LocalTangentFrame& world) {
    utime_gps_.reserve(nav.samples.size());
    T_world_vehicle_.reserve(nav.samples.size());
    for (const survey::NavSample& s : nav.samples) {
        utime_gps_.push_back(s.utime_gps);
        T_world_vehicle_.push_back(
            MakePose(frames::RotationWorldFromRpy(s.roll_rad, s.pitch_rad, s.yaw_rad),
                     world.ToEnu(s.position)));
    }
}

std::optional<Pose> Trajectory::PoseAt(std::int64_t utime_gps,
                                       double max_gap_s,
                                       double max_extrapolation_s) const {
    if (utime_gps_.empty()) return std::nullopt;
    const auto outside_s = [](std::int64_t a, std::int64_t b) {
        return static_cast<double>(a - b) * 1e-6;
    };
    if (utime_gps < utime_gps_.front() || utime_gps > utime_gps_.back()) {
        const bool before = utime_gps < utime_gps_.front();
        const double by_s = before ? outside_s(utime_gps_.front(), utime_gps)
                                   : outside_s(utime_gps, utime_gps_.back());
        if (by_s > max_extrapolation_s || utime_gps_.size() < 2) return std::nullopt;
        // The end samples' motion carried on: alpha < 0 before the first, > 1 after the last.
        const std::size_t i0 = before ? 0 : utime_gps_.size() - 2;
        const double dt_s = outside_s(utime_gps_[i0 + 1], utime_gps_[i0]);
        if (!(dt_s > 0) || dt_s > max_gap_s) return std::nullopt;
        const double alpha = outside_s(utime_gps, utime_gps_[i0]) / dt_s;
        return InterpolatePose(T_world_vehicle_[i0], T_world_vehicle_[i0 + 1], alpha);
    }
    auto it = std::lower_bound(utime_gps_.begin(), utime_gps_.end(), utime_gps);
    const auto i1 = static_cast<std::size_t>(it - utime_gps_.begin());
    if (utime_gps_[i1] == utime_gps) return T_world_vehicle_[i1];
    const std::size_t i0 = i1 - 1;
    const double dt_s = outside_s(utime_gps_[i1], utime_gps_[i0]);
    if (dt_s > max_gap_s) return std::nullopt;
    const double alpha = outside_s(utime_gps, utime_gps_[i0]) / dt_s;
    return InterpolatePose(T_world_vehicle_[i0], T_world_vehicle_[i1], alpha);
}

Eigen::Vector3d BeamVectorSonar(double range_m, double angle_rad, double tilt_rad) {
    const Eigen::Vector3d v(0.0, range_m * std::sin(angle_rad), range_m * std::cos(angle_rad));
    if (tilt_rad == 0.0) return v;
    // Tilt about the sonar y axis: positive tilts the fan forward (x grows for z > 0).
    const double c = std::cos(tilt_rad), s = std::sin(tilt_rad);
    return Eigen::Vector3d(c * v.x() + s * v.z(), v.y(), -s * v.x() + c * v.z());
}

int SpikeFilter(const std::vector<double>& r,
                int half_window,
                double abs_m,
                double rel,
                std::vector<char>& keep) {
    const int n = static_cast<int>(r.size());
    keep.assign(r.size(), 1);
    if (half_window <= 0) return 0;
    int spikes = 0;
    double window[101];
    for (int i = 0; i < n; ++i) {
        if (!(r[i] > 0)) continue;
        int m = 0;
        for (int j = std::max(0, i - half_window); j <= std::min(n - 1, i + half_window); ++j) {
            if (r[j] > 0) window[m++] = r[j];
        }
        if (m < 3) continue;  // too few neighbours to judge
        std::nth_element(window, window + m / 2, window + m);
        const double med = window[m / 2];
        if (std::abs(r[i] - med) > abs_m + rel * med) {
            keep[i] = 0;
            ++spikes;
        }
    }
    return spikes;
}

namespace {

struct PingWork {
    bool ok = false;
    int reason = 0;  // 1 outside, 2 gap, 3 bad header
    GeorefPing ping;
};

// Whether a sounding of status `s` (Resolve) belongs to the view; `georef` is georef's own
// verdict.
bool InView(survey::SoundingStatus s, survey::SoundingStatus georef, survey::SoundingView view) {
    switch (view) {
        case survey::SoundingView::kAccepted:
            return s == survey::SoundingStatus::kAccepted;
        case survey::SoundingView::kRejected:
            return s != survey::SoundingStatus::kAccepted &&
                   s != survey::SoundingStatus::kNoDetection &&
                   s != survey::SoundingStatus::kRefraction;
        case survey::SoundingView::kCandidates: {
            if (s == survey::SoundingStatus::kAccepted) return true;
            if (!survey::IsCleaningStatus(s)) return false;
            return georef == survey::SoundingStatus::kAccepted;
        }
    }
    return false;
}

// What refraction needs per ping: transducer depth and the speed at the face.
struct PingWater {
    double transducer_depth_m = 0;
    double face_speed_mps = 0;
};

PingWater WaterAt(const svp::Refraction& refr,
                  const GeorefPing& ping,
                  const survey::SonarMount& mount,
                  double header_speed_mps) {
    PingWater w;
    w.transducer_depth_m = refr.TransducerDepth(ping.T_world_vehicle.linear() * mount.lever_arm_m);
    w.face_speed_mps = refr.FaceSpeed(ping.cast, w.transducer_depth_m, header_speed_mps);
    return w;
}

// The soundings in the input's flat layout (one slot per input beam; range -1 = no point), as
// the per-ping work writes them: positions, ranges and angles straight into the result's
// arrays (compacted in place afterwards, CompactSoundings), and every sounding's status.
struct FlatSoundings {
    std::vector<Eigen::Vector3d>& pos;
    std::vector<float>& rng;
    std::vector<float>& ang;
    std::vector<std::uint8_t>& status;  // survey::SoundingStatus
};

// What every ping's work reads.
struct PingContext {
    const survey::PingSeries& series;
    const Trajectory& trajectory;
    const LocalTangentFrame& world;
    const survey::SonarMount& mount;
    const Pose& T_vehicle_sonar;
    const GeorefConfig& config;
    const svp::Refraction* refraction;  // null: straight rays
    const survey::SoundingFlags* flags;
    survey::SoundingView view;
};

// The ping's pose and its refraction set-up, or why it has none (bad header, outside the
// navigation, in a navigation gap).
PingWork PlacePing(const PingContext& ctx, std::size_t k, PingWater& water) {
    const survey::PingHeader& h = ctx.series.pings[k];
    const GeorefConfig& config = ctx.config;
    PingWork w;
    if (!(h.range_resolution_m > 0) || !std::isfinite(h.start_angle_deg) ||
        !std::isfinite(h.angle_increment_deg) || !std::isfinite(h.profile_tilt_deg)) {
        w.reason = 3;
        return w;
    }
    const std::int64_t t = h.utime_gps;
    const auto& times = ctx.trajectory.times();
    const auto extrapolation_us = static_cast<std::int64_t>(config.max_nav_extrapolation_s * 1e6);
    if (times.empty() || t < times.front() - extrapolation_us ||
        t > times.back() + extrapolation_us) {
        w.reason = 1;
        return w;
    }
    const auto T_world_vehicle =
        ctx.trajectory.PoseAt(t, config.max_nav_gap_s, config.max_nav_extrapolation_s);
    if (!T_world_vehicle) {
        w.reason = t < times.front() || t > times.back() ? 1 : 2;
        return w;
    }
    w.ok = true;
    w.ping.utime_gps = t;
    w.ping.ping_number = h.ping_number;
    w.ping.header_index = static_cast<std::uint32_t>(k);
    w.ping.T_world_vehicle = *T_world_vehicle;
    w.ping.sensor_world = (*T_world_vehicle * ctx.T_vehicle_sonar).translation();
    w.ping.profile_tilt_rad =
        config.apply_profile_tilt ? frames::DegToRad(h.profile_tilt_deg) : 0.0;
    if (ctx.refraction) {
        w.ping.assumed_sound_speed_mps =
            h.sound_speed_mps > 0 ? h.sound_speed_mps : config.nominal_sound_speed_mps;
        double lat = 0, lon = 0;
        if (ctx.refraction->selection() == svp::CastSelection::kNearestInDistance) {
            const Geodetic g = ctx.world.FromEnu(w.ping.sensor_world);
            lat = g.latitude_deg;
            lon = g.longitude_deg;
        }
        w.ping.cast = ctx.refraction->SelectCast(t, lat, lon);
        water = WaterAt(*ctx.refraction, w.ping, ctx.mount, w.ping.assumed_sound_speed_mps);
    }
    return w;
}

// The ping's ranges (-1 where the beam has none, with status kNoDetection), the range gate's
// verdicts in `status` (the ping's beams from slot `at` on).
void GateRanges(const PingContext& ctx,
                const survey::PingHeader& h,
                std::size_t at,
                std::vector<double>& r,
                std::vector<std::uint8_t>& status) {
    const GeorefConfig& config = ctx.config;
    double scale = h.range_resolution_m;
    if (config.sound_speed_scaling && h.sound_speed_valid) {
        scale *= h.sound_speed_mps / config.nominal_sound_speed_mps;
    }
    r.assign(h.num_beams, -1.0);
    for (std::size_t i = 0; i < h.num_beams; ++i) {
        const std::size_t j = h.beam_offset + i;
        const std::uint32_t c = ctx.series.range_counts[j];
        if (c == 0) {
            status[at + i] = static_cast<std::uint8_t>(survey::SoundingStatus::kNoDetection);
            continue;
        }
        const double range = c * scale;
        r[i] = range;
        if (range < config.min_range_m || range > config.max_range_m) {
            status[at + i] = static_cast<std::uint8_t>(survey::SoundingStatus::kRangeGate);
        }
    }
}

// Marks the ping's spikes (SpikeFilter; the median runs over the ranges inside the gate) in
// `status` from slot `at` on. `keep_range` and `keep` are scratch.
void FlagSpikes(const GeorefConfig& config,
                const survey::PingHeader& h,
                std::size_t at,
                const std::vector<double>& r,
                std::vector<double>& keep_range,
                std::vector<char>& keep,
                std::vector<std::uint8_t>& status) {
    keep_range = r;
    for (std::size_t i = 0; i < h.num_beams; ++i) {
        if (status[at + i] != 0) keep_range[i] = -1.0;
    }
    SpikeFilter(keep_range, config.spike_half_window, config.spike_abs_m, config.spike_rel, keep);
    for (std::size_t i = 0; i < h.num_beams; ++i) {
        if (keep_range[i] > 0 && !keep[i]) {
            status[at + i] = static_cast<std::uint8_t>(survey::SoundingStatus::kSpike);
        }
    }
}

// Every beam with a range: its final status (georef's own, resolved against the edit flags),
// and, when it belongs to the view, its world position (traced through the water column with
// refraction, else a straight ray; a beam that does not trace gets kRefraction), in `out`
// from slot `at` on.
void PositionBeams(const PingContext& ctx,
                   const survey::PingHeader& h,
                   std::size_t at,
                   const GeorefPing& ping,
                   const PingWater& water,
                   const std::vector<double>& r,
                   FlatSoundings& out) {
    const Pose T_world_sonar = ping.T_world_vehicle * ctx.T_vehicle_sonar;
    for (std::size_t i = 0; i < h.num_beams; ++i) {
        const std::size_t j = at + i;
        if (!(r[i] > 0)) continue;
        const auto own = static_cast<survey::SoundingStatus>(out.status[j]);
        const survey::SoundingStatus s =
            ctx.flags ? survey::Resolve(own, *ctx.flags, h.beam_offset + i) : own;
        out.status[j] = static_cast<std::uint8_t>(s);
        if (!InView(s, own, ctx.view)) continue;
        const double theta = frames::DegToRad(ctx.series.BeamAngleDeg(h, i));
        if (ctx.refraction) {
            const svp::BeamGeometry b = ctx.refraction->Beam(ping.cast,
                                                             T_world_sonar.linear(),
                                                             theta,
                                                             ping.profile_tilt_rad,
                                                             r[i],
                                                             ping.assumed_sound_speed_mps,
                                                             water.transducer_depth_m,
                                                             water.face_speed_mps);
            if (b.steering_failed || b.status != svp::RayStatus::kOk) {
                out.status[j] = static_cast<std::uint8_t>(survey::SoundingStatus::kRefraction);
                continue;
            }
            out.pos[j] = ping.sensor_world + b.offset_world;
        } else {
            out.pos[j] = T_world_sonar * BeamVectorSonar(r[i], theta, ping.profile_tilt_rad);
        }
        out.rng[j] = static_cast<float>(r[i]);
        out.ang[j] = static_cast<float>(theta);
    }
}

// Where each ping's beams sit in the flat arrays: the input's layout (beam_offset) for the
// whole survey, or a block's own (`slots`, one per ping from `first`).
struct FlatLayout {
    std::size_t first = 0;           // the first ping
    std::size_t end = 0;             // one past the last
    std::vector<std::size_t> slots;  // empty: PingHeader::beam_offset
    std::size_t At(const survey::PingSeries& series, std::size_t k) const {
        return slots.empty() ? std::size_t{series.pings[k].beam_offset} : slots[k - first];
    }
};

// Georeferences pings layout.first .. layout.end into `flat`, in parallel (tbb;
// config.num_threads). Returns the pings' work (index k - layout.first); `cancelled` when the
// progress callback asked to stop.
std::vector<PingWork> GeoreferencePings(const PingContext& ctx,
                                        const FlatLayout& layout,
                                        FlatSoundings& flat,
                                        const ProgressCallback& progress,
                                        bool& cancelled) {
    const std::size_t n_pings = layout.end - layout.first;
    std::vector<PingWork> work(n_pings);
    std::unique_ptr<tbb::global_control> limit;
    if (ctx.config.num_threads > 0) {
        limit =
            std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(ctx.config.num_threads));
    }
    std::atomic<std::size_t> done{0};
    std::atomic<bool> cancel{false};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_pings, 64), [&](const auto& block) {
        std::vector<double> r, keep_range;
        std::vector<char> keep;
        for (std::size_t w = block.begin(); w != block.end(); ++w) {
            if (cancel.load(std::memory_order_relaxed)) return;
            const std::size_t k = layout.first + w;
            PingWater water;
            work[w] = PlacePing(ctx, k, water);
            if (!work[w].ok) continue;
            const survey::PingHeader& h = ctx.series.pings[k];
            const std::size_t at = layout.At(ctx.series, k);
            GateRanges(ctx, h, at, r, flat.status);
            FlagSpikes(ctx.config, h, at, r, keep_range, keep, flat.status);
            PositionBeams(ctx, h, at, work[w].ping, water, r, flat);
        }
        const std::size_t d = done.fetch_add(block.size()) + block.size();
        if (progress && !progress(static_cast<double>(d) / static_cast<double>(n_pings))) {
            cancel = true;
        }
    });
    cancelled = cancel;
    return work;
}

// Compacts the georeferenced pings' soundings in ping order (deterministic, independent of the
// thread count) into result.points and result.pings, counting statuses and lost pings. In
// place when the pings' beams follow each other in the flat array (every reader builds it so):
// the write index then never passes the read index. Otherwise into fresh arrays.
void CompactSoundings(const survey::PingSeries& series,
                      const FlatLayout& layout,
                      const std::vector<PingWork>& work,
                      const std::vector<std::uint8_t>& status,
                      survey::SoundingView view,
                      GeorefResult& result) {
    GeorefPoints& P = result.points;
    std::vector<Eigen::Vector3d>& pos = P.position_world;
    std::vector<float>& rng = P.range_m;
    std::vector<float>& ang = P.angle_rad;
    const std::size_t n_pings = layout.end - layout.first;
    std::size_t n_points = 0;
    bool in_place = true;
    std::size_t next_offset = 0;
    for (std::size_t w = 0; w < n_pings; ++w) {
        const std::size_t k = layout.first + w;
        const survey::PingHeader& h = series.pings[k];
        const std::size_t at = layout.At(series, k);
        in_place = in_place && at >= next_offset;
        next_offset = at + h.num_beams;
        if (!work[w].ok) continue;
        for (std::size_t i = 0; i < h.num_beams; ++i) n_points += rng[at + i] > 0;
    }
    std::vector<Eigen::Vector3d> pos_out;
    std::vector<float> rng_out, ang_out;
    if (!in_place) {
        pos_out.resize(n_points);
        rng_out.resize(n_points);
        ang_out.resize(n_points);
    }
    Eigen::Vector3d* pos_to = in_place ? pos.data() : pos_out.data();
    float* rng_to = in_place ? rng.data() : rng_out.data();
    float* ang_to = in_place ? ang.data() : ang_out.data();
    P.ping.reserve(n_points);
    P.beam.reserve(n_points);
    const bool with_status = view != survey::SoundingView::kAccepted;
    if (with_status) P.status.reserve(n_points);
    std::size_t out = 0;
    GeorefCounts& c = result.counts;
    for (std::size_t k = 0; k < n_pings; ++k) {
        const PingWork& w = work[k];
        if (!w.ok) {
            if (w.reason == 1) ++c.pings_outside_nav;
            if (w.reason == 2) ++c.pings_in_nav_gap;
            if (w.reason == 3) ++c.pings_bad_header;
            continue;
        }
        const survey::PingHeader& h = series.pings[layout.first + k];
        const std::size_t at = layout.At(series, layout.first + k);
        for (std::size_t i = 0; i < h.num_beams; ++i) ++c.status[status[at + i]];
        const auto ping_index = static_cast<std::uint32_t>(result.pings.size());
        result.pings.push_back(w.ping);
        for (std::size_t i = 0; i < h.num_beams; ++i) {
            const std::size_t j = at + i;
            if (!(rng[j] > 0)) continue;
            pos_to[out] = pos[j];
            rng_to[out] = rng[j];
            ang_to[out] = ang[j];
            if (with_status) P.status.push_back(status[j]);
            ++out;
            P.ping.push_back(ping_index);
            P.beam.push_back(static_cast<std::uint16_t>(i));
        }
    }
    if (!in_place) {
        pos.swap(pos_out);
        rng.swap(rng_out);
        ang.swap(ang_out);
    }
    pos.resize(out);
    rng.resize(out);
    ang.resize(out);
}

// The summary counters from the per-status counts (`points`: the soundings in the view), and
// the result's message.
void FinishCounts(GeorefResult& result, std::size_t points) {
    GeorefCounts& c = result.counts;
    c.no_detection = c.status[static_cast<int>(survey::SoundingStatus::kNoDetection)];
    c.range_gate = c.status[static_cast<int>(survey::SoundingStatus::kRangeGate)];
    c.spikes = c.status[static_cast<int>(survey::SoundingStatus::kSpike)];
    c.refraction_failed = c.status[static_cast<int>(survey::SoundingStatus::kRefraction)];
    c.cleaned = 0;
    for (int code = 0; code < survey::kNumSoundingStatus; ++code) {
        if (survey::IsCleaningStatus(static_cast<survey::SoundingStatus>(code)))
            c.cleaned += c.status[code];
    }
    c.manual = c.status[static_cast<int>(survey::SoundingStatus::kManual)];
    c.pings_georeferenced = static_cast<std::int64_t>(result.pings.size());
    c.points = static_cast<std::int64_t>(points);
    result.message = std::to_string(c.points) + " points from " +
                     std::to_string(c.pings_georeferenced) + " of " + std::to_string(c.pings_in) +
                     " pings";
}

}  // namespace

Eigen::Vector3d SoundingVectorSonar(const GeorefResult& result, std::size_t j) {
    return SoundingVectorSonar(result, result.points, j);
}

Eigen::Vector3d SoundingVectorSonar(const GeorefResult& result,
                                    const GeorefPoints& P,
                                    std::size_t j) {
    const GeorefPing& ping = result.pings[P.ping[j]];
    if (!result.refraction) {
        return BeamVectorSonar(P.range_m[j], P.angle_rad[j], ping.profile_tilt_rad);
    }
    const Pose T_world_sonar = ping.T_world_vehicle * result.mount.T_vehicle_sonar();
    return T_world_sonar.inverse() * P.position_world[j];
}

namespace {

// The result's mount, refraction, input counts and world origin (the given one, else the first
// navigation sample's); false, with the message, when there is no navigation to georeference on.
bool StartResult(const survey::NavSeries& nav,
                 const survey::PingSeries& series,
                 const survey::SonarMount& mount,
                 const std::shared_ptr<const svp::Refraction>& refraction,
                 std::optional<Geodetic> origin,
                 GeorefResult& result) {
    result.mount = mount;
    result.refraction = refraction;
    result.counts.pings_in = static_cast<std::int64_t>(series.pings.size());
    result.counts.soundings_in = static_cast<std::int64_t>(series.range_counts.size());
    if (nav.samples.empty()) {
        result.message = "no navigation samples";
        result.counts.pings_outside_nav = result.counts.pings_in;
        return false;
    }
    result.world_origin = origin ? *origin : nav.samples.front().position;
    return true;
}

}  // namespace

GeorefResult RunGeoref(const survey::NavSeries& nav,
                       const survey::PingSeries& series,
                       const survey::SonarMount& mount,
                       const GeorefConfig& config,
                       std::optional<Geodetic> origin,
                       const ProgressCallback& progress,
                       std::shared_ptr<const svp::Refraction> refraction,
                       const survey::SoundingFlags* flags,
                       survey::SoundingView view) {
    GeorefResult result;
    if (!StartResult(nav, series, mount, refraction, origin, result)) return result;
    const LocalTangentFrame world(result.world_origin);
    const Trajectory trajectory(nav, world);
    const Pose T_vehicle_sonar = mount.T_vehicle_sonar();

    // The outputs are written in the input's flat layout and compacted in place below: no
    // provisional copy of every beam, whose pages the kernel would zero (docs/benchmarks.md, the
    // georef and calibrate stages).
    const std::size_t n_beams = series.range_counts.size();
    GeorefPoints& P = result.points;
    P.position_world.resize(n_beams);
    P.range_m.assign(n_beams, -1.0f);
    P.angle_rad.resize(n_beams);
    std::vector<std::uint8_t> status(n_beams,
                                     static_cast<std::uint8_t>(survey::SoundingStatus::kAccepted));
    FlatSoundings flat{P.position_world, P.range_m, P.angle_rad, status};
    const PingContext ctx{
        series, trajectory, world, mount, T_vehicle_sonar, config, refraction.get(), flags, view};
    bool cancelled = false;
    const FlatLayout layout{0, series.pings.size(), {}};
    const std::vector<PingWork> work = GeoreferencePings(ctx, layout, flat, progress, cancelled);
    if (cancelled) {
        result.points = GeorefPoints{};
        result.cancelled = true;
        result.message = "cancelled";
        return result;
    }
    CompactSoundings(series, layout, work, status, view, result);
    FinishCounts(result, result.points.size());
    return result;
}

namespace {

// One past the last ping of the block that starts at ping `first`: whole pings whose beams add
// up to at most `block_soundings`, at least one ping.
std::size_t BlockEnd(const survey::PingSeries& series,
                     std::size_t first,
                     std::size_t block_soundings) {
    std::size_t k = first, beams = 0;
    while (k < series.pings.size() &&
           (k == first || beams + series.pings[k].num_beams <= block_soundings)) {
        beams += series.pings[k].num_beams;
        ++k;
    }
    return k;
}

// The block's own layout: its pings' beams one after the other from slot 0; `beams` their sum.
FlatLayout BlockLayout(const survey::PingSeries& series,
                       std::size_t first,
                       std::size_t end,
                       std::size_t& beams) {
    FlatLayout layout{first, end, {}};
    layout.slots.reserve(end - first);
    beams = 0;
    for (std::size_t k = first; k < end; ++k) {
        layout.slots.push_back(beams);
        beams += series.pings[k].num_beams;
    }
    return layout;
}

}  // namespace

GeorefResult RunGeorefByBlocks(const survey::NavSeries& nav,
                               const survey::PingSeries& series,
                               const survey::SonarMount& mount,
                               const GeorefConfig& config,
                               std::size_t block_soundings,
                               const GeorefBlockSink& sink,
                               std::optional<Geodetic> origin,
                               const ProgressCallback& progress,
                               std::shared_ptr<const svp::Refraction> refraction,
                               const survey::SoundingFlags* flags,
                               survey::SoundingView view) {
    GeorefResult result;
    if (!StartResult(nav, series, mount, refraction, origin, result)) return result;
    const LocalTangentFrame world(result.world_origin);
    const Trajectory trajectory(nav, world);
    const Pose T_vehicle_sonar = mount.T_vehicle_sonar();
    const PingContext ctx{
        series, trajectory, world, mount, T_vehicle_sonar, config, refraction.get(), flags, view};
    const std::size_t n_pings = series.pings.size();
    std::size_t points = 0;
    std::vector<std::uint8_t> status;
    auto stop = [&](const char* why) {
        result.points = GeorefPoints{};
        result.cancelled = true;
        result.message = why;
        return result;
    };
    for (std::size_t first = 0; first < n_pings;) {
        std::size_t beams = 0;
        const FlatLayout layout =
            BlockLayout(series, first, BlockEnd(series, first, block_soundings), beams);
        GeorefPoints& P = result.points;
        P = GeorefPoints{};
        P.position_world.resize(beams);
        P.range_m.assign(beams, -1.0f);
        P.angle_rad.resize(beams);
        status.assign(beams, static_cast<std::uint8_t>(survey::SoundingStatus::kAccepted));
        FlatSoundings flat{P.position_world, P.range_m, P.angle_rad, status};
        ProgressCallback part;
        if (progress) {
            part = [&](double f) {
                const double done =
                    static_cast<double>(first) + f * static_cast<double>(layout.end - layout.first);
                return progress(done / static_cast<double>(n_pings));
            };
        }
        bool cancelled = false;
        const std::vector<PingWork> work = GeoreferencePings(ctx, layout, flat, part, cancelled);
        if (cancelled) return stop("cancelled");
        CompactSoundings(series, layout, work, status, view, result);
        points += P.size();
        if (!sink(P, result)) return stop("stopped: the view's soundings could not be kept");
        first = layout.end;
    }
    result.points = GeorefPoints{};
    FinishCounts(result, points);
    return result;
}

Remount::Remount(GeorefResult& result, const survey::SonarMount& mount)
    : result_(result), T_vehicle_sonar_(mount.T_vehicle_sonar()) {
    for (GeorefPing& ping : result.pings) {
        ping.sensor_world = (ping.T_world_vehicle * T_vehicle_sonar_).translation();
    }
    result.mount = mount;
    const svp::Refraction* refr = result.refraction.get();
    if (refr == nullptr) return;
    depth_m_.resize(result.pings.size());
    face_speed_mps_.resize(result.pings.size());
    for (std::size_t k = 0; k < result.pings.size(); ++k) {
        const PingWater w =
            WaterAt(*refr, result.pings[k], mount, result.pings[k].assumed_sound_speed_mps);
        depth_m_[k] = w.transducer_depth_m;
        face_speed_mps_[k] = w.face_speed_mps;
    }
}

void Remount::Apply(GeorefPoints& P) const {
    const GeorefResult& result = result_;
    const Pose& T_vehicle_sonar = T_vehicle_sonar_;
    const svp::Refraction* refr = result.refraction.get();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P.size(), 4096), [&](const auto& b) {
        for (std::size_t j = b.begin(); j != b.end(); ++j) {
            const GeorefPing& ping = result.pings[P.ping[j]];
            const Pose T_world_sonar = ping.T_world_vehicle * T_vehicle_sonar;
            if (refr) {
                const svp::BeamGeometry g = refr->Beam(ping.cast,
                                                       T_world_sonar.linear(),
                                                       P.angle_rad[j],
                                                       ping.profile_tilt_rad,
                                                       P.range_m[j],
                                                       ping.assumed_sound_speed_mps,
                                                       depth_m_[P.ping[j]],
                                                       face_speed_mps_[P.ping[j]]);
                // A beam that traced before and not now (a mount change of a fraction of a
                // degree at a turning ray) keeps its straight position.
                P.position_world[j] =
                    g.status == svp::RayStatus::kOk && !g.steering_failed
                        ? Eigen::Vector3d(ping.sensor_world + g.offset_world)
                        : Eigen::Vector3d(T_world_sonar * BeamVectorSonar(P.range_m[j],
                                                                          P.angle_rad[j],
                                                                          ping.profile_tilt_rad));
            } else {
                P.position_world[j] =
                    T_world_sonar *
                    BeamVectorSonar(P.range_m[j], P.angle_rad[j], ping.profile_tilt_rad);
            }
        }
    });
}

void Regeoreference(GeorefResult& result, const survey::SonarMount& mount) {
    const Remount remount(result, mount);
    remount.Apply(result.points);
}

GeorefPoints SliceOf(const GeorefPoints& p, std::size_t first, std::size_t count) {
    GeorefPoints out;
    const auto take = [&](const auto& from, auto& to) {
        if (from.empty()) return;
        to.assign(from.begin() + static_cast<std::ptrdiff_t>(first),
                  from.begin() + static_cast<std::ptrdiff_t>(first + count));
    };
    take(p.position_world, out.position_world);
    take(p.ping, out.ping);
    take(p.beam, out.beam);
    take(p.range_m, out.range_m);
    take(p.angle_rad, out.angle_rad);
    take(p.status, out.status);
    return out;
}

void AppendPoints(const GeorefPoints& from, GeorefPoints& to) {
    const auto append = [](const auto& src, auto& dst) {
        dst.insert(dst.end(), src.begin(), src.end());
    };
    append(from.position_world, to.position_world);
    append(from.ping, to.ping);
    append(from.beam, to.beam);
    append(from.range_m, to.range_m);
    append(from.angle_rad, to.angle_rad);
    append(from.status, to.status);
}

Expected<UtmProjection> UtmProjectionOf(const GeorefResult& result) {
    UtmProjection out;
    auto o = UtmFromGeodetic(result.world_origin);
    if (!o) return o.error();
    out.zone = o->zone;
    out.northern = o->northern;
    out.epsg = UtmEpsgCode(o->zone, o->northern);
    const LocalTangentFrame world(result.world_origin);
    // Jacobian of (E, N) w.r.t. (east, north) at the origin, by central differences over 10 m.
    Eigen::Matrix2d J;
    for (int axis = 0; axis < 2; ++axis) {
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        d[axis] = 10.0;
        auto plus = UtmFromGeodetic(world.FromEnu(d), out.zone);
        auto minus = UtmFromGeodetic(world.FromEnu(-d), out.zone);
        if (!plus || !minus) return Error{"UTM: cannot project around the world origin"};
        J(0, axis) = (plus->easting_m - minus->easting_m) / 20.0;
        J(1, axis) = (plus->northing_m - minus->northing_m) / 20.0;
    }
    out.en_per_world = J;
    out.sensor_utm.resize(result.pings.size());
    for (std::size_t k = 0; k < result.pings.size(); ++k) {
        auto u = UtmFromGeodetic(world.FromEnu(result.pings[k].sensor_world), out.zone);
        if (!u) return u.error();
        out.sensor_utm[k] = Eigen::Vector3d(u->easting_m, u->northing_m, u->height_m);
    }
    return out;
}

Expected<UtmPoints> ToUtm(const GeorefResult& result) {
    auto projection = UtmProjectionOf(result);
    if (!projection) return projection.error();
    UtmPoints out;
    out.zone = projection->zone;
    out.northern = projection->northern;
    out.epsg = projection->epsg;
    out.easting_northing_height.resize(result.points.size());
    for (std::size_t j = 0; j < result.points.size(); ++j) {
        out.easting_northing_height[j] = projection->At(result, j);
    }
    return out;
}

}  // namespace pitmap::proc::georef
