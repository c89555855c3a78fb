// SPDX-License-Identifier: MIT
#include "tools/sim/echo_artifacts.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/frames.hpp"
#include "tools/sim/sonar_model.hpp"

namespace pitmap::sim {
namespace {

// Target strengths of the artifacts' echoes, dB, in the place of BS + AR(theta) of the
// seabed's echo level (scenario.hpp BackscatterConfig): a fish school is a weaker volume
// target than rock, near-field bubbles are loud, a multipath ghost has lost energy on its
// extra bounce, the smile is a side lobe of the strong specular nadir echo.
constexpr double kMidWaterDb = -30.0;
constexpr double kBubbleDb = -18.0;
constexpr double kMultipathDb = -38.0;
constexpr double kSmileDb = -28.0;

std::uint64_t Mix(std::uint64_t a, std::uint64_t b) {
    std::uint64_t x = a ^ (b + 0x9E3779B97F4A7C15ull + (a << 6) + (a >> 2));
    x ^= x >> 31;
    x *= 0xBF58476D1CE4E5B9ull;
    x ^= x >> 27;
    return x;
}

}  // namespace

const char* EchoArtifactName(EchoArtifactKind kind) {
    switch (kind) {
        case EchoArtifactKind::kNone:
            return "none";
        case EchoArtifactKind::kMidWater:
            return "mid_water";
        case EchoArtifactKind::kBubble:
            return "bubble";
        case EchoArtifactKind::kDropout:
            return "dropout";
        case EchoArtifactKind::kMultipath:
            return "multipath";
        case EchoArtifactKind::kSmile:
            return "smile";
        case EchoArtifactKind::kOutlier:
            return "outlier";
    }
    return "unknown";
}

EchoArtifactModel::EchoArtifactModel(const EchoArtifactConfig& config,
                                     const SonarConfig& sonar,
                                     const BackscatterConfig& backscatter,
                                     const PitWorld& world,
                                     std::uint64_t seed)
    : cfg_(config),
      sonar_(sonar),
      bs_(backscatter),
      world_(world),
      seed_(seed),
      rng_(Mix(seed, 0xEC405ull)) {}

EchoArtifactModel::School EchoArtifactModel::SchoolAt(int index, double t_s) const {
    // Staggered lifetimes: school k is reborn at k / n of a lifetime, generation g from then.
    const double life = cfg_.school_lifetime_s;
    const double phase = life * static_cast<double>(index) / std::max(cfg_.num_schools, 1);
    const auto g = static_cast<std::int64_t>(std::floor((t_s + phase) / life));
    const double born_s = static_cast<double>(g) * life - phase;
    std::mt19937_64 rng(Mix(Mix(seed_, 0x5C400ull + static_cast<std::uint64_t>(index)),
                            static_cast<std::uint64_t>(g)));
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const TerrainGrid& grid = world_.grid();
    const double w = grid.resolution_m * (grid.nx - 1), h = grid.resolution_m * (grid.ny - 1);
    School s{Eigen::Vector3d(std::nan(""), 0, 0), 0};
    s.radius_m =
        cfg_.school_min_radius_m + (cfg_.school_max_radius_m - cfg_.school_min_radius_m) * uni(rng);
    // A centre over water deep enough for the school (rejection; at most 32 draws).
    for (int k = 0; k < 32; ++k) {
        const double x = grid.x0_m + w * uni(rng), y = grid.y0_m + h * uni(rng);
        const double top = cfg_.school_min_depth_m, bottom = world_.Depth(x, y) - 1.0 - s.radius_m;
        if (bottom <= top) continue;
        s.centre = Eigen::Vector3d(x, y, -(top + (bottom - top) * uni(rng)));
        break;
    }
    const double heading = 2 * M_PI * uni(rng), speed = cfg_.school_drift_mps * uni(rng);
    s.centre += (t_s - born_s) * speed * Eigen::Vector3d(std::cos(heading), std::sin(heading), 0);
    return s;
}

double EchoArtifactModel::Intensity(double range_m, double target_db, std::mt19937_64& rng) const {
    std::normal_distribution<double> gauss(0.0, 1.0);
    const double r = std::max(range_m, 0.1);
    const double level = bs_.source_level_db - bs_.spreading_db_per_decade * std::log10(r) -
                         2.0 * bs_.absorption_db_per_m * r + target_db +
                         bs_.speckle_db * gauss(rng);
    return std::clamp(std::round(std::pow(10.0, level / 20.0)), 1.0, 65535.0);
}

void EchoArtifactModel::Apply(SimPing& ping,
                              const Pose& T_world_sonar,
                              double t_s,
                              const PingMotion& motion) {
    const std::size_t nb = ping.range_counts.size();
    ping.artifact.assign(nb, EchoArtifactKind::kNone);
    for (std::size_t i = 0; i < nb; ++i) {
        if (ping.outcome[i] == BeamOutcome::kOutlier) ping.artifact[i] = EchoArtifactKind::kOutlier;
    }
    if (!cfg_.enabled()) return;
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::normal_distribution<double> gauss(0.0, 1.0);
    const double res_m = sonar_.range_resolution_mm / 1000.0;
    const Eigen::Vector3d origin = T_world_sonar.translation();
    const Eigen::Matrix3d R = T_world_sonar.linear();
    const auto angle_rad = [&](std::size_t i) {
        return frames::DegToRad(sonar_.start_angle_deg +
                                static_cast<double>(i) * sonar_.angle_increment_deg);
    };
    const auto sigma = [&](double r) {
        return sonar_.range_noise_fraction * r + sonar_.range_noise_constant_m;
    };
    // Sets beam i to an artifact at range r (with the sonar's noise), unless that lies within
    // max(0.3 m, 5 sigma) of the true range: then the beam keeps its own echo.
    const auto set = [&](std::size_t i, double r, EchoArtifactKind kind, double target_db) {
        r += sigma(r) * gauss(rng_);
        const double rt = ping.true_range_m[i];
        if (std::isfinite(rt) && std::abs(r - rt) < std::max(0.3, 5 * sigma(rt))) return;
        if (!(r > res_m) || r > sonar_.max_range_m) return;
        ping.range_counts[i] =
            static_cast<std::uint16_t>(std::clamp(std::round(r / res_m), 1.0, 65535.0));
        if (!ping.intensities.empty())
            ping.intensities[i] = static_cast<std::uint16_t>(Intensity(r, target_db, rng_));
        ping.artifact[i] = kind;
    };
    const std::int64_t k = ping.ping_number;

    // Multipath ghosts: active episodes first, then new ones from the candidate beams.
    std::vector<bool> held(nb, false);
    std::erase_if(multipath_, [k](const Episode& e) { return e.last_ping < k; });
    for (const Episode& e : multipath_) {
        for (int b = e.first_beam; b < e.first_beam + e.num_beams; ++b) {
            const auto i = static_cast<std::size_t>(b);
            held[i] = true;
            if (std::isfinite(ping.true_range_m[i]))
                set(i,
                    ping.true_range_m[i] * (1.0 + e.a),
                    EchoArtifactKind::kMultipath,
                    kMultipathDb);
        }
    }
    if (cfg_.multipath_probability > 0) {
        const double cos_grazing = std::cos(frames::DegToRad(cfg_.multipath_grazing_deg));
        const double cos_wall = std::cos(frames::DegToRad(cfg_.multipath_wall_slope_deg));
        for (std::size_t i = 0; i < nb; ++i) {
            if (held[i] || !std::isfinite(ping.true_range_m[i])) continue;
            if (uni(rng_) >= cfg_.multipath_probability) continue;
            const Eigen::Vector3d& hit = ping.true_hit_world[i];
            const Eigen::Vector3d n = world_.Normal(hit.x(), hit.y());
            const Eigen::Vector3d dir = (hit - origin).normalized();
            if (std::abs(dir.dot(n)) > cos_grazing && std::abs(n.z()) > cos_wall) continue;
            Episode e;
            std::uniform_int_distribution<int> beams(cfg_.multipath_min_beams,
                                                     cfg_.multipath_max_beams);
            std::uniform_int_distribution<int> pings(cfg_.multipath_min_pings,
                                                     cfg_.multipath_max_pings);
            e.first_beam = static_cast<int>(i);
            e.num_beams = std::min(beams(rng_), static_cast<int>(nb - i));
            e.last_ping = k + pings(rng_) - 1;
            e.a = cfg_.multipath_min_excess +
                  (cfg_.multipath_max_excess - cfg_.multipath_min_excess) * uni(rng_);
            for (int b = e.first_beam; b < e.first_beam + e.num_beams; ++b) {
                const auto j = static_cast<std::size_t>(b);
                held[j] = true;
                if (std::isfinite(ping.true_range_m[j]))
                    set(j,
                        ping.true_range_m[j] * (1.0 + e.a),
                        EchoArtifactKind::kMultipath,
                        kMultipathDb);
            }
            multipath_.push_back(e);
        }
    }

    // The smile: the nadir beam's true range at short range.
    std::size_t nadir = 0;
    for (std::size_t i = 1; i < nb; ++i) {
        if (std::abs(angle_rad(i)) < std::abs(angle_rad(nadir))) nadir = i;
    }
    const double r0 = nb > 0 ? ping.true_range_m[nadir] : std::nan("");
    if (std::isfinite(r0) && r0 < cfg_.smile_max_nadir_range_m) {
        if (smile_.last_ping < k && uni(rng_) < cfg_.smile_probability) {
            std::uniform_int_distribution<int> pings(cfg_.smile_min_pings, cfg_.smile_max_pings);
            smile_.last_ping = k + pings(rng_) - 1;
            // How far out this episode's side lobe reaches.
            smile_.a = frames::DegToRad(cfg_.smile_min_angle_deg +
                                        (cfg_.smile_max_angle_deg - cfg_.smile_min_angle_deg) *
                                            (0.5 + 0.5 * uni(rng_)));
        }
        if (smile_.last_ping >= k) {
            const double lo = frames::DegToRad(cfg_.smile_min_angle_deg);
            for (std::size_t i = 0; i < nb; ++i) {
                const double a = std::abs(angle_rad(i));
                const double rt = ping.true_range_m[i];
                if (a < lo || a > smile_.a || !std::isfinite(rt) || rt < 1.05 * r0) continue;
                set(i, r0, EchoArtifactKind::kSmile, kSmileDb);
            }
        }
    }

    // Mid-water targets: the nearest school a beam's axis enters before the bottom.
    if (cfg_.num_schools > 0) {
        std::vector<School> schools;
        for (int s = 0; s < cfg_.num_schools; ++s) {
            School sc = SchoolAt(s, t_s);
            // Patchy: a school answers a ping as a whole or not at all (its echo spans
            // neighbouring beams, which a median over a few beams keeps).
            if (uni(rng_) >= cfg_.school_fill) continue;
            if (!std::isfinite(sc.centre.x())) continue;
            // Only schools within reach of the fan (cheap pre-test).
            if ((sc.centre - origin).norm() > sonar_.max_range_m + sc.radius_m) continue;
            schools.push_back(sc);
        }
        for (std::size_t i = 0; i < nb && !schools.empty(); ++i) {
            const double th = angle_rad(i);
            const Eigen::Vector3d d = R * Eigen::Vector3d(0, std::sin(th), std::cos(th));
            const double bottom =
                std::isfinite(ping.true_range_m[i]) ? ping.true_range_m[i] : sonar_.max_range_m;
            double best = std::numeric_limits<double>::infinity();
            for (const School& sc : schools) {
                const Eigen::Vector3d oc = origin - sc.centre;
                const double b = oc.dot(d), c = oc.squaredNorm() - sc.radius_m * sc.radius_m;
                const double disc = b * b - c;
                if (disc < 0) continue;
                const double s = -b - std::sqrt(disc);
                if (s > 0.5 && s < bottom) best = std::min(best, s);
            }
            if (std::isfinite(best)) set(i, best, EchoArtifactKind::kMidWater, kMidWaterDb);
        }
    }

    // Bubble sweep-down: episodes at random, more often while turning or pitching hard.
    if (cfg_.bubble_episodes_per_min > 0) {
        if (bubble_.last_ping < k) {
            const bool manoeuvre = std::abs(motion.yaw_rate_deg_s) > cfg_.bubble_turn_rate_deg_s ||
                                   std::abs(motion.pitch_rate_deg_s) > cfg_.bubble_pitch_rate_deg_s;
            const double p = cfg_.bubble_episodes_per_min / 60.0 / sonar_.ping_rate_hz *
                             (manoeuvre ? cfg_.bubble_manoeuvre_factor : 1.0);
            if (uni(rng_) < p) {
                std::uniform_int_distribution<int> pings(cfg_.bubble_min_pings,
                                                         cfg_.bubble_max_pings);
                bubble_.last_ping = k + pings(rng_) - 1;
                const double share = cfg_.bubble_sector_min +
                                     (cfg_.bubble_sector_max - cfg_.bubble_sector_min) * uni(rng_);
                bubble_.num_beams = std::max(1, static_cast<int>(share * static_cast<double>(nb)));
                bubble_.first_beam = static_cast<int>(
                    uni(rng_) * static_cast<double>(static_cast<int>(nb) - bubble_.num_beams));
            }
        }
        if (bubble_.last_ping >= k) {
            // The sector in bubble clouds of 4-16 beams: each a near-field echo at one range
            // (a cloud), no detection, or left alone.
            std::uniform_int_distribution<int> cloud(4, 16);
            for (int b0 = bubble_.first_beam; b0 < bubble_.first_beam + bubble_.num_beams;) {
                const int b1 = std::min(b0 + cloud(rng_), bubble_.first_beam + bubble_.num_beams);
                const double u = uni(rng_);
                const double r = cfg_.bubble_min_range_m +
                                 (cfg_.bubble_max_range_m - cfg_.bubble_min_range_m) * uni(rng_);
                for (int b = b0; b < b1; ++b) {
                    const auto i = static_cast<std::size_t>(b);
                    if (u < cfg_.bubble_return_share) {
                        set(i, r + 0.05 * gauss(rng_), EchoArtifactKind::kBubble, kBubbleDb);
                    } else if (u < cfg_.bubble_return_share + cfg_.bubble_dropout_share &&
                               ping.range_counts[i] > 0) {
                        ping.range_counts[i] = 0;
                        if (!ping.intensities.empty()) ping.intensities[i] = 0;
                        ping.artifact[i] = EchoArtifactKind::kDropout;
                    }
                }
                b0 = b1;
            }
        }
    }
}

std::int64_t ArtifactTruth::artifact_soundings() const {
    return beams_by_kind[static_cast<int>(EchoArtifactKind::kMidWater)] +
           beams_by_kind[static_cast<int>(EchoArtifactKind::kBubble)] +
           beams_by_kind[static_cast<int>(EchoArtifactKind::kMultipath)] +
           beams_by_kind[static_cast<int>(EchoArtifactKind::kSmile)];
}

void ArtifactTruth::Add(const SimPing& ping, const PitWorld& world) {
    ++pings;
    const std::size_t nb = ping.range_counts.size();
    beams_per_ping = static_cast<int>(nb);
    for (std::size_t i = 0; i < nb; ++i) {
        const EchoArtifactKind kind =
            i < ping.artifact.size() ? ping.artifact[i] : EchoArtifactKind::kNone;
        if (kind == EchoArtifactKind::kNone) {
            if (ping.range_counts[i] == 0) continue;
            ++good_soundings;
            const Eigen::Vector3d& hit = ping.true_hit_world[i];
            const double nz = std::clamp(std::abs(world.Normal(hit.x(), hit.y()).z()), 0.0, 1.0);
            const double slope = frames::RadToDeg(std::acos(nz));
            for (int c = 0; c < kNumArtifactSlopeClasses; ++c) {
                if (slope >= kArtifactSlopeEdgesDeg[c] && slope < kArtifactSlopeEdgesDeg[c + 1])
                    ++good_by_slope[c];
            }
            continue;
        }
        ++beams_by_kind[static_cast<int>(kind)];
        ArtifactRun* last = runs.empty() ? nullptr : &runs.back();
        if (last != nullptr && last->ping_number == static_cast<std::uint32_t>(ping.ping_number) &&
            last->kind == kind && last->first_beam + last->num_beams == static_cast<int>(i)) {
            ++last->num_beams;
        } else {
            runs.push_back({static_cast<std::uint32_t>(ping.ping_number),
                            static_cast<std::uint16_t>(i),
                            1,
                            kind});
        }
    }
}

EchoArtifactKind ArtifactTruth::KindOf(std::int64_t ping_number, int beam) const {
    if (ping_number < 0 || ping_number > std::numeric_limits<std::uint32_t>::max())
        return EchoArtifactKind::kNone;
    const auto p = static_cast<std::uint32_t>(ping_number);
    // The first run after (p, beam); the one before it may hold the beam.
    auto it = std::upper_bound(runs.begin(),
                               runs.end(),
                               std::pair{p, beam},
                               [](const std::pair<std::uint32_t, int>& key, const ArtifactRun& r) {
                                   return key.first < r.ping_number ||
                                          (key.first == r.ping_number && key.second < r.first_beam);
                               });
    if (it == runs.begin()) return EchoArtifactKind::kNone;
    --it;
    if (it->ping_number == p && beam < it->first_beam + it->num_beams) return it->kind;
    return EchoArtifactKind::kNone;
}

}  // namespace pitmap::sim
