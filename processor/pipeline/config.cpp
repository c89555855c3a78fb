// SPDX-License-Identifier: MIT
// The processor's YAML configuration: reading with every problem listed, validation, defaults.
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <sstream>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/config.hpp"
#include "common/vehicle.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pitmap::proc::pipeline {

namespace {

// THE CONFIG KEY TABLE. Every key of every section is one entry, visited by the reader
// (LoadConfig: types checked, unknown keys rejected, every problem listed) and by the printer
// (ConfigYaml / `pitmap config --defaults`), so reading, the printed defaults and validation
// cannot drift apart. An entry is one call on the visitor `v`:
//   v("key", field, "comment")                a bool, int, double or string
//   v.Enum("key", field, kAllValues, "comment") an enum spelled by its ToString names
//   v.Optional("key", value, known, "comment")  a number or null (known = given)
//   v.NanIsNull("key", value, "comment")        a number or null (NaN = not given)
//   v.Section("name", [&](auto& s) { ... })     a nested map of entries
// A comment may hold '\n' for more lines. To add a section: write a Visit<Name>(v, config)
// with one entry per key (like VisitGeoref below) and add one v.Section line to VisitConfig;
// validation stays in the config struct's Validate(), listed in PipelineConfig::Validate.

constexpr slam::CorrespondenceType kCorrespondences[] = {slam::CorrespondenceType::kPointToPoint,
                                                         slam::CorrespondenceType::kPointToPlane,
                                                         slam::CorrespondenceType::kGicp};
constexpr slam::RobustKernel kKernels[] = {
    slam::RobustKernel::kNone, slam::RobustKernel::kHuber, slam::RobustKernel::kCauchy};
constexpr fusion::SensorModel kSensorModels[] = {fusion::SensorModel::kBeamWidth,
                                                 fusion::SensorModel::kRay};

constexpr io::IngestSource kIngestSources[] = {
    io::IngestSource::kAuto, io::IngestSource::kDecoded, io::IngestSource::kRaw};

template <class V>
void VisitIngest(V&& v, io::IngestConfig& c) {
    v.Enum("source", c.source, kIngestSources, "auto | decoded | raw (re-decode RAW_* channels)");
    v("nav_channel_id", c.nav_channel_id, "e.g. novatel_com1; \"\" = every INS channel");
    v("sonar_channel_id", c.sonar_channel_id, "e.g. deltat_udp; \"\" = every sonar channel");
    v.Optional("sonar_clock_offset_s",
               c.sonar_clock_offset_s,
               c.sonar_clock_offset_known,
               ".83P files: sonar (header) clock minus UTC, s:\n"
               "> 0 = the sonar clock is ahead, < 0 = behind;\n"
               "null = vehicle.yaml's sonar.clock_offset_s, else 0");
    v("require_good_ins",
      c.require_good_ins,
      "also drop degraded INS samples (only INS_SOLUTION_GOOD kept)");
    v("degraded_ins_sigma_m", c.degraded_ins_sigma_m, "degraded INS: position sigma floor, m");
    v("degraded_ins_sigma_deg", c.degraded_ins_sigma_deg, "... attitude sigma floor, deg");
    v("session_gap_s", c.session_gap_s, "a longer gap separates two recordings, s");
    v("max_session_speed_mps", c.max_session_speed_mps, "a faster jump separates them, m/s");
    v("report_gap_s", c.report_gap_s, "gaps within a recording reported beyond, s");
    v("session", c.session, "the recording to process when there are several (1-based)");
}

template <class V>
void VisitGeoref(V&& v, georef::GeorefConfig& c) {
    v("max_nav_gap_s", c.max_nav_gap_s, "refuse pings across longer INS gaps, s");
    v("max_nav_extrapolation_s",
      c.max_nav_extrapolation_s,
      "place pings this close outside the INS span, s");
    v("min_range_m", c.min_range_m, "range gate, m");
    v("max_range_m", c.max_range_m, "range gate, m");
    v("sound_speed_scaling", c.sound_speed_scaling, "r *= c_header / nominal");
    v("nominal_sound_speed_mps", c.nominal_sound_speed_mps, "the sound speed of the counts, m/s");
    v("apply_profile_tilt", c.apply_profile_tilt, "rotate the fan by the header's profile tilt");
    v("spike_half_window", c.spike_half_window, "beams each side of the median; 0 = off");
    v("spike_abs_m", c.spike_abs_m, "spike if |r - median| > abs + rel * median");
    v("spike_rel", c.spike_rel, "");
    v("num_threads", c.num_threads, "0 = all cores");
}

constexpr svp::CastSelection kCastSelections[] = {svp::CastSelection::kNearestPreceding,
                                                  svp::CastSelection::kNearestInTime,
                                                  svp::CastSelection::kNearestInDistance};
constexpr svp::SurfaceSpeedSource kSurfaceSpeeds[] = {svp::SurfaceSpeedSource::kProfile,
                                                      svp::SurfaceSpeedSource::kHeader};

template <class V>
void VisitRefraction(V&& v, svp::RefractionConfig& c) {
    v("svp_files", c.svp_files, "CARIS .svp, CSV or two-column casts (--svp); [] = straight rays");
    v.Enum("selection",
           c.selection,
           kCastSelections,
           "nearest_preceding | nearest_in_time | nearest_in_distance");
    v.Enum("surface_speed",
           c.surface_speed,
           kSurfaceSpeeds,
           "speed at the face: profile (the cast) | header (83P, no steering change)");
    v.NanIsNull(
        "ins_height_above_waterline_m", c.ins_height_above_waterline_m, "m; null = vehicle.yaml's");
}

template <class V>
void VisitCalibrate(V&& v, calib::BoresightConfig& c) {
    v("segment_start_s", c.segment_start_s, "GPS seconds; < 0 = automatic");
    v("segment_duration_s", c.segment_duration_s, "s (clamped to the survey)");
    v("part_duration_s", c.part_duration_s, "trajectory parts, s");
    v("min_separation_s", c.min_separation_s, "pairs only between soundings this far apart, s");
    v("beam_stride", c.beam_stride, "every n-th sounding of a ping");
    v("max_distance_m", c.max_distance_m, "correspondence gate, first iteration, m");
    v("min_distance_m", c.min_distance_m, "... last iteration, m");
    v("normal_radius_m", c.normal_radius_m, "neighbourhood for the normals, m");
    v("cauchy_scale_m", c.cauchy_scale_m, "robust kernel scale, m");
    v("max_iterations", c.max_iterations, "outer (correspondence) iterations");
    v("accelerate",
      c.accelerate,
      "extrapolate rotation and latency along aligned steps (Besl & McKay)");
    v("convergence_deg", c.convergence_deg, "stop below this update, deg");
    v("max_position_stddev_m", c.max_position_stddev_m, "low-drift limit (horizontal 1 sigma), m");
    v("max_heading_stddev_deg", c.max_heading_stddev_deg, "low-drift limit, deg");
    v("num_verify_segments", c.num_verify_segments, "other segments to verify on");
    v("verify_query_every",
      c.verify_query_every,
      "on the verification segments, pairs sought from every n-th sample only");
    v("estimate_height_offsets",
      c.estimate_height_offsets,
      "per-node INS height corrections (else parallel passes bias roll)");
    v("height_offset_sigma_m", c.height_offset_sigma_m, "their prior, m");
    v("estimate_horizontal_offsets",
      c.estimate_horizontal_offsets,
      "per-node INS horizontal corrections too");
    v("horizontal_offset_sigma_m", c.horizontal_offset_sigma_m, "their prior, m");
    v("offset_correlation_time_s", c.offset_correlation_time_s, "GM correlation time, s");
    v("ins_attitude_correlation_time_s",
      c.ins_attitude_correlation_time_s,
      "the INS attitude error's correlation time, s (the boresight's stated uncertainty)");
    v("range_noise_fraction",
      c.range_noise_fraction,
      "pair weights 1/sigma^2, sigma = fraction * range + constant");
    v("range_noise_constant_m", c.range_noise_constant_m, "m");
    v("estimate_latency",
      c.estimate_latency,
      "the sonar time offset as a 4th unknown (patch test latency)");
    v("latency_sigma_s", c.latency_sigma_s, "its prior, 1 sigma, s");
    v("latency_scan_step_s",
      c.latency_scan_step_s,
      "scan step when the clock is uncertain beyond the linear range, s");
}

template <class V>
void VisitSlam(V&& v, slam::SlamConfig& c, SlamStageConfig& s) {
    v.Enum("correspondence",
           c.correspondence,
           kCorrespondences,
           "point_to_point (the paper) | point_to_plane | gicp");
    v.Enum("robust_kernel", c.robust_kernel, kKernels, "none | huber | cauchy");
    v("point_stride", s.point_stride, "every n-th kept sounding of a ping enters SLAM");
    v("min_time_separation_s",
      c.min_time_separation_s,
      "t_d: pairs only between slices this far apart, s");
    v("max_pair_distance_m",
      c.max_pair_distance_m,
      "d_max: closest-point pairs closer than this, m");
    v("max_partner_passes",
      c.max_partner_passes,
      "pairs only with the passes over a cell nearest in time, this many\n"
      "before and after (0 = all: the cost grows with the square of the survey)");
    v("section_length_s", c.section_length_s, "rigid stage sections, s");
    v("rigid_iterations", c.rigid_iterations, "0 = no rigid stage");
    v("rigid_max_pair_distance_m",
      c.rigid_max_pair_distance_m,
      "rigid pair distance, first iteration, m");
    v("rigid_interpolate_sections",
      c.rigid_interpolate_sections,
      "corrections interpolated between section centres (false: the paper's rigid sections)");
    v("coarse_search_m",
      c.coarse_search_m,
      "horizontal search for sections of a drifting INS, m; 0 = off");
    v("coarse_search_step_m", c.coarse_search_step_m, "its step, m");
    v("coarse_search_cell_m", c.coarse_search_cell_m, "its height-grid cell, m");
    v("coarse_search_min_sigma_m",
      c.coarse_search_min_sigma_m,
      "searched when the INS 1-sigma exceeds this, m");
    v("min_section_link_pairs", c.min_section_link_pairs, "pairs needed to link two sections");
    v("bin_slices", c.bin_slices, "semi-rigid: slices per pose (1 = one pose per slice)");
    v("max_iterations", c.max_iterations, "semi-rigid iterations");
    v("semi_rigid_window_s",
      c.semi_rigid_window_s,
      "semi-rigid solve (and posterior) by windows of about this, s; 0 = the whole survey");
    v("semi_rigid_window_overlap_s",
      c.semi_rigid_window_overlap_s,
      "each window reaches this far past its core on both sides, s");
    v("semi_rigid_window_coarse_s",
      c.semi_rigid_window_coarse_s,
      "the windows' coarse level: a node every this many s; 0 = a tenth of the window");
    v("rigid_window_s",
      c.rigid_window_s,
      "rigid solve by windows of about this, s; 0 = the whole survey");
    v("rigid_window_overlap_s",
      c.rigid_window_overlap_s,
      "each rigid window reaches this far past its core, s");
    v("rigid_window_coarse_s",
      c.rigid_window_coarse_s,
      "the rigid windows' coarse level: a node every this many s; 0 = a tenth of the window");
    v("convergence_rotation_rad", c.convergence_rotation_rad, "converged below this pose update");
    v("convergence_translation_m", c.convergence_translation_m, "... and this one");
    v("normal_neighbours", c.normal_neighbours, "neighbours for normals / covariances");
    v("point_sigma_m", c.point_sigma_m, "1-sigma of a point along the surface normal, m");
    v("gicp_tangent_sigma_m", c.gicp_tangent_sigma_m, "GICP: 1-sigma along the surface, m");
    v("robust_width", c.robust_width, "robust kernel width, point sigmas");
    v("query_stride", c.query_stride, "every n-th point of a slice is a query point");
    v("pass_cell_m",
      c.pass_cell_m,
      "per pass (section) and cube of this, m, only pass_cell_points enter SLAM; 0 = all");
    v("pass_cell_points", c.pass_cell_points, "points a pass keeps per cube of pass_cell_m");
    v("pass_cell_max_sigma_m",
      c.pass_cell_max_sigma_m,
      "a section whose INS horizontal sigma exceeds this keeps every point, m; 0 = none");
    v("ins_correlation_time_s", c.ins_correlation_time_s, "INS error correlation time, s");
    v("ins_sigma_scale", c.ins_sigma_scale, "scales the INS relative-motion sigmas");
    v("ins_sigma_recovery_time_s",
      c.ins_sigma_recovery_time_s,
      "the INS sigma is not believed to shrink faster, s");
    v("drift_velocity_random_walk_mps_per_sqrt_s",
      c.drift_velocity_random_walk_mps_per_sqrt_s,
      "drift smoothness");
    v("min_relative_rotation_sigma_rad", c.min_relative_rotation_sigma_rad, "floor, rad");
    v("min_relative_translation_sigma_m", c.min_relative_translation_sigma_m, "floor, m");
    v("drift_by_smoothness_only",
      c.drift_by_smoothness_only,
      "an outage's drift is stated by the smoothness term alone (docs/decisions/022)");
    v("absolute_position_terms", c.absolute_position_terms, "GNSS/INS position prior per pose");
    v("absolute_attitude_terms", c.absolute_attitude_terms, "INS attitude prior per pose");
    v("absolute_sigma_scale",
      c.absolute_sigma_scale,
      "scales the steady part of the absolute priors' sigmas (not an outage's drift)");
    v("score_cell_m", c.score_cell_m, "plane-fit consistency score grid cell (reported), m");
    v("score_patience",
      c.score_patience,
      "stop after this many iterations without a better pair score");
    v("score_tolerance",
      c.score_tolerance,
      "a gain counts above this fraction; the last iterate is kept unless this much worse");
    v("num_threads", c.num_threads, "0 = all cores");
    v("posterior",
      c.posterior,
      "pose sigma per ping: normal equations + perturbed-start runs (docs/uncertainty.md)");
    v("posterior_cluster_robust",
      c.posterior_cluster_robust,
      "sandwich covariance, pairs clustered by section pair (else the formal H^-1)");
    v("posterior_reference_sigma",
      c.posterior_reference_sigma,
      "add the INS's steady sigma (the reference SLAM is tied to) to the posterior");
    v("posterior_tangent_information",
      c.posterior_tangent_information,
      "GICP pairs inform the posterior along the surface too (false: along the normal only)");
    v("posterior_variance_factor",
      c.posterior_variance_factor,
      "formal H^-1 times sigma0^2 (without the sandwich)");
    v("posterior_batch_nodes", c.posterior_batch_nodes, "nodes per CHOLMOD solve (6 columns each)");
    v("posterior_start_runs",
      c.posterior_start_runs,
      "SLAM runs from perturbed starts whose spread is added to the posterior (0 = off)");
    v("posterior_start_seed", c.posterior_start_seed, "seed of those runs' perturbations");
    v("sigma_max_age_s", s.sigma_max_age_s, "INS stddev records further from a ping are unused, s");
    v("ins_slow_error_from_fixes",
      s.ins_slow_error_from_fixes,
      "the posterior's reference: the INS's slow error from the header GNSS fixes where larger "
      "(docs/decisions/027)");
}

template <class V>
void VisitClean(V&& v, clean::CleanConfig& c) {
    v("enabled", c.enabled, "clean the soundings in 3D before the grid and the TSDF (run, rerun)");
    v("voxel_m", c.voxel_m, "the evidence grid's voxel, m");
    v("cluster_max_voxels", c.cluster_max_voxels, "smaller connected sets of voxels are clusters");
    v("margin_m", c.margin_m, "a ray stops this far before its own end, m ...");
    v("margin_rel", c.margin_rel, "... or this share of its range, whichever is larger");
    v("free_min_rays", c.free_min_rays, "free space: other rays through a cluster voxel, at least");
    v("free_ratio", c.free_ratio, "... and this many times its own soundings");
    v("surface_min_hits", c.surface_min_hits, "multipath: soundings in a surface patch, at least");
    v("surface_max_thickness_m", c.surface_max_thickness_m, "... its 1-sigma thickness, m");
    v("hole_tolerance",
      c.hole_tolerance,
      "a hole in a run of rejections: on the line, share of range; 0 = off");
    v("fill_max_soundings",
      c.fill_max_soundings,
      "a piece of continuous range enclosed by rejections: at most this many; 0 = off");
    v("fill_min_contacts", c.fill_min_contacts, "... touching rejected soundings this often");
    v("fill_break_m", c.fill_break_m, "... its other edges breaks of this (or margin_rel), m");
    v("fill_across_fan",
      c.fill_across_fan,
      "... grown across the fan too over steps short of a break (a ghost's noise parts its beams)");
    v("terrain_piece_soundings",
      c.terrain_piece_soundings,
      "a rejection continuous in range with this many accepted soundings is terrain; 0 = off");
    v("min_crossing_deg", c.min_crossing_deg, "a ray crosses a patch at more than this, deg");
    v("solid_ratio",
      c.solid_ratio,
      "a patch crossed by fewer rays than this share of its support is solid");
    v("profile_pings", c.profile_pings, "range profiles: neighbouring pings each side; 0 = off");
    v("profile_beams", c.profile_beams, "... and beams each side; 0 = off");
    v("profile_sigmas", c.profile_sigmas, "... off the neighbours' line by this many spreads");
    v("profile_min_m", c.profile_min_m, "... and this far, m");
    v("profile_max_spread", c.profile_max_spread, "... where their spread / range is below");
    v("near_field_max_range_m",
      c.near_field_max_range_m,
      "near-field echoes (bubbles): soundings at most this range are judged, m; 0 = off");
    v("near_field_ratio",
      c.near_field_ratio,
      "... rejected under this share of the beam's median range over the pings each side");
    v("near_field_min_m", c.near_field_min_m, "... and this far in front of both, m");
    v("smile_nadir_deg",
      c.smile_nadir_deg,
      "the nadir smile: a ping's nadir is its sounding nearest to 0 deg within this, deg; 0 = off");
    v("num_threads", c.num_threads, "0 = all cores");
}

template <class V>
void VisitFuse(V&& v, fusion::TsdfConfig& c, fusion::WeightFilterConfig& w) {
    v.Enum("sensor_model", c.sensor_model, kSensorModels, "beam_width (May et al.) | ray");
    v("voxel_size_m", c.voxel_size_m, "voxel edge, m");
    v("truncation_m", c.truncation_m, "truncation band, m");
    v("weight_per_measurement", c.weight_per_measurement, "f (uniform weights)");
    v("max_weight", c.max_weight, "w_max");
    v("beam_width_rad", c.beam_width_rad, "out-of-plane beam width, rad");
    v("footprint_gate_m", c.footprint_gate_m, "beam-width: a footprint beam agrees within this");
    v("footprint_gate_fraction", c.footprint_gate_fraction, "... plus this share of the range");
    v("ping_gap_fill_m", c.ping_gap_fill_m, "beam-width: bridge gaps between pings up to this, m");
    v("ping_gap_fill_per_beam",
      c.ping_gap_fill_per_beam,
      "beam-width: a beam missing in the next ping is bridged to the one after it");
    v("ping_gap_bridge_pings",
      c.ping_gap_bridge_pings,
      "... and across up to this many pings where both sides' footprints agree (0 = off)");
    v("footprint_neighbour_pings",
      c.footprint_neighbour_pings,
      "beam-width: along-track footprint slope from this many pings each side (0 = off)");
    v("min_range_m", c.min_range_m, "shorter ranges are not detections, m");
    v("max_range_m", c.max_range_m, "longer ranges are not detections, m");
    v("num_threads", c.num_threads, "0 = all cores");
    v("min_weight", w.min_weight, "weight filter: voxels observed less are removed");
}

template <class V>
void VisitMesh(V&& v, mesh::MeshConfig& c) {
    v("iso_m", c.iso_m, "level of the surface in the distance field, m");
    v("max_hole_edges", c.max_hole_edges, "display mesh: fill holes up to this many edges");
    v("colour_min_z_m", c.colour_min_z_m, "depth colour ramp; both 0 = the mesh's range");
    v("colour_max_z_m", c.colour_max_z_m, "");
}

template <class V>
void VisitQuality(V&& v, QualityConfig& q) {
    v("calibration_residual_ratio",
      q.calibration_residual_ratio,
      "calibration residual RMS / the range noise's, above: gate");
    v("max_clock_scan_s", q.max_clock_scan_s, "widest sonar-clock uncertainty the data resolve, s");
    v("clock_disagreement_s", q.clock_disagreement_s, "configured vs found clock, beyond 3 sigma");
    v("slam_sigma_multiple",
      q.slam_sigma_multiple,
      "SLAM may move a good-INS ping this many sigma");
    v("slam_min_allowance_m", q.slam_min_allowance_m, "... or this far, m");
    v("slam_good_ins_sigma_m", q.slam_good_ins_sigma_m, "INS horizontal sigma below: good, m");
    v("slam_max_fraction", q.slam_max_fraction, "share of good pings moved further: gate");
    v("slam_drift_window_s",
      q.slam_drift_window_s,
      "window in which most good pings moved further: drift gate, s");
    v("slam_consistency_ratio",
      q.slam_consistency_ratio,
      "passes' consistency after SLAM / the range noise's, above: gate");
    v("max_outside_nav_fraction", q.max_outside_nav_fraction, "share of pings outside the nav");
    v("max_cleaned_share",
      q.max_cleaned_share,
      "the cleaning rejecting a larger share of the soundings is a gate");
    v("max_boresight_change_deg",
      q.max_boresight_change_deg,
      "calibration turning the mount further (deg): error");
    v("crossline_tvu_ratio",
      q.crossline_tvu_ratio,
      "crossline RMS / the median TVU's prediction, above: gate");
    v("check_mount", q.check_mount, "georef: the mount against the roll in the soundings");
}

constexpr hydro::Disambiguation kDisambiguations[] = {hydro::Disambiguation::kDensity,
                                                      hydro::Disambiguation::kLocale,
                                                      hydro::Disambiguation::kPredictedSurface};

template <class V>
void VisitGrid(V&& v, GridStageConfig& c) {
    v.Enum("disambiguation",
           c.cube.disambiguation,
           kDisambiguations,
           "density | locale | predicted_surface");
    hydro::CubeConfig& q = c.cube;
    v("in_run", c.in_run, "`pitmap run` makes the grid");
    v("surface_filter", c.surface_filter, "reject soundings off the CUBE surface (floors)");
    v("surface_filter_gate", c.surface_filter_gate, "... beyond this many combined sigmas");
    v("surface_filter_min_m", c.surface_filter_min_m, "... and this far, m");
    v("surface_filter_max_slope_deg", c.surface_filter_max_slope_deg, "... where not steeper, deg");
    v("resolution_m", q.resolution_m, "node spacing, m; 0 = from the median depth");
    v("resolution_depth_fraction", q.resolution_depth_fraction, "auto: depth * this, rounded down");
    v("min_resolution_m", q.min_resolution_m, "auto resolution bounds, m");
    v("max_resolution_m", q.max_resolution_m, "");
    v("capture_distance_scale", q.capture_distance_scale, "capture distance, share of the depth");
    v("min_capture_distance_res", q.min_capture_distance_res, "... at least, in resolutions");
    v("max_capture_distance_res", q.max_capture_distance_res, "... at most, in resolutions");
    v("distance_exponent", q.distance_exponent, "CUBE alpha: variance growth with distance");
    v("horizontal_error_scale", q.horizontal_error_scale, "CUBE rho: THU sigmas added to d");
    v("queue_length", q.queue_length, "median pre-filter queue; 1 = none");
    v("pass_gap_s",
      q.pass_gap_s,
      "soundings of a node further apart are different passes (node uncertainty), s");
    v("common_correlation_s",
      q.common_correlation_s,
      "correlation time of the pass-common errors between passes (node uncertainty), s");
    v("hypothesis_gate", q.hypothesis_gate, "normalised innovation opening a hypothesis");
    v("slope_correction", q.slope_correction, "carry soundings along the predicted surface");
    v("predicted_surface_cells", q.predicted_surface_cells, "predicted surface cell, resolutions");
    v("locale_radius", q.locale_radius, "locale disambiguation radius, nodes");
    v("max_nodes", q.max_nodes, "refuse larger grids");
    v("num_threads", q.num_threads, "0 = all cores");
    v("tpu_sound_speed_mps", c.tpu_sound_speed_mps, "nominal sound speed of the TPU terms");
    v("ins_sigma_max_age_s", c.ins_sigma_max_age_s, "INSSTDEV records used within this, s");
    v("tpu_slam_posterior",
      c.tpu_slam_posterior,
      "TPU pose sigma from SLAM's posterior where SLAM's trajectory is used (false: the INS's);\n"
      "without slam.posterior_start_runs it is optimistic and trips a quality gate");
    v("tpu_sound_speed_from_data",
      c.tpu_sound_speed_from_data,
      "TPU sound speed sigmas from the casts' age, distance and surface disagreement and the\n"
      "swath overlap (docs/uncertainty.md); false: the error model's alone");
    v("sound_speed_cast_age_rate_mps_per_h",
      c.sound_speed.cast_age_rate_mps_per_h,
      "column speed sigma added per hour of the cast's age, m/s");
    v("sound_speed_cast_distance_rate_mps_per_km",
      c.sound_speed.cast_distance_rate_mps_per_km,
      "column speed sigma added per km from the cast, m/s");
    v("write_geotiff", c.write_geotiff, "P/dem.tif (COG)");
    v("write_bag", c.write_bag, "P/dem.bag");
    v("write_sounding_tpu", c.write_sounding_tpu, "P/soundings_tpu.ply (THU/TVU per sounding)");
    v("write_point_tpu",
      c.write_point_tpu,
      "points.ply/.las rewritten with THU, TVU (and the vertical datum)");
}

constexpr hydro::VerticalDatum kDatums[] = {hydro::VerticalDatum::kEllipsoid,
                                            hydro::VerticalDatum::kGeoid,
                                            hydro::VerticalDatum::kWaterLevel};
constexpr hydro::WaterLevelSource kLevelSources[] = {hydro::WaterLevelSource::kGnss,
                                                     hydro::WaterLevelSource::kFile};

template <class V>
void VisitVertical(V&& v, hydro::VerticalDatumConfig& c) {
    v.Enum("datum",
           c.datum,
           kDatums,
           "vertical datum of dem.tif/.bag, points.las, the S-44 depths:\n"
           "ellipsoid (WGS 84) | geoid (PROJ grid) | water_level (the pit's surface)");
    v("geoid_vertical_epsg",
      c.geoid_vertical_epsg,
      "geoid: 5773 EGM96 height | 3855 EGM2008 height");
    v("geoid_grid", c.geoid_grid, "geoid: PROJ grid name or path; \"\" = egm96_15.gtx (proj-data)");
    v.Enum("water_level_source",
           c.water_level_source,
           kLevelSources,
           "water_level: gnss (INS heights, survey median) | file (levels above the datum)");
    v("water_level_file", c.water_level_file, "file: CSV time (UTC ISO 8601), level (m)");
    v("smoothing_window_s", c.smoothing_window_s, "running median of the GNSS water surface, s");
    v("step_s", c.step_s, "its time step, s");
    v.NanIsNull("ins_height_above_waterline_m",
                c.ins_height_above_waterline_m,
                "INS above the water line, m; null = vehicle.yaml's");
    v("max_level_gap_s", c.max_level_gap_s, "file: a ping further from any level is an error, s");
}

constexpr hydro::S44Order kOrders[] = {hydro::S44Order::kExclusive,
                                       hydro::S44Order::kSpecial,
                                       hydro::S44Order::kOrder1a,
                                       hydro::S44Order::kOrder1b,
                                       hydro::S44Order::kOrder2};

template <class V>
void VisitS44(V&& v, GridStageConfig& g) {
    hydro::S44Config& c = g.s44_config;
    v("enabled", g.s44, "IHO S-44 Ed. 6.1 quality control in the grid stage");
    v.Enum("order", c.order, kOrders, "exclusive | special | 1a | 1b | 2");
    v("min_holiday_nodes", c.min_holiday_nodes, "a holiday is at least this many nodes a side");
    v("crossing_angle_deg", c.crossing_angle_deg, "crossline: headings this far apart cross, deg");
    v("min_time_separation_s",
      c.min_time_separation_s,
      "crossline: earlier soundings this older, s");
    v("crossline_cell_m", c.crossline_cell_m, "crossline cell, m; 0 = 2 x grid resolution");
    v("min_reference_soundings", c.min_reference_soundings, "crossing soundings needed a cell");
}

constexpr hydro::AngularCorrection kAngularCorrections[] = {hydro::AngularCorrection::kNone,
                                                            hydro::AngularCorrection::kLambert,
                                                            hydro::AngularCorrection::kEmpirical};

template <class V>
void VisitMosaic(V&& v, GridStageConfig& g) {
    hydro::MosaicConfig& c = g.mosaic_config;
    v("enabled", g.mosaic, "P/mosaic.tif from the 83P intensities in the grid stage");
    v("spreading_db_per_decade",
      c.spreading_db_per_decade,
      "range correction k log10(R): 40 = two-way spherical spreading\n"
      "(40 minus the slope of a TVG the head applied)");
    v("absorption_db_per_m",
      c.absorption_db_per_m,
      "one-way absorption, dB/m (2 a R removed); 0.021 = fresh water, 260 kHz, 10 degC");
    v.Enum("angular",
           c.angular,
           kAngularCorrections,
           "incidence correction: none | lambert (cos^2) | empirical (the survey's mean\n"
           "angular response, incidence from the DEM's slopes)");
    v("reference_angle_deg", c.reference_angle_deg, "corrected to this incidence, deg");
    v("angle_bin_deg", c.angle_bin_deg, "empirical angular response bin, deg");
    v("min_bin_soundings", c.min_bin_soundings, "thinner bins interpolated");
    v("empirical_iterations",
      c.empirical_iterations,
      "refinements of the empirical response against the nodes' means (0 = bin mean)");
    v("max_incidence_deg", c.max_incidence_deg, "soundings beyond are not used, deg");
}

template <class V>
void VisitRun(V&& v, RunOptions& r) {
    v("calibrate", r.calibrate, "boresight calibration before SLAM");
    v("slam", r.slam, "continuous-time SLAM (else the INS trajectory is fused)");
    v("mesh_before_slam", r.mesh_before_slam, "mesh_initial.ply: the mesh before SLAM");
    v("initial_mesh_voxel_factor",
      r.initial_mesh_voxel_factor,
      "mesh_initial's voxel size / fuse.voxel_size_m (a picture for the report)");
    v("initial_mesh_ping_stride",
      r.initial_mesh_ping_stride,
      "mesh_initial is fused from every n-th ping");
    v("report", r.report, "report.html");
    v("report_equipment",
      r.report_equipment,
      "YAML list of .glb equipment models placed in the report's 3D view\n"
      "(pitmap-report --equipment; docs/report.md); \"\" = none");
    v("memory_budget_mb",
      r.memory_budget_mb,
      "the memory a run may hold, MB: stages over it trip a quality gate\n"
      "(docs/decisions/018-memory-budget.md)");
    v("block_soundings",
      r.block_soundings,
      "soundings per block of the block-wise parts (64 bytes each within the budget)");
}

template <class V>
void VisitProducts(V&& v, PipelineConfig& c) {
    v("write_las", c.write_las, "points.las (UTM) beside points.ply");
    v("write_points_utm",
      c.write_points_utm,
      "points_utm.ply (+ .prj) beside points.las: absolute UTM doubles for PLY readers");
    v("write_rejected",
      c.write_rejected,
      "points.ply/las also hold the rejected soundings (PLY status, LAS withheld noise)");
    v("vehicle_yaml", c.vehicle_yaml, "\"\" = vehicle.yaml beside the first log (--vehicle)");
    v.Section("origin", [&](auto& o) {
        o.NanIsNull("latitude_deg", c.origin_latitude_deg, "world origin; null = first INS fix");
        o.NanIsNull("longitude_deg", c.origin_longitude_deg, "");
        o.NanIsNull("height_m", c.origin_height_m, "ellipsoidal, m");
    });
}

template <class V>
void VisitMetadata(V&& v, SurveyMetadataConfig& c) {
    v("project", c.project, "project name (the products' title)");
    v("client", c.client, "who the survey is for");
    v("site", c.site, "the pit's name (also names a water-level vertical datum)");
    v("survey_id", c.survey_id, "the survey's reference");
    v("surveyor", c.surveyor, "the person responsible for the survey");
    v("organisation", c.organisation, "the surveyor's organisation");
    v("vessel", c.vessel, "\"\" = vehicle.yaml's name");
    v("s44_order_target", c.s44_order_target, "\"\" | exclusive | special | 1a | 1b | 2");
    v("notes", c.notes, "free text (several lines allowed)");
}

template <class V>
void VisitTerrain(V&& v, GridStageConfig& g) {
    hydro::TerrainConfig& c = g.terrain_config;
    v("enabled", g.terrain, "P/terrain.tif and P/crawler.tif (mine planning) in the grid stage");
    v("window_m",
      c.window_m,
      "slope and roughness from the plane of a square window this wide, m\n"
      "(the crawler's footprint: wider smooths the slope, narrower follows noise)");
    v("step_window_m",
      c.step_window_m,
      "steps: height range left within this window once the plane is removed, m");
    v("min_fill", c.min_fill, "share of a window's nodes that must have a height");
    v("crawler_max_slope_deg", c.crawler_max_slope_deg, "the crawler drives up to this slope");
    v("crawler_max_step_m", c.crawler_max_step_m, "... climbs steps up to this height, m");
    v("crawler_max_roughness_m", c.crawler_max_roughness_m, "... on ground this rough (RMS), m");
    v.NanIsNull("launch_easting",
                c.launch_easting,
                "launch point in the products' UTM zone, m; null = no reachable area");
    v.NanIsNull("launch_northing", c.launch_northing, "(with launch_easting)");
    v("launch_snap_m", c.launch_snap_m, "start from the traversable node nearest, this close, m");
}

template <class V>
void VisitTiles(V&& v, TilesConfig& c) {
    v("enabled", c.enabled, "grid and fuse tile by tile (docs/tiles.md); off = whole survey");
    v("tile_size_m", c.tile_size_m, "nominal tile edge, m (>= 64 voxels, >= 8 grid nodes)");
    v("overlap_m", c.overlap_m, "data around a tile's core, m (>= truncation, >= CUBE's reach)");
    v("write_products", c.write_products, "P/tiles/: DEM tiles (COG) + VRT, mesh tiles + index");
}

// The sections of the processor config, in file order.
template <class V>
void VisitConfig(V&& v, PipelineConfig& c) {
    v.Section("ingest", [&](auto& s) { VisitIngest(s, c.ingest); });
    v.Section("georef", [&](auto& s) { VisitGeoref(s, c.georef); });
    v.Section("refraction", [&](auto& s) { VisitRefraction(s, c.refraction); });
    v.Section("calibrate", [&](auto& s) { VisitCalibrate(s, c.calibrate); });
    v.Section("slam", [&](auto& s) { VisitSlam(s, c.slam, c.slam_stage); });
    v.Section("clean", [&](auto& s) { VisitClean(s, c.clean); });
    v.Section("fuse", [&](auto& s) { VisitFuse(s, c.tsdf, c.weight_filter); });
    v.Section("mesh", [&](auto& s) { VisitMesh(s, c.mesh); });
    v.Section("grid", [&](auto& s) { VisitGrid(s, c.grid); });
    v.Section("vertical", [&](auto& s) { VisitVertical(s, c.grid.vertical); });
    v.Section("s44", [&](auto& s) { VisitS44(s, c.grid); });
    v.Section("mosaic", [&](auto& s) { VisitMosaic(s, c.grid); });
    v.Section("terrain", [&](auto& s) { VisitTerrain(s, c.grid); });
    v.Section("tiles", [&](auto& s) { VisitTiles(s, c.tiles); });
    v.Section("run", [&](auto& s) { VisitRun(s, c.run); });
    v.Section("quality", [&](auto& s) { VisitQuality(s, c.quality); });
    v.Section("products", [&](auto& s) { VisitProducts(s, c); });
    v.Section("metadata", [&](auto& s) { VisitMetadata(s, c.metadata); });
}

// Reads every entry from a YAML map; problems are collected in the ConfigReader.
class ReadVisitor {
public:
    explicit ReadVisitor(ConfigReader in) : in_(std::move(in)) {}
    template <class T>
    void operator()(const char* key, T& value, const char*) {
        in_.Read(key, value);
    }
    // An enum spelled as one of its ToString names; a problem lists the valid ones.
    template <class E, std::size_t N>
    void Enum(const char* key, E& value, const E (&all)[N], const char*) {
        std::string text = ToString(value);
        if (!in_.Read(key, text)) return;
        std::string valid;
        for (E e : all) {
            if (text == ToString(e)) {
                value = e;
                return;
            }
            valid += std::string(valid.empty() ? "" : ", ") + ToString(e);
        }
        in_.AddProblem(in_.Path(key) + ": '" + text + "' is not one of " + valid);
    }
    void Optional(const char* key, double& value, bool& known, const char*) {
        if (in_.Read(key, value)) known = true;
    }
    void NanIsNull(const char* key, double& value, const char*) { in_.Read(key, value); }
    template <class F>
    void Section(const char* name, F&& entries) {
        ReadVisitor child(in_.Child(name));
        entries(child);
        child.in_.RejectUnknownKeys();
    }

private:
    ConfigReader in_;
};

// A YAML double-quoted scalar: backslash, quote and control characters escaped (a newline
// printed as such would fold into a space when read back).
std::string YamlQuoted(const std::string& s) {
    std::string o = "\"";
    for (const char c : s) {
        if (c == '"' || c == '\\') {
            o += '\\';
            o += c;
        } else if (c == '\n') {
            o += "\\n";
        } else if (c == '\t') {
            o += "\\t";
        } else if (static_cast<unsigned char>(c) < 0x20) {
            char b[8];
            std::snprintf(b, sizeof b, "\\x%02x", static_cast<unsigned>(c));
            o += b;
        } else {
            o += c;
        }
    }
    return o + "\"";
}

// Prints every entry as YAML, "key: value  # comment", indented by section depth.
class PrintVisitor {
public:
    PrintVisitor(std::ostringstream& out, int depth) : out_(out), depth_(depth) {}
    template <class T>
    void operator()(const char* key, T& value, const char* comment) {
        std::ostringstream v;
        v << std::setprecision(15);
        if constexpr (std::is_same_v<T, bool>) {
            v << (value ? "true" : "false");
        } else if constexpr (std::is_same_v<T, std::string>) {
            v << YamlQuoted(value);
        } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
            v << "[";
            for (std::size_t i = 0; i < value.size(); ++i) {
                v << (i > 0 ? ", " : "") << YamlQuoted(value[i]);
            }
            v << "]";
        } else {
            v << value;
        }
        Line(key, v.str(), comment);
    }
    template <class E, std::size_t N>
    void Enum(const char* key, E& value, const E (&)[N], const char* comment) {
        Line(key, ToString(value), comment);
    }
    void Optional(const char* key, double& value, bool& known, const char* comment) {
        double v = known ? value : std::numeric_limits<double>::quiet_NaN();
        NanIsNull(key, v, comment);
    }
    void NanIsNull(const char* key, double& value, const char* comment) {
        std::ostringstream v;
        v << std::setprecision(15);
        if (std::isnan(value)) {
            v << "null";
        } else {
            v << value;
        }
        Line(key, v.str(), comment);
    }
    template <class F>
    void Section(const char* name, F&& entries) {
        out_ << std::string(2 * depth_, ' ') << name << ":\n";
        PrintVisitor child(out_, depth_ + 1);
        entries(child);
    }

private:
    void Line(const char* key, const std::string& value, const std::string& comment) {
        std::string text = std::string(2 * depth_, ' ') + key + ": " + value;
        std::istringstream lines(comment);
        for (std::string c; std::getline(lines, c);) {
            text.resize(std::max<std::size_t>(text.size() + 1, 38), ' ');
            out_ << text << "# " << c << "\n";
            text.clear();
        }
        if (!text.empty()) out_ << text << "\n";
    }
    std::ostringstream& out_;
    int depth_;
};

}  // namespace

