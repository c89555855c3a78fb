// SPDX-License-Identifier: MIT
// Total propagated uncertainty (TPU) of every georeferenced sounding, after Hare, Godin & Mayer
// (1995, "Accuracy estimation of Canadian swath (multibeam) and sweep (multitransducer)
// sounding systems") and IHO S-44 Ed. 6.1: the sensor error model (common/vehicle.hpp
// SensorErrorModel) is propagated through the georeferencing equation to the sounding's
// world-frame position by the law of propagation of variance (first order, independent
// terms), in vector form rather than Hare's scalar depth/along/across equations, so that any
// mount, tilt and attitude is handled.
//
// The georeferencing equation (processor/georef/georef.hpp):
//   p = t + R (L + R_vs b(r, theta)),  R = R_world_vehicle(roll, pitch, yaw),
//   b = Ry(tilt) (0, r sin theta, r cos theta).
// With d = p - t (INS reference point to the sounding, world frame) and the unit beam vector
// u = R R_vs b / r, each term adds J sigma^2 J^T to the 3x3 covariance of p:
//   range         J = u;  sigma_r^2 = (a + f r)^2 (range noise)
//   beam angle    J = R R_vs db/dtheta;  sigma^2 = sigma_theta^2 (pointing)
//   sound speed   the column: J = (2 o_E, 2 o_N, (1 - tan^2 phi0) o_U) with o = R R_vs b the
//                 transducer-to-sounding offset and tan^2 phi0 = (o_E^2 + o_N^2) / o_U^2, per
//                 relative column speed error (the refraction-error relation of Snell's law,
//                 processor/hydro/sound_speed.hpp; at nadir Hare's range scaling);
//                 (sigma_c / c)^2 = (the ping's column speed sigma / c)^2 + the swath-overlap
//                 estimate's relative sigma at the sounding's depth; plus the swath-common
//                 part J = m o_U e_U (TpuConfig::column_swath_half_angle_deg), in quadrature;
//                 the surface: J = dp/dtheta,
//                 sigma^2 = (tan(theta) sigma_cs / c)^2 (the steering error of a flat array from
//                 the surface sound speed: Snell at the face, d theta = tan(theta) dc / c)
//   attitude      J_k = a_k x d for the rotation axes a_roll = R e_x, a_pitch = M Rz(yaw) e_y,
//                 a_yaw = M e_z (M: NED -> ENU), since dR/dk = [a_k]x R for R = M Rz Ry Rx;
//                 sigma_k^2 = pose sigma_k^2 (the INS's, or SLAM's posterior) + boresight
//                 sigma_k^2 (the calibrated one per axis when known, else the model's)
//   position      diag(sigma_E^2, sigma_N^2, sigma_U^2) (INS) + position_noise^2 I
//   heave         e_z e_z^T sigma_heave^2
//   lever arm     R sigma_L^2 I R^T = sigma_L^2 I
//   latency       J = v + w x d (vehicle velocity and angular rate at the ping, from the
//                 neighbouring pings' poses); sigma_t^2 = latency^2 + clock sigma^2
// TVU (95 %) = 1.96 sqrt(C_zz); THU (95 %) = 2.45 sqrt((C_xx + C_yy) / 2) (IHO S-44's 2-D
// factor, exact for a circular error). Heights are ellipsoidal (WGS 84): no water-level or
// datum term (those belong to the vertical reference when it is added).
// Thread safety: ComputeTpu is reentrant; results do not depend on the thread count.
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "common/vehicle.hpp"
#include "processor/georef/georef.hpp"
#include "processor/survey/series.hpp"

