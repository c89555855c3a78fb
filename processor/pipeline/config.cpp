// SPDX-License-Identifier: MIT
// The processor's YAML configuration: reading with every problem listed, validation, defaults.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <type_traits>

#include "common/config.hpp"
#include "common/vehicle.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pitmap::proc::pipeline {

namespace {

// The keys of the 3-D stages, visited once for reading (ConfigReader) and once for printing
// the defaults, so the two cannot drift apart. Enums are handled beside the visitors.
template <class V>
void VisitSlam(V&& v, slam::SlamConfig& c, SlamStageConfig& s) {
    v("point_stride", s.point_stride, "every n-th kept sounding of a ping enters SLAM");
    v("min_time_separation_s",
      c.min_time_separation_s,
      "t_d: pairs only between slices this far apart, s");
    v("max_pair_distance_m",
      c.max_pair_distance_m,
      "d_max: closest-point pairs closer than this, m");
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
    v("convergence_rotation_rad", c.convergence_rotation_rad, "converged below this pose update");
    v("convergence_translation_m", c.convergence_translation_m, "... and this one");
    v("normal_neighbours", c.normal_neighbours, "neighbours for normals / covariances");
    v("point_sigma_m", c.point_sigma_m, "1-sigma of a point along the surface normal, m");
    v("gicp_tangent_sigma_m", c.gicp_tangent_sigma_m, "GICP: 1-sigma along the surface, m");
    v("robust_width", c.robust_width, "robust kernel width, point sigmas");
    v("query_stride", c.query_stride, "every n-th point of a slice is a query point");
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
    v("absolute_position_terms", c.absolute_position_terms, "GNSS/INS position prior per pose");
    v("absolute_attitude_terms", c.absolute_attitude_terms, "INS attitude prior per pose");
    v("absolute_sigma_scale", c.absolute_sigma_scale, "scales the absolute priors' sigmas");
    v("score_cell_m", c.score_cell_m, "plane-fit consistency score grid cell (reported), m");
    v("score_patience",
      c.score_patience,
      "stop after this many iterations without a better pair score");
    v("score_tolerance", c.score_tolerance, "a gain counts above this fraction");
    v("num_threads", c.num_threads, "0 = all cores");
    v("sigma_max_age_s", s.sigma_max_age_s, "INS stddev records further from a ping are unused, s");
}

template <class V>
void VisitFuse(V&& v, fusion::TsdfConfig& c, fusion::WeightFilterConfig& w) {
    v("voxel_size_m", c.voxel_size_m, "voxel edge, m");
    v("truncation_m", c.truncation_m, "truncation band, m");
    v("weight_per_measurement", c.weight_per_measurement, "f (uniform weights)");
    v("max_weight", c.max_weight, "w_max");
    v("beam_width_rad", c.beam_width_rad, "out-of-plane beam width, rad");
    v("footprint_gate_m", c.footprint_gate_m, "beam-width: a footprint beam agrees within this");
    v("footprint_gate_fraction", c.footprint_gate_fraction, "... plus this share of the range");
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
    v("max_outside_nav_fraction", q.max_outside_nav_fraction, "share of pings outside the nav");
}

template <class V>
void VisitRun(V&& v, RunOptions& r) {
    v("calibrate", r.calibrate, "boresight calibration before SLAM");
    v("slam", r.slam, "continuous-time SLAM (else the INS trajectory is fused)");
    v("mesh_before_slam", r.mesh_before_slam, "mesh_initial.ply: the mesh before SLAM");
    v("report", r.report, "report.html");
}

struct ReadVisitor {
    ConfigReader& in;
    template <class T>
    void operator()(const char* key, T& value, const char*) {
        in.Read(key, value);
    }
};

struct PrintVisitor {
    std::ostringstream& out;
    template <class T>
    void operator()(const char* key, T& value, const char* comment) {
        std::ostringstream line;
        line << std::setprecision(10) << "  " << key << ": ";
        if constexpr (std::is_same_v<T, bool>) {
            line << (value ? "true" : "false");
        } else {
            line << value;
        }
        std::string text = line.str();
        if (*comment != 0) {
            text.resize(std::max<std::size_t>(text.size() + 1, 38), ' ');
            text += std::string("# ") + comment;
        }
        out << text << "\n";
    }
};

// Reads an enum spelled as one of its ToString names; a problem lists the valid ones.
template <class E, std::size_t N>
void ReadEnum(ConfigReader& in, const char* key, E& value, const E (&all)[N]) {
    std::string text = ToString(value);
    if (!in.Read(key, text)) return;
    std::string valid;
    for (E e : all) {
        if (text == ToString(e)) {
            value = e;
            return;
        }
        valid += std::string(valid.empty() ? "" : ", ") + ToString(e);
    }
    in.AddProblem(in.Path(key) + ": '" + text + "' is not one of " + valid);
}

constexpr slam::CorrespondenceType kCorrespondences[] = {slam::CorrespondenceType::kPointToPoint,
                                                         slam::CorrespondenceType::kPointToPlane,
                                                         slam::CorrespondenceType::kGicp};
constexpr slam::RobustKernel kKernels[] = {
    slam::RobustKernel::kNone, slam::RobustKernel::kHuber, slam::RobustKernel::kCauchy};
constexpr fusion::SensorModel kSensorModels[] = {fusion::SensorModel::kBeamWidth,
                                                 fusion::SensorModel::kRay};

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
    if (!(max_outside_nav_fraction >= 0 && max_outside_nav_fraction <= 1))
        p.push_back("max_outside_nav_fraction must be in [0, 1]");
    return p;
}