const char* ToString(slam::CorrespondenceType t) {
    switch (t) {
        case slam::CorrespondenceType::kPointToPoint:
            return "point_to_point";
        case slam::CorrespondenceType::kPointToPlane:
            return "point_to_plane";
        case slam::CorrespondenceType::kGicp:
            return "gicp";
    }
    return "?";
}

const char* ToString(slam::RobustKernel k) {
    switch (k) {
        case slam::RobustKernel::kNone:
            return "none";
        case slam::RobustKernel::kHuber:
            return "huber";
        case slam::RobustKernel::kCauchy:
            return "cauchy";
    }
    return "?";
}

const char* ToString(fusion::SensorModel m) {
    return m == fusion::SensorModel::kRay ? "ray" : "beam_width";
}

std::vector<std::string> QualityConfig::Validate() const {
    std::vector<std::string> p;
    if (!(calibration_residual_ratio >= 1)) p.push_back("calibration_residual_ratio must be >= 1");
    if (!(max_clock_scan_s > 0)) p.push_back("max_clock_scan_s must be > 0");
    if (!(clock_disagreement_s >= 0)) p.push_back("clock_disagreement_s must be >= 0");
    if (!(slam_sigma_multiple > 0)) p.push_back("slam_sigma_multiple must be > 0");
    if (!(slam_min_allowance_m >= 0)) p.push_back("slam_min_allowance_m must be >= 0");
    if (!(slam_good_ins_sigma_m > 0)) p.push_back("slam_good_ins_sigma_m must be > 0");
    if (!(slam_max_fraction >= 0 && slam_max_fraction <= 1))
        p.push_back("slam_max_fraction must be in [0, 1]");
    if (!(slam_consistency_ratio >= 1)) p.push_back("slam_consistency_ratio must be >= 1");
    if (!(slam_drift_window_s >= 1 && slam_drift_window_s <= 3600))
        p.push_back("slam_drift_window_s must be in [1, 3600]");
    if (!(max_outside_nav_fraction >= 0 && max_outside_nav_fraction <= 1))
        p.push_back("max_outside_nav_fraction must be in [0, 1]");
    if (!(max_cleaned_share > 0 && max_cleaned_share <= 1))
        p.push_back("max_cleaned_share must be in (0, 1]");
    if (!(max_boresight_change_deg > 0 && max_boresight_change_deg <= 90))
        p.push_back("max_boresight_change_deg must be in (0, 90]");
    if (!(crossline_tvu_ratio >= 1)) p.push_back("crossline_tvu_ratio must be >= 1");
    return p;
}

