// SPDX-License-Identifier: MIT
// The sound speed uncertainty of the TPU from the data (issue 36 item 2; docs/uncertainty.md
// "Sound speed uncertainty from the data"). Two quantities, 1 sigma, m/s:
//   - the column speed sigma: how far the water column's speed below the transducer may lie
//     from the profile the soundings were computed with (the cast, or the sonar's own speed
//     when no cast was given: straight rays);
//   - the surface speed sigma: of the speed at the transducer face that the beam steering
//     correction used.
// They come from
//   1. a cast: the error model's sigmas (vehicle.yaml `uncertainty:`), grown with the cast's
//      age and distance from the ping, sigma^2 = sigma0^2 + (age_rate * |t - t_cast|)^2 +
//      (distance_rate * distance)^2 (CastSpeedSigma; a stated assumption, not a measurement:
//      SoundSpeedSigmaConfig's defaults), and with the observed disagreement between the
//      sonar's own surface speed (the 83P header's, a probe at the head) and the cast at the
//      transducer depth, added in quadrature to both: water that changed at the surface since
//      the cast changed below it too;
//   2. the swath overlap (EstimateColumnSpeedError): where soundings of different beam angles
//      hit the same floor, a column speed error dc shows as a depth error that depends on the
//      angle (the refraction-error relation below), which a least-squares fit over the overlaps
//      measures, per depth class. That estimate bounds what the profile in use gets wrong, cast
//      or no cast (without a cast it is the only knowledge of the column).
//   3. no cast, and the overlap showing stratified water (the overlap then sees only part of
//      the error: calibration and SLAM absorb some of the angle-dependent disagreement, and the
//      depth error common to all angles is invisible to it): the a-priori bound of a
//      fresh-water pit (NoCastPriorSigma): the column's speed lies between the surface speed
//      and the speed of water at 4 degC (the density maximum, the coldest water a stratified
//      lake holds at depth), uniformly: sigma = |c_surface - c(4 degC)| / sqrt(3) (the RMS of
//      the error of using the surface speed over that range). No cast and an overlap too small
//      to stand for the column (its estimated depth classes hold less than
//      overlap_min_estimated_share of its soundings) keeps the error model's column term and
//      flags the survey as not assessable for sound speed (the grid stage's gate): nothing
//      measured says the water is stratified, so the bound is not taken on no evidence.
//
// The refraction-error relation (Snell's law, first order; the TPU's kSoundSpeed term): with
// the speed at the face known (the ray parameter p = sin(phi0) / c0 fixed) and the column's
// speed off by dc (uniformly), a sounding at depth d below the transducer and horizontal
// distance x moves by
//   dz = d (dc / c) (1 - tan^2 phi0),   dx = 2 x (dc / c),
// from dz/dt = c cos(phi), dx/dt = c sin(phi) = p c^2 and d(c cos phi)/dc = cos(2 phi)/cos(phi)
// at fixed p. At nadir it is Hare, Godin & Mayer's (1995) range scaling d dc / c; towards 45 deg
// the slower travel and the bending cancel in depth; beyond, the bending dominates.
//
// Thread safety: all functions are reentrant.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace pitmap::proc::hydro {

struct SoundSpeedSigmaConfig {
    // Growth of the column speed sigma with the cast's age and distance (stated assumptions:
    // a sunlit pit's mixed layer warms by about 0.3 degC an hour, 3 m/s per degC in fresh
    // water at 20 degC; a pit's water is horizontally uniform to about 1 m/s a kilometre).
    double cast_age_rate_mps_per_h = 1.0;
    double cast_distance_rate_mps_per_km = 1.0;
    // The swath-overlap estimate.
    double overlap_cell_m = 1.0;          // cells the overlapping soundings are compared in
    double overlap_max_slope_deg = 15.0;  // floors only (a plane is fitted per cell)
    int overlap_min_cell_soundings = 6;
    double overlap_max_angle_deg = 65.0;  // beams beyond (from the vertical) are not used
    // Depth classes (below the transducer) estimated on their own, m: a stratified column's
    // error grows with depth through the thermocline.
    // Cells shallower than the first edge are not fitted (the first class's estimate applies
    // there): within 6 m of the transducer a column error moves a sounding by a few cm at most
    // and the passes' own height and attitude errors, common to a pass and so not in the
    // jackknife's error, fit as one (the demo's homogeneous 3-6 m: -12 +- 0.4 m/s).
    std::vector<double> overlap_depth_edges_m = {
        6, 10, 15, 20, 30, 50, std::numeric_limits<double>::infinity()};
    // A column speed error beyond this (m/s, and beyond 3 standard errors) in any class is
    // water the soundings' profile does not describe (stratified water without a cast): the
    // overlap sees only the part of it that differs between beam angles after calibration and
    // SLAM have absorbed what they could, so without a cast the a-priori bound applies.
    double overlap_stratified_mps = 5.0;
    // Without a cast the overlap must estimate the classes that hold at least this share of
    // its soundings to stand for the column (else: not assessable, the a-priori bound).
    double overlap_min_estimated_share = 0.8;
    double overlap_min_weight_m2 = 50.0;            // sum of the residual regressor^2 a class needs
    std::size_t overlap_max_soundings = 2'000'000;  // evenly strided beyond