std::vector<std::string> PipelineConfig::Validate() const {
    std::vector<std::string> p = ingest.Validate();
    for (auto& s : georef.Validate()) p.push_back(s);
    for (auto& s : calibrate.Validate()) p.push_back(s);
    for (auto& s : slam.Validate()) p.push_back("slam." + s);
    for (auto& s : tsdf.Validate()) p.push_back("fuse." + s);
    for (auto& s : weight_filter.Validate()) p.push_back("fuse." + s);
    for (auto& s : mesh.Validate()) p.push_back("mesh." + s);
    for (auto& s : quality.Validate()) p.push_back("quality." + s);
    for (auto& s : grid.Validate()) p.push_back(s);
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
    ConfigReader in = reader->Child("ingest");
    std::string source = io::ToString(c.ingest.source);
    in.Read("source", source);
    if (!io::ParseIngestSource(source, c.ingest.source)) {
        in.AddProblem(in.Path("source") + ": must be auto, decoded or raw");
    }
    in.Read("nav_channel_id", c.ingest.nav_channel_id);
    in.Read("sonar_channel_id", c.ingest.sonar_channel_id);
    if (in.Has("sonar_clock_offset_s")) c.ingest.sonar_clock_offset_known = true;
    in.Read("sonar_clock_offset_s", c.ingest.sonar_clock_offset_s);
    in.Read("require_good_ins", c.ingest.require_good_ins);
    in.RejectUnknownKeys();
    ConfigReader g = reader->Child("georef");
    auto& gc = c.georef;
    g.Read("max_nav_gap_s", gc.max_nav_gap_s);
    g.Read("min_range_m", gc.min_range_m);
    g.Read("max_range_m", gc.max_range_m);
    g.Read("sound_speed_scaling", gc.sound_speed_scaling);
    g.Read("nominal_sound_speed_mps", gc.nominal_sound_speed_mps);
    g.Read("apply_profile_tilt", gc.apply_profile_tilt);
    g.Read("spike_half_window", gc.spike_half_window);
    g.Read("spike_abs_m", gc.spike_abs_m);
    g.Read("spike_rel", gc.spike_rel);
    g.Read("num_threads", gc.num_threads);
    g.RejectUnknownKeys();
    ConfigReader b = reader->Child("calibrate");
    auto& bc = c.calibrate;
    b.Read("segment_start_s", bc.segment_start_s);
    b.Read("segment_duration_s", bc.segment_duration_s);
    b.Read("part_duration_s", bc.part_duration_s);
    b.Read("min_separation_s", bc.min_separation_s);
    b.Read("beam_stride", bc.beam_stride);
    b.Read("max_distance_m", bc.max_distance_m);
    b.Read("min_distance_m", bc.min_distance_m);
    b.Read("normal_radius_m", bc.normal_radius_m);
    b.Read("cauchy_scale_m", bc.cauchy_scale_m);
    b.Read("max_iterations", bc.max_iterations);
    b.Read("convergence_deg", bc.convergence_deg);
    b.Read("max_position_stddev_m", bc.max_position_stddev_m);
    b.Read("max_heading_stddev_deg", bc.max_heading_stddev_deg);
    b.Read("num_verify_segments", bc.num_verify_segments);
    b.Read("estimate_height_offsets", bc.estimate_height_offsets);
    b.Read("height_offset_sigma_m", bc.height_offset_sigma_m);
    b.Read("range_noise_fraction", bc.range_noise_fraction);
    b.Read("range_noise_constant_m", bc.range_noise_constant_m);
    b.Read("estimate_latency", bc.estimate_latency);
    b.Read("latency_sigma_s", bc.latency_sigma_s);
    b.Read("latency_scan_step_s", bc.latency_scan_step_s);
    b.RejectUnknownKeys();
    {
        ConfigReader sl = reader->Child("slam");
        VisitSlam(ReadVisitor{sl}, c.slam, c.slam_stage);
        ReadEnum(sl, "correspondence", c.slam.correspondence, kCorrespondences);
        ReadEnum(sl, "robust_kernel", c.slam.robust_kernel, kKernels);
        sl.RejectUnknownKeys();
        ConfigReader fu = reader->Child("fuse");
        VisitFuse(ReadVisitor{fu}, c.tsdf, c.weight_filter);
        ReadEnum(fu, "sensor_model", c.tsdf.sensor_model, kSensorModels);
        fu.RejectUnknownKeys();
        ConfigReader me = reader->Child("mesh");
        VisitMesh(ReadVisitor{me}, c.mesh);
        me.RejectUnknownKeys();
        ConfigReader ru = reader->Child("run");
        VisitRun(ReadVisitor{ru}, c.run);
        ru.RejectUnknownKeys();
        ConfigReader qu = reader->Child("quality");
        VisitQuality(ReadVisitor{qu}, c.quality);
        qu.RejectUnknownKeys();
    }
    {
        ConfigReader gr = reader->Child("grid");
        ReadGridConfig(gr, c.grid);
    }
    ConfigReader pr = reader->Child("products");
    pr.Read("write_las", c.write_las);
    pr.Read("vehicle_yaml", c.vehicle_yaml);
    ConfigReader o = pr.Child("origin");
    o.Read("latitude_deg", c.origin_latitude_deg);
    o.Read("longitude_deg", c.origin_longitude_deg);
    o.Read("height_m", c.origin_height_m);
    o.RejectUnknownKeys();
    pr.RejectUnknownKeys();
    reader->RejectUnknownKeys();
    std::vector<std::string> problems = reader->problems();
    for (auto& s : c.Validate()) problems.push_back(path + ": " + s);
    if (!problems.empty()) return Error{"invalid config:\n" + FormatProblems(problems)};
    return c;
}