std::vector<std::string> RunOptions::Validate() const {
    std::vector<std::string> p;
    if (!(initial_mesh_voxel_factor >= 1.0 && initial_mesh_voxel_factor <= 8.0))
        p.push_back("run.initial_mesh_voxel_factor must be within 1..8");
    if (initial_mesh_ping_stride < 1 || initial_mesh_ping_stride > 8)
        p.push_back("run.initial_mesh_ping_stride must be within 1..8");
    if (!report_equipment.empty() && ::access(report_equipment.c_str(), R_OK) != 0)
        p.push_back("run.report_equipment: " + report_equipment + ": no such readable file");
    if (!(memory_budget_mb >= 64)) p.push_back("run.memory_budget_mb must be >= 64");
    if (block_soundings < 1024) {
        p.push_back("run.block_soundings must be >= 1024 (a ping of the widest sonar)");
    } else if (std::isfinite(memory_budget_mb) &&
               static_cast<double>(block_soundings) * kBlockBytesPerSounding >
                   memory_budget_mb * 1048576.0) {
        p.push_back(
            "run.block_soundings: one block of " + std::to_string(block_soundings) +
            " soundings (" +
            std::to_string(static_cast<long long>(std::ceil(static_cast<double>(block_soundings) *
                                                            kBlockBytesPerSounding / 1048576.0))) +
            " MB at " + std::to_string(static_cast<int>(kBlockBytesPerSounding)) +
            " bytes a sounding) does not fit in run.memory_budget_mb (" +
            std::to_string(static_cast<long long>(memory_budget_mb)) + " MB)");
    }
    return p;
}