namespace pitmap::proc::hydro {

// 95 % factors: 1-D normal, and the radius of a circular 2-D normal (sqrt(chi2_2(0.95))).
inline constexpr double kTvu95 = 1.96;
inline constexpr double kThu95 = 2.4477;

// The INS's own 1-sigma at a ping.
struct PingSigma {
    Eigen::Vector3d position_enu_m = Eigen::Vector3d::Zero();    // east, north, up
    Eigen::Vector3d attitude_rpy_rad = Eigen::Vector3d::Zero();  // roll, pitch, yaw
    // The sound speed sigmas at the ping (processor/hydro/sound_speed.hpp), m/s: of the water
    // column against the profile used, and of the speed at the face; NaN = the error model's.
    double column_speed_sigma_mps = std::numeric_limits<double>::quiet_NaN();
    double surface_speed_sigma_mps = std::numeric_limits<double>::quiet_NaN();
};

// The error model's INS terms as a PingSigma: what applies where the INS reports no sigma.
PingSigma FallbackSigma(const SensorErrorModel& model);

// The INS's own 1 sigma at `utime_gps`: the stddev record (INSSTDEV, or INSPVAX's) nearest in
// time (records are ~1 Hz; the INS error changes slowly). Components the receiver did not
// report (NaN, <= 0), and all of them when no record lies within max_age_s, take `fallback`.
// `stddevs` is time-sorted; `from_ins`, if given, says whether a record was used. Shared by the
// shore grid stage (through pipeline::PoseSigmaAt) and pitmap live.
PingSigma InsSigmaAt(const std::vector<survey::NavStdDev>& stddevs,
                     std::int64_t utime_gps,
                     double max_age_s,
                     const PingSigma& fallback,
                     bool* from_ins = nullptr);

struct TpuConfig {
    SensorErrorModel model;      // 1-sigma sensor errors (vehicle.yaml `uncertainty:`)
    double clock_sigma_s = 0.0;  // the sonar clock's remaining sigma (summary.json)
    // The calibrated boresight's 1-sigma about roll, pitch, yaw (deg), replacing the model's
    // a-priori boresight_sigma_deg (one or the other, never both); NaN = the model's.
    std::array<double, 3> boresight_sigma_rpy_deg = {std::numeric_limits<double>::quiet_NaN(),
                                                     std::numeric_limits<double>::quiet_NaN(),
                                                     std::numeric_limits<double>::quiet_NaN()};
    double sound_speed_mps = 1500.0;  // nominal speed for the sound-speed terms
    // The relative column speed sigma at a depth below the transducer (m) once the swath
    // overlap has been seen (OverlapSpeedEstimate::RelativeSigmaAt), given the ping's own
    // relative column sigma (its column speed sigma over sound_speed_mps); it replaces the
    // ping's where finite; empty = none. Called concurrently: must be reentrant.
    std::function<double(double, double)> column_relative_sigma_at;
    // The fan's half-width (deg; 0 = off) over which the column error's vertical effect is
    // averaged into every beam of a swath: calibration and SLAM align each sounding to the
    // overlapping soundings of other beam angles, so what the column error does to one beam
    // angle, d (dc / c) (1 - tan^2 phi), is spread over the swath as its mean over the angles,
    // d (dc / c) m, m = (2 a - tan a) / a for beam angles uniform in 0..a (a = 60 deg: 0.346).
    // The TPU adds that swath-common part in quadrature to the per-angle one, so that a beam
    // near 45 deg, where the per-angle part vanishes, still states it (docs/decisions/019).
    double column_swath_half_angle_deg = 60.0;
    int num_threads = 0;  // 0 = all cores (TBB)