std::string DefaultsYaml() {
    const PipelineConfig c;
    std::ostringstream o;
    auto b = [](bool v) { return v ? "true" : "false"; };
    o << "# pitmap processor configuration: every key with its default.\n"
      << "ingest:\n"
      << "  source: " << io::ToString(c.ingest.source)
      << "            # auto | decoded | raw (re-decode RAW_* channels)\n"
      << "  nav_channel_id: \"\"        # e.g. novatel_com1; \"\" = every INS channel\n"
      << "  sonar_channel_id: \"\"      # e.g. deltat_udp; \"\" = every sonar channel\n"
      << "  sonar_clock_offset_s: null  # .83P files: sonar (header) clock minus UTC, s:\n"
      << "                              # > 0 = the sonar clock is ahead, < 0 = behind;\n"
      << "                              # null = vehicle.yaml's sonar.clock_offset_s, else 0\n"
      << "  require_good_ins: " << b(c.ingest.require_good_ins)
      << "   # drop INS samples not INS_SOLUTION_GOOD\n"
      << "georef:\n"
      << "  max_nav_gap_s: " << c.georef.max_nav_gap_s
      << "          # refuse pings across longer INS gaps, s\n"
      << "  min_range_m: " << c.georef.min_range_m << "            # range gate, m\n"
      << "  max_range_m: " << c.georef.max_range_m << "            # range gate, m\n"
      << "  sound_speed_scaling: " << b(c.georef.sound_speed_scaling)
      << "  # r *= c_header / nominal\n"
      << "  nominal_sound_speed_mps: " << c.georef.nominal_sound_speed_mps << "\n"
      << "  apply_profile_tilt: " << b(c.georef.apply_profile_tilt) << "\n"
      << "  spike_half_window: " << c.georef.spike_half_window
      << "      # beams each side of the median; 0 = off\n"
      << "  spike_abs_m: " << c.georef.spike_abs_m
      << "            # spike if |r - median| > abs + rel * median\n"
      << "  spike_rel: " << c.georef.spike_rel << "\n"
      << "  num_threads: " << c.georef.num_threads << "              # 0 = all cores\n"
      << "calibrate:\n"
      << "  segment_start_s: " << c.calibrate.segment_start_s
      << "         # GPS seconds; < 0 = automatic\n"
      << "  segment_duration_s: " << c.calibrate.segment_duration_s << "\n"
      << "  part_duration_s: " << c.calibrate.part_duration_s << "\n"
      << "  min_separation_s: " << c.calibrate.min_separation_s
      << "      # pairs only between soundings this far apart\n"
      << "  beam_stride: " << c.calibrate.beam_stride << "\n"
      << "  max_distance_m: " << c.calibrate.max_distance_m
      << "        # correspondence gate, first iteration\n"
      << "  min_distance_m: " << c.calibrate.min_distance_m << "        # ... last iteration\n"
      << "  normal_radius_m: " << c.calibrate.normal_radius_m << "\n"
      << "  cauchy_scale_m: " << c.calibrate.cauchy_scale_m << "\n"
      << "  max_iterations: " << c.calibrate.max_iterations << "\n"
      << "  convergence_deg: " << c.calibrate.convergence_deg << "\n"
      << "  max_position_stddev_m: " << c.calibrate.max_position_stddev_m << " # low-drift limit\n"
      << "  max_heading_stddev_deg: " << c.calibrate.max_heading_stddev_deg << "\n"
      << "  num_verify_segments: " << c.calibrate.num_verify_segments << "\n"
      << "  estimate_height_offsets: " << b(c.calibrate.estimate_height_offsets)
      << "  # per-node INS height corrections (else parallel passes bias roll)\n"
      << "  height_offset_sigma_m: " << c.calibrate.height_offset_sigma_m << "  # their prior\n"
      << "  range_noise_fraction: " << c.calibrate.range_noise_fraction
      << "  # pair weights 1/sigma^2, sigma = fraction * range + constant\n"
      << "  range_noise_constant_m: " << c.calibrate.range_noise_constant_m << "\n"
      << "  estimate_latency: " << b(c.calibrate.estimate_latency)
      << "      # the sonar time offset as a 4th unknown (patch test latency)\n"
      << "  latency_sigma_s: " << c.calibrate.latency_sigma_s
      << "         # its prior, 1 sigma, s\n"
      << "  latency_scan_step_s: " << c.calibrate.latency_scan_step_s
      << "  # scan step when the clock is uncertain beyond the linear range, s\n";
    {
        PipelineConfig d;
        o << "slam:\n";
        o << "  correspondence: " << ToString(d.slam.correspondence)
          << "          # point_to_point (the paper) | point_to_plane | gicp\n";
        o << "  robust_kernel: " << ToString(d.slam.robust_kernel)
          << "            # none | huber | cauchy\n";
        VisitSlam(PrintVisitor{o}, d.slam, d.slam_stage);
        o << "fuse:\n";
        o << "  sensor_model: " << ToString(d.tsdf.sensor_model)
          << "       # beam_width (May et al.) | ray\n";
        VisitFuse(PrintVisitor{o}, d.tsdf, d.weight_filter);
        o << "mesh:\n";
        VisitMesh(PrintVisitor{o}, d.mesh);
        o << "run:\n";
        VisitRun(PrintVisitor{o}, d.run);
        o << "quality:\n";
        VisitQuality(PrintVisitor{o}, d.quality);
    }
    o << GridDefaultsYaml();
    o << "products:\n"
      << "  write_las: " << b(c.write_las) << "\n"
      << "  vehicle_yaml: \"\"          # \"\" = vehicle.yaml beside the first log (--vehicle)\n"
      << "  origin:                    # world origin; absent = first INS position\n"
      << "    latitude_deg: null\n    longitude_deg: null\n    height_m: null\n";
    // The vehicle file is separate (products.vehicle_yaml, --vehicle): its schema as comments,
    // so that this output stays a valid processor config.
    o << "#\n# vehicle.yaml, a separate file (`pitmap config --vehicle` prints it uncommented):\n";
    std::istringstream vehicle(VehicleYamlTemplate());
    for (std::string line; std::getline(vehicle, line);) o << "#   " << line << "\n";
    return o.str();
}

}  // namespace pitmap::proc::pipeline