std::vector<std::string> PipelineConfig::Validate() const {
    std::vector<std::string> p = ingest.Validate();
    for (auto& s : run.Validate()) p.push_back(s);
    for (auto& s : georef.Validate()) p.push_back(s);
    for (auto& s : refraction.Validate()) p.push_back(s);
    for (auto& s : calibrate.Validate()) p.push_back(s);
    for (auto& s : slam.Validate()) p.push_back("slam." + s);
    for (auto& s : clean.Validate()) p.push_back(s);
    for (auto& s : tsdf.Validate()) p.push_back("fuse." + s);
    for (auto& s : weight_filter.Validate()) p.push_back("fuse." + s);
    for (auto& s : mesh.Validate()) p.push_back("mesh." + s);
    for (auto& s : quality.Validate()) p.push_back("quality." + s);
    for (auto& s : grid.Validate()) p.push_back(s);
    for (auto& s : tiles.Validate()) p.push_back(s);
    for (auto& s : ValidateTiles(tiles, tsdf, grid.cube)) p.push_back(s);
    for (auto& s : metadata.Validate()) p.push_back(s);
    if (slam_stage.point_stride < 1) p.push_back("slam.point_stride must be >= 1");
    if (!(slam_stage.sigma_max_age_s > 0)) p.push_back("slam.sigma_max_age_s must be > 0");
    const bool any = !std::isnan(origin_latitude_deg) || !std::isnan(origin_longitude_deg) ||
                     !std::isnan(origin_height_m);
    const bool all = !std::isnan(origin_latitude_deg) && !std::isnan(origin_longitude_deg) &&
                     !std::isnan(origin_height_m);
    if (any && !all) p.push_back("products.origin needs latitude_deg, longitude_deg and height_m");
    if (all && std::abs(origin_latitude_deg) > 90)
        p.push_back("products.origin.latitude_deg out of range");
    return p;
}

