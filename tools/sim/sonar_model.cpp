// SPDX-License-Identifier: MIT
#include "tools/sim/sonar_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>

#include "common/frames.hpp"

namespace pitmap::sim {

SonarModel::SonarModel(const SonarConfig& config,
                       const PitWorld& world,
                       std::uint64_t seed,
                       const WaterColumn* water,
                       const BackscatterConfig& backscatter)
    : cfg_(config),
      world_(world),
      seed_(seed),
      water_(water),
      seabed_(backscatter, seed, world.boulders()) {}

double SonarModel::BeamAngleDeg(int i) const {
    const long start = std::lround((cfg_.start_angle_deg + 180.0) * 100.0);
    const long inc = std::lround(cfg_.angle_increment_deg * 100.0);
    return static_cast<double>(start + i * inc) / 100.0 - 180.0;
}

double SonarModel::RangeSigma(double r) const {
    return cfg_.range_noise_fraction * r + cfg_.range_noise_constant_m;
}

SimPing SonarModel::Ping(const Pose& T_world_sonar, std::int64_t ping_number) const {
    const auto nb = static_cast<std::size_t>(cfg_.num_beams);
    SimPing out;
    out.ping_number = ping_number;
    out.range_counts.assign(nb, 0);
    out.intensities.assign(cfg_.intensities ? nb : 0, 0);
    out.true_range_m.assign(nb, std::numeric_limits<float>::quiet_NaN());
    out.outcome.assign(nb, BeamOutcome::kNoHit);
    out.true_hit_world.assign(nb, Eigen::Vector3d::Constant(std::nan("")));
    std::mt19937_64 rng(seed_ * 0x9E3779B97F4A7C15ull + static_cast<std::uint64_t>(ping_number));
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::uniform_real_distribution<double> uni(0.0, 1.0);

    const Eigen::Vector3d origin = T_world_sonar.translation();
    const Eigen::Matrix3d R = T_world_sonar.linear();
    const double half_width = frames::DegToRad(cfg_.beam_width_deg) / 2;
    // Footprint pattern: the beam axis, then pairs across and along track at half the half-width.
    const int nsub = cfg_.footprint_rays;
    const double res_m = cfg_.range_resolution_mm / 1000.0;
    // The sonar's sound speed: a probe at the head (the water column at the transducer), or the
    // configured one. Ranges are that speed times the one-way travel time.
    // The 83P field holds 0.1 m/s: the sonar works with what it reports.
    const double c_assumed =
        water_ ? std::round(water_->SpeedAt(-origin.z()) * 10.0) / 10.0 : cfg_.sound_speed_mps;
    out.sound_speed_mps = c_assumed;
    struct SubHit {
        double range_m;
        Eigen::Vector3d point;
    };
    const auto cast = [&](const Eigen::Vector3d& d_world) -> std::optional<SubHit> {
        if (water_) {
            auto h = water_->Cast(world_, origin, d_world, cfg_.max_range_m / c_assumed);
            if (!h) return std::nullopt;
            return SubHit{h->one_way_time_s * c_assumed, h->point};
        }
        auto r = world_.RayCast(origin, d_world, cfg_.max_range_m);
        if (!r) return std::nullopt;
        return SubHit{*r, origin + *r * d_world};
    };
    for (std::size_t i = 0; i < nb; ++i) {
        const double theta = frames::DegToRad(BeamAngleDeg(static_cast<int>(i)));
        double hits_m[9];
        SubHit sub[9];
        int hits = 0;
        for (int k = 0; k < nsub; ++k) {
            // Footprint pattern (across, along) in units of 0.6 half-widths: the axis, a cross,
            // then the diagonals.
            static constexpr double kPattern[9][2] = {{0, 0},
                                                      {1, 0},
                                                      {-1, 0},
                                                      {0, 1},
                                                      {0, -1},
                                                      {0.7, 0.7},
                                                      {-0.7, 0.7},
                                                      {0.7, -0.7},
                                                      {-0.7, -0.7}};
            const double dtheta = kPattern[k][0] * 0.6 * half_width;
            const double dphi = kPattern[k][1] * 0.6 * half_width;
            // Beam direction in the sonar frame: rotate nadir (z) by theta about x (towards +y),
            // then by phi about y (towards +x, along track).
            const double t = theta + dtheta;
            const Eigen::Vector3d d_sonar(
                std::sin(dphi) * std::cos(t), std::sin(t), std::cos(dphi) * std::cos(t));
            if (auto h = cast(R * d_sonar)) {
                sub[hits] = *h;
                hits_m[hits++] = h->range_m;
            }
        }
        if (hits * 2 <= nsub) continue;  // most of the footprint saw nothing
        // The detection is the median range over the footprint: unbiased on a plane (a mean
        // of 1/cos over the beam width is biased long at oblique incidence) and, at a bench
        // edge, the range of the surface that fills most of the beam.
        std::nth_element(hits_m, hits_m + hits / 2, hits_m + hits);
        const double r_true = hits_m[hits / 2];
        out.true_range_m[i] = static_cast<float>(r_true);
        // Where the detection lies: on the beam axis at the true range (straight rays), or the
        // curved sub-ray whose range is the median.
        if (water_) {
            for (int k = 0; k < hits; ++k) {
                if (sub[k].range_m == r_true) out.true_hit_world[i] = sub[k].point;
            }
        } else {
            out.true_hit_world[i] =
                origin + R * Eigen::Vector3d(0, std::sin(theta), std::cos(theta)) * r_true;
        }
        double r = r_true + RangeSigma(r_true) * gauss(rng);
        const double u = uni(rng);
        out.outcome[i] = BeamOutcome::kValid;
        if (u < cfg_.dropout_probability) {
            out.outcome[i] = BeamOutcome::kDropout;
            continue;
        }
        if (cfg_.dropout_patch_radius_m > 0 &&
            std::hypot(out.true_hit_world[i].x() - cfg_.dropout_patch_x_m,
                       out.true_hit_world[i].y() - cfg_.dropout_patch_y_m) <
                cfg_.dropout_patch_radius_m) {
            out.outcome[i] = BeamOutcome::kDropout;
            continue;
        }
        if (u < cfg_.dropout_probability + cfg_.outlier_probability) {
            out.outcome[i] = BeamOutcome::kOutlier;
            r = r_true * (0.3 + 1.0 * uni(rng));  // coarse: 30 % .. 130 % of the true range
        }
        const double counts = std::round(std::clamp(r, 0.0, cfg_.max_range_m) / res_m);
        out.range_counts[i] = static_cast<std::uint16_t>(std::clamp(counts, 1.0, 65535.0));
        if (cfg_.intensities) {
            // The echo level (BackscatterConfig): the seabed's backscatter at the true hit, its
            // angular response at the true incidence, two-way spreading and absorption over
            // the true range, speckle; the 83P value is the amplitude.
            const Eigen::Vector3d hit = out.true_hit_world[i];
            const Eigen::Vector3d n = world_.Normal(hit.x(), hit.y());
            const Eigen::Vector3d dir = (hit - origin).normalized();
            const double incidence_deg =
                std::acos(std::clamp(-dir.dot(n), 0.0, 1.0)) * 180.0 / 3.14159265358979323846;
            const double level =
                seabed_.LevelDb(r_true, incidence_deg, seabed_.At(hit.x(), hit.y())) +
                seabed_.config().speckle_db * gauss(rng);
            out.intensities[i] = static_cast<std::uint16_t>(
                std::clamp(std::round(std::pow(10.0, level / 20.0)), 1.0, 65535.0));
        }
    }
    return out;
}

}  // namespace pitmap::sim
