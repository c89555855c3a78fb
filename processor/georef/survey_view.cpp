// SPDX-License-Identifier: MIT
#include "processor/georef/survey_view.hpp"
#include "processor/georef/georef_blocks.hpp"

#include <utility>
#include <vector>

namespace pitmap::proc::georef {

survey::PingTrajectory TrajectoryOf(const GeorefResult& geo, std::size_t num_pings) {
    survey::PingTrajectory t;
    t.T_world_vehicle.assign(num_pings, Pose::Identity());
    t.valid.assign(num_pings, 0);
    for (const GeorefPing& p : geo.pings) {
        if (p.header_index >= num_pings) continue;
        t.T_world_vehicle[p.header_index] = p.T_world_vehicle;
        t.valid[p.header_index] = 1;
    }
    return t;
}

std::vector<Pose> MovePings(GeorefResult& geo, const survey::PingTrajectory& t, std::size_t* kept) {
    std::vector<Pose> delta(geo.pings.size(), Pose::Identity());
    std::size_t same = 0;
    const Pose T_vehicle_sonar = geo.mount.T_vehicle_sonar();
    for (std::size_t k = 0; k < geo.pings.size(); ++k) {
        GeorefPing& p = geo.pings[k];
        const std::size_t i = p.header_index;
        if (i >= t.T_world_vehicle.size() || i >= t.valid.size() || t.valid[i] == 0) {
            ++same;
            continue;
        }
        delta[k] = t.T_world_vehicle[i] * p.T_world_vehicle.inverse();
        p.T_world_vehicle = t.T_world_vehicle[i];
        p.sensor_world = (p.T_world_vehicle * T_vehicle_sonar).translation();
    }
    if (kept != nullptr) *kept = same;
    return delta;
}

void MovePoints(GeorefPoints& points, const std::vector<Pose>& delta) {
    for (std::size_t j = 0; j < points.size(); ++j) {
        points.position_world[j] = delta[points.ping[j]] * points.position_world[j];
    }
}

std::size_t ApplyTrajectory(GeorefResult& geo, const survey::PingTrajectory& t) {
    std::size_t kept = 0;
    MovePoints(geo.points, MovePings(geo, t, &kept));
    return kept;
}

namespace {

// The trajectory version Georeference moves the pings onto (-1: none): the newest present at or
// before `v`, unless it is the one RunGeoref puts them on (the calibrated version once the
// calibration ran, else the INS one).
int MovedOnto(const survey::SurveyModel& m, survey::TrajectoryVersion v) {
    int chosen = -1;
    for (int i = static_cast<int>(v); i >= 0; --i) {
        if (!m.trajectories[i].empty()) {
            chosen = i;
            break;
        }
    }
    const int current = static_cast<int>(m.has(survey::TrajectoryVersion::kCalibrated)
                                             ? survey::TrajectoryVersion::kCalibrated
                                             : survey::TrajectoryVersion::kIns);
    return chosen != current ? chosen : -1;
}

// ApplyTrajectory's move of a ping: from its pose in `p` to its pose in `t` (identity where `t`
// has none).
Pose MoveOf(const GeorefPing& p, const survey::PingTrajectory& t) {
    const std::size_t i = p.header_index;
    if (i >= t.T_world_vehicle.size() || i >= t.valid.size() || t.valid[i] == 0)
        return Pose::Identity();
    return t.T_world_vehicle[i] * p.T_world_vehicle.inverse();
}

}  // namespace

GeorefResult GeoreferenceByBlocks(const survey::SurveyModel& m,
                                  survey::TrajectoryVersion v,
                                  const GeorefConfig& config,
                                  std::shared_ptr<const svp::Refraction> refraction,
                                  std::size_t block_soundings,
                                  const GeorefBlockSink& sink,
                                  const ProgressCallback& progress,
                                  std::size_t* kept,
                                  survey::SoundingView which) {
    const int onto = MovedOnto(m, v);
    GeorefPoints moved;
    // Each block moved as ApplyTrajectory moves the whole view (the same product per point).
    const auto move_sink = [&](const GeorefPoints& b, const GeorefResult& so_far) {
        if (onto < 0) return sink(b, so_far);
        moved = b;
        const survey::PingTrajectory& t = m.trajectories[static_cast<std::size_t>(onto)];
        for (std::size_t j = 0; j < moved.size(); ++j) {
            moved.position_world[j] =
                MoveOf(so_far.pings[moved.ping[j]], t) * moved.position_world[j];
        }
        return sink(moved, so_far);
    };
    GeorefResult geo = RunGeorefByBlocks(m.ingest.nav,
                                         m.ingest.pings,
                                         m.mount,
                                         config,
                                         block_soundings,
                                         move_sink,
                                         m.origin,
                                         progress,
                                         std::move(refraction),
                                         &m.flags,
                                         which);
    std::size_t k = 0;
    if (!geo.cancelled && onto >= 0)
        k = ApplyTrajectory(geo, m.trajectories[static_cast<std::size_t>(onto)]);
    if (kept != nullptr) *kept = k;
    return geo;
}

GeorefResult Georeference(const survey::SurveyModel& m,
                          survey::TrajectoryVersion v,
                          const GeorefConfig& config,
                          std::shared_ptr<const svp::Refraction> refraction,
                          const ProgressCallback& progress,
                          std::size_t* kept,
                          survey::SoundingView which) {
    // By blocks of pings into arrays reserved for every beam (decisions 033, 041): only the
    // pages of the soundings kept are touched, where RunGeoref holds every beam's position
    // before it compacts them (33 bytes a beam). The same points bit for bit.
    const std::size_t beams = m.ingest.pings.range_counts.size();
    GeorefPoints held;
    held.position_world.reserve(beams);
    held.ping.reserve(beams);
    held.beam.reserve(beams);
    held.range_m.reserve(beams);
    held.angle_rad.reserve(beams);
    if (which != survey::SoundingView::kAccepted) held.status.reserve(beams);
    const auto sink = [&held](const GeorefPoints& b, const GeorefResult&) {
        AppendPoints(b, held);
        return true;
    };
    constexpr std::size_t kBlockSoundings = std::size_t{1} << 20;
    GeorefResult geo = GeoreferenceByBlocks(
        m, v, config, std::move(refraction), kBlockSoundings, sink, progress, kept, which);
    if (!geo.cancelled) geo.points = std::move(held);
    return geo;
}

}  // namespace pitmap::proc::georef