    std::vector<std::string> Validate() const;
};

// Column speed sigma (m/s) of a ping computed with a cast (1. above). base_sigma_mps: the error
// model's; age_s, distance_m: from the cast to the ping (NaN = unknown: not counted);
// surface_disagreement_mps: header speed - cast speed at the transducer depth (NaN = unknown).
double CastSpeedSigma(double base_sigma_mps,
                      double age_s,
                      double distance_m,
                      double surface_disagreement_mps,
                      const SoundSpeedSigmaConfig& config);

// 3. above: |surface_speed - c(0 psu, 4 degC, 0 dbar)| / sqrt(3), Chen & Millero (UNESCO 1983).
double NoCastPriorSigma(double surface_speed_mps);

// The refraction-error regressor of a sounding: its depth change per unit relative column
// speed error, d (1 - tan^2 phi0), from its offset from the transducer (world, z up). 0 for a
// sounding not below the transducer.
double RefractionRegressor(const Eigen::Vector3d& offset_world);

struct OverlapDepthClass {
    double lo_m = 0, hi_m = 0;  // depth below the transducer
    std::size_t cells = 0, soundings = 0;
    double weight_m2 = 0;          // sum of the residual regressor^2
    bool estimated = false;        // weight >= overlap_min_weight_m2
    double relative_error = 0;     // dc / c, least squares over the class's cells
    double relative_error_se = 0;  // its standard error (delete-a-group jackknife, 8 groups)
};
struct OverlapSpeedEstimate {
    std::vector<OverlapDepthClass> classes;
    std::size_t soundings_used = 0, cells_used = 0;
    bool estimated() const;  // any class
    // The share of the overlap's soundings in estimated classes (0 without soundings).
    double EstimatedShare() const;
    // The class with the largest significant error (|e| c > stratified_mps and |e| > 3 se),
    // or -1: whether the overlap shows stratified water the profile does not describe.
    int StratifiedClass(double c_mps, double stratified_mps) const;
    // The relative column speed sigma at a depth below the transducer once the overlap has been
    // seen (ColumnRelativeSigma with its class's estimate), or for a class without an estimate
    // the largest of the nearest estimated classes above and below. `prior_relative_sigma`: the
    // ping's column sigma before the overlap (the cast's or the error model's, over the sound
    // speed). NaN when nothing was estimated.
    double RelativeSigmaAt(double depth_m, double prior_relative_sigma) const;
    std::string message;
};

// The column's relative speed error after the overlap's estimate e +- se of it (one depth
// class), for a column a priori within p (1 sigma; the cast's or the error model's): the root
// mean square of the error the soundings carry (docs/decisions/028).
//   - |e| <= 3 se (the overlap does not contradict the prior): the posterior of a Gaussian prior
//     N(0, p^2) updated by the measurement e ~ N(dc/c, se^2): k = p^2 / (p^2 + se^2), mean k e,
//     variance k se^2; the soundings were not corrected, so they carry sqrt((k e)^2 + k se^2).
//     An overlap that measures little (se >> p) leaves the prior; one that measures well
//     (se << p) states what it measured.
//   - |e| > 3 se (the prior is contradicted: the test StratifiedClass makes): the prior and the
//     estimate as they are, sqrt(p^2 + e^2 + se^2).
// Before, every class added sqrt(e^2 + se^2) to the prior: a flat prior, so that a class the
// overlap hardly measures (a 120 s quarry's 6-10 m: -0.069 +- 0.046, 104 +- 69 m/s) stated a
// column error no fresh water can have at every depth it stood for.
double ColumnRelativeSigma(double prior_relative_sigma,
                           double relative_error,
                           double relative_error_se);

// 2. above. Soundings in cells of overlap_cell_m (world x, y); per cell a plane z = a + b x +
// c y + k g is fitted jointly over all cells of a depth class (the cell's mean depth) with one
// k per class (the cells' planes eliminated: Frisch-Waugh), g = RefractionRegressor. Cells
// whose own plane is steeper than overlap_max_slope_deg are left out, and so, three times over,
// are cells whose residual RMS after the plane and k exceeds 3 times their class's median (no
// floor: a bench edge, two surfaces, echoes); a class whose |k| exceeds 0.07 (100 m/s, more
// than any fresh water spans) is not estimated (the fit explains something else, e.g. a wrong
// boresight on a few cells). k = dc / c, dc the true
// column's speed minus the profile's (a sounding's height error is g dc / c: positive, the
// water is faster than the soundings assumed). Preconditions: the vectors have equal sizes;
// config.Validate() is empty.
// The stride EstimateColumnSpeedError takes the soundings at (every stride-th from the first,
// at most overlap_max_soundings of them): a caller that reads the soundings by blocks may give
// it only those (then ceil(soundings / stride) <= overlap_max_soundings, whose own stride is 1:
// the same estimate bit for bit).
std::size_t OverlapStride(std::size_t soundings, const SoundSpeedSigmaConfig& config);

OverlapSpeedEstimate EstimateColumnSpeedError(const std::vector<Eigen::Vector3d>& points_world,
                                              const std::vector<Eigen::Vector3d>& offsets_world,
                                              const SoundSpeedSigmaConfig& config);

}  // namespace pitmap::proc::hydro