Expected<PipelineConfig> LoadConfig(const std::string& path) {
    auto reader = ConfigReader::FromFile(path);
    if (!reader) return reader.error();
    PipelineConfig c;
    VisitConfig(ReadVisitor(*reader), c);
    reader->RejectUnknownKeys();
    std::vector<std::string> problems = reader->problems();
    for (auto& s : c.Validate()) problems.push_back(path + ": " + s);
    if (!problems.empty()) return Error{"invalid config:\n" + FormatProblems(problems)};
    return c;
}

std::size_t BlockWithinBudget(const RunOptions& run, double resident_mb) {
    const auto configured =
        static_cast<std::size_t>(std::max<int>(run.block_soundings, kMinBlockSoundings));
    const double headroom_mb = run.memory_budget_mb - std::max(0.0, resident_mb);
    if (!(headroom_mb < std::numeric_limits<double>::infinity())) return configured;
    const double fits = std::floor(std::max(0.0, headroom_mb) * 1048576.0 / kBlockBytesPerSounding);
    if (fits >= static_cast<double>(configured)) return configured;
    return std::max(kMinBlockSoundings, static_cast<std::size_t>(fits));
}

std::string ConfigYaml(const PipelineConfig& config) {
    PipelineConfig c = config;
    std::ostringstream o;
    VisitConfig(PrintVisitor(o, 0), c);
    return o.str();
}

std::string DefaultsYaml() {
    std::ostringstream o;
    o << "# pitmap processor configuration: every key with its default.\n"
      << ConfigYaml(PipelineConfig{});
    // The vehicle file is separate (products.vehicle_yaml, --vehicle): its schema as comments,
    // so that this output stays a valid processor config.
    o << "#\n# vehicle.yaml, a separate file (`pitmap config --vehicle` prints it uncommented):\n";
    std::istringstream vehicle(VehicleYamlTemplate());
    for (std::string line; std::getline(vehicle, line);) o << "#   " << line << "\n";
    return o.str();
}

}  // namespace pitmap::proc::pipeline