    std::vector<std::string> Validate() const;
};

// The error terms, in the order TpuResult reports them.
enum class TpuTerm {
    kRange = 0,
    kBeamAngle,
    kSoundSpeed,
    kAttitude,
    kPosition,
    kHeave,
    kLeverArm,
    kLatency,
    kCount
};
inline constexpr int kNumTpuTerms = static_cast<int>(TpuTerm::kCount);
const char* ToString(TpuTerm t);

// One sounding's geometry, all in the world frame (ENU) except b (sonar frame).
struct SoundingGeometry {
    Eigen::Matrix3d R_world_vehicle = Eigen::Matrix3d::Identity();
    Eigen::Matrix3d R_vehicle_sonar = Eigen::Matrix3d::Identity();
    Eigen::Vector3d lever_arm_m = Eigen::Vector3d::Zero();  // vehicle frame
    double range_m = 0;
    double angle_rad = 0;                                          // beam angle theta, sonar frame
    double tilt_rad = 0;                                           // profile tilt
    Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();        // world
    Eigen::Vector3d angular_rate_radps = Eigen::Vector3d::Zero();  // world
};

// The 3x3 world-frame covariance of one sounding (m^2); `terms`, if given, receives each
// term's share.
Eigen::Matrix3d SoundingCovariance(const SoundingGeometry& g,
                                   const PingSigma& sigma,
                                   const TpuConfig& config,
                                   std::array<Eigen::Matrix3d, kNumTpuTerms>* terms = nullptr);

struct TpuResult {
    std::vector<float> thu_95_m;  // one per sounding of GeorefResult::points
    std::vector<float> tvu_95_m;
    // The vertical 1 sigma of the terms common to the soundings of a pass (all but the range
    // noise, the beam pointing and the INS's white output noise: what CUBE's node does not
    // average over the soundings of one pass), m; one per sounding.
    std::vector<float> sigma_v_common_m;
    // The same for the horizontal 1 sigma per axis (sqrt of the mean of the east and north
    // variances without the range noise, the beam pointing and the INS's white output noise),
    // m; one per sounding. CUBE takes it on slopes (CubeSounding::sigma_h_common_m).
    std::vector<float> sigma_h_common_m;
    // Mean over the soundings of each term's share of the vertical variance (sums to 1).
    std::array<double, kNumTpuTerms> tvu_variance_share{};
    double median_tvu_95_m = 0, median_thu_95_m = 0;
    std::string message;
};

// TPU of every sounding of `geo` on its current poses. `ping_sigma` has one entry per
// GeorefResult::pings (the INS's 1 sigma there). Preconditions: config.Validate() is empty,
// ping_sigma.size() == geo.pings.size(). It is TpuByBlocks with one block.
TpuResult ComputeTpu(const georef::GeorefResult& geo,
                     const survey::SonarMount& mount,
                     const std::vector<PingSigma>& ping_sigma,
                     const TpuConfig& config);

// ComputeTpu over the view's soundings a block at a time (a view read block by block from its
// scratch file, decision 031): Add the blocks in the view's order, each sounding once, then
// Finish. The result is ComputeTpu's of the whole view bit for bit, whatever the blocks (the
// variance shares are summed in the same chunks of soundings, in the same order). `pings` are
// the view's pings (GeorefResult::pings), `soundings` the view's size; both are borrowed
// until Finish.
class TpuByBlocks {
public:
    TpuByBlocks(const std::vector<georef::GeorefPing>& pings,
                const survey::SonarMount& mount,
                const std::vector<PingSigma>& ping_sigma,
                const TpuConfig& config,
                std::size_t soundings);
    // Soundings first .. first + points.size() - 1 of the view (points: a block of it, its
    // ping indices into `pings`). Preconditions: first is the end of the previous block.
    void Add(const georef::GeorefPoints& points, std::size_t first);
    // The result; the per-sounding arrays are moved out.
    TpuResult Finish();

    static constexpr std::size_t kShareChunk = 8192;  // soundings a variance-share partial sum

private:
    const std::vector<georef::GeorefPing>& pings_;
    const std::vector<PingSigma>& ping_sigma_;
    const TpuConfig& config_;
    Eigen::Vector3d lever_arm_m_;
    Eigen::Matrix3d R_vehicle_sonar_;
    std::vector<Eigen::Vector3d> velocity_, rate_;         // per ping
    std::vector<std::array<double, kNumTpuTerms>> share_;  // per chunk of kShareChunk
    std::size_t next_ = 0;                                 // the next sounding expected
    TpuResult out_;
};

}  // namespace pitmap::proc::hydro
